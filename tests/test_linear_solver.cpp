// The linear solvers on their own: the direct back-ends (Eigen's SimplicialLDLT, CHOLMOD's
// supernodal LL^T where the build has it) and CG solve the same Newmark and static systems,
// reject singular and indefinite matrices with a SolverError, and a back-end the build lacks is
// refused with an InvalidArgument that says how to get it. CG's preconditioners: X-FEM's
// coupled rows, and the node blocks (CgPreconditioner::BlockJacobi) on their own and in every
// mode of a solver; the vector passes by chunks, the same bits on any number of threads.
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

TEST_CASE("CG with coupled rows: each group's diagonal block is inverted, the answer does not change",
          "[linear][cg]") {
  // A dense SPD system in block storage (every block stored): 6 block rows, rows 4 and 5
  // "enriched" copies of rows 1 and 2 (columns nearly parallel: [K, K; K, K + eps I], as
  // Heaviside enrichment makes them).
  auto block_matrix = [](const Eigen::MatrixXd& dense) {
    const Index nb = dense.rows() / 3;
    std::vector<std::vector<Index>> lower(nb);
    for (Index I = 0; I < nb; ++I)
      for (Index J = 0; J <= I; ++J) lower[I].push_back(J);
    BlockSymmetricMatrix A(BlockPattern::from_lower_neighbours(lower));
    const auto& p = A.pattern();
    for (Index I = 0; I < nb; ++I)
      for (int k = p.row_start[I]; k < p.row_start[I + 1]; ++k)
        for (int i = 0; i < 3; ++i)
          for (int j = 0; j < 3; ++j) A.values()[9 * k + 3 * i + j] = dense(3 * I + i, 3 * p.column[k] + j);
    return A;
  };
  constexpr int n = 18;
  std::srand(5);
  const Eigen::MatrixXd B = Eigen::MatrixXd::Random(n, n);
  Eigen::MatrixXd dense = B * B.transpose() / n + Eigen::MatrixXd::Identity(n, n);
  for (int i = 0; i < 3; ++i)
    for (int pair = 1; pair <= 2; ++pair) {  // row 3 + pair mirrors row pair, plus 1e-3
      const int u = 3 * pair + i, a = 3 * (pair + 3) + i;
      dense.row(a) = dense.row(u);
      dense.col(a) = dense.col(u);
      dense(a, a) = dense(u, u) + 1e-3;
    }
  REQUIRE(Eigen::LLT<Eigen::MatrixXd>(dense).info() == Eigen::Success);
  const BlockSymmetricMatrix A = block_matrix(dense);
  const Vector b = Vector::LinSpaced(n, -1, 2);
  const Vector exact = dense.llt().solve(b);
  const LinearSolverSettings st{LinearSolverKind::ConjugateGradient, 1e-12, 500};
  auto solve = [&](const BlockSymmetricMatrix& M, const Vector& rhs, std::vector<std::vector<Index>> groups,
                   int& iterations) {
    LinearSolver s(st);
    s.set_coupled_rows(std::move(groups));
    Vector x = Vector::Zero(rhs.size());
    const LinearSolveReport r = s.solve(M, rhs, x);
    REQUIRE(r.converged);
    iterations = r.iterations;
    return x;
  };
  int jacobi = 0, paired = 0, too_big = 0;
  const Vector x0 = solve(A, b, {}, jacobi), x1 = solve(A, b, {{1, 4}, {2, 5}}, paired);
  // Either way the system's solution (CG to 1e-12, condition ~1e5: 1e-6 bounds the error).
  CHECK((x0 - exact).norm() <= 1e-6 * exact.norm());
  CHECK((x1 - exact).norm() <= 1e-6 * exact.norm());
  // The pairs take the near-parallel columns out of the spectrum CG sees.
  INFO("CG iterations: Jacobi " << jacobi << ", node pairs " << paired);
  CHECK(paired < jacobi);
  // A group of more than 4 rows keeps Jacobi: the same iterates, bit for bit.
  const Vector x3 = solve(A, b, {{0, 1, 2, 3, 4, 5}}, too_big);
  CHECK(too_big == jacobi);
  CHECK(x3 == x0);
  // One group holding a whole 4-row system: the preconditioner is its inverse, one iteration.
  const Eigen::MatrixXd small = dense.topLeftCorner(12, 12);
  int one = 0;
  const Vector y = solve(block_matrix(small), b.head(12), {{0, 1, 2, 3}}, one);
  CHECK(one == 1);
  CHECK((y - small.llt().solve(b.head(12))).norm() <= 1e-10 * y.norm());
}

