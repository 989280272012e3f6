#pragma once
// Sub-element integration of a cut element (seed 001, section 5.2, Fig. 5-6): the element is
// split, in its reference coordinates, into sub-tetrahedra on either side of the cut, each with
// its own quadrature points and weights.
//
// 1. The reference element is decomposed into reference tetrahedra whose vertices are element
//    nodes (sub_tetrahedra_of): Tet4 itself; Tet10 into 8 (its four corner tetrahedra and the
//    inner octahedron split along the 6-8 diagonal); Hex8 into the 6 tetrahedra around its 0-6
//    diagonal (the Kuhn split); Wedge6 into 3 chosen from its global node ids
//    (Wedge6::conforming_sub_tetrahedra). Neighbours must split a shared face alike, or a curved
//    cut's interpolant (below) does not meet itself across it: Tet4 and Tet10 faces are split
//    alike by any numbering, a Wedge6 quadrilateral by its diagonal through its lowest global
//    id, and a Hex8 face by its diagonal through local node 0 or 6, alike in grids whose cells
//    are numbered alike (bar_mesh, cages) but not in general (a hex mesh from Gmsh, a thick
//    shell of an unstructured quad surface): a known limitation.
// 2. On each of them the level set is the linear interpolant of its vertices' nodal values, and
//    the tetrahedron is split by that plane: the thesis' case analysis by the signs of the four
//    values (+ - - -: a tetrahedron and a prism; + + - -: two prisms; with a vertex on the cut
//    (value 0): a tetrahedron and a pyramid, or two tetrahedra; all of one sign: uncut), every
//    prism into 3 tetrahedra and every pyramid into 2. A value of exactly 0 counts as +
//    (the thesis: "above the crack and on the crack line"); the zero-volume pieces this makes
//    are dropped.
// 3. Each piece gets the tetrahedron rule of the degree asked for, mapped to the element's
//    reference coordinates; the weights carry the piece's reference volume.
//
// What the cut is then: for Tet4, and for any element whose geometry map is affine (a
// parallelepiped Hex8, a straight-edged Tet10) cut by a plane, the nodal signed distances are
// linear in reference coordinates and the split is the exact plane. Otherwise (a curved cut
// surface, a distorted Hex8, a curved Tet10) the cut inside the element is the piecewise-planar
// interpolant of the nodal level set on the reference sub-tetrahedra: exact at the nodes, second
// order in the element size.
//
// Exactness: on each piece the rule integrates polynomials of its degree in reference
// coordinates exactly. The solver asks for the degrees of linear elasticity's integrands
// (the element traits' piece_*_degree): Tet4 stiffness 1 and mass 2, Tet10 and Wedge6 2 and 4,
// Hex8 4 and 6 (its mass integrand N_a N_b det J on a parallelepiped). The stiffness rule
// of each side is then compressed (compress_rule below; CutOptions::compress_quadrature) to at
// most as many points as the integrand's polynomial space has members, with the same integrals
// of them: the same stiffness on an affine element, a tenth of the points on a cut Hex8.
#include <plastifem/core/nonnegative_least_squares.hpp>
#include <plastifem/element/element.hpp>

#include <array>
#include <cmath>
#include <span>
#include <type_traits>
#include <vector>

