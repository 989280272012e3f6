#pragma once
// Sparse pattern computed once per dof map, and race-free deterministic assembly into it.
//
// Rows: the DofMap's block rows (assembly/dof_map.hpp): node i's displacement is block row i
// (dofs 3 i + d); added slots (enrichment) follow. Each element couples its span of rows: its
// nodes, plus the extension rows of a cut element.
// System matrices are BlockSymmetricMatrix (assembly/block_matrix.hpp): the lower triangle of
// the row graph's 3x3 blocks. For every element we precompute where each of its blocks lives
// in the value array (and whether it lands transposed), so a re-assembly writes straight into
// memory: no search, no allocation. Standard elements use a fixed N x N table; extended
// elements one of their span's size.
//
// Order and threads: elements are cut into chunks of consecutive indices (about 1/256 of the
// mesh each, at least 16 elements; in a spatial order instead if the mesh's numbering has no
// coherence: build_colours), and the chunks are greedily coloured so that no two chunks
// of one colour share a row. Colours run one after the other, the chunks of a colour in
// parallel, the elements of a chunk in their (index or spatial) order. Each matrix entry then receives its
// contributions in the same order whatever the thread count, so results are bit-identical
// from 1 to N threads, with no atomics and no critical sections; and consecutive elements
// (neighbours, in a mesh numbered with any spatial coherence: the generators, Gmsh) touch the
// same matrix rows, which stay in cache. Colouring single elements instead spread each colour
// over the whole mesh, so every element's scatter missed the cache: bar5760 Tet4 spent 50% of
// its assembly waiting on the block offsets and matrix values.
#include <plastifem/assembly/block_matrix.hpp>
#include <plastifem/assembly/dof_map.hpp>
#include <plastifem/core/error.hpp>
#include <plastifem/mesh/mesh.hpp>

