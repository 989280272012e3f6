// Implicit time integration beyond Newmark's average acceleration: the generalized-alpha method
// (Chung and Hulbert 1993) and its HHT special case, checked against independent facts:
//  - on one mode of a linear bar, the solver's one-step map of (u, v, a) equals the scheme's
//    amplification matrix, derived here by hand from the scheme's three equations, to round-off
//    (so do its spectral radius and its phase per step), in accurate and real-time modes, with
//    and without Rayleigh damping;
//  - the parameter formulas give the published high-frequency spectral radius rho_inf;
//  - second-order accuracy: halving dt divides the error of a free vibration by four;
//  - after a sudden release of a bent nonlinear bar, the scheme's dissipation takes energy out
//    of the ringing while average acceleration keeps it, with no failed step;
//  - parameters that are not a stable second-order scheme are refused.
#include "catch.hpp"

#include <plastifem/plastifem.hpp>

#include <Eigen/Eigenvalues>
#include <fmt/core.h>

#include <array>
#include <cmath>
#include <complex>
#include <numbers>

using namespace plastifem;

namespace {

const Material soft{3000, 0.45, 1.0};  // SCENES.md bar material

/// The scheme on the modal equation q'' + c q' + w2 q = 0, written from its definition
/// (solver/newmark.hpp), as the 3x3 matrix A with (q, v, a)_{n+1} = A (q, v, a)_n:
///   (1 - am) a1 + am a0 + (1 - af)(c v1 + w2 q1) + af (c v0 + w2 q0) = 0,
///   q1 = q0 + dt v0 + dt^2 ((1/2 - beta) a0 + beta a1),   v1 = v0 + dt ((1 - gamma) a0 + gamma a1).
Eigen::Matrix3d amplification(const NewmarkSettings& s, Scalar w2, Scalar c, Scalar dt) {
  const Scalar am = s.alpha_m, af = s.alpha_f, b = s.beta, g = s.gamma;
  Eigen::Matrix3d A;
  for (int k = 0; k < 3; ++k) {
    const Eigen::Vector3d x0 = Eigen::Vector3d::Unit(k);
    const Scalar q0 = x0[0], v0 = x0[1], a0 = x0[2];
    const Scalar q_star = q0 + dt * v0 + dt * dt * (0.5 - b) * a0, v_star = v0 + dt * (1 - g) * a0;
    const Scalar a1 = -(am * a0 + (1 - af) * (c * v_star + w2 * q_star) + af * (c * v0 + w2 * q0)) /
                      ((1 - am) + (1 - af) * (c * g * dt + w2 * b * dt * dt));
    A.col(k) << q_star + b * dt * dt * a1, v_star + g * dt * a1, a1;
  }
  return A;
}

/// The principal (complex) eigenvalue of A, or its largest one when all are real.
std::complex<Scalar> principal_root(const Eigen::Matrix3d& A) {
  const Eigen::Vector3cd l = A.eigenvalues();
  int best = 0;
  for (int i = 1; i < 3; ++i)
    if (std::abs(l[i].imag()) > std::abs(l[best].imag()) + 1e-14 ||
        (std::abs(l[i].imag()) <= 1e-14 && std::abs(l[best].imag()) <= 1e-14 && std::abs(l[i]) > std::abs(l[best])))
      best = i;
  return l[best].imag() < 0 ? std::conj(l[best]) : l[best];
}

/// Bar 4x1x1 fixed at x = 0: its first mode phi (K phi = w^2 M phi over the free dofs), scaled
/// to a 0.01 peak, and the mass matrix for the modal projection.
struct Mode {
  Mesh<Hex8> mesh = bar_mesh<Hex8>(4, 1, 1);
  Vector phi;
  Eigen::MatrixXd M;
  Scalar w2 = 0;
  Mode() {
    SolverSettings s;
    Solver<Hex8, Linear> probe(mesh, soft, s);
    probe.fix(mesh.node_set("xmin"));
    std::vector<Index> free;
    for (Index d = 0; d < probe.num_dofs(); ++d)
      if (!probe.is_constrained(d)) free.push_back(d);
    const Eigen::MatrixXd K = Eigen::MatrixXd(probe.tangent());
    M = Eigen::MatrixXd(probe.mass_matrix());
    const auto n = static_cast<Index>(free.size());
    Eigen::MatrixXd Kf(n, n), Mf(n, n);
    for (Index i = 0; i < n; ++i)
      for (Index j = 0; j < n; ++j) Kf(i, j) = K(free[i], free[j]), Mf(i, j) = M(free[i], free[j]);
    Eigen::GeneralizedSelfAdjointEigenSolver<Eigen::MatrixXd> es(Kf, Mf);
    w2 = es.eigenvalues()[0];
    phi = Vector::Zero(probe.num_dofs());
    for (Index i = 0; i < n; ++i) phi[free[i]] = es.eigenvectors()(i, 0);
    phi *= 0.01 / phi.cwiseAbs().maxCoeff();
  }
  /// The modal coordinate of a field: phi^T M x / phi^T M phi.
  Scalar coordinate(const Vector& x) const { return phi.dot(M * x) / phi.dot(M * phi); }
};

const Mode& first_mode() {
  static const Mode mode;
  return mode;
}

/// The solver's one-step map on the mode: column k is the step from (q, v, a) = e_k.
Eigen::Matrix3d solver_amplification(const SolverSettings& s, Scalar dt) {
  const Mode& m = first_mode();
  Eigen::Matrix3d A;
  for (int k = 0; k < 3; ++k) {
    Solver<Hex8, Linear> solver(m.mesh, soft, s);
    solver.fix(m.mesh.node_set("xmin"));
    const Vector zero = Vector::Zero(solver.num_dofs());
    solver.set_state(k == 0 ? m.phi : zero, k == 1 ? m.phi : zero);
    solver.set_acceleration(k == 2 ? m.phi : zero);
    solver.step(dt);
    A.col(k) << m.coordinate(solver.displacement()), m.coordinate(solver.velocity()), m.coordinate(solver.acceleration());
  }
  return A;
}

}  // namespace

