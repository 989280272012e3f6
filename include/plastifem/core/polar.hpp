#pragma once
// Rotation part of a deformation gradient, F = R S (R a proper rotation, S symmetric).
//
// Well-conditioned F (det F > 0, not near singular), with X_0 = F / rms(sigma(F)) and
// E_k = X_k^T X_k - I:
//   - while |E_k| >= 1/4 (stretches beyond ~12%): Higham's scaled Newton step
//       X_{k+1} = (g X_k + X_k^{-T} / g) / 2,  g = sqrt(|X_k^{-1}| / |X_k|)  (Frobenius norms),
//     which brings any stretch close to 1 in a few steps;
//   - then Newton-Schulz steps X_{k+1} = X_k (I - E_k / 2), which converge quadratically
//     (|E_{k+1}| ~ 3/4 |E_k|^2) for |E_k|_2 < 1 and need no inverse, no division, no square
//     root: ~45 multiply-adds. Tissue strains of a few percent take 3-4 of them.
//   The iteration stops after the step taken from |E| < 1e-8, which leaves |E| ~ 1e-16.
// Near-singular or reflected F (det F <= 0, an inverted element): SVD F = U diag(s) V^T with
// the sign of the smallest singular value flipped so that det R = +1 (Irving, Teran and Fedkiw
// 2004, "invertible FEM"): the element is then treated as a rotated element compressed through
// zero in its weakest direction, and pushed back.
// Cost (this machine, -march=native): ~65 ns at 0.1% strain, ~100 ns at 5%, ~155 ns at 20%.
#include <plastifem/core/types.hpp>

#include <Eigen/SVD>
#include <array>
#include <cmath>

