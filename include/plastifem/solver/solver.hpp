#pragma once
// Solver<Element, Elastic, Plastic, Enrichment>: the one type a simulator holds. It owns the
// per-element data (prepared once from the rest shapes), the sparse pattern, the boundary
// conditions and loads, and the state (u, v, a, t); it solves for static equilibrium and
// advances in time with Newmark's method.
//
// Newmark (beta, gamma), seed 001 section 3.5 and [1]; from t_n to t_{n+1} = t_n + dt:
//   a(u) = (u - u_n - dt v_n) / (beta dt^2) - (1 / (2 beta) - 1) a_n
//   v(u) = v_n + dt ((1 - gamma) a_n + gamma a(u))
//   r(u) = M a(u) + D v(u) + f_int(u) - f_ext(t_{n+1}) = 0,   D = alpha M + beta_R K(u)
// Newton on r with the tangent  A = (1/(beta dt^2) + alpha gamma/(beta dt)) M
//                                  + (1 + beta_R gamma/(beta dt)) K(u).
//   - Accurate mode: Newton to convergence (residual and increment tolerances) with a
//     backtracking line search on |r| (the residual of a non-conservative corotational force has
//     no potential to search on, so the norm is used for every model).
//   - Real-time mode: one linearised solve per step from u_n (what SOFA and VegaFEM do); for a
//     Linear model the two modes coincide.
// Initial acceleration from equilibrium: M a_0 = f_ext(0) - f_int(u_0) - D v_0, unless given.
// A step that fails (no convergence, NaN, singular system) throws SolverError and leaves the
// state exactly as it was: all work happens in scratch vectors, committed at the end.
#include <plastifem/assembly/element_data.hpp>
#include <plastifem/assembly/mass.hpp>
#include <plastifem/elastic/elastic.hpp>
#include <plastifem/enrichment/none.hpp>
#include <plastifem/mesh/selection.hpp>
#include <plastifem/plastic/none.hpp>
#include <plastifem/solver/boundary.hpp>
#include <plastifem/solver/linear_solver.hpp>

#include <chrono>
#include <cstdint>
#include <map>
#include <span>

namespace plastifem {

enum class NewmarkMode { Accurate, RealTime };

struct NewtonSettings {
  /// Converged when |r| <= tol * max(|f_ext|, |f_int|) over free dofs. 1e-6 matches the CG
  /// tolerance the benchmarks use; with the corotational (warped) tangent Newton converges
  /// linearly, so much tighter values cost many iterations.
  Scalar residual_tolerance = 1e-6;
  Scalar increment_tolerance = 1e-10;  ///< or when |du| <= tol * (|u| + mesh size)
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
  /// Without the exact tangent: assemble the tangent once per Newmark step, at the predictor,
  /// and use force-only evaluations in the later iterations. The warped tangent already omits
  /// dR/dx, and the step's motion changes it far less than that; bar5760 Hex8 Corotational:
  /// the same 1.9 Newton iterations per step with a third fewer element-matrix evaluations.
  /// The exact tangent is always updated (quadratic Newton).
  bool tangent_once_per_step = true;
};

struct NewmarkSettings {
  Scalar beta = 0.25, gamma = 0.5;  ///< average acceleration: unconditionally stable, no dissipation
  NewmarkMode mode = NewmarkMode::Accurate;
};

/// What one step or static solve did.
struct StepReport {
  int newton_iterations = 0;
  int linear_iterations = 0;     ///< summed over Newton iterations
  Scalar residual = 0;           ///< final |r| (accurate mode) or |r| before the one solve (real time)
  Scalar relative_residual = 0;  ///< residual / force scale
  int load_steps = 1;            ///< statics: increments used (after automatic cutting)
  int substeps = 1;              ///< dynamics: Newmark sub-steps used (> 1 after automatic step cutting)
  int predictor_retries = 0;     ///< dynamics: sub-steps redone from u_n after failing from the predictor
  double wall_ms = 0;
};

struct SolverSettings {
  MassKind mass = MassKind::Consistent;
  NewmarkSettings newmark;
  NewtonSettings newton;
  LinearSolverSettings linear;  ///< dynamics (default: warm-started Jacobi CG, 1e-8)
  /// statics (default: the direct solver, CHOLMOD where built in, else SimplicialLDLT)
  LinearSolverSettings static_linear{LinearSolverKind::Direct};
  Scalar rayleigh_mass = 0, rayleigh_stiffness = 0;  ///< D = alpha M + beta K
  /// Threads for element loops and products: 1 by default (predictable; on small scenes and
  /// busy machines threads cost more than they give), 0: OpenMP default, N: N threads.
  int threads = 1;
  /// A Newmark step whose Newton iteration fails is cut in halves, up to this many times.
  int max_step_cuts = 6;
};

template <FiniteElement E, class Elastic, class Plastic = NoPlasticity, class Enrich = NoEnrichment>
  requires ElasticModel<Elastic, E>
class Solver {
  static_assert(std::is_same_v<Plastic, NoPlasticity>, "plastic policies other than NoPlasticity arrive with seed 000");
  static_assert(std::is_same_v<Enrich, NoEnrichment>, "enrichment policies other than NoEnrichment arrive with seed 001");

 public:
  using Element = E;
  using ElasticModel = Elastic;
  using Data = typename Elastic::template ElementData<E>;
  static constexpr int N = E::num_nodes;

  Solver(const Mesh<E>& mesh, const Material& material, SolverSettings settings = {})
      : mesh_(mesh), material_(material.validated()), settings_(validated(settings)), assembler_(mesh),
        data_(mesh_, material_), linear_(settings.linear), static_linear_(settings.static_linear) {
    const Index n = num_dofs();
    element_energy_.assign(mesh_.num_elements(), 0.0);
    u_ = v_ = a_ = Vector::Zero(n);
    constrained_.assign(n, 0);
    build_mass();
    K_ = assembler_.zero_matrix();
    A_ = assembler_.zero_matrix();
    set_solver_threads();
    f_int_.resize(n), f_ext_.resize(n), r_.resize(n), du_.resize(n), rhs_.resize(n);
    u_try_.resize(n), a_try_.resize(n), v_try_.resize(n), work_.resize(n), prescribed_.resize(n);
    X_ = Eigen::Map<const Vector>(mesh_.nodes().data(), n);
    mesh_size_ = (mesh_.nodes().rowwise().maxCoeff() - mesh_.nodes().rowwise().minCoeff()).norm();
  }

