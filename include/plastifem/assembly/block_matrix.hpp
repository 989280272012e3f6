#pragma once
// BlockSymmetricMatrix: the storage of every system matrix (stiffness, mass, Newmark system).
//
// The matrices of a 3-dof-per-node FE model are symmetric and made of 3x3 blocks, one per pair
// of nodes that share an element. Only the lower triangle of blocks is stored (block (I, J),
// J <= I, the diagonal block whole), by block rows, each block row-major:
//   value of entry (3 I + i, 3 J + j) = values[9 k + 3 i + j],  k = the block's index.
// Against Eigen's general CSC with both triangles (12 bytes per scalar nonzero) this streams
// 72 + 4 bytes per stored block instead of 2 x 9 x 12: 2.8x fewer bytes. The product then
// runs at about 10 cycles per block, bound by its loads and stores rather than by memory
// (docs/performance.md, "Where a step's time goes").
//
// y = A x visits each stored block once: y_I += B x_J and, off the diagonal, y_J += B^T x_I.
// With threads, block rows are split into ranges of equal block counts; contributions a thread
// makes to rows of an earlier range go to its own buffer, summed after a barrier, so the
// product is race-free, deterministic and allocation-free after the first call.
#include <plastifem/core/error.hpp>
#include <plastifem/core/types.hpp>

#include <Eigen/SparseCore>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <memory>
#include <vector>

#ifdef _OPENMP
#include <omp.h>
#endif

namespace plastifem {

using SparseMatrix = Eigen::SparseMatrix<Scalar, Eigen::ColMajor, int>;

/// Structure of a BlockSymmetricMatrix, shared by all matrices of one mesh.
struct BlockPattern {
  Index num_block_rows = 0;
  std::vector<int> row_start;  ///< first block of each block row; size num_block_rows + 1
  std::vector<int> column;     ///< block column J <= I of each block, ascending (diagonal last)

  /// Pattern from, for every node I, the sorted nodes J <= I it is coupled to (I included).
  static std::shared_ptr<const BlockPattern> from_lower_neighbours(const std::vector<std::vector<Index>>& lower) {
    auto p = std::make_shared<BlockPattern>();
    p->num_block_rows = static_cast<Index>(lower.size());
    p->row_start.assign(lower.size() + 1, 0);
    for (size_t I = 0; I < lower.size(); ++I) {
      if (lower[I].empty() || lower[I].back() != static_cast<Index>(I))
        fail<Error>("block pattern: row {} must end with its diagonal block", I);
      p->row_start[I + 1] = p->row_start[I] + static_cast<int>(lower[I].size());
    }
    p->column.reserve(p->row_start.back());
    for (const auto& row : lower)
      for (Index J : row) p->column.push_back(static_cast<int>(J));
    return p;
  }

  Index num_blocks() const { return static_cast<Index>(column.size()); }

  /// Index of block (I, J) with J <= I, or -1 if the nodes are not coupled.
  int block(Index I, Index J) const {
    const int* begin = column.data() + row_start[I];
    const int* end = column.data() + row_start[I + 1];
    const int* it = std::lower_bound(begin, end, static_cast<int>(J));
    return (it != end && *it == J) ? static_cast<int>(it - column.data()) : -1;
  }
};

class BlockSymmetricMatrix {
 public:
  BlockSymmetricMatrix() = default;
  explicit BlockSymmetricMatrix(std::shared_ptr<const BlockPattern> pattern)
      : pattern_(std::move(pattern)), values_(9 * static_cast<size_t>(pattern_->num_blocks()), 0.0) {}
  BlockSymmetricMatrix(const BlockSymmetricMatrix&) = default;
  BlockSymmetricMatrix(BlockSymmetricMatrix&&) noexcept = default;
  BlockSymmetricMatrix& operator=(BlockSymmetricMatrix&&) noexcept = default;
  /// Between matrices of one pattern only the values are copied: this matrix keeps its scratch
  /// (CSC view, product split and buffers), which depends on the pattern alone. So `A = K` in a
  /// Newton loop neither allocates nor rebuilds the CSC map the direct solvers read (it did, and
  /// that map took 7% of a bar90 Neo-Hookean static solve).
  BlockSymmetricMatrix& operator=(const BlockSymmetricMatrix& o) {
    if (this == &o) return *this;
    if (pattern_ && pattern_ == o.pattern_) {
      copy_values(o);
      return *this;
    }
    return *this = BlockSymmetricMatrix(o);  // another pattern: a whole copy
  }

