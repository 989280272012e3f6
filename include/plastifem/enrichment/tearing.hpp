#pragma once
// Tearing: a crack that starts where the tissue's stress exceeds its strength and runs from
// element to element while the load continues, applied by the X-FEM machinery (Solver::cut and
// grow_cut) to the running simulation, elastic or plastic.
//
// Criterion: the maximum principal Cauchy stress at an element's centre, sigma_1 >= strength
// (Rankine's criterion). Soft tissues fail in tension at a measured ultimate tensile stress
// (e.g. liver capsule ~1 MPa, peritoneum ~1-4 MPa); the criterion needs nothing the elastic
// models do not have, works for every composition (plastic or not), and gives the direction the
// crack opens in: across n_1, the direction of sigma_1. (Accumulated plastic stretch, the seed's
// other suggestion, needs a plastic policy and says nothing about the direction.)
//
// Geometry: the crack is a ribbon, a polyline path p_0 ... p_k in the material swept along a
// fixed direction w through the body's whole extent along w (a sheet's normal: the default, w is
// the axis along which the mesh is thinnest). Each segment's plane contains w; its normal is the
// material normal of the torn element's principal plane, N ~ F^T n_1 (Nanson's formula: the
// material plane that deforms into the plane across n_1), projected off w.
//
// Growth, after each step (update()). The path runs from element face to element face: each
// point is where the crack line leaves an element (1e-3 of the element size before it: a ribbon
// ending on a face would count as crossing the element past it too).
//  - No crack yet: the uncut element A with the largest sigma_1 at its centre, if it reaches the
//    strength, starts one through its centre along d = N x w / |N x w|, across A and on through
//    the element beyond each of A's exits. An X-FEM crack opens only where every element around
//    a node that the level set crosses is crossed by the surface (docs/xfem.md: a node at the
//    tip stays shared), so a crack through A alone would open nothing: through three elements,
//    A opens and the path's ends are its tips.
//  - A tip looks at the element B just past it. The stress there is recovered at the middle of
//    the crack line's way through B, sum N_a(xi) sigma_a with sigma_a the volume-weighted mean of
//    the centre stresses of the uncut elements around node a: B's own centre lies off the line,
//    on one side of the tip's field, and its principal direction leans (25 degrees ahead of a
//    notch in a test). If that sigma_1 reaches the strength, the path gains the point where the
//    line along B's d leaves B: d from the principal direction of the stress averaged around the
//    tip (the centre stresses of the uncut elements near it, Gaussian-weighted by distance),
//    turned to go on forward. The opening
//    follows one element behind the path's tip, as above.
//  - One element per tip per update: the crack runs at most an element per step (the stresses
//    are those of the step just solved; the next solve redistributes them).
//  - A tip whose next element is outside the body has run through it and stops; so does one
//    whose next element another cut crosses already, or whose growth the solver refuses. The
//    elements past the path's end that the crack itself crosses already (a Tet4 cell's beside
//    it, or one whose nodes were snapped onto the crack line) are split by it: the tip is
//    carried through them, and B is the first element after them (or the path runs on to the
//    boundary through them).
//  - Ties for the start (a uniform field) go to the middle of the tied elements.
// The cut is rebuilt as a CutSurface of the whole path and applied with grow_cut: the grown
// ribbon contains the old one, so what was cut stays cut (docs/xfem.md, "Tearing"). The path
// is in the mesh's coordinates, where cuts are given, with a plastic policy too (a cut is a
// material surface: docs/xfem.md, "Cutting plastic tissue").
#include <plastifem/core/log.hpp>
#include <plastifem/core/symmetric_eigen.hpp>
#include <plastifem/enrichment/level_set.hpp>
#include <plastifem/mesh/selection.hpp>

#include <cmath>
#include <deque>
#include <optional>
#include <vector>

namespace plastifem {

struct TearingSettings {
  /// Tensile strength: an element tears when its maximum principal Cauchy stress reaches it.
  Scalar strength = 0;
  /// The direction the crack runs through the body along (a sheet's normal); zero: the axis of
  /// the mesh's bounding box along which it is thinnest.
  Vec3 sweep = Vec3::Zero();
  CutOptions cut;

