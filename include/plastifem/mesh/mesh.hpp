#pragma once
// A volume mesh of one element type: node coordinates, connectivity, named node sets and
// named boundary-face sets. A Mesh is validated when it is built, so every Mesh in a program
// is usable: indices in range, finite coordinates, no degenerate or inverted element.
//
// The mesh is the undeformed reference geometry only. Per-element rest shapes (plasticity)
// and enriched dofs (X-FEM) live in the solver, which keeps the mesh immutable and shared.
#include <plastifem/core/error.hpp>
#include <plastifem/element/element.hpp>

#include <algorithm>
#include <array>
#include <cctype>
#include <limits>
#include <cmath>
#include <map>
#include <string>
#include <vector>

namespace plastifem {

/// One face of one element: `element`'s local face `face` (index into E::faces).
struct FaceRef {
  Index element;
  int face;
  friend bool operator==(const FaceRef&, const FaceRef&) = default;
};

/// Global node ids of one element face: as many as its kind has (E::face_shape), corners
/// first, in the element's local face order (outward normal).
template <FiniteElement E>
struct FaceNodes {
  std::array<Index, E::nodes_per_face> ids = filled(-1);  ///< -1 beyond size() (a triangle of a Wedge6)
  FaceShape shape{};
  int size() const { return face_node_count(shape); }
  Index operator[](int k) const { return ids[static_cast<size_t>(k)]; }
  const Index* begin() const { return ids.data(); }
  const Index* end() const { return ids.data() + size(); }

 private:
  static constexpr std::array<Index, E::nodes_per_face> filled(Index v) {
    std::array<Index, E::nodes_per_face> a{};
    a.fill(v);
    return a;
  }
};

/// The largest mesh plastifem can index: each node carries 3 degrees of freedom, and nodes,
/// elements and degrees of freedom are numbered by Index (32 bits).
inline constexpr std::int64_t max_mesh_nodes = std::numeric_limits<Index>::max() / 3;
inline constexpr std::int64_t max_mesh_elements = std::numeric_limits<Index>::max();

/// What validation found that is not an error.
struct MeshReport {
  std::vector<Index> unused_nodes;  ///< nodes no element refers to (they carry no stiffness)
  Scalar min_scaled_jacobian = 1;   ///< min over elements and points of det J / (h^3 / V_ref)
};

template <FiniteElement E>
class Mesh {
 public:
  using Element = E;
  using Connectivity = std::array<Index, E::num_nodes>;
  using Nodes = Eigen::Matrix<Scalar, 3, Eigen::Dynamic>;

  Mesh() = default;

  /// Builds and validates; throws MeshError naming the first bad node or element.
  Mesh(Nodes nodes, std::vector<Connectivity> elements)
      : nodes_(std::move(nodes)), elements_(std::move(elements)) {
    report_ = validate();
  }

  Index num_nodes() const { return static_cast<Index>(nodes_.cols()); }
  Index num_elements() const { return static_cast<Index>(elements_.size()); }
  const Nodes& nodes() const { return nodes_; }
  /// i, if it is a node of this mesh (else InvalidArgument).
  Index checked_node(Index i) const { return checked_index(i, num_nodes(), "node"); }
  Vec3 node(Index i) const { return nodes_.col(checked_node(i)); }
  const std::vector<Connectivity>& elements() const { return elements_; }
  const Connectivity& element(Index e) const { return elements_[checked_index(e, num_elements(), "element")]; }
  const MeshReport& report() const { return report_; }

  /// Coordinates of element e's nodes, one per column.
  ElementNodes<E> element_nodes(Index e) const {
    ElementNodes<E> X;
    for (int a = 0; a < E::num_nodes; ++a) X.col(a) = nodes_.col(elements_[e][a]);
    return X;
  }
  /// Element e's nodes at other positions of the mesh's nodes (3 per node: a material mesh).
  ElementNodes<E> element_nodes(Index e, const Vector& positions) const {
    ElementNodes<E> X;
    for (int a = 0; a < E::num_nodes; ++a) X.col(a) = positions.segment<3>(3 * elements_[e][a]);
    return X;
  }

  /// Global node ids of a face, in the element's local face order (outward normal).
  FaceNodes<E> face_nodes(FaceRef f) const {
    FaceNodes<E> n;
    n.shape = E::face_shape(f.face);
    for (int k = 0; k < n.size(); ++k) n.ids[static_cast<size_t>(k)] = elements_[f.element][E::faces[f.face][k]];
    return n;
  }

