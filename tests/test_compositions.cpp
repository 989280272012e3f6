// Every composition of the one list (solver/instantiations.hpp), run through the invariants any
// Solver must keep, so that a new element or model added to the list is tested here at once:
//  - the mass is density x volume;
//  - statics under gravity: the reactions at the clamp carry the weight;
//  - a step from that equilibrium stays there (Newmark started from equilibrium);
//  - with a plastic policy: flow under a low yield stress moves the material mesh, whose mean
//    change over the clamp is zero (the clamp anchors it), and the state stays finite;
//  - with an enrichment (with or without plasticity): after a cut across the bar, the piece
//    beyond it falls freely, its centre of mass at g t^2 / 2.
// Built against plastifem::compiled, each composition is linked from the library (the list's
// own instantiations), so this file compiles only its own code.
#include "catch.hpp"
#include "compositions.hpp"
#include "free_piece.hpp"

#include <plastifem/cutting.hpp>
#include <plastifem/plasticity.hpp>

#include <fmt/core.h>

#include <cmath>
#include <tuple>

using namespace plastifem;
using namespace plastifem::testing;

namespace {

#define PLASTIFEM_TEST_ELASTIC(E, M) , Solver<E, M>
#define PLASTIFEM_TEST_PLASTIC(E, M, P) , Solver<E, M, P>
#define PLASTIFEM_TEST_ENRICHED(E, M, X) , Solver<E, M, NoPlasticity, X>
#define PLASTIFEM_TEST_PLASTIC_ENRICHED(E, M, P, X) , Solver<E, M, P, X>
using ElasticSolvers = DropFirst<std::tuple<void PLASTIFEM_ELASTIC_SOLVERS(PLASTIFEM_TEST_ELASTIC)>>;
using PlasticSolvers = DropFirst<std::tuple<void PLASTIFEM_PLASTIC_SOLVERS(PLASTIFEM_TEST_PLASTIC)>>;
using EnrichedSolvers = DropFirst<std::tuple<void PLASTIFEM_ENRICHED_SOLVERS(PLASTIFEM_TEST_ENRICHED)
                                                  PLASTIFEM_PLASTIC_ENRICHED_SOLVERS(PLASTIFEM_TEST_PLASTIC_ENRICHED)>>;

const Material soft{3000, 0.45, 1.0};  // SCENES.md bar material
const Vec3 g(0, 0, -9.81);

template <class S>
std::string name_of() {
  return fmt::format("{} {} {} {}", S::Element::name, S::ElasticModel::name, S::PlasticPolicy::name,
                     S::EnrichmentPolicy::name);
}

/// A 3 x 1 x 1 bar of the solver's element, clamped at x = 0.
template <class S>
Mesh<typename S::Element> bar() {
  return bar_mesh<typename S::Element>(3, 1, 1);
}

}  // namespace

TEMPLATE_LIST_TEST_CASE("every elastic composition: mass, reactions, equilibrium kept by Newmark", "[compositions]",
                        ElasticSolvers) {
  using S = TestType;
  const auto mesh = bar<S>();
  S solver(mesh, soft);
  INFO(name_of<S>());
  // The mass matrix integrates the density exactly (mass_degree): rho V = 3 to round-off.
  CHECK(std::abs(solver.mass() - 3.0) < 1e-12);
  solver.fix(mesh.node_set("xmin"));
  solver.add_gravity(g);
  const StepReport st = solver.solve_static();
  REQUIRE(st.relative_residual <= 1e-6);  // converged (a linear model in its one verified solve)
  const Vector reactions = solver.reaction_forces();
  Scalar rz = 0;
  for (Index i = 0; i < mesh.num_nodes(); ++i) rz += reactions[3 * i + 2];
  // The reactions balance the weight to the static tolerance (1e-8 of the load, direct solve).
  CHECK(std::abs(rz - 3.0 * 9.81) < 1e-7 * 3.0 * 9.81);
  const Vector u_static = solver.displacement();
  for (int k = 0; k < 10; ++k) REQUIRE(solver.step(0.01).substeps == 1);
  // Started from equilibrium (a_0 = 0 there), Newmark stays at it: what moves is the step's
  // residual tolerance (1e-6 of the force scale) acting on the stiffness: ~1e-6 of u.
  CHECK((solver.displacement() - u_static).norm() < 1e-5 * u_static.norm());
}

TEMPLATE_LIST_TEST_CASE("every plastic composition: flow moves the material mesh, anchored at the clamp", "[compositions]",
                        PlasticSolvers) {
  using S = TestType;
  const auto mesh = bar<S>();
  PlasticParams p;
  p.yield_stress = 10;  // gravity bends the bar to ~250 at the clamp: it flows there
  p.flow_rate = 1;
  S solver(mesh, soft, SolverSettings{}, p);
  INFO(name_of<S>());
  solver.fix(mesh.node_set("xmin"));
  solver.add_gravity(g);
  int flowed = 0;
  for (int k = 0; k < 20; ++k) {
    const StepReport r = solver.step(0.01);
    REQUIRE(r.substeps == 1);
    flowed += r.plastic.points_yielded;
  }
  const Eigen::Matrix3Xd X = solver.material_positions();
  REQUIRE(X.allFinite());
  REQUIRE(solver.displacement().allFinite());
  CHECK(flowed > 0);
  const Scalar moved = (X - mesh.nodes()).cwiseAbs().maxCoeff();
  CHECK(moved > 1e-8);
  // The clamp anchors the material mesh (plastic/fusion.hpp): the mean change over its nodes is
  // zero, to the round-off of the fusion's solve (~1e-15 of the change).
  Vec3 mean = Vec3::Zero();
  for (Index i : mesh.node_set("xmin")) mean += X.col(i) - mesh.nodes().col(i);
  mean /= static_cast<Scalar>(mesh.node_set("xmin").size());
  CHECK(mean.norm() <= 1e-10 * moved);
}

TEMPLATE_LIST_TEST_CASE("every cut composition: the piece beyond a cut falls freely", "[compositions]",
                        EnrichedSolvers) {
  using S = TestType;
  const auto mesh = bar<S>();
  SolverSettings settings;
  // The formulation, not the solver tolerance, is under test (as test_dynamics' free fall).
  settings.newton.residual_tolerance = 1e-10;
  settings.linear.tolerance = 1e-12;
  S solver(mesh, soft, settings);
  INFO(name_of<S>());
  solver.fix(mesh.node_set("xmin"));
  solver.add_gravity(g);
  solver.cut(CutPlane(Vec3(1.5, 0.5, 0.5), Vec3(1, 0, 0)));
  const auto [volume, z0] = free_piece_centre(solver, 1.5);
  CHECK(std::abs(volume - 1.5) < 1e-12);  // the piece's mass points integrate its volume exactly
  for (int k = 0; k < 10; ++k) REQUIRE(solver.step(0.01).substeps == 1);
  const Scalar z1 = free_piece_centre(solver, 1.5).second;
  const Scalar t = solver.time(), expected = -0.5 * 9.81 * t * t;
  // Nothing holds the piece: M 1 g = f_ext on it and Newmark integrates a constant acceleration
  // exactly, so the centre falls at g to the step's tolerance: 1e-10 of a force of order 1,
  // amplified by 1 / (beta dt^2) per step, 1e-6 relative (as test_enrichment's free fall).
  CHECK(std::abs((z1 - z0) - expected) < 1e-6 * std::abs(expected));
}