TEST_CASE("CG with node blocks: the same solution, iterations a rotation of the mesh does not change",
          "[linear][cg]") {
  // CgPreconditioner::BlockJacobi inverts each node's 3 x 3 diagonal block. Turning the mesh
  // by a rotation Q turns A into Q A Q^T node by node and its block-diagonal inverse with it,
  // so CG's residuals are those of the unturned system: the same iteration count (up to the
  // round-off of where the last one crosses the tolerance). Jacobi's diag(A) is not turned with
  // it. Measured (bar90 Hex8, CG to 1e-10): static 156 iterations turned or not, Jacobi 177
  // and 225 turned; Newmark (dt = 0.01, mass-dominated) 35 and 35, Jacobi 37 and 37.
  const auto mesh = bar_mesh<Hex8>(10, 3, 3);  // bar90
  const Mat3 Q = Eigen::AngleAxisd(0.7, Vec3(1, 2, 3).normalized()).toRotationMatrix();
  Mesh<Hex8>::Nodes turned_nodes(3, mesh.num_nodes());
  for (Index i = 0; i < mesh.num_nodes(); ++i) turned_nodes.col(i) = Q * mesh.node(i);
  std::vector<Mesh<Hex8>::Connectivity> elements;
  for (Index e = 0; e < mesh.num_elements(); ++e) elements.push_back(mesh.element(e));
  const Mesh<Hex8> turned(turned_nodes, elements);
  const Matrices m = assemble_linear(mesh), mt = assemble_linear(turned);
  const auto fixed = mesh.node_set("xmin");
  const Scalar dt = 0.01, c0 = 1 / (0.25 * dt * dt);
  for (const auto& [a, what] : {std::pair{c0, "Newmark"}, std::pair{0.0, "static"}}) {
    CAPTURE(what);
    const BlockSymmetricMatrix A = combine(m, a, 1.0, fixed), At = combine(mt, a, 1.0, fixed);
    Vector b = Vector::Random(A.rows());
    for (Index n : fixed) b.segment<3>(3 * n).setZero();
    Vector bt(b.size());
    for (Index i = 0; i < mesh.num_nodes(); ++i) bt.segment<3>(3 * i) = Q * b.segment<3>(3 * i);
    auto solve = [](const BlockSymmetricMatrix& M, const Vector& rhs, CgPreconditioner pc, int& iterations) {
      LinearSolverSettings st{LinearSolverKind::ConjugateGradient, 1e-10, 100000};
      st.preconditioner = pc;
      LinearSolver s(st);
      Vector x = Vector::Zero(rhs.size());
      const LinearSolveReport r = s.solve(M, rhs, x);
      REQUIRE(r.converged);
      iterations = r.iterations;
      return x;
    };
    int blocks = 0, blocks_turned = 0, jacobi = 0, jacobi_turned = 0;
    const Vector x = solve(A, b, CgPreconditioner::BlockJacobi, blocks);
    const Vector xt = solve(At, bt, CgPreconditioner::BlockJacobi, blocks_turned);
    const Vector xj = solve(A, b, CgPreconditioner::Jacobi, jacobi);
    solve(At, bt, CgPreconditioner::Jacobi, jacobi_turned);
    INFO("iterations: blocks " << blocks << ", turned " << blocks_turned << "; Jacobi " << jacobi << ", turned "
                               << jacobi_turned);
    CHECK(std::abs(blocks - blocks_turned) <= 1);
    // The static matrix, where the stiffness's coupling of x, y and z decides: well clear
    // (156 against 225). The Newmark matrix is mass-dominated: no more iterations than Jacobi.
    if (a == 0) CHECK(blocks_turned < 0.9 * jacobi_turned);
    else CHECK(blocks_turned <= jacobi_turned);
    // Both the system's solution: each CG stops at |r| <= 1e-10 |b|, so its error is at most
    // cond(A) 1e-10 (cond ~1e5 for the static matrix), and two solutions differ by at most twice
    // that; the turned solution turned back alike.
    CHECK((x - xj).norm() <= 2e-5 * xj.norm());
    Vector x_back(x.size());
    for (Index i = 0; i < mesh.num_nodes(); ++i) x_back.segment<3>(3 * i) = Q.transpose() * xt.segment<3>(3 * i);
    CHECK((x_back - x).norm() <= 2e-5 * x.norm());
  }
  SECTION("a diagonal block that is not positive definite: a SolverError that names the first") {
    // Sylvester's criterion on each node's block (its first minor, the diagonal, is CG's own
    // check before it). Two blocks broken, the later in row order by B00 B11 - B01^2 < 0, the
    // first by that minor or by det alone; the message names the first. 9,604 nodes: 10 chunks
    // of the factorisation, the two blocks in chunks 1 and 9, on different threads of 2.
    const auto big_mesh = bar_mesh<Hex8>(48, 13, 13);
    const Matrices big = assemble_linear(big_mesh);
    const Index I = big_mesh.num_nodes() - 1, J = 1500;
    for (int minor = 2; minor <= 3; ++minor) {
      CAPTURE(minor);
      BlockSymmetricMatrix A = combine(big, c0, 1.0, big_mesh.node_set("xmin"));
      const auto& p = A.pattern();
      auto block = [&](Index row) { return A.values() + 9 * static_cast<size_t>(p.row_start[row + 1] - 1); };
      Scalar* B = block(I);
      B[1] = B[3] = 2 * std::sqrt(B[0] * B[4]);  // B00 B11 - B01^2 < 0, the diagonal positive
      Scalar* C = block(J);
      if (minor == 2) C[1] = C[3] = 2 * std::sqrt(C[0] * C[4]);
      else {  // D [1 k k; k 1 -k; k -k 1], k = 3/4: minors 1 and 1 - k^2 positive, det (1 + k)^2 (1 - 2k) < 0
        const Scalar D = C[0], k = 0.75;
        const Scalar det_only[9] = {D, k * D, k * D, k * D, D, -k * D, k * D, -k * D, D};
        std::copy(det_only, det_only + 9, C);
      }
      LinearSolverSettings st{LinearSolverKind::ConjugateGradient, 1e-10, 1000};
      st.preconditioner = CgPreconditioner::BlockJacobi;
      LinearSolver s(st);
      s.set_threads(2);
      Vector x = Vector::Zero(A.rows());
      try {
        s.solve(A, Vector::Ones(A.rows()), x);
        FAIL("no SolverError");
      } catch (const SolverError& e) {
        CHECK(std::string(e.what()).find("diagonal block of block row " + std::to_string(J) + " ") !=
              std::string::npos);
      }
    }
  }
}

