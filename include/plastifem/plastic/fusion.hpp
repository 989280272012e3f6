#pragma once
// Fusion of the elements' plastic rest shapes into one material mesh (seed 000, after eq. 9:
// "the material space vertex x_j ... is updated x_j <- sum_k Pi^k_q y^k_q / n_j ... This fuses
// the vertices y^k_i of the elements to form a consistent material").
//
// Each element k proposes new rest positions z^k for its nodes (plastic/flow.hpp), defined up
// to a translation (they are computed about the element's centre). The fused mesh is the
// vertex average of the proposals with every element placed where it fits best:
//     min over x and t^k of  sum_k sum_a |x_j(k,a) - t^k - z^k_a|^2,
// whose optimality conditions are exactly "x_j = the average over the elements sharing j of
// t^k + z^k_a" and "t^k = the translation that best fits element k to x". Eliminating t^k,
// with P = I - 1 1^T / N (centring an element's N nodes):
//     L x = sum_k A_k^T P z^k,   L = sum_k A_k^T P A_k   (A_k: element k's nodes),
// an element-centring Laplacian that depends on the mesh only (one scalar row per node; the three
// coordinates share it): assembled and factorised once (sparse LDL^T: no BLAS, whose threads
// spin between the small solves of consecutive steps), then one solve per plastic update, for
// the change dx = x_new - x of the mesh:
//     L dx = sum_k A_k^T P (z^k - X^k)      (X^k: element k's current rest nodes).
// L's null space is the translations of each connected piece of the mesh; one node per piece
// is held (dx = 0 there) for the solve, and then each piece is moved so that the mean dx of
// its anchored nodes (those the solver holds in the world: a clamp) is zero, or of all its
// nodes if none is: the material mesh stays where the body is held, and a symmetric flow
// stays symmetric. Frozen nodes (those of elements a cut enriched, which stop flowing) are the
// held nodes of their piece: with the move above (anchored mean) they only translate, so their
// elements keep their rest shapes, and a piece cut free is at most translated, never distorted,
// by flow on the other side of the cut (the two meet only at those nodes). (Two separate frozen
// bands in one piece keep their distance: flow between two cuts does not move them apart.)
//
// Why not the plain one-pass average of the paper's formula, with each element left where it
// was: a uniform plastic stretch of a bar then moves only its end nodes (every interior node
// is the mean of one element's stretched right end and its neighbour's left end, which cancel);
// the fixed point above reproduces any compatible field (a uniform stretch, a rigid rotation of
// every element alike) exactly.
#include <plastifem/assembly/block_matrix.hpp>
#include <plastifem/mesh/mesh.hpp>

#include <Eigen/SparseCholesky>
#include <memory>
#include <numeric>
#include <vector>

namespace plastifem::plastic {

template <FiniteElement E>
class MaterialFusion {
 public:
  static constexpr int N = E::num_nodes;

  /// L for `mesh` (one scalar row per node: the three coordinates solve with the same matrix),
  /// its held nodes, and its factorisation. `frozen` (per node, may be empty): nodes held at
  /// their rest positions (see the file comment).
  void build(const Mesh<E>& mesh, const std::vector<char>& frozen = {}) {
    const Index n = mesh.num_nodes();
    // One held node per connected piece (its smallest), and every node no element uses.
    std::vector<Index> parent(n);
    std::iota(parent.begin(), parent.end(), 0);
    auto find = [&](Index i) {
      while (parent[i] != i) i = parent[i] = parent[parent[i]];
      return i;
    };
    std::vector<char> used(n, 0);
    for (Index e = 0; e < mesh.num_elements(); ++e) {
      const auto& c = mesh.element(e);
      for (int a = 0; a < N; ++a) {
        used[c[a]] = 1;
        const Index r0 = find(c[0]), ra = find(c[a]);
        if (r0 != ra) parent[std::max(r0, ra)] = std::min(r0, ra);
      }
    }
    piece_.assign(n, -1);
    piece_size_.clear();
    pinned_.clear();
    held_.assign(n, 0);
    const bool any_frozen = static_cast<Index>(frozen.size()) == n;
    for (Index i = 0; i < n; ++i) {
      if (!used[i]) {
        held_[i] = 1;
        continue;
      }
      const Index root = find(i);
      if (piece_[root] < 0)
        piece_[root] = static_cast<Index>(piece_size_.size()), piece_size_.push_back(0), pinned_.push_back(0);
      piece_[i] = piece_[root];
      ++piece_size_[piece_[i]];
      if (any_frozen && frozen[i]) held_[i] = 1, pinned_[piece_[i]] = 1;
    }
    for (Index i = 0; i < n; ++i)  // one held node in each piece without a frozen one
      if (used[i] && find(i) == i && !pinned_[piece_[i]]) held_[i] = 1;
    piece_mean_.assign(piece_size_.size(), Vec3::Zero());
    // L = sum_k A_k^T P A_k, P = I - 1 1^T / N, lower triangle; held rows and columns identity.
    std::vector<Eigen::Triplet<Scalar, int>> t;
    t.reserve(static_cast<size_t>(mesh.num_elements()) * N * (N + 1) / 2 + n);
    for (Index e = 0; e < mesh.num_elements(); ++e) {
      const auto& c = mesh.element(e);
      for (int a = 0; a < N; ++a)
        for (int b = 0; b < N; ++b) {
          const Index i = c[a], j = c[b];
          if (i < j || held_[i] || held_[j]) continue;
          t.emplace_back(i, j, (a == b ? 1.0 : 0.0) - 1.0 / N);
        }
    }
    for (Index i = 0; i < n; ++i)
      if (held_[i]) t.emplace_back(i, i, 1.0);
    SparseMatrix L(n, n);
    L.setFromTriplets(t.begin(), t.end());
    ldlt_ = std::make_unique<LDLT>();
    ldlt_->compute(L);
    if (ldlt_->info() != Eigen::Success)
      fail<SolverError>("material mesh fusion: the element-centring Laplacian could not be factorised");
    rhs_.setZero(n, 3);
    dx_.setZero(n, 3);
    y_.setZero(n, 3);
  }

