// Hyperelastic models (NeoHookean, NeoHookeanAbaqus, StableNeoHookean) on Tet4, Tet10, Hex8:
// finite-difference consistency, closed-form uniaxial stretch, small-strain agreement with
// Linear, frame indifference, and the extremes (inversion, nu = 0.499, huge time steps).
#include "catch.hpp"

#include <plastifem/plastifem.hpp>

#include <fmt/core.h>

#include <random>

using namespace plastifem;

namespace {

const Material rubber{3000, 0.45, 1.0};

template <FiniteElement E>
ElementNodes<E> distorted_element(std::mt19937& rng) {
  std::uniform_real_distribution<Scalar> u(-0.1, 0.1);
  ElementNodes<E> X = E::reference_nodes();
  for (int a = 0; a < E::num_vertices; ++a) X.col(a) += Vec3(u(rng), u(rng), u(rng));
  if constexpr (std::is_same_v<E, Tet10>)
    for (int k = 0; k < 6; ++k) X.col(4 + k) = 0.5 * (X.col(E::edges[k][0]) + X.col(E::edges[k][1]));
  return X;
}

template <FiniteElement E>
ElementNodes<E> deformed(const ElementNodes<E>& X, Scalar delta, std::mt19937& rng) {
  std::uniform_real_distribution<Scalar> u(-delta, delta);
  Mat3 G;
  for (int i = 0; i < 9; ++i) G.data()[i] = u(rng);
  ElementNodes<E> x = (Mat3::Identity() + G) * X;  // a homogeneous part ...
  for (int a = 0; a < E::num_nodes; ++a) x.col(a) += 0.3 * Vec3(u(rng), u(rng), u(rng));  // ... and a random one
  return x;
}

Mat3 big_rotation() { return Eigen::AngleAxisd(1.1, Vec3(1, -2, 0.5).normalized()).toRotationMatrix(); }

}  // namespace


template <class E_, class M_>
struct Combo {
  using E = E_;
  using M = M_;
};
using AllHyper = std::tuple<Combo<Tet4, NeoHookean>, Combo<Tet10, NeoHookean>, Combo<Hex8, NeoHookean>,
                            Combo<Tet4, NeoHookeanAbaqus>, Combo<Tet10, NeoHookeanAbaqus>, Combo<Hex8, NeoHookeanAbaqus>,
                            Combo<Tet4, StableNeoHookean>, Combo<Tet10, StableNeoHookean>, Combo<Hex8, StableNeoHookean>,
                            Combo<Hex8, NeoHookeanMeanDilatation>, Combo<Hex8, NeoHookeanAbaqusMeanDilatation>,
                            Combo<Hex8, StableNeoHookeanMeanDilatation>>;

TEMPLATE_LIST_TEST_CASE("hyperelastic force = -dW/dx and tangent = df/dx (finite differences)", "[hyper][fd]", AllHyper) {
  using E = typename TestType::E;
  using M = typename TestType::M;
  std::mt19937 rng(5);
  for (int trial = 0; trial < 3; ++trial) {
    const ElementNodes<E> X = distorted_element<E>(rng);
    const auto d = M::template prepare<E>(X, rubber);
    // 15% homogeneous + 4.5% random nodal strain, rotated: large but not inverted. The FD
    // Jacobian is compared with the exact tangent; the projected one the solver uses is
    // checked below to be PSD and equal to it wherever the exact one is already PSD.
    const ElementNodes<E> x = big_rotation() * deformed<E>(X, 0.15, rng);
    ElementVector<E> f, fp, fm;
    ElementMatrix<E> K, Kp;
    M::template evaluate<E>(d, x, f, &K, M::TangentKind::Exact);
    M::template evaluate<E>(d, x, fp, &Kp);
    const auto ev = Eigen::SelfAdjointEigenSolver<ElementMatrix<E>>(Kp, Eigen::EigenvaluesOnly).eigenvalues();
    // PSD up to round-off of the sum of clamped point contributions (~eps |K|).
    REQUIRE(ev.minCoeff() >= -1e-12 * Kp.norm());
    if (Eigen::SelfAdjointEigenSolver<ElementMatrix<E>>(K, Eigen::EigenvaluesOnly).eigenvalues().minCoeff() >= 0 &&
        d.points.size == 1)
      REQUIRE((Kp - K).norm() <= 1e-12 * K.norm());  // one point: nothing was clamped
    // Central differences, h = 1e-6: truncation ~h^2 |W'''| ~ 1e-12, round-off ~eps |W| / h ~
    // 1e-10 relative: 1e-6 (the bound) has four decades of margin, and a wrong term
    // in P or A is O(1) relative.
    const Scalar h = 1e-6;
    ElementVector<E> grad;
    ElementMatrix<E> jac;
    for (int i = 0; i < 3 * E::num_nodes; ++i) {
      ElementNodes<E> xp = x, xm = x;
      xp.data()[i] += h;
      xm.data()[i] -= h;
      grad[i] = (M::template evaluate<E>(d, xp, fp, nullptr) - M::template evaluate<E>(d, xm, fm, nullptr)) / (2 * h);
      jac.col(i) = (fp - fm) / (2 * h);
    }
    INFO(E::name << " " << M::name << " trial " << trial);
    REQUIRE((grad - f).norm() <= 1e-6 * f.norm());
    REQUIRE((jac - K).norm() <= 1e-6 * K.norm());
    REQUIRE((K - K.transpose()).norm() <= 1e-12 * K.norm());
  }
}

