// Extremes: the solver at the edges of its parameters. Every case asserts that no NaN or Inf is
// committed, that the energy stays bounded, and that the outcome makes sense, and prints one
// line of figures (fmt::print) so the CI log shows them.
//
// Facts checked, one per case:
//  1. Poisson ratio 0.499, every element and every elastic model (23 compositions): a clamped
//     bar under an end traction of nominal strain 1% solves statically, and 10 dynamic steps of
//     the suddenly applied load run, with the volume change bounded by what nu = 0.499 allows;
//  2. Young's modulus from 1e1 to 1e9: the same load scaled with E gives the same static
//     displacement (Linear to 1e-9, the nonlinear models to the Newton tolerance), and with
//     the time step scaled by 1/sqrt(E) the same motion; at a fixed dt dynamic steps stay
//     finite (Linear: energy equal to the input work);
//  3. time steps from 1e-6 to 1.0 on the SCENES bar90 under gravity: finite, and the energy
//     equals the work of the load (Linear: to the solver tolerance; nonlinear models: to the
//     trapezoidal rule's O(dt^2) error while omega dt is small, bounded beyond);
//  4. 100,000 steps of an undamped linear bar in free vibration: the trapezoidal rule conserves
//     the energy to round-off (direct solver), and to the CG tolerance with the default solver;
//  5. a grasper pulls the end of a 4-long bar 40 (10 lengths) away and lets go: every step
//     either commits a finite state or throws SolverError leaving the state bit for bit as it
//     was; after the release the energy of the damped bar falls and that of the undamped one
//     stays bounded (Corotational; Neo-Hookean with Newmark's numerical dissipation);
//  6. the end face of a bar twisted by 4 pi and back (statics in load steps, dynamics along a
//     smooth path), Corotational and Neo-Hookean: converges, finite, and back at 0 the
//     displacement returns to 0 (to the Newton tolerance);
//  7. a body with every node fixed (or every node on a prescribed path): static solves and
//     dynamic steps succeed at once and u is exactly the prescribed one;
//  8. free flight (no constraint, no load), every element and both mass kinds: linear momentum
//     conserved to round-off; a spinning corotational body keeps its angular momentum and
//     energy within the trapezoidal rule's O((omega dt)^2);
//  9. a plastic bar spinning freely at 10 rad/s, stretch and rotation flowing, both policies:
//     the material mesh is not turned (the spin is rigid motion), its volume kept to 1e-3;
// 10. 5000 steps of a cyclic end traction on a plastic bar (issue 33's scene): no update
//     rejected twice in a row, still flowing at the end, the material volume within 0.1 % with a
//     restitution of 10/s and 0.5 % with the paper's 1/s (tagged [long]: 37 s);
// 11. a cut through a badly drawn sheet (a needle, a point, a repeat, a turned triangle) lying
//     exactly on a plane of nodes, both enrichments: repaired, and the free half falls as the
//     closed-form damped free fall; a sheet that misses is refused;
// 12. a grasp following device samples with +-0.02 of noise, accurate and real time: the nodes
//     are exactly on the samples' path, and after the release the energy falls.
//
// Cases 1-9, 11 and 12 run in ~12 s (Release, one core). The two library defects
// found while writing them (stiff bodies refused by the direct solvers, converged steps reported
// as stagnated) are fixed; their regression tests are at the end of the file.
#include "catch.hpp"
#include "moved_mesh.hpp"
#include "material_mesh.hpp"

#include <plastifem/cutting.hpp>
#include <plastifem/plasticity.hpp>
#include <plastifem/plastifem.hpp>

#include <fmt/core.h>

#include <chrono>
#include <cmath>
#include <numbers>
#include <random>
#include <string>

using namespace plastifem;
using test::material_volume;

