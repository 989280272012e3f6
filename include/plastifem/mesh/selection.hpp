#pragma once
// Selecting nodes and boundary faces: by predicate on positions, or by an axis-aligned box.
#include <plastifem/mesh/mesh.hpp>

#include <algorithm>
#include <optional>
#include <unordered_map>

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

/// Faces that belong to exactly one element, found by matching the sorted corner ids of every
/// element face. Order: by element, then local face.
template <FiniteElement E>
std::vector<FaceRef> boundary_faces(const Mesh<E>& mesh) {
  constexpr int nc = E::nodes_per_face == 6 ? 3 : E::nodes_per_face;  // corners of a face
  using Key = std::array<Index, nc>;
  struct KeyHash {
    size_t operator()(const Key& k) const {
      size_t h = 0;
      for (Index v : k) h = h * 1000003u ^ static_cast<size_t>(v);
      return h;
    }
  };
  std::unordered_map<Key, int, KeyHash> count;
  count.reserve(static_cast<size_t>(mesh.num_elements()) * E::num_faces);
  auto key = [&](FaceRef f) {
    const auto ids = mesh.face_nodes(f);
    Key k;
    std::copy_n(ids.begin(), nc, k.begin());
    std::sort(k.begin(), k.end());
    return k;
  };
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

/// The boundary surface as a polygon soup over the mesh's own nodes (Tri3, Tri6 or Quad4 per
/// E::vtk_face_type), with outward orientation. For output and surface loads.
template <FiniteElement E>
struct Surface {
  std::vector<FaceRef> faces;
  std::vector<std::array<Index, E::nodes_per_face>> connectivity;
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
  if constexpr (E::num_vertices == 8) return (xi.array().abs() <= 1 + tol).all();
  else return (xi.array() >= -tol).all() && xi.sum() <= 1 + tol;
}

/// The element containing X in the rest configuration (the first found, for a point on a face
/// shared by several) and X's reference coordinates in it, by Newton on x(xi) = X from the
/// element's centre; nothing if no element contains X (within tol relative to the element).
template <FiniteElement E>
std::optional<PointLocation> locate_point(const Mesh<E>& mesh, const Vec3& X, Scalar tol = 1e-9) {
  for (Index e = 0; e < mesh.num_elements(); ++e) {
    const ElementNodes<E> Xe = mesh.element_nodes(e);
    const Vec3 lo = Xe.rowwise().minCoeff(), hi = Xe.rowwise().maxCoeff();
    const Scalar h = (hi - lo).maxCoeff();
    if (((X - lo).array() < -tol * h).any() || ((X - hi).array() > tol * h).any()) continue;
    Vec3 xi = reference_centre<E>();
    for (int it = 0; it < 30; ++it) {
      const Vec3 r = Xe * E::shape(xi) - X;
      if (r.norm() <= 1e-14 * h) break;
      xi -= jacobian<E>(Xe, xi).inverse() * r;
    }
    if ((Xe * E::shape(xi) - X).norm() <= tol * h && in_reference_element<E>(xi, tol)) return PointLocation{e, xi};
  }
  return std::nullopt;
}

}  // namespace plastifem