TEMPLATE_LIST_TEST_CASE("hyperelastic: rest state, small strain = Linear, frame indifference", "[hyper]", AllHyper) {
  using E = typename TestType::E;
  using M = typename TestType::M;
  std::mt19937 rng(7);
  const ElementNodes<E> X = distorted_element<E>(rng);
  const auto d = M::template prepare<E>(X, rubber);
  const auto d0 = prepare_small_strain<E>(X, rubber);
  ElementVector<E> f, fl;
  ElementMatrix<E> K;
  // Rest: zero energy and force (to round-off), tangent = K0 (the linearisation is linear
  // elasticity; for Stable Neo-Hookean thanks to its Lame reparametrisation).
  // Exact tangent: for the mean-dilatation variants the per-point part alone (without the
  // element-level U'' term) is not PSD at rest, so its projection is only a fallback.
  const Scalar W0 = M::template evaluate<E>(d, X, f, &K, M::TangentKind::Exact);
  REQUIRE(std::abs(W0) <= 1e-12 * d0.K0.norm());
  REQUIRE(f.norm() <= 1e-12 * d0.K0.norm());
  if constexpr (M::volumetric == Volumetric::Full) {
    REQUIRE((K - d0.K0).norm() <= 1e-12 * d0.K0.norm());
  } else if constexpr (std::is_same_v<M, NeoHookeanAbaqusMeanDilatation>) {
    // Only the Abaqus form splits psi exactly into isochoric + U(J): its linearisation is the
    // B-bar (mean-dilatation) small-strain stiffness. The other two keep some volumetric
    // stiffness in their psi_dev (mu ln J, mu' ln(I1 + 1)), so they are only checked below.
    const auto dmd = prepare_small_strain<E>(X, rubber, Volumetric::MeanDilatation);
    REQUIRE((K - dmd.K0).norm() <= 1e-12 * dmd.K0.norm());
  }
  REQUIRE((K - K.transpose()).norm() <= 1e-12 * K.norm());
  // Small strain: the force is the rest tangent times u to relative O(delta) (for the full
  // variants the rest tangent is K0, checked above, so this is agreement with Linear).
  const Scalar delta = 1e-6;
  const ElementNodes<E> x = deformed<E>(X, delta, rng);
  M::template evaluate<E>(d, x, f, nullptr);
  fl = K * (Eigen::Map<const ElementVector<E>>(x.data()) - Eigen::Map<const ElementVector<E>>(X.data()));
  REQUIRE((f - fl).norm() <= 30 * delta * fl.norm());
  // Frame indifference: W(Qx) = W(x), f(Qx) = Q f(x).
  const ElementNodes<E> y = deformed<E>(X, 0.2, rng);
  ElementVector<E> fy, fq;
  const Scalar Wy = M::template evaluate<E>(d, y, fy, nullptr);
  const Mat3 Q = big_rotation();
  const Scalar Wq = M::template evaluate<E>(d, ElementNodes<E>(Q * y), fq, nullptr);
  REQUIRE(Wq == Approx(Wy).epsilon(1e-12));
  ElementVector<E> Qf;
  for (int a = 0; a < E::num_nodes; ++a) Qf.template segment<3>(3 * a) = Q * fy.template segment<3>(3 * a);
  REQUIRE((fq - Qf).norm() <= 1e-11 * fy.norm());
}