TEST_CASE("generalized-alpha on one mode: the solver's step is the scheme's amplification matrix", "[dynamics][alpha]") {
  const Mode& m = first_mode();
  const Scalar w = std::sqrt(m.w2);
  struct Case {
    const char* name;
    NewmarkSettings scheme;
  };
  const Case cases[] = {{"Newmark 1/4, 1/2", NewmarkSettings{}},
                        {"gen-alpha rho 1", NewmarkSettings::generalized_alpha(1.0)},
                        {"gen-alpha rho 0.8", NewmarkSettings::generalized_alpha(0.8)},
                        {"gen-alpha rho 0.5", NewmarkSettings::generalized_alpha(0.5)},
                        {"gen-alpha rho 0", NewmarkSettings::generalized_alpha(0.0)},
                        {"HHT -0.05", NewmarkSettings::hht(-0.05)},
                        {"HHT -1/3", NewmarkSettings::hht(-1.0 / 3.0)}};
  for (const Case& c : cases)
    for (const Scalar wdt : {0.3, 3.0})
      for (const Scalar zeta : {0.0, 0.05})
        for (const NewmarkMode mode : {NewmarkMode::Accurate, NewmarkMode::RealTime}) {
          SolverSettings s;
          s.linear.kind = LinearSolverKind::Direct;  // exact solves: the comparison is a round-off one
          s.newmark = c.scheme;
          s.newmark.mode = mode;
          s.rayleigh_mass = zeta * w;  // split evenly: alpha / (2 w) = beta w / 2 = zeta / 2
          s.rayleigh_stiffness = zeta / w;
          const Scalar dt = wdt / w, damping = s.rayleigh_mass + s.rayleigh_stiffness * m.w2;
          const Eigen::Matrix3d A = amplification(s.newmark, m.w2, damping, dt);
          const Eigen::Matrix3d As = solver_amplification(s, dt);
          // In the step's natural units (q, dt v, dt^2 a), S A S^-1 with S = diag(1, dt, dt^2), so
          // that one relative error covers all nine entries.
          const Eigen::Matrix3d S = Eigen::Vector3d(1, dt, dt * dt).asDiagonal(), Si = S.inverse();
          const Scalar err = (S * (As - A) * Si).norm() / (S * A * Si).norm();
          const std::complex<Scalar> l = principal_root(A), ls = principal_root(As);
          INFO(fmt::format("{}, w dt = {}, zeta = {}, {}", c.name, wdt, zeta, mode == NewmarkMode::Accurate ? "accurate" : "real time"));
          // One linear step with direct solves: round-off of a 33-dof factorisation (~1e-15 x
          // its condition number, ~1e2 for this mass-dominated system) and of the projection.
          CHECK(err < 1e-11);
          // Its spectral radius and its phase per step (the numerical frequency: period error).
          CHECK(std::abs(std::abs(ls) - std::abs(l)) < 1e-11);
          CHECK(std::abs(std::arg(ls) - std::arg(l)) < 1e-11);
          if (mode == NewmarkMode::Accurate && zeta == 0)
            fmt::print("{:18} w dt = {:3}: |A_solver - A| / |A| = {:.1e}, spectral radius {:.6f}, phase error "
                       "(w_h - w) / w = {:+.3e}\n",
                       c.name, wdt, err, std::abs(l), std::arg(l) / wdt - 1);
        }
}