  Index rows() const { return pattern_ ? 3 * pattern_->num_block_rows : 0; }
  Index cols() const { return rows(); }
  const BlockPattern& pattern() const { return *pattern_; }
  /// Stored scalars (9 per block): same layout for every matrix of one pattern, so linear
  /// combinations of matrices are one pass over this array.
  Index num_values() const { return static_cast<Index>(values_.size()); }
  Scalar* values() { return values_.data(); }
  const Scalar* values() const { return values_.data(); }
  /// All values zero, with up to `threads` threads (0: OpenMP's default), split as the product
  /// splits (for_value_ranges).
  void set_zero(int threads = 1) {
    for_value_ranges(threads, [this](Index v0, Index v1) { std::fill(values_.data() + v0, values_.data() + v1, 0.0); });
  }
  /// Values copied from a matrix of the same pattern, with up to `threads` threads.
  void copy_values(const BlockSymmetricMatrix& o, int threads = 1) {
    if (o.pattern_ != pattern_) fail<Error>("copy_values: the matrices have different patterns");
    for_value_ranges(threads, [&](Index v0, Index v1) {
      std::copy(o.values_.data() + v0, o.values_.data() + v1, values_.data() + v0);
    });
  }
  /// This = a X + Y, plus b Z when Z is given (a Newton matrix cm M + K + cd Kd), all of this
  /// pattern: one pass over the values with up to `threads` threads (for_value_ranges), each
  /// value computed as written whatever the thread count.
  void set_combination(Scalar a, const BlockSymmetricMatrix& X, const BlockSymmetricMatrix& Y, Scalar b = 0,
                       const BlockSymmetricMatrix* Z = nullptr, int threads = 1) {
    if (X.pattern_ != pattern_ || Y.pattern_ != pattern_ || (Z && Z->pattern_ != pattern_))
      fail<Error>("set_combination: the matrices have different patterns");
    Scalar* out = values_.data();
    const Scalar *x = X.values_.data(), *y = Y.values_.data(), *z = Z ? Z->values_.data() : nullptr;
    for_value_ranges(threads, [&](Index v0, Index v1) {
      if (z)
        for (Index i = v0; i < v1; ++i) out[i] = a * x[i] + y[i] + b * z[i];
      else
        for (Index i = v0; i < v1; ++i) out[i] = a * x[i] + y[i];
    });
  }

  /// Runs pass(v0, v1) over ranges [v0, v1) of the value array that together cover it: with
  /// threads (0: OpenMP's default), one range per thread, cut where the product cuts its block
  /// rows, so each thread writes the blocks it multiplies next. A pass over the values (zeroing
  /// before an assembly, forming A = cm M + K) made by one thread leaves the values in that
  /// core's cache, and the other thread's product or scatter then waits while each line
  /// travels: on bar5760 Hex8 with 2 threads a serial form and the 7 products after it took
  /// 1.78 ms, a threaded one 1.21; a serial zeroing and the scatter after it 0.93 ms, a
  /// threaded one 0.68 (bench_memory, docs/performance.md). Elementwise passes: the same values
  /// whatever the thread count.
  template <class Pass>
  void for_value_ranges(int threads, Pass&& pass) const {
#ifdef _OPENMP
    if (threads <= 0) threads = omp_get_max_threads();
    if (threads > 1 && pattern_ && pattern_->num_blocks() > 3000) {
      prepare_split(threads);
      const auto& p = *pattern_;
#pragma omp parallel num_threads(threads)
      {
        if (omp_get_num_threads() != threads) {  // fewer threads granted (nested region): serial
#pragma omp single
          pass(Index(0), num_values());
        } else {
          const int t = omp_get_thread_num();
          pass(9 * static_cast<Index>(p.row_start[split_[t]]), 9 * static_cast<Index>(p.row_start[split_[t + 1]]));
        }
      }
      return;
    }
#endif
    (void)threads;
    pass(Index(0), num_values());
  }

  /// Entry (row, col) of the full symmetric matrix (zero outside the pattern).
  Scalar coeff(Index row, Index col) const {
    if (row / 3 < col / 3) std::swap(row, col);
    const int k = pattern_->block(row / 3, col / 3);
    return k < 0 ? 0.0 : values_[9 * static_cast<size_t>(k) + 3 * (row % 3) + col % 3];
  }

