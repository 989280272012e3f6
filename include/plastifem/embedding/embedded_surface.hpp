#pragma once
// A triangle surface embedded in a volume mesh: an organ's smooth visual surface carried by a
// coarser simulation mesh (seed 000 Fig. 3b: a liver in a hexahedral cage). Its vertices are
// EmbeddedPoints, located once in the rest mesh; update(solver) moves them with the tissue (in a
// cut body each with its own piece; under plasticity with the permanent set, which is part of
// the displacement) and recomputes the vertex normals (area-weighted, embedding/
// triangle_surface.hpp). Written as OBJ, or VTU frames for ParaView with PvdWriter::write_frame.
//
// Cut with the tissue: whenever the solver's cuts change, the surface is split along them
// again from the surface given. For each cut, a vertex's sign is the side it moves with (its
// piece's, in one of the cut's elements; elsewhere the side of the cut surface it lies on). An
// edge whose ends differ crosses the cut where the cut's signed distance, linear along the edge,
// is zero. If that point lies in one of the cut's elements the tissue opens there: the crossing
// gets two vertices, one moving with each side (EmbeddedPoints with given sides); elsewhere (past
// the cut's end) one. A triangle with an opening edge is split into its part on each side (one
// triangle and a quad of two), each made of its side's vertices, so the surface opens exactly
// along the cut and stays closed everywhere else. Vertices keep their numbers; the crossings'
// follow them.
#include <plastifem/embedding/embedded_points.hpp>
#include <plastifem/embedding/triangle_surface.hpp>
#include <plastifem/mesh/io/surface.hpp>

#include <algorithm>
#include <cstdint>
#include <map>
#include <optional>
#include <utility>

namespace plastifem {

template <FiniteElement E>
class EmbeddedSurface {
 public:
  /// Checks the surface (check_surface) and locates its vertices in `mesh` (the rest mesh of the
  /// solvers it will follow); a vertex in no element is refused with InvalidArgument naming it.
  EmbeddedSurface(const Mesh<E>& mesh, TriangleSurface surface)
      : given_((check_surface(surface, "embedded surface"), std::move(surface))), surface_(given_),
        points_(mesh, given_.vertices) {
    points_.rest_positions(positions_);
    vertex_normals(surface_, positions_, normals_);
  }

  /// The surface as it is now: the one given, split along the cuts since.
  const TriangleSurface& surface() const { return surface_; }
  /// Vertices added by the cuts (after the given ones).
  Index num_crossing_vertices() const { return surface_.num_vertices() - given_.num_vertices(); }
  EmbeddedPoints<E>& points() { return points_; }
  const EmbeddedPoints<E>& points() const { return points_; }

  /// Splits the surface along the solver's cuts if they changed, moves the vertices to the
  /// solver's committed state and recomputes the normals.
  template <class S>
  void update(const S& solver) {
    if constexpr (S::EnrichmentPolicy::active) {
      const Enrichment<E>& enr = solver.enrichment();
      if (&enr != split_for_ || enr.revision() != split_revision_) split(solver.mesh(), enr);
    }
    points_.positions(solver, given_x_);
    positions_.resize(3, surface_.num_vertices());
    positions_.leftCols(given_.num_vertices()) = given_x_;
    if (crossings_) {
      crossings_->positions(solver, crossing_x_);
      positions_.rightCols(crossing_x_.cols()) = crossing_x_;
    }
    // One pass over the triangles (0.86 ms for 81,920; a parallel gather over each vertex's
    // triangles was slower: bench_points).
    vertex_normals(surface_, positions_, normals_);
  }
  /// Vertex positions and unit normals of the last update (the rest surface before one).
  const Eigen::Matrix3Xd& positions() const { return positions_; }
  const Eigen::Matrix3Xd& normals() const { return normals_; }

  void write_obj(const std::filesystem::path& path) const { io::write_obj(path, surface_, positions_, normals_); }
  /// A VTU of triangles at the current positions, with the point fields "normal" and
  /// "displacement" (from the rest surface; warp by it in ParaView to see both).
  void write_vtu(const std::filesystem::path& path, const io::VtuOptions& options = {}) const {
    io::write_surface_vtu(path, surface_, positions_,
                          {io::Field("normal", normals_), io::Field("displacement", positions_ - surface_.vertices)}, {},
                          options);
  }

