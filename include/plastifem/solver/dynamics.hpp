#pragma once
// One Newmark (or generalized-alpha) step from a state n to a trial state n+1 (solver/newmark.hpp
// for the formulas), in the two modes:
//
//  - Accurate: Newton on r(u) = 0 (solver/newton.hpp) from the constant-acceleration predictor
//    (a retry from u_n if that fails), with the tangent assembled lazily, inexact CG, and a line
//    search on |r| when the exact tangent is in use.
//  - Real time: one linearised solve at u_n, the classic linearly implicit step SOFA and
//    VegaFEM take: A du = -r_lin with r_lin = w_m M a + D v + f_int(u_n) + K(u_n) (g - u_n) - f_ext + h_n,
//    the prescribed motion's increment g - u_n at constrained dofs entering through the tangent.
//    Then the new state is evaluated, force and tangent in one assembly, which the next step
//    needs anyway as its linearisation: an element the model cannot evaluate there (inverted,
//    for an energy with ln J), a non-finite value or a CG that did not converge (unless capped on
//    purpose, LinearSolverSettings::accept_capped) fail the step as in accurate mode, and the
//    residual it reports is the true |r(u_{n+1})| after the solve. The check costs nothing per
//    step: the assembly moved from the start of the next step to the end of this one.
//    The linearisation holds for small increments: with NewmarkSettings::realtime_reach set, a
//    step that changes some element edge (a cut body's pieces' edges included) by more than that
//    fraction of its length is redone as an accurate step. A Neo-Hookean vessel twisted 90 degrees
//    and let go needs it: the one linearised step after the release moves its end ring along
//    chords (90 -> 12 degrees, accurate: -46), squashing the elements beside it so far that no
//    later step, however cut, can evaluate them (examples/vessel_twist). It is off by default: a
//    released grasp rings at 3-6 edge lengths per step in accurate steps too (fat_grasp), which
//    Corotational's linearised steps take at a fixed cost.
//    With NewmarkSettings::tangent_reach set (opt-in), the evaluation at a step's end is of the
//    forces only while no edge has changed by more than that fraction of its length since the
//    state the tangent K was assembled at: the next step solves with that K (and, when undamped,
//    with the matrix A as it was, and the direct solver's factorisation). In a cut body the
//    measure reads each piece's own motion (the enriched dofs), so a piece turning away, or a cut
//    opening where it deforms the elements around it, counts, and a piece falling away whole does
//    not. The forces stay exact, so only the one solve's Jacobian is older; the step's increment
//    changes by about A^-1 (K - K_kept) du, and a run moves from the fresh-tangent one by 0.3-2.9
//    reach^2 of its largest displacement (tests/test_dynamics.cpp: Hex8, Tet4, Tet10 bars swinging
//    under gravity, reach 0.01 and 0.02). On bar5760 (Hex8, 2 threads) a reach of 0.02 keeps 77%
//    of the tangents and takes the step from 5.8 to 4.4 ms (CorotationalPerElement) and 10.6 to
//    5.6 ms (Corotational); docs/performance.md has the table. A body turning faster than the
//    reach per step assembles every step; at a reach just above its turn per step the kept tangent
//    lags a whole step's rotation (a bar spinning 0.02 rad per step, reach 0.03: 2.7% of its
//    motion per element, against the linearisation's own 4.7%; 3.7% per point, against 1.6%), so
//    keep the reach below the fastest rotation per step the scene expects.
//
// At constrained dofs u, v and a are the prescribed path's (solver/boundary.hpp). The initial
// acceleration, unless the state's balances the current loads, constraints and inertia settings
// (MotionState::balance), comes from equilibrium at t_n:
//   M_ff a_f = f_ext(t_n) - f_int(u_n) - D v_n - M_fc a_c  at the free dofs f, a_c = the path's
// at the constrained ones c.
//
// Rayleigh damping D = alpha M + beta Kd (seed 001 eq. 20, D = alpha M + beta K, with the
// stiffness of its corotational balance eq. 40, R K_lin R^T): Kd = K_proj(u_p), the projected
// tangent at the step's predicted end u_p = u_n + dt v_n + dt^2/2 a_n, fixed within the step
// (R K0 R^T for the corotational models, the hyperelastic tangent made positive semi-definite,
// K0 for Linear). The damping then turns with the body: the step commutes with a rigid
// rotation, and a stress-free spin is damped only through the predictor's lag. Measured on a
// bar spinning at 2 rad/s (dt = 0.01, beta = 0.01, nu = 0.45, half a turn), corotational:
//   Kd = K0 at rest (before 2026-11-28): the rotated body is damped in the wrong directions
//     (the vessel twisted by 90 degrees: torque 0.762 against 0.393 N mm undamped);
//   Kd at u_n: 23-27% of the spin's energy lost (a lag of one step's rotation, omega^2 r dt);
//   Kd at u_p: 0.2-0.3%.
// A hyperelastic tangent carries the stress (geometric stiffness), which the rotation of a
// stressed body does change: there beta also damps the spin of a body stretched by it.
// Failures throw SolverError; the trial state may then hold anything, the state n is untouched.
#include <plastifem/solver/equation_of_motion.hpp>
#include <plastifem/solver/newmark.hpp>
#include <plastifem/solver/newton.hpp>
#include <plastifem/solver/state.hpp>

#include <plastifem/core/parallel.hpp>

#include <array>
#include <chrono>
#include <cmath>