namespace {

const Material soft{3000, 0.45, 1.0};  // SCENES.md bar material

template <class... Ms>
struct Models {};
using CommonModels = Models<Linear, Corotational, CorotationalPerElement, NeoHookean, NeoHookeanAbaqus, StableNeoHookean>;
using MeanDilatationModels = Models<LinearMeanDilatation, CorotationalMeanDilatation, NeoHookeanMeanDilatation,
                                    NeoHookeanAbaqusMeanDilatation, StableNeoHookeanMeanDilatation>;

template <class S>
bool state_finite(const S& s) {
  return s.displacement().allFinite() && s.velocity().allFinite() && s.acceleration().allFinite() &&
         std::isfinite(s.time());
}

double ms_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

const char* mass_name(MassKind k) { return k == MassKind::Lumped ? "lumped" : "consistent"; }

/// Mean x displacement of the nodes in `nodes`.
template <class S>
Scalar mean_x(const S& s, const std::vector<Index>& nodes) {
  Scalar x = 0;
  for (Index i : nodes) x += s.displacement(i).x();
  return x / static_cast<Scalar>(nodes.size());
}

/// Rotation by theta about the x axis through (., cy, cz), as a displacement of X.
Vec3 twist_displacement(Scalar theta, const Vec3& X, Scalar cy = 0.5, Scalar cz = 0.5) {
  const Scalar c = std::cos(theta), s = std::sin(theta);
  const Scalar y = X.y() - cy, z = X.z() - cz;
  return Vec3(0, cy + c * y - s * z - X.y(), cz + s * y + c * z - X.z());
}

// --- 1. nu = 0.499 ------------------------------------------------------------------------

/// A 6 x 2 x 2 bar clamped at x = 0 under a traction sigma = 0.01 E along +x on x = 6.
template <FiniteElement E, class M>
void poisson_0499() {
  const Mesh<E> mesh = bar_mesh<E>(6, 2, 2);
  const Material mat{3000, 0.499, 1.0};
  const Scalar strain = 0.01, sigma = strain * mat.young;
  const auto t0 = std::chrono::steady_clock::now();
  auto set_up = [&](Solver<E, M>& s) {
    s.fix(mesh.node_set("xmin"));
    s.add_traction(mesh.face_set("xmax"), Vec3(sigma, 0, 0));
  };
  Solver<E, M> st(mesh, mat);
  set_up(st);
  const Scalar V0 = st.volume();
  const StepReport r = st.solve_static(1);
  REQUIRE(state_finite(st));
  const Scalar tip = mean_x(st, mesh.node_set("xmax"));
  const Scalar dv_static = st.volume() / V0 - 1;

  // Dynamics: the same load applied suddenly at t = 0 to the bar at rest, 10 steps of 0.01.
  Solver<E, M> dy(mesh, mat);
  set_up(dy);
  int newton = 0, cg = 0, substeps = 0;
  Scalar W_max = 0, H_max = 0, dv_dynamic = 0;
  for (int k = 0; k < 10; ++k) {
    const StepReport q = dy.step(0.01);
    REQUIRE(state_finite(dy));
    newton += q.newton_iterations, cg += q.linear_iterations, substeps += q.substeps;
    const Scalar W = dy.external_work_potential();  // f . u: the work of the constant load
    W_max = std::max(W_max, W);
    H_max = std::max(H_max, std::abs(dy.kinetic_energy() + dy.strain_energy() - W));
    dv_dynamic = std::max(dv_dynamic, std::abs(dy.volume() / V0 - 1));
  }
  fmt::print("nu 0.499 {:5} {:30}: static Newton {}, tip {:.4f} (sigma L / E = {:.2f}), V/V0 - 1 = {:.2e}; "
             "dynamic 10 steps: Newton {}, CG {}, sub-steps {}, |KE + SE - W| / W = {:.1e}, max |V/V0 - 1| = {:.1e}; "
             "{:.0f} ms\n",
             E::name, M::name, r.newton_iterations, tip, sigma * 6 / mat.young, dv_static, newton, cg, substeps,
             H_max / W_max, dv_dynamic, ms_since(t0));
  // The bar stretches: between a fully locked answer (Hex8 locks to 0.43 of sigma L / E here,
  // measured) and a bit more than the free uniaxial one (the clamp only stiffens).
  CHECK(tip > 0.3 * sigma * 6 / mat.young);
  CHECK(tip < 1.1 * sigma * 6 / mat.young);
  // Volume: in uniaxial stress tr(eps) = (1 - 2 nu) sigma / E = 2e-5, which the hyperelastic
  // models' J - 1 = p / K reproduces; the small-strain models measure the deformed volume with
  // J = (1 + eps)(1 - nu eps)^2, which adds -(2 nu - nu^2) eps^2 ~ -eps^2 = -1e-4. Bound
  // (1 - 2 nu) eps + 1.5 eps^2 = 1.7e-4 statically (the clamp's triaxial corner adds a little:
  // measured at most 4.9e-5); in dynamics the sudden load overshoots to at most twice the
  // static strain, so (1 - 2 nu) 2 eps + 1.5 (2 eps)^2 = 6.4e-4 (measured at most 9.5e-5). The
  // same load at nu = 0.3 changes the volume by (1 - 2 nu) eps = 4e-3, far above either bound.
  CHECK(std::abs(dv_static) < (1 - 2 * mat.poisson) * strain + 1.5 * strain * strain);
  CHECK(dv_dynamic < (1 - 2 * mat.poisson) * 2 * strain + 1.5 * 4 * strain * strain);
  // Energy: undamped trapezoidal steps conserve KE + SE - f.u (= 0 from rest) exactly for a
  // linear model, up to the accepted residual (CG, Newton: 1e-6 relative; measured <= 1e-5);
  // for the nonlinear models up to O(dt^2) terms of the nonlinearity (measured <= 1.3e-4).
  CHECK(H_max <= 1e-3 * W_max);
}

template <FiniteElement E, class... Ms>
void poisson_0499_all(Models<Ms...>) {
  (poisson_0499<E, Ms>(), ...);
}

// --- 2. E from 1e1 to 1e9 --------------------------------------------------------------------

/// A 6 x 2 x 2 Hex8 bar clamped at x = 0, end traction E (0.002, 0, -0.003) (bending and
/// stretch, tip deflection ~0.5, 8% of the length: the nonlinear models are nonlinear here).
/// For each E: a static solve; 10 dynamic steps of dt = 0.01 from rest under the suddenly
/// applied load; and 10 steps of dt = 0.01 sqrt(10 / E), the time scale on which the scaled
/// problem is the E = 10 one (M a + K(E) u = f(E) with f, K ~ E and dt ~ 1 / sqrt(E): the same
/// Newmark equations, so the same displacements).
template <class M>
void young_decades(const SolverSettings& settings, int first_decade, int last_decade, const char* what) {
  const Mesh<Hex8> mesh = bar_mesh<Hex8>(6, 2, 2);
  const auto t0 = std::chrono::steady_clock::now();
  Vector u_ref, u_dyn_ref;
  Scalar worst = 0, worst_dyn = 0;
  int newton_min = 1 << 30, newton_max = 0;
  std::string energies;
  for (int p = first_decade; p <= last_decade; ++p) {
    const Scalar E = std::pow(10.0, p);
    const Material mat{E, 0.45, 1.0};
    const Vec3 traction = E * Vec3(0.002, 0, -0.003);
    auto set_up = [&](Solver<Hex8, M>& s) {
      s.fix(mesh.node_set("xmin"));
      s.add_traction(mesh.face_set("xmax"), traction);
    };
    Solver<Hex8, M> st(mesh, mat, settings);
    set_up(st);
    const StepReport r = st.solve_static(4);
    REQUIRE(state_finite(st));
    newton_min = std::min(newton_min, r.newton_iterations), newton_max = std::max(newton_max, r.newton_iterations);
    if (u_ref.size() == 0) u_ref = st.displacement();
    worst = std::max(worst, (st.displacement() - u_ref).norm() / u_ref.norm());

    // Fixed dt = 0.01: omega dt grows like sqrt(E) (beam theory omega_1 dt ~ 2e-3 and the
    // mesh's highest omega dt ~ 0.2 at E = 10; 1e4 times these at E = 1e9).
    Solver<Hex8, M> dy(mesh, mat, settings);
    set_up(dy);
    Scalar W_max = 0, H_max = 0;
    for (int k = 0; k < 10; ++k) {
      dy.step(0.01);
      REQUIRE(state_finite(dy));
      const Scalar W = dy.external_work_potential();
      W_max = std::max(W_max, W);
      H_max = std::max(H_max, std::abs(dy.kinetic_energy() + dy.strain_energy() - W));
    }
    energies += fmt::format(" {:.0e}", H_max / W_max);
    // Linear: KE + SE = f . u (from rest, constant load) whatever omega dt, to the accepted
    // residual (measured <= 2.8e-4 at E = 1e9, where CG works hardest). The nonlinear models
    // only stay finite: the trapezoidal rule is not energy-stable for them at omega dt >> 1
    // (measured up to 365 times the input work for Corotational at E = 1e7, see the report).
    if (M::constant_tangent) CHECK(H_max < 1e-3 * W_max);

    // Time scaled with the material: the E = 10 motion.
    Solver<Hex8, M> sc(mesh, mat, settings);
    set_up(sc);
    for (int k = 0; k < 10; ++k) sc.step(0.01 * std::sqrt(std::pow(10.0, first_decade) / E));
    REQUIRE(state_finite(sc));
    if (u_dyn_ref.size() == 0) u_dyn_ref = sc.displacement();
    worst_dyn = std::max(worst_dyn, (sc.displacement() - u_dyn_ref).norm() / u_dyn_ref.norm());
  }
  fmt::print("E 1e{}..1e{} {:12} ({}): static Newton {}..{} iterations, max |u(E) - u(1e{})| / |u| = {:.1e} (tip z "
             "{:.4f}); dt ~ 1/sqrt(E): max difference {:.1e}; dt = 0.01: |KE + SE - W| / W per decade{}; {:.0f} ms\n",
             first_decade, last_decade, M::name, what, newton_min, newton_max, first_decade, worst,
             u_ref[3 * mesh.node_set("xmax").back() + 2], worst_dyn, energies, ms_since(t0));
  // Load and stiffness scale together: every Newton iterate is the same up to the round-off of
  // the scaling, so the solves agree to round-off times the conditioning (measured <= 1e-13).
  // Linear: 1e-9. Nonlinear: to the Newton tolerance (1e-6), which they agree far better
  // than, since the same iterates are accepted.
  const Scalar tolerance = M::constant_tangent ? 1e-9 : settings.newton.residual_tolerance;
  CHECK(worst < tolerance);
  CHECK(worst_dyn < tolerance);
}

// --- 3. dt from 1e-6 to 1 --------------------------------------------------------------------

/// SCENES bar90 (Hex8, clamped, gravity, from rest), 20 steps of each dt.
template <class M>
void time_step_decades() {
  const Mesh<Hex8> mesh = bar_mesh<Hex8>(10, 3, 3);
  const auto t0 = std::chrono::steady_clock::now();
  std::string line;
  for (int p = -6; p <= 0; ++p) {
    const Scalar dt = std::pow(10.0, p);
    Solver<Hex8, M> s(mesh, soft);
    s.fix(mesh.node_set("xmin"));
    s.add_gravity(Vec3(0, 0, -9.81));
    Scalar W_max = 0, H_max = 0;
    int newton = 0, substeps = 0, taken = 0;
    for (; taken < 20; ++taken) {
      const auto before = s.state();
      try {
        const StepReport r = s.step(dt);
        newton += r.newton_iterations, substeps += r.substeps;
      } catch (const SolverError&) {
        REQUIRE(s.state() == before);  // refused: the state as it was
        break;
      }
      REQUIRE(state_finite(s));
      const Scalar W = s.external_work_potential();
      W_max = std::max(W_max, W);
      H_max = std::max(H_max, std::abs(s.kinetic_energy() + s.strain_energy() - W));
    }
    // Every step is taken up to dt = 0.1 (omega_1 dt ~ 1). At dt = 1 a nonlinear model may be
    // refused: the trapezoidal rule is known to gain energy on a nonlinear body at omega dt >> 1
    // (Simo & Tarnow 1992), and Corotational reaches a state at t = 15 from which no step, not
    // even 64 sub-steps of 1/64, converges in 50 Newton iterations (measured: refused at
    // t = 16). A SolverError with the state unchanged is the answer the
    // standards ask for; before Newton's scale excluded the predictor's forces, the step was
    // accepted unbalanced and the run ended at 3.7 times the input work.
    if (M::constant_tangent || dt <= 0.1) CHECK(taken == 20);
    CHECK(s.time() == Approx(taken * dt).epsilon(1e-12));
    const Scalar rel = W_max > 0 ? H_max / W_max : 0;
    line += fmt::format(" | 1e{}: {:.1e} ({} N, {} sub{})", p, rel, newton, substeps,
                        taken < 20 ? fmt::format(", refused at t = {:g}", (taken + 1) * dt) : "");
    // Undamped Newmark (1/4, 1/2) from rest under a constant load: KE + SE - f.u = 0 exactly
    // for a linear model, whatever dt (unconditionally stable, no numerical dissipation); what
    // remains is the accepted residual (inexact CG, 1e-6 of the force scale at most; measured
    // <= 2.8e-8).
    if (M::constant_tangent) CHECK(rel < 1e-6);
    // Nonlinear models: the trapezoidal rule is not energy conserving; its error is
    // O((omega dt)^2) in the nonlinear part while the step resolves the motion (measured
    // <= 1.1e-6 up to dt = 0.01, 1.3e-3 at dt = 0.1, where omega_1 dt ~ 1 for bar90), and at
    // omega dt >> 1 nothing bounds it (Simo & Tarnow 1992): measured 8.6 times the input work
    // for Corotational at dt = 1 before the refusal, 0.25 for NeoHookean. Asserted: 1e-4 while
    // dt <= 0.01, 1e-2 at 0.1; at dt = 1 only that each step is finite or refused (the
    // dissipative scheme that bounds the energy there is below).
    else if (dt <= 0.01) CHECK(rel < 1e-4);
    else if (dt <= 0.1) CHECK(rel < 1e-2);
  }
  fmt::print("dt 1e-6..1 bar90 {:12}: max |KE + SE - W| / W per dt{}; {:.0f} ms\n", M::name, line, ms_since(t0));
}

/// bar90 as above, 20 steps of dt = 1 (omega_1 dt ~ 3.5) with generalized-alpha at rho_inf =
/// 0.5: every step taken, and the energy stays below the input work. From rest under a constant
/// load the work done is f.u, and a scheme that dissipates the unresolved modes leaves the body
/// at most that (measured: KE + SE at most 0.97 W, both models, on the first step; it then
/// tends to 0.5 W, a linear body's static share). Returns the largest (KE + SE) / W.
template <class M>
Scalar dissipative_huge_steps() {
  const Mesh<Hex8> mesh = bar_mesh<Hex8>(10, 3, 3);
  SolverSettings settings;
  settings.newmark = NewmarkSettings::generalized_alpha(0.5);
  Solver<Hex8, M> s(mesh, soft, settings);
  s.fix(mesh.node_set("xmin"));
  s.add_gravity(Vec3(0, 0, -9.81));
  Scalar worst = 0;
  for (int k = 0; k < 20; ++k) {
    s.step(1.0);
    REQUIRE(state_finite(s));
    const Scalar W = s.external_work_potential();
    REQUIRE(W > 0);  // the bar hangs below its rest position throughout (measured W >= 0.24 W_1)
    worst = std::max(worst, (s.kinetic_energy() + s.strain_energy()) / W);
  }
  fmt::print("dt = 1 bar90 {:12}, generalized-alpha rho_inf 0.5: 20 steps, (KE + SE) / W at most {:.3f}\n", M::name,
             worst);
  return worst;
}

// --- 4. 100,000 steps ------------------------------------------------------------------------

/// Free vibration of a 4 x 1 x 1 bar (clamped at x = 0) released from the static deflection
/// under an end load, no damping, dt = 0.01.
template <FiniteElement E>
std::pair<Scalar, Scalar> energy_drift(int steps, LinearSolverKind kind) {
  const Mesh<E> mesh = bar_mesh<E>(4, 1, 1);
  SolverSettings settings;
  settings.linear.kind = kind;
  Solver<E, Linear> s(mesh, soft, settings);
  s.fix(mesh.node_set("xmin"));
  const LoadHandle h = s.add_nodal_force(mesh.node_set("xmax"), Vec3(0, 5, -10));
  s.solve_static(1);
  s.remove_load(h);
  s.set_state(s.displacement(), Vector::Zero(s.num_dofs()));
  auto energy = [&] { return s.kinetic_energy() + s.strain_energy(); };
  const Scalar E0 = energy();
  Scalar previous = E0, worst = 0;
  const auto t0 = std::chrono::steady_clock::now();
  for (int k = 1; k <= steps; ++k) {
    s.step(0.01);
    if (k % 1000 == 0) {
      REQUIRE(state_finite(s));
      const Scalar e = energy();
      worst = std::max(worst, std::abs(e - previous) / E0);
      previous = e;
    }
  }
  const Scalar total = (energy() - E0) / E0;
  fmt::print("{} steps, free vibration, {:5} Linear, {:6}: energy {:.6f}, max drift per 1000 steps {:.1e}, total "
             "{:.1e}; {:.0f} ms\n",
             steps, E::name, kind == LinearSolverKind::Direct ? "direct" : "CG", E0, worst, total, ms_since(t0));
  return {worst, total};
}

// --- 5. a grasper pulls 10 bar lengths away, lets go -----------------------------------------

struct GuardedSteps {
  int steps = 0, failures = 0, substeps = 0;
  bool all_rollbacks_exact = true;
};

/// One step that either commits a finite state or throws SolverError and leaves the state bit
/// for bit as it was. Returns whether it committed.
template <class S>
bool guarded_step(S& s, Scalar dt, GuardedSteps& g) {
  const auto before = s.state();
  try {
    g.substeps += s.step(dt).substeps;
  } catch (const SolverError&) {
    ++g.failures;
    g.all_rollbacks_exact = g.all_rollbacks_exact && s.state() == before;
    return false;
  }
  ++g.steps;
  return true;
}

enum class Undamped { Trapezoidal, Dissipative };

/// A 4 x 1 x 1 Hex8 bar clamped at x = 0; the grasper holds the end face (or its corner node
/// alone) and pulls it 40 = 10 lengths along (1, 0, 1) / sqrt 2 over 1 s (dt = 1e-3), then
/// lets go. From the release on, two copies move freely for 0.2 s at dt = 1e-4: one without
/// damping (Newmark trapezoidal, or gamma = 0.6, beta = 0.3025, which dissipates numerically),
/// one with Rayleigh damping alpha = 2, beta = 1e-3 (trapezoidal).
/// `damped_pull`: the pull with that Rayleigh damping too (the free copies as above);
/// `jitter`: every node moved by up to that much (a round-off-sized change of the input).
/// Returns the undamped copy's largest energy over its energy at release.
template <class M>
Scalar grasp_far(bool single_node, Undamped undamped, bool damped_pull = false, Scalar jitter = 0) {
  const Mesh<Hex8> mesh = moved_mesh(bar_mesh<Hex8>(4, 1, 1), jitter);
  const auto t0 = std::chrono::steady_clock::now();
  SolverSettings pull_settings;
  if (damped_pull) pull_settings.rayleigh_mass = 2, pull_settings.rayleigh_stiffness = 1e-3;
  Solver<Hex8, M> s(mesh, soft, pull_settings);
  s.fix(mesh.node_set("xmin"));
  std::vector<Index> nodes = mesh.node_set("xmax");
  if (single_node) nodes.resize(1);
  const Scalar L = 4;
  const Vec3 direction = Vec3(1, 0, 1).normalized();
  const ConstraintHandle grasp =
      s.grasp(nodes, [&](Scalar t) -> Vec3 { return 10 * L * std::min(t, 1.0) * direction; });
  GuardedSteps pull;
  for (int k = 0; k < 1000; ++k) {
    if (!guarded_step(s, 1e-3, pull)) break;  // the grasper lets go where the tissue fails
    REQUIRE(state_finite(s));
  }
  const Scalar reach = s.displacement(nodes[0]).norm();

  SolverSettings damped_settings;
  damped_settings.rayleigh_mass = 2;
  damped_settings.rayleigh_stiffness = 1e-3;
  Solver<Hex8, M> d(mesh, soft, damped_settings);
  d.fix(mesh.node_set("xmin"));
  d.set_state(s.displacement(), s.velocity(), s.time());
  s.release(grasp);
  if (undamped == Undamped::Dissipative) {
    SolverSettings dissipative;
    dissipative.newmark.gamma = 0.6;
    dissipative.newmark.beta = 0.25 * (0.5 + 0.6) * (0.5 + 0.6);
    s.set_settings(dissipative);
  } else if (damped_pull) {
    s.set_settings(SolverSettings{});
  }

  auto energy = [](const auto& x) { return x.kinetic_energy() + x.strain_energy(); };
  const Scalar E0 = energy(s);
  REQUIRE(energy(d) == Approx(E0).epsilon(1e-12));
  Scalar undamped_max = E0, damped_max = E0, damped_rise = 0, damped_previous = E0;
  GuardedSteps free_undamped, free_damped;
  bool undamped_on = true, damped_on = true;
  for (int k = 0; k < 2000; ++k) {
    if (undamped_on && (undamped_on = guarded_step(s, 1e-4, free_undamped))) {
      REQUIRE(state_finite(s));
      undamped_max = std::max(undamped_max, energy(s));
    }
    if (damped_on && (damped_on = guarded_step(d, 1e-4, free_damped))) {
      REQUIRE(state_finite(d));
      const Scalar e = energy(d);
      damped_max = std::max(damped_max, e);
      damped_rise = std::max(damped_rise, (e - damped_previous) / E0);
      damped_previous = e;
    }
  }
  fmt::print("grasp 10 L {:12} {:11}{}: pull {} steps ({} sub-steps), {} failed, reach {:.1f}; energy at release {:.4g}; "
             "undamped ({}) {} steps, {} failed, max {:.4g} E0; damped {} steps, {} failed, max {:.4f} E0, largest "
             "rise in a step {:.1e} E0, end {:.3f} E0; {:.0f} ms\n",
             M::name, single_node ? "corner node" : "end face",
             damped_pull ? fmt::format(" (damped pull, jitter {:.0e})", jitter) : std::string(), pull.steps, pull.substeps, pull.failures, reach, E0,
             undamped == Undamped::Trapezoidal ? "trapezoidal" : "gamma 0.6", free_undamped.steps,
             free_undamped.failures, undamped_max / E0, free_damped.steps, free_damped.failures, damped_max / E0,
             damped_rise, damped_previous / E0, ms_since(t0));
  // Transactions: a failed step leaves the state bit for bit as it was, never NaN.
  CHECK(pull.all_rollbacks_exact);
  CHECK(free_undamped.all_rollbacks_exact);
  CHECK(free_damped.all_rollbacks_exact);
  // It did pull: 10 lengths (measured: all the way in every variant).
  CHECK(reach > 2 * L);
  // Damped: the energy falls (end <= 0.5 E0; measured 0.20-0.27 after 0.2 s) and never rises
  // above its value at release by more than 1% (the trapezoidal rule is not exactly
  // conservative for a nonlinear model; largest single-step rise measured 7.9e-3 E0 for
  // NeoHookean, 0 for Corotational).
  CHECK(free_damped.failures == 0);
  CHECK(damped_max <= 1.01 * E0);
  CHECK(damped_previous <= 0.5 * E0);
  return undamped_max / E0;
}

// --- 6. a twist of 4 pi and back -------------------------------------------------------------

/// A 16 x 1 x 1 Hex8 bar clamped at x = 0; its x = 16 face turned about the bar axis by
/// theta(t): up to 4 pi and back to 0 in 64 static increments of pi / 8.
template <class M>
void twist_static() {
  const Mesh<Hex8> mesh = bar_mesh<Hex8>(16, 1, 1);
  const auto t0 = std::chrono::steady_clock::now();
  Solver<Hex8, M> s(mesh, soft);
  s.fix(mesh.node_set("xmin"));
  auto theta = [](Scalar t) { return (t <= 32 ? t : 64 - t) * std::numbers::pi / 8; };
  s.prescribe(mesh.node_set("xmax"), [&](Scalar t, const Vec3& X) { return twist_displacement(theta(t), X); });
  int newton = 0, increments = 0;
  Scalar u_max = 0, energy_4pi = 0;
  for (int k = 1; k <= 64; ++k) {
    // Statics solve at the state's time: move it to t = k (the face at theta(k)).
    s.set_state(s.displacement(), Vector::Zero(s.num_dofs()), k);
    const StepReport r = s.solve_static(1);
    REQUIRE(state_finite(s));
    newton += r.newton_iterations, increments += r.load_steps;
    u_max = std::max(u_max, s.displacement().cwiseAbs().maxCoeff());
    if (k == 32) energy_4pi = s.strain_energy();
  }
  const Scalar u_end = s.displacement().cwiseAbs().maxCoeff();
  fmt::print("twist 4 pi and back, statics, Hex8 16x1x1 {:12}: {} Newton iterations in {} increments, strain energy at "
             "4 pi {:.1f}, max |u| {:.3f}, back at 0: max |u| {:.1e}, strain energy {:.1e}; {:.0f} ms\n",
             M::name, newton, increments, energy_4pi, u_max, u_end, s.strain_energy(), ms_since(t0));
  CHECK(energy_4pi > 100);  // it was twisted (two full turns over 16 cells: shear ~0.55)
  // Back at 0 the elastic bar is at rest (u = 0 is the solution). Newton stops at |r| <= 1e-6
  // of the last increment's initial imbalance, so u is within ~1e-6 of that increment's motion
  // (pi / 8 x 0.7) times the conditioning between residual and displacement: 1e-5 of the
  // largest displacement leaves a factor ~10 for that (measured 3.5e-8, 9e-9).
  CHECK(u_end < 1e-5 * u_max);
}

/// The same bar in dynamics: theta(t) = 2 pi (1 - cos(pi t / 2)) up to 4 pi at t = 2 and back
/// to 0 at t = 4 (smooth: zero angular velocity at both ends), then held at 0 for 2 s, with
/// Rayleigh mass damping alpha = 2; then a static solve from where the motion ends.
template <class M>
void twist_dynamic() {
  const Mesh<Hex8> mesh = bar_mesh<Hex8>(16, 1, 1);
  const auto t0 = std::chrono::steady_clock::now();
  SolverSettings settings;
  settings.rayleigh_mass = 2;
  Solver<Hex8, M> s(mesh, soft, settings);
  s.fix(mesh.node_set("xmin"));
  auto theta = [](Scalar t) { return t >= 4 ? 0.0 : 2 * std::numbers::pi * (1 - std::cos(std::numbers::pi * t / 2)); };
  s.prescribe(mesh.node_set("xmax"), [&](Scalar t, const Vec3& X) { return twist_displacement(theta(t), X); });
  int newton = 0, substeps = 0;
  Scalar u_max = 0, u_back = 0;
  for (int k = 1; k <= 600; ++k) {
    const StepReport r = s.step(0.01);
    REQUIRE(state_finite(s));
    newton += r.newton_iterations, substeps += r.substeps;
    u_max = std::max(u_max, s.displacement().cwiseAbs().maxCoeff());
    if (k == 400) u_back = s.displacement().cwiseAbs().maxCoeff();
  }
  const Scalar u_held = s.displacement().cwiseAbs().maxCoeff();
  s.solve_static(1);
  const Scalar u_static = s.displacement().cwiseAbs().maxCoeff();
  fmt::print("twist 4 pi and back, dynamics, Hex8 16x1x1 {:12}: {} Newton iterations, {} sub-steps in 600 steps, max "
             "|u| {:.3f}; max |u| back at 0 (t = 4) {:.1e}, after 2 s held {:.1e}, then static {:.1e}; {:.0f} ms\n",
             M::name, newton, substeps, u_max, u_back, u_held, u_static, ms_since(t0));
  CHECK(u_max > 1);  // the twist did reach the bar (the corner of the face moves by ~1.4)
  // Mass damping makes every mode decay like exp(-alpha t / 2): e^-2 = 0.14 over the 2 s hold
  // (measured 0.12); 0.5 leaves room for the nonlinear part of the motion.
  CHECK(u_held < 0.5 * u_back + 1e-12);
  // The static solve from there: back at rest, to the Newton tolerance as in statics.
  CHECK(u_static < 1e-5 * u_max);
}

// --- 7. every node fixed ---------------------------------------------------------------------

template <FiniteElement E, class M>
void all_fixed() {
  const Mesh<E> mesh = bar_mesh<E>(2, 1, 1);
  std::vector<Index> all(static_cast<size_t>(mesh.num_nodes()));
  for (Index i = 0; i < mesh.num_nodes(); ++i) all[static_cast<size_t>(i)] = i;
  Solver<E, M> fixed(mesh, soft);
  fixed.fix(all);
  fixed.add_gravity(Vec3(0, 0, -9.81));
  const StepReport r = fixed.solve_static(1);
  const bool static_zero = fixed.displacement().isZero(0);
  const StepReport q = fixed.step(0.01);
  const bool dynamic_zero =
      fixed.displacement().isZero(0) && fixed.velocity().isZero(0) && fixed.acceleration().isZero(0);

  // Every node on a path: a rigid rotation about x by t plus a translation t along x.
  auto path = [](Scalar t, const Vec3& X) -> Vec3 { return twist_displacement(t, X) + Vec3(t, 0, 0); };
  Solver<E, M> moving(mesh, soft);
  moving.prescribe(all, path);
  moving.add_gravity(Vec3(0, 0, -9.81));
  Scalar worst = 0;
  auto check_path = [&] {
    for (Index i = 0; i < mesh.num_nodes(); ++i)
      worst = std::max(worst, (moving.displacement(i) - path(moving.time(), mesh.node(i))).norm());
  };
  for (int k = 0; k < 5; ++k) {
    moving.step(0.01);
    check_path();
  }
  moving.solve_static(1);
  check_path();
  fmt::print("every node fixed {:5} {:12}: static Newton {} |u| {}; step Newton {} u, v, a zero: {}; every node on a "
             "path: max |u - path| {:.1e} over 5 steps and a static solve\n",
             E::name, M::name, r.newton_iterations, fixed.displacement().norm(), q.newton_iterations, dynamic_zero, worst);
  CHECK(r.newton_iterations == 0);  // nothing is free: converged before any iteration
  CHECK(static_zero);
  CHECK(dynamic_zero);
  CHECK(q.substeps == 1);
  CHECK(worst == 0);  // the constrained dofs are set from the path, not solved for
}

// --- 8. free flight --------------------------------------------------------------------------

/// Sum over nodes of (M v)_i, and of x_i x (M v)_i (x = X + u): the linear and angular
/// momentum of the finite element field (exact for the consistent mass, int rho x x v dV, since
/// x and v share the interpolation; the lumped mass's own for the lumped one).
template <class S>
std::pair<Vec3, Vec3> momenta(const S& s, const SparseMatrix& M) {
  const Vector Mv = M * s.velocity();
  const Eigen::Matrix3Xd x = s.positions();
  Vec3 P = Vec3::Zero(), L = Vec3::Zero();
  for (Index i = 0; i < x.cols(); ++i) {
    const Vec3 p = Mv.template segment<3>(3 * i);
    P += p;
    L += Vec3(x.col(i)).cross(p);
  }
  return {P, L};
}

/// A 4 x 1 x 1 bar with no constraint and no load, Linear model, direct solver: random nodal
/// velocities (fixed seed) plus a drift (1, -2, 0.5); 2000 steps of 0.01.
template <FiniteElement E>
void free_flight_momentum(MassKind kind) {
  const Mesh<E> mesh = bar_mesh<E>(4, 1, 1);
  SolverSettings settings;
  settings.mass = kind;
  settings.linear.kind = LinearSolverKind::Direct;  // exact solves: the momentum is a round-off matter
  Solver<E, Linear> s(mesh, soft, settings);
  std::mt19937 rng(7);
  std::uniform_real_distribution<Scalar> uniform(-1, 1);
  Vector v(s.num_dofs());
  for (Index i = 0; i < v.size(); ++i) v[i] = 0.1 * uniform(rng);
  for (Index i = 0; i < mesh.num_nodes(); ++i) v.template segment<3>(3 * i) += Vec3(1, -2, 0.5);
  s.set_state(Vector::Zero(s.num_dofs()), v);
  const SparseMatrix M = s.mass_matrix();
  // K 1 = 0 (a translation is stress-free) holds to the round-off of the element matrices
  // only; with f_int = K u the body's net force is then (K 1_d) . u, which grows with the
  // rigid drift u ~ 20 x (1, -2, 0.5). Its measure: max_d |K 1_d|.
  const SparseMatrix K = s.tangent();
  Scalar k1 = 0;
  for (int d = 0; d < 3; ++d) {
    Vector one = Vector::Zero(s.num_dofs());
    for (Index i = 0; i < mesh.num_nodes(); ++i) one[3 * i + d] = 1;
    k1 = std::max(k1, Vector(K * one).norm());
  }
  const Vec3 P0 = momenta(s, M).first;
  const Scalar dt = 0.01;
  Scalar worst = 0, bound = 0;
  for (int k = 0; k < 2000; ++k) {
    s.step(dt);
    REQUIRE(state_finite(s));
    worst = std::max(worst, (momenta(s, M).first - P0).norm());
    // |P_{n+1} - P_n| = dt |1^T K (u_n + u_{n+1})| / 2 <= dt |K 1| |u_{n+1}| (u grows).
    bound += dt * k1 * s.displacement().norm();
  }
  fmt::print("free flight {:5} Linear {:10}: |P - P0| / |P0| <= {:.1e} over 2000 steps (round-off bound from |K 1| = "
             "{:.1e}: {:.1e})\n",
             E::name, mass_name(kind), worst / P0.norm(), k1, bound / P0.norm());
  // Newmark: P_{n+1} - P_n = dt/2 1^T M (a_n + a_{n+1}) = -dt/2 1^T (f_n + f_{n+1}) plus the
  // residual of the solve (direct: round-off). So |P - P0| is the round-off bound above plus
  // the solves' round-off: assert 2x the bound + 2e-12 |P0| (measured 2e-10 to 7e-10
  // relative, against bounds of 7e-10 to 5e-9).
  CHECK(worst <= 2 * bound + 2e-12 * P0.norm());
}

/// A 4 x 1 x 1 bar spinning at omega = (0.3, 0.5, 2) about its centre and drifting at
/// (0.5, 0, 0), no constraint or load, Corotational, 2000 steps of 0.01 (20 s, ~6.6 turns).
template <FiniteElement E>
void free_flight_spin(MassKind kind) {
  const Mesh<E> mesh = bar_mesh<E>(4, 1, 1);
  SolverSettings settings;
  settings.mass = kind;
  // A tight Newton tolerance and exact linear solves, so that the residual left in each step
  // (which the momentum balance integrates) is round-off.
  settings.linear.kind = LinearSolverKind::Direct;
  settings.newton.residual_tolerance = 1e-12;
  Solver<E, Corotational> s(mesh, soft, settings);
  const Vec3 c = mesh.nodes().rowwise().mean();
  const Vec3 omega(0.3, 0.5, 2.0);
  Vector v(s.num_dofs());
  for (Index i = 0; i < mesh.num_nodes(); ++i) v.template segment<3>(3 * i) = omega.cross(mesh.node(i) - c) + Vec3(0.5, 0, 0);
  s.set_state(Vector::Zero(s.num_dofs()), v);
  const SparseMatrix M = s.mass_matrix();
  const auto [P0, L0] = momenta(s, M);
  const Scalar E0 = s.kinetic_energy();
  Scalar dP = 0, dL = 0, dE = 0;
  int newton = 0;
  const auto t0 = std::chrono::steady_clock::now();
  for (int k = 0; k < 2000; ++k) {
    newton += s.step(0.01).newton_iterations;
    REQUIRE(state_finite(s));
    const auto [P, L] = momenta(s, M);
    dP = std::max(dP, (P - P0).norm() / P0.norm());
    dL = std::max(dL, (L - L0).norm() / L0.norm());
    dE = std::max(dE, std::abs(s.kinetic_energy() + s.strain_energy() - E0) / E0);
  }
  fmt::print("free spin {:5} Corotational {:10}: {:.2f} Newton iterations per step; max relative change of P {:.1e}, "
             "of L {:.1e}, of energy {:.1e} over 2000 steps; {:.0f} ms\n",
             E::name, mass_name(kind), newton / 2000.0, dP, dL, dE, ms_since(t0));
  // Linear momentum: sum f_int = 0 for the corotational force of any element (K0's rows sum to
  // zero, and it acts on the unrotated deformation, which carries no rigid drift), so P moves
  // only by the residual left per step: round-off here, which accumulates step by step: 1e-14
  // of |P| per step bounds it (measured 1.2e-12 to 3.3e-12 over the 2000 steps).
  CHECK(dP < 2000 * 1e-14);
  // Angular momentum and energy: the trapezoidal rule conserves neither exactly for a rotating
  // nonlinear body; its error is O((omega dt)^2) = 4.3e-4 (|omega| = 2.08, dt = 0.01), and it
  // oscillates with the spin instead of drifting (Hex8 over 6000 steps, 20 turns: L within
  // 2.1e-4, energy within 3.9e-4 throughout). Bound: 5 (omega dt)^2.
  const Scalar bound = 5 * std::pow(omega.norm() * 0.01, 2);
  CHECK(dL < bound);
  CHECK(dE < bound);
}

}  // namespace

