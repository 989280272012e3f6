// Volumetric locking, measured: the SCENES bar (10 x 3 x 3 unit cubes, clamped at x = 0,
// gravity) in static linear elasticity for nu from 0.3 to 0.499, every element on the scene's
// own mesh against an independent reference: the continuum answer, estimated by Richardson
// extrapolation of a refined sequence with the convergence order theory predicts for this
// problem (and which the sequence shows).
//
// Quantity: the load-weighted mean deflection delta = f_ext . u / W (W the weight), i.e. the
// volume average of -u_z, = 2 x strain energy / W at equilibrium. It is a functional of the
// continuum solution that every mesh and element evaluates exactly (consistent gravity loads),
// and for conforming displacement elements (Tet4, Tet10, Hex8) delta_h <= delta: the discrete
// solution minimises the potential energy over a subspace, so it underestimates the compliance.
//
// Order: the clamp meets each lateral face in a right-angle edge, clamped on one side and free
// on the other, where the plane-strain stresses grow like r^(lambda - 1) (Williams 1952),
// lambda the root in (1/2, 1) of
//   kappa sin^2(lambda pi / 2) = (kappa + 1)^2 / 4 - lambda^2,   kappa = 3 - 4 nu,
// (0.711 at nu = 0.3, 0.595 at nu = 0.5). The energy, hence delta, converges like h^(2 lambda)
// for every element (1.42 at nu = 0.3 down to 1.19 at 0.499), not the h^2 of smooth solutions.
//
// Reference sequence: Hex8 mean dilatation (Q1/P0, free of volumetric locking) on the half bar
// y in [0, 1.5] with u_y = 0 on the symmetry plane y = 1.5 (the Hex8 grid is symmetric, so this
// is the full bar's answer bit for bit at half the cost), cells of h = 1/2 and 1/4, extrapolated
// with p = 2 lambda: delta_ref = d(1/4) + (d(1/4) - d(1/2)) / (2^p - 1). The scene's own
// h = 1 gives a third level, from which the observed order is printed.
// Measured offline with h = 1/8 too (79k dofs, 5 s per nu; the [long] case below redoes it):
// orders from h = 1/2, 1/4, 1/8 of 1.39, 1.22, 1.20, 1.19 for nu = 0.3, 0.45, 0.49, 0.499
// against 2 lambda = 1.42, 1.24, 1.20, 1.19, and the extrapolation from (1/4, 1/8) within
// 7e-5 of the one from (1/2, 1/4).
//
// Locking factor L(nu) = [delta(nu) / ref(nu)] / [delta(0.3) / ref(0.3)]: the discretisation
// error an element already has at nu = 0.3 (e.g. Hex8's shear stiffness in bending) divides
// out, what is left is the stiffening caused by the incompressibility constraint (plus the
// change of the corner singularity with nu, which the non-locking elements show as a few
// percent). L = 1: no volumetric locking; L -> 0: the element freezes as nu -> 0.5.
#include "catch.hpp"

#include <plastifem/plastifem.hpp>

#include <fmt/core.h>

#include <cmath>
#include <map>
#include <numbers>

using namespace plastifem;

