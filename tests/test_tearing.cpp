// Tearing (enrichment/tearing.hpp): a crack that starts where sigma_1 reaches the strength and
// runs from element to element.
//
// Facts checked:
//  - a sheet pulled uniformly (Poisson 0: clamped edges leave the stress uniaxial, sigma = E
//    delta / H exactly) starts to tear in the load increment where E delta / H passes the
//    strength, in statics and in a slow dynamic pull; the crack runs straight across the sheet,
//    perpendicular to the pull, the pieces come apart (the lower one stress-free, the gap the
//    pull), nothing is NaN and the energy stays bounded by the energy stored at the tear;
//  - the same with the pull at 45 degrees to the mesh's lines: the crack runs across the pull,
//    through the elements diagonally;
//  - a notched sheet tears from the notch's tip, at the pull at which the element ahead of the
//    tip reaches the strength (linear elasticity: a static solve at unit pull predicts it);
//  - plastic tissue tears too (VertexBlended and ShiftedHeaviside in one Solver);
//  - bad settings are refused.
#include "catch.hpp"

#include <plastifem/cutting.hpp>
#include <plastifem/enrichment/tearing.hpp>
#include <plastifem/plasticity.hpp>

#include <fmt/core.h>

#include <cmath>
#include <functional>
#include <numbers>
#include <type_traits>

using namespace plastifem;

namespace {

// A 10 x 10.5 x 0.5 sheet of 20 x 21 x 1 Hex8 (elements 0.5 across; a middle row of elements,
// so the crack that starts in the middle has as much sheet above as below), E = 3000, Poisson 0.
constexpr Scalar W = 10, H = 10.5, T = 0.5, strength = 30;
const Material sheet_material{3000, 0.0, 1.0};
// The pull at which the uniform uniaxial stress E delta / H reaches the strength.
constexpr Scalar delta_star = strength * H / 3000;

TearingSettings tear(Scalar strength_, Vec3 sweep = Vec3::Zero()) {
  TearingSettings t;
  t.strength = strength_, t.sweep = sweep;
  return t;
}

Mesh<Hex8> sheet() { return bar_mesh<Hex8>(BoxSpec{20, 21, 1, Vec3(W, H, T)}); }

/// The displacement field of uniaxial stress along a (Poisson 0): u = (delta / L) (a . X) a,
/// with L the sheet's extent along a.
Vec3 uniaxial(const Vec3& a, Scalar delta, const Vec3& X) { return delta / H * a.dot(X) * a; }

/// The largest departure from two rigid pieces: below the crack line y0 at rest, above it moved
/// by (0, delta, 0) (each node's own side's displacement), relative to delta.
template <class S>
Scalar apart(const S& s, Scalar y0, Scalar delta) {
  const Eigen::Matrix3Xd u = s.nodal_displacements();
  Scalar worst = 0;
  for (Index n = 0; n < s.mesh().num_nodes(); ++n)
    worst = std::max(worst, (u.col(n) - (s.mesh().nodes()(1, n) > y0 ? Vec3(0, delta, 0) : Vec3::Zero())).norm());
  return worst / delta;
}

const std::vector<Vec3> notch{Vec3(-1, 5.25, 0.25), Vec3(2.1, 5.25, 0.25)};  // to x = 2.1 at mid-height

PrescribedMotion pull_up(Scalar delta) {
  return PrescribedMotion{[delta](Scalar, const Vec3&) { return Vec3(0, delta, 0); }, {}, {}};
}

/// The pull at which the element ahead of the notch's tip reaches the strength, from a static
/// solve at a small pull (0.1% strain) scaled: exact for linear elasticity, within the
/// corotational model's departure from it at 0.5% strain otherwise.
template <class S>
Scalar notch_tearing_pull(const Mesh<Hex8>& mesh) {
  const Scalar probe_pull = 1e-3 * H;
  S unit(mesh, sheet_material);
  unit.fix(mesh.node_set("ymin"));
  unit.prescribe(mesh.node_set("ymax"), pull_up(probe_pull));
  Tearing<S> probe(unit, tear(strength));
  probe.start(notch);
  REQUIRE(probe.num_tips() == 1);
  unit.solve_static();
  return probe_pull * strength / probe.update().largest_stress;  // sigma_1 ahead of the tip
}

template <class S>
bool finite(const S& s) {
  return s.displacement().allFinite() && s.velocity().allFinite() && std::isfinite(s.strain_energy());
}

/// Statics in increments k = 1 .. increments of the pull k delta* / 10.5 (the constraint set
/// `held` given pull(delta)), each followed by growing the crack until it stops at that pull
/// (every growth re-solved); `before_update` runs before each update. Returns the increment the
/// crack started in (-1: none).
template <class S, class Pull>
int tear_in_increments(S& s, Tearing<S>& tearing, ConstraintHandle held, const Pull& pull, int increments,
                       const std::function<void()>& before_update = [] {}) {
  int started_at = -1;
  for (int k = 1; k <= increments; ++k) {
    s.replace(held, pull(k * delta_star / 10.5));
    s.solve_static();
    for (int round = 0; round < 100; ++round) {
      before_update();
      const TearReport r = tearing.update();
      if (r.started) started_at = k;
      if (!r.started && r.grown == 0) break;
      s.solve_static();
      REQUIRE(finite(s));
    }
  }
  return started_at;
}

}  // namespace

