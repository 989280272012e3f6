#pragma once
// Linear prism (wedge), 6 nodes: a triangle times a segment. The element of thick shells made
// from triangulated surfaces (membranes, capsules: mesh/generators.hpp, thick_shell_wedge6).
//
// Reference nodes (xi, eta, zeta): 0 (0,0,-1), 1 (0,1,-1), 2 (1,0,-1) at the bottom, and 3, 4, 5
// above them at zeta = 1.
//
// VTK_WEDGE (13) order: the right-hand normal of the triangle 0-1-2 points away from 3-4-5
// (VTK's documentation and face list; ParaView's cell size is negative for a wedge numbered
// the other way round). Gmsh's prism (type 6) numbers 0-1-2 the other way round, so the Gmsh
// reader takes a prism's nodes in the order `gmsh_nodes`.
//
// With L = (1 - xi - eta, eta, xi): N_i = L_i (1 - zeta) / 2, N_{3+i} = L_i (1 + zeta) / 2.
#include <plastifem/element/face.hpp>
#include <plastifem/element/quadrature.hpp>

#include <algorithm>
#include <array>

namespace plastifem {

/// A rule on the prism {x, y >= 0, x + y <= 1} x [-1, 1] (volume 1) of degree `Degree`: exact
/// for every x^a y^b z^c with a + b <= Degree and c <= Degree (tests/test_elements.cpp checks
/// it, and that it fails one degree above). A triangle rule of total degree Degree times the
/// Gauss-Legendre rule of Degree in z. The triangle rules: the centroid (degree 1), the 3-point
/// rule at (1/6, 1/6) and its permutations (degree 2), and above the collapsed 3 x 3 Gauss rule
/// (Stroud's conical product: x = u, y = v (1 - u), dA = (1 - u) du dv; a degree-d polynomial
/// becomes degree d + 1 in u and d in v, exact to d = 4 with 3 points each way). Up to degree 4.
template <int Degree>
auto prism_rule() {
  static_assert(Degree >= 0 && Degree <= 4, "prism rules are tabulated up to degree 4");
  constexpr int n_line = (Degree + 2) / 2;
  const auto line = detail::gauss_legendre_1d<n_line>();
  std::array<Scalar, 9> tx{}, ty{}, tw{};
  int n_tri = 0;
  if constexpr (Degree <= 1) {
    tx[0] = ty[0] = 1.0 / 3.0, tw[0] = 0.5, n_tri = 1;
  } else if constexpr (Degree == 2) {
    const Scalar p[3][2] = {{1.0 / 6, 1.0 / 6}, {2.0 / 3, 1.0 / 6}, {1.0 / 6, 2.0 / 3}};
    for (int k = 0; k < 3; ++k) tx[k] = p[k][0], ty[k] = p[k][1], tw[k] = 1.0 / 6;
    n_tri = 3;
  } else {
    const auto g = detail::gauss_legendre_1d<3>();
    for (int a = 0; a < 3; ++a)
      for (int b = 0; b < 3; ++b, ++n_tri) {
        const Scalar u = (1 + g[a][0]) / 2, v = (1 + g[b][0]) / 2;
        tx[n_tri] = u, ty[n_tri] = v * (1 - u), tw[n_tri] = g[a][1] * g[b][1] / 4 * (1 - u);
      }
  }
  constexpr int N = (Degree <= 1 ? 1 : Degree == 2 ? 3 : 9) * n_line;
  Quadrature<N> q{};
  int k = 0;
  for (int c = 0; c < n_line; ++c)
    for (int t = 0; t < n_tri; ++t, ++k) {
      q.points[k] = Vec3(tx[t], ty[t], line[c][0]);
      q.weights[k] = tw[t] * line[c][1];
    }
  q.degree = std::max(Degree, 1);
  return q;
}

struct Wedge6 {
  static constexpr const char* name = "Wedge6";
  static constexpr int num_nodes = 6;
  static constexpr int num_vertices = 6;
  static constexpr int order = 1;
  static constexpr int vtk_cell_type = 13, gmsh_type = 6;
  /// Local node k is node gmsh_nodes[k] of a Gmsh prism (0-1-2 counter-clockwise seen from 3-4-5).
  static constexpr std::array<int, 6> gmsh_nodes{0, 2, 1, 3, 5, 4};
  static constexpr Scalar reference_volume = 1.0;  // triangle 1/2 times height 2

  /// Faces with outward normals by the right-hand rule: the two triangles (Tri3, the fourth
  /// entry unused), then the three quadrilaterals (Quad4).
  static constexpr int num_faces = 5, nodes_per_face = 4;
  static constexpr std::array<std::array<int, 4>, 5> faces{
      {{0, 1, 2, -1}, {3, 5, 4, -1}, {0, 2, 5, 3}, {2, 1, 4, 5}, {1, 0, 3, 4}}};
  static constexpr FaceShape face_shape(int face) { return face < 2 ? FaceShape::triangle3 : FaceShape::quadrilateral4; }
  static constexpr std::array<std::array<int, 2>, 9> edges{
      {{0, 1}, {1, 2}, {2, 0}, {3, 4}, {4, 5}, {5, 3}, {0, 3}, {1, 4}, {2, 5}}};

  using ShapeVector = Eigen::Matrix<Scalar, num_nodes, 1>;
  using ShapeGradient = Eigen::Matrix<Scalar, num_nodes, 3>;
  using NodeMatrix = Eigen::Matrix<Scalar, 3, num_nodes>;

  static NodeMatrix reference_nodes() {
    NodeMatrix X;
    X << 0, 0, 1, 0, 0, 1,
         0, 1, 0, 0, 1, 0,
        -1, -1, -1, 1, 1, 1;
    return X;
  }