TEST_CASE("extremes 1: nu = 0.499, every element and elastic model, statics and dynamics", "[extremes][poisson]") {
  poisson_0499_all<Tet4>(CommonModels{});
  poisson_0499_all<Tet10>(CommonModels{});
  poisson_0499_all<Hex8>(CommonModels{});
  poisson_0499_all<Hex8>(MeanDilatationModels{});
}

TEST_CASE("extremes 2: E from 1e1 to 1e9 with the load scaled by E: the same displacement", "[extremes][young]") {
  // Statics through Eigen's LDLT here, through the default (CHOLMOD where built) at the end.
  SolverSettings ldlt;
  ldlt.static_linear.direct = DirectSolver::SimplicialLDLT;
  young_decades<Linear>(ldlt, 1, 9, "LDLT");
  young_decades<Corotational>(ldlt, 1, 9, "LDLT");
  young_decades<NeoHookean>(ldlt, 1, 9, "LDLT");
}

TEST_CASE("extremes 3: dt from 1e-6 to 1 on bar90: finite, energy bounded by the input work, or refused", "[extremes][dt]") {
  time_step_decades<Linear>();
  time_step_decades<Corotational>();
  time_step_decades<NeoHookean>();
  // 1.05: the measured 0.97 with a margin; a scheme without dissipation there reached 8.6.
  CHECK(dissipative_huge_steps<Corotational>() <= 1.05);
  CHECK(dissipative_huge_steps<NeoHookean>() <= 1.05);
}