  // --- problem set-up ---------------------------------------------------------------------
  const Mesh<E>& mesh() const { return mesh_; }
  const Material& material() const { return material_; }
  const SolverSettings& settings() const { return settings_; }
  Index num_dofs() const { return 3 * mesh_.num_nodes(); }
  void set_settings(const SolverSettings& s) {
    validate_settings(s);
    settings_ = s;
    linear_.set_settings(s.linear);
    static_linear_.set_settings(s.static_linear);
    set_solver_threads();
    build_mass();
    system_coefficients_ = {0.0, 0.0};
  }

  /// Fixes the given nodes (all components, or those in `mask`).
  void fix(std::span<const Index> nodes, DofMask mask = {}) { prescribe(nodes, {}, mask); }

  /// Prescribes u(t, X) on the given nodes (components in `mask`); e.g. a grasper pull.
  void prescribe(std::span<const Index> nodes, PrescribedDisplacement u, DofMask mask = {}) {
    check_nodes(nodes, "boundary condition");
    dirichlet_.push_back({std::vector<Index>(nodes.begin(), nodes.end()), mask, std::move(u)});
    for (Index i : nodes)
      for (int d = 0; d < 3; ++d)
        if (mask[d]) constrained_[3 * i + d] = 1;
    constrained_blocks_current_ = false;
    initial_acceleration_known_ = false;
    system_coefficients_ = {0.0, 0.0};  // the constrained rows of the system change
  }

  /// Force `f` on each of the given nodes, scaled by `curve(t)`.
  void add_nodal_force(std::span<const Index> nodes, const Vec3& f, LoadCurve curve = {}) {
    check_nodes(nodes, "nodal force");
    check_finite(f, "nodal force");
    Vector F = Vector::Zero(num_dofs());
    for (Index i : nodes) F.segment<3>(3 * i) += f;
    loads_.push_back({std::move(F), std::move(curve), "nodal force"});
    initial_acceleration_known_ = false;
  }

  /// Body force per unit mass (gravity), as consistent nodal loads rho int N_a g dV.
  void add_gravity(const Vec3& g, LoadCurve curve = {}) {
    check_finite(g, "gravity");
    Vector F = body_force_load(mesh_, material_.density, g);
    loads_.push_back({std::move(F), std::move(curve), "gravity"});
    initial_acceleration_known_ = false;
  }

  /// Traction t (force per unit reference area) on boundary faces, as consistent nodal loads
  /// int_face N_a t dA. Faces are integrated with the element's own shape functions on the
  /// face (the reference face is mapped into the reference element), with a rule exact for
  /// the face's N_a times its area element on flat faces.
  void add_traction(const std::vector<FaceRef>& faces, const Vec3& t, LoadCurve curve = {}) {
    check_finite(t, "traction");
    Vector F = Vector::Zero(num_dofs());
    for (const FaceRef& f : faces) {
      if (f.element < 0 || f.element >= mesh_.num_elements() || f.face < 0 || f.face >= E::num_faces)
        fail<InvalidArgument>("traction: face (element {}, local face {}) out of range", f.element, f.face);
      const ElementNodes<E> X = mesh_.element_nodes(f.element);
      for_each_face_point(f.face, [&](const Vec3& xi, const Vec3& dxi_ds, const Vec3& dxi_dt, Scalar w) {
        const Mat3 J = jacobian<E>(X, xi);
        const Scalar dA = (J * dxi_ds).cross(J * dxi_dt).norm();
        const auto Nf = E::shape(xi);
        for (int a = 0; a < N; ++a) F.segment<3>(3 * mesh_.element(f.element)[a]) += w * dA * Nf[a] * t;
      });
    }
    loads_.push_back({std::move(F), std::move(curve), "traction"});
    initial_acceleration_known_ = false;
  }

  /// Removes every load (boundary conditions stay).
  void clear_loads() {
    loads_.clear();
    initial_acceleration_known_ = false;
  }

  // --- state ------------------------------------------------------------------------------
  Scalar time() const { return time_; }
  const Vector& displacement() const { return u_; }
  const Vector& velocity() const { return v_; }
  const Vector& acceleration() const { return a_; }
  Vec3 displacement(Index node) const { return u_.segment<3>(3 * node); }
  /// Current positions x = X + u, one node per column.
  Eigen::Matrix3Xd positions() const {
    Eigen::Matrix3Xd x = mesh_.nodes();
    x += Eigen::Map<const Eigen::Matrix3Xd>(u_.data(), 3, mesh_.num_nodes());
    return x;
  }
  void set_state(const Vector& u, const Vector& v, Scalar time = 0) {
    if (u.size() != num_dofs() || v.size() != num_dofs())
      fail<InvalidArgument>("state vectors need {} entries, got {} and {}", num_dofs(), u.size(), v.size());
    if (!u.allFinite() || !v.allFinite()) fail<InvalidArgument>("state vectors must be finite");
    u_ = u, v_ = v, time_ = time;
    initial_acceleration_known_ = false;
  }
  /// Uses `a` as the acceleration at the current time instead of solving for equilibrium.
  void set_acceleration(const Vector& a) {
    if (a.size() != num_dofs() || !a.allFinite())
      fail<InvalidArgument>("acceleration needs {} finite entries", num_dofs());
    a_ = a;
    initial_acceleration_known_ = true;
  }

