// Element traits checked against independent facts: partition of unity, Kronecker property,
// finite-difference gradients, exact monomial integration (and failure one degree above),
// closed-form volumes, Jacobian sign.
#include "catch.hpp"
#include "compositions.hpp"

#include <plastifem/plastifem.hpp>

#include <algorithm>
#include <cmath>
#include <random>
#include <utility>

using namespace plastifem;
using namespace plastifem::testing;

namespace {

// A point inside the reference element, drawn uniformly enough for these checks.
template <FiniteElement E>
Vec3 random_reference_point(std::mt19937& rng) {
  std::uniform_real_distribution<Scalar> u(0.0, 1.0);
  if constexpr (std::is_same_v<E, Hex8>) {
    return Vec3(2 * u(rng) - 1, 2 * u(rng) - 1, 2 * u(rng) - 1);
  } else if constexpr (std::is_same_v<E, Wedge6>) {
    Vec3 p(u(rng), u(rng), 2 * u(rng) - 1);
    while (p.x() + p.y() > 1) p.head<2>() = Vec3(u(rng), u(rng), 0).head<2>();
    return p;
  } else {
    Vec3 p(u(rng), u(rng), u(rng));
    while (p.sum() > 1) p = Vec3(u(rng), u(rng), u(rng));
    return p;
  }
}

// Exact integrals of x^a y^b z^c: tet a! b! c! / (a + b + c + 3)!, cube prod of 2/(k+1) for even k.
Scalar factorial(int n) { return n <= 1 ? 1.0 : n * factorial(n - 1); }
Scalar tet_monomial(int a, int b, int c) { return factorial(a) * factorial(b) * factorial(c) / factorial(a + b + c + 3); }
Scalar cube_monomial_1d(int k) { return k % 2 ? 0.0 : 2.0 / (k + 1); }
Scalar cube_monomial(int a, int b, int c) { return cube_monomial_1d(a) * cube_monomial_1d(b) * cube_monomial_1d(c); }

template <class Q>
Scalar integrate_monomial(const Q& q, int a, int b, int c) {
  Scalar s = 0;
  for (int k = 0; k < q.size; ++k)
    s += q.weights[k] * std::pow(q.points[k].x(), a) * std::pow(q.points[k].y(), b) * std::pow(q.points[k].z(), c);
  return s;
}

// Checks total-degree exactness for tets: all monomials of degree <= d exact to 1e-14 (the
// tabulated abscissae carry ~18-20 digits), and at least one monomial of degree d+1 off by > 1e-6.
template <class Q>
void check_tet_rule(const Q& q) {
  INFO("tet rule with " << q.size << " points, degree " << q.degree);
  for (int a = 0; a <= q.degree; ++a)
    for (int b = 0; a + b <= q.degree; ++b)
      for (int c = 0; a + b + c <= q.degree; ++c)
        REQUIRE(integrate_monomial(q, a, b, c) == Approx(tet_monomial(a, b, c)).epsilon(1e-13).margin(1e-15));
  Scalar worst = 0;
  const int d = q.degree + 1;
  for (int a = 0; a <= d; ++a)
    for (int b = 0; a + b <= d; ++b) {
      const int c = d - a - b;
      worst = std::max(worst, std::abs(integrate_monomial(q, a, b, c) / tet_monomial(a, b, c) - 1));
    }
  REQUIRE(worst > 1e-6);
}

template <class Q>
void check_hex_rule(const Q& q) {
  INFO("hex rule with " << q.size << " points, degree " << q.degree);
  for (int a = 0; a <= q.degree; ++a)
    for (int b = 0; b <= q.degree; ++b)
      for (int c = 0; c <= q.degree; ++c)
        REQUIRE(integrate_monomial(q, a, b, c) == Approx(cube_monomial(a, b, c)).epsilon(1e-14).margin(1e-15));
  const int d = q.degree + 1;  // even: its exact integral is non-zero
  REQUIRE(std::abs(integrate_monomial(q, d, 0, 0) / cube_monomial(d, 0, 0) - 1) > 1e-6);
  REQUIRE(std::abs(integrate_monomial(q, 0, d, 0) / cube_monomial(0, d, 0) - 1) > 1e-6);
  REQUIRE(std::abs(integrate_monomial(q, 0, 0, d) / cube_monomial(0, 0, d) - 1) > 1e-6);
}

// Prism {x, y >= 0, x + y <= 1} x [-1, 1]: x^a y^b z^c integrates to a! b! / (a + b + 2)! times
// the segment's integral of z^c. A rule of degree d is exact for a + b <= d and c <= d, and off
// by > 1e-6 for some monomial of degree d + 1 in (x, y) or in z.
Scalar prism_monomial(int a, int b, int c) {
  return factorial(a) * factorial(b) / factorial(a + b + 2) * cube_monomial_1d(c);
}
template <class Q>
void check_prism_rule(const Q& q) {
  INFO("prism rule with " << q.size << " points, degree " << q.degree);
  for (int a = 0; a <= q.degree; ++a)
    for (int b = 0; a + b <= q.degree; ++b)
      for (int c = 0; c <= q.degree; ++c)
        REQUIRE(integrate_monomial(q, a, b, c) == Approx(prism_monomial(a, b, c)).epsilon(1e-14).margin(1e-15));
  const int d = q.degree + 1;
  Scalar worst = 0;
  for (int a = 0; a <= d; ++a) worst = std::max(worst, std::abs(integrate_monomial(q, a, d - a, 0) / prism_monomial(a, d - a, 0) - 1));
  if (d % 2 == 0) worst = std::max(worst, std::abs(integrate_monomial(q, 0, 0, d) / prism_monomial(0, 0, d) - 1));
  REQUIRE(worst > 1e-6);
}

}  // namespace

