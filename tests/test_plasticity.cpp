// Plasticity (seed 000): the vertex-blended and cell-centered policies.
//
// Facts checked, each against something independent of the code under test:
//  - rotations: exp(log R) = R and |log R| = the angle, near 0 and near pi; powers compose
//    (R^a R^b = R^(a+b)); the geodesic distance of rotations about one axis is the difference
//    of their angles;
//  - the plastic stretch Sp = exp(gamma dev(log U)) is symmetric, has det 1, is I for gamma = 0,
//    the isochoric stretch U / det(U)^(1/3) for gamma = 1, and coaxial with U;
//  - the fusion reproduces any compatible proposal exactly (a uniform stretch of every element,
//    the same rotation of every element), where the paper's one-pass average does not;
//  - per combination (every element x policy x elastic family): no flow below yield (rest
//    shapes bit for bit those of the mesh), no flow under a rigid motion of the whole body
//    (translation and rotation through 2 pi), flow above yield that keeps the volume, and a
//    failing step after flow leaves the whole state, plastic table included, bit for bit;
//  - the residual deformation grows with the load and with the flow rate; a second identical
//    load cycle adds less than the first (hardening);
//  - the plastic state does not depend on how closely Newton converged (1e-6 against 1e-10:
//    the same to the tolerance's order);
//  - the symmetric stretch keeps its mirror symmetry to 1e-8; a twist beyond pi runs with no
//    inverted element; a bend is kept by the plastic rotation (10 times what the stretch alone
//    keeps);
//  - the Neo-Hookean closed-form flow stress equals the law's F^-1 P;
//  - statics carry the plastic state from increment to increment (path dependence);
//  - real-time mode and the lumped mass run plasticity too; bad parameters are refused by name.
#include "catch.hpp"
#include "material_mesh.hpp"

#include <plastifem/plasticity.hpp>
#include <plastifem/plastifem.hpp>

#include <fmt/core.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <random>
#include <stdexcept>

using namespace plastifem;
using test::RigidFit;
using test::rigid_fit;
using test::material_volume;

namespace {

const Material soft{3000, 0.45, 1.0};  // SCENES.md bar material
constexpr Scalar pi = std::numbers::pi;

Mat3 rotation_about(const Vec3& axis, Scalar angle) { return rotation_exp(axis.normalized() * angle); }

/// The largest |x - X| of the material mesh.
template <class S>
Scalar max_rest_change(const S& s) {
  return (s.material_positions() - s.mesh().nodes()).cwiseAbs().maxCoeff();
}

PlasticParams stretch_params(Scalar tau, Scalar nu, Scalar scale = 50) {
  PlasticParams p;
  p.yield_stress = tau;
  p.flow_rate = nu;
  p.stress_scale = scale;
  p.hardening = 0.2;
  return p;
}

/// The stretch scene on bar cells (nx, ny, nz) (unit cubes), the force spread over the end
/// face as a uniform traction, mass damping 1, dt = 0.01:
/// returns the solver after `seconds` (load 0-1 s, hold 1-2 s, released after).
template <FiniteElement E, class M, class P>
Solver<E, M, P> stretch(int nx, int ny, int nz, Scalar force, const PlasticParams& pp, Scalar seconds,
                        SolverSettings st = {}) {
  const Mesh<E> mesh = bar_mesh<E>(nx, ny, nz);
  st.rayleigh_mass = 1.0;
  Solver<E, M, P> s(mesh, soft, st, pp);
  s.fix(mesh.node_set("xmin"));
  s.add_traction(mesh.face_set("xmax"), Vec3(force / (ny * nz), 0, 0), ramp_hold_release(1.0, 2.0));
  const int steps = static_cast<int>(std::lround(seconds / 0.01));
  for (int k = 0; k < steps; ++k) s.step(0.01);
  return s;
}

}  // namespace

// --- the pieces ------------------------------------------------------------------------------

TEST_CASE("rotations: log and exp invert each other near 0 and near pi, powers compose", "[plasticity]") {
  const Vec3 axis = Vec3(1, -2, 0.5).normalized();
  for (Scalar angle : {0.0, 1e-12, 1e-7, 1e-4, 0.3, 1.0, pi / 2, 2.0, 3.0, pi - 1e-6, pi - 1e-10, pi}) {
    const Mat3 R = rotation_about(axis, angle);
    const Vec3 w = rotation_log(R);
    CHECK(std::abs(w.norm() - angle) <= 1e-12 * std::max(1.0, angle));
    CHECK((rotation_exp(w) - R).norm() <= 1e-14);
    CHECK(std::abs(rotation_angle(R) - angle) <= 1e-12 * std::max(1.0, angle));
    if (angle > 1e-7 && angle < pi - 1e-6) CHECK((w.normalized() - axis).norm() <= 1e-9);
    // R^a R^b = R^(a + b) about one axis (below pi, where the power is unique).
    if (angle < 3.0) CHECK((rotation_power(R, 0.3) * rotation_power(R, 0.45) - rotation_power(R, 0.75)).norm() <= 1e-14);
  }
  // The geodesic distance of two rotations about one axis is the difference of their angles,
  // and does not depend on a rotation applied to both.
  const Mat3 A = rotation_about(axis, 0.4), B = rotation_about(axis, 1.7), C = rotation_about(Vec3(0, 0, 1), 2.5);
  CHECK(std::abs(geodesic_distance(A, B) - 1.3) <= 1e-14);
  CHECK(std::abs(geodesic_distance(C * A, C * B) - 1.3) <= 1e-13);
}

TEST_CASE("plastic stretch: symmetric, det 1, I at gamma 0, the isochoric stretch at gamma 1", "[plasticity]") {
  // F = R U with U the stretch diag(1.3, 0.9, 1.05) in a rotated frame Q, and a rotation R.
  const Mat3 Q = rotation_about(Vec3(1, 1, 0), 0.7), R = rotation_about(Vec3(0, 1, 2), 1.1);
  const Vec3 d(1.3, 0.9, 1.05);
  const Mat3 U = Q * d.asDiagonal() * Q.transpose();
  const Mat3 F = R * U;
  const Mat3 U_iso = U / std::cbrt(U.determinant());
  Mat3 Sp;
  REQUIRE(plastic::isochoric_stretch_power(F, 0, Sp));
  CHECK((Sp - Mat3::Identity()).norm() <= 1e-14);
  REQUIRE(plastic::isochoric_stretch_power(F, 1, Sp));
  CHECK((Sp - U_iso).norm() <= 1e-13);
  REQUIRE(plastic::isochoric_stretch_power(F, 0.37, Sp));
  CHECK((Sp - Sp.transpose()).norm() <= 1e-14);
  CHECK(std::abs(Sp.determinant() - 1) <= 1e-14);
  CHECK((Sp * U - U * Sp).norm() <= 1e-13);  // coaxial
  // Its eigenvalues are (d_i / det(d)^(1/3))^0.37.
  const Mat3 expected = Q * (d / std::cbrt(d.prod())).array().pow(0.37).matrix().asDiagonal() * Q.transpose();
  CHECK((Sp - expected).norm() <= 1e-13);
  // A reflected F (an inverted point) has the same right stretch: the same Sp.
  Mat3 Sp_reflected;
  const Mat3 reflect = Vec3(1, 1, -1).asDiagonal();
  REQUIRE(plastic::isochoric_stretch_power(reflect * F, 0.37, Sp_reflected));
  CHECK((Sp_reflected - Sp).norm() <= 1e-13);
  // A collapsed F has none.
  CHECK_FALSE(plastic::isochoric_stretch_power(Mat3::Zero(), 0.5, Sp));
  // Tissue strains: the closed form (no eigenvectors) to round-off of the exact Sp, also at
  // rest.
  for (const Vec3& small : {Vec3(1.02, 0.99, 1.005), Vec3(1.1, 0.97, 1.0), Vec3(1.0, 1.0, 1.0), Vec3(1.11, 0.95, 1.02)}) {
    const Mat3 Us = Q * small.asDiagonal() * Q.transpose();
    REQUIRE(plastic::isochoric_stretch_power(R * Us, 0.6, Sp));
    const Mat3 ref = Q * (small / std::cbrt(small.prod())).array().pow(0.6).matrix().asDiagonal() * Q.transpose();
    CHECK((Sp - ref).norm() <= 1e-14);
    CHECK(std::abs(Sp.determinant() - 1) <= 1e-14);
  }
}

