#pragma once
// Random elements for the hyperelastic tests (test_hyperelastic, test_mooney_rivlin): a
// distorted reference element, a deformed copy of it, and a large rotation.
#include <plastifem/plastifem.hpp>

#include <random>
#include <type_traits>
#include <utility>

namespace plastifem::testing {

/// The reference element with its vertices moved by up to 0.1 (Tet10's mid-edge nodes kept at
/// their edges' midpoints).
template <FiniteElement E>
ElementNodes<E> distorted_element(std::mt19937& rng) {
  std::uniform_real_distribution<Scalar> u(-0.1, 0.1);
  ElementNodes<E> X = E::reference_nodes();
  for (int a = 0; a < E::num_vertices; ++a) X.col(a) += Vec3(u(rng), u(rng), u(rng));
  if constexpr (std::is_same_v<E, Tet10>)
    for (int k = 0; k < 6; ++k) X.col(4 + k) = 0.5 * (X.col(E::edges[k][0]) + X.col(E::edges[k][1]));
  return X;
}

/// X deformed by a random homogeneous gradient I + G (|G_ij| <= delta) and a random nodal part.
template <FiniteElement E>
ElementNodes<E> deformed(const ElementNodes<E>& X, Scalar delta, std::mt19937& rng) {
  std::uniform_real_distribution<Scalar> u(-delta, delta);
  Mat3 G;
  for (int i = 0; i < 9; ++i) G.data()[i] = u(rng);
  ElementNodes<E> x = (Mat3::Identity() + G) * X;  // a homogeneous part ...
  for (int a = 0; a < E::num_nodes; ++a) x.col(a) += 0.3 * Vec3(u(rng), u(rng), u(rng));  // ... and a random one
  return x;
}

/// A rotation by 1.1 rad about a generic axis.
inline Mat3 big_rotation() { return Eigen::AngleAxisd(1.1, Vec3(1, -2, 0.5).normalized()).toRotationMatrix(); }

/// Central differences with step h of an element model's energy and force at x: the gradient
/// of W (to compare with the force) and the Jacobian of f (with the tangent).
template <class M, FiniteElement E, class Data>
std::pair<ElementVector<E>, ElementMatrix<E>> element_differences(const Data& d, const ElementNodes<E>& x, Scalar h) {
  ElementVector<E> grad, fp, fm;
  ElementMatrix<E> jac;
  for (int i = 0; i < 3 * E::num_nodes; ++i) {
    ElementNodes<E> xp = x, xm = x;
    xp.data()[i] += h;
    xm.data()[i] -= h;
    grad[i] = (M::template evaluate<E>(d, xp, fp, nullptr) - M::template evaluate<E>(d, xm, fm, nullptr)) / (2 * h);
    jac.col(i) = (fp - fm) / (2 * h);
  }
  return {grad, jac};
}

}  // namespace plastifem::testing