  void validate() const {
    if (!(strength > 0) || !std::isfinite(strength))
      fail<InvalidArgument>("tearing: strength {} (> 0, finite: the stress at which tissue tears)", strength);
    if (!sweep.allFinite()) fail<InvalidArgument>("tearing: the sweep direction is not finite");
    cut.validate();
  }
};

/// What one update() did.
struct TearReport {
  bool started = false;          ///< a crack started this update
  int grown = 0;                 ///< segments added at the tips
  Index cut_elements = 0;        ///< elements newly cut
  Scalar largest_stress = 0;     ///< the largest sigma_1 looked at (the candidates' if a crack exists)
};

template <class S>
  requires S::EnrichmentPolicy::active
class Tearing {
  using E = typename S::Element;

 public:
  Tearing(S& solver, TearingSettings settings) : solver_(&solver), settings_(settings), locator_(solver.mesh()) {
    settings_.validate();
    const Eigen::Matrix3Xd& X = solver.mesh().nodes();
    if (settings_.sweep == Vec3::Zero()) {  // exactly: any other vector is a direction
      const Vec3 extent = X.rowwise().maxCoeff() - X.rowwise().minCoeff();
      Index thinnest;
      extent.minCoeff(&thinnest);
      settings_.sweep = Vec3::Unit(thinnest);
    }
    settings_.sweep.normalize();
    const Eigen::RowVectorXd along = settings_.sweep.transpose() * X;
    half_width_ = along.maxCoeff() - along.minCoeff();  // the ribbon reaches past the body both ways
    const Mesh<E>& mesh = solver.mesh();
    node_start_.assign(static_cast<size_t>(mesh.num_nodes()) + 1, 0);
    min_size_ = std::numeric_limits<Scalar>::max();
    for (Index e = 0; e < mesh.num_elements(); ++e) {
      for (Index n : mesh.element(e)) ++node_start_[static_cast<size_t>(n) + 1];
      volume_.push_back(element_volume<E>(mesh.element_nodes(e)));
      min_size_ = std::min(min_size_, std::cbrt(volume_.back()));
    }
    for (size_t n = 1; n < node_start_.size(); ++n) node_start_[n] += node_start_[n - 1];
    mean_volume_ = 0;
    centre_.resize(3, mesh.num_elements());
    for (Index e = 0; e < mesh.num_elements(); ++e)
      mean_volume_ += volume_[static_cast<size_t>(e)] / static_cast<Scalar>(mesh.num_elements()),
          centre_.col(e) = mesh.element_nodes(e).rowwise().mean();
    node_elements_.resize(static_cast<size_t>(node_start_.back()));
    std::vector<Index> fill(node_start_.begin(), node_start_.end() - 1);
    for (Index e = 0; e < mesh.num_elements(); ++e)
      for (Index n : mesh.element(e)) node_elements_[static_cast<size_t>(fill[static_cast<size_t>(n)]++)] = e;
  }

  /// Starts from a given crack (a notch): the path's points in the rest configuration, at least
  /// two; each end is a tip unless it lies outside the body (an end inside an element is moved
  /// on to where the line leaves the element).
  void start(std::vector<Vec3> path) {
    if (cut_) fail<InvalidArgument>("tearing: the crack has started already");
    if (path.size() < 2) fail<InvalidArgument>("tearing: a crack path needs at least 2 points, got {}", path.size());
    for (const Vec3& p : path)
      if (!p.allFinite()) fail<InvalidArgument>("tearing: a crack path point is not finite");
    // A repeated point (closer than the inset to the one before) is one: a segment of no length
    // has no direction, and a tip along it never grew.
    std::deque<Vec3> points;
    for (const Vec3& p : path)
      if (points.empty() || (p - points.back()).norm() > inset()) points.push_back(p);
    if (points.size() < 2)
      fail<InvalidArgument>("tearing: a crack path needs at least 2 distinct points, got {} (all within {} of each "
                            "other)",
                            path.size(), inset());
    // An end inside an element is carried on to where the line leaves it: the path runs from
    // element face to element face (the file comment).
    for (const bool front : {false, true}) {
      Vec3& end = front ? points.front() : points.back();
      const Vec3 d = (end - (front ? points[1] : points[points.size() - 2])).normalized();
      const auto e = element_past(end, d);
      if (e && exit(*e, end, Vec3(-d)) > inset()) end += (exit(*e, end, d) - inset()) * d;
      else end -= inset() * d;  // on a face: just inside the element it ends in
    }
    std::vector<Tip> tips;
    if (auto t = tip_at(points.back(), points.back() - points[points.size() - 2])) tips.push_back(*t);
    if (auto t = tip_at(points.front(), points.front() - points[1])) tips.push_back(*t), tips.back().front = true;
    cut_ = solver_->cut(ribbon(points), settings_.cut);
    path_ = std::move(points);
    tips_ = std::move(tips);
  }

