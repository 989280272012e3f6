#pragma once
// Boundary conditions and loads, stored as the solver needs them at step time: constrained
// dofs with a displacement that may vary in time, and external force vectors precomputed once
// (consistent nodal loads) and scaled by a load curve.
#include <plastifem/assembly/assembler.hpp>

#include <functional>

namespace plastifem {

/// Scales a load or a prescribed displacement over time; default: constant 1.
using LoadCurve = std::function<Scalar(Scalar time)>;

/// Ramp 0 -> 1 over [0, t_ramp], hold until t_release, then 0: the grasper pull of seed 000
/// Fig. 1 and the stretch profile of SCENES.md.
inline LoadCurve ramp_hold_release(Scalar t_ramp, Scalar t_release) {
  return [=](Scalar t) { return t >= t_release ? 0.0 : (t_ramp > 0 ? std::min(t / t_ramp, 1.0) : 1.0); };
}

/// Which displacement components a constraint fixes.
struct DofMask {
  bool x = true, y = true, z = true;
  bool operator[](int d) const { return d == 0 ? x : d == 1 ? y : z; }
};

/// Displacement of a constrained node: at time t, for rest position X.
using PrescribedDisplacement = std::function<Vec3(Scalar time, const Vec3& rest_position)>;

struct DirichletCondition {
  std::vector<Index> nodes;
  DofMask mask;
  PrescribedDisplacement displacement;  ///< empty: fixed (zero)
};

struct ExternalLoad {
  Vector force;  ///< consistent nodal force at curve value 1
  LoadCurve curve;
  std::string what;
};

}  // namespace plastifem
