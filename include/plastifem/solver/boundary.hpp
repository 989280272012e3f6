#pragma once
// Dirichlet conditions as sets with handles, so that a grasper can attach, move and let go.
//
// A constraint set is a list of nodes, a mask of components, and a prescribed motion u(t, X).
// Sets apply in the order they were added; where two sets constrain the same dof, the later one
// wins, and releasing it lets the earlier one apply again. A handle names the set for
// release() and replace().
//
// In dynamics the velocity and acceleration at constrained dofs come from the prescribed path
// itself, never from Newmark-differencing the prescribed displacements (which, after any kink
// of the path, alternates in sign and grows like 1 / dt, and through the consistent mass
// coupling M_fc a_c feeds into the free dofs and the reactions). The user may give the
// velocity and acceleration of the path; otherwise they are taken from one-sided (backward)
// differences of the path at t, of second order,
//   v(t) = (3 g(t) - 4 g(t - h) + g(t - 2h)) / (2h),
//   a(t) = (2 g(t) - 5 g(t - h) + 4 g(t - 2h) - g(t - 3h)) / h^2,
// (evaluated as differences of neighbouring values, so that a constant path gives exactly 0)
// with h = min(dt / 16, 1e-4) rounded to what the clock holds at t (fl(t + h) - t, so that
// the differences see the path over the h they divide by: at t = 1e9 an ulp is 1.2e-7): backward, so that a path held constant from the previous step on
// (a grasp that stops) gives v = a = 0 exactly, and a path linear over the step (a ramp) gives
// its slope and zero acceleration exactly; h well inside the step, so that a kink at a step
// boundary affects one step only; h no smaller than it must be for the round-off of the second
// difference (12 eps |g| / h^2: 3e-7 |g| at h = 1e-4, for paths of unit time scale). Fixed dofs
// (no path) have v = a = 0.
#include <plastifem/core/error.hpp>
#include <plastifem/core/handle_owner.hpp>
#include <plastifem/core/types.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <deque>
#include <functional>
#include <limits>
#include <memory>
#include <span>
#include <vector>

namespace plastifem {

/// Scales a load or a prescribed displacement over time; default: constant 1.
using LoadCurve = std::function<Scalar(Scalar time)>;

/// Ramp 0 -> 1 over [0, t_ramp], hold until t_release, then 0: the grasper pull of seed 000
/// Fig. 1 and the stretch profile of SCENES.md.
inline LoadCurve ramp_hold_release(Scalar t_ramp, Scalar t_release) {
  return [=](Scalar t) { return t >= t_release ? 0.0 : (t_ramp > 0 ? std::min(t / t_ramp, 1.0) : 1.0); };
}

/// The path of a grasper driven by a device read between steps (a haptic arm), for
/// Solver::grasp. A path that returns the latest reading is a staircase in time: its velocity is
/// 0 inside every step, so the grasp moves without velocity and damping and inertia see none.
/// Here each reading is a sample (t, p) of the device's position, and the path runs linearly
/// from sample to sample:
///
///   DeviceSamples device(s.time(), arm.position());
///   const ConstraintHandle h = s.grasp(nodes, device.path());
///   every frame: device.add(s.time() + dt, arm.position()); s.step(dt);
///
/// Read that way, a reading is the position for the end of the coming step (one frame of
/// latency, as in haptic rendering) and a step sees one straight segment: the grasp moves at
/// the samples' velocity with zero acceleration, and its path is continuous. Beyond the last
/// sample the path goes on at the last segment's velocity (a sample that comes late does not
/// stop the grasp); before the first it stays at the first. A reading for the current time
/// (add(s.time(), p)) is accepted too, but the path then jumps to it at that time and the step
/// that follows carries the jump, as any discontinuous path does.
/// Samples must come in increasing time. A recorded trajectory may be queued ahead; the last
/// `capacity` samples are kept, and a path asked for a time before the oldest kept one, once
/// older ones were dropped, is refused (it kept 8, and returned the oldest of them for any
/// earlier time: 20 samples queued ahead left the grasp still; found by review, 2026-12-01).
class DeviceSamples {
 public:
  static constexpr size_t capacity = 4096;

