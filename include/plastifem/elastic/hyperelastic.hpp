#pragma once
// Hyperelastic models evaluated at the quadrature points of full Gauss integration:
//   energy   W = sum_q dv_q psi(F_q),   F_q = sum_a x_a g_qa^T
//   force    f_a = sum_q dv_q P(F_q) g_qa,                 P = d psi / dF
//   tangent  K_ab(i,k) = sum_q dv_q sum_jl A_ijkl g_qa[j] g_qb[l],   A = dP/dF
// A is projected to positive semi-definite per point (eigenvalue clamping) when it is
// indefinite, so the assembled tangent stays usable by CG and LDLT far from the rest state;
// at and near the rest state A is positive definite and the tangent is the exact Jacobian.
//
// Energies (all from E and nu through mu = E / (2 (1 + nu)), lambda = E nu / ((1 + nu)(1 - 2 nu));
// each reduces to linear elasticity for small strains):
//   NeoHookeanEnergy        psi = mu/2 (I1 - 3) - mu ln J + lambda/2 (ln J)^2        (J > 0)
//   NeoHookeanAbaqusEnergy  psi = C10 (I1bar - 3) + (J - 1)^2 / D1,  I1bar = J^(-2/3) I1,
//                           C10 = mu / 2, D1 = 2 / K, K = lambda + 2 mu / 3            (J > 0)
//     (Abaqus' NEO_HOOKE form, so results can be compared with commercial solvers)
//   StableNeoHookeanEnergy  psi = mu'/2 (I1 - 3) + lambda'/2 (J - alpha)^2 - mu'/2 ln(I1 + 1),
//                           mu' = 4 mu / 3, lambda' = lambda + 5 mu / 6, alpha = 1 + 3 mu' / (4 lambda')
//     (Smith, de Goes and Kim 2018): defined and smooth for every F, including inverted
//     elements (J <= 0), whose energy pushes them back; the Lame reparametrisation makes its
//     linearisation at F = I equal to linear elasticity with (mu, lambda).
// Each has a MeanDilatation variant (one volumetric constraint per element) against locking.
// An energy whose domain excludes F (J <= 0 for the ln J and Abaqus forms) makes evaluate()
// return an infinite energy and NaN forces: the solver's line search then rejects the step
// that would invert an element, and a state that is already inverted gives a clear error.
#include <plastifem/elastic/point_law.hpp>

#include <limits>

namespace plastifem {

namespace detail {

/// A += scale d(cof F)/dF, with d(cof_ij)/dF_kl = sum_mn e_ikm e_jln F_mn (the Hessian of J).
template <class L = void>  // see Lazy (core/types.hpp)
void add_cofactor_derivative(Eigen::Matrix<Lazy<L>, 9, 9>& A, const Mat3& F_, Scalar scale) {
  const Eigen::Matrix<Lazy<L>, 3, 3>& F = F_;
  auto eps = [](int p, int q, int r) { return static_cast<Scalar>((p - q) * (q - r) * (r - p)) / 2; };
  for (int l = 0; l < 3; ++l)
    for (int k = 0; k < 3; ++k)
      for (int j = 0; j < 3; ++j)
        for (int i = 0; i < 3; ++i) {
          if (i == k || j == l) continue;
          const int m = 3 - i - k, n = 3 - j - l;
          A(i + 3 * j, k + 3 * l) += scale * eps(i, k, m) * eps(j, l, n) * F(m, n);
        }
}

}  // namespace detail

// Each energy is written psi(F) = psi_dev(F) + U(J): `deviatoric` gives psi_dev, its P and A
// (false outside its domain), `volumetric` gives U, U', U''. The volumetric contributions are
// P_vol = U'(J) cof F and A_vol = U'' cof (x) cof + U' d(cof)/dF for every energy; the
// mean-dilatation variant evaluates U at the element-mean J instead of at each point.

template <class T = Scalar>
struct BasicNeoHookeanEnergy {
  using M3 = Eigen::Matrix<T, 3, 3>;
  using M9 = Eigen::Matrix<T, 9, 9>;
  static constexpr const char* name = "NeoHookean";
  static constexpr const char* mean_dilatation_name = "NeoHookeanMeanDilatation";
  T mu, lambda;
  explicit BasicNeoHookeanEnergy(const Material& m) : mu(m.mu()), lambda(m.lambda()) {}

