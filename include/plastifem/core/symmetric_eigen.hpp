#pragma once
// Eigen-decomposition of small symmetric matrices by the cyclic Jacobi method, and the
// projection onto the positive semi-definite cone built on it.
//
// Why not Eigen::SelfAdjointEigenSolver: for the 9x9 per-point tangents of the hyperelastic
// models it instantiates Householder tridiagonalisation, block reflectors and the implicit
// QR, which cost 3.2 s of compile time in every translation unit that included the elastic
// models (measured with g++ 12 -O2; clang's -ftime-trace put it first of all instantiations).
// Cyclic Jacobi is a few dozen lines, as accurate (it computes small eigenvalues to high
// relative accuracy), and fast enough at this size: each sweep applies N (N - 1) / 2 plane
// rotations of O(N) work, and 6-8 sweeps reach round-off.
//
// A = V diag(lambda) V^T: sweeps over the off-diagonal entries (p, q), each annihilated by the
// rotation with t = tan(theta) the smaller root of t^2 + 2 tau t - 1 = 0,
// tau = (a_qq - a_pp) / (2 a_pq) (Golub and Van Loan, Matrix Computations, section 8.5.2).
#include <plastifem/core/types.hpp>

#include <cmath>

namespace plastifem {

/// Eigenvalues and orthonormal eigenvectors (columns) of the symmetric matrix A.
template <int N>
void symmetric_eigen(const Eigen::Matrix<Scalar, N, N>& A, Eigen::Matrix<Scalar, N, 1>& values,
                     Eigen::Matrix<Scalar, N, N>& vectors) {
  Eigen::Matrix<Scalar, N, N> a = A;
  vectors.setIdentity();
  const Scalar scale = a.cwiseAbs().maxCoeff();
  if (!(scale > 0) || !std::isfinite(scale)) {
    values = a.diagonal();
    return;
  }
  for (int sweep = 0; sweep < 50; ++sweep) {
    Scalar off = 0;
    for (int q = 1; q < N; ++q)
      for (int p = 0; p < q; ++p) off += a(p, q) * a(p, q);
    // Off-diagonal mass below round-off of the largest entry: the diagonal is the spectrum.
    if (off <= Scalar(1e-34) * scale * scale) break;
    for (int p = 0; p < N - 1; ++p)
      for (int q = p + 1; q < N; ++q) {
        const Scalar apq = a(p, q);
        if (apq == 0) continue;
        const Scalar tau = (a(q, q) - a(p, p)) / (2 * apq);
        const Scalar t = (tau >= 0 ? 1 : -1) / (std::abs(tau) + std::sqrt(1 + tau * tau));
        const Scalar c = 1 / std::sqrt(1 + t * t), s = t * c;
        // a <- J^T a J with J the rotation in the (p, q) plane.
        for (int k = 0; k < N; ++k) {
          const Scalar akp = a(k, p), akq = a(k, q);
          a(k, p) = c * akp - s * akq;
          a(k, q) = s * akp + c * akq;
        }
        for (int k = 0; k < N; ++k) {
          const Scalar apk = a(p, k), aqk = a(q, k);
          a(p, k) = c * apk - s * aqk;
          a(q, k) = s * apk + c * aqk;
        }
        a(p, q) = a(q, p) = 0;
        for (int k = 0; k < N; ++k) {
          const Scalar vkp = vectors(k, p), vkq = vectors(k, q);
          vectors(k, p) = c * vkp - s * vkq;
          vectors(k, q) = s * vkp + c * vkq;
        }
      }
  }
  values = a.diagonal();
}

/// true when the symmetric A is positive definite (a Cholesky factorisation succeeds).
template <int N>
bool is_positive_definite(const Eigen::Matrix<Scalar, N, N>& A) {
  Eigen::Matrix<Scalar, N, N> L = A;
  for (int j = 0; j < N; ++j) {
    Scalar d = L(j, j);
    for (int k = 0; k < j; ++k) d -= L(j, k) * L(j, k);
    if (!(d > 0)) return false;
    d = std::sqrt(d);
    L(j, j) = d;
    for (int i = j + 1; i < N; ++i) {
      Scalar v = L(i, j);
      for (int k = 0; k < j; ++k) v -= L(i, k) * L(j, k);
      L(i, j) = v / d;
    }
  }
  return true;
}

/// A <- its projection onto the positive semi-definite matrices (negative eigenvalues clamped
/// to zero); A unchanged, and cheap, when it is already positive definite.
template <int N>
void project_psd(Eigen::Matrix<Scalar, N, N>& A) {
  if (is_positive_definite<N>(A)) return;
  Eigen::Matrix<Scalar, N, 1> values;
  Eigen::Matrix<Scalar, N, N> V;
  symmetric_eigen<N>(A, values, V);
  A = V * values.cwiseMax(0.0).asDiagonal() * V.transpose();
}

}  // namespace plastifem
