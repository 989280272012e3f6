#pragma once
// PlasticParams: what a user sets for the plastic policies (seed 000), validated with errors
// that name the parameter, and PlasticReport: what one plastic update did.
#include <plastifem/core/error.hpp>
#include <plastifem/core/types.hpp>

#include <cmath>
#include <numbers>

namespace plastifem {

struct PlasticParams {
  // --- plastic stretch (eq. 4) -------------------------------------------------------------
  /// Yield stress tau: the von Mises norm of the (deviatoric, shifted) flow stress, the second
  /// Piola-Kirchhoff stress as the Mandel stress C S (plastic/flow.hpp), above which the
  /// material flows. >= 0; +inf: no plastic stretch.
  Scalar yield_stress = 1000;
  /// Flow rate nu, per unit time, in [0, 1]: gamma = min(nu dt (|s| - tau) / |s|, 1) is the
  /// fraction of the current isochoric stretch that becomes plastic in a step of dt.
  Scalar flow_rate = 0.2;
  /// The stress is multiplied by this factor before the yield test and the flow rule (1: the
  /// physical stress, the default). The paper's scenes do not reach their yield stresses with
  /// a physical stress measure (docs/plasticity.md); the examples that reproduce its figures
  /// say which factor they use. In (0, 1e100]: the yield test squares the scaled stress, which
  /// must stay finite (see validate()).
  Scalar stress_scale = 1;

  // --- plastic rotation (eq. 5-6) ------------------------------------------------------------
  /// Rotation yield tau_R in [0, pi]: the geodesic distance between a vertex rotation and the
  /// element's centre rotation above which the rotation flows.
  Scalar rotation_yield = std::numbers::pi;
  /// Rotational flow rate nu_R, per unit time, in [0, 1]. 0 (the default): no plastic rotation.
  Scalar rotation_flow_rate = 0;
  /// What the plastic rotation Rp = R^eta takes a power of (docs/plasticity.md, "Plastic
  /// rotation and rigid motion").
  enum class RotationFrame {
    /// R measured against the tissue's rigid frame, the best-fit rotation of the held nodes
    /// (or of the whole body when they do not span a plane): invariant to any superposed rigid
    /// motion, so an organ that is lifted and turned keeps its permanent set. The default.
    Tissue,
    /// R as the paper writes it (eq. 5-6), the element's absolute rotation: a body that turns
    /// as a whole flows. Bit for bit the Tissue frame's result while the held nodes do not move.
    World,
  };
  RotationFrame rotation_frame = RotationFrame::Tissue;

  // --- hardening --------------------------------------------------------------------------------
  /// Isotropic hardening kappa >= 0: tau += kappa gamma |s| and tau_R += kappa eta phi per step.
  Scalar hardening = 0.2;
  /// Kinematic hardening kappa_k >= 0: the centre of the yield surface moves towards the
  /// stress, alpha += min(kappa_k gamma, 1) (s - alpha): at most onto it. 0 (the default): none.
  Scalar kinematic_hardening = 0;

  // --- volume and safeguards ---------------------------------------------------------------------
  /// Volume restitution rate (eq. 9), per unit time, >= 0: each step an element whose rest
  /// volume differs from its original one by the ratio beta is scaled about its centre by
  /// 1 + (1 - beta) min(rate dt, 1/3). 1: the paper's.
  Scalar volume_restitution = 1;
  /// Rest volumes within this relative error are left alone (unless the element flowed).
  Scalar volume_tolerance = 1e-4;
  /// The plastic rotation of one step is capped at this angle (rad, in (0, pi)).
  Scalar max_step_rotation = 0.25;
  /// An element's accumulated plastic rotation is capped below this angle (rad, in (0, pi]):
  /// the paper caps the per-element rotation below pi to keep the polar rotation unambiguous.
  Scalar max_total_rotation = 0.9 * std::numbers::pi;
  /// Plasticity is switched off for an element whose updated rest shape would have a smallest
  /// scaled Jacobian determinant (element/element.hpp, check_shape) below this fraction of its
  /// original one, in (0, 1): the element goes on elastically with its last rest shape.
  Scalar min_rest_quality = 0.1;
  /// Statics: a static solve represents this much time, shared among its load increments
  /// by load fraction (the flow rates are per unit time).
  Scalar static_time = 1;