TEST_CASE("generalized-alpha: the published spectral radius at high frequency, and energy conservation at rho 1",
          "[dynamics][alpha]") {
  for (const Scalar rho : {0.0, 0.3, 0.5, 0.8, 1.0}) {
    const NewmarkSettings s = NewmarkSettings::generalized_alpha(rho);
    // Chung and Hulbert: every root tends to -rho_inf as w dt -> infinity, so the amplification
    // matrix's characteristic polynomial tends to (lambda + rho)^3. Its invariants (trace, sum
    // of principal minors, determinant) are compared, not its roots: the limit is a triple root,
    // which an eigenvalue solver resolves only to ~eps^(1/3). At w dt = 1e6 the limit is
    // approached to O(1 / (w dt)^2) = 1e-12; 1e-9 leaves room for the round-off of entries ~1.
    const Eigen::Matrix3d A = amplification(s, 1e12, 0, 1);
    const Scalar I1 = A.trace(), I2 = 0.5 * (I1 * I1 - (A * A).trace()), I3 = A.determinant();
    INFO("rho_inf " << rho);
    CHECK(std::abs(I1 + 3 * rho) < 1e-9);
    CHECK(std::abs(I2 - 3 * rho * rho) < 1e-9);
    CHECK(std::abs(I3 + rho * rho * rho) < 1e-9);
    // Low modes keep their amplitude to second order: 1 - |lambda| = O((w dt)^3) at w dt = 0.1.
    const Scalar r_low = std::abs(principal_root(amplification(s, 0.01, 0, 1)));
    CHECK(1 - r_low < 2e-3 * (1 - rho) + 1e-14);
    CHECK(r_low <= 1 + 1e-14);
  }
  // rho_inf = 1 is the trapezoidal rule on linear problems: |lambda| = 1 at every frequency.
  // (The eigenvalue solver's round-off grows with the entries, ~(w dt)^2 eps.)
  for (const Scalar wdt : {0.1, 1.0, 10.0, 100.0})
    CHECK(std::abs(std::abs(principal_root(amplification(NewmarkSettings::generalized_alpha(1.0), wdt * wdt, 0, 1))) - 1) < 1e-11);
  // HHT's published limit: rho_inf = (1 + alpha) / (1 - alpha) for its principal roots.
  for (const Scalar a : {-0.05, -0.1, -1.0 / 3.0}) {
    const Scalar r = std::abs(principal_root(amplification(NewmarkSettings::hht(a), 1e12, 0, 1)));
    CHECK(std::abs(r - (1 + a) / (1 - a)) < 1e-4);
  }
}

TEST_CASE("generalized-alpha is second order: halving dt quarters the error of a free vibration", "[dynamics][alpha]") {
  const Mode& m = first_mode();
  const Scalar w = std::sqrt(m.w2), period = 2 * std::numbers::pi / w;
  for (const Scalar rho : {0.5, 0.8}) {
    Scalar errors[2];
    for (int level = 0; level < 2; ++level) {
      SolverSettings s;
      s.linear.kind = LinearSolverKind::Direct;
      s.newmark = NewmarkSettings::generalized_alpha(rho);
      Solver<Hex8, Linear> solver(m.mesh, soft, s);
      solver.fix(m.mesh.node_set("xmin"));
      solver.set_state(m.phi, Vector::Zero(solver.num_dofs()));  // a_0 from equilibrium: -w^2 phi
      const int steps = 40 << level;  // one period, w dt = 0.157 and 0.079
      const Scalar dt = period / steps;
      errors[level] = 0;
      // The largest error over the period: the phase error, O((w dt)^2) per unit time, shows
      // wherever the motion is fast (at the period's end alone its first-order effect vanishes).
      for (int k = 0; k < steps; ++k) {
        solver.step(dt);
        errors[level] = std::max(errors[level], std::abs(m.coordinate(solver.displacement()) - std::cos(w * solver.time())));
      }
    }
    const Scalar ratio = errors[0] / errors[1];
    fmt::print("gen-alpha rho {}: error after one period {:.3e} (40 steps), {:.3e} (80 steps), ratio {:.3f}\n", rho,
               errors[0], errors[1], ratio);
    // Second order: the ratio tends to 4 as dt -> 0; its O(w dt) correction at w dt = 0.16 is a
    // few percent.
    CHECK(ratio > 3.8);
    CHECK(ratio < 4.2);
  }
}