TEST_CASE("tearing: a uniformly pulled sheet tears at the strength, straight across, in statics", "[tearing]") {
  const Mesh<Hex8> mesh = sheet();
  using S = Solver<Hex8, Corotational, NoPlasticity, ShiftedHeaviside>;
  S s(mesh, sheet_material);
  s.fix(mesh.node_set("ymin"));
  auto pull = [](Scalar delta) { return PrescribedMotion{[delta](Scalar, const Vec3&) { return Vec3(0, delta, 0); }, {}, {}}; };
  const ConstraintHandle top = s.prescribe(mesh.node_set("ymax"), pull(0));
  Tearing<S> tearing(s, tear(strength));
  CHECK(tearing.sweep() == Vec3::UnitZ());  // the sheet's thinnest axis

  // Increments of delta* / 10.5: the strength is passed in the 11th (delta 1.048 delta*; the
  // 10th reaches 0.952 delta*, and corotational Cauchy stress under a pure stretch with Poisson
  // 0 is E (stretch - 1) exactly).
  Scalar energy_at_tear = 0;
  const int started_at = tear_in_increments(s, tearing, top, pull, 16, [&] {
    if (!tearing.started()) energy_at_tear = s.strain_energy();
  });
  INFO("started in increment " << started_at << ", path of " << tearing.path().size() << " points");
  CHECK(started_at == 11);
  REQUIRE(tearing.started());
  CHECK(tearing.num_tips() == 0);  // both tips ran out of the sheet
  // Straight across, perpendicular to the pull: every path point at the first one's height.
  Scalar off_line = 0, lo = W, hi = 0;
  for (const Vec3& p : tearing.path()) {
    off_line = std::max(off_line, std::abs(p.y() - tearing.path().front().y()));
    lo = std::min(lo, p.x()), hi = std::max(hi, p.x());
  }
  CHECK(off_line < 1e-4);  // the directions' round-off, summed over 20 elements
  CHECK(lo < 0.25);
  CHECK(hi > W - 0.25);
  // Apart: stress-free (the upper piece moves rigidly with the pull), the gap the pull.
  CHECK(s.strain_energy() < 1e-8 * energy_at_tear);
  const Scalar apart_by = apart(s, tearing.path().front().y(), 16 * delta_star / 10.5);
  INFO("two rigid pieces to " << apart_by << " of the pull");
  CHECK(apart_by < 1e-6);
}