TEST_CASE("plastic stretch: the closed form equals the eigen-decomposition, close and equal eigenvalues included", "[plasticity]") {
  // 8000 right stretches U = Q diag(d) Q^T in random frames, F = R U: d from rest (d = 1) and
  // round-off (1e-14) to stretch ratios of 8 (the closed form hands over to the decomposition
  // beyond l1 / l3 = 16, C's eigenvalues), with two equal and two nearly equal (1e-9) stretches.
  // The closed form is a polynomial in C through its eigenvalues, the reference rotates C to
  // diagonal: independent computations, agreeing to 1e-13 of |Sp| (measured: 8.6e-15 at worst,
  // rising to 3e-11 at l1 / l3 = 1000 where the hand-over prevents it).
  std::mt19937 rng(7);
  std::normal_distribution<Scalar> normal;
  Scalar worst = 0, worst_det = 0;
  for (int k = 0; k < 8000; ++k) {
    const Scalar spread = std::pow(10.0, -14 + 14 * (k % 100) / 99.0) * (k % 3 == 0 ? 2.0 : 0.2);
    Vec3 d(std::exp(spread * normal(rng)), std::exp(spread * normal(rng)), std::exp(spread * normal(rng)));
    if (k % 4 == 1) d[2] = d[1];
    if (k % 4 == 2) d[2] = d[1] * (1 + 1e-9 * normal(rng));
    if (k % 100 == 0) d = Vec3::Ones();
    const Mat3 Q = rotation_about(Vec3(normal(rng), normal(rng), normal(rng)), 3 * normal(rng));
    const Mat3 R = rotation_about(Vec3(normal(rng), normal(rng), normal(rng)), 3 * normal(rng));
    const Mat3 F = R * Q * d.asDiagonal() * Q.transpose();
    for (Scalar gamma : {0.004, 0.37, 1.0}) {
      Mat3 a = Mat3::Zero(), b = Mat3::Zero();
      REQUIRE(plastic::isochoric_stretch_power(F, gamma, a));
      REQUIRE(plastic::isochoric_stretch_power_eigen(F.transpose() * F, gamma, b));
      worst = std::max(worst, (a - b).norm() / b.norm());
      worst_det = std::max(worst_det, std::abs(a.determinant() - 1));
    }
  }
  INFO("largest relative difference " << worst << ", largest |det Sp - 1| " << worst_det);
  CHECK(worst <= 1e-13);
  CHECK(worst_det <= 1e-13);
}

TEST_CASE("flow stress: the Neo-Hookean closed form M = mu (C - I) + lambda ln J I is F^T P", "[plasticity]") {
  // The flow reads the hyperelastic stress as the Mandel stress M = F^T P of the law (the
  // generic path); the Neo-Hookean energy gives it in closed form. The two must agree at any F
  // with J > 0 (to 1e-12 of |M|: both are a few dozen operations, with an inverse of condition
  // <= 1e3 inside P here).
  const Material m{3000, 0.45, 1};
  const NeoHookean::Law law(m);
  const Mat3 R = rotation_about(Vec3(0, 1, 2), 1.1), Q = rotation_about(Vec3(1, 1, 0), 0.7);
  for (const Vec3& d : {Vec3(1, 1, 1), Vec3(1.02, 0.99, 1.005), Vec3(1.3, 0.9, 1.05), Vec3(0.2, 1.5, 3.0), Vec3(0.05, 0.1, 0.3)}) {
    const Mat3 F = R * Q * d.asDiagonal() * Q.transpose() + 0.01 * Mat3::Ones();
    Mat3 P = Mat3::Zero(), M = Mat3::Zero();
    REQUIRE(std::isfinite(law.evaluate(F, P, nullptr)));
    REQUIRE(law.energy.mandel_stress(F, M));
    const Mat3 generic = F.transpose() * P;
    CHECK((M - generic).norm() <= 1e-12 * generic.norm() + 1e-12 * m.mu());
    CHECK((M - M.transpose()).norm() <= 1e-14 * M.norm() + 1e-14);
  }
  // Where J <= 0 the stress is undefined, as the law's.
  Mat3 M = Mat3::Zero();
  CHECK_FALSE(law.energy.mandel_stress(Vec3(1, 1, -1).asDiagonal(), M));
  CHECK_FALSE(law.energy.mandel_stress(Mat3::Zero(), M));
}

TEST_CASE("flow stress: the yield measure of every hyperelastic model is free of the pressure", "[plasticity]") {
  // Von Mises plasticity must not yield on a pressure. At finite strain the deviator of the
  // second Piola-Kirchhoff stress S keeps one (p J dev C^-1); the Mandel stress M = C S = F^T P
  // has the Kirchhoff stress's invariants, and the pressure terms of these energies
  // (lambda ln J, the volumetric U(J), a mean-dilatation's U'(Jbar)) add to M a multiple of I.
  // Independent facts: (1) a pure volume change F = s I gives a zero deviator; (2) at the same F,
  // materials of the same shear modulus whose bulk moduli differ 100 times (nu = 0.3 and
  // 0.4977) give the same deviator, to round-off of the pressure term, which is up to 1e3 times
  // the deviator here (1e-11 of |dev|); (3) it is 2 mu dev E to first order in the strain.
  // Measured with dev S (review, 2026-12-03): Mooney-Rivlin under 10% confined compression read
  // a von Mises stress of 476 at nu = 0.447 and 10,820 at 0.499 for the same shear.
  const Scalar mu = 1000;
  const auto material = [&](Scalar nu) { return Material{2 * mu * (1 + nu), nu, 1}; };
  const Material soft = material(0.3), stiff = material(0.4977);
  REQUIRE(stiff.lambda() + 2 * mu / 3 == Approx(100 * (soft.lambda() + 2 * mu / 3)).epsilon(1e-2));
  const auto check = [&]<class Model>() {
    INFO(Model::name);
    const typename Model::Law soft_law(soft), stiff_law(stiff);
    for (const Scalar s : {0.9, 1.1}) {
      Mat3 dev;
      REQUIRE(plastic::deviatoric_flow_stress<Model>(stiff_law, stiff, s * Mat3::Identity(), dev));
      CHECK(dev.norm() <= 1e-12 * mu);
    }
    const Mat3 R = rotation_about(Vec3(1, 2, 0.5), 0.8);
    for (const Mat3& U : {Mat3(Vec3(0.9, 1, 1).asDiagonal()), Mat3(Vec3(1.1, 1, 1).asDiagonal()),
                          Mat3(Vec3(0.8, 1.05, 0.97).asDiagonal())}) {
      const Mat3 F = R * U;
      Mat3 dev_soft, dev_stiff;
      REQUIRE(plastic::deviatoric_flow_stress<Model>(soft_law, soft, F, dev_soft));
      REQUIRE(plastic::deviatoric_flow_stress<Model>(stiff_law, stiff, F, dev_stiff));
      CHECK((dev_soft - dev_stiff).norm() <= 1e-11 * dev_soft.norm());
    }
    const Mat3 small = Mat3::Identity() + 1e-6 * Mat3(Vec3(1, -0.5, 0.2).asDiagonal());
    Mat3 dev;
    REQUIRE(plastic::deviatoric_flow_stress<Model>(stiff_law, stiff, small, dev));
    const Mat3 Eg = 0.5 * (small.transpose() * small - Mat3::Identity());
    const Mat3 expected = 2 * mu * (Eg - Eg.trace() / 3 * Mat3::Identity());
    // Second order in the strain (1e-6) relative to the first, and the bulk term's round-off.
    CHECK((dev - expected).norm() <= 1e-5 * expected.norm());
  };
  check.template operator()<NeoHookean>();
  check.template operator()<NeoHookeanAbaqus>();
  check.template operator()<NeoHookeanMeanDilatation>();
  check.template operator()<NeoHookeanAbaqusMeanDilatation>();
  check.template operator()<StableNeoHookean>();
}

TEST_CASE("yield check: the Neo-Hookean measure at all Gauss points at once is the point-wise one", "[plasticity]") {
  // may_flow reads |dev M|^2 of the Neo-Hookean energy at an element's Gauss points in one
  // batch (one SIMD lane per point); run() computes the stress point by point. The two agree to
  // round-off (1e-9 of |dev M|^2: the deviator of C cancels where the distortion is small
  // against the volume change, here down to 1e-2), NaN where J <= 0.
  const Material m{3000, 0.45, 1};
  const NeoHookean::Law law(m);
  static_assert(requires { law.energy.template deviatoric_mandel_norm2<8>(PointMat3<8>{}); },
                "the Neo-Hookean check must take the batched path");
  std::mt19937 rng(7);
  std::uniform_real_distribution<Scalar> u(-0.4, 0.4);
  for (int trial = 0; trial < 200; ++trial) {
    PointMat3<8> F;
    std::array<Mat3, 8> Fq;
    for (int q = 0; q < 8; ++q) {
      Fq[q] = Mat3::Identity();
      for (int i = 0; i < 9; ++i) Fq[q](i % 3, i / 3) += u(rng) * (trial % 2 ? 1.0 : 0.05);
      if (trial % 10 == 0 && q == 3) Fq[q].col(2) *= -1;  // an inverted point
      for (int i = 0; i < 9; ++i) F[i][q] = Fq[q](i % 3, i / 3);
    }
    const PointArray<8> s2 = law.energy.deviatoric_mandel_norm2<8>(F);
    for (int q = 0; q < 8; ++q) {
      Mat3 dev = Mat3::Zero();
      if (!plastic::deviatoric_flow_stress<NeoHookean>(law, m, Fq[q], dev)) {
        CHECK(std::isnan(s2[q]));
        continue;
      }
      CHECK(std::abs(s2[q] - dev.squaredNorm()) <= 1e-9 * dev.squaredNorm());
    }
  }

  // The check's decision: an element whose largest point stress is 0.1% below the yield stress
  // does not flow, 0.1% above does, and one within 1e-9 of it goes to run() (conservative);
  // the point-wise path of the other energies decides the same.
  const auto X = bar_mesh<Hex8>(1, 1, 1).element_nodes(0);
  const auto check = [&]<class Model>() {
    using Flow = plastic::ElementFlow<Hex8, Model, true>;
    const typename Model::Law model_law(m);
    const typename Flow::Points pts;
    const typename Flow::Gradients grad(pts, X);
    ElementNodes<Hex8> x = X;
    for (int a = 0; a < 8; ++a) x.col(a) = Vec3(1.1 * X(0, a) + 0.05 * X(1, a), 0.97 * X(1, a), X(2, a) + 0.02 * X(0, a) * X(1, a));
    std::array<Mat3, Flow::P> F;
    for (int k = 0; k < Flow::P; ++k) F[k] = grad.gauss_gradient(x, k);
    Scalar s_max = 0;
    for (int k = 0; k < Flow::P; ++k) {
      Mat3 dev = Mat3::Zero();
      REQUIRE(plastic::deviatoric_flow_stress<Model>(model_law, m, F[k], dev));
      s_max = std::max(s_max, plastic::von_mises_norm(dev));
    }
    PlasticParams prm;
    std::array<Scalar, Flow::P> tau;
    const plastic::ElementPlasticEntries en{tau.data(), nullptr, nullptr, nullptr};
    for (const auto& [factor, flows] : {std::pair{1.001, false}, std::pair{0.999, true}, std::pair{1 + 1e-9, true}}) {
      tau.fill(factor * s_max);
      INFO(Model::name << " tau = " << factor << " |s|max");
      if (factor == 1 + 1e-9 && !std::is_same_v<Model, NeoHookean>) continue;  // exact there
      CHECK(Flow::may_flow(grad, model_law, m, prm, x, 1.0, en) == flows);
    }
  };
  check.template operator()<NeoHookean>();
  check.template operator()<NeoHookeanAbaqus>();
  check.template operator()<NeoHookeanMeanDilatation>();  // the point-wise path, F^T P of the deviatoric energy
}