TEST_CASE("extremes 4: 100,000 undamped linear steps conserve energy to round-off", "[extremes][energy]") {
  // The trapezoidal rule conserves KE + SE of a linear undamped system exactly; with exact
  // (direct) solves what remains is round-off: ~1e-16 per step, a random walk of ~3e-15 per
  // 1000 steps amplified by the conditioning of c0 M + K (measured 1e-13). 1e-9 per 1000 steps
  // leaves four orders.
  for (auto [drift, total] : {energy_drift<Hex8>(100000, LinearSolverKind::Direct),
                              energy_drift<Tet4>(100000, LinearSolverKind::Direct)}) {
    CHECK(drift < 1e-9);
    CHECK(std::abs(total) < 1e-8);
  }
  // Default CG: each step's solve stops at the inexact-Newton tolerance (a residual of at most
  // 1e-6 of the force scale), which does work on the step's motion: at most ~1e-6 of the energy
  // per step, 1e-3 per 1000 steps (measured 8.1e-8: the errors mostly cancel).
  const auto [drift, total] = energy_drift<Hex8>(100000, LinearSolverKind::ConjugateGradient);
  CHECK(drift < 1e-3);
  CHECK(std::abs(total) < 1e-2);
}

TEST_CASE("extremes 5: a grasper pulls 10 bar lengths away and lets go", "[extremes][grasp]") {
  // After the release the bar snaps back at ~c eps = 55 x 10 units/s; dt = 1e-4 resolves that
  // (0.05 units per step). Undamped, the energy stays bounded: 5% over 0.2 s (measured <= 0.2%
  // for Corotational with the trapezoidal rule; the dissipative gamma = 0.6 only loses).
  CHECK(grasp_far<Corotational>(false, Undamped::Trapezoidal) <= 1.05);
  CHECK(grasp_far<Corotational>(true, Undamped::Trapezoidal) <= 1.05);
  // NeoHookean: the undamped pull of this 4-element bar to 10 lengths is chaotic: moving the
  // nodes by 1e-15 to 1e-8 made it fail at 88-99.8% of the way (det F -> 0 at a Gauss point,
  // energy 4e7-3e8 against the 2.6e5 of the unperturbed mesh, whose pull passes by luck, and
  // the damped release then gained 3-22 times its energy). With the Rayleigh damping of the
  // damped copy during the pull as well (tissue is damped), every one of those meshes reaches
  // 40 with the same energy (2.372e5 to 4 digits) and a stable release: the pull is damped
  // here, and repeated on a mesh moved by 1e-13 to assert that the outcome no longer hinges on
  // round-off.
  CHECK(grasp_far<NeoHookean>(false, Undamped::Dissipative, true) <= 1.05);
  CHECK(grasp_far<NeoHookean>(false, Undamped::Dissipative, true, 1e-13) <= 1.05);
  // NeoHookean with the undamped trapezoidal rule: once an element of the rebounding bar nearly
  // collapses (ln J barrier), each step gains energy, whatever the step (dt = 1e-4, 3e-5,
  // 1e-5: 8.6e3, 5.5e3, 1.2e4 E0 after 0.16-0.19 s; the force is the energy's gradient to 1e-9
  // there, so this is the integrator, not the model). With each step balanced to the
  // tolerance of its own forces rather than the predictor's, the gain ends in a step no Newton
  // converges on: refused after 1550 steps at 487 E0 (dt = 1e-4). Only the transactions are
  // asserted; the figures are printed (see the report).
  grasp_far<NeoHookean>(false, Undamped::Trapezoidal, true);
}

