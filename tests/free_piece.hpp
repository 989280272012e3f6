#pragma once
// The centre of mass of the piece beyond a cut at x = xc (a plane across a bar along x), for
// the free-fall tests of X-FEM (test_enrichment.cpp, test_plastic_cut.cpp): integrated over the
// mass points of the cut elements' pieces above the cut (side 0) and of the elements wholly
// beyond it, with the mesh's densities (the mass matrix's). Returns (volume, z of the centre).
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
