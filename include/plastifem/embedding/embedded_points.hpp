#pragma once
// Points fixed in a body's material: a visual surface's vertices, a sensor, a grasp point.
// Each is located once in the rest mesh (its element and reference coordinates xi, by a
// PointLocator) and its fields are interpolated from the nodal values whenever asked,
//   u(X) = sum_a N_a(xi) u_a                                   (a standard element),
//   u(X) = sum_a N_a(xi) (u_a + sum_{k at a} psi_k^s a_k)      (an enriched one, seed 001 eq. 42),
// with s the side of the cut the point lies on: the piece of the cut element (a reference
// tetrahedron of CutElement::pieces[s]) that contains xi, the same pieces the element is
// integrated and written over, so a point in a cut element moves with its own piece. A
// blending element (enriched nodes, not cut) has one side.
//
// With a Solver (any composition), per point and in the order given:
//   displacements, velocities  u(X), v(X) as above;
//   positions                  x = X + u(X), X = sum N_a X_a (the point itself; at a node, the
//                              node's position exactly);
//   material_positions         sum N_a Xbar_a, Xbar the material mesh (moved by plastic flow);
//   stresses                   the Cauchy stress of the point's element at its centre, of its
//                              own piece in a cut element (Solver::stress): constant per
//                              element, as the VTU cell data.
// Sides are assigned again by these calls whenever the solver's cuts changed (a new or grown
// cut), so a point follows the tissue as it opens. Cost: one pass over the points reading
// N nodal vectors each (bench_points: a 20,000-point surface in a few tenths of a ms).
#include <plastifem/core/parallel.hpp>
#include <plastifem/assembly/discretization.hpp>  // Enrichment and CutElement, declared (enrichment/)
#include <plastifem/mesh/selection.hpp>
#include <plastifem/plastic/hooks.hpp>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <span>
#include <vector>

namespace plastifem {

template <FiniteElement E>
class EmbeddedPoints {
 public:
  static constexpr int N = E::num_nodes;

  /// Locates every point of X (rest coordinates) in the mesh; a point in no element is refused
  /// with InvalidArgument naming it.
  EmbeddedPoints(const Mesh<E>& mesh, std::span<const Vec3> X)
      : EmbeddedPoints(mesh, static_cast<Index>(X.size()), [&](Index k) { return X[static_cast<size_t>(k)]; }) {}
  /// The same, one point per column.
  EmbeddedPoints(const Mesh<E>& mesh, const Eigen::Matrix3Xd& X)
      : EmbeddedPoints(mesh, X.cols(), [&](Index k) { return Vec3(X.col(k)); }) {}
  /// Points on a cut, each with the side it belongs to (0: the level set's >= 0 side, 1: the
  /// other; -1: the side whose piece contains it, as above). In a cut element the given side
  /// is taken; elsewhere the point has the element's one side. (A surface split along a cut
  /// puts two such points at each crossing: embedded_surface.hpp.)
  EmbeddedPoints(const Mesh<E>& mesh, const Eigen::Matrix3Xd& X, std::vector<signed char> sides)
      : EmbeddedPoints(mesh, X) {
    set_sides(std::move(sides));
  }

  /// Points located already, each in element where[k].element at reference coordinates
  /// where[k].xi, with their sides as above: a point on a face shared by a cut element and an
  /// uncut one belongs to the one it is given in (located again, it would go to either).
  EmbeddedPoints(const Mesh<E>& mesh, std::span<const PointLocation> where, std::vector<signed char> sides)
      : num_nodes_(mesh.num_nodes()), num_elements_(mesh.num_elements()) {
    for (size_t k = 0; k < where.size(); ++k) {
      const PointLocation& w = where[k];
      if (w.element < 0 || w.element >= mesh.num_elements() || !w.xi.allFinite() ||
          !in_reference_element<E>(w.xi, 1e-6))
        fail<InvalidArgument>("embedded point {}: element {} of {}, reference point ({}, {}, {}) not in it", k,
                              w.element, mesh.num_elements(), w.xi.x(), w.xi.y(), w.xi.z());
      place(mesh, w);
    }
    side_.assign(where.size(), 0);
    record_samples(mesh);
    set_sides(std::move(sides));
  }

  /// Gives each point the side it belongs to in a cut element (as the constructor above; -1:
  /// the containing piece's), from the next field asked on.
  void set_sides(std::vector<signed char> sides) {
    if (static_cast<Index>(sides.size()) != size())
      fail<InvalidArgument>("embedded points: {} sides for {} points", sides.size(), size());
    for (signed char s : sides)
      if (s < -1 || s > 1) fail<InvalidArgument>("embedded points: side {} (0, 1, or -1 for the containing piece's)", s);
    given_side_ = std::move(sides);
    sides_of_ = 0;
  }