  /// After a step (or a static solve): starts or grows the crack where sigma_1 >= strength.
  /// Throws InvalidArgument, with the solver unchanged, if the solver refuses a new crack.
  TearReport update() {
    TearReport report;
    if (!cut_) {
      const Index ne = solver_->mesh().num_elements();
      std::vector<Scalar> sigma_1(static_cast<size_t>(ne), -std::numeric_limits<Scalar>::max());
      Scalar largest = -std::numeric_limits<Scalar>::max();
      for (Index e = 0; e < ne; ++e) {
        if (is_cut(e)) continue;  // another cut's
        sigma_1[static_cast<size_t>(e)] = principal(solver_->stress(e)).first;
        largest = std::max(largest, sigma_1[static_cast<size_t>(e)]);
      }
      report.largest_stress = largest;
      if (!(largest >= settings_.strength)) return report;
      // Ties (a uniform field: equal to 1e-6 of the largest, past the solvers' tolerances) start at the middle of the tied
      // elements, the one nearest their centroid, not wherever round-off puts the largest.
      Vec3 middle = Vec3::Zero();
      Index tied = 0;
      for (Index e = 0; e < ne; ++e)
        if (sigma_1[static_cast<size_t>(e)] >= largest - 1e-6 * std::abs(largest)) middle += centre_.col(e), ++tied;
      middle /= static_cast<Scalar>(tied);
      Index worst = -1;
      for (Index e = 0; e < ne; ++e)
        if (sigma_1[static_cast<size_t>(e)] >= largest - 1e-6 * std::abs(largest) &&
            (worst < 0 || (centre_.col(e) - middle).squaredNorm() < (centre_.col(worst) - middle).squaredNorm()))
          worst = e;
      const Vec3 c = centre(worst), xi = reference_centre<E>();
      const Vec3 d = direction(worst, xi, principal(solver_->stress(worst)).second, Vec3::Zero());
      std::deque<Vec3> points{c - (exit(worst, c, -d) - inset()) * d, c + (exit(worst, c, d) - inset()) * d};
      // On through the element beyond each exit (see the file comment).
      std::vector<Tip> tips;
      for (const bool front : {false, true}) {
        const Vec3 towards = front ? Vec3(-d) : d;
        Vec3& end = front ? points.front() : points.back();
        if (const auto next = element_past(end, towards)) {
          const Vec3 entry = end + 2 * inset() * towards;
          end = entry + (exit(*next, entry, towards) - inset()) * towards;
          if (element_past(end, towards)) tips.push_back(Tip{end, towards, front});
        }
      }
      const CutHandle h = solver_->cut(ribbon(points), settings_.cut);
      report.cut_elements = solver_->last_cut_report().cut_elements;
      cut_ = h, path_ = std::move(points), report.started = true;
      tips_ = std::move(tips);
      return report;
    }
    std::vector<Tip> next;
    std::deque<Vec3> path = path_;
    for (const Tip& t : tips_) {
      // Through the body or into another cut: done. The elements past the path's end that the
      // crack itself crosses already (its ribbon, swept along w, crosses the elements of a Tet4
      // cell beside the end; nodes snapped onto the crack line make the element past it a cut
      // one) are split by the crack: the tip is carried through them along its direction, to
      // the first element it does not cross, which is torn or not by the criterion. (Stopping at
      // them stopped a Tet4 crack at once, and a Hex8 one run within the snap distance of a node
      // row; found by review, 2026-11-30.)
      Tip tip = t;
      std::vector<Vec3> carried;
      std::optional<Index> b = element_past(tip.point, tip.direction);
      for (int k = 0; b && is_cut(*b) && k < 16; ++k) {
        const Vec3 in = tip.point + 2 * inset() * tip.direction;
        tip.point = in + (exit(*b, in, tip.direction) - inset()) * tip.direction;
        carried.push_back(tip.point);
        b = element_past(tip.point, tip.direction);
      }
      if (!b || is_cut(*b)) {
        if (!b && !carried.empty()) {  // out of the body through them: the path runs on to its boundary
          for (const Vec3& p : carried) t.front ? path.push_front(p) : path.push_back(p);
          ++report.grown;
        }
        continue;
      }
      const ElementNodes<E> Xb = solver_->mesh().element_nodes(*b);
      const Vec3 entry = tip.point + 2 * inset() * tip.direction;  // in B
      const Vec3 q = entry + 0.5 * exit(*b, entry, tip.direction) * tip.direction;
      const Vec3 xi = locate_in_element<E>(Xb, q, 1e-6).value_or(reference_centre<E>());
      const Scalar s = principal(recovered_stress(*b, xi)).first;
      report.largest_stress = std::max(report.largest_stress, s);
      if (!(s >= settings_.strength)) {  // NaN: undefined there, no growth
        next.push_back(t);
        continue;
      }
      Vec3 d = direction(*b, xi, principal(averaged_stress(tip.point)).second, tip.direction);
      Scalar length = exit(*b, entry, d);
      if (length < 0.05 * extent(*b, d)) d = tip.direction, length = exit(*b, entry, d);  // d leaves B at once
      carried.push_back(entry + (length - inset()) * d);
      for (const Vec3& p : carried) t.front ? path.push_front(p) : path.push_back(p);
      next.push_back(Tip{carried.back(), d, t.front});
      ++report.grown;
    }
    if (report.grown > 0) {
      try {
        solver_->grow_cut(*cut_, ribbon(path), settings_.cut);
      } catch (const InvalidArgument& refused) {
        note(fmt::format("tearing: the crack stops ({})", refused.what()));
        tips_.clear();
        report.grown = 0;
        return report;
      }
      report.cut_elements = solver_->last_cut_report().cut_elements;
      path_ = std::move(path);
    }
    tips_ = std::move(next);
    return report;
  }

