#pragma once
// Isotropic material constants, validated once so that every model can trust them.
#include <plastifem/core/error.hpp>
#include <plastifem/core/types.hpp>

#include <cmath>

namespace plastifem {

struct Material {
  Scalar young = 0;    ///< E > 0
  Scalar poisson = 0;  ///< -1 < nu < 0.5
  Scalar density = 0;  ///< rho > 0
  /// Mooney-Rivlin only (elastic/mooney_rivlin.hpp), ignored by every other model: the share
  /// C01 / (C10 + C01) of the small-strain shear modulus mu = 2 (C10 + C01) that the second
  /// invariant carries. 0 (the default) is Neo-Hookean, C10 = mu / 2; any finite value is
  /// accepted (Abaqus too allows a negative C01 or C10: see from_mooney_rivlin).
  Scalar c01_share = 0;

  /// Lame constants mu = E / (2 (1 + nu)), lambda = E nu / ((1 + nu)(1 - 2 nu)).
  Scalar mu() const { return young / (2 * (1 + poisson)); }
  Scalar lambda() const { return young * poisson / ((1 + poisson) * (1 - 2 * poisson)); }

  /// From Lame constants: E = mu (3 lambda + 2 mu) / (lambda + mu), nu = lambda / (2 (lambda + mu)).
  static Material from_lame(Scalar lambda, Scalar mu, Scalar density) {
    if (!(mu > 0) || !(lambda + 2.0 / 3.0 * mu > 0))
      fail<InvalidArgument>("Lame constants need mu > 0 and bulk modulus lambda + 2 mu / 3 > 0, got lambda = {}, "
                            "mu = {}",
                            lambda, mu);
    return Material{mu * (3 * lambda + 2 * mu) / (lambda + mu), lambda / (2 * (lambda + mu)), density}.validated();
  }

  /// From Abaqus' NEO_HOOKE constants, psi = C10 (I1bar - 3) + (J - 1)^2 / D1: mu = 2 C10,
  /// bulk modulus K = 2 / D1, lambda = K - 2 mu / 3 (the NeoHookeanAbaqus energy reproduces
  /// Abaqus exactly; the other models see the same small-strain E and nu).
  static Material from_abaqus(Scalar C10, Scalar D1, Scalar density) {
    if (!(C10 > 0) || !std::isfinite(C10) || !(D1 > 0) || !std::isfinite(D1))
      fail<InvalidArgument>("Abaqus Neo-Hookean constants need C10 > 0 and D1 > 0 (finite), got C10 = {}, D1 = {}", C10,
                            D1);
    const Scalar mu = 2 * C10, K = 2 / D1;
    return from_lame(K - 2 * mu / 3, mu, density);
  }

  /// From Abaqus' MOONEY_RIVLIN constants, psi = C10 (I1bar - 3) + C01 (I2bar - 3) + (J - 1)^2 / D1
  /// (CalculiX's too): mu = 2 (C10 + C01), K = 2 / D1 as from_abaqus, and c01_share =
  /// C01 / (C10 + C01). The MooneyRivlin model reproduces the energy (to round-off of the
  /// E, nu round trip); every other model sees the same small-strain E and nu. Needs
  /// C10 + C01 > 0 and D1 > 0, all finite (D1 = 0, Abaqus' incompressible material, has no
  /// displacement-only form: take D1 = 2 / K with K 100 to 500 times mu). One of C10, C01 may
  /// be negative, as Abaqus allows: the material is then stable at small strain (mu > 0,
  /// K > 0) but may lose Drucker stability at large ones. With C01 < 0 the incompressible
  /// equibiaxial stress 2 (l^2 - l^-4)(C10 + l^2 C01) peaks before l = sqrt(C10 / -C01) and then
  /// falls. That is not checked here: it is the user's. (The solver's tangent is projected to
  /// positive semi-definite per point, so its linear solves stay defined, but where the energy
  /// is not convex a body can snap or have no equilibrium near.)
  static Material from_mooney_rivlin(Scalar C10, Scalar C01, Scalar D1, Scalar density) {
    if (D1 == 0)
      fail<InvalidArgument>("Abaqus Mooney-Rivlin constants: D1 = 0 (incompressible) has no displacement-only form; "
                            "give D1 = 2 / K with a bulk modulus K of 100 to 500 times mu = 2 (C10 + C01) = {}",
                            2 * (C10 + C01));
    if (!std::isfinite(C10) || !std::isfinite(C01) || !(C10 + C01 > 0) || !(D1 > 0) || !std::isfinite(D1))
      fail<InvalidArgument>("Abaqus Mooney-Rivlin constants need C10 + C01 > 0 and D1 > 0 (finite), got C10 = {}, "
                            "C01 = {}, D1 = {}",
                            C10, C01, D1);
    const Scalar mu = 2 * (C10 + C01), K = 2 / D1;
    Material m = from_lame(K - 2 * mu / 3, mu, density);
    m.c01_share = C01 / (C10 + C01);
    return m;
  }

