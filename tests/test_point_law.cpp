// The point-wise constitutive interface (elastic/point_law.hpp) against independent facts:
//  - kinematics: F at the centre, the vertices and the Gauss points of an element moved by an
//    affine map x = A X + b is A, exactly (every element reproduces linear fields);
//  - each model's point law: P is the derivative of psi and A the derivative of P (central
//    differences), for the exact and the projected tangents;
//  - each model's integral over a PointSet equals its fused element kernel over the Gauss rule
//    (force, energy, both tangents) to round-off: the fused kernels are an optimisation of the
//    same formula, and X-FEM's sub-element integration rests on the point-set path.
#include "catch.hpp"
#include "compositions.hpp"

#include <plastifem/elastic/elastic.hpp>
#include <plastifem/mesh/generators.hpp>

#include <random>

using namespace plastifem;
using namespace plastifem::testing;

namespace {

const Material tissue{3000, 0.45, 1.0};

/// A deformed configuration of element 0 of a small bar: 8% random nodal noise on a stretch,
/// then a 50 degree rotation.
template <FiniteElement E>
std::pair<ElementNodes<E>, ElementNodes<E>> deformed_element(unsigned seed) {
  const Mesh<E> mesh = bar_mesh<E>(2, 1, 1);
  const ElementNodes<E> X = mesh.element_nodes(0);
  std::mt19937 rng(seed);
  std::normal_distribution<Scalar> n(0.0, 0.04);
  const Mat3 Q = Eigen::AngleAxisd(0.87, Vec3(1, 2, -1).normalized()).toRotationMatrix();
  ElementNodes<E> x = X;
  for (int a = 0; a < E::num_nodes; ++a)
    x.col(a) = Q * (Vec3(1.05, 0.97, 1.0).asDiagonal() * X.col(a) + Vec3(n(rng), n(rng), n(rng))) + Vec3(3, -1, 2);
  return {X, x};
}

template <class M, FiniteElement E>
void check_point_set_equals_fused(unsigned seed) {
  const auto [X, x] = deformed_element<E>(seed);
  const auto data = M::template prepare<E>(X, tissue);
  const typename M::Law law(tissue);
  const PointSet<E> ps = gauss_point_set<E>(X);
  std::vector<TangentKind> kinds{TangentKind::Projected};
  if constexpr (has_exact_tangent_v<M>) kinds.push_back(TangentKind::Exact);
  for (TangentKind kind : kinds) {
    ElementVector<E> f0, f1;
    ElementMatrix<E> K0, K1;
    Scalar W0;
    if constexpr (has_exact_tangent_v<M>) W0 = M::template evaluate<E>(data, x, f0, &K0, kind);
    else W0 = M::template evaluate<E>(data, x, f0, &K0);
    const Scalar W1 = M::template evaluate_points<E>(law, ps, x, f1, &K1, kind);
    INFO(M::name << " on " << E::name << (kind == TangentKind::Exact ? ", exact tangent" : ", projected tangent"));
    // Same formula, different summation order and (for Corotational) a scalar instead of a
    // batched polar iteration: ~1e-14 relative; 1e-11 bounds it with room.
    CHECK(std::abs(W1 - W0) <= 1e-11 * std::abs(W0));
    CHECK((f1 - f0).norm() <= 1e-11 * f0.norm());
    CHECK((K1 - K0).norm() <= 1e-11 * K0.norm());
  }
}

/// Central differences of psi and P at F, against P and A.
template <class Law>
void check_law_derivatives(const Law& law, const Mat3& F, TangentKind kind, Scalar tol) {
  Mat3 P;
  Matrix9 A;
  law.evaluate(F, P, &A, kind);
  const Scalar h = 1e-6;
  Matrix9 Afd;
  Mat3 Pfd;
  for (int k = 0; k < 9; ++k) {
    Mat3 Fp = F, Fm = F, Pp, Pm;
    Fp.data()[k] += h;
    Fm.data()[k] -= h;
    const Scalar wp = law.evaluate(Fp, Pp, nullptr), wm = law.evaluate(Fm, Pm, nullptr);
    Pfd.data()[k] = (wp - wm) / (2 * h);
    Afd.col(k) = Eigen::Map<const Eigen::Matrix<Scalar, 9, 1>>(Mat3((Pp - Pm) / (2 * h)).data());
  }
  // Central differences: truncation ~h^2 |psi'''| ~ 1e-12 relative, round-off ~eps |psi| / h
  // ~ 1e-10 relative: tol (1e-6 for P, 1e-5 for A) is far above both and far below an error
  // in a formula (O(1)).
  CHECK((P - Pfd).norm() <= 1e-6 * P.norm());
  if (kind == TangentKind::Exact) CHECK((A - Afd).norm() <= tol * A.norm());
}

}  // namespace

