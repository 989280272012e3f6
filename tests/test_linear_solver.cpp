// The linear solvers on their own: the direct back-ends (Eigen's SimplicialLDLT, CHOLMOD's
// supernodal LL^T where the build has it) and CG solve the same Newmark and static systems,
// reject singular and indefinite matrices with a SolverError, and a back-end the build lacks is
// refused with an InvalidArgument that says how to get it.
#include "catch.hpp"

#include <plastifem/plastifem.hpp>

#include <string>

using namespace plastifem;

namespace {

const Material soft{3000.0, 0.45, 1.0};  // SCENES.md bar material

/// Stiffness K0 and consistent mass M of a Hex8 box, assembled into the toolkit's block storage.
struct Matrices {
  BlockSymmetricMatrix K, M;
};
Matrices assemble_linear(const Mesh<Hex8>& mesh) {
  Assembler<Hex8> assembler(mesh);
  Matrices m{assembler.zero_matrix(), assembler.zero_matrix()};
  for (Index e = 0; e < mesh.num_elements(); ++e) {
    const ElementNodes<Hex8> X = mesh.element_nodes(e);
    ElementVector<Hex8> f;
    ElementMatrix<Hex8> Ke;
    Linear::evaluate<Hex8>(Linear::prepare<Hex8>(X, soft), X, f, &Ke);
    assembler.add_element_matrix(e, Ke, m.K.values());
  }
  assemble_mass(mesh, assembler, soft.density, MassKind::Consistent, m.M);
  return m;
}

/// A = a M + k K, with the rows and columns of the nodes at x = 0 replaced by identity.
BlockSymmetricMatrix combine(const Matrices& m, Scalar a, Scalar k, const std::vector<Index>& fixed) {
  BlockSymmetricMatrix A = m.K;
  for (Index i = 0; i < A.num_values(); ++i) A.values()[i] = a * m.M.values()[i] + k * m.K.values()[i];
  std::vector<char> c(A.rows() / 3, 0);
  for (Index n : fixed) c[n] = 1;
  const auto& p = A.pattern();
  for (Index I = 0; I < p.num_block_rows; ++I)
    for (int b = p.row_start[I]; b < p.row_start[I + 1]; ++b) {
      const Index J = p.column[b];
      if (!c[I] && !c[J]) continue;
      Scalar* B = A.values() + 9 * static_cast<size_t>(b);
      for (int i = 0; i < 9; ++i) B[i] = (I == J && i % 4 == 0) ? 1.0 : 0.0;
    }
  return A;
}

std::vector<DirectSolver> built_in_direct_solvers() {
  std::vector<DirectSolver> d{DirectSolver::SimplicialLDLT};
  if (cholmod_available()) d.push_back(DirectSolver::CholmodSupernodal);
  return d;
}

}  // namespace

TEST_CASE("direct back-ends and CG solve the same Newmark and static systems", "[linear][direct]") {
  const auto mesh = bar_mesh<Hex8>(10, 3, 3);  // bar90
  const Matrices m = assemble_linear(mesh);
  const auto fixed = mesh.node_set("xmin");
  const Scalar dt = 0.01, c0 = 1 / (0.25 * dt * dt);
  // The Newmark matrix (mass-dominated, well conditioned) and the static stiffness (condition
  // number ~1e5 on bar90: long, clamped at one end).
  for (const auto& [a, k, what] : {std::tuple{c0, 1.0, "Newmark"}, std::tuple{0.0, 1.0, "static"}}) {
    CAPTURE(what);
    const BlockSymmetricMatrix A = combine(m, a, k, fixed);
    Vector b = Vector::Random(A.rows());
    for (Index n : fixed) b.segment<3>(3 * n).setZero();
    // Reference: CG to 1e-14 relative residual.
    Vector x_cg = Vector::Zero(A.rows());
    LinearSolver cg({LinearSolverKind::ConjugateGradient, 1e-14, 100000});
    REQUIRE(cg.solve(A, b, x_cg).converged);
    for (DirectSolver d : built_in_direct_solvers()) {
      CAPTURE(static_cast<int>(d));
      LinearSolver direct({LinearSolverKind::Direct, 0, 1, d});
      Vector x = Vector::Zero(A.rows());
      REQUIRE(direct.solve(A, b, x).iterations == 1);  // one factorisation
      Vector Ax(A.rows());
      A.multiply(x, Ax);
      // A backward-stable factorisation leaves a residual of a few n eps |A| |x|; 1e-11
      // relative is far above that (n = 528) and far below anything a wrong solve gives.
      CHECK((Ax - b).norm() <= 1e-11 * b.norm());
      // Forward error <= cond(A) x residual: ~1e5 x 1e-14 for the static matrix.
      CHECK((x - x_cg).norm() <= 1e-8 * x_cg.norm());
      // Same matrix again: the numeric factorisation is reused (no new factorisation).
      Vector x2 = Vector::Zero(A.rows());
      REQUIRE(direct.solve(A, b, x2, 0, true).iterations == 0);
      CHECK(x2 == x);
    }
  }
}

