#pragma once
// NoEnrichment: no cut, no enriched dofs; the dof map is 3 per node. The solver's enrichment
// hooks compile to nothing for it.
namespace plastifem {

struct NoEnrichment {
  static constexpr const char* name = "NoEnrichment";
  static constexpr bool active = false;
  struct Params {};
};

}  // namespace plastifem
