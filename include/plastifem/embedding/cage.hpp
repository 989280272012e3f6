#pragma once
// A cage around a closed surface (seed 000 Fig. 3b; SOFA's sparse grid): the cells of a regular
// grid of spacing h that overlap the inside of a closed triangle surface, as Hex8 elements (or
// their Kuhn Tet4 split, or its Tet10), each with the fraction of its volume that is inside.
//
// The fraction of a cell is measured on s x s vertical lines through it (s = CageOptions::
// lines_per_cell, at the centres of an s x s sub-grid of the cell's base): along each line the
// inside is exact, the intervals between the surface's crossings where the winding number is
// positive (a crossing enters through a triangle facing down, leaves through one facing up, so
// nested or touching parts count right); the cell's fraction is the mean over its lines of the
// inside length within the cell, divided by h. The sum of fraction x h^3 is then the enclosed
// volume to the midpoint rule's error across the lines, O((h/s)^2) per unit of surface area.
//
// Kept cells: those with a positive fraction, and those a triangle of the surface meets (so that
// every vertex of the surface lies in the cage and can be embedded in it). An element's mass
// and stiffness are weighted by its cell's fraction (Cage::weight, set as the mesh's element
// weights: Mesh::set_element_weights), at least one line's share,
// 1 / s^2: a cell kept for a triangle whose lines measured no inside still carries some (the
// solver needs it), the least the measurement can tell from none.
//
// The grid is centred on the surface's bounding box with ceil(extent / h) cells per axis; the
// lines are offset from the sub-grid centres by an irrational fraction of the sub-cell, so that
// a surface built on the grid (a box) is not met exactly at its edges.
#include <plastifem/embedding/triangle_surface.hpp>
#include <plastifem/enrichment/level_set.hpp>  // Box, triangle_meets_box
#include <plastifem/mesh/generators.hpp>

#include <algorithm>
#include <cmath>
#include <type_traits>
#include <vector>

namespace plastifem {

struct CageOptions {
  int lines_per_cell = 8;  ///< s: the fraction is measured on s x s vertical lines per cell
};

template <FiniteElement E>
struct Cage {
  Mesh<E> mesh;
  std::vector<Scalar> fraction;           ///< per element: the inside fraction of its cell measured, in [0, 1]
  std::vector<std::array<int, 3>> cell;   ///< per element: its grid cell
  Scalar cell_size = 0;
  Vec3 origin = Vec3::Zero();             ///< the grid's corner
  std::array<int, 3> cells{0, 0, 0};      ///< the grid's cells per axis

  Scalar floor = 0;                       ///< the least weight: one line's share, 1 / s^2

  /// The weight of element e's mass and stiffness: its fraction, at least `floor` (a cell kept
  /// for a triangle it holds, whose lines measured no inside).
  Scalar weight(Index e) const { return std::max(fraction[static_cast<size_t>(e)], floor); }
  /// sum fraction x element volume: the enclosed volume the cage measured.
  Scalar inside_volume() const { return weighted_volume([&](Index e) { return fraction[static_cast<size_t>(e)]; }); }
  /// sum weight x element volume: what the weighted elements' mass is density times.
  Scalar weighted_volume() const { return weighted_volume([&](Index e) { return weight(e); }); }

