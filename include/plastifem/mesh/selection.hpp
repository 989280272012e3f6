#pragma once
// Selecting nodes and boundary faces: by predicate on positions, or by an axis-aligned box.
#include <plastifem/mesh/mesh.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <optional>
#include <unordered_map>
#include <vector>

namespace plastifem {

/// Nodes whose position satisfies `pred(Vec3) -> bool`.
template <FiniteElement E, class Pred>
std::vector<Index> select_nodes(const Mesh<E>& mesh, Pred&& pred) {
  std::vector<Index> ids;
  for (Index i = 0; i < mesh.num_nodes(); ++i)
    if (pred(mesh.node(i))) ids.push_back(i);
  return ids;
}

/// Nodes inside the box [lo - tol, hi + tol] (tol absorbs round-off in generated coordinates).
template <FiniteElement E>
std::vector<Index> select_nodes_in_box(const Mesh<E>& mesh, const Vec3& lo, const Vec3& hi, Scalar tol = 1e-9) {
  return select_nodes(mesh, [&](const Vec3& p) {
    return (p.array() >= lo.array() - tol).all() && (p.array() <= hi.array() + tol).all();
  });
}

namespace detail {

/// A face's identity: its sorted corner ids (padded with -1 where faces of several kinds have
/// fewer), the same from every element that has the face.
template <FiniteElement E>
struct FaceKey {
  static constexpr int corners = [] {
    int most = 0;
    for (int f = 0; f < E::num_faces; ++f) most = std::max(most, face_corners(E::face_shape(f)));
    return most;
  }();
  using Key = std::array<Index, corners>;
  struct Hash {
    size_t operator()(const Key& k) const {
      size_t h = 0;
      for (Index v : k) h = h * 1000003u ^ static_cast<size_t>(v);
      return h;
    }
  };
  static Key of(const Mesh<E>& mesh, FaceRef f) {
    const auto ids = mesh.face_nodes(f);
    Key k;
    k.fill(-1);
    std::copy_n(ids.begin(), face_corners(ids.shape), k.begin());
    std::sort(k.begin(), k.end());
    return k;
  }
};

}  // namespace detail

/// Faces that belong to exactly one element, found by matching the sorted corner ids of every
/// element face. Order: by element, then local face.
template <FiniteElement E>
std::vector<FaceRef> boundary_faces(const Mesh<E>& mesh) {
  using Key = detail::FaceKey<E>;
  std::unordered_map<typename Key::Key, int, typename Key::Hash> count;
  count.reserve(static_cast<size_t>(mesh.num_elements()) * E::num_faces);
  auto key = [&](FaceRef f) { return Key::of(mesh, f); };
  for (Index e = 0; e < mesh.num_elements(); ++e)
    for (int f = 0; f < E::num_faces; ++f) ++count[key({e, f})];
  std::vector<FaceRef> faces;
  for (Index e = 0; e < mesh.num_elements(); ++e)
    for (int f = 0; f < E::num_faces; ++f) {
      const int c = count[key({e, f})];
      if (c > 2) fail<MeshError>("element {} face {} is shared by {} elements (non-manifold mesh)", e, f, c);
      if (c == 1) faces.push_back({e, f});
    }
  return faces;
}

/// Throws InvalidArgument (`what`: the message's subject) unless every face of `faces` is a
/// boundary face of the mesh, listed once: a face shared with another element is inside the
/// body, and one listed twice (itself, or the same face from its other element) counts twice.
/// One pass over the mesh's faces, with lookups in a table of the given ones.
template <FiniteElement E>
void check_boundary_faces(const Mesh<E>& mesh, const std::vector<FaceRef>& faces, const char* what) {
  using Key = detail::FaceKey<E>;
  std::unordered_map<typename Key::Key, size_t, typename Key::Hash> listed;
  listed.reserve(faces.size());
  for (size_t i = 0; i < faces.size(); ++i) {
    const auto [it, added] = listed.try_emplace(Key::of(mesh, faces[i]), i);
    if (!added)
      fail<InvalidArgument>("{}: face (element {}, local face {}) is listed twice (as entries {} and {})", what,
                            faces[i].element, faces[i].face, it->second, i);
  }
  for (Index e = 0; e < mesh.num_elements(); ++e)
    for (int f = 0; f < E::num_faces; ++f) {
      const auto it = listed.find(Key::of(mesh, {e, f}));
      if (it == listed.end()) continue;
      const FaceRef& given = faces[it->second];
      if (given.element != e)
        fail<InvalidArgument>("{}: face (element {}, local face {}) is shared with element {}: not a boundary face",
                              what, given.element, given.face, e);
    }
}

/// Boundary faces all of whose nodes satisfy `pred(Vec3) -> bool`.
template <FiniteElement E, class Pred>
std::vector<FaceRef> select_boundary_faces(const Mesh<E>& mesh, Pred&& pred) {
  std::vector<FaceRef> faces;
  for (const FaceRef& f : boundary_faces(mesh)) {
    const auto ids = mesh.face_nodes(f);
    if (std::all_of(ids.begin(), ids.end(), [&](Index i) { return pred(mesh.node(i)); })) faces.push_back(f);
  }
  return faces;
}

/// Boundary faces with every node inside the box [lo - tol, hi + tol].
template <FiniteElement E>
std::vector<FaceRef> select_boundary_faces_in_box(const Mesh<E>& mesh, const Vec3& lo, const Vec3& hi,
                                                  Scalar tol = 1e-9) {
  return select_boundary_faces(mesh, [&](const Vec3& p) {
    return (p.array() >= lo.array() - tol).all() && (p.array() <= hi.array() + tol).all();
  });
}

/// Distinct nodes of a set of faces, sorted.
template <FiniteElement E>
std::vector<Index> nodes_of_faces(const Mesh<E>& mesh, const std::vector<FaceRef>& faces) {
  std::vector<Index> ids;
  for (const FaceRef& f : faces) {
    const auto fn = mesh.face_nodes(f);
    ids.insert(ids.end(), fn.begin(), fn.end());
  }
  std::sort(ids.begin(), ids.end());
  ids.erase(std::unique(ids.begin(), ids.end()), ids.end());
  return ids;
}

/// The boundary surface as a polygon soup over the mesh's own nodes (each face's kind in its
/// FaceNodes: face_vtk_type gives its VTK cell type), with outward orientation. For output and
/// surface loads.
template <FiniteElement E>
struct Surface {
  std::vector<FaceRef> faces;
  std::vector<FaceNodes<E>> connectivity;
};

template <FiniteElement E>
Surface<E> extract_surface(const Mesh<E>& mesh) {
  Surface<E> s;
  s.faces = boundary_faces(mesh);
  s.connectivity.reserve(s.faces.size());
  for (const FaceRef& f : s.faces) s.connectivity.push_back(mesh.face_nodes(f));
  return s;
}

/// Where a point lies in a mesh: an element and the point's reference coordinates in it.
struct PointLocation {
  Index element = -1;
  Vec3 xi = Vec3::Zero();
};

/// Whether reference coordinates lie in the reference element (within tol).
template <FiniteElement E>
bool in_reference_element(const Vec3& xi, Scalar tol = 1e-10) {
  return E::contains(xi, tol);
}

/// A box holding the whole element with rest nodes Xe: its nodes' box for a linear element
/// (non-negative shape functions: each point is a convex combination of the nodes). A
/// quadratic tetrahedron's edges and faces bulge past its nodes: x(xi) is the corners' affine
/// map plus sum_k 4 L_i L_j d_k over its edges (i, j), d_k = X_{4+k} - (X_i + X_j) / 2, and
/// sum_k 4 L_i L_j = 2 (1 - sum L^2) <= 3/2, so the box widens by 3/2 max_k |d_k| per axis (a
/// point inside a curved Tet10 but outside its nodes' box was refused; straight, it is unchanged).
template <FiniteElement E>
std::array<Vec3, 2> element_box(const ElementNodes<E>& Xe) {
  Vec3 lo = Xe.rowwise().minCoeff(), hi = Xe.rowwise().maxCoeff();
  if constexpr (E::order == 2 && E::num_vertices == 4 && E::num_nodes == 10) {
    Vec3 bulge = Vec3::Zero();
    for (int k = 0; k < 6; ++k) {
      const auto [i, j] = E::edges[static_cast<size_t>(k)];
      bulge = bulge.cwiseMax((Xe.col(4 + k) - 0.5 * (Xe.col(i) + Xe.col(j))).cwiseAbs());
    }
    lo -= 1.5 * bulge, hi += 1.5 * bulge;
  } else {
    static_assert(E::order == 1, "element_box: a bound for this element's curved shape is needed");
  }
  return {lo, hi};
}

/// X's reference coordinates in the element with rest nodes Xe, if it lies in it (within tol
/// relative to the element's size): Newton on x(xi) = X from the element's centre.
template <FiniteElement E>
std::optional<Vec3> locate_in_element(const ElementNodes<E>& Xe, const Vec3& X, Scalar tol = 1e-9) {
  const auto [lo, hi] = element_box<E>(Xe);
  const Scalar h = (hi - lo).maxCoeff();
  if (((X - lo).array() < -tol * h).any() || ((X - hi).array() > tol * h).any()) return std::nullopt;
  Vec3 xi = reference_centre<E>();
  for (int it = 0; it < 30; ++it) {
    const Vec3 r = Xe * E::shape(xi) - X;
    if (r.norm() <= 1e-14 * h) break;
    xi -= jacobian<E>(Xe, xi).inverse() * r;
  }
  if ((Xe * E::shape(xi) - X).norm() <= tol * h && in_reference_element<E>(xi, tol)) return xi;
  return std::nullopt;
}

/// The element containing X in the rest configuration (the lowest-numbered, for a point on a
/// face shared by several) and X's reference coordinates in it; nothing if no element contains
/// X (within tol relative to the element). Tests every element: for many points, PointLocator.
template <FiniteElement E>
std::optional<PointLocation> locate_point(const Mesh<E>& mesh, const Vec3& X, Scalar tol = 1e-9) {
  for (Index e = 0; e < mesh.num_elements(); ++e)
    if (const auto xi = locate_in_element<E>(mesh.element_nodes(e), X, tol)) return PointLocation{e, *xi};
  return std::nullopt;
}

/// Locates many points in a mesh's rest configuration. A uniform grid over the mesh's bounding
/// box, of about one cell per element, lists in each cell the elements whose bounding boxes
/// overlap it; a point tests only its cell's elements, in increasing order. An element that
/// contains X has X in its bounding box and so is listed in X's cell: the answer is
/// locate_point's, element for element, at O(elements per cell) instead of O(elements).
/// Built in O(elements); the mesh's nodes must not move afterwards (the rest configuration).
template <FiniteElement E>
class PointLocator {
 public:
  explicit PointLocator(const Mesh<E>& mesh, Scalar tol = 1e-9) : mesh_(&mesh), tol_(tol) {
    const Index ne = mesh.num_elements();
    if (ne == 0) return;
    lo_ = mesh.nodes().rowwise().minCoeff();
    const Vec3 hi = mesh.nodes().rowwise().maxCoeff();
    // Element boxes, widened by the tolerance (relative to the element, as locate_in_element).
    std::vector<std::array<Vec3, 2>> box(static_cast<size_t>(ne));
    for (Index e = 0; e < ne; ++e) {
      const auto [a, b] = element_box<E>(mesh.element_nodes(e));
      const Scalar pad = tol * (b - a).maxCoeff();
      box[static_cast<size_t>(e)] = {a.array() - pad, b.array() + pad};
    }
    // About one cell per element; a flat or thin mesh gets one cell across its thin sides.
    const Vec3 size = (hi - lo_).cwiseMax(Vec3::Constant(1e-300));
    const Scalar cell = std::cbrt(size.prod() / static_cast<Scalar>(ne));
    for (int d = 0; d < 3; ++d) {
      const Scalar n = std::clamp(std::floor(size[d] / cell), Scalar(1), Scalar(1024));
      dims_[d] = static_cast<Index>(n);
      inv_cell_[d] = static_cast<Scalar>(dims_[d]) / size[d];
    }
    // Counting sort of (cell, element) pairs: cells in CSR form, elements increasing in each.
    start_.assign(static_cast<size_t>(dims_.prod()) + 1, 0);
    auto for_cells = [&](Index e, auto&& f) {
      const auto& [a, b] = box[static_cast<size_t>(e)];
      const Eigen::Array<Index, 3, 1> c0 = cell_of(a), c1 = cell_of(b);
      for (Index k = c0[2]; k <= c1[2]; ++k)
        for (Index j = c0[1]; j <= c1[1]; ++j)
          for (Index i = c0[0]; i <= c1[0]; ++i) f(i + dims_[0] * (j + dims_[1] * k));
    };
    for (Index e = 0; e < ne; ++e) for_cells(e, [&](Index c) { ++start_[static_cast<size_t>(c) + 1]; });
    for (size_t c = 1; c < start_.size(); ++c) start_[c] += start_[c - 1];
    elements_.resize(static_cast<size_t>(start_.back()));
    std::vector<Index> fill(start_.begin(), start_.end() - 1);
    for (Index e = 0; e < ne; ++e) for_cells(e, [&](Index c) { elements_[static_cast<size_t>(fill[static_cast<size_t>(c)]++)] = e; });
  }