TEMPLATE_TEST_CASE("tearing: Tet10 and Wedge6 sheets tear at the strength and come apart, in statics", "[tearing]", Tet10,
                   Wedge6) {
  // The uniform pull of the Hex8 test (Poisson 0: the stress is E delta / H exactly, for the
  // quadratic tetrahedra too), on Wedge6 prisms (the element for membranes) and on Tet10 (10 x
  // 11 cells: elements about 1 across). Both start in the same increment as Hex8, the 11th,
  // and run out of both sides, the path wandering within an element row (y from 5.18 to 5.35 on
  // Tet10, 4.96 to 5.17 on Wedge6: 0.5 allows three times that). Tet10 comes apart as Hex8 does
  // (3e-25 of the strain energy at the tear left; 1e-8 allows for the solves' round-off, as
  // there); on Wedge6 some nodes beside the wandering path stay unenriched, as beside a crack
  // along a node row (docs/xfem.md), and 2.8e-4 is left: 1e-3 allows 3.5 times that.
  using E = TestType;
  const bool tet10 = std::is_same_v<E, Tet10>;
  const Mesh<E> mesh = bar_mesh<E>(BoxSpec{tet10 ? 10 : 20, tet10 ? 11 : 21, 1, Vec3(W, H, T)});
  using S = Solver<E, Corotational, NoPlasticity, ShiftedHeaviside>;
  S s(mesh, sheet_material);
  s.fix(mesh.node_set("ymin"));
  const ConstraintHandle top = s.prescribe(mesh.node_set("ymax"), pull_up(0));
  Tearing<S> tearing(s, tear(strength));
  Scalar energy_at_tear = 0;
  const int started_at = tear_in_increments(s, tearing, top, pull_up, 16, [&] {
    if (!tearing.started()) energy_at_tear = s.strain_energy();
  });
  REQUIRE(tearing.started());
  Scalar lo = W, hi = 0, y_lo = H, y_hi = 0;
  for (const Vec3& p : tearing.path())
    lo = std::min(lo, p.x()), hi = std::max(hi, p.x()), y_lo = std::min(y_lo, p.y()), y_hi = std::max(y_hi, p.y());
  const Scalar left = s.strain_energy() / energy_at_tear;
  fmt::print("tearing {}: started in increment {}, path x in [{:.3f}, {:.3f}], y in [{:.3f}, {:.3f}], strain energy {:.2g} "
             "of that at the tear\n",
             E::name, started_at, lo, hi, y_lo, y_hi, left);
  CHECK(started_at == 11);
  CHECK(tearing.num_tips() == 0);
  CHECK(lo < 0.25);
  CHECK(hi > W - 0.25);
  CHECK(y_hi - y_lo < 0.5);  // across the pull
  CHECK(left < (tet10 ? 1e-8 : 1e-3));
}

TEMPLATE_TEST_CASE("a cut through nodes held in one direction only opens in the others (a sheet on a tray)",
                   "[tearing][xfem]", Heaviside, ShiftedHeaviside) {
  // Every node held in z (DofMask z only), the sheet cut across at mid-height and pulled: the
  // pieces part in y. A node's enriched dofs are held only in the directions the node is held
  // (Heaviside: the node is u_i + H_i a_i on both sides, so a_i,z = 0 keeps it where it is held
  // in z; x and y stay free). Holding all three kept the crack shut: the energy of a pull
  // across an uncut sheet.
  const Mesh<Hex8> mesh = sheet();
  using S = Solver<Hex8, Corotational, NoPlasticity, TestType>;
  S s(mesh, sheet_material);
  s.fix(select_nodes(mesh, [](const Vec3&) { return true; }), DofMask{false, false, true});
  s.fix(mesh.node_set("ymin"));
  const Scalar delta = 0.5 * delta_star;
  s.prescribe(mesh.node_set("ymax"), pull_up(delta));
  s.cut(CutPlane(Vec3(0, 5.2, 0), Vec3(0, 1, 0)));  // through the middle row of elements
  s.solve_static();
  REQUIRE(finite(s));
  // Uncut, the pull stores E (delta / H)^2 / 2 per volume; cut, the pieces move rigidly.
  const Scalar uncut_energy = 0.5 * 3000 * (delta / H) * (delta / H) * W * H * T;
  INFO("strain energy " << s.strain_energy() << " against " << uncut_energy << " uncut");
  CHECK(s.strain_energy() < 1e-10 * uncut_energy);
  CHECK(apart(s, 5.2, delta) < 1e-8);  // rigid pieces, the upper one carried by the pull
  CHECK(s.nodal_displacements().row(2).cwiseAbs().maxCoeff() == 0.0);  // held in z exactly
}