  Index size() const { return static_cast<Index>(element_.size()); }
  Index element(Index k) const { return element_[k]; }
  const Vec3& xi(Index k) const { return xi_[k]; }
  /// The side of the cut point k lies on (0 outside cut elements).
  int side(Index k) const { return side_[k]; }
  /// The points' rest positions sum N_a X_a (at the mesh's nodes; the given points to the
  /// location's round-off).
  void rest_positions(Eigen::Matrix3Xd& out) const {
    out.resize(3, size());
    for (size_t k = 0; k < rest_.size(); ++k) out.col(static_cast<Index>(k)) = rest_[k];
  }

  /// The points were located in this solver's mesh (the solver keeps its own copy): its sizes,
  /// and for the sampled points (see record_samples) their elements' node ids and those nodes'
  /// rest positions, bit for bit. Another mesh of the same sizes (renumbered, moved) would
  /// otherwise give wrong fields silently. At most 64 x N comparisons per call.
  template <class S>
  void check_mesh(const S& solver) const {
    const Mesh<E>& mesh = solver.mesh();
    if (mesh.num_nodes() != num_nodes_ || mesh.num_elements() != num_elements_)
      fail<InvalidArgument>("embedded points: located in a mesh of {} nodes and {} elements, asked for a solver's of "
                            "{} and {}",
                            num_nodes_, num_elements_, mesh.num_nodes(), mesh.num_elements());
    for (size_t i = 0, m = num_samples(); i < m; ++i) {
      const size_t k = sample(i);
      const auto& c = nodes_[k];
      bool same = mesh.element(element_[k]) == c;
      for (int a = 0; a < N && same; ++a) {
        const Vec3 X = mesh.node(c[a]);
        same = std::memcmp(X.data(), sampled_nodes_[i * N + a].data(), 3 * sizeof(Scalar)) == 0;
      }
      if (!same)
        fail<InvalidArgument>("embedded points: located in another mesh (point {}'s element {} has other nodes or "
                              "node positions in the solver's mesh of the same size); locate them in the solver's mesh",
                              k, element_[k]);
    }
  }
  /// Each point's side in its element of `enrichment` (after a cut, or a grown one; the
  /// Solver-level calls below do this themselves).
  void assign_sides(const Enrichment<E>& enrichment) {
    for (size_t k = 0; k < element_.size(); ++k) {
      const CutElement<E>* cut = enrichment.element(element_[k]);
      side_[k] = !(cut && cut->num_sides == 2)        ? 0
                 : !given_side_.empty() && given_side_[k] >= 0 ? given_side_[k]
                                                               : cut->side_containing(xi_[k]);
    }
    sides_of_ = enrichment.instance(), sides_revision_ = enrichment.revision();
  }

  // --- fields of a Solver's committed state (see the file comment) --------------------------
  template <class S>
  void displacements(const S& solver, Eigen::Matrix3Xd& out) {
    field(solver, solver.displacement(), out);
  }
  template <class S>
  void velocities(const S& solver, Eigen::Matrix3Xd& out) {
    field(solver, solver.velocity(), out);
  }
  template <class S>
  void positions(const S& solver, Eigen::Matrix3Xd& out) {
    displacements(solver, out);
    for (size_t k = 0; k < element_.size(); ++k) out.col(static_cast<Index>(k)) += rest_[k];
  }
  template <class S>
  void material_positions(const S& solver, Eigen::Matrix3Xd& out) {
    check_mesh(solver);
    using Hooks = PlasticHooks<typename S::PlasticPolicy, E, typename S::ElasticModel>;
    if (const Vector* rest = Hooks::rest_positions(solver.state().plastic))
      return interpolate(*rest, out, solver.settings().threads);
    rest_positions(out);
  }
  template <class S>
  void stresses(const S& solver, std::vector<Mat3>& out) {
    check_mesh(solver);
    if constexpr (S::EnrichmentPolicy::active) sync_sides(solver.enrichment());
    out.resize(element_.size());
    for (size_t k = 0; k < element_.size(); ++k) out[k] = solver.stress(element_[k], side_[k]);
  }

  /// out.col(k) = the field of nodal values u (3 per node) at point k.
  /// `threads`: OpenMP threads for the points (0: OpenMP's default).
  void interpolate(const Vector& u, Eigen::Matrix3Xd& out, int threads = 1) const {
    interpolate_over(u, out, threads, [](Index, Vec3&) {});
  }
  /// The same in a cut body: u has the enriched rows after the nodes', read where `enrichment`
  /// enriches the point's element, with the point's side (assign_sides first).
  void interpolate(const Vector& u, Eigen::Matrix3Xd& out, const Enrichment<E>& enrichment, int threads = 1) const {
    if (enrichment.instance() != sides_of_ || enrichment.revision() != sides_revision_)
      fail<InvalidArgument>("embedded points: the sides were not assigned for this enrichment or it changed since "
                            "(assign_sides, or the Solver-level calls, which assign them)");
    for (const auto& el : enrichment.elements())
      for (const auto& d : el.enriched)
        if (3 * d.row + 3 > u.size())
          fail<InvalidArgument>("embedded points: a field of {} entries, the enrichment reads row {} (a cut body's "
                                "field has the enriched rows after the nodes')",
                                u.size(), d.row);
    interpolate_over(u, out, threads, [&](Index k, Vec3& x) {
      if (const CutElement<E>* cut = enrichment.element(element_[k]))
        for (const auto& d : cut->enriched) x += (shape_[k][d.node] * d.psi[side_[k]]) * u.template segment<3>(3 * d.row);
    });
  }