  DeviceSamples(Scalar t0, const Vec3& p0) : data_(std::make_shared<Data>()) { add(t0, p0); }
  /// The device's position p at time t, later than the last sample's.
  void add(Scalar t, const Vec3& p) {
    if (!std::isfinite(t) || !p.allFinite())
      fail<InvalidArgument>("device sample: time {} and position ({}, {}, {}) must be finite", t, p.x(), p.y(), p.z());
    auto& d = *data_;
    if (!d.time.empty() && !(t > d.time.back()))
      fail<InvalidArgument>("device sample: time {} is not after the last sample's, {}", t, d.time.back());
    d.time.push_back(t), d.position.push_back(p);
    if (d.time.size() > capacity) d.time.pop_front(), d.position.pop_front(), d.dropped = true;
  }
  /// The path through the samples (shares them: samples added later move it).
  std::function<Vec3(Scalar)> path() const {
    return [data = data_](Scalar t) { return data->at(t); };
  }

 private:
  struct Data {
    std::deque<Scalar> time;
    std::deque<Vec3> position;
    bool dropped = false;  ///< older samples than time.front() were dropped
    Vec3 at(Scalar t) const {
      if (dropped && t < time.front())
        fail<InvalidArgument>("device samples: the path at t = {} is before the oldest sample kept, at {} (the last {} "
                              "are kept: add samples as the simulation comes to them)",
                              t, time.front(), capacity);
      const size_t n = time.size();
      if (n == 1 || t <= time.front()) return position.front();
      // The segment [k - 1, k] containing t, or the last one, extended.
      const size_t k = std::min(n - 1, static_cast<size_t>(std::lower_bound(time.begin(), time.end(), t) - time.begin()));
      const Scalar w = (t - time[k - 1]) / (time[k] - time[k - 1]);
      return Vec3(position[k - 1] + w * (position[k] - position[k - 1]));
    }
  };
  std::shared_ptr<Data> data_;
};

/// Which displacement components a constraint fixes.
struct DofMask {
  bool x = true, y = true, z = true;
  bool operator[](int d) const { return d == 0 ? x : d == 1 ? y : z; }
};

/// Displacement (or its velocity, or acceleration) of a constrained node at time t, for rest
/// position X.
using PrescribedDisplacement = std::function<Vec3(Scalar time, const Vec3& rest_position)>;

/// A prescribed path: the displacement, and optionally its exact time derivatives.
struct PrescribedMotion {
  PrescribedDisplacement displacement;  ///< empty: fixed (zero)
  PrescribedDisplacement velocity;      ///< empty: one-sided differences of `displacement`
  PrescribedDisplacement acceleration;  ///< empty: differences of `velocity`, or of `displacement`
};

/// Names a constraint set (Solver::fix, prescribe, grasp) for release() and replace(), of the
/// solver that issued it only (core/handle_owner.hpp).
struct ConstraintHandle {
  std::uint32_t id = 0;     ///< 0: none
  std::uint32_t owner = 0;  ///< the issuing Constraints' HandleOwner number
  explicit operator bool() const { return id != 0; }
  friend bool operator==(ConstraintHandle, ConstraintHandle) = default;
};

/// Values of a path at time t: the entries at constrained dofs, others untouched.
struct PathValues {
  Vector u, v, a;
};

/// Refuses a node id outside [0, num_nodes): "`what`: node i out of range [0, n)".
inline void check_node_ids(std::span<const Index> nodes, Index num_nodes, const char* what) {
  for (Index i : nodes)
    if (i < 0 || i >= num_nodes) fail<InvalidArgument>("{}: node {} out of range [0, {})", what, i, num_nodes);
}

class Constraints {
 public:
  Constraints() = default;
  explicit Constraints(Index num_nodes) : num_nodes_(num_nodes) {}

