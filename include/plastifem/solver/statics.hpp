#pragma once
// Static equilibrium f_int(u) = f_ext at the state's time, by Newton (solver/newton.hpp) with
// an Armijo line search on the potential energy, in load increments that continue from the
// state: the external force goes from the load the state is balanced with (State::load) to the
// current one, and prescribed displacements from their current values to their prescribed
// ones, each increment solved from the last. Path-dependent materials (plasticity) see the
// loading path, not a restart from zero. An increment that fails is halved, and the next ones
// keep its length, down to 1/1024 of the first (10 cuts in a solve).
// The residual is the equation of motion's (solver/equation_of_motion.hpp) with a = v = 0:
//   r(u) = f_int(u) - f_ext  at the free dofs.
#include <plastifem/solver/dynamics.hpp>

#include <chrono>

namespace plastifem {

template <FiniteElement E, class Elastic, bool Enriched = false>
class Statics {
 public:
  using Parts = SolverParts<E, Elastic, Enriched>;
  using Equation = EquationOfMotion<E, Elastic, Enriched>;
  using Motion = typename Equation::Motion;
  using StateT = MotionState;  // the plastic part is the solver's (plastic/)
  static constexpr bool has_exact_tangent = has_exact_tangent_v<Elastic>;
  static constexpr bool constant_tangent = Elastic::constant_tangent;

  /// `state` -> static equilibrium at state.t, in `load_steps` increments (or more, after
  /// cutting). After every converged increment `increment_done(state, fraction)` runs, with the
  /// fraction of the load interval the increment covered (the plastic update), and returns
  /// whether it changed the rest shapes; if the last one did, the state is brought back to
  /// equilibrium at the full load with the new rest shapes by one more Newton solve. Throws
  /// SolverError if an increment fails after 10 cuts.
  template <class AfterIncrement>
  StepReport solve(Parts& p, StateT& state, int load_steps, AfterIncrement&& increment_done) {
    const auto t0 = std::chrono::steady_clock::now();
    if (load_steps < 1) fail<InvalidArgument>("load_steps must be >= 1, got {}", load_steps);
    if (!p.system.any_constrained())
      fail<SolverError>("static solve: no degree of freedom is constrained, so the body can move rigidly and K is "
                        "singular; fix some nodes (Solver::fix) first");
    const Index n = state.num_dofs();
    f_target_.resize(n), g_target_.resize(n), f_start_.resize(n), f_ext_.resize(n), f_int_.resize(n);
    r_.resize(n), du_.resize(n), rhs_.resize(n), u_new_.resize(n), u_.resize(n);
    equation_.resize(n);
    p.loads.assemble(state.t, f_target_);
    if (!f_target_.allFinite()) fail<InvalidArgument>("external loads at t = {} are not finite", state.t);
    g_target_ = state.u;
    p.constraints.evaluate(state.t, 1.0, [&mesh = p.body.mesh()](Index i) { return Vec3(mesh.node(i)); }, g_target_,
                           nullptr, nullptr);
    // The ramp starts from the load u balances statically: State::load after a static solve or
    // set_state. A state in motion balances M a + D v + f_int(u) = load, statically f_int(u);
    // starting from its load asked every fraction of the ramp for the whole load at once (found
    // by review: a bar failed at fraction 5e-5 after one step of 1e-6 s from rest).
    if (state.load.size() == n && (state.v.array() == 0).all() && (state.a.array() == 0).all()) f_start_ = state.load;
    else if (!equation_.internal_force(p, state.u, f_start_, false, TangentKind::Projected))
      fail<SolverError>("static solve: the state's internal force is not finite{}", p.body.locate_invalid(state.u));
    const Vector u_start = state.u;
    StepReport rep;
    Scalar done = 0, step = 1.0 / load_steps;
    int cuts = 0, increments = 0;
    bool rest_changed = false;
    while (done < 1 - 1e-12) {
      const Scalar s = std::min(1.0, done + step);
      u_ = state.u;
      for (Index d : p.system.constrained_dofs()) u_[d] = u_start[d] + s * (g_target_[d] - u_start[d]);
      f_ext_ = f_start_ + s * (f_target_ - f_start_);
      try {
        record(rep, increment(p, state.t));
        state.u = u_;
        state.load = f_ext_;
        rest_changed = increment_done(state, s - done);
        done = s;
        ++increments;
      } catch (const SolverError& err) {
        if (constant_tangent || cuts == 10)
          fail<SolverError>("static solve failed at load fraction {:.4g} after {} cuts: {}", s, cuts, err.what());
        ++cuts, step /= 2;
      }
    }
    if (rest_changed) {
      // Equilibrium with the rest shapes the last increment's flow left (no further flow).
      u_ = state.u;
      record(rep, increment(p, state.t));
      state.u = u_;
    }
    state.v.setZero();
    state.a.setZero();
    state.balance = p.balance();
    state.load = f_target_;
    state.force_scale = -1;  // f_int = load: the next step's balance_scale finds |load|
    state.warm_start.resize(0);
    rep.load_steps = increments;
    rep.wall_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    return rep;
  }

