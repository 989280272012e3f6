#pragma once
// Rotations as axis-angle vectors: the logarithm and exponential maps of SO(3), powers R^eta,
// and the geodesic distance Phi(R1, R2) = |log(R1 R2^T)| in [0, pi] (Huynh 2009, metric
// Phi_6), which seed 000 uses to measure rotational distortion (eq. 5-6).
//
// Robust over the whole of SO(3):
//  - the angle is atan2(|a|, c) with a = axial(R - R^T) / 2 = sin(theta) n and
//    c = (tr R - 1) / 2 = cos(theta): accurate near 0 and near pi, where acos(c) loses half
//    the digits;
//  - below pi/2 the axis comes from a (theta / sin(theta) by its series near 0);
//  - from pi/2 up, where a vanishes towards pi, from the symmetric part
//    (R + R^T) / 2 - c I = (1 - c) n n^T (its largest column), signed by a. At exactly pi both
//    axis signs are the same rotation; the one from the largest column is returned.
#include <plastifem/core/types.hpp>

#include <algorithm>
#include <cmath>

namespace plastifem {

// Each function is written in the Lazy form (core/types.hpp): its Eigen code depends on L, so a
// file that includes this header and calls nothing compiles none of it.

/// The skew-symmetric matrix of w: hat(w) v = w x v.
template <class L = void>  // see Lazy (core/types.hpp)
Eigen::Matrix<Lazy<L>, 3, 3> hat(const Vec3& w_) {
  const Eigen::Matrix<Lazy<L>, 3, 1>& w = w_;
  Eigen::Matrix<Lazy<L>, 3, 3> W;
  W << 0, -w.z(), w.y(), w.z(), 0, -w.x(), -w.y(), w.x(), 0;
  return W;
}

/// The rotation angle of R in [0, pi].
template <class L = void>  // see Lazy (core/types.hpp)
Lazy<L> rotation_angle(const Mat3& R_) {
  const Eigen::Matrix<Lazy<L>, 3, 3>& R = R_;
  const Eigen::Matrix<Lazy<L>, 3, 1> a(0.5 * (R(2, 1) - R(1, 2)), 0.5 * (R(0, 2) - R(2, 0)), 0.5 * (R(1, 0) - R(0, 1)));
  return std::atan2(a.norm(), 0.5 * (R.trace() - 1));
}

/// log(R) as a rotation vector w = theta n, |w| = theta in [0, pi].
template <class L = void>  // see Lazy (core/types.hpp)
Eigen::Matrix<Lazy<L>, 3, 1> rotation_log(const Mat3& R_) {
  using M3 = Eigen::Matrix<Lazy<L>, 3, 3>;
  using V3 = Eigen::Matrix<Lazy<L>, 3, 1>;
  const M3& R = R_;
  const V3 a(0.5 * (R(2, 1) - R(1, 2)), 0.5 * (R(0, 2) - R(2, 0)), 0.5 * (R(1, 0) - R(0, 1)));
  const Scalar s = a.norm(), c = 0.5 * (R.trace() - 1);
  const Scalar theta = std::atan2(s, c);
  if (c > 0) {
    // theta < pi/2: w = a theta / sin(theta); the series 1 + theta^2 / 6 below 1e-4 (error
    // theta^4 / 120 < 1e-18).
    const Scalar f = theta < 1e-4 ? 1 + theta * theta / 6 : theta / s;
    return f * a;
  }
  // theta >= pi/2: n n^T = ((R + R^T) / 2 - c I) / (1 - c), with 1 - c >= 1.
  const M3 B = 0.5 * (R + R.transpose()) - c * M3::Identity();
  int k = 0;
  B.diagonal().maxCoeff(&k);
  V3 n = B.col(k) / std::sqrt(std::max(B(k, k), Scalar(0)) * (1 - c));
  n.normalize();
  if (n.dot(a) < 0) n = -n;
  return theta * n;
}

/// exp(hat(w)): Rodrigues' formula, with series for the coefficients below |w| = 1e-4.
template <class L = void>  // see Lazy (core/types.hpp)
Eigen::Matrix<Lazy<L>, 3, 3> rotation_exp(const Vec3& w_) {
  using M3 = Eigen::Matrix<Lazy<L>, 3, 3>;
  const Eigen::Matrix<Lazy<L>, 3, 1>& w = w_;
  const Scalar t2 = w.squaredNorm(), t = std::sqrt(t2);
  Scalar A, B;  // sin(t) / t and (1 - cos(t)) / t^2
  if (t < 1e-4) {
    A = 1 - t2 / 6;
    B = 0.5 - t2 / 24;
  } else {
    A = std::sin(t) / t;
    B = (1 - std::cos(t)) / t2;
  }
  const M3 W = hat<L>(w);
  return M3::Identity() + A * W + B * W * W;
}

/// R^eta = exp(eta log R): the rotation about R's axis by eta times its angle.
template <class L = void>  // see Lazy (core/types.hpp)
Eigen::Matrix<Lazy<L>, 3, 3> rotation_power(const Mat3& R, Scalar eta) {
  return rotation_exp<L>(eta * rotation_log<L>(R));
}

/// Phi(R1, R2) = |log(R1 R2^T)|: the angle of the rotation taking R2 to R1, in [0, pi].
template <class L = void>  // see Lazy (core/types.hpp)
Lazy<L> geodesic_distance(const Mat3& R1_, const Mat3& R2_) {
  using M3 = Eigen::Matrix<Lazy<L>, 3, 3>;
  const M3& R1 = R1_;
  const M3& R2 = R2_;
  return rotation_angle<L>(R1 * R2.transpose());
}

}  // namespace plastifem