namespace plastifem {

namespace detail {
/// The largest value `raise(e, m)` raises m to over the elements (each call: m = max(m, element
/// e's values)), a NaN kept; over a fixed number of chunks, so the result does not depend on
/// the thread count. (A running maximum per chunk rather than one per element: its comparison
/// is then nearly always false, a branch the CPU predicts; per element it took twice as long.)
template <class Raise>
Scalar largest_over_elements(Index ne, int threads, const Raise& raise) {
  constexpr Index chunks = 64;
  std::array<Scalar, chunks> largest{};
  parallel_for(chunks, threads, [&](Index c) {
    Scalar m = 0;
    // 64-bit products: ne * 64 overflows an Index past 33 million elements.
    const auto first = static_cast<Index>(std::int64_t{ne} * c / chunks);
    const auto last = static_cast<Index>(std::int64_t{ne} * (c + 1) / chunks);
    for (Index e = first; e < last; ++e) raise(e, m);
    largest[c] = m;
  });
  Scalar m = 0;
  for (Scalar x : largest)
    if (x > m || std::isnan(x)) m = x;
  return m;
}

/// m raised to the squared change of each of element e's corner-to-corner edges (E::edges)
/// when its nodes move by dU_a = `change(a)`, relative to the edge's squared length.
template <FiniteElement E, class Change>
void raise_to_edge_changes(const Mesh<E>& mesh, Index e, const Change& change, Scalar& m) {
  const auto& nodes = mesh.element(e);
  for (const auto& [a, b] : E::edges) {
    const Scalar r = (change(b) - change(a)).squaredNorm() / (mesh.node(nodes[b]) - mesh.node(nodes[a])).squaredNorm();
    if (r > m || std::isnan(r)) m = r;  // a NaN stays
  }
}
}  // namespace detail

/// The largest change of an element edge from displacement u0 to u1, relative to its length:
/// max over the corner-to-corner edges (E::edges) of |(u1 - u0)_j - (u1 - u0)_i| / |X_j - X_i|,
/// read from the first 3 n dofs, the nodes' standard dofs. For a displacement increment linear
/// in X it is |dF e| on the edge's unit direction e. NaN if an increment is not finite. Each
/// edge is visited once per element that has it. A cut body: the overload below.
template <FiniteElement E>
Scalar largest_edge_change(const Mesh<E>& mesh, const Vector& u0, const Vector& u1, int threads) {
  return std::sqrt(detail::largest_over_elements(mesh.num_elements(), threads, [&](Index e, Scalar& m) {
    const auto& nodes = mesh.element(e);
    auto change = [&](int a) { return u1.segment<3>(3 * nodes[a]) - u0.segment<3>(3 * nodes[a]); };
    detail::raise_to_edge_changes(mesh, e, change, m);
  }));
}

/// The same in a body cut by `enrichment` (enrichment/enrichment.hpp): an enriched element's
/// edges as each of its sides moves them, the nodes displaced by u_a + sum_k psi_k^s a_k over
/// its enriched dofs (as enrichment/output.hpp draws its pieces). A side with no material (the
/// empty side of an element a cut runs along the face of) is not measured: it has no
/// stiffness. So a piece turning away, or a cut opening where it deforms the elements around
/// it, counts, and a piece moving away whole does not.
template <FiniteElement E, class EnrichmentT>
Scalar largest_edge_change(const Mesh<E>& mesh, const EnrichmentT& enrichment, const Vector& u0, const Vector& u1,
                           int threads) {
  return std::sqrt(detail::largest_over_elements(mesh.num_elements(), threads, [&](Index e, Scalar& m) {
    const auto& nodes = mesh.element(e);
    auto change = [&](Index row) { return u1.segment<3>(3 * row) - u0.segment<3>(3 * row); };
    const auto* cut = enrichment.element(e);
    if (!cut) return detail::raise_to_edge_changes(mesh, e, [&](int a) { return change(nodes[a]); }, m);
    ElementNodes<E> dU;
    for (int a = 0; a < E::num_nodes; ++a) dU.col(a) = change(nodes[a]);
    for (int s = 0; s < cut->num_sides; ++s) {
      if (!cut->has_material(s)) continue;  // no stiffness: nothing to measure
      const ElementNodes<E> side = cut->side_nodes(dU, s, change);
      detail::raise_to_edge_changes(mesh, e, [&](int a) { return side.col(a); }, m);
    }
  }));
}

template <FiniteElement E, class Elastic, bool Enriched = false>
class Dynamics {
 public:
  using Parts = SolverParts<E, Elastic, Enriched>;
  using Equation = EquationOfMotion<E, Elastic, Enriched>;
  using StateT = MotionState;  // the plastic part is the solver's (plastic/)
  static constexpr bool has_exact_tangent = has_exact_tangent_v<Elastic>;
  static constexpr bool constant_tangent = Elastic::constant_tangent;

  /// Sizes the scratch vectors for n dofs (no allocation in the step loop afterwards).
  void resize(Index n) {
    for (Vector* x : {&f_int_, &f_lin_, &f_ext_, &r_, &du_, &rhs_, &u_, &u_new_, &a_, &v_, &a_start_, &work_, &path_.u,
                      &path_.v, &path_.a, &first_increment_, &history_, &tangent_u_})
      x->setZero(n);
    equation_.resize(n);
    linearisation_ = {};
    tangent_ = {};
  }