TEST_CASE("prism rules are exact to their degree and not above", "[quadrature]") {
  check_prism_rule(prism_rule<1>());
  check_prism_rule(prism_rule<2>());
  check_prism_rule(prism_rule<3>());
  check_prism_rule(prism_rule<4>());
}

TEST_CASE("tetrahedron rules are exact to their degree and not above", "[quadrature]") {
  check_tet_rule(tet_rule_1());
  check_tet_rule(tet_rule_4());
  check_tet_rule(tet_rule_14());
  check_tet_rule(tet_rule_24());
}

TEST_CASE("hexahedron Gauss rules are exact to their degree and not above", "[quadrature]") {
  check_hex_rule(hex_gauss<1>());
  check_hex_rule(hex_gauss<2>());
  check_hex_rule(hex_gauss<3>());
}

TEST_CASE("the face pieces' triangle rule is exact to degree 4 and not above", "[quadrature]") {
  // On the unit triangle {s, t >= 0, s + t <= 1}, s^a t^b integrates to a! b! / (a + b + 2)!.
  // The rule is called on a triangle of the reference element, p0 + s e1 + t e2: checked on the
  // unit triangle's own map, and its weights on the mapped area |e1 x e2| / 2.
  auto integrate = [](int a, int b) {
    Scalar sum = 0;
    for_each_triangle_point(Vec3::Zero(), Vec3::UnitX(), Vec3::UnitY(), [&](const Vec3& x, const Vec3&, const Vec3&, Scalar w) {
      sum += w * std::pow(x.x(), a) * std::pow(x.y(), b);
    });
    return sum;
  };
  auto exact = [](int a, int b) { return factorial(a) * factorial(b) / factorial(a + b + 2); };
  for (int a = 0; a <= 4; ++a)
    for (int b = 0; a + b <= 4; ++b) REQUIRE(integrate(a, b) == Approx(exact(a, b)).epsilon(1e-14));
  Scalar worst = 0;
  for (int a = 0; a <= 5; ++a) worst = std::max(worst, std::abs(integrate(a, 5 - a) / exact(a, 5 - a) - 1));
  REQUIRE(worst > 1e-6);
}