  /// A set: nodes, motion, mask, and optionally one constant displacement per node added to the
  /// motion's (a grasp holds each node at its displacement when grasped, plus the grasper's path).
  /// `what` names the set in an error ("boundary condition", "grasp").
  ConstraintHandle add(std::span<const Index> nodes, PrescribedMotion motion, DofMask mask,
                       std::vector<Vec3> offsets = {}, const char* what = "boundary condition") {
    check_node_ids(nodes, num_nodes_, what);
    check_motion(motion);
    if (!offsets.empty() && offsets.size() != nodes.size())
      fail<InvalidArgument>("constraint: {} offsets for {} nodes", offsets.size(), nodes.size());
    for (const Vec3& o : offsets)
      if (!o.allFinite()) fail<InvalidArgument>("constraint: offsets must be finite");
    sets_.push_back({++next_id_, std::vector<Index>(nodes.begin(), nodes.end()), mask, std::move(motion),
                     std::move(offsets)});
    ++version_;
    return {next_id_, owner_.id()};
  }
  /// A grasp at time `now`: each node follows the path's translation from its displacement u
  /// now, u_i(t) = u_i(now) + path(t) - path(now) (all components).
  ConstraintHandle grasp(std::span<const Index> nodes, std::function<Vec3(Scalar)> path, Scalar now, const Vector& u) {
    check_node_ids(nodes, num_nodes_, "grasp");
    if (!path) fail<InvalidArgument>("grasp: the path is empty");
    const Vec3 p0 = path(now);
    if (!p0.allFinite()) fail<InvalidArgument>("grasp: path({}) is not finite", now);
    std::vector<Vec3> offsets;
    offsets.reserve(nodes.size());
    for (Index i : nodes) offsets.push_back(u.segment<3>(3 * i) - p0);
    return add(nodes, PrescribedMotion{[path](Scalar t, const Vec3&) { return path(t); }, {}, {}}, DofMask{},
               std::move(offsets), "grasp");
  }
  /// Removes a set; its dofs become free (or fall back to an earlier set on the same dofs).
  void remove(ConstraintHandle h) {
    sets_.erase(find(h));
    ++version_;
  }
  /// Gives a set a new motion (same nodes and components).
  void replace(ConstraintHandle h, PrescribedMotion motion) {
    check_motion(motion);
    find(h)->motion = std::move(motion);
    ++version_;
  }
  bool contains(ConstraintHandle h) const {
    return h.owner == owner_.id() && std::any_of(sets_.begin(), sets_.end(), [&](const Set& s) { return s.id == h.id; });
  }
  /// Changes whenever a set is added, removed or replaced.
  std::uint64_t version() const { return version_; }
  bool empty() const { return sets_.empty(); }
  Index num_nodes() const { return num_nodes_; }

  /// Per standard dof (3 x nodes): 1 if some set constrains it.
  std::vector<char> constrained_dofs() const {
    std::vector<char> c(3 * static_cast<size_t>(num_nodes_), 0);
    for (const Set& s : sets_)
      for (Index i : s.nodes)
        for (int d = 0; d < 3; ++d)
          if (s.mask[d]) c[3 * i + d] = 1;
    return c;
  }
  /// Whether any set has a non-zero path (a fixed-only scene skips path evaluation).
  bool any_motion() const {
    return std::any_of(sets_.begin(), sets_.end(),
                       [](const Set& s) { return bool(s.motion.displacement) || !s.offsets.empty(); });
  }