  /// psi_dev = mu/2 (I1 - 3) - mu ln J, P = mu (F - F^{-T}),
  /// A_ijab = mu d_ia d_jb + mu Finv_bi Finv_ja.
  bool deviatoric(const M3& F, T& psi, M3& P, M9* A) const {
    const T J = F.determinant();
    if (!(J > 0)) return false;
    const M3 Finv = F.inverse();
    psi = 0.5 * mu * (F.squaredNorm() - 3) - mu * std::log(J);
    P = mu * (F - Finv.transpose());
    if (A)
      for (int b = 0; b < 3; ++b)
        for (int a = 0; a < 3; ++a)
          for (int j = 0; j < 3; ++j)
            for (int i = 0; i < 3; ++i)
              (*A)(i + 3 * j, a + 3 * b) = (i == a && j == b ? mu : 0.0) + mu * Finv(b, i) * Finv(j, a);
    return true;
  }
  /// U = lambda/2 (ln J)^2.
  bool volumetric(T J, T& U, T& dU, T& ddU) const {
    if (!(J > 0)) return false;
    const T l = std::log(J);
    U = 0.5 * lambda * l * l, dU = lambda * l / J, ddU = lambda * (1 - l) / (J * J);
    return true;
  }
  /// The Mandel stress of the whole energy (deviatoric + volumetric parts), M = C S = F^T P
  /// = mu (C - I) + lambda ln J I, in closed form: the plastic flow's stress (plastic/flow.hpp)
  /// without P's cofactor. false where J <= 0.
  bool mandel_stress(const M3& F, M3& M) const {
    const T J = F.determinant();
    if (!(J > 0)) return false;
    M = mu * (F.transpose() * F);
    M.diagonal().array() += lambda * std::log(J) - mu;
    return true;
  }
  /// |dev M|^2 = mu^2 |dev C|^2 for that M at Q points at once (the plastic yield check,
  /// plastic/flow.hpp; one SIMD lane per point, F component-wise). NaN where J <= 0, where the
  /// energy is undefined.
  template <int Q>
  PointArray<Q> deviatoric_mandel_norm2(const PointMat3<Q>& F) const {
    using PA = PointArray<Q>;
    const PA J = F[0] * (F[4] * F[8] - F[7] * F[5]) - F[3] * (F[1] * F[8] - F[7] * F[2]) + F[6] * (F[1] * F[5] - F[4] * F[2]);
    auto dot = [&](int c, int d) -> PA { return F[3 * c] * F[3 * d] + F[3 * c + 1] * F[3 * d + 1] + F[3 * c + 2] * F[3 * d + 2]; };
    const PA C00 = dot(0, 0), C11 = dot(1, 1), C22 = dot(2, 2), C01 = dot(0, 1), C02 = dot(0, 2), C12 = dot(1, 2);
    const PA mean = (C00 + C11 + C22) / 3;
    const PA dev2 = (C00 - mean).square() + (C11 - mean).square() + (C22 - mean).square() +
                    2 * (C01.square() + C02.square() + C12.square());
    return (J > 0).select((mu * mu) * dev2, PA::Constant(std::numeric_limits<Scalar>::quiet_NaN()));
  }
};
using NeoHookeanEnergy = BasicNeoHookeanEnergy<>;

template <class T = Scalar>
struct BasicNeoHookeanAbaqusEnergy {
  using M3 = Eigen::Matrix<T, 3, 3>;
  using M9 = Eigen::Matrix<T, 9, 9>;
  static constexpr const char* name = "NeoHookeanAbaqus";
  static constexpr const char* mean_dilatation_name = "NeoHookeanAbaqusMeanDilatation";
  T C10, kappa;  ///< kappa = 2 / D1, the bulk modulus
  explicit BasicNeoHookeanAbaqusEnergy(const Material& m) : C10(m.mu() / 2), kappa(m.lambda() + 2 * m.mu() / 3) {}

