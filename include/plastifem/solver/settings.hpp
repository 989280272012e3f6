#pragma once
// What a user sets (SolverSettings) and what a step or static solve reports (StepReport).
#include <plastifem/assembly/mass.hpp>
#include <plastifem/plastic/params.hpp>
#include <plastifem/solver/linear_solver.hpp>

#include <cmath>
#include <limits>

namespace plastifem {

enum class NewmarkMode { Accurate, RealTime };

/// NewmarkSettings::realtime_reach that never redoes a real-time step (the default).
inline constexpr Scalar unlimited_reach = std::numeric_limits<Scalar>::infinity();

struct NewtonSettings {
  /// Converged when |r| <= tol * (force scale) over free dofs; the scale is the largest of the
  /// terms of the balance: |f_ext|, |f_int|, and in dynamics |M a| and |D v| (a body in rigid
  /// motion under no load is then held to its inertia, not to round-off). 1e-6 matches the CG
  /// tolerance the benchmarks use.
  Scalar residual_tolerance = 1e-6;
  /// A step also ends when the increment stagnates, |du| <= tol * (|u| + mesh size), with
  /// |r| <= sqrt(residual_tolerance) * scale: reported as StepReport::stagnated.
  Scalar increment_tolerance = 1e-10;
  int max_iterations = 50;
  /// Backtracking line search when the exact tangent is in use: Armijo on the potential
  /// energy or a decrease of |r| in statics, a decrease of |r| in dynamics. The warped and
  /// projected tangents give no descent guarantee, so with them Newton takes full steps.
  bool line_search = true;
  /// Use the model's exact tangent where it has one (hyperelastic models, per-point
  /// Corotational): quadratic Newton. It is indefinite under strong compression; the solver
  /// then falls back to the projected (PSD) tangent for the rest of the step. false: always
  /// the projected one (for Corotational the warped R K0 R^T, SOFA's and VegaFEM's choice).
  bool exact_tangent = true;
  /// Assemble the tangent once per Newmark step, at the predictor, and use force-only
  /// evaluations in the later iterations while Newton converges: for the projected tangent
  /// while each iteration at least halves |r| (the warped tangent already omits dR/dx, and the
  /// step's motion changes it far less than that; bar5760 Hex8 Corotational: the same 1.9
  /// Newton iterations per step with a third fewer element-matrix evaluations); for the exact
  /// tangent while each iteration reduces |r| tenfold or more (bar90 Hex8 Corotational: the
  /// same 1.6 Newton iterations per step, 1.0 instead of 1.6 tangent assemblies, 0.49 -> 0.38
  /// ms). An iteration short of that refreshes the tangent at its iterate. false: a fresh
  /// tangent at every iterate that failed the convergence test.
  bool tangent_once_per_step = true;
};

struct NewmarkSettings {
  Scalar beta = 0.25, gamma = 0.5;  ///< average acceleration: unconditionally stable, no dissipation
  NewmarkMode mode = NewmarkMode::Accurate;
  /// Generalized-alpha weights of the balance (solver/newmark.hpp); 0, 0 is Newmark's method.
  /// Set them through generalized_alpha() or hht() rather than by hand.
  Scalar alpha_m = 0, alpha_f = 0;
  /// Real time's reach: the largest change of an element edge in one step, relative to the edge's
  /// length (|du_j - du_i| / |X_j - X_i| over the mesh's corner-to-corner edges; in a cut
  /// element, over each piece's own nodal motion), that one linearised solve may make; a
  /// real-time step that moves further is redone as an accurate (Newton) step, counted in
  /// StepReport::realtime_redone. The linearisation moves nodes along chords: an edge turned by
  /// theta in one step is stretched by about theta^2 / 2 (12% at 0.5). Off (unlimited_reach) by
  /// default, for a fixed cost per step. Set it (0.5) for a model undefined for inverted elements
  /// (NeoHookean, MooneyRivlin) that is let go suddenly: solver/dynamics.hpp says why, with the
  /// figures.
  Scalar realtime_reach = unlimited_reach;
  /// Real time's tangent reuse (opt-in; 0, the default, assembles K at every step's end): a
  /// step keeps the tangent K its linearisation was assembled with, and evaluates only the
  /// forces at its end, while no element edge has changed by more than this fraction of its
  /// length since that tangent's state (the measure of realtime_reach, from that state rather
  /// than over one step); then the tangent is assembled afresh. The forces stay exact, so the
  /// step still balances the equation of motion up to the linear solve: only its Jacobian is
  /// older, which changes the step's increment by about A^-1 (K - K_kept) du, small where the
  /// Newmark matrix A = M / (beta dt^2) + K is mass-dominated. In a cut body the measure reads
  /// each cut element's pieces as they move: a piece moving away whole does not count.
  /// Counted in StepReport::tangents_kept; solver/dynamics.hpp gives the measured cost and error.
  Scalar tangent_reach = 0;

