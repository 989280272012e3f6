// Hyperelastic models (NeoHookean, NeoHookeanAbaqus, StableNeoHookean) on every element:
// finite-difference consistency, closed-form homogeneous states (uniaxial, equibiaxial, simple
// shear: the energies' stress-stretch relations written out here and solved by scalar root
// finding), small-strain agreement with Linear, frame indifference, the extremes (inversion,
// nu = 0.499, huge time steps), and mean dilatation against locking in bending, measured
// against the continuum answer (Richardson extrapolation with the clamp singularity's order).
#include "catch.hpp"
#include "compositions.hpp"
#include "eigenvalues.hpp"
#include "random_elements.hpp"
#include "moved_mesh.hpp"

#include <plastifem/plastifem.hpp>

#include <fmt/core.h>

#include <cmath>
#include <numbers>
#include <random>

using namespace plastifem;
using namespace plastifem::testing;
using testing::big_rotation, testing::deformed, testing::distorted_element;

namespace {

const Material rubber{3000, 0.45, 1.0};

}  // namespace

// The hyperelastic models on every element, and Hex8's mean-dilatation variants of them.
using AllHyper = Concat<OnEveryElement<NeoHookean, NeoHookeanAbaqus, StableNeoHookean>,
                        std::tuple<Combo<Hex8, NeoHookeanMeanDilatation>, Combo<Hex8, NeoHookeanAbaqusMeanDilatation>,
                                   Combo<Hex8, StableNeoHookeanMeanDilatation>>>;

