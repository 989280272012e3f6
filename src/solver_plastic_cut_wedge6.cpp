// Plasticity and cutting in one Solver, on Wedge6: a source file of its own, so that the library
// builds in parallel.
#include "instantiate.hpp"
PLASTIFEM_PLASTIC_ENRICHED_SOLVERS_OF(PLASTIFEM_INSTANTIATE_PLASTIC_ENRICHED_SOLVER, Wedge6)
