#pragma once
// Rotation part of a deformation gradient, F = R S (R a proper rotation, S symmetric).
//
// Well-conditioned F (det F > 0, not near singular): Higham's scaled Newton iteration
//   X_{k+1} = (g X_k + X_k^{-T} / g) / 2,  g = sqrt(|X_k^{-1}| / |X_k|)  (Frobenius norms),
// which converges quadratically to the orthogonal polar factor, ~6 iterations from any
// moderately stretched F. Near-singular or reflected F (det F <= 0, an inverted element):
// SVD F = U diag(s) V^T with the sign of the smallest singular value flipped so that
// det R = +1 (Irving, Teran and Fedkiw 2004, "invertible FEM"): the element is then treated as
// a rotated element compressed through zero in its weakest direction, and pushed back.
#include <plastifem/core/types.hpp>

#include <Eigen/SVD>
#include <cmath>

namespace plastifem {

/// Closest proper rotation to F (det R = +1), robust to degenerate and inverted F.
inline Mat3 rotation_of(const Mat3& F) {
  const Scalar scale = F.norm();
  if (!(scale > 0) || !std::isfinite(scale)) return Mat3::Identity();
  const Mat3 X0 = F / scale;  // unit Frobenius norm: thresholds below are relative
  if (X0.determinant() > 1e-3) {
    Mat3 X = X0;
    for (int k = 0; k < 30; ++k) {
      const Mat3 Xinv = X.inverse();
      const Scalar g = std::sqrt(Xinv.norm() / X.norm());
      const Mat3 Xn = 0.5 * (g * X + Xinv.transpose() / g);
      const Scalar change = (Xn - X).norm();
      X = Xn;
      if (change < 1e-13) return X;
    }
  }
  Eigen::JacobiSVD<Mat3> svd(X0, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Mat3 U = svd.matrixU();
  const Mat3 V = svd.matrixV();
  if ((U * V.transpose()).determinant() < 0) U.col(2) *= -1;  // singular values sorted: col 2 is smallest
  return U * V.transpose();
}

}  // namespace plastifem