  /// psi_dev = C10 (J^(-2/3) I1 - 3).
  bool deviatoric(const M3& F, T& psi, M3& P, M9* A) const {
    const T J = F.determinant();
    if (!(J > 0)) return false;
    const M3 Finv = F.inverse();
    const T I1 = F.squaredNorm(), a = std::pow(J, -2.0 / 3.0);
    psi = C10 * (a * I1 - 3);
    P = 2 * C10 * a * (F - I1 / 3 * Finv.transpose());
    if (A)
      // d(a)/dF_kb = -2/3 a Finv_bk, d(I1)/dF_kb = 2 F_kb, d(Finv_ji)/dF_kb = -Finv_jk Finv_bi.
      for (int b = 0; b < 3; ++b)
        for (int k = 0; k < 3; ++k)
          for (int j = 0; j < 3; ++j)
            for (int i = 0; i < 3; ++i)
              (*A)(i + 3 * j, k + 3 * b) =
                  2 * C10 *
                  (-2.0 / 3.0 * a * Finv(b, k) * (F(i, j) - I1 / 3 * Finv(j, i)) +
                   a * ((i == k && j == b ? 1.0 : 0.0) - 2.0 / 3.0 * F(k, b) * Finv(j, i) + I1 / 3 * Finv(j, k) * Finv(b, i)));
    return true;
  }
  /// U = kappa/2 (J - 1)^2 = (J - 1)^2 / D1.
  bool volumetric(T J, T& U, T& dU, T& ddU) const {
    U = 0.5 * kappa * (J - 1) * (J - 1), dU = kappa * (J - 1), ddU = kappa;
    return true;
  }
};
using NeoHookeanAbaqusEnergy = BasicNeoHookeanAbaqusEnergy<>;

template <class T = Scalar>
struct BasicStableNeoHookeanEnergy {
  using M3 = Eigen::Matrix<T, 3, 3>;
  using M9 = Eigen::Matrix<T, 9, 9>;
  static constexpr const char* name = "StableNeoHookean";
  static constexpr const char* mean_dilatation_name = "StableNeoHookeanMeanDilatation";
  static constexpr bool defined_when_inverted = true;  ///< no ln J: U = lambda'/2 (J - alpha)^2
  T mu, lambda, alpha;  ///< the reparametrised mu', lambda' and the rest offset alpha
  T psi_rest;           ///< psi(I), subtracted so that the rest state has zero energy
  explicit BasicStableNeoHookeanEnergy(const Material& m)
      : mu(4.0 / 3.0 * m.mu()), lambda(m.lambda() + 5.0 / 6.0 * m.mu()), alpha(1 + 0.75 * mu / lambda),
        psi_rest(0.5 * lambda * (1 - alpha) * (1 - alpha) - 0.5 * mu * std::log(4.0)) {
    if (!(lambda > 0))
      fail<InvalidArgument>("Stable Neo-Hookean needs lambda + 5 mu / 6 > 0 (Poisson ratio above about -0.31), got "
                            "nu = {}",
                            m.poisson);
  }

  /// psi_dev = mu'/2 (I1 - 3) - mu'/2 ln(I1 + 1) - psi(I): defined for every F.
  bool deviatoric(const M3& F, T& psi, M3& P, M9* A) const {
    const T I1 = F.squaredNorm();
    psi = 0.5 * mu * (I1 - 3) - 0.5 * mu * std::log(I1 + 1) - psi_rest;
    const T s = mu * (1 - 1 / (I1 + 1));
    P = s * F;
    if (A) {
      const Eigen::Map<const Eigen::Matrix<T, 9, 1>> f(F.data());
      *A = s * M9::Identity() + (2 * mu / ((I1 + 1) * (I1 + 1))) * f * f.transpose();
    }
    return true;
  }
  /// U = lambda'/2 (J - alpha)^2: defined for J <= 0 too, pushing inverted elements back.
  bool volumetric(T J, T& U, T& dU, T& ddU) const {
    U = 0.5 * lambda * (J - alpha) * (J - alpha), dU = lambda * (J - alpha), ddU = lambda;
    return true;
  }
};
using StableNeoHookeanEnergy = BasicStableNeoHookeanEnergy<>;

template <FiniteElement E>
struct HyperelasticData {
  QuadraturePoints<E> points;
  ShapeGradients<E> G_centre;
  Scalar volume;  ///< rest volume, sum_q dv_q
};

/// An ElasticModel from a per-point energy (see the file comment for the formulas).
/// Volumetric::MeanDilatation evaluates the volumetric energy once per element at the mean
/// dilatation Jbar = (1/V) sum_q dv_q J_q (Nagtegaal, Parks and Rice 1974; the finite-strain
/// form of B-bar, equivalent to Q1/P0 on Hex8), which removes volumetric locking near
/// nu = 0.5:
///   W = sum_q dv_q psi_dev(F_q) + V U(Jbar),   dJbar/dx_a = (1/V) sum_q dv_q cof(F_q) g_qa
///   f_a = sum_q dv_q [P_dev(F_q) + U'(Jbar) cof(F_q)] g_qa
///   K = sum_q dv_q [A_dev + U'(Jbar) d(cof)/dF]_q : g g + V U''(Jbar) (dJbar/dx)(dJbar/dx)^T
template <class Energy, Volumetric V = Volumetric::Full>
struct Hyperelastic {
  static constexpr const char* name = V == Volumetric::Full ? Energy::name : Energy::mean_dilatation_name;
  static constexpr bool constant_tangent = false;
  static constexpr Volumetric volumetric = V;
  /// Whether the energy is defined at J <= 0 (it says so; the ln J and Abaqus forms are not).
  static constexpr bool defined_when_inverted = requires { requires Energy::defined_when_inverted; };
  // The energy's matrix types (Mat3 and Matrix9): written with them, the code below depends on
  // Energy, so a file that uses no hyperelastic model does not instantiate any of it.
  using M3 = typename Energy::M3;
  using M9 = typename Energy::M9;