  /// The element containing X (the lowest-numbered) and X's reference coordinates in it, or
  /// nothing: locate_point(mesh, X, tol).
  std::optional<PointLocation> locate(const Vec3& X) const {
    std::optional<PointLocation> found;
    visit(X, [&](const PointLocation& where) {
      found = where;
      return false;  // the first, the lowest-numbered: stop
    });
    return found;
  }

  /// Calls f(PointLocation) for every element containing X (within the tolerance: a point on a
  /// shared face or edge is in each of its elements), in increasing element order.
  template <class F>
  void for_each_containing(const Vec3& X, F&& f) const {
    visit(X, [&](const PointLocation& where) {
      f(where);
      return true;
    });
  }

  /// Cells per direction, and the elements listed per cell on average (a query's cost).
  Eigen::Array<Index, 3, 1> grid() const { return dims_; }
  Scalar elements_per_cell() const {
    return static_cast<Scalar>(elements_.size()) / static_cast<Scalar>(std::max<Index>(dims_.prod(), 1));
  }

 private:
  /// Calls go(PointLocation) for the elements of X's cell that contain X, in increasing order,
  /// while it returns true.
  template <class F>
  void visit(const Vec3& X, F&& go) const {
    if (elements_.empty() || !X.allFinite()) return;
    const Eigen::Array<Index, 3, 1> c = cell_of(X);
    const Index cell = c[0] + dims_[0] * (c[1] + dims_[1] * c[2]);
    for (Index k = start_[static_cast<size_t>(cell)]; k < start_[static_cast<size_t>(cell) + 1]; ++k) {
      const Index e = elements_[static_cast<size_t>(k)];
      if (const auto xi = locate_in_element<E>(mesh_->element_nodes(e), X, tol_))
        if (!go(PointLocation{e, *xi})) return;
    }
  }

  /// The grid cell of p, clamped to the grid (a point outside it lands in a border cell, whose
  /// elements then refuse it).
  Eigen::Array<Index, 3, 1> cell_of(const Vec3& p) const {
    Eigen::Array<Index, 3, 1> c;
    for (int d = 0; d < 3; ++d) {
      const Scalar x = std::floor((p[d] - lo_[d]) * inv_cell_[d]);
      c[d] = static_cast<Index>(std::clamp(x, Scalar(0), static_cast<Scalar>(dims_[d] - 1)));
    }
    return c;
  }

  const Mesh<E>* mesh_;
  Scalar tol_;
  Vec3 lo_ = Vec3::Zero(), inv_cell_ = Vec3::Ones();
  Eigen::Array<Index, 3, 1> dims_ = Eigen::Array<Index, 3, 1>::Ones();
  std::vector<Index> start_, elements_;
};

}  // namespace plastifem
