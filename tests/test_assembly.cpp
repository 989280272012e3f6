// Polar decomposition, block-symmetric storage and assembly, each against an independent
// reference: the SVD, a dense matrix assembled entry by entry, and Eigen's sparse product.
#include "catch.hpp"

#include <plastifem/plastifem.hpp>

#include <fmt/core.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <random>

using namespace plastifem;

namespace {

Mat3 random_rotation(std::mt19937& rng) {
  std::normal_distribution<Scalar> n;
  const Vec3 axis = Vec3(n(rng), n(rng), n(rng)).normalized();
  return Eigen::AngleAxisd(3 * std::uniform_real_distribution<Scalar>(0, 1)(rng), axis).toRotationMatrix();
}

}  // namespace

TEST_CASE("polar rotation matches the SVD from tiny to large stretches, and handles inversion", "[polar]") {
  std::mt19937 rng(7);
  std::uniform_real_distribution<Scalar> u(-1, 1);
  // Stretch amplitudes from round-off to 100% (singular values ~0.3 to ~2.5).
  for (Scalar amp : {0.0, 1e-9, 1e-3, 0.05, 0.3, 0.7}) {
    Scalar worst = 0, worst_sym = 0, worst_orth = 0;
    for (int k = 0; k < 2000; ++k) {
      Mat3 D;
      for (int i = 0; i < 9; ++i) D(i / 3, i % 3) = amp * u(rng);
      const Mat3 F = random_rotation(rng) * (Mat3::Identity() + D);
      if (!(F.determinant() > 0.05 * std::pow(F.norm(), 3))) continue;  // well-conditioned branch
      const Mat3 R = rotation_of(F);
      Eigen::JacobiSVD<Mat3> svd(F, Eigen::ComputeFullU | Eigen::ComputeFullV);
      const Mat3 R_svd = svd.matrixU() * svd.matrixV().transpose();
      const Mat3 S = R.transpose() * F;
      worst = std::max(worst, (R - R_svd).norm());
      worst_sym = std::max(worst_sym, (S - S.transpose()).norm() / F.norm());
      worst_orth = std::max(worst_orth, (R.transpose() * R - Mat3::Identity()).norm());
    }
    fmt::print("polar, stretch amplitude {:g}: |R - R_svd| {:.1e}, asym(R^T F) {:.1e}, |R^T R - I| {:.1e}\n", amp, worst,
               worst_sym, worst_orth);
    // Round-off of a few dozen flops on unit-size entries, amplified by the conditioning of
    // the polar factor (1 / (s_i + s_j) <= ~3 here).
    CHECK(worst < 1e-13);
    CHECK(worst_sym < 1e-14);
    CHECK(worst_orth < 1e-14);
  }
  // Inverted (det F < 0): the element is read as compressed through zero along its weakest
  // direction, not reflected: F = diag(1.2, 0.9, -0.1), rotated, gives back the rotation.
  const Mat3 Q = Eigen::AngleAxisd(0.8, Vec3(1, 2, 3).normalized()).toRotationMatrix();
  const Mat3 R = rotation_of(Q * Vec3(1.2, 0.9, -0.1).asDiagonal());
  CHECK(R.determinant() == Approx(1.0));
  CHECK((R - Q).norm() < 1e-14);
  // Degenerate and non-finite: identity, no NaN.
  CHECK(rotation_of(Mat3::Zero()) == Mat3::Identity());
  CHECK(rotation_of(Mat3::Constant(std::nan(""))) == Mat3::Identity());
  CHECK(rotation_of(Vec3(1, 1, 0).asDiagonal()).allFinite());
}

