#pragma once
// SharedByShape<E, T>: what elements precompute from their rest shapes (an elastic model's
// element data, the plastic flow's shape gradients), one T per distinct shape, with rest shapes
// that change during a run.
//
// Sharing. Elements whose rest positions relative to their first node are equal bit for bit
// (translated copies: every cell of a structured grid) share one entry: every model
// differences positions relative to node 0, so its data depends on that shape only. A
// structured bar keeps one entry instead of one per hex and streams it from cache.
//
// Change. reshape(elements, make) gives each listed element an entry of its own, copy-on-write:
// the elements that shared its old entry keep it, and an entry only that element uses is
// rewritten in place. The bookkeeping runs first, serially; then every element's make(e) goes
// into its own entry, on the given threads.
#include <plastifem/core/parallel.hpp>
#include <plastifem/mesh/mesh.hpp>

#include <cstdint>
#include <map>
#include <span>
#include <vector>

namespace plastifem {

template <FiniteElement E, class T>
class SharedByShape {
 public:
  SharedByShape() = default;
  /// One entry per distinct rest shape of the mesh's elements: make(X) for the first element
  /// (nodes X) of each shape.
  template <class Make>
  SharedByShape(const Mesh<E>& mesh, Make&& make) {
    const Index ne = mesh.num_elements();
    std::map<std::vector<Scalar>, std::uint32_t> shape_index;
    of_.resize(ne);
    for (Index e = 0; e < ne; ++e) {
      const ElementNodes<E> X = mesh.element_nodes(e);
      const ElementNodes<E> rel = X.colwise() - X.col(0);
      auto [it, inserted] = shape_index.try_emplace(std::vector<Scalar>(rel.data(), rel.data() + rel.size()),
                                                    static_cast<std::uint32_t>(entries_.size()));
      if (inserted) entries_.push_back(make(X)), users_.push_back(0);
      of_[e] = it->second;
      ++users_[it->second];
    }
    entries_.shrink_to_fit();
  }

  /// Element e's entry.
  const T& operator[](Index e) const { return entries_[of_[e]]; }
  /// Number of distinct entries in use (one for a structured Hex8 grid, six for its Kuhn Tet4
  /// split; more as elements get rest shapes of their own).
  Index num_shapes() const { return static_cast<Index>(entries_.size()); }

  /// Gives each of the distinct elements `elements` the entry make(e) of its own (see the file
  /// comment). If a make throws, the first exception is rethrown after the loop; the elements
  /// whose make threw keep a copy of their old entry.
  template <class Make>
  void reshape(std::span<const Index> elements, Make&& make, int threads) {
    for (Index e : elements) {
      const std::uint32_t old = of_[e];
      if (users_[old] == 1) continue;  // e alone uses it: rewritten in place
      --users_[old];
      of_[e] = static_cast<std::uint32_t>(entries_.size());
      entries_.push_back(entries_[old]);  // a placeholder (not every T has a default), made below
      users_.push_back(1);
    }
    parallel_for(static_cast<Index>(elements.size()), threads, [&](Index k) {
      const Index e = elements[static_cast<size_t>(k)];
      entries_[of_[e]] = make(e);
    });
  }

 private:
  std::vector<T> entries_;              ///< one per distinct rest shape
  std::vector<std::uint32_t> users_;    ///< elements using each entry (never 0: an entry only one
                                        ///< element uses is rewritten in place)
  std::vector<std::uint32_t> of_;       ///< element -> its entry
};

}  // namespace plastifem
