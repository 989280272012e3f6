#pragma once
// Cut surfaces and their level sets (seed 001, eq. 72-73): the signed distance
//     Lambda(x) = +-min_{x* in Gamma_cut} |x - x*|
// to a cut surface Gamma_cut, positive on the side its normal points to ("above the cut").
//
//  - CutPlane: an infinite plane through a point with a normal;
//  - CutPatch: a bounded planar patch, the parallelogram origin + s e1 + t e2, s, t in [0, 1]
//    (the thesis' rectangle S_cut); its sign is its plane's;
//  - CutSurface: a triangulated surface, open or closed, with consistently oriented triangles;
//    the sign of the distance comes from the angle-weighted pseudo-normal of the closest
//    feature (face, edge or vertex; Baerentzen and Aanaes 2005), which is robust where the
//    closest point is an edge or a vertex: for a closed surface the sign is inside/outside
//    exactly, for an open one it is the side of the nearest part of the surface.
//
// A CutSurface keeps a bounding-volume hierarchy over its triangles (built once, median splits
// on the longest axis, leaves of up to 4 triangles): a distance or box query visits the
// triangles whose boxes can matter, O(log T) instead of O(T), with the same result as a scan of
// every triangle (ties go to the lowest triangle index, as a scan's first minimum would).
// A growing cut re-applies its whole grown surface at every growth; without the tree that cost
// grew with the surface's size.
//
// Each also says whether it meets an axis-aligned box (the elements' bounding boxes): with a
// sign change of the nodal level set (eq. 73) this makes an element cut; the sign alone would
// also cut the elements beyond a bounded surface's edge. A surface whose edge ends inside an
// element cuts that element whole (the thesis: "we let a cutting surface which partially
// intersects an element continue through it").
//
// Construction validates: finite coordinates, a non-zero normal, a patch of non-zero area, a
// surface with at least one triangle of non-zero area and no index out of range.
#include <plastifem/core/error.hpp>
#include <plastifem/core/log.hpp>
#include <plastifem/core/types.hpp>
#include <plastifem/enrichment/cut_types.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <map>
#include <numbers>
#include <string>
#include <utility>
#include <variant>
#include <vector>

namespace plastifem {

/// An axis-aligned box [lo, hi].
struct Box {
  Vec3 lo = Vec3::Constant(std::numeric_limits<Scalar>::max());
  Vec3 hi = Vec3::Constant(std::numeric_limits<Scalar>::lowest());
  void add(const Vec3& p) { lo = lo.cwiseMin(p), hi = hi.cwiseMax(p); }
  Box inflated(Scalar d) const { return {lo.array() - d, hi.array() + d}; }
  bool overlaps(const Box& b) const { return (lo.array() <= b.hi.array()).all() && (b.lo.array() <= hi.array()).all(); }
};

namespace detail {

/// Whether the triangle (a, b, c) meets the box (separating-axis test: the box's three axes,
/// the triangle's normal, and the nine cross products of edges; Akenine-Moeller 2001).
inline bool triangle_meets_box(const Vec3& a, const Vec3& b, const Vec3& c, const Box& box) {
  const Vec3 centre = 0.5 * (box.lo + box.hi), half = 0.5 * (box.hi - box.lo);
  const Vec3 v0 = a - centre, v1 = b - centre, v2 = c - centre;
  const Vec3 e[3] = {v1 - v0, v2 - v1, v0 - v2};
  auto separated = [&](const Vec3& axis) {
    if (axis.squaredNorm() < 1e-300) return false;
    const Scalar p0 = axis.dot(v0), p1 = axis.dot(v1), p2 = axis.dot(v2);
    const Scalar r = half.x() * std::abs(axis.x()) + half.y() * std::abs(axis.y()) + half.z() * std::abs(axis.z());
    return std::min({p0, p1, p2}) > r || std::max({p0, p1, p2}) < -r;
  };
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      if (separated(Vec3::Unit(j).cross(e[i]))) return false;
  for (int j = 0; j < 3; ++j)
    if (separated(Vec3::Unit(j))) return false;
  return !separated(e[0].cross(e[1]));
}

/// The closest point of triangle (a, b, c) to p, and which feature it lies on: 0 the face,
/// 1-3 the edges ab, bc, ca, 4-6 the vertices a, b, c (Ericson, Real-Time Collision Detection,
/// 5.1.5).
inline Vec3 closest_on_triangle(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c, int& feature) {
  const Vec3 ab = b - a, ac = c - a, ap = p - a;
  const Scalar d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0 && d2 <= 0) return feature = 4, a;
  const Vec3 bp = p - b;
  const Scalar d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0 && d4 <= d3) return feature = 5, b;
  const Scalar vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) return feature = 1, Vec3(a + d1 / (d1 - d3) * ab);
  const Vec3 cp = p - c;
  const Scalar d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0 && d5 <= d6) return feature = 6, c;
  const Scalar vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) return feature = 3, Vec3(a + d2 / (d2 - d6) * ac);
  const Scalar va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0)
    return feature = 2, Vec3(b + (d4 - d3) / ((d4 - d3) + (d5 - d6)) * (c - b));
  const Scalar denom = 1 / (va + vb + vc);
  return feature = 0, Vec3(a + ab * (vb * denom) + ac * (vc * denom));
}

