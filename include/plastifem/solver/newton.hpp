#pragma once
// One Newton iteration loop for every nonlinear solve the toolkit makes (a Newmark step, a
// static load increment), generic over the problem (the NewtonProblem concept below says what
// it must answer) and over two policies: the line search (ResidualBacktracking in dynamics,
// EnergyArmijo in statics, where the residual of a conservative model has a potential), and the
// tangent's timing (lazily, only for an iterate that failed the convergence test; or eagerly).
#include <plastifem/core/vector_ops.hpp>
#include <plastifem/solver/linear_solver.hpp>
#include <plastifem/solver/settings.hpp>

#include <cmath>
#include <concepts>
#include <limits>

namespace plastifem {

/// What newton() asks of a nonlinear problem r(u) = 0 over the free dofs.
template <class P>
concept NewtonProblem = requires(P& p, const Vector& u, Vector& du, bool with_tangent, int iteration, Scalar r) {
  /// |r(u)| (+inf or NaN if some element cannot be evaluated); with_tangent: K(u) too.
  { p.residual(u, with_tangent) } -> std::same_as<Scalar>;
  /// K at u (the last residual's u).
  p.tangent(u);
  /// Whether the last residual came with its tangent.
  { p.tangent_current() } -> std::same_as<bool>;
  /// The force scale of the last residual (the largest term of the balance).
  { p.scale() } -> std::same_as<Scalar>;
  /// du = -A^{-1} r with the problem's matrix, linear solver and a tolerance that reaches
  /// `target` from |r| (inexact Newton); falls back from the exact to the projected tangent if
  /// the system is indefinite.
  { p.solve(iteration, r, r, du) } -> std::same_as<LinearSolveReport>;
  /// Use the projected tangent from now on (false if it already does).
  { p.fall_back() } -> std::same_as<bool>;
  /// [[noreturn]]: says which element made r non-finite.
  p.invalid(u);
};

/// A problem with a potential (statics of a hyperelastic body), as EnergyArmijo needs it.
template <class P>
concept NewtonProblemWithPotential = NewtonProblem<P> && requires(P& p, const Vector& u) {
  /// The potential energy at the last residual's u, and its derivative r . du along du.
  { p.merit(u) } -> std::same_as<Scalar>;
  { p.slope(u) } -> std::same_as<Scalar>;
  /// Whether a step the search does not apply to evaluates its tangent with its residual.
  { p.eager_tangent() } -> std::same_as<bool>;
};

/// A line search for problem P: from u along du with |r(u)| = r0, the step length s taken, with
/// u_new = u + s du, r_new = |r(u_new)|, and `found` false if no length decreased the merit.
template <class L, class P>
concept LineSearch = requires(const L& search, P& p, const Vector& u, Vector& u_new, Scalar r0, Scalar& r_new,
                              bool applies, bool& found) {
  { search(p, u, u, r0, applies, u_new, r_new, found) } -> std::same_as<Scalar>;
};

struct NewtonOptions {
  Scalar tolerance = 1e-6;            ///< |r| <= tolerance * scale
  Scalar increment_tolerance = 1e-10; ///< stagnation: s |du| <= tol (|u| + length)
  Scalar length = 1;                  ///< the body's size (increment test)
  int max_iterations = 50;
  int min_iterations = 0;             ///< dynamics: 1 (the first solve also gives the next step's CG start)
  bool stagnation = false;            ///< accept a stagnated iterate (dynamics)
  bool constant_tangent = false;      ///< a linear model: one converged solve is the answer
  /// Check the residual after that solve (statics: a solve short of the tolerance goes on).
  /// Without it the result's residual is the one before the solve (Dynamics computes the
  /// committed state's from it).
  bool verify_one_solve = false;
  bool line_search = false;           ///< whether the line search policy may backtrack
  bool eager_tangent = false;         ///< evaluate the tangent with each new iterate
  Scalar refresh_ratio = 0;           ///< keep the tangent while |r| falls by this factor per iteration (0: never)
  /// Without a reference_scale, the scale the tolerance applies to: true, the largest seen over
  /// the iterations (a step whose inertia vanishes as Newton converges keeps the scale it started
  /// with; dynamics from a state with no force at all); false, the
  /// larger of the first iterate's (the initial imbalance) and the current iterate's (statics: an
  /// iterate far from equilibrium, with huge internal forces, must not set the scale its
  /// successors are held to; a body held by one node under CG took |r| = 4.6e6 against
  /// |f_ext| = 0.02 as converged, relative to an intermediate iterate's |f_int| ~ 6e13).
  bool running_max_scale = true;
  /// With the running maximum, how far above the first iterate's scale an iterate may raise it.
  /// A garbage iterate far from the solution has huge inertia and internal forces that cancel
  /// each other: measured on a nearly incompressible StableNeoHookean bar stepped at dt = 1
  /// (its nodes moved by 1e-13), Newton "converged" to |u| = 4e7 on a bar 10 long, relative to
  /// its own forces. Capped, such an iterate must meet the tolerance of the step's own scale,
  /// fails, and the step is cut.
  Scalar max_scale_growth = 1e3;
  /// If > 0, the force scale of the state the solve starts from (dynamics: the committed
  /// state's, Dynamics::start_step). The scale at an iterate is then this raised to the
  /// iterate's own, at most max_scale_growth times this or the first iterate's (a start state
  /// at rest under no load has a round-off scale), with no running maximum: at a dt far
  /// beyond the body's lowest period the predictor's forces are (omega dt)^2 times the
  /// physical ones, and a scale that kept them accepted states far from equilibrium (Hex8
  /// 4x1x1 bar under gravity, first period 1.8 s, dt = 10: |M a + f_int - f_ext| = 0.40 |f_ext|
  /// "converged" at tolerance 1e-6; with this, 1.1e-6).
  Scalar reference_scale = 0;
  /// Also converged when |r| <= this: the round-off level of the force evaluation
  /// (System::rest_force_roundoff), for a body at rest under no load, whose force scale is that
  /// round-off itself (an unloaded Hex8 bar failed its fourth step: |r| = 1.9e-11, "relative 0.58").
  Scalar absolute_tolerance = 0;
};

struct NewtonResult {
  int iterations = 0, linear_iterations = 0;
  Scalar residual = 0, relative_residual = 0, scale = 0;
  Convergence convergence = Convergence::Converged;
  bool converged = false;
  bool linear_converged = true;
  Scalar linear_relative_residual = 0;
  /// The exact tangent was given up on the way (set by the problem's owner, who holds the
  /// tangent kind: Problem::fall_back).
  bool exact_tangent_dropped = false;
};

/// A Newton solve into a step's report: its iterations are added, its end (residual, how it
/// ended, its last linear solve) is the report's.
inline void record(StepReport& rep, const NewtonResult& r) {
  rep.newton_iterations += r.iterations;
  rep.linear_iterations += r.linear_iterations;
  rep.residual = r.residual;
  rep.relative_residual = r.relative_residual;
  rep.convergence = r.convergence;
  rep.stagnated = rep.stagnated || r.convergence == Convergence::Stagnated;
  rep.linear_converged = rep.linear_converged && r.linear_converged;
  rep.linear_relative_residual = r.linear_relative_residual;
  rep.exact_tangent_dropped += r.exact_tangent_dropped;
}

/// Backtracking on |r| along du (force-only evaluations): the full step if it decreases |r|,
/// else the first halved step that does. If none does (the warped corotational tangent is not
/// the exact Jacobian, so du need not descend; or the tangent is stale), `found` is false and
/// u_new is the full step.
struct ResidualBacktracking {
  template <NewtonProblem Problem>
  Scalar operator()(Problem& p, const Vector& u, const Vector& du, Scalar r0, bool applies, Vector& u_new,
                    Scalar& r_new, bool& found) const {
    found = true;
    u_new = u + du;
    r_new = p.residual(u_new, false);
    if (!applies || (std::isfinite(r_new) && r_new < (1 - 1e-4) * r0)) return 1;
    Scalar s = 0.5;
    for (int k = 0; k < 7; ++k, s *= 0.5) {
      u_new = u + s * du;
      r_new = p.residual(u_new, false);
      if (std::isfinite(r_new) && r_new < (1 - 1e-4 * s) * r0) return s;
    }
    found = false;
    u_new = u + du;
    r_new = p.residual(u_new, false);
    return 1;
  }
};

/// Backtracking (Armijo) on the potential energy Pi = W(u) - f_ext . u, which the exact Newton
/// direction descends whenever K is positive definite (slope r . du < 0), or a decrease of |r|.
/// On |r| alone, bending crawls: the full step that straightens the rotation field raises |r|
/// before it falls (Hex8 bar at 1 g: 179 Newton iterations on |r|, 31 on Pi). If no step length
/// decreases either, `found` is false and u_new is the full step.
struct EnergyArmijo {
  template <NewtonProblemWithPotential Problem>
  Scalar operator()(Problem& p, const Vector& u, const Vector& du, Scalar r0, bool applies, Vector& u_new,
                    Scalar& r_new, bool& found) const {
    found = true;
    if (!applies) {
      u_new = u + du;
      r_new = p.residual(u_new, p.eager_tangent());
      return 1;
    }
    const Scalar pi0 = p.merit(u), slope = p.slope(du);
    Scalar s = 1;
    bool decreased = false;
    for (int k = 0; k < 8 && !decreased && slope < 0; ++k) {
      u_new = u + s * du;
      r_new = p.residual(u_new, false);
      const Scalar pi = p.merit(u_new);
      // Either merit may accept: Pi (with the round-off of Pi near convergence allowed for) or |r|.
      decreased = std::isfinite(pi) && std::isfinite(r_new) &&
                  (pi <= pi0 + 1e-4 * s * slope + 1e-12 * (std::abs(pi0) + 1e-30) || r_new < (1 - 1e-4 * s) * r0);
      if (!decreased) s *= 0.5;
    }
    if (!decreased) {
      found = false;
      s = 1;
      u_new = u + du;
      r_new = p.residual(u_new, false);
    }
    return s;
  }
};

/// Newton from u (updated in place). Returns with `converged` false if it did not converge
/// (the caller says what failed; u is the caller's trial vector, its state is untouched).
///
/// Tangent reuse (NewtonOptions::refresh_ratio > 0): the tangent assembled at the step's first
/// iterate is kept while every iteration reduces |r| at least that much; an iteration that
/// reduces it less (or a line search that finds no decrease along the kept tangent's
/// direction) refreshes it at the current iterate. Most Newmark steps need one or two
/// iterations, and the tangent of the first is as good as a fresh one for the second: bar90
/// Hex8 Corotational (exact tangent) keeps 1.60 Newton and 18.0 CG iterations per step and
/// assembles 1.0 instead of 1.6 tangents, 0.49 -> 0.38 ms per step.
/// A line search that fails along a fresh exact tangent falls back to the projected tangent
/// for the rest of the solve (an exact Hessian that does not descend is indefinite there).
template <NewtonProblem Problem, LineSearch<Problem> Search>
NewtonResult newton(Problem& p, Vector& u, const NewtonOptions& o, const Search& line_search, Vector& du,
                    Vector& u_new) {
  NewtonResult res;
  Scalar rnorm = p.residual(u, true);
  bool tangent_at_u = true, stale = false;
  Scalar first_scale = 0;
  // The force scale |r| is measured against at the current iterate: with a reference scale,
  // the reference raised to the iterate's own (capped); else `previous` (the largest so far, or
  // the first) raised to the iterate's own, which may exceed the first iterate's at most
  // max_scale_growth times (with the running maximum).
  auto scale_from = [&](Scalar previous) {
    if (o.reference_scale > 0) {
      const Scalar cap = o.max_scale_growth * std::max(o.reference_scale, first_scale);
      return std::max({o.reference_scale, std::min(p.scale(), cap), Scalar(1e-30)});
    }
    const Scalar own = o.running_max_scale ? std::min(p.scale(), o.max_scale_growth * first_scale) : p.scale();
    return std::max({previous, own, Scalar(1e-30)});
  };
  for (int it = 0;; ++it) {
    if (!std::isfinite(rnorm)) p.invalid(u);
    if (it == 0) first_scale = p.scale();
    res.scale = scale_from(o.running_max_scale ? res.scale : first_scale);
    res.residual = rnorm;
    res.relative_residual = rnorm / res.scale;
    if (it >= o.min_iterations && (rnorm <= o.tolerance * res.scale || rnorm <= o.absolute_tolerance)) {
      res.converged = true;
      return res;
    }
    if (it == o.max_iterations) break;
    if (!tangent_at_u) {
      p.tangent(u);
      tangent_at_u = true;
      stale = false;
    }
    // Inexact Newton (Eisenstat-Walker style): the problem solves only as accurately as this
    // iteration needs to reach the tolerance.
    const LinearSolveReport lr = p.solve(it, rnorm, o.tolerance * res.scale, du);
    res.linear_iterations += lr.iterations;
    res.linear_converged = res.linear_converged && lr.converged;
    res.linear_relative_residual = lr.relative_residual;
    ++res.iterations;
    if (o.constant_tangent && lr.converged) {
      u += du;
      res.convergence = Convergence::OneSolve;
      if (!o.verify_one_solve) {
        res.converged = true;
        return res;
      }
      rnorm = p.residual(u, false);
      tangent_at_u = false;
      // The test above decides; a linear model is then solved again from there, unless the
      // correction no longer changes u (the residual is at its round-off floor).
      if (o.stagnation && !(rnorm <= o.tolerance * scale_from(res.scale) || rnorm <= o.absolute_tolerance) &&
          norm(du) <= o.increment_tolerance * (norm(u) + o.length) && rnorm <= std::sqrt(o.tolerance) * res.scale) {
        res.residual = rnorm;
        res.relative_residual = rnorm / res.scale;
        res.convergence = Convergence::Stagnated;
        res.converged = true;
        return res;
      }
      continue;
    }
    Scalar r_new;
    bool found;
    const Scalar s = line_search(p, u, du, rnorm, o.line_search, u_new, r_new, found);
    if (!found && stale) {
      // No decrease along a kept tangent: refresh it here and solve again, without moving.
      rnorm = p.residual(u, true);
      stale = false;
      continue;
    }
    if (!found) p.fall_back();
    u.swap(u_new);
    const Scalar reduction = r_new / rnorm;
    rnorm = r_new;
    tangent_at_u = p.tangent_current();
    if (!tangent_at_u && o.refresh_ratio > 0 && std::isfinite(reduction) && reduction <= o.refresh_ratio) {
      tangent_at_u = true;  // keep the tangent: this iteration converged fast
      stale = true;
    }
    // Stagnation: the increment no longer changes u and |r| is near the tolerance. A residual
    // that already meets the tolerance goes round the loop instead, to be reported converged.
    const bool meets_tolerance = rnorm <= o.tolerance * scale_from(res.scale) || rnorm <= o.absolute_tolerance;
    if (o.stagnation && !meets_tolerance && s * norm(du) <= o.increment_tolerance * (norm(u) + o.length) &&
        rnorm <= std::sqrt(o.tolerance) * res.scale) {
      res.residual = rnorm;
      res.relative_residual = rnorm / res.scale;
      res.convergence = Convergence::Stagnated;
      res.converged = true;  // at round-off level: the increment no longer changes u
      return res;
    }
  }
  return res;
}

}  // namespace plastifem
