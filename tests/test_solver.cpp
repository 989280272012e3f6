// Whole-solver checks against independent facts: the patch test on distorted meshes, a
// cantilever against Timoshenko beam theory with measured convergence orders, exact energy
// conservation of undamped average-acceleration Newmark, damped dynamics settling on the static
// solution (the toolkit's own in bending; a closed form, P L / (E A) and its Neo-Hookean
// counterpart, for a bar in uniaxial tension on rollers), balance of forces and moments,
// reactions against the weight, determinism across thread counts, input validation, and the
// "failed step leaves the state alone" contract.
#include "catch.hpp"
#include "compositions.hpp"

#include <plastifem/plastifem.hpp>

#include <fmt/core.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <random>
#include <set>
#include <tuple>

using namespace plastifem;
using namespace plastifem::testing;

namespace {

template <class Err = Error>
std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const Err& e) {
    return e.what();
  } catch (const std::exception& e) {
    return std::string("wrong exception type: ") + e.what();
  }
  return "(no error)";
}

bool contains(const std::string& s, const std::string& part) { return s.find(part) != std::string::npos; }

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

/// Box meshes of every element type: Hex8 grid, Kuhn Tet4, its Tet10, or prisms.
template <FiniteElement E>
Mesh<E> box_mesh(const BoxSpec& b) {
  return bar_mesh<E>(b);
}

/// Moves every node strictly inside the box [0, n]^3 (unit cells) by a random vector of length
/// up to 0.2. Kuhn tets have heights >= 1/sqrt(2) = 0.71 (the prisms' triangles too) and two
/// moved corners close a gap by at most 0.4, so no element inverts (the Mesh constructor would
/// throw if one did).
template <FiniteElement E>
Mesh<E> perturb_interior(const Mesh<E>& m, int n, std::mt19937& rng) {
  std::uniform_real_distribution<Scalar> u(-1.0, 1.0);
  Eigen::Matrix3Xd X = m.nodes();
  for (Index i = 0; i < X.cols(); ++i) {
    const Vec3 p = X.col(i);
    if ((p.array() > 1e-9).all() && (p.array() < n - 1e-9).all()) {
      Vec3 d;
      do d = Vec3(u(rng), u(rng), u(rng));
      while (d.norm() > 1);
      X.col(i) += 0.2 * d;
    }
  }
  return Mesh<E>(X, m.elements());
}

/// A distorted n^3 box: Hex8 and Tet4 with moved interior nodes; Tet10 promoted from the
/// distorted Tet4, so mid-edge nodes sit at the middle of straight edges.
template <FiniteElement E>
Mesh<E> distorted_box(int n, std::mt19937& rng) {
  if constexpr (std::is_same_v<E, Tet10>) return promote_to_tet10(perturb_interior(box_tet4_kuhn({n, n, n}), n, rng));
  else return perturb_interior(box_mesh<E>({n, n, n}), n, rng);
}

Eigen::Matrix3Xd as_nodes(const Vector& u) { return Eigen::Map<const Eigen::Matrix3Xd>(u.data(), 3, u.size() / 3); }

template <class S>
bool state_finite(const S& s) {
  return s.displacement().allFinite() && s.velocity().allFinite() && s.acceleration().allFinite();
}

/// Mean z-displacement of a node set.
template <class S>
Scalar mean_uz(const S& s, const std::vector<Index>& nodes) {
  Scalar z = 0;
  for (Index i : nodes) z += s.displacement(i).z();
  return z / static_cast<Scalar>(nodes.size());
}

const Material soft{3000.0, 0.45, 1.0};  // SCENES.md bar material

}  // namespace

// ---- patch test ------------------------------------------------------------------------------

TEMPLATE_LIST_TEST_CASE("patch test: a linear displacement field is reproduced on a distorted mesh",
                        "[solver][patch]", AllElements) {
  using E = TestType;
  std::mt19937 rng(42);
  const int n = 4;
  const Mesh<E> mesh = distorted_box<E>(n, rng);
  const std::vector<Index> boundary = nodes_of_faces(mesh, boundary_faces(mesh));
  std::vector<char> on_boundary(mesh.num_nodes(), 0);
  for (Index i : boundary) on_boundary[i] = 1;
  REQUIRE(boundary.size() < static_cast<size_t>(mesh.num_nodes()));  // there are interior nodes

  std::uniform_real_distribution<Scalar> u(-1e-3, 1e-3);
  Mat3 A;
  for (int i = 0; i < 9; ++i) A(i / 3, i % 3) = u(rng);
  const Vec3 b(u(rng), u(rng), u(rng));
  auto field = [A, b](Scalar, const Vec3& X) -> Vec3 { return A * X + b; };

  auto error = [&](const auto& solver) {
    Scalar worst = 0;
    for (Index i = 0; i < mesh.num_nodes(); ++i)
      if (!on_boundary[i]) worst = std::max(worst, (solver.displacement(i) - field(0, mesh.node(i))).norm());
    return worst / (A.norm() * n);  // relative to the field's variation over the box
  };

  Solver<E, Linear> lin(mesh, soft);
  lin.prescribe(boundary, field);
  lin.solve_static();
  const Scalar e_lin = error(lin);

  SolverSettings tight;
  tight.newton.residual_tolerance = 1e-12;
  Solver<E, Corotational> cor(mesh, soft, tight);
  cor.prescribe(boundary, field);
  const StepReport rep = cor.solve_static();
  const Scalar e_cor = error(cor);
  fmt::print("patch test {:6} ({} nodes, {} interior): linear error {:.2e}, corotational {:.2e} ({} Newton it.)\n",
             E::name, mesh.num_nodes(), mesh.num_nodes() - static_cast<Index>(boundary.size()), e_lin, e_cor,
             rep.newton_iterations);
  // Linear: the exact solution is in the FE space, so the only error is the LDLT solve,
  // ~cond(K) eps ~ 1e3 * 1e-16 on these <= 2,200-dof systems (measured 3e-14 to 5e-14).
  // 1e-10 as asked.
  REQUIRE(e_lin <= 1e-10);
  // Corotational: with a homogeneous F = I + A every element extracts the same R, and
  // R K0 (R^T x - X0) with R^T x - X0 linear is the (rotated) linear patch force, which cancels
  // at interior nodes: the linear field is an exact equilibrium here too. What is left is the
  // Newton stopping test (|r| <= 1e-12 of the initial imbalance; with the exact tangent Newton
  // converges quadratically, measured 5e-14 to 2e-13 in 3 iterations; the warped tangent omits
  // dR/dx, a relative O(|A|) = 1e-3 error, and took 4-5 iterations to 1.2e-12). 1e-8 bounds
  // that with margin while failing for any error at the level of the nonlinearity (|A| = 1e-3).
  REQUIRE(e_cor <= 1e-8);
  REQUIRE(state_finite(lin));
  REQUIRE(state_finite(cor));
}

// ---- cantilever vs Timoshenko ----------------------------------------------------------------

namespace {

struct CantileverResult {
  Scalar deflection;  // end-face average, work-conjugate to the uniform shear traction
  Index dofs;
  double seconds;
};

/// Cantilever 10 x 1 x 1 with (10 r) x r x r cells, clamped at x = 0, uniform shear traction of
/// total P = 1 along -z on x = 10. Returns f_ext . u / P: the traction-weighted (= area) average
/// of -u_z over the end face, the quantity beam theory predicts.
template <FiniteElement E>
CantileverResult cantilever(int r, Scalar nu) {
  const auto t0 = std::chrono::steady_clock::now();
  const Mesh<E> mesh = box_mesh<E>({10 * r, r, r, Vec3(10, 1, 1)});
  SolverSettings s;
  s.static_linear.kind = LinearSolverKind::Direct;
  Solver<E, Linear> solver(mesh, Material{1000.0, nu, 1.0}, s);
  solver.fix(mesh.node_set("xmin"));
  solver.add_traction(mesh.face_set("xmax"), Vec3(0, 0, -1.0));
  solver.solve_static();
  return {solver.external_work_potential() / 1.0, solver.num_dofs(), seconds_since(t0)};
}

/// Timoshenko tip deflection P L^3 / (3 E I) + P L / (kappa G A), kappa = 5/6 (rectangle).
Scalar timoshenko(Scalar nu) {
  const Scalar P = 1, L = 10, E = 1000, I = 1.0 / 12, A = 1, G = E / (2 * (1 + nu));
  return P * L * L * L / (3 * E * I) + P * L / (5.0 / 6.0 * G * A);
}

template <FiniteElement E>
std::vector<Scalar> cantilever_series(const std::vector<int>& levels, Scalar nu, Scalar exact) {
  std::vector<Scalar> d;
  for (int r : levels) {
    const CantileverResult c = cantilever<E>(r, nu);
    const Scalar err = c.deflection / exact - 1;
    std::string order = "-";
    if (d.size() >= 1 && nu == 0) order = fmt::format("{:.2f}", std::log2((d.back() / exact - 1) / err));
    fmt::print("  {:6} nu={:4} {:>9} {:6} dofs  deflection {:.7f}  vs Timoshenko {:+.3e}  order {:>5}  {:.2f} s\n",
               E::name, nu, fmt::format("{}x{}x{}", 10 * r, r, r), c.dofs, c.deflection, err, order, c.seconds);
    d.push_back(c.deflection);
  }
  return d;
}

}  // namespace