  /// n -> trial by one step of dt; the trial state gets `serial`. Throws SolverError on failure.
  StepReport attempt(Parts& p, const StateT& n, StateT& trial, Scalar dt, std::uint64_t serial) {
    // A sub-step of a cut step can be smaller than any dt Solver::step accepts.
    if (!clock_represents(n.t, dt))
      fail<SolverError>("Newmark step at t = {}: a sub-step of dt = {} is lost in the round-off of the clock; the state "
                        "is unchanged",
                        n.t, dt);
    if (!std::isfinite(scheme(p.settings, dt).c0()))
      fail<SolverError>("Newmark step at t = {}: dt = {} is too small (1 / (beta dt^2) overflows); the state is "
                        "unchanged",
                        n.t + dt, dt);
    if (p.settings.newmark.mode == NewmarkMode::RealTime) return realtime(p, n, trial, dt, serial);
    return accurate_with_retry(p, n, trial, dt, serial);
  }

  /// a = the acceleration of state s from equilibrium (see the file comment). Returns the
  /// state's force scale: the largest of |f_ext|, |f_int|, |D v| and |M a| over the free dofs.
  Scalar initial_acceleration(Parts& p, const StateT& s, Vector& a) {
    Equation::damping_stiffness_at(p, s.u);
    p.loads.assemble(s.t, f_ext_);
    const bool ok = equation_.internal_force(p, s.u, f_int_, false, TangentKind::Projected);
    if (!ok || !f_ext_.allFinite())
      fail<SolverError>("acceleration at t = {}: the force is not finite{}; the state is unchanged", s.t,
                        where_invalid(p, s.u));
    // M a_f = -r with r the residual at a = 0 on the free dofs and the path's accelerations on
    // the constrained ones (their inertia M_fc a_c moves to the right-hand side).
    path_.a.setZero();
    const bool moving = p.constraints.any_motion();
    if (moving) {
      work_ = s.u;
      p.constraints.evaluate(s.t, 1.0, position_of(p), work_, nullptr, &path_.a, /*from_right=*/true);
    }
    const auto norms = equation_.residual(p, {moving ? &path_.a : nullptr, &s.v, nullptr, 1}, f_int_, f_ext_, r_);
    rhs_ = -r_;
    p.system.form_mass(p.threads);
    p.system.zero_held(rhs_);
    // The mass matrix is well conditioned (Jacobi-scaled condition number ~10-50 for the
    // consistent mass, 1 for the lumped one), so CG reaches round-off in a few dozen products,
    // where a sparse factorisation costs seconds on large meshes.
    a.setZero(s.num_dofs());
    LinearSolver cg({LinearSolverKind::ConjugateGradient, 1e-13, 2000});
    cg.set_threads(p.threads);
    if (!cg.solve(p.system.A, rhs_, a).converged) {
      LinearSolver direct({LinearSolverKind::Direct});
      direct.solve(p.system.A, rhs_, a);
    }
    for (Index d : p.system.constrained_dofs()) a[d] = path_.a[d];
    // |M a| = |r| at the free dofs (the prescribed dofs' inertia aside).
    return std::max({p.system.free_norm(f_ext_), norms.largest_term, norms.residual});
  }

  /// " (element e is inverted ...)" for a non-finite force at u, or "" if none is found.
  std::string where_invalid(Parts& p, const Vector& u) const {
    std::string s = p.body.locate_invalid(u);
    // Every element force finite: the loads, the path or the sums over them (an overflow).
    return s.empty() ? " (external loads or prescribed motion not finite, or the residual overflowed)" : s;
  }

 private:
  static bool use_exact(const SolverSettings& s) { return has_exact_tangent && s.newton.exact_tangent; }
  static Newmark scheme(const SolverSettings& s, Scalar dt) {
    return {s.newmark.beta, s.newmark.gamma, dt, s.newmark.alpha_m, s.newmark.alpha_f};
  }

  /// Node i's rest position, for the prescribed paths.
  static auto position_of(Parts& p) {
    return [&mesh = p.body.mesh()](Index i) { return Vec3(mesh.node(i)); };
  }