inline void check_finite_point(const Vec3& p, const char* what) {
  if (!p.allFinite()) fail<InvalidArgument>("{}: coordinates must be finite, got ({}, {}, {})", what, p.x(), p.y(), p.z());
}

/// The largest coordinate a bounded cut's geometry (a patch's corners, a surface's vertices) may
/// have. Its distances come from closest_on_triangle, whose barycentric terms (vc = d1 d4 - d3 d2,
/// each d a dot product of two lengths) are products of four lengths: they overflow, and the
/// level set turns NaN or lands on the wrong feature, once lengths pass 1.8e308^(1/4) ~ 1.2e77
/// (a triangle of 1e100 gave |Lambda| = sqrt(DBL_MAX) for a point a unit from it). 1e75 leaves a
/// factor of ten for the differences and sums of coordinates.
inline constexpr Scalar max_cut_coordinate = 1e75;
inline void check_cut_magnitude(const Vec3& p, const char* what) {
  if (!(p.cwiseAbs().maxCoeff() <= max_cut_coordinate))
    fail<InvalidArgument>("{}: coordinates up to 1e75 in magnitude are supported (its distances are formed from "
                          "products of four lengths, which must stay finite), got ({}, {}, {})",
                          what, p.x(), p.y(), p.z());
}

/// v / |v| for any finite v, whatever its scale. |v|^2 over- or underflows for components beyond
/// ~1e154 or below ~1e-154 (|(1e200, 0, 0)| = inf, |(1e-200, 0, 0)| = 0); divided by its largest
/// component first, v has a norm in [1, sqrt 3], which does neither. Where |v|^2 is well inside
/// the range, v / |v| directly: the same bits as before the scaled path existed, for every
/// ordinary normal. Zero for a zero v.
inline Vec3 unit_direction(const Vec3& v) {
  const Scalar z = v.squaredNorm();
  if (z >= 1e-200 && z <= 1e200) return v / std::sqrt(z);
  const Scalar m = v.cwiseAbs().maxCoeff();
  if (!(m > 0)) return Vec3::Zero();
  const Vec3 w = v / m;
  return w / w.norm();
}

/// The unit normal of a x b, whatever the edges' scale (for edges of 1e200 the cross product
/// overflows, for 1e-200 it underflows: then each edge is scaled by its largest component
/// first). Zero if the edges are parallel or one is zero.
inline Vec3 unit_cross(const Vec3& a, const Vec3& b) {
  const Vec3 c = a.cross(b);
  if (const Scalar z = c.squaredNorm(); z >= 1e-200 && z <= 1e200) return c / std::sqrt(z);
  const Scalar ma = a.cwiseAbs().maxCoeff(), mb = b.cwiseAbs().maxCoeff();
  if (!(ma > 0) || !(mb > 0)) return Vec3::Zero();
  return unit_direction((a / ma).cross(b / mb));
}

}  // namespace detail

