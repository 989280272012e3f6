#pragma once
// Plasticity<E, Elastic, PerVertexRotation>: the plastic update of a whole body after a
// converged (sub-)step, and the link between the plastic table (in the State) and the elastic
// models' per-element data (in the Discretization).
//
// update(): from the committed displacement u and the table, every element's flow
// (plastic/flow.hpp) in parallel, then the fusion of the changed elements' proposals into the
// material mesh (plastic/fusion.hpp), then a check of the fused rest shapes. An element whose
// proposal or fused shape would degenerate has its plasticity switched off and the fusion is
// redone without it (up to three rounds; after that the whole update is dropped and counted).
// The table changes only at the very end, and only if something changed: a step with no flow
// leaves it bit for bit as it was. Nothing here is evaluated inside a force or residual: the
// flow runs once per converged (sub-)step, so it does not depend on how many Newton iterations
// the step took.
//
// sync(): re-prepares the element data of the elements whose rest nodes differ from the table's
// (copy-on-write per element, assembly/shared_by_shape.hpp; the elements in parallel), and hands
// the body the rest displacement x - X (for constant-tangent models, f = K (u - (x - X))). A
// failed or cut step can leave the data at a sub-step's table; the solver syncs back to the
// committed one.
#include <plastifem/assembly/discretization.hpp>
#include <plastifem/assembly/shared_by_shape.hpp>
#include <plastifem/core/parallel.hpp>
#include <plastifem/core/polar.hpp>
#include <plastifem/plastic/flow.hpp>
#include <plastifem/plastic/fusion.hpp>
#include <plastifem/plastic/params.hpp>
#include <plastifem/plastic/table.hpp>

#include <algorithm>
#include <optional>
#include <vector>

namespace plastifem::plastic {

template <FiniteElement E, class Elastic, bool PerVertexRotation>
class Plasticity {
 public:
  using Flow = ElementFlow<E, Elastic, PerVertexRotation>;
  static constexpr int N = E::num_nodes;
  static constexpr int P = Flow::P;    ///< flow points per element
  static constexpr int NR = Flow::NR;  ///< rotation entries per element

  /// Sizes the table for `body` (rest = the mesh, thresholds from `prm`) and this update's
  /// work space; factorises nothing yet.
  template <bool Enriched>
  void init(const Discretization<E, Elastic, Enriched>& body, const PlasticParams& prm, PlasticTable& table) {
    const Mesh<E>& mesh = body.mesh();
    const Index ne = mesh.num_elements();
    table.rest = Eigen::Map<const Vector>(mesh.nodes().data(), 3 * mesh.num_nodes());
    table.tau.assign(static_cast<size_t>(ne) * P, prm.yield_stress);
    table.alpha.assign(prm.kinematic_hardening > 0 ? static_cast<size_t>(ne) * P * 6 : 0, 0.0);
    // Rotation thresholds and maps only where plastic rotation is on (their copies cost a step
    // time otherwise).
    table.tau_R.assign(prm.rotation_active() ? static_cast<size_t>(ne) * NR : 0, prm.rotation_yield);
    table.rotation.assign(prm.rotation_active() ? static_cast<size_t>(ne) * NR * 3 : 0, 0.0);
    table.volume.assign(ne, 1.0);
    table.off.assign(ne, 0);
    table.version = 0;
    table.tau_origin = prm.yield_stress, table.tau_R_origin = prm.rotation_yield;
    V0_.resize(ne), h_.resize(ne), q0_.resize(ne);
    for (Index e = 0; e < ne; ++e) {
      const ElementNodes<E> X = mesh.element_nodes(e);
      V0_[e] = rest_volume<E>(X);
      q0_[e] = check_shape<E>(X).min_scaled_jacobian;
      Scalar h = std::numeric_limits<Scalar>::max();
      for (const auto& ed : E::edges) h = std::min(h, (X.col(ed[0]) - X.col(ed[1])).norm());
      h_[e] = h;
    }
    // Flow gradients, shared by translated copies (every cell of a structured grid) until a
    // rest shape changes, as the element data are.
    grads_ = SharedByShape<E, typename Flow::Gradients>(
        mesh, [&](const ElementNodes<E>& X) { return typename Flow::Gradients(points_, X); });
    z_.assign(ne, ElementNodes<E>::Zero());
    result_.assign(ne, FlowResult::Unchanged);
    changed_.assign(ne, 0);
    degenerate_.assign(ne, 0);
    element_moved_.assign(ne, 0);
    reports_.assign(ne, PlasticReport{});
    out_ = table;
    rest_new_ = table.rest;
    fusion_off_.clear();
    law_.emplace(body.material());
    synced_rest_ = table.rest;
    synced_version_ = 0;
  }