TEST_CASE("plasticity on a mean-dilatation hyperelastic model flows on the model's stress", "[plasticity]") {
  // Found by review (2026-12-01): the flow read each Gauss point's own volumetric stress U'(J),
  // the locked pressure the variant removes. On this nearly incompressible cantilever the flow
  // saw |s| up to 38,600 where the model's stress is under 900: 1006 points yielded at a yield
  // stress above every point's. The yield is taken here from the elastic solution's largest
  // element von Mises stress (at the centres; the Gauss points' exceed it by up to 1.6 in
  // bending): 3 times it flows nowhere, 0.3 times it flows.
  const Mesh<Hex8> mesh = bar_mesh<Hex8>(8, 2, 2);
  const Material m{3000, 0.499, 1.0};
  const Vec3 t(0, 0, -60);
  Solver<Hex8, NeoHookeanMeanDilatation> elastic(mesh, m);
  elastic.fix(mesh.node_set("xmin"));
  elastic.add_traction(mesh.face_set("xmax"), t);
  elastic.solve_static(5);
  const Scalar von_mises = elastic.von_mises_stress().maxCoeff();
  INFO("largest element von Mises stress " << von_mises);
  for (const auto& [factor, flows] : {std::pair{3.0, false}, std::pair{0.3, true}}) {
    PlasticParams p;
    p.yield_stress = factor * von_mises;
    Solver<Hex8, NeoHookeanMeanDilatation, VertexBlended> s(mesh, m, {}, p);
    s.fix(mesh.node_set("xmin"));
    s.add_traction(mesh.face_set("xmax"), t);
    const PlasticReport r = s.solve_static(5).plastic;
    INFO("yield " << factor << " x: " << r.points_yielded << " points yielded");
    CHECK((r.points_yielded > 0) == flows);
  }
}

TEST_CASE("fusion: compatible proposals are reproduced exactly, a one-pass average is not", "[plasticity]") {
  const Mesh<Hex8> mesh = bar_mesh<Hex8>(6, 2, 2);
  plastic::MaterialFusion<Hex8> fusion;
  fusion.build(mesh);
  const Index ne = mesh.num_elements();
  const Vector X = Eigen::Map<const Vector>(mesh.nodes().data(), 3 * mesh.num_nodes());
  std::vector<char> all(ne, 1);
  auto proposals = [&](const Mat3& A) {  // every element mapped by A about its own centre
    std::vector<ElementNodes<Hex8>> z(ne);
    for (Index e = 0; e < ne; ++e) {
      const ElementNodes<Hex8> Xe = mesh.element_nodes(e);
      const Vec3 c = Xe.rowwise().mean();
      z[e] = (A * (Xe.colwise() - c)).colwise() + c;
    }
    return z;
  };
  for (const Mat3& A : {Mat3(Vec3(1.2, 0.95, 0.9).asDiagonal()), rotation_about(Vec3(1, 2, 3), 0.4)}) {
    Vector rest = X;
    fusion.fuse(mesh, proposals(A), all, rest);
    // The fused mesh is A X up to a translation: its node differences are A's.
    const Eigen::Map<const Eigen::Matrix3Xd> x(rest.data(), 3, mesh.num_nodes());
    const Eigen::Matrix3Xd expected = A * mesh.nodes();
    const Vec3 shift = (x - expected).rowwise().mean();
    CHECK(((x - expected).colwise() - shift).cwiseAbs().maxCoeff() <= 1e-12);
    // The paper's one-pass average, every element left at its own centre: an interior node
    // is the mean of neighbours' opposite corners, so it does not move with the stretch.
    if (A.isDiagonal()) {
      Eigen::Matrix3Xd avg = Eigen::Matrix3Xd::Zero(3, mesh.num_nodes());
      Eigen::VectorXd count = Eigen::VectorXd::Zero(mesh.num_nodes());
      const auto z = proposals(A);
      for (Index e = 0; e < ne; ++e)
        for (int a = 0; a < 8; ++a) avg.col(mesh.element(e)[a]) += z[e].col(a), count[mesh.element(e)[a]] += 1;
      for (Index i = 0; i < mesh.num_nodes(); ++i) avg.col(i) /= count[i];
      const Scalar error = ((avg - expected).colwise() - (avg - expected).rowwise().mean()).cwiseAbs().maxCoeff();
      CHECK(error > 0.1);  // a 20% stretch over 6 cells: the average misses most of it
    }
  }
}

TEST_CASE("point force: consistent nodal loads of a force at a point", "[plasticity]") {
  const Mesh<Tet10> mesh = bar_mesh<Tet10>(4, 3, 3);
  Solver<Tet10, Linear> s(mesh, soft);
  const Vec3 X(4, 1.5, 1.2), f(2, -1, 3);
  s.add_point_force(X, f);
  // The loads sum to f and have no moment about X (they reproduce the point force exactly for
  // the linear and quadratic fields the element interpolates).
  Vector fe(s.num_dofs());
  s.fix(mesh.node_set("xmin"));
  s.solve_static();
  const Vector r = s.internal_force();  // balances the loads at the free dofs
  Vec3 sum = Vec3::Zero(), moment = Vec3::Zero();
  const Vector reactions = s.reaction_forces();
  for (Index i = 0; i < mesh.num_nodes(); ++i) {
    const Vec3 load = r.segment<3>(3 * i) - reactions.segment<3>(3 * i);
    sum += load;
    moment += (Vec3(mesh.node(i)) - X).cross(load);
  }
  CHECK((sum - f).norm() <= 1e-9 * f.norm());
  CHECK(moment.norm() <= 1e-9 * f.norm());
  CHECK_THROWS_AS(s.add_point_force(Vec3(5, 1, 1), f), InvalidArgument);
}

TEST_CASE("plastic parameters: out-of-range values are refused by name", "[plasticity]") {
  const Mesh<Hex8> mesh = bar_mesh<Hex8>(2, 1, 1);
  auto refused = [&](auto change, const char* name) {
    PlasticParams p;
    change(p);
    try {
      Solver<Hex8, Corotational, VertexBlended> s(mesh, soft, {}, p);
      FAIL("accepted " << name);
    } catch (const InvalidArgument& e) {
      CHECK(std::string(e.what()).find(name) != std::string::npos);
    }
  };
  const Scalar nan = std::numeric_limits<Scalar>::quiet_NaN();
  refused([](PlasticParams& p) { p.yield_stress = -1; }, "yield_stress");
  refused([&](PlasticParams& p) { p.yield_stress = nan; }, "yield_stress");
  refused([](PlasticParams& p) { p.flow_rate = 1.5; }, "flow_rate");
  refused([](PlasticParams& p) { p.flow_rate = -0.1; }, "flow_rate");
  refused([&](PlasticParams& p) { p.flow_rate = nan; }, "flow_rate");
  refused([](PlasticParams& p) { p.rotation_yield = 4; }, "rotation_yield");
  refused([](PlasticParams& p) { p.rotation_flow_rate = 2; }, "rotation_flow_rate");
  refused([](PlasticParams& p) { p.hardening = -0.2; }, "hardening");
  refused([&](PlasticParams& p) { p.hardening = nan; }, "hardening");
  refused([](PlasticParams& p) { p.kinematic_hardening = -1; }, "kinematic_hardening");
  refused([](PlasticParams& p) { p.stress_scale = 0; }, "stress_scale");
  refused([](PlasticParams& p) { p.max_step_rotation = 4; }, "max_step_rotation");
  refused([](PlasticParams& p) { p.min_rest_quality = 0; }, "min_rest_quality");
  refused([&](PlasticParams& p) { p.volume_restitution = nan; }, "volume_restitution");
  refused([](PlasticParams& p) { p.rotation_frame = static_cast<PlasticParams::RotationFrame>(7); }, "rotation_frame");
  // Also when changed mid-run, with the parameters unchanged.
  Solver<Hex8, Corotational, CellCentered> s(mesh, soft);
  PlasticParams bad;
  bad.flow_rate = 3;
  CHECK_THROWS_AS(s.set_plastic_params(bad), InvalidArgument);
  CHECK(s.plastic_params().flow_rate == PlasticParams{}.flow_rate);
}

