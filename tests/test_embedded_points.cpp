// Points embedded in a body (embedding/embedded_points.hpp).
//
// Facts checked:
//  - isoparametric elements reproduce a linear field exactly: u = A X + b interpolated at random
//    points equals A X + b (round-off), on every element;
//  - at a node the field is the node's value;
//  - a cut bar whose free half falls: points on the free side move by the closed-form damped
//    free fall, points on the clamped side by the clamped half's own field, whichever element
//    (cut or not) they are in; the sides follow the solver's cut as it grows, and a point's
//    stress is its own piece's (zero on the falling piece);
//  - with a solver, in statics and dynamics: a point at a node has the node's position and
//    velocity exactly; a point inside a cell keeps its reference coordinates in the deformed
//    cell (it stays inside it); its stress is its element's; under plastic flow its material
//    position is interpolated from the material mesh, exactly the node's at a node.
#include "catch.hpp"
#include "compositions.hpp"

#include <plastifem/cutting.hpp>
#include <plastifem/embedding/embedded_points.hpp>
#include <plastifem/plastifem.hpp>
#include <plastifem/plasticity.hpp>

#include <random>
#include <vector>

using namespace plastifem;
using namespace plastifem::testing;

TEMPLATE_LIST_TEST_CASE("embedded points: a linear field is reproduced, nodes give their values",
                        "[points]", AllElements) {
  const Mesh<TestType> mesh = bar_mesh<TestType>(6, 2, 2);
  std::mt19937 rng(5);
  std::uniform_real_distribution<Scalar> u01(0, 1);
  std::vector<Vec3> X;
  for (int k = 0; k < 500; ++k) X.emplace_back(6 * u01(rng), 2 * u01(rng), 2 * u01(rng));
  for (Index i = 0; i < mesh.num_nodes(); ++i) X.push_back(mesh.node(i));
  const EmbeddedPoints<TestType> points(mesh, X);
  Mat3 A;
  A << 0.1, -0.3, 0.2, 0.05, 0.4, -0.1, 0.3, 0.0, -0.2;
  const Vec3 b(1, -2, 0.5);
  Vector u(3 * mesh.num_nodes());
  for (Index i = 0; i < mesh.num_nodes(); ++i) u.segment<3>(3 * i) = A * mesh.node(i) + b;
  Eigen::Matrix3Xd at;
  points.interpolate(u, at);
  Scalar worst = 0;
  for (Index k = 0; k < points.size(); ++k) worst = std::max(worst, (at.col(k) - (A * X[k] + b)).norm());
  INFO("largest error of the linear field " << worst);
  CHECK(worst < 1e-13);
  CHECK_THROWS_AS(EmbeddedPoints<TestType>(mesh, std::vector<Vec3>{Vec3(7, 1, 1)}), InvalidArgument);
}

TEST_CASE("embedded points in a cut body take their own piece's field", "[points][enrichment]") {
  // bar90 cut across, its free half falling under gravity with mass damping alpha: the free
  // side's points fall by z(t) = -(g / alpha) (t - (1 - e^{-alpha t}) / alpha). Cut at x = 5.5
  // (through elements: points either side of the cut in one element) and at x = 5 (a plane of
  // nodes: the clamped side is then exactly the bar 5 x 3 x 3, solved separately).
  const Scalar alpha = 0.5, g = 9.81;
  SolverSettings st;
  st.rayleigh_mass = alpha;
  const Material soft{3000, 0.45, 1.0};
  auto fallen = [&](Scalar t) { return -(g / alpha) * (t - (1 - std::exp(-alpha * t)) / alpha); };
  for (const Scalar x_cut : {5.5, 5.0}) {
    const Mesh<Hex8> mesh = bar_mesh<Hex8>(10, 3, 3);
    Solver<Hex8, Corotational, NoPlasticity, Heaviside> s(mesh, soft, st);
    s.fix(mesh.node_set("xmin"));
    s.add_gravity(Vec3(0, 0, -g));
    s.cut(CutPlane(Vec3(x_cut, 0, 0), Vec3(1, 0, 0)));
    std::vector<Vec3> X;
    for (Scalar x : {4.2, 4.7, 5.1, 5.4, 5.6, 5.9, 8.0})
      for (Scalar y : {0.3, 1.5, 2.7}) X.emplace_back(x, y, 1.2);
    EmbeddedPoints<Hex8> points(mesh, X);
    points.assign_sides(s.enrichment());
    // The clamped side alone (x_cut = 5: exactly the bar 5 x 3 x 3).
    const Mesh<Hex8> half = bar_mesh<Hex8>(5, 3, 3);
    Solver<Hex8, Corotational> h(half, soft, st);
    h.fix(half.node_set("xmin"));
    h.add_gravity(Vec3(0, 0, -g));
    std::vector<Vec3> X_half;
    for (const Vec3& x : X)
      if (x_cut == 5.0 && x.x() < x_cut) X_half.push_back(x);
    const EmbeddedPoints<Hex8> half_points(half, X_half);
    for (int k = 0; k < 50; ++k) s.step(0.01), h.step(0.01);
    Eigen::Matrix3Xd at, at_half;
    points.interpolate(s.displacement(), at, s.enrichment());
    half_points.interpolate(h.displacement(), at_half);
    const Scalar fall = fallen(s.time());
    Scalar free_off = 0, clamped_off = 0;
    Index j = 0;
    for (Index k = 0; k < points.size(); ++k) {
      if (X[k].x() > x_cut) free_off = std::max(free_off, (at.col(k) - Vec3(0, 0, fall)).norm());
      else if (x_cut == 5.0) clamped_off = std::max(clamped_off, (at.col(k) - at_half.col(j++)).norm());
    }
    INFO("cut at x = " << x_cut << ": free fall " << fall << ", the free side's points off it by " << free_off
                       << "; the clamped side's off the half bar's by " << clamped_off);
    CHECK(free_off < 1e-3 * std::abs(fall));  // the trapezoidal rule's O((alpha dt)^2) = 2.5e-5 relative
    if (x_cut == 5.0) CHECK(clamped_off < 1e-6);  // the same space: Newton's and CG's tolerances
    if (x_cut == 5.5) CHECK(points.side(2 * 3) != points.side(5 * 3));  // x = 5.1 and 5.9: one cut element, two sides
  }
}

