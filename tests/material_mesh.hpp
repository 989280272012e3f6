#pragma once
// Measures of a material (rest) mesh moved by plastic flow, for the plasticity tests: its
// volume, and the best rigid fit between two placements of its nodes (Kabsch), to compare
// material meshes up to rigid motion.
#include <plastifem/core/polar.hpp>
#include <plastifem/core/types.hpp>
#include <plastifem/element/element.hpp>
#include <plastifem/mesh/mesh.hpp>

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

/// The volume of the mesh's elements with nodes at x (the material mesh: sum of exact element
/// volumes).
template <FiniteElement E>
Scalar material_volume(const Mesh<E>& mesh, const Eigen::Matrix3Xd& x) {
  Scalar v = 0;
  for (Index e = 0; e < mesh.num_elements(); ++e) {
    ElementNodes<E> X;
    for (int a = 0; a < E::num_nodes; ++a) X.col(a) = x.col(mesh.element(e)[a]);
    v += element_volume<E>(X);
  }
  return v;
}

}  // namespace plastifem::test