TEMPLATE_LIST_TEST_CASE("shape functions: partition of unity, Kronecker property, FD gradients",
                        "[element]", AllElements) {
  using E = TestType;
  const auto Xref = E::reference_nodes();
  SECTION("Kronecker property at the nodes") {
    for (int a = 0; a < E::num_nodes; ++a) {
      const auto N = E::shape(Xref.col(a));
      for (int b = 0; b < E::num_nodes; ++b) REQUIRE(N[b] == Approx(a == b ? 1.0 : 0.0).margin(1e-15));
    }
  }
  std::mt19937 rng(42);
  SECTION("partition of unity, linear completeness, gradient sums") {
    for (int trial = 0; trial < 50; ++trial) {
      const Vec3 p = random_reference_point<E>(rng);
      const auto N = E::shape(p);
      const auto G = E::gradient(p);
      REQUIRE(N.sum() == Approx(1.0).epsilon(1e-14));
      // sum_a N_a X_a = p (isoparametric: reproduces the reference coordinates).
      REQUIRE(((Xref * N) - p).norm() < 1e-14);
      REQUIRE(G.colwise().sum().norm() < 1e-14);
      REQUIRE((Xref * G - Mat3::Identity()).norm() < 1e-14);
    }
  }
  SECTION("reference gradients match central finite differences") {
    // Shape functions are polynomials of degree <= 3: the central difference error is
    // h^2/6 f''' ~ 1e-10 for h = 1e-5, above round-off (1e-16 / 1e-5 = 1e-11).
    const Scalar h = 1e-5;
    for (int trial = 0; trial < 20; ++trial) {
      const Vec3 p = random_reference_point<E>(rng);
      const auto G = E::gradient(p);
      for (int d = 0; d < 3; ++d) {
        const Vec3 e = Vec3::Unit(d) * h;
        const auto fd = ((E::shape(p + e) - E::shape(p - e)) / (2 * h)).eval();
        REQUIRE((fd - G.col(d)).norm() < 1e-9);
      }
    }
  }
  SECTION("faces and edges refer to valid local nodes and faces point outwards") {
    const Vec3 centroid = Xref.rowwise().mean();
    for (int face = 0; face < E::num_faces; ++face) {
      const auto& f = E::faces[static_cast<size_t>(face)];
      for (int k = 0; k < face_node_count(E::face_shape(face)); ++k)
        REQUIRE((f[static_cast<size_t>(k)] >= 0 && f[static_cast<size_t>(k)] < E::num_nodes));
      const Vec3 n = (Xref.col(f[1]) - Xref.col(f[0])).cross(Xref.col(f[2]) - Xref.col(f[0]));
      REQUIRE(n.dot(Xref.col(f[0]) - centroid) > 0);
    }
    for (const auto& ed : E::edges) REQUIRE(ed[0] != ed[1]);
  }
}

TEST_CASE("Tet10 mid-edge nodes sit at the middle of their edges", "[element]") {
  const auto X = Tet10::reference_nodes();
  for (int k = 0; k < 6; ++k)
    REQUIRE((X.col(4 + k) - 0.5 * (X.col(Tet10::edges[k][0]) + X.col(Tet10::edges[k][1]))).norm() == 0);
  // Faces list their mid-edge nodes between the corners they join.
  for (const auto& f : Tet10::faces)
    for (int k = 0; k < 3; ++k)
      REQUIRE((X.col(f[3 + k]) - 0.5 * (X.col(f[k]) + X.col(f[(k + 1) % 3]))).norm() == 0);
}

TEMPLATE_LIST_TEST_CASE("element volumes match closed form", "[element]", AllElements) {
  using E = TestType;
  // Affine map x = A xi + b with det A = 2.7: volume = |det A| * reference volume.
  Mat3 A;
  A << 1.2, 0.3, -0.1,
       0.1, 1.5, 0.2,
       0.0, -0.2, 1.4;
  const Vec3 b(0.3, -1.0, 2.0);
  const ElementNodes<E> Xa = (A * E::reference_nodes()).colwise() + b;
  REQUIRE(element_volume<E>(Xa) == Approx(A.determinant() * E::reference_volume).epsilon(1e-14));
  REQUIRE(jacobian<E>(Xa, Vec3(0.1, 0.2, 0.3)).isApprox(A, 1e-14));
  // Physical gradients of x_d are unit vectors: X^T dN/dx = I.
  REQUIRE((Xa * physical_gradient<E>(Xa, Vec3(0.2, 0.1, 0.3)) - Mat3::Identity()).norm() < 1e-13);
}