/// An infinite cutting plane through `point` with normal `normal` (not necessarily unit).
struct CutPlane {
  Vec3 point = Vec3::Zero(), normal = Vec3::UnitZ();

  CutPlane() = default;
  CutPlane(const Vec3& p, const Vec3& n) : point(p), normal(n) {
    detail::check_finite_point(p, "cut plane point");
    detail::check_finite_point(n, "cut plane normal");
    // Normalised whatever its scale (n.normalized() turned (1e200, 0, 0) into zero and refused
    // (1e-200, 0, 0) as zero; only the direction matters).
    normal = detail::unit_direction(n);
    if (!(normal.norm() > 0)) fail<InvalidArgument>("cut plane: the normal is zero");
  }
  Scalar signed_distance(const Vec3& x) const { return normal.dot(x - point); }
  bool meets(const Box& box) const {
    // The box's corners on both sides (or on the plane).
    Scalar lo = std::numeric_limits<Scalar>::max(), hi = std::numeric_limits<Scalar>::lowest();
    for (int k = 0; k < 8; ++k) {
      const Vec3 c((k & 1) ? box.hi.x() : box.lo.x(), (k & 2) ? box.hi.y() : box.lo.y(), (k & 4) ? box.hi.z() : box.lo.z());
      const Scalar d = signed_distance(c);
      lo = std::min(lo, d), hi = std::max(hi, d);
    }
    return lo <= 0 && hi >= 0;
  }
  Box bounds() const { return {Vec3::Constant(-std::numeric_limits<Scalar>::max()), Vec3::Constant(std::numeric_limits<Scalar>::max())}; }
};

/// A bounded planar cut: the parallelogram origin + s e1 + t e2, s, t in [0, 1]; positive on
/// the side of e1 x e2.
struct CutPatch {
  Vec3 origin = Vec3::Zero(), e1 = Vec3::UnitX(), e2 = Vec3::UnitY();

  CutPatch() = default;
  CutPatch(const Vec3& o, const Vec3& a, const Vec3& b) : origin(o), e1(a), e2(b) {
    detail::check_finite_point(o, "cut patch origin");
    detail::check_finite_point(a, "cut patch edge");
    detail::check_finite_point(b, "cut patch edge");
    // Parallel or zero edges span no area at any scale: the sine of their angle, from the edges
    // scaled by their largest components (|a x b| over- or underflowed for edges of 1e200 or
    // 1e-200, and refused them as spanning no area).
    const Vec3 as = detail::unit_direction(a), bs = detail::unit_direction(b);
    if (!(as.cross(bs).norm() > 1e-14))
      fail<InvalidArgument>("cut patch: its edges ({}, {}, {}) and ({}, {}, {}) span no area", a.x(), a.y(), a.z(), b.x(),
                            b.y(), b.z());
    for (const Vec3& corner : {o, Vec3(o + a), Vec3(o + b), Vec3(o + a + b)})
      detail::check_cut_magnitude(corner, "cut patch corner");
  }
  /// The unit normal e1 x e2 / |e1 x e2|, whatever the edges' scale.
  Vec3 normal() const { return detail::unit_cross(e1, e2); }
  /// The patch's plane's side, and the distance to the patch.
  Scalar signed_distance(const Vec3& x) const {
    const Vec3 n = normal();
    const Scalar h = n.dot(x - origin);
    // Closest point: on the patch's two triangles.
    int f;
    const Vec3 p1 = detail::closest_on_triangle(x, origin, origin + e1, origin + e1 + e2, f);
    const Vec3 p2 = detail::closest_on_triangle(x, origin, origin + e1 + e2, origin + e2, f);
    const Scalar d = std::min((x - p1).norm(), (x - p2).norm());
    return h >= 0 ? d : -d;
  }
  bool meets(const Box& box) const {
    return detail::triangle_meets_box(origin, origin + e1, origin + e1 + e2, box) ||
           detail::triangle_meets_box(origin, origin + e1 + e2, origin + e2, box);
  }
  /// Whether the patch's interior (shrunk by 1e-9 of its edges) meets the box: an element that
  /// only touches the patch's boundary (the front of a slit) is not cut by it.
  bool meets_interior(const Box& box) const {
    const Scalar eps = 1e-9;
    return CutPatch(origin + eps * (e1 + e2), (1 - 2 * eps) * e1, (1 - 2 * eps) * e2).meets(box);
  }
  Box bounds() const {
    Box b;
    for (const Vec3& p : {origin, Vec3(origin + e1), Vec3(origin + e2), Vec3(origin + e1 + e2)}) b.add(p);
    return b;
  }
};

