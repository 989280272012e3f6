#pragma once
// The centre of mass of the piece beyond a cut at x = xc (a plane across a bar along x), for
// the free-fall tests of X-FEM (test_enrichment.cpp, test_plastic_cut.cpp): integrated over the
// mass points of the cut elements' pieces above the cut (side 0) and of the elements wholly
// beyond it, with the mesh's densities (the mass matrix's). Returns (volume, z of the centre).
// And the momentum of that piece (free_piece_momentum), for the tests of loads on a cut body.
#include <plastifem/enrichment/cut_element.hpp>
#include <plastifem/plastifem.hpp>

#include <utility>

template <class S>
std::pair<plastifem::Scalar, plastifem::Scalar> free_piece_centre(const S& s, plastifem::Scalar xc) {
  using namespace plastifem;
  using E = typename S::Element;
  const Mesh<E>& mesh = s.mesh();
  const Vector& u = s.displacement();
  Scalar m = 0, mz = 0;
  for (Index e = 0; e < mesh.num_elements(); ++e) {
    const ElementNodes<E> X = mesh.element_nodes(e);
    ElementNodes<E> U;
    for (int a = 0; a < E::num_nodes; ++a) U.col(a) = u.template segment<3>(3 * mesh.element(e)[a]);
    const CutElement<E>* c = s.enrichment().element(e);
    if (c && c->num_sides == 1 && X.row(0).mean() < xc) continue;  // a blending element on the clamped side
    if (c) {
      // Side 0 of a cut element is above the cut (x > xc); a blending element beyond the cut
      // has its one side, with psi[0].
      ElementNodes<E> Us = U;
      for (const EnrichedDof& d : c->enriched) Us.col(d.node) += d.psi[0] * u.template segment<3>(3 * d.row);
      for (size_t q = 0; q < c->mass_xi[0].size(); ++q) {
        m += c->mass_dv[0][q];
        mz += c->mass_dv[0][q] * (Us * E::shape(c->mass_xi[0][q])).z();
      }
      continue;
    }
    if (X.row(0).mean() < xc) continue;
    const auto q = E::template quadrature<E::mass_degree>();
    for (int k = 0; k < q.size; ++k) {
      const Scalar dv = q.weights[k] * jacobian<E>(X, q.points[k]).determinant();
      m += dv, mz += dv * (U * E::shape(q.points[k])).z();
    }
  }
  return {m, mz / m};
}

/// The rigid translation along d of the piece on which `on_free` holds, in the dofs of a body cut
/// through by one cut (its first): a node's enriched dof takes the value that makes its field 1
/// on the free side and 0 on the other.
template <class S, class OnFree>
plastifem::Vector free_piece_translation(const S& s, const OnFree& on_free, int d) {
  using namespace plastifem;
  using Enrich = typename S::EnrichmentPolicy;
  const auto& mesh = s.mesh();
  const auto& en = s.enrichment();
  Vector r = Vector::Zero(s.num_dofs());
  for (Index i = 0; i < mesh.num_nodes(); ++i) {
    if (const Index row = en.row(0, i); row >= 0) {
      const Scalar h = en.sign(0, i), free = Enrich::psi(1, h), held = Enrich::psi(-1, h);
      r[3 * row + d] = 1 / (free - held);
      r[3 * i + d] = -held / (free - held);
    } else {
      r[3 * i + d] = on_free(Vec3(mesh.node(i)));
    }
  }
  return r;
}

/// The momentum along d of the piece x > xc of a bar cut through by one cut: r_d^T M v with r_d
/// its rigid translation (free_piece_translation). With the body held on the other piece only,
/// it grows by exactly F dt per step under a force F on the free piece (f_int does no work on a
/// rigid translation of a piece, r_d is zero where the body is held, and Newmark's update keeps
/// r^T M v - t r^T f_ext), to the solves' residuals.
template <class S>
plastifem::Scalar free_piece_momentum(const S& s, plastifem::Scalar xc, int d) {
  const auto r = free_piece_translation(s, [xc](const plastifem::Vec3& X) { return X.x() > xc; }, d);
  return r.dot(s.mass_matrix() * s.velocity());
}
