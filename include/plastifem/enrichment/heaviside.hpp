#pragma once
// Heaviside (seed 001, eq. 43): the enriched dofs' function is the generalised Heaviside
// function H(x) = +1 above the cut (and on it), -1 below. Its enriched basis functions N_i H
// reach into every element around an enriched node (the blending elements), and a node's
// displacement is u_i + H_i a_i, not u_i: a Dirichlet condition on an enriched node therefore
// also holds its enriched dofs at zero (the solver does this), which keeps the node where it is
// prescribed on both sides of the cut. ShiftedHeaviside spans the same space with local
// functions and u_i the physical displacement. Implementation: enrichment/enrichment.hpp,
// enrichment/cut_element.hpp.
#include <plastifem/enrichment/enrichment.hpp>

namespace plastifem {

struct Heaviside {
  static constexpr const char* name = "Heaviside";
  static constexpr bool active = true;
  using Params = CutOptions;
  static constexpr Scalar psi(Scalar side, Scalar /*node*/) { return side; }
};

}  // namespace plastifem