TEST_CASE("polar rotation of near-singular and inverted F is the closest proper rotation", "[polar]") {
  // rotation_of's other branch (det F <= 5e-3 |F|^3 / 5.2: inverted, flattened, collapsed
  // elements). The closest proper rotation maximises tr(R^T F) over det R = +1, and the
  // maximum is s1 + s2 + sign(det F) s3 for the singular values s1 >= s2 >= s3 (the
  // independent fact, with the singular values from Eigen's JacobiSVD); where s1 > s2 > s3 are
  // apart the maximiser is unique and must equal U diag(1, 1, sign det F) V^T.
  std::mt19937 rng(5);
  std::uniform_real_distribution<Scalar> u(0, 1);
  Scalar worst_trace = 0, worst_R = 0, worst_orth = 0;
  int unique = 0, cases = 0;
  for (int k = 0; k < 4000; ++k) {
    // Singular values spanning collapse (0), rank 1 and 2, near-equal pairs; either sign of det.
    Vec3 s(0.5 + u(rng), 0.5 + u(rng), 0.0);
    const int kind = k % 5;
    s[2] = kind == 0 ? 0.0 : kind == 1 ? 1e-9 * u(rng) : kind == 2 ? 0.004 * u(rng) : 0.02 * u(rng);
    if (kind == 3) s[1] = s[0] * (1 + 1e-10 * u(rng));  // two equal singular values
    if (kind == 4 && k % 2 == 0) s[1] = 1e-11;           // rank 1
    if (k % 2 == 1) s[2] = -s[2];                         // inverted
    const Mat3 F = random_rotation(rng) * s.asDiagonal() * random_rotation(rng).transpose();
    const Mat3 R = rotation_of(F);
    Eigen::JacobiSVD<Mat3> svd(F, Eigen::ComputeFullU | Eigen::ComputeFullV);
    const Vec3 sv = svd.singularValues();
    const Scalar sign = F.determinant() < 0 ? -1.0 : 1.0;
    const Scalar best = sv[0] + sv[1] + sign * sv[2];
    worst_trace = std::max(worst_trace, std::abs((R.transpose() * F).trace() - best) / sv[0]);
    worst_orth = std::max(worst_orth, (R.transpose() * R - Mat3::Identity()).norm() + std::abs(R.determinant() - 1));
    const Scalar l1 = sv[0] * sv[0], l2 = sv[1] * sv[1], l3 = sv[2] * sv[2];
    if (l1 - l2 > 1e-3 * l1 && l2 - l3 > 1e-3 * l1) {
      Mat3 U = svd.matrixU();
      if ((U * svd.matrixV().transpose()).determinant() < 0) U.col(2) *= -1;
      worst_R = std::max(worst_R, (R - U * svd.matrixV().transpose()).norm());
      ++unique;
    }
    ++cases;
  }
  fmt::print("polar, near-singular and inverted F ({} cases, {} with a unique answer): tr(R^T F) against its "
             "maximum {:.1e}, |R - R_svd| {:.1e}, |R^T R - I| + |det R - 1| {:.1e}\n",
             cases, unique, worst_trace, worst_R, worst_orth);
  // The maximum is flat at the maximiser (the error in tr(R^T F) is second order in R's), so
  // 1e-12 of s1 is round-off. R is computed from the eigenvectors of F^T F, each accurate to
  // about 1e-16 s1^2 / (its eigenvalue's gap): 1e-13 for the gaps of at least 1e-3 s1^2 of
  // the unique cases (1e-12 allowed). Closer gaps (s2 and s3 both near zero) leave R less
  // accurate, but then nearly any rotation in the plane of the collapse serves.
  CHECK(worst_trace < 1e-12);
  CHECK(worst_R < 1e-12);
  CHECK(worst_orth < 1e-13);
  CHECK(unique > 500);
}

TEST_CASE("batched polar rotations equal one-at-a-time ones, with every branch in one batch", "[polar]") {
  std::mt19937 rng(11);
  std::uniform_real_distribution<Scalar> u(-1, 1);
  // Each batch of 8 mixes a rotation, small and large stretches (the lockstep and the scaled-
  // Newton branch), an inverted and a degenerate F (the SVD branch) and a non-finite one.
  for (int trial = 0; trial < 500; ++trial) {
    std::array<Mat3, 8> F, R;
    const Scalar amps[5] = {0.0, 1e-6, 0.03, 0.1, 0.7};
    for (int q = 0; q < 5; ++q) {
      Mat3 D;
      for (int i = 0; i < 9; ++i) D(i / 3, i % 3) = amps[q] * u(rng);
      F[q] = random_rotation(rng) * (Mat3::Identity() + D) * (1 + 3 * std::abs(u(rng)));  // any scale
    }
    F[5] = random_rotation(rng) * Vec3(1.2, 0.9, -0.1).asDiagonal();
    F[6] = Vec3(1, 1, 0).asDiagonal();
    F[7] = trial % 2 ? Mat3::Constant(std::nan("")) : Mat3::Zero();
    std::shuffle(F.begin(), F.end(), rng);
    rotations_of<8>(F, R);
    for (int q = 0; q < 8; ++q) {
      // A point converged early takes the others' remaining Newton-Schulz steps, which leave
      // it fixed to round-off: a few eps, like two orderings of the same sums.
      INFO("trial " << trial << " point " << q << "\nF =\n" << F[q]);
      REQUIRE((R[q] - rotation_of(F[q])).norm() < 1e-14);
    }
  }
  // Q = 4 (Tet10) and Q = 1 (Tet4, bit-identical to rotation_of).
  std::array<Mat3, 4> F4, R4;
  for (auto& F : F4) F = random_rotation(rng) * (Mat3::Identity() + 0.02 * Mat3::Random());
  rotations_of<4>(F4, R4);
  for (int q = 0; q < 4; ++q) CHECK((R4[q] - rotation_of(F4[q])).norm() < 1e-14);
  std::array<Mat3, 1> F1{random_rotation(rng) * Vec3(1.01, 0.98, 1.02).asDiagonal()}, R1;
  rotations_of<1>(F1, R1);
  CHECK(R1[0] == rotation_of(F1[0]));
}

