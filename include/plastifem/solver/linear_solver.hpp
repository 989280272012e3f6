#pragma once
// Linear solvers for the symmetric systems of a step: a sparse direct factorisation with the
// symbolic analysis done once (statics, linear models, very large time steps), and
// Jacobi-preconditioned conjugate gradients warm-started from the previous solution (the
// real-time choice: at usual time steps the Newmark matrix is dominated by M / (beta dt^2) and
// CG needs ~10 iterations). Where X-FEM has enriched a node, the node's standard and enriched
// rows are preconditioned together (their diagonal block inverted: set_coupled_rows), which
// brought Heaviside enrichment's CG iterations on a cut bar5760 from 1.9 to 1.06 times the uncut
// body's. CgPreconditioner::BlockJacobi does the same for every node's own 3 x 3 block.
//
// Direct back-ends:
//  - Eigen's SimplicialLDLT with AMD ordering: always available, no dependency.
//  - CHOLMOD's supernodal LL^T through Eigen's CholmodSupport module, when the toolkit is built
//    with it (CMake option PLASTIFEM_WITH_CHOLMOD, on where SuiteSparse is installed; it defines
//    PLASTIFEM_HAS_CHOLMOD). Supernodes turn the factorisation into dense BLAS-3 blocks: on
//    bar5760 Hex8 statics (20,280 free dofs) it factorises in 0.48 s against 5.9 s for the
//    simplicial LDLT, with OpenBLAS on 2 cores (0.75 s on one; 3.4 s with the reference BLAS).
//    It uses the BLAS threads (OPENBLAS_NUM_THREADS), not SolverSettings::threads.
#include <plastifem/assembly/block_matrix.hpp>
#include <plastifem/core/vector_ops.hpp>

#include <Eigen/SparseCholesky>
#include <cmath>

#ifdef PLASTIFEM_HAS_CHOLMOD
#include <Eigen/CholmodSupport>
#endif
#if defined(PLASTIFEM_HAS_CHOLMOD) && defined(_OPENMP)
#include <omp.h>
#endif