  /// Writes the prescribed displacement at time t into u, and (when v, a are given) the path's
  /// velocity and acceleration, at every constrained dof; other entries are untouched. `dt`
  /// (the step that ends at t) sets the difference step h = min(dt / 16, 1e-4).
  ///
  /// Derivatives a motion does not give are one-sided differences over [t - 3h, t], the left
  /// limits a step that ends at t needs. A path that jumps inside that window (t < 1 ? 0.5 t : 0
  /// at t = 1) would give a velocity of J / h and an acceleration of J / h^2 there; such a jump is
  /// found (one_sided) and the derivatives are taken after it instead, by differences over
  /// [t, t + 3h]: the node jumps with the step and goes on at the path's velocity after the jump
  /// (so a path that jumps must be defined a little beyond t). The same holds for a given
  /// velocity whose acceleration is differenced. Returns the number of constrained nodes (per
  /// constraint set holding them) whose path or velocity jumped so.
  ///
  /// `from_right`: the derivatives as the right limits, over [t, t + 3h], what a step that
  /// starts at t needs (its initial acceleration): a path need not be defined before the time
  /// the simulation starts at (a recorded table from t = 0 made the first step fail; found by
  /// review, 2026-12-01).
  template <class NodePosition>
  Index evaluate(Scalar t, Scalar dt, const NodePosition& X, Vector& u, Vector* v, Vector* a,
                 bool from_right = false) const {
    // h as the clock can hold it: t - k h and t + k h exact, so the differences see the path
    // over exactly k h (at t = 1e9 an ulp is 1.2e-7, and h = 6e-5 taken as written made the
    // acceleration of a constant-velocity path 0.9).
    const Scalar h = (t + std::min(dt / 16, Scalar(1e-4))) - t;
    if ((v || a) && !(h > 0) && any_motion())
      fail<InvalidArgument>("prescribed motion at t = {}: the path's derivatives need a difference step of {}, which "
                            "the round-off of t loses",
                            t, std::min(dt / 16, Scalar(1e-4)));
    Index jumps = 0;
    for (const Set& s : sets_) {
      for (size_t k = 0; k < s.nodes.size(); ++k) {
        const Index i = s.nodes[k];
        Vec3 g = Vec3::Zero(), gv = Vec3::Zero(), ga = Vec3::Zero();
        const auto& m = s.motion;
        if (m.displacement) {
          const Vec3 Xi = X(i);
          g = checked(m.displacement(t, Xi), "displacement", i, t);
          bool jumped = false;
          if (v || a) {
            auto at = [&](const PrescribedDisplacement& f, const char* what) {
              return [&f, &Xi, what, i](Scalar time) { return checked(f(time, Xi), what, i, time); };
            };
            if (m.velocity) {
              gv = checked(m.velocity(t, Xi), "velocity", i, t);
            } else {
              const OneSided d = one_sided(at(m.displacement, "displacement"), t, g, h, a && !m.acceleration, from_right);
              gv = d.first, ga = d.second, jumped = d.jumped;
            }
            if (m.acceleration) {
              ga = checked(m.acceleration(t, Xi), "acceleration", i, t);
            } else if (a && m.velocity) {
              const OneSided d = one_sided(at(m.velocity, "velocity"), t, gv, h, false, from_right);
              ga = d.first, jumped = d.jumped;
            }
          }
          jumps += jumped;
        }
        if (!s.offsets.empty()) g += s.offsets[k];
        for (int d = 0; d < 3; ++d) {
          if (!s.mask[d]) continue;
          u[3 * i + d] = g[d];
          if (v) (*v)[3 * i + d] = gv[d];
          if (a) (*a)[3 * i + d] = ga[d];
        }
      }
    }
    return jumps;
  }

