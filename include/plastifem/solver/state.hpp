#pragma once
// State: everything a step changes, so that a step is a transaction. A step works on a trial
// copy and commits it by a swap; any failure anywhere in a step (Newton, CG, a NaN, an inverted
// element, an exception from a load callback or a policy) leaves the committed State bit for
// bit as it was.
//
//   u, v, a    displacement, velocity, acceleration, one entry per dof of the dof map (they
//              grow with zeros when the dof map grows: exact for enriched dofs, whose added
//              functions are zero at the instant of the cut);
//   t          time;
//   balance    what a balances: the versions of the loads and constraints and the inertia
//              settings it was solved with. A step uses a as a_n only while they are the
//              solver's current ones, else solves it from equilibrium: a change of the loads,
//              the constraints, the mass or the damping needs no one to remember to forget a;
//   load       the external force the state is balanced with, statically or with M a + D v
//              (statics continue from it, or from f_int(u) for a state in motion);
//   force_scale the largest term of that balance over the free dofs, as the step that made the
//              state evaluated it (-1: not known); the next accurate step's Newton measures its
//              residual against at least this (solver/dynamics.hpp);
//   warm_start the first Newton increment of the last step and its dt (the next step's CG
//              start), and in real-time mode the one before (linear extrapolation of the two,
//              when both steps had the current dt: 7-13% fewer CG iterations);
//   plastic    the plastic policy's per-element table (empty for NoPlasticity; plastic/table.hpp);
//   serial     an identity: a quantity derived from this state (the real-time step's
//              linearisation) names the state by it, beside what else it was made of (the
//              tangent's stamp, the rest shapes' epoch: solver/dynamics.hpp);
//   lineage    the number of the solver whose state it is (its HandleOwner number, which moves
//              with the solver): restore() refuses another solver's state of the same sizes,
//              whose enriched dofs and plastic rest shapes belong to another body.
#include <plastifem/assembly/block_matrix.hpp>
#include <plastifem/assembly/mass.hpp>
#include <plastifem/plastic/none.hpp>

#include <cstdint>
#include <optional>
#include <utility>

namespace plastifem {

/// What an acceleration balances, M a + D v + f_int(u) = f_ext(t): the loads and constraint sets
/// (their versions) and the inertia settings (mass kind, Rayleigh coefficients) it was solved with.
struct Balance {
  std::uint64_t loads = 0, constraints = 0;
  MassKind mass = MassKind::Consistent;
  Scalar rayleigh_mass = 0, rayleigh_stiffness = 0;
  bool operator==(const Balance&) const = default;
};

/// The motion part of a State: everything a Newmark step or a static solve changes. Dynamics
/// and Statics work on it alone, so that they are compiled once per (element, model) whatever
/// the plastic policy.
struct MotionState {
  Vector u, v, a;
  Scalar t = 0;
  std::optional<Balance> balance;  ///< what a balances (none, or not the solver's now: solved from equilibrium)
  Vector load;
  Scalar force_scale = -1;
  Vector warm_start, warm_start_previous;
  Scalar warm_dt = 0, warm_dt_previous = 0;
  std::uint64_t serial = 0;
  std::uint32_t lineage = 0;

  Index num_dofs() const { return static_cast<Index>(u.size()); }

  /// n dofs, all zero (a body at rest).
  void reset(Index n) {
    u = v = a = load = Vector::Zero(n);
    warm_start.resize(0), warm_start_previous.resize(0);
    warm_dt = warm_dt_previous = 0;
    t = 0;
    force_scale = -1;
    balance.reset();
  }
  /// Grows to n dofs with zeros in the new entries (the dof map grew).
  void grow(Index n) {
    auto extend = [n](Vector& x) {
      const Index old = static_cast<Index>(x.size());
      if (old >= n) return;
      x.conservativeResize(n);
      x.tail(n - old).setZero();
    };
    extend(u), extend(v), extend(a), extend(load);
    if (warm_start.size() > 0) extend(warm_start);
    if (warm_start_previous.size() > 0) extend(warm_start_previous);
  }
  /// Assignment that reuses this state's storage (no allocation when the sizes match).
  void assign_motion(const MotionState& o) {
    u = o.u, v = o.v, a = o.a, t = o.t, balance = o.balance;
    load = o.load, force_scale = o.force_scale, warm_start = o.warm_start, warm_start_previous = o.warm_start_previous;
    warm_dt = o.warm_dt, warm_dt_previous = o.warm_dt_previous, serial = o.serial;
    lineage = o.lineage;
  }
  void swap_motion(MotionState& o) noexcept {
    u.swap(o.u), v.swap(o.v), a.swap(o.a), load.swap(o.load), warm_start.swap(o.warm_start);
    warm_start_previous.swap(o.warm_start_previous);
    std::swap(warm_dt, o.warm_dt), std::swap(warm_dt_previous, o.warm_dt_previous);
    std::swap(t, o.t), std::swap(balance, o.balance), std::swap(serial, o.serial);
    std::swap(force_scale, o.force_scale);
    std::swap(lineage, o.lineage);
  }
  /// Every field equal, bit for bit (NaN payloads aside).
  bool same_motion(const MotionState& y) const {
    auto same = [](const Vector& p, const Vector& q) {
      return p.size() == q.size() && std::equal(p.data(), p.data() + p.size(), q.data());
    };
    return same(u, y.u) && same(v, y.v) && same(a, y.a) && t == y.t && balance == y.balance &&
           same(load, y.load) && force_scale == y.force_scale && same(warm_start, y.warm_start) && same(warm_start_previous, y.warm_start_previous) &&
           warm_dt == y.warm_dt && warm_dt_previous == y.warm_dt_previous && serial == y.serial &&
           lineage == y.lineage;
  }
};

template <class PlasticState = NoPlasticState>
struct State : MotionState {
  [[no_unique_address]] PlasticState plastic;

  void assign(const State& o) {
    assign_motion(o);
    plastic = o.plastic;
  }
  void swap(State& o) noexcept {
    swap_motion(o);
    using std::swap;
    swap(plastic, o.plastic);
  }
  /// Every field equal, bit for bit (NaN payloads aside): what the rollback tests compare.
  friend bool operator==(const State& x, const State& y) { return x.same_motion(y) && x.plastic == y.plastic; }
};

}  // namespace plastifem