namespace plastifem {

enum class LinearSolverKind { Direct, ConjugateGradient };

/// The conjugate-gradient preconditioner P ~ A^-1.
enum class CgPreconditioner {
  /// P = diag(A)^-1.
  Jacobi,
  /// P = the inverse of A's block diagonal of 3 x 3 node blocks: a node's x, y and z rows solved
  /// together. Elasticity couples them within a node wherever an element is not aligned with
  /// the axes: on Gmsh's unstructured livers CG takes about a fifth fewer iterations, on the
  /// axis-aligned bars a few percent, and the iteration count no longer changes when the mesh
  /// is turned. It costs one 3 x 3 inversion per node per solve and 72 bytes of inverse per node
  /// read in each iteration's update (fused into it): a liver5 step takes about 0.87-0.97 of
  /// Jacobi's time, a liver4 step no less (docs/performance.md, "Large and irregular meshes").
  /// Its iterates are not Jacobi's; the solutions agree within what the CG tolerance allows.
  BlockJacobi,
};

/// Which sparse factorisation LinearSolverKind::Direct uses.
enum class DirectSolver {
  Auto,               ///< CHOLMOD where built in, else SimplicialLDLT
  SimplicialLDLT,     ///< Eigen's, built in
  CholmodSupernodal,  ///< CHOLMOD supernodal LL^T (needs PLASTIFEM_HAS_CHOLMOD)
};

/// Whether the toolkit was built with CHOLMOD (PLASTIFEM_WITH_CHOLMOD).
constexpr bool cholmod_available() {
#ifdef PLASTIFEM_HAS_CHOLMOD
  return true;
#else
  return false;
#endif
}

/// The back-end `Auto` resolves to, and a check that an explicit choice is built in.
inline DirectSolver resolve_direct_solver(DirectSolver d) {
  if (d == DirectSolver::Auto) return cholmod_available() ? DirectSolver::CholmodSupernodal : DirectSolver::SimplicialLDLT;
  if (d == DirectSolver::CholmodSupernodal && !cholmod_available())
    fail<InvalidArgument>("DirectSolver::CholmodSupernodal: this build has no CHOLMOD; install SuiteSparse "
                          "(Debian: libsuitesparse-dev) and configure with -DPLASTIFEM_WITH_CHOLMOD=ON, or use "
                          "DirectSolver::Auto / SimplicialLDLT");
  return d;
}

inline const char* direct_solver_name(DirectSolver d) {
  switch (resolve_direct_solver(d)) {
    case DirectSolver::CholmodSupernodal: return "CHOLMOD";
    default: return "LDLT";
  }
}

struct LinearSolverSettings {
  LinearSolverKind kind = LinearSolverKind::ConjugateGradient;
  Scalar tolerance = 1e-8;    ///< CG: stop when |r| <= tolerance |b|
  int max_iterations = 2000;  ///< CG: iteration cap (real-time mode may set it low)
  DirectSolver direct = DirectSolver::Auto;  ///< Direct: the factorisation
  /// CG: recompute the true residual b - A x at the end (one more product) and report
  /// convergence from it. On by default for statics, where a solve must not be trusted blindly.
  bool verify_residual = false;
  /// Real-time mode with a deliberately low CG cap (max_iterations): accept the iterate CG
  /// reached instead of failing the step; StepReport::linear_converged says it did not converge.
  bool accept_capped = false;
  CgPreconditioner preconditioner = CgPreconditioner::Jacobi;  ///< CG
};

#ifdef PLASTIFEM_HAS_CHOLMOD
namespace detail {
/// CHOLMOD's supernodal LL^T, quiet (failures become SolverError) and with its pivot ratio.
class CholmodLLT : public Eigen::CholmodSupernodalLLT<SparseMatrix, Eigen::Lower> {
 public:
  CholmodLLT() { this->cholmod().print = 0; }
  /// min diag(L) / max diag(L) of the last factorisation.
  double rcond() { return cholmod_rcond(this->m_cholmodFactor, &this->cholmod()); }
};

/// CHOLMOD 3 (SuiteSparse 5, Debian 12) opens an OpenMP region of a compile-time 4 threads
/// (CHOLMOD_OMP_NUM_THREADS; OMP_NUM_THREADS does not bound it) around the scatter loops of every
/// supernode wider than 32-64 columns. On 2 cores waking those threads costs more than the
/// factorisation: a bar90 Hex8 Neo-Hookean static solve took 62-73 ms with them, 20-24 ms
/// without (SimplicialLDLT: 24-28 ms). The dense work runs in the BLAS, which has its own
/// threads (OPENBLAS_NUM_THREADS), so CHOLMOD's regions are made inactive (one thread) for the
/// duration of a call: max-active-levels 0, restored on exit. Needs the caller built with OpenMP
/// (as the toolkit's threads do); without it, run with OMP_THREAD_LIMIT=1 for the same effect.
class SerialOpenMPScope {
 public:
#ifdef _OPENMP
  SerialOpenMPScope() : saved_(omp_get_max_active_levels()) { omp_set_max_active_levels(0); }
  ~SerialOpenMPScope() { omp_set_max_active_levels(saved_); }

 private:
  int saved_;
#endif
};
}  // namespace detail
#endif

struct LinearSolveReport {
  int iterations = 0;
  Scalar relative_residual = 0;
  bool converged = true;
};

/// The linear solver of a step (see the file comment). A class template of an unused parameter
/// only so that a file that does not solve compiles none of it, and a file built against
/// plastifem::compiled takes it from the library (the sparse factorisations are ~1 s of
/// compile time).
template <class Unused = void>
class BasicLinearSolver {
 public:
  explicit BasicLinearSolver(LinearSolverSettings s = {}) : settings_(s) {}
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
  /// Block rows the CG preconditioner solves together: each group is a node's standard row and
  /// its enriched rows (X-FEM), whose dofs the element integrals couple strongly (under Heaviside
  /// enrichment a node's u and a enter every uncut element around it as u + H a, so the two
  /// columns are nearly parallel there). The group's (3k x 3k) diagonal block of A is inverted;
  /// every other dof keeps the preconditioner of the settings (Jacobi, or its node's block), so
  /// a system without groups is solved as before, bit for bit. Groups of more than 4 rows, or
  /// whose block is not positive definite, keep it too.
  void set_coupled_rows(std::vector<std::vector<Index>> groups) {
    groups_ = std::move(groups);
    group_offset_.assign(groups_.size() + 1, 0);
    for (size_t g = 0; g < groups_.size(); ++g) {
      const Index k = 3 * static_cast<Index>(groups_[g].size());
      group_offset_[g + 1] = group_offset_[g] + (k <= max_group_dofs ? k * k : 0);
    }
    group_inverse_.assign(group_offset_.back(), 0.0);
    group_valid_.assign(groups_.size(), 0);
  }