TEST_CASE("plastic parameters mid-run: thresholds keep their hardening, also through an infinite yield",
          "[plasticity]") {
  // A yield of +inf switches the stretch flow off (test_plastic_cut does so); switching it on
  // again used to set every threshold to the new value, the hardening lost (found by review,
  // 2026-11-30: tau in [7.7, 10.9] became 5 everywhere).
  const Mesh<Hex8> mesh = bar_mesh<Hex8>(4, 1, 1);
  PlasticParams p;
  p.yield_stress = 5, p.flow_rate = 1, p.hardening = 1;
  Solver<Hex8, Corotational, VertexBlended> s(mesh, soft, {}, p);
  s.fix(mesh.node_set("xmin"));
  s.add_traction(mesh.face_set("xmax"), Vec3(30, 0, 0));
  for (int k = 0; k < 20; ++k) s.step(0.01);
  const std::vector<Scalar> hardened = s.state().plastic.tau;
  REQUIRE(*std::max_element(hardened.begin(), hardened.end()) > 6);  // it hardened
  auto shifted = [&](Scalar by) {
    std::vector<Scalar> t = hardened;
    for (Scalar& x : t) x = std::max(Scalar(0), x + by);
    return t;
  };
  PlasticParams q = p;
  q.yield_stress = 7;
  s.set_plastic_params(q);
  CHECK(s.state().plastic.tau == shifted(2));  // shifted by the change of the initial value
  PlasticParams off = q;
  off.yield_stress = std::numeric_limits<Scalar>::infinity();
  s.set_plastic_params(off);
  CHECK(s.state().plastic.tau == shifted(2));  // left as they are
  s.set_plastic_params(q);
  CHECK(s.state().plastic.tau == shifted(2));  // on again at the same value: nothing changed
  // A body built with the flow off starts at the value it is switched on with.
  Solver<Hex8, Corotational, VertexBlended> later(mesh, soft, {}, off);
  later.set_plastic_params(p);
  for (const Scalar t : later.state().plastic.tau) CHECK(t == 5);
}

TEST_CASE("kinematic hardening: the centre moves towards the stress, at most onto it", "[plasticity]") {
  // alpha += kappa_k gamma (s - alpha) overshot for kappa_k gamma > 1 and diverged past 2: at
  // kappa_k = 500 the centre reached 1e154, |s| overflowed, and the steps reported 32 points
  // yielding with gamma 0 (found by review, 2026-11-30). With the step capped at 1 the centre
  // is a convex combination of zero and past stresses: bounded by the largest of them.
  const Mesh<Hex8> mesh = bar_mesh<Hex8>(4, 1, 1);
  for (const Scalar kk : {0.5, 500.0}) {
    INFO("kinematic_hardening " << kk);
    PlasticParams p;
    p.yield_stress = 0, p.flow_rate = 1, p.hardening = 0, p.kinematic_hardening = kk;
    Solver<Hex8, Corotational, VertexBlended> s(mesh, soft, {}, p);
    s.fix(mesh.node_set("xmin"));
    s.add_traction(mesh.face_set("xmax"), Vec3(30, 0, 0));
    Scalar largest_stress = 0;
    int inconsistent = 0;
    for (int k = 0; k < 320; ++k) {
      const StepReport r = s.step(0.01);
      inconsistent += r.plastic.points_yielded > 0 && !(r.plastic.max_gamma > 0);
      largest_stress = std::max(largest_stress, s.von_mises_stress().maxCoeff());
    }
    CHECK(inconsistent == 0);
    Scalar largest_centre = 0;
    for (const Scalar a : s.state().plastic.alpha) largest_centre = std::max(largest_centre, std::abs(a));
    INFO("largest centre entry " << largest_centre << ", largest von Mises stress " << largest_stress);
    // An entry of a deviator is at most its von Mises norm (|s_ij| <= sqrt(2/3) |s|_vM); the
    // flow measures the second Piola-Kirchhoff deviator, within a factor (1 + strain)^2 of the
    // Cauchy stress von_mises_stress gives: 2 covers strains to 40%.
    CHECK(std::isfinite(largest_centre));
    CHECK(largest_centre <= 2 * largest_stress);
    CHECK(largest_centre > 0);
  }
}

// --- invariants, every element x policy x elastic family ------------------------------------------

namespace {

template <FiniteElement E, class M, class P>
void invariants() {
  INFO(E::name << " " << M::name << " " << P::name);
  const Mesh<E> mesh = bar_mesh<E>(3, 1, 1);
  const Index tip = [&] {
    for (Index i : mesh.node_set("xmax"))
      if (mesh.node(i).y() == 1 && mesh.node(i).z() == 1) return i;
    return Index(-1);
  }();
  PlasticParams yielding = stretch_params(0, 1, 1);  // flows at any stress
  yielding.rotation_yield = 0.01;
  yielding.rotation_flow_rate = 1;

  // 1. Below yield: nothing changes, bit for bit.
  {
    PlasticParams high = yielding;
    high.yield_stress = 1e9;
    high.rotation_yield = pi;
    Solver<E, M, P> s(mesh, soft, {}, high);
    s.fix(mesh.node_set("xmin"));
    s.add_nodal_force(std::vector<Index>{tip}, Vec3(0, 20, 40));
    int yielded = 0;
    for (int k = 0; k < 10; ++k) yielded += s.step(0.02).plastic.points_yielded;
    CHECK(yielded == 0);
    CHECK(max_rest_change(s) == 0);
    CHECK(s.state().plastic.version == 0);
  }
  // 2. A rigid motion (translation and a rotation through 2 pi about a skew axis) of the whole
  //    body, prescribed at every node: no flow, even with tau = 0.
  {
    Solver<E, M, P> s(mesh, soft, {}, yielding);
    std::vector<Index> all(mesh.num_nodes());
    for (Index i = 0; i < mesh.num_nodes(); ++i) all[i] = i;
    const Vec3 axis = Vec3(1, 2, -1).normalized();
    s.prescribe(all, [axis](Scalar t, const Vec3& X) {
      return Vec3(rotation_about(axis, 2 * pi * t) * X + Vec3(0.3, -0.2, 0.5) * t - X);
    });
    PlasticReport total;
    for (int k = 0; k < 25; ++k) total.add(s.step(0.04).plastic);
    CHECK(std::abs(s.time() - 1.0) < 1e-12);
    CHECK(total.points_yielded == 0);
    CHECK(total.rotations_yielded == 0);
    CHECK(max_rest_change(s) == 0);
  }
  // 3. Above yield: the rest shape flows and keeps its volume (to the restitution's tolerance).
  Solver<E, M, P> s(mesh, soft, {}, yielding);
  s.fix(mesh.node_set("xmin"));
  s.add_nodal_force(std::vector<Index>{tip}, Vec3(30, 0, 10), [](Scalar t) { return t < 0.2 ? 1.0 : 0.0; });
  PlasticReport total;
  for (int k = 0; k < 10; ++k) total.add(s.step(0.02).plastic);
  CHECK(total.points_yielded > 0);
  CHECK(max_rest_change(s) > 1e-4);
  const Scalar V0 = material_volume(mesh, mesh.nodes());
  CHECK(std::abs(material_volume(mesh, s.material_positions()) / V0 - 1) < 1e-3);
  // 4. A step that fails after plastic flow: the whole state, plastic table included, bit for
  //    bit as before. The load overflows to inf at t0 + dt (SolverError: the full step and
  //    every second half are cut); the first half step flows and commits to the working copy;
  //    then the first quarter of the second half has its load callback throw.
  s.set_settings([&] {
    SolverSettings st = s.settings();
    st.max_step_cuts = 2;
    return st;
  }());
  const Scalar t0 = s.time(), huge = std::numeric_limits<Scalar>::max();
  const LoadHandle h = s.add_nodal_force(std::vector<Index>{tip}, Vec3(0, 60, 0), [t0, huge](Scalar t) {
    if (t > t0 + 0.0199) return huge;  // x 60: inf
    if (t > t0 + 0.012) throw std::runtime_error("a load callback failed");
    return 1.0;
  });
  const auto before = s.state();
  CHECK_THROWS_AS(s.step(0.02), std::runtime_error);
  CHECK(s.state() == before);
  // Same when the last sub-step fails as the solver's: the halves and quarters before it flow,
  // the last quarter fails at the deepest cut.
  s.remove_load(h);
  s.add_nodal_force(std::vector<Index>{tip}, Vec3(0, 60, 0), [t0, huge](Scalar t) { return t > t0 + 0.0199 ? huge : 1.0; });
  const auto before_overflow = s.state();
  const Scalar energy = s.strain_energy();
  CHECK_THROWS_AS(s.step(0.02), SolverError);
  CHECK(s.state() == before_overflow);
  // The element data went back with the state: the body's energy is that of the committed one.
  CHECK(s.strain_energy() == energy);
}

}  // namespace