TEST_CASE("CG's vector passes by chunks: any thread count gives the same bits, appended zeros change nothing",
          "[linear][cg]") {
  // core/vector_ops.hpp: each chunk of vector_chunk dofs is summed as dot() sums, the chunks'
  // sums added in chunk order, whichever thread ran them. 11 chunks and a partial one: above the
  // 4 chunks per thread from which the passes run on threads.
  const Index n = 11 * vector_chunk + 3 * 41;
  const Vector p0 = Vector::Random(n), q0 = Vector::Random(n), d0 = Vector::Random(n).cwiseAbs(),
               x0 = Vector::Random(n), r0 = Vector::Random(n);
  std::vector<Scalar> blocks(3 * static_cast<size_t>(n));  // a symmetric positive definite 3 x 3 per node
  for (Index I = 0; I < n / 3; ++I) {
    const Mat3 R = Mat3::Random();
    Eigen::Map<Eigen::Matrix<Scalar, 3, 3, Eigen::RowMajor>>(blocks.data() + 9 * I) = R * R.transpose() + Mat3::Identity();
  }
  const Scalar alpha = 0.37, beta = 0.81;
  struct Result {
    Vector x, r, z, p;
    Scalar pq = 0, rz = 0, rr = 0, rz_blocks = 0, rr_blocks = 0;
    Vector x_blocks, r_blocks, z_blocks, z_initial;
  };
  auto run = [&](int threads, Index zeros) {
    const Index m = n + zeros;
    auto grow = [&](const Vector& v) {
      Vector w = Vector::Zero(m);
      w.head(n) = v;
      return w;
    };
    std::vector<Scalar> partial(2 * static_cast<size_t>(num_vector_chunks(m)));
    std::vector<Scalar> grown_blocks(blocks);
    grown_blocks.resize(3 * static_cast<size_t>(m), 0.0);
    Result o;
    o.x = o.x_blocks = grow(x0), o.r = o.r_blocks = grow(r0), o.p = grow(p0);
    o.z.resize(m), o.z_blocks.resize(m), o.z_initial.resize(m);
    const Vector q = grow(q0), d = grow(d0);
    apply_node_blocks(grown_blocks.data(), o.r.data(), o.z_initial.data(), m, threads);  // CG's initial z
    o.pq = dot(o.p.data(), q.data(), m, threads, partial.data());
    cg_update(alpha, o.p.data(), q.data(), d.data(), o.x.data(), o.r.data(), o.z.data(), m, o.rz, o.rr, threads,
              partial.data());
    cg_update_node_blocks(alpha, o.p.data(), q.data(), grown_blocks.data(), o.x_blocks.data(), o.r_blocks.data(),
                          o.z_blocks.data(), m, o.rz_blocks, o.rr_blocks, threads, partial.data());
    update_direction(o.z.data(), beta, o.p.data(), m, threads);
    return o;
  };
  const Result one = run(1, 0);
  // Against the formulas, to round-off: sums of ~3e4 terms of O(1), each within its terms' sum
  // times n eps ~ 1e-11; the elementwise values to a few eps.
  const Vector r = r0 - alpha * q0, z = d0.cwiseProduct(r);
  Vector zb(n);
  for (Index I = 0; I < n / 3; ++I)
    zb.segment<3>(3 * I) = Eigen::Map<const Eigen::Matrix<Scalar, 3, 3, Eigen::RowMajor>>(blocks.data() + 9 * I) *
                           r.segment<3>(3 * I);
  CHECK(std::abs(one.pq - p0.dot(q0)) <= 1e-11 * p0.cwiseAbs().dot(q0.cwiseAbs()));
  CHECK((one.x - (x0 + alpha * p0)).norm() <= 1e-15 * x0.norm());
  CHECK((one.r - r).norm() <= 1e-15 * r.norm());
  CHECK((one.z - z).norm() <= 1e-15 * z.norm());
  CHECK(std::abs(one.rz - r.dot(z)) <= 1e-11 * r.dot(z));
  CHECK(std::abs(one.rr - r.squaredNorm()) <= 1e-11 * r.squaredNorm());
  // The node-block pass sums in row order, the Jacobi pass in lanes (and a compiler may fuse
  // its multiply-adds): equal to the formulas, not to each other's bits.
  CHECK((one.x_blocks - (x0 + alpha * p0)).norm() <= 1e-15 * x0.norm());
  CHECK((one.r_blocks - r).norm() <= 1e-15 * r.norm());
  CHECK((one.z_blocks - zb).norm() <= 1e-14 * zb.norm());
  Vector zb0(n);  // the initial pass, z = B r0
  for (Index I = 0; I < n / 3; ++I)
    zb0.segment<3>(3 * I) = Eigen::Map<const Eigen::Matrix<Scalar, 3, 3, Eigen::RowMajor>>(blocks.data() + 9 * I) *
                            r0.segment<3>(3 * I);
  CHECK((one.z_initial - zb0).norm() <= 1e-14 * zb0.norm());
  CHECK(std::abs(one.rz_blocks - r.dot(zb)) <= 1e-11 * r.dot(zb));
  CHECK(std::abs(one.rr_blocks - r.squaredNorm()) <= 1e-11 * r.squaredNorm());
  CHECK((one.p - (z + beta * p0)).norm() <= 1e-15 * one.p.norm());
  // Bit for bit: 2 and 3 threads, and zeros appended (the partial chunk filled and one chunk
  // more; whole nodes, as the dof map appends them).
  for (const auto& [threads, zeros] : {std::pair{2, Index{0}}, std::pair{3, Index{0}}, std::pair{2, Index{5001}}}) {
    CAPTURE(threads, zeros);
    const Result o = run(threads, zeros);
    CHECK(o.pq == one.pq);
    CHECK(o.rz == one.rz);
    CHECK(o.rr == one.rr);
    CHECK(o.rz_blocks == one.rz_blocks);
    CHECK(o.rr_blocks == one.rr_blocks);
    CHECK(o.x.head(n) == one.x);
    CHECK(o.r.head(n) == one.r);
    CHECK(o.z.head(n) == one.z);
    CHECK(o.x_blocks.head(n) == one.x_blocks);
    CHECK(o.r_blocks.head(n) == one.r_blocks);
    CHECK(o.z_blocks.head(n) == one.z_blocks);
    CHECK(o.z_initial.head(n) == one.z_initial);
    CHECK(o.p.head(n) == one.p);
  }
}

