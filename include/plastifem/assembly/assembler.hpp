#pragma once
// Sparse pattern computed once, and race-free deterministic assembly into it.
//
// Dofs: 3 per node, dof = 3 node + d (enriched dofs will be appended after these).
// The system matrix is a column-major Eigen::SparseMatrix whose structure is the node graph
// expanded to 3x3 blocks. For every element we precompute where each of its 3x3 blocks starts
// in the value array, so a re-assembly writes straight into memory: no search, no allocation.
//
// Threads: elements are greedily coloured so that no two elements of one colour share a node;
// colours run one after the other, the elements of a colour in parallel. Each matrix entry then
// receives its contributions in the same order whatever the thread count, so results are
// bit-identical from 1 to N threads, with no atomics and no critical sections.
#include <plastifem/core/error.hpp>
#include <plastifem/mesh/mesh.hpp>

#include <Eigen/SparseCore>
#include <algorithm>
#include <bit>
#include <cstdint>
#include <vector>

#ifdef _OPENMP
#include <omp.h>
#endif

namespace plastifem {

using SparseMatrix = Eigen::SparseMatrix<Scalar, Eigen::ColMajor, int>;
using Vector = Eigen::Matrix<Scalar, Eigen::Dynamic, 1>;

/// Number of threads element loops use (OpenMP's setting; 1 without OpenMP).
inline int max_threads() {
#ifdef _OPENMP
  return omp_get_max_threads();
#else
  return 1;
#endif
}

template <FiniteElement E>
class Assembler {
 public:
  static constexpr int N = E::num_nodes;

  Assembler() = default;
  explicit Assembler(const Mesh<E>& mesh) : num_nodes_(mesh.num_nodes()) {
    build_pattern(mesh);
    build_colours(mesh);
  }

  Index num_dofs() const { return 3 * num_nodes_; }
  /// A matrix with the system's structure and all values zero.
  const SparseMatrix& pattern() const { return pattern_; }
  const std::vector<std::vector<Index>>& colours() const { return colours_; }

  /// Runs body(e) for every element, colour by colour, in parallel within a colour.
  template <class Body>
  void for_each_element(Body&& body, int threads = 0) const {
    for (const auto& colour : colours_) {
      const Index n = static_cast<Index>(colour.size());
#ifdef _OPENMP
      const int t = threads > 0 ? threads : omp_get_max_threads();
#pragma omp parallel for schedule(static) num_threads(t) if (t > 1 && n > 64)
#else
      (void)threads;
#endif
      for (Index i = 0; i < n; ++i) body(colour[i]);
    }
  }

  /// values += the 3N x 3N element matrix Ke of element e (dense, dof 3a + d).
  template <class Matrix>
  void add_element_matrix(Index e, const Matrix& Ke, Scalar* values) const {
    const int* base = &block_base_[static_cast<size_t>(e) * N * N];
    const int* len = &column_length_[static_cast<size_t>(e) * N];
    for (int b = 0; b < N; ++b)
      for (int q = 0; q < 3; ++q) {
        const int col_offset = q * len[b];
        for (int a = 0; a < N; ++a) {
          Scalar* v = values + base[b * N + a] + col_offset;
          v[0] += Ke(3 * a + 0, 3 * b + q);
          v[1] += Ke(3 * a + 1, 3 * b + q);
          v[2] += Ke(3 * a + 2, 3 * b + q);
        }
      }
  }

  /// values += m_ab I3 for the N x N scalar element matrix m (mass-like).
  template <class Matrix>
  void add_element_scalar_matrix(Index e, const Matrix& m, Scalar* values) const {
    const int* base = &block_base_[static_cast<size_t>(e) * N * N];
    const int* len = &column_length_[static_cast<size_t>(e) * N];
    for (int b = 0; b < N; ++b)
      for (int a = 0; a < N; ++a)
        for (int q = 0; q < 3; ++q) values[base[b * N + a] + q * len[b] + q] += m(a, b);
  }