TEST_CASE("polar rotation does not depend on F's scale, from 1e-300 to 1e300, one at a time and batched", "[polar]") {
  // R(c F) = R(F) for every c > 0: the polar factor is scale-free. |F|^2 overflows for entries
  // beyond ~1e154 and goes subnormal below ~1e-154, which must not change the answer (it gave
  // the identity, or a rotation off by the subnormal's lost digits). The tolerance is that of
  // the tests above: the scaled iterate differs from the unit one by one rounding per entry.
  std::mt19937 rng(5);
  std::uniform_real_distribution<Scalar> u(-1, 1);
  for (Scalar scale : {1e-300, 1e-200, 1e-160, 1e-150, 1e150, 1e160, 1e200, 1e300}) {
    std::array<Mat3, 8> F, R;
    for (int q = 0; q < 8; ++q) {
      Mat3 D;
      for (int i = 0; i < 9; ++i) D(i / 3, i % 3) = (q < 4 ? 0.02 : 0.5) * u(rng);
      F[q] = random_rotation(rng) * (Mat3::Identity() + D);
    }
    F[7] = random_rotation(rng) * Vec3(1.2, 0.9, -0.1).asDiagonal();  // the SVD branch
    std::array<Mat3, 8> Fs;
    for (int q = 0; q < 8; ++q) Fs[q] = F[q] * scale;
    rotations_of<8>(Fs, R);
    for (int q = 0; q < 8; ++q) {
      INFO("scale " << scale << " point " << q);
      const Mat3 R_unit = rotation_of(F[q]);
      CHECK((rotation_of(Fs[q]) - R_unit).norm() < 1e-13);
      CHECK((R[q] - R_unit).norm() < 1e-13);
      CHECK(std::abs(R[q].determinant() - 1) < 1e-14);
    }
  }
  // Still the identity for what has no rotation: zero, non-finite, infinite entries.
  CHECK(rotation_of(Mat3::Constant(std::numeric_limits<Scalar>::infinity())) == Mat3::Identity());
  Mat3 one_inf = Mat3::Identity();
  one_inf(1, 2) = -std::numeric_limits<Scalar>::infinity();
  CHECK(rotation_of(one_inf) == Mat3::Identity());
  CHECK(rotation_of(Mat3::Identity() * 1e-320) == Mat3::Identity());  // subnormal: still a scaled I
}

TEST_CASE("block-symmetric matrix: assembly, product, diagonal, sum and CSC copy against dense", "[assembly]") {
  // A Kuhn Tet4 bar: node numbers are not monotone within elements, so blocks land both as
  // K_ab and transposed.
  const auto mesh = bar_mesh<Tet4>(5, 3, 2);
  const Assembler<Tet4> assembler(mesh);
  BlockSymmetricMatrix A = assembler.zero_matrix();
  const Index n = A.rows();
  Eigen::MatrixXd dense = Eigen::MatrixXd::Zero(n, n);
  std::mt19937 rng(3);
  std::uniform_real_distribution<Scalar> u(-1, 1);
  for (Index e = 0; e < mesh.num_elements(); ++e) {
    Eigen::Matrix<Scalar, 12, 12> Ke;
    for (int i = 0; i < 144; ++i) Ke(i / 12, i % 12) = u(rng);
    Ke = (Ke + Ke.transpose()).eval();
    assembler.add_element_matrix(e, Ke, A.values());
    const auto& c = mesh.element(e);
    for (int a = 0; a < 4; ++a)
      for (int b = 0; b < 4; ++b) dense.block<3, 3>(3 * c[a], 3 * c[b]) += Ke.block<3, 3>(3 * a, 3 * b);
  }
  Vector x(n);
  for (Index i = 0; i < n; ++i) x[i] = u(rng);
  Vector y(n);
  A.multiply(x, y, 1);
  const Vector y_dense = dense * x;
  CHECK((y - y_dense).norm() <= 1e-13 * y_dense.norm());
  Vector y2(n);
  A.multiply(x, y2, 2);
  CHECK((y2 - y_dense).norm() <= 1e-13 * y_dense.norm());
  CHECK((A.diagonal() - dense.diagonal()).norm() == 0);
  CHECK(A.sum() == Approx(dense.sum()).epsilon(1e-12));
  CHECK(A.coeff(7, 2) == dense(7, 2));
  CHECK(A.coeff(2, 7) == dense(2, 7));
  const SparseMatrix S = A.to_sparse();
  CHECK((Eigen::MatrixXd(S) - dense).norm() == 0);
  // The CSC copy reuses its pattern: after a value change only values move.
  A.values()[0] += 1;
  SparseMatrix S2 = S;
  A.copy_to(S2);
  CHECK(S2.nonZeros() == S.nonZeros());
  CHECK((Eigen::MatrixXd(S2) - Eigen::MatrixXd(S)).cwiseAbs().sum() == Approx(1.0));
}