  /// Throws InvalidArgument naming the first parameter out of range.
  void validate() const {
    auto check = [](bool ok, const char* what, Scalar v, const char* range) {
      if (!ok) fail<InvalidArgument>("plasticity: {} = {} is out of range (must be {})", what, v, range);
    };
    check(yield_stress >= 0 && !std::isnan(yield_stress), "yield_stress (tau)", yield_stress, ">= 0, or +inf for none");
    check(flow_rate >= 0 && flow_rate <= 1, "flow_rate (nu)", flow_rate, "in [0, 1], per unit time");
    // The yield test squares stress_scale x the stress (|s|^2 = 3/2 |scale dev M|^2): at 1e300
    // that is inf for any stress, every point "yields" with gamma = nu dt (inf - tau) / inf =
    // NaN, and nothing flows. Up to 1e100 the square stays finite (below 1.8e308) for stresses
    // up to 1e50 in the user's units, beyond any material's (steel's modulus is 2e11 Pa).
    check(stress_scale > 0 && stress_scale <= 1e100, "stress_scale", stress_scale, "in (0, 1e100]");
    check(rotation_yield >= 0 && rotation_yield <= std::numbers::pi, "rotation_yield (tau_R)", rotation_yield,
          "in [0, pi]");
    check(rotation_flow_rate >= 0 && rotation_flow_rate <= 1, "rotation_flow_rate (nu_R)", rotation_flow_rate,
          "in [0, 1], per unit time");
    if (rotation_frame != RotationFrame::Tissue && rotation_frame != RotationFrame::World)
      fail<InvalidArgument>("plasticity: rotation_frame = {} is not a RotationFrame (Tissue or World)",
                            static_cast<int>(rotation_frame));
    check(hardening >= 0 && std::isfinite(hardening), "hardening (kappa)", hardening, "finite and >= 0");
    check(kinematic_hardening >= 0 && std::isfinite(kinematic_hardening), "kinematic_hardening", kinematic_hardening,
          "finite and >= 0");
    check(volume_restitution >= 0 && std::isfinite(volume_restitution), "volume_restitution", volume_restitution,
          "finite and >= 0");
    check(volume_tolerance >= 0 && std::isfinite(volume_tolerance), "volume_tolerance", volume_tolerance,
          "finite and >= 0");
    check(max_step_rotation > 0 && max_step_rotation < std::numbers::pi, "max_step_rotation", max_step_rotation,
          "in (0, pi)");
    check(max_total_rotation > 0 && max_total_rotation <= std::numbers::pi, "max_total_rotation", max_total_rotation,
          "in (0, pi]");
    check(min_rest_quality > 0 && min_rest_quality < 1, "min_rest_quality", min_rest_quality, "in (0, 1)");
    check(static_time > 0 && std::isfinite(static_time), "static_time", static_time, "finite and > 0");
  }
  /// Whether any flow can happen at all.
  bool stretch_active() const { return flow_rate > 0 && std::isfinite(yield_stress); }
  bool rotation_active() const { return rotation_flow_rate > 0 && rotation_yield < std::numbers::pi; }
};

/// What one plastic update (or the updates of a step's sub-steps, summed) did.
struct PlasticReport {
  int points_yielded = 0;     ///< flow points whose stretch flowed (gamma > 0)
  int rotations_yielded = 0;  ///< vertices (vertex-blended) or elements (cell-centered) whose rotation flowed
  int elements_changed = 0;   ///< elements whose rest shape changed (flow, restitution, or fusion with a neighbour)
  int gamma_clamped = 0;      ///< points where gamma = nu dt (|s| - tau) / |s| was clamped to 1
  int rotation_clamped = 0;   ///< plastic rotations capped (per step or in total)
  int switched_off = 0;       ///< elements whose plasticity was switched off in this update (shape safeguard)
  int undefined_points = 0;   ///< points skipped: the stress is undefined there (an inverted element)
  int inverted_elements = 0;  ///< elements not flowed: inverted (det F <= 0) at a flow point or vertex
  int updates_rejected = 0;   ///< updates whose rest shapes were dropped because the fused shape failed its check
                              ///< (the elements that failed it stay switched off, so the next update progresses)
  int elements_off = 0;       ///< elements whose plasticity is switched off after the update (all of them: the
                              ///< body no longer flows; the solver logs a note when this grows)
  Scalar max_gamma = 0;       ///< the largest gamma of the update
  Scalar max_rotation = 0;    ///< the largest plastic rotation angle of the update (rad)
  double wall_ms = 0;         ///< time in the plastic updates and in re-preparing the element data after them

  void add(const PlasticReport& o) {
    points_yielded += o.points_yielded, rotations_yielded += o.rotations_yielded;
    elements_changed += o.elements_changed, gamma_clamped += o.gamma_clamped;
    rotation_clamped += o.rotation_clamped, switched_off += o.switched_off;
    undefined_points += o.undefined_points, updates_rejected += o.updates_rejected;
    inverted_elements += o.inverted_elements;
    elements_off = std::max(elements_off, o.elements_off);  // a state count: sub-steps only add to it
    max_gamma = std::max(max_gamma, o.max_gamma), max_rotation = std::max(max_rotation, o.max_rotation);
    wall_ms += o.wall_ms;
  }
};

}  // namespace plastifem