namespace {

constexpr Scalar kG = 9.81;

/// Load-weighted mean deflection f_ext . u / W of the bar [0, 10] x [0, 3] x [0, 3] under
/// gravity, clamped at x = 0 (Linear statics, direct solver), with cells of size 1/r. `half`:
/// the half y in [0, 1.5] with u_y = 0 on y = 1.5 (r even).
template <class E, class M>
Scalar mean_deflection(int r, Scalar nu, bool half = false) {
  const Scalar width = half ? 1.5 : 3.0;
  const Mesh<E> mesh = bar_mesh<E>(BoxSpec{10 * r, half ? 3 * r / 2 : 3 * r, 3 * r, Vec3(10, width, 3)});
  Solver<E, M> s(mesh, Material{3000, nu, 1.0});
  s.fix(mesh.node_set("xmin"));
  if (half) s.fix(mesh.node_set("ymax"), {false, true, false});
  s.add_gravity(Vec3(0, 0, -kG));
  s.solve_static();
  return s.external_work_potential() / (kG * 1.0 * 10 * width * 3);
}

/// Williams' exponent lambda for a right-angle corner, one face clamped, one free (plane
/// strain), by Newton on g(l) = kappa sin^2(l pi/2) - (kappa + 1)^2 / 4 + l^2 from l = 0.7
/// (g(1/2) < 0 < g(1) for 0 <= nu <= 1/2, and g is increasing there).
Scalar williams_clamped_free(Scalar nu) {
  const Scalar k = 3 - 4 * nu, c = std::numbers::pi / 2;
  Scalar l = 0.7;
  for (int it = 0; it < 50; ++it) {
    const Scalar s = std::sin(l * c);
    const Scalar g = k * s * s - (k + 1) * (k + 1) / 4 + l * l;
    const Scalar dg = k * c * std::sin(2 * l * c) + 2 * l;
    const Scalar step = g / dg;
    l -= step;
    if (std::abs(step) < 1e-15) break;
  }
  return l;
}

struct Reference {
  Scalar nu, p;     // p = 2 lambda(nu), the theoretical order
  Scalar d1, d2, d4;  // mean dilatation at h = 1, 1/2, 1/4
  Scalar value;     // extrapolated with p from h = 1/2, 1/4
  Scalar p_obs;     // observed from h = 1, 1/2, 1/4
  Scalar estimated_error;  // relative: |value - extrapolation with p_obs|
};

Scalar richardson(Scalar coarse, Scalar fine, Scalar p) { return fine + (fine - coarse) / (std::pow(2.0, p) - 1); }

Reference reference(Scalar nu, int finest = 4) {
  Reference r;
  r.nu = nu;
  r.p = 2 * williams_clamped_free(nu);
  r.d1 = mean_deflection<Hex8, LinearMeanDilatation>(finest / 4, nu, finest / 4 % 2 == 0);
  r.d2 = mean_deflection<Hex8, LinearMeanDilatation>(finest / 2, nu, true);
  r.d4 = mean_deflection<Hex8, LinearMeanDilatation>(finest, nu, true);
  r.value = richardson(r.d2, r.d4, r.p);
  r.p_obs = std::log2((r.d2 - r.d1) / (r.d4 - r.d2));
  // The exponent is the extrapolation's main uncertainty: the spread between the theoretical
  // and the observed one (pre-asymptotic at h = 1, so this over-estimates the error: with
  // h = 1/8 the two extrapolations agree to 7e-5).
  r.estimated_error = std::abs(r.value - richardson(r.d2, r.d4, r.p_obs)) / r.value;
  return r;
}

/// Timoshenko cantilever under the uniform load q = rho g A, averaged over the length:
/// w(x) = q x^2 (6 L^2 - 4 L x + x^2) / (24 E I) + q (2 L x - x^2) / (2 k G A), mean
/// q L^4 / (20 E I) + q L^2 / (3 k G A), Cowper's k = 10 (1 + nu) / (12 + 11 nu) (rectangle).
Scalar timoshenko_mean(Scalar nu) {
  const Scalar E = 3000, L = 10, A = 9, I = 3.0 * 27 / 12, G = E / (2 * (1 + nu));
  const Scalar q = 1.0 * kG * A, k = 10 * (1 + nu) / (12 + 11 * nu);
  return q * std::pow(L, 4) / (20 * E * I) + q * L * L / (3 * k * G * A);
}

}  // namespace