  /// Chung and Hulbert's generalized-alpha (1993) with high-frequency spectral radius
  /// rho_inf in [0, 1]: second order, unconditionally stable, and the most dissipation of
  /// high modes for the least of low ones (a sudden release's ringing in the smallest elements
  /// dies out, the body's own motion keeps its energy). rho_inf = 1 conserves energy on linear
  /// problems like the trapezoidal rule; 0.8 is a common choice; 0 annihilates the highest modes
  /// in one step. alpha_m = (2 rho - 1) / (rho + 1), alpha_f = rho / (rho + 1),
  /// gamma = 1/2 - alpha_m + alpha_f, beta = (1 - alpha_m + alpha_f)^2 / 4 (their eq. 25-26).
  /// Like hht(), it returns whole settings: assigning them replaces the mode and the reach too,
  /// so pass those here (`s.newmark = NewmarkSettings::generalized_alpha(0.8, NewmarkMode::RealTime, 0.5)`),
  /// and set tangent_reach after.
  static NewmarkSettings generalized_alpha(Scalar rho_inf, NewmarkMode mode = NewmarkMode::Accurate,
                                           Scalar realtime_reach = unlimited_reach) {
    if (!(rho_inf >= 0 && rho_inf <= 1))
      fail<InvalidArgument>("generalized-alpha needs a spectral radius rho_inf in [0, 1], got {}", rho_inf);
    const Scalar am = (2 * rho_inf - 1) / (rho_inf + 1), af = rho_inf / (rho_inf + 1);
    return {0.25 * (1 - am + af) * (1 - am + af), 0.5 - am + af, mode, am, af, realtime_reach};
  }
  /// Hilber, Hughes and Taylor's alpha method (1977) with their alpha in [-1/3, 0] (Abaqus'
  /// parameter of the same name; its default is -0.05): alpha_m = 0, alpha_f = -alpha,
  /// gamma = 1/2 - alpha, beta = (1 - alpha)^2 / 4. Whole settings, as generalized_alpha():
  /// set tangent_reach after.
  static NewmarkSettings hht(Scalar alpha, NewmarkMode mode = NewmarkMode::Accurate,
                             Scalar realtime_reach = unlimited_reach) {
    if (!(alpha >= -1.0 / 3.0 && alpha <= 0))
      fail<InvalidArgument>("HHT needs alpha in [-1/3, 0], got {}", alpha);
    return {0.25 * (1 - alpha) * (1 - alpha), 0.5 - alpha, mode, 0, -alpha, realtime_reach};
  }
};

/// How a Newton solve ended.
enum class Convergence {
  Converged,  ///< |r| <= residual_tolerance * scale
  Stagnated,  ///< the increment stopped changing u with |r| <= sqrt(residual_tolerance) * scale
  OneSolve,   ///< real-time mode, or a linear model: one linear solve is the step
};

/// What one step or static solve did.
struct StepReport {
  /// The Newton and CG iterations of the accepted (sub-)steps and load increments. Attempts that
  /// failed and were redone (from u_n after the predictor, or in halves) are not counted: their
  /// number is in predictor_retries and substeps. A real-time step redone as an accurate one
  /// counts its abandoned solve's CG iterations (they are part of that accepted sub-step).
  int newton_iterations = 0;
  int linear_iterations = 0;     ///< summed over Newton iterations, as newton_iterations
  Scalar residual = 0;           ///< |r| over free dofs at the committed state (real time: after its one solve)
  /// residual / the force scale Newton held it to (NewtonOptions::running_max_scale): in
  /// dynamics the largest balance term over the step's iterations, in statics the larger of the
  /// initial imbalance's and the last iterate's; not the committed state's own largest force,
  /// which may be several times smaller
  Scalar relative_residual = 0;
  Convergence convergence = Convergence::Converged;
  bool stagnated = false;        ///< a (sub-)step was accepted on stagnation, not on the tolerance
  bool linear_converged = true;  ///< every linear solve reached its tolerance (false: CG stopped at its cap)
  Scalar linear_relative_residual = 0;  ///< the last linear solve's |A x - b| / |b|
  int load_steps = 1;            ///< statics: increments used (after automatic cutting)
  int substeps = 1;              ///< dynamics: Newmark sub-steps used (> 1 after automatic step cutting)
  int predictor_retries = 0;     ///< dynamics: sub-steps redone from u_n after failing from the predictor
  int realtime_redone = 0;       ///< real time: sub-steps redone as accurate steps (NewmarkSettings::realtime_reach)
  int tangents_kept = 0;         ///< real time: sub-steps that kept their linearisation's tangent (NewmarkSettings::tangent_reach)
                                 ///< and whose plastic update left the rest shapes (moved ones make it stale)
  /// Sub-steps (statics: load increments) that gave up the exact tangent, indefinite or not a
  /// descent direction, and went on with the projected one (NewtonSettings::exact_tangent): an
  /// unstable equilibrium (a cut body's pieces, which have no contact), strong compression, or
  /// a load near a limit point. Convergence there is linear at best.
  int exact_tangent_dropped = 0;
  /// dynamics: constrained nodes whose prescribed path (or given velocity) jumps at the end of a
  /// (sub-)step, summed over sub-steps; their velocity and acceleration are the path's after
  /// the jump (Constraints::evaluate).
  Index path_jumps = 0;
  PlasticReport plastic;         ///< what the plastic updates of the step (its sub-steps, increments) did
  double wall_ms = 0;

