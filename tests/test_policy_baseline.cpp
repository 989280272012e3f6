// The policy-overhead benchmark (bench/bench_policy_overhead.cpp) compares
// Solver<E, Model, NoPlasticity, NoEnrichment> with BareNewmark, the same real-time step
// composed without policy parameters. Its ratio means something only while both compute the
// same thing: this test holds them to bit-for-bit equal displacements after a few steps, so a
// change to the Solver's step that the baseline does not follow fails here, in CI, rather
// than in a benchmark nobody runs.
#include "catch.hpp"

#include "../bench/bare_newmark.hpp"

using namespace plastifem;

TEMPLATE_TEST_CASE("the policy-free baseline reproduces the Solver's real-time step bit for bit", "[policy][bench]",
                   CorotationalPerElement, Corotational) {
  const Material material{3000, 0.45, 1.0};
  const LinearSolverSettings cg{LinearSolverKind::ConjugateGradient, 1e-6, 1000};
  auto check = [&]<class E>(const Mesh<E>& mesh, int threads) {
    SolverSettings st;
    st.threads = threads;
    st.linear = cg;
    st.newmark.mode = NewmarkMode::RealTime;
    Solver<E, TestType, NoPlasticity, NoEnrichment> solver(mesh, material, st);
    solver.fix(mesh.node_set("xmin"));
    solver.add_gravity(Vec3(0, 0, -9.81));
    bench::BareNewmark<E, TestType> bare(mesh, material, mesh.node_set("xmin"), Vec3(0, 0, -9.81), cg, threads);
    for (int k = 0; k < 10; ++k) {
      solver.step(0.01);
      bare.step(0.01);
    }
    CHECK(solver.displacement().cwiseAbs().maxCoeff() > 1e-3);  // the bar moved
    CHECK((solver.displacement() - bare.displacement()).cwiseAbs().maxCoeff() == 0);
  };
  check(bar_mesh<Hex8>(10, 3, 3), 1);
  check(bar_mesh<Tet4>(10, 3, 3), 1);
#ifdef _OPENMP
  // bar720 on two threads: above the size from which matrix-vector products are threaded (and
  // round differently from one thread), so every solve of both must run on the same threads
  // (the baseline's initial-acceleration CG once ran on one).
  check(bar_mesh<Hex8>(20, 6, 6), 2);
#endif
}
