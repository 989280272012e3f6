#pragma once
// The enrichment axis of the composition: the EnrichmentModel concept and its three policies.
//
//   NoEnrichment       no cut; compiles to nothing
//   Heaviside          seed 001, eq. 43: enriched functions N_i H(x)
//   ShiftedHeaviside   seed 001, eq. 44: N_i (H(x) - H_i) / 2, local to the cut elements
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

namespace plastifem {

template <class P>
concept EnrichmentModel = requires {
  { P::name } -> std::convertible_to<const char*>;
  { P::active } -> std::convertible_to<bool>;
  { P::shifted } -> std::convertible_to<bool>;
  typename P::Params;
} && (!P::active || std::same_as<typename P::Params, CutOptions>);

static_assert(EnrichmentModel<NoEnrichment>);  // the others: <plastifem/cutting.hpp>

}  // namespace plastifem
