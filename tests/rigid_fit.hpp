#pragma once
// The best rigid fit between two placements of the same points (Kabsch), for tests that compare
// material meshes up to rigid motion.
#include <plastifem/core/polar.hpp>
#include <plastifem/core/types.hpp>

#include <algorithm>

namespace plastifem::test {

struct RigidFit {
  Scalar angle;      ///< the fitted rotation's angle (rad)
  Scalar non_rigid;  ///< the largest distance of a point of b from a moved by the fit
};

/// The rotation and translation that best map the columns of a onto those of b: the rotation of
/// sum_i (b_i - b_mean)(a_i - a_mean)^T; what is left is the non-rigid part.
inline RigidFit rigid_fit(const Eigen::Matrix3Xd& a, const Eigen::Matrix3Xd& b) {
  const Vec3 ca = a.rowwise().mean(), cb = b.rowwise().mean();
  Mat3 H = Mat3::Zero();
  for (Index i = 0; i < a.cols(); ++i) H += (b.col(i) - cb) * (a.col(i) - ca).transpose();
  const Mat3 R = detail::rotation_by_svd(H);
  Scalar worst = 0;
  for (Index i = 0; i < a.cols(); ++i) worst = std::max(worst, (b.col(i) - cb - R * (a.col(i) - ca)).norm());
  return {Eigen::AngleAxisd(R).angle(), worst};
}

}  // namespace plastifem::test
