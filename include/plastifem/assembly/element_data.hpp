#pragma once
// ElementDataTable<E, Model>: what an elastic model precomputes per element (K0, shape
// gradients, quadrature weights) from its rest shape, with one entry per distinct shape, and
// rest shapes that can change during a run (plasticity).
//
// Sharing. Elements whose rest positions relative to their first node are equal bit for bit
// (translated copies: every cell of a structured grid) share one entry, since the models
// difference positions relative to node 0 and their data depends only on that shape. A
// structured bar keeps one 24 x 24 K0 instead of one per hex (bar46080
// CorotationalPerElement: 403 -> 190 MB of solver heap) and streams it from cache instead of
// memory.
//
// Change. set_rest_shape(e, X) gives element e a rest shape of its own: copy-on-write, so the
// elements that shared e's old entry keep it, and an entry e alone uses is rewritten in place.
// Every change bumps epoch(), which invalidates what was derived from the rest shapes (a
// linear model's assembled constant tangent, the initial stiffness of Rayleigh damping).
// check_rest_shape(X) is the per-element rest-shape test (positive Jacobian at every corner and
// quadrature point) a plastic update runs before it commits a new shape.
#include <plastifem/core/parallel.hpp>
#include <plastifem/elastic/elastic.hpp>
#include <plastifem/mesh/mesh.hpp>

#include <cstdint>
#include <map>
#include <vector>

namespace plastifem {

template <FiniteElement E, class Model>
  requires ElasticModel<Model, E>
class ElementDataTable {
 public:
  using Data = typename Model::template ElementData<E>;

  ElementDataTable() = default;
  ElementDataTable(const Mesh<E>& mesh, const Material& material) : material_(material) {
    const Index ne = mesh.num_elements();
    std::map<std::vector<Scalar>, std::uint32_t> shape_index;
    shape_of_.resize(ne);
    for (Index e = 0; e < ne; ++e) {
      const ElementNodes<E> X0 = mesh.element_nodes(e);
      const ElementNodes<E> rel = X0.colwise() - X0.col(0);
      auto [it, inserted] = shape_index.try_emplace(std::vector<Scalar>(rel.data(), rel.data() + rel.size()),
                                                    static_cast<std::uint32_t>(data_.size()));
      if (inserted) {
        data_.push_back(Model::template prepare<E>(X0, material));
        users_.push_back(0);
      }
      shape_of_[e] = it->second;
      ++users_[it->second];
    }
    data_.shrink_to_fit();
  }

  /// The data of element e.
  const Data& operator[](Index e) const { return data_[shape_of_[e]]; }
  /// Number of distinct element shapes in use (one for a structured Hex8 grid, six for its
  /// Kuhn Tet4 split; more as plastic flow gives elements shapes of their own).
  Index num_shapes() const { return static_cast<Index>(data_.size()); }
  /// Changes whenever a rest shape does.
  std::uint64_t epoch() const { return epoch_; }
  const Material& material() const { return material_; }

  /// The rest-shape test: det J positive (scale-free, element/element.hpp) at every corner and
  /// quadrature point.
  static ShapeCheck check_rest_shape(const ElementNodes<E>& X) { return check_shape<E>(X); }

  /// Gives element e the rest shape X (its nodes' positions in its own rest space). Throws
  /// InvalidArgument, with the table unchanged, if X fails the rest-shape test (unless the
  /// caller has `checked` it already: the plastic update checks what it proposes).
  void set_rest_shape(Index e, const ElementNodes<E>& X, bool checked = false) {
    if (!checked) {
      const ShapeCheck c = check_rest_shape(X);
      if (!c.valid())
        fail<InvalidArgument>("element {}: rest shape rejected, scaled det J = {:.3g} at {} {}", e,
                              c.min_scaled_jacobian, c.at_corner ? "corner" : "quadrature point", c.where);
    }
    Data d = Model::template prepare<E>(X, material_);
    const std::uint32_t old = shape_of_[e];
    if (users_[old] == 1) {
      data_[old] = std::move(d);  // e alone used it: rewrite in place
    } else {
      --users_[old];  // still used by the others: e gets a new entry
      shape_of_[e] = static_cast<std::uint32_t>(data_.size());
      data_.push_back(std::move(d));
      users_.push_back(1);
    }
    ++epoch_;
  }

  /// set_rest_shape for the distinct elements `elements`, each with its rest shape
  /// `rest_of(e)` as the caller checked it, the preparations on `threads` threads: the
  /// copy-on-write bookkeeping first, serially, then every element's preparation into its own
  /// entry (independent work: a plastic step re-prepares every element it changed).
  template <class RestOf>
  void set_rest_shapes(const std::vector<Index>& elements, RestOf&& rest_of, int threads) {
    if (elements.empty()) return;
    for (Index e : elements) {
      const std::uint32_t old = shape_of_[e];
      if (users_[old] == 1) continue;  // e alone uses it: rewritten in place
      --users_[old];
      shape_of_[e] = static_cast<std::uint32_t>(data_.size());
      data_.push_back(data_[old]);  // a placeholder (not every Data has a default), prepared below
      users_.push_back(1);
    }
    parallel_for(static_cast<Index>(elements.size()), threads, [&](Index k) {
      const Index e = elements[static_cast<size_t>(k)];
      data_[shape_of_[e]] = Model::template prepare<E>(rest_of(e), material_);
    });
    ++epoch_;
  }

 private:
  Material material_;
  std::vector<Data> data_;                ///< one per distinct element shape
  std::vector<std::uint32_t> users_;      ///< elements using each entry (never 0: an entry
                                          ///< only one element uses is rewritten in place)
  std::vector<std::uint32_t> shape_of_;  ///< element -> its shape's entry in data_
  std::uint64_t epoch_ = 0;
};

}  // namespace plastifem
