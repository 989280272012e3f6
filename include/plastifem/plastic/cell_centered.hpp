#pragma once
// CellCentered (seed 000): plastic stretch per vertex (or Gauss point) as VertexBlended, and
// one rigid plastic rotation per element at its centre, R_o^eta~ with eta~ from the largest
// vertex distortion phi~ = max_i phi_i (eq. 6). An element keeps its box shape; the twist
// shows in how the elements are turned against each other once fused into the material mesh,
// which distorts the cross-section more than VertexBlended (the paper's Fig. 6).
#include <plastifem/plastic/params.hpp>
#include <plastifem/plastic/plasticity.hpp>

namespace plastifem {

struct CellCentered {
  static constexpr const char* name = "CellCentered";
  static constexpr bool active = true;
  static constexpr bool per_vertex_rotation = false;
  using Params = PlasticParams;
  /// What the Solver keeps in its State, and the update it runs (plastic/plasticity.hpp).
  using State = PlasticTable;
  template <FiniteElement E, class Elastic>
  using Engine = plastic::Plasticity<E, Elastic, per_vertex_rotation>;
};

}  // namespace plastifem