  /// Refuses (InvalidArgument) a table this engine did not make for this mesh: entries per
  /// element of another policy (VertexBlended and CellCentered share the table's type), values
  /// that are not finite, or thresholds that are negative or NaN (+inf is a threshold: the
  /// yield value that switches a flow off, PlasticParams). Solver::restore asks before it
  /// installs a state's table.
  void check_table(const PlasticTable& t) const {
    const size_t ne = V0_.size(), np = ne * P, nr = ne * NR;
    if (t.tau.size() != np || !(t.tau_R.empty() || t.tau_R.size() == nr) || t.rotation.size() != 3 * t.tau_R.size() ||
        !(t.alpha.empty() || t.alpha.size() == 6 * np) || t.volume.size() != ne)
      fail<InvalidArgument>("restore: the state's plastic table is not this policy's: {} thresholds, {} rotation "
                            "thresholds, {} volumes for {} elements with {} flow points and {} rotation entries each "
                            "(a state of another plastic policy?)",
                            t.tau.size(), t.tau_R.size(), t.volume.size(), ne, P, NR);
    auto finite = [](const auto& v) { return std::all_of(v.begin(), v.end(), [](Scalar x) { return std::isfinite(x); }); };
    auto thresholds = [](const auto& v) { return std::all_of(v.begin(), v.end(), [](Scalar x) { return x >= 0; }); };
    if (!t.rest.allFinite() || !thresholds(t.tau) || !finite(t.alpha) || !thresholds(t.tau_R) || !finite(t.rotation) ||
        !finite(t.volume))
      fail<InvalidArgument>("restore: the state's plastic table has values that are not finite (or negative thresholds)");
  }

  /// The assembler's pattern changed (the dof map grew, a cut froze elements): the fusion is
  /// rebuilt when next needed.
  void pattern_changed() { fusion_off_.clear(); }

  /// New parameters mid-run: thresholds keep their hardening, shifted by the change of the
  /// initial yield values; kinematic centres start at zero when kinematic hardening is switched
  /// on. An infinite yield value switches that flow off and leaves its thresholds as they are,
  /// so that switching it on again, to the value it had, changes nothing (they were all set to
  /// the new value: the hardening was lost); a table that never had a finite one starts at the
  /// new value.
  void change_params(const PlasticParams&, const PlasticParams& prm, PlasticTable& table) const {
    auto shift = [](std::vector<Scalar>& v, Scalar& origin, Scalar to) {
      if (!std::isfinite(to)) return;
      if (!std::isfinite(origin)) std::fill(v.begin(), v.end(), to);
      else if (origin != to)
        for (Scalar& t : v) t = std::max(Scalar(0), t + (to - origin));
      origin = to;
    };
    shift(table.tau, table.tau_origin, prm.yield_stress);
    shift(table.tau_R, table.tau_R_origin, prm.rotation_yield);
    if (prm.kinematic_hardening > 0 && table.alpha.empty()) table.alpha.assign(table.tau.size() * 6, 0.0);
    if (prm.rotation_active() && table.tau_R.empty()) {
      const size_t ne = table.off.size();
      table.tau_R.assign(ne * NR, prm.rotation_yield);
      table.rotation.assign(ne * NR * 3, 0.0);
    }
    if (prm.kinematic_hardening == 0) table.alpha.clear();
  }