  /// The step's fixed data: a_n (the state's, or from equilibrium), f_ext(t_{n+1}), the
  /// prescribed path's u, v, a at t_{n+1}, and Rayleigh's Kd: at the predicted end of the step
  /// (the prescribed dofs at their new values), or at u_n for a step that starts from there (the
  /// accurate retry at huge steps) or whose predictor inverts an element; and the start state's
  /// force scale (start_scale_: remembered from the step that stored it, else balance_scale).
  void start_step(Parts& p, const StateT& n, Scalar dt, bool predictor = true) {
    const bool balanced = n.balance == p.balance();
    if (balanced) a_start_ = n.a;
    else start_scale_ = initial_acceleration(p, n, a_start_);
    const Scalar t1 = n.t + dt;
    p.loads.assemble(t1, f_ext_);
    if (!f_ext_.allFinite()) fail<SolverError>("external loads at t = {} are not finite; the state is unchanged", t1);
    path_.u = n.u;
    path_.v.setZero();
    path_.a.setZero();
    // Every set writes its dofs (a fixed one zeros: its dofs may have been moved by a set
    // released since).
    path_jumps_ = p.constraints.empty() ? 0 : p.constraints.evaluate(t1, dt, position_of(p), path_.u, &path_.v, &path_.a);
    if (p.settings.rayleigh_stiffness != 0) {
      if (predictor) scheme(p.settings, dt).predictor(n.u, n.v, a_start_, u_);
      else u_ = n.u;
      set_prescribed(p, u_);
      if (!Equation::damping_stiffness_at(p, u_) && !Equation::damping_stiffness_at(p, n.u))
        fail<SolverError>("Newmark step at t = {}: the current state cannot be evaluated{}; the state is unchanged", t1,
                          where_invalid(p, n.u));
    }
    if (balanced) start_scale_ = n.force_scale;
  }
  /// The start state's force scale: start_scale_, or balance_scale the first time it is asked
  /// for (a step that needs none, real-time or a linear model's within tolerance, pays nothing).
  Scalar start_scale(Parts& p, const StateT& n) {
    if (start_scale_ < 0) start_scale_ = balance_scale(p, n);
    return start_scale_;
  }
  /// The force scale of a state whose acceleration balances it (M a + D v + f_int(u) = load) and
  /// whose own scale is not known: max(|load|, |M a|, |D v|) over the free dofs (D with the
  /// step's Kd), at least a third of the largest term (|f_int| <= the sum of the others) without
  /// a force evaluation. Uses work_ and rhs_ as scratch.
  Scalar balance_scale(Parts& p, const StateT& n) {
    Scalar scale = n.load.size() == n.num_dofs() ? p.system.free_norm(n.load) : 0;
    p.system.M.multiply(n.a, work_, p.threads);
    scale = std::max(scale, p.system.free_norm(work_));
    if (has_rayleigh_damping(p.settings)) {
      rhs_.setZero();
      equation_.add_damping(p, n.v, 1.0, rhs_);
      scale = std::max(scale, p.system.free_norm(rhs_));
    }
    return scale;
  }

  /// Generalized-alpha: h_n = (alpha_m M a_n + alpha_f (f_int(u_n) + D v_n - f_ext(t_n))) / (1 - alpha_f)
  /// (solver/newmark.hpp), the step's fixed share of the balance; f_int_n = f_int(u_n). Uses rhs_
  /// as scratch.
  void weighted_history(Parts& p, const StateT& n, const Newmark& nm, const Vector& f_int_n) {
    p.system.M.multiply(a_start_, history_, p.threads);
    history_ *= nm.alpha_m;
    if (nm.alpha_f != 0) {
      p.loads.assemble(n.t, rhs_);
      history_ += nm.alpha_f * (f_int_n - rhs_);
      equation_.add_damping(p, n.v, nm.alpha_f, history_);
    }
    history_ /= 1 - nm.alpha_f;
    if (!history_.allFinite())
      fail<SolverError>("Newmark step at t = {}: the forces at t = {} are not finite{}; the state is unchanged",
                        n.t + nm.dt, n.t, where_invalid(p, n.u));
  }
  /// The held dofs of u at their path: a constrained dof's prescribed value, any other held dof
  /// (the enriched dofs of a node held after a cut opened) where it was at the step's start
  /// (start_step). The solve leaves them there. (Before 2026-11-30 only the constrained dofs
  /// were set: the others kept the predictor's value, so a node grasped on a falling piece had
  /// its enriched dofs drift on at their old velocity, dragging the body.)
  void set_prescribed(Parts& p, Vector& u) const {
    for (Index d : p.system.held_dofs()) u[d] = path_.u[d];
  }

  /// a_, v_ from u by Newmark at the free dofs, the path's at held ones (zero where nothing is
  /// prescribed).
  void kinematics(Parts& p, const StateT& n, const Newmark& nm, const Vector& u) {
    nm.acceleration(u, n.u, n.v, a_start_, a_);
    for (Index d : p.system.held_dofs()) a_[d] = path_.a[d];
    nm.velocity(a_, n.v, a_start_, v_);
    for (Index d : p.system.held_dofs()) v_[d] = path_.v[d];
  }

  /// r_ = the residual at u (EquationOfMotion, with Newmark's a(u), v(u) and generalized-alpha's
  /// weights; f_int holds f_int(u)); returns |r| over the free dofs and sets `scale` to the
  /// largest term of the balance.
  Scalar dynamic_residual(Parts& p, const StateT& n, const Newmark& nm, const Vector& u, const Vector& f_int,
                          Scalar f_ext_norm, Scalar& scale) {
    kinematics(p, n, nm, u);
    const bool weighted = nm.weighted();
    const auto norms = equation_.residual(p, {&a_, &v_, weighted ? &history_ : nullptr, nm.mass_weight()}, f_int,
                                          f_ext_, r_);
    scale = std::max(f_ext_norm, norms.largest_term);
    return norms.residual;
  }

  // --- accurate mode ----------------------------------------------------------------------
  struct Problem {
    Dynamics& d;
    Parts& p;
    const StateT& n;
    Newmark nm;
    Scalar cm, cd;     ///< A = cm M + K + cd Kd
    TangentKind kind;  ///< exact, or projected after a fall-back
    Scalar f_ext_norm = 0;
    bool system_stale = true, tangent_now = false, first_solve = true;
    Scalar scale_ = 0;

