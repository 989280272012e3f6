#pragma once
// The Solver types the optional compiled library (CMake target plastifem::compiled) holds,
// instantiated once. A translation unit built against that target (it defines
// PLASTIFEM_USE_COMPILED) declares them `extern template`: their member functions are then
// neither instantiated nor optimised in that translation unit but linked from the library.
// A file using one Solver<Hex8, Corotational> and stepping it compiles in a third of the time
// (docs/build_time.md). Other compositions are instantiated where they are used, as usual.
//
// Every elastic model on every element, and the mean-dilatation variants on Hex8 (the element
// they are for; on Tet4 they equal the full models).
#define PLASTIFEM_COMMON_SOLVERS(X)                                                                          \
  X(Tet4, Linear)                                                                                            \
  X(Tet4, Corotational)                                                                                      \
  X(Tet4, CorotationalPerElement)                                                                            \
  X(Tet4, NeoHookean)                                                                                        \
  X(Tet4, NeoHookeanAbaqus)                                                                                  \
  X(Tet4, StableNeoHookean)                                                                                  \
  X(Tet10, Linear)                                                                                           \
  X(Tet10, Corotational)                                                                                     \
  X(Tet10, CorotationalPerElement)                                                                           \
  X(Tet10, NeoHookean)                                                                                       \
  X(Tet10, NeoHookeanAbaqus)                                                                                 \
  X(Tet10, StableNeoHookean)                                                                                 \
  X(Hex8, Linear)                                                                                            \
  X(Hex8, Corotational)                                                                                      \
  X(Hex8, CorotationalPerElement)                                                                            \
  X(Hex8, NeoHookean)                                                                                        \
  X(Hex8, NeoHookeanAbaqus)                                                                                  \
  X(Hex8, StableNeoHookean)                                                                                  \
  X(Hex8, LinearMeanDilatation)                                                                              \
  X(Hex8, CorotationalMeanDilatation)                                                                        \
  X(Hex8, NeoHookeanMeanDilatation)                                                                          \
  X(Hex8, NeoHookeanAbaqusMeanDilatation)                                                                    \
  X(Hex8, StableNeoHookeanMeanDilatation)

// The plastic compositions (seed 000): both policies with the elastic families on every element
// (Linear, Corotational per point and per element, Neo-Hookean), and the mean-dilatation
// models on Hex8. Compiled beside the elastic Solver of the same element and model, they share
// its dynamics, statics and assembly: each adds ~3.5 s of CPU to the library.
#define PLASTIFEM_PLASTIC_SOLVERS(X)                                                                         \
  X(Tet4, Linear, VertexBlended)                                                                             \
  X(Tet4, Linear, CellCentered)                                                                              \
  X(Tet4, Corotational, VertexBlended)                                                                       \
  X(Tet4, Corotational, CellCentered)                                                                        \
  X(Tet4, CorotationalPerElement, VertexBlended)                                                             \
  X(Tet4, CorotationalPerElement, CellCentered)                                                              \
  X(Tet4, NeoHookean, VertexBlended)                                                                         \
  X(Tet4, NeoHookean, CellCentered)                                                                          \
  X(Tet10, Linear, VertexBlended)                                                                            \
  X(Tet10, Linear, CellCentered)                                                                             \
  X(Tet10, Corotational, VertexBlended)                                                                      \
  X(Tet10, Corotational, CellCentered)                                                                       \
  X(Tet10, CorotationalPerElement, VertexBlended)                                                            \
  X(Tet10, CorotationalPerElement, CellCentered)                                                             \
  X(Tet10, NeoHookean, VertexBlended)                                                                        \
  X(Tet10, NeoHookean, CellCentered)                                                                         \
  X(Hex8, Linear, VertexBlended)                                                                             \
  X(Hex8, Linear, CellCentered)                                                                              \
  X(Hex8, Corotational, VertexBlended)                                                                       \
  X(Hex8, Corotational, CellCentered)                                                                        \
  X(Hex8, CorotationalPerElement, VertexBlended)                                                             \
  X(Hex8, CorotationalPerElement, CellCentered)                                                              \
  X(Hex8, NeoHookean, VertexBlended)                                                                         \
  X(Hex8, NeoHookean, CellCentered)                                                                          \
  X(Hex8, CorotationalMeanDilatation, VertexBlended)                                                         \
  X(Hex8, CorotationalMeanDilatation, CellCentered)                                                          \
  X(Hex8, NeoHookeanMeanDilatation, VertexBlended)                                                           \
  X(Hex8, NeoHookeanMeanDilatation, CellCentered)

// The cut compositions (seed 001): both enrichments with the elastic families on every element.
#define PLASTIFEM_ENRICHED_SOLVERS(X)                                                                        \
  X(Tet4, Linear, Heaviside) \
  X(Tet4, Linear, ShiftedHeaviside) \
  X(Tet4, Corotational, Heaviside) \
  X(Tet4, Corotational, ShiftedHeaviside) \
  X(Tet4, CorotationalPerElement, Heaviside) \
  X(Tet4, CorotationalPerElement, ShiftedHeaviside) \
  X(Tet4, NeoHookean, Heaviside) \
  X(Tet4, NeoHookean, ShiftedHeaviside) \
  X(Tet10, Linear, Heaviside) \
  X(Tet10, Linear, ShiftedHeaviside) \
  X(Tet10, Corotational, Heaviside) \
  X(Tet10, Corotational, ShiftedHeaviside) \
  X(Tet10, CorotationalPerElement, Heaviside) \
  X(Tet10, CorotationalPerElement, ShiftedHeaviside) \
  X(Tet10, NeoHookean, Heaviside) \
  X(Tet10, NeoHookean, ShiftedHeaviside) \
  X(Hex8, Linear, Heaviside) \
  X(Hex8, Linear, ShiftedHeaviside) \
  X(Hex8, Corotational, Heaviside) \
  X(Hex8, Corotational, ShiftedHeaviside) \
  X(Hex8, CorotationalPerElement, Heaviside) \
  X(Hex8, CorotationalPerElement, ShiftedHeaviside) \
  X(Hex8, NeoHookean, Heaviside) \
  X(Hex8, NeoHookean, ShiftedHeaviside)

// The extern declarations of the elastic types are here; those of the plastic and cut types are
// in <plastifem/plasticity.hpp> and <plastifem/cutting.hpp>, which define those policies.
#ifdef PLASTIFEM_USE_COMPILED
#define PLASTIFEM_EXTERN_SOLVER(E, M) extern template class plastifem::Solver<plastifem::E, plastifem::M>;
PLASTIFEM_COMMON_SOLVERS(PLASTIFEM_EXTERN_SOLVER)
#undef PLASTIFEM_EXTERN_SOLVER
#endif