  // --- solving ----------------------------------------------------------------------------
  /// Static equilibrium f_int(u) = f_ext(t) at the current time, by Newton with `load_steps`
  /// increments of the loads and prescribed displacements; an increment that fails is halved
  /// (up to 10 times) before giving up. Velocity and acceleration are set to zero.
  StepReport solve_static(int load_steps = 1) {
    const auto t0 = std::chrono::steady_clock::now();
    if (load_steps < 1) fail<InvalidArgument>("load_steps must be >= 1, got {}", load_steps);
    if (std::none_of(constrained_.begin(), constrained_.end(), [](char c) { return c; }))
      fail<SolverError>("static solve: no degree of freedom is constrained, so the body can move rigidly and "
                        "K is singular; fix some nodes (Solver::fix) first");
    external_force(time_, f_ext_);
    const Vector f_target = f_ext_;
    prescribed_values(time_, prescribed_);
    const Vector g_target = prescribed_;
    Vector u = u_;
    const Vector u_start = u_;
    StepReport rep;
    Scalar done = 0, step = 1.0 / load_steps;
    int cuts = 0, increments = 0;
    while (done < 1 - 1e-12) {
      const Scalar s = std::min(1.0, done + step);
      Vector u_trial = u;
      try {
        for (Index i = 0; i < num_dofs(); ++i)
          if (constrained_[i]) u_trial[i] = u_start[i] + s * (g_target[i] - u_start[i]);
        f_ext_ = s * f_target;
        const StepReport r = newton_static(u_trial);
        rep.newton_iterations += r.newton_iterations;
        rep.linear_iterations += r.linear_iterations;
        rep.residual = r.residual;
        rep.relative_residual = r.relative_residual;
        u = u_trial;
        done = s;
        ++increments;
      } catch (const SolverError& err) {
        if (Elastic::constant_tangent || ++cuts > 10)
          fail<SolverError>("static solve failed at load fraction {:.4g} after {} cuts: {}", s, cuts, err.what());
        step /= 2;
      }
    }
    u_ = u;
    v_.setZero();
    a_.setZero();
    initial_acceleration_known_ = true;
    rep.load_steps = increments;
    rep.wall_ms = ms_since(t0);
    return rep;
  }

  /// Advances by dt with Newmark's method. If Newton fails, the step is redone as two half
  /// steps, recursively, up to settings().max_step_cuts times (2^cuts sub-steps): a huge time
  /// step is then a sequence of smaller ones, like load stepping in statics. Throws SolverError
  /// with the state unchanged if even the smallest sub-step fails.
  StepReport step(Scalar dt) {
    const auto t0 = std::chrono::steady_clock::now();
    if (!(dt > 0) || !std::isfinite(dt)) fail<InvalidArgument>("time step must be finite and > 0, got dt = {}", dt);
    StepReport rep;
    try {
      rep = newmark_step(dt);
    } catch (const SolverError& first_failure) {
      if (settings_.max_step_cuts < 1) throw;
      const Vector u = u_, v = v_, a = a_, w = first_increment_;
      const Scalar t = time_;
      const bool known = initial_acceleration_known_;
      try {
        rep = {};
        rep.substeps = 0;
        substep(dt / 2, 1, rep);
        substep(dt / 2, 1, rep);
      } catch (const SolverError& e) {
        u_ = u, v_ = v, a_ = a, first_increment_ = w, time_ = t, initial_acceleration_known_ = known;
        fail<SolverError>("{} (also with the step cut into up to {} sub-steps: {})", first_failure.what(),
                          1 << settings_.max_step_cuts, e.what());
      }
      time_ = t + dt;  // exactly, whatever the sub-steps' round-off
    }
    rep.wall_ms = ms_since(t0);
    return rep;
  }

 private:
  void substep(Scalar dt, int depth, StepReport& total) {
    StepReport r;
    try {
      r = newmark_step(dt);
    } catch (const SolverError&) {
      if (depth >= settings_.max_step_cuts) throw;
      substep(dt / 2, depth + 1, total);
      substep(dt / 2, depth + 1, total);
      return;
    }
    total.newton_iterations += r.newton_iterations;
    total.linear_iterations += r.linear_iterations;
    total.predictor_retries += r.predictor_retries;
    total.residual = r.residual;
    total.relative_residual = r.relative_residual;
    total.substeps += 1;
  }

  /// One Newmark step of size dt; throws SolverError (state unchanged) if Newton fails, from
  /// the predictor and then from u_n. At huge time steps (stiffness-dominated, dt * omega >> 1)
  /// the constant-acceleration predictor can start Newton far from the solution, where u_n is
  /// the better guess: the retry costs only when a step fails.
  StepReport newmark_step(Scalar dt) {
    // Real-time mode linearises at u_n, the classic linearly implicit scheme: one linearised
    // solve from the predictor instead feeds each step's unconverged acceleration into the
    // next start, and the corotational bar (Tet10 bar90, Tet4 at h = 0.5) gains energy without
    // bound within 2 s (kinetic energy x 1e4; tests/test_solver.cpp keeps it bounded).
    if (settings_.newmark.mode == NewmarkMode::RealTime) return newmark_attempt(dt, false);
    try {
      return newmark_attempt(dt, true);
    } catch (const SolverError&) {
      StepReport r = newmark_attempt(dt, false);
      r.predictor_retries = 1;
      return r;
    }
  }