  /// Position in the value array of entry (row, col), or -1 if outside the pattern.
  int position(Index row, Index col) const {
    const int* begin = pattern_.innerIndexPtr() + pattern_.outerIndexPtr()[col];
    const int* end = pattern_.innerIndexPtr() + pattern_.outerIndexPtr()[col + 1];
    const int* it = std::lower_bound(begin, end, row);
    return (it != end && *it == row) ? static_cast<int>(it - pattern_.innerIndexPtr()) : -1;
  }

 private:
  void build_pattern(const Mesh<E>& mesh) {
    // Node adjacency (including self), sorted.
    std::vector<std::vector<Index>> adj(num_nodes_);
    for (const auto& c : mesh.elements())
      for (Index i : c) adj[i].insert(adj[i].end(), c.begin(), c.end());
    for (auto& a : adj) {
      std::sort(a.begin(), a.end());
      a.erase(std::unique(a.begin(), a.end()), a.end());
    }
    const Index n = num_dofs();
    std::vector<int> outer(n + 1, 0);
    for (Index j = 0; j < num_nodes_; ++j)
      for (int q = 0; q < 3; ++q) outer[3 * j + q + 1] = 3 * static_cast<int>(adj[j].size());
    for (Index k = 0; k < n; ++k) outer[k + 1] += outer[k];
    std::vector<int> inner(outer[n]);
    for (Index j = 0; j < num_nodes_; ++j)
      for (int q = 0; q < 3; ++q) {
        int p = outer[3 * j + q];
        for (Index i : adj[j])
          for (int d = 0; d < 3; ++d) inner[p++] = 3 * i + d;
      }
    std::vector<Scalar> zeros(inner.size(), 0.0);
    pattern_ = Eigen::Map<const SparseMatrix>(n, n, static_cast<Index>(inner.size()), outer.data(), inner.data(),
                                              zeros.data());
    pattern_.makeCompressed();
    // Where each element's 3x3 blocks start.
    const Index ne = mesh.num_elements();
    block_base_.resize(static_cast<size_t>(ne) * N * N);
    column_length_.resize(static_cast<size_t>(ne) * N);
    for (Index e = 0; e < ne; ++e) {
      const auto& c = mesh.element(e);
      for (int b = 0; b < N; ++b) {
        const auto& col_nodes = adj[c[b]];
        column_length_[static_cast<size_t>(e) * N + b] = 3 * static_cast<int>(col_nodes.size());
        for (int a = 0; a < N; ++a) {
          const auto it = std::lower_bound(col_nodes.begin(), col_nodes.end(), c[a]);
          block_base_[(static_cast<size_t>(e) * N + b) * N + a] =
              outer[3 * c[b]] + 3 * static_cast<int>(it - col_nodes.begin());
        }
      }
    }
  }

  void build_colours(const Mesh<E>& mesh) {
    std::vector<std::uint64_t> node_colours(num_nodes_, 0);  // bit k: a colour-k element uses this node
    std::vector<int> colour_of(mesh.num_elements());
    for (Index e = 0; e < mesh.num_elements(); ++e) {
      std::uint64_t used = 0;
      for (Index i : mesh.element(e)) used |= node_colours[i];
      if (~used == 0) fail<MeshError>("element {}: more than 64 element colours needed (a node shared by too many elements)", e);
      const int k = std::countr_one(used);
      colour_of[e] = k;
      for (Index i : mesh.element(e)) node_colours[i] |= std::uint64_t{1} << k;
      if (k >= static_cast<int>(colours_.size())) colours_.resize(k + 1);
      colours_[k].push_back(e);
    }
  }

  Index num_nodes_ = 0;
  SparseMatrix pattern_;
  std::vector<int> block_base_;     // [e][b][a]: value index of entry (3 n_a, 3 n_b)
  std::vector<int> column_length_;  // [e][b]: entries in each column of node n_b
  std::vector<std::vector<Index>> colours_;
};

}  // namespace plastifem
