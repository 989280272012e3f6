#pragma once
// BareNewmark<E, Model>: the elastic real-time Newmark step composed by hand from the toolkit's
// parts (Assembler, ElementDataTable, the model's evaluate, assemble_mass, body_force_load,
// ConstrainedBlocks, LinearSolver), with no plastic or enrichment policy parameters: the
// baseline against which bench_policy_overhead measures Solver<E, Model, NoPlasticity,
// NoEnrichment>. It performs the Solver's real-time step operation for operation, so the two
// agree bit for bit (tests/test_policy_baseline.cpp checks it; the benchmark checks it too).
// Scene: SCENES.md bar conditions (fixed nodes at 0, one body-force load, beta 1/4, gamma 1/2).
#include <plastifem/plastifem.hpp>

namespace plastifem::bench {

/// The elastic real-time Newmark step without policy axes, written against the toolkit's
/// parts. Mirrors Solver::newmark_attempt (real-time branch) and its initial acceleration.
template <FiniteElement E, class Model>
class BareNewmark {
  static constexpr int N = E::num_nodes;
  static constexpr bool has_exact_tangent = has_exact_tangent_v<Model>;

 public:
  BareNewmark(const Mesh<E>& mesh, const Material& material, const std::vector<Index>& fixed, const Vec3& g,
              const LinearSolverSettings& linear, int threads)
      : mesh_(mesh), assembler_(mesh), data_(mesh, material), linear_(linear), threads_(threads) {
    const Index n = 3 * mesh.num_nodes();
    X_ = Eigen::Map<const Vector>(mesh.nodes().data(), n);
    u_ = v_ = a_ = Vector::Zero(n);
    constrained_.assign(n, 0);
    for (Index i : fixed) constrained_[3 * i] = constrained_[3 * i + 1] = constrained_[3 * i + 2] = 1;
    assemble_mass(mesh, assembler_, material.density, MassKind::Consistent, M_);
    K_ = A_ = assembler_.zero_matrix();
    constrained_blocks_ = ConstrainedBlocks(M_.pattern(), constrained_);
    gravity_ = body_force_load(mesh, material.density, g);
    linear_.set_threads(threads);
    f_int_.resize(n), f_ext_.resize(n), r_.resize(n), du_.resize(n), rhs_.resize(n);
    u_try_.resize(n), a_try_.resize(n), v_try_.resize(n), a_start_.resize(n), f_lin_.resize(n);
    initial_acceleration();
  }

  /// The Solver's real-time step (solver/dynamics.hpp): the linearisation at u_n kept from the
  /// end of the previous step, one solve, then the new state evaluated (force and tangent, the
  /// next step's linearisation) and its residual computed for the report.
  void step(Scalar dt) {
    const Scalar beta = 0.25, gamma = 0.5;
    a_start_ = a_;
    const Scalar c0 = 1 / (beta * dt * dt);
    external_force();
    if (!linearised_) {
      assemble(u_, &K_);
      f_lin_ = f_int_;
      linearised_ = true;
    }
    u_try_ = u_;
    for (Index i = 0; i < num_dofs(); ++i)
      if (constrained_[i]) u_try_[i] = 0;  // fixed: prescribed value 0
    const Scalar f_ext_norm = free_norm(f_ext_);
    residual(u_try_, f_lin_, c0, dt, beta, gamma, f_ext_norm);
    rhs_ = -r_;
    constrained_blocks_.zero(rhs_);
    if (first_increment_.size() == num_dofs() && previous_increment_.size() == num_dofs() && dt_last_ == dt &&
        dt_previous_ == dt)
      du_ = 2 * first_increment_ - previous_increment_;  // the Solver's extrapolated CG start
    else if (first_increment_.size() == num_dofs())
      du_ = first_increment_;
    else
      du_.setZero();
    constrained_blocks_.zero(du_);
    const Scalar* m = M_.values();
    const Scalar* k = K_.values();
    Scalar* a = A_.values();
    for (Index i = 0; i < A_.num_values(); ++i) a[i] = c0 * m[i] + k[i];
    constrained_blocks_.apply(A_);
    linear_.solve(A_, rhs_, du_, linear_.settings().tolerance, false);
    previous_increment_ = first_increment_;
    first_increment_ = du_;
    dt_previous_ = dt_last_;
    dt_last_ = dt;
    u_try_ += du_;
    assemble(u_try_, &K_);
    if (!f_int_.allFinite() || !u_try_.allFinite()) fail<SolverError>("bare step: non-finite state");
    residual(u_try_, f_int_, c0, dt, beta, gamma, f_ext_norm);
    if (!v_try_.allFinite() || !a_try_.allFinite()) fail<SolverError>("bare step: non-finite state");
    u_.swap(u_try_);
    v_.swap(v_try_);
    a_.swap(a_try_);
    f_lin_.swap(f_int_);
  }

