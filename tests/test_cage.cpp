// The cage around a closed surface (embedding/cage.hpp).
//
// Facts checked:
//  - a box whose faces lie inside cells in z and on the grid in x and y: every cell's fraction is
//    exact (the inside along each vertical line is exact), 0.6 in the partial layers, 1 inside;
//  - the cage of a sphere represents the enclosed volume, sum fraction x cell volume, within the
//    line sampling's error, which falls under refinement; deep cells have fraction 1; Tet4 and
//    Tet10 cages have the Hex8 cage's inside volume to round-off;
//  - every vertex of the surface lies in the cage (it embeds), for every element;
//  - open or inward-facing surfaces and bad cell sizes are refused.
#include "catch.hpp"

#include <plastifem/cutting.hpp>
#include <plastifem/embedding/cage.hpp>
#include <plastifem/embedding/embedded_points.hpp>
#include <plastifem/plastifem.hpp>

#include <numbers>

using namespace plastifem;

namespace {

/// The box [lo, hi] as 12 outward triangles.
TriangleSurface box_surface(const Vec3& lo, const Vec3& hi) {
  TriangleSurface b;
  b.vertices.resize(3, 8);
  for (int i = 0; i < 8; ++i) b.vertices.col(i) = Vec3(i & 1 ? hi.x() : lo.x(), i & 2 ? hi.y() : lo.y(), i & 4 ? hi.z() : lo.z());
  b.triangles = {{0, 2, 1}, {1, 2, 3}, {4, 5, 6}, {5, 7, 6}, {0, 1, 4}, {1, 5, 4},
                 {2, 6, 3}, {3, 6, 7}, {0, 4, 2}, {2, 4, 6}, {1, 3, 5}, {3, 7, 5}};
  return b;
}

}  // namespace

TEST_CASE("cage: exact fractions of a box cut by cell layers", "[cage]") {
  // [0, 1] x [0, 1] x [0.1, 0.9] with cells of 0.25: the grid is centred on the box, so x and y
  // fill 4 cells each and z spans 4 layers [0, 0.25] ... [0.75, 1] with 0.15 / 0.25 = 0.6 of the
  // end layers inside.
  const Cage<Hex8> cage = cage_around<Hex8>(box_surface(Vec3(0, 0, 0.1), Vec3(1, 1, 0.9)), 0.25);
  CHECK(cage.cells == std::array<int, 3>{4, 4, 4});
  CHECK(cage.mesh.num_elements() == 64);
  Scalar worst = 0;
  for (size_t e = 0; e < cage.fraction.size(); ++e) {
    const int k = cage.cell[e][2];
    worst = std::max(worst, std::abs(cage.fraction[e] - (k == 0 || k == 3 ? 0.6 : 1.0)));
  }
  INFO("largest fraction error " << worst);
  CHECK(worst < 1e-14);
  CHECK(std::abs(cage.inside_volume() - 0.8) < 1e-14);
}

TEMPLATE_TEST_CASE("cage: a sphere's volume under refinement, every vertex embedded", "[cage]", Hex8, Tet4, Tet10) {
  using E = TestType;
  const TriangleSurface sphere = sphere_surface(Vec3(0.3, -0.2, 0.1), 1.0, 4);
  const Scalar V = enclosed_volume(sphere, sphere.vertices);
  std::vector<Scalar> errors;
  for (const Scalar h : {0.5, 0.25, 0.125}) {
    const Cage<E> cage = cage_around<E>(sphere, h);
    const Scalar error = std::abs(cage.inside_volume() - V) / V;
    const Scalar added = (cage.weighted_volume() - cage.inside_volume()) / V;
    INFO("h = " << h << ": " << cage.mesh.num_elements() << " elements, volume error " << error
                << ", the floor weight adds " << added);
    // The midpoint rule over 8 x 8 lines per cell: O((h / 8)^2) times the surface's curvature.
    CHECK(error < 0.005);
    errors.push_back(error);
    CHECK(added >= 0);
    CHECK(added < 0.01);
    // The cell at the centre is wholly inside.
    Scalar largest = 0;
    for (Scalar f : cage.fraction) largest = std::max(largest, f);
    CHECK(largest == 1.0);
    if (h == 0.25) {
      const Cage<Hex8> hex = cage_around<Hex8>(sphere, h);
      CHECK(std::abs(cage.inside_volume() - hex.inside_volume()) < 1e-12 * V);
      CHECK_NOTHROW(EmbeddedPoints<E>(cage.mesh, sphere.vertices));  // every vertex in an element
    }
  }
  CHECK(errors.back() < errors.front() / 2);  // converging (not monotonically: cancellation)
}

