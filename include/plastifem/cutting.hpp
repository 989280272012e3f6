#pragma once
// plastifem's cutting without remeshing (X-FEM, seed 001): the Heaviside and ShiftedHeaviside
// policies of Solver<E, Elastic, NoPlasticity, Enrich>, the cut geometries (CutPlane, CutPatch,
// CutSurface) and the code behind them (enrichment/). Included on its own, like the readers
// (mesh/io/io.hpp), so that a file that cuts nothing does not compile it: the umbrella header
// <plastifem/plastifem.hpp> has the elastic core and NoEnrichment. The VTU output that shows the
// opened cut is in <plastifem/enrichment/output.hpp> (it needs the writers).
#include <plastifem/plastifem.hpp>
#include <plastifem/enrichment/enrichment_policy.hpp>
#include <plastifem/enrichment/heaviside.hpp>
#include <plastifem/enrichment/shifted.hpp>
#include <plastifem/solver/instantiations.hpp>

namespace plastifem {
static_assert(EnrichmentModel<Heaviside> && EnrichmentModel<ShiftedHeaviside>);
}  // namespace plastifem

// Against plastifem::compiled, the cut compositions it holds are extern templates
// (solver/instantiations.hpp).
#if defined(PLASTIFEM_USE_COMPILED) && !defined(PLASTIFEM_COMPILED_ELASTIC_ONLY)
#define PLASTIFEM_EXTERN_ENRICHED_SOLVER(E, M, X) \
  extern template class plastifem::Solver<plastifem::E, plastifem::M, plastifem::NoPlasticity, plastifem::X>;
PLASTIFEM_ENRICHED_SOLVERS(PLASTIFEM_EXTERN_ENRICHED_SOLVER)
#undef PLASTIFEM_EXTERN_ENRICHED_SOLVER
#endif

// The compositions with both a plastic policy and an enrichment: declared by whichever of
// <plastifem/plasticity.hpp> and <plastifem/cutting.hpp> is included second.
#define PLASTIFEM_CUTTING_INCLUDED
#if defined(PLASTIFEM_PLASTICITY_INCLUDED) && defined(PLASTIFEM_USE_COMPILED) && !defined(PLASTIFEM_COMPILED_ELASTIC_ONLY)
#define PLASTIFEM_EXTERN_PLASTIC_ENRICHED_SOLVER(E, M, P, X) \
  extern template class plastifem::Solver<plastifem::E, plastifem::M, plastifem::P, plastifem::X>;
PLASTIFEM_PLASTIC_ENRICHED_SOLVERS(PLASTIFEM_EXTERN_PLASTIC_ENRICHED_SOLVER)
#undef PLASTIFEM_EXTERN_PLASTIC_ENRICHED_SOLVER
#endif