  /// Throws InvalidArgument unless E > 0, -1 < nu < 0.5 and rho > 0 (all finite) and c01_share
  /// is finite.
  const Material& validated() const {
    if (!(young > 0) || !std::isfinite(young))
      fail<InvalidArgument>("Young's modulus must be finite and > 0, got E = {}", young);
    // Normal numbers: a denormal E or density (1e-320) turns every product with it to round-off.
    if (!std::isnormal(young))
      fail<InvalidArgument>("Young's modulus must be at least the smallest normal double, got E = {}", young);
    if (!(poisson > -1 && poisson < 0.5))
      fail<InvalidArgument>("Poisson ratio must satisfy -1 < nu < 0.5, got nu = {} (nu = 0.5 is incompressible: "
                            "use nu = 0.49 to 0.499)",
                            poisson);
    if (!std::isfinite(lambda()) || !std::isfinite(mu()))
      fail<InvalidArgument>("E = {} and nu = {} give Lame constants beyond double precision (lambda = {}, mu = {}); "
                            "give E in larger units (kPa, MPa)",
                            young, poisson, lambda(), mu());
    if (!(density > 0) || !std::isfinite(density))
      fail<InvalidArgument>("density must be finite and > 0, got rho = {}", density);
    if (!std::isnormal(density))
      fail<InvalidArgument>("density must be at least the smallest normal double, got rho = {}", density);
    if (!std::isfinite(c01_share)) fail<InvalidArgument>("the Mooney-Rivlin c01_share must be finite, got {}", c01_share);
    // C01 = c01_share mu / 2 and C10 = (1 - c01_share) mu / 2 (elastic/mooney_rivlin.hpp).
    if (!std::isfinite(c01_share * mu()) || !std::isfinite((1 - c01_share) * mu()))
      fail<InvalidArgument>("the Mooney-Rivlin c01_share = {} with mu = {} gives C10, C01 beyond double precision",
                            c01_share, mu());
    return *this;
  }
};

/// Isotropic elasticity tensor in Voigt form (xx, yy, zz, xy, yz, zx; engineering shear).
template <class L = void>  // see Lazy (core/types.hpp)
Eigen::Matrix<Lazy<L>, 6, 6> voigt_elasticity(const Material& m) {
  using C6 = Eigen::Matrix<Lazy<L>, 6, 6>;
  const Scalar mu = m.mu(), la = m.lambda();
  C6 C = C6::Zero();
  C.template topLeftCorner<3, 3>().setConstant(la);
  C.template topLeftCorner<3, 3>().diagonal().array() += 2 * mu;
  C.template bottomRightCorner<3, 3>().diagonal().setConstant(mu);
  return C;
}

/// Linear isotropic stress sigma = 2 mu eps + lambda tr(eps) I.
template <class L = void>  // see Lazy (core/types.hpp)
Eigen::Matrix<Lazy<L>, 3, 3> hooke(const Material& m, const Mat3& eps_) {
  using M3 = Eigen::Matrix<Lazy<L>, 3, 3>;
  const M3& eps = eps_;
  return 2 * m.mu() * eps + m.lambda() * eps.trace() * M3::Identity();
}

/// Von Mises equivalent stress sqrt(3/2 s:s), s the deviator.
template <class L = void>  // see Lazy (core/types.hpp)
Lazy<L> von_mises(const Mat3& sigma_) {
  using M3 = Eigen::Matrix<Lazy<L>, 3, 3>;
  const M3& sigma = sigma_;
  const M3 s = sigma - sigma.trace() / 3 * M3::Identity();
  return std::sqrt(1.5 * s.squaredNorm());
}

}  // namespace plastifem