TEST_CASE("CG with node blocks in every mode of a solver: steps and a static solve agree with Jacobi's",
          "[linear][cg]") {
  // The preconditioner changes CG's iterates, not the system: each result agrees with the
  // Jacobi run to what the tolerances allow, on 1 thread and on 2 (bar720 Tet4 is above the
  // 3000 blocks from which the products split; a split product sums in another order, so 2
  // threads are not 1 thread's bits, but the same bits on every run).
  // Real time: one linear solve per step, to 1e-10 relative. Accurate: Newton to 1e-10 of the
  // force scale (CG's inexact-Newton tolerance follows it down). A displacement error of
  // cond(A) 1e-10 ~ 1e-7 per step at most (the Newmark matrix at dt = 0.01 is mass-dominated,
  // cond ~1e2-1e3) over 20 steps: 1e-6 bounds the difference. Measured: 1.4e-12 and 2.2e-12
  // (accurate), 2.4e-10 and 4.2e-10 (real time).
  const auto mesh = bar_mesh<Tet4>(20, 6, 6);
  for (NewmarkMode mode : {NewmarkMode::Accurate, NewmarkMode::RealTime}) {
    for (MassKind mass : {MassKind::Consistent, MassKind::Lumped}) {
      CAPTURE(static_cast<int>(mode), static_cast<int>(mass));
      auto run = [&](CgPreconditioner pc, int threads) {
        SolverSettings st;
        st.newmark.mode = mode;
        st.mass = mass;
        st.threads = threads;
        st.linear.tolerance = 1e-10;
        st.newton.residual_tolerance = 1e-10;
        st.linear.preconditioner = pc;
        Solver<Tet4, Corotational> s(mesh, soft, st);
        s.fix(mesh.node_set("xmin"));
        s.add_gravity(Vec3(0, 0, -9.81));
        for (int k = 0; k < 20; ++k) s.step(0.01);
        return Vector(s.displacement());
      };
      const Vector uj = run(CgPreconditioner::Jacobi, 1);
      const Vector ub = run(CgPreconditioner::BlockJacobi, 1);
      const Vector ub2 = run(CgPreconditioner::BlockJacobi, 2);
      INFO("relative difference from Jacobi's: " << (ub - uj).norm() / uj.norm() << ", 2 threads from 1: "
                                                  << (ub2 - ub).norm() / ub.norm());
      CHECK((ub - uj).norm() <= 1e-6 * uj.norm());
      CHECK((ub2 - ub).norm() <= 1e-6 * ub.norm());
      CHECK(run(CgPreconditioner::BlockJacobi, 2) == ub2);
    }
  }
  SECTION("statics with CG") {
    // CG to 1e-12 with the true residual checked (verify_residual), Newton to its default 1e-6 of
    // the force scale: the converged displacements may differ by up to about that tolerance;
    // Newton's quadratic convergence lands both far inside it (measured 1e-16).
    auto solve = [&](CgPreconditioner pc) {
      SolverSettings st;
      st.static_linear = {LinearSolverKind::ConjugateGradient, 1e-12, 100000};
      st.static_linear.verify_residual = true;
      st.static_linear.preconditioner = pc;
      Solver<Tet4, Corotational> s(mesh, soft, st);
      s.fix(mesh.node_set("xmin"));
      s.add_gravity(Vec3(0, 0, -9.81));
      s.solve_static();
      return Vector(s.displacement());
    };
    const Vector uj = solve(CgPreconditioner::Jacobi), ub = solve(CgPreconditioner::BlockJacobi);
    INFO("relative difference: " << (ub - uj).norm() / uj.norm());
    CHECK((ub - uj).norm() <= 1e-5 * uj.norm());
  }
}
