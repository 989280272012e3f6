#pragma once
// Points fixed in a body's material: a visual surface's vertices, a sensor, a grasp point.
// Each is located once in the rest mesh (its element and reference coordinates xi, by a
// PointLocator) and its field is interpolated from the nodal values every step,
//   u(X) = sum_a N_a(xi) u_a                                   (a standard element),
//   u(X) = sum_a N_a(xi) (u_a + sum_{k at a} psi_k^s a_k)      (an enriched one, seed 001 eq. 42),
// with s the side of the cut the point lies on: the piece of the cut element (a reference
// tetrahedron of CutElement::pieces[s]) that contains xi, the same pieces the element is
// integrated and written over, so a point in a cut element moves with its own piece. A
// blending element (enriched nodes, not cut) has one side. Sides are assigned again after
// every cut (assign_sides).
#include <plastifem/enrichment/enrichment.hpp>
#include <plastifem/mesh/selection.hpp>

#include <span>
#include <vector>

namespace plastifem {

template <FiniteElement E>
class EmbeddedPoints {
 public:
  static constexpr int N = E::num_nodes;

  /// Locates every point of X (rest coordinates) in the mesh; a point in no element is refused
  /// with InvalidArgument naming it.
  EmbeddedPoints(const Mesh<E>& mesh, std::span<const Vec3> X) : mesh_(&mesh) {
    const PointLocator<E> locator(mesh);
    element_.reserve(X.size()), xi_.reserve(X.size()), shape_.reserve(X.size());
    for (size_t k = 0; k < X.size(); ++k) {
      const auto where = locator.locate(X[k]);
      if (!where)
        fail<InvalidArgument>("embedded point {} at ({}, {}, {}) is in no element of the mesh (rest configuration)", k,
                              X[k].x(), X[k].y(), X[k].z());
      element_.push_back(where->element), xi_.push_back(where->xi), shape_.push_back(E::shape(where->xi));
    }
    side_.assign(X.size(), 0);
  }

  Index size() const { return static_cast<Index>(element_.size()); }
  Index element(Index k) const { return element_[k]; }
  const Vec3& xi(Index k) const { return xi_[k]; }
  /// The side of the cut point k lies on (0 outside cut elements).
  int side(Index k) const { return side_[k]; }

  /// Each point's side in its element of `enrichment` (after a cut, or a grown one).
  void assign_sides(const Enrichment<E>& enrichment) {
    for (size_t k = 0; k < element_.size(); ++k) {
      const CutElement<E>* cut = enrichment.element(element_[k]);
      side_[k] = cut && cut->num_sides == 2 ? side_of(*cut, xi_[k]) : 0;
    }
  }

  /// out.col(k) = the field of nodal values u (3 per dof block: the nodes', then the enriched
  /// rows) at point k; enriched rows are read where `enrichment` enriches the point's element.
  void interpolate(const Vector& u, Eigen::Matrix3Xd& out, const Enrichment<E>* enrichment = nullptr) const {
    out.resize(3, size());
    for (size_t k = 0; k < element_.size(); ++k) {
      const auto& c = mesh_->element(element_[k]);
      Vec3 x = Vec3::Zero();
      for (int a = 0; a < N; ++a) x += shape_[k][a] * u.template segment<3>(3 * c[a]);
      if (const CutElement<E>* cut = enrichment ? enrichment->element(element_[k]) : nullptr)
        for (const EnrichedDof& d : cut->enriched)
          x += (shape_[k][d.node] * d.psi[side_[k]]) * u.template segment<3>(3 * d.row);
      out.col(static_cast<Index>(k)) = x;
    }
  }

 private:
  /// The side whose pieces contain xi; on the interface (round-off), the one it is least
  /// outside of.
  static int side_of(const CutElement<E>& cut, const Vec3& xi) {
    int best = 0;
    Scalar best_outside = std::numeric_limits<Scalar>::infinity();
    for (int s = 0; s < 2; ++s)
      for (const ReferenceTet& t : cut.pieces[s]) {
        Mat3 A;
        for (int j = 0; j < 3; ++j) A.col(j) = t[j + 1] - t[0];
        const Vec3 b = A.partialPivLu().solve(Vec3(xi - t[0]));
        const Scalar outside = std::max({Scalar(0), -b.minCoeff(), b.sum() - 1});
        if (outside < best_outside) best_outside = outside, best = s;
        if (outside == 0) return s;
      }
    return best;
  }

  const Mesh<E>* mesh_;
  std::vector<Index> element_;
  std::vector<Vec3> xi_;
  std::vector<typename E::ShapeVector> shape_;
  std::vector<int> side_;
};

}  // namespace plastifem