  static ShapeVector shape(const Vec3& p) {
    const Scalar L[3] = {1 - p.x() - p.y(), p.y(), p.x()};
    const Scalar lo = (1 - p.z()) / 2, hi = (1 + p.z()) / 2;
    ShapeVector N;
    for (int i = 0; i < 3; ++i) N[i] = L[i] * lo, N[3 + i] = L[i] * hi;
    return N;
  }

  static ShapeGradient gradient(const Vec3& p) {
    const Scalar L[3] = {1 - p.x() - p.y(), p.y(), p.x()};
    const Scalar dL[3][2] = {{-1, -1}, {0, 1}, {1, 0}};  // dL_i / d(xi, eta)
    const Scalar lo = (1 - p.z()) / 2, hi = (1 + p.z()) / 2;
    ShapeGradient G;
    for (int i = 0; i < 3; ++i) {
      G(i, 0) = dL[i][0] * lo, G(i, 1) = dL[i][1] * lo, G(i, 2) = -L[i] / 2;
      G(3 + i, 0) = dL[i][0] * hi, G(3 + i, 1) = dL[i][1] * hi, G(3 + i, 2) = L[i] / 2;
    }
    return G;
  }

  /// The prism rule of `Degree`: total degree in (xi, eta), degree in zeta (prism_rule above).
  template <int Degree>
  static auto quadrature() {
    return prism_rule<Degree>();
  }
  /// Full integration. Stiffness: the textbook 3 x 2 = 6-point rule (degree 2: B^T D B of a
  /// right prism has degree 2 in (xi, eta) and in zeta). Mass: N_a N_b det J of a distorted
  /// prism has degree 3 in (xi, eta) and 4 in zeta: 9 x 3 = 27 points. Volume: det J has degree
  /// 1 in (xi, eta) and 2 in zeta (the 3 x 2 rule).
  static constexpr int stiffness_degree = 2, mass_degree = 4, volume_degree = 2;

  /// Whether reference coordinates lie in the element (within tol).
  static bool contains(const Vec3& xi, Scalar tol) {
    return xi.x() >= -tol && xi.y() >= -tol && xi.x() + xi.y() <= 1 + tol && std::abs(xi.z()) <= 1 + tol;
  }

  /// Three tetrahedra on the nodes (each of volume 1/3 in reference coordinates), fixed by local
  /// numbering: the X-FEM split uses conforming_sub_tetrahedra instead.
  static constexpr std::array<std::array<int, 4>, 3> sub_tetrahedra{{{0, 1, 2, 3}, {1, 2, 3, 4}, {2, 3, 4, 5}}};

  /// The split into three tetrahedra chosen from the element's global node ids (Dompierre,
  /// Labbe, Vallet and Camarero 1999, "How to subdivide pyramids, prisms and hexahedra into
  /// tetrahedra"): every quadrilateral face is split by its diagonal through the face's lowest
  /// id, so two prisms sharing a face split it alike (the X-FEM cut's piecewise-planar
  /// interpolant then meets itself across the face). The lowest id v of the element is on two
  /// quadrilaterals, whose diagonals both end at v: the tetrahedron of v and the opposite
  /// triangle, and the pyramid of v over the third quadrilateral, split by that face's own
  /// diagonal. (Of the 8 choices of three diagonals, the 2 cyclic ones have no split into 3
  /// tetrahedra; this rule never makes them.) Local node indices, each tetrahedron of positive
  /// volume in reference coordinates.
  template <class Id>
  static std::array<std::array<int, 4>, 3> conforming_sub_tetrahedra(const std::array<Id, 6>& ids) {
    int v = 0;
    for (int k = 1; k < 6; ++k)
      if (ids[static_cast<size_t>(k)] < ids[static_cast<size_t>(v)]) v = k;
    const int level = v < 3 ? 0 : 3, up = 3 - level;  // v's triangle, and the other one's offset from it
    const int a = level + (v - level + 1) % 3, b = level + (v - level + 2) % 3;  // the rest of v's triangle
    const int ap = a + up - level, bp = b + up - level, vp = v + up - level;      // their partners
    std::array<std::array<int, 4>, 3> t{};
    t[0] = {v, vp, ap, bp};
    // The quadrilateral a-b-b'-a' (without v): its diagonal through its lowest id.
    int low = a;
    for (int c : {b, bp, ap})
      if (ids[static_cast<size_t>(c)] < ids[static_cast<size_t>(low)]) low = c;
    if (low == a || low == bp) t[1] = {v, a, b, bp}, t[2] = {v, a, bp, ap};
    else t[1] = {v, a, b, ap}, t[2] = {v, b, bp, ap};
    for (auto& tet : t)
      if (reference_orientation(tet) < 0) std::swap(tet[2], tet[3]);
    return t;
  }
  /// Six times the signed volume of a tetrahedron on the nodes, in reference coordinates.
  static Scalar reference_orientation(const std::array<int, 4>& t) {
    const NodeMatrix X = reference_nodes();
    const Vec3 o = X.col(t[0]);
    return (X.col(t[1]) - o).cross(X.col(t[2]) - o).dot(X.col(t[3]) - o);
  }
  /// Degrees of the integrands on a tetrahedral piece of a right prism (the X-FEM pieces'
  /// rules): each dN/dxi has total degree 1 (linear in zeta, or in (xi, eta)), so the stiffness
  /// integrand has degree 2 in all and in each variable; the mass N_a N_b total degree 4.
  static constexpr int piece_stiffness_degree = 2, piece_stiffness_variable_degree = 2, piece_mass_degree = 4;
};

}  // namespace plastifem
