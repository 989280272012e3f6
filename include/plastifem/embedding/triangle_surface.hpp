#pragma once
// A triangle surface: vertices (one per column) and triangles of vertex indices, counter-
// clockwise seen from outside (their normals, by the right-hand rule, point out of a closed
// surface). What an organ's visual surface is made of: read from OBJ or STL
// (mesh/io/surface.hpp) or given as arrays, embedded in a volume mesh (embedded_surface.hpp).
#include <plastifem/core/error.hpp>
#include <plastifem/core/types.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <utility>
#include <vector>

namespace plastifem {

using Triangle = std::array<Index, 3>;

struct TriangleSurface {
  Eigen::Matrix3Xd vertices;
  std::vector<Triangle> triangles;

  Index num_vertices() const { return vertices.cols(); }
  Index num_triangles() const { return static_cast<Index>(triangles.size()); }
};

/// Refuses, naming the first culprit, a surface with a non-finite vertex, a triangle index out of
/// range or a triangle that repeats a vertex (`what` names the surface in the message).
inline void check_surface(const TriangleSurface& s, const char* what = "surface") {
  for (Index i = 0; i < s.num_vertices(); ++i)
    if (!s.vertices.col(i).allFinite())
      fail<MeshError>("{}: vertex {} is not finite ({}, {}, {})", what, i, s.vertices(0, i), s.vertices(1, i),
                      s.vertices(2, i));
  for (Index t = 0; t < s.num_triangles(); ++t) {
    const Triangle& c = s.triangles[static_cast<size_t>(t)];
    for (Index i : c)
      if (i < 0 || i >= s.num_vertices())
        fail<MeshError>("{}: triangle {} has vertex {} out of range [0, {})", what, t, i, s.num_vertices());
    if (c[0] == c[1] || c[1] == c[2] || c[0] == c[2])
      fail<MeshError>("{}: triangle {} repeats a vertex ({}, {}, {})", what, t, c[0], c[1], c[2]);
  }
}

/// Unit vertex normals at positions x (one column per vertex): the sum of the adjacent
/// triangles' (b - a) x (c - a), i.e. weighted by area, normalised; zero for a vertex of no
/// triangle of non-zero area.
inline void vertex_normals(const TriangleSurface& s, const Eigen::Matrix3Xd& x, Eigen::Matrix3Xd& n) {
  n.setZero(3, s.num_vertices());
  for (const Triangle& t : s.triangles) {
    const Vec3 a = x.col(t[0]), area2 = (x.col(t[1]) - a).cross(x.col(t[2]) - a);
    for (Index i : t) n.col(i) += area2;
  }
  for (Index i = 0; i < n.cols(); ++i)
    if (const Scalar len = n.col(i).norm(); len > 0) n.col(i) /= len;
}

/// How the surface's edges are shared: a closed, consistently oriented (watertight) surface
/// has every edge in exactly two triangles, traversed in opposite directions.
struct SurfaceEdges {
  Index edges = 0;
  Index boundary = 0;     ///< edges of one triangle: the rims of an open surface
  Index non_manifold = 0; ///< edges of three or more triangles
  Index misoriented = 0;  ///< edges of two triangles that traverse it the same way
  bool closed() const { return edges > 0 && boundary == 0 && non_manifold == 0 && misoriented == 0; }
};

inline SurfaceEdges surface_edges(const TriangleSurface& s) {
  // (lower, higher) vertex -> triangles traversing it lower -> higher, and higher -> lower
  std::map<std::pair<Index, Index>, std::array<int, 2>> count;
  for (const Triangle& t : s.triangles)
    for (int k = 0; k < 3; ++k) {
      const Index a = t[k], b = t[(k + 1) % 3];
      ++count[{std::min(a, b), std::max(a, b)}][a < b ? 0 : 1];
    }
  SurfaceEdges r;
  r.edges = static_cast<Index>(count.size());
  for (const auto& [edge, c] : count) {
    const int n = c[0] + c[1];
    if (n == 1) ++r.boundary;
    else if (n > 2) ++r.non_manifold;
    else if (c[0] != 1) ++r.misoriented;
  }
  return r;
}

/// The volume a closed surface at positions x encloses (divergence theorem: the sum of
/// a . (b x c) / 6 over its triangles); positive when the triangles face out.
inline Scalar enclosed_volume(const TriangleSurface& s, const Eigen::Matrix3Xd& x) {
  Scalar v = 0;
  for (const Triangle& t : s.triangles) v += x.col(t[0]).dot(Vec3(x.col(t[1])).cross(Vec3(x.col(t[2])))) / 6;
  return v;
}

/// A sphere: an icosahedron whose triangles are split in four `subdivisions` times, the new
/// vertices pushed out onto the sphere (20 * 4^k triangles, 10 * 4^k + 2 vertices; the
/// enclosed volume approaches 4/3 pi r^3 as 4^-k). Outward-facing.
inline TriangleSurface sphere_surface(const Vec3& center, Scalar radius, int subdivisions) {
  if (!(radius > 0) || !std::isfinite(radius) || !center.allFinite() || subdivisions < 0 || subdivisions > 8)
    fail<InvalidArgument>("sphere_surface: radius {} (> 0, finite), subdivisions {} (0-8), centre finite", radius,
                          subdivisions);
  const Scalar g = (1 + std::sqrt(5.0)) / 2;
  std::vector<Vec3> v{{-1, g, 0}, {1, g, 0}, {-1, -g, 0}, {1, -g, 0}, {0, -1, g}, {0, 1, g},
                      {0, -1, -g}, {0, 1, -g}, {g, 0, -1}, {g, 0, 1}, {-g, 0, -1}, {-g, 0, 1}};
  for (Vec3& p : v) p.normalize();
  std::vector<Triangle> t{{0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11}, {1, 5, 9}, {5, 11, 4},
                          {11, 10, 2}, {10, 7, 6}, {7, 1, 8},   {3, 9, 4},  {3, 4, 2},   {3, 2, 6}, {3, 6, 8},
                          {3, 8, 9},  {4, 9, 5},  {2, 4, 11}, {6, 2, 10}, {8, 6, 7},   {9, 8, 1}};
  for (int level = 0; level < subdivisions; ++level) {
    std::map<std::pair<Index, Index>, Index> midpoint;
    auto mid = [&](Index a, Index b) {
      const auto [it, added] = midpoint.try_emplace({std::min(a, b), std::max(a, b)}, static_cast<Index>(v.size()));
      if (added) v.push_back((v[static_cast<size_t>(a)] + v[static_cast<size_t>(b)]).normalized());
      return it->second;
    };
    std::vector<Triangle> finer;
    for (const Triangle& c : t) {
      const Index ab = mid(c[0], c[1]), bc = mid(c[1], c[2]), ca = mid(c[2], c[0]);
      finer.insert(finer.end(), {{c[0], ab, ca}, {c[1], bc, ab}, {c[2], ca, bc}, {ab, bc, ca}});
    }
    t = std::move(finer);
  }
  TriangleSurface s;
  s.vertices.resize(3, static_cast<Index>(v.size()));
  for (size_t i = 0; i < v.size(); ++i) s.vertices.col(static_cast<Index>(i)) = center + radius * v[i];
  s.triangles = std::move(t);
  return s;
}

/// The liver-like map of the unit ball (liver_surface): p = (x, y, z) -> size * f(p), with
/// u = (1 + x) / 2 running from the thin left lobe to the thick right one,
///   f_x = x
///   f_y = 0.6 y (0.7 + 0.3 u)                                     narrower on the left
///   f_z = (0.18 + 0.32 u^2) g(z) - 0.12 x^2 + 0.08 y                thick right lobe, arched
///   g(z) = z (0.775 + 0.225 tanh 3z)                                domed top, flatter underside
/// Each component is increasing in its own coordinate with the earlier ones fixed (f_y' > 0,
/// g' >= 0.505), so f is one-to-one with det Df > 0: the image of a closed, outward triangulated
/// sphere is closed, does not cross itself and faces out.
inline Vec3 liver_map(const Vec3& p) {
  const Scalar x = p.x(), y = p.y(), z = p.z(), u = (1 + x) / 2;
  const Scalar g = z * (0.775 + 0.225 * std::tanh(3 * z));
  return {x, 0.6 * y * (0.7 + 0.3 * u), (0.18 + 0.32 * u * u) * g - 0.12 * x * x + 0.08 * y};
}

/// A smooth liver-like closed surface of about `size` across (2 size long in x, 0.84-1.2 size
/// wide, 0.28-0.78 size thick from the left lobe to the right), around `center`: the icosphere (sphere_surface) of
/// `subdivisions` mapped by liver_map. 5: 20,480 triangles. Procedural, no data file: a
/// stand-in for an organ a user reads from OBJ or STL (io::read_surface).
inline TriangleSurface liver_surface(const Vec3& center, Scalar size, int subdivisions) {
  if (!(size > 0) || !std::isfinite(size) || !center.allFinite())
    fail<InvalidArgument>("liver_surface: size {} (> 0, finite), centre ({}, {}, {}) finite", size, center.x(),
                          center.y(), center.z());
  TriangleSurface s = sphere_surface(Vec3::Zero(), 1, subdivisions);
  for (Index i = 0; i < s.num_vertices(); ++i) s.vertices.col(i) = center + size * liver_map(s.vertices.col(i));
  return s;
}

}  // namespace plastifem
