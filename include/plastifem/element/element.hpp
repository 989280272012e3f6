#pragma once
// What a finite element trait must provide, and the geometry every element shares:
// Jacobian, physical shape gradients, volume.
#include <plastifem/element/hex8.hpp>
#include <plastifem/element/tet10.hpp>
#include <plastifem/element/tet4.hpp>
#include <plastifem/element/wedge6.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <concepts>
#include <limits>

namespace plastifem {

/// A reference element: everything the library asks of an element type, so that a new element
/// is one header (Tet4, Tet10, Hex8, Wedge6 are the examples to read):
/// - nodes: `num_nodes`, the `num_vertices` corners first, polynomial `order`,
///   `reference_nodes()`, `reference_volume`;
/// - shape functions N(xi) (`shape`) and their gradients dN/dxi (`gradient`);
/// - quadrature: `quadrature<Degree>()` and the degrees of full integration
///   (`stiffness_degree`, `mass_degree`) and of det J (`volume_degree`, exact rest volumes);
/// - boundary: `num_faces` faces, each of its own kind (`face_shape(f)`, element/face.hpp)
///   with its nodes in `faces[f]` (outward by the right-hand rule; `nodes_per_face` is the
///   longest list), and `edges` as node pairs;
/// - `contains(xi, tol)`: point containment in reference coordinates;
/// - X-FEM cuts: `sub_tetrahedra` (a split into tetrahedra on the nodes), optionally
///   `conforming_sub_tetrahedra(ids)` (a split chosen from the element's global node ids, used
///   instead: needed where local numbering alone would let neighbours split a shared
///   quadrilateral face by different diagonals, as Wedge6's does; enrichment/subdivision.hpp),
///   and the degrees of the stiffness and mass integrands on a tetrahedral piece (`piece_*_degree`);
/// - file formats: `vtk_cell_type` (the node order is VTK's), `gmsh_type` and `gmsh_nodes` (the
///   Gmsh node of each local node).
namespace detail {
/// The node lists an element trait gives are consistent: one per face, as long as the face's
/// kind says and no longer than nodes_per_face; sub-tetrahedra and edges on the element's
/// nodes; gmsh_nodes a permutation.
template <class E>
consteval bool node_lists_consistent() {
  if (E::faces.size() != static_cast<size_t>(E::num_faces)) return false;
  for (int f = 0; f < E::num_faces; ++f) {
    const int n = face_node_count(E::face_shape(f));
    if (n > E::nodes_per_face || static_cast<int>(E::faces[static_cast<size_t>(f)].size()) != E::nodes_per_face) return false;
    for (int k = 0; k < n; ++k)
      if (E::faces[static_cast<size_t>(f)][static_cast<size_t>(k)] < 0 ||
          E::faces[static_cast<size_t>(f)][static_cast<size_t>(k)] >= E::num_nodes)
        return false;
  }
  for (const auto& t : E::sub_tetrahedra)
    for (int a : t)
      if (a < 0 || a >= E::num_nodes) return false;
  for (const auto& edge : E::edges)
    if (edge[0] < 0 || edge[0] >= E::num_nodes || edge[1] < 0 || edge[1] >= E::num_nodes || edge[0] == edge[1])
      return false;
  // gmsh_nodes is a permutation of the nodes.
  std::array<bool, E::num_nodes> seen{};
  for (int a : E::gmsh_nodes) {
    if (a < 0 || a >= E::num_nodes || seen[static_cast<size_t>(a)]) return false;
    seen[static_cast<size_t>(a)] = true;
  }
  return true;
}
}  // namespace detail

template <class E>
concept FiniteElement = requires(const Vec3& xi, Scalar tol) {
  { E::name } -> std::convertible_to<const char*>;
  { E::num_nodes } -> std::convertible_to<int>;
  { E::num_vertices } -> std::convertible_to<int>;
  { E::order } -> std::convertible_to<int>;
  { E::vtk_cell_type } -> std::convertible_to<int>;
  { E::gmsh_type } -> std::convertible_to<int>;
  { E::gmsh_nodes.size() } -> std::convertible_to<size_t>;
  { E::reference_volume } -> std::convertible_to<Scalar>;
  { E::reference_nodes() } -> std::same_as<Eigen::Matrix<Scalar, 3, E::num_nodes>>;
  { E::shape(xi) } -> std::same_as<Eigen::Matrix<Scalar, E::num_nodes, 1>>;
  { E::gradient(xi) } -> std::same_as<Eigen::Matrix<Scalar, E::num_nodes, 3>>;
  { E::num_faces } -> std::convertible_to<int>;
  { E::face_shape(0) } -> std::same_as<FaceShape>;
  E::faces[E::num_faces - 1][E::nodes_per_face - 1];
  E::edges[0][1];
  E::template quadrature<E::stiffness_degree>();
  E::template quadrature<E::mass_degree>();
  E::template quadrature<E::volume_degree>();
  { E::contains(xi, tol) } -> std::same_as<bool>;
  E::sub_tetrahedra[0][3];
  { E::piece_stiffness_degree } -> std::convertible_to<int>;
  { E::piece_stiffness_variable_degree } -> std::convertible_to<int>;
  { E::piece_mass_degree } -> std::convertible_to<int>;
} && detail::node_lists_consistent<E>();

static_assert(FiniteElement<Tet4> && FiniteElement<Tet10> && FiniteElement<Hex8> && FiniteElement<Wedge6>);

/// Node coordinates of one element, one node per column.
template <FiniteElement E>
using ElementNodes = Eigen::Matrix<Scalar, 3, E::num_nodes>;

/// Reference coordinates of the element centre (mean of the corners).
template <FiniteElement E>
Vec3 reference_centre() {
  const auto X = E::reference_nodes();
  Vec3 c = Vec3::Zero();
  for (int a = 0; a < E::num_vertices; ++a) c += X.col(a);
  return c / E::num_vertices;
}

/// J = dx/dxi = X dN for the reference gradient dN = dN/dxi at one point. (Written as loops:
/// Eigen's 3 x N by N x 3 product costs ~0.3 s of compile time per element type, in every file.)
template <FiniteElement E>
Mat3 jacobian_at(const ElementNodes<E>& X, const Eigen::Matrix<Scalar, E::num_nodes, 3>& dN) {
  Mat3 J;
  for (int j = 0; j < 3; ++j)
    for (int i = 0; i < 3; ++i) {
      Scalar s = 0;
      for (int a = 0; a < E::num_nodes; ++a) s += X(i, a) * dN(a, j);
      J(i, j) = s;
    }
  return J;
}

/// J = dx/dxi at the reference point xi.
template <FiniteElement E>
Mat3 jacobian(const ElementNodes<E>& X, const Vec3& xi) {
  return jacobian_at<E>(X, E::gradient(xi));
}

namespace detail {
/// p[Start] + ... + p[Start + Length - 1] summed pairwise (halves first), as Eigen reduces a
/// fixed-size expression it cannot vectorise.
template <int Start, int Length>
Scalar pairwise_sum(const Scalar* p) {
  if constexpr (Length == 1) return p[Start];
  else return pairwise_sum<Start, Length / 2>(p) + pairwise_sum<Start + Length / 2, Length - Length / 2>(p);
}
}  // namespace detail

/// Shape gradients with respect to physical coordinates, dN/dx = dN/dxi J^{-1}, for the
/// reference gradient dN at one point; `det_J`, if given, gets det J.
template <FiniteElement E>
Eigen::Matrix<Scalar, E::num_nodes, 3> physical_gradient_at(const ElementNodes<E>& X,
                                                           const Eigen::Matrix<Scalar, E::num_nodes, 3>& dN,
                                                           Scalar* det_J = nullptr) {
  if (det_J) *det_J = jacobian_at<E>(X, dN).determinant();
  // G = dN (X dN)^-1 as loops, with the round-off of Eigen's expression `dN * (X * dN).inverse()`
  // that earlier versions used (bit for bit with SSE2, the default x86-64 build; tested): the
  // expression cost 43 MB of g++'s memory in every file with a Solver, and an extremes case
  // (a chaotic release) follows Newton paths that a change of round-off can flip. Eigen sums
  // X dN's rows 0 and 1 in sequence (as one 2-wide packet) and row 2 pairwise (its scalar
  // reduction); G's three terms are summed in sequence.
  constexpr int N = E::num_nodes;
  Mat3 J;
  for (int j = 0; j < 3; ++j) {
    Scalar p[N];
    for (int i = 0; i < 2; ++i) {
      Scalar s = X(i, 0) * dN(0, j);
      for (int a = 1; a < N; ++a) s += X(i, a) * dN(a, j);
      J(i, j) = s;
    }
    for (int a = 0; a < N; ++a) p[a] = X(2, a) * dN(a, j);
    J(2, j) = detail::pairwise_sum<0, N>(p);
  }
  const Mat3 J_inverse = J.inverse();
  Eigen::Matrix<Scalar, N, 3> G;
  for (int j = 0; j < 3; ++j)
    for (int a = 0; a < N; ++a)
      G(a, j) = dN(a, 0) * J_inverse(0, j) + dN(a, 1) * J_inverse(1, j) + dN(a, 2) * J_inverse(2, j);
  return G;
}

/// dN/dx at the reference point xi.
template <FiniteElement E>
Eigen::Matrix<Scalar, E::num_nodes, 3> physical_gradient(const ElementNodes<E>& X, const Vec3& xi) {
  return physical_gradient_at<E>(X, E::gradient(xi));
}

/// dN/dxi at the points of the quadrature rule of `Degree` and (corner_gradients) at the
/// vertices, evaluated once per element type: the rest-shape updates of plasticity recompute
/// Jacobians at these points for every flowing element in every step.
template <FiniteElement E, int Degree>
const auto& quadrature_gradients() {
  using Rule = decltype(E::template quadrature<Degree>());
  static const auto table = [] {
    const auto q = E::template quadrature<Degree>();
    std::array<Eigen::Matrix<Scalar, E::num_nodes, 3>, Rule::size> g;
    for (int k = 0; k < q.size; ++k) g[k] = E::gradient(q.points[k]);
    return g;
  }();
  return table;
}
template <FiniteElement E>
const auto& corner_gradients() {
  static const auto table = [] {
    const auto Xref = E::reference_nodes();
    std::array<Eigen::Matrix<Scalar, E::num_nodes, 3>, E::num_vertices> g;
    for (int a = 0; a < E::num_vertices; ++a) g[a] = E::gradient(Xref.col(a));
    return g;
  }();
  return table;
}

/// What the shape check of one element found: the smallest scaled Jacobian determinant over
/// its corners and the points of its mass rule, and where.
struct ShapeCheck {
  Scalar min_scaled_jacobian = 1;  ///< det J of the element scaled to a unit longest edge, / that of the reference
  bool at_corner = false;          ///< the minimum is at a corner (else at a quadrature point)
  int where = 0;                   ///< which corner or point
  /// Degenerate below 1e-10 of a unit cube's value, inverted below -1e-10.
  bool valid() const { return min_scaled_jacobian > 1e-10; }
  bool inverted() const { return min_scaled_jacobian < -1e-10; }
};

/// The shape check of one element (rest shape or current configuration): det J at every corner
/// and at every point of the mass rule, for the element translated to its first node and scaled
/// to a unit longest edge. Scale-free: a valid element scaled by 1e200 or 1e-120 passes (its
/// raw det J over- or underflows), and a NaN coordinate fails.
template <FiniteElement E>
ShapeCheck check_shape(const ElementNodes<E>& X) {
  ShapeCheck r;
  r.min_scaled_jacobian = std::numeric_limits<Scalar>::max();
  Scalar h = 0;
  for (const auto& ed : E::edges) h = std::max(h, (X.col(ed[0]) - X.col(ed[1])).cwiseAbs().maxCoeff());
  if (!(h > 0) || !std::isfinite(h)) {
    r.min_scaled_jacobian = std::numeric_limits<Scalar>::quiet_NaN();
    return r;
  }
  ElementNodes<E> Y = (X.colwise() - X.col(0)) / h;  // longest edge component 1: no overflow
  Scalar len = 0;
  for (const auto& ed : E::edges) len = std::max(len, (Y.col(ed[0]) - Y.col(ed[1])).norm());
  Y /= len;  // longest edge exactly of unit length
  const Scalar scale = E::reference_volume;  // det J of the reference element mapped to itself is 1
  const auto& corners = corner_gradients<E>();
  const auto& points = quadrature_gradients<E, E::mass_degree>();
  auto check = [&](const auto& dN, bool corner, int k) {
    const Scalar s = jacobian_at<E>(Y, dN).determinant() * scale;
    if (!(s >= r.min_scaled_jacobian)) r = {std::isnan(s) ? std::numeric_limits<Scalar>::quiet_NaN() : s, corner, k};
  };
  for (int a = 0; a < E::num_vertices; ++a) check(corners[a], true, a);
  for (size_t k = 0; k < points.size(); ++k) check(points[k], false, static_cast<int>(k));
  return r;
}

/// Volume of an element, exact for the element's own geometry: det J has the degree of the
/// mass integrand or less (Tet4: 0, Tet10: 3, Hex8: 2 per variable).
template <FiniteElement E>
Scalar element_volume(const ElementNodes<E>& X) {
  const auto q = E::template quadrature<E::mass_degree>();
  const auto& dN = quadrature_gradients<E, E::mass_degree>();
  Scalar v = 0;
  for (int k = 0; k < q.size; ++k) v += q.weights[k] * jacobian_at<E>(X, dN[k]).determinant();
  return v;
}

/// Area element dA = |(J dxi/ds) x (J dxi/dt)| at reference point xi of a face parametrised by
/// (s, t), for an element of rest shape X: a face point's weight times it integrates over the
/// rest face (for_each_face_point, for_each_triangle_point).
template <FiniteElement E>
Scalar face_area_element(const ElementNodes<E>& X, const Vec3& xi, const Vec3& dxi_ds, const Vec3& dxi_dt) {
  const Mat3 J = jacobian<E>(X, xi);
  return (J * dxi_ds).cross(J * dxi_dt).norm();
}

/// Calls f(xi, dxi/ds, dxi/dt, weight) at the quadrature points of local face `face`, mapped
/// into the reference element, by the face's kind. Tri faces: 3-point degree-2 rule (exact
/// for Tet10's quadratic N_a on flat faces); quad faces: 2x2 Gauss (exact for bilinear N_a
/// times a bilinear dA).
template <FiniteElement E, class F>
void for_each_face_point(int face, F&& f) {
  const auto Xref = E::reference_nodes();
  const auto& fn = E::faces[static_cast<size_t>(face)];
  if constexpr (E::nodes_per_face >= 4) {  // an element with quadrilateral faces
    if (face_corners(E::face_shape(face)) == 4) {
      const Scalar g = 0.57735026918962576451;
      for (Scalar s : {-g, g})
        for (Scalar t : {-g, g}) {
          // Bilinear map of the reference face corners (flat faces of the reference cube).
          const Scalar Ns[4] = {(1 - s) * (1 - t) / 4, (1 + s) * (1 - t) / 4, (1 + s) * (1 + t) / 4,
                                (1 - s) * (1 + t) / 4};
          const Scalar dNs[4] = {-(1 - t) / 4, (1 - t) / 4, (1 + t) / 4, -(1 + t) / 4};
          const Scalar dNt[4] = {-(1 - s) / 4, -(1 + s) / 4, (1 + s) / 4, (1 - s) / 4};
          Vec3 xi = Vec3::Zero(), ds = Vec3::Zero(), dt = Vec3::Zero();
          for (int k = 0; k < 4; ++k) {
            xi += Ns[k] * Xref.col(fn[k]);
            ds += dNs[k] * Xref.col(fn[k]);
            dt += dNt[k] * Xref.col(fn[k]);
          }
          f(xi, ds, dt, 1.0);
        }
      return;
    }
  }
  // Triangles: Strang-Fix 3-point rule on the unit triangle (area 1/2), degree 2.
  const Scalar pts[3][2] = {{1.0 / 6, 1.0 / 6}, {2.0 / 3, 1.0 / 6}, {1.0 / 6, 2.0 / 3}};
  const Vec3 p0 = Xref.col(fn[0]), e1 = Xref.col(fn[1]) - p0, e2 = Xref.col(fn[2]) - p0;
  for (const auto& p : pts) f(Vec3(p0 + p[0] * e1 + p[1] * e2), e1, e2, 1.0 / 6);
}

/// Calls f(xi, dxi/ds, dxi/dt, weight) at the points of Dunavant's 6-point degree-4 rule on the
/// triangle p0 + s e1 + t e2 (s, t >= 0, s + t <= 1) of the reference element: exact for a
/// bilinear N_a times the bilinear area element of a flat Hex8 face, on any triangle of it (a
/// face cut into pieces, enrichment/cut_element.hpp).
template <class F>
void for_each_triangle_point(const Vec3& p0, const Vec3& e1, const Vec3& e2, F&& f) {
  // (D. A. Dunavant, IJNME 21, 1985, table for p = 4): two orbits of three points, weights for
  // the unit triangle's area 1/2.
  const Scalar a = 0.445948490915964886318, wa = 0.223381589678011465945 / 2;
  const Scalar b = 0.091576213509770743460, wb = 0.109951743655321867389 / 2;
  const Scalar pts[6][3] = {{a, a, wa}, {1 - 2 * a, a, wa}, {a, 1 - 2 * a, wa},
                            {b, b, wb}, {1 - 2 * b, b, wb}, {b, 1 - 2 * b, wb}};
  for (const auto& p : pts) f(Vec3(p0 + p[0] * e1 + p[1] * e2), e1, e2, p[2]);
}

}  // namespace plastifem