  bool started() const { return cut_.has_value(); }
  /// The crack's cut (for Solver::enrichment and output), once started.
  std::optional<CutHandle> cut() const { return cut_; }
  /// The crack path in the rest configuration, from its front to its back.
  const std::deque<Vec3>& path() const { return path_; }
  /// Tips still growing.
  Index num_tips() const { return static_cast<Index>(tips_.size()); }
  const Vec3& sweep() const { return settings_.sweep; }

  /// The largest principal value of a Cauchy stress and its direction (deformed).
  static std::pair<Scalar, Vec3> principal(const Mat3& sigma) {
    Vec3 values;
    Mat3 vectors;
    symmetric_eigen<3>(sigma, values, vectors);
    Index k;
    values.maxCoeff(&k);
    return {values[k], vectors.col(k)};
  }

 private:
  struct Tip {
    Vec3 point, direction;  ///< in the rest configuration; the direction the crack runs in
    bool front;             ///< at the path's front (else its back)
  };

  /// A tip at the path's end p running along `towards`, if the body goes on past p.
  std::optional<Tip> tip_at(const Vec3& p, const Vec3& towards) const {
    const Vec3 d = towards.normalized();
    if (!element_past(p, d)) return std::nullopt;
    return Tip{p, d, false};
  }

  /// Whether a cut crosses element e (any cut; the crack's own included).
  bool is_cut(Index e) const { return solver_->enrichment().element(e) != nullptr; }
  /// Whether a cut other than the crack crosses element e (the crack's ribbon ends on an
  /// element's face: the element past it may count as crossed by it).
  bool crossed_by_another(Index e) const {
    const auto* c = solver_->enrichment().element(e);
    return c && (!cut_ || c->cut != cut_->id);
  }
  Vec3 centre(Index e) const { return solver_->mesh().element_nodes(e).rowwise().mean(); }
  Scalar extent(Index e, const Vec3& d) const {
    const Eigen::RowVectorXd s = d.transpose() * solver_->mesh().element_nodes(e);
    return s.maxCoeff() - s.minCoeff();
  }
  /// How far inside its last element the path ends: a ribbon ending on an element's face would
  /// count as crossing the element past it too.
  Scalar inset() const { return 1e-3 * min_size_; }
  /// The element just past p along d (two insets on), if there is one and no other cut crosses it.
  std::optional<Index> element_past(const Vec3& p, const Vec3& d) const {
    const std::optional<PointLocation> at = locator_.locate(p + 2 * inset() * d);
    if (!at || crossed_by_another(at->element)) return std::nullopt;
    return at->element;
  }
  /// How far from p (in or on element e) the line p + s d stays in e: bisection on s.
  Scalar exit(Index e, const Vec3& p, const Vec3& d) const {
    const ElementNodes<E> X = solver_->mesh().element_nodes(e);
    Scalar in = 0, out = 2 * (X.rowwise().maxCoeff() - X.rowwise().minCoeff()).norm();
    for (int k = 0; k < 50; ++k) {
      const Scalar mid = (in + out) / 2;
      (locate_in_element<E>(X, p + mid * d, 1e-12) ? in : out) = mid;
    }
    return in;
  }

