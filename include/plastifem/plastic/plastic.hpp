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
#include <cstdint>
#include <type_traits>
#include <vector>

namespace plastifem {

/// A plastic policy: a name, whether it is active, its parameters, and for an active one what
/// the Solver's hooks (plastic/hooks.hpp) and State (solver/state.hpp) use: parameters that
/// validate themselves and say how much time a static solve flows over; a State (its part of
/// the Solver's State: copied, swapped and compared bit for bit) with the material mesh `rest`
/// (a Vector, 3 per node), a `version` that changes whenever the rest shapes do, and per
/// element an `off` flag, 0 while it flows, that a cut sets to State::cut; and an Engine
/// (PlasticEngine).
template <class P>
concept PlasticModel = requires {
  { P::name } -> std::convertible_to<const char*>;
  { P::active } -> std::convertible_to<bool>;
  typename P::Params;
} && (!P::active || requires(const typename P::Params& prm, typename P::State& s) {
  prm.validate();
  { prm.static_time } -> std::convertible_to<Scalar>;
  requires std::copyable<typename P::State> && std::swappable<typename P::State>;
  requires std::same_as<std::remove_cvref_t<decltype(s.rest)>, Vector>;
  { s.version } -> std::convertible_to<std::uint64_t>;
  { s.off[0] == 0 } -> std::convertible_to<bool>;
  s.off[0] = P::State::cut;
  { s == s } -> std::convertible_to<bool>;
  // and `template <FiniteElement E, class Elastic> using Engine`, a PlasticEngine
});

/// An active policy's Engine for a body type: what the hooks call (plastic/hooks.hpp).
///   init(body, params, state)        the first state: rest = the mesh, nothing flowed
///   sync(body, state, threads)       the body's element data to the state's rest shapes; true if changed
///   update(body, u, dt, params, state, version, threads, anchor)
///                                    the flow after a converged step of dt that ended at u; on
///                                    change, the state gets the new rest shapes and `version`;
///                                    anchor: per node, where the material mesh stays put
///   change_params(old, new, state)   new parameters mid-run
///   pattern_changed()                the dof map changed (a cut)
template <class Engine, class Policy, class Body>
concept PlasticEngine = std::default_initializable<Engine> && requires(Engine& en, Body& body, const Body& cbody, const Vector& u,
                                 const typename Policy::Params& prm, typename Policy::State& s,
                                 const typename Policy::State& cs, std::uint64_t version,
                                 const std::vector<char>& anchor) {
  en.init(cbody, prm, s);
  { en.sync(body, cs, 1) } -> std::convertible_to<bool>;
  { en.update(cbody, u, Scalar{}, prm, s, version, 1, anchor) } -> std::same_as<PlasticReport>;
  en.change_params(prm, prm, s);
  en.pattern_changed();
};

static_assert(PlasticModel<NoPlasticity>);  // the others: <plastifem/plasticity.hpp>

}  // namespace plastifem