TEMPLATE_LIST_TEST_CASE("F at the centre, vertices and Gauss points of an affinely moved element is exact",
                        "[point][kinematics]", AllElements) {
  using E = TestType;
  const ElementNodes<E> X = deformed_element<E>(1).first;
  Mat3 A;
  A << 1.1, 0.2, -0.1, 0.05, 0.9, 0.3, -0.2, 0.1, 1.2;
  const ElementNodes<E> x = (A * X).colwise() + Vec3(0.5, -2, 7);
  CHECK((centre_deformation_gradient<E>(X, x) - A).norm() <= 1e-14 * A.norm());
  for (const Mat3& F : vertex_deformation_gradients<E>(X, x)) CHECK((F - A).norm() <= 1e-14 * A.norm());
  for (const Mat3& F : gauss_deformation_gradients<E>(X, x)) CHECK((F - A).norm() <= 1e-14 * A.norm());
  // And the point set's mean gradient gives the same F; its volume is the element's.
  const PointSet<E> ps = gauss_point_set<E>(X);
  CHECK(((x * ps.mean_gradient()) - A).norm() <= 1e-14 * A.norm());
  CHECK(ps.volume() == Approx(element_volume<E>(X)).epsilon(1e-14));
}

TEMPLATE_TEST_CASE("point laws: P = dpsi/dF and A = dP/dF by central differences", "[point][law]", Linear,
                   Corotational, NeoHookean, NeoHookeanAbaqus, StableNeoHookean) {
  using M = TestType;
  const typename M::Law law(tissue);
  std::mt19937 rng(3);
  std::normal_distribution<Scalar> n(0.0, 0.1);
  const Mat3 Q = Eigen::AngleAxisd(2.1, Vec3(-1, 2, 0.5).normalized()).toRotationMatrix();
  for (int trial = 0; trial < 5; ++trial) {
    Mat3 F = Mat3::Identity();
    for (int k = 0; k < 9; ++k) F.data()[k] += n(rng);
    F = Q * F;
    INFO(M::name << ", trial " << trial << ", det F = " << F.determinant());
    REQUIRE(F.determinant() > 0.5);
    if constexpr (std::is_same_v<M, Linear>) {
      // The small-strain law (frame R = I) is quadratic: A is exact and constant.
      Mat3 P;
      Matrix9 A;
      law.evaluate(F, Mat3::Identity(), P, &A);
      struct Wrapped {
        const SmallStrainLaw& l;
        Scalar evaluate(const Mat3& F_, Mat3& P_, Matrix9* A_, TangentKind = TangentKind::Exact) const {
          return l.evaluate(F_, Mat3::Identity(), P_, A_);
        }
      };
      check_law_derivatives(Wrapped{law}, F, TangentKind::Exact, 1e-6);
    } else {
      check_law_derivatives(law, F, TangentKind::Exact, 1e-5);
      // The projected tangent is symmetric positive semi-definite.
      Mat3 P;
      Matrix9 A;
      law.evaluate(F, P, &A, TangentKind::Projected);
      CHECK((A - A.transpose()).norm() <= 1e-12 * A.norm());
      Eigen::Matrix<Scalar, 9, 1> values;
      Matrix9 V;
      symmetric_eigen<9>(Matrix9(0.5 * (A + A.transpose())), values, V);
      CHECK(values.minCoeff() >= -1e-10 * values.cwiseAbs().maxCoeff());
    }
  }
}