  Vector diagonal() const {
    Vector d(rows());
    diagonal_into(d);
    return d;
  }
  /// The diagonal written into d, already sized rows(): no allocation (the CG preconditioner).
  void diagonal_into(Vector& d) const {
    const auto& p = *pattern_;
    for (Index I = 0; I < p.num_block_rows; ++I) {
      const Scalar* B = &values_[9 * static_cast<size_t>(p.row_start[I + 1] - 1)];  // diagonal block: last
      d.segment<3>(3 * I) << B[0], B[4], B[8];
    }
  }

  /// Sum of the entries of the full symmetric matrix's leading `block_rows` x `block_rows` blocks
  /// (all of it by default).
  Scalar sum(Index block_rows = -1) const {
    Scalar s = 0;
    const auto& p = *pattern_;
    const Index rows = block_rows < 0 ? p.num_block_rows : std::min(block_rows, p.num_block_rows);
    for (Index I = 0; I < rows; ++I)  // lower triangle: column <= I
      for (int k = p.row_start[I]; k < p.row_start[I + 1]; ++k) {
        Scalar b = 0;
        for (int q = 0; q < 9; ++q) b += values_[9 * static_cast<size_t>(k) + q];
        s += (p.column[k] == I) ? b : 2 * b;
      }
    return s;
  }

  /// y = A x, with up to `threads` threads (1: serial).
  void multiply(const Vector& x, Vector& y, int threads = 1) const {
    const auto& p = *pattern_;
    const Index nb = p.num_block_rows;
#ifdef _OPENMP
    // Below ~3000 blocks (bar720: 13k) a thread's start-up costs more than its half of the work.
    if (threads > 1 && p.num_blocks() > 3000) {
      prepare_split(threads);
      prepare_buffers(threads);
#pragma omp parallel num_threads(threads)
      {
        if (omp_get_num_threads() != threads) {  // fewer threads granted (nested region): serial
#pragma omp single
          multiply_rows(0, nb, x.data(), y.data(), nullptr);
        } else {
          const int t = omp_get_thread_num();
          const Index r0 = split_[t], r1 = split_[t + 1];
          Scalar* z = t == 0 ? nullptr : buffers_[t].data();
          if (z) std::fill(z + 3 * buffer_start_[t], z + 3 * r0, 0.0);  // below: never written, zero
          multiply_rows(r0, r1, x.data(), y.data(), z);
#pragma omp barrier
          // y += the buffered contributions to rows before each thread's range.
#pragma omp for schedule(static)
          for (Index i = 3 * reduction_start_; i < 3 * split_[threads - 1]; ++i) {
            Scalar s = 0;
            for (int u = 1; u < threads; ++u)
              if (i < 3 * split_[u]) s += buffers_[u][i];
            y[i] += s;
          }
        }
      }
      return;
    }
#endif
    (void)threads;
    multiply_rows(0, nb, x.data(), y.data(), nullptr);
  }

  /// The full symmetric matrix (both triangles) in Eigen's CSC format.
  SparseMatrix to_sparse() const {
    SparseMatrix A;
    copy_to(A);
    return A;
  }

  /// A = this matrix in Eigen's CSC format (both triangles). The CSC pattern and the map from
  /// its entries to the blocks are built on the first call, then only values are copied.
  void copy_to(SparseMatrix& A) const {
    build_csc_map();
    if (A.rows() != rows() || A.nonZeros() != static_cast<Index>(csc_from_.size()) ||
        !std::equal(csc_outer_.begin(), csc_outer_.end(), A.outerIndexPtr())) {
      std::vector<Scalar> zeros(csc_inner_.size(), 0.0);
      A = Eigen::Map<const SparseMatrix>(rows(), cols(), static_cast<Index>(csc_inner_.size()), csc_outer_.data(),
                                         csc_inner_.data(), zeros.data());
    }
    Scalar* v = A.valuePtr();
    for (size_t k = 0; k < csc_from_.size(); ++k) v[k] = values_[csc_from_[k]];
  }