TEST_CASE("constrained rows and columns become diagonal, exactly as on the dense matrix", "[assembly][dirichlet]") {
  const auto mesh = bar_mesh<Tet4>(4, 2, 2);
  const Assembler<Tet4> assembler(mesh);
  BlockSymmetricMatrix A = assembler.zero_matrix();
  std::mt19937 rng(11);
  std::uniform_real_distribution<Scalar> u(-1, 1);
  for (Index i = 0; i < A.num_values(); ++i) A.values()[i] = u(rng);
  Eigen::MatrixXd dense = A.to_sparse();
  const Index n = A.rows();
  // Whole nodes and single components (a sliding support), scattered over the numbering.
  std::vector<char> c(n, 0);
  for (Index d = 0; d < n; d += 7) c[d] = 1;
  for (Index i : mesh.node_set("xmin")) c[3 * i] = c[3 * i + 1] = c[3 * i + 2] = 1;
  // A constrained diagonal entry keeps its value where positive (the matrix's own scale), else
  // takes the mean of the positive ones; every other entry of its row and column is zero.
  Scalar sum = 0;
  int count = 0, kept = 0;
  for (Index d = 0; d < n; ++d)
    if (c[d] && dense(d, d) > 0) sum += dense(d, d), ++count;
  REQUIRE(count > 0);
  for (Index r = 0; r < n; ++r)
    for (Index k = 0; k < n; ++k)
      if (c[r] || c[k]) {
        if (r != k) dense(r, k) = 0.0;
        else if (dense(r, r) > 0) ++kept;
        else dense(r, r) = sum / count;
      }
  REQUIRE(kept < std::count(c.begin(), c.end(), 1));  // both branches are exercised
  const ConstrainedBlocks cb(A.pattern(), c);
  cb.apply(A);
  CHECK((Eigen::MatrixXd(A.to_sparse()) - dense).norm() == 0);
  Vector b = Vector::Ones(n);
  cb.zero(b);
  for (Index d = 0; d < n; ++d) CHECK(b[d] == (c[d] ? 0.0 : 1.0));
}

TEST_CASE("threaded block product equals the serial one to round-off on a large pattern", "[assembly][threads]") {
  // Above the threading threshold (3000 blocks): bar720-size Hex8.
  const auto mesh = bar_mesh<Hex8>(20, 6, 6);
  const Assembler<Hex8> assembler(mesh);
  BlockSymmetricMatrix A = assembler.zero_matrix();
  REQUIRE(A.pattern().num_blocks() > 3000);
  std::mt19937 rng(5);
  std::uniform_real_distribution<Scalar> u(-1, 1);
  for (Index i = 0; i < A.num_values(); ++i) A.values()[i] = u(rng);
  for (Index I = 0; I < A.pattern().num_block_rows; ++I) {  // diagonal blocks must be symmetric
    Scalar* D = A.values() + 9 * static_cast<size_t>(A.pattern().row_start[I + 1] - 1);
    D[3] = D[1], D[6] = D[2], D[7] = D[5];
  }
  Vector x = Vector::NullaryExpr(A.rows(), [&](Index) { return u(rng); });
  Vector y1(A.rows()), y2(A.rows());
  A.multiply(x, y1, 1);
  A.multiply(x, y2, 2);
  const Vector ref = A.to_sparse() * x;
  CHECK((y1 - ref).norm() <= 1e-13 * ref.norm());
  CHECK((y2 - ref).norm() <= 1e-13 * ref.norm());
  // Each product zeroes a thread's buffer only over the band its rows reach back to (here a
  // part of the rows before its range): what lies below must stay zero from one product to the
  // next. A product of another vector first, then x; on three threads, then on two again (a
  // new split, new buffers).
  Vector y3(A.rows());
  A.multiply(Vector::Ones(A.rows()), y3, 3);
  A.multiply(x, y3, 3);
  CHECK((y3 - ref).norm() <= 1e-13 * ref.norm());
  A.multiply(Vector::Ones(A.rows()), y2, 2);
  A.multiply(x, y2, 2);
  CHECK((y2 - ref).norm() <= 1e-13 * ref.norm());
}