  LinearSolveReport solve(const BlockSymmetricMatrix& A, const Vector& b, Vector& x, Scalar tolerance = 0,
                          bool same_matrix = false) {
    return settings_.kind == LinearSolverKind::Direct
               ? solve_direct(A, b, x, same_matrix)
               : solve_cg(A, b, x, tolerance > 0 ? tolerance : settings_.tolerance);
  }

 private:
  LinearSolveReport solve_direct(const BlockSymmetricMatrix& block, const Vector& b, Vector& x, bool same_matrix);

  /// A zero or sign-changed pivot means the system is singular or indefinite (e.g. a body that
  /// is free to move rigidly in a static solve, or an exact tangent under compression).
  [[noreturn]] static void singular(Scalar smallest, Scalar largest, const char* what) {
    fail<SolverError>("the system matrix is singular or indefinite (smallest {} {:.3g}, largest {:.3g}): check that "
                      "boundary conditions prevent rigid-body motion",
                      what, smallest, largest);
  }

  void factorise_ldlt();

  void factorise_cholmod();

  LinearSolveReport solve_cg(const BlockSymmetricMatrix& A, const Vector& b, Vector& x, Scalar tolerance);

  static constexpr int max_group_dofs = 12;

  /// Inverts the symmetric positive definite k x k matrix `a` (column-major, k <= max_group_dofs)
  /// in place: a = L L^T (Cholesky), a^-1 = L^-T L^-1. False, `a` undefined, where a pivot is not
  /// positive (or not finite). Plain loops on purpose: Eigen's LLT of a dynamic matrix pulls its
  /// blocked GEMM and triangular-solve kernels into every translation unit with a Solver (2 s of
  /// CPU and 100 MB of the compiler's memory), for matrices of at most 12 x 12.
  static bool invert_spd(Scalar* a, int k) {
    Scalar l[max_group_dofs][max_group_dofs] = {};  // L, then L^-1, row-major, lower
    for (int j = 0; j < k; ++j) {
      Scalar d = a[j + k * j];
      for (int m = 0; m < j; ++m) d -= l[j][m] * l[j][m];
      if (!(d > 0) || !std::isfinite(d)) return false;
      l[j][j] = std::sqrt(d);
      for (int i = j + 1; i < k; ++i) {
        Scalar s = a[i + k * j];
        for (int m = 0; m < j; ++m) s -= l[i][m] * l[j][m];
        l[i][j] = s / l[j][j];
      }
    }
    for (int j = 0; j < k; ++j) {  // L^-1 column by column, by forward substitution (in place)
      l[j][j] = 1 / l[j][j];
      for (int i = j + 1; i < k; ++i) {
        Scalar s = 0;
        for (int m = j; m < i; ++m) s -= l[i][m] * l[m][j];
        l[i][j] = s / l[i][i];
      }
    }
    for (int j = 0; j < k; ++j)  // (L^-T L^-1)_ij = sum_m>=max(i,j) (L^-1)_mi (L^-1)_mj
      for (int i = j; i < k; ++i) {
        Scalar s = 0;
        for (int m = i; m < k; ++m) s += l[m][i] * l[m][j];
        a[i + k * j] = a[j + k * i] = s;
      }
    return true;
  }