TEST_CASE("extremes 6: twist of 4 pi and back, statics and dynamics", "[extremes][twist]") {
  twist_static<Corotational>();
  twist_static<NeoHookean>();
  twist_dynamic<Corotational>();
  twist_dynamic<NeoHookean>();
}

TEST_CASE("extremes 7: every node fixed or prescribed: solves succeed at once, u is the prescribed one",
          "[extremes][fixed]") {
  all_fixed<Tet4, Linear>();
  all_fixed<Tet4, Corotational>();
  all_fixed<Tet10, Corotational>();
  all_fixed<Tet10, NeoHookean>();
  all_fixed<Hex8, NeoHookean>();
  all_fixed<Hex8, CorotationalMeanDilatation>();
}

TEST_CASE("extremes 8: free flight: momentum to round-off, a spinning body's angular momentum and energy bounded",
          "[extremes][free]") {
  for (MassKind kind : {MassKind::Consistent, MassKind::Lumped}) {
    free_flight_momentum<Tet4>(kind);
    free_flight_momentum<Tet10>(kind);
    free_flight_momentum<Hex8>(kind);
    free_flight_spin<Tet4>(kind);
    free_flight_spin<Tet10>(kind);
    free_flight_spin<Hex8>(kind);
  }
}

// Regression: the default direct solver (CHOLMOD) refused a well-posed stiff problem as
// "singular" (cholmod_rcond's already-squared pivot ratio squared again, and held rows with a unit
// diagonal that did not scale with E h). Reproduction was bar_mesh<Hex8>(2, 1, 1), E = 1e7.
TEST_CASE("extremes 2, default statics: E from 1e1 to 1e9", "[extremes][young]") {
  young_decades<Linear>(SolverSettings{}, 1, 9, "default");
  young_decades<Corotational>(SolverSettings{}, 1, 9, "default");
}