 private:
  void multiply_rows(Index r0, Index r1, const Scalar* x, Scalar* y, Scalar* buffer) const {
    const auto& p = *pattern_;
    const int* col = p.column.data();
    const Scalar* val = values_.data();
    for (Index I = r0; I < r1; ++I) {
      const Scalar x0 = x[3 * I], x1 = x[3 * I + 1], x2 = x[3 * I + 2];
      Scalar s0 = 0, s1 = 0, s2 = 0;
      const int end = p.row_start[I + 1] - 1;  // the diagonal block is last
      for (int k = p.row_start[I]; k < end; ++k) {
        const Scalar* B = val + 9 * static_cast<size_t>(k);
        const Index J = col[k];
        const Scalar* xj = x + 3 * J;
        s0 += B[0] * xj[0] + B[1] * xj[1] + B[2] * xj[2];
        s1 += B[3] * xj[0] + B[4] * xj[1] + B[5] * xj[2];
        s2 += B[6] * xj[0] + B[7] * xj[1] + B[8] * xj[2];
        Scalar* yj = (J >= r0 || !buffer) ? y + 3 * J : buffer + 3 * J;
        yj[0] += B[0] * x0 + B[3] * x1 + B[6] * x2;
        yj[1] += B[1] * x0 + B[4] * x1 + B[7] * x2;
        yj[2] += B[2] * x0 + B[5] * x1 + B[8] * x2;
      }
      const Scalar* D = val + 9 * static_cast<size_t>(end);
      // Row I receives transposed contributions only from later rows: assign, then they add.
      y[3 * I] = s0 + D[0] * x0 + D[1] * x1 + D[2] * x2;
      y[3 * I + 1] = s1 + D[3] * x0 + D[4] * x1 + D[5] * x2;
      y[3 * I + 2] = s2 + D[6] * x0 + D[7] * x1 + D[8] * x2;
    }
  }

  void prepare_split(int threads) const {
    if (static_cast<int>(split_.size()) == threads + 1) return;
    const auto& p = *pattern_;
    split_.assign(threads + 1, p.num_block_rows);
    split_[0] = 0;
    Index I = 0;
    for (int t = 1; t < threads; ++t) {
      // 64-bit: num_blocks * t passes 2^31 at ~33 million blocks on 64 threads.
      const auto target = std::int64_t{p.num_blocks()} * t / threads;
      while (I < p.num_block_rows && p.row_start[I] < target) ++I;
      split_[t] = I;
    }
    buffers_.clear();  // of the old split; the product sizes them (prepare_buffers)
  }
  /// The product's buffers for threads 1.. of the split: the rows before each thread's range
  /// (only matrices that are multiplied need them). A thread's transposed updates reach back
  /// only to the smallest column of its rows (the band behind its range): buffer_start_[t].
  /// Each product zeroes them only from there, and sums them into y from the smallest of those
  /// starts (reduction_start_).
  void prepare_buffers(int threads) const {
    if (static_cast<int>(buffers_.size()) == threads) return;
    const auto& p = *pattern_;
    buffers_.assign(threads, Vector());
    buffer_start_.assign(threads, 0);
    Index first = p.num_block_rows;
    for (int t = 1; t < threads; ++t) {
      buffers_[t] = Vector::Zero(3 * split_[t]);
      Index lo = split_[t];
      for (Index I = split_[t]; I < split_[t + 1]; ++I) lo = std::min<Index>(lo, p.column[p.row_start[I]]);
      buffer_start_[t] = lo;
      first = std::min(first, lo);
    }
    reduction_start_ = first;
  }

  void build_csc_map() const {
    if (!csc_outer_.empty()) return;
    const auto& p = *pattern_;
    const Index n = rows();
    // Column c of the full matrix = row c (symmetry): entries from the lower blocks (I, J <= I)
    // of block row c/3, read transposed, and from the blocks (I > c/3, c/3) below it.
    std::vector<std::vector<std::pair<int, size_t>>> cols(n);  // (row, value index)
    for (Index I = 0; I < p.num_block_rows; ++I)
      for (int k = p.row_start[I]; k < p.row_start[I + 1]; ++k) {
        const Index J = p.column[k];
        for (int i = 0; i < 3; ++i)
          for (int j = 0; j < 3; ++j) {
            const size_t v = 9 * static_cast<size_t>(k) + 3 * i + j;
            cols[3 * J + j].push_back({static_cast<int>(3 * I + i), v});  // entry (3I+i, 3J+j)
            if (J != I) cols[3 * I + i].push_back({static_cast<int>(3 * J + j), v});  // its mirror
          }
      }
    csc_outer_.assign(n + 1, 0);
    for (Index c = 0; c < n; ++c) {
      std::sort(cols[c].begin(), cols[c].end());
      csc_outer_[c + 1] = csc_outer_[c] + static_cast<int>(cols[c].size());
      for (const auto& [r, v] : cols[c]) {
        csc_inner_.push_back(r);
        csc_from_.push_back(v);
      }
    }
  }

