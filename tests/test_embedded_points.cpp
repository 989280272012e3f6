// Points embedded in a body (enrichment/embedded_points.hpp).
//
// Facts checked:
//  - isoparametric elements reproduce a linear field exactly: u = A X + b interpolated at random
//    points equals A X + b (round-off), on every element;
//  - at a node the field is the node's value;
//  - a cut bar whose free half falls: points on the free side move by the closed-form damped
//    free fall, points on the clamped side by the clamped half's own field, whichever element
//    (cut or not) they are in.
#include "catch.hpp"

#include <plastifem/cutting.hpp>
#include <plastifem/enrichment/embedded_points.hpp>
#include <plastifem/plastifem.hpp>

#include <random>

using namespace plastifem;

TEMPLATE_TEST_CASE("embedded points: a linear field is reproduced, nodes give their values", "[points]", Tet4, Tet10,
                   Hex8) {
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
    points.interpolate(s.displacement(), at, &s.enrichment());
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
