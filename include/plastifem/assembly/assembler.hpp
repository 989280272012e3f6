#pragma once
// Sparse pattern computed once, and race-free deterministic assembly into it.
//
// Dofs: 3 per node, dof = 3 node + d (enriched dofs will be appended after these).
// System matrices are BlockSymmetricMatrix (assembly/block_matrix.hpp): the lower triangle of
// the node graph's 3x3 blocks. For every element we precompute where each of its blocks lives
// in the value array (and whether it lands transposed), so a re-assembly writes straight into
// memory: no search, no allocation.
//
// Order and threads: elements are cut into chunks of consecutive indices (about 1/256 of the
// mesh each, at least 16 elements), and the chunks are greedily coloured so that no two chunks
// of one colour share a node. Colours run one after the other, the chunks of a colour in
// parallel, the elements of a chunk in index order. Each matrix entry then receives its
// contributions in the same order whatever the thread count, so results are bit-identical
// from 1 to N threads, with no atomics and no critical sections; and consecutive elements
// (neighbours, in a mesh numbered with any spatial coherence: the generators, Gmsh) touch the
// same matrix rows, which stay in cache. Colouring single elements instead spread each colour
// over the whole mesh, so every element's scatter missed the cache: bar5760 Tet4 spent 50% of
// its assembly waiting on the block offsets and matrix values.
#include <plastifem/assembly/block_matrix.hpp>
#include <plastifem/core/error.hpp>
#include <plastifem/mesh/mesh.hpp>

#include <algorithm>
#include <bit>
#include <cstdint>
#include <vector>

#ifdef _OPENMP
#include <omp.h>
#endif

namespace plastifem {

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
  BlockSymmetricMatrix zero_matrix() const { return BlockSymmetricMatrix(pattern_); }
  /// Number of chunk colours (parallel phases of an element loop).
  Index num_colours() const { return static_cast<Index>(colours_.size()); }

  /// Runs body(e) for every element: colour by colour, the chunks of a colour in parallel, the
  /// elements of a chunk in index order (the same order for any thread count).
  template <class Body>
  void for_each_element(Body&& body, int threads = 0) const {
    for (const auto& colour : colours_) {
      const Index n = static_cast<Index>(colour.size());
#ifdef _OPENMP
      const int t = threads > 0 ? threads : omp_get_max_threads();
#pragma omp parallel for schedule(static) num_threads(t) if (t > 1 && n > 1 && n * chunk_size_ > 64)
#else
      (void)threads;
#endif
      for (Index i = 0; i < n; ++i)
        for (Index e = colour[i].first; e < colour[i].second; ++e) body(e);
    }
  }

  /// values += the symmetric 3N x 3N element matrix Ke of element e (dense, dof 3a + d): its
  /// blocks K_ab with node(a) >= node(b), which are the lower-triangle blocks.
  template <class Matrix>
  void add_element_matrix(Index e, const Matrix& Ke, Scalar* values) const {
    const int* base = &block_base_[static_cast<size_t>(e) * N * N];
    for (int b = 0; b < N; ++b)
      for (int a = 0; a < N; ++a) {
        if (base[b * N + a] < 0) continue;  // upper triangle: added as the transpose of (b, a)
        Scalar* v = values + base[b * N + a];
        for (int i = 0; i < 3; ++i)
          for (int j = 0; j < 3; ++j) v[3 * i + j] += Ke(3 * a + i, 3 * b + j);
      }
  }

  /// values += m_ab I3 for the N x N symmetric scalar element matrix m (mass-like).
  template <class Matrix>
  void add_element_scalar_matrix(Index e, const Matrix& m, Scalar* values) const {
    const int* base = &block_base_[static_cast<size_t>(e) * N * N];
    for (int b = 0; b < N; ++b)
      for (int a = 0; a < N; ++a) {
        if (base[b * N + a] < 0) continue;
        Scalar* v = values + base[b * N + a];
        v[0] += m(a, b), v[4] += m(a, b), v[8] += m(a, b);
      }
  }

 private:
  void build_pattern(const Mesh<E>& mesh) {
    // Lower node adjacency (J <= I, including I itself), sorted.
    std::vector<std::vector<Index>> lower(num_nodes_);
    for (const auto& c : mesh.elements())
      for (Index i : c)
        for (Index j : c)
          if (j <= i) lower[i].push_back(j);
    for (auto& a : lower) {
      std::sort(a.begin(), a.end());
      a.erase(std::unique(a.begin(), a.end()), a.end());
      if (a.empty()) a.push_back(&a - lower.data());  // unused node: a diagonal block only
    }
    pattern_ = BlockPattern::from_lower_neighbours(lower);
    // Where each element block (a, b) with node(a) >= node(b) lives; -1 for the others.
    const Index ne = mesh.num_elements();
    block_base_.resize(static_cast<size_t>(ne) * N * N);
    for (Index e = 0; e < ne; ++e) {
      const auto& c = mesh.element(e);
      for (int b = 0; b < N; ++b)
        for (int a = 0; a < N; ++a)
          block_base_[(static_cast<size_t>(e) * N + b) * N + a] =
              c[a] >= c[b] ? 9 * pattern_->block(c[a], c[b]) : -1;
    }
  }

  void build_colours(const Mesh<E>& mesh) {
    const Index ne = mesh.num_elements();
    chunk_size_ = std::max<Index>(16, ne / 256);
    std::vector<std::uint64_t> node_colours(num_nodes_, 0);  // bit k: a colour-k chunk uses this node
    for (Index begin = 0; begin < ne; begin += chunk_size_) {
      const Index end = std::min(ne, begin + chunk_size_);
      std::uint64_t used = 0;
      for (Index e = begin; e < end; ++e)
        for (Index i : mesh.element(e)) used |= node_colours[i];
      if (~used == 0)
        fail<MeshError>("elements {}..{}: more than 64 chunk colours needed (a node shared by too many elements)",
                        begin, end - 1);
      const int k = std::countr_one(used);
      for (Index e = begin; e < end; ++e)
        for (Index i : mesh.element(e)) node_colours[i] |= std::uint64_t{1} << k;
      if (k >= static_cast<int>(colours_.size())) colours_.resize(k + 1);
      colours_[k].push_back({begin, end});
    }
  }

  Index num_nodes_ = 0;
  std::shared_ptr<const BlockPattern> pattern_;
  std::vector<int> block_base_;  // [e][b][a]: value index of block (n_a, n_b) if n_a >= n_b, else -1
  std::vector<std::vector<std::pair<Index, Index>>> colours_;  // [colour]: chunks [begin, end)
  Index chunk_size_ = 16;
};

}  // namespace plastifem