    Scalar residual(const Vector& u, bool with_tangent) {
      const bool ok = d.equation_.internal_force(p, u, d.f_int_, with_tangent, kind);
      if (with_tangent) system_stale = true;
      tangent_now = with_tangent;
      const Scalar r = d.dynamic_residual(p, n, nm, u, d.f_int_, f_ext_norm, scale_);
      return ok ? r : std::numeric_limits<Scalar>::quiet_NaN();
    }
    void tangent(const Vector& u) { residual(u, true); }
    bool tangent_current() const { return tangent_now; }
    Scalar scale() const { return scale_; }
    bool fall_back() {
      if (kind != TangentKind::Exact) return false;
      kind = TangentKind::Projected;
      return true;
    }
    [[noreturn]] void invalid(const Vector& u) const {
      fail<SolverError>("Newmark step at t = {}: the residual is not finite{}; the state is unchanged", n.t + nm.dt,
                        d.where_invalid(p, u));
    }
    LinearSolveReport solve(int it, Scalar rnorm, Scalar target, Vector& du) {
      d.rhs_ = -d.r_;
      p.system.zero_held(d.rhs_);
      // Inexact Newton: never looser than 0.1 nor tighter than the configured tolerance.
      const Scalar tol = std::max(p.settings.linear.tolerance, std::min(0.1, 0.5 * target / rnorm));
      auto attempt = [&] {
        // CG warm start: the first increment of the previous step (the motion over one step
        // changes slowly); later increments start from zero.
        if (it == 0 && n.warm_start.size() == n.num_dofs()) du = n.warm_start;
        else du.setZero();
        p.system.zero_held(du);
        const bool same = Equation::form_matrix(p, cm, cd, !system_stale);
        system_stale = false;
        return p.system.linear().solve(p.system.A, d.rhs_, du, tol, same);
      };
      LinearSolveReport lr;
      try {
        lr = attempt();
      } catch (const SolverError&) {
        // The exact tangent made the system indefinite (negative pivot, CG breakdown): the
        // projected tangent from now on. d.u_ is the iterate the tangent belongs to.
        if (!fall_back()) throw;
        tangent(d.u_);
        d.rhs_ = -d.r_;
        p.system.zero_held(d.rhs_);
        lr = attempt();
      }
      if (first_solve) d.first_increment_ = du;
      first_solve = false;
      return lr;
    }
  };