  /// The report of a step made of sub-steps, one more of which is `r`: counts add up, the
  /// residual and how it ended are the last sub-step's (the wall time is the caller's).
  void add_substep(const StepReport& r) {
    newton_iterations += r.newton_iterations;
    linear_iterations += r.linear_iterations;
    predictor_retries += r.predictor_retries;
    realtime_redone += r.realtime_redone;
    tangents_kept += r.tangents_kept;
    exact_tangent_dropped += r.exact_tangent_dropped;
    path_jumps += r.path_jumps;
    residual = r.residual;
    relative_residual = r.relative_residual;
    convergence = r.convergence;
    stagnated = stagnated || r.stagnated;
    linear_converged = linear_converged && r.linear_converged;
    linear_relative_residual = r.linear_relative_residual;
    plastic.add(r.plastic);
    substeps += 1;
  }
};

struct SolverSettings {
  MassKind mass = MassKind::Consistent;
  NewmarkSettings newmark;
  NewtonSettings newton;
  LinearSolverSettings linear;  ///< dynamics (default: warm-started Jacobi CG, 1e-8)
  /// statics (default: the direct solver, CHOLMOD where built in, else SimplicialLDLT)
  LinearSolverSettings static_linear{LinearSolverKind::Direct, 1e-8, 2000, DirectSolver::Auto, /*verify_residual=*/true};
  /// Rayleigh damping D = alpha M + beta Kd, with Kd the projected (positive semi-definite)
  /// tangent at the step's predicted end, fixed within the step: R K0 R^T for the corotational
  /// models, so the damping turns with the body; K0 for Linear. The exact tangent would be indefinite
  /// under compression (negative damping) and change within a step (solver/dynamics.hpp).
  Scalar rayleigh_mass = 0, rayleigh_stiffness = 0;
  /// Threads for element loops and products: 1 by default (predictable; on small scenes and
  /// busy machines threads cost more than they give), 0: OpenMP default, N: N threads.
  int threads = 1;
  /// A Newmark step whose Newton iteration fails is cut in halves, up to this many times
  /// (at most 30: 2^30 sub-steps).
  int max_step_cuts = 6;
};

/// Throws InvalidArgument naming the first setting out of range.
inline void validate_settings(const SolverSettings& s) {
  const auto& nm = s.newmark;
  if (nm.alpha_m == 0 && nm.alpha_f == 0) {
    if (!(nm.gamma >= 0.5) || !(nm.beta >= 0.25 * (0.5 + nm.gamma) * (0.5 + nm.gamma) - 1e-15) || !(nm.beta <= 0.5))
      fail<InvalidArgument>("Newmark parameters beta = {}, gamma = {} are not unconditionally stable: need gamma >= "
                            "1/2 and (gamma + 1/2)^2 / 4 <= beta <= 1/2 (default 1/4, 1/2)",
                            nm.beta, nm.gamma);
  } else if (!(nm.alpha_m <= nm.alpha_f && nm.alpha_f <= 0.5 && nm.alpha_m >= -1) ||
             !(std::abs(nm.gamma - (0.5 - nm.alpha_m + nm.alpha_f)) <= 1e-12) ||
             !(nm.beta >= 0.25 + 0.5 * (nm.alpha_f - nm.alpha_m) - 1e-15) || !(nm.beta <= 1)) {
    // Chung and Hulbert (1993): second order with gamma = 1/2 - alpha_m + alpha_f, unconditionally
    // stable for alpha_m <= alpha_f <= 1/2 and beta >= 1/4 + (alpha_f - alpha_m) / 2.
    fail<InvalidArgument>("generalized-alpha parameters alpha_m = {}, alpha_f = {}, beta = {}, gamma = {} are not a "
                          "second-order unconditionally stable scheme: use NewmarkSettings::generalized_alpha(rho_inf) "
                          "or NewmarkSettings::hht(alpha)",
                          nm.alpha_m, nm.alpha_f, nm.beta, nm.gamma);
  }
  if (!(s.rayleigh_mass >= 0) || !(s.rayleigh_stiffness >= 0) || !std::isfinite(s.rayleigh_mass) ||
      !std::isfinite(s.rayleigh_stiffness))
    fail<InvalidArgument>("Rayleigh coefficients must be finite and >= 0, got alpha = {}, beta = {}", s.rayleigh_mass,
                          s.rayleigh_stiffness);
  // A relative residual tolerance of 1 or more is met by the unloaded start itself (|r| = |f_ext|
  // there): a static solve would return u = 0 after no iteration.
  if (!(s.newton.residual_tolerance > 0 && s.newton.residual_tolerance < 1) ||
      !(s.newton.increment_tolerance >= 0) || !std::isfinite(s.newton.increment_tolerance) ||
      s.newton.max_iterations < 1)
    fail<InvalidArgument>("Newton needs a residual tolerance in (0, 1), a finite increment tolerance >= 0 and at least "
                          "one iteration, got {}, {} and {}",
                          s.newton.residual_tolerance, s.newton.increment_tolerance, s.newton.max_iterations);
  for (const LinearSolverSettings* l : {&s.linear, &s.static_linear})  // a direct solve uses neither
    if (!std::isfinite(l->tolerance) ||
        (l->kind == LinearSolverKind::ConjugateGradient && (!(l->tolerance > 0 && l->tolerance < 1) || l->max_iterations < 1)))
      fail<InvalidArgument>("CG needs a tolerance in (0, 1) and at least one iteration, got {} and {}", l->tolerance,
                            l->max_iterations);
  if (!(nm.realtime_reach > 0))  // infinity allowed: never redone
    fail<InvalidArgument>("realtime_reach must be > 0 (infinity: never redo a real-time step), got {}",
                          nm.realtime_reach);
  if (!(nm.tangent_reach >= 0) || !std::isfinite(nm.tangent_reach))  // 0: never kept
    fail<InvalidArgument>("tangent_reach must be finite and >= 0 (0: assemble the tangent every step), got {}",
                          nm.tangent_reach);
  if (s.max_step_cuts < 0 || s.max_step_cuts > 30)
    fail<InvalidArgument>("max_step_cuts must be in [0, 30] (2^30 sub-steps), got {}", s.max_step_cuts);
  if (s.threads < 0) fail<InvalidArgument>("threads must be >= 0 (0: OpenMP's default), got {}", s.threads);
  // An enumerator made from an integer (settings read from a file) that names none would run as
  // whatever branch the code falls to.
  auto unknown = [](auto value, auto last) { return static_cast<unsigned>(value) > static_cast<unsigned>(last); };
  if (unknown(s.mass, MassKind::Lumped)) fail<InvalidArgument>("unknown mass kind {}", static_cast<int>(s.mass));
  if (unknown(nm.mode, NewmarkMode::RealTime))
    fail<InvalidArgument>("unknown Newmark mode {}", static_cast<int>(nm.mode));
  for (const LinearSolverSettings* l : {&s.linear, &s.static_linear})
    if (unknown(l->kind, LinearSolverKind::ConjugateGradient) ||
        unknown(l->preconditioner, CgPreconditioner::BlockJacobi) || unknown(l->direct, DirectSolver::CholmodSupernodal))
      fail<InvalidArgument>("unknown linear solver kind {}, preconditioner {} or direct solver {}",
                            static_cast<int>(l->kind), static_cast<int>(l->preconditioner),
                            static_cast<int>(l->direct));
  resolve_direct_solver(s.linear.direct);  // a back-end this build lacks: a clear error now
  resolve_direct_solver(s.static_linear.direct);
}

}  // namespace plastifem