  /// The plastic update after a converged step of dt that ended at displacement u (see the file
  /// comment). The body's element data must be at `table`'s rest shapes. On change, `table`
  /// gets the new rest shapes and thresholds and the version `version`.
  /// `anchor` (per node, may be empty): the nodes the material mesh stays put at (fusion.hpp).
  template <bool Enriched>
  PlasticReport update(const Discretization<E, Elastic, Enriched>& body, const Vector& u, Scalar dt, const PlasticParams& prm, PlasticTable& table,
                       std::uint64_t version, int threads, const std::vector<char>& anchor = {}) {
    PlasticReport rep;
    const Mesh<E>& mesh = body.mesh();
    const Index ne = mesh.num_elements();
    if (out_.alpha.size() != table.alpha.size()) out_.alpha.resize(table.alpha.size());
    if (out_.tau_R.size() != table.tau_R.size()) out_.tau_R.resize(table.tau_R.size());
    if (out_.rotation.size() != table.rotation.size()) out_.rotation.resize(table.rotation.size());
    const Vector& rest = table.rest;
    const Mat3 frame = prm.rotation_active() && prm.rotation_frame == PlasticParams::RotationFrame::Tissue
                           ? tissue_frame(mesh, u, rest, anchor)
                           : Mat3::Identity();
    body.assembler().for_each_element(
        [&](Index e) {
          result_[e] = FlowResult::Unchanged;
          reports_[e] = PlasticReport{};
          if (table.off[e]) return;
          const auto& c = mesh.element(e);
          ElementNodes<E> X, x;
          for (int a = 0; a < N; ++a) x.col(a) = mesh.node(c[a]) + u.template segment<3>(3 * c[a]);
          const auto en = entries(table, e);
          if (!Flow::may_flow(grads_[e], *law_, body.material(), prm, x, table.volume[e], en)) return;
          for (int a = 0; a < N; ++a) X.col(a) = rest.template segment<3>(3 * c[a]);
          result_[e] = Flow::run(points_, grads_[e], *law_, body.material(), prm, dt, frame, X, x, V0_[e],
                                 table.volume[e], q0_[e], en, entries(out_, e), z_[e], reports_[e]);
        },
        threads);
    bool any = false;
    for (Index e = 0; e < ne; ++e) {
      rep.add(reports_[e]);
      changed_[e] = result_[e] == FlowResult::Changed;
      any = any || result_[e] != FlowResult::Unchanged;
    }
    if (!any) {
      rep.elements_off = count_off(table);
      return rep;
    }

    std::vector<char>& off = off_new_;
    off.assign(table.off.begin(), table.off.end());
    for (Index e = 0; e < ne; ++e)
      if (result_[e] == FlowResult::Refused) off[e] = PlasticTable::switched_off, ++rep.switched_off;
    // Fuse, check, and redo without the elements the fusion would degenerate.
    bool accepted = false;
    for (int round = 0; round < 3 && !accepted; ++round) {
      fit_fusion(mesh, off);
      rest_new_ = rest;
      bool changes = false;
      for (Index e = 0; e < ne; ++e) changes = changes || changed_[e];
      if (changes) fusion_.fuse(mesh, z_, changed_, rest_new_, anchor);
      // Each moved element's fused shape checked on the threads (nearly every element, right
      // after a release), the verdicts applied in element order: the same result for any
      // number of threads.
      parallel_for(ne, threads, [&](Index e) {
        degenerate_[e] = 0;
        if (!moved(mesh, e, rest, rest_new_, 1e-4 * h_[e])) return;
        const ElementNodes<E> X_new = element_of(mesh, e, rest_new_);
        degenerate_[e] = !(shape_quality_at_least<E>(X_new, prm.min_rest_quality * q0_[e]) ||
                           check_shape<E>(X_new).min_scaled_jacobian >=
                               check_shape<E>(element_of(mesh, e, rest)).min_scaled_jacobian);
      });
      accepted = true;
      for (Index e = 0; e < ne; ++e) {
        if (!degenerate_[e]) continue;
        accepted = false;
        if (!off[e]) off[e] = PlasticTable::switched_off, ++rep.switched_off;
        changed_[e] = 0;
      }
    }
    if (!accepted) {
      // The rest shapes stay, but the elements found degenerating stay switched off: the next
      // update runs without them. (Dropping the switch-offs with the update made the same
      // update fail again every step, the body silently elastic from then on.)
      ++rep.updates_rejected;
      table.off.assign(off.begin(), off.end());
      rep.elements_off = count_off(table);
      return rep;
    }

    // Commit into the table.
    for (Index e = 0; e < ne; ++e) {
      if (!changed_[e]) continue;
      copy_entries(out_, table, e);
    }
    parallel_for(ne, threads, [&](Index e) {
      element_moved_[e] = moved(mesh, e, rest, rest_new_, 0);
      if (element_moved_[e]) table.volume[e] = rest_volume<E>(element_of(mesh, e, rest_new_)) / V0_[e];
    });
    rep.elements_changed = static_cast<int>(std::count(element_moved_.begin(), element_moved_.end(), 1));
    table.rest.swap(rest_new_);
    table.off.assign(off.begin(), off.end());
    table.version = version;
    rep.elements_off = count_off(table);
    return rep;
  }