#include <algorithm>
#include <bit>
#include <cstdint>
#include <span>
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
  explicit Assembler(const Mesh<E>& mesh) : Assembler(mesh, DofMap(mesh.num_nodes())) {}
  Assembler(const Mesh<E>& mesh, const DofMap& dofs)
      : num_rows_(dofs.num_block_rows()), dof_version_(dofs.version()) {
    if (dofs.num_nodes() != mesh.num_nodes())
      fail<InvalidArgument>("assembler: the dof map has {} nodes, the mesh {}", dofs.num_nodes(), mesh.num_nodes());
    build_pattern(mesh, dofs);
    build_colours(mesh, dofs);
  }

  Index num_dofs() const { return 3 * num_rows_; }
  Index num_block_rows() const { return num_rows_; }
  /// The DofMap version this assembler was built for.
  std::uint64_t dof_version() const { return dof_version_; }
  /// A matrix with the system's structure and all values zero.
  BlockSymmetricMatrix zero_matrix() const { return BlockSymmetricMatrix(pattern_); }
  const std::shared_ptr<const BlockPattern>& pattern() const { return pattern_; }
  /// Number of chunk colours (parallel phases of an element loop).
  Index num_colours() const { return static_cast<Index>(colours_.size()); }
  /// Per block row: 1 if some element couples it, 0 for a row no element touches (a node no
  /// element uses, a slot with no extension): such rows carry no mass and no stiffness.
  const std::vector<char>& coupled_rows() const { return coupled_; }

  /// Runs body(e) for every element: colour by colour, the chunks of a colour in parallel, the
  /// elements of a chunk in the assembly order (index order, or build_colours' spatial one; the
  /// same for any thread count).
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
      for (Index i = 0; i < n; ++i) {
        if (order_.empty())
          for (Index e = colour[i].first; e < colour[i].second; ++e) body(e);
        else
          for (Index k = colour[i].first; k < colour[i].second; ++k) body(order_[k]);
      }
    }
  }

  /// values += the symmetric 3N x 3N element matrix Ke of element e (dense, dof 3a + d over its
  /// nodes). Only Ke's lower blocks K_ab, a >= b (local numbering), are read: a block whose
  /// nodes come in the other order globally (node(a) < node(b)) is added transposed, as the
  /// block K_ba = K_ab^T the lower-triangle storage keeps. Kernels may therefore leave the upper
  /// blocks unset (the `lower` argument of the models' evaluate), which saves the corotational
  /// and Neo-Hookean kernels their mirror copy and the per-element corotational one half of
  /// its R K0 R^T.
  template <class Matrix>
  void add_element_matrix(Index e, const Matrix& Ke, Scalar* values) const {
    const int* base = &lower_base_[static_cast<size_t>(e) * num_lower];
    int k = 0;
    for (int b = 0; b < N; ++b)
      for (int a = b; a < N; ++a, ++k) {
        const int o = base[k];
        if (o >= 0) {
          Scalar* v = values + o;
          for (int i = 0; i < 3; ++i)
            for (int j = 0; j < 3; ++j) v[3 * i + j] += Ke(3 * a + i, 3 * b + j);
        } else {
          Scalar* v = values + (-o - 1);  // block (node b, node a): K_ab^T
          for (int i = 0; i < 3; ++i)
            for (int j = 0; j < 3; ++j) v[3 * j + i] += Ke(3 * a + i, 3 * b + j);
        }
      }
  }

  /// values += the symmetric matrix Ke over an extended element's whole span (its nodes, then
  /// its extension rows; 3 dofs each).
  template <class Matrix>
  void add_extended_matrix(Index e, const Matrix& Ke, Scalar* values) const {
    const Extended& x = extended_of(e);
    const int s = x.span;
    if (Ke.rows() != 3 * s || Ke.cols() != 3 * s)
      fail<Error>("element {}: extended matrix is {}x{}, its span needs {}x{}", e, Ke.rows(), Ke.cols(), 3 * s, 3 * s);
    const int* base = &extended_base_[x.base_offset];
    for (int b = 0; b < s; ++b)
      for (int a = 0; a < s; ++a) {
        if (base[b * s + a] < 0) continue;
        Scalar* v = values + base[b * s + a];
        for (int i = 0; i < 3; ++i)
          for (int j = 0; j < 3; ++j) v[3 * i + j] += Ke(3 * a + i, 3 * b + j);
      }
  }

  /// values += m_ab I3 for the N x N symmetric scalar element matrix m (mass-like; its lower
  /// triangle is read).
  template <class Matrix>
  void add_element_scalar_matrix(Index e, const Matrix& m, Scalar* values) const {
    const int* base = &lower_base_[static_cast<size_t>(e) * num_lower];
    int k = 0;
    for (int b = 0; b < N; ++b)
      for (int a = b; a < N; ++a, ++k) {
        Scalar* v = values + (base[k] >= 0 ? base[k] : -base[k] - 1);
        v[0] += m(a, b), v[4] += m(a, b), v[8] += m(a, b);
      }
  }
  /// The same over an extended element's span (m is span x span).
  template <class Matrix>
  void add_extended_scalar_matrix(Index e, const Matrix& m, Scalar* values) const {
    const Extended& x = extended_of(e);
    const int s = x.span;
    const int* base = &extended_base_[x.base_offset];
    for (int b = 0; b < s; ++b)
      for (int a = 0; a < s; ++a) {
        if (base[b * s + a] < 0) continue;
        Scalar* v = values + base[b * s + a];
        v[0] += m(a, b), v[4] += m(a, b), v[8] += m(a, b);
      }
  }

  /// Whether element e's span was extended (it then assembles with add_extended_*).
  bool is_extended(Index e) const { return !extended_index_.empty() && extended_index_[e] >= 0; }
  /// The rows of an extended element's span: its nodes, then its extension rows.
  std::span<const Index> extended_rows(Index e) const {
    const Extended& x = extended_of(e);
    return {extended_rows_.data() + x.rows_offset, static_cast<size_t>(x.span)};
  }

 private:
  struct Extended {
    int span = 0;             ///< rows in the span
    size_t rows_offset = 0;   ///< into extended_rows_
    size_t base_offset = 0;   ///< into extended_base_ (span^2 entries)
  };
  const Extended& extended_of(Index e) const {
    if (!is_extended(e)) fail<Error>("element {} is not extended", e);
    return extended_[extended_index_[e]];
  }

  /// Calls f(row) for every row of element e's span.
  template <class F>
  static void for_each_row(const Mesh<E>& mesh, const DofMap& dofs, Index e, F&& f) {
    for (Index i : mesh.element(e)) f(i);
    for (Index r : dofs.extension(e)) f(r);
  }

  void build_pattern(const Mesh<E>& mesh, const DofMap& dofs) {
    // Lower row adjacency (J <= I, including I itself), sorted.
    std::vector<std::vector<Index>> lower(num_rows_);
    coupled_.assign(num_rows_, 0);
    std::vector<Index> span;
    for (Index e = 0; e < mesh.num_elements(); ++e) {
      span.clear();
      for_each_row(mesh, dofs, e, [&](Index r) { span.push_back(r); });
      for (Index i : span) {
        coupled_[i] = 1;
        for (Index j : span)
          if (j <= i) lower[i].push_back(j);
      }
    }
    for (auto& a : lower) {
      std::sort(a.begin(), a.end());
      a.erase(std::unique(a.begin(), a.end()), a.end());
      if (a.empty()) a.push_back(static_cast<Index>(&a - lower.data()));  // uncoupled row: a diagonal block only
    }
    pattern_ = BlockPattern::from_lower_neighbours(lower);
    // Where each local lower block (a >= b) of an element lives: its value offset if
    // node(a) >= node(b), else -(offset of block (node b, node a)) - 1 (added transposed).
    const Index ne = mesh.num_elements();
    lower_base_.resize(static_cast<size_t>(ne) * num_lower);
    for (Index e = 0; e < ne; ++e) {
      const auto& c = mesh.element(e);
      int k = 0;
      for (int b = 0; b < N; ++b)
        for (int a = b; a < N; ++a, ++k)
          lower_base_[static_cast<size_t>(e) * num_lower + k] =
              c[a] >= c[b] ? 9 * pattern_->block(c[a], c[b]) : -9 * pattern_->block(c[b], c[a]) - 1;
    }
    extended_index_.clear();
    extended_.clear();
    extended_rows_.clear();
    extended_base_.clear();
    if (!dofs.extensions().empty()) extended_index_.assign(ne, -1);
    for (const auto& x : dofs.extensions()) {
      if (x.element < 0 || x.element >= ne)
        fail<InvalidArgument>("dof map extends element {}, the mesh has {}", x.element, ne);
      Extended ex;
      ex.rows_offset = extended_rows_.size();
      ex.base_offset = extended_base_.size();
      for_each_row(mesh, dofs, x.element, [&](Index r) { extended_rows_.push_back(r); });
      ex.span = static_cast<int>(extended_rows_.size() - ex.rows_offset);
      const Index* rows = extended_rows_.data() + ex.rows_offset;
      for (int b = 0; b < ex.span; ++b)
        for (int a = 0; a < ex.span; ++a)
          extended_base_.push_back(rows[a] >= rows[b] ? 9 * pattern_->block(rows[a], rows[b]) : -1);
      extended_index_[x.element] = static_cast<int>(extended_.size());
      extended_.push_back(ex);
    }
  }

  /// Chunks and colours in the elements' index order; if a mesh numbered without spatial
  /// coherence (Gmsh's HXT mesher numbers its tetrahedra so: a 2,559-tet liver needed more than
  /// 64 colours) makes that fail, in the order of their centres along a Z-order curve, in which
  /// consecutive elements are neighbours whatever the numbering. The index order stays the first
  /// choice: it is the order every mesh was assembled in before, so their results stay bit for bit.
  void build_colours(const Mesh<E>& mesh, const DofMap& dofs) {
    const Index ne = mesh.num_elements();
    chunk_size_ = std::max<Index>(16, ne / 256);
    order_.clear();
    if (colour_chunks(mesh, dofs)) return;
    order_ = spatial_order(mesh);
    if (!colour_chunks(mesh, dofs))
      fail<MeshError>("assembly: more than 64 chunk colours needed even in spatial order (a node shared by too many "
                      "elements)");
  }

  /// Greedy colouring of the chunks of `chunk_size_` consecutive elements (in order_ if set):
  /// false if a chunk finds all 64 colours taken.
  bool colour_chunks(const Mesh<E>& mesh, const DofMap& dofs) {
    const Index ne = mesh.num_elements();
    colours_.clear();
    std::vector<std::uint64_t> row_colours(num_rows_, 0);  // bit k: a colour-k chunk uses this row
    auto element = [&](Index k) { return order_.empty() ? k : order_[k]; };
    for (Index begin = 0; begin < ne; begin += chunk_size_) {
      const Index end = std::min(ne, begin + chunk_size_);
      std::uint64_t used = 0;
      for (Index k = begin; k < end; ++k) for_each_row(mesh, dofs, element(k), [&](Index r) { used |= row_colours[r]; });
      if (~used == 0) return false;
      const int c = std::countr_one(used);
      for (Index k = begin; k < end; ++k)
        for_each_row(mesh, dofs, element(k), [&](Index r) { row_colours[r] |= std::uint64_t{1} << c; });
      if (c >= static_cast<int>(colours_.size())) colours_.resize(c + 1);
      colours_[c].push_back({begin, end});
    }
    return true;
  }

  /// The elements sorted by the Z-order (Morton) code of their centres on a 1024^3 grid over the
  /// mesh's bounding box; ties keep index order.
  static std::vector<Index> spatial_order(const Mesh<E>& mesh) {
    const Index ne = mesh.num_elements();
    Eigen::Matrix3Xd centre(3, ne);
    for (Index e = 0; e < ne; ++e) centre.col(e) = mesh.element_nodes(e).rowwise().mean();
    const Vec3 lo = centre.rowwise().minCoeff(), extent = (centre.rowwise().maxCoeff() - lo).cwiseMax(1e-300);
    auto spread = [](std::uint64_t v) {  // the 10 bits of v to every third bit
      std::uint64_t x = v & 0x3ff;
      x = (x | (x << 16)) & 0x30000ff;
      x = (x | (x << 8)) & 0x300f00f;
      x = (x | (x << 4)) & 0x30c30c3;
      x = (x | (x << 2)) & 0x9249249;
      return x;
    };
    std::vector<std::pair<std::uint64_t, Index>> key(static_cast<size_t>(ne));
    for (Index e = 0; e < ne; ++e) {
      std::uint64_t code = 0;
      for (int d = 0; d < 3; ++d) {
        const auto q = static_cast<std::uint64_t>(std::clamp(1023.0 * (centre(d, e) - lo[d]) / extent[d], 0.0, 1023.0));
        code |= spread(q) << d;
      }
      key[static_cast<size_t>(e)] = {code, e};
    }
    std::sort(key.begin(), key.end());
    std::vector<Index> order(static_cast<size_t>(ne));
    for (Index k = 0; k < ne; ++k) order[static_cast<size_t>(k)] = key[static_cast<size_t>(k)].second;
    return order;
  }

  Index num_rows_ = 0;
  std::uint64_t dof_version_ = 0;
  std::shared_ptr<const BlockPattern> pattern_;
  static constexpr int num_lower = N * (N + 1) / 2;
  std::vector<int> lower_base_;  // [e][lower block k]: see build_pattern
  std::vector<std::vector<std::pair<Index, Index>>> colours_;  // [colour]: chunks [begin, end) of positions in order_
  std::vector<Index> order_;  // the elements in assembly order; empty: index order
  Index chunk_size_ = 16;
  std::vector<char> coupled_;
  std::vector<int> extended_index_;  // element -> index into extended_, -1 if standard (empty: none)
  std::vector<Extended> extended_;
  std::vector<Index> extended_rows_;
  std::vector<int> extended_base_;
};

}  // namespace plastifem