  /// S = B^-1 for a symmetric 3 x 3 block B (row-major; its upper triangle is read), by the
  /// adjugate: B^-1 = adj(B) / det B. False where B is not positive definite by Sylvester's
  /// criterion (its leading minors B00, B00 B11 - B01^2 and det B not all positive and finite).
  static bool invert_spd3(const Scalar* B, Scalar* S) {
    const Scalar a = B[0], b = B[1], c = B[2], d = B[4], e = B[5], f = B[8];
    const Scalar c00 = d * f - e * e, c01 = c * e - b * f, c02 = b * e - c * d;  // cofactors
    const Scalar det = a * c00 + b * c01 + c * c02;
    if (!(a > 0) || !(a * d - b * b > 0) || !(det > 0) || !std::isfinite(det)) return false;
    const Scalar s = 1 / det;
    S[0] = s * c00, S[1] = S[3] = s * c01, S[2] = S[6] = s * c02;
    S[4] = s * (a * f - c * c), S[5] = S[7] = s * (b * c - a * e), S[8] = s * (a * d - b * b);
    return true;
  }

  /// The inverses of A's 3 x 3 diagonal blocks (CgPreconditioner::BlockJacobi), each a node's,
  /// in chunks on the solver's threads; throws SolverError naming the first block row whose block
  /// is not positive definite (then neither is A).
  void factorise_node_blocks(const BlockSymmetricMatrix& A) {
    const BlockPattern& p = A.pattern();
    const Index rows = p.num_block_rows;
    node_inverse_.resize(9 * static_cast<size_t>(rows));
    bad_row_.assign(static_cast<size_t>(num_vector_chunks(3 * rows)), -1);
    for_each_vector_chunk(3 * rows, threads_, [&](Index c, Index i0, Index i1) {
      for (Index I = i0 / 3; I < i1 / 3; ++I) {
        const Scalar* B = A.values() + 9 * static_cast<size_t>(p.row_start[I + 1] - 1);  // the diagonal block: last
        if (!invert_spd3(B, node_inverse_.data() + 9 * static_cast<size_t>(I))) {
          bad_row_[static_cast<size_t>(c)] = I;
          return;
        }
      }
    });
    for (Index I : bad_row_)
      if (I >= 0) fail<SolverError>("CG: the diagonal block of block row {} is not positive definite (indefinite system)", I);
  }
  /// The inverses of the groups' diagonal blocks of A (set_coupled_rows).
  void factorise_groups(const BlockSymmetricMatrix& A) {
    const BlockPattern& p = A.pattern();
    for (size_t g = 0; g < groups_.size(); ++g) {
      const auto& rows = groups_[g];
      const int k = 3 * static_cast<int>(rows.size());
      group_valid_[g] = 0;
      if (k > max_group_dofs) continue;
      Scalar* S = group_inverse_.data() + group_offset_[g];  // k x k, column-major
      for (size_t a = 0; a < rows.size(); ++a)
        for (size_t c = 0; c < rows.size(); ++c) {
          const bool lower = rows[a] >= rows[c];
          const int blk = lower ? p.block(rows[a], rows[c]) : p.block(rows[c], rows[a]);
          for (int i = 0; i < 3; ++i)
            for (int j = 0; j < 3; ++j)
              S[static_cast<int>(3 * a) + i + k * (static_cast<int>(3 * c) + j)] =
                  blk < 0 ? 0.0 : A.values()[9 * static_cast<size_t>(blk) + (lower ? 3 * i + j : 3 * j + i)];
        }
      group_valid_[g] = invert_spd(S, k);
    }
  }
  /// z = P r on the groups' rows (the Jacobi or node-block z is there already); returns the
  /// change of r.z.
  Scalar apply_groups(const Vector& r, Vector& z) const {
    Scalar change = 0;
    for (size_t g = 0; g < groups_.size(); ++g) {
      if (!group_valid_[g]) continue;
      const auto& rows = groups_[g];
      const int k = 3 * static_cast<int>(rows.size());
      const Scalar* inverse = group_inverse_.data() + group_offset_[g];  // k x k, symmetric
      Scalar rg[max_group_dofs];
      for (size_t a = 0; a < rows.size(); ++a)
        for (int i = 0; i < 3; ++i) rg[3 * a + i] = r[3 * rows[a] + i];
      for (int i = 0; i < k; ++i) {
        Scalar zi = 0;  // row i of the inverse is its column i
        for (int j = 0; j < k; ++j) zi += inverse[j + k * i] * rg[j];
        Scalar& zr = z[3 * rows[static_cast<size_t>(i / 3)] + i % 3];
        change += rg[i] * (zi - zr);
        zr = zi;
      }
    }
    return change;
  }