  StepReport accurate(Parts& p, const StateT& n, StateT& trial, Scalar dt, bool predictor, std::uint64_t serial) {
    const auto& st = p.settings;
    const auto t0 = std::chrono::steady_clock::now();
    const Newmark nm = scheme(st, dt);
    start_step(p, n, dt, predictor);
    if (nm.weighted()) {
      if (!equation_.internal_force(p, n.u, f_int_, false, TangentKind::Projected))
        fail<SolverError>("Newmark step at t = {}: the current state cannot be evaluated{}; the state is unchanged",
                          n.t + dt, where_invalid(p, n.u));
      weighted_history(p, n, nm, f_int_);
    }
    // Start from the constant-acceleration predictor u_n + dt v_n + dt^2/2 a_n, with the
    // constrained dofs at their new values: the first residual is then the change of
    // acceleration over the step, not the inertia of the whole step, which saves a Newton
    // iteration (bar90 Hex8 Corotational at dt = 0.01: 3.33 -> 2.51 per step). A linear model
    // is still solved exactly by one solve from there.
    if (predictor) nm.predictor(n.u, n.v, a_start_, u_);
    else u_ = n.u;
    set_prescribed(p, u_);
    const auto coefficients = nm.matrix(st.rayleigh_mass, st.rayleigh_stiffness);
    const Scalar cm = coefficients.mass, cd = coefficients.damping_stiffness;
    Problem prob{*this, p, n, nm, cm, cd,
                 use_exact(st) ? TangentKind::Exact : TangentKind::Projected};
    prob.f_ext_norm = p.system.free_norm(f_ext_);
    NewtonOptions o;
    o.tolerance = st.newton.residual_tolerance;
    o.increment_tolerance = st.newton.increment_tolerance;
    o.length = p.body.size();
    o.max_iterations = st.newton.max_iterations;
    o.min_iterations = 1;
    o.stagnation = true;
    o.constant_tangent = constant_tangent;
    o.absolute_tolerance = 10 * p.system.rest_force_roundoff(p.body, p.threads);
    // Measured against the forces of the state the step starts from and of the iterate, not the
    // predictor's: at dt >> 1 / omega those are (omega dt)^2 times too large (NewtonOptions).
    // A linear model's one solve keeps the predictor's scale (the solve's tolerance is the same
    // as ever); its result is checked against the start state's below.
    auto reference_scale = [&] { return std::max(prob.f_ext_norm, start_scale(p, n)); };
    if (!constant_tangent) o.reference_scale = reference_scale();
    // Backtracking needs a descent direction for |r|, which only the exact Jacobian guarantees:
    // with the warped corotational tangent it mostly fails and costs force evaluations (bar720
    // Tet4 Corotational: 9.2 ms per Newton iteration against 4.8 ms without), so without the
    // exact tangent Newton takes full steps. A step that fell back to the projected tangent
    // keeps the search: for the ln J energies it is what rejects a trial step that inverts an
    // element.
    o.line_search = st.newton.line_search && use_exact(st);
    // The tangent is assembled at the predictor and kept while Newton converges fast enough,
    // else refreshed at the iterate (solver/newton.hpp): the exact one while every iteration
    // reduces |r| tenfold; the warped (projected) one, which converges linearly anyway, while
    // |r| at least halves. A warped tangent kept for the whole step diverged at dt >> 1 / omega
    // (CorotationalPerElement at dt = 10 on a bar of period 1.8: |r| ~ 1e146 after 50
    // iterations, the predictor 490 m from the solution); refreshed where |r| stalls, it
    // converges in about 10 iterations a step at any dt.
    NewtonResult res;
    Scalar final_scale = -1;  // the accepted iterate's own (MotionState::force_scale), if evaluated
    // Newton on `problem` (the frozen tangent's copy, or prob itself: the scale and the first
    // increment are the object's that ran).
    auto run_newton = [&](auto& problem) {
      res = newton(problem, u_, o, ResidualBacktracking{}, du_, u_new_);
      if (res.convergence != Convergence::OneSolve) {
        if (res.converged) final_scale = problem.scale();
        return;
      }
      // A linear model's one solve: Newton reported the predictor's residual (relative 5.5e-2 on
      // a bar under gravity; found by review). The residual is linear in u, r(u + du) = r(u) +
      // A du = A du - b, which CG tracks to its end (relative to |b| = |r(u)|); after a direct
      // solve it costs one product. (A force evaluation cost 24% of a Linear bar5760 step, the
      // product 9%.) Within the tolerance by the solve's own (Problem::solve).
      if (st.linear.kind == LinearSolverKind::ConjugateGradient) {
        res.residual *= res.linear_relative_residual;
      } else {
        p.system.A.multiply(du_, work_, p.threads);
        work_ += r_;
        res.residual = p.system.free_norm(work_);
      }
      res.relative_residual = res.residual / res.scale;
      // That solve's tolerance referred to the predictor's residual, which at dt >> 1 / omega is
      // (omega dt)^2 times the physical forces (Linear, CG, dt = 1000 on a 4 x 1 x 1 bar: |r| =
      // 0.54 |f_ext|). Short of the tolerance of the start state's scale, Newton goes on from
      // the solution, checking each residual against its own scale.
      auto within = [&](Scalar scale) {
        return res.residual <= o.tolerance * scale || res.residual <= o.absolute_tolerance;
      };
      // |f_ext| and a scale already known first: the start state's costs a mass product.
      if (within(std::max(prob.f_ext_norm, start_scale_)) || within(reference_scale())) return;
      o.reference_scale = reference_scale();
      o.verify_one_solve = true;
      o.min_iterations = 0;
      const NewtonResult more = newton(problem, u_, o, ResidualBacktracking{}, du_, u_new_);
      res.residual = more.residual, res.relative_residual = more.relative_residual, res.scale = more.scale;
      res.converged = more.converged;
      if (more.converged) final_scale = problem.scale();
      if (more.iterations == 0) return;  // the solution met its own scale: still one solve
      res.iterations += more.iterations;
      res.linear_iterations += more.linear_iterations;
      res.linear_converged = res.linear_converged && more.linear_converged;
      res.linear_relative_residual = more.linear_relative_residual;
      res.convergence = more.convergence;
    };
    if (constant_tangent && st.newton.tangent_once_per_step) {
      FrozenTangent<Problem> frozen{prob};
      run_newton(frozen);
    } else {
      if (st.newton.tangent_once_per_step) o.refresh_ratio = use_exact(st) ? 0.1 : 0.5;
      run_newton(prob);
    }
    res.exact_tangent_dropped = use_exact(st) && prob.kind == TangentKind::Projected;
    const Scalar t1 = n.t + dt;
    if (!res.converged)
      fail<SolverError>("Newmark step at t = {} did not converge in {} Newton iterations (|r| = {:.3g}, relative "
                        "{:.3g}); the state is unchanged. Try a smaller dt or more iterations",
                        t1, res.iterations, res.residual, res.relative_residual);
    kinematics(p, n, nm, u_);
    if (!u_.allFinite() || !v_.allFinite() || !a_.allFinite())
      fail<SolverError>("Newmark step at t = {} produced non-finite values; the state is unchanged", t1);
    store(p, n, trial, dt, serial, final_scale);
    StepReport rep;
    record(rep, res);
    rep.path_jumps = path_jumps_;
    rep.wall_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    return rep;
  }

  /// A problem whose tangent, once assembled at the step's first iterate, stays: a linear
  /// model's, which does not depend on u.
  template <class P>
  struct FrozenTangent : P {
    explicit FrozenTangent(P& problem) : P(problem) {}
    bool tangent_current() const { return true; }
  };

  /// Moves u_, v_, a_ and the step's data into the trial state.
  void store(const Parts& p, const StateT& n, StateT& trial, Scalar dt, std::uint64_t serial, Scalar force_scale,
             bool keep_previous_start = false) {
    trial.force_scale = force_scale;
    trial.u.swap(u_);
    trial.v.swap(v_);
    trial.a.swap(a_);
    trial.load.swap(f_ext_);  // recomputed by the next step
    if (keep_previous_start) {
      trial.warm_start_previous = n.warm_start;
      trial.warm_dt_previous = n.warm_dt;
    } else {
      trial.warm_start_previous.resize(0);
      trial.warm_dt_previous = 0;
    }
    trial.warm_start.swap(first_increment_);
    trial.warm_dt = dt;
    trial.t = n.t + dt;
    trial.balance = p.balance();
    trial.serial = serial;
    trial.lineage = n.lineage;
  }

