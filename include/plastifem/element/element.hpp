#pragma once
// What a finite element trait must provide, and the geometry every element shares:
// Jacobian, physical shape gradients, volume.
#include <plastifem/element/hex8.hpp>
#include <plastifem/element/tet10.hpp>
#include <plastifem/element/tet4.hpp>

#include <concepts>

namespace plastifem {

/// A reference element: nodes, shape functions N(xi) and their gradients dN/dxi, quadrature
/// rules, boundary faces and edges, and the VTK cell type used for output.
template <class E>
concept FiniteElement = requires(const Vec3& xi) {
  { E::name } -> std::convertible_to<const char*>;
  { E::num_nodes } -> std::convertible_to<int>;
  { E::num_vertices } -> std::convertible_to<int>;
  { E::vtk_cell_type } -> std::convertible_to<int>;
  { E::reference_volume } -> std::convertible_to<Scalar>;
  { E::reference_nodes() } -> std::same_as<Eigen::Matrix<Scalar, 3, E::num_nodes>>;
  { E::shape(xi) } -> std::same_as<Eigen::Matrix<Scalar, E::num_nodes, 1>>;
  { E::gradient(xi) } -> std::same_as<Eigen::Matrix<Scalar, E::num_nodes, 3>>;
  E::faces[0][E::nodes_per_face - 1];
  E::edges[0][1];
  E::template quadrature<E::stiffness_degree>();
  E::template quadrature<E::mass_degree>();
};

static_assert(FiniteElement<Tet4> && FiniteElement<Tet10> && FiniteElement<Hex8>);

/// Node coordinates of one element, one node per column.
template <FiniteElement E>
using ElementNodes = Eigen::Matrix<Scalar, 3, E::num_nodes>;

/// J = dx/dxi = X dN/dxi at the reference point xi.
template <FiniteElement E>
Mat3 jacobian(const ElementNodes<E>& X, const Vec3& xi) {
  return X * E::gradient(xi);
}

/// Shape gradients with respect to physical coordinates: dN/dx = dN/dxi J^{-1}.
template <FiniteElement E>
Eigen::Matrix<Scalar, E::num_nodes, 3> physical_gradient(const ElementNodes<E>& X, const Vec3& xi) {
  const auto dN = E::gradient(xi);
  return dN * (X * dN).inverse();
}

/// Volume of an element, exact for the element's own geometry: det J has the degree of the
/// mass integrand or less (Tet4: 0, Tet10: 3, Hex8: 2 per variable).
template <FiniteElement E>
Scalar element_volume(const ElementNodes<E>& X) {
  const auto q = E::template quadrature<E::mass_degree>();
  Scalar v = 0;
  for (int k = 0; k < q.size; ++k) v += q.weights[k] * jacobian<E>(X, q.points[k]).determinant();
  return v;
}

}  // namespace plastifem
