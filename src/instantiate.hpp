// Explicit instantiation definitions of the compiled compositions (solver/instantiations.hpp:
// the one list), in the source files CMakeLists.txt generates from that list: one per element,
// so that the library builds in parallel, and one for Hex8's mean-dilatation models.
#include <plastifem/cutting.hpp>
#include <plastifem/plasticity.hpp>

#define PLASTIFEM_INSTANTIATE_SOLVER(E, M) template class plastifem::Solver<plastifem::E, plastifem::M>;
#ifdef PLASTIFEM_COMPILED_ELASTIC_ONLY  // PLASTIFEM_COMPILED_POLICIES=OFF: the elastic types only
#define PLASTIFEM_INSTANTIATE_PLASTIC_SOLVER(E, M, P)
#define PLASTIFEM_INSTANTIATE_ENRICHED_SOLVER(E, M, X)
#define PLASTIFEM_INSTANTIATE_PLASTIC_ENRICHED_SOLVER(E, M, P, X)
#else
#define PLASTIFEM_INSTANTIATE_PLASTIC_SOLVER(E, M, P) template class plastifem::Solver<plastifem::E, plastifem::M, plastifem::P>;
#define PLASTIFEM_INSTANTIATE_ENRICHED_SOLVER(E, M, X) \
  template class plastifem::Solver<plastifem::E, plastifem::M, plastifem::NoPlasticity, plastifem::X>;
#define PLASTIFEM_INSTANTIATE_PLASTIC_ENRICHED_SOLVER(E, M, P, X) \
  template class plastifem::Solver<plastifem::E, plastifem::M, plastifem::P, plastifem::X>;
#endif