TEST_CASE("tearing: a notched sheet pulled slowly in dynamics tears at the predicted pull, the pieces separate, "
          "the energy stays bounded",
          "[tearing]") {
  const Mesh<Hex8> mesh = sheet();
  using S = Solver<Hex8, Corotational, NoPlasticity, ShiftedHeaviside>;
  const Scalar predicted = notch_tearing_pull<S>(mesh);
  SolverSettings st;
  st.rayleigh_mass = 4;  // the pieces' vibration after the tear gone (e^(-4 t / 2)) by the end
  S s(mesh, sheet_material, st);
  s.fix(mesh.node_set("ymin"));
  // delta(t) = 1.5 delta_t (1 - cos(pi t / 4)) / 2: starting at rest, over 4 s against the
  // sheet's first axial period 4 H / sqrt(E / rho) = 0.77 s, so the stress follows the pull
  // quasi-statically; it passes delta_t at t = 4 acos(1 - 2 / 1.5) / pi = 2.43 s.
  auto delta = [&](Scalar t) { return 1.5 * predicted * (1 - std::cos(std::numbers::pi * std::min(t, 4.0) / 4)) / 2; };
  s.prescribe(mesh.node_set("ymax"), [&](Scalar t, const Vec3&) { return Vec3(0, delta(t), 0); });
  Tearing<S> tearing(s, tear(strength));
  tearing.start(notch);
  Scalar grew_at = -1, energy_at_tear = 0, largest_after = 0, energy_a_second_before = 0;
  for (int k = 0; k < 600; ++k) {
    s.step(0.01);
    REQUIRE(finite(s));
    const Scalar energy = s.strain_energy() + s.kinetic_energy();
    if (grew_at >= 0) largest_after = std::max(largest_after, energy);
    else energy_at_tear = energy;
    if (tearing.update().grown > 0 && grew_at < 0) grew_at = s.time();
    if (k == 499) energy_a_second_before = energy;
  }
  INFO("grew first at a pull of " << delta(grew_at) / predicted << " of the predicted one, energy at the tear "
                                  << energy_at_tear << ", largest after " << largest_after << "; path of "
                                  << tearing.path().size() << " points, " << tearing.num_tips() << " tips");
  // Within a step's pull (0.6%) and the dynamic stress's departure from the static one (1%).
  CHECK(std::abs(delta(grew_at) / predicted - 1) < 0.02);
  CHECK(tearing.num_tips() == 0);
  CHECK(largest_after < 1.05 * energy_at_tear);
  // Coming to rest (damped): the energy the tear released as vibration decays (0.5% of the
  // stored energy left at the end, half of it a second before), the lower piece still, the
  // upper one moved with the pull.
  CHECK(s.strain_energy() + s.kinetic_energy() < 0.02 * energy_at_tear);
  CHECK(s.strain_energy() + s.kinetic_energy() < 0.75 * energy_a_second_before);
  const Scalar apart_by = apart(s, 5.25, 1.5 * predicted);
  INFO("two rigid pieces to " << apart_by << " of the pull");
  CHECK(apart_by < 0.01);
}

TEST_CASE("tearing: pulled at 45 degrees to the mesh's lines, the crack runs across the pull", "[tearing]") {
  // Uniaxial stress along a = (1, 1, 0) / sqrt 2 held on all four edges (Poisson 0: u = (delta /
  // H) (a . X) a is the exact field, sigma = E delta / H a a^T). The crack must run along (1, -1),
  // diagonally through the elements, here 0.5 x 0.4 (on square ones the diagonal through an
  // element's centre runs through nodes).
  const Mesh<Hex8> mesh = bar_mesh<Hex8>(BoxSpec{20, 21, 1, Vec3(W, 8.4, T)});
  using S = Solver<Hex8, Corotational, NoPlasticity, ShiftedHeaviside>;
  S s(mesh, sheet_material);
  const Vec3 a = Vec3(1, 1, 0).normalized();
  std::vector<Index> edges;
  for (const char* side : {"xmin", "xmax", "ymin", "ymax"})
    for (Index n : mesh.node_set(side)) edges.push_back(n);
  std::sort(edges.begin(), edges.end());
  edges.erase(std::unique(edges.begin(), edges.end()), edges.end());
  auto pull = [a](Scalar delta) { return PrescribedMotion{[a, delta](Scalar, const Vec3& X) { return uniaxial(a, delta, X); }, {}, {}}; };
  const ConstraintHandle held = s.prescribe(edges, pull(0));
  Tearing<S> tearing(s, tear(strength));
  const int started_at = tear_in_increments(s, tearing, held, pull, 14);
  CHECK(started_at == 11);
  REQUIRE(tearing.path().size() > 10);
  // Across the pull: each segment's direction's component along a, in the middle of the sheet
  // (within 2.5 of its centre: near the held edges the field is theirs), and the chord's.
  const Vec3 middle(W / 2, 4.2, T / 2);
  Scalar along_pull = 0;
  for (size_t i = 0; i + 1 < tearing.path().size(); ++i) {
    const Vec3 p = tearing.path()[i], q = tearing.path()[i + 1];
    if (((p + q) / 2 - middle).head<2>().norm() < 2.5) along_pull = std::max(along_pull, std::abs((q - p).normalized().dot(a)));
  }
  const Scalar chord = std::abs((tearing.path().back() - tearing.path().front()).normalized().dot(a));
  INFO(tearing.path().size() << " path points; largest |d . a| in the middle " << along_pull << ", the chord's " << chord);
  CHECK(tearing.num_tips() == 0);
  CHECK(along_pull < 0.1);  // within 6 degrees of perpendicular
  CHECK(chord < 0.26);      // within 15 degrees, the held edges' pull on the ends included
}