TEST_CASE("cantilever under end shear converges to Timoshenko theory (nu = 0)", "[solver][cantilever]") {
  // nu = 0: the clamp imposes no lateral-contraction constraint, and for nu = 0 the elementary
  // parabolic shear distribution is exact, so Timoshenko with kappa = 5/6 is the 3D answer up to
  // the clamp's local warping restraint: Richardson extrapolation of the Tet10 series lands
  // within 2e-5 of it (measured), far below the tolerances below.
  const Scalar exact = timoshenko(0.0);
  fmt::print("Cantilever 10x1x1, E = 1000, nu = 0, P = 1: Timoshenko deflection {:.6f}\n", exact);
  // Compliance (P delta = 2 x energy) converges at twice the energy-norm rate: h^2 for the
  // linear elements, h^4 for Tet10 on smooth solutions. Levels double the resolution.
  const auto hex = cantilever_series<Hex8>({1, 2, 4, 8}, 0.0, exact);
  const auto tet4 = cantilever_series<Tet4>({1, 2, 4, 8}, 0.0, exact);
  const auto tet10 = cantilever_series<Tet10>({1, 2, 4}, 0.0, exact);
  const auto wedge = cantilever_series<Wedge6>({1, 2, 4, 8}, 0.0, exact);
  auto order = [&](const std::vector<Scalar>& d, size_t i) {  // from levels i-1 and i, vs exact
    return std::log2((exact - d[i - 1]) / (exact - d[i]));
  };
  // Conforming displacement FE on nested meshes (the Kuhn split of a refined grid refines the
  // coarse Kuhn split) underestimate the compliance and increase monotonically with refinement.
  for (const auto* d : {&hex, &tet4, &tet10, &wedge})
    for (size_t i = 1; i < d->size(); ++i) REQUIRE((*d)[i] > (*d)[i - 1]);
  // Tet10 (quadratic, no shear locking): the finest level (40x4x4, 20k dofs, ~2 s) is within
  // 0.1% as required (measured -6e-6; 20x2x2 is already at -1.5e-4).
  REQUIRE(std::abs(tet10.back() / exact - 1) < 1e-3);
  // Tet10 order from successive differences (the last error is at the level of the model
  // error, so differences are the cleaner measure): measured 3.3. Theory 4 for smooth
  // solutions; the singular stress at the clamped edges lowers it. [2.5, 4.5] rejects a
  // linear-element rate (2) and anything faster than theory.
  const Scalar p10 = std::log2((tet10[1] - tet10[0]) / (tet10[2] - tet10[1]));
  fmt::print("  Tet10 order from successive differences: {:.2f}\n", p10);
  REQUIRE(p10 > 2.5);
  REQUIRE(p10 < 4.5);
  // Hex8 (fully integrated trilinear: shear locking in bending) and Tet4 (constant strain:
  // locks worse) cannot reach 0.1% within the time budget: 0.1% would need ~240x24x24 Hex8
  // cells (1.4 M dofs). At 80x8x8 (20k dofs, ~2 s) they are at -0.78% and -5.1% (measured);
  // the bounds 1% and 6% assert that with ~20% margin on the error.
  REQUIRE(std::abs(hex.back() / exact - 1) < 0.01);
  REQUIRE(std::abs(tet4.back() / exact - 1) < 0.06);
  // Their asymptotic order is 2: measured Hex8 1.58, 1.87, 1.97 and Tet4 0.75, 1.36, 1.77
  // (pre-asymptotic: the coarse Tet4 meshes are almost rigid). The last order must be in
  // [1.7, 2.3] for Hex8 and [1.5, 2.3] for Tet4 (still approaching 2 from below).
  fmt::print("  Hex8 orders {:.2f} {:.2f} {:.2f}; Tet4 orders {:.2f} {:.2f} {:.2f}\n", order(hex, 1), order(hex, 2),
             order(hex, 3), order(tet4, 1), order(tet4, 2), order(tet4, 3));
  REQUIRE(order(hex, 3) > 1.7);
  REQUIRE(order(hex, 3) < 2.3);
  REQUIRE(order(tet4, 3) > 1.5);
  REQUIRE(order(tet4, 3) < 2.3);
  // Richardson extrapolation with the theoretical order 2 removes the h^2 term: Hex8's limit
  // is then within 0.1% of Timoshenko (measured -2.4e-4) -- the locking error is pure
  // discretisation error, not a wrong answer.
  const Scalar hex_limit = hex[3] + (hex[3] - hex[2]) / 3;
  fmt::print("  Hex8 Richardson (p = 2) limit {:.6f} ({:+.2e})\n", hex_limit, hex_limit / exact - 1);
  REQUIRE(std::abs(hex_limit / exact - 1) < 1e-3);
  // Wedge6 (two prisms per Hex8 cell, fully integrated: it locks in bending as Hex8 does,
  // -0.78% at 80x8x8, measured): orders 1.50, 1.80, 1.94 (measured), asymptotically 2, and the
  // same Richardson limit within 0.1% (measured -4.5e-4).
  const Scalar wedge_limit = wedge[3] + (wedge[3] - wedge[2]) / 3;
  fmt::print("  Wedge6 orders {:.2f} {:.2f} {:.2f}; Richardson (p = 2) limit {:.6f} ({:+.2e})\n", order(wedge, 1),
             order(wedge, 2), order(wedge, 3), wedge_limit, wedge_limit / exact - 1);
  REQUIRE(std::abs(wedge.back() / exact - 1) < 0.01);
  REQUIRE(order(wedge, 3) > 1.7);
  REQUIRE(order(wedge, 3) < 2.3);
  REQUIRE(std::abs(wedge_limit / exact - 1) < 1e-3);
}

TEST_CASE("cantilever with nu = 0.45: refinement series converge", "[solver][cantilever]") {
  // With nu = 0.45 the clamp prevents the section's lateral contraction and the 3D answer is a
  // few percent below beam theory, so the series are only checked for convergence.
  const Scalar beam = timoshenko(0.45);
  fmt::print("Cantilever 10x1x1, E = 1000, nu = 0.45, P = 1: Timoshenko deflection {:.6f}\n", beam);
  const auto hex = cantilever_series<Hex8>({1, 2, 4, 8}, 0.45, beam);
  const auto tet4 = cantilever_series<Tet4>({1, 2, 4, 8}, 0.45, beam);
  const auto tet10 = cantilever_series<Tet10>({1, 2, 4}, 0.45, beam);
  auto diffs = [](const std::vector<Scalar>& d) {
    std::vector<Scalar> out;
    for (size_t i = 1; i < d.size(); ++i) out.push_back(d[i] - d[i - 1]);
    return out;
  };
  const auto dh = diffs(hex), d4 = diffs(tet4), d10 = diffs(tet10);
  fmt::print("  differences: Hex8 {:.4f} {:.4f} {:.4f}; Tet4 {:.4f} {:.4f} {:.4f}; Tet10 {:.4f} {:.4f}\n", dh[0], dh[1],
             dh[2], d4[0], d4[1], d4[2], d10[0], d10[1]);
  // Nested conforming spaces: monotone increase (compliance is a lower bound).
  for (const auto* d : {&dh, &d4, &d10})
    for (Scalar x : *d) REQUIRE(x > 0);
  // Converging: successive differences shrink. Hex8 and Tet10 from the first level on; Tet4
  // (volumetric locking at nu = 0.45 on top of shear locking: its coarsest meshes are nearly
  // rigid, 0.44 vs ~3.97) only from 20x2x2 on -- measured 0.77, 1.21, 0.96.
  REQUIRE(dh[1] < dh[0]);
  REQUIRE(dh[2] < dh[1]);
  REQUIRE(d10[1] < d10[0]);
  REQUIRE(d4[2] < d4[1]);
  // Tet10 contracts by ~4 per level (measured 0.177 -> 0.043): at least 2.
  REQUIRE(d10[1] < 0.5 * d10[0]);
  // A common limit: every element's finest value lies below the Tet10 limit estimate (lower
  // bounds), and Tet10's own estimate (Richardson with its measured ratio) is below beam theory
  // by the expected few percent (measured about -1.7%): between 0 and -5%.
  const Scalar ratio = d10[0] / d10[1];
  const Scalar tet10_limit = tet10[2] + d10[1] / (ratio - 1);
  fmt::print("  Tet10 extrapolated limit {:.5f} ({:+.2f}% vs beam theory)\n", tet10_limit, 100 * (tet10_limit / beam - 1));
  REQUIRE(hex.back() < tet10_limit);
  REQUIRE(tet4.back() < tet10_limit);
  REQUIRE(tet10_limit < beam);
  REQUIRE(tet10_limit > 0.95 * beam);
}