// Regression: a step whose residual met the tolerance after an increment below
// increment_tolerance (small dt) was reported as stagnated instead of converged.
TEST_CASE("extremes 3, report: a step that meets the tolerance is not reported as stagnated", "[extremes][dt]") {
  const Mesh<Hex8> mesh = bar_mesh<Hex8>(10, 3, 3);
  Solver<Hex8, Corotational> s(mesh, soft);
  s.fix(mesh.node_set("xmin"));
  s.add_gravity(Vec3(0, 0, -9.81));
  for (Scalar dt : {1e-4, 1e-6}) {
    const StepReport r = s.step(dt);
    CHECK(r.relative_residual <= s.settings().newton.residual_tolerance);
    CHECK_FALSE(r.stagnated);
    CHECK(r.convergence == Convergence::Converged);
  }
}

// --- issue 33: plastic and cut bodies at the extremes -------------------------------------

namespace {

/// Plastic updates rejected in a row, at most, over a run (a rejection must make progress).
struct RejectionRun {
  int total = 0, in_a_row = 0, worst = 0;
  void add(const PlasticReport& r) {
    total += r.updates_rejected;
    in_a_row = r.updates_rejected ? in_a_row + 1 : 0;
    worst = std::max(worst, in_a_row);
  }
};

template <class Policy>
void plastic_spin() {
  // bar90 spinning freely at 10 rad/s about its axis, stretch and rotation flow on. The
  // centrifugal stress (rho omega^2 r^2 ~ 200 at the edges) is above the yield of 20, so the
  // body flows while it turns 1.6 times.
  const Mesh<Hex8> mesh = bar_mesh<Hex8>(10, 3, 3);
  PlasticParams p;
  p.yield_stress = 20, p.flow_rate = 0.5;
  p.rotation_yield = 1e-3, p.rotation_flow_rate = 0.5;
  Solver<Hex8, Corotational, Policy> s(mesh, soft, {}, p);
  Vector v(s.num_dofs());
  for (Index i = 0; i < mesh.num_nodes(); ++i) v.segment<3>(3 * i) = Vec3(10, 0, 0).cross(mesh.node(i) - Vec3(5, 1.5, 1.5));
  s.set_state(Vector::Zero(s.num_dofs()), v);
  RejectionRun rejected;
  int yielded = 0;
  bool finite = true;
  for (int k = 0; k < 200; ++k) {
    const PlasticReport r = s.step(0.005).plastic;
    rejected.add(r);
    yielded += r.points_yielded;
    finite = finite && state_finite(s);
  }
  const test::RigidFit fit = test::rigid_fit(mesh.nodes(), s.material_positions());
  const Scalar volume = material_volume(mesh, s.material_positions()) / 90 - 1;
  fmt::print("extremes 9, {} spinning at 10 rad/s: {} points yielded, material mesh turned {:.2e} rad, non-rigid "
             "change {:.3g}, material volume {:+.2e}, updates rejected {} (at most {} in a row)\n",
             Policy::name, yielded, fit.angle, fit.non_rigid, volume, rejected.total, rejected.worst);
  CHECK(finite);
  CHECK(yielded > 0);
  // The spin is rigid motion and does not turn the material mesh (the paper's World frame turns
  // it by radians, tests/test_plasticity.cpp). What is left is the Coriolis lag of the flowing
  // cross-section (a real shear: it expands while it turns): measured 5.5e-5 and 4.2e-5 rad
  // with a non-rigid change of 0.045.
  CHECK(fit.angle < 1e-3);
  CHECK(std::abs(volume) < 1e-3);  // isochoric flow, restituted to volume_tolerance 1e-4
  CHECK(rejected.worst <= 1);
}

template <class Policy>
Scalar plastic_cycles(int steps, Scalar restitution) {
  // Issue 33 item 2's scene: bar90 clamped at x = 0 under gravity, Rayleigh alpha 0.2, the end
  // face pulled and pushed by a traction of resultant 350 sin(pi t) (set 1 of the stretch
  // scene, kinematic hardening 0.1, rotation flow on). Cell-centered rejected 2196 of the
  // updates from step 2488 to 5000 (up to 761 in a row) before rejections kept their
  // switch-offs. Returns the largest |material volume / 90 - 1| (sampled every 100 steps).
  const Mesh<Hex8> mesh = bar_mesh<Hex8>(10, 3, 3);
  PlasticParams p;
  p.yield_stress = 1000, p.flow_rate = 0.4, p.hardening = 0.2, p.kinematic_hardening = 0.1;
  p.rotation_yield = 1e-3, p.rotation_flow_rate = 0.5;
  p.volume_restitution = restitution;
  SolverSettings st;
  st.rayleigh_mass = 0.2;
  Solver<Hex8, Corotational, Policy> s(mesh, soft, st, p);
  s.fix(mesh.node_set("xmin"));
  s.add_gravity(Vec3(0, 0, -9.81));
  s.add_traction(mesh.face_set("xmax"), Vec3(350.0 / 9, 0, 0), [](Scalar t) { return std::sin(std::numbers::pi * t); });
  RejectionRun rejected;
  int flowing_late = 0, off = 0;
  bool finite = true;
  Scalar volume_worst = 0;
  const auto t0 = std::chrono::steady_clock::now();
  for (int k = 1; k <= steps; ++k) {
    const PlasticReport r = s.step(0.01).plastic;
    rejected.add(r);
    if (k > steps / 2) flowing_late += r.points_yielded + r.rotations_yielded;
    off = r.elements_off;
    finite = finite && state_finite(s);
    if (k % 100 == 0)
      volume_worst = std::max(volume_worst, std::abs(material_volume(mesh, s.material_positions()) / 90 - 1));
  }
  fmt::print("extremes 10, {}, {} cyclic steps, volume restitution {}/s: flow events in the second half {}, updates "
             "rejected {} (at most {} in a row), elements off {}, material volume within {:.2e}, {:.0f} ms\n",
             Policy::name, steps, restitution, flowing_late, rejected.total, rejected.worst, off, volume_worst,
             ms_since(t0));
  CHECK(finite);
  CHECK(flowing_late > 0);      // still flowing in the second half (the rotation; the stretch has hardened)
  CHECK(rejected.worst <= 1);   // a rejected update makes progress
  return volume_worst;
}

template <class Enrich>
void degenerate_cut() {
  // A cut sheet at x = 5, exactly through a plane of nodes, drawn badly: its diagonal opened
  // into a needle of width 1.4e-9 (kept: it has area), a zero-area triangle, a repeated one, and
  // one turned over. It is repaired and cuts the bar in two. The free half (x > 5) is a free
  // body under gravity and mass damping alpha: it falls without turning, by
  // z(t) = -(g / alpha) (t - (1 - e^{-alpha t}) / alpha). A sheet that misses the bar is refused
  // and changes nothing.
  const Mesh<Hex8> mesh = bar_mesh<Hex8>(10, 3, 3);
  const std::vector<Vec3> v{Vec3(5, -1, -1), Vec3(5, 4, -1), Vec3(5, 4, 4), Vec3(5, -1, 4),
                            Vec3(5, 1.5 + 1e-9, 1.5 - 1e-9)};
  std::vector<std::string> notes;
  const NoteHandler previous = set_note_handler([&](const std::string& n) { notes.push_back(n); });
  //                            ,--- point   ,--- turned  ,--- needle            ,--- repeat
  const CutSurface sheet(v, {{0, 1, 4}, {3, 3, 3}, {2, 1, 4}, {0, 4, 2}, {0, 2, 3}, {2, 3, 0}});
  set_note_handler(previous);
  const Scalar alpha = 0.5, g = 9.81;
  SolverSettings st;
  st.rayleigh_mass = alpha;
  Solver<Hex8, Corotational, NoPlasticity, Enrich> s(mesh, soft, st);
  s.fix(mesh.node_set("xmin"));
  s.add_gravity(Vec3(0, 0, -g));
  const CutSurface away(std::vector<Vec3>{Vec3(20, 0, 0), Vec3(20, 3, 0), Vec3(20, 0, 3)}, {{0, 1, 2}});
  CHECK_THROWS_AS(s.cut(away), InvalidArgument);
  CHECK(s.num_dofs() == 3 * mesh.num_nodes());
  s.cut(sheet);
  const Index enriched = s.last_cut_report().enriched_nodes;
  bool finite = true;
  for (int k = 0; k < 50; ++k) {
    s.step(0.01);
    finite = finite && state_finite(s);
  }
  const Scalar t = s.time();
  const Scalar fall = -(g / alpha) * (t - (1 - std::exp(-alpha * t)) / alpha);
  Scalar off = 0;
  for (Index i = 0; i < mesh.num_nodes(); ++i)
    if (mesh.node(i).x() > 5.5) off = std::max(off, (s.displacement(i) - Vec3(0, 0, fall)).norm());
  fmt::print("extremes 11, degenerate sheet, {}: {} triangles dropped, {} turned; {} nodes enriched; the free half "
             "fell {:.4f} (closed form {:.4f}), its nodes off by at most {:.1e}\n",
             Enrich::name, sheet.dropped_triangles(), sheet.flipped_triangles(), enriched,
             -s.displacement(mesh.node_set("xmax")[0]).z(), -fall, off);
  CHECK(sheet.dropped_triangles() == 2);
  CHECK(sheet.flipped_triangles() == 1);
  // The repair is said once, with its counts (a user's sheet changed under them).
  REQUIRE(notes.size() == 1);
  CHECK(notes[0].find("cut surface repaired: 2 of 6 triangles dropped") != std::string::npos);
  CHECK(notes[0].find("1 turned over") != std::string::npos);
  CHECK(enriched == 16);  // the nodes on the plane x = 5: the only supports the sheet crosses
  CHECK(finite);
  CHECK(off < 1e-3 * std::abs(fall));  // measured 1.4e-5: the trapezoidal rule's O((alpha dt)^2) = 2.5e-5
}

void noisy_grasp(NewmarkMode mode) {
  // A grasp of the end of bar90 driven by device readings every 10 ms that lift it to 2 over 1 s,
  // each with +-0.02 of noise (velocity noise of +-4 between readings), then released: every step
  // commits a finite state, the grasped nodes are where the samples put them, and after the
  // release the damped bar's energy falls.
  const Mesh<Hex8> mesh = bar_mesh<Hex8>(10, 3, 3);
  const std::vector<Index> end = mesh.node_set("xmax");
  SolverSettings st;
  st.newmark.mode = mode;
  st.rayleigh_mass = 0.5;
  st.rayleigh_stiffness = 0.01;
  Solver<Hex8, Corotational> s(mesh, soft, st);
  s.fix(mesh.node_set("xmin"));
  DeviceSamples device(0, Vec3::Zero());
  const auto path = device.path();
  const ConstraintHandle h = s.grasp(end, path);
  std::mt19937 rng(7);
  std::uniform_real_distribution<Scalar> noise(-0.02, 0.02);
  Scalar off_path = 0, energy_at_release = 0, energy_end = 0;
  bool finite = true;
  for (int k = 1; k <= 150; ++k) {
    const Scalar t = 0.01 * k;
    if (k <= 100) device.add(t, Vec3(0, 0, 2 * t + noise(rng)));
    if (k == 101) {
      s.release(h);
      energy_at_release = s.kinetic_energy() + s.strain_energy();
    }
    s.step(0.01);
    finite = finite && state_finite(s);
    if (k <= 100)
      for (Index i : end) off_path = std::max(off_path, std::abs(s.displacement(i).z() - path(s.time()).z()));
  }
  energy_end = s.kinetic_energy() + s.strain_energy();
  fmt::print("extremes 12, noisy device grasp, {}: grasped nodes off their samples by {:.1e}; energy at release {:.4g}, "
             "0.5 s later {:.4g}\n",
             mode == NewmarkMode::Accurate ? "accurate" : "real time", off_path, energy_at_release, energy_end);
  CHECK(finite);
  CHECK(off_path < 1e-12);  // prescribed: exactly the samples' path, up to the sum's round-off
  CHECK(energy_end < energy_at_release);
}

}  // namespace

