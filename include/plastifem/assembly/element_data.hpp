#pragma once
// ElementDataTable<E, Model>: what an elastic model precomputes per element (K0, shape
// gradients, quadrature weights) from its rest shape, one entry per distinct shape
// (assembly/shared_by_shape.hpp: a structured bar keeps one 24 x 24 K0 instead of one per hex,
// bar46080 CorotationalPerElement 403 -> 190 MB of solver heap, streamed from cache instead of
// memory), and rest shapes that can change during a run (plasticity), copy-on-write.
//
// Every change bumps epoch(), which invalidates what was derived from the rest shapes (a
// linear model's assembled constant tangent, a constant tangent's Rayleigh damping stiffness,
// the real-time step's linearisation: each records the epoch it was made at).
// check_rest_shape(X) is the per-element rest-shape test (positive Jacobian at every corner and
// quadrature point) a plastic update runs before it commits a new shape.
#include <plastifem/assembly/shared_by_shape.hpp>
#include <plastifem/elastic/elastic.hpp>

#include <cstdint>
#include <span>
#include <vector>

namespace plastifem {

template <FiniteElement E, class Model>
  requires ElasticModel<Model, E>
class ElementDataTable {
 public:
  using Data = typename Model::template ElementData<E>;

  ElementDataTable() = default;
  ElementDataTable(const Mesh<E>& mesh, const Material& material)
      : material_(material), data_(mesh, [&](const ElementNodes<E>& X0) { return Model::template prepare<E>(X0, material); }) {}

  /// The data of element e.
  const Data& operator[](Index e) const { return data_[e]; }
  /// Number of distinct element shapes in use (one for a structured Hex8 grid, six for its
  /// Kuhn Tet4 split; more as plastic flow gives elements shapes of their own).
  Index num_shapes() const { return data_.num_shapes(); }
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
    data_.reshape(std::span<const Index>(&e, 1), [&](Index) { return Model::template prepare<E>(X, material_); }, 1);
    ++epoch_;
  }

  /// set_rest_shape for the distinct elements `elements`, each with its rest shape
  /// `rest_of(e)` as the caller checked it, prepared on `threads` threads (a plastic step
  /// re-prepares every element it changed).
  template <class RestOf>
  void set_rest_shapes(const std::vector<Index>& elements, RestOf&& rest_of, int threads) {
    if (elements.empty()) return;
    data_.reshape(elements, [&](Index e) { return Model::template prepare<E>(rest_of(e), material_); }, threads);
    ++epoch_;
  }

 private:
  Material material_;
  SharedByShape<E, Data> data_;
  std::uint64_t epoch_ = 0;
};

}  // namespace plastifem