TEST_CASE("tearing: a notched sheet tears from the notch's tip at the predicted pull", "[tearing]") {
  // A notch from the left edge to x = 2.1 at mid-height, y = 5.25 (the middle of an element row), the
  // crack's start. With linear elasticity the stress ahead of its tip is proportional to the
  // pull: a static solve at unit pull predicts the pull that tears, delta_t = strength /
  // sigma_1(1).
  const Mesh<Hex8> mesh = sheet();
  using S = Solver<Hex8, Linear, NoPlasticity, Heaviside>;
  auto pull = pull_up;
  const Scalar predicted = notch_tearing_pull<S>(mesh);
  S s(mesh, sheet_material);
  s.fix(mesh.node_set("ymin"));
  const ConstraintHandle top = s.prescribe(mesh.node_set("ymax"), pull(0));
  Tearing<S> tearing(s, tear(strength));
  tearing.start(notch);
  // Increments of predicted / 10.5: the first growth must come in the 11th.
  int grew_at = -1;
  for (int k = 1; k <= 12 && grew_at < 0; ++k) {
    s.replace(top, pull(k * predicted / 10.5));
    s.solve_static();
    if (tearing.update().grown > 0) grew_at = k;
  }
  INFO("predicted pull " << predicted << " (the unnotched sheet's: " << delta_star << ")");
  CHECK(predicted < delta_star);  // the notch concentrates the stress
  CHECK(grew_at == 11);
  // It grew from the tip (carried on to x = 2.5, the face of the element the notch ends in) by
  // one element, along the notch's line.
  CHECK(tearing.path().size() == 3);
  CHECK(tearing.path().back().x() > 2.9);
  // Pulled on, it runs straight across (the sheet is symmetric about the notch's line) and the
  // sheet comes apart.
  for (int k = 12; k <= 16; ++k) {
    s.replace(top, pull(k * predicted / 10.5));
    s.solve_static();
    for (int round = 0; round < 100 && tearing.update().grown > 0; ++round) s.solve_static();
  }
  Scalar off_line = 0;
  for (const Vec3& p : tearing.path()) off_line = std::max(off_line, std::abs(p.y() - 5.25));
  INFO("path of " << tearing.path().size() << " points, off the line by " << off_line);
  CHECK(tearing.num_tips() == 0);
  CHECK(tearing.path().back().x() > W - 0.25);
  CHECK(off_line < 1e-6);
  CHECK(apart(s, 5.25, 16 * predicted / 10.5) < 1e-6);
}

