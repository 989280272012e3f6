#pragma once
// The plastic axis of the composition: the PlasticModel concept and its three policies.
//
//   NoPlasticity    rest shapes never change; compiles to nothing
//   VertexBlended   seed 000: plastic stretch and rotation per vertex (eq. 4-5)
//   CellCentered    seed 000: plastic stretch per vertex, rotation per element (eq. 4, 6)
//
// The policies are small types; what they do is in plastic/flow.hpp (one element's flow, the
// formulas), plastic/fusion.hpp (the material mesh) and plastic/plasticity.hpp (a body's
// update and its link to the element data). This header is light: the Solver includes it.
// The active policies, with the code behind them, come with <plastifem/plasticity.hpp>, so an
// elastic file does not compile them.
#include <plastifem/plastic/none.hpp>
#include <plastifem/plastic/params.hpp>

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
  typename P::State;  // its part of the Solver's State
  // and `template <FiniteElement E, class Elastic> using Engine`: its update (plastic/plasticity.hpp)
});

static_assert(PlasticModel<NoPlasticity>);  // the others: <plastifem/plasticity.hpp>

}  // namespace plastifem