  /// Brings the body's element data to the table's rest shapes (see the file comment), the
  /// elements prepared on `threads` threads (every flowing element, in every step: a third of
  /// the plastic work). Returns whether anything changed.
  template <bool Enriched>
  bool sync(Discretization<E, Elastic, Enriched>& body, const PlasticTable& table, int threads) {
    if (table.version == synced_version_) return false;
    const Mesh<E>& mesh = body.mesh();
    const Index n = mesh.num_nodes();
    node_moved_.assign(n, 0);
    for (Index i = 0; i < n; ++i)
      for (int d = 0; d < 3; ++d)
        if (table.rest[3 * i + d] != synced_rest_[3 * i + d]) node_moved_[i] = 1;
    moved_elements_.clear();
    for (Index e = 0; e < mesh.num_elements(); ++e) {
      const auto& c = mesh.element(e);
      bool m = false;
      for (int a = 0; a < N && !m; ++a) m = node_moved_[c[a]];
      if (m) moved_elements_.push_back(e);
    }
    auto rest_of = [&](Index e) { return element_of(mesh, e, table.rest); };
    body.set_rest_shapes(moved_elements_, rest_of, threads);  // checked by the update that proposed them
    grads_.reshape(moved_elements_, [&](Index e) { return typename Flow::Gradients(points_, rest_of(e)); }, threads);
    rest_u_ = table.rest - Eigen::Map<const Vector>(mesh.nodes().data(), 3 * n);
    body.set_rest_displacement(rest_u_);
    synced_rest_ = table.rest;
    synced_version_ = table.version;
    return true;
  }

