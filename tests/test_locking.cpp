// Volumetric locking, measured: the bar scene (10 x 3 x 3, clamped, gravity) in static linear
// elasticity for nu from 0.3 to 0.499, each element against a Tet10 reference on the twice
// refined mesh (quadratic tets do not lock at these nu: Schneider et al.'s tet-vs-hex study).
//
// Locking factor L(nu) = [tip(nu) / ref(nu)] / [tip(0.3) / ref(0.3)]: the discretisation error
// an element already has at nu = 0.3 (e.g. Hex8's shear stiffness in bending) divides out, what
// is left is the stiffening caused by the incompressibility constraint. L = 1: no volumetric
// locking; L -> 0: the element freezes as nu -> 0.5.
#include "catch.hpp"

#include <plastifem/plastifem.hpp>

#include <fmt/core.h>

#include <map>

using namespace plastifem;

namespace {

/// Mean vertical deflection of the free end face under gravity (Linear statics, LDLT).
template <class E, class M>
Scalar tip_deflection(int r, Scalar nu) {
  const Mesh<E> mesh = bar_mesh<E>(BoxSpec{10 * r, 3 * r, 3 * r, Vec3(10, 3, 3)});
  Solver<E, M> s(mesh, Material{3000, nu, 1.0});
  s.fix(mesh.node_set("xmin"));
  s.add_gravity(Vec3(0, 0, -9.81));
  s.solve_static();
  Scalar uz = 0;
  for (Index i : mesh.node_set("xmax")) uz += s.displacement(i).z();
  return -uz / static_cast<Scalar>(mesh.node_set("xmax").size());
}

}  // namespace

TEST_CASE("volumetric locking per element, and the mean-dilatation remedy for Hex8", "[locking]") {
  const std::vector<Scalar> nus{0.3, 0.45, 0.49, 0.499};
  std::map<std::string, std::vector<Scalar>> tip;
  std::vector<Scalar> ref;
  for (Scalar nu : nus) {
    ref.push_back(tip_deflection<Tet10, Linear>(2, nu));
    tip["Hex8"].push_back(tip_deflection<Hex8, Linear>(1, nu));
    tip["Hex8 mean dilatation"].push_back(tip_deflection<Hex8, LinearMeanDilatation>(1, nu));
    tip["Tet4"].push_back(tip_deflection<Tet4, Linear>(1, nu));
    tip["Tet10"].push_back(tip_deflection<Tet10, Linear>(1, nu));
  }
  fmt::print("\nvolumetric locking, bar 10x3x3 under gravity (reference: Tet10 on 20x6x6)\n");
  fmt::print("{:22}", "element \\ nu");
  for (Scalar nu : nus) fmt::print(" {:>17}", nu);
  fmt::print("\n{:22}", "reference tip");
  for (Scalar r : ref) fmt::print(" {:>17.5f}", r);
  fmt::print("\n");
  std::map<std::string, std::vector<Scalar>> L;
  for (const auto& [name, t] : tip) {
    fmt::print("{:22}", name);
    for (size_t k = 0; k < nus.size(); ++k) {
      L[name].push_back((t[k] / ref[k]) / (t[0] / ref[0]));
      fmt::print(" {:>8.5f} L={:.3f}", t[k], L[name][k]);
    }
    fmt::print("\n");
  }
  // Tet4 (constant strain, one volumetric constraint per tet, ~5 tets per node) and full-
  // integration Hex8 (8 constraints per element) lock: at nu = 0.499 they keep well under
  // 80% of their nu = 0.3 flexibility (measured in the table above).
  REQUIRE(L["Tet4"][3] < 0.8);
  REQUIRE(L["Hex8"][3] < 0.8);
  // Mean dilatation (one constraint per element, Q1/P0) removes it: within 5% at nu = 0.499
  // (what is left is the change of the bending answer itself, which the reference captures
  // only to its own discretisation error).
  REQUIRE(L["Hex8 mean dilatation"][3] == Approx(1.0).epsilon(0.05));
  REQUIRE(L["Tet10"][3] == Approx(1.0).epsilon(0.05));
  // And it is identical to full integration's answer where nothing is nearly incompressible?
  // No: it also removes part of Hex8's parasitic stiffness at nu = 0.3, so only the trend is
  // asserted. The remedy must not over-soften: it stays below the (converged) reference.
  for (size_t k = 0; k < nus.size(); ++k) REQUIRE(tip["Hex8 mean dilatation"][k] <= ref[k] * 1.01);
}