TEST_CASE("tearing: a crack along a node row or within the snap distance of one, and a Tet4 sheet's, run across",
          "[tearing]") {
  // The elements past a path's end that the crack itself crosses already stopped it: a Tet4
  // crack's ribbon crosses the elements of the cell beside the end, and nodes snapped onto the
  // crack line make the element past it a cut one (found by review, 2026-11-30: a notch at
  // y = 5.003 or 5 never grew, sigma_1 up to 167 against the strength 30; a Tet4 sheet's crack
  // stopped in its first cell). The tip is now carried through them. That it then runs across is
  // what is checked: so close to a node row, or through Kuhn tetrahedra, the sheet does not come
  // fully apart (docs/xfem.md, "Tearing", its limits).
  {
    using S = Solver<Hex8, Corotational, NoPlasticity, ShiftedHeaviside>;
    const Mesh<Hex8> mesh = sheet();
    for (const Scalar y0 : {5.0, 5.003, 4.997}) {
      INFO("notch at y = " << y0);
      S s(mesh, sheet_material);
      s.fix(mesh.node_set("ymin"));
      const ConstraintHandle top = s.prescribe(mesh.node_set("ymax"), pull_up(0));
      Tearing<S> tearing(s, tear(strength));
      tearing.start({Vec3(-1, y0, 0.25), Vec3(2.1, y0, 0.25)});
      for (int k = 1; k <= 12; ++k) {  // it first grows at a pull of 0.07 to 0.09
        s.replace(top, pull_up(0.01 * k));
        s.solve_static();
        for (int round = 0; round < 60 && tearing.update().grown > 0; ++round) s.solve_static();
      }
      CHECK(tearing.num_tips() == 0);
      CHECK(tearing.path().back().x() > W - 0.25);
    }
  }
  // The uniform pull of the first test on the sheet's Kuhn tetrahedra: it starts in the same
  // increment and runs out of both sides.
  using S = Solver<Tet4, Corotational, NoPlasticity, ShiftedHeaviside>;
  const Mesh<Tet4> mesh = bar_mesh<Tet4>(BoxSpec{20, 21, 1, Vec3(W, H, T)});
  S s(mesh, sheet_material);
  s.fix(mesh.node_set("ymin"));
  const ConstraintHandle top = s.prescribe(mesh.node_set("ymax"), pull_up(0));
  Tearing<S> tearing(s, tear(strength));
  const int started_at = tear_in_increments(s, tearing, top, pull_up, 16);
  Scalar lo = W, hi = 0;
  for (const Vec3& p : tearing.path()) lo = std::min(lo, p.x()), hi = std::max(hi, p.x());
  INFO("path of " << tearing.path().size() << " points, x in [" << lo << ", " << hi << "]");
  CHECK(started_at == 11);
  CHECK(tearing.num_tips() == 0);
  CHECK(lo < 0.25);
  CHECK(hi > W - 0.25);
}

TEST_CASE("tearing: plastic tissue tears (plasticity and cutting in one Solver)", "[tearing][plasticity]") {
  // The uniform pull with VertexBlended plasticity yielding before the strength: the crack
  // starts, runs across and the pieces separate; the material mesh keeps its permanent set.
  const Mesh<Hex8> mesh = sheet();
  using S = Solver<Hex8, Corotational, VertexBlended, ShiftedHeaviside>;
  PlasticParams p;
  p.yield_stress = 20;
  p.flow_rate = 0.4;
  p.stress_scale = 1;
  p.hardening = 0.2;
  SolverSettings st;
  st.rayleigh_mass = 2;
  S s(mesh, sheet_material, st, p);
  s.fix(mesh.node_set("ymin"));
  auto delta = [](Scalar t) { return 2 * delta_star * std::min(t, 2.0) / 2; };
  s.prescribe(mesh.node_set("ymax"), [&](Scalar t, const Vec3&) { return Vec3(0, delta(t), 0); });
  Tearing<S> tearing(s, tear(strength));
  for (int k = 0; k < 300; ++k) {
    s.step(0.01);
    REQUIRE(finite(s));
    tearing.update();
  }
  REQUIRE(tearing.started());
  CHECK(tearing.num_tips() == 0);
  const Scalar flowed = (s.material_positions() - mesh.nodes()).cwiseAbs().maxCoeff();
  INFO("material mesh moved by " << flowed);
  CHECK(flowed > 1e-4);
}