  StepReport newmark_attempt(Scalar dt, bool predictor) {
    const auto t0 = std::chrono::steady_clock::now();
    // a_n: the committed acceleration, or (first step, or after loads changed) the one from
    // equilibrium, kept in scratch until the step succeeds.
    if (!initial_acceleration_known_) solve_initial_acceleration(a_start_);
    else a_start_ = a_;
    const auto& nm = settings_.newmark;
    const Scalar t1 = time_ + dt;
    const Scalar c0 = 1 / (nm.beta * dt * dt), c1 = nm.gamma / (nm.beta * dt);
    const Scalar alpha = settings_.rayleigh_mass, betaR = settings_.rayleigh_stiffness;
    const Scalar mass_coef = c0 + alpha * c1, stiff_coef = 1 + betaR * c1;
    external_force(t1, f_ext_);
    prescribed_values(t1, prescribed_);

    // Start from the constant-acceleration predictor u_n + dt v_n + dt^2/2 a_n, with the
    // constrained dofs at their new values: the first residual is then the change of
    // acceleration over the step, not the inertia of the whole step, which saves a Newton
    // iteration (bar90 Hex8 Corotational at dt = 0.01: 3.33 -> 2.51 per step). A linear model
    // is still solved exactly by one solve from there.
    u_try_ = u_;
    if (predictor) u_try_ += dt * v_ + (0.5 * dt * dt) * a_start_;
    for (Index i = 0; i < num_dofs(); ++i)
      if (constrained_[i]) u_try_[i] = prescribed_[i];

    StepReport rep;
    const bool realtime = nm.mode == NewmarkMode::RealTime;
    exact_tangent_ = use_exact_tangent();  // exact Hessian first; projected if it is indefinite
    const int max_it = realtime ? 1 : settings_.newton.max_iterations;
    Scalar scale = 0;
    bool converged = false;
    // Each iteration: solve A du = -r, then evaluate the residual at u + du (force only); only
    // if |r| did not decrease, backtrack (force-only evaluations) along du.
    // The tangent is re-assembled at every iterate (exact tangent) or only here (warped). It
    // is assembled lazily, once an iterate has failed the convergence test: most steps
    // converge after one Newton iteration, and a tangent at the converged point would be
    // wasted (bar5760 Hex8 NeoHookean: one of two tangent assemblies per step). Rayleigh
    // stiffness damping D = beta K(u) needs K with every residual.
    const bool update_tangent = exact_tangent_ || !settings_.newton.tangent_once_per_step;
    const bool tangent_with_residual = settings_.rayleigh_stiffness != 0;
    dynamic_residual(u_try_, dt, c0, true);  // fills r_, K_ (and f_int_)
    bool tangent_at_iterate = true;         // K_ is the tangent at u_try_
    bool system_stale = true;               // A_ = c M + K_ needs forming from the new K_
    Scalar rnorm = free_norm(r_);
    for (int it = 0;; ++it) {
      if (!std::isfinite(rnorm))
        fail<SolverError>("Newmark step at t = {}: the residual is not finite{}; the state is unchanged", t1,
                          locate_blow_up(u_try_));
      scale = std::max(scale, force_scale());
      rep.residual = rnorm;
      rep.relative_residual = rnorm / scale;
      if (!realtime && it > 0 && rnorm <= settings_.newton.residual_tolerance * scale) {
        converged = true;
        break;
      }
      if (it == max_it) break;
      if (update_tangent && !tangent_at_iterate) {
        assemble(u_try_, f_int_, &K_);  // f_int_ is unchanged: same u
        tangent_at_iterate = system_stale = true;
      }
      rhs_ = -r_;
      for (Index i = 0; i < num_dofs(); ++i)
        if (constrained_[i]) rhs_[i] = 0;
      // Inexact Newton (Eisenstat-Walker style): solve only as accurately as this iteration
      // needs to reach the Newton tolerance, never looser than 0.1 nor tighter than the
      // configured linear tolerance. Real-time mode uses the configured tolerance.
      const Scalar target = settings_.newton.residual_tolerance * scale;
      const Scalar cg_tol = realtime ? settings_.linear.tolerance
                                     : std::max(settings_.linear.tolerance, std::min(0.1, 0.5 * target / rnorm));
      const LinearSolveReport lr = solve_with_fallback(
          [&] {
            // CG warm start: the first increment of the previous step (the motion over one
            // step changes slowly); later increments start from zero.
            if (it == 0 && first_increment_.size() == num_dofs()) du_ = first_increment_;
            else du_.setZero();
            for (Index i = 0; i < num_dofs(); ++i)
              if (constrained_[i]) du_[i] = 0;
            // A linear model at an unchanged time step has the same matrix as last step.
            const bool same = Elastic::constant_tangent ? system_coefficients_ == std::pair{mass_coef, stiff_coef}
                                                        : !system_stale;
            if (!same) {
              system_stale = false;
              form_system(mass_coef, stiff_coef);
              apply_dirichlet(A_, rhs_);
              system_coefficients_ = Elastic::constant_tangent ? std::pair{mass_coef, stiff_coef} : std::pair{0.0, 0.0};
            }
            return linear_.solve(A_, rhs_, du_, cg_tol, same);
          },
          [&] {
            assemble(u_try_, f_int_, &K_);
            system_stale = true;
          });
      if (it == 0) next_first_increment_ = du_;  // committed with the step
      rep.linear_iterations += lr.iterations;
      ++rep.newton_iterations;
      // One linearised solve (real-time mode), or a linear model solved exactly by it.
      if (realtime || (Elastic::constant_tangent && lr.converged)) {
        u_try_ += du_;
        converged = true;
        break;
      }
      work2_ = u_try_ + du_;
      dynamic_residual(work2_, dt, c0, tangent_with_residual);
      tangent_at_iterate = tangent_with_residual;
      system_stale = system_stale || tangent_with_residual;
      Scalar r_new = free_norm(r_), step = 1;
      if (line_search_applies() && !(std::isfinite(r_new) && r_new < (1 - 1e-4) * rnorm)) {
        step = line_search(u_try_, du_, rnorm, dt, c0);
        // No descent along an exact-Hessian direction: use the projected (PSD) tangent for the
        // rest of this step.
        if (step == 1) exact_tangent_ = false;
        work2_ = u_try_ + step * du_;
        dynamic_residual(work2_, dt, c0, tangent_with_residual);
        r_new = free_norm(r_);
      }
      u_try_.swap(work2_);
      rnorm = r_new;
      if (step * du_.norm() <= settings_.newton.increment_tolerance * (u_try_.norm() + mesh_size_) &&
          rnorm <= std::sqrt(settings_.newton.residual_tolerance) * scale) {
        rep.residual = rnorm;
        rep.relative_residual = rnorm / scale;
        converged = true;  // stagnated at round-off level: the increment no longer changes u
        break;
      }
    }
    if (!converged)
      fail<SolverError>("Newmark step at t = {} did not converge in {} Newton iterations (|r| = {:.3g}, relative "
                        "{:.3g}); the state is unchanged. Try a smaller dt or more iterations",
                        t1, rep.newton_iterations, rep.residual, rep.relative_residual);
    // Commit.
    a_try_ = c0 * (u_try_ - u_) - c0 * dt * v_ - (1 / (2 * nm.beta) - 1) * a_start_;
    v_try_ = v_ + dt * ((1 - nm.gamma) * a_start_ + nm.gamma * a_try_);
    if (!u_try_.allFinite() || !v_try_.allFinite())
      fail<SolverError>("Newmark step at t = {} produced non-finite values; the state is unchanged", t1);
    u_.swap(u_try_);
    v_.swap(v_try_);
    a_.swap(a_try_);
    time_ = t1;
    initial_acceleration_known_ = true;
    first_increment_ = next_first_increment_;
    rep.wall_ms = ms_since(t0);
    return rep;
  }