namespace {

/// Every node of the mesh and `n` random points inside the box [0, nx] x [0, ny] x [0, nz].
template <FiniteElement E>
std::vector<Vec3> nodes_and_random_points(const Mesh<E>& mesh, Vec3 box, int n, unsigned seed) {
  std::vector<Vec3> X;
  for (Index i = 0; i < mesh.num_nodes(); ++i) X.push_back(mesh.node(i));
  std::mt19937 rng(seed);
  std::uniform_real_distribution<Scalar> u01(0, 1);
  for (int k = 0; k < n; ++k) X.emplace_back(box.x() * u01(rng), box.y() * u01(rng), box.z() * u01(rng));
  return X;
}

}  // namespace

TEMPLATE_LIST_TEST_CASE("embedded points follow a solver: nodes exactly, cell points at their reference coordinates",
                        "[points]", AllElements) {
  using E = TestType;
  const Mesh<E> mesh = bar_mesh<E>(6, 2, 2);
  const std::vector<Vec3> X = nodes_and_random_points(mesh, Vec3(6, 2, 2), 300, 11);
  EmbeddedPoints<E> points(mesh, X);
  SolverSettings st;
  st.rayleigh_mass = 0.5;
  Solver<E, Corotational> s(mesh, Material{3000, 0.45, 1.0}, st);
  s.fix(mesh.node_set("xmin"));
  s.add_gravity(Vec3(0, 0, -9.81));
  Eigen::Matrix3Xd x, v, Xm;
  std::vector<Mat3> sigma;
  auto check = [&](const char* mode) {
    points.positions(s, x), points.velocities(s, v), points.material_positions(s, Xm), points.stresses(s, sigma);
    const Eigen::Matrix3Xd nodes_x = s.positions();
    const std::vector<Mat3> element_sigma = s.element_stress();
    Index node_mismatch = 0, stress_mismatch = 0;
    Scalar xi_drift = 0;
    for (Index k = 0; k < points.size(); ++k) {
      if (k < mesh.num_nodes()) {  // bitwise: the node's own values
        node_mismatch += x.col(k) != nodes_x.col(k) || v.col(k) != s.velocity().template segment<3>(3 * k) ||
                         Xm.col(k) != mesh.node(k);
      } else {
        // Where the deformed cell puts the deformed point: the point's own xi.
        ElementNodes<E> xe;
        for (int a = 0; a < E::num_nodes; ++a) xe.col(a) = nodes_x.col(mesh.element(points.element(k))[a]);
        const auto xi = locate_in_element<E>(xe, x.col(k));
        xi_drift = std::max(xi_drift, xi ? (*xi - points.xi(k)).norm() : Scalar(1));
      }
      stress_mismatch += sigma[k] != element_sigma[points.element(k)];
    }
    INFO(mode << ": largest change of a point's reference coordinates " << xi_drift);
    CHECK(node_mismatch == 0);
    CHECK(stress_mismatch == 0);
    CHECK(xi_drift < 1e-9);  // locate_in_element's Newton tolerance
  };
  s.solve_static();
  check("statics");
  CHECK(x.col(mesh.num_nodes() - 1).z() < mesh.node(mesh.num_nodes() - 1).z() - 1e-3);  // the bar sagged: a test of something that moved
  s.set_state(Vector::Zero(s.num_dofs()), Vector::Zero(s.num_dofs()));
  for (int k = 0; k < 20; ++k) s.step(0.01);
  check("dynamics");
  CHECK(v.col(mesh.num_nodes() - 1).norm() > 1e-2);
  CHECK_THROWS_AS(points.positions(Solver<E, Corotational>(bar_mesh<E>(3, 2, 2), Material{3000, 0.45, 1.0}), x),
                  InvalidArgument);
}