/// A triangulated cut surface, open or closed: vertices and counter-clockwise triangles
/// (their normals, by the right-hand rule, point to the positive side).
class CutSurface {
 public:
  CutSurface() = default;
  CutSurface(std::vector<Vec3> vertices, std::vector<std::array<Index, 3>> triangles)
      : v_(std::move(vertices)), t_(std::move(triangles)) {
    if (t_.empty()) fail<InvalidArgument>("cut surface: no triangles");
    for (size_t i = 0; i < v_.size(); ++i) {
      if (!v_[i].allFinite()) fail<InvalidArgument>("cut surface: vertex {} is not finite", i);
      detail::check_cut_magnitude(v_[i], "cut surface vertex");
    }
    for (size_t k = 0; k < t_.size(); ++k)
      for (Index i : t_[k])
        if (i < 0 || static_cast<size_t>(i) >= v_.size())
          fail<InvalidArgument>("cut surface: triangle {} has vertex {} out of range [0, {})", k, i, v_.size());
    repair();
    build_pseudo_normals();
    for (const Vec3& p : v_) bounds_.add(p);
    build_tree();
  }
  const std::vector<Vec3>& vertices() const { return v_; }
  /// The triangles after repair (see repair()): degenerate and repeated ones dropped, every
  /// connected part consistently oriented.
  const std::vector<std::array<Index, 3>>& triangles() const { return t_; }
  /// Triangles the repair dropped (zero area, or a repeat of another's vertices).
  int dropped_triangles() const { return dropped_; }
  /// Triangles the repair turned over to agree with their neighbours.
  int flipped_triangles() const { return flipped_; }

  /// Signed distance by the closest triangle's pseudo-normal (see the file comment).
  Scalar signed_distance(const Vec3& x) const {
    Scalar best = std::numeric_limits<Scalar>::max();
    size_t best_k = t_.size();
    Vec3 normal = Vec3::Zero(), closest = Vec3::Zero();
    if (nodes_.empty()) return std::sqrt(best);  // a default-constructed surface: nothing is near
    // Branch and bound over the tree, nearer child first; a node is skipped only if its box is
    // strictly farther than the best so far, so that ties are all seen.
    int stack[64];
    int top = 0;
    stack[top++] = 0;
    while (top > 0) {
      const Node& node = nodes_[stack[--top]];
      if (squared_distance(node.box, x) > best) continue;
      if (node.left < 0) {
        for (int j = node.begin; j < node.end; ++j) {
          const size_t k = static_cast<size_t>(order_[j]);
          const auto& t = t_[k];
          int feature = 0;
          const Vec3 p = detail::closest_on_triangle(x, v_[t[0]], v_[t[1]], v_[t[2]], feature);
          const Scalar d = (x - p).squaredNorm();
          if (d < best || (d == best && k < best_k)) {
            best = d, best_k = k, closest = p;
            if (feature == 0) normal = face_normal_[k];
            else if (feature <= 3) normal = edge_normal(t[feature - 1], t[feature % 3]);
            else normal = vertex_normal_[t[feature - 4]];
          }
        }
        continue;
      }
      const bool left_first = squared_distance(nodes_[node.left].box, x) <= squared_distance(nodes_[node.right].box, x);
      stack[top++] = left_first ? node.right : node.left;
      stack[top++] = left_first ? node.left : node.right;
    }
    const Scalar d = std::sqrt(best);
    return normal.dot(x - closest) >= 0 ? d : -d;
  }
  bool meets(const Box& box) const {
    if (nodes_.empty()) return false;
    int stack[64];
    int top = 0;
    stack[top++] = 0;
    while (top > 0) {
      const Node& node = nodes_[stack[--top]];
      if (!node.box.overlaps(box)) continue;
      if (node.left < 0) {
        for (int j = node.begin; j < node.end; ++j) {
          const auto& t = t_[order_[j]];
          if (detail::triangle_meets_box(v_[t[0]], v_[t[1]], v_[t[2]], box)) return true;
        }
        continue;
      }
      stack[top++] = node.right;
      stack[top++] = node.left;
    }
    return false;
  }
  Box bounds() const { return bounds_; }