  template <FiniteElement E>
  struct ElementData : HyperelasticData<E> {
    Energy energy;
  };

  template <FiniteElement E>
  static ElementData<E> prepare(const ElementNodes<E>& X0, const Material& m) {
    ElementData<E> d{{prepare_points<E>(X0), physical_gradient<E>(X0, reference_centre<E>()), 0}, Energy(m)};
    for (Scalar dv : d.points.dv) d.volume += dv;
    return d;
  }

  /// Projected: A clamped to positive semi-definite per point (what the solver falls back
  /// to); Exact: the true Jacobian of the force (indefinite under compression, e.g. for ln J
  /// Neo-Hookean when J < 1 in rotational directions).
  using TangentKind = plastifem::TangentKind;
  static constexpr bool has_exact_tangent = true;

  /// The point law: psi(F) = psi_dev(F) + U(J), P = P_dev + U'(J) cof F,
  /// A = A_dev + U''(J) cof (x) cof + U'(J) d(cof)/dF (projected to PSD when asked).
  /// Returns +inf (and NaN P) outside the energy's domain (J <= 0 for the ln J and Abaqus forms).
  struct Law {
    Energy energy;
    explicit Law(const Material& m) : energy(m) {}
    Scalar evaluate(const M3& F, M3& P, M9* A, TangentKind kind = TangentKind::Projected) const {
      Scalar psi, U, dU, ddU;
      const Scalar J = F.determinant();
      if (!energy.deviatoric(F, psi, P, A) || !energy.volumetric(J, U, dU, ddU)) {
        P.setConstant(std::numeric_limits<Scalar>::quiet_NaN());
        return std::numeric_limits<Scalar>::infinity();
      }
      const M3 cof = detail::cofactor(F);
      P += dU * cof;
      if (A) {
        const Eigen::Map<const Eigen::Matrix<typename M3::Scalar, 9, 1>> c(cof.data());
        A->noalias() += ddU * c * c.transpose();
        detail::add_cofactor_derivative(*A, F, dU);
        if (kind == TangentKind::Projected) project_psd<9>(*A);
      }
      return psi + U;
    }
  };

  template <FiniteElement E>
  static Scalar evaluate(const ElementData<E>& d, const ElementNodes<E>& x, ElementVector<E>& f,
                         ElementMatrix<E>* K) {
    return evaluate<E>(d, x, f, K, TangentKind::Projected);
  }

  /// `lower`: only K's lower blocks (a >= b) are needed (the solver's assembly reads no
  /// others); the closed-form Neo-Hookean kernel then leaves the upper ones unset.
  template <FiniteElement E>
  static Scalar evaluate(const ElementData<E>& d, const ElementNodes<E>& x, ElementVector<E>& f, ElementMatrix<E>* K,
                         TangentKind tangent, bool lower = false) {
    if constexpr (std::is_same_v<Energy, NeoHookeanEnergy> && V == Volumetric::Full)
      if (!K || tangent == TangentKind::Exact) return evaluate_neo_hookean<E>(d, x, f, K, lower);
    return integrate<E>(d.energy, d.points.G, d.points.dv, d.volume, x, f, K, tangent);
  }

  /// The element integral over any point set (a cut element's sub-tetrahedra), with the mean
  /// dilatation taken over the set; equal to evaluate() over the Gauss rule.
  template <FiniteElement E>
  static Scalar evaluate_points(const Law& law, const PointSet<E>& ps, const ElementNodes<E>& x, ElementVector<E>& f,
                                ElementMatrix<E>* K, TangentKind tangent = TangentKind::Projected) {
    return integrate<E>(law.energy, ps.G, ps.dv, ps.volume(), x, f, K, tangent);
  }