 private:
  /// The given surface split along every cut of `enr` (see the file comment).
  void split(const Mesh<E>& mesh, const Enrichment<E>& enr) {
    points_.assign_sides(enr);
    // The locator over the solver's mesh, built on the first cut and kept (the solver's mesh
    // does not change; another solver's mesh gets its own).
    if (!locator_ || locator_mesh_ != &mesh) locator_.emplace(mesh), locator_mesh_ = &mesh;
    const PointLocator<E>& locator = *locator_;
    std::vector<Vec3> X;  // rest positions: the given vertices', then the crossings'
    for (Index i = 0; i < given_.num_vertices(); ++i) X.push_back(given_.vertices.col(i));
    std::vector<signed char> crossing_side;  // per crossing vertex: its side, -1 where not opened
    std::vector<signed char> given_side(static_cast<size_t>(given_.num_vertices()), -1);
    std::vector<Triangle> triangles = given_.triangles;
    const Index n_given = given_.num_vertices();
    for (int c = 0; c < enr.num_cuts(); ++c) {
      const auto& cut = enr.geometry(c);  // dependent: signed_distance is found where the cut types are complete
      auto in_cut_element = [&](Index e) {
        const CutElement<E>* el = enr.element(e);
        return el && el->cut == c && el->num_sides == 2;
      };
      // The level set at a point: in one of the cut's elements, its nodal level set interpolated
      // (what the element's pieces are cut by); elsewhere the cut surface's signed distance.
      auto level_set_in = [&](Index e, const Vec3& xi) {
        const auto N = E::shape(xi);
        Scalar phi = 0;
        for (int k = 0; k < E::num_nodes; ++k) phi += N[k] * enr.level_set(c, mesh.element(e)[static_cast<size_t>(k)]);
        return phi;
      };
      auto level_set = [&](const Vec3& x, const std::optional<PointLocation>& where) {
        return where && in_cut_element(where->element) ? level_set_in(where->element, where->xi) : signed_distance(cut, x);
      };
      std::vector<Scalar> phi(X.size());
      for (size_t v = 0; v < X.size(); ++v) {
        const Index vi = static_cast<Index>(v);
        phi[v] = vi < n_given ? (in_cut_element(points_.element(vi)) ? level_set_in(points_.element(vi), points_.xi(vi))
                                                                        : signed_distance(cut, X[v]))
                              : level_set(X[v], locator.locate(X[v]));
        // A given vertex in one of the cut's elements moves with the side its level set gives.
        if (vi < n_given && in_cut_element(points_.element(vi))) given_side[v] = phi[v] >= 0 ? 0 : 1;
      }
      // Each crossed edge's vertices: [0] on the + side, [1] on the - side (the same if the
      // tissue does not open there). The crossing: the level set's sign change along the edge,
      // by regula falsi (Illinois): exact where the level set is linear along the edge, a few
      // iterations where an element is trilinear or the edge spans several elements.
      std::map<std::pair<Index, Index>, std::array<Index, 2>> crossing;
      auto cross = [&](Index a, Index b) {
        const auto key = std::make_pair(std::min(a, b), std::max(a, b));
        if (const auto it = crossing.find(key); it != crossing.end()) return it->second;
        const Index p = phi[static_cast<size_t>(a)] >= 0 ? a : b, m = p == a ? b : a;
        const Vec3 Xp = X[static_cast<size_t>(p)], Xm = X[static_cast<size_t>(m)];
        Scalar t0 = 0, t1 = 1, f0 = phi[static_cast<size_t>(p)], f1 = phi[static_cast<size_t>(m)];
        Vec3 at = Xp;
        std::optional<PointLocation> where;
        const Scalar tol = 1e-13 * (std::abs(f0) + std::abs(f1));
        for (int it = 0, retained = 0; it < 60; ++it) {
          const Scalar t = f0 - f1 > 0 ? t0 + (t1 - t0) * f0 / (f0 - f1) : 0.5 * (t0 + t1);
          at = Xp + t * (Xm - Xp), where = locator.locate(at);
          const Scalar f = level_set(at, where);
          if (std::abs(f) <= tol || t1 - t0 <= 1e-14) break;
          if (f >= 0) {
            t0 = t, f0 = f;
            if (++retained > 1) f1 /= 2;  // Illinois: the end kept twice is halved
          } else {
            t1 = t, f1 = f;
            retained = 0, f0 /= 2;
          }
        }
        const bool opens = where && in_cut_element(where->element);
        std::array<Index, 2> r;
        for (int s = 0; s < (opens ? 2 : 1); ++s) {
          r[static_cast<size_t>(s)] = static_cast<Index>(X.size());
          X.push_back(at), crossing_side.push_back(opens ? static_cast<signed char>(s) : -1);
        }
        if (!opens) r[1] = r[0];
        return crossing[key] = r;
      };
      std::vector<char> plus(phi.size());
      for (size_t v = 0; v < phi.size(); ++v) plus[v] = phi[v] >= 0;
      std::vector<Triangle> next;
      next.reserve(triangles.size());
      for (const Triangle& t : triangles) {
        const bool p0 = plus[static_cast<size_t>(t[0])], p1 = plus[static_cast<size_t>(t[1])],
                   p2 = plus[static_cast<size_t>(t[2])];
        if (p0 == p1 && p1 == p2) {
          next.push_back(t);
          continue;
        }
        // The vertex alone on its side first, the triangle's orientation kept.
        const int i = p1 == p2 ? 0 : p0 == p2 ? 1 : 2;
        const Index a = t[static_cast<size_t>(i)], b = t[static_cast<size_t>((i + 1) % 3)],
                    d = t[static_cast<size_t>((i + 2) % 3)];
        const std::array<Index, 2> ab = cross(a, b), ad = cross(a, d);
        if (ab[0] == ab[1] && ad[0] == ad[1]) {  // the tissue does not open here
          next.push_back(t);
          continue;
        }
        const size_t lone = plus[static_cast<size_t>(a)] ? 0 : 1, other = 1 - lone;
        next.push_back({a, ab[lone], ad[lone]});
        next.push_back({ab[other], b, d});
        next.push_back({ab[other], d, ad[other]});
      }
      triangles = std::move(next);
    }
    points_.set_sides(std::move(given_side));
    // Crossings of triangles that were kept whole are not used: drop them, renumbering.
    std::vector<Index> renumber(X.size(), -1);
    for (Index i = 0; i < n_given; ++i) renumber[static_cast<size_t>(i)] = i;
    for (const Triangle& t : triangles)
      for (Index v : t) renumber[static_cast<size_t>(v)] = v;  // marks use
    Index next_id = n_given;
    std::vector<Vec3> kept;
    std::vector<signed char> kept_side;
    for (size_t v = static_cast<size_t>(n_given); v < X.size(); ++v)
      if (renumber[v] >= 0) {
        renumber[v] = next_id++;
        kept.push_back(X[v]), kept_side.push_back(crossing_side[v - static_cast<size_t>(n_given)]);
      }
    for (Triangle& t : triangles)
      for (Index& v : t) v = renumber[static_cast<size_t>(v)];
    surface_.triangles = std::move(triangles);
    surface_.vertices.resize(3, next_id);
    surface_.vertices.leftCols(n_given) = given_.vertices;
    Eigen::Matrix3Xd crossing_X(3, static_cast<Index>(kept.size()));
    for (size_t k = 0; k < kept.size(); ++k) crossing_X.col(static_cast<Index>(k)) = kept[k];
    surface_.vertices.rightCols(crossing_X.cols()) = crossing_X;
    crossings_.reset();
    if (!kept.empty()) crossings_.emplace(mesh, crossing_X, std::move(kept_side));
    split_for_ = &enr, split_revision_ = enr.revision();
  }

  TriangleSurface given_, surface_;
  EmbeddedPoints<E> points_;                      ///< the given vertices
  std::optional<EmbeddedPoints<E>> crossings_;    ///< the vertices the cuts added
  Eigen::Matrix3Xd positions_, normals_, given_x_, crossing_x_;
  std::optional<PointLocator<E>> locator_;  ///< for the crossings, over locator_mesh_
  const Mesh<E>* locator_mesh_ = nullptr;
  const Enrichment<E>* split_for_ = nullptr;  ///< the enrichment surface_ was split along
  std::uint64_t split_revision_ = 0;
};

}  // namespace plastifem