 private:
  /// The tissue's rigid frame (PlasticParams::RotationFrame::Tissue): the rotation R that best
  /// maps the material positions X_i of the held nodes to their current positions x_i (Kabsch:
  /// the rotation of sum_i (x_i - x_mean)(X_i - X_mean)^T, core/polar.hpp), or of every node
  /// when the held ones do not span a plane (a free body, one grasped node). Exactly I while
  /// every held node is where the material mesh has it (a fixed clamp): then the Tissue frame's
  /// flow is the World frame's bit for bit.
  static Mat3 tissue_frame(const Mesh<E>& mesh, const Vector& u, const Vector& rest, const std::vector<char>& anchor) {
    auto fit = [&](bool held_only) -> std::optional<Mat3> {
      auto used = [&](Index i) { return !held_only || (i < static_cast<Index>(anchor.size()) && anchor[i]); };
      Vec3 X_mean = Vec3::Zero(), x_mean = Vec3::Zero();
      Index n = 0;
      bool at_rest = true;
      for (Index i = 0; i < mesh.num_nodes(); ++i) {
        if (!used(i)) continue;
        const Vec3 X = rest.template segment<3>(3 * i), x = mesh.node(i) + u.template segment<3>(3 * i);
        at_rest = at_rest && x == X;
        X_mean += X, x_mean += x, ++n;
      }
      if (n < 3) return std::nullopt;
      X_mean /= static_cast<Scalar>(n), x_mean /= static_cast<Scalar>(n);
      Mat3 H = Mat3::Zero(), C = Mat3::Zero();
      for (Index i = 0; i < mesh.num_nodes(); ++i) {
        if (!used(i)) continue;
        const Vec3 dX = rest.template segment<3>(3 * i) - X_mean;
        const Vec3 dx = mesh.node(i) + u.template segment<3>(3 * i) - x_mean;
        H += dx * dX.transpose(), C += dX * dX.transpose();
      }
      // A plane at least: the second invariant of the spread (the sum of its eigenvalues'
      // pairwise products) is not round-off against the first squared.
      const Scalar t = C.trace(), i2 = 0.5 * (t * t - (C * C).trace());
      if (!(i2 > 1e-12 * t * t)) return std::nullopt;
      if (at_rest) return Mat3::Identity();
      return ::plastifem::detail::rotation_by_svd(H);
    };
    if (auto R = fit(true)) return *R;
    if (auto R = fit(false)) return *R;
    return Mat3::Identity();
  }
  /// The fusion holds the nodes of every element that does not flow, a cut's (docs/xfem.md) or
  /// one the shape safeguard switched off, so that those keep their last rest shapes: a
  /// switched-off element is elastic with its last rest shape, not distorted by its neighbours'
  /// flow (which failed the shape check in every later update, so none was ever accepted again).
  /// Refactorised when that set changes (rarely: a cut, a switch-off, a rolled-back step).
  void fit_fusion(const Mesh<E>& mesh, const std::vector<char>& off) {
    if (!fusion_off_.empty() && fusion_off_ == off) return;
    std::vector<char> frozen(mesh.num_nodes(), 0);
    for (Index e = 0; e < mesh.num_elements(); ++e)
      if (off[e])
        for (Index i : mesh.element(e)) frozen[i] = 1;
    fusion_.build(mesh, frozen);
    fusion_off_ = off;
  }
  /// Elements whose plasticity the shape safeguard switched off (a cut's frozen ones not counted).
  static int count_off(const PlasticTable& t) {
    return static_cast<int>(std::count(t.off.begin(), t.off.end(), PlasticTable::switched_off));
  }
  static ElementPlasticEntries entries(PlasticTable& t, Index e) {
    return {t.tau.data() + static_cast<size_t>(e) * P,
            t.alpha.empty() ? nullptr : t.alpha.data() + static_cast<size_t>(e) * P * 6,
            t.tau_R.empty() ? nullptr : t.tau_R.data() + static_cast<size_t>(e) * NR,
            t.rotation.empty() ? nullptr : t.rotation.data() + static_cast<size_t>(e) * NR * 3};
  }
  static void copy_entries(const PlasticTable& from, PlasticTable& to, Index e) {
    const size_t p = static_cast<size_t>(e) * P, r = static_cast<size_t>(e) * NR;
    std::copy_n(from.tau.data() + p, P, to.tau.data() + p);
    if (!to.alpha.empty()) std::copy_n(from.alpha.data() + 6 * p, 6 * P, to.alpha.data() + 6 * p);
    if (!to.tau_R.empty()) {
      std::copy_n(from.tau_R.data() + r, NR, to.tau_R.data() + r);
      std::copy_n(from.rotation.data() + 3 * r, 3 * NR, to.rotation.data() + 3 * r);
    }
  }
  static ElementNodes<E> element_of(const Mesh<E>& mesh, Index e, const Vector& rest) {
    return mesh.element_nodes(e, rest);
  }
  /// Whether one of element e's rest nodes moved by more than `tol` from a to b. The shape
  /// check skips elements moved by less than 1e-4 of their shortest original edge: that changes
  /// a scaled Jacobian by ~1e-3 at most.
  static bool moved(const Mesh<E>& mesh, Index e, const Vector& a, const Vector& b, Scalar tol) {
    const auto& c = mesh.element(e);
    for (int k = 0; k < N; ++k)
      if ((a.template segment<3>(3 * c[k]) - b.template segment<3>(3 * c[k])).cwiseAbs().maxCoeff() > tol) return true;
    return false;
  }

  typename Flow::Points points_;
  SharedByShape<E, typename Flow::Gradients> grads_;
  std::optional<typename Elastic::Law> law_;
  std::vector<Scalar> V0_, h_, q0_;
  std::vector<ElementNodes<E>> z_;
  std::vector<FlowResult> result_;
  std::vector<char> changed_, off_new_, node_moved_;
  std::vector<char> degenerate_, element_moved_;  ///< per element: its fused shape degenerates; its rest shape moved
  std::vector<Index> moved_elements_;
  std::vector<PlasticReport> reports_;
  PlasticTable out_;  ///< the flowed entries of the changed elements, before the commit
  Vector rest_new_, synced_rest_, rest_u_;
  std::uint64_t synced_version_ = 0;
  MaterialFusion<E> fusion_;
  std::vector<char> fusion_off_;  ///< the table's off flags the fusion was built for (empty: none built)
};

}  // namespace plastifem::plastic