TEMPLATE_TEST_CASE("the corotational law's rotation and stretch: F = R S, R proper, S symmetric", "[point][law]", Tet4) {
  const Mat3 Q = Eigen::AngleAxisd(3.0, Vec3(1, 1, 0).normalized()).toRotationMatrix();
  Mat3 U;
  U << 1.2, 0.1, 0.0, 0.1, 0.8, -0.05, 0.0, -0.05, 1.1;
  Mat3 R, S;
  Corotational::Law::rotation_stretch(Q * U, R, S);
  CHECK((R * S - Q * U).norm() <= 1e-14);
  CHECK((R - Q).norm() <= 1e-13);
  CHECK((S - S.transpose()).norm() <= 1e-13);
  CHECK(R.determinant() == Approx(1.0).epsilon(1e-14));
}

TEMPLATE_LIST_TEST_CASE("every model's point-set integral equals its fused kernel over the Gauss rule",
                        "[point][kernel]", AllElements) {
  using E = TestType;
  for (unsigned seed : {1u, 2u}) {
    check_point_set_equals_fused<Linear, E>(seed);
    check_point_set_equals_fused<Corotational, E>(seed);
    check_point_set_equals_fused<CorotationalPerElement, E>(seed);
    check_point_set_equals_fused<NeoHookean, E>(seed);
    check_point_set_equals_fused<NeoHookeanAbaqus, E>(seed);
    check_point_set_equals_fused<StableNeoHookean, E>(seed);
    check_point_set_equals_fused<NeoHookeanMeanDilatation, E>(seed);
    check_point_set_equals_fused<LinearMeanDilatation, E>(seed);
    check_point_set_equals_fused<CorotationalMeanDilatation, E>(seed);
  }
}

TEMPLATE_LIST_TEST_CASE("a point set of any size: the model's integral is the sum of its point law over the points",
                        "[point][kernel]", AllElements) {
  // Corotational takes a point set in chunks of the Gauss rule's size through its batched kernel
  // (padding the last chunk with zero-weight points); here the points of the mass rule (4 on
  // Tet4, 14 on Tet10, 27 on Hex8 and Wedge6), not a multiple of the chunk (the stiffness rule's
  // 1, 4, 8 and 6 points), against the plain sum over the points of the law,
  // whose derivatives the central differences above check. Same formula, other summation order
  // and polar iteration: ~1e-14 relative; 1e-11 bounds it with room.
  using E = TestType;
  const auto [X, x] = deformed_element<E>(4);
  PointSet<E> ps;
  const auto rule = E::template quadrature<E::mass_degree>();
  for (int k = 0; k < rule.size; ++k) ps.add(X, rule.points[k], rule.weights[k]);
  if constexpr (QuadraturePoints<E>::size > 1) REQUIRE(ps.size() % QuadraturePoints<E>::size != 0);  // a padded chunk
  auto check = [&]<class M>() {
    const typename M::Law law(tissue);
    for (TangentKind kind : {TangentKind::Projected, TangentKind::Exact}) {
      ElementVector<E> f0 = ElementVector<E>::Zero(), f1;
      ElementMatrix<E> K0 = ElementMatrix<E>::Zero(), K1;
      Scalar W0 = 0;
      for (int q = 0; q < ps.size(); ++q) {
        Mat3 P;
        Matrix9 A;
        W0 += ps.dv[q] * law.evaluate(x * ps.G[q], P, &A, kind);
        detail::add_point_contribution<E>(ps.G[q], ps.dv[q], P, &A, f0, &K0);
      }
      const Scalar W1 = M::template evaluate_points<E>(law, ps, x, f1, &K1, kind);
      INFO(M::name << " on " << E::name << (kind == TangentKind::Exact ? ", exact tangent" : ", projected tangent"));
      CHECK(std::abs(W1 - W0) <= 1e-11 * std::abs(W0));
      CHECK((f1 - f0).norm() <= 1e-11 * f0.norm());
      CHECK((K1 - K0).norm() <= 1e-11 * K0.norm());
    }
  };
  check.template operator()<Corotational>();
  check.template operator()<NeoHookean>();
  check.template operator()<StableNeoHookean>();
}