namespace plastifem {

namespace detail {

/// The cofactor matrix cof X = det(X) X^{-T} = dJ/dX, defined for every X: columns x1 x x2,
/// x2 x x0, x0 x x1.
inline Mat3 cofactor(const Mat3& X) {
  Mat3 C;
  C.col(0) = X.col(1).cross(X.col(2));
  C.col(1) = X.col(2).cross(X.col(0));
  C.col(2) = X.col(0).cross(X.col(1));
  return C;
}

/// det X for X given as 9 column-major components x[r + 3c] (one point's X; rotations_of
/// gathers each lane into such an array for its entry tests).
template <class T>
T determinant(const T* x) {
  return x[0] * (x[4] * x[8] - x[7] * x[5]) - x[3] * (x[1] * x[8] - x[7] * x[2]) + x[6] * (x[1] * x[5] - x[4] * x[2]);
}

/// E = X^T X - I, the Gram matrix of X's columns minus I (symmetric: 6 entries), for X as in
/// determinant(); and the Newton-Schulz step built on it.
template <class T>
struct GramDeviation {
  T e00, e11, e22, e01, e02, e12;
  explicit GramDeviation(const T* x)
      : e00(x[0] * x[0] + x[1] * x[1] + x[2] * x[2] - 1), e11(x[3] * x[3] + x[4] * x[4] + x[5] * x[5] - 1),
        e22(x[6] * x[6] + x[7] * x[7] + x[8] * x[8] - 1), e01(x[0] * x[3] + x[1] * x[4] + x[2] * x[5]),
        e02(x[0] * x[6] + x[1] * x[7] + x[2] * x[8]), e12(x[3] * x[6] + x[4] * x[7] + x[5] * x[8]) {}
  /// |E|_F^2
  T squared_norm() const { return e00 * e00 + e11 * e11 + e22 * e22 + 2 * (e01 * e01 + e02 * e02 + e12 * e12); }
  /// Newton-Schulz: X <- X - X E / 2, each row of X times E.
  void newton_schulz_step(T* x) const {
    for (int r = 0; r < 3; ++r) {
      const T a = x[r], b = x[r + 3], c = x[r + 6];
      x[r] = a - 0.5 * (a * e00 + b * e01 + c * e02);
      x[r + 3] = b - 0.5 * (a * e01 + b * e11 + c * e12);
      x[r + 6] = c - 0.5 * (a * e02 + b * e12 + c * e22);
    }
  }
};

inline Mat3 rotation_by_svd(const Mat3& X) {
  Eigen::JacobiSVD<Mat3> svd(X, Eigen::ComputeFullU | Eigen::ComputeFullV);
  if (svd.info() != Eigen::Success) return Mat3::Identity();  // non-finite X: no rotation to take
  Mat3 U = svd.matrixU();
  const Mat3 V = svd.matrixV();
  if ((U * V.transpose()).determinant() < 0) U.col(2) *= -1;  // singular values sorted: col 2 is smallest
  return U * V.transpose();
}

}  // namespace detail

/// Closest proper rotation to F (det R = +1), robust to degenerate and inverted F.
///
/// The iteration is written out in scalars on a local array: Eigen's 3x3 product assignments
/// are not all inlined at this size, and the scalar form is 1.6-2.5x faster (at 0.1% strain
/// 163 -> 64 ns per decomposition, at 5% 245 -> 98 ns, at 20% 330 -> 154 ns).
inline Mat3 rotation_of(const Mat3& F) {
  const Scalar norm2 = F.squaredNorm();
  // The rotation does not depend on F's scale, but |F|^2 overflows beyond entries of ~1e154
  // and loses digits (subnormal) below ~1e-154: outside a safe range, F is first divided by
  // its largest entry (exact up to one rounding), so F and 1e200 F give the same R.
  if (!(norm2 > 1e-280 && norm2 < 1e280)) {
    const Scalar largest = F.cwiseAbs().maxCoeff();
    if (!F.allFinite() || !(largest > 0)) return Mat3::Identity();
    return rotation_of(F / largest);  // |F / largest|^2 in [1, 9]: one level deep
  }
  const Scalar scale = std::sqrt(3 / norm2);  // rms singular value 1: thresholds below are relative
  Scalar x[9];                                // X, column-major: X(r, c) = x[r + 3c]
  for (int i = 0; i < 9; ++i) x[i] = scale * F.data()[i];
  if (!(detail::determinant(x) > 5e-3)) return detail::rotation_by_svd(Eigen::Map<const Mat3>(x));
  for (int k = 0; k < 40; ++k) {
    const detail::GramDeviation<Scalar> E(x);
    const Scalar e2 = E.squared_norm();
    if (e2 < 1.0 / 16) {
      E.newton_schulz_step(x);
      if (e2 < 1e-16) return Eigen::Map<const Mat3>(x);
    } else {
      // Scaled Newton (Higham): X <- (g X + X^{-T} / g) / 2, with X^{-T} = cof(X) / det X.
      Eigen::Map<Mat3> X(x);
      const Mat3 C = detail::cofactor(X);
      const Scalar d = X.col(0).dot(C.col(0));
      const Scalar g = std::sqrt(C.norm() / (d * X.norm()));
      X = 0.5 * (g * X + C / (g * d));
    }
  }
  return detail::rotation_by_svd(Eigen::Map<const Mat3>(x));  // not reached for det X > 5e-3
}

/// One value per quadrature point of an element: the SIMD lane of the point-batched kernels.
template <int Q>
using PointArray = Eigen::Array<Scalar, Q, 1>;
/// A 3x3 matrix field over Q points, component-wise: m[r + 3c](q) = M_q(r, c) (column-major).
template <int Q>
using PointMat3 = std::array<PointArray<Q>, 9>;

/// x[q] <- sqrt(x[q]) for the Q lanes at x, in SIMD (Eigen's packet square root: a loop of
/// std::sqrt is not vectorised, as it must keep errno).
template <int Q>
void lane_sqrt(Scalar* x) {
  Eigen::Map<PointArray<Q>> m(x);
  m = m.sqrt();
}

/// The rotations of Q deformation gradients at once (the quadrature points of one element),
/// component-wise: F[r + 3c](q) = F_q(r, c), and R likewise. rotation_of's Newton-Schulz
/// iteration runs in lockstep, each of the nine components of X an array over the points, so
/// the arithmetic vectorises across points and their dependency chains overlap; points with
/// stretches beyond about 12% first take rotation_of's scaled Newton steps, in lockstep too.
/// A point that needs the SVD branch (near-singular or inverted F) is left out and done by
/// rotation_of. Agrees with rotation_of to round-off: a point whose iteration has converged
/// takes the others' remaining steps, which leave X fixed to ~1e-16. Hex8 (8 points): 8 x 98
/// -> 190 ns in all at 5% strain.
template <int Q>
void rotations_of(const PointMat3<Q>& F, PointMat3<Q>& R) {
  // Plain lane loops over fixed-size arrays: the compiler turns each into a few SIMD
  // instructions. (Written with Eigen arrays, the 8-lane temporaries went through the stack in
  // 128-bit halves and were reloaded as 256-bit vectors: store-forwarding stalls that made
  // this 3x slower.)
  alignas(64) Scalar x[9][Q];
  Scalar norm2[Q], det[Q], gram[Q];
  bool alone[Q];
  for (int q = 0; q < Q; ++q) norm2[q] = 0;
  for (int i = 0; i < 9; ++i)
    for (int q = 0; q < Q; ++q) norm2[q] += F[i](q) * F[i](q);
  // Scaled to rms singular value 1, then the same entry tests as rotation_of: det X > 5e-3
  // and |X^T X - I| < 1/4. Other points are replaced by the identity (converged) here. A lane
  // whose |F|^2 is outside rotation_of's safe range gets X = 0, so it is done there, rescaled.
  for (int q = 0; q < Q; ++q) norm2[q] = (norm2[q] > 1e-280 && norm2[q] < 1e280) ? std::sqrt(3 / norm2[q]) : 0.0;
  for (int i = 0; i < 9; ++i)
    for (int q = 0; q < Q; ++q) x[i][q] = F[i](q) * norm2[q];
  bool any_alone = false, any_far = false;
  bool far[Q];
  for (int q = 0; q < Q; ++q) {
    Scalar xq[9];
    for (int i = 0; i < 9; ++i) xq[i] = x[i][q];
    det[q] = detail::determinant(xq);
    gram[q] = detail::GramDeviation<Scalar>(xq).squared_norm();
    alone[q] = !(det[q] > 5e-3);  // also true for NaN: the SVD branch
    far[q] = !alone[q] && !(gram[q] < 1.0 / 16);
    any_far = any_far || far[q];
  }
  // Stretches beyond ~12%: rotation_of's scaled Newton steps, in lockstep over the points that
  // need them (soft tissue reaches such strains; one at a time they took a sixth of a
  // corotational step on the bench's bar), the others left as they are.
  for (int k = 0; k < 40 && any_far; ++k) {
    Scalar c[9][Q], a[Q], b[Q];
    for (int q = 0; q < Q; ++q) {  // cof X: columns x1 x x2, x2 x x0, x0 x x1
      c[0][q] = x[4][q] * x[8][q] - x[5][q] * x[7][q];
      c[1][q] = x[5][q] * x[6][q] - x[3][q] * x[8][q];
      c[2][q] = x[3][q] * x[7][q] - x[4][q] * x[6][q];
      c[3][q] = x[7][q] * x[2][q] - x[8][q] * x[1][q];
      c[4][q] = x[8][q] * x[0][q] - x[6][q] * x[2][q];
      c[5][q] = x[6][q] * x[1][q] - x[7][q] * x[0][q];
      c[6][q] = x[1][q] * x[5][q] - x[2][q] * x[4][q];
      c[7][q] = x[2][q] * x[3][q] - x[0][q] * x[5][q];
      c[8][q] = x[0][q] * x[4][q] - x[1][q] * x[3][q];
    }
    for (int q = 0; q < Q; ++q) {
      Scalar nc = 0, nx = 0;
      for (int i = 0; i < 9; ++i) nc += c[i][q] * c[i][q], nx += x[i][q] * x[i][q];
      const Scalar d = x[0][q] * c[0][q] + x[1][q] * c[1][q] + x[2][q] * c[2][q];
      const Scalar g = std::sqrt(std::sqrt(nc) / (d * std::sqrt(nx)));
      // X <- (g X + cof X / (g det X)) / 2 where far; X unchanged elsewhere
      a[q] = far[q] ? 0.5 * g : 1.0;
      b[q] = far[q] ? 0.5 / (g * d) : 0.0;
    }
    for (int i = 0; i < 9; ++i)
      for (int q = 0; q < Q; ++q) x[i][q] = a[q] * x[i][q] + b[q] * c[i][q];
    any_far = false;
    for (int q = 0; q < Q; ++q) {
      Scalar xq[9];
      for (int i = 0; i < 9; ++i) xq[i] = x[i][q];
      far[q] = far[q] && !(detail::GramDeviation<Scalar>(xq).squared_norm() < 1.0 / 16);
      any_far = any_far || far[q];
    }
  }
  for (int q = 0; q < Q; ++q) {
    alone[q] = alone[q] || far[q];  // not brought near in 40 steps (not seen): one at a time
    any_alone = any_alone || alone[q];
  }
  if (any_alone)
    for (int q = 0; q < Q; ++q)
      if (alone[q])
        for (int i = 0; i < 9; ++i) x[i][q] = i % 4 == 0 ? 1 : 0;
  bool converged = false;
  for (int k = 0; k < 40 && !converged; ++k) {
    // E = X^T X - I (6 entries), then X <- X - X E / 2.
    Scalar e00[Q], e11[Q], e22[Q], e01[Q], e02[Q], e12[Q];
    int unconverged = 0;  // an integer or-reduction vectorises; a max of doubles does not
    for (int q = 0; q < Q; ++q) {
      e00[q] = x[0][q] * x[0][q] + x[1][q] * x[1][q] + x[2][q] * x[2][q] - 1;
      e11[q] = x[3][q] * x[3][q] + x[4][q] * x[4][q] + x[5][q] * x[5][q] - 1;
      e22[q] = x[6][q] * x[6][q] + x[7][q] * x[7][q] + x[8][q] * x[8][q] - 1;
      e01[q] = x[0][q] * x[3][q] + x[1][q] * x[4][q] + x[2][q] * x[5][q];
      e02[q] = x[0][q] * x[6][q] + x[1][q] * x[7][q] + x[2][q] * x[8][q];
      e12[q] = x[3][q] * x[6][q] + x[4][q] * x[7][q] + x[5][q] * x[8][q];
      const Scalar n2 = e00[q] * e00[q] + e11[q] * e11[q] + e22[q] * e22[q] +
                        2 * (e01[q] * e01[q] + e02[q] * e02[q] + e12[q] * e12[q]);
      unconverged |= !(n2 < 1e-16);  // NaN: not converged
    }
    for (int r = 0; r < 3; ++r)
      for (int q = 0; q < Q; ++q) {
        const Scalar a = x[r][q], b = x[r + 3][q], c = x[r + 6][q];
        x[r][q] = a - 0.5 * (a * e00[q] + b * e01[q] + c * e02[q]);
        x[r + 3][q] = b - 0.5 * (a * e01[q] + b * e11[q] + c * e12[q]);
        x[r + 6][q] = c - 0.5 * (a * e02[q] + b * e12[q] + c * e22[q]);
      }
    converged = !unconverged;  // every point: |E| < 1e-8 before this step, ~1e-16 after
  }
  for (int i = 0; i < 9; ++i)
    for (int q = 0; q < Q; ++q) R[i](q) = x[i][q];
  if (!any_alone && converged) return;
  for (int q = 0; q < Q; ++q) {
    if (!alone[q] && converged) continue;
    Mat3 Fq;
    for (int i = 0; i < 9; ++i) Fq.data()[i] = F[i](q);
    const Mat3 Rq = rotation_of(Fq);
    for (int i = 0; i < 9; ++i) R[i](q) = Rq.data()[i];
  }
}

/// The same for matrices given one per point.
template <int Q>
void rotations_of(const std::array<Mat3, Q>& F, std::array<Mat3, Q>& R) {
  if constexpr (Q == 1) {
    R[0] = rotation_of(F[0]);
  } else {
    PointMat3<Q> f, r;
    for (int q = 0; q < Q; ++q)
      for (int i = 0; i < 9; ++i) f[i](q) = F[q].data()[i];
    rotations_of<Q>(f, r);
    for (int q = 0; q < Q; ++q)
      for (int i = 0; i < 9; ++i) R[q].data()[i] = r[i](q);
  }
}

}  // namespace plastifem
