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
  /// solver's committed state and recomputes the normals. If the split fails (InvalidArgument),
  /// the surface is left as it was.
  template <class S>
  void update(const S& solver) {
    points_.check_mesh(solver);  // before the split reads the solver's mesh with our element ids
    if constexpr (S::EnrichmentPolicy::active) {
      const Enrichment<E>& enr = solver.enrichment();
      if (enr.instance() != split_instance_ || enr.revision() != split_revision_) split(solver.mesh(), enr);
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
  /// "displacement" (from the rest surface: colour by it; the points are already moved, so
  /// VtuOptions::deform_by is refused).
  void write_vtu(const std::filesystem::path& path, const io::VtuOptions& options = {}) const {
    if (!options.deform_by.empty())
      fail<InvalidArgument>("EmbeddedSurface::write_vtu: the points are the current positions already; deform_by "
                            "('{}') would move them twice",
                            options.deform_by);
    io::write_surface_vtu(path, surface_, positions_,
                          {io::Field("normal", normals_), io::Field("displacement", positions_ - surface_.vertices)}, {},
                          options);
  }

 private:
  /// The given surface split along every cut of `enr` (see the file comment). Everything is
  /// built aside and committed at the end: a failure leaves the surface as it was.
  void split(const Mesh<E>& mesh, const Enrichment<E>& enr) {
    // The locator over the solver's mesh, built on the first cut and kept while the solver's
    // enrichment is the same object (another solver's mesh gets its own).
    if (!locator_ || locator_instance_ != enr.instance()) locator_.emplace(mesh), locator_instance_ = enr.instance();
    const PointLocator<E>& locator = *locator_;
    points_.assign_sides(enr);
    const Index n_given = given_.num_vertices();
    std::vector<Vec3> X;  // rest positions: the given vertices', then the crossings'
    for (Index i = 0; i < n_given; ++i) X.push_back(given_.vertices.col(i));
    std::vector<signed char> crossing_side;  // per crossing vertex: its side, -1 where not opened
    std::vector<std::optional<PointLocation>> crossing_at;  // per crossing vertex: the cut element it opens in
    std::vector<signed char> given_side(static_cast<size_t>(n_given), -1);
    std::vector<Triangle> triangles = given_.triangles;
    for (int c = 0; c < enr.num_cuts(); ++c) {
      const auto& cut = enr.geometry(c);  // dependent: signed_distance is found where the cut types are complete
      auto in_cut_element = [&](Index e) {
        const CutElement<E>* el = enr.element(e);
        return el && el->cut == c && el->num_sides == 2;
      };
      // The level set at a point: in an element whose nodes all have it (the cut's elements and
      // those around them), the nodal level set interpolated, what the elements' pieces are cut
      // by; elsewhere the cut surface's signed distance. A point in several elements (on a
      // shared face) takes a cut element of this cut among them if there is one.
      auto nodal_level_set = [&](Index e, const Vec3& xi, Scalar& phi) {
        const auto N = E::shape(xi);
        phi = 0;
        for (int k = 0; k < E::num_nodes; ++k) {
          const Scalar v = enr.level_set(c, mesh.element(e)[static_cast<size_t>(k)]);
          if (std::isnan(v)) return false;
          phi += N[k] * v;
        }
        return true;
      };
      struct At {
        Scalar phi;
        bool in_cut_element;
        PointLocation where;  // in the cut element, if in one
      };
      auto level_set = [&](const Vec3& x) {
        At r{signed_distance(cut, x), false, {}};
        bool nodal = false;
        locator.for_each_containing(x, [&](const PointLocation& where) {
          if (r.in_cut_element) return;
          Scalar phi;
          const bool cut_here = in_cut_element(where.element);
          if ((cut_here || !nodal) && nodal_level_set(where.element, where.xi, phi)) r.phi = phi, nodal = true;
          r.in_cut_element = cut_here;
          if (cut_here) r.where = where;
        });
        return r;
      };
      std::vector<Scalar> phi(X.size());
      for (size_t v = 0; v < X.size(); ++v) {
        const Index vi = static_cast<Index>(v);
        Scalar nodal = 0;
        const bool in_cut = vi < n_given && in_cut_element(points_.element(vi));
        // A given vertex's element is known: no search.
        if (vi < n_given) phi[v] = nodal_level_set(points_.element(vi), points_.xi(vi), nodal) ? nodal : signed_distance(cut, X[v]);
        else phi[v] = level_set(X[v]).phi;
        // A given vertex in one of the cut's elements moves with the side its level set gives.
        if (in_cut) given_side[v] = phi[v] >= 0 ? 0 : 1;
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
        At here{f0, false, {}};
        const Scalar tol = 1e-13 * (std::abs(f0) + std::abs(f1));
        for (int it = 0, last = 0; it < 60; ++it) {
          const Scalar t = f0 - f1 > 0 ? t0 + (t1 - t0) * f0 / (f0 - f1) : 0.5 * (t0 + t1);
          at = Xp + t * (Xm - Xp), here = level_set(at);
          if (std::abs(here.phi) <= tol || t1 - t0 <= 1e-14) break;
          // Illinois: an end kept twice in a row has its value halved (no one-sided stall).
          if (here.phi >= 0) {
            t0 = t, f0 = here.phi;
            if (last > 0) f1 /= 2;
            last = 1;
          } else {
            t1 = t, f1 = here.phi;
            if (last < 0) f0 /= 2;
            last = -1;
          }
        }
        // A crossing outside the mesh (a chord of the surface leaving a non-convex mesh) is put
        // on the nearer end, which is inside.
        if (!locator.locate(at)) at = (at - Xp).norm() <= (at - Xm).norm() ? Xp : Xm;
        const bool opens = here.in_cut_element;
        std::array<Index, 2> r;
        for (int s = 0; s < (opens ? 2 : 1); ++s) {
          r[static_cast<size_t>(s)] = static_cast<Index>(X.size());
          X.push_back(at), crossing_side.push_back(opens ? static_cast<signed char>(s) : -1);
          crossing_at.push_back(opens ? std::optional<PointLocation>(here.where) : std::nullopt);
        }
        if (!opens) r[1] = r[0];
        return crossing[key] = r;
      };
      std::vector<Triangle> next;
      next.reserve(triangles.size());
      struct Kept {  // a triangle across the cut where the tissue does not open
        Triangle t;    // lone vertex first
        std::array<Index, 2> ab, ad;
      };
      std::vector<Kept> kept;
      std::vector<char> used(X.size(), 0);  // the crossings split triangles use
      for (const Triangle& t : triangles) {
        const bool p0 = phi[static_cast<size_t>(t[0])] >= 0, p1 = phi[static_cast<size_t>(t[1])] >= 0,
                   p2 = phi[static_cast<size_t>(t[2])] >= 0;
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
          kept.push_back({{a, b, d}, ab, ad});
          continue;
        }
        const size_t lone = phi[static_cast<size_t>(a)] >= 0 ? 0 : 1, other = 1 - lone;
        next.push_back({a, ab[lone], ad[lone]});
        next.push_back({ab[other], b, d});
        next.push_back({ab[other], d, ad[other]});
        used.resize(X.size(), 0);
        for (Index v : {ab[0], ab[1], ad[0], ad[1]}) used[static_cast<size_t>(v)] = 1;
      }
      used.resize(X.size(), 0);
      // A triangle kept whole next to a split one shares an edge whose crossing the split one
      // uses: it is split there too (no T-junction; from the opposite vertex, using only
      // crossings already used, so this does not spread).
      for (const Kept& k : kept) {
        const auto [a, b, d] = k.t;
        const bool on_ab = used[static_cast<size_t>(k.ab[0])], on_ad = used[static_cast<size_t>(k.ad[0])];
        const Index m1 = k.ab[0], m2 = k.ad[0];
        if (on_ab && on_ad) {
          next.push_back({a, m1, m2}), next.push_back({m1, b, d}), next.push_back({m1, d, m2});
        } else if (on_ab) {
          next.push_back({a, m1, d}), next.push_back({m1, b, d});
        } else if (on_ad) {
          next.push_back({b, d, m2}), next.push_back({b, m2, a});
        } else {
          next.push_back(k.t);
        }
      }
      triangles = std::move(next);
    }
    // Crossings no triangle uses (of triangles kept whole) are dropped, renumbering.
    std::vector<Index> renumber(X.size(), -1);
    for (const Triangle& t : triangles)
      for (Index v : t) renumber[static_cast<size_t>(v)] = v;  // marks use
    for (Index i = 0; i < n_given; ++i) renumber[static_cast<size_t>(i)] = i;
    Index next_id = n_given;
    std::vector<Vec3> kept_X;
    std::vector<signed char> kept_side;
    // Where the crossings are: an opening one in the cut element it opens in (on a face the cut
    // runs along, located again it could go to the uncut element beside, which has one side:
    // both copies then moved together; found by review, 2026-11-30).
    std::vector<PointLocation> kept_at;
    for (size_t v = static_cast<size_t>(n_given); v < X.size(); ++v)
      if (renumber[v] >= 0) {
        renumber[v] = next_id++;
        const size_t k = v - static_cast<size_t>(n_given);
        const std::optional<PointLocation> at = crossing_at[k] ? crossing_at[k] : locator.locate(X[v]);
        if (!at) fail<InvalidArgument>("embedded surface: crossing {} at ({}, {}, {}) is in no element", k, X[v].x(), X[v].y(), X[v].z());
        kept_X.push_back(X[v]), kept_side.push_back(crossing_side[k]), kept_at.push_back(*at);
      }
    for (Triangle& t : triangles)
      for (Index& v : t) v = renumber[static_cast<size_t>(v)];
    TriangleSurface split_surface;
    split_surface.triangles = std::move(triangles);
    split_surface.vertices.resize(3, next_id);
    split_surface.vertices.leftCols(n_given) = given_.vertices;
    for (size_t k = 0; k < kept_X.size(); ++k) split_surface.vertices.col(n_given + static_cast<Index>(k)) = kept_X[k];
    std::optional<EmbeddedPoints<E>> crossings;
    if (!kept_X.empty()) crossings.emplace(mesh, std::span<const PointLocation>(kept_at), std::move(kept_side));
    // Commit (nothing below throws).
    surface_ = std::move(split_surface);
    crossings_ = std::move(crossings);
    points_.set_sides(std::move(given_side));
    split_instance_ = enr.instance(), split_revision_ = enr.revision();
  }

  TriangleSurface given_, surface_;
  EmbeddedPoints<E> points_;                      ///< the given vertices
  std::optional<EmbeddedPoints<E>> crossings_;    ///< the vertices the cuts added
  Eigen::Matrix3Xd positions_, normals_, given_x_, crossing_x_;
  std::optional<PointLocator<E>> locator_;  ///< for the crossings, over the mesh of locator_instance_'s solver
  std::uint64_t locator_instance_ = 0;
  std::uint64_t split_instance_ = 0, split_revision_ = 0;  ///< the enrichment surface_ was split along
};

}  // namespace plastifem
