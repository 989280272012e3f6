#pragma once
// Linear solvers for the symmetric systems of a step: sparse LDLT with the symbolic analysis
// done once (statics, linear models, very large time steps), and Jacobi-preconditioned
// conjugate gradients warm-started from the previous solution (the real-time choice: at usual
// time steps the Newmark matrix is dominated by M / (beta dt^2) and CG needs ~10 iterations).
#include <plastifem/assembly/block_matrix.hpp>

#include <Eigen/SparseCholesky>

namespace plastifem {

enum class LinearSolverKind { Direct, ConjugateGradient };

struct LinearSolverSettings {
  LinearSolverKind kind = LinearSolverKind::ConjugateGradient;
  Scalar tolerance = 1e-8;    ///< CG: stop when |r| <= tolerance |b|
  int max_iterations = 2000;  ///< CG: iteration cap (real-time mode may set it low)
};

struct LinearSolveReport {
  int iterations = 0;
  Scalar relative_residual = 0;
  bool converged = true;
};

class LinearSolver {
 public:
  explicit LinearSolver(LinearSolverSettings s = {}) : settings_(s) {}
  const LinearSolverSettings& settings() const { return settings_; }
  int threads() const { return threads_; }
  void set_threads(int threads) { threads_ = std::max(1, threads); }
  void set_settings(const LinearSolverSettings& s) {
    settings_ = s;
    analysed_ = factorised_ = false;
  }

  /// Solves A x = b; x holds the initial guess on entry (CG warm start). A is symmetric with
  /// constrained rows and columns replaced by identity rows.
  /// `tolerance` > 0 overrides the CG tolerance for this solve (inexact Newton).
  /// `same_matrix`: A is the matrix of the previous solve (e.g. a linear model at a fixed time
  /// step), so the direct solver reuses its numeric factorisation too.
  /// Matrix-vector products use up to threads() threads.
  LinearSolveReport solve(const BlockSymmetricMatrix& A, const Vector& b, Vector& x, Scalar tolerance = 0,
                          bool same_matrix = false) {
    return settings_.kind == LinearSolverKind::Direct
               ? solve_direct(A, b, x, same_matrix)
               : solve_cg(A, b, x, tolerance > 0 ? tolerance : settings_.tolerance);
  }

 private:
  LinearSolveReport solve_direct(const BlockSymmetricMatrix& block, const Vector& b, Vector& x, bool same_matrix) {
    if (same_matrix && factorised_) {
      x = ldlt_.solve(b);
      LinearSolveReport r;
      r.iterations = 0;  // no factorisation, one pair of triangular solves
      return r;
    }
    block.copy_to(csc_);  // Eigen's LDLT reads a CSC matrix (its lower triangle)
    const SparseMatrix& A = csc_;
    if (!analysed_) {
      ldlt_.analyzePattern(A);
      analysed_ = true;
      factorised_ = false;
    }
    factorised_ = false;
    ldlt_.factorize(A);
    // A zero or sign-changed pivot means the system is singular or indefinite (e.g. a body
    // that is free to move rigidly in a static solve).
    const auto D = ldlt_.vectorD();
    const Scalar dmax = D.cwiseAbs().maxCoeff();
    if (ldlt_.info() != Eigen::Success || !(D.minCoeff() > 1e-12 * dmax))
      fail<SolverError>("the system matrix is singular or indefinite (smallest LDLT pivot {:.3g}, largest {:.3g}): "
                        "check that boundary conditions prevent rigid-body motion",
                        D.minCoeff(), dmax);
    factorised_ = true;
    x = ldlt_.solve(b);
    LinearSolveReport r;
    r.iterations = 1;
    return r;
  }

  LinearSolveReport solve_cg(const BlockSymmetricMatrix& A, const Vector& b, Vector& x, Scalar tolerance) {
    const Index n = static_cast<Index>(b.size());
    if (r_.size() != n) {
      r_.resize(n), z_.resize(n), p_.resize(n), q_.resize(n), inv_diag_.resize(n);
    }
    inv_diag_ = A.diagonal();
    for (Index i = 0; i < n; ++i) {
      if (!(inv_diag_[i] > 0))
        fail<SolverError>("CG needs a positive diagonal; entry {} is {} (singular or indefinite system)", i,
                          inv_diag_[i]);
      inv_diag_[i] = 1 / inv_diag_[i];
    }
    LinearSolveReport rep;
    const Scalar bnorm = b.norm();
    if (bnorm == 0) {
      x.setZero();
      return rep;
    }
    A.multiply(x, q_, threads_);
    r_ = b - q_;
    z_ = inv_diag_.cwiseProduct(r_);
    p_ = z_;
    Scalar rz = r_.dot(z_);
    const Scalar target = tolerance * bnorm;
    Scalar rnorm = r_.norm();
    int k = 0;
    while (rnorm > target && k < settings_.max_iterations) {
      A.multiply(p_, q_, threads_);
      const Scalar pq = p_.dot(q_);
      if (!(pq > 0)) fail<SolverError>("CG breakdown (p.Ap = {:.3g}): the system is not positive definite", pq);
      const Scalar alpha = rz / pq;
      x += alpha * p_;
      r_ -= alpha * q_;
      z_ = inv_diag_.cwiseProduct(r_);
      const Scalar rz_new = r_.dot(z_);
      p_ = z_ + (rz_new / rz) * p_;
      rz = rz_new;
      rnorm = r_.norm();
      ++k;
    }
    rep.iterations = k;
    rep.relative_residual = rnorm / bnorm;
    rep.converged = rnorm <= target;
    return rep;
  }

  LinearSolverSettings settings_;
  Eigen::SimplicialLDLT<SparseMatrix, Eigen::Lower, Eigen::AMDOrdering<int>> ldlt_;
  SparseMatrix csc_;
  bool analysed_ = false, factorised_ = false;
  int threads_ = 1;
  Vector r_, z_, p_, q_, inv_diag_;
};

}  // namespace plastifem