TEST_CASE("volumetric locking per element, and the mean-dilatation remedy for Hex8", "[locking]") {
  const std::vector<Scalar> nus{0.3, 0.45, 0.49, 0.499};
  // Williams' exponent against the tabulated value (0.7112 at nu = 0.3; 4 digits, so 5e-5).
  fmt::print("\nWilliams clamped-free right-angle exponent: lambda(0.3) = {:.4f}, lambda(0.5) = {:.4f}\n",
             williams_clamped_free(0.3), williams_clamped_free(0.5));
  REQUIRE(williams_clamped_free(0.3) == Approx(0.7112).margin(5e-5));

  std::map<std::string, std::vector<Scalar>> d;
  std::vector<Reference> ref;
  for (Scalar nu : nus) {
    ref.push_back(reference(nu));
    d["Hex8"].push_back(mean_deflection<Hex8, Linear>(1, nu));
    d["Hex8 mean dilatation"].push_back(ref.back().d1);
    d["Tet4"].push_back(mean_deflection<Tet4, Linear>(1, nu));
    d["Tet10"].push_back(mean_deflection<Tet10, Linear>(1, nu));
  }
  fmt::print("locking reference, bar 10x3x3 under gravity, mean deflection f.u / W: Hex8 mean dilatation "
             "h = 1, 1/2, 1/4, Richardson with p = 2 lambda\n");
  for (const Reference& r : ref) {
    fmt::print("  nu = {:5}: h=1 {:.6f}  h=1/2 {:.6f}  h=1/4 {:.6f}  -> {:.6f} (correction {:+.2e}); order 2 lambda "
               "{:.3f}, observed {:.3f}; estimated error {:.1e}\n",
               r.nu, r.d1, r.d2, r.d4, r.value, r.value / r.d4 - 1, r.p, r.p_obs, r.estimated_error);
    // 0.5% is ten times below the smallest margin asserted on L below (5%); measured
    // 0.08% (nu = 0.3) to 0.2% (0.499), from the pre-asymptotic h = 1 level.
    REQUIRE(r.estimated_error < 5e-3);
    // Observed against theoretical order: h = 1 (3 cells through the depth) is pre-asymptotic,
    // measured 13-15% low (1.23 vs 1.42 ... 1.04 vs 1.19); 25% rejects a smooth-solution rate
    // (2) and a sequence that is not converging at all.
    REQUIRE(std::abs(r.p_obs / r.p - 1) < 0.25);
  }
  // Beam theory, for scale: the 3D clamp also holds the end section's warping and lateral
  // contraction, which Timoshenko's clamp does not, so the bar is a few percent stiffer at
  // L/h = 3.3 (measured 2.7% at nu = 0.3, growing with nu). 5% below, never above, checks the
  // reference's magnitude independently of any mesh.
  const Scalar beam = timoshenko_mean(0.3);
  fmt::print("  Timoshenko (Cowper's k) mean deflection at nu = 0.3: {:.6f}; reference / beam = {:.4f}\n", beam,
             ref[0].value / beam);
  REQUIRE(ref[0].value / beam < 1.0);
  REQUIRE(ref[0].value / beam > 0.95);

  fmt::print("{:22}", "element \\ nu");
  for (Scalar nu : nus) fmt::print(" {:>17}", nu);
  fmt::print("\n{:22}", "reference");
  for (const Reference& r : ref) fmt::print(" {:>17.5f}", r.value);
  fmt::print("\n");
  std::map<std::string, std::vector<Scalar>> L;
  for (const auto& [name, t] : d) {
    fmt::print("{:22}", name);
    for (size_t k = 0; k < nus.size(); ++k) {
      L[name].push_back((t[k] / ref[k].value) / (t[0] / ref[0].value));
      fmt::print(" {:>8.5f} L={:.3f}", t[k], L[name][k]);
    }
    fmt::print("\n");
  }
  // Conforming elements underestimate the compliance (see the top): a reference below any of
  // them would be wrong by more than its estimated error.
  for (const char* name : {"Hex8", "Tet4", "Tet10"})
    for (size_t k = 0; k < nus.size(); ++k) REQUIRE(d[name][k] < ref[k].value);
  // Tet4 (constant strain, one volumetric constraint per tet, ~5 tets per node) and full-
  // integration Hex8 (8 constraints per element) lock: at nu = 0.499 they keep well under 80%
  // of their nu = 0.3 flexibility (measured 0.26 and 0.35), and the loss keeps growing with
  // lambda / mu: ten times more from nu = 0.49 to 0.499 costs them another 40-45% (measured
  // L(0.499) / L(0.49) = 0.61 and 0.55); 0.8 separates that from the non-locking ones (> 0.98).
  for (const char* name : {"Tet4", "Hex8"}) {
    REQUIRE(L[name][3] < 0.8);
    REQUIRE(L[name][3] / L[name][2] < 0.8);
  }
  // Mean dilatation (one constraint per element, Q1/P0) removes it: within 5% at nu = 0.499
  // (measured 0.974). What is left is not locking but the clamp's singularity getting stronger
  // (2 lambda from 1.42 to 1.19), whose error on 3 cells through the depth grows accordingly;
  // it saturates: L(0.499) / L(0.49) = 0.998 (measured), bound 0.98.
  REQUIRE(L["Hex8 mean dilatation"][3] == Approx(1.0).epsilon(0.05));
  REQUIRE(L["Hex8 mean dilatation"][3] / L["Hex8 mean dilatation"][2] > 0.98);
  // Tet10 (quadratic, 4 volumetric constraints per tet against ~4 dofs per tet: nearly, not
  // quite, locking-free): measured L(0.499) = 0.938 on the scene mesh, i.e. 3.6% more loss than
  // mean dilatation's; 10% bounds it. (Against its own h = 1/2 result as the reference, as this
  // test had it, it read 0.964: the reference shared part of the loss.) The loss saturates
  // with lambda / mu, unlike the locking elements': L(0.499) / L(0.49) = 0.984 (measured), > 0.95.
  REQUIRE(L["Tet10"][3] == Approx(1.0).epsilon(0.10));
  REQUIRE(L["Tet10"][3] / L["Tet10"][2] > 0.95);
  // The remedy must not over-soften: mean dilatation on the scene mesh stays below the
  // continuum answer (measured 2.2-4.7% below) by more than the reference's estimated error.
  for (size_t k = 0; k < nus.size(); ++k)
    REQUIRE(d["Hex8 mean dilatation"][k] <= ref[k].value * (1 - ref[k].estimated_error));
}