TEST_CASE("cage: open or inward surfaces and bad cell sizes are refused", "[cage]") {
  TriangleSurface box = box_surface(Vec3::Zero(), Vec3::Ones());
  CHECK_THROWS_AS(cage_around<Hex8>(box, 0), InvalidArgument);
  CHECK_THROWS_AS(cage_around<Hex8>(box, std::numeric_limits<Scalar>::quiet_NaN()), InvalidArgument);
  CHECK_THROWS_AS(cage_around<Hex8>(box, 1e-6), InvalidArgument);  // 1e6 cells a side
  // 1667 cells a side passes the per-axis bound, but 4.6e9 cells would take 37 GB: refused with
  // a message, not a bad_alloc (found by review, 2026-11-30).
  try {
    cage_around<Hex8>(box, 1.0 / 1667);
    FAIL("accepted 4.6e9 cells");
  } catch (const InvalidArgument& e) {
    CHECK(std::string(e.what()).find("at most 1e8") != std::string::npos);
  }
  TriangleSurface open = box;
  open.triangles.pop_back();
  CHECK_THROWS_AS(cage_around<Hex8>(open, 0.25), InvalidArgument);
  TriangleSurface inward = box;
  for (Triangle& t : inward.triangles) std::swap(t[1], t[2]);
  CHECK_THROWS_AS(cage_around<Hex8>(inward, 0.25), InvalidArgument);
}

// ---- element weights (Mesh::set_element_weights) ---------------------------------------------

namespace {

template <FiniteElement E>
Mesh<E> weighted(Mesh<E> mesh, Scalar w) {
  mesh.set_element_weights(std::vector<Scalar>(static_cast<size_t>(mesh.num_elements()), w));
  return mesh;
}

Scalar relative(const Vector& a, const Vector& b) { return (a - b).norm() / b.norm(); }

}  // namespace

TEMPLATE_TEST_CASE("element weights: a uniform weight scales mass, load and stiffness alike, so gravity's "
                   "statics and dynamics do not change",
                   "[cage][weights]", Hex8, Tet4) {
  using E = TestType;
  // M, f_int, K and rho g all carry the factor w, so the equations of motion are the unweighted
  // ones times w: the same u(t). w = 0.37 is not a power of two, so the factor is not exact in
  // floating point; the tolerances are the Newton and CG tolerances' (1e-10, 1e-8) reach.
  const Mesh<E> mesh = bar_mesh<E>(4, 1, 1);
  const Material soft{3000, 0.3, 1.0};
  for (const MassKind mass : {MassKind::Consistent, MassKind::Lumped}) {
    SolverSettings s;
    s.mass = mass;
    s.newton.residual_tolerance = 1e-10;
    Solver<E, Corotational> plain(mesh, soft, s), scaled(weighted(mesh, 0.37), soft, s);
    for (auto* solver : {&plain, &scaled}) {
      solver->fix(mesh.node_set("xmin"));
      solver->add_gravity(Vec3(0, 0, -9.81));
    }
    CHECK(std::abs(scaled.mass() - 0.37 * plain.mass()) < 1e-13 * plain.mass());
    for (int k = 0; k < 10; ++k) plain.step(0.01), scaled.step(0.01);
    INFO((mass == MassKind::Lumped ? "lumped" : "consistent") << ": after 10 steps u differs by "
                                                                << relative(scaled.displacement(), plain.displacement()));
    CHECK(relative(scaled.displacement(), plain.displacement()) < 1e-7);
    CHECK(relative(scaled.velocity(), plain.velocity()) < 1e-6);
    CHECK(std::abs(scaled.strain_energy() - 0.37 * plain.strain_energy()) < 1e-6 * plain.strain_energy());
    CHECK(std::abs(scaled.kinetic_energy() - 0.37 * plain.kinetic_energy()) < 1e-6 * plain.kinetic_energy());
    plain.solve_static(2), scaled.solve_static(2);
    CHECK(relative(scaled.displacement(), plain.displacement()) < 1e-9);
  }
}

