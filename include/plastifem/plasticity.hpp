#pragma once
// plastifem's plasticity (seed 000): the VertexBlended and CellCentered policies of
// Solver<E, Elastic, Plastic> and the code behind them (plastic/). Included on its own, like the
// readers (mesh/io/io.hpp), so that a file that simulates elastic tissue only does not compile
// it: the umbrella header <plastifem/plastifem.hpp> has the elastic core and NoPlasticity.
#include <plastifem/plastifem.hpp>
#include <plastifem/plastic/cell_centered.hpp>
#include <plastifem/plastic/plastic.hpp>
#include <plastifem/plastic/vertex_blended.hpp>
#include <plastifem/solver/instantiations.hpp>

namespace plastifem {
static_assert(PlasticModel<VertexBlended> && PlasticModel<CellCentered>);
}  // namespace plastifem

// Against plastifem::compiled, the plastic compositions it holds are extern templates
// (solver/instantiations.hpp).
#if defined(PLASTIFEM_USE_COMPILED) && !defined(PLASTIFEM_COMPILED_ELASTIC_ONLY)
#define PLASTIFEM_EXTERN_PLASTIC_SOLVER(E, M, P) \
  extern template class plastifem::Solver<plastifem::E, plastifem::M, plastifem::P>;
PLASTIFEM_PLASTIC_SOLVERS(PLASTIFEM_EXTERN_PLASTIC_SOLVER)
#undef PLASTIFEM_EXTERN_PLASTIC_SOLVER
#endif

// The compositions with both a plastic policy and an enrichment: declared by whichever of
// <plastifem/plasticity.hpp> and <plastifem/cutting.hpp> is included second.
#define PLASTIFEM_PLASTICITY_INCLUDED
#if defined(PLASTIFEM_CUTTING_INCLUDED) && defined(PLASTIFEM_USE_COMPILED) && !defined(PLASTIFEM_COMPILED_ELASTIC_ONLY)
#define PLASTIFEM_EXTERN_PLASTIC_ENRICHED_SOLVER(E, M, P, X) \
  extern template class plastifem::Solver<plastifem::E, plastifem::M, plastifem::P, plastifem::X>;
PLASTIFEM_PLASTIC_ENRICHED_SOLVERS(PLASTIFEM_EXTERN_PLASTIC_ENRICHED_SOLVER)
#undef PLASTIFEM_EXTERN_PLASTIC_ENRICHED_SOLVER
#endif