TEST_CASE("locking reference: the extrapolation order confirmed with h = 1/8", "[locking][long]") {
  // The reference above from h = 1/2, 1/4, 1/8 (79k dofs per solve, ~5 s per nu): the observed
  // order from these three levels is the theoretical 2 lambda to within the h^2 terms' share
  // (measured 2% low at nu = 0.3, within 0.2% at 0.49 and 0.499; bound 5%), and the
  // extrapolation from (1/4, 1/8) agrees with the one from (1/2, 1/4) to within the latter's
  // estimated error (measured 7e-5 and 1e-5; estimated 8e-4 and 2e-3).
  for (Scalar nu : {0.3, 0.499}) {
    const Reference coarse = reference(nu), fine = reference(nu, 8);
    fmt::print("locking reference nu = {}: h=1/8 {:.6f}, order from h=1/2,1/4,1/8 {:.3f} (2 lambda {:.3f}); "
               "extrapolated {:.6f} vs {:.6f} from h=1/2,1/4: {:.1e} (estimated {:.1e})\n",
               nu, fine.d4, fine.p_obs, fine.p, fine.value, coarse.value, std::abs(fine.value / coarse.value - 1),
               coarse.estimated_error);
    REQUIRE(std::abs(fine.p_obs / fine.p - 1) < 0.05);
    REQUIRE(std::abs(fine.value / coarse.value - 1) < coarse.estimated_error);
  }
}