  /// Cauchy stress at xi in element e, from nodal values: each node's the volume-weighted mean
  /// of the centre stresses of the uncut elements around it.
  Mat3 recovered_stress(Index e, const Vec3& xi) const {
    const auto N = E::shape(xi);
    Mat3 sigma = Mat3::Zero();
    for (int a = 0; a < E::num_nodes; ++a) {
      const Index node = solver_->mesh().element(e)[static_cast<size_t>(a)];
      Mat3 mean = Mat3::Zero();
      Scalar volume = 0;
      for (Index k = node_start_[static_cast<size_t>(node)]; k < node_start_[static_cast<size_t>(node) + 1]; ++k) {
        const Index around = node_elements_[static_cast<size_t>(k)];
        if (is_cut(around)) continue;
        mean += volume_[static_cast<size_t>(around)] * solver_->stress(around);
        volume += volume_[static_cast<size_t>(around)];
      }
      sigma += N[a] * (volume > 0 ? Mat3(mean / volume) : solver_->stress(e));
    }
    return sigma;
  }

  /// The stress around a crack tip at p, for the direction it runs in: the mean of the uncut
  /// elements' centre stresses with Gaussian weights exp(-r^2 / (2 l^2)) (r the distance of the
  /// element's centre from p, l the element size) times their volumes, over r < 3 l. Element by
  /// element, the stress next to a tip leans with the tip's position in its element; averaged
  /// over a disc around the tip (the non-local direction of Wells and Sluys, 2001) it does not.
  Mat3 averaged_stress(const Vec3& p) const {
    const Scalar l = std::cbrt(mean_volume_);
    Mat3 sum = Mat3::Zero();
    Scalar weights = 0;
    for (Index e = 0; e < solver_->mesh().num_elements(); ++e) {
      const Scalar r2 = (centre_.col(e) - p).squaredNorm();
      if (r2 > 9 * l * l || is_cut(e)) continue;
      const Scalar w = std::exp(-r2 / (2 * l * l)) * volume_[static_cast<size_t>(e)];
      sum += w * solver_->stress(e), weights += w;
    }
    return weights > 0 ? Mat3(sum / weights) : Mat3::Zero();
  }

  /// The direction the crack runs in through element e at xi, where sigma_1's direction is n:
  /// in the plane spanned by w and d, normal to N ~ F^T n projected off w; turned along
  /// `forward` (if not zero).
  Vec3 direction(Index e, const Vec3& xi, const Vec3& n, const Vec3& forward) const {
    const ElementNodes<E> X = solver_->mesh().element_nodes(e);
    const Eigen::Matrix3Xd u = solver_->nodal_displacements();
    Mat3 F = Mat3::Identity();
    const auto dN = physical_gradient<E>(X, xi);
    for (int a = 0; a < E::num_nodes; ++a) F += u.col(solver_->mesh().element(e)[static_cast<size_t>(a)]) * dN.row(a);
    const Vec3& w = settings_.sweep;
    Vec3 normal = F.transpose() * n;
    normal -= normal.dot(w) * w;
    if (!(normal.norm() > 0)) normal = w.unitOrthogonal();  // sigma_1 along w: any plane containing w
    Vec3 d = normal.cross(w).normalized();
    if (d.dot(forward) < 0) d = -d;
    return d;
  }

  /// The ribbon swept along w through the path (in the mesh's coordinates, as every cut: the
  /// path was never moved by plastic flow, and the cut is not either).
  CutSurface ribbon(const std::deque<Vec3>& path) const {
    std::vector<Vec3> v;
    std::vector<std::array<Index, 3>> t;
    for (const Vec3& p : path) {
      v.push_back(p - half_width_ * settings_.sweep), v.push_back(p + half_width_ * settings_.sweep);
    }
    for (Index i = 0; i + 1 < static_cast<Index>(path.size()); ++i) {
      const Index a = 2 * i, b = a + 1, c = a + 2, d = a + 3;
      t.push_back({a, c, d}), t.push_back({a, d, b});
    }
    return CutSurface(std::move(v), std::move(t));
  }

  S* solver_;
  TearingSettings settings_;
  PointLocator<E> locator_;
  Scalar half_width_ = 0;
  std::optional<CutHandle> cut_;
  std::deque<Vec3> path_;
  std::vector<Tip> tips_;
  std::vector<Index> node_start_, node_elements_;  ///< the elements around each node (CSR)
  std::vector<Scalar> volume_;                     ///< per element, at rest
  Scalar min_size_ = 0;                            ///< the smallest element's cube root of volume
  Scalar mean_volume_ = 0;
  Eigen::Matrix3Xd centre_;                        ///< element centres at rest
};

}  // namespace plastifem
