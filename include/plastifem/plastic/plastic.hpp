#pragma once
// The plastic axis of the composition: the PlasticModel concept and its three policies.
//
//   NoPlasticity    rest shapes never change; compiles to nothing
//   VertexBlended   seed 000: plastic stretch and rotation per vertex (eq. 4-5)
//   CellCentered    seed 000: plastic stretch per vertex, rotation per element (eq. 4, 6)
//
// The policies are small types; what they do is in plastic/flow.hpp (one element's flow, the
// formulas), plastic/fusion.hpp (the material mesh) and plastic/plasticity.hpp (a body's
// update and its link to the element data).
#include <plastifem/plastic/cell_centered.hpp>
#include <plastifem/plastic/none.hpp>
#include <plastifem/plastic/vertex_blended.hpp>

#include <concepts>

namespace plastifem {

/// A plastic policy: a name, whether it is active, its parameters, and for an active one
/// where its plastic rotation lives (per vertex, or one per element).
template <class P>
concept PlasticModel = requires {
  { P::name } -> std::convertible_to<const char*>;
  { P::active } -> std::convertible_to<bool>;
  typename P::Params;
} && (!P::active || requires {
  { P::per_vertex_rotation } -> std::convertible_to<bool>;
  requires std::same_as<typename P::Params, PlasticParams>;
});

static_assert(PlasticModel<NoPlasticity> && PlasticModel<VertexBlended> && PlasticModel<CellCentered>);

}  // namespace plastifem