TEST_CASE("value passes with threads cover every value once and equal the serial passes", "[assembly][threads]") {
  // Above the threading threshold (3000 blocks): bar720-size Hex8. The ranges must be disjoint
  // and cover the array (a gap leaves stale values in A, an overlap would race), whatever the
  // thread count, including more threads than cores and OpenMP's default (0).
  const auto mesh = bar_mesh<Hex8>(20, 6, 6);
  const Assembler<Hex8> assembler(mesh);
  BlockSymmetricMatrix A = assembler.zero_matrix(), B = assembler.zero_matrix();
  REQUIRE(A.pattern().num_blocks() > 3000);
  for (int threads : {0, 1, 2, 3, 5}) {
    CAPTURE(threads);
    std::vector<int> visits(static_cast<size_t>(A.num_values()), 0);
    A.for_value_ranges(threads, [&](Index v0, Index v1) {
      for (Index i = v0; i < v1; ++i) ++visits[static_cast<size_t>(i)];  // disjoint ranges: no race
    });
    CHECK(std::all_of(visits.begin(), visits.end(), [](int v) { return v == 1; }));
  }
  std::mt19937 rng(7);
  std::uniform_real_distribution<Scalar> u(-1, 1);
  for (Index i = 0; i < A.num_values(); ++i) B.values()[i] = u(rng);
  A.copy_values(B, 2);
  CHECK(std::equal(A.values(), A.values() + A.num_values(), B.values()));
  A.set_zero(2);
  CHECK(std::all_of(A.values(), A.values() + A.num_values(), [](Scalar v) { return v == 0; }));
  A = B;  // same pattern: the values only
  CHECK(std::equal(A.values(), A.values() + A.num_values(), B.values()));
  // A Newton matrix a X + Y + b Z, with and without Z: on any thread count the same bits as on
  // one; and the formula's value, checked on dyadic values (multiples of 1/1024, a = 1/2,
  // b = 1/4), whose products and sums are exact with or without fused multiply-adds.
  BlockSymmetricMatrix Y = assembler.zero_matrix(), Z = assembler.zero_matrix(), serial = assembler.zero_matrix();
  for (Index i = 0; i < A.num_values(); ++i) Y.values()[i] = u(rng), Z.values()[i] = u(rng);
  auto same_bits = [](const BlockSymmetricMatrix& P, const BlockSymmetricMatrix& Q) {
    return std::equal(P.values(), P.values() + P.num_values(), Q.values());
  };
  for (const BlockSymmetricMatrix* z : std::array<const BlockSymmetricMatrix*, 2>{&Z, nullptr}) {
    serial.set_combination(1.0 / 3, B, Y, 0.7, z, 1);
    for (int threads : {2, 3}) {
      CAPTURE(threads, z != nullptr);
      A.set_combination(1.0 / 3, B, Y, 0.7, z, threads);
      CHECK(same_bits(A, serial));
    }
  }
  auto dyadic = [](Scalar x) { return std::round(1024 * x) / 1024; };
  for (Index i = 0; i < A.num_values(); ++i)
    B.values()[i] = dyadic(B.values()[i]), Y.values()[i] = dyadic(Y.values()[i]), Z.values()[i] = dyadic(Z.values()[i]);
  A.set_combination(0.5, B, Y, 0.25, &Z, 2);
  bool exact = true;
  for (Index i = 0; i < A.num_values(); ++i)
    exact = exact && A.values()[i] == 0.5 * B.values()[i] + Y.values()[i] + 0.25 * Z.values()[i];
  CHECK(exact);
  A.set_combination(0.5, B, Y, 0, nullptr, 2);  // without damping, as System::form mostly runs
  for (Index i = 0; i < A.num_values(); ++i) exact = exact && A.values()[i] == 0.5 * B.values()[i] + Y.values()[i];
  CHECK(exact);
  // Another pattern's values would be read out of order: refused.
  const Assembler<Hex8> other(bar_mesh<Hex8>(20, 6, 5));
  BlockSymmetricMatrix C = other.zero_matrix();
  CHECK_THROWS_AS(A.copy_values(C, 2), Error);
  CHECK_THROWS_AS(A.set_combination(0.5, B, C, 0, nullptr, 2), Error);
  CHECK_THROWS_AS(A.set_combination(0.5, B, Y, 0.25, &C, 2), Error);
}