// ---- Newmark energy --------------------------------------------------------------------------

TEST_CASE("undamped average-acceleration Newmark conserves energy on a linear problem", "[solver][newmark]") {
  const Mesh<Hex8> mesh = bar_mesh<Hex8>(4, 1, 1);
  SolverSettings s;
  s.linear.kind = LinearSolverKind::Direct;  // exact solves: no CG residual feeding the drift
  const auto t0 = std::chrono::steady_clock::now();

  SECTION("free vibration from a bent shape, 10,000 steps, and 100x the time step") {
    for (Scalar dt : {0.01, 1.0}) {
      Solver<Hex8, Linear> solver(mesh, soft, s);
      solver.fix(mesh.node_set("xmin"));
      Vector u0(solver.num_dofs());
      for (Index i = 0; i < mesh.num_nodes(); ++i) {
        const Vec3 X = mesh.node(i);
        u0.segment<3>(3 * i) = Vec3(0.002 * X.x() * (X.z() - 0.5), 0.001 * X.x(), -0.01 * X.x() * X.x());
      }
      solver.set_state(u0, Vector::Zero(solver.num_dofs()));
      const Scalar E0 = solver.kinetic_energy() + solver.strain_energy();
      Scalar drift = 0, max_kinetic = 0, max_u = 0;
      const int steps = dt < 0.1 ? 10000 : 1000;
      for (int k = 0; k < steps; ++k) {
        solver.step(dt);
        const Scalar Ek = solver.kinetic_energy();
        drift = std::max(drift, std::abs(Ek + solver.strain_energy() - E0) / E0);
        max_kinetic = std::max(max_kinetic, Ek);
        max_u = std::max(max_u, solver.displacement().cwiseAbs().maxCoeff());
      }
      fmt::print("Newmark free vibration, dt = {}: {} steps, max |E - E0| / E0 = {:.2e}, max KE / E0 = {:.3f}, "
                 "max |u| = {:.4f} (|u0| = {:.4f})\n",
                 dt, steps, drift, max_kinetic / E0, max_u, u0.cwiseAbs().maxCoeff());
      // Trapezoidal rule on M a + K u = 0: 0.5 v.Mv + 0.5 u.Ku is an exact invariant; only
      // round-off of the direct solves accumulates (a random walk of ~1e-16 per step: ~1e-14
      // after 1e4 steps; measured 6e-13 at dt = 0.01, 2e-12 at dt = 1). 1e-8 as asked.
      REQUIRE(drift < 1e-8);
      // It really oscillates (energy goes back and forth between the two forms) ...
      REQUIRE(max_kinetic > 0.1 * E0);
      // ... and stays bounded: u.Ku <= 2 E0 bounds |u|; the initial shape is near the lowest
      // mode, so |u| never exceeds ~1x its initial size (2x allowed).
      REQUIRE(max_u < 2 * u0.cwiseAbs().maxCoeff());
      REQUIRE(state_finite(solver));
      REQUIRE(solver.time() == Approx(steps * dt).epsilon(1e-12));
    }
  }
  SECTION("constant load from rest: kinetic + strain - f.u is conserved") {
    Solver<Hex8, Linear> solver(mesh, soft, s);
    solver.fix(mesh.node_set("xmin"));
    solver.add_nodal_force(mesh.node_set("xmax"), Vec3(0, 5.0, -10.0));
    // From rest at u = 0 the total energy is 0 and must stay 0. Scale: the largest strain
    // energy reached (the bar swings to twice its static deflection: 4x the static energy).
    Scalar drift = 0, scale = 0;
    for (int k = 0; k < 2000; ++k) {
      solver.step(0.01);
      const Scalar H = solver.kinetic_energy() + solver.strain_energy() - solver.external_work_potential();
      scale = std::max(scale, solver.strain_energy());
      drift = std::max(drift, std::abs(H));
    }
    fmt::print("Newmark under constant load: max |KE + SE - f.u| / max SE = {:.2e}\n", drift / scale);
    REQUIRE(scale > 0);
    REQUIRE(drift < 1e-8 * scale);  // exact invariant of the trapezoidal rule for constant f
  }
  fmt::print("  (energy section took {:.2f} s)\n", seconds_since(t0));
}

// ---- damped dynamics reach the static solution -----------------------------------------------

template <class E, class M>
void damped_to_static(const Mesh<E>& mesh, Vec3 g, int steps, Scalar dt, Scalar alpha, Scalar tol,
                      SolverSettings s = {}) {
  s.rayleigh_mass = alpha;
  Solver<E, M> dyn(mesh, soft, s);
  dyn.fix(mesh.node_set("xmin"));
  dyn.add_gravity(g);
  SolverSettings st = s;
  st.newton.residual_tolerance = 1e-10;
  Solver<E, M> sta(mesh, soft, st);
  sta.fix(mesh.node_set("xmin"));
  sta.add_gravity(g);
  sta.solve_static(M::constant_tangent ? 1 : 4);
  const Vector& us = sta.displacement();
  Scalar half = 0;
  for (int k = 0; k < steps; ++k) {
    dyn.step(dt);
    if (k == steps / 2) half = (dyn.displacement() - us).norm() / us.norm();
  }
  const Scalar end = (dyn.displacement() - us).norm() / us.norm();
  fmt::print("damped {:6} {:13}: |u(T) - u_static| / |u_static| = {:.2e} (at T/2: {:.2e}), |v(T)| = {:.1e}\n",
             E::name, M::name, end, half, dyn.velocity().norm());
  REQUIRE(state_finite(dyn));
  REQUIRE(end < tol);
  REQUIRE((end < half || end < 1e-9));  // approaching it, unless already at round-off
}

TEST_CASE("a long damped run settles on the static solution", "[solver][damping]") {
  // bar 4x1x1, gravity 9.81 (beam theory: tip deflection 1.26 = 31% of the length, tip rotation
  // 0.42 rad: a large rotation for the corotational run). Mass damping alpha = 7 ~ 2 omega_1 (omega_1 = 3.5 rad/s from beam
  // theory): mode 1 is critically damped, every other mode decays like exp(-alpha t / 2).
  // 1,000 steps of 0.01 s: exp(-35) ~ 1e-15 in exact time integration; the stiffest modes
  // (omega dt ~ 4) are damped a little less by the trapezoidal rule but start ~1e-4 smaller.
  // What remains is the solver tolerance: CG stops at 1e-8 of the right-hand side, and the
  // corotational Newton at a relative residual of 1e-6 per step -- but near rest the step's
  // right-hand side, hence its error, is tiny. Measured 1e-9 to 4e-9 for both models (at the
  // CG tolerance's level, so it moves with round-off from build to build); bounds 1e-7 and
  // 1e-6 (the latter the Newton tolerance).
  const Mesh<Hex8> mesh = bar_mesh<Hex8>(4, 1, 1);
  damped_to_static<Hex8, Linear>(mesh, Vec3(0, 0, -9.81), 1000, 0.01, 7.0, 1e-7);
  damped_to_static<Hex8, Corotational>(mesh, Vec3(0, 0, -9.81), 1000, 0.01, 7.0, 1e-6);
}

// ---- damped dynamics reach the closed-form static solution -----------------------------------