 private:
  struct Set {
    std::uint32_t id;
    std::vector<Index> nodes;
    DofMask mask;
    PrescribedMotion motion;
    std::vector<Vec3> offsets;  ///< per node, added to the motion's displacement (empty: none)
  };
  std::vector<Set>::iterator find(ConstraintHandle h) {
    if (h.owner != owner_.id())
      fail<InvalidArgument>("constraint handle {} {}", h.id,
                            h.owner == 0 ? "was never issued (a default handle names no constraint set)"
                                         : "belongs to another solver: a handle names a set of the solver that issued it");
    auto it = std::find_if(sets_.begin(), sets_.end(), [&](const Set& s) { return s.id == h.id; });
    if (it == sets_.end())
      fail<InvalidArgument>("constraint handle {} names no current constraint set (released already?)", h.id);
    return it;
  }
  /// f's first (and, if `second`, second) derivative at t from one side, f0 = f(t): from the
  /// left by the second-order differences
  ///   f'  = (3 d1 - d2) / 2h,   f'' = (2 d1 - 3 d2 + d3) / h^2,   d_k = f(t-(k-1)h) - f(t-kh),
  /// written in differences of neighbouring values so that a constant path gives exactly 0;
  /// from the right by their mirror images (e_k = f(t+kh) - f(t+(k-1)h): f' = (3 e1 - e2) / 2h,
  /// f'' = -(2 e1 - 3 e2 + e3) / h^2) when f jumps inside [t - 3h, t].
  struct OneSided {
    Vec3 first = Vec3::Zero(), second = Vec3::Zero();
    bool jumped = false;
  };
  template <class F>
  static OneSided one_sided(const F& f, Scalar t, const Vec3& f0, Scalar h, bool second, bool from_right) {
    OneSided r;
    if (!from_right) {
      // f3 also when only f' is wanted: the jump test needs three differences.
      const std::array<Vec3, 4> v{f0, f(t - h), f(t - 2 * h), f(t - 3 * h)};
      const std::array<Vec3, 3> d{v[0] - v[1], v[1] - v[2], v[2] - v[3]};
      if (!jump_inside(f, t, h, v, d)) {
        r.first = (3 * d[0] - d[1]) / (2 * h);
        if (second) r.second = (2 * d[0] - 3 * d[1] + d[2]) / (h * h);
        return r;
      }
      r.jumped = true;
    }
    const Vec3 g1 = f(t + h), g2 = f(t + 2 * h), g3 = second ? f(t + 3 * h) : g2;
    const Vec3 e1 = g1 - f0, e2 = g2 - g1, e3 = g3 - g2;
    r.first = (3 * e1 - e2) / (2 * h);
    if (second) r.second = -(2 * e1 - 3 * e2 + e3) / (h * h);
    return r;
  }
  /// Whether f jumps inside [t - 3h, t], given its values v_k = f(t - kh) and their differences
  /// d_k = v_k - v_{k+1}.
  /// Over a continuous stretch the three differences change smoothly (by about h^2 |f''| from
  /// one to the next); a jump J makes one of them stand out from the line through the other two
  /// by about |J|. Such an outlier's interval is halved down to adjacent doubles, keeping the
  /// half that changes more: a continuous f's change shrinks with the interval, a jump's stays.
  /// (A kink passes the first test at times and is then found continuous.)
  template <class F>
  static bool jump_inside(const F& f, Scalar t, Scalar h, const std::array<Vec3, 4>& v, const std::array<Vec3, 3>& d) {
    const Scalar size = std::max({v[0].norm(), v[1].norm(), v[2].norm(), v[3].norm()});
    // Changes within a few thousand ulps of the values, or of f's change over an ulp of t, are
    // round-off, not jumps.
    const Scalar largest = std::max({d[0].norm(), d[1].norm(), d[2].norm()});
    const Scalar noise =
        4096 * std::numeric_limits<Scalar>::epsilon() * (size + largest * std::max(std::abs(t), h) / h);
    for (int k = 0; k < 3; ++k) {
      const Vec3 &dj = d[(k + 1) % 3], &dl = d[(k + 2) % 3];
      // d_k against the line through the other two: their mean for k = 1, extrapolated for the
      // ends (d_0 = 2 d_1 - d_2, d_2 = 2 d_1 - d_0).
      const Vec3 expected = k == 1 ? Vec3(0.5 * (d[0] + d[2])) : Vec3(2 * d[1] - d[k == 0 ? 2 : 0]);
      const Scalar outlier = (d[k] - expected).norm(), spread = (dj - dl).norm();
      if (!(outlier > 8 * spread + noise)) continue;
      Scalar lo = t - (k + 1) * h, hi = t - k * h;
      Vec3 f_lo = v[k + 1], f_hi = v[k];
      for (int halving = 0; halving < 64; ++halving) {
        const Scalar mid = lo + (hi - lo) / 2;
        if (mid <= lo || mid >= hi) break;
        const Vec3 f_mid = f(mid);
        if ((f_mid - f_lo).norm() >= (f_hi - f_mid).norm()) hi = mid, f_hi = f_mid;
        else lo = mid, f_lo = f_mid;
      }
      const Scalar change = (f_hi - f_lo).norm();
      return change > outlier / 2 && change > noise;
    }
    return false;
  }
  static void check_motion(const PrescribedMotion& m) {
    if ((m.velocity || m.acceleration) && !m.displacement)
      fail<InvalidArgument>("a prescribed motion with a velocity or acceleration needs its displacement too");
  }
  static Vec3 checked(const Vec3& x, const char* what, Index node, Scalar t) {
    if (!x.allFinite())
      fail<InvalidArgument>("prescribed {} at node {}, t = {} is not finite ({}, {}, {})", what, node, t, x.x(), x.y(),
                            x.z());
    return x;
  }

  Index num_nodes_ = 0;
  std::vector<Set> sets_;
  std::uint32_t next_id_ = 0;
  std::uint64_t version_ = 0;
  HandleOwner owner_;
};

}  // namespace plastifem