 private:
  /// What can be repaired is, what cannot is refused naming the triangle (issue 33 item 7):
  /// - a triangle of zero area (a repeated vertex, collinear or coincident vertices) has no
  ///   normal; as the closest feature of a point it gave that point the sign of a zero normal
  ///   (one such triangle flipped the side of 16 nodes): dropped, as is a repeat of another
  ///   triangle's three vertices;
  /// - an edge on three or more triangles (a non-manifold sheet) has no one side: refused;
  /// - neighbours must run through their shared edge in opposite directions (one orientation
  ///   per connected part): the triangles that disagree with the majority of their part are
  ///   turned over; a part that cannot be oriented (a Moebius strip) is refused.
  /// Each repair is announced as a note (core/log.hpp). Self-intersection is not detected.
  void repair() {
    const size_t given = t_.size();
    std::vector<std::array<Index, 3>> kept;
    std::map<std::array<Index, 3>, size_t> seen;
    std::vector<size_t> dropped_ids;
    for (size_t k = 0; k < t_.size(); ++k) {
      std::array<Index, 3> key = t_[k];
      std::sort(key.begin(), key.end());
      // Whatever its scale: |e1 x e2| of a triangle of 1e-160 underflowed to 0.
      const bool area = key[0] != key[1] && key[1] != key[2] && face_unit_normal(k).norm() > 0;
      if (!area || !seen.emplace(key, k).second) {
        dropped_ids.push_back(k);
        continue;
      }
      kept.push_back(t_[k]);
    }
    if (kept.empty()) fail<InvalidArgument>("cut surface: all {} triangles have zero area", given);
    t_.swap(kept);
    dropped_ = static_cast<int>(dropped_ids.size());

    // Edges and the triangles on them.
    std::map<std::pair<Index, Index>, std::vector<size_t>> on_edge;
    for (size_t k = 0; k < t_.size(); ++k)
      for (int c = 0; c < 3; ++c) {
        const Index a = t_[k][c], b = t_[k][(c + 1) % 3];
        auto& list = on_edge[{std::min(a, b), std::max(a, b)}];
        list.push_back(k);
        if (list.size() > 2)
          fail<InvalidArgument>("cut surface: edge ({}, {}) is on {} triangles (triangles {}, {} and {} after "
                                "dropping degenerate ones): a cut surface must be a manifold, each edge on at most two",
                                a, b, list.size(), list[0], list[1], list[2]);
      }
    // Whether triangle k, turned over or not, runs from a to b.
    std::vector<char> flip(t_.size(), 0), visited(t_.size(), 0);
    auto runs = [&](size_t k, Index a, Index b) {
      const auto& t = t_[k];
      for (int c = 0; c < 3; ++c)
        if (t[c] == a) return (t[(c + 1) % 3] == b) != static_cast<bool>(flip[k]);
      return false;
    };
    std::vector<size_t> part, queue;
    for (size_t start = 0; start < t_.size(); ++start) {
      if (visited[start]) continue;
      part.clear(), queue.assign(1, start);
      visited[start] = 1;
      while (!queue.empty()) {
        const size_t k = queue.back();
        queue.pop_back();
        part.push_back(k);
        for (int c = 0; c < 3; ++c) {
          const Index a = t_[k][c], b = t_[k][(c + 1) % 3];
          for (size_t j : on_edge[{std::min(a, b), std::max(a, b)}]) {
            if (j == k) continue;
            // Consistent: j runs b -> a where k runs a -> b.
            const bool need_flip = runs(k, a, b) == runs(j, a, b);
            if (!visited[j]) {
              if (need_flip) flip[j] = !flip[j];
              visited[j] = 1;
              queue.push_back(j);
            } else if (need_flip) {
              fail<InvalidArgument>("cut surface: triangles {} and {} cannot be oriented alike (the part they belong "
                                    "to is not orientable, like a Moebius strip): a cut needs two sides",
                                    k, j);
            }
          }
        }
      }
      // Keep the orientation most of the part's triangles were given.
      size_t turned = 0;
      for (size_t k : part) turned += flip[k];
      if (2 * turned > part.size())
        for (size_t k : part) flip[k] = !flip[k];
    }
    for (size_t k = 0; k < t_.size(); ++k)
      if (flip[k]) std::swap(t_[k][1], t_[k][2]), ++flipped_;
    if (dropped_ > 0 || flipped_ > 0) {
      std::string ids;
      for (size_t i = 0; i < dropped_ids.size() && i < 10; ++i) ids += fmt::format("{}{}", i ? ", " : "", dropped_ids[i]);
      note(fmt::format("cut surface repaired: {} of {} triangles dropped (zero area or repeated{}{}{}), {} turned over "
                       "to agree with their neighbours",
                       dropped_, given, dropped_ > 0 ? ": " : "", ids, dropped_ids.size() > 10 ? ", ..." : "", flipped_));
    }
  }
  Vec3 face_normal(size_t k) const {
    const auto& t = t_[k];
    return (v_[t[1]] - v_[t[0]]).cross(v_[t[2]] - v_[t[0]]);  // |n| = twice the area
  }
  Vec3 face_unit_normal(size_t k) const {
    const auto& t = t_[k];
    return detail::unit_cross(v_[t[1]] - v_[t[0]], v_[t[2]] - v_[t[0]]);
  }
  Vec3 edge_normal(Index a, Index b) const {
    const auto it = edge_normal_.find({std::min(a, b), std::max(a, b)});
    return it == edge_normal_.end() ? Vec3::Zero() : it->second;
  }
  void build_pseudo_normals() {
    vertex_normal_.assign(v_.size(), Vec3::Zero());
    face_normal_.resize(t_.size());
    for (size_t k = 0; k < t_.size(); ++k) {
      // Unit normals whatever the triangle's scale (detail::unit_cross; n.normalized() left a
      // normal that underflowed unnormalised). The face normal the sign test uses is e1 x e2 where
      // that is well inside the range (the bits it always had; only its direction matters), else
      // the unit one.
      const Vec3 n = face_normal(k);
      const Vec3 u = face_unit_normal(k);
      const Scalar z = n.squaredNorm();
      face_normal_[k] = z >= 1e-200 && z <= 1e200 ? n : u;
      if (!(u.norm() > 0)) continue;
      const auto& t = t_[k];
      for (int c = 0; c < 3; ++c) {
        const Index a = t[c], b = t[(c + 1) % 3], p = t[(c + 2) % 3];
        // Angle-weighted vertex normals; edges get the sum of their faces' unit normals.
        const Vec3 e1 = detail::unit_direction(v_[b] - v_[a]), e2 = detail::unit_direction(v_[p] - v_[a]);
        vertex_normal_[a] += std::acos(std::clamp(e1.dot(e2), Scalar(-1), Scalar(1))) * u;
        // (Eigen leaves a default-constructed Vec3 uninitialised: start the sum at zero.)
        edge_normal_.try_emplace({std::min(a, b), std::max(a, b)}, Vec3::Zero()).first->second += u;
      }
    }
  }