TEST_CASE("element weights: a bar of two weighted halves stretches as two springs in series", "[cage][weights]") {
  // Linear elasticity, Poisson 0, symmetry planes at x, y, z = 0 and an axial end load F: the
  // stress is uniform and each half a spring of stiffness w E A / L_half, so the end moves
  // F L1 / (w1 E A) + F L2 / (w2 E A) (Hex8 reproduces the uniform state exactly). A point load
  // on a uniformly weighted bar moves by 1 / w times the unweighted one.
  const Mesh<Hex8> bar = bar_mesh<Hex8>(4, 1, 1);
  const Material steel_like{1000, 0.0, 1.0};
  const Scalar F = 2.0, w1 = 0.25, w2 = 0.8;
  Mesh<Hex8> halves = bar;
  std::vector<Scalar> w;
  for (Index e = 0; e < bar.num_elements(); ++e) w.push_back(bar.element_nodes(e).row(0).mean() < 2 ? w1 : w2);
  halves.set_element_weights(w);
  Solver<Hex8, Linear> s(halves, steel_like);
  s.fix(bar.node_set("xmin"), {true, false, false});
  s.fix(bar.node_set("ymin"), {false, true, false});
  s.fix(bar.node_set("zmin"), {false, false, true});
  s.add_nodal_force(bar.node_set("xmax"), Vec3(F / 4, 0, 0));
  s.solve_static();
  const Scalar expected = F * 2 / (w1 * 1000) + F * 2 / (w2 * 1000);
  Scalar worst = 0;
  for (Index n : bar.node_set("xmax")) worst = std::max(worst, std::abs(s.displacement(n).x() - expected) / expected);
  INFO("end displacement relative error " << worst);
  CHECK(worst < 1e-10);

  auto tip_under_point_load = [&](Scalar uniform) {
    Solver<Hex8, Linear> p(weighted(bar, uniform), Material{1000, 0.3, 1.0});
    p.fix(bar.node_set("xmin"));
    p.add_point_force(Vec3(4, 0.5, 0.5), Vec3(0, 0, -1));
    p.solve_static();
    return p.displacement(bar.node_set("xmax")[0]).z();
  };
  const Scalar unweighted = tip_under_point_load(1.0);
  CHECK(std::abs(tip_under_point_load(0.4) * 0.4 - unweighted) < 1e-10 * std::abs(unweighted));
}

TEMPLATE_TEST_CASE("element weights: a cut body falls and bends as the unweighted one (enriched mass, body force "
                   "and pieces weighted)",
                   "[cage][weights][enrichment]", Heaviside, ShiftedHeaviside) {
  const Mesh<Hex8> mesh = bar_mesh<Hex8>(4, 1, 1);
  const Material soft{3000, 0.3, 1.0};
  Solver<Hex8, Corotational, NoPlasticity, TestType> plain(mesh, soft), scaled(weighted(mesh, 0.37), soft);
  for (auto* solver : {&plain, &scaled}) {
    solver->fix(mesh.node_set("xmin"));
    solver->add_gravity(Vec3(0, 0, -9.81));
    solver->cut(CutPlane(Vec3(2.3, 0, 0), Vec3(1, 0.2, 0)));
  }
  CHECK(std::abs(scaled.mass() - 0.37 * plain.mass()) < 1e-13 * plain.mass());
  for (int k = 0; k < 10; ++k) plain.step(0.01), scaled.step(0.01);
  INFO("after 10 steps u differs by " << relative(scaled.displacement(), plain.displacement()));
  CHECK(relative(scaled.displacement(), plain.displacement()) < 1e-7);
  CHECK(std::abs(scaled.strain_energy() - 0.37 * plain.strain_energy()) < 1e-6 * plain.strain_energy());
}

TEMPLATE_TEST_CASE("cage: the solver's mass is density times the weighted volume", "[cage][weights]", Hex8, Tet4,
                   Tet10) {
  using E = TestType;
  const Cage<E> cage = cage_around<E>(sphere_surface(Vec3::Zero(), 1.0, 3), 0.3);
  REQUIRE(cage.mesh.weighted());
  for (Index e = 0; e < cage.mesh.num_elements(); ++e) REQUIRE(cage.mesh.weight(e) == cage.weight(e));
  for (const MassKind kind : {MassKind::Consistent, MassKind::Lumped}) {
    SolverSettings s;
    s.mass = kind;
    const Solver<E, Corotational> solver(cage.mesh, Material{3000, 0.45, 1070}, s);
    INFO("mass " << solver.mass() << " against " << 1070 * cage.weighted_volume());
    CHECK(std::abs(solver.mass() - 1070 * cage.weighted_volume()) < 1e-12 * solver.mass());
  }
  std::vector<Scalar> bad(static_cast<size_t>(cage.mesh.num_elements()), 1.0);
  Mesh<E> m = cage.mesh;
  CHECK_THROWS_AS(m.set_element_weights(std::vector<Scalar>(3, 1.0)), MeshError);
  bad[1] = 0;
  CHECK_THROWS_AS(m.set_element_weights(bad), MeshError);
  bad[1] = std::numeric_limits<Scalar>::quiet_NaN();
  CHECK_THROWS_AS(m.set_element_weights(bad), MeshError);
}
