#pragma once
// ElementDataTable<E, Model>: what an elastic model precomputes per element (K0, shape
// gradients, quadrature weights), prepared once from the rest shapes, with one entry per
// distinct shape.
//
// Elements whose rest positions relative to their first node are equal bit for bit
// (translated copies: every cell of a structured grid) share one entry, since the models
// difference positions relative to node 0 and their data depends only on that shape. A
// structured bar keeps one 24 x 24 K0 instead of one per hex (bar46080
// CorotationalPerElement: 403 -> 190 MB of solver heap) and streams it from cache instead of
// memory.
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
  ElementDataTable(const Mesh<E>& mesh, const Material& material) {
    const Index ne = mesh.num_elements();
    std::map<std::vector<Scalar>, std::uint32_t> shape_index;
    shape_of_.resize(ne);
    for (Index e = 0; e < ne; ++e) {
      const ElementNodes<E> X0 = mesh.element_nodes(e);
      const ElementNodes<E> rel = X0.colwise() - X0.col(0);
      auto [it, inserted] = shape_index.try_emplace(std::vector<Scalar>(rel.data(), rel.data() + rel.size()),
                                                    static_cast<std::uint32_t>(data_.size()));
      if (inserted) data_.push_back(Model::template prepare<E>(X0, material));
      shape_of_[e] = it->second;
    }
    data_.shrink_to_fit();
  }

  /// The data of element e.
  const Data& operator[](Index e) const { return data_[shape_of_[e]]; }
  /// Number of distinct element shapes (one for a structured Hex8 grid, six for its Kuhn
  /// Tet4 split).
  Index num_shapes() const { return static_cast<Index>(data_.size()); }

 private:
  std::vector<Data> data_;                ///< one per distinct element shape
  std::vector<std::uint32_t> shape_of_;  ///< element -> its shape's entry in data_
};

}  // namespace plastifem