  /// Jbar = (1/V) sum_q dv_q det(x G_q): the element's deformed volume over its rest volume.
  template <FiniteElement E, class Gradients, class Weights>
  static Scalar mean_dilatation(const Gradients& Gs, const Weights& dvs, Scalar volume, const ElementNodes<E>& x) {
    Scalar Jbar = 0;
    for (int q = 0; q < static_cast<int>(dvs.size()); ++q) Jbar += dvs[q] * (x * Gs[q]).determinant();
    return Jbar / volume;
  }

  /// The generic integral over the points (G[q], dv[q]) of any container: the fixed Gauss
  /// arrays of the fused path or a PointSet's vectors.
  template <FiniteElement E, class Gradients, class Weights>
  static Scalar integrate(const Energy& energy, const Gradients& Gs, const Weights& dvs, Scalar volume,
                          const ElementNodes<E>& x, ElementVector<E>& f, ElementMatrix<E>* K, TangentKind tangent) {
    constexpr int N = E::num_nodes;
    constexpr Scalar inf = std::numeric_limits<Scalar>::infinity();
    const int Q = static_cast<int>(dvs.size());
    f.setZero();
    if (K) K->setZero();
    auto invalid = [&] {
      f.setConstant(std::numeric_limits<Scalar>::quiet_NaN());
      return inf;
    };
    // Volumetric state: at each point (Full) or once at the mean dilatation.
    Scalar U = 0, dU = 0, ddU = 0, W = 0;
    if constexpr (V == Volumetric::MeanDilatation) {
      if (!energy.volumetric(mean_dilatation<E>(Gs, dvs, volume, x), U, dU, ddU)) return invalid();
      W += volume * U;
    }
    M9 A;
    ElementVector<E> dJbar = ElementVector<E>::Zero();
    for (int q = 0; q < Q; ++q) {
      const ShapeGradients<E>& G = Gs[q];
      const Scalar dv = dvs[q];
      const M3 F = x * G;
      const M3 cof = detail::cofactor(F);
      Scalar psi;
      M3 P;
      if (!energy.deviatoric(F, psi, P, K ? &A : nullptr)) return invalid();
      if constexpr (V == Volumetric::Full) {
        if (!energy.volumetric(F.determinant(), U, dU, ddU)) return invalid();
        psi += U;
        if (K) {
          const Eigen::Map<const Eigen::Matrix<typename M3::Scalar, 9, 1>> c(cof.data());
          A.noalias() += ddU * c * c.transpose();
        }
      } else if (K) {
        Eigen::Map<ElementNodes<E>>(dJbar.data()).noalias() += (dv / volume) * cof * G.transpose();
      }
      P += dU * cof;
      W += dv * psi;
      if (K) {
        detail::add_cofactor_derivative(A, F, dU);
        if (tangent == TangentKind::Projected) project_psd<9>(A);
      }
      detail::add_point_contribution<E>(G, dv, P, K ? &A : nullptr, f, K);
    }
    if constexpr (V == Volumetric::MeanDilatation)
      if (K) {
        // V U'' b b^T: positive semi-definite wherever U'' >= 0 (all three energies near J = 1).
        const Scalar c = volume * (tangent == TangentKind::Projected ? std::max(ddU, 0.0) : ddU);
        K->noalias() += c * dJbar * dJbar.transpose();
      }
    (void)N;
    return W;
  }

