#pragma once
// The Solver types the optional compiled library (CMake target plastifem::compiled) holds,
// instantiated once. A translation unit built against that target (it defines
// PLASTIFEM_USE_COMPILED) declares them `extern template`: their member functions are then
// neither instantiated nor optimised in that translation unit but linked from the library.
// A file using one Solver<Hex8, Corotational> and stepping it compiles in ~4 s instead of ~18
// (README, "Build time"). Other compositions are instantiated where they are used, as usual.
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

#ifdef PLASTIFEM_USE_COMPILED
#define PLASTIFEM_EXTERN_SOLVER(E, M) extern template class plastifem::Solver<plastifem::E, plastifem::M>;
PLASTIFEM_COMMON_SOLVERS(PLASTIFEM_EXTERN_SOLVER)
#undef PLASTIFEM_EXTERN_SOLVER
#endif