// ---- closed-form homogeneous uniaxial stretch ----------------------------------------------

namespace {

// Lateral stretch l2 with zero lateral stress for axial stretch l1, and the axial first
// Piola-Kirchhoff stress, from the energies' formulas written out for F = diag(l1, l2, l2).
struct Uniaxial {
  Scalar l2, P11;
};

template <class P22, class Pxx>
Uniaxial solve_uniaxial(P22 p22, Pxx p11) {
  // Bisection on P22(l2) = 0 over (0.3, 1.5): P22 increases with l2 for these energies.
  Scalar lo = 0.3, hi = 1.5;
  for (int k = 0; k < 200; ++k) {
    const Scalar mid = 0.5 * (lo + hi);
    (p22(mid) > 0 ? hi : lo) = mid;
  }
  const Scalar l2 = 0.5 * (lo + hi);
  return {l2, p11(l2)};
}

Uniaxial neo_hookean_uniaxial(Scalar l1, const Material& m) {
  const Scalar mu = m.mu(), la = m.lambda();
  auto P = [&](Scalar l2, Scalar li) { return mu * li + (la * std::log(l1 * l2 * l2) - mu) / li; };
  return solve_uniaxial([&](Scalar l2) { return P(l2, l2); }, [&](Scalar l2) { return P(l2, l1); });
}

Uniaxial abaqus_uniaxial(Scalar l1, const Material& m) {
  const Scalar C10 = m.mu() / 2, K = m.lambda() + 2 * m.mu() / 3;
  auto P = [&](Scalar l2, Scalar li) {
    const Scalar J = l1 * l2 * l2, I1 = l1 * l1 + 2 * l2 * l2, a = std::pow(J, -2.0 / 3.0);
    return 2 * C10 * a * (li - I1 / (3 * li)) + K * (J - 1) * J / li;
  };
  return solve_uniaxial([&](Scalar l2) { return P(l2, l2); }, [&](Scalar l2) { return P(l2, l1); });
}

template <class M>
void check_uniaxial(Scalar l1, const Uniaxial& exact) {
  // Unit cube of 2 x 2 x 2 Hex8: x = 0 face held in x only, x = 1 face pulled to l1, with
  // the rigid modes removed by symmetric pins; the exact answer is homogeneous, which the
  // trilinear space contains, so the discrete solution equals it up to solver tolerance.
  const auto mesh = box_hex8({2, 2, 2, Vec3(1, 1, 1)});
  SolverSettings s;
  s.newton.residual_tolerance = 1e-12;
  Solver<Hex8, M> solver(mesh, rubber, s);
  solver.fix(mesh.node_set("xmin"), {true, false, false});
  solver.prescribe(mesh.node_set("xmax"), [=](Scalar, const Vec3&) { return Vec3(l1 - 1, 0, 0); }, {true, false, false});
  solver.fix(mesh.node_set("ymin"), {false, true, false});
  solver.fix(mesh.node_set("zmin"), {false, false, true});
  solver.solve_static(4);
  // Lateral stretch from the node at (1, 1, 1): y = l2.
  Index corner = 0;
  for (Index i = 0; i < mesh.num_nodes(); ++i)
    if ((mesh.node(i) - Vec3(1, 1, 1)).norm() < 1e-12) corner = i;
  const Scalar l2 = 1 + solver.displacement(corner).y();
  // Axial force on the pulled face = P11 * reference area (1).
  const Vector R = solver.reaction_forces();
  Scalar Fx = 0;
  for (Index i : mesh.node_set("xmax")) Fx += R[3 * i];
  fmt::print("uniaxial {:16} l1 = {}: l2 {:.12f} (exact {:.12f}), P11 {:.10g} (exact {:.10g})\n", M::name, l1, l2,
             exact.l2, Fx, exact.P11);
  // Newton to 1e-12 relative and bisection to 1e-15: 1e-8 is the bound with margin.
  REQUIRE(l2 == Approx(exact.l2).epsilon(1e-8));
  REQUIRE(Fx == Approx(exact.P11).epsilon(1e-8));
}

}  // namespace

