#pragma once
// The enrichment axis of the composition: the EnrichmentModel concept and its three policies.
//
//   NoEnrichment       no cut; compiles to nothing
//   Heaviside          seed 001, eq. 43: enriched functions N_i H(x)
//   ShiftedHeaviside   seed 001, eq. 44: N_i (H(x) - H_i) / 2, local to the cut elements
//
// An active policy is its enrichment function: psi(side, node), the value on the side of the
// cut where the generalised Heaviside function H is `side` (+1 above the cut and on it, -1
// below) of the enriched function of a node where H is `node`; node i's enriched basis
// function is N_i psi(H(x), H_i). The library asks nothing else of it: which elements carry a
// node's enriched dofs follows from where psi is not zero, a node's displacement is
// u_i + psi(H_i, H_i) a_i, and a Dirichlet condition holds a node's enriched dofs too.
// psi must be constexpr (whether it vanishes at the nodes is decided at compile time).
//
// This header is light: the Solver includes it. The active policies and the X-FEM code behind
// them come with <plastifem/cutting.hpp>, so a file that cuts nothing does not compile them.
// Cuts are applied with Solver::cut (a plane, a bounded patch or a triangulated surface,
// enrichment/level_set.hpp), any number of times during a run; what a cut does to the body is in
// enrichment/enrichment.hpp, the enriched element integrals in enrichment/cut_element.hpp, the
// sub-element quadrature in enrichment/subdivision.hpp, and the output that shows the opened cut
// in enrichment/output.hpp.
#include <plastifem/enrichment/cut_types.hpp>
#include <plastifem/enrichment/none.hpp>

#include <concepts>
#include <type_traits>

namespace plastifem {

template <class P>
concept EnrichmentModel = requires {
  { P::name } -> std::convertible_to<const char*>;
  { P::active } -> std::convertible_to<bool>;
  typename P::Params;
} && (!P::active || (std::same_as<typename P::Params, CutOptions> && requires {
                       // a function the cut code can hold (EnrichmentFunction), and constexpr
                       { &P::psi } -> std::convertible_to<EnrichmentFunction>;
                       typename std::bool_constant<(P::psi(Scalar(1), Scalar(1)) == P::psi(Scalar(1), Scalar(1)))>;
                     }));

/// Whether an active enrichment's functions vanish at every node (psi(H, H) = 0 on both sides):
/// then u_i is node i's physical displacement (the Kronecker-delta property).
template <class P>
constexpr bool vanishes_at_nodes() {
  return P::psi(1, 1) == 0 && P::psi(-1, -1) == 0;
}

static_assert(EnrichmentModel<NoEnrichment>);  // the others: <plastifem/cutting.hpp>

}  // namespace plastifem
