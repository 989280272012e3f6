#pragma once
// ShiftedHeaviside (seed 001, eq. 44): psi_i(x) = (H(x) - H_i) / 2, zero at every node, so the
// enriched functions N_i psi_i live on the cut elements only (and on the elements around a node
// lying exactly on the cut), and u_i is node i's physical displacement (the Kronecker-delta
// property): Dirichlet conditions constrain u_i alone. The same space as Heaviside, with
// a_shifted = 2 a_Heaviside and u_shifted = u_Heaviside + H_i a_Heaviside (tested to round-off).
#include <plastifem/enrichment/enrichment.hpp>

namespace plastifem {

struct ShiftedHeaviside {
  static constexpr const char* name = "ShiftedHeaviside";
  static constexpr bool active = true;
  using Params = CutOptions;
  static constexpr Scalar psi(Scalar side, Scalar node) { return 0.5 * (side - node); }
};

}  // namespace plastifem