TEST_CASE("embedded points under plastic flow follow the material mesh", "[points][plasticity]") {
  // The stretch scene (SCENES.md bar, bar cells 10 x 3 x 3, end traction 350 ramped over 1 s,
  // released at 2 s), run to 2.5 s: the material mesh's free corner moves by 0.026. A point's material position is
  // sum N_a Xbar_a, at a node the node's Xbar exactly; its deformed position keeps following the
  // deformed cell.
  const Mesh<Hex8> mesh = bar_mesh<Hex8>(10, 3, 3);
  PlasticParams pp;
  pp.yield_stress = 1000, pp.flow_rate = 0.4, pp.stress_scale = 50, pp.hardening = 0.2;
  SolverSettings st;
  st.rayleigh_mass = 1.0;
  Solver<Hex8, Corotational, VertexBlended> s(mesh, Material{3000, 0.45, 1.0}, st, pp);
  s.fix(mesh.node_set("xmin"));
  s.add_traction(mesh.face_set("xmax"), Vec3(350.0 / 9, 0, 0), ramp_hold_release(1.0, 2.0));
  const std::vector<Vec3> X = nodes_and_random_points(mesh, Vec3(10, 3, 3), 300, 12);
  EmbeddedPoints<Hex8> points(mesh, X);
  for (int k = 0; k < 250; ++k) s.step(0.01);
  Eigen::Matrix3Xd Xm, x;
  points.material_positions(s, Xm), points.positions(s, x);
  const Eigen::Matrix3Xd Xbar = s.material_positions(), nodes_x = s.positions();
  Index node_mismatch = 0;
  Scalar interpolation_error = 0, xi_drift = 0;
  for (Index k = 0; k < points.size(); ++k) {
    if (k < mesh.num_nodes()) {
      node_mismatch += Xm.col(k) != Xbar.col(k);
      continue;
    }
    const auto& c = mesh.element(points.element(k));
    const auto N = Hex8::shape(points.xi(k));
    Vec3 expected = Vec3::Zero();
    ElementNodes<Hex8> xe;
    for (int a = 0; a < 8; ++a) expected += N[a] * Xbar.col(c[a]), xe.col(a) = nodes_x.col(c[a]);
    interpolation_error = std::max(interpolation_error, (Xm.col(k) - expected).norm());
    const auto xi = locate_in_element<Hex8>(xe, x.col(k));
    xi_drift = std::max(xi_drift, xi ? (*xi - points.xi(k)).norm() : Scalar(1));
  }
  const Scalar set = (Xbar.col(mesh.num_nodes() - 1) - mesh.node(mesh.num_nodes() - 1)).norm();
  INFO("material mesh moved by " << set << " at the free corner; interpolation off by " << interpolation_error
                                 << ", reference coordinates by " << xi_drift);
  CHECK(set > 0.01);  // the plastic set the test is about (0.026)
  CHECK(node_mismatch == 0);
  CHECK(interpolation_error < 1e-13);
  CHECK(xi_drift < 1e-9);
}