namespace {

/// Uniaxial stress under a dead-load traction t: the stretches (l1, l2 = l3) with P11 = t and
/// P22 = 0, for the Neo-Hookean energy (P_i = mu l_i + (lambda ln J - mu) / l_i, J = l1 l2^2),
/// by nested scalar Newton (slopes by central differences); for the models that are linear in
/// a pure stretch (Linear; Corotational, whose polar rotation is I for F = diag) the linear
/// answer l1 = 1 + t / E, l2 = 1 - nu t / E.
struct Stretches {
  Scalar l1, l2;
};

template <class Fn>
Scalar newton_root(Fn f, Scalar x) {
  for (int it = 0; it < 100; ++it) {
    const Scalar h = 1e-7, step = f(x) / ((f(x + h) - f(x - h)) / (2 * h));
    x -= step;
    if (std::abs(step) < 1e-15 * std::abs(x)) break;
  }
  return x;
}

template <class M>
Stretches uniaxial_stress(const Material& m, Scalar t) {
  if constexpr (!std::is_same_v<M, NeoHookean>) {
    return {1 + t / m.young, 1 - m.poisson * t / m.young};
  } else {
    const Scalar mu = m.mu(), la = m.lambda();
    auto P = [&](Scalar l1, Scalar l2, Scalar li) { return mu * li + (la * std::log(l1 * l2 * l2) - mu) / li; };
    auto lateral = [&](Scalar l1) { return newton_root([&](Scalar l2) { return P(l1, l2, l2); }, 1.0); };
    const Scalar axial = newton_root([&](Scalar l1) { return P(l1, lateral(l1), l1) - t; }, 1 + t / m.young);
    return {axial, lateral(axial)};
  }
}

/// A bar 4 x 1 x 1 on rollers (u_x = 0 on x = 0, u_y = 0 on y = 0, u_z = 0 on z = 0) pulled by
/// a uniform traction t on x = 4: uniaxial stress, u = ((l1 - 1) x, (l2 - 1) y, (l2 - 1) z),
/// homogeneous, so in every element's space: the static FE answer is the closed form, and a
/// damped run from rest must approach it (relative error of the whole field, at 1 s and 2 s).
template <FiniteElement E, class M>
void damped_uniaxial(Scalar t, Scalar tol) {
  const Mesh<E> mesh = box_mesh<E>({4, 1, 1});
  SolverSettings s;
  // Rayleigh damping: the first axial mode (fixed-free rod, omega_1 = pi c / (2 L) with
  // c = sqrt(E / rho) = 54.8: 21.5 rad/s) critically damped by alpha + beta omega_1^2 = 2
  // omega_1 (alpha = 42.5, beta = 1e-3). beta K0 overdamps the stiff modes (continuous decay
  // ~1 / beta = 1000/s); the trapezoidal rule damps them less where omega dt >> 1, but a
  // uniform end load hardly excites them: the floor measured below is Newton's, not theirs.
  s.rayleigh_mass = 42.5;
  s.rayleigh_stiffness = 1e-3;
  // Newton (and with it the inexact CG, whose tolerance follows Newton's) to 1e-10 of the force
  // scale: what is left at the end is then the stopping test's, ~5e-2 of it (measured: with
  // the default 1e-6 Tet10 stalls at 3e-8 to 7e-8, with 1e-8 at 5e-10, with 1e-10 at 1e-11).
  s.newton.residual_tolerance = 1e-10;
  Solver<E, M> solver(mesh, soft, s);
  solver.fix(mesh.node_set("xmin"), {true, false, false});
  solver.fix(mesh.node_set("ymin"), {false, true, false});
  solver.fix(mesh.node_set("zmin"), {false, false, true});
  solver.add_traction(mesh.face_set("xmax"), Vec3(t, 0, 0));  // suddenly applied at t = 0
  const Stretches l = uniaxial_stress<M>(soft, t);
  Vector exact(solver.num_dofs());
  for (Index i = 0; i < mesh.num_nodes(); ++i) {
    const Vec3 X = mesh.node(i);
    exact.segment<3>(3 * i) = Vec3((l.l1 - 1) * X.x(), (l.l2 - 1) * X.y(), (l.l2 - 1) * X.z());
  }
  // The toolkit's own static solve reproduces it (a patch test under load).
  SolverSettings st = s;
  st.newton.residual_tolerance = 1e-12;
  Solver<E, M> sta(mesh, soft, st);
  sta.fix(mesh.node_set("xmin"), {true, false, false});
  sta.fix(mesh.node_set("ymin"), {false, true, false});
  sta.fix(mesh.node_set("zmin"), {false, false, true});
  sta.add_traction(mesh.face_set("xmax"), Vec3(t, 0, 0));
  sta.solve_static(M::constant_tangent ? 1 : 4);
  const Scalar static_err = (sta.displacement() - exact).norm() / exact.norm();

  const int steps = 200;
  Scalar half = 0;
  for (int k = 0; k < steps; ++k) {
    solver.step(0.01);
    if (k == steps / 2 - 1) half = (solver.displacement() - exact).norm() / exact.norm();
  }
  const Scalar end = (solver.displacement() - exact).norm() / exact.norm();
  Scalar tip = 0;
  for (Index i : mesh.node_set("xmax")) tip += solver.displacement(i).x();
  tip /= static_cast<Scalar>(mesh.node_set("xmax").size());
  fmt::print("uniaxial {:6} {:13}: tip u_x {:.9f} (closed form {:.9f}, P L / (E A) = {:.9f}); static solve {:.1e}, "
             "damped run {:.2e} at 1 s, {:.2e} at 2 s from it\n",
             E::name, M::name, tip, 4 * (l.l1 - 1), 4 * t / soft.young, static_err, half, end);
  REQUIRE(state_finite(solver));
  // Static: the closed form is in the FE space; direct solves to round-off (Linear) or Newton
  // to 1e-12 of the force scale: measured <= 1.3e-13; 1e-9.
  REQUIRE(static_err < 1e-9);
  REQUIRE(end < tol);
  REQUIRE((end < half || end < 1e-13));  // approaching it, unless already at round-off
}

}  // namespace

TEST_CASE("a damped bar in uniaxial tension settles on the closed form P L / (E A)", "[solver][damping]") {
  // Traction 150 = 5% of E: the Neo-Hookean answer is 4.8% longer than the linear one
  // (tip 0.2096 against P L / (E A) = 0.2), so the closed form tells the models apart. 2 s =
  // 43 time constants of the critically damped first mode: e^-43 (1 + 43) ~ 1e-17, and the
  // stiff modes are damped by beta K0; what is left is Newton's stopping test at 1e-10 of the
  // force scale, measured 1e-15 (Hex8, Tet4) to 1e-11 (Tet10, the least well conditioned).
  // 1e-9 bounds that by 100x and is far below the distance of any wrong static answer (the
  // linear one for Neo-Hookean is ~5e-2 away).
  damped_uniaxial<Hex8, Linear>(150, 1e-9);
  damped_uniaxial<Tet4, Linear>(150, 1e-9);
  damped_uniaxial<Tet10, Linear>(150, 1e-9);
  damped_uniaxial<Hex8, Corotational>(150, 1e-9);
  damped_uniaxial<Tet4, Corotational>(150, 1e-9);
  damped_uniaxial<Tet10, Corotational>(150, 1e-9);
  damped_uniaxial<Hex8, NeoHookean>(150, 1e-9);
  damped_uniaxial<Tet4, NeoHookean>(150, 1e-9);
  damped_uniaxial<Tet10, NeoHookean>(150, 1e-9);
}

// ---- determinism across threads --------------------------------------------------------------

TEST_CASE("one and two threads: assembly bit for bit, steps to round-off", "[solver][threads]") {
  // The assembly is coloured: each matrix entry and force entry receives its contributions in
  // the same order whatever the thread count, so forces and tangents must be equal bit for bit.
  // The threaded symmetric matrix-vector product adds the contributions a thread makes to an
  // earlier thread's rows after a barrier, which changes the order of a few additions: the same
  // Newton and CG iterations, and displacements that differ by that round-off as 5 steps of
  // 13-16 CG iterations each carry and amplify it (measured 3.2e-13 relative).
  if (max_threads() == 1)
    WARN("built without OpenMP: settings.threads has no effect, so this test cannot tell threads apart");
  const Mesh<Hex8> mesh = bar_mesh<Hex8>(20, 6, 6);
  std::vector<Vector> u, f;
  std::vector<SparseMatrix> K;
  std::vector<std::vector<int>> iterations(2);
  for (int threads : {1, 2}) {
    SolverSettings s;
    s.threads = threads;
    Solver<Hex8, Corotational> solver(mesh, soft, s);
    solver.fix(mesh.node_set("xmin"));
    solver.add_gravity(Vec3(0, 0, -9.81));
    for (int k = 0; k < 5; ++k) {
      const StepReport r = solver.step(0.01);
      iterations[threads - 1].push_back(r.newton_iterations);
      iterations[threads - 1].push_back(r.linear_iterations);
    }
    REQUIRE(state_finite(solver));
    u.push_back(solver.displacement());
    // Assembly at one common state.
    solver.set_state(Vector::Constant(solver.num_dofs(), 0.01), Vector::Zero(solver.num_dofs()));
    f.push_back(solver.internal_force());
    K.push_back(solver.tangent());
  }
  REQUIRE(u[0].norm() > 0);
  const Scalar du = (u[0] - u[1]).norm() / u[0].norm();
  INFO("relative difference of u after 5 steps, 1 vs 2 threads: " << du);
  CHECK(iterations[0] == iterations[1]);
  CHECK(du < 1e-12);
  CHECK((f[0].array() == f[1].array()).all());
  REQUIRE(K[0].nonZeros() == K[1].nonZeros());
  CHECK(std::equal(K[0].valuePtr(), K[0].valuePtr() + K[0].nonZeros(), K[1].valuePtr()));
}

// ---- invariants for every element x elastic model --------------------------------------------