 private:
  struct Problem {
    Statics& s;
    Parts& p;
    Scalar t;
    TangentKind kind;
    bool eager;
    bool tangent_now = false;
    Scalar scale_ = 0;

    Scalar residual(const Vector& u, bool with_tangent) {
      const bool ok = s.equation_.internal_force(p, u, s.f_int_, with_tangent, kind);
      tangent_now = with_tangent;
      const auto norms = s.equation_.residual(p, Motion{}, s.f_int_, s.f_ext_, s.r_);
      scale_ = std::max(p.system.free_norm(s.f_ext_), norms.largest_term);
      return ok ? norms.residual : std::numeric_limits<Scalar>::quiet_NaN();
    }
    void tangent(const Vector& u) { residual(u, true); }
    bool tangent_current() const { return tangent_now; }
    bool eager_tangent() const { return eager; }
    Scalar scale() const { return scale_; }
    bool fall_back() {
      if (kind != TangentKind::Exact) return false;
      kind = TangentKind::Projected;
      return true;
    }
    /// Potential energy W(u) - f_ext . u at the last residual's u.
    Scalar merit(const Vector& u) const { return p.body.energy() - s.f_ext_.dot(u); }
    /// d(merit)/ds along du: r . du.
    Scalar slope(const Vector& du) const { return s.r_.dot(du); }
    [[noreturn]] void invalid(const Vector& u) const {
      const std::string where = p.body.locate_invalid(u);
      fail<SolverError>("static Newton: the residual is not finite{}",
                        where.empty() ? " (external loads or prescribed displacements not finite, or the residual overflowed)"
                                      : where);
    }
    LinearSolveReport solve(int, Scalar, Scalar, Vector& du) {
      s.rhs_ = -s.r_;
      p.system.zero_held(s.rhs_);
      auto attempt = [&] {
        du.setZero();
        p.system.form_stiffness(p.threads);
        return p.system.static_linear().solve(p.system.A, s.rhs_, du);
      };
      try {
        return attempt();
      } catch (const SolverError&) {
        if (!fall_back()) throw;
        tangent(s.u_);
        s.rhs_ = -s.r_;
        p.system.zero_held(s.rhs_);
        return attempt();
      }
    }
  };

  NewtonResult increment(Parts& p, Scalar t) {
    const auto& st = p.settings;
    const bool exact = has_exact_tangent && st.newton.exact_tangent;
    const bool search = st.newton.line_search && exact && !constant_tangent;
    Problem prob{*this, p, t, exact ? TangentKind::Exact : TangentKind::Projected, !search};
    NewtonOptions o;
    o.tolerance = st.newton.residual_tolerance;
    o.max_iterations = st.newton.max_iterations;
    o.min_iterations = 0;
    o.constant_tangent = constant_tangent;
    o.verify_one_solve = true;  // a linear model's one solve is checked against the tolerance
    o.line_search = search;
    o.length = p.body.size();
    o.absolute_tolerance = 10 * p.system.rest_force_roundoff(p.body, p.threads);
    o.running_max_scale = false;  // the initial imbalance's and the current iterate's scale (NewtonOptions)
    NewtonResult r = newton(prob, u_, o, EnergyArmijo{}, du_, u_new_);
    r.exact_tangent_dropped = exact && prob.kind == TangentKind::Projected;
    if (!r.converged)
      fail<SolverError>("static Newton did not converge in {} iterations (|r| = {:.3g}, relative {:.3g}){}",
                        st.newton.max_iterations, r.residual, r.relative_residual,
                        r.exact_tangent_dropped ? "; the exact tangent was indefinite or did not descend on the way (an unstable "
                                         "equilibrium, or a load past a limit point), and the projected tangent it "
                                         "went on with converges slowly at best there"
                                       : "");
    if (!u_.allFinite()) fail<SolverError>("static Newton produced a non-finite displacement");
    return r;
  }

  Equation equation_;
  Vector f_target_, g_target_, f_start_, f_ext_, f_int_, r_, du_, rhs_, u_new_, u_;
};

}  // namespace plastifem