TEST_CASE("homogeneous uniaxial stretch matches the closed-form Neo-Hookean solution", "[hyper][uniaxial]") {
  for (Scalar l1 : {1.5, 0.7}) {
    check_uniaxial<NeoHookean>(l1, neo_hookean_uniaxial(l1, rubber));
    check_uniaxial<NeoHookeanAbaqus>(l1, abaqus_uniaxial(l1, rubber));
  }
}

// ---- extremes --------------------------------------------------------------------------------

TEST_CASE("Stable Neo-Hookean: an element pushed through inversion recovers its shape", "[hyper][inversion]") {
  // One Tet4 with its apex pushed through the opposite face (J < 0), then released: Newmark
  // with mass damping brings it back to the rest shape. (ln J Neo-Hookean cannot even start
  // there: its energy is undefined, which the next test checks gives a clear error.)
  const Mesh<Tet4> mesh(Tet4::reference_nodes(), {{0, 1, 2, 3}});
  SolverSettings s;
  s.rayleigh_mass = 5;
  Solver<Tet4, StableNeoHookean> solver(mesh, rubber, s);
  solver.fix(std::vector<Index>{0, 1, 2});
  Vector u = Vector::Zero(12);
  u[11] = -1.5;  // apex (0, 0, 1) -> (0, 0, -0.5): inverted
  solver.set_state(u, Vector::Zero(12));
  REQUIRE(solver.volume() < 0);
  for (int k = 0; k < 3000; ++k) solver.step(0.01);
  fmt::print("inverted Tet4 released: apex at {:.6f} after 30 s, volume {:.6f} (rest 1/6)\n",
             1 + solver.displacement(3).z(), solver.volume());
  REQUIRE(solver.displacement(3).norm() < 1e-6);  // back at rest (damped to ~e^-75)
  REQUIRE(solver.volume() == Approx(1.0 / 6).epsilon(1e-6));
}

TEST_CASE("ln J Neo-Hookean: an inverted start gives a clear error and an unchanged state", "[hyper][inversion]") {
  const Mesh<Tet4> mesh(Tet4::reference_nodes(), {{0, 1, 2, 3}});
  Solver<Tet4, NeoHookean> solver(mesh, rubber);
  solver.fix(std::vector<Index>{0, 1, 2});
  Vector u = Vector::Zero(12);
  u[11] = -1.5;
  solver.set_state(u, Vector::Zero(12));
  try {
    solver.step(0.01);
    FAIL("expected SolverError");
  } catch (const SolverError& e) {
    REQUIRE(std::string(e.what()).find("element 0 is inverted") != std::string::npos);
  }
  REQUIRE(solver.displacement() == u);
  REQUIRE(solver.time() == 0);
}