TEST_CASE("generalized-alpha damps the ringing after a sudden release, average acceleration keeps it",
          "[dynamics][alpha]") {
  // bar90 (SCENES.md) pinched statically by a force on one tip corner node, then released (a
  // grasper letting go): the free vibration that follows rings in the high modes the local load
  // excites as well as in the bar's bending. Average acceleration conserves the energy of every
  // mode; generalized-alpha with rho_inf = 0.5 takes it out of the modes with w dt >> 1 (bar90's
  // highest frequencies are ~1e3 rad/s, w dt ~ 10 at dt = 0.01) and keeps the bending mode's
  // (w dt ~ 0.06). The high modes carry the acceleration: its norm is the measure of ringing.
  const Mesh<Hex8> mesh = bar_mesh<Hex8>(10, 3, 3);
  Index corner = -1;
  for (Index i = 0; i < mesh.num_nodes(); ++i)
    if (mesh.node(i).isApprox(Vec3(10, 3, 3))) corner = i;
  REQUIRE(corner >= 0);
  for (const MassKind mass : {MassKind::Consistent, MassKind::Lumped})
    for (const NewmarkMode mode : {NewmarkMode::Accurate, NewmarkMode::RealTime}) {
      Scalar energy[2], ringing[2], start_energy = 0, worst_rise = 0;
      for (int scheme = 0; scheme < 2; ++scheme) {
        SolverSettings s;
        s.mass = mass;
        s.newmark = scheme == 0 ? NewmarkSettings{} : NewmarkSettings::generalized_alpha(0.5);
        s.newmark.mode = mode;
        Solver<Hex8, Corotational> solver(mesh, soft, s);
        solver.fix(mesh.node_set("xmin"));
        const std::array<Index, 1> at{corner};
        const LoadHandle pinch = solver.add_nodal_force(at, Vec3(0, -20, -20));
        solver.solve_static();
        solver.remove_load(pinch);
        start_energy = solver.strain_energy();
        Scalar previous = start_energy, a2 = 0;
        const int steps = 200;
        for (int k = 0; k < steps; ++k) {
          const StepReport r = solver.step(0.01);
          REQUIRE(r.substeps == 1);  // no step failed and was cut
          const Scalar e = solver.kinetic_energy() + solver.strain_energy();
          REQUIRE(std::isfinite(e));
          if (scheme == 1) worst_rise = std::max(worst_rise, (e - previous) / start_energy);
          previous = e;
          if (k >= steps - 50) a2 += solver.acceleration().squaredNorm() / 50;
        }
        energy[scheme] = previous / start_energy;
        ringing[scheme] = std::sqrt(a2);
      }
      const char* what = mode == NewmarkMode::Accurate ? "accurate" : "real time";
      fmt::print("release, {:10} mass, {:9}: energy after 2 s / before: Newmark {:.4f}, gen-alpha 0.5 {:.4f}; rms |a| "
                 "over the last 0.5 s: {:.3g} and {:.3g}; largest one-step energy rise {:.1e}\n",
                 mass == MassKind::Lumped ? "lumped" : "consistent", what, energy[0], energy[1], ringing[0], ringing[1],
                 worst_rise);
      INFO(what);
      // Average acceleration conserves energy on the linearised problem; the corotational
      // nonlinearity and the Newton tolerance change it by well under 1% over 200 steps.
      CHECK(std::abs(energy[0] - 1) < 0.01);
      CHECK(energy[1] < energy[0]);
      // What stays under generalized-alpha is the bending mode's own acceleration (~40-50 with
      // either mass), which it keeps; the high modes' share is gone (measured 41 against 600
      // with the consistent mass, 48 against 103 with the lumped one, whose highest modes are
      // lower and carry less).
      CHECK(ringing[1] < 0.6 * ringing[0]);
      // The scheme never adds energy beyond the nonlinear residual's share per step.
      CHECK(worst_rise < 1e-3);
    }
}