  std::shared_ptr<const BlockPattern> pattern_;
  std::vector<Scalar> values_;
  // Scratch for threaded products and the CSC view, built on first use.
  mutable std::vector<Index> split_;
  mutable std::vector<Vector> buffers_;
  mutable std::vector<Index> buffer_start_;
  mutable Index reduction_start_ = 0;
  mutable std::vector<int> csc_outer_, csc_inner_;
  mutable std::vector<size_t> csc_from_;
};

/// Dirichlet conditions on a system matrix: the rows and columns of constrained dofs become
/// those of a diagonal matrix (A stays symmetric; the increment there is then the right-hand
/// side's zero). Each such diagonal entry keeps the value it had, so the held rows scale with
/// the rest of the matrix (a diagonal of 1 made a stiff body's pivot ratio 1 / (E h): CHOLMOD
/// and LDLT refused E = 1e7 on unit cells as singular); an entry that was not positive (a node
/// no element uses) gets the mean of the others, or 1 if there are none. The
/// blocks a constrained dof touches are found once from the pattern, so each application costs
/// O(those blocks) instead of a pass over the whole matrix (bar5760 clamped at x = 0: 2.7% of
/// the blocks).
class ConstrainedBlocks {
 public:
  ConstrainedBlocks() = default;
  /// `constrained[d]` != 0 for each constrained dof d.
  ConstrainedBlocks(const BlockPattern& p, const std::vector<char>& constrained) {
    for (Index I = 0; I < p.num_block_rows; ++I)
      for (int k = p.row_start[I]; k < p.row_start[I + 1]; ++k) {
        const Index J = p.column[k];
        std::uint16_t mask = 0;  // bit 3 i + j: entry (i, j) of the block is replaced
        for (int i = 0; i < 3; ++i)
          for (int j = 0; j < 3; ++j)
            if (constrained[3 * I + i] || constrained[3 * J + j]) mask |= std::uint16_t(1u << (3 * i + j));
        if (mask) blocks_.push_back({k, mask, I == J});
      }
    for (size_t d = 0; d < constrained.size(); ++d)
      if (constrained[d]) dofs_.push_back(static_cast<Index>(d));
  }

  /// Rows and columns of the constrained dofs of A become diagonal (see the class comment).
  void apply(BlockSymmetricMatrix& A) const {
    Scalar* val = A.values();
    Scalar sum = 0;
    int count = 0;
    for (const Block& b : blocks_)
      if (b.diagonal)
        for (int e = 0; e < 9; e += 4)
          if (const Scalar d = val[9 * static_cast<size_t>(b.index) + e]; (b.mask & (1u << e)) && d > 0 && std::isfinite(d)) {
            sum += d;
            ++count;
          }
    const Scalar fallback = count > 0 ? sum / count : 1.0;
    for (const Block& b : blocks_) {
      Scalar* B = val + 9 * static_cast<size_t>(b.index);
      for (int e = 0; e < 9; ++e)
        if (b.mask & (1u << e)) {
          if (b.diagonal && e % 4 == 0)
            B[e] = B[e] > 0 && std::isfinite(B[e]) ? B[e] : fallback;
          else
            B[e] = 0.0;
        }
    }
  }
  /// v = 0 at the constrained dofs.
  void zero(Vector& v) const {
    for (Index d : dofs_) v[d] = 0;
  }
  const std::vector<Index>& dofs() const { return dofs_; }

 private:
  struct Block {
    int index;             ///< the block's position in the pattern
    std::uint16_t mask;    ///< entries to replace
    bool diagonal;         ///< a diagonal block (I == J): its replaced diagonal entries become 1
  };
  std::vector<Block> blocks_;
  std::vector<Index> dofs_;
};

}  // namespace plastifem