TEMPLATE_LIST_TEST_CASE("invariants of every element and elastic model", "[solver][invariants]", ElasticCombos) {
  using E = typename TestType::E;
  using M = typename TestType::M;
  const Mesh<E> mesh = bar_mesh<E>(4, 2, 2);
  Solver<E, M> solver(mesh, soft);
  const Index n = mesh.num_nodes();

  // At rest: no internal force. Linear: K0 * 0, exactly. Corotational: R = polar(X G) = I to
  // ~eps, so f ~ eps E h^2 per node (h = 1 here, E = 3000): 1e-12 E is ample.
  REQUIRE(solver.internal_force().cwiseAbs().maxCoeff() <= (M::constant_tangent ? 0.0 : 1e-12 * soft.young));

  // A random deformed state: 2% random nodal displacements, then a 60 degree rotation about an
  // oblique axis through the bar's centre.
  std::mt19937 rng(5);
  std::normal_distribution<Scalar> nd(0.0, 0.02);
  const Mat3 Q = Eigen::AngleAxisd(std::numbers::pi / 3, Vec3(1, -2, 3).normalized()).toRotationMatrix();
  const Vec3 c = mesh.nodes().rowwise().mean();
  Vector u(3 * n);
  for (Index i = 0; i < n; ++i) {
    const Vec3 X = mesh.node(i);
    u.segment<3>(3 * i) = Q * (X + Vec3(nd(rng), nd(rng), nd(rng)) - c) + c - X;
  }
  solver.set_state(u, Vector::Zero(3 * n));
  const Vector f = solver.internal_force();
  const Eigen::Matrix3Xd F = as_nodes(f);
  // Linear theory balances moments in the reference configuration (sum X x K0 u = 0 because
  // K0 annihilates infinitesimal rotations about any point); the corotational force must
  // balance them in the current one (x = X + u).
  const Eigen::Matrix3Xd P = M::constant_tangent ? Eigen::Matrix3Xd(mesh.nodes()) : solver.positions();
  Vec3 net = Vec3::Zero(), torque = Vec3::Zero();
  Scalar total = 0;
  for (Index i = 0; i < n; ++i) {
    net += F.col(i);
    torque += P.col(i).cross(F.col(i));
    total += F.col(i).norm();
  }
  const Scalar size = (mesh.nodes().rowwise().maxCoeff() - mesh.nodes().rowwise().minCoeff()).norm();
  const Scalar rel_net = net.norm() / total, rel_torque = torque.norm() / (total * size);
  fmt::print("invariants {:6} {:22}: net force {:.1e}, net torque {:.1e} (relative to sum |f| and sum |f| x size)\n",
             E::name, M::name, rel_net, rel_torque);
  // Sums of ~1e3 nodal forces that cancel: ~n eps relative; 1e-12.
  REQUIRE(rel_net <= 1e-12);
  if (!(std::is_same_v<M, CorotationalPerElement> || std::is_same_v<M, CorotationalMeanDilatation>) ||
      std::is_same_v<E, Tet4>) {
    // Exact theorems: Linear (see above); Corotational with the polar R at every quadrature
    // point, whose stretch part is coaxial with Hooke's stress, so every point's moment
    // vanishes identically (per element for Tet4, where the two variants coincide).
    REQUIRE(rel_torque <= 1e-12);
  } else {
    // CorotationalPerElement on Hex8 and Tet10 (one R from the centre F) does NOT balance moments
    // exactly: the force misses the dR/dx term, which is non-zero for an element that is not
    // homogeneously strained, leaving a net moment of relative size O(strain) (measured here
    // 1.4e-4 Hex8, 2.5e-4 Tet10 at 2% strain; per single element 1e-4 at 0.1%, 2e-3 at 1%,
    // 1e-2 at 10%). Bounded by a tenth of the strain level, 2e-3: a wrong rotation (e.g. R^T
    // for R) would give O(1). See the report: this is a modelling limitation, not round-off.
    REQUIRE(rel_torque <= 2e-3);
  }

  // Symmetric tangent at that state (R K0 R^T block by block): a few ulps.
  const SparseMatrix K = solver.tangent();
  const SparseMatrix KT = K.transpose();
  REQUIRE((K - KT).norm() <= 1e-14 * K.norm());

  // Damped dynamics from rest under gravity settle towards the static solution (bar 4x2x2:
  // omega_1 ~ 7 rad/s; alpha = 14 damps mode 1 critically, the rest like exp(-7 t)). After 3 s
  // (300 steps): exp(-21) ~ 1e-9 for resolved modes, the stiff ones a bit less; default
  // settings (CG 1e-8, Newton 1e-6). Measured 4e-7 (Tet4), 1e-8 (Hex8), 1e-5 (Tet10, whose
  // stiffest modes, omega dt >> 1, decay slowest under the trapezoidal rule). 1e-3 leaves room
  // for that while still failing if the run settled anywhere else.
  damped_to_static<E, M>(mesh, Vec3(0, 0, -9.81), 300, 0.01, 14.0, 1e-3);
}

// ---- reactions, mass ---------------------------------------------------------------------------

TEMPLATE_LIST_TEST_CASE("reactions at the clamp balance the weight, mass = density x volume",
                        "[solver][reactions]", AllElements) {
  using E = TestType;
  const Mesh<E> mesh = bar_mesh<E>(4, 2, 2);
  const Scalar volume = 16, rho = soft.density;
  const Vec3 g(0.5, -1.0, -9.81);
  auto check = [&](auto& solver, const char* what) {
    solver.fix(mesh.node_set("xmin"));
    solver.add_gravity(g);
    solver.solve_static(4);
    const Eigen::Matrix3Xd R = as_nodes(solver.reaction_forces());
    const Vec3 sum = R.rowwise().sum();
    const Vec3 weight = rho * volume * g;
    fmt::print("reactions {:6} {:13}: |sum R + m g| / |m g| = {:.1e}\n", E::name, what,
               (sum + weight).norm() / weight.norm());
    // Equilibrium at free dofs to the Newton tolerance (1e-10 of the load here), plus round-off
    // of the sums (measured 1e-14): 1e-8 as asked.
    REQUIRE((sum + weight).norm() <= 1e-8 * weight.norm());
    // Reactions only at constrained dofs.
    for (Index i = 0; i < mesh.num_nodes(); ++i)
      if (!solver.is_constrained(3 * i)) REQUIRE(R.col(i).norm() == 0);
  };
  // 1e-10, not tighter: the linear model's LDLT residual floor is ~3e-12 to 9e-12 relative on
  // these meshes, and a static Newton that cannot reach its tolerance throws after 50 iterations.
  SolverSettings s;
  s.newton.residual_tolerance = 1e-10;
  Solver<E, Linear> lin(mesh, soft, s);
  check(lin, "Linear");
  Solver<E, Corotational> cor(mesh, soft, s);
  check(cor, "Corotational");

  // Mass: the consistent mass integrates rho N_a N_b exactly, and sum_ab N_a N_b = 1, so its
  // sum is rho V to round-off (1e-13 for ~1e4 terms); HRZ lumping rescales to the same total.
  for (MassKind kind : {MassKind::Consistent, MassKind::Lumped}) {
    SolverSettings ms;
    ms.mass = kind;
    Solver<E, Linear> m(mesh, Material{3000, 0.45, 2.5}, ms);
    REQUIRE(m.mass() == Approx(2.5 * volume).epsilon(1e-13));
    REQUIRE(m.volume() == Approx(volume).epsilon(1e-13));
  }
}

// ---- bad input and the failed-step contract -----------------------------------------------------

