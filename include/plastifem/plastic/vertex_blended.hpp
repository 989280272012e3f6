#pragma once
// VertexBlended (seed 000): plastic stretch and plastic rotation per vertex, from the blended
// gradients Fbar_i = (F_i + F_o) / 2 (eq. 4-5, 7-8). The per-vertex rotations let an element
// take a plastic twist or bend of its own: it keeps the cross-section's shape under twist
// better than CellCentered, and distorts each element more. The formulas are in
// plastic/flow.hpp, the update in plastic/plasticity.hpp.
#include <plastifem/plastic/params.hpp>
#include <plastifem/plastic/plasticity.hpp>

namespace plastifem {

struct VertexBlended {
  static constexpr const char* name = "VertexBlended";
  static constexpr bool active = true;
  static constexpr bool per_vertex_rotation = true;
  using Params = PlasticParams;
  /// What the Solver keeps in its State, and the update it runs (plastic/plasticity.hpp).
  using State = PlasticTable;
  template <FiniteElement E, class Elastic>
  using Engine = plastic::Plasticity<E, Elastic, per_vertex_rotation>;
};

}  // namespace plastifem