TEST_CASE("extremes 9: a plastic body spinning at 10 rad/s: its material mesh is not turned, its volume kept",
          "[extremes][plasticity]") {
  plastic_spin<VertexBlended>();
  plastic_spin<CellCentered>();
}

TEST_CASE("extremes 10: 5000 steps of cyclic plastic load: no silent stop, material volume kept",
          "[extremes][plasticity][long]") {
  // Fusing elements that plastic rotation turned by different amounts averages rotated node
  // positions, which shrinks them (cell-centered proposals are rigid rotations of each element,
  // so the loss is the fusion's): without plastic rotation the material volume stays within
  // 7e-6. The restitution (eq. 9) pulls it back at its rate: at the paper's 1/s the volume
  // stays within 0.27 % (measured 2.7e-3 vertex-blended, 2.3e-3 cell-centered); at 10/s within
  // 0.03 % (3.0e-4, 2.7e-4), the 0.1 %. docs/plasticity.md, "Volume".
  CHECK(plastic_cycles<VertexBlended>(5000, 10) < 1e-3);
  CHECK(plastic_cycles<CellCentered>(5000, 10) < 1e-3);
  CHECK(plastic_cycles<VertexBlended>(5000, 1) < 5e-3);
  CHECK(plastic_cycles<CellCentered>(5000, 1) < 5e-3);
}

TEST_CASE("extremes 11: a cut through a degenerate sheet on a plane of nodes, and one that misses",
          "[extremes][cut]") {
  degenerate_cut<Heaviside>();
  degenerate_cut<ShiftedHeaviside>();
}

TEST_CASE("extremes 12: a grasp following noisy device samples, accurate and real time", "[extremes][grasp]") {
  noisy_grasp(NewmarkMode::Accurate);
  noisy_grasp(NewmarkMode::RealTime);
}