TEST_CASE("invariants: every element x plastic policy x elastic family", "[plasticity]") {
  invariants<Hex8, Linear, VertexBlended>();
  invariants<Hex8, Linear, CellCentered>();
  invariants<Hex8, Corotational, VertexBlended>();
  invariants<Hex8, Corotational, CellCentered>();
  invariants<Hex8, CorotationalPerElement, VertexBlended>();
  invariants<Hex8, CorotationalPerElement, CellCentered>();
  invariants<Hex8, NeoHookean, VertexBlended>();
  invariants<Hex8, NeoHookean, CellCentered>();
  invariants<Hex8, CorotationalMeanDilatation, VertexBlended>();
  invariants<Hex8, NeoHookeanMeanDilatation, CellCentered>();
  invariants<Tet4, Linear, VertexBlended>();
  invariants<Tet4, Linear, CellCentered>();
  invariants<Tet4, Corotational, VertexBlended>();
  invariants<Tet4, Corotational, CellCentered>();
  invariants<Tet4, CorotationalPerElement, VertexBlended>();
  invariants<Tet4, CorotationalPerElement, CellCentered>();
  invariants<Tet4, NeoHookean, VertexBlended>();
  invariants<Tet4, NeoHookean, CellCentered>();
  invariants<Tet10, Linear, VertexBlended>();
  invariants<Tet10, Linear, CellCentered>();
  invariants<Tet10, Corotational, VertexBlended>();
  invariants<Tet10, Corotational, CellCentered>();
  invariants<Tet10, CorotationalPerElement, VertexBlended>();
  invariants<Tet10, CorotationalPerElement, CellCentered>();
  invariants<Tet10, NeoHookean, VertexBlended>();
  invariants<Tet10, NeoHookean, CellCentered>();
}

// --- the stretch and twist scenes (SCENES.md, seed 000 Fig. 5-6) -----------------------------------

namespace {

/// The residual (material) displacement of the end face's centre after the stretch scene.
template <class S>
Scalar material_tip(const S& s) {
  const auto& mesh = s.mesh();
  const Vec3 X = mesh.nodes().rowwise().maxCoeff();
  Scalar best = 1e300;
  Index tip = 0;
  for (Index i = 0; i < mesh.num_nodes(); ++i)
    if (const Scalar d = (Vec3(mesh.node(i)) - Vec3(X.x(), 0.5 * X.y(), 0.5 * X.z())).norm(); d < best) best = d, tip = i;
  return s.material_positions()(0, tip) - mesh.node(tip).x();
}

}  // namespace

TEST_CASE("stretch: residual deformation grows with the load and with the flow rate - volume kept", "[plasticity]") {
  // bar90 Hex8 Corotational vertex-blended, the paper's first parameter set, 2 s (load and hold).
  Scalar previous = 0;
  for (Scalar force : {250.0, 300.0, 350.0, 400.0}) {
    const auto s = stretch<Hex8, Corotational, VertexBlended>(10, 3, 3, force, stretch_params(1000, 0.4), 2.0);
    const Scalar tip = material_tip(s);
    INFO("force " << force << ": material tip " << tip);
    CHECK(tip > previous);
    previous = tip;
  }
  CHECK(previous > 0.02);  // a visible plastic stretch at the paper's load (0.03 measured)
  previous = 0;
  for (Scalar rate : {0.1, 0.2, 0.4, 0.8}) {
    const auto s = stretch<Hex8, Corotational, VertexBlended>(10, 3, 3, 350, stretch_params(1000, rate), 2.0);
    const Scalar tip = material_tip(s);
    INFO("flow rate " << rate << ": material tip " << tip);
    CHECK(tip > previous);
    previous = tip;
    const Mesh<Hex8>& mesh = s.mesh();
    CHECK(std::abs(material_volume(mesh, s.material_positions()) / 90 - 1) < 1e-3);
    CHECK(std::abs(s.volume() / 90 - 1) < 1e-2);
  }
}

TEST_CASE("stretch: the plastic state does not depend on how closely Newton converged", "[plasticity]") {
  // The flow runs once per converged step from the committed state: tolerances 1e-6 and 1e-10
  // give plastic states that differ by the tolerance's order, not by the flow itself.
  auto run = [](Scalar tol) {
    SolverSettings st;
    st.newton.residual_tolerance = tol;
    st.linear.tolerance = std::min(1e-8, tol);
    return stretch<Hex8, Corotational, VertexBlended>(10, 3, 3, 350, stretch_params(1000, 0.4), 1.5, st);
  };
  const auto loose = run(1e-6), tight = run(1e-10);
  const Scalar flow = max_rest_change(tight);
  const Scalar diff = (loose.material_positions() - tight.material_positions()).cwiseAbs().maxCoeff();
  INFO("rest change " << flow << ", difference between tolerances " << diff);
  CHECK(flow > 1e-2);
  CHECK(diff < 1e-5 * flow / 1e-2);  // ~1e-6 relative of the motion, not the flow's size
  for (size_t k = 0; k < tight.state().plastic.tau.size(); ++k)
    CHECK(std::abs(loose.state().plastic.tau[k] - tight.state().plastic.tau[k]) <= 1e-3);
}

TEST_CASE("stretch: mirror symmetry of the cross-section to 1e-8", "[plasticity]") {
  // Hex8 bar90 is symmetric about y = 1.5 and z = 1.5, and so is the load at the face centre.
  // (The Kuhn split of Tet4/Tet10 is not: the paper's point about tetrahedra.)
  auto check = [](const auto& s) {
    const auto& mesh = s.mesh();
    const Eigen::Matrix3Xd x = s.positions(), m = s.material_positions();
    Scalar worst = 0, scale = 0;
    for (Index i = 0; i < mesh.num_nodes(); ++i) {
      const Vec3 p = mesh.node(i);
      for (int axis : {1, 2}) {
        Vec3 q = p;
        q[axis] = 3 - p[axis];
        const auto j = locate_point(mesh, q);
        Index mirror = -1;
        for (Index k = 0; k < mesh.num_nodes(); ++k)
          if ((Vec3(mesh.node(k)) - q).norm() < 1e-12) mirror = k;
        REQUIRE(mirror >= 0);
        (void)j;
        for (const Eigen::Matrix3Xd* f : {&x, &m}) {
          Vec3 a = f->col(i), b = f->col(mirror);
          b[axis] = 3 - b[axis];
          worst = std::max(worst, (a - b).norm());
        }
      }
      scale = std::max(scale, (x.col(i) - p).norm());
    }
    INFO("largest mirror mismatch " << worst << " of a displacement " << scale);
    CHECK(worst <= 1e-8 * scale);
  };
  PlasticParams p = stretch_params(1000, 0.4);
  p.rotation_yield = 0.01;
  p.rotation_flow_rate = 0.5;
  check(stretch<Hex8, Corotational, VertexBlended>(10, 3, 3, 350, p, 3.0));
  check(stretch<Hex8, Corotational, CellCentered>(10, 3, 3, 350, p, 3.0));
  check(stretch<Hex8, NeoHookean, VertexBlended>(10, 3, 3, 1000, stretch_params(1500, 0.25, 25), 3.0));
}

TEST_CASE("hardening: a second identical load cycle adds less plastic deformation than the first", "[plasticity]") {
  // Quasi-static cycles (static solves, so that no vibration of the first cycle is left over
  // into the second): load in 10 increments, unload. Isotropic hardening raises tau by kappa
  // gamma |s| wherever the material flowed: the second cycle flows less; the stronger the
  // hardening, the less.
  const Mesh<Hex8> mesh = bar_mesh<Hex8>(10, 3, 3);
  auto cycles = [&](Scalar kappa) {
    PlasticParams p = stretch_params(1000, 0.4);
    p.hardening = kappa;
    Solver<Hex8, Corotational, VertexBlended> s(mesh, soft, {}, p);
    s.fix(mesh.node_set("xmin"));
    std::vector<Scalar> tips{0};
    for (int cycle = 0; cycle < 2; ++cycle) {
      const LoadHandle h = s.add_traction(mesh.face_set("xmax"), Vec3(350.0 / 9, 0, 0));
      s.solve_static(10);
      s.remove_load(h);
      s.solve_static();
      tips.push_back(material_tip(s));
    }
    return std::pair{tips[1] - tips[0], tips[2] - tips[1]};
  };
  const auto [first, second] = cycles(0.2);
  const auto [first_hard, second_hard] = cycles(5);
  INFO("plastic tip displacement, kappa = 0.2: first cycle " << first << ", second " << second << "; kappa = 5: "
                                                              << first_hard << ", " << second_hard);
  CHECK(first > 0.002);  // 0.0049 measured
  CHECK(second < first);
  CHECK(second > 0);
  CHECK(second_hard / first_hard < second / first);
}