TEST_CASE("tearing: in plastic tissue a notch is cut where it is given (the mesh's coordinates)", "[tearing][plasticity]") {
  // Found by review (2026-12-01): the crack path was moved with the plastic set before the cut,
  // though cuts are given in the mesh's coordinates (docs/xfem.md); a bar stretched with a
  // permanent set of 0.083 at x = 9 had a notch at x = 8.95 cut the elements beyond x = 9 too.
  const Mesh<Hex8> mesh = bar_mesh<Hex8>(10, 3, 3);
  PlasticParams p;
  p.yield_stress = 1000, p.flow_rate = 0.4, p.stress_scale = 50, p.hardening = 0.2;
  using S = Solver<Hex8, Corotational, VertexBlended, ShiftedHeaviside>;
  S s(mesh, Material{3000, 0.45, 1.0}, {}, p);
  s.fix(mesh.node_set("xmin"));
  const LoadHandle pull = s.add_traction(mesh.face_set("xmax"), Vec3(1600.0 / 9, 0, 0));
  s.solve_static(10);
  s.remove_load(pull);
  s.solve_static();
  const auto flowed = s.material_positions();
  Scalar set = 0;
  for (Index i = 0; i < mesh.num_nodes(); ++i)
    if (std::abs(mesh.node(i).x() - 9) < 1e-9) set = std::max(set, flowed(0, i) - 9);
  CHECK(set > 0.05);  // measured 0.083: more than the notch's distance to x = 9
  TearingSettings t;
  t.strength = 1e9, t.sweep = Vec3(0, 0, 1);
  Tearing<S> tearing(s, t);
  tearing.start({Vec3(8.95, -1, 1.5), Vec3(8.95, 1.5, 1.5), Vec3(8.95, 4, 1.5)});
  int cut = 0, elsewhere = 0;
  for (size_t k = 0; k < s.enrichment().elements().size(); ++k) {
    if (s.enrichment().elements()[k].num_sides != 2) continue;
    ++cut;
    elsewhere += std::abs(mesh.element_nodes(s.enrichment().element_of(k)).row(0).mean() - 8.5) > 1e-9;
  }
  CHECK(cut == 9);  // the 3 x 3 elements between x = 8 and 9
  CHECK(elsewhere == 0);
}

TEST_CASE("tearing: bad settings and crack paths are refused", "[tearing]") {
  const Mesh<Hex8> mesh = sheet();
  using S = Solver<Hex8, Corotational, NoPlasticity, Heaviside>;
  S s(mesh, sheet_material);
  CHECK_THROWS_AS(Tearing<S>(s, tear(0)), InvalidArgument);
  CHECK_THROWS_AS(Tearing<S>(s, tear(std::numeric_limits<Scalar>::infinity())), InvalidArgument);
  CHECK_THROWS_AS(Tearing<S>(s, tear(30, Vec3(std::nan(""), 0, 1))), InvalidArgument);
  Tearing<S> t(s, tear(30));
  CHECK_THROWS_AS(t.start({Vec3(1, 1, 0)}), InvalidArgument);
  CHECK_THROWS_AS(t.start({Vec3(1, 1, 0), Vec3(std::nan(""), 1, 0)}), InvalidArgument);
  CHECK_THROWS_AS(t.start({Vec3(1, 1, 0), Vec3(1, 1, 0)}), InvalidArgument);
  CHECK(!t.started());
  // A short sweep vector is a direction all the same (Eigen's isZero took any vector of
  // components below 1e-12 for "none" and put the thinnest axis, z here, in its place).
  CHECK(Tearing<S>(s, tear(30, Vec3(1e-13, 0, 0))).sweep() == Vec3::UnitX());
  // Unloaded: nothing tears.
  const TearReport r = t.update();
  CHECK(!r.started);
  CHECK(std::abs(r.largest_stress) < 1e-9);
  // A repeated point is one: the notch's end keeps its direction and is carried on to the
  // element's face, a tip as without it (found by review, 2026-11-30: the tip's direction was
  // zero, and the first update dropped it).
  for (const bool at_front : {false, true}) {
    S twice(mesh, sheet_material);
    Tearing<S> doubled(twice, tear(30));
    doubled.start(at_front ? std::vector<Vec3>{notch[1], notch[1], notch[0]} : std::vector<Vec3>{notch[0], notch[1], notch[1]});
    INFO((at_front ? "tip at the front" : "tip at the back"));
    CHECK(doubled.num_tips() == 1);
    CHECK(doubled.path().size() == 2);
    const Vec3 tip = at_front ? doubled.path().front() : doubled.path().back();
    CHECK(std::abs(tip.x() - 2.4995) < 1e-9);
  }
}