  // --- real-time mode ---------------------------------------------------------------------
  StepReport realtime(Parts& p, const StateT& n, StateT& trial, Scalar dt, std::uint64_t serial) {
    const auto& st = p.settings;
    const auto t0 = std::chrono::steady_clock::now();
    const Newmark nm = scheme(st, dt);
    const Scalar t1 = n.t + dt;
    start_step(p, n, dt);
    TangentKind kind = use_exact(st) ? TangentKind::Exact : TangentKind::Projected;
    // The linearisation at u_n: kept from the end of the previous step when that step made
    // this state and nothing has changed K or the rest shapes since; else assembled now.
    if (!linearisation_.of(p, n, kind)) {
      if (!equation_.internal_force(p, n.u, f_lin_, true, kind))
        fail<SolverError>("real-time step at t = {}: the current state cannot be evaluated{}", t1,
                          where_invalid(p, n.u));
      linearisation_ = Linearisation::at(p, n.serial, kind);
      tangent_assembled_at(p, n.u, kind);
    }
    if (nm.weighted()) weighted_history(p, n, nm, f_lin_);
    const auto coefficients = nm.matrix(st.rayleigh_mass, st.rayleigh_stiffness);
    const Scalar cm = coefficients.mass, cd = coefficients.damping_stiffness;
    const Scalar f_ext_norm = p.system.free_norm(f_ext_);
    Scalar scale = 0;
    auto linear_residual = [&] {
      u_ = n.u;
      set_prescribed(p, u_);
      dynamic_residual(p, n, nm, u_, f_lin_, f_ext_norm, scale);
      // The prescribed increment through the tangent: + K(u_n) (g - u_n) at the free rows.
      bool moved = false;
      work_.setZero();
      for (Index d : p.system.constrained_dofs())
        if (path_.u[d] != n.u[d]) work_[d] = path_.u[d] - n.u[d], moved = true;
      if (moved) {
        p.system.K.multiply(work_, rhs_, p.threads);
        r_ += rhs_;
      }
      rhs_ = -r_;
      p.system.zero_held(rhs_);
    };
    auto solve = [&] {
      // CG start: the last step's increment, or the linear extrapolation of the last two when
      // both had this dt (bar90 Hex8 Corotational: 10.9 -> 9.8 CG iterations per step).
      if (n.warm_start.size() == n.num_dofs() && n.warm_start_previous.size() == n.num_dofs() && n.warm_dt == dt &&
          n.warm_dt_previous == dt)
        du_ = 2 * n.warm_start - n.warm_start_previous;
      else if (n.warm_start.size() == n.num_dofs())
        du_ = n.warm_start;
      else
        du_.setZero();
      p.system.zero_held(du_);
      // A tangent kept from the last step (NewmarkSettings::tangent_reach) leaves A = cm M + K as
      // that step formed it, and the direct solver its factorisation, unless damped (Kd moves
      // every step) or written since (System::same_coefficients).
      const bool current = keeps_tangents(st) && cd == 0 && p.system.same_coefficients(cm, cd);
      const bool same = Equation::form_matrix(p, cm, cd, current);
      return p.system.linear().solve(p.system.A, rhs_, du_, st.linear.tolerance, same);
    };
    linear_residual();
    LinearSolveReport lr;
    try {
      lr = solve();
    } catch (const SolverError&) {
      if (kind != TangentKind::Exact) throw;
      kind = TangentKind::Projected;  // indefinite exact tangent: the projected one
      linearisation_ = {};
      if (!equation_.internal_force(p, n.u, f_lin_, true, kind))
        fail<SolverError>("real-time step at t = {}: the current state cannot be evaluated{}", t1,
                          where_invalid(p, n.u));
      linearisation_ = Linearisation::at(p, n.serial, kind);
      tangent_assembled_at(p, n.u, kind);
      linear_residual();
      lr = solve();
    }
    first_increment_ = du_;
    u_ += du_;
    const bool dropped = use_exact(st) && kind == TangentKind::Projected;
    // Beyond the linearisation's reach (NewmarkSettings::realtime_reach, if set), the step is
    // redone as an accurate one from n.
    linearisation_ = {};  // the accurate redo or the evaluation below writes K
    if (const Scalar reach = st.newmark.realtime_reach;
        std::isfinite(reach) && !(edge_change(p, n.u, u_) <= reach)) {
      StepReport r = redone(p, n, trial, dt, serial, t0, lr.iterations);
      r.exact_tangent_dropped = std::max(r.exact_tangent_dropped, int(dropped));  // one sub-step
      return r;
    }
    // The new state, evaluated: the check, the reported residual, and the next linearisation
    // (its tangent kept while within NewmarkSettings::tangent_reach of the kept one's state).
    const TangentKind next_kind = use_exact(st) ? TangentKind::Exact : TangentKind::Projected;
    const bool keep_tangent = keeps_tangent(p, next_kind, u_);
    const bool ok = equation_.internal_force(p, u_, f_int_, !keep_tangent, next_kind);
    if (!keep_tangent) tangent_assembled_at(p, u_, next_kind);
    if (!ok || !u_.allFinite())
      fail<SolverError>("real-time step at t = {}: the new state cannot be evaluated{}; the state is unchanged", t1,
                        where_invalid(p, u_));
    if (!lr.converged && !st.linear.accept_capped)
      fail<SolverError>("real-time step at t = {}: CG did not converge in {} iterations (relative residual {:.3g}); "
                        "the state is unchanged. Raise the CG cap, or set accept_capped for a fixed-cost step",
                        t1, lr.iterations, lr.relative_residual);
    const Scalar rnorm = dynamic_residual(p, n, nm, u_, f_int_, f_ext_norm, scale);
    if (!v_.allFinite() || !a_.allFinite())
      fail<SolverError>("real-time step at t = {} produced non-finite values; the state is unchanged", t1);
    store(p, n, trial, dt, serial, scale, true);
    f_lin_.swap(f_int_);
    linearisation_ = Linearisation::at(p, serial, next_kind);  // the trial state's, if it is committed
    StepReport rep;
    rep.newton_iterations = 1;
    rep.tangents_kept = keep_tangent;
    rep.exact_tangent_dropped = dropped;
    rep.linear_iterations = lr.iterations;
    rep.residual = rnorm;
    rep.relative_residual = rnorm / std::max(scale, Scalar(1e-30));
    rep.convergence = Convergence::OneSolve;
    rep.path_jumps = path_jumps_;
    rep.linear_converged = lr.converged;
    rep.linear_relative_residual = lr.relative_residual;
    rep.wall_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    return rep;
  }