TEST_CASE("twist beyond pi: no inverted element, no remeshing, volume kept", "[plasticity]") {
  // The end face turned by 1.2 pi about the bar's axis in 1 s, held, released; rotational
  // plasticity on. Every step: every element of the current configuration and of the
  // material mesh has a positive Jacobian everywhere.
  auto run = [](auto tag) {
    using P = decltype(tag);
    const Mesh<Hex8> mesh = bar_mesh<Hex8>(10, 3, 3);
    PlasticParams p = stretch_params(1000, 0.4);
    p.rotation_yield = 0.02;
    p.rotation_flow_rate = 1;
    SolverSettings st;
    st.rayleigh_mass = 1;
    Solver<Hex8, Corotational, P> s(mesh, soft, st, p);
    s.fix(mesh.node_set("xmin"));
    const Scalar turn = 1.2 * pi;
    const ConstraintHandle h = s.prescribe(mesh.node_set("xmax"), [turn](Scalar t, const Vec3& X) {
      const Vec3 c(X.x(), 1.5, 1.5);
      return Vec3(rotation_about(Vec3(1, 0, 0), turn * std::min(t, 1.0)) * (X - c) + c - X);
    });
    Scalar worst = 1;
    int rotations = 0;
    for (int k = 0; k < 300; ++k) {
      if (k == 150) s.release(h);
      rotations += s.step(0.01).plastic.rotations_yielded;
      const Eigen::Matrix3Xd x = s.positions(), m = s.material_positions();
      for (Index e = 0; e < mesh.num_elements(); ++e) {
        ElementNodes<Hex8> xe, me;
        for (int a = 0; a < 8; ++a) xe.col(a) = x.col(mesh.element(e)[a]), me.col(a) = m.col(mesh.element(e)[a]);
        worst = std::min({worst, check_shape<Hex8>(xe).min_scaled_jacobian, check_shape<Hex8>(me).min_scaled_jacobian});
      }
    }
    INFO(P::name << ": smallest scaled Jacobian " << worst << ", vertex rotations flowed " << rotations);
    CHECK(worst > 0.05);
    CHECK(rotations > 0);
    CHECK(std::abs(material_volume(mesh, s.material_positions()) / 90 - 1) < 1e-2);
    CHECK(std::abs(s.volume() / 90 - 1) < 1e-2);
  };
  run(VertexBlended{});
  run(CellCentered{});
}

TEST_CASE("bending: plastic rotation keeps a bend, a plastic stretch alone barely does", "[plasticity]") {
  // bar90 bent by a downward traction on its end face (60 in all; ramped over 0.5 s, held to
  // 1.5 s, released, 0.5 s more): the tip goes down by ~0.95. A bend is a turn of each element
  // against its neighbours. The plastic stretch gives the elements trapezoid rest shapes, but
  // the fusion into one material mesh moves element shapes by translation only (fusion.hpp),
  // and unturned trapezoids do not chain into a curve; the plastic rotation (eq. 5-6) turns
  // them. Measured: material tip -0.0043 with stretch plasticity only, -0.094 (vertex-blended)
  // and -0.111 (cell-centered) with rotation yield 0.001 rad and rate 0.5 (docs/plasticity.md).
  // Asserted: a downward material bend of at least 0.05 and 10 times the stretch-only one.
  const Mesh<Hex8> mesh = bar_mesh<Hex8>(10, 3, 3);
  auto material_tip = [&](auto tag, bool rotation) {
    using P = decltype(tag);
    PlasticParams p = stretch_params(1000, 0.4);
    if (rotation) p.rotation_yield = 0.001, p.rotation_flow_rate = 0.5;
    SolverSettings st;
    st.rayleigh_mass = 1;
    Solver<Hex8, Corotational, P> s(mesh, soft, st, p);
    s.fix(mesh.node_set("xmin"));
    s.add_traction(mesh.face_set("xmax"), Vec3(0, 0, -60.0 / 9), ramp_hold_release(0.5, 1.5));
    int rotations = 0;
    for (int k = 0; k < 200; ++k) rotations += s.step(0.01).plastic.rotations_yielded;
    const Eigen::Matrix3Xd m = s.material_positions();
    Scalar tip = 0;
    for (Index i : mesh.node_set("xmax")) tip += m(2, i) - mesh.node(i).z();
    tip /= static_cast<Scalar>(mesh.node_set("xmax").size());
    INFO(P::name << (rotation ? " with" : " without") << " plastic rotation: material tip " << tip
                 << ", vertex rotations flowed " << rotations);
    CHECK(std::abs(material_volume(mesh, m) / 90 - 1) < 1e-2);
    CHECK((rotations > 0) == rotation);
    return tip;
  };
  for (int policy = 0; policy < 2; ++policy) {
    const Scalar stretch_only = policy ? material_tip(CellCentered{}, false) : material_tip(VertexBlended{}, false);
    const Scalar rotated = policy ? material_tip(CellCentered{}, true) : material_tip(VertexBlended{}, true);
    INFO((policy ? "CellCentered" : "VertexBlended") << ": material tip " << stretch_only << " without, " << rotated
                                                      << " with plastic rotation");
    CHECK(rotated < -0.05);
    CHECK(rotated < 10 * std::min(stretch_only, Scalar(0)) - 1e-12);
  }
}

TEST_CASE("statics: the plastic state is carried from increment to increment", "[plasticity]") {
  // A static pull in one increment and in four: the flow after each increment depends on the
  // path; both leave the body in equilibrium with its new rest shapes. Unloading afterwards
  // continues from that state and keeps the plastic stretch.
  const Mesh<Hex8> mesh = bar_mesh<Hex8>(10, 3, 3);
  auto pull = [&](int increments) {
    Solver<Hex8, Corotational, VertexBlended> s(mesh, soft, {}, stretch_params(1000, 0.4));
    s.fix(mesh.node_set("xmin"));
    const LoadHandle h = s.add_traction(mesh.face_set("xmax"), Vec3(350.0 / 9, 0, 0));
    const StepReport r = s.solve_static(increments);
    CHECK(r.plastic.points_yielded > 0);
    CHECK(r.relative_residual <= 1e-6);
    const Scalar loaded = material_tip(s);
    s.remove_load(h);
    s.solve_static();
    // Unloaded, the body keeps the plastic stretch and sits near its material mesh (not on it:
    // the clamp holds the x = 0 face where the material mesh would contract).
    const Scalar unloaded = material_tip(s);
    CHECK(unloaded >= loaded);
    CHECK(unloaded < 1.2 * loaded);
    return loaded;
  };
  const Scalar one = pull(1), four = pull(4);
  INFO("plastic tip displacement: 1 increment " << one << ", 4 increments " << four);
  CHECK(one > 0);
  CHECK(four > 0);
  CHECK(std::abs(one - four) > 1e-6 * one);  // path dependent
}

TEST_CASE("statics: a body settled after plastic flow is accepted by a second and third solve and the next step",
          "[plasticity][statics]") {
  // Issue 33 item 4, plastic: a 2 x 2 x 2 box of Kuhn Tet4 unit cells, clamped at x = 0 and
  // pulled by 0.2 at x = 1 (prescribed displacements only, no load), yields in the first solve
  // (tau 10 against stresses ~ 300): the flow moves the rest shapes off the integer nodes, the
  // state is brought back to equilibrium, and the free internal forces that remain (the statics
  // scale of any later solve) are the residual's round-off. The floor, measured once at the
  // original rest shape, where the Tet4 kernels are exact, was 0: the second solve failed at
  // |r| ~ 1e-11 ("did not converge").
  const Mesh<Tet4> mesh = box_tet4_kuhn({2, 2, 2});
  PlasticParams prm;
  prm.yield_stress = 10;
  Solver<Tet4, Corotational, VertexBlended> s(mesh, soft, {}, prm);
  s.fix(mesh.node_set("xmin"));
  s.prescribe(mesh.node_set("xmax"), [](Scalar, const Vec3&) { return Vec3(0.2, 0, 0); });
  auto attempt = [&](const char* what, const auto& run) {
    try {
      const StepReport r = run();
      fmt::print("settled plastic Tet4 box: {} {} Newton it., |r| = {:.3g}, {} points yielded\n", what,
                 r.newton_iterations, r.residual, r.plastic.points_yielded);
      return r;
    } catch (const Error& e) {
      FAIL_CHECK(what << " failed: " << e.what());
    }
    return StepReport{};
  };
  const StepReport first = attempt("solve 1", [&] { return s.solve_static(); });
  REQUIRE(first.plastic.points_yielded > 0);  // the rest shapes moved
  const Vector u1 = s.displacement();
  attempt("solve 2", [&] { return s.solve_static(); });
  attempt("solve 3", [&] { return s.solve_static(); });
  // Each solve flows on (the held pull keeps the body above yield) and ends in equilibrium with
  // its new rest shapes; the step starts there at rest, so its Newton correction is that of a
  // round-off residual, |A^-1 r| ~ 1e-11 / 3000, nowhere near 1e-10 of |u| ~ 0.6 (the flow
  // after the step moves the rest shapes, not u).
  const Vector u3 = s.displacement();
  attempt("step", [&] { return s.step(0.01); });
  CHECK(s.displacement().allFinite());
  CHECK((s.displacement() - u3).norm() <= 1e-10 * u3.norm());
  CHECK((u3 - u1).norm() > 0);  // (the later solves did flow: they were not no-ops)
}

