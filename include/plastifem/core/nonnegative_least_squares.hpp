#pragma once
// Non-negative least squares, min |A x - b|_2 subject to x >= 0, by the active-set method of
// Lawson and Hanson ("Solving Least Squares Problems", 1974, ch. 23, algorithm NNLS).
//
// Used to compress a quadrature rule (enrichment/subdivision.hpp): A holds m basis polynomials at
// n > m points, b their moments. The solution it returns is a basic one: at most rank(A) non-zero
// entries, which is what makes the compressed rule short.
#include <plastifem/core/types.hpp>

#include <Eigen/Dense>

#include <algorithm>
#include <vector>

namespace plastifem {

namespace detail {

/// The QR factorisation A_P = Q R of the passive columns, updated as columns enter (Gram-Schmidt
/// with reorthogonalisation) and leave (Givens rotations restore R's triangle), with Q^T b kept
/// alongside: each least-squares solve is then a back substitution.
class PassiveQR {
 public:
  static constexpr int max_columns = 64;
  PassiveQR(Index m, const Eigen::VectorXd& b) : b_(b), Q_(m, max_columns), qtb_(max_columns) {}

  Index size() const { return p_; }
  /// Appends column a; false (nothing changed) if it is, to round-off, a combination of the
  /// others, or if there are 64 already.
  template <class Column>
  bool add_column(const Column& a) {
    if (p_ == max_columns) return false;
    Eigen::VectorXd v = a;
    R_.col(p_).head(p_).setZero();
    for (int pass = 0; pass < 2; ++pass) {  // twice is enough (Giraud et al. 2005)
      const Eigen::VectorXd h = Q_.leftCols(p_).transpose() * v;
      v.noalias() -= Q_.leftCols(p_) * h;
      R_.col(p_).head(p_) += h;
    }
    const Scalar rho = v.norm();
    if (!(rho > 1e-12 * a.norm())) return false;
    Q_.col(p_) = v / rho;
    R_(p_, p_) = rho;
    qtb_[p_] = Q_.col(p_).dot(b_);
    ++p_;
    return true;
  }
  /// Removes column k: the columns after it move left and Givens rotations zero the subdiagonal
  /// this leaves in R (applied to Q's columns and Q^T b too).
  void remove(Index k) {
    for (Index c = k; c + 1 < p_; ++c) R_.col(c).head(p_) = R_.col(c + 1).head(p_);
    for (Index i = k; i + 1 < p_; ++i) {
      Eigen::JacobiRotation<Scalar> G;
      G.makeGivens(R_(i, i), R_(i + 1, i));
      R_.block(i, i, 2, p_ - 1 - i).applyOnTheLeft(0, 1, G.adjoint());
      R_(i + 1, i) = 0;
      Q_.applyOnTheRight(i, i + 1, G);
      Eigen::Matrix<Scalar, 2, 1> t(qtb_[i], qtb_[i + 1]);
      t.applyOnTheLeft(0, 1, G.adjoint());
      qtb_[i] = t[0], qtb_[i + 1] = t[1];
    }
    --p_;
  }
  /// The least-squares solution on the passive columns.
  Eigen::VectorXd solve() const {
    return R_.topLeftCorner(p_, p_).triangularView<Eigen::Upper>().solve(qtb_.head(p_));
  }
  /// b - A_P z for the least-squares z: b minus its projection Q Q^T b.
  Eigen::VectorXd residual() const { return b_ - Q_.leftCols(p_) * qtb_.head(p_); }

 private:
  const Eigen::VectorXd& b_;
  Eigen::MatrixXd Q_;
  Eigen::Matrix<Scalar, max_columns, max_columns> R_ = Eigen::Matrix<Scalar, max_columns, max_columns>::Zero();
  Eigen::VectorXd qtb_;
  Index p_ = 0;
};

}  // namespace detail

/// x >= 0 minimising |A x - b|; stops when no free column's gradient entry (A^T (b - A x))_j
/// exceeds `tolerance`, after 3 n additions, or with 64 columns passive.
inline Eigen::VectorXd nonnegative_least_squares(const Eigen::MatrixXd& A, const Eigen::VectorXd& b,
                                                 Scalar tolerance) {
  const Index n = A.cols();
  // The gradient A^T r is the loop's main cost: as a product with A^T stored column-major it is
  // m axpys of length n (SIMD along the candidates) instead of n short dot products.
  const Eigen::MatrixXd At = A.transpose();
  Eigen::VectorXd x = Eigen::VectorXd::Zero(n), w(n), r = b, z;
  std::vector<char> passive(n, 0), blocked(n, 0);  // blocked: its addition was just undone
  std::vector<Index> P;                            // the passive set, in the QR's column order
  detail::PassiveQR qr(A.rows(), b);
  for (Index additions = 0; additions < 3 * n; ++additions) {
    w.noalias() = At * r;
    // The column of largest gradient; of near-equal ones (within 1e-9 times the largest) the
    // first, so that round-off in A or b does not decide between them. Any column of positive
    // gradient keeps Lawson and Hanson's descent: the largest is a heuristic, not a condition.
    Scalar top = tolerance;
    for (Index k = 0; k < n; ++k)
      if (!passive[k] && !blocked[k]) top = std::max(top, w[k]);
    Index j = -1;
    for (Index k = 0; k < n && j < 0; ++k)
      if (!passive[k] && !blocked[k] && w[k] > tolerance && w[k] >= top - 1e-9 * top) j = k;
    if (j < 0) break;
    if (!qr.add_column(A.col(j))) {  // dependent on the passive columns (or 64 of them)
      blocked[j] = 1;
      continue;
    }
    passive[j] = 1;
    P.push_back(j);
    z = qr.solve();
    if (z[z.size() - 1] <= 0) {  // the new column cannot enter (round-off): undo
      qr.remove(qr.size() - 1);
      P.pop_back();
      passive[j] = 0, blocked[j] = 1;
      continue;
    }
    for (;;) {
      if ((z.array() > 0).all()) {
        for (size_t c = 0; c < P.size(); ++c) x[P[c]] = z[c];
        r = qr.residual();
        std::fill(blocked.begin(), blocked.end(), 0);
        break;
      }
      // Step from x toward z until the first passive entry reaches 0; those leave the set.
      Scalar alpha = 1;
      Index limiting = -1;
      for (size_t c = 0; c < P.size(); ++c)
        if (z[c] <= 0 && x[P[c]] - z[c] > 0 && x[P[c]] / (x[P[c]] - z[c]) < alpha)
          alpha = x[P[c]] / (x[P[c]] - z[c]), limiting = static_cast<Index>(c);
      for (size_t c = 0; c < P.size(); ++c) x[P[c]] += alpha * (z[c] - x[P[c]]);
      if (limiting >= 0) x[P[limiting]] = 0;  // exactly, not a round-off remainder
      for (Index c = static_cast<Index>(P.size()) - 1; c >= 0; --c)
        if (!(x[P[c]] > 0)) {
          x[P[c]] = 0, passive[P[c]] = 0;
          qr.remove(c);
          P.erase(P.begin() + c);
        }
      if (P.empty()) {
        r = b;
        break;
      }
      z = qr.solve();
    }
  }
  return x;
}

}  // namespace plastifem
