#pragma once
// The Solver types the optional compiled library (CMake target plastifem::compiled) holds,
// instantiated once. A translation unit built against that target (it defines
// PLASTIFEM_USE_COMPILED) declares them `extern template`: their member functions are then
// neither instantiated nor optimised in that translation unit but linked from the library.
// A file using one Solver<Hex8, Corotational> and stepping it compiles in a third of the time
// (docs/build_time.md). Other compositions are instantiated where they are used, as usual.
//
// This file is the one list of compositions, macros only (it includes nothing, so a test can
// take its lists without compiling the Solver):
// - the library's source files, which CMake generates from it (one per element, through
//   src/instantiate.hpp), instantiate it;
// - solver_members.hpp (included at the end of solver.hpp) declares its elastic types extern,
//   the policy headers (<plastifem/plasticity.hpp>, <plastifem/cutting.hpp>) its plastic and cut
//   types;
// - the tests take their element and composition lists from it (tests/compositions.hpp): the
//   per-composition test runs every entry, and every test of "each element" runs each element.
// A new elastic model is one entry in PLASTIFEM_MODELS (and in PLASTIFEM_POLICY_MODELS to be
// compiled with the policies); a new element is one entry in PLASTIFEM_FOR_EACH_ELEMENT besides
// its header (docs/architecture.md, "Adding an element").

// Every element (F(X, Element)): the lists below apply their per-element lists through it.
#define PLASTIFEM_FOR_EACH_ELEMENT(F, X) F(X, Tet4) F(X, Tet10) F(X, Hex8) F(X, Wedge6)

// Every elastic model, instantiated on every element (X(Element, Model)).
#define PLASTIFEM_MODELS(X, E)                                                                               \
  X(E, Linear) X(E, Corotational) X(E, CorotationalPerElement) X(E, NeoHookean) X(E, NeoHookeanAbaqus)       \
  X(E, StableNeoHookean) X(E, MooneyRivlin)
// The mean-dilatation variants, on Hex8 only: the element they are for (on Tet4 they equal the
// full models).
#define PLASTIFEM_MEAN_DILATATION_MODELS(X, E)                                                               \
  X(E, LinearMeanDilatation) X(E, CorotationalMeanDilatation) X(E, NeoHookeanMeanDilatation)                 \
  X(E, NeoHookeanAbaqusMeanDilatation) X(E, StableNeoHookeanMeanDilatation) X(E, MooneyRivlinMeanDilatation)
// The models compiled with each plastic policy and each enrichment (X(Element, Model, Policy)):
// the elastic families (linear, corotational per point and per element, Neo-Hookean).
#define PLASTIFEM_POLICY_MODELS(X, E, P)                                                                     \
  X(E, Linear, P) X(E, Corotational, P) X(E, CorotationalPerElement, P) X(E, NeoHookean, P)
#define PLASTIFEM_PLASTIC_MEAN_DILATATION_MODELS(X, E, P) X(E, CorotationalMeanDilatation, P) X(E, NeoHookeanMeanDilatation, P)
// The tissue models compiled with plasticity and cutting together (X(Element, Model, Plastic,
// Enrichment)): a plastically deformed organ that is cut.
#define PLASTIFEM_TISSUE_MODELS(X, E, P, C) X(E, Corotational, P, C) X(E, CorotationalPerElement, P, C) X(E, NeoHookean, P, C)

// Per element: what one source file of the library compiles.
#define PLASTIFEM_ELASTIC_SOLVERS_OF(X, E) PLASTIFEM_MODELS(X, E)
#define PLASTIFEM_PLASTIC_SOLVERS_OF(X, E)                                                                   \
  PLASTIFEM_POLICY_MODELS(X, E, VertexBlended) PLASTIFEM_POLICY_MODELS(X, E, CellCentered)
#define PLASTIFEM_ENRICHED_SOLVERS_OF(X, E)                                                                  \
  PLASTIFEM_POLICY_MODELS(X, E, Heaviside) PLASTIFEM_POLICY_MODELS(X, E, ShiftedHeaviside)
#define PLASTIFEM_PLASTIC_ENRICHED_SOLVERS_OF(X, E)                                                          \
  PLASTIFEM_TISSUE_MODELS(X, E, VertexBlended, Heaviside) PLASTIFEM_TISSUE_MODELS(X, E, VertexBlended, ShiftedHeaviside) \
  PLASTIFEM_TISSUE_MODELS(X, E, CellCentered, Heaviside) PLASTIFEM_TISSUE_MODELS(X, E, CellCentered, ShiftedHeaviside)
// Hex8's mean-dilatation models, in a source file of their own (the library builds in parallel).
#define PLASTIFEM_ELASTIC_SOLVERS_OF_HEX8_MEAN_DILATATION(X) PLASTIFEM_MEAN_DILATATION_MODELS(X, Hex8)
#define PLASTIFEM_PLASTIC_SOLVERS_OF_HEX8_MEAN_DILATATION(X)                                                 \
  PLASTIFEM_PLASTIC_MEAN_DILATATION_MODELS(X, Hex8, VertexBlended) PLASTIFEM_PLASTIC_MEAN_DILATATION_MODELS(X, Hex8, CellCentered)

// The whole list, by kind.
#define PLASTIFEM_ELASTIC_SOLVERS(X)                                                                         \
  PLASTIFEM_FOR_EACH_ELEMENT(PLASTIFEM_ELASTIC_SOLVERS_OF, X) PLASTIFEM_ELASTIC_SOLVERS_OF_HEX8_MEAN_DILATATION(X)
#define PLASTIFEM_PLASTIC_SOLVERS(X)                                                                         \
  PLASTIFEM_FOR_EACH_ELEMENT(PLASTIFEM_PLASTIC_SOLVERS_OF, X) PLASTIFEM_PLASTIC_SOLVERS_OF_HEX8_MEAN_DILATATION(X)
#define PLASTIFEM_ENRICHED_SOLVERS(X) PLASTIFEM_FOR_EACH_ELEMENT(PLASTIFEM_ENRICHED_SOLVERS_OF, X)
#define PLASTIFEM_PLASTIC_ENRICHED_SOLVERS(X) PLASTIFEM_FOR_EACH_ELEMENT(PLASTIFEM_PLASTIC_ENRICHED_SOLVERS_OF, X)