 public:
  // --- observables ------------------------------------------------------------------------
  Scalar kinetic_energy() const {
    M_.multiply(v_, work_, threads());
    return 0.5 * v_.dot(work_);
  }
  /// Elastic strain energy summed over elements.
  Scalar strain_energy() const {
    Scalar w = 0;
    ElementVector<E> fe;
    for (Index e = 0; e < mesh_.num_elements(); ++e)
      w += Elastic::template evaluate<E>(data(e), current_nodes(e, u_), fe, nullptr);
    return w;
  }
  /// Work potential of the external loads at the current time: f_ext . u.
  Scalar external_work_potential() const {
    Vector f(num_dofs());
    external_force(time_, f);
    return f.dot(u_);
  }
  /// Deformed volume.
  Scalar volume() const {
    Scalar v = 0;
    for (Index e = 0; e < mesh_.num_elements(); ++e) v += element_volume<E>(current_nodes(e, u_));
    return v;
  }
  /// Total mass, 1^T M 1 per direction.
  Scalar mass() const { return M_.sum() / 3; }
  /// Reaction forces at constrained dofs: f_int + M a + D v - f_ext (zero elsewhere).
  Vector reaction_forces() const {
    Vector f(num_dofs()), fe(num_dofs()), r(num_dofs());
    internal_force(u_, f);
    external_force(time_, fe);
    M_.multiply(a_, r, threads());
    r += f - fe;
    if (settings_.rayleigh_stiffness != 0) {
      BlockSymmetricMatrix K = assembler_.zero_matrix();
      assemble_tangent(u_, K);
      add_damping_force(K, v_, 1.0, r);
    } else {
      add_damping_force(M_, v_, 1.0, r);  // K unused without stiffness damping
    }
    for (Index i = 0; i < num_dofs(); ++i)
      if (!constrained_[i]) r[i] = 0;
    return r;
  }
  /// Internal elastic forces at the current state.
  Vector internal_force() const {
    Vector f(num_dofs());
    internal_force(u_, f);
    return f;
  }
  /// Tangent stiffness at the current state (full symmetric storage).
  SparseMatrix tangent() const {
    BlockSymmetricMatrix K = assembler_.zero_matrix();
    assemble_tangent(u_, K);
    return K.to_sparse();
  }
  /// Mass matrix (full symmetric storage).
  SparseMatrix mass_matrix() const { return M_.to_sparse(); }
  /// Cauchy stress per element at its centre.
  std::vector<Mat3> element_stress() const {
    std::vector<Mat3> s(mesh_.num_elements());
    for (Index e = 0; e < mesh_.num_elements(); ++e)
      s[e] = Elastic::template cauchy_stress<E>(data(e), current_nodes(e, u_), material_);
    return s;
  }
  Vector von_mises_stress() const {
    const auto s = element_stress();
    Vector vm(static_cast<Index>(s.size()));
    for (size_t e = 0; e < s.size(); ++e) vm[static_cast<Index>(e)] = von_mises(s[e]);
    return vm;
  }
  bool is_constrained(Index dof) const { return constrained_[dof] != 0; }
  /// Number of distinct element shapes (elements that are translated copies share their
  /// precomputed data: one for a structured Hex8 grid, six for its Kuhn Tet4 split).
  Index num_element_shapes() const { return data_.num_shapes(); }

 private:
  /// Threads for element loops and matrix products (settings().threads, 0: OpenMP's default).
  int threads() const { return settings_.threads > 0 ? settings_.threads : max_threads(); }
  void set_solver_threads() {
    linear_.set_threads(threads());
    static_linear_.set_threads(threads());
  }

  static SolverSettings validated(const SolverSettings& s) {
    validate_settings(s);
    return s;
  }
  static void validate_settings(const SolverSettings& s) {
    const auto& nm = s.newmark;
    if (!(nm.gamma >= 0.5) || !(nm.beta >= 0.25 * (0.5 + nm.gamma) * (0.5 + nm.gamma) - 1e-15) || nm.beta > 0.5)
      fail<InvalidArgument>("Newmark parameters beta = {}, gamma = {} are not unconditionally stable: need gamma >= "
                            "1/2 and (gamma + 1/2)^2 / 4 <= beta <= 1/2 (default 1/4, 1/2)",
                            nm.beta, nm.gamma);
    if (!(s.rayleigh_mass >= 0) || !(s.rayleigh_stiffness >= 0))
      fail<InvalidArgument>("Rayleigh coefficients must be >= 0, got alpha = {}, beta = {}", s.rayleigh_mass,
                            s.rayleigh_stiffness);
    if (!(s.newton.residual_tolerance > 0) || s.newton.max_iterations < 1)
      fail<InvalidArgument>("Newton needs a positive tolerance and at least one iteration");
    if (!(s.linear.tolerance > 0) || s.linear.max_iterations < 1)
      fail<InvalidArgument>("CG needs a positive tolerance and at least one iteration");
    resolve_direct_solver(s.linear.direct);  // a back-end this build lacks: a clear error now
    resolve_direct_solver(s.static_linear.direct);
  }
  void check_nodes(std::span<const Index> nodes, const char* what) const {
    for (Index i : nodes)
      if (i < 0 || i >= mesh_.num_nodes())
        fail<InvalidArgument>("{}: node {} out of range [0, {})", what, i, mesh_.num_nodes());
  }
  static void check_finite(const Vec3& v, const char* what) {
    if (!v.allFinite()) fail<InvalidArgument>("{} must be finite, got ({}, {}, {})", what, v.x(), v.y(), v.z());
  }
  static double ms_since(std::chrono::steady_clock::time_point t0) {
    return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  }

