#pragma once
// The Mooney-Rivlin soft-tissue model in Abaqus' (and CalculiX's) MOONEY_RIVLIN form,
//   psi = C10 (I1bar - 3) + C01 (I2bar - 3) + (J - 1)^2 / D1,
//   I1bar = J^(-2/3) I1,  I2bar = J^(-4/3) I2,  I1 = tr C,  I2 = (I1^2 - tr(C^2)) / 2,  C = F^T F,
// so that constants from a paper or an Abaqus input deck are used as they are: build the
// Material with Material::from_mooney_rivlin(C10, C01, D1, density). From any other Material
// it takes mu = 2 (C10 + C01) and K = 2 / D1 from E and nu and splits mu by the Material's
// c01_share = C01 / (C10 + C01) (0 by default: then it is NeoHookeanAbaqus to round-off).
// Its linearisation at F = I is linear elasticity with mu and lambda = K - 2 mu / 3. The
// deviatoric part is purely isochoric, so the MeanDilatation variant linearises to the B-bar
// small-strain stiffness, as NeoHookeanAbaqus's does. Defined for J > 0 (like the other Abaqus
// form: outside it evaluate() returns an infinite energy and NaN forces, which the solver's line
// search rejects). The exact tangent is below; the solver projects it to positive
// semi-definite per point (elastic/hyperelastic.hpp). A negative C10 or C01 is accepted, as by
// Abaqus; the material's Drucker stability at large strain is then the user's to check
// (Material::from_mooney_rivlin).
//
// Plasticity (plastic/flow.hpp) takes the generic hyperelastic stress S = F^-1 P of the point
// law, at the Gauss points, as for NeoHookeanAbaqus.
//
// Like the energies of elastic/hyperelastic.hpp a class template of its scalar: a file that
// includes this header and does not use the model compiles none of its Eigen code.
#include <plastifem/elastic/hyperelastic.hpp>

#include <cmath>

namespace plastifem {

template <class T = Scalar>
struct BasicMooneyRivlinEnergy {
  using M3 = Eigen::Matrix<T, 3, 3>;
  using M9 = Eigen::Matrix<T, 9, 9>;
  static constexpr const char* name = "MooneyRivlin";
  static constexpr const char* mean_dilatation_name = "MooneyRivlinMeanDilatation";
  T C10, C01, kappa;  ///< kappa = 2 / D1, the bulk modulus
  /// C01 = c01_share mu / 2, C10 = mu / 2 - C01: with c01_share = 0, C10 and kappa are
  /// NeoHookeanAbaqusEnergy's bit for bit.
  explicit BasicMooneyRivlinEnergy(const Material& m)
      : C10(m.mu() / 2 - m.c01_share * (m.mu() / 2)), C01(m.c01_share * (m.mu() / 2)),
        kappa(m.lambda() + 2 * m.mu() / 3) {}

  /// psi_dev = C10 (a I1 - 3) + C01 (b I2 - 3), a = J^(-2/3), b = a^2 = J^(-4/3);
  /// P_dev = 2 C10 a (F - I1/3 F^-T) + 2 C01 b G,  G = H - 2/3 I2 F^-T,  H = I1 F - F C
  /// (dI2/dF = 2 H, dJ/dF = J F^-T).
  bool deviatoric(const M3& F, T& psi, M3& P, M9* A) const {
    const T J = F.determinant();
    if (!(J > 0)) return false;
    const M3 Finv = F.inverse();
    const M3 C = F.transpose() * F, B = F * F.transpose();
    const T I1 = F.squaredNorm(), I2 = (I1 * I1 - C.squaredNorm()) / 2;  // tr(C^2) = |C|^2, C symmetric
    const M3 H = I1 * F - F * C;
    const T a = std::pow(J, -2.0 / 3.0), b = a * a;
    const M3 G = H - 2.0 / 3.0 * I2 * Finv.transpose();
    psi = C10 * (a * I1 - 3) + C01 * (b * I2 - 3);
    P = 2 * C10 * a * (F - I1 / 3 * Finv.transpose()) + 2 * C01 * b * G;
    if (A)
      // A_ijkl = dP_ij/dF_kl at (i + 3j, k + 3l). C10 part as NeoHookeanAbaqusEnergy's. C01 part:
      // d(b)/dF_kl = -4/3 b Finv_lk, and
      // dG_ij/dF_kl = 2 F_kl F_ij + I1 d_ik d_jl - d_ik C_lj - F_il F_kj - B_ik d_jl
      //               - 2/3 (2 H_kl Finv_ji - I2 Finv_jk Finv_li)
      // (d(F C)_ij/dF_kl = d_ik C_lj + F_il F_kj + B_ik d_jl, d(Finv_ji)/dF_kl = -Finv_jk Finv_li).
      for (int l = 0; l < 3; ++l)
        for (int k = 0; k < 3; ++k)
          for (int j = 0; j < 3; ++j)
            for (int i = 0; i < 3; ++i) {
              const T dik = i == k ? 1.0 : 0.0, djl = j == l ? 1.0 : 0.0;
              const T A10 = 2 * C10 *
                            (-2.0 / 3.0 * a * Finv(l, k) * (F(i, j) - I1 / 3 * Finv(j, i)) +
                             a * (dik * djl - 2.0 / 3.0 * F(k, l) * Finv(j, i) + I1 / 3 * Finv(j, k) * Finv(l, i)));
              const T dG = 2 * F(k, l) * F(i, j) + I1 * dik * djl - dik * C(l, j) - F(i, l) * F(k, j) - B(i, k) * djl -
                           2.0 / 3.0 * (2 * H(k, l) * Finv(j, i) - I2 * Finv(j, k) * Finv(l, i));
              (*A)(i + 3 * j, k + 3 * l) = A10 + 2 * C01 * b * (-4.0 / 3.0 * Finv(l, k) * G(i, j) + dG);
            }
    return true;
  }
  /// U = kappa/2 (J - 1)^2 = (J - 1)^2 / D1.
  bool volumetric(T J, T& U, T& dU, T& ddU) const {
    U = 0.5 * kappa * (J - 1) * (J - 1), dU = kappa * (J - 1), ddU = kappa;
    return true;
  }
};
using MooneyRivlinEnergy = BasicMooneyRivlinEnergy<>;

using MooneyRivlin = Hyperelastic<MooneyRivlinEnergy>;
using MooneyRivlinMeanDilatation = Hyperelastic<MooneyRivlinEnergy, Volumetric::MeanDilatation>;

}  // namespace plastifem