  /// Whether real-time steps may keep their tangent (NewmarkSettings::tangent_reach set). A
  /// constant tangent is never assembled again anyway.
  static bool keeps_tangents(const SolverSettings& st) { return !constant_tangent && st.newmark.tangent_reach > 0; }
  /// Records that the system's K was just assembled at u, of kind `kind` (for
  /// NewmarkSettings::tangent_reach).
  void tangent_assembled_at(const Parts& p, const Vector& u, TangentKind kind) {
    if (!keeps_tangents(p.settings)) return;
    tangent_u_ = u;
    tangent_ = Linearisation::at(p, 0, kind);
  }
  /// largest_edge_change over the body: in a cut body each enriched element by its sides.
  static Scalar edge_change(const Parts& p, const Vector& u0, const Vector& u1) {
    if constexpr (Enriched) return largest_edge_change(p.body.mesh(), p.body.enrichment(), u0, u1, p.threads);
    else return largest_edge_change(p.body.mesh(), u0, u1, p.threads);
  }
  /// Whether the system's K serves as the tangent of kind `kind` at u instead of one assembled
  /// there: reuse is on, K is the one recorded at tangent_u_ (nothing has assembled another or
  /// moved rest shapes since), and no element edge, a cut body's pieces' included, has changed
  /// by more than tangent_reach of its length from there.
  bool keeps_tangent(const Parts& p, TangentKind kind, const Vector& u) const {
    return keeps_tangents(p.settings) && tangent_.tangent_of(p, kind) &&
           edge_change(p, tangent_u_, u) <= p.settings.newmark.tangent_reach;
  }

  /// The accurate step from the predictor, else from u_n. At huge time steps (stiffness-
  /// dominated, dt omega >> 1) the constant-acceleration predictor can start Newton far from the
  /// solution, where u_n is the better guess: the retry costs only when a step fails.
  StepReport accurate_with_retry(Parts& p, const StateT& n, StateT& trial, Scalar dt, std::uint64_t serial) {
    try {
      return accurate(p, n, trial, dt, true, serial);
    } catch (const SolverError&) {
      StepReport r = accurate(p, n, trial, dt, false, serial);
      r.predictor_retries = 1;
      return r;
    }
  }

  /// The real-time step from n redone as an accurate one (with accurate_with_retry);
  /// its wall time and CG iterations count the abandoned linearised solve (from t0, and
  /// `abandoned_cg`). Its warm start for the next step is the whole step's increment, which is
  /// what a real-time step starts CG from (accurate's own is its first Newton increment, from
  /// the predictor).
  StepReport redone(Parts& p, const StateT& n, StateT& trial, Scalar dt, std::uint64_t serial,
                    std::chrono::steady_clock::time_point t0, int abandoned_cg) {
    StepReport r = accurate_with_retry(p, n, trial, dt, serial);
    trial.warm_start = trial.u - n.u;
    trial.warm_start_previous.resize(0);
    r.realtime_redone = 1;
    r.linear_iterations += abandoned_cg;
    r.wall_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    return r;
  }

  Equation equation_;
  Vector f_int_, f_lin_, f_ext_, r_, du_, rhs_, u_, u_new_, a_, v_, a_start_, work_, first_increment_;
  Vector history_;  ///< generalized-alpha's h_n for the step under way
  PathValues path_;
  Index path_jumps_ = 0;  ///< nodes whose path jumps at the step's end (Constraints::evaluate)
  /// What f_lin_ and the system's K are the linearisation of: the state (its serial), the K
  /// (System::tangent_stamp), the rest shapes (the element data's epoch) and the tangent kind.
  /// Each is compared, so nothing outside has to say when the linearisation goes stale.
  struct Linearisation {
    std::uint64_t state = 0, tangent = 0, rest_shapes = 0;  // tangent 0: none
    TangentKind kind = TangentKind::Projected;
    static Linearisation at(const Parts& p, std::uint64_t state, TangentKind kind) {
      return {state, p.system.tangent_stamp(), p.body.data().epoch(), kind};
    }
    /// Whether the system's K is still this tangent, of kind k: nothing has assembled another
    /// or moved rest shapes since.
    bool tangent_of(const Parts& p, TangentKind k) const {
      return tangent != 0 && tangent == p.system.tangent_stamp() && rest_shapes == p.body.data().epoch() && kind == k;
    }
    bool of(const Parts& p, const StateT& n, TangentKind k) const { return state == n.serial && tangent_of(p, k); }
  };
  Linearisation linearisation_;
  Scalar start_scale_ = -1;  ///< the force scale of the step's start state (start_step); -1: not known yet
  /// The displacement a real-time step last assembled the system's K at, and that K (its state
  /// unused); recorded only with NewmarkSettings::tangent_reach.
  Vector tangent_u_;
  Linearisation tangent_;
};

}  // namespace plastifem
