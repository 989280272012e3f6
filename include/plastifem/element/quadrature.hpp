#pragma once
// Quadrature rules on the reference elements.
//
// Reference domains: the tetrahedron {x, y, z >= 0, x + y + z <= 1} (volume 1/6) and the
// cube [-1, 1]^3 (volume 8). A rule of `degree` d integrates exactly
//   - on the tetrahedron: every polynomial of total degree <= d;
//   - on the cube: every x^a y^b z^c with max(a, b, c) <= d (tensor Gauss-Legendre).
// tests/test_quadrature.cpp checks both claims and that each rule fails one degree above.
#include <plastifem/core/types.hpp>

#include <array>
#include <cmath>

namespace plastifem {

/// N points with positive weights on a reference element.
template <int N>
struct Quadrature {
  static constexpr int size = N;
  std::array<Vec3, N> points;
  std::array<Scalar, N> weights;
  int degree;  ///< polynomial degree integrated exactly (see file comment for its meaning)
};

namespace detail {

/// n-point Gauss-Legendre abscissae and weights on [-1, 1], exact to degree 2n - 1.
template <int n>
constexpr std::array<std::array<Scalar, 2>, n> gauss_legendre_1d() {
  static_assert(n >= 1 && n <= 3, "Gauss-Legendre rules are tabulated for 1..3 points");
  if constexpr (n == 1) {
    return {{{0.0, 2.0}}};
  } else if constexpr (n == 2) {
    constexpr Scalar a = 0.57735026918962576451;  // 1/sqrt(3)
    return {{{-a, 1.0}, {a, 1.0}}};
  } else {
    constexpr Scalar a = 0.77459666924148337704;  // sqrt(3/5)
    return {{{-a, 5.0 / 9.0}, {0.0, 8.0 / 9.0}, {a, 5.0 / 9.0}}};
  }
}

}  // namespace detail

/// Tensor-product Gauss-Legendre rule with n points per direction on [-1, 1]^3.
template <int n>
Quadrature<n * n * n> hex_gauss() {
  const auto g = detail::gauss_legendre_1d<n>();
  Quadrature<n * n * n> q{};
  int k = 0;
  for (int c = 0; c < n; ++c)
    for (int b = 0; b < n; ++b)
      for (int a = 0; a < n; ++a, ++k) {
        q.points[k] = Vec3(g[a][0], g[b][0], g[c][0]);
        q.weights[k] = g[a][1] * g[b][1] * g[c][1];
      }
  q.degree = 2 * n - 1;
  return q;
}

namespace detail {
/// Appends the four points with barycentric coordinates (a, a, a, 1 - 3a) and their
/// permutations, each of weight w, at q's entry k onwards.
template <int N>
void add_vertex_orbit(Quadrature<N>& q, int& k, Scalar a, Scalar w) {
  const Scalar b = 1.0 - 3.0 * a;
  for (const Vec3& p : {Vec3(a, a, a), Vec3(b, a, a), Vec3(a, b, a), Vec3(a, a, b)}) q.points[k] = p, q.weights[k++] = w;
}
}  // namespace detail

/// Midpoint rule on the reference tetrahedron: degree 1.
inline Quadrature<1> tet_rule_1() {
  return {{Vec3(0.25, 0.25, 0.25)}, {1.0 / 6.0}, 1};
}

/// Symmetric 4-point rule (Hammer, Marlowe and Stroud 1956): degree 2.
inline Quadrature<4> tet_rule_4() {
  const Scalar a = 0.13819660112501051518;  // (5 - sqrt 5) / 20
  const Scalar b = 1.0 - 3.0 * a;
  const Scalar w = 1.0 / 24.0;
  return {{Vec3(a, a, a), Vec3(b, a, a), Vec3(a, b, a), Vec3(a, a, b)}, {w, w, w, w}, 2};
}

/// 14-point rule with positive weights (Walkington 2000; Gellert and Harbord 1991,
/// Table VI): degree 5. Exact for the Tet10 consistent mass (degree 4).
inline Quadrature<14> tet_rule_14() {
  Quadrature<14> q{};
  int k = 0;
  // Class 1 and 2: barycentric (a, a, a, 1 - 3a), four permutations each.
  detail::add_vertex_orbit(q, k, 0.31088591926330060980, 0.018781320953002641800);
  detail::add_vertex_orbit(q, k, 0.092735250310891226402, 0.012248840519393658257);
  // Class 3: barycentric (a, a, b, b) with b = 1/2 - a, six permutations.
  const Scalar a = 0.045503704125649649492, b = 0.5 - a;
  const Scalar w = (1.0 / 6.0 - 4.0 * (0.018781320953002641800 + 0.012248840519393658257)) / 6.0;
  const Vec3 pts[6] = {Vec3(a, a, b), Vec3(a, b, a), Vec3(b, a, a),
                       Vec3(a, b, b), Vec3(b, a, b), Vec3(b, b, a)};
  for (const auto& p : pts) {
    q.points[k] = p;
    q.weights[k++] = w;
  }
  q.degree = 5;
  return q;
}

/// 24-point rule with positive weights (Keast 1986, degree 6): three orbits (a, a, a, 1 - 3a)
/// and one (a, a, b, 1 - 2a - b) of twelve points. Exact for the Hex8 mass on a tetrahedral
/// piece of a parallelepiped (degree 6). The constants are Keast's, refined by Newton on the
/// moment equations of every monomial of degree <= 6 to 40 digits (all met to 1e-41).
inline Quadrature<24> tet_rule_24() {
  Quadrature<24> q{};
  int k = 0;
  // Keast's weights sum to 1: divided by 6, the reference volume.
  detail::add_vertex_orbit(q, k, 0.2146028712591520292888392, 0.03992275025816749209969063 / 6);
  detail::add_vertex_orbit(q, k, 0.04067395853461135311557945, 0.01007721105532064294801324 / 6);
  detail::add_vertex_orbit(q, k, 0.3223378901422755103439945, 0.05535718154365472209515328 / 6);
  // Barycentric (a, a, b, c), c = 1 - 2a - b: its twelve distinct permutations, weight 27/560.
  const Scalar a = 0.06366100187501752529923553, b = 0.2696723314583158080340978, c = 1 - 2 * a - b;
  const Scalar l[4] = {a, a, b, c};
  const int perms[12][4] = {{0, 1, 2, 3}, {0, 1, 3, 2}, {0, 2, 1, 3}, {0, 2, 3, 1}, {0, 3, 1, 2}, {0, 3, 2, 1},
                            {2, 0, 1, 3}, {2, 0, 3, 1}, {3, 0, 1, 2}, {3, 0, 2, 1}, {2, 3, 0, 1}, {3, 2, 0, 1}};
  for (const auto& p : perms) q.points[k] = Vec3(l[p[1]], l[p[2]], l[p[3]]), q.weights[k++] = 27.0 / 560 / 6;
  q.degree = 6;
  return q;
}

/// Quadrature selection shared by the tetrahedra: the smallest tabulated rule exact for total
/// degree `Degree`.
struct TetrahedronQuadrature {
  template <int Degree>
  static auto quadrature() {
    static_assert(Degree >= 0 && Degree <= 6, "tetrahedron rules are tabulated up to degree 6");
    if constexpr (Degree <= 1) return tet_rule_1();
    else if constexpr (Degree == 2) return tet_rule_4();
    else if constexpr (Degree <= 5) return tet_rule_14();
    else return tet_rule_24();
  }
};

}  // namespace plastifem