  const Data& data(Index e) const { return data_[e]; }

  ElementNodes<E> current_nodes(Index e, const Vector& u) const {
    ElementNodes<E> x;
    const auto& c = mesh_.element(e);
    for (int a = 0; a < N; ++a) x.col(a) = X_.segment<3>(3 * c[a]) + u.segment<3>(3 * c[a]);
    return x;
  }

  /// Backtracking needs a descent direction for |r|, which only the exact Jacobian guarantees:
  /// with the warped corotational tangent it mostly fails and costs force evaluations
  /// (bar720 Tet4 Corotational: 9.2 ms per accurate-mode Newton iteration against 4.8 ms for
  /// the real-time one, the difference being rejected trial steps), so without the exact
  /// tangent Newton takes full steps. A step that fell back to the projected tangent keeps the
  /// search: for the ln J energies it is what rejects a trial step that inverts an element.
  bool line_search_applies() const { return settings_.newton.line_search && use_exact_tangent(); }
  bool use_exact_tangent() const { return has_exact_tangent && settings_.newton.exact_tangent; }

  /// Runs a linear solve; if it fails because the exact tangent made the system indefinite
  /// (negative LDLT pivot, CG breakdown), switches to the projected tangent and solves again.
  template <class Solve, class Reassemble>
  LinearSolveReport solve_with_fallback(Solve&& solve, Reassemble&& reassemble) {
    try {
      return solve();
    } catch (const SolverError&) {
      if (!exact_tangent_) throw;
      exact_tangent_ = false;
      reassemble();
      return solve();
    }
  }

  /// Says where a non-finite residual comes from: the first element whose force is not finite,
  /// and whether it is inverted (det F <= 0 at a quadrature point, outside the domain of
  /// energies with ln J).
  std::string locate_blow_up(const Vector& u) const {
    if (!u.allFinite()) return " (the displacement itself is not finite)";
    const auto q = E::template quadrature<E::stiffness_degree>();
    ElementVector<E> fe;
    for (Index e = 0; e < mesh_.num_elements(); ++e) {
      const ElementNodes<E> x = current_nodes(e, u);
      const Scalar w = Elastic::template evaluate<E>(data(e), x, fe, nullptr);
      if (std::isfinite(w) && fe.allFinite()) continue;
      for (int k = 0; k < q.size; ++k)
        if (!(jacobian<E>(x, q.points[k]).determinant() > 0))
          return fmt::format(" (element {} is inverted at quadrature point {}: det F <= 0; {} is undefined there, "
                             "StableNeoHookean is not)",
                             e, k, Elastic::name);
      return fmt::format(" (element {} has a non-finite internal force)", e);
    }
    return " (external loads or prescribed displacements are not finite)";
  }

  /// Calls f(xi, dxi/ds, dxi/dt, weight) at the quadrature points of local face `face`, mapped
  /// into the reference element. Tri faces: 3-point degree-2 rule (exact for Tet10's quadratic
  /// N_a on flat faces); quad faces: 2x2 Gauss (exact for bilinear N_a times a bilinear dA).
  template <class F>
  static void for_each_face_point(int face, F&& f) {
    const auto Xref = E::reference_nodes();
    const auto& fn = E::faces[face];
    if constexpr (E::nodes_per_face == 4) {
      const Scalar g = 0.57735026918962576451;
      for (Scalar s : {-g, g})
        for (Scalar t : {-g, g}) {
          // Bilinear map of the reference face corners (flat faces of the reference cube).
          const Scalar Ns[4] = {(1 - s) * (1 - t) / 4, (1 + s) * (1 - t) / 4, (1 + s) * (1 + t) / 4,
                                (1 - s) * (1 + t) / 4};
          const Scalar dNs[4] = {-(1 - t) / 4, (1 - t) / 4, (1 + t) / 4, -(1 + t) / 4};
          const Scalar dNt[4] = {-(1 - s) / 4, -(1 + s) / 4, (1 + s) / 4, (1 - s) / 4};
          Vec3 xi = Vec3::Zero(), ds = Vec3::Zero(), dt = Vec3::Zero();
          for (int k = 0; k < 4; ++k) {
            xi += Ns[k] * Xref.col(fn[k]);
            ds += dNs[k] * Xref.col(fn[k]);
            dt += dNt[k] * Xref.col(fn[k]);
          }
          f(xi, ds, dt, 1.0);
        }
    } else {
      // Strang-Fix 3-point rule on the unit triangle (area 1/2), degree 2.
      const Scalar pts[3][2] = {{1.0 / 6, 1.0 / 6}, {2.0 / 3, 1.0 / 6}, {1.0 / 6, 2.0 / 3}};
      const Vec3 p0 = Xref.col(fn[0]), e1 = Xref.col(fn[1]) - p0, e2 = Xref.col(fn[2]) - p0;
      for (const auto& p : pts) f(Vec3(p0 + p[0] * e1 + p[1] * e2), e1, e2, 1.0 / 6);
    }
  }

  void build_mass() { assemble_mass(mesh_, assembler_, material_.density, settings_.mass, M_); }

  void external_force(Scalar t, Vector& f) const {
    f.setZero();
    for (const auto& l : loads_) f += (l.curve ? l.curve(t) : 1.0) * l.force;
  }