TEST_CASE("volumes of non-affinely distorted elements match closed form", "[element]") {
  SECTION("Hex8: a frustum-like hexahedron") {
    // Unit square bottom at z=0, top square of side s at z=1 (both centred): the exact volume
    // of this frustum of a square pyramid is (1 + s + s^2) / 3; trilinear interpolation spans
    // exactly the same ruled surfaces (planar faces).
    const Scalar s = 0.4;
    ElementNodes<Hex8> X;
    X << -0.5, 0.5, 0.5, -0.5, -s / 2, s / 2, s / 2, -s / 2,
         -0.5, -0.5, 0.5, 0.5, -s / 2, -s / 2, s / 2, s / 2,
          0, 0, 0, 0, 1, 1, 1, 1;
    REQUIRE(element_volume<Hex8>(X) == Approx((1 + s + s * s) / 3).epsilon(1e-14));
  }
  SECTION("Hex8: a twisted hexahedron (hyperbolic-paraboloid top face)") {
    // Unit cube with node 6 raised to (1, 1, 1 + t). Trilinear interpolation gives
    // z = w (1 + t x y) for (x, y, w) in [0, 1]^3, so det J = 1 + t x y and V = 1 + t/4.
    const Scalar t = 0.5;
    ElementNodes<Hex8> X;
    X << 0, 1, 1, 0, 0, 1, 1, 0,
         0, 0, 1, 1, 0, 0, 1, 1,
         0, 0, 0, 0, 1, 1, 1 + t, 1;
    REQUIRE(element_volume<Hex8>(X) == Approx(1 + t / 4).epsilon(1e-14));
  }
  SECTION("Wedge6: a prism with one top corner raised") {
    // Unit right prism over the triangle (0,0), (0,1), (1,0) with node 5 raised to (1, 0, 1 + t):
    // the prism's map gives z = w (1 + t x) for w in [0, 1], so V = int_T (1 + t x) dA = 1/2 + t/6.
    const Scalar t = 0.6;
    ElementNodes<Wedge6> X;
    X << 0, 0, 1, 0, 0, 1,
         0, 1, 0, 0, 1, 0,
         0, 0, 0, 1, 1, 1 + t;
    REQUIRE(element_volume<Wedge6>(X) == Approx(0.5 + t / 6).epsilon(1e-14));
  }
  SECTION("Tet10: a curved edge") {
    // Mid-node 4 of edge (0,1) pulled outwards by d along -y: x(xi) = xi + N_4(xi) (0, -d, 0)
    // with N_4 = 4 L0 L1 = 4 (1 - x - y - z) x, so det J = 1 - d dN_4/dy = 1 + 4 d x and
    // V = 1/6 + 4 d int x = 1/6 + 4 d / 24 = (1 + d) / 6.
    const Scalar d = 0.1;
    ElementNodes<Tet10> X = Tet10::reference_nodes();
    X(1, 4) -= d;
    REQUIRE(element_volume<Tet10>(X) == Approx((1 + d) / 6).epsilon(1e-14));
  }
}

// The concept checks the node lists, not only that they exist: a face naming a node the element
// does not have, or a sub-tetrahedron off the element, is refused.
struct FaceOffTheElement : Tet4 {
  static constexpr std::array<std::array<int, 3>, 4> faces{{{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 4}}};
};
struct SubTetOffTheElement : Hex8 {
  static constexpr std::array<std::array<int, 4>, 1> sub_tetrahedra{{{0, 1, 2, 8}}};
};
static_assert(FiniteElement<Tet4> && !FiniteElement<FaceOffTheElement> && !FiniteElement<SubTetOffTheElement>);