TEMPLATE_TEST_CASE("nearly incompressible (nu = 0.499) bending: no NaN, bounded Newton iterations, 100x dt stable",
                   "[hyper][extreme]", NeoHookean, StableNeoHookean) {
  using M = TestType;
  const auto mesh = bar_mesh<Hex8>(10, 3, 3);
  Solver<Hex8, M> solver(mesh, Material{3000, 0.499, 1.0});
  solver.fix(mesh.node_set("xmin"));
  solver.add_gravity(Vec3(0, 0, -9.81));
  int max_newton = 0;
  for (int k = 0; k < 50; ++k) max_newton = std::max(max_newton, solver.step(0.01).newton_iterations);
  const Scalar tip = solver.displacement(mesh.node_set("xmax").back()).z();
  fmt::print("{} nu = 0.499 bar90, 50 steps: tip uz {:.5f}, max Newton iterations {}\n", M::name, tip, max_newton);
  REQUIRE(solver.displacement().allFinite());
  REQUIRE(tip < 0);
  // Newton with the exact (projected) tangent: a handful per step; 20 would mean it is not
  // converging quadratically any more.
  REQUIRE(max_newton <= 20);
  // 100x the time step: the implicit step stays bounded (the bar cannot fall further than
  // its static deflection plus the dynamic overshoot, well under its length).
  // At such steps stiffness dominates the Newmark matrix and lambda / mu = 500 makes Jacobi-CG
  // crawl: this is where the direct solver earns its place.
  SolverSettings direct = solver.settings();
  direct.linear.kind = LinearSolverKind::Direct;
  solver.set_settings(direct);
  int max_newton_big = 0;
  for (int k = 0; k < 10; ++k) max_newton_big = std::max(max_newton_big, solver.step(1.0).newton_iterations);
  fmt::print("{} nu = 0.499 bar90, 10 steps of dt = 1: tip uz {:.5f}, max Newton iterations {}\n", M::name,
             solver.displacement(mesh.node_set("xmax").back()).z(), max_newton_big);
  REQUIRE(solver.displacement().allFinite());
  REQUIRE(solver.displacement().cwiseAbs().maxCoeff() < 10);
}

TEST_CASE("mean dilatation removes Neo-Hookean volumetric locking on Hex8, homogeneous states unchanged",
          "[hyper][locking]") {
  // Homogeneous uniaxial stretch: Jbar = J at every point, so the closed form still holds.
  check_uniaxial<NeoHookeanMeanDilatation>(1.5, neo_hookean_uniaxial(1.5, rubber));
  check_uniaxial<NeoHookeanAbaqusMeanDilatation>(0.7, abaqus_uniaxial(0.7, rubber));
  // Static bending of the bar scene at nu = 0.499 under a tenth of gravity (small strain, so
  // the Linear Tet10 reference on 20 x 6 x 6 applies to within the nonlinearity, ~1%).
  auto tip = [](auto solver_tag, const auto& mesh) {
    using S = decltype(solver_tag);
    S s(mesh, Material{3000, 0.499, 1.0});
    s.fix(mesh.node_set("xmin"));
    s.add_gravity(Vec3(0, 0, -0.981));
    s.solve_static(2);
    Scalar uz = 0;
    for (Index i : mesh.node_set("xmax")) uz += s.displacement(i).z();
    return -uz / static_cast<Scalar>(mesh.node_set("xmax").size());
  };
  const auto hex = bar_mesh<Hex8>(10, 3, 3);
  const auto ref_mesh = promote_to_tet10(box_tet4_kuhn({20, 6, 6, Vec3(10, 3, 3)}));
  const Scalar ref = tip(Solver<Tet10, Linear>(ref_mesh, rubber), ref_mesh);
  const Scalar full = tip(Solver<Hex8, NeoHookean>(hex, rubber), hex);
  const Scalar mean = tip(Solver<Hex8, NeoHookeanMeanDilatation>(hex, rubber), hex);
  const Scalar sfull = tip(Solver<Hex8, StableNeoHookean>(hex, rubber), hex);
  const Scalar smean = tip(Solver<Hex8, StableNeoHookeanMeanDilatation>(hex, rubber), hex);
  fmt::print("nu = 0.499 bar90 Hex8 tip / Tet10 reference: NeoHookean {:.3f}, mean dilatation {:.3f}; "
             "StableNeoHookean {:.3f}, mean dilatation {:.3f}\n",
             full / ref, mean / ref, sfull / ref, smean / ref);
  // Full integration locks (the Linear study measured 0.36 x its nu = 0.3 flexibility);
  // mean dilatation recovers the Linear mean-dilatation answer (0.93 of the reference here,
  // the rest being Hex8's bending error on 3 cells through the depth).
  REQUIRE(full / ref < 0.5);
  REQUIRE(mean / ref > 0.85);
  REQUIRE(sfull / ref < 0.5);
  REQUIRE(smean / ref > 0.85);
}