  void prescribed_values(Scalar t, Vector& g) const {
    g.setZero();
    for (const auto& bc : dirichlet_) {
      if (!bc.displacement) continue;
      for (Index i : bc.nodes) {
        const Vec3 d = bc.displacement(t, mesh_.node(i));
        if (!d.allFinite()) fail<InvalidArgument>("prescribed displacement at node {}, t = {} is not finite", i, t);
        for (int k = 0; k < 3; ++k)
          if (bc.mask[k]) g[3 * i + k] = d[k];
      }
    }
  }

  /// f = f_int(u); with K: also the tangent, written into K's values (pattern fixed).
  void assemble(const Vector& u, Vector& f, BlockSymmetricMatrix* K) const {
    f.setZero();
    Scalar* values = K ? K->values() : nullptr;
    if (K) K->set_zero();
    assembler_.for_each_element(
        [&](Index e) {
          ElementVector<E> fe;
          ElementMatrix<E> Ke;
          if constexpr (has_exact_tangent)
            element_energy_[e] = Elastic::template evaluate<E>(
                data(e), current_nodes(e, u), fe, K ? &Ke : nullptr,
                exact_tangent_ ? Elastic::TangentKind::Exact : Elastic::TangentKind::Projected);
          else
            element_energy_[e] = Elastic::template evaluate<E>(data(e), current_nodes(e, u), fe, K ? &Ke : nullptr);
          const auto& c = mesh_.element(e);
          for (int a = 0; a < N; ++a) f.segment<3>(3 * c[a]) += fe.template segment<3>(3 * a);
          if (K) assembler_.add_element_matrix(e, Ke, values);
        },
        settings_.threads);
  }
  void internal_force(const Vector& u, Vector& f) const { assemble(u, f, nullptr); }
  /// Total potential energy W(u) - f_ext . u of the last assembled u (dead loads).
  Scalar potential_energy(const Vector& u) const {
    Scalar w = 0;
    for (Scalar we : element_energy_) w += we;
    return w - f_ext_.dot(u);
  }
  void assemble_tangent(const Vector& u, BlockSymmetricMatrix& K) const {
    Vector f(num_dofs());
    assemble(u, f, &K);
  }

  /// r_ = M a(u) + D v(u) + f_int(u) - f_ext; fills a_try_, v_try_ and (optionally) K_.
  void dynamic_residual(const Vector& u, Scalar dt, Scalar c0, bool tangent) {
    const auto& nm = settings_.newmark;
    const bool constant = Elastic::constant_tangent;
    if (constant) {
      if (!K_assembled_) {
        assemble_tangent(u, K_);
        K_assembled_ = true;
      }
      K_.multiply(u, f_int_, threads());
      // Linear: f_int = K0 (x - X0) = K u.
    } else {
      assemble(u, f_int_, tangent ? &K_ : nullptr);
    }
    a_try_ = c0 * (u - u_) - c0 * dt * v_ - (1 / (2 * nm.beta) - 1) * a_start_;
    v_try_ = v_ + dt * ((1 - nm.gamma) * a_start_ + nm.gamma * a_try_);
    M_.multiply(a_try_, r_, threads());
    r_ += f_int_ - f_ext_;
    add_damping_force(K_, v_try_, 1.0, r_);
  }

  /// out += sign D v with D = alpha M + beta K (Rayleigh); K is read only when beta != 0.
  void add_damping_force(const BlockSymmetricMatrix& K, const Vector& v, Scalar sign, Vector& out) const {
    if (settings_.rayleigh_mass != 0) {
      M_.multiply(v, work_, threads());
      out += (sign * settings_.rayleigh_mass) * work_;
    }
    if (settings_.rayleigh_stiffness != 0) {
      K.multiply(v, work_, threads());
      out += (sign * settings_.rayleigh_stiffness) * work_;
    }
  }

  /// Scale for relative residuals: the largest of the force terms in the balance.
  Scalar force_scale() const {
    const Scalar s = std::max({free_norm(f_ext_), free_norm(f_int_), 1e-30});
    return s;
  }
  Scalar free_norm(const Vector& v) const {
    Scalar s = 0;
    for (Index i = 0; i < num_dofs(); ++i)
      if (!constrained_[i]) s += v[i] * v[i];
    return std::sqrt(s);
  }

  /// A_ = mass_coef M + stiff_coef K_ (same pattern: one pass over the values).
  void form_system(Scalar mass_coef, Scalar stiff_coef) {
    const Index nnz = A_.num_values();
    Scalar* a = A_.values();
    const Scalar* m = M_.values();
    const Scalar* k = K_.values();
    for (Index i = 0; i < nnz; ++i) a[i] = mass_coef * m[i] + stiff_coef * k[i];
  }

  /// Constrained dofs: the increment is zero there (u already holds the prescribed value), so
  /// rows and columns become identity and the right-hand side zero. Keeps A symmetric. The
  /// touched blocks are found once per change of the constraints.
  void apply_dirichlet(BlockSymmetricMatrix& A, Vector& b) {
    if (!constrained_blocks_current_) {
      constrained_blocks_ = ConstrainedBlocks(A.pattern(), constrained_);
      constrained_blocks_current_ = true;
    }
    constrained_blocks_.apply(A);
    constrained_blocks_.zero(b);
  }

  /// Backtracking on |r| along du (force-only evaluations): the first halved step that
  /// decreases the residual; if none does (the warped corotational tangent is not the exact
  /// Jacobian, so du need not descend), the full step, and the iteration cap decides.
  Scalar line_search(const Vector& u, const Vector& du, Scalar r0, Scalar dt, Scalar c0) {
    Scalar s = 0.5;
    for (int k = 0; k < 7; ++k, s *= 0.5) {
      work3_ = u + s * du;
      dynamic_residual(work3_, dt, c0, false);
      const Scalar r = free_norm(r_);
      if (std::isfinite(r) && r < (1 - 1e-4 * s) * r0) return s;
    }
    return 1;
  }