TEMPLATE_LIST_TEST_CASE("element traits: containment, faces, sub-tetrahedra and volume degree",
                        "[element]", AllElements) {
  using E = TestType;
  const auto Xref = E::reference_nodes();
  const Vec3 centre = reference_centre<E>();
  SECTION("contains: every node and random inner points in; nodes pushed outward out") {
    std::mt19937 rng(7);
    REQUIRE(E::contains(centre, 0.0));
    for (int a = 0; a < E::num_nodes; ++a) {
      REQUIRE(E::contains(Xref.col(a), 1e-14));
      // 1% beyond a corner is outside; the reference elements are convex, so corners are extreme.
      if (a < E::num_vertices) REQUIRE_FALSE(E::contains(Vec3(Xref.col(a) + 0.01 * (Xref.col(a) - centre)), 1e-10));
    }
    for (int k = 0; k < 100; ++k) REQUIRE(E::contains(random_reference_point<E>(rng), 1e-12));
  }
  SECTION("faces: node lists by kind, corners first, closed and outward (divergence theorem)") {
    // On the closed reference boundary, the integral of n dA vanishes and (1/3) of x . n dA is
    // the volume; both integrands are exact for the face rules on the flat reference faces.
    Vec3 n_total = Vec3::Zero();
    Scalar volume = 0;
    for (int f = 0; f < E::num_faces; ++f) {
      const FaceShape kind = E::face_shape(f);
      for (int k = 0; k < face_node_count(kind); ++k) {
        const int node = E::faces[static_cast<size_t>(f)][static_cast<size_t>(k)];
        REQUIRE((k < face_corners(kind)) == (node < E::num_vertices));
      }
      for_each_face_point<E>(f, [&](const Vec3& xi, const Vec3& ds, const Vec3& dt, Scalar w) {
        const Vec3 n_dA = w * ds.cross(dt);
        n_total += n_dA;
        volume += xi.dot(n_dA) / 3;
      });
    }
    REQUIRE(n_total.norm() < 1e-14);
    REQUIRE(volume == Approx(E::reference_volume).epsilon(1e-14));
  }
  SECTION("sub-tetrahedra partition the reference element") {
    // Non-degenerate, their volumes add up to the element's, and every random point of the
    // element lies in exactly one of them (barycentric coordinates; a random point falls on an
    // inner face with probability 0).
    Scalar v = 0;
    for (const auto& t : E::sub_tetrahedra) {
      const Scalar vt = (Xref.col(t[1]) - Xref.col(t[0])).cross(Xref.col(t[2]) - Xref.col(t[0])).dot(Xref.col(t[3]) - Xref.col(t[0])) / 6;
      REQUIRE(std::abs(vt) > 1e-3 * E::reference_volume);
      v += std::abs(vt);
    }
    REQUIRE(v == Approx(E::reference_volume).epsilon(1e-14));
    std::mt19937 rng(5);
    for (int k = 0; k < 200; ++k) {
      const Vec3 p = random_reference_point<E>(rng);
      int inside = 0;
      for (const auto& t : E::sub_tetrahedra) {
        Mat3 A;
        A << Xref.col(t[1]) - Xref.col(t[0]), Xref.col(t[2]) - Xref.col(t[0]), Xref.col(t[3]) - Xref.col(t[0]);
        const Vec3 b = A.inverse() * (p - Xref.col(t[0]));
        if ((b.array() >= -1e-12).all() && b.sum() <= 1 + 1e-12) ++inside;
      }
      REQUIRE(inside == 1);
    }
  }
  SECTION("volume_degree integrates det J of a distorted element exactly, one degree less does not") {
    std::mt19937 rng(11);
    std::uniform_real_distribution<Scalar> u(-0.1, 0.1);
    ElementNodes<E> X = Xref;
    for (int a = 0; a < E::num_nodes; ++a) X.col(a) += Vec3(u(rng), u(rng), u(rng));
    auto volume_by = [&](auto rule) {
      Scalar v = 0;
      for (int k = 0; k < rule.size; ++k) v += rule.weights[k] * jacobian<E>(X, rule.points[k]).determinant();
      return v;
    };
    const Scalar exact = volume_by(E::template quadrature<E::mass_degree>());  // exact for N_a N_b det J, so for det J
    REQUIRE(volume_by(E::template quadrature<E::volume_degree>()) == Approx(exact).epsilon(1e-13));
    if constexpr (E::volume_degree > 0) {
      // The distortion's O(0.1^2) terms: above 1e-6 of the volume for these seeds.
      REQUIRE(std::abs(volume_by(E::template quadrature<E::volume_degree - 1>()) - exact) > 1e-6 * exact);
    }
  }
}