  // --- element weights (a cage's partly filled cells: embedding/cage.hpp) -----------------
  /// Scales each element's mass, body force, internal force, tangent and strain energy by w_e
  /// (the fraction of a cage cell that is tissue); stresses are the material's. Positive and
  /// finite, one per element; empty: every weight 1.
  void set_element_weights(std::vector<Scalar> w) {
    if (!w.empty() && static_cast<Index>(w.size()) != num_elements())
      fail<MeshError>("element weights: {} for {} elements", w.size(), num_elements());
    for (size_t e = 0; e < w.size(); ++e)
      if (!(w[e] > 0) || !std::isfinite(w[e]))
        fail<MeshError>("element weights: element {} has weight {} (positive and finite)", e, w[e]);
    weights_ = std::move(w);
  }
  bool weighted() const { return !weights_.empty(); }
  Scalar weight(Index e) const { return weights_.empty() ? Scalar(1) : weights_[static_cast<size_t>(e)]; }
  const std::vector<Scalar>& element_weights() const { return weights_; }

  // --- named sets (from a generator, a file's physical groups, or a selection) -----------
  void add_node_set(const std::string& name, std::vector<Index> ids) {
    for (Index i : ids)
      if (i < 0 || i >= num_nodes())
        fail<MeshError>("node set '{}': node {} out of range [0, {})", name, i, num_nodes());
    node_sets_[name] = std::move(ids);
  }
  void add_face_set(const std::string& name, std::vector<FaceRef> faces) {
    for (const FaceRef& f : faces)
      if (f.element < 0 || f.element >= num_elements() || f.face < 0 || f.face >= E::num_faces)
        fail<MeshError>("face set '{}': face (element {}, local face {}) out of range", name, f.element,
                        f.face);
    face_sets_[name] = std::move(faces);
  }
  bool has_node_set(const std::string& name) const { return node_sets_.count(name) != 0; }
  bool has_face_set(const std::string& name) const { return face_sets_.count(name) != 0; }
  const std::vector<Index>& node_set(const std::string& name) const {
    auto it = node_sets_.find(name);
    if (it == node_sets_.end()) fail<MeshError>("no node set named '{}'{}", name, list_names(node_sets_));
    return it->second;
  }
  const std::vector<FaceRef>& face_set(const std::string& name) const {
    auto it = face_sets_.find(name);
    if (it == face_sets_.end()) fail<MeshError>("no face set named '{}'{}", name, list_names(face_sets_));
    return it->second;
  }
  const std::map<std::string, std::vector<Index>>& node_sets() const { return node_sets_; }
  const std::map<std::string, std::vector<FaceRef>>& face_sets() const { return face_sets_; }

  /// Checks indices, coordinates and every element's Jacobian at the corners and at the points
  /// of its mass quadrature rule. Throws MeshError on the first problem; returns what is
  /// worth knowing but not fatal.
  MeshReport validate() const;

 private:
  // The scale-free shape check of element/element.hpp: det J of the element scaled to a unit
  // longest edge, relative to the reference element's; degenerate below 1e-10 (of a unit
  // cube's value), inverted below -1e-10.
  Scalar check_jacobian(Index e) const;
  // Two elements over the same nodes (in any order) would double their mass and stiffness.
  void check_duplicates() const;
  static std::string lower(std::string s) {
    for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    return s;
  }
  template <class Map>
  static std::string list_names(const Map& m) {
    if (m.empty()) return " (the mesh has none)";
    std::string s = " (have:";
    for (const auto& [k, v] : m) s += " '" + k + "'";
    return s + ")";
  }

