#pragma once
// The names the Solver's cutting interface uses, without their implementation: the cut
// geometries (declared; defined in enrichment/level_set.hpp), the options of a cut, its handle
// and its report. Solver.hpp needs only these, so a file that cuts nothing does not compile the
// X-FEM code (include <plastifem/cutting.hpp> to cut).
#include <plastifem/core/error.hpp>
#include <plastifem/core/handle_owner.hpp>
#include <plastifem/core/types.hpp>

#include <variant>

namespace plastifem {

/// An active enrichment's function psi(side, node) (enrichment/enrichment_policy.hpp), as the
/// cut code takes it.
using EnrichmentFunction = Scalar (*)(Scalar side, Scalar node);

struct CutPlane;
struct CutPatch;
class CutSurface;
/// Any of the three cut geometries (enrichment/level_set.hpp).
using Cut = std::variant<CutPlane, CutPatch, CutSurface>;

/// How a cut is applied (defaults documented in enrichment/enrichment.hpp).
struct CutOptions {
  /// A node closer to the cut than snap x (the shortest edge of its elements) is moved onto it.
  Scalar snap = 0.01;
  /// A node whose support has less than this fraction of its volume on one side is not enriched.
  Scalar min_fragment = 1e-4;
  /// A cut element's stiffness rule on each side: the sub-tetrahedra's rules (degree 4 for Hex8,
  /// 2 for Tet10 and Wedge6) compressed to at most as many points as the integrand of linear
  /// elasticity has polynomials (Hex8 23, Tet10 and Wedge6 10; Tet4 keeps one point per piece),
  /// with the same integrals of them: the same stiffness on an affine element, a tenth of the
  /// points for Hex8 (enrichment/subdivision.hpp). false keeps every sub-tetrahedron's points (the thesis'
  /// sub-element integration: up to ~250 per side of a Hex8).
  bool compress_quadrature = true;

  void validate() const {
    if (!(snap >= 0 && snap < 0.5)) fail<InvalidArgument>("cut: snap = {} must be in [0, 0.5)", snap);
    if (!(min_fragment >= 0 && min_fragment < 0.5))
      fail<InvalidArgument>("cut: min_fragment = {} must be in [0, 0.5)", min_fragment);
  }
};

/// Identifies a cut applied to a solver (to grow it later), of that solver only
/// (core/handle_owner.hpp).
struct CutHandle {
  int id = -1;              ///< -1: none
  std::uint32_t owner = 0;  ///< the issuing solver's HandleOwner number for cuts
};

/// What applying a cut did.
struct CutReport {
  int cut_elements = 0;       ///< elements the cut crosses (new ones, for a growing cut)
  int blending_elements = 0;  ///< uncut elements that couple enriched dofs
  int enriched_nodes = 0;     ///< nodes that got an enriched dof block (new ones)
  int snapped_nodes = 0;      ///< nodes moved onto the cut (level set set to 0)
  int dropped_nodes = 0;      ///< nodes of cut elements left unenriched (sliver support)
  Index dofs_added = 0;
  int stiffness_points = 0;   ///< integration points of the new cut elements' sides (stiffness rule)
  int plastic_frozen = 0;     ///< with a plastic policy: enriched elements whose plastic flow stopped
  double ms = 0;              ///< time to classify, split and extend the dof map (not the solver's rebuild)
};

}  // namespace plastifem
