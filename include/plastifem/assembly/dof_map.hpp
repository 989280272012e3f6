#pragma once
// DofMap: where each degree of freedom lives in the system vectors and matrices.
//
// Dofs come in 3x3 blocks: one block row per (node, slot). Slot 0 of node i is its
// displacement and sits at block row i, so the standard dofs are 3 i + d as before. Further
// slots (X-FEM enrichment, seed 001 eq. 74-75: "the new dofs are appended after the standard
// ones") get block rows num_nodes, num_nodes + 1, ... in the order they are added.
//
// Each element couples a span of block rows: its nodes' slot-0 rows, plus, for an element
// whose span was extended (a cut element), the rows its extension lists. The sparsity pattern,
// the assembly tables, the colouring, the system matrices, the symbolic factorisation and the
// preconditioner are all derived from the spans; `version()` changes whenever a slot or an
// extension is added, and everything derived is rebuilt when it does, and only then.
//
// A block row that no element couples (a dummy slot, or a node no element uses) carries no
// mass and no stiffness: the solver holds it fixed at zero (`active_rows`).
#include <plastifem/core/error.hpp>
#include <plastifem/core/types.hpp>

#include <algorithm>
#include <cstdint>
#include <span>
#include <vector>

namespace plastifem {

class DofMap {
 public:
  DofMap() = default;
  explicit DofMap(Index num_nodes) : num_nodes_(num_nodes) {}

  Index num_nodes() const { return num_nodes_; }
  /// Block rows: nodes plus added slots.
  Index num_block_rows() const { return num_nodes_ + static_cast<Index>(slot_node_.size()); }
  Index num_dofs() const { return 3 * num_block_rows(); }
  /// Changes whenever a slot or an element extension is added.
  std::uint64_t version() const { return version_; }

  /// Adds a slot to `node` and returns its block row (appended after every existing row).
  Index add_slot(Index node) {
    check_node(node);
    slot_node_.push_back(node);
    ++version_;
    return num_block_rows() - 1;
  }
  /// The node a block row belongs to, and its slot number (0: displacement).
  Index node_of(Index row) const { return row < num_nodes_ ? row : slot_node_[row - num_nodes_]; }
  int slot_of(Index row) const {
    if (row < num_nodes_) return 0;
    int s = 1;
    const Index node = slot_node_[row - num_nodes_];
    for (Index r = num_nodes_; r < row; ++r) s += slot_node_[r - num_nodes_] == node;
    return s;
  }

  /// Extends element e's span by `rows` (after its nodes' rows): the element then couples them
  /// too. Replaces any earlier extension of e.
  void extend_element(Index e, std::vector<Index> rows) {
    for (Index r : rows)
      if (r < num_nodes_ || r >= num_block_rows())
        fail<InvalidArgument>("element {}: extension row {} is not an added slot (rows [{}, {}))", e, r, num_nodes_,
                              num_block_rows());
    auto it = std::lower_bound(extended_.begin(), extended_.end(), e,
                               [](const Extension& x, Index key) { return x.element < key; });
    if (it != extended_.end() && it->element == e) it->rows = std::move(rows);
    else extended_.insert(it, Extension{e, std::move(rows)});
    ++version_;
  }
  /// The extra rows of element e (empty for a standard element).
  std::span<const Index> extension(Index e) const {
    auto it = std::lower_bound(extended_.begin(), extended_.end(), e,
                               [](const Extension& x, Index key) { return x.element < key; });
    if (it == extended_.end() || it->element != e) return {};
    return it->rows;
  }
  struct Extension {
    Index element;
    std::vector<Index> rows;
  };
  /// Every extended element with its extra rows, by element.
  const std::vector<Extension>& extensions() const { return extended_; }

 private:
  void check_node(Index node) const {
    if (node < 0 || node >= num_nodes_) fail<InvalidArgument>("dof map: node {} out of range [0, {})", node, num_nodes_);
  }

  Index num_nodes_ = 0;
  std::vector<Index> slot_node_;     ///< node of each added block row
  std::vector<Extension> extended_;  ///< sorted by element
  std::uint64_t version_ = 0;
};

}  // namespace plastifem