  Nodes nodes_;
  std::vector<Connectivity> elements_;
  std::map<std::string, std::vector<Index>> node_sets_;
  std::map<std::string, std::vector<FaceRef>> face_sets_;
  std::vector<Scalar> weights_;  ///< per element, or empty: all 1
  MeshReport report_;
};

template <FiniteElement E>
MeshReport Mesh<E>::validate() const {
  MeshReport r;
  if (nodes_.cols() > max_mesh_nodes || elements_.size() > static_cast<size_t>(max_mesh_elements))
    fail<MeshError>("the mesh has {} nodes and {} elements; a mesh holds at most {} nodes (3 degrees of freedom "
                    "each) and {} elements (32-bit indices)", nodes_.cols(), elements_.size(), max_mesh_nodes,
                    max_mesh_elements);
  if (num_elements() == 0)
    fail<MeshError>("the mesh has no elements ({} nodes): nothing to simulate", num_nodes());
  for (Index i = 0; i < num_nodes(); ++i)
    if (!nodes_.col(i).allFinite())
      fail<MeshError>("node {} has a non-finite coordinate ({}, {}, {})", i, nodes_(0, i), nodes_(1, i),
                      nodes_(2, i));
  std::vector<char> used(nodes_.cols(), 0);
  for (Index e = 0; e < num_elements(); ++e) {
    const auto& c = elements_[e];
    for (int a = 0; a < E::num_nodes; ++a) {
      if (c[a] < 0 || c[a] >= num_nodes())
        fail<MeshError>("element {}, local node {}: node index {} out of range [0, {})", e, a, c[a],
                        num_nodes());
      for (int b = 0; b < a; ++b)
        if (c[b] == c[a])
          fail<MeshError>("element {} is degenerate: local nodes {} and {} are both node {}", e, b, a, c[a]);
      used[c[a]] = 1;
    }
    r.min_scaled_jacobian = std::min(r.min_scaled_jacobian, check_jacobian(e));
  }
  for (Index i = 0; i < num_nodes(); ++i)
    if (!used[i]) r.unused_nodes.push_back(i);
  check_duplicates();
  return r;
}

template <FiniteElement E>
Scalar Mesh<E>::check_jacobian(Index e) const {
  const ShapeCheck c = check_shape<E>(element_nodes(e));
  const char* what = c.at_corner ? "corner" : "quadrature point";
  if (c.inverted())
    fail<MeshError>("element {} is inverted: scaled det J = {:.3g} at {} {} (reorder its nodes: the {} "
                    "numbering is documented in element/{}.hpp)",
                    e, c.min_scaled_jacobian, what, c.where, E::name, lower(E::name));
  if (!c.valid())
    fail<MeshError>("element {} is degenerate: scaled det J = {:.3g} at {} {} (zero or near-zero volume, or a "
                    "non-finite coordinate)",
                    e, c.min_scaled_jacobian, what, c.where);
  return c.min_scaled_jacobian;
}

template <FiniteElement E>
void Mesh<E>::check_duplicates() const {
  std::vector<std::pair<Connectivity, Index>> sorted(elements_.size());
  for (Index e = 0; e < num_elements(); ++e) {
    sorted[e] = {elements_[e], e};
    std::sort(sorted[e].first.begin(), sorted[e].first.end());
  }
  std::sort(sorted.begin(), sorted.end());
  for (size_t k = 1; k < sorted.size(); ++k)
    if (sorted[k].first == sorted[k - 1].first)
      fail<MeshError>("elements {} and {} have the same nodes (a duplicated element would count its mass and "
                      "stiffness twice)",
                      std::min(sorted[k - 1].second, sorted[k].second), std::max(sorted[k - 1].second, sorted[k].second));
}

#ifdef PLASTIFEM_USE_COMPILED  // plastifem::compiled holds these (solver/instantiations.hpp)
extern template class Mesh<Tet4>;
extern template class Mesh<Tet10>;
extern template class Mesh<Hex8>;
extern template class Mesh<Wedge6>;
#endif

/// The mesh without the nodes no element refers to (report().unused_nodes: a CAD file's geometry
/// points, say). The other nodes keep their order and are renumbered 0..n-1; connectivity and node
/// sets follow (a set loses its dropped nodes and is kept even if that empties it); face sets are
/// unchanged, as they name elements. If `old_to_new` is given, it receives the new index of every
/// old node, -1 for a dropped one. A mesh without unused nodes is returned as it is.
template <FiniteElement E>
Mesh<E> drop_unused_nodes(const Mesh<E>& mesh, std::vector<Index>* old_to_new = nullptr) {
  std::vector<Index> map(static_cast<size_t>(mesh.num_nodes()), 0);
  for (Index i : mesh.report().unused_nodes) map[static_cast<size_t>(i)] = -1;
  Index n = 0;
  for (Index& m : map)
    if (m == 0) m = n++;
  if (n == mesh.num_nodes()) {
    if (old_to_new) *old_to_new = std::move(map);
    return mesh;
  }
  typename Mesh<E>::Nodes nodes(3, n);
  for (Index i = 0; i < mesh.num_nodes(); ++i)
    if (map[static_cast<size_t>(i)] >= 0) nodes.col(map[static_cast<size_t>(i)]) = mesh.nodes().col(i);
  std::vector<typename Mesh<E>::Connectivity> elements = mesh.elements();
  for (auto& c : elements)
    for (Index& i : c) i = map[static_cast<size_t>(i)];
  Mesh<E> out(std::move(nodes), std::move(elements));
  for (const auto& [name, ids] : mesh.node_sets()) {
    std::vector<Index> kept;
    for (Index i : ids)
      if (map[static_cast<size_t>(i)] >= 0) kept.push_back(map[static_cast<size_t>(i)]);
    out.add_node_set(name, std::move(kept));
  }
  for (const auto& [name, faces] : mesh.face_sets()) out.add_face_set(name, faces);
  out.set_element_weights(mesh.element_weights());
  if (old_to_new) *old_to_new = std::move(map);
  return out;
}

}  // namespace plastifem