  StepReport newton_static(Vector& u) {
    StepReport rep;
    exact_tangent_ = use_exact_tangent();
    Scalar scale = std::max(free_norm(f_ext_), 1e-30);
    for (int it = 0; it < settings_.newton.max_iterations + 1; ++it) {
      assemble(u, f_int_, &K_);
      r_ = f_int_ - f_ext_;
      const Scalar rnorm = free_norm(r_);
      if (!std::isfinite(rnorm)) fail<SolverError>("static Newton: the residual is not finite{}", locate_blow_up(u));
      scale = std::max(scale, free_norm(f_int_));
      rep.residual = rnorm;
      rep.relative_residual = rnorm / scale;
      if (rnorm <= settings_.newton.residual_tolerance * scale) return rep;
      if (it == settings_.newton.max_iterations) break;
      rhs_ = -r_;
      const LinearSolveReport lr = solve_with_fallback(
          [&] {
            du_.setZero();
            A_ = K_;
            system_coefficients_ = {0.0, 0.0};
            apply_dirichlet(A_, rhs_);
            return static_linear_.solve(A_, rhs_, du_);
          },
          [&] { assemble(u, f_int_, &K_); });
      rep.linear_iterations += lr.iterations;
      ++rep.newton_iterations;
      if (Elastic::constant_tangent && lr.converged) {  // one exact solve is the answer
        u += du_;
        internal_force(u, f_int_);
        r_ = f_int_ - f_ext_;
        rep.residual = free_norm(r_);
        rep.relative_residual = rep.residual / scale;
        return rep;
      }
      // Backtracking (Armijo) on the potential energy Pi = W(u) - f_ext . u, which the exact
      // Newton direction descends whenever K is positive definite (slope r . du < 0). On |r|
      // instead, bending crawls: the full step that straightens the rotation field raises |r|
      // before it falls (Hex8 bar at 1 g: 179 Newton iterations on |r|, 31 on Pi). If no
      // step length decreases Pi, take the full Newton step and project from now on.
      Scalar s = 1;
      if (line_search_applies() && !Elastic::constant_tangent) {
        const Scalar pi0 = potential_energy(u), slope = r_.dot(du_);
        bool decreased = false;
        for (int k = 0; k < 8 && !decreased && slope < 0; ++k) {
          work2_ = u + s * du_;
          internal_force(work2_, work_);
          const Scalar pi = potential_energy(work2_);
          work_ -= f_ext_;
          const Scalar r = free_norm(work_);
          // Either merit function may accept: Pi (with the round-off of Pi near convergence
          // allowed for) or |r|.
          decreased = std::isfinite(pi) && std::isfinite(r) &&
                      (pi <= pi0 + 1e-4 * s * slope + 1e-12 * (std::abs(pi0) + 1e-30) || r < (1 - 1e-4 * s) * rnorm);
          if (!decreased) s *= 0.5;
        }
        if (!decreased) {
          s = 1;
          exact_tangent_ = false;  // an exact Hessian that does not descend: project from now on
        }
      }
      u += s * du_;
    }
    fail<SolverError>("static Newton did not converge in {} iterations (|r| = {:.3g}, relative {:.3g})",
                      settings_.newton.max_iterations, rep.residual, rep.relative_residual);
  }

  /// M a_0 = f_ext(t) - f_int(u) - D v at the current time; zero at constrained dofs.
  void solve_initial_acceleration(Vector& a) {
    external_force(time_, f_ext_);
    internal_force(u_, f_int_);
    if (!f_int_.allFinite() || !f_ext_.allFinite())
      fail<SolverError>("initial acceleration at t = {}: the force is not finite{}; the state is unchanged", time_,
                        locate_blow_up(u_));
    rhs_ = f_ext_ - f_int_;
    if (settings_.rayleigh_stiffness != 0) assemble_tangent(u_, K_);
    add_damping_force(K_, v_, -1.0, rhs_);
    A_ = M_;
    system_coefficients_ = {0.0, 0.0};
    apply_dirichlet(A_, rhs_);
    // The mass matrix is well conditioned (Jacobi-scaled condition number ~10-50 for
    // consistent mass, 1 for lumped), so CG reaches round-off in a few dozen products, where a
    // sparse factorisation costs seconds on large meshes (the first bar5760 Hex8 step now
    // takes 0.18 s in all).
    a = Vector::Zero(num_dofs());
    LinearSolver cg({LinearSolverKind::ConjugateGradient, 1e-13, 2000});
    if (!cg.solve(A_, rhs_, a).converged) {
      LinearSolver direct({LinearSolverKind::Direct});
      direct.solve(A_, rhs_, a);
    }
  }

  Mesh<E> mesh_;  // a copy: the solver stays valid whatever happens to the caller's mesh
  Material material_;
  SolverSettings settings_;
  Assembler<E> assembler_;
  ElementDataTable<E, Elastic> data_;  ///< prepared once, shared by translated copies
  LinearSolver linear_, static_linear_;
  std::vector<DirichletCondition> dirichlet_;
  std::vector<ExternalLoad> loads_;
  std::vector<char> constrained_;
  ConstrainedBlocks constrained_blocks_;  ///< where constrained_ touches the system matrix
  bool constrained_blocks_current_ = false;
  BlockSymmetricMatrix M_, K_, A_;
  bool K_assembled_ = false;
  /// (mass, stiffness) coefficients of the system matrix in A_ for a constant-tangent model;
  /// (0, 0): A_ holds something else (it is also used by statics and the initial acceleration).
  std::pair<Scalar, Scalar> system_coefficients_{0.0, 0.0};
  /// Models with an exact and a projected tangent (hyperelastic): which one assembly uses.
  static constexpr bool has_exact_tangent = requires { Elastic::TangentKind::Exact; };
  bool exact_tangent_ = has_exact_tangent;
  Vector X_, u_, v_, a_;
  Vector f_int_, f_ext_, r_, du_, rhs_, u_try_, a_try_, v_try_, prescribed_;
  mutable Vector work_;
  mutable std::vector<Scalar> element_energy_;  ///< W_e of the last assembly (line search)
  Vector work2_, work3_, first_increment_, next_first_increment_, a_start_;
  Scalar time_ = 0, mesh_size_ = 1;
  bool initial_acceleration_known_ = false;
};

}  // namespace plastifem