TEST_CASE("generalized-alpha and HHT refuse parameters outside their stable second-order range", "[dynamics][alpha]") {
  CHECK_THROWS_AS(NewmarkSettings::generalized_alpha(1.5), InvalidArgument);
  CHECK_THROWS_AS(NewmarkSettings::generalized_alpha(-0.1), InvalidArgument);
  CHECK_THROWS_AS(NewmarkSettings::generalized_alpha(std::nan("")), InvalidArgument);
  CHECK_THROWS_AS(NewmarkSettings::hht(0.1), InvalidArgument);
  CHECK_THROWS_AS(NewmarkSettings::hht(-0.5), InvalidArgument);
  const Mesh<Hex8> mesh = bar_mesh<Hex8>(2, 1, 1);
  auto accepts = [&](const NewmarkSettings& nm) {
    SolverSettings s;
    s.newmark = nm;
    try {
      Solver<Hex8, Linear> solver(mesh, soft, s);
      return true;
    } catch (const InvalidArgument&) {
      return false;
    }
  };
  CHECK(accepts(NewmarkSettings::generalized_alpha(0.0)));
  CHECK(accepts(NewmarkSettings::hht(-1.0 / 3.0)));
  NewmarkSettings bad = NewmarkSettings::generalized_alpha(0.8);
  bad.gamma = 0.5;  // first order: not the documented scheme
  CHECK_FALSE(accepts(bad));
  bad = NewmarkSettings::generalized_alpha(0.8);
  bad.alpha_f = 0.6;  // alpha_f > 1/2: unstable
  bad.gamma = 0.5 - bad.alpha_m + bad.alpha_f;
  CHECK_FALSE(accepts(bad));
  bad = NewmarkSettings::generalized_alpha(0.8);
  bad.beta = 0.2;  // below 1/4 + (alpha_f - alpha_m) / 2: conditionally stable
  CHECK_FALSE(accepts(bad));
  // The mode and the real-time reach pass through (assigning the settings replaces both); a reach
  // given here is checked like one set by hand.
  for (const NewmarkSettings& nm : {NewmarkSettings::generalized_alpha(0.8, NewmarkMode::RealTime, 0.5),
                                    NewmarkSettings::hht(-0.05, NewmarkMode::RealTime, 0.5)}) {
    CHECK(nm.mode == NewmarkMode::RealTime);
    CHECK(nm.realtime_reach == 0.5);
    CHECK(accepts(nm));
  }
  CHECK(std::isinf(NewmarkSettings::generalized_alpha(0.8).realtime_reach));
  CHECK_FALSE(accepts(NewmarkSettings::generalized_alpha(0.8, NewmarkMode::RealTime, 0.0)));
  CHECK_FALSE(accepts(NewmarkSettings::hht(-0.05, NewmarkMode::RealTime, -1.0)));
}

TEST_CASE("an accurate step of a linear model reports the residual of the state it committed", "[dynamics]") {
  // Found by review (2026-12-01): the one solve of a linear model was taken as converged and the
  // report gave the predictor's residual (relative 5.5e-2 to 1.5e-1 on this bar under gravity,
  // the tolerance 1e-6). The residual is checked against M a + K u - M g over the free dofs,
  // computed here from the solver's matrices (Newmark without damping: the balance at t_n+1).
  // CG's residual is its recursive one (the true one to 1e-10 of |M g| here), the direct
  // solver's a product.
  const Mesh<Hex8> mesh = bar_mesh<Hex8>(4, 1, 1);
  for (MassKind mass : {MassKind::Consistent, MassKind::Lumped})
    for (const bool hht : {false, true})
      for (LinearSolverKind kind : {LinearSolverKind::ConjugateGradient, LinearSolverKind::Direct}) {
        INFO((mass == MassKind::Lumped ? "lumped" : "consistent") << (hht ? ", HHT -0.1" : ", Newmark")
             << (kind == LinearSolverKind::Direct ? ", direct" : ", CG"));
        SolverSettings st;
        st.mass = mass;
        st.linear.kind = kind;
        if (hht) st.newmark = NewmarkSettings::hht(-0.1);
        Solver<Hex8, Linear> s(mesh, soft, st);
        s.fix(mesh.node_set("xmin"));
        s.add_gravity(Vec3(0, 0, -9.81));
        for (int k = 0; k < 3; ++k) {
          const StepReport r = s.step(0.01);
          CHECK(r.relative_residual <= st.newton.residual_tolerance);
          if (hht) continue;  // (its balance weighs two states: the closed form above does not apply)
          const SparseMatrix K = s.tangent(), M = s.mass_matrix();
          Vector g = Vector::Zero(s.num_dofs());
          for (Index i = 0; i < mesh.num_nodes(); ++i) g[3 * i + 2] = -9.81;
          const Vector residual = K * s.displacement() + M * (s.acceleration() - g);
          Scalar free = 0;
          for (Index d = 0; d < s.num_dofs(); ++d)
            if (!s.is_constrained(d)) free += residual[d] * residual[d];
          // Equal to round-off (the predictor's residual, which the report gave, is 0.49 here).
          CHECK(std::abs(std::sqrt(free) - r.residual) <= 1e-10);
        }
      }
}