TEST_CASE("plastic parameters: a stress_scale whose scaled stress squares past the largest double is refused",
          "[plasticity]") {
  // Issue 33 item 5a: stress_scale = 1e300 was accepted; the yield test squares stress_scale x
  // the stress, (1e300 x 2 mu x strain)^2 = inf, so every point "yielded" with gamma = NaN -> 0
  // and nothing flowed. The bound 1e100 keeps (stress_scale x stress)^2 finite for any stress
  // below 1e50 in the user's units (1.8e308 is the largest double), far above any material's.
  const Mesh<Hex8> mesh = bar_mesh<Hex8>(2, 1, 1);
  for (const Scalar scale : {1e300, 1e101, std::numeric_limits<Scalar>::max()}) {
    PlasticParams p;
    p.stress_scale = scale;
    try {
      Solver<Hex8, Corotational, VertexBlended> s(mesh, soft, {}, p);
      FAIL_CHECK("stress_scale = " << scale << " accepted");
    } catch (const InvalidArgument& e) {
      fmt::print("stress_scale = {:g} refused: {}\n", scale, e.what());
      CHECK(std::string(e.what()).find("stress_scale") != std::string::npos);
    }
  }
  // Mid-run too, leaving the parameters as they were.
  Solver<Hex8, Corotational, VertexBlended> s(mesh, soft);
  PlasticParams bad;
  bad.stress_scale = 1e300;
  CHECK_THROWS_AS(s.set_plastic_params(bad), InvalidArgument);
  CHECK(s.plastic_params().stress_scale == PlasticParams{}.stress_scale);
  // The bound itself is usable: at stress_scale 1e100 a loaded bar yields with a finite gamma,
  // nu dt (|s| - tau) / |s| = nu dt = 0.002, since |s| ~ 1e100 x 2 mu x strain dwarfs tau = 1000.
  PlasticParams big;
  big.stress_scale = 1e100;
  Solver<Hex8, Corotational, VertexBlended> b(mesh, soft, {}, big);
  b.fix(mesh.node_set("xmin"));
  b.add_traction(mesh.face_set("xmax"), Vec3(30, 0, 0));
  const StepReport r = b.step(0.01);
  fmt::print("stress_scale = 1e100: {} points yielded, max gamma {:.3g}\n", r.plastic.points_yielded, r.plastic.max_gamma);
  CHECK(r.plastic.points_yielded > 0);
  CHECK(r.plastic.max_gamma == Approx(0.2 * 0.01).epsilon(1e-9));
  CHECK(b.displacement().allFinite());
}

TEST_CASE("real-time mode and the lumped mass run plasticity too", "[plasticity]") {
  for (auto mode : {NewmarkMode::Accurate, NewmarkMode::RealTime})
    for (auto mass : {MassKind::Consistent, MassKind::Lumped}) {
      SolverSettings st;
      st.newmark.mode = mode;
      st.mass = mass;
      const auto s = stretch<Hex8, CorotationalPerElement, CellCentered>(10, 3, 3, 350, stretch_params(1000, 0.4), 3.0, st);
      const auto r = stretch<Hex8, Corotational, VertexBlended>(10, 3, 3, 350, stretch_params(1000, 0.4), 3.0, st);
      const Scalar tip = material_tip(s), tip_r = material_tip(r);
      INFO("mode " << int(mode) << " mass " << int(mass) << ": material tips " << tip << ", " << tip_r);
      CHECK(tip > 0.01);
      CHECK(tip_r > 0.01);
      CHECK(std::abs(s.volume() / 90 - 1) < 1e-2);
      CHECK(s.displacement().allFinite());
    }
}

#ifdef _OPENMP
TEST_CASE("threads: a plastic run on two threads is bit for bit the run on one", "[plasticity][threads]") {
  // bar90: below the size from which matrix-vector products are threaded, so every loop of a
  // step sums in the same order whatever the thread count: the elements, the plastic update
  // (one flow per element; the checks and volumes of the fused shapes, each element's verdict
  // gathered in element order) and the re-preparation of the changed elements' data (each
  // element into its own entry, in parallel since the sync went parallel).
  SolverSettings one, two;
  one.threads = 1;
  two.threads = 2;
  auto check = [&](auto a, auto b) {
    using E = typename decltype(a)::Element;
    REQUIRE(Assembler<E>(a.mesh()).pattern()->num_blocks() <= 3000);
    INFO(E::name);
    CHECK(max_rest_change(a) > 0.01);  // it flowed, and every flowing step re-prepared elements
    CHECK((a.displacement().array() == b.displacement().array()).all());
    CHECK((a.velocity().array() == b.velocity().array()).all());
    CHECK((a.material_positions().array() == b.material_positions().array()).all());
  };
  check(stretch<Hex8, Corotational, VertexBlended>(10, 3, 3, 350, stretch_params(1000, 0.4), 2.5, one),
        stretch<Hex8, Corotational, VertexBlended>(10, 3, 3, 350, stretch_params(1000, 0.4), 2.5, two));
  check(stretch<Tet4, NeoHookean, CellCentered>(10, 3, 3, 1000, stretch_params(1500, 0.25, 25), 2.5, one),
        stretch<Tet4, NeoHookean, CellCentered>(10, 3, 3, 1000, stretch_params(1500, 0.25, 25), 2.5, two));
}
#endif

TEST_CASE("safeguard: plasticity is switched off before an element degenerates", "[plasticity]") {
  // Full flow (rate 1, dt 0.5, tau 0: gamma = 0.5 per step) under a crushing load: the
  // elements flatten step by step; each one's plasticity is switched off once its shape
  // quality would fall below 90% of the original (min_rest_quality), and every rest shape
  // stays valid.
  const Mesh<Hex8> mesh = bar_mesh<Hex8>(4, 1, 1);
  PlasticParams p = stretch_params(0, 1, 1);
  p.hardening = 0;
  p.min_rest_quality = 0.9;  // switched off once an element loses 10% of its shape quality
  Solver<Hex8, NeoHookean, VertexBlended> s(mesh, soft, {}, p);
  s.fix(mesh.node_set("xmin"));
  s.add_nodal_force(mesh.node_set("xmax"), Vec3(-150, 0, 0));
  int off = 0;
  for (int k = 0; k < 20; ++k) {
    try {
      off += s.step(0.5).plastic.switched_off;
    } catch (const SolverError&) {
      break;  // crushed beyond what the elastic model holds: the state stays valid
    }
  }
  const Eigen::Matrix3Xd m = s.material_positions();
  for (Index e = 0; e < mesh.num_elements(); ++e) {
    ElementNodes<Hex8> me;
    for (int a = 0; a < 8; ++a) me.col(a) = m.col(mesh.element(e)[a]);
    CHECK(check_shape<Hex8>(me).min_scaled_jacobian > 0.85);
  }
  int flagged = 0;
  for (auto f : s.state().plastic.off) flagged += f;
  INFO("switched off: " << off << " (flags " << flagged << ")");
  CHECK(off > 0);
  CHECK(flagged == off);
}

TEST_CASE("safeguard: a rejected update keeps its switch-offs, so creep goes on and the stop is reported",
          "[plasticity]") {
  // Issue 33 item 2. Creep of bar90 under gravity (yield 0, rate 1, no hardening): from step
  // 1028 on every update was rejected, because a switched-off element's rest shape was still
  // moved by its neighbours' flow and failed the shape check, and the switch-off was dropped
  // with the update: 3973 of the last 3973 updates rejected, the body silently elastic. Now a
  // switched-off element keeps its last rest shape (its nodes are held in the fusion), and a
  // rejected update's switch-offs stay.
  const Mesh<Hex8> mesh = bar_mesh<Hex8>(10, 3, 3);
  PlasticParams p;
  p.yield_stress = 0;
  p.flow_rate = 1;
  p.hardening = 0;
  SolverSettings st;
  st.rayleigh_mass = 0.2;
  Solver<Hex8, Corotational, VertexBlended> s(mesh, Material{3000, 0.45, 1.0}, st, p);
  s.fix(mesh.node_set("xmin"));
  s.add_gravity(Vec3(0, 0, -9.81));
  std::vector<std::string> notes;
  const NoteHandler previous = set_note_handler([&](const std::string& n) { notes.push_back(n); });
  const Index tip = mesh.node_set("xmax")[0];
  int rejected = 0, in_a_row = 0, worst_in_a_row = 0, switched_off = 0, last_off = 0;
  Scalar tip_at_1000 = 0;
  for (int k = 1; k <= 1500; ++k) {
    const PlasticReport r = s.step(0.01).plastic;
    rejected += r.updates_rejected;
    switched_off += r.switched_off;
    in_a_row = r.updates_rejected ? in_a_row + 1 : 0;
    worst_in_a_row = std::max(worst_in_a_row, in_a_row);
    last_off = r.elements_off;
    if (k == 1000) tip_at_1000 = s.material_positions()(2, tip);
  }
  set_note_handler(previous);
  const Scalar creep = tip_at_1000 - s.material_positions()(2, tip);
  int flagged = 0;
  for (auto f : s.state().plastic.off) flagged += f == PlasticTable::switched_off;
  INFO("updates rejected " << rejected << " (at most " << worst_in_a_row << " in a row), elements switched off "
                           << switched_off << ", material tip sank " << creep << " over steps 1000-1500, notes "
                           << notes.size());
  CHECK(worst_in_a_row <= 1);   // a rejection makes progress: the next update runs without the culprits
  CHECK(creep > 0.03);          // measured 0.073 (before the fix it rose by 0.003: the flow had stopped at step 1028)
  CHECK(switched_off == flagged);
  CHECK(last_off == flagged);
  CHECK(flagged > 0);
  // Every switch-off was announced, with the count of elements that no longer flow.
  REQUIRE_FALSE(notes.empty());
  CHECK(notes.back().find(fmt::format("{} of 90 elements no longer flow", flagged)) != std::string::npos);
  // Switched-off elements keep their rest shapes from then on: none degenerates.
  const Eigen::Matrix3Xd m = s.material_positions();
  for (Index e = 0; e < mesh.num_elements(); ++e) {
    ElementNodes<Hex8> me;
    for (int a = 0; a < 8; ++a) me.col(a) = m.col(mesh.element(e)[a]);
    CHECK(check_shape<Hex8>(me).min_scaled_jacobian > 0);
  }
}