 private:
  /// The solver's field f at the points, with its enrichment if it has one.
  template <class S>
  void field(const S& solver, const Vector& f, Eigen::Matrix3Xd& out) {
    check_mesh(solver);
    if constexpr (S::EnrichmentPolicy::active) {
      sync_sides(solver.enrichment());
      interpolate(f, out, solver.enrichment(), solver.settings().threads);
    } else {
      interpolate(f, out, solver.settings().threads);
    }
  }
  /// The sides brought up to date with the enrichment (a new or grown cut changes them).
  template <class Enr>
  void sync_sides(const Enr& enrichment) {
    if (sides_of_ != enrichment.instance() || sides_revision_ != enrichment.revision()) assign_sides(enrichment);
  }
  /// sum_a N_a u_a at every point, plus what enriched(k, x) adds.
  template <class Enriched>
  void interpolate_over(const Vector& u, Eigen::Matrix3Xd& out, int threads, Enriched&& enriched) const {
    if (u.size() < 3 * num_nodes_)
      fail<InvalidArgument>("embedded points: a field of {} entries, the mesh has {} nodes", u.size(), num_nodes_);
    out.resize(3, size());
    parallel_for(size(), threads, [&](Index k) {
      const auto& c = nodes_[k];
      Vec3 x = Vec3::Zero();
      for (int a = 0; a < N; ++a) x += shape_[k][a] * u.template segment<3>(3 * c[a]);
      enriched(k, x);
      out.col(k) = x;
    });
  }

  /// Locates point X(k), k < count (the public constructors' one body).
  template <class Point>
  EmbeddedPoints(const Mesh<E>& mesh, Index count, Point X)
      : num_nodes_(mesh.num_nodes()), num_elements_(mesh.num_elements()) {
    const PointLocator<E> locator(mesh);
    element_.reserve(static_cast<size_t>(count)), xi_.reserve(static_cast<size_t>(count)),
        shape_.reserve(static_cast<size_t>(count));
    for (Index k = 0; k < count; ++k) {
      const Vec3 p = X(k);
      const auto where = locator.locate(p);
      if (!where)
        fail<InvalidArgument>("embedded point {} at ({}, {}, {}) is in no element of the mesh (rest configuration)", k,
                              p.x(), p.y(), p.z());
      place(mesh, *where);
    }
    side_.assign(static_cast<size_t>(count), 0);
    record_samples(mesh);
  }
  /// The points check_mesh compares: up to 64, spread evenly over the list (i * n / m).
  size_t num_samples() const { return std::min<size_t>(element_.size(), 64); }
  size_t sample(size_t i) const { return i * element_.size() / num_samples(); }
  /// The rest positions of the sampled points' element nodes (their ids are in nodes_).
  void record_samples(const Mesh<E>& mesh) {
    sampled_nodes_.clear();
    for (size_t i = 0; i < num_samples(); ++i)
      for (int a = 0; a < N; ++a) sampled_nodes_.push_back(mesh.node(nodes_[sample(i)][a]));
  }
  /// Adds a point at `where`.
  void place(const Mesh<E>& mesh, const PointLocation& where) {
    typename E::ShapeVector n = E::shape(where.xi);
    // A point on a node takes exactly the node's values (Newton's xi is off by round-off).
    for (int a = 0; a < N; ++a)
      if (std::abs(n[a] - 1) <= 1e-12) n.setZero(), n[a] = 1;
    element_.push_back(where.element), xi_.push_back(where.xi), shape_.push_back(n);
    nodes_.push_back(mesh.element(where.element));
    Vec3 at = Vec3::Zero();
    for (int a = 0; a < N; ++a) at += n[a] * mesh.node(nodes_.back()[a]);
    rest_.push_back(at);
  }

  Index num_nodes_, num_elements_;       ///< of the mesh the points were located in
  std::vector<typename Mesh<E>::Connectivity> nodes_;  ///< each point's element's nodes
  std::vector<Vec3> rest_;                 ///< each point's rest position sum N_a X_a
  std::vector<Vec3> sampled_nodes_;        ///< N nodes' rest positions per sampled point (check_mesh)
  std::vector<Index> element_;
  std::vector<Vec3> xi_;
  std::vector<typename E::ShapeVector> shape_;
  std::vector<int> side_;
  std::vector<signed char> given_side_;  ///< per point, or empty: none given
  std::uint64_t sides_of_ = 0;  ///< the instance() of the enrichment side_ was assigned from
  std::uint64_t sides_revision_ = 0;
};

}  // namespace plastifem