 private:
  template <class W>
  Scalar weighted_volume(W w) const {
    Scalar v = 0;
    for (Index e = 0; e < mesh.num_elements(); ++e) v += w(e) * element_volume<E>(mesh.element_nodes(e));
    return v;
  }
};

namespace detail {

/// Inside fraction of every cell of the grid (origin, h, n), index i + n0 (j + n1 k).
inline std::vector<Scalar> inside_fractions(const TriangleSurface& s, const Vec3& origin, Scalar h,
                                            const std::array<int, 3>& n, int lines) {
  const size_t n0 = static_cast<size_t>(n[0]), n1 = static_cast<size_t>(n[1]), n2 = static_cast<size_t>(n[2]);
  // Triangles by the columns (i, j) their xy bounding box overlaps.
  std::vector<std::vector<Index>> column(n0 * n1);
  for (Index t = 0; t < s.num_triangles(); ++t) {
    const Triangle& c = s.triangles[static_cast<size_t>(t)];
    Vec3 lo = s.vertices.col(c[0]), hi = lo;
    for (int k = 1; k < 3; ++k) lo = lo.cwiseMin(s.vertices.col(c[static_cast<size_t>(k)])), hi = hi.cwiseMax(s.vertices.col(c[static_cast<size_t>(k)]));
    const int i0 = std::clamp(static_cast<int>(std::floor((lo.x() - origin.x()) / h)), 0, n[0] - 1);
    const int i1 = std::clamp(static_cast<int>(std::floor((hi.x() - origin.x()) / h)), 0, n[0] - 1);
    const int j0 = std::clamp(static_cast<int>(std::floor((lo.y() - origin.y()) / h)), 0, n[1] - 1);
    const int j1 = std::clamp(static_cast<int>(std::floor((hi.y() - origin.y()) / h)), 0, n[1] - 1);
    for (int j = j0; j <= j1; ++j)
      for (int i = i0; i <= i1; ++i) column[static_cast<size_t>(i) + n0 * static_cast<size_t>(j)].push_back(t);
  }
  std::vector<Scalar> inside(n0 * n1 * n2, 0);
  std::vector<std::pair<Scalar, int>> hits;
  const Scalar offset = 1e-7 * (std::sqrt(5.0) - 1) / 2;  // off the sub-grid centres (file comment)
  const Scalar weight = 1.0 / (static_cast<Scalar>(lines) * lines * h);
  for (size_t j = 0; j < n1; ++j)
    for (size_t i = 0; i < n0; ++i) {
      const auto& tris = column[i + n0 * j];
      if (tris.empty()) continue;
      for (int b = 0; b < lines; ++b)
        for (int a = 0; a < lines; ++a) {
          const Scalar px = origin.x() + h * (static_cast<Scalar>(i) + (a + 0.5 + offset) / lines);
          const Scalar py = origin.y() + h * (static_cast<Scalar>(j) + (b + 0.5 + offset * 1.7) / lines);
          hits.clear();
          for (Index t : tris) {
            const Triangle& c = s.triangles[static_cast<size_t>(t)];
            const Vec3 A = s.vertices.col(c[0]), B = s.vertices.col(c[1]), C = s.vertices.col(c[2]);
            // Twice the projected area, positive when the triangle faces up (n_z > 0).
            const Scalar d = (B.x() - A.x()) * (C.y() - A.y()) - (B.y() - A.y()) * (C.x() - A.x());
            if (d == 0) continue;  // vertical: a vertical line meets it nowhere generically
            const Scalar wa = ((B.x() - px) * (C.y() - py) - (B.y() - py) * (C.x() - px)) / d;
            const Scalar wb = ((C.x() - px) * (A.y() - py) - (C.y() - py) * (A.x() - px)) / d;
            const Scalar wc = 1 - wa - wb;
            if (wa < 0 || wb < 0 || wc < 0) continue;
            hits.emplace_back(wa * A.z() + wb * B.z() + wc * C.z(), d < 0 ? +1 : -1);
          }
          if (hits.empty()) continue;
          std::sort(hits.begin(), hits.end());
          int winding = 0;
          for (size_t k = 0; k + 1 < hits.size(); ++k) {
            winding += hits[k].second;
            if (winding <= 0) continue;
            // [z0, z1] is inside: add its overlap with each cell of the column.
            const Scalar z0 = hits[k].first, z1 = hits[k + 1].first;
            const int k0 = std::clamp(static_cast<int>(std::floor((z0 - origin.z()) / h)), 0, n[2] - 1);
            const int k1 = std::clamp(static_cast<int>(std::floor((z1 - origin.z()) / h)), 0, n[2] - 1);
            for (int kk = k0; kk <= k1; ++kk) {
              const Scalar lo = std::max(z0, origin.z() + h * kk), hi = std::min(z1, origin.z() + h * (kk + 1));
              if (hi > lo) inside[i + n0 * (j + n1 * static_cast<size_t>(kk))] += (hi - lo) * weight;
            }
          }
        }
    }
  for (Scalar& f : inside) f = std::min(f, Scalar(1));  // round-off above a full cell
  return inside;
}

}  // namespace detail

/// The cage of grid spacing h around the closed surface `s` (see the file comment), as Hex8,
/// Tet4 (each cell's 6 Kuhn tetrahedra, each with its cell's fraction) or Tet10. Refuses an
/// open, non-manifold or inconsistently oriented surface, and h that is not positive and finite.
template <FiniteElement E>
Cage<E> cage_around(const TriangleSurface& s, Scalar h, const CageOptions& options = {}) {
  static_assert(std::is_same_v<E, Hex8> || std::is_same_v<E, Tet4> || std::is_same_v<E, Tet10>,
                "cage_around builds Hex8 cells, or their Kuhn Tet4 split, or its Tet10");
  check_surface(s, "cage surface");
  if (!surface_edges(s).closed())
    fail<InvalidArgument>("cage: the surface is not closed and consistently oriented ({} rim, {} non-manifold, {} "
                          "misoriented edges): it has no inside",
                          surface_edges(s).boundary, surface_edges(s).non_manifold, surface_edges(s).misoriented);
  if (enclosed_volume(s, s.vertices) <= 0)
    fail<InvalidArgument>("cage: the surface's triangles face inwards (enclosed volume {}); reverse them",
                          enclosed_volume(s, s.vertices));
  if (!(h > 0) || !std::isfinite(h)) fail<InvalidArgument>("cage: cell size {} (> 0, finite)", h);
  if (options.lines_per_cell < 1 || options.lines_per_cell > 64)
    fail<InvalidArgument>("cage: lines_per_cell {} (1-64)", options.lines_per_cell);
  const Vec3 lo = s.vertices.rowwise().minCoeff(), hi = s.vertices.rowwise().maxCoeff();
  Cage<E> cage;
  cage.cell_size = h;
  for (int a = 0; a < 3; ++a) {
    const Scalar cells = std::ceil((hi[a] - lo[a]) / h);
    if (cells > 2000) fail<InvalidArgument>("cage: {} cells along axis {} (at most 2000): a larger cell size", cells, a);
    cage.cells[static_cast<size_t>(a)] = std::max(1, static_cast<int>(cells));
  }
  // The inside fractions take 8 bytes a cell: 1e8 cells (800 MB) before a clear refusal rather
  // than an allocation failure (2000 per axis alone would allow 8e9).
  if (const Scalar total = Scalar(cage.cells[0]) * cage.cells[1] * cage.cells[2]; total > 1e8)
    fail<InvalidArgument>("cage: {} x {} x {} = {:.3g} cells (at most 1e8): a larger cell size", cage.cells[0],
                          cage.cells[1], cage.cells[2], total);
  const Vec3 extent(h * cage.cells[0], h * cage.cells[1], h * cage.cells[2]);
  cage.origin = (lo + hi) / 2 - extent / 2;
  const int n0 = cage.cells[0], n1 = cage.cells[1], n2 = cage.cells[2];
  std::vector<Scalar> fraction = detail::inside_fractions(s, cage.origin, h, cage.cells, options.lines_per_cell);
  // Cells a triangle meets are kept too (every surface vertex inside the cage).
  std::vector<char> touched(fraction.size(), 0);
  for (const Triangle& t : s.triangles) {
    const Vec3 A = s.vertices.col(t[0]), B = s.vertices.col(t[1]), C = s.vertices.col(t[2]);
    const Vec3 tlo = A.cwiseMin(B).cwiseMin(C), thi = A.cwiseMax(B).cwiseMax(C);
    std::array<int, 3> c0, c1;
    for (int a = 0; a < 3; ++a) {
      const int m = cage.cells[static_cast<size_t>(a)];
      c0[static_cast<size_t>(a)] = std::clamp(static_cast<int>(std::floor((tlo[a] - cage.origin[a]) / h)), 0, m - 1);
      c1[static_cast<size_t>(a)] = std::clamp(static_cast<int>(std::floor((thi[a] - cage.origin[a]) / h)), 0, m - 1);
    }
    for (int k = c0[2]; k <= c1[2]; ++k)
      for (int j = c0[1]; j <= c1[1]; ++j)
        for (int i = c0[0]; i <= c1[0]; ++i) {
          const Vec3 cell_lo = cage.origin + h * Vec3(i, j, k);
          const size_t id = static_cast<size_t>(i) + static_cast<size_t>(n0) * (static_cast<size_t>(j) + static_cast<size_t>(n1) * static_cast<size_t>(k));
          if (!touched[id] && detail::triangle_meets_box(A, B, C, Box{cell_lo, cell_lo + Vec3::Constant(h)})) touched[id] = 1;
        }
  }
  cage.floor = 1.0 / (static_cast<Scalar>(options.lines_per_cell) * options.lines_per_cell);
  const BoxSpec box{n0, n1, n2, extent, cage.origin};
  const Eigen::Matrix3Xd grid_nodes = detail::box_nodes(box);
  std::vector<Index> node_of(static_cast<size_t>(grid_nodes.cols()), -1);
  std::vector<Vec3> nodes;
  std::vector<typename Mesh<E>::Connectivity> elements;
  auto node = [&](Index g) {
    Index& n = node_of[static_cast<size_t>(g)];
    if (n < 0) n = static_cast<Index>(nodes.size()), nodes.push_back(grid_nodes.col(g));
    return n;
  };
  static constexpr int kuhn_paths[6][2] = {{1, 3}, {1, 5}, {2, 3}, {2, 6}, {4, 5}, {4, 6}};  // generators.hpp
  std::vector<Mesh<Tet4>::Connectivity> tets;
  for (int k = 0; k < n2; ++k)
    for (int j = 0; j < n1; ++j)
      for (int i = 0; i < n0; ++i) {
        const size_t id = static_cast<size_t>(i) + static_cast<size_t>(n0) * (static_cast<size_t>(j) + static_cast<size_t>(n1) * static_cast<size_t>(k));
        if (!(fraction[id] > 0) && !touched[id]) continue;
        const Scalar f = fraction[id];
        std::array<Index, 8> c = detail::cell_corners(box, i, j, k);
        for (Index& g : c) g = node(g);
        if constexpr (std::is_same_v<E, Hex8>) {
          elements.push_back({c[0], c[1], c[3], c[2], c[4], c[5], c[7], c[6]});  // box_hex8's order
          cage.fraction.push_back(f), cage.cell.push_back({i, j, k});
        } else {
          for (const auto& p : kuhn_paths) {
            tets.push_back({c[0], c[static_cast<size_t>(p[0])], c[static_cast<size_t>(p[1])], c[7]});
            cage.fraction.push_back(f), cage.cell.push_back({i, j, k});
          }
        }
      }
  Eigen::Matrix3Xd X(3, static_cast<Index>(nodes.size()));
  for (size_t a = 0; a < nodes.size(); ++a) X.col(static_cast<Index>(a)) = nodes[a];
  if constexpr (std::is_same_v<E, Hex8>) {
    cage.mesh = Mesh<Hex8>(X, std::move(elements));
  } else {
    for (auto& t : tets) detail::orient_tet(X, t);
    Mesh<Tet4> tet4(X, std::move(tets));
    if constexpr (std::is_same_v<E, Tet4>) cage.mesh = std::move(tet4);
    else cage.mesh = promote_to_tet10(tet4);
  }
  std::vector<Scalar> weights(cage.fraction.size());
  for (size_t e = 0; e < weights.size(); ++e) weights[e] = cage.weight(static_cast<Index>(e));
  cage.mesh.set_element_weights(std::move(weights));
  return cage;
}

}  // namespace plastifem