TEST_CASE("a mesh numbered without spatial coherence assembles in spatial order, equal to its coherent copy",
          "[assembly][threads]") {
  // Gmsh's HXT mesher numbers tetrahedra with no spatial coherence. In index order, chunks of 16
  // such elements touch rows all over the mesh, every chunk conflicts with nearly every other,
  // and a 2,559-tet liver needed more than the 64 colours the assembler has (MeshError). It then
  // assembles in the Z-order of the element centres. The bar's Tet4s in a random order (2,160
  // elements, 135 chunks) fail the index order the same way.
  const Mesh<Tet4> bar = bar_mesh<Tet4>(10, 6, 6);
  std::vector<Mesh<Tet4>::Connectivity> elements;
  for (Index e = 0; e < bar.num_elements(); ++e) elements.push_back(bar.element(e));
  std::mt19937 rng(3);
  std::shuffle(elements.begin(), elements.end(), rng);
  const Mesh<Tet4> shuffled(bar.nodes(), elements);
  const Assembler<Tet4> assembler(shuffled);
  CHECK(assembler.num_colours() <= 32);  // chunks along the curve conflict with their neighbours only (measured 19)
  std::vector<int> visits(static_cast<size_t>(shuffled.num_elements()), 0);
  assembler.for_each_element([&](Index e) { ++visits[static_cast<size_t>(e)]; }, 2);  // a colour's chunks share no row: no race
  CHECK(std::all_of(visits.begin(), visits.end(), [](int v) { return v == 1; }));
  // The same nodes and elements give the same steps, force and tangent as the coherent bar (to
  // the round-off of another summation order); on 2 threads the same force and tangent bits as
  // on 1 at a common state (the threaded product reorders a few additions: the steps differ by
  // round-off, as in test_solver's thread test).
  std::vector<Index> clamped;
  for (Index i = 0; i < bar.num_nodes(); ++i)
    if (bar.node(i).x() == 0) clamped.push_back(i);
  std::vector<Vector> u, f;
  std::vector<SparseMatrix> K;
  for (const Mesh<Tet4>* mesh : {&bar, &shuffled, &shuffled}) {
    SolverSettings st;
    st.threads = u.size() == 2 ? 2 : 1;
    Solver<Tet4, Corotational> s(*mesh, Material{3000, 0.45, 1.0}, st);
    s.fix(clamped);
    s.add_gravity(Vec3(0, 0, -9.81));
    for (int k = 0; k < 3; ++k) s.step(0.01);
    u.push_back(s.displacement());
    s.set_state(Vector::Constant(s.num_dofs(), 0.01), Vector::Zero(s.num_dofs()));
    f.push_back(s.internal_force());
    K.push_back(s.tangent());
  }
  REQUIRE(u[0].norm() > 0);
  // Newton stops at |r| <= 1e-6 relative (CG 1e-8): another summation order can end Newton one
  // iteration earlier or later, which moves u by about that tolerance; 1e-5 leaves it room.
  CHECK((u[1] - u[0]).norm() <= 1e-5 * u[0].norm());
  CHECK((f[1] - f[0]).norm() <= 1e-12 * f[0].norm() + 1e-12 * (f[1] - f[0]).size());
  CHECK((Eigen::MatrixXd(K[1]) - Eigen::MatrixXd(K[0])).norm() <= 1e-12 * Eigen::MatrixXd(K[0]).norm());
  CHECK((u[2] - u[1]).norm() <= 1e-12 * u[1].norm());
  CHECK((f[2].array() == f[1].array()).all());
  REQUIRE(K[1].nonZeros() == K[2].nonZeros());
  CHECK(std::equal(K[1].valuePtr(), K[1].valuePtr() + K[1].nonZeros(), K[2].valuePtr()));
}