TEST_CASE("bad input is rejected with clear errors", "[solver][errors]") {
  const Mesh<Hex8> mesh = bar_mesh<Hex8>(4, 1, 1);
  const Scalar nan = std::numeric_limits<Scalar>::quiet_NaN(), inf = std::numeric_limits<Scalar>::infinity();

  SECTION("invalid material through the constructor") {
    REQUIRE(contains(error_of<InvalidArgument>([&] { (void)Solver<Hex8, Linear>(mesh, Material{-1, 0.3, 1}); }),
                     "Young's modulus"));
    REQUIRE(contains(error_of<InvalidArgument>([&] { (void)Solver<Hex8, Corotational>(mesh, Material{1, 0.5, 1}); }),
                     "Poisson ratio"));
    REQUIRE(contains(error_of<InvalidArgument>([&] { (void)Solver<Tet4, Linear>(bar_mesh<Tet4>(2, 1, 1), Material{1, 0.3, nan}); }),
                     "density"));
  }
  SECTION("a real-time reach that is not > 0") {
    for (Scalar reach : {0.0, -1.0, nan}) {
      SolverSettings s;
      s.newmark.realtime_reach = reach;
      REQUIRE(contains(error_of<InvalidArgument>([&] { (void)Solver<Hex8, Linear>(mesh, soft, s); }), "realtime_reach"));
    }
    SolverSettings s;  // infinity: never redone
    s.newmark.realtime_reach = inf;
    REQUIRE_NOTHROW((void)Solver<Hex8, Linear>(mesh, soft, s));
  }
  SECTION("a Newton residual tolerance outside (0, 1)") {
    // At 1 or more the unloaded start meets it (|r| = |f_ext| there): a static solve under
    // gravity returned u = 0 after no iteration (review).
    for (Scalar tol : {0.0, -1e-6, 1.0, 2.0, 1e6, nan, inf}) {
      SolverSettings s;
      s.newton.residual_tolerance = tol;
      INFO("tolerance " << tol);
      REQUIRE(contains(error_of<InvalidArgument>([&] { (void)Solver<Hex8, Corotational>(mesh, soft, s); }),
                       "residual tolerance in (0, 1)"));
    }
    SolverSettings s;
    s.newton.residual_tolerance = 0.5;  // loose, but a solve: it must move the bar
    Solver<Hex8, Corotational> loose(mesh, soft, s);
    loose.fix(mesh.node_set("xmin"));
    loose.add_gravity(Vec3(0, 0, -9.81));
    loose.solve_static();
    REQUIRE(loose.displacement(mesh.node_set("xmax")[0]).norm() > 0);
  }
  SECTION("Newmark parameters that are not unconditionally stable") {
    for (const auto& [beta, gamma] : {std::pair{0.0, 0.5}, {1.0 / 6, 0.5}, {0.25, 0.4}, {0.3, 0.7}, {nan, 0.5}}) {
      SolverSettings s;
      s.newmark.beta = beta;
      s.newmark.gamma = gamma;
      INFO("beta " << beta << ", gamma " << gamma);
      REQUIRE(contains(error_of<InvalidArgument>([&] { (void)Solver<Hex8, Linear>(mesh, soft, s); }), "unconditionally stable"));
      Solver<Hex8, Linear> ok(mesh, soft);
      REQUIRE(contains(error_of<InvalidArgument>([&] { ok.set_settings(s); }), "unconditionally stable"));
      REQUIRE(ok.settings().newmark.beta == 0.25);  // rejected settings are not kept
    }
    // gamma = 0.6, beta = (gamma + 1/2)^2 / 4 = 0.3025: stable, dissipative; accepted.
    SolverSettings s;
    s.newmark.gamma = 0.6;
    s.newmark.beta = 0.3025;
    REQUIRE(error_of([&] { (void)Solver<Hex8, Linear>(mesh, soft, s); }) == "(no error)");
  }
  SECTION("time step, node indices, no constraint; state unchanged after each failure") {
    Solver<Hex8, Corotational> s(mesh, soft);
    s.add_gravity(Vec3(0, 0, -9.81));
    // No constrained dof: statics are singular; the message says what to do.
    const std::string msg = error_of<SolverError>([&] { s.solve_static(); });
    INFO(msg);
    REQUIRE(contains(msg, "no degree of freedom is constrained"));
    REQUIRE(contains(msg, "fix some nodes"));
    // A bad node in a list: nothing of the call is applied (still no constraint afterwards).
    std::vector<Index> nodes = mesh.node_set("xmin");
    nodes.push_back(mesh.num_nodes());
    REQUIRE(contains(error_of<InvalidArgument>([&] { s.fix(nodes); }),
                     fmt::format("node {} out of range [0, {})", mesh.num_nodes(), mesh.num_nodes())));
    REQUIRE(contains(error_of<SolverError>([&] { s.solve_static(); }), "no degree of freedom is constrained"));
    REQUIRE(contains(error_of<InvalidArgument>([&] { s.add_nodal_force(std::vector<Index>{0, -1}, Vec3(1, 0, 0)); }),
                     "node -1 out of range"));
    REQUIRE(contains(error_of<InvalidArgument>([&] { s.add_nodal_force(std::vector<Index>{0}, Vec3(nan, 0, 0)); }),
                     "must be finite"));
    // A traction acts on the body's surface: a face inside it, or one listed twice (itself, or
    // from the element on its other side), is refused (found by review, 2026-12-01: accepted,
    // the load acted inside the body or counted twice).
    const std::vector<FaceRef> surface = boundary_faces(mesh);
    FaceRef inside{0, -1};
    for (int f = 0; f < Hex8::num_faces && inside.face < 0; ++f)
      if (std::find(surface.begin(), surface.end(), FaceRef{0, f}) == surface.end()) inside.face = f;
    REQUIRE(inside.face >= 0);
    REQUIRE(contains(error_of<InvalidArgument>([&] { s.add_traction({inside}, Vec3(0, 0, 1)); }),
                     fmt::format("traction: face (element 0, local face {}) is shared with element 1: not a boundary face",
                                 inside.face)));
    const FaceRef top = mesh.face_set("zmax")[1];
    REQUIRE(contains(error_of<InvalidArgument>([&] { s.add_traction({top, top}, Vec3(0, 0, 1)); }),
                     fmt::format("traction: face (element {}, local face {}) is listed twice (as entries 0 and 1)",
                                 top.element, top.face)));
    s.fix(mesh.node_set("xmin"));
    s.step(0.01);
    s.step(0.01);
    const Vector u = s.displacement(), v = s.velocity(), a = s.acceleration();
    const Scalar t = s.time();
    // The rejected nodal forces were not added: the work potential is that of gravity alone.
    {
      Solver<Hex8, Corotational> g(mesh, soft);
      g.add_gravity(Vec3(0, 0, -9.81));
      g.set_state(u, v, t);
      REQUIRE(s.external_work_potential() == g.external_work_potential());
    }
    for (Scalar dt : {0.0, -0.01, nan, inf}) {
      INFO("dt = " << dt);
      REQUIRE(contains(error_of<InvalidArgument>([&] { s.step(dt); }), "time step must be finite and > 0"));
      REQUIRE((s.displacement().array() == u.array()).all());
      REQUIRE((s.velocity().array() == v.array()).all());
      REQUIRE((s.acceleration().array() == a.array()).all());
      REQUIRE(s.time() == t);
    }
    REQUIRE(contains(error_of<InvalidArgument>([&] { s.solve_static(0); }), "load_steps"));
    REQUIRE(contains(error_of<InvalidArgument>([&] { s.set_state(Vector::Zero(3), v); }), "state vectors"));
    REQUIRE((s.displacement().array() == u.array()).all());
  }
}

TEST_CASE("a step that fails leaves displacement, velocity, acceleration and time unchanged", "[solver][errors]") {
  const Mesh<Hex8> mesh = bar_mesh<Hex8>(4, 1, 1);
  // Accurate mode with one Newton iteration: a corotational step cannot converge (the first
  // residual check comes after the first update). Tip load 4 x 5 = 20, about the bar's weight:
  // a static deflection of ~40% of the length, so Newton has real work to do.
  SolverSettings one;
  one.newton.max_iterations = 1;
  one.newton.residual_tolerance = 1e-15;  // out of reach in one iteration, predictor or not
  auto expect_unchanged = [](auto& s) {
    const Vector u = s.displacement(), v = s.velocity(), a = s.acceleration();
    const Scalar t = s.time();
    const std::string msg = error_of<SolverError>([&] { s.step(0.01); });
    INFO(msg);
    REQUIRE(contains(msg, "did not converge"));
    CHECK((s.displacement().array() == u.array()).all());
    CHECK((s.velocity().array() == v.array()).all());
    CHECK((s.acceleration().array() == a.array()).all());
    CHECK(s.time() == t);
  };
  SECTION("after successful steps") {
    Solver<Hex8, Corotational> s(mesh, soft);
    s.fix(mesh.node_set("xmin"));
    s.add_nodal_force(mesh.node_set("xmax"), Vec3(0, 0, -5.0));
    s.step(0.01);
    s.step(0.01);
    s.set_settings(one);
    expect_unchanged(s);
    // And the solver is still usable: with enough iterations the same step succeeds and equals
    // the step of a twin that never failed, bit for bit (no scratch state leaks).
    s.set_settings(SolverSettings{});
    Solver<Hex8, Corotational> twin(mesh, soft);
    twin.fix(mesh.node_set("xmin"));
    twin.add_nodal_force(mesh.node_set("xmax"), Vec3(0, 0, -5.0));
    for (int k = 0; k < 3; ++k) twin.step(0.01);
    s.step(0.01);
    REQUIRE((s.displacement().array() == twin.displacement().array()).all());
    REQUIRE((s.velocity().array() == twin.velocity().array()).all());
  }
  SECTION("the very first step") {
    // Before the first step the initial acceleration is not yet known (acceleration() is 0);
    // the step computes it from equilibrium. If the step then fails, acceleration() must still
    // be what it was (it once was not: the initial acceleration was written into the state
    // before the Newton loop).
    Solver<Hex8, Corotational> s(mesh, soft, one);
    s.fix(mesh.node_set("xmin"));
    s.add_nodal_force(mesh.node_set("xmax"), Vec3(0, 0, -5.0));
    expect_unchanged(s);
  }
  SECTION("a static solve that fails") {
    Solver<Hex8, Corotational> s(mesh, soft);
    s.fix(mesh.node_set("xmin"));
    s.add_nodal_force(mesh.node_set("xmax"), Vec3(0, 0, -5.0));
    s.step(0.01);
    s.set_settings(one);
    const Vector u = s.displacement(), v = s.velocity(), a = s.acceleration();
    REQUIRE(contains(error_of<SolverError>([&] { s.solve_static(); }), "static solve failed"));
    CHECK((s.displacement().array() == u.array()).all());
    CHECK((s.velocity().array() == v.array()).all());
    CHECK((s.acceleration().array() == a.array()).all());
  }
}