  const Vector& displacement() const { return u_; }
  Scalar force_scale() const { return scale_; }

 private:
  Index num_dofs() const { return static_cast<Index>(u_.size()); }

  void external_force() {
    f_ext_.setZero();
    f_ext_ += 1.0 * gravity_;  // one load, no load curve: as the Solver sums its loads
  }

  void initial_acceleration() {
    external_force();
    assemble(u_, nullptr);
    rhs_ = f_ext_ - f_int_;
    A_ = M_;
    constrained_blocks_.apply(A_);
    constrained_blocks_.zero(rhs_);
    a_ = Vector::Zero(num_dofs());
    LinearSolver cg({LinearSolverKind::ConjugateGradient, 1e-13, 2000});
    cg.set_threads(threads_);  // as the Solver's: threaded products round differently
    cg.solve(A_, rhs_, a_);
  }

  void assemble(const Vector& u, BlockSymmetricMatrix* K) {
    f_int_.setZero();
    if (K) K->set_zero();
    Scalar* values = K ? K->values() : nullptr;
    assembler_.for_each_element(
        [&](Index e) {
          ElementVector<E> fe;
          ElementMatrix<E> Ke;
          ElementNodes<E> x;
          const auto& c = mesh_.element(e);
          for (int b = 0; b < N; ++b) x.col(b) = X_.segment<3>(3 * c[b]) + u.segment<3>(3 * c[b]);
          Model::template evaluate<E>(data_[e], x, fe, K ? &Ke : nullptr,
                                      has_exact_tangent ? TangentKind::Exact : TangentKind::Projected, true);
          for (int b = 0; b < N; ++b) f_int_.segment<3>(3 * c[b]) += fe.template segment<3>(3 * b);
          if (K) assembler_.add_element_matrix(e, Ke, values);
        },
        threads_);
  }

  /// r_ = M a(u) + f - f_ext with the Newmark a(u), v(u); scale_ as the Solver reports it.
  Scalar residual(const Vector& u, const Vector& f, Scalar c0, Scalar dt, Scalar beta, Scalar gamma, Scalar f_ext_norm) {
    a_try_ = c0 * (u - u_) - c0 * dt * v_ - (1 / (2 * beta) - 1) * a_start_;
    for (Index i = 0; i < num_dofs(); ++i)
      if (constrained_[i]) a_try_[i] = 0;
    v_try_ = v_ + dt * ((1 - gamma) * a_start_ + gamma * a_try_);
    for (Index i = 0; i < num_dofs(); ++i)
      if (constrained_[i]) v_try_[i] = 0;
    M_.multiply(a_try_, r_, threads_);
    const Scalar inertia = free_norm(r_);
    r_ += f - f_ext_;
    scale_ = std::max({f_ext_norm, free_norm(f), inertia, 0.0});
    return free_norm(r_);
  }

  Scalar free_norm(const Vector& v) const {
    Scalar s = 0;
    for (Index i = 0; i < num_dofs(); ++i)
      if (!constrained_[i]) s += v[i] * v[i];
    return std::sqrt(s);
  }

  const Mesh<E>& mesh_;
  Assembler<E> assembler_;
  ElementDataTable<E, Model> data_;
  LinearSolver linear_;
  int threads_;
  Scalar scale_ = 0;
  std::vector<char> constrained_;
  ConstrainedBlocks constrained_blocks_;
  BlockSymmetricMatrix M_, K_, A_;
  Vector X_, u_, v_, a_, gravity_;
  Vector f_int_, f_lin_, f_ext_, r_, du_, rhs_, u_try_, a_try_, v_try_, a_start_, first_increment_;
  bool linearised_ = false;
  Vector previous_increment_;
  Scalar dt_last_ = 0, dt_previous_ = 0;
};

}  // namespace plastifem::bench