  /// rest += dx with L dx = sum over `changed` elements of A_k^T P (z^k - X^k); z holds each
  /// element's proposal (column block k), X^k is read from `rest`. `anchor` (per node, may be
  /// empty): the nodes whose mean change is made zero.
  void fuse(const Mesh<E>& mesh, const std::vector<ElementNodes<E>>& z, const std::vector<char>& changed,
            Vector& rest, const std::vector<char>& anchor = {}) {
    const Index n = mesh.num_nodes();
    rhs_.setZero();
    for (Index e = 0; e < mesh.num_elements(); ++e) {
      if (!changed[e]) continue;
      const auto& c = mesh.element(e);
      ElementNodes<E> d;
      for (int a = 0; a < N; ++a) d.col(a) = z[e].col(a) - rest.template segment<3>(3 * c[a]);
      const Vec3 mean = d.rowwise().mean();
      for (int a = 0; a < N; ++a) rhs_.row(c[a]) += (d.col(a) - mean).transpose();
    }
    for (Index i = 0; i < n; ++i)
      if (held_[i]) rhs_.row(i).setZero();
    solve();
    // Each piece's mean change over its anchored nodes, or all its nodes, to zero (see the file
    // comment).
    for (Vec3& m : piece_mean_) m.setZero();
    piece_count_.assign(piece_size_.size(), 0);
    const bool anchored = static_cast<Index>(anchor.size()) == n;
    for (Index i = 0; i < n; ++i)
      if (piece_[i] >= 0 && anchored && anchor[i]) piece_mean_[piece_[i]] += dx_.row(i).transpose(), ++piece_count_[piece_[i]];
    for (Index i = 0; i < n; ++i)
      if (piece_[i] >= 0 && piece_count_[piece_[i]] == 0) piece_mean_[piece_[i]] += dx_.row(i).transpose();
    for (size_t k = 0; k < piece_mean_.size(); ++k)
      piece_mean_[k] /= static_cast<Scalar>(piece_count_[k] > 0 ? piece_count_[k] : piece_size_[k]);
    for (Index i = 0; i < n; ++i)
      if (piece_[i] >= 0) rest.template segment<3>(3 * i) += dx_.row(i).transpose() - piece_mean_[piece_[i]];
  }

 private:
  /// dx_ = L^-1 rhs_ = P^T L_f^-T D^-1 L_f^-1 P rhs_ with the factorisation P L P^T = L_f D L_f^T,
  /// the three coordinates together in one sweep over the factor per triangle. (Eigen's solve
  /// takes the columns one at a time: three passes over a factor that outgrows the cache,
  /// measured a ninth of a flowing step at bar5760.)
  void solve() {
    const auto& perm = ldlt_->permutationP().indices();
    const SparseMatrix& Lf = ldlt_->matrixL().nestedExpression();  // unit lower: entries below the diagonal
    const auto& D = ldlt_->vectorD();
    const Index n = rhs_.rows();
    for (Index i = 0; i < n; ++i) y_.row(perm(i)) = rhs_.row(i);
    for (Index j = 0; j < n; ++j) {
      const Eigen::Matrix<Scalar, 1, 3> yj = y_.row(j);
      for (SparseMatrix::InnerIterator it(Lf, j); it; ++it)
        if (it.index() > j) y_.row(it.index()) -= it.value() * yj;
    }
    for (Index j = 0; j < n; ++j) y_.row(j) /= D(j);
    for (Index j = n - 1; j >= 0; --j) {
      Eigen::Matrix<Scalar, 1, 3> yj = y_.row(j);
      for (SparseMatrix::InnerIterator it(Lf, j); it; ++it)
        if (it.index() > j) yj -= it.value() * y_.row(it.index());
      y_.row(j) = yj;
    }
    for (Index i = 0; i < n; ++i) dx_.row(i) = y_.row(perm(i));
  }

  // The linear solver's LDLT type (solver/linear_solver.hpp): compiled once with it.
  using LDLT = Eigen::SimplicialLDLT<SparseMatrix, Eigen::Lower, Eigen::AMDOrdering<int>>;
  std::unique_ptr<LDLT> ldlt_;
  Eigen::Matrix<Scalar, Eigen::Dynamic, 3, Eigen::RowMajor> rhs_, dx_, y_;
  std::vector<char> held_;          ///< one node per piece without frozen nodes, frozen nodes, unused nodes
  std::vector<char> pinned_;        ///< per piece: it holds frozen nodes (no other held node needed)
  std::vector<Index> piece_;        ///< connected piece of each node (-1: used by no element)
  std::vector<Index> piece_size_;   ///< nodes per piece
  std::vector<Vec3> piece_mean_;    ///< scratch
  std::vector<Index> piece_count_;  ///< scratch
};

}  // namespace plastifem::plastic