  /// A node of the triangle tree: its box, and its children, or (a leaf, left < 0) its
  /// triangles order_[begin, end).
  struct Node {
    Box box;
    int left = -1, right = -1, begin = 0, end = 0;
  };
  static Scalar squared_distance(const Box& b, const Vec3& x) {
    return (b.lo - x).cwiseMax(x - b.hi).cwiseMax(0.0).squaredNorm();
  }
  void build_tree() {
    order_.resize(t_.size());
    std::vector<Vec3> centroid(t_.size());
    for (size_t k = 0; k < t_.size(); ++k) {
      order_[k] = static_cast<Index>(k);
      centroid[k] = (v_[t_[k][0]] + v_[t_[k][1]] + v_[t_[k][2]]) / 3;
    }
    nodes_.clear();
    nodes_.reserve(2 * t_.size());
    build_node(0, static_cast<int>(t_.size()), centroid, 0);
  }
  int build_node(int begin, int end, const std::vector<Vec3>& centroid, int depth) {
    const int id = static_cast<int>(nodes_.size());
    nodes_.push_back(Node{});
    Box box, centres;
    for (int j = begin; j < end; ++j) {
      for (Index i : t_[order_[j]]) box.add(v_[i]);
      centres.add(centroid[order_[j]]);
    }
    nodes_[id].box = box;
    // Depth <= 60 keeps the traversal stacks (64) safe whatever the triangles; a median split
    // halves the count, so only 2^60 triangles would reach it.
    if (end - begin <= 4 || depth >= 60) {
      nodes_[id].begin = begin, nodes_[id].end = end;
      return id;
    }
    int axis = 0;
    (centres.hi - centres.lo).maxCoeff(&axis);
    const int mid = (begin + end) / 2;
    std::nth_element(order_.begin() + begin, order_.begin() + mid, order_.begin() + end, [&](Index a, Index b) {
      return centroid[a][axis] < centroid[b][axis] || (centroid[a][axis] == centroid[b][axis] && a < b);
    });
    const int left = build_node(begin, mid, centroid, depth + 1);
    const int right = build_node(mid, end, centroid, depth + 1);
    nodes_[id].left = left, nodes_[id].right = right;
    return id;
  }