namespace plastifem {

/// A reference sub-tetrahedron: four points in the element's reference coordinates.
using ReferenceTet = std::array<Vec3, 4>;

/// The decomposition of an element with global node ids `ids` into tetrahedra on its nodes
/// (local indices): the element's conforming_sub_tetrahedra(ids) where it has one (a split
/// chosen from global ids, matching its neighbours'), else its fixed sub_tetrahedra.
template <FiniteElement E>
auto sub_tetrahedra_of(const std::array<Index, E::num_nodes>& ids) {
  if constexpr (requires { E::conforming_sub_tetrahedra(ids); }) {
    using Fixed = std::remove_const_t<decltype(E::sub_tetrahedra)>;
    static_assert(std::is_same_v<decltype(E::conforming_sub_tetrahedra(ids)), Fixed>,
                  "conforming_sub_tetrahedra returns as many tetrahedra as sub_tetrahedra");
    return E::conforming_sub_tetrahedra(ids);
  } else {
    (void)ids;
    return E::sub_tetrahedra;
  }
}

inline Scalar tet_volume(const ReferenceTet& t) {
  return std::abs((t[1] - t[0]).cross(t[2] - t[0]).dot(t[3] - t[0])) / 6;
}

/// The pieces of one reference tetrahedron on the side phi >= 0 (`positive`) or phi < 0.
/// Appends to `out`; zero-volume pieces are left out.
inline void split_tetrahedron(const ReferenceTet& v, const std::array<Scalar, 4>& phi, std::vector<ReferenceTet>& plus,
                              std::vector<ReferenceTet>& minus) {
  std::array<int, 4> p{}, m{};  // vertices on each side (phi == 0 counts as +)
  int np = 0, nm = 0;
  for (int k = 0; k < 4; ++k) (phi[k] >= 0 ? p[np++] : m[nm++]) = k;
  const Scalar tiny = 1e-14 * tet_volume(v);
  auto push = [&](std::vector<ReferenceTet>& out, const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d) {
    const ReferenceTet t{a, b, c, d};
    if (tet_volume(t) > tiny) out.push_back(t);
  };
  // The point on edge (i, j) where the linear level set vanishes (i on one side, j on the other).
  auto cut = [&](int i, int j) {
    const Scalar t = phi[i] / (phi[i] - phi[j]);
    return Vec3(v[i] + t * (v[j] - v[i]));
  };
  // A prism with triangles (a0 a1 a2) and (b0 b1 b2), edges ak-bk: three tetrahedra.
  auto prism = [&](std::vector<ReferenceTet>& out, const Vec3& a0, const Vec3& a1, const Vec3& a2, const Vec3& b0,
                   const Vec3& b1, const Vec3& b2) {
    push(out, a0, a1, a2, b0);
    push(out, a1, a2, b0, b1);
    push(out, a2, b0, b1, b2);
  };
  if (nm == 0) return push(plus, v[0], v[1], v[2], v[3]);
  if (np == 0) return push(minus, v[0], v[1], v[2], v[3]);
  if (np == 1) {  // + - - -: a tetrahedron above, a prism below
    const int a = p[0];
    const Vec3 q0 = cut(a, m[0]), q1 = cut(a, m[1]), q2 = cut(a, m[2]);
    push(plus, v[a], q0, q1, q2);
    prism(minus, q0, q1, q2, v[m[0]], v[m[1]], v[m[2]]);
  } else if (nm == 1) {  // + + + -: a prism above, a tetrahedron below
    const int b = m[0];
    const Vec3 q0 = cut(p[0], b), q1 = cut(p[1], b), q2 = cut(p[2], b);
    push(minus, v[b], q0, q1, q2);
    prism(plus, q0, q1, q2, v[p[0]], v[p[1]], v[p[2]]);
  } else {  // + + - -: two prisms
    const int a0 = p[0], a1 = p[1], b0 = m[0], b1 = m[1];
    const Vec3 q00 = cut(a0, b0), q01 = cut(a0, b1), q10 = cut(a1, b0), q11 = cut(a1, b1);
    prism(plus, v[a0], q00, q01, v[a1], q10, q11);
    prism(minus, v[b0], q00, q10, v[b1], q01, q11);
  }
}

/// Quadrature points of a set of reference pieces: reference coordinates and weights.
struct ReferencePoints {
  std::vector<Vec3> xi;
  std::vector<Scalar> w;
  Scalar volume() const {
    Scalar s = 0;
    for (Scalar x : w) s += x;
    return s;
  }
};

/// The tetrahedron rule of `Degree` on each piece, in the element's reference coordinates.
template <int Degree>
ReferencePoints piece_quadrature(const std::vector<ReferenceTet>& pieces) {
  const auto q = TetrahedronQuadrature::quadrature<Degree>();
  ReferencePoints r;
  for (const ReferenceTet& t : pieces) {
    Mat3 A;
    A << t[1] - t[0], t[2] - t[0], t[3] - t[0];
    const Scalar det = std::abs(A.determinant());
    for (int k = 0; k < q.size; ++k) {
      r.xi.push_back(t[0] + A * q.points[k]);
      r.w.push_back(q.weights[k] * det);
    }
  }
  return r;
}

/// Exponents (a, b, c) of the polynomials x^a y^b z^c (reference coordinates) that linear
/// elasticity's stiffness integrand B^T D B det J spans on an affine element: a + b + c <=
/// E::piece_stiffness_degree and each <= E::piece_stiffness_variable_degree. Tet4: total degree
/// <= 1 (the integrand is constant; one point per piece is kept), Tet10 and Wedge6 <= 2, Hex8
/// a, b, c <= 2 with a + b + c <= 4 (dN/dxi is bilinear in the other two coordinates, so a
/// product of two has degree <= 2 in each and <= 4 in all): 4, 10 and 23 polynomials.
template <FiniteElement E>
std::vector<std::array<int, 3>> stiffness_exponents() {
  constexpr int total = E::piece_stiffness_degree, each = E::piece_stiffness_variable_degree;
  std::vector<std::array<int, 3>> e;
  for (int a = 0; a <= each; ++a)
    for (int b = 0; b <= each; ++b)
      for (int c = 0; c <= each; ++c)
        if (a + b + c <= total) e.push_back({a, b, c});
  return e;
}

/// A rule with the same integrals as `rule` of the polynomials `exponents`, with at most as
/// many points as there are polynomials, all of them points of `rule`, with non-negative
/// weights (Tchakaloff's theorem says such a rule exists among the points of any positive rule
/// exact for the space; Sommariva and Vianello, "Compression of multivariate discrete measures
/// and applications", 2015, find it by non-negative least squares on the moment equations
/// V w = m, V the polynomials at the points, m = V w_rule the moments). The polynomials are
/// Legendre products on the points' bounding box: they span the same space as the monomials (it is
/// invariant under scaling and shifting each coordinate) and keep V well conditioned on a small
/// side. Returns an empty rule if no subset carries the moments to 1e-13 of the side's volume.
inline ReferencePoints compress_rule(const ReferencePoints& rule, const std::vector<std::array<int, 3>>& exponents) {
  const Index m = static_cast<Index>(exponents.size()), n = static_cast<Index>(rule.xi.size());
  Vec3 lo = rule.xi[0], hi = rule.xi[0];
  for (const Vec3& p : rule.xi) lo = lo.cwiseMin(p), hi = hi.cwiseMax(p);
  const Vec3 centre = (lo + hi) / 2, half = ((hi - lo) / 2).cwiseMax(1e-300);
  auto basis = [&](const Vec3& x, auto&& column) {
    const Vec3 t = (x - centre).cwiseQuotient(half);
    Scalar L[3][3];  // Legendre P0, P1, P2 of each coordinate
    for (int d = 0; d < 3; ++d) L[d][0] = 1, L[d][1] = t[d], L[d][2] = (3 * t[d] * t[d] - 1) / 2;
    for (Index i = 0; i < m; ++i) column[i] = L[0][exponents[i][0]] * L[1][exponents[i][1]] * L[2][exponents[i][2]];
  };
  Eigen::MatrixXd V(m, n);
  for (Index k = 0; k < n; ++k) basis(rule.xi[k], V.col(k));
  const Eigen::VectorXd moments = V * Eigen::Map<const Eigen::VectorXd>(rule.w.data(), n);
  const Scalar volume = moments[0];  // exponents[0] is (0, 0, 0)
  const Eigen::VectorXd w = nonnegative_least_squares(V, moments, 1e-15 * volume);
  ReferencePoints c;
  if ((V * w - moments).lpNorm<Eigen::Infinity>() > 1e-13 * volume) return c;
  for (Index k = 0; k < n; ++k)
    if (w[k] > 0) c.xi.push_back(rule.xi[k]), c.w.push_back(w[k]);
  return c;
}

/// The two sides of an element cut by a level set with nodal values phi: its reference pieces
/// on each side (phi >= 0: side 0, "above"; phi < 0: side 1, "below"), split on its tetrahedra
/// `tets` (local nodes: sub_tetrahedra_of(the element's node ids)).
template <FiniteElement E>
std::array<std::vector<ReferenceTet>, 2> split_element(const std::array<Scalar, E::num_nodes>& phi,
                                                       std::span<const std::array<int, 4>> tets) {
  std::array<std::vector<ReferenceTet>, 2> sides;
  const auto Xref = E::reference_nodes();
  for (const auto& t : tets) {
    const ReferenceTet v{Vec3(Xref.col(t[0])), Vec3(Xref.col(t[1])), Vec3(Xref.col(t[2])), Vec3(Xref.col(t[3]))};
    split_tetrahedron(v, {phi[t[0]], phi[t[1]], phi[t[2]], phi[t[3]]}, sides[0], sides[1]);
  }
  return sides;
}

}  // namespace plastifem
