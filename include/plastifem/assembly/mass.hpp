#pragma once
// Mass matrix and body-force loads: the rest-shape integrals every dynamic scene needs, shared
// by the Solver and by anything that composes the toolkit's parts itself (bench/ does).
//
//   consistent mass   m_ab = rho int N_a N_b dV             (block m_ab I3)
//   HRZ-lumped mass   m_aa = diag(m) * sum(m) / tr(m)       (Hinton-Rock-Zienkiewicz)
//   body force        f_a  = rho int N_a g dV  with the consistent mass,  m_aa g  with the lumped
// Both integrals use the element's mass rule (E::mass_degree), exact for N_a N_b det J on the
// element's own geometry (Tet4, Tet10 with straight edges, trilinear Hex8).
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
    const Scalar dm = density * q.weights[k] * jacobian<E>(X, q.points[k]).determinant();
    for (int b = 0; b < E::num_nodes; ++b)
      for (int a = 0; a < E::num_nodes; ++a) m(a, b) += dm * Nk[a] * Nk[b];
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

/// rho int N_a dV per node a, over the element's mass rule: its consistent nodal loads per unit
/// body force (the row sums of its consistent mass, since sum_b N_b = 1).
template <FiniteElement E>
Eigen::Matrix<Scalar, E::num_nodes, 1> element_nodal_mass(const ElementNodes<E>& X, Scalar density) {
  const auto q = E::template quadrature<E::mass_degree>();
  Eigen::Matrix<Scalar, E::num_nodes, 1> v = Eigen::Matrix<Scalar, E::num_nodes, 1>::Zero();
  for (int k = 0; k < q.size; ++k)
    v += (density * q.weights[k] * jacobian<E>(X, q.points[k]).determinant()) * E::shape(q.points[k]);
  return v;
}

/// M = the element scalar mass matrices mass_of(e) scattered into `assembler`'s pattern (M's
/// values are overwritten).
template <FiniteElement E, class ElementMassOf>
void scatter_mass(const Mesh<E>& mesh, const Assembler<E>& assembler, ElementMassOf&& mass_of, BlockSymmetricMatrix& M) {
  M = assembler.zero_matrix();
  for (Index e = 0; e < mesh.num_elements(); ++e) assembler.add_element_scalar_matrix(e, mass_of(e), M.values());
}

/// M = the assembled mass matrix (its values are overwritten; pattern from `assembler`).
template <FiniteElement E>
void assemble_mass(const Mesh<E>& mesh, const Assembler<E>& assembler, Scalar density, MassKind kind,
                   BlockSymmetricMatrix& M) {
  scatter_mass(
      mesh, assembler,
      [&](Index e) { return element_mass<E>(mesh.element_nodes(e), density * mesh.weight(e), kind); }, M);
}

/// Nodal loads of a body force per unit mass g (gravity), paired with the mass matrix so that
/// an unconstrained body falls at exactly g: with the consistent mass, the consistent loads
/// f_a = rho int N_a g dV (= M 1g, since sum_b N_b = 1); with the lumped mass, f_a = m_aa g
/// (= M_L 1g). Consistent loads with a lumped mass would not: on Tet10 the corner loads point
/// against gravity while the corner masses are positive. Size: 3 x the mesh's nodes.
template <FiniteElement E>
Vector body_force_load(const Mesh<E>& mesh, Scalar density, const Vec3& g, MassKind kind = MassKind::Consistent) {
  Vector F = Vector::Zero(3 * mesh.num_nodes());
  for (Index e = 0; e < mesh.num_elements(); ++e) {
    const ElementNodes<E> X = mesh.element_nodes(e);
    const auto& c = mesh.element(e);
    const Scalar rho = density * mesh.weight(e);
    const Eigen::Matrix<Scalar, E::num_nodes, 1> m =
        kind == MassKind::Lumped ? element_mass<E>(X, rho, MassKind::Lumped).diagonal().eval() : element_nodal_mass<E>(X, rho);
    for (int a = 0; a < E::num_nodes; ++a) F.segment<3>(3 * c[a]) += m[a] * g;
  }
  return F;
}

}  // namespace plastifem