TEST_CASE("plastic rotation: a superposed rigid rotation leaves the permanent set as it was (Tissue frame)",
          "[plasticity]") {
  // Issue 33 item 1. bar90 twisted by 0.8 rad over 1 s and held (every node prescribed, so the
  // two runs differ by the rigid rotation alone, not by their dynamics), once as is and once
  // turned as a whole at 0.5 rad/s about its axis. The flow takes a power of each rotation
  // relative to the tissue's rigid frame, which the turn cancels: the two material meshes
  // agree up to a rigid motion to round-off (measured 1e-14 and 2e-14 of a permanent twist
  // of 0.27). The paper's rule (World frame) takes a power of the absolute rotation: measured
  // 4.4e-3 apart.
  const Mesh<Hex8> mesh = bar_mesh<Hex8>(10, 3, 3);
  std::vector<Index> all(static_cast<size_t>(mesh.num_nodes()));
  for (Index i = 0; i < mesh.num_nodes(); ++i) all[static_cast<size_t>(i)] = i;
  auto run = [&](auto tag, PlasticParams::RotationFrame frame, Scalar omega) {
    using P = decltype(tag);
    PlasticParams p;
    p.yield_stress = std::numeric_limits<Scalar>::infinity();  // rotation only
    p.rotation_yield = 0.001, p.rotation_flow_rate = 0.5, p.rotation_frame = frame;
    Solver<Hex8, Corotational, P> s(mesh, soft, {}, p);
    s.prescribe(all, [omega](Scalar t, const Vec3& X) {
      const Vec3 axis(0, 1.5, 1.5), c(X.x(), 1.5, 1.5);
      const Vec3 twisted = rotation_about(Vec3(1, 0, 0), 0.8 * std::min(t, 1.0) * X.x() / 10) * (X - c) + c;
      return Vec3(rotation_about(Vec3(1, 0, 0), omega * t) * (twisted - axis) + axis - X);
    });
    int rotations = 0;
    for (int k = 0; k < 150; ++k) rotations += s.step(0.01).plastic.rotations_yielded;
    CHECK(rotations > 0);
    return Eigen::Matrix3Xd(s.material_positions());
  };
  using F = PlasticParams::RotationFrame;
  auto both = [&](auto tag) {
    const Eigen::Matrix3Xd tissue = run(tag, F::Tissue, 0), tissue_turned = run(tag, F::Tissue, 0.5);
    const Eigen::Matrix3Xd world = run(tag, F::World, 0), world_turned = run(tag, F::World, 0.5);
    const Scalar set = rigid_fit(mesh.nodes(), tissue).non_rigid;
    const Scalar tissue_diff = rigid_fit(tissue, tissue_turned).non_rigid;
    const Scalar world_diff = rigid_fit(world, world_turned).non_rigid;
    INFO(decltype(tag)::name << ": permanent set " << set << "; turned against unturned: Tissue frame " << tissue_diff
                             << ", World frame " << world_diff);
    CHECK(set > 0.1);
    CHECK(tissue_diff <= 1e-10 * set);  // 150 steps of rotations composed: round-off
    CHECK(world_diff > 1e-3);
  };
  both(VertexBlended{});
  both(CellCentered{});
}

TEST_CASE("plastic rotation: a free body spinning does not turn its material mesh (Tissue frame)", "[plasticity]") {
  // Issue 33 item 1: a free bar90 spinning at 2 rad/s about its axis, no load, plastic rotation
  // on (yield 1e-4 rad, rate 1). The paper's rule turned its material mesh by 2.78 rad
  // (vertex-blended) and 2.75 rad (cell-centered) in 3 s. In the Tissue frame it is not turned;
  // what flows is the centrifugal distortion's own rotation (relative vertex rotations ~1e-3,
  // above the yield): 4.7e-5 and 5.0e-5 of non-rigid change, against 3.7e-2 and 6.5e-2.
  const Mesh<Hex8> mesh = bar_mesh<Hex8>(10, 3, 3);
  auto run = [&](auto tag, PlasticParams::RotationFrame frame) {
    using P = decltype(tag);
    PlasticParams p;
    p.yield_stress = std::numeric_limits<Scalar>::infinity();
    p.rotation_yield = 1e-4, p.rotation_flow_rate = 1, p.rotation_frame = frame;
    Solver<Hex8, Corotational, P> s(mesh, soft, {}, p);
    Vector v(s.num_dofs());
    for (Index i = 0; i < mesh.num_nodes(); ++i) v.segment<3>(3 * i) = Vec3(2, 0, 0).cross(mesh.node(i) - Vec3(5, 1.5, 1.5));
    s.set_state(Vector::Zero(s.num_dofs()), v);
    for (int k = 0; k < 300; ++k) s.step(0.01);
    return rigid_fit(mesh.nodes(), s.material_positions());
  };
  using F = PlasticParams::RotationFrame;
  auto both = [&](auto tag) {
    const RigidFit tissue = run(tag, F::Tissue), world = run(tag, F::World);
    INFO(decltype(tag)::name << ": material mesh turned " << tissue.angle << " rad, non-rigid " << tissue.non_rigid
                             << " (World frame: " << world.angle << " rad, " << world.non_rigid << ")");
    CHECK(world.angle > 1);
    CHECK(tissue.angle < 1e-6);
    CHECK(tissue.non_rigid < 0.01 * world.non_rigid);
  };
  both(VertexBlended{});
  both(CellCentered{});
}

TEST_CASE("inverted elements do not flow, and are counted", "[plasticity]") {
  // Issue 33 item 3: the corotational stress is defined on an inverted element, so the flow ran
  // there (up to 37 of 90 elements committed inverted and flowing, undefined_points 0). An
  // interior node of bar90 pushed through its neighbours inverts the elements around it; one
  // short step later they are still inverted. Flow everywhere else (yield 0, hardening 0.2):
  // every element that is not inverted hardens, no inverted one does, and the report counts
  // them.
  const Mesh<Hex8> mesh = bar_mesh<Hex8>(10, 3, 3);
  auto run = [&](auto tag) {
    using P = decltype(tag);
    PlasticParams p = stretch_params(0, 1, 1);
    Solver<Hex8, Corotational, P> s(mesh, soft, {}, p);
    s.fix(mesh.node_set("xmin"));
    Index pushed = 0;
    for (Index i = 1; i < mesh.num_nodes(); ++i)
      if ((mesh.node(i) - Vec3(5, 1, 1)).norm() < (mesh.node(pushed) - Vec3(5, 1, 1)).norm()) pushed = i;
    Vector u = Vector::Zero(s.num_dofs());
    u.segment<3>(3 * pushed) = Vec3(1.6, 1.6, 1.6);
    s.set_state(u, Vector::Zero(s.num_dofs()));
    const std::vector<Scalar> tau0 = s.state().plastic.tau;
    const PlasticReport r = s.step(1e-4).plastic;
    const auto& tau = s.state().plastic.tau;
    const size_t per = tau.size() / static_cast<size_t>(mesh.num_elements());
    int inverted = 0, inverted_hardened = 0, others_hardened = 0;
    const Eigen::Matrix3Xd x = s.positions();
    for (Index e = 0; e < mesh.num_elements(); ++e) {
      ElementNodes<Hex8> xe;
      for (int a = 0; a < 8; ++a) xe.col(a) = x.col(mesh.element(e)[a]);
      const bool inv = !(check_shape<Hex8>(xe).min_scaled_jacobian > 0);
      bool hardened = false;
      for (size_t q = 0; q < per; ++q) hardened = hardened || tau[e * per + q] != tau0[e * per + q];
      inverted += inv;
      (inv ? inverted_hardened : others_hardened) += hardened;
    }
    INFO(P::name << ": inverted " << inverted << " (reported " << r.inverted_elements << "), of them flowed "
                 << inverted_hardened << "; others flowed " << others_hardened);
    CHECK(inverted >= 4);
    CHECK(inverted_hardened == 0);
    CHECK(r.inverted_elements >= inverted);  // also those inverted only at a flow point
    CHECK(others_hardened > 0);
  };
  run(VertexBlended{});
  run(CellCentered{});
}