// ---- real-time vs accurate ----------------------------------------------------------------------

TEST_CASE("real-time and accurate Newmark agree on bar90 within a few percent", "[solver][realtime]") {
  const Mesh<Hex8> mesh = bar_mesh<Hex8>(10, 3, 3);
  const std::vector<Index>& tip = mesh.node_set("xmax");
  std::vector<Scalar> tip_z;
  std::vector<int> max_newton;
  for (NewmarkMode mode : {NewmarkMode::Accurate, NewmarkMode::RealTime}) {
    SolverSettings s;
    s.newmark.mode = mode;
    Solver<Hex8, Corotational> solver(mesh, soft, s);
    solver.fix(mesh.node_set("xmin"));
    solver.add_gravity(Vec3(0, 0, -9.81));
    int most = 0, least = 1 << 30;
    for (int k = 0; k < 100; ++k) {
      const StepReport r = solver.step(0.01);
      most = std::max(most, r.newton_iterations);
      least = std::min(least, r.newton_iterations);
    }
    REQUIRE(state_finite(solver));
    if (mode == NewmarkMode::RealTime) {
      REQUIRE(most == 1);
      REQUIRE(least == 1);
    }
    tip_z.push_back(mean_uz(solver, tip));
    max_newton.push_back(most);
  }
  const Scalar diff = std::abs(tip_z[1] - tip_z[0]) / std::abs(tip_z[0]);
  fmt::print("bar90 Hex8 corotational, 100 steps of 0.01: tip uz accurate {:.5f} (<= {} Newton it./step), "
             "real-time {:.5f}: relative difference {:.2e}\n",
             tip_z[0], max_newton[0], tip_z[1], diff);
  // Real time solves each step's equations linearised at u_n, so each increment is wrong by a
  // fraction of the order of the rotation increment per step (the end turns by ~0.6 rad in the
  // 100 steps, ~6e-3 rad per step); accumulated over a quarter period, the tip is off by a
  // comparable fraction, well under a percent (measured 1.6e-4 with the exact tangent at u_n,
  // 1.8e-3 with the warped one, which also errs in the linearisation). The bound is 1%, tighter than
  // the 5% suggested, since 5% would not catch an error several times the expected size.
  REQUIRE(diff < 0.01);
  REQUIRE(tip_z[0] < 0);  // it fell
}

TEST_CASE("real-time mode stays bounded over long runs (Tet10 corotational bar90, 2 s)", "[solver][realtime][extreme]") {
  // Regression: one linearised solve per step started from the constant-acceleration predictor
  // instead of u_n gained energy without bound here (kinetic energy 7e6 at 2 s against a peak
  // of ~1e3 in accurate mode). The bar falls under gravity from rest: the energy available is
  // the work of gravity, so the kinetic energy can never exceed the accurate run's by much.
  const Mesh<Tet10> mesh = bar_mesh<Tet10>(10, 3, 3);
  std::vector<Scalar> peak;
  for (NewmarkMode mode : {NewmarkMode::Accurate, NewmarkMode::RealTime}) {
    SolverSettings s;
    s.newmark.mode = mode;
    s.linear.tolerance = 1e-6;
    Solver<Tet10, Corotational> solver(mesh, Material{3000, 0.45, 1.0}, s);
    solver.fix(mesh.node_set("xmin"));
    solver.add_gravity(Vec3(0, 0, -9.81));
    Scalar most = 0;
    for (int k = 0; k < 200; ++k) {
      solver.step(0.01);
      most = std::max(most, solver.kinetic_energy());
    }
    REQUIRE(state_finite(solver));
    peak.push_back(most);
  }
  fmt::print("Tet10 bar90 corotational, 2 s: peak kinetic energy accurate {:.4g}, real-time {:.4g}\n", peak[0], peak[1]);
  // Real time is a different discretisation (linearised per step), so its peak differs by a
  // few percent (measured below 1%); 1.5x would already mean energy is being created.
  CHECK(peak[1] < 1.5 * peak[0]);
}

TEMPLATE_TEST_CASE("translated copies share element data, and a far-translated body moves the same", "[solver][sharing]",
                   Linear, CorotationalPerElement, Corotational, NeoHookean) {
  using M = TestType;
  const Mesh<Hex8> bar = bar_mesh<Hex8>(6, 2, 2);
  const Mesh<Tet4> tets = bar_mesh<Tet4>(6, 2, 2);
  CHECK(Solver<Hex8, M>(bar, soft).num_element_shapes() == 1);  // every cube is a translated copy
  CHECK(Solver<Tet4, M>(tets, soft).num_element_shapes() == 6);  // the six Kuhn tets of a cube
  // A perturbed mesh has no two equal shapes.
  Eigen::Matrix3Xd X = bar.nodes();
  std::mt19937 rng(11);
  std::uniform_real_distribution<Scalar> jitter(-0.05, 0.05);
  for (Index i = 0; i < X.cols(); ++i)
    for (int d = 0; d < 3; ++d) X(d, i) += jitter(rng);
  const Mesh<Hex8> perturbed(X, bar.elements());
  CHECK(Solver<Hex8, M>(perturbed, soft).num_element_shapes() == perturbed.num_elements());
  // The same bar 1000 lengths away (positions ~7e3): the models see x = X + u, whose round-off
  // 2 x 1.1e-16 x 7e3 ~ 1.5e-12 over a unit cell is a strain error of that size, against
  // strains of a few 1e-4 after 10 steps: ~5e-9 relative expected (measured 2e-9), and no more
  // since shared element data is differenced relative to node 0, never against the offset.
  auto run = [](const Mesh<Hex8>& mesh) {
    Solver<Hex8, M> s(mesh, soft);
    s.fix(mesh.node_set("xmin"));
    s.add_gravity(Vec3(0, 0, -9.81));
    for (int k = 0; k < 10; ++k) s.step(0.01);
    return Vector(s.displacement());
  };
  Eigen::Matrix3Xd far = bar.nodes();
  far.colwise() += Vec3(6000, -3000, 2000);
  Mesh<Hex8> bar_far(far, bar.elements());
  bar_far.add_node_set("xmin", bar.node_set("xmin"));
  const Vector u0 = run(bar), u1 = run(bar_far);
  const Scalar diff = (u1 - u0).norm() / u0.norm();
  INFO(M::name << ": relative difference after 10 steps, translated by ~7e3: " << diff);
  CHECK(diff < 2e-8);
}

// ---- exact corotational tangent ---------------------------------------------------------------

TEST_CASE("corotational statics: exact and warped tangents reach the same equilibrium, only the exact one at 3 g",
          "[solver][corotational][tangent]") {
  // The SCENES bar (bar90 Hex8, E 3000, nu 0.45) clamped at x = 0 under gravity, statics with
  // 8 load steps. The tangent changes Newton's path, never its fixed point: at 1 g both reach
  // f_int = f_ext to 1e-6 of the force scale, so their tips agree to about that relative to
  // the stiffness-scaled solution (measured 1.2e-7; bound 5e-6). The exact tangent (the
  // derivative of each point's rotation included) converges quadratically: fewer iterations
  // (measured 31 against 55). Under 3 g the tip rotates by ~1 rad; the warped R K0 R^T then
  // loses Newton's convergence at 63% of the load whatever the cutting (seen in the accuracy
  // study), and the exact one converges (measured 42 iterations).
  const Mesh<Hex8> mesh = bar_mesh<Hex8>(10, 3, 3);
  const Index tip = mesh.num_nodes() - 1;  // (10, 3, 3)
  REQUIRE((mesh.node(tip) - Vec3(10, 3, 3)).norm() == 0);
  auto solve = [&](Scalar g, bool exact) {
    SolverSettings st;
    st.newton.exact_tangent = exact;
    st.static_linear = {LinearSolverKind::Direct};
    Solver<Hex8, Corotational> s(mesh, Material{3000, 0.45, 1.0}, st);
    s.fix(mesh.node_set("xmin"));
    s.add_gravity(Vec3(0, 0, -9.81 * g));
    const StepReport r = s.solve_static(8);
    REQUIRE(state_finite(s));
    return std::pair{s.displacement(tip), r.newton_iterations};
  };
  const auto [u_exact, it_exact] = solve(1, true);
  const auto [u_warped, it_warped] = solve(1, false);
  const auto [u3, it3] = solve(3, true);
  fmt::print("bar90 Hex8 corotational statics: 1 g tip uz {:.7f} exact ({} Newton it.) vs {:.7f} warped ({}); "
             "3 g exact: {:.5f} ({} it.)\n",
             u_exact.z(), it_exact, u_warped.z(), it_warped, u3.z(), it3);
  REQUIRE((u_exact - u_warped).norm() <= 5e-6 * u_exact.norm());
  REQUIRE(it_exact < it_warped);
  REQUIRE(u3.z() < 1.5 * u_exact.z());  // it bends further, less than linearly (it stiffens by rotating)
  REQUIRE(u3.z() > 3 * u_exact.z());
  REQUIRE_THROWS_AS(solve(3, false), SolverError);
}

