#pragma once
// Mass matrix and body-force loads: the rest-shape integrals every dynamic scene needs, shared
// by the Solver and by anything that composes the toolkit's parts itself (bench/ does).
//
//   consistent mass   m_ab = rho int N_a N_b dV             (block m_ab I3)
//   HRZ-lumped mass   m_aa = diag(m) * sum(m) / tr(m)       (Hinton-Rock-Zienkiewicz)
//   body force        f_a  = rho int N_a g dV                (gravity: consistent nodal loads)
// Both integrals use the element's mass rule (E::mass_degree), exact for N_a N_b on affine
// elements.
#include <plastifem/assembly/assembler.hpp>

namespace plastifem {

enum class MassKind { Consistent, Lumped };

template <FiniteElement E>
using ElementScalarMatrix = Eigen::Matrix<Scalar, E::num_nodes, E::num_nodes>;

/// The N x N scalar mass matrix of one element (rest nodes X).
template <FiniteElement E>
ElementScalarMatrix<E> element_mass(const ElementNodes<E>& X, Scalar density, MassKind kind) {
  const auto q = E::template quadrature<E::mass_degree>();
  ElementScalarMatrix<E> m = ElementScalarMatrix<E>::Zero();
  for (int k = 0; k < q.size; ++k) {
    const auto Nk = E::shape(q.points[k]);
    m += (density * q.weights[k] * jacobian<E>(X, q.points[k]).determinant()) * Nk * Nk.transpose();
  }
  if (kind == MassKind::Lumped) {
    // HRZ lumping: the diagonal scaled to keep the element mass; positive for Tet10, whose row
    // sums would give negative corner masses.
    const Scalar total = m.sum(), diag = m.diagonal().sum();
    const Eigen::Matrix<Scalar, E::num_nodes, 1> d = m.diagonal() * (total / diag);
    m.setZero();
    m.diagonal() = d;
  }
  return m;
}

/// M = the assembled mass matrix (its values are overwritten; pattern from `assembler`).
template <FiniteElement E>
void assemble_mass(const Mesh<E>& mesh, const Assembler<E>& assembler, Scalar density, MassKind kind,
                   BlockSymmetricMatrix& M) {
  M = assembler.zero_matrix();
  for (Index e = 0; e < mesh.num_elements(); ++e)
    assembler.add_element_scalar_matrix(e, element_mass<E>(mesh.element_nodes(e), density, kind), M.values());
}

/// Consistent nodal loads of a body force per unit mass g (gravity): f_a = rho int N_a g dV.
template <FiniteElement E>
Vector body_force_load(const Mesh<E>& mesh, Scalar density, const Vec3& g) {
  Vector F = Vector::Zero(3 * mesh.num_nodes());
  const auto q = E::template quadrature<E::mass_degree>();
  for (Index e = 0; e < mesh.num_elements(); ++e) {
    const ElementNodes<E> X = mesh.element_nodes(e);
    for (int k = 0; k < q.size; ++k) {
      const Scalar dm = density * q.weights[k] * jacobian<E>(X, q.points[k]).determinant();
      const auto Nk = E::shape(q.points[k]);
      for (int a = 0; a < E::num_nodes; ++a) F.segment<3>(3 * mesh.element(e)[a]) += dm * Nk[a] * g;
    }
  }
  return F;
}

}  // namespace plastifem