TEST_CASE("direct back-ends reject singular and indefinite matrices", "[linear][direct][errors]") {
  const auto mesh = bar_mesh<Hex8>(4, 2, 2);
  const Matrices m = assemble_linear(mesh);
  Vector b = Vector::Ones(m.K.rows());
  for (DirectSolver d : built_in_direct_solvers()) {
    CAPTURE(static_cast<int>(d));
    // No constrained node: the six rigid-body modes make K0 singular.
    LinearSolver s1({LinearSolverKind::Direct, 0, 1, d});
    Vector x = Vector::Zero(b.size());
    const BlockSymmetricMatrix K = combine(m, 0, 1, {});
    try {
      s1.solve(K, b, x);
      FAIL("a singular matrix was factorised");
    } catch (const SolverError& e) {
      CHECK(std::string(e.what()).find("singular or indefinite") != std::string::npos);
    }
    // K - 1e4 M (clamped): indefinite, the shape of an exact tangent under compression.
    LinearSolver s2({LinearSolverKind::Direct, 0, 1, d});
    const BlockSymmetricMatrix A = combine(m, -1e4, 1, mesh.node_set("xmin"));
    CHECK_THROWS_AS(s2.solve(A, b, x), SolverError);
  }
}

TEST_CASE("static solves agree between direct back-ends - a back-end the build lacks is refused",
          "[linear][direct][statics]") {
  const auto mesh = bar_mesh<Hex8>(10, 3, 3);
  Index tip = 0;
  for (Index i : mesh.node_set("xmax"))
    if (mesh.node(i).y() == 3 && mesh.node(i).z() == 3) tip = i;
  auto solve = [&](DirectSolver d) {
    SolverSettings st;
    st.static_linear = {LinearSolverKind::Direct, 0, 1, d};
    Solver<Hex8, NeoHookean> s(mesh, soft, st);
    s.fix(mesh.node_set("xmin"));
    s.add_gravity(Vec3(0, 0, -9.81));
    const StepReport r = s.solve_static();
    CHECK(r.relative_residual <= 1e-6);
    return s.displacement(tip);
  };
  const Vec3 ldlt = solve(DirectSolver::SimplicialLDLT);
  CHECK(ldlt.z() < -1);  // the bar sags by several units under 1 g (Linear: 4.6)
  if (cholmod_available()) {
    CHECK(resolve_direct_solver(DirectSolver::Auto) == DirectSolver::CholmodSupernodal);
    // Both take the same Newton path; each solve differs only by round-off amplified by the
    // condition number (~1e5 x 1e-16), so 1e-8 relative is a safe bound and a wrong solve
    // (or a different number of Newton steps, each changing u by > 1e-6) breaks it.
    const Vec3 chol = solve(DirectSolver::CholmodSupernodal);
    CHECK((chol - ldlt).norm() <= 1e-8 * ldlt.norm());
  } else {
    CHECK(resolve_direct_solver(DirectSolver::Auto) == DirectSolver::SimplicialLDLT);
    try {
      solve(DirectSolver::CholmodSupernodal);
      FAIL("CHOLMOD was accepted by a build without it");
    } catch (const InvalidArgument& e) {
      CHECK(std::string(e.what()).find("PLASTIFEM_WITH_CHOLMOD") != std::string::npos);
    }
  }
}