  /// The ln J Neo-Hookean in closed form (the generic path contracts a 9x9 A per point). With
  /// h_a = F^{-T} g_a, P = mu (F - F^{-T}) + lambda ln J F^{-T}, and the exact tangent
  ///   K_ab = sum_q dv_q [mu (g_a . g_b) I + lambda h_a h_b^T + (mu - lambda ln J) h_b h_a^T]
  /// (from A = mu I + mu Finv^T (x) Finv + U'' cof (x) cof + U' d(cof)/dF with
  /// d(cof)_ij/dF_kl = J (Finv_ji Finv_lk - Finv_li Finv_jk), U' J = lambda ln J and
  /// U'' J^2 + U' J = lambda): the corotational kernel's shape, one rotation-free part and two
  /// rank-Q products per block, about a quarter of the generic cost on Hex8.
  template <FiniteElement E>
  static Scalar evaluate_neo_hookean(const ElementData<E>& d, const ElementNodes<E>& x, ElementVector<E>& f,
                                     ElementMatrix<E>* K, bool lower = false) {
    constexpr int N = E::num_nodes, Q = QuadraturePoints<E>::size;
    const Scalar mu = d.energy.mu, lambda = d.energy.lambda;
    Eigen::Map<ElementNodes<E>> fm(f.data());
    fm.setZero();
    Eigen::Matrix<Scalar, 3 * N, Q> H, Hd, Hc;  // h_qa, dv_q h_qa, dv_q (mu - lambda ln J_q) h_qa
    Scalar W = 0;
    for (int q = 0; q < Q; ++q) {
      const ShapeGradients<E>& G = d.points.G[q];
      const Scalar dv = d.points.dv[q];
      const M3 F = x * G;
      const Scalar J = F.determinant();
      if (!(J > 0)) {
        f.setConstant(std::numeric_limits<Scalar>::quiet_NaN());
        return std::numeric_limits<Scalar>::infinity();
      }
      const Scalar lnJ = std::log(J);
      const M3 FinvT = detail::cofactor(F) / J;
      W += dv * (0.5 * mu * (F.squaredNorm() - 3) - mu * lnJ + 0.5 * lambda * lnJ * lnJ);
      const M3 P = mu * F + (lambda * lnJ - mu) * FinvT;
      fm.noalias() += (dv * P) * G.transpose();
      if (K) {
        Eigen::Map<Eigen::Matrix<Scalar, 3, N>> h(H.col(q).data());
        h.noalias() = FinvT * G.transpose();
        Hd.col(q) = dv * H.col(q);
        Hc.col(q) = (dv * (mu - lambda * lnJ)) * H.col(q);
      }
    }
    if (K) {
      const auto& L = d.points.L;  // sum_q dv g_a . g_b, precomputed
      for (int b = 0; b < N; ++b)
        for (int a = b; a < N; ++a) {
          const auto Hb = H.template middleRows<3>(3 * b).transpose();
          M3 Kab = lambda * Hd.template middleRows<3>(3 * a).lazyProduct(Hb) +
                     Hc.template middleRows<3>(3 * a).lazyProduct(Hb).transpose();
          Kab.diagonal().array() += mu * L(a, b);
          K->template block<3, 3>(3 * a, 3 * b) = Kab;
          if (a != b && !lower) K->template block<3, 3>(3 * b, 3 * a) = Kab.transpose();
        }
    }
    return W;
  }

  /// Cauchy stress at the element centre: sigma = P F^T / J, P = P_dev(F) + U'(J) cof F with the
  /// centre's J, or with MeanDilatation the element's Jbar (the pressure U'(Jbar) its forces
  /// use: the centre's J carries the locked pressure the variant removes; a nearly
  /// incompressible cantilever's element showed +1036 for the model's -92). Given a cut
  /// element's `piece`, Jbar is the piece's, as its forces take it.
  template <FiniteElement E>
  static M3 cauchy_stress(const ElementData<E>& d, const ElementNodes<E>& x, const Material&,
                          const PointSet<E>* piece = nullptr) {
    const M3 F = x * d.G_centre;
    Scalar psi, U, dU, ddU;
    M3 P;
    Scalar J = F.determinant();
    if constexpr (V == Volumetric::MeanDilatation)
      J = piece ? mean_dilatation<E>(piece->G, piece->dv, piece->volume(), x)
                : mean_dilatation<E>(d.points.G, d.points.dv, d.volume, x);
    if (!d.energy.deviatoric(F, psi, P, nullptr) || !d.energy.volumetric(J, U, dU, ddU))
      return M3::Constant(std::numeric_limits<Scalar>::quiet_NaN());
    P += dU * detail::cofactor(F);
    return P * F.transpose() / F.determinant();
  }
};

using NeoHookean = Hyperelastic<NeoHookeanEnergy>;
using NeoHookeanAbaqus = Hyperelastic<NeoHookeanAbaqusEnergy>;
using StableNeoHookean = Hyperelastic<StableNeoHookeanEnergy>;
using NeoHookeanMeanDilatation = Hyperelastic<NeoHookeanEnergy, Volumetric::MeanDilatation>;
using NeoHookeanAbaqusMeanDilatation = Hyperelastic<NeoHookeanAbaqusEnergy, Volumetric::MeanDilatation>;
using StableNeoHookeanMeanDilatation = Hyperelastic<StableNeoHookeanEnergy, Volumetric::MeanDilatation>;

}  // namespace plastifem