TEST_CASE("embedded points follow a growing cut: sides reassigned, each piece's stress", "[points][enrichment]") {
  // bar90 (10 x 3 x 3 Hex8), clamped at x = 0, cut by a blade at x = 5.5 down to z = 1.5 first,
  // then grown through the whole section: the free half falls only then. Points either side of the
  // cut in the cut elements (x = 5.3 and 5.7, low z) are on one side of an uncut element first
  // and on two sides after the cut grew; the falling piece falls rigidly by the closed-form
  // damped fall and is stress-free, the clamped side carries the bending stress.
  const Mesh<Hex8> mesh = bar_mesh<Hex8>(10, 3, 3);
  SolverSettings st;
  st.rayleigh_mass = 0.5;
  Solver<Hex8, Corotational, NoPlasticity, Heaviside> s(mesh, Material{3000, 0.45, 1.0}, st);
  s.fix(mesh.node_set("xmin"));
  s.add_gravity(Vec3(0, 0, -9.81));
  const std::vector<Vec3> X{Vec3(5.3, 1.5, 0.4), Vec3(5.7, 1.5, 0.4), Vec3(2.0, 1.5, 0.4), Vec3(8.0, 1.5, 0.4)};
  EmbeddedPoints<Hex8> points(mesh, X);
  auto blade = [](Scalar depth) { return CutPatch(Vec3(5.5, -0.1, 3.1), Vec3(0, 3.2, 0), Vec3(0, 0, -depth)); };
  const CutHandle cut = s.cut(blade(1.6));
  Eigen::Matrix3Xd u;
  points.displacements(s, u);
  CHECK(points.side(0) == points.side(1));  // below the partial cut: one uncut element
  s.grow_cut(cut, blade(3.2));
  points.displacements(s, u);  // no assign_sides: the call sees the grown cut
  CHECK(points.side(0) != points.side(1));
  for (int k = 0; k < 30; ++k) s.step(0.01);
  std::vector<Mat3> sigma;
  points.displacements(s, u), points.stresses(s, sigma);
  INFO("stress norms: clamped side " << sigma[0].norm() << " and " << sigma[2].norm() << ", falling side "
                                     << sigma[1].norm() << " and " << sigma[3].norm());
  // The free side's points fell together (a rigid translation) by the damped free fall.
  const Scalar t = s.time(), fall = -(9.81 / 0.5) * (t - (1 - std::exp(-0.5 * t)) / 0.5);
  CHECK((u.col(1) - Vec3(0, 0, fall)).norm() < 1e-3 * std::abs(fall));  // the trapezoidal rule's O((alpha dt)^2)
  CHECK((u.col(1) - u.col(3)).norm() < 1e-6 * std::abs(fall));
  CHECK(sigma[2].norm() > 10);
  // A rigid fall is stress-free: what is left is Newton's and CG's tolerances (5e-7 of the
  // clamped side's stress measured).
  CHECK(sigma[1].norm() < 1e-5 * sigma[2].norm());
  CHECK(sigma[3].norm() < 1e-5 * sigma[2].norm());
  // The low-level call refuses an enrichment the sides were not assigned for.
  EmbeddedPoints<Hex8> fresh(mesh, X);
  CHECK_THROWS_AS(fresh.interpolate(s.displacement(), u, s.enrichment()), InvalidArgument);
}

TEST_CASE("embedded points located in another mesh of the same sizes are refused", "[points]") {
  // A solver on a mesh of the same node and element counts but other coordinates or another
  // element node order would give the points wrong fields: check_mesh compares the sampled
  // points' elements node by node, bit for bit, with the mesh they were located in.
  const Mesh<Hex8> mesh = bar_mesh<Hex8>(4, 2, 2);
  const std::vector<Vec3> X = nodes_and_random_points(mesh, Vec3(4, 2, 2), 200, 13);
  EmbeddedPoints<Hex8> points(mesh, X);
  const Material m{3000, 0.45, 1.0};
  // (a) Every node moved by 1e-9 along x: the same sizes and numbering.
  Eigen::Matrix3Xd moved_nodes = mesh.nodes();
  moved_nodes.row(0).array() += 1e-9;
  const Mesh<Hex8> moved(moved_nodes, mesh.elements());
  // (b) The same nodes, each element's node list rotated about its z axis (still positively
  // oriented): the same geometry, other node ids at each local position.
  std::vector<Mesh<Hex8>::Connectivity> rotated = mesh.elements();
  for (auto& c : rotated) c = {c[1], c[2], c[3], c[0], c[5], c[6], c[7], c[4]};
  const Mesh<Hex8> permuted(mesh.nodes(), rotated);
  Eigen::Matrix3Xd x;
  for (const Mesh<Hex8>* other : {&moved, &permuted}) {
    INFO((other == &moved ? "moved coordinates" : "permuted element node order"));
    Solver<Hex8, Corotational> s(*other, m);
    CHECK_THROWS_AS(points.check_mesh(s), InvalidArgument);
    CHECK_THROWS_AS(points.positions(s, x), InvalidArgument);
    std::vector<Mat3> sigma;
    CHECK_THROWS_AS(points.stresses(s, sigma), InvalidArgument);
  }
  // A solver on an identical mesh (built again, not the same object) takes them.
  Solver<Hex8, Corotational> same(bar_mesh<Hex8>(4, 2, 2), m);
  CHECK_NOTHROW(points.check_mesh(same));
  points.positions(same, x);
  Eigen::Matrix3Xd rest;
  points.rest_positions(rest);
  CHECK(x == rest);  // no displacement yet
  // Points located from given locations are checked the same way.
  std::vector<PointLocation> where;
  for (Index k = 0; k < points.size(); ++k) where.push_back({points.element(k), points.xi(k)});
  const EmbeddedPoints<Hex8> given(mesh, where, std::vector<signed char>(where.size(), -1));
  CHECK_NOTHROW(given.check_mesh(same));
  CHECK_THROWS_AS(given.check_mesh(Solver<Hex8, Corotational>(permuted, m)), InvalidArgument);
}