TEMPLATE_LIST_TEST_CASE("hyperelastic force = -dW/dx and tangent = df/dx (finite differences)",
                        "[hyper][fd]", AllHyper) {
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
    ElementVector<E> f, fp;
    ElementMatrix<E> K, Kp;
    M::template evaluate<E>(d, x, f, &K, M::TangentKind::Exact);
    M::template evaluate<E>(d, x, fp, &Kp);
    const Vector ev = testing::symmetric_eigenvalues(Kp);
    // PSD up to round-off of the sum of clamped point contributions (~eps |K|).
    REQUIRE(ev.minCoeff() >= -1e-12 * Kp.norm());
    if (testing::symmetric_eigenvalues(K).minCoeff() >= 0 &&
        d.points.size == 1)
      REQUIRE((Kp - K).norm() <= 1e-12 * K.norm());  // one point: nothing was clamped
    // Central differences, h = 1e-6: truncation ~h^2 |W'''| ~ 1e-12, round-off ~eps |W| / h ~
    // 1e-10 relative: 1e-6 (the bound) has four decades of margin, and a wrong term
    // in P or A is O(1) relative.
    const auto [grad, jac] = testing::element_differences<M, E>(d, x, 1e-6);
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

// ---- closed-form equibiaxial stretch and simple shear, every energy -------------------------

namespace {

enum class Law { NeoHookean, Abaqus, Stable };

/// P = d psi / dF written out from the energies' formulas (the header of
/// elastic/hyperelastic.hpp), nothing of the library's:
///   Neo-Hookean  P = mu (F - F^-T) + lambda ln J F^-T
///   Abaqus       P = 2 C10 J^(-2/3) (F - I1/3 F^-T) + K (J - 1) J F^-T
///   Stable       P = mu' (1 - 1/(I1 + 1)) F + lambda' (J - alpha) J F^-T
Mat3 first_piola(Law law, const Mat3& F, const Material& m) {
  const Scalar mu = m.mu(), la = m.lambda(), J = F.determinant(), I1 = F.squaredNorm();
  const Mat3 FinvT = F.inverse().transpose();
  switch (law) {
    case Law::NeoHookean: return mu * (F - FinvT) + la * std::log(J) * FinvT;
    case Law::Abaqus: {
      const Scalar C10 = mu / 2, K = la + 2 * mu / 3;
      return 2 * C10 * std::pow(J, -2.0 / 3.0) * (F - I1 / 3 * FinvT) + K * (J - 1) * J * FinvT;
    }
    case Law::Stable: {
      const Scalar mus = 4 * mu / 3, las = la + 5 * mu / 6, alpha = 1 + 0.75 * mus / las;
      return mus * (1 - 1 / (I1 + 1)) * F + las * (J - alpha) * J * FinvT;
    }
  }
  return Mat3::Zero();
}

/// The root of a scalar function by Newton from x0, the slope by central differences
/// (h = 1e-6: slope error ~1e-12 relative, which only slows the last iteration).
template <class Fn>
Scalar scalar_newton(Fn f, Scalar x0) {
  Scalar x = x0;
  for (int it = 0; it < 100; ++it) {
    const Scalar h = 1e-6, slope = (f(x + h) - f(x - h)) / (2 * h);
    const Scalar step = f(x) / slope;
    x -= step;
    if (std::abs(step) < 1e-15 * std::abs(x)) break;
  }
  return x;
}

/// 2 x 2 x 2 Hex8 on the unit cube, Newton to 1e-12 of the force scale.
template <class M>
Solver<Hex8, M> unit_cube_solver(const Mesh<Hex8>& mesh) {
  SolverSettings s;
  s.newton.residual_tolerance = 1e-12;
  return Solver<Hex8, M>(mesh, rubber, s);
}

Index node_at(const Mesh<Hex8>& mesh, const Vec3& X) {
  for (Index i = 0; i < mesh.num_nodes(); ++i)
    if ((mesh.node(i) - X).norm() < 1e-12) return i;
  return -1;
}

/// Sum of the reaction forces over a node set: P N A for a homogeneous P on a face of
/// normal N and area A (sum_a in face N_a is 1 on the face and falls to 0 over one cell
/// layer, so the nodal sum integrates P grad of it = P N / layer over the layer).
template <class S>
Vec3 face_force(const S& solver, const std::vector<Index>& nodes) {
  const Vector R = solver.reaction_forces();
  Vec3 F = Vec3::Zero();
  for (Index i : nodes) F += R.segment<3>(3 * i);
  return F;
}

/// Equibiaxial stretch l in x and y, z free (rollers on the three min faces): F = diag(l, l,
/// l3) with P33 = 0, solved for l3 by scalar Newton; the force on the x = 1 face is P11.
template <class M>
void check_equibiaxial(Law law, Scalar l) {
  const Scalar l3 = scalar_newton(
      [&](Scalar z) { return first_piola(law, Vec3(l, l, z).asDiagonal().toDenseMatrix(), rubber)(2, 2); }, 1.0);
  const Scalar P11 = first_piola(law, Vec3(l, l, l3).asDiagonal().toDenseMatrix(), rubber)(0, 0);
  const auto mesh = box_hex8({2, 2, 2, Vec3(1, 1, 1)});
  auto solver = unit_cube_solver<M>(mesh);
  solver.fix(mesh.node_set("xmin"), {true, false, false});
  solver.fix(mesh.node_set("ymin"), {false, true, false});
  solver.fix(mesh.node_set("zmin"), {false, false, true});
  solver.prescribe(mesh.node_set("xmax"), [=](Scalar, const Vec3&) { return Vec3(l - 1, 0, 0); }, {true, false, false});
  solver.prescribe(mesh.node_set("ymax"), [=](Scalar, const Vec3&) { return Vec3(0, l - 1, 0); }, {false, true, false});
  solver.solve_static(4);
  const Scalar l3_fe = 1 + solver.displacement(node_at(mesh, Vec3(1, 1, 1))).z();
  const Scalar Fx = face_force(solver, mesh.node_set("xmax")).x();
  fmt::print("equibiaxial {:32} l = {}: l3 {:.12f} (exact {:.12f}), P11 {:.10g} (exact {:.10g})\n", M::name, l, l3_fe,
             l3, Fx, P11);
  // The homogeneous field is in the trilinear space, so the discrete solution is it up to
  // Newton's 1e-12; the scalar Newton converges to round-off: 1e-8 has ample margin.
  REQUIRE(l3_fe == Approx(l3).epsilon(1e-8));
  REQUIRE(Fx == Approx(P11).epsilon(1e-8));
}

/// Simple shear x = X + gamma Y e_x, imposed on every boundary node (the centre node free):
/// J = 1 and the force on the y = 1 face is P e_y = (P12, P22, P32) from the closed form:
/// Neo-Hookean (mu gamma, 0, 0); Abaqus (mu gamma, -2/3 C10 gamma^2, 0); Stable
/// (mu' s gamma, mu' s + lambda' (1 - alpha), 0), s = 1 - 1/(4 + gamma^2).
template <class M>
void check_simple_shear(Law law, Scalar gamma) {
  Mat3 F = Mat3::Identity();
  F(0, 1) = gamma;
  const Vec3 exact = first_piola(law, F, rubber).col(1);
  const auto mesh = box_hex8({2, 2, 2, Vec3(1, 1, 1)});
  auto solver = unit_cube_solver<M>(mesh);
  const Index centre = node_at(mesh, Vec3(0.5, 0.5, 0.5));
  std::vector<Index> boundary;
  for (Index i = 0; i < mesh.num_nodes(); ++i)
    if (i != centre) boundary.push_back(i);
  solver.prescribe(boundary, [=](Scalar, const Vec3& X) { return Vec3(gamma * X.y(), 0, 0); });
  solver.solve_static(4);
  const Vec3 force = face_force(solver, mesh.node_set("ymax"));
  const Vec3 u_centre = solver.displacement(centre);
  const Scalar scale = rubber.mu() * std::abs(gamma);
  fmt::print("simple shear {:31} gamma = {}: face force ({:.10g}, {:.10g}, {:.3g}), exact ({:.10g}, {:.10g}, 0); "
             "centre off the affine field by {:.1e}\n",
             M::name, gamma, force.x(), force.y(), force.z(), exact.x(), exact.y(),
             (u_centre - Vec3(gamma * 0.5, 0, 0)).norm());
  // Newton to 1e-12 of the force scale (mu gamma ~ 500): 1e-8 of it, with margin (measured
  // 1e-11 at most); the components that vanish are held to the same absolute bound. The
  // centre node sits where the affine field puts it to round-off (measured <= 2e-15): 1e-10.
  REQUIRE((force - exact).norm() <= 1e-8 * scale);
  REQUIRE((u_centre - Vec3(gamma * 0.5, 0, 0)).norm() <= 1e-10);
}

}  // namespace

TEST_CASE("homogeneous equibiaxial stretch and simple shear match the energies' closed forms", "[hyper][closed]") {
  // Uniaxial for the Stable Neo-Hookean energy, by the bisection above on its P22.
  for (Scalar l1 : {1.5, 0.7}) {
    auto P = [&](Scalar l2, int i) {
      return first_piola(Law::Stable, Vec3(l1, l2, l2).asDiagonal().toDenseMatrix(), rubber)(i, i);
    };
    check_uniaxial<StableNeoHookean>(l1, solve_uniaxial([&](Scalar l2) { return P(l2, 1); },
                                                        [&](Scalar l2) { return P(l2, 0); }));
  }
  for (Scalar l : {1.3, 0.8}) {
    check_equibiaxial<NeoHookean>(Law::NeoHookean, l);
    check_equibiaxial<NeoHookeanAbaqus>(Law::Abaqus, l);
    check_equibiaxial<StableNeoHookean>(Law::Stable, l);
  }
  // Mean dilatation: Jbar = J in a homogeneous state, the same closed form.
  check_equibiaxial<StableNeoHookeanMeanDilatation>(Law::Stable, 1.3);
  for (Scalar gamma : {0.5, -1.2}) {
    check_simple_shear<NeoHookean>(Law::NeoHookean, gamma);
    check_simple_shear<NeoHookeanAbaqus>(Law::Abaqus, gamma);
    check_simple_shear<StableNeoHookean>(Law::Stable, gamma);
  }
  check_simple_shear<NeoHookeanMeanDilatation>(Law::NeoHookean, 0.5);
  check_simple_shear<NeoHookeanAbaqusMeanDilatation>(Law::Abaqus, 0.5);
  check_simple_shear<StableNeoHookeanMeanDilatation>(Law::Stable, 0.5);
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
  // Refused where it is set (before 2026-12-02 set_state took it, and the first step refused it).
  const auto before = solver.state();
  try {
    solver.set_state(u, Vector::Zero(12));
    FAIL("expected InvalidArgument");
  } catch (const InvalidArgument& e) {
    REQUIRE(std::string(e.what()).find("element 0 is inverted") != std::string::npos);
  }
  REQUIRE(solver.state() == before);
  // A step that would end inverted (the apex prescribed through its base) is refused likewise.
  solver.prescribe(std::vector<Index>{3}, [](Scalar t, const Vec3&) { return Vec3(0, 0, -150 * t); });
  try {
    solver.step(0.01);
    FAIL("expected SolverError");
  } catch (const SolverError& e) {
    REQUIRE(std::string(e.what()).find("element 0 is inverted") != std::string::npos);
  }
  REQUIRE(solver.displacement() == before.u);
  REQUIRE(solver.time() == 0);
}

TEMPLATE_TEST_CASE("nearly incompressible (nu = 0.499) bending: no NaN, bounded Newton iterations, 100x dt stable",
                   "[hyper][extreme]", NeoHookean, StableNeoHookean) {
  using M = TestType;
  // On the bar and on the bar with its nodes moved by 1e-13: at dt = 1 Newton once "converged"
  // to |u| = 4e7 on the moved bar (StableNeoHookean), relative to the garbage iterate's own
  // inertia and internal forces (NewtonOptions::max_scale_growth now bounds that scale).
  for (const Scalar jitter : {0.0, 1e-13}) {
    const Mesh<Hex8> mesh = moved_mesh(bar_mesh<Hex8>(10, 3, 3), jitter);
    Solver<Hex8, M> solver(mesh, Material{3000, 0.499, 1.0});
    solver.fix(mesh.node_set("xmin"));
    solver.add_gravity(Vec3(0, 0, -9.81));
    int max_newton = 0;
    for (int k = 0; k < 50; ++k) max_newton = std::max(max_newton, solver.step(0.01).newton_iterations);
    const Scalar tip = solver.displacement(mesh.node_set("xmax").back()).z();
    fmt::print("{} nu = 0.499 bar90 (nodes moved by {:.0e}), 50 steps: tip uz {:.5f}, max Newton iterations {}\n",
               M::name, jitter, tip, max_newton);
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
    int max_newton_big = 0, substeps = 0;
    for (int k = 0; k < 10; ++k) {
      const StepReport r = solver.step(1.0);
      max_newton_big = std::max(max_newton_big, r.newton_iterations);
      substeps += r.substeps;
    }
    fmt::print("{} nu = 0.499 bar90, 10 steps of dt = 1: tip uz {:.5f}, |u|max {:.4f}, max Newton iterations {}, "
               "{} sub-steps\n",
               M::name, solver.displacement(mesh.node_set("xmax").back()).z(), solver.displacement().cwiseAbs().maxCoeff(),
               max_newton_big, substeps);
    REQUIRE(solver.displacement().allFinite());
    REQUIRE(solver.displacement().cwiseAbs().maxCoeff() < 10);
  }
}

namespace {

/// Load-weighted mean deflection f_ext . u / W of the bar [0, 10] x [0, 3] x [0, 3] clamped at
/// x = 0 under gravity g_z, cells of size 1/r; `half`: y in [0, 1.5] with u_y = 0 on y = 1.5
/// (the symmetric Hex8 grid's answer at half the cost). Statics in `steps` load increments.
template <class M>
Scalar bar_mean_deflection(int r, bool half, const Material& m, Scalar g_z, int steps) {
  const Scalar width = half ? 1.5 : 3.0;
  const auto mesh = bar_mesh<Hex8>(BoxSpec{10 * r, half ? 3 * r / 2 : 3 * r, 3 * r, Vec3(10, width, 3)});
  Solver<Hex8, M> s(mesh, m);
  s.fix(mesh.node_set("xmin"));
  if (half) s.fix(mesh.node_set("ymax"), {false, true, false});
  s.add_gravity(Vec3(0, 0, -g_z));
  s.solve_static(steps);
  return s.external_work_potential() / (g_z * m.density * 10 * width * 3);
}

/// Williams' exponent for a right-angle corner, one face clamped and one free (plane strain):
/// the root in (1/2, 1) of kappa sin^2(l pi/2) = (kappa + 1)^2 / 4 - l^2, kappa = 3 - 4 nu, by
/// Newton (test_locking.cpp explains and checks it: 0.7112 at nu = 0.3).
Scalar williams_clamped_free(Scalar nu) {
  const Scalar k = 3 - 4 * nu, c = std::numbers::pi / 2;
  Scalar l = 0.7;
  for (int it = 0; it < 50; ++it) {
    const Scalar sn = std::sin(l * c);
    const Scalar step = (k * sn * sn - (k + 1) * (k + 1) / 4 + l * l) / (k * c * std::sin(2 * l * c) + 2 * l);
    l -= step;
    if (std::abs(step) < 1e-15) break;
  }
  return l;
}

/// The continuum answer by Richardson extrapolation of the mean-dilatation sequence h = 1,
/// 1/2, 1/4 with the clamp singularity's order p = 2 lambda (the energy converges like
/// h^(2 lambda); test_locking.cpp shows the sequence following it, and the [long] case there
/// confirms it with h = 1/8).
struct Extrapolated {
  Scalar d1, d2, d4, p, p_obs, value, estimated_error;
};

template <class M>
Extrapolated extrapolate(const Material& m, Scalar g_z, int steps) {
  Extrapolated e;
  e.d1 = bar_mean_deflection<M>(1, false, m, g_z, steps);
  e.d2 = bar_mean_deflection<M>(2, true, m, g_z, steps);
  e.d4 = bar_mean_deflection<M>(4, true, m, g_z, steps);
  e.p = 2 * williams_clamped_free(m.poisson);
  e.p_obs = std::log2((e.d2 - e.d1) / (e.d4 - e.d2));
  auto richardson = [&](Scalar p) { return e.d4 + (e.d4 - e.d2) / (std::pow(2.0, p) - 1); };
  e.value = richardson(e.p);
  // The exponent is the main uncertainty: the spread between theory's and the observed one.
  e.estimated_error = std::abs(e.value - richardson(e.p_obs)) / e.value;
  return e;
}

}  // namespace

TEST_CASE("mean dilatation removes Neo-Hookean volumetric locking on Hex8, homogeneous states unchanged",
          "[hyper][locking]") {
  // Homogeneous uniaxial stretch: Jbar = J at every point, so the closed form still holds.
  check_uniaxial<NeoHookeanMeanDilatation>(1.5, neo_hookean_uniaxial(1.5, rubber));
  check_uniaxial<NeoHookeanAbaqusMeanDilatation>(0.7, abaqus_uniaxial(0.7, rubber));
  // Static bending of the bar scene at nu = 0.499 under a tenth of gravity, against the
  // continuum Neo-Hookean answer: Richardson extrapolation of the NeoHookeanMeanDilatation
  // sequence (h = 1, 1/2, 1/4; the half bar by symmetry for the fine two). Quantity: the
  // load-weighted mean deflection f.u / W (the volume average of -u_z).
  const Material m{3000, 0.499, 1.0};
  const Scalar g = 0.981;
  const Extrapolated ref = extrapolate<NeoHookeanMeanDilatation>(m, g, 1);
  // The linear continuum answer, extrapolated the same way: the two differ by the
  // nonlinearity at this load alone (rotations ~0.03, bending strain ~3% at the clamp).
  const Extrapolated lin = extrapolate<LinearMeanDilatation>(m, g, 1);
  fmt::print("nu = 0.499 bar, g/10, mean deflection: NeoHookeanMeanDilatation h=1 {:.6f} h=1/2 {:.6f} h=1/4 {:.6f} "
             "-> {:.6f}; order 2 lambda {:.3f}, observed {:.3f}; estimated error {:.1e}; linear continuum {:.6f} "
             "({:+.1e})\n",
             ref.d1, ref.d2, ref.d4, ref.value, ref.p, ref.p_obs, ref.estimated_error, lin.value,
             lin.value / ref.value - 1);
  // Measured 6.5e-5 (the observed order, 1.194, is theory's 1.190 already from h = 1 here);
  // 0.5% is ten times below the margins asserted below. Newton stops at 1e-6 of the force
  // scale: ~1e-6 relative in each level, against level differences of 2-4%.
  REQUIRE(ref.estimated_error < 5e-3);
  // Observed against theoretical order: the Neo-Hookean sequence sits on it (measured 0.3%
  // apart); 10% rejects a smooth-solution rate (2) or a sequence not converging.
  REQUIRE(std::abs(ref.p_obs / ref.p - 1) < 0.1);
  // Nonlinearity at g/10: the linear continuum answer is 3.8e-4 above (measured; tension and
  // compression sides nearly cancel in the deflection); 1% bounds an effect of the order of
  // the clamp's bending strain.
  REQUIRE(std::abs(lin.value / ref.value - 1) < 0.01);

  const Scalar full = bar_mean_deflection<NeoHookean>(1, false, m, g, 2);
  const Scalar mean = ref.d1;
  const Scalar sfull = bar_mean_deflection<StableNeoHookean>(1, false, m, g, 2);
  const Scalar smean = bar_mean_deflection<StableNeoHookeanMeanDilatation>(1, false, m, g, 2);
  fmt::print("nu = 0.499 bar90 Hex8 mean deflection / continuum: NeoHookean {:.3f}, mean dilatation {:.3f}; "
             "StableNeoHookean {:.3f}, mean dilatation {:.3f} (LinearMeanDilatation {:.3f})\n",
             full / ref.value, mean / ref.value, sfull / ref.value, smean / ref.value, lin.d1 / ref.value);
  // Full integration locks: a third of the continuum deflection (measured 0.324 for both,
  // as Linear Hex8 in test_locking); 0.5 keeps it apart from mean dilatation's > 0.9.
  REQUIRE(full / ref.value < 0.5);
  REQUIRE(sfull / ref.value < 0.5);
  // Mean dilatation recovers all but the scene mesh's own discretisation error (3 cells
  // through the depth, the clamp singularity): LinearMeanDilatation 0.953, Stable 0.957,
  // NeoHookean 0.932 (its psi_dev keeps a pointwise mu ln J volumetric stiffness, which the
  // element mean does not relax). 0.9 leaves 3% margin under the lowest.
  REQUIRE(mean / ref.value > 0.9);
  REQUIRE(smean / ref.value > 0.9);
  // And neither over-softens: below the continuum answer by more than its estimated error.
  REQUIRE(mean < ref.value * (1 - ref.estimated_error));
  REQUIRE(smean < ref.value * (1 - ref.estimated_error));
}