  std::vector<Vec3> v_;
  std::vector<std::array<Index, 3>> t_;
  std::vector<Node> nodes_;     ///< the triangle tree, root first
  std::vector<Index> order_;    ///< triangle indices, each leaf's a contiguous range
  std::vector<Vec3> vertex_normal_;
  int dropped_ = 0, flipped_ = 0;  ///< what repair() did
  std::vector<Vec3> face_normal_;  ///< per triangle, for the sign (build_pseudo_normals)
  std::map<std::pair<Index, Index>, Vec3> edge_normal_;
  Box bounds_;
};

inline Scalar signed_distance(const Cut& c, const Vec3& x) {
  return std::visit([&](const auto& s) { return s.signed_distance(x); }, c);
}
inline bool cut_meets(const Cut& c, const Box& box) {
  return std::visit([&](const auto& s) { return s.meets(box); }, c);
}
/// Whether the cut's interior meets the box (a patch's boundary does not count).
inline bool cut_meets_interior(const Cut& c, const Box& box) {
  if (const auto* p = std::get_if<CutPatch>(&c)) return p->meets_interior(box);
  return cut_meets(c, box);
}
inline Box cut_bounds(const Cut& c) {
  return std::visit([](const auto& s) { return s.bounds(); }, c);
}

}  // namespace plastifem
