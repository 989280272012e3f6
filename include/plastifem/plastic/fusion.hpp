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
// an element-centring Laplacian that depends on the mesh only: assembled and factorised once,
// then one solve per plastic update, for the change dx = x_new - x of the mesh:
//     L dx = sum_k A_k^T P (z^k - X^k)      (X^k: element k's current rest nodes).
// L's null space is the translations of each connected piece of the mesh; one node per piece
// is held (dx = 0 there) for the solve, and then each piece is moved so that the mean dx of
// its anchored nodes (those the solver holds in the world: a clamp) is zero, or of all its
// nodes if none is: the material mesh stays where the body is held, and a symmetric flow
// stays symmetric.
//
// Why not the plain one-pass average of the paper's formula, with each element left where it
// was: a uniform plastic stretch of a bar then moves only its end nodes (every interior node
// is the mean of one element's stretched right end and its neighbour's left end, which cancel);
// the fixed point above reproduces any compatible field (a uniform stretch, a rigid rotation of
// every element alike) exactly.
#include <plastifem/assembly/assembler.hpp>
#include <plastifem/solver/linear_solver.hpp>

#include <numeric>
#include <vector>

namespace plastifem::plastic {

template <FiniteElement E>
class MaterialFusion {
 public:
  static constexpr int N = E::num_nodes;

  /// L for `mesh` on the assembler's pattern, its held nodes, and its factorisation (on the
  /// first solve).
  void build(const Mesh<E>& mesh, const Assembler<E>& assembler) {
    L_ = assembler.zero_matrix();
    ElementMatrix<E> Ke = ElementMatrix<E>::Zero();
    for (int a = 0; a < N; ++a)
      for (int b = 0; b < N; ++b)
        Ke.template block<3, 3>(3 * a, 3 * b) = ((a == b ? 1.0 : 0.0) - 1.0 / N) * Mat3::Identity();
    Scalar* values = L_.values();
    for (Index e = 0; e < mesh.num_elements(); ++e) assembler.add_element_matrix(e, Ke, values);
    // One held node per connected piece (its smallest), and every node no element uses.
    const Index n = mesh.num_nodes();
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
    for (Index i = 0; i < n; ++i) {
      if (!used[i]) continue;
      const Index root = find(i);
      if (piece_[root] < 0) piece_[root] = static_cast<Index>(piece_size_.size()), piece_size_.push_back(0);
      piece_[i] = piece_[root];
      ++piece_size_[piece_[i]];
    }
    piece_mean_.assign(piece_size_.size(), Vec3::Zero());
    const Index rows = L_.rows() / 3;
    std::vector<char> held(static_cast<size_t>(rows) * 3, 0);
    for (Index i = 0; i < n; ++i)
      if (!used[i] || find(i) == i) held[3 * i] = held[3 * i + 1] = held[3 * i + 2] = 1;
    for (Index r = n; r < rows; ++r) held[3 * r] = held[3 * r + 1] = held[3 * r + 2] = 1;
    blocks_ = ConstrainedBlocks(L_.pattern(), held);
    blocks_.apply(L_);
    solver_.set_settings({LinearSolverKind::Direct});
    factorised_ = false;
    rhs_.setZero(L_.rows());
    dx_.setZero(rhs_.size());
  }

  /// rest += dx with L dx = sum over `changed` elements of A_k^T P (z^k - X^k); z holds each
  /// element's proposal (column block k), X^k is read from `rest`. `anchor` (per node, may be
  /// empty): the nodes whose mean change is made zero.
  void fuse(const Mesh<E>& mesh, const std::vector<ElementNodes<E>>& z, const std::vector<char>& changed,
            Vector& rest, const std::vector<char>& anchor = {}) {
    rhs_.setZero();
    for (Index e = 0; e < mesh.num_elements(); ++e) {
      if (!changed[e]) continue;
      const auto& c = mesh.element(e);
      ElementNodes<E> d;
      for (int a = 0; a < N; ++a) d.col(a) = z[e].col(a) - rest.template segment<3>(3 * c[a]);
      const Vec3 mean = d.rowwise().mean();
      for (int a = 0; a < N; ++a) rhs_.template segment<3>(3 * c[a]) += d.col(a) - mean;
    }
    blocks_.zero(rhs_);
    dx_.setZero();
    solver_.solve(L_, rhs_, dx_, 0, factorised_);
    factorised_ = true;
    // Each piece's mean change over its anchored nodes, or all its nodes, to zero (see the file
    // comment).
    const Index n = mesh.num_nodes();
    for (Vec3& m : piece_mean_) m.setZero();
    piece_count_.assign(piece_size_.size(), 0);
    const bool anchored = static_cast<Index>(anchor.size()) == n;
    for (Index i = 0; i < n; ++i)
      if (piece_[i] >= 0 && anchored && anchor[i])
        piece_mean_[piece_[i]] += dx_.template segment<3>(3 * i), ++piece_count_[piece_[i]];
    for (Index i = 0; i < n; ++i)
      if (piece_[i] >= 0 && piece_count_[piece_[i]] == 0) piece_mean_[piece_[i]] += dx_.template segment<3>(3 * i);
    for (size_t k = 0; k < piece_mean_.size(); ++k)
      piece_mean_[k] /= static_cast<Scalar>(piece_count_[k] > 0 ? piece_count_[k] : piece_size_[k]);
    for (Index i = 0; i < n; ++i)
      if (piece_[i] >= 0) rest.template segment<3>(3 * i) += dx_.template segment<3>(3 * i) - piece_mean_[piece_[i]];
  }

 private:
  BlockSymmetricMatrix L_;
  ConstrainedBlocks blocks_;
  LinearSolver solver_;
  bool factorised_ = false;
  Vector rhs_, dx_;
  std::vector<Index> piece_;        ///< connected piece of each node (-1: used by no element)
  std::vector<Index> piece_size_;   ///< nodes per piece
  std::vector<Vec3> piece_mean_;    ///< scratch
  std::vector<Index> piece_count_;  ///< scratch
};

}  // namespace plastifem::plastic
