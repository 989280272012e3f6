#pragma once
// PlasticTable: the plastic part of a State (solver/state.hpp), everything a plastic update
// changes, so that a step stays a transaction: a failed or cut step leaves it bit for bit as
// it was, like u, v and a.
//
//   rest        the material mesh x (seed 000, section 3): every node's rest position, 3 per
//               node. The elastic models measure F = dx^/dx against it (eq. 1: "x the start
//               position, possibly plastically deformed in the previous iterations"); the
//               rest positions y^k of element k are x at its nodes once the per-element
//               updates are fused (plastic/fusion.hpp);
//   tau         yield stress per flow point (vertices or Gauss points, plastic/flow.hpp) of
//               each element, raised by isotropic hardening;
//   alpha       the kinematic centre of each flow point's yield surface (6 entries of a
//               symmetric deviator); empty without kinematic hardening;
//   tau_R       rotation yield per vertex (vertex-blended) or per element (cell-centered);
//   rotation    the accumulated plastic rotation Pi (eq. 8) at the same places, as a unit
//               quaternion (w, x, y, z);
//   volume      per element: its rest volume over its original volume (beta of eq. 9);
//   off         per element: plasticity switched off, because its rest shape would have
//               degenerated (switched_off) or because a cut enriched it (cut);
//   version     changes whenever `rest` does: the solver re-prepares the element data of the
//               elements whose rest nodes moved when it meets a table of another version;
//   tau_origin, tau_R_origin  the initial yield values tau and tau_R hardened from: the last
//               finite ones (an infinite yield switches the flow off and leaves the thresholds).
#include <plastifem/core/types.hpp>

#include <algorithm>
#include <array>
#include <cstdint>
#include <vector>

namespace plastifem {

struct PlasticTable {
  Vector rest;
  std::vector<Scalar> tau, alpha, tau_R, rotation, volume;
  std::vector<std::uint8_t> off;  ///< per element: 0 flows; switched_off (shape safeguard) or cut (enriched) do not
  static constexpr std::uint8_t switched_off = 1, cut = 2;
  std::uint64_t version = 0;
  Scalar tau_origin = 0, tau_R_origin = 0;

  void resize(Index) {}  // (the State's dof count; the table is sized by the plastic policy)

  /// Assignment that reuses this table's storage (no allocation when the sizes match).
  void assign(const PlasticTable& o) {
    rest = o.rest;
    tau.assign(o.tau.begin(), o.tau.end());
    alpha.assign(o.alpha.begin(), o.alpha.end());
    tau_R.assign(o.tau_R.begin(), o.tau_R.end());
    rotation.assign(o.rotation.begin(), o.rotation.end());
    volume.assign(o.volume.begin(), o.volume.end());
    off.assign(o.off.begin(), o.off.end());
    version = o.version;
    tau_origin = o.tau_origin, tau_R_origin = o.tau_R_origin;
  }
  PlasticTable() = default;
  PlasticTable(const PlasticTable& o) = default;
  PlasticTable& operator=(const PlasticTable& o) {
    if (this != &o) assign(o);
    return *this;
  }
  PlasticTable(PlasticTable&&) noexcept = default;
  PlasticTable& operator=(PlasticTable&&) noexcept = default;

  /// Every entry equal, bit for bit: what the rollback tests compare.
  friend bool operator==(const PlasticTable& a, const PlasticTable& b) {
    auto same = [](const auto& p, const auto& q) {
      return p.size() == q.size() && std::equal(p.data(), p.data() + p.size(), q.data());
    };
    return same(a.rest, b.rest) && same(a.tau, b.tau) && same(a.alpha, b.alpha) && same(a.tau_R, b.tau_R) &&
           same(a.rotation, b.rotation) && same(a.volume, b.volume) && same(a.off, b.off) && a.version == b.version &&
           same(std::array{a.tau_origin, a.tau_R_origin}, std::array{b.tau_origin, b.tau_R_origin});
  }
};

}  // namespace plastifem