TEMPLATE_LIST_TEST_CASE("Jacobian sign detects inverted elements", "[element]", AllElements) {
  using E = TestType;
  ElementNodes<E> X = E::reference_nodes();
  REQUIRE(jacobian<E>(X, Vec3(0.2, 0.2, 0.2)).determinant() > 0);
  X.row(2) *= -1;  // mirror: every det J flips sign
  REQUIRE(jacobian<E>(X, Vec3(0.2, 0.2, 0.2)).determinant() < 0);
  REQUIRE(element_volume<E>(X) == Approx(-E::reference_volume));
}

namespace {

/// physical_gradient_at against the Eigen expression it replaced, `dN * (X * dN).inverse()`, on
/// random elements (scaled from 0.05 to 20, moved up to 30 from the origin, distorted by up to
/// 20% of their size) at random points: returns how many of `n` differ in any bit, and the
/// largest difference relative to the gradient's size.
template <FiniteElement E>
std::pair<int, Scalar> gradients_against_eigen(int n) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<Scalar> u(-1, 1);
  int differ = 0;
  Scalar worst = 0;
  for (int t = 0; t < n; ++t) {
    const Scalar size = std::exp(3 * u(rng));
    ElementNodes<E> X = E::reference_nodes() * size;
    for (int a = 0; a < E::num_nodes; ++a) X.col(a) += 0.2 * size * Vec3(u(rng), u(rng), u(rng)) + Vec3::Constant(30 * u(rng));
    const Vec3 xi = 0.25 * Vec3::Ones() + 0.2 * Vec3(u(rng), u(rng), u(rng));
    const auto dN = E::gradient(xi);
    const Eigen::Matrix<Scalar, E::num_nodes, 3> expected = dN * (X * dN).inverse();
    const Eigen::Matrix<Scalar, E::num_nodes, 3> G = physical_gradient_at<E>(X, dN);
    if ((G.array() != expected.array()).any()) {
      ++differ;
      worst = std::max(worst, (G - expected).cwiseAbs().maxCoeff() / expected.cwiseAbs().maxCoeff());
    }
  }
  return {differ, worst};
}

}  // namespace

TEST_CASE("shape gradients: the loops keep the round-off of Eigen's product-of-inverse", "[element]") {
  // physical_gradient_at sums in the order Eigen's expression did (element/element.hpp), so that
  // element data, and the Newton paths of chaotic extremes cases, stay bit for bit those of
  // earlier versions in the default x86-64 build (SSE2 packets of two doubles). With AVX, Eigen
  // takes other paths (packets of four, FMA): there the two agree to round-off only, 1e-15 times
  // the condition number of J, which these elements' offsets from the origin raise to ~1e3.
  for (const auto& [name, r] : {std::pair{"Tet4", gradients_against_eigen<Tet4>(50000)},
                                std::pair{"Tet10", gradients_against_eigen<Tet10>(50000)},
                                std::pair{"Hex8", gradients_against_eigen<Hex8>(50000)}}) {
    INFO(name << ": " << r.first << " of 50000 differ, by up to " << r.second << " relative");
#if defined(__AVX__) || defined(__FMA__)
    CHECK(r.second < 1e-11);
#else
    CHECK(r.first == 0);
#endif
  }
}