  LinearSolverSettings settings_;
  using LDLT = Eigen::SimplicialLDLT<SparseMatrix, Eigen::Lower, Eigen::AMDOrdering<int>>;
  std::unique_ptr<LDLT> ldlt_;  // created on first use (held by pointer: the solver stays movable)
#ifdef PLASTIFEM_HAS_CHOLMOD
  std::unique_ptr<detail::CholmodLLT> cholmod_;  // created on first use (its cholmod_common)
#endif
  SparseMatrix csc_;
  bool analysed_ = false, factorised_ = false;
  int threads_ = 1;
  Vector r_, z_, p_, q_, inv_diag_;
  std::vector<Index> bad_row_;  ///< factorise_node_blocks' first failed row per chunk
  std::vector<Scalar> partial_;  ///< the chunks' sums of the CG vector passes (core/vector_ops.hpp)
  std::vector<Scalar> node_inverse_;  ///< factorise_node_blocks, 9 per block row
  std::vector<std::vector<Index>> groups_;  ///< set_coupled_rows
  std::vector<Index> group_offset_;
  std::vector<Scalar> group_inverse_;
  std::vector<char> group_valid_;
};

template <class Unused>
LinearSolveReport BasicLinearSolver<Unused>::solve_direct(const BlockSymmetricMatrix& block, const Vector& b, Vector& x,
                                                          bool same_matrix) {
  const bool cholmod = resolve_direct_solver(settings_.direct) == DirectSolver::CholmodSupernodal;
  LinearSolveReport r;
  r.iterations = 0;  // reused factorisation: one pair of triangular solves
  if (!(same_matrix && factorised_)) {
    block.copy_to(csc_);  // both read a CSC matrix (its lower triangle)
    factorised_ = false;
    if (cholmod) factorise_cholmod();
    else factorise_ldlt();
    factorised_ = true;
    r.iterations = 1;
  }
#ifdef PLASTIFEM_HAS_CHOLMOD
  if (cholmod) {
    const detail::SerialOpenMPScope serial;
    x = cholmod_->solve(b);
    return r;
  }
#endif
  x = ldlt_->solve(b);
  return r;
}

template <class Unused>
void BasicLinearSolver<Unused>::factorise_ldlt() {
  if (!ldlt_) ldlt_ = std::make_unique<LDLT>();
  if (!analysed_) {
    ldlt_->analyzePattern(csc_);
    analysed_ = true;
  }
  ldlt_->factorize(csc_);
  const auto D = ldlt_->vectorD();
  const Scalar dmax = D.cwiseAbs().maxCoeff();
  if (ldlt_->info() != Eigen::Success || !(D.minCoeff() > 1e-12 * dmax)) singular(D.minCoeff(), dmax, "LDLT pivot");
}

template <class Unused>
void BasicLinearSolver<Unused>::factorise_cholmod() {
#ifdef PLASTIFEM_HAS_CHOLMOD
  if (!cholmod_) cholmod_ = std::make_unique<detail::CholmodLLT>();
  const detail::SerialOpenMPScope serial;
  if (!analysed_) {
    cholmod_->analyzePattern(csc_);
    analysed_ = true;
  }
  cholmod_->factorize(csc_);
  // LL^T fails at the first non-positive pivot; a positive but tiny one is caught by the
  // pivot ratio. For an LL^T factor cholmod_rcond returns (min diag(L) / max diag(L))^2,
  // already LDLT's min D / max D (D = diag(L)^2): the same 1e-12 bound applies to it as it is.
  if (cholmod_->info() != Eigen::Success) singular(-1, 1, "CHOLMOD pivot ratio (not positive definite)");
  const Scalar pivot_ratio = cholmod_->rcond();
  if (!(pivot_ratio > 1e-12)) singular(pivot_ratio, 1, "CHOLMOD pivot ratio");
#endif
}

template <class Unused>
LinearSolveReport BasicLinearSolver<Unused>::solve_cg(const BlockSymmetricMatrix& A, const Vector& b, Vector& x,
                                                      Scalar tolerance) {
  const Index n = static_cast<Index>(b.size());
  if (r_.size() != n) {
    r_.resize(n), z_.resize(n), p_.resize(n), q_.resize(n), inv_diag_.resize(n);
    partial_.resize(2 * static_cast<size_t>(num_vector_chunks(n)));
  }
  A.diagonal_into(inv_diag_);
  for (Index i = 0; i < n; ++i) {
    if (!(inv_diag_[i] > 0))
      fail<SolverError>("CG needs a positive diagonal; entry {} is {} (singular or indefinite system)", i,
                        inv_diag_[i]);
    inv_diag_[i] = 1 / inv_diag_[i];
  }
  const bool node_blocks = settings_.preconditioner == CgPreconditioner::BlockJacobi;
  if (node_blocks) factorise_node_blocks(A);
  if (!groups_.empty()) factorise_groups(A);
  LinearSolveReport rep;
  // Reductions through core/vector_ops.hpp: independent of zeros appended to the vectors.
  const Scalar bnorm = norm(b);
  if (bnorm == 0) {
    x.setZero();
    return rep;
  }
  A.multiply(x, q_, threads_);
  r_ = b - q_;
  if (node_blocks) apply_node_blocks(node_inverse_.data(), r_.data(), z_.data(), n, threads_);
  else z_ = inv_diag_.cwiseProduct(r_);
  if (!groups_.empty()) apply_groups(r_, z_);
  p_ = z_;
  Scalar rz = dot(r_, z_);
  const Scalar target = tolerance * bnorm;
  Scalar rnorm = norm(r_);
  int k = 0;
  while (rnorm > target && k < settings_.max_iterations) {
    A.multiply(p_, q_, threads_);
    const Scalar pq = dot(p_.data(), q_.data(), n, threads_, partial_.data());
    if (!(pq > 0)) fail<SolverError>("CG breakdown (p.Ap = {:.3g}): the system is not positive definite", pq);
    const Scalar alpha = rz / pq;
    Scalar rz_new, rr;
    if (node_blocks)
      cg_update_node_blocks(alpha, p_.data(), q_.data(), node_inverse_.data(), x.data(), r_.data(), z_.data(), n,
                            rz_new, rr, threads_, partial_.data());
    else
      cg_update(alpha, p_.data(), q_.data(), inv_diag_.data(), x.data(), r_.data(), z_.data(), n, rz_new, rr,
                threads_, partial_.data());
    if (!groups_.empty()) rz_new += apply_groups(r_, z_);
    update_direction(z_.data(), rz_new / rz, p_.data(), n, threads_);
    rz = rz_new;
    rnorm = std::sqrt(rr);
    ++k;
  }
  rep.iterations = k;
  if (settings_.verify_residual) {
    // The recursively updated r drifts from b - A x on ill-conditioned systems (a body held
    // by one node): a "converged" CG then returned x ~ 1e6. One more product tells the truth.
    A.multiply(x, q_, threads_);
    r_ = b - q_;
    rnorm = norm(r_);
  }
  rep.relative_residual = rnorm / bnorm;
  rep.converged = rnorm <= target;
  if (!x.allFinite()) fail<SolverError>("CG produced a non-finite solution (singular or indefinite system)");
  return rep;
}

using LinearSolver = BasicLinearSolver<>;

#ifdef PLASTIFEM_USE_COMPILED
extern template class BasicLinearSolver<void>;
#endif

}  // namespace plastifem