TEMPLATE_TEST_CASE("a settled body is accepted by every later solve: static solves again, then steps (Tet4 unit cells)",
                   "[solver][statics][convergence]", Linear, Corotational, NeoHookean) {
  // Issue 33 item 4. A 2 x 2 x 2 box of Kuhn Tet4 unit cells, clamped at x = 0 and pulled by
  // 0.2 at x = 1 by prescribed displacements only: no load, so at equilibrium the free internal
  // forces (the statics scale) are the residual itself, and the only force scale a later solve
  // can hold it to is the round-off floor. At rest on integer nodes the Tet4 kernels are exact
  // (f_int = 0 bit for bit), so a floor measured there was 0 and a second or third solve, or
  // the next step, failed at |r| ~ 1e-11 ("did not converge").
  const Mesh<Tet4> mesh = box_tet4_kuhn({2, 2, 2});
  Solver<Tet4, TestType> s(mesh, soft);
  s.fix(mesh.node_set("xmin"));
  s.prescribe(mesh.node_set("xmax"), [](Scalar, const Vec3&) { return Vec3(0.2, 0, 0); });
  auto attempt = [&](const char* what, const auto& run) {
    const std::string err = error_of([&] {
      const StepReport r = run();
      fmt::print("settled Tet4 box, {}: {} {} Newton it., |r| = {:.3g}\n", TestType::name, what, r.newton_iterations,
                 r.residual);
    });
    if (err != "(no error)") fmt::print("settled Tet4 box, {}: {} failed: {}\n", TestType::name, what, err);
    return err == "(no error)";
  };
  REQUIRE(attempt("solve 1", [&] { return s.solve_static(); }));
  CHECK(attempt("solve 2", [&] { return s.solve_static(); }));
  // Settled: solve 1 stops at 1e-6 of its own scale (the pull's first imbalance), solve 2 from
  // there near the round-off (measured |r| 4e-12 to 6e-10). A later solve or step starts from
  // that state and corrects only such a residual: a displacement of order |r| / (E h) < 1e-12
  // (E 3000, h 1), far under the 1e-10 |u| allowed (|u| > 0.6: nine nodes pulled by 0.2).
  const Vector u2 = s.displacement();
  CHECK(attempt("solve 3", [&] { return s.solve_static(); }));
  CHECK((s.displacement() - u2).norm() <= 1e-10 * u2.norm());
  CHECK(attempt("step 1", [&] { return s.step(0.01); }));
  CHECK(attempt("step 2", [&] { return s.step(0.01); }));
  CHECK((s.displacement() - u2).norm() <= 1e-10 * u2.norm());  // and the steps leave it there
}

TEST_CASE("a static solve from a state in motion ramps from the load its displacement balances statically",
          "[solver][statics]") {
  // Statics ramp the load from the one the state balances. After a step the state's load is
  // f_ext(t), balanced with M a + D v; ramping from it asked every fraction of the ramp for the
  // whole load at once, and the solve failed at fraction 5e-5 after 10 cuts though the body had
  // moved by 7e-11 (found by review, 2026-12-01). It now starts from f_int(u): the same ramp as
  // from rest, so the same increments (the 20 asked, cut to 80) and the same equilibrium
  // (elastic, so path independent, to the Newton tolerance's effect: 1e-6 of the load over a
  // stiffness ~E h).
  const Mesh<Hex8> mesh = bar_mesh<Hex8>(8, 1, 1);
  for (NewmarkMode mode : {NewmarkMode::Accurate, NewmarkMode::RealTime}) {
    INFO((mode == NewmarkMode::Accurate ? "accurate" : "real time"));
    SolverSettings st;
    st.newmark.mode = mode;
    st.newton.max_iterations = 6;
    auto loaded = [&] {
      Solver<Hex8, NeoHookean> s(mesh, Material{3000, 0.45, 1.0}, st);
      s.fix(mesh.node_set("xmin"));
      s.add_nodal_force(mesh.node_set("xmax"), Vec3(0, 20, 0));
      return s;
    };
    Solver<Hex8, NeoHookean> rest = loaded(), moving = loaded();
    const StepReport from_rest = rest.solve_static(20);
    moving.step(1e-6);
    REQUIRE(moving.displacement().norm() > 0);
    REQUIRE(moving.velocity().norm() > 0);
    StepReport from_motion;
    REQUIRE(error_of([&] { from_motion = moving.solve_static(20); }) == "(no error)");
    CHECK(from_motion.load_steps == from_rest.load_steps);
    const Vector& u = rest.displacement();
    CHECK(u.norm() > 1);  // a large deflection: the tip moves by about 4.4
    CHECK((moving.displacement() - u).norm() <= 1e-6 * u.norm());
    CHECK(moving.velocity().norm() == 0);
  }
}

namespace {
// A nonlinear problem written outside the library, to show what newton() asks of one
// (NewtonProblem): r(u) = A u + u.^3 - b, the gradient of Pi(u) = u'Au/2 + sum u_i^4/4 - b'u,
// with K = A + 3 diag(u.^2) (A symmetric positive definite: Pi is convex, one root), solved
// densely.
struct CubicSprings {
  Eigen::Matrix2d A;
  Eigen::Vector2d b;
  Eigen::Vector2d r = Eigen::Vector2d::Zero();
  Eigen::Matrix2d K = Eigen::Matrix2d::Identity();
  bool tangent_now = false;
  std::vector<Scalar> residuals;  // |r| of the evaluations, in order, a repeated value once

  Scalar residual(const Vector& u, bool with_tangent) {
    r = A * u + u.array().cube().matrix() - b;
    if (with_tangent) K = A + Eigen::Matrix2d(3 * u.array().square().matrix().asDiagonal());
    tangent_now = with_tangent;
    if (residuals.empty() || residuals.back() != r.norm()) residuals.push_back(r.norm());  // the tangent's own call repeats it
    return r.norm();
  }
  void tangent(const Vector& u) { residual(u, true); }
  bool tangent_current() const { return tangent_now; }
  Scalar scale() const { return b.norm(); }
  LinearSolveReport solve(int, Scalar, Scalar, Vector& du) {
    du = K.ldlt().solve(-r);
    return {1, 0, true};
  }
  bool fall_back() { return false; }
  [[noreturn]] void invalid(const Vector&) const { fail<SolverError>("CubicSprings: r is not finite"); }
  Scalar merit(const Vector& u) const { return 0.5 * u.dot(A * u) + u.array().pow(4).sum() / 4 - b.dot(u); }
  Scalar slope(const Vector& du) const { return r.dot(du); }
  bool eager_tangent() const { return false; }
};
static_assert(NewtonProblemWithPotential<CubicSprings>);
static_assert(!NewtonProblem<Vector>);
static_assert(LineSearch<ResidualBacktracking, CubicSprings> && LineSearch<EnergyArmijo, CubicSprings>);
}  // namespace

TEST_CASE("newton() solves a problem written outside the library, quadratically", "[solver][newton]") {
  CubicSprings p;
  p.A << 2, -1, -1, 2;
  p.b << 1, 20;
  NewtonOptions o;
  o.tolerance = 1e-13;
  o.line_search = true;
  auto run = [&](const auto& search) {
    p.residuals.clear();
    Vector u = Vector::Zero(2), du(2), u_new(2);
    const NewtonResult res = newton(p, u, o, search, du, u_new);
    REQUIRE(res.converged);
    // The root, checked by evaluating r independently of the solve.
    const Eigen::Vector2d r = p.A * u + u.array().cube().matrix() - p.b;
    REQUIRE(r.norm() <= 1e-13 * p.b.norm());
    // Quadratic convergence: once |r| < 1, |r_k+1| <= C |r_k|^2 with C of the order of
    // |K^-1| |d2r/du2| = 6 |u| / lambda_min(K) <= 6 * 3 / 1 here (the evaluations along the
    // converged path: a full step is accepted at once near the root).
    int quadratic_steps = 0;
    for (size_t k = 0; k + 1 < p.residuals.size(); ++k)
      if (p.residuals[k] < 1 && p.residuals[k + 1] > 1e-14 * p.b.norm()) {
        REQUIRE(p.residuals[k + 1] <= 20 * p.residuals[k] * p.residuals[k]);
        ++quadratic_steps;
      }
    REQUIRE(quadratic_steps >= 2);
    return u;
  };
  const Vector by_residual = run(ResidualBacktracking{});
  const Vector by_energy = run(EnergyArmijo{});
  REQUIRE((by_residual - by_energy).norm() <= 1e-12);
  // A residual that is not finite ends in the problem's own error.
  p.b << 1, std::numeric_limits<Scalar>::quiet_NaN();
  Vector u = Vector::Zero(2), du(2), u_new(2);
  REQUIRE_THROWS_AS(newton(p, u, o, ResidualBacktracking{}, du, u_new), SolverError);
}
