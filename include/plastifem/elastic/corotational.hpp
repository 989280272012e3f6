#pragma once
// Corotational elasticity (seed 001 eq. 31-40): the rotation R of the deformation is factored
// out, the linear (small-strain) element works in the rotated frame, and its forces are
// rotated back. Two variants:
//
// Corotational (default): one rotation per quadrature point, R_q = polar(F_q), as seed 001
// prescribes for quadratic tetrahedra ("a separate polar decomposition ... for each cubature
// point"). With S_q = R_q^T F_q (symmetric) and eps_q = S_q - I:
//   energy  W = sum_q dv_q (mu eps:eps + lambda/2 tr(eps)^2)
//   force   f_a = sum_q dv_q R_q sigma(eps_q) g_qa,          sigma = 2 mu eps + lambda tr(eps) I
//   tangent K_ab = sum_q dv_q [mu (g_a.g_b) I + mu h_b h_a^T + lambda h_a h_b^T],  h_a = R_q g_qa
// i.e. K = sum_q R_q K0_q R_q^T. The force is the exact gradient of W (the polar R_q makes the
// rotated stress symmetric, so the derivative of R_q drops out of it): the model is
// conservative and its internal forces have zero net force and zero net torque. For Tet4
// (one point) it coincides with the per-element variant.
//
// CorotationalPerElement: one rotation per element from F at the element centre,
//   f = R K0 (R^T x - X0),   K = R K0 R^T,
// SOFA's and VegaFEM's choice for hexahedra ("polar" method): one polar decomposition and one
// rotation of the precomputed K0 per element. Cheaper on Hex8 and Tet10, but not the gradient
// of an energy: a bent element's internal forces carry a net torque of the order of the
// strain times the stress (tests/test_elastic.cpp measures it), so a free body can gain
// spurious angular momentum.
//
// Rotations come from core/polar.hpp: robust to near-degenerate and inverted F.
//
// Tangent. The warped tangent R K0 R^T omits the derivative of R with respect to x (VegaFEM's
// warp=1, SOFA's choice): symmetric positive semi-definite, so CG and LDLT apply, but Newton
// converges only linearly once the stress is large. The per-point variant also has the exact
// tangent (VegaFEM's warp=2; TangentKind::Exact). With P = R sigma, F = R S and
// Omega = R^T dR = hat(omega):
//   dS = R^T dF - Omega S,   Omega S + S Omega = R^T dF - dF^T R  =>  omega = Z^{-1} axial(2 skew(R^T dF)),
//   Z = tr(S) I - S  (eigenvalues s_i + s_j: positive while the point is not inverted), and
//   dP = 2 mu dF + lambda tr(R^T dF) R + c dR,   c = lambda tr(eps) - 2 mu,
// which for dF = dx_b g_b^T gives, with D = c Z^{-1} + mu I (zero at rest: c = -2 mu, Z = 2 I),
//   K_ab = sum_q dv_q [mu (g_a.g_b) I + mu h_b h_a^T + lambda h_a h_b^T - hat(h_a) R D R^T hat(h_b)]
// i.e. the warped tangent plus a rotational-stress correction. The correction is indefinite
// under compression (D < 0), which is the physics (a compressed bar buckles); the solver then
// falls back to the warped tangent (TangentKind::Projected). Where Z is near singular (an
// inverted or collapsed point, where the polar factor is not differentiable) the point keeps
// its warped contribution.
#include <plastifem/core/polar.hpp>
#include <plastifem/core/rotation.hpp>
#include <plastifem/elastic/small_strain_law.hpp>

namespace plastifem {

/// Cauchy stress of the corotational law at a deformation gradient F = R S (polar):
///   sigma = P F^T / J = R (T S) R^T / J,   P = R T,   T = C(S - I)   (Biot stress)
/// the force per deformed area. psi(S) = mu |S - I|^2 + lambda/2 tr(S - I)^2 is isotropic, so
/// T and S are coaxial and T S is symmetric (symmetrised here against round-off). To first
/// order in the strain it is R T R^T, the rotated linear stress, which at a 10% uniaxial
/// stretch with nu = 0.3 is 6% below the force per deformed area. At an inverted or collapsed
/// point (J <= 0), where a force per deformed area means nothing but the law is defined, it is
/// R T R^T, the force per reference area: finite, so output and tearing read a number.
/// Given the element's mean gradient Fbar (the MeanDilatation variants), the strain's trace is
/// the mean dilatation tr(R^T Fbar) - 3 their volumetric force uses:
/// T = 2 mu dev(S - I) + kappa (tr(R^T Fbar) - 3) I, still coaxial with S.
template <class L = void>  // see Lazy (core/types.hpp)
Eigen::Matrix<Lazy<L>, 3, 3> corotated_stress(const Material& m, const Mat3& F_, const Mat3* Fbar = nullptr) {
  using M3 = Eigen::Matrix<Lazy<L>, 3, 3>;
  const M3& F = F_;
  const M3 R = rotation_of(F);
  const M3 RtF = R.transpose() * F;
  const M3 S = 0.5 * (RtF + RtF.transpose());
  M3 strain = S - M3::Identity();
  if (Fbar) strain.diagonal().array() += ((R.transpose() * *Fbar).trace() - S.trace()) / 3;
  const M3 T = hooke<L>(m, strain);
  const Scalar J = F.determinant();
  if (!(J > 0)) return R * T * R.transpose();
  const M3 TS = T * S;
  return R * (0.5 * (TS + TS.transpose())) * R.transpose() / J;
}

/// Volumetric::MeanDilatation: the B-bar locking remedy (elastic/small_strain.hpp) in the
/// rotated frame.
template <Volumetric V = Volumetric::Full>
struct CorotationalPerElementT {
  static constexpr const char* name =
      V == Volumetric::Full ? "CorotationalPerElement" : "CorotationalMeanDilatation";
  static constexpr bool constant_tangent = false;
  static constexpr bool defined_when_inverted = true;  ///< an inverted element reads as compressed through zero

  template <FiniteElement E>
  using ElementData = SmallStrainDataOf<E, V>;

  template <FiniteElement E>
  static ElementData<E> prepare(const ElementNodes<E>& X0, const Material& m) {
    return prepare_small_strain_data<E, V>(X0, m);
  }

  template <FiniteElement E>
  static Scalar evaluate(const ElementData<E>& d, const ElementNodes<E>& x, ElementVector<E>& f,
                         ElementMatrix<E>* K) {
    return evaluate<E>(d, x, f, K, TangentKind::Projected, false);
  }

  /// `lower`: only K's lower blocks (a >= b) are needed (the solver's assembly reads no
  /// others): half the rotation of K0.
  template <FiniteElement E>
  static Scalar evaluate(const ElementData<E>& d, const ElementNodes<E>& x, ElementVector<E>& f, ElementMatrix<E>* K,
                         TangentKind, bool lower) {
    constexpr int N = E::num_nodes;
    const Mat3 R = rotation_of(x * d.G_centre);
    // Displacement in the rotated frame, relative to node 0 (K0 annihilates translations).
    const ElementNodes<E> y = R.transpose() * relative_to_first_node<E>(x) - d.X0;
    // Coefficient-based product: Eigen's general GEMV dispatch costs more than 24 x 24 flops.
    const ElementVector<E> f0 = d.K0.lazyProduct(as_vector<E>(y));
    Eigen::Map<ElementNodes<E>>(f.data()) = R * Eigen::Map<const ElementNodes<E>>(f0.data());
    if (K) {
      // K = Rb K0 Rb^T with Rb = blockdiag(R, ..., R), as 2N products of 3N x 3 and 3 x 3N
      // panels (vectorise far better than N^2 products of 3 x 3 blocks; same 6.9k flop on Hex8).
      Eigen::Matrix<Scalar, 3 * N, 3 * N> T;
      for (int b = 0; b < N; ++b) T.template middleCols<3>(3 * b).noalias() = d.K0.template middleCols<3>(3 * b) * R.transpose();
      if (lower) {
        for (int a = 0; a < N; ++a)
          for (int b = 0; b <= a; ++b)
            K->template block<3, 3>(3 * a, 3 * b).noalias() = R.lazyProduct(T.template block<3, 3>(3 * a, 3 * b));
      } else {
        for (int a = 0; a < N; ++a) K->template middleRows<3>(3 * a).noalias() = R * T.template middleRows<3>(3 * a);
      }
    }
    return 0.5 * as_vector<E>(y).dot(f0);
  }

  /// The point law in the element's rotated frame (elastic/small_strain_law.hpp) and the
  /// element integral over any point set, with R the polar rotation of the set's mean
  /// deformation gradient (for a cut element, one rotation per side: seed 001 eq. 64-71); over
  /// the Gauss rule it equals evaluate() on parallelepipeds, tetrahedra and straight Tet10s.
  using Law = SmallStrainLaw;
  template <FiniteElement E>
  static Scalar evaluate_points(const Law& law, const PointSet<E>& ps, const ElementNodes<E>& x, ElementVector<E>& f,
                                ElementMatrix<E>* K, TangentKind = TangentKind::Projected) {
    const Mat3 R = rotation_of(relative_to_first_node<E>(x) * ps.mean_gradient());
    return detail::small_strain_points<E>(law, V == Volumetric::MeanDilatation, ps, x, R, f, K);
  }

  /// Cauchy stress at the element centre: corotated_stress of the centre's F (with
  /// MeanDilatation, and the element's mean F for the dilatation its forces use: a cut
  /// element's `piece`'s mean F, given one).
  template <FiniteElement E>
  static Mat3 cauchy_stress(const ElementData<E>& d, const ElementNodes<E>& x, const Material& m,
                            const PointSet<E>* piece = nullptr) {
    const Mat3 F = x * d.G_centre;
    if constexpr (V == Volumetric::MeanDilatation) {
      const Mat3 Fbar = relative_to_first_node<E>(x) * (piece ? piece->mean_gradient() : d.G_mean);
      return corotated_stress(m, F, &Fbar);
    }
    return corotated_stress(m, F);
  }
};

using CorotationalPerElement = CorotationalPerElementT<>;
using CorotationalMeanDilatation = CorotationalPerElementT<Volumetric::MeanDilatation>;

template <FiniteElement E>
struct CorotationalData {
  PointMajorQuadraturePoints<E> points;  ///< with L = sum_q dv_q g_qa . g_qb (rotation-free part)
  ShapeGradients<E> G_centre;
  Scalar mu, lambda;
};

struct Corotational {
  static constexpr const char* name = "Corotational";
  static constexpr bool constant_tangent = false;
  static constexpr bool defined_when_inverted = true;  ///< an inverted point reads as compressed through zero

  template <FiniteElement E>
  using ElementData = CorotationalData<E>;

  template <FiniteElement E>
  static ElementData<E> prepare(const ElementNodes<E>& X0, const Material& m) {
    ElementData<E> d;
    d.points = prepare_point_major<E>(X0);
    d.G_centre = physical_gradient<E>(X0, reference_centre<E>());
    d.mu = m.mu();
    d.lambda = m.lambda();
    return d;
  }

  /// Projected: the warped tangent R K0 R^T (positive semi-definite; the default and the
  /// fallback); Exact: the true Jacobian of the force, including the derivative of R.
  using TangentKind = plastifem::TangentKind;
  static constexpr bool has_exact_tangent = true;

  /// The point law: R = polar(F), S = R^T F, eps = sym(S) - I,
  /// psi = mu eps:eps + lambda/2 tr(eps)^2, P = R sigma(eps); A exact (see the file comment:
  /// dP = 2 mu dF + lambda tr(R^T dF) R + c dR, dR = R hat(omega), omega = Z^{-1} axial(R^T dF -
  /// dF^T R), Z = tr(S) I - S, c = lambda tr(eps) - 2 mu) or warped (R held fixed), the warped
  /// one also where Z is near singular.
  struct Law {
    Scalar mu = 0, lambda = 0;
    Law() = default;
    explicit Law(const Material& m) : mu(m.mu()), lambda(m.lambda()) {}
    /// F = R S, R the closest proper rotation (core/polar.hpp), S = R^T F.
    static void rotation_stretch(const Mat3& F, Mat3& R, Mat3& S) {
      R = rotation_of(F);
      S = R.transpose() * F;
    }
    template <class L = void>  // see Lazy (core/types.hpp)
    Scalar evaluate(const Mat3& F_, Mat3& P_, Eigen::Matrix<Lazy<L>, 9, 9>* A,
                    TangentKind kind = TangentKind::Projected) const {
      using M3 = Eigen::Matrix<Lazy<L>, 3, 3>;
      using V3 = Eigen::Matrix<Lazy<L>, 3, 1>;
      const M3& F = F_;
      M3& P = P_;
      M3 R, S;
      rotation_stretch(F, R, S);
      const M3 Ss = 0.5 * (S + S.transpose());
      const M3 eps = Ss - M3::Identity();
      const Scalar tr = eps.trace();
      P = R * (2 * mu * eps + lambda * tr * M3::Identity());
      if (A) {
        const M3 Z = Ss.trace() * M3::Identity() - Ss;
        const Scalar z = Z.trace() / 3;
        const bool spd = Z(0, 0) > 0 && Z.template topLeftCorner<2, 2>().determinant() > 0 && Z.determinant() > 1e-8 * z * z * z;
        if (kind == TangentKind::Exact && spd) {
          const M3 Zinv = Z.inverse();
          const Scalar c = lambda * tr - 2 * mu;
          for (int l = 0; l < 3; ++l)
            for (int k = 0; k < 3; ++k) {
              M3 dF = M3::Zero();
              dF(k, l) = 1;
              const M3 W = R.transpose() * dF - dF.transpose() * R;  // = hat(Z omega)
              const V3 omega = Zinv * V3(W(2, 1), W(0, 2), W(1, 0));
              const M3 dP = 2 * mu * dF + lambda * (R.transpose() * dF).trace() * R + c * (R * hat<L>(omega));
              A->col(k + 3 * l) = Eigen::Map<const Eigen::Matrix<Lazy<L>, 9, 1>>(dP.data());
            }
        } else {
          *A = detail::rotated_hooke_tangent<L>(R, mu, lambda);
        }
      }
      return mu * eps.squaredNorm() + 0.5 * lambda * tr * tr;
    }
  };

  /// The element integral over any point set (one rotation per point), equal to evaluate()
  /// over the Gauss rule: the set is taken in chunks of the Gauss rule's size (the last padded
  /// with points of zero weight), each through the batched kernel below, whose per-point cost
  /// is a quarter of the point law's (a cut Hex8 side has up to 23 points: 3 chunks of 8).
  template <FiniteElement E>
  static Scalar evaluate_points(const Law& law, const PointSet<E>& ps, const ElementNodes<E>& x, ElementVector<E>& f,
                                ElementMatrix<E>* K, TangentKind kind = TangentKind::Projected) {
    constexpr int N = E::num_nodes, Q = QuadraturePoints<E>::size;
    f.setZero();
    if (K) K->setZero();
    ElementData<E> d;
    d.mu = law.mu, d.lambda = law.lambda;
    ElementVector<E> fc;
    ElementMatrix<E> Kc;
    Scalar W = 0;
    for (int q0 = 0; q0 < ps.size(); q0 += Q) {
      PointMajorQuadraturePoints<E>& c = d.points;
      for (int k = 0; k < Q; ++k) {
        const int q = std::min(q0 + k, ps.size() - 1);  // a padding point repeats the last one
        c.dv(k) = q0 + k < ps.size() ? ps.dv[q] : 0.0;
        for (int a = 0; a < N; ++a)
          for (int j = 0; j < 3; ++j) c.GT(k, 3 * a + j) = ps.G[q](a, j);
      }
      if (K) c.L = rotation_free_tangent<E>(c.GT, c.dv);
      W += evaluate<E>(d, x, fc, K ? &Kc : nullptr, kind);
      f += fc;
      if (K) *K += Kc;
    }
    return W;
  }

  template <FiniteElement E>
  static Scalar evaluate(const ElementData<E>& d, const ElementNodes<E>& x, ElementVector<E>& f,
                         ElementMatrix<E>* K) {
    return evaluate<E>(d, x, f, K, TangentKind::Projected);
  }

  /// The kernel is batched over the quadrature points: every per-point quantity (F, R, the
  /// strain, the stress, the rotated gradients) is a PointArray with one lane per point, so the
  /// arithmetic runs as SIMD across points with no per-point 3x3 library calls, and the sums
  /// over points are the only horizontal reductions.
  /// `lower`: only K's lower blocks (a >= b) are needed (the solver's assembly reads no
  /// others): the upper ones are left unset.
  template <FiniteElement E>
  static Scalar evaluate(const ElementData<E>& d, const ElementNodes<E>& x, ElementVector<E>& f, ElementMatrix<E>* K,
                         TangentKind tangent, bool lower = false) {
    constexpr int N = E::num_nodes, Q = QuadraturePoints<E>::size;
    using PA = PointArray<Q>;
    const auto& GT = d.points.GT;  // GT(q, 3a + j) = g_qa[j]
    const PA& dv = d.points.dv;
    auto g = [&](int a, int j) { return GT.col(3 * a + j).array(); };
    // F(i, j) = sum_a x(i, a) g_a[j], at every point.
    PointMat3<Q> F, R;
    for (int j = 0; j < 3; ++j)
      for (int i = 0; i < 3; ++i) {
        PA s = x(i, 0) * g(0, j);
        for (int a = 1; a < N; ++a) s += x(i, a) * g(a, j);
        F[i + 3 * j] = s;
      }
    rotations_of<Q>(F, R);
    auto r = [&](int i, int j) -> const PA& { return R[i + 3 * j]; };
    // S = R^T F, eps = sym(S) - I (S is symmetric for the polar R, up to round-off).
    auto S = [&](int i, int j) -> PA { return r(0, i) * F[3 * j] + r(1, i) * F[1 + 3 * j] + r(2, i) * F[2 + 3 * j]; };
    const PA e00 = S(0, 0) - 1, e11 = S(1, 1) - 1, e22 = S(2, 2) - 1;
    const PA e01 = 0.5 * (S(0, 1) + S(1, 0)), e02 = 0.5 * (S(0, 2) + S(2, 0)), e12 = 0.5 * (S(1, 2) + S(2, 1));
    const PA tr = e00 + e11 + e22;
    const Scalar W =
        (dv * (d.mu * (e00 * e00 + e11 * e11 + e22 * e22 + 2 * (e01 * e01 + e02 * e02 + e12 * e12)) +
               0.5 * d.lambda * tr * tr))
            .sum();
    // sigma = 2 mu eps + lambda tr(eps) I, and P = dv R sigma (first Piola-Kirchhoff stress
    // times the point's volume): f_a = sum_q P_q g_qa.
    const PA sd = d.lambda * tr;
    const std::array<PA, 9> sigma{2 * d.mu * e00 + sd, 2 * d.mu * e01, 2 * d.mu * e02,
                                  2 * d.mu * e01,      2 * d.mu * e11 + sd, 2 * d.mu * e12,
                                  2 * d.mu * e02,      2 * d.mu * e12, 2 * d.mu * e22 + sd};
    PointMat3<Q> P;
    for (int j = 0; j < 3; ++j)
      for (int i = 0; i < 3; ++i)
        P[i + 3 * j] = dv * (r(i, 0) * sigma[3 * j] + r(i, 1) * sigma[1 + 3 * j] + r(i, 2) * sigma[2 + 3 * j]);
    for (int a = 0; a < N; ++a)
      for (int i = 0; i < 3; ++i) f[3 * a + i] = (P[i] * g(a, 0) + P[i + 3] * g(a, 1) + P[i + 6] * g(a, 2)).sum();
    if (!K) return W;

    // Rotated gradients h_qa = R_q g_qa, scaled by sqrt(dv_q): Ht(q, 3a + i) = hs_qa[i].
    const PA sq = dv.sqrt();
    Eigen::Matrix<Scalar, Q, 3 * N> Ht;
    for (int a = 0; a < N; ++a)
      for (int i = 0; i < 3; ++i) Ht.col(3 * a + i) = sq * (r(i, 0) * g(a, 0) + r(i, 1) * g(a, 1) + r(i, 2) * g(a, 2));
    if (tangent == TangentKind::Exact) exact_tangent<E>(d, e00, e11, e22, e01, e02, e12, R, Ht, *K, lower);
    else warped_tangent<E>(d, Ht, *K, lower);
    return W;
  }

  /// Cauchy stress at the element centre: corotated_stress of the centre's F (no element mean,
  /// so a cut element's piece changes nothing).
  template <FiniteElement E>
  static Mat3 cauchy_stress(const ElementData<E>& d, const ElementNodes<E>& x, const Material& m,
                            const PointSet<E>* = nullptr) {
    return corotated_stress(m, x * d.G_centre);
  }

 private:
  /// The lower block triangle of C = U diag(w) U^T (blocks of 3 rows / columns: rows
  /// >= 3 floor(c / 3) of each column c, whole SIMD packets) for U (PaddedRows x Inner,
  /// column-major, rows beyond Rows zero); C is column-major with leading dimension
  /// PaddedRows. A register-blocked kernel on Eigen's packets: each column's packets stay in
  /// SIMD registers over the whole inner sum (written with Eigen expressions or plain loops,
  /// the accumulators went through the stack at every step). Block columns are unrolled at
  /// compile time, so each knows its first packet. C(r, c) and C(c, r) are the same sum of the
  /// same products in the same order, so the result is symmetric bit for bit.
  template <int Rows, int PaddedRows, int Inner>
  static void lower_blocks_of_weighted_gram(const Scalar* U, const Scalar* w, Scalar* C) {
    using Packet = typename Eigen::internal::packet_traits<Scalar>::type;
    constexpr int P = Eigen::internal::packet_traits<Scalar>::size;
    static_assert(PaddedRows % P == 0);
    constexpr int RP = PaddedRows / P;
    auto block_column = [&]<int B>() {
      constexpr int p0 = (3 * B) / P, count = RP - p0;
      for (int c = 3 * B; c < 3 * B + 3; ++c) {
        Packet acc[count];
        {
          const Packet w0 = Eigen::internal::pset1<Packet>(w[0] * U[c]);
          for (int p = 0; p < count; ++p) acc[p] = Eigen::internal::pmul(Eigen::internal::ploadu<Packet>(U + (p0 + p) * P), w0);
        }
        for (int m = 1; m < Inner; ++m) {
          const Scalar* u = U + PaddedRows * m;
          const Packet wm = Eigen::internal::pset1<Packet>(w[m] * u[c]);
          for (int p = 0; p < count; ++p)
            acc[p] = Eigen::internal::pmadd(Eigen::internal::ploadu<Packet>(u + (p0 + p) * P), wm, acc[p]);
        }
        for (int p = 0; p < count; ++p) Eigen::internal::pstoreu(C + PaddedRows * c + (p0 + p) * P, acc[p]);
      }
    };
    [&]<int... B>(std::integer_sequence<int, B...>) {
      (block_column.template operator()<B>(), ...);
    }(std::make_integer_sequence<int, Rows / 3>{});
  }

  /// K_ab = lambda M_ab + mu M_ab^T + mu L_ab I with M = Hs Hs^T = sum_q dv_q h_q h_q^T (the
  /// warped tangent R K0 R^T). M is formed a column at a time (3N-vectors: SIMD down the
  /// column), the blocks a >= b from it and mirrored.
  template <FiniteElement E>
  static void warped_tangent(const CorotationalData<E>& d, const Eigen::Matrix<Scalar, QuadraturePoints<E>::size, 3 * E::num_nodes>& Ht,
                             ElementMatrix<E>& K, bool lower) {
    constexpr int N = E::num_nodes, Q = QuadraturePoints<E>::size;
    using Column = Eigen::Matrix<Scalar, 3 * N, 1>;
    const Eigen::Matrix<Scalar, 3 * N, Q> Hs = Ht.transpose();
    ElementMatrix<E> M;
    for (int c = 0; c < 3 * N; ++c) {
      Column m = Hs.col(0) * Ht(0, c);
      for (int q = 1; q < Q; ++q) m += Hs.col(q) * Ht(q, c);
      M.col(c) = m;
    }
    for (int b = 0; b < N; ++b)
      for (int a = b; a < N; ++a) {
        const Scalar l = d.mu * d.points.L(a, b);
        for (int j = 0; j < 3; ++j)
          for (int i = 0; i < 3; ++i) {
            const Scalar v = d.lambda * M(3 * a + i, 3 * b + j) + d.mu * M(3 * a + j, 3 * b + i) + (i == j ? l : 0.0);
            K(3 * a + i, 3 * b + j) = v;
            if (!lower) K(3 * b + j, 3 * a + i) = v;
          }
      }
  }

  /// The exact tangent (see the header comment),
  ///   K_ab = sum_q [2 mu (g_a.g_b) dv I + lambda hs_a hs_b^T + hat(hs_a) D'~_q hat(hs_b)^T],
  /// D'~ = R D' R^T with D' = c Z^{-1} (= D - mu I), or -mu I (the warped contribution) where Z
  /// is near singular. D' is definite, with the sign s of c (Z is SPD), so D'~ = s C C^T with
  /// C = R chol(|c| Z^{-1}), and hat(hs_a) D'~ hat(hs_b)^T = s (hs_a x C) (hs_b x C)^T: with the
  /// 3N x 4Q matrix U = [hs_q, hs_q x C_q(:, 0..2)] over the points and weights
  /// w = (lambda, s_q, s_q, s_q),
  ///   K = U diag(w) U^T + 2 mu L (x) I,
  /// one product formed a column at a time (3N-vectors: SIMD down the column), symmetric bit
  /// for bit (each entry is the same sum of the same products in the same order as its mirror).
  template <FiniteElement E>
  static void exact_tangent(const CorotationalData<E>& d, const PointArray<QuadraturePoints<E>::size>& e00,
                            const PointArray<QuadraturePoints<E>::size>& e11,
                            const PointArray<QuadraturePoints<E>::size>& e22,
                            const PointArray<QuadraturePoints<E>::size>& e01,
                            const PointArray<QuadraturePoints<E>::size>& e02,
                            const PointArray<QuadraturePoints<E>::size>& e12, const PointMat3<QuadraturePoints<E>::size>& R,
                            const Eigen::Matrix<Scalar, QuadraturePoints<E>::size, 3 * E::num_nodes>& Ht,
                            ElementMatrix<E>& K, bool lower) {
    constexpr int N = E::num_nodes, Q = QuadraturePoints<E>::size;
    // Per point: Z = tr(S) I - sym(S) with S = I + eps (Z_ii = tr(eps) + 2 - eps_ii, Z_ij =
    // -eps_ij), cof(Z) (symmetric) and det Z; Z is SPD iff its leading minors are positive,
    // and 1e-8 z^3 (z: Z's mean eigenvalue) keeps Z^{-1} (and with it the correction) below
    // 1e8 / z, far from the non-differentiable inverted states. c = lambda tr(eps) - 2 mu.
    // |c| Z^{-1} = k cof(Z), k = |c| / det Z, has the Cholesky factor L (lower), and C = R L.
    // Where Z is not SPD: D'~ = -mu I, i.e. s = -1 and C = sqrt(mu) I (L = sqrt(mu) R^T).
    // Written as loops over the points (vectorised across them by the compiler), with the
    // square roots of the factorisation as whole-lane passes (lane_sqrt): bit for bit the
    // arithmetic of the Eigen array expressions this was before, as fast, and 78 MB less
    // compiler memory in every file that steps a corotational Solver.
    alignas(64) Scalar k[Q], c00[Q], c01[Q], c02[Q], c11[Q], c12[Q], c22[Q], s[Q], spd[Q];  // spd: 1 or 0
    for (int q = 0; q < Q; ++q) {
      const Scalar tr = e00[q] + e11[q] + e22[q];
      const Scalar z00 = tr + 2 - e00[q], z11 = tr + 2 - e11[q], z22 = tr + 2 - e22[q];
      const Scalar z01 = -e01[q], z02 = -e02[q], z12 = -e12[q];
      c00[q] = z11 * z22 - z12 * z12, c11[q] = z00 * z22 - z02 * z02, c22[q] = z00 * z11 - z01 * z01;
      c01[q] = z02 * z12 - z01 * z22, c02[q] = z01 * z12 - z02 * z11, c12[q] = z01 * z02 - z00 * z12;
      const Scalar detZ = z00 * c00[q] + z01 * c01[q] + z02 * c02[q];
      const Scalar z = (tr + 3) * (2.0 / 3);
      const bool p = (z00 > 0) & (c22[q] > 0) & (detZ > 1e-8 * z * z * z);  // & : no branches, SIMD
      const Scalar c = d.lambda * tr - 2 * d.mu;
      spd[q] = p ? 1.0 : 0.0;
      k[q] = p ? std::abs(c) / detZ : 0.0;
      s[q] = (p & (c >= 0)) ? 1.0 : -1.0;
    }
    alignas(64) Scalar l00[Q], l10[Q], l20[Q], l11[Q], l21[Q], l22[Q];
    for (int q = 0; q < Q; ++q) l00[q] = k[q] * c00[q];
    lane_sqrt<Q>(l00);
    for (int q = 0; q < Q; ++q) {
      const Scalar i00 = l00[q] > 0 ? 1 / l00[q] : 0.0;
      l10[q] = k[q] * c01[q] * i00, l20[q] = k[q] * c02[q] * i00;
      l11[q] = std::max(k[q] * c11[q] - l10[q] * l10[q], Scalar(0));
    }
    lane_sqrt<Q>(l11);
    for (int q = 0; q < Q; ++q) {
      const Scalar i11 = l11[q] > 0 ? 1 / l11[q] : 0.0;
      l21[q] = (k[q] * c12[q] - l20[q] * l10[q]) * i11;
      l22[q] = std::max(k[q] * c22[q] - l20[q] * l20[q] - l21[q] * l21[q], Scalar(0));
    }
    lane_sqrt<Q>(l22);
    // C(i, l) = sum_m R(i, m) L(m, l), L lower triangular; sqrt(mu) I where Z is not SPD.
    const Scalar root_mu = std::sqrt(d.mu);
    alignas(64) Scalar C[9][Q];
    for (int q = 0; q < Q; ++q) {
      auto r = [&](int i, int j) { return R[i + 3 * j][q]; };
      const bool p = spd[q] != 0;
      for (int i = 0; i < 3; ++i) {
        C[i][q] = p ? r(i, 0) * l00[q] + r(i, 1) * l10[q] + r(i, 2) * l20[q] : (i == 0 ? root_mu : 0.0);
        C[3 + i][q] = p ? r(i, 1) * l11[q] + r(i, 2) * l21[q] : (i == 1 ? root_mu : 0.0);
        C[6 + i][q] = p ? r(i, 2) * l22[q] : (i == 2 ? root_mu : 0.0);
      }
    }
    // U (3N x 4Q, rows padded to whole SIMD packets with zeros): columns q = hs_q, columns
    // Q (1 + l) + q = hs_q x C_q(:, l); weights w = (lambda, s, s, s).
    constexpr int M3 = 3 * N, K4 = 4 * Q;
    constexpr int P = Eigen::internal::packet_traits<Scalar>::size, Padded = (M3 + P - 1) / P * P;
    Eigen::Matrix<Scalar, Padded, K4> U;
    for (int c = 0; c < K4; ++c)
      for (int row = M3; row < Padded; ++row) U(row, c) = 0;
    for (int q = 0; q < Q; ++q)
      for (int row = 0; row < M3; ++row) U(row, q) = Ht(q, row);
    Eigen::Matrix<Scalar, K4, 1> w;
    for (int q = 0; q < Q; ++q) {
      w[q] = d.lambda;
      for (int l = 0; l < 3; ++l) w[Q * (1 + l) + q] = s[q];
    }
    for (int a = 0; a < N; ++a) {
      const Scalar *hx = &Ht(0, 3 * a), *hy = &Ht(0, 3 * a + 1), *hz = &Ht(0, 3 * a + 2);
      for (int l = 0; l < 3; ++l) {
        const Scalar *cx = C[3 * l], *cy = C[3 * l + 1], *cz = C[3 * l + 2];
        for (int q = 0; q < Q; ++q) {
          Scalar* u = &U(3 * a, Q * (1 + l) + q);
          u[0] = hy[q] * cz[q] - hz[q] * cy[q], u[1] = hz[q] * cx[q] - hx[q] * cz[q], u[2] = hx[q] * cy[q] - hy[q] * cx[q];
        }
      }
    }
    // The lower blocks of U diag(w) U^T, straight into K where its columns are whole packets.
    if constexpr (Padded == M3) {
      lower_blocks_of_weighted_gram<M3, Padded, K4>(U.data(), w.data(), K.data());
    } else {
      Eigen::Matrix<Scalar, Padded, M3> Kp;
      lower_blocks_of_weighted_gram<M3, Padded, K4>(U.data(), w.data(), Kp.data());
      for (int b = 0; b < N; ++b)
        for (int a = b; a < N; ++a)
          for (int j = 0; j < 3; ++j)
            for (int i = 0; i < 3; ++i) K(3 * a + i, 3 * b + j) = Kp(3 * a + i, 3 * b + j);
    }
    // + 2 mu L_ab I on the lower blocks, then the upper blocks as their mirror (unless only the
    // lower ones are asked for).
    for (int b = 0; b < N; ++b)
      for (int a = b; a < N; ++a) {
        const Scalar l2 = 2 * d.mu * d.points.L(a, b);
        for (int i = 0; i < 3; ++i) K(3 * a + i, 3 * b + i) += l2;
        if (a != b && !lower)
          for (int j = 0; j < 3; ++j)
            for (int i = 0; i < 3; ++i) K(3 * b + j, 3 * a + i) = K(3 * a + i, 3 * b + j);
      }
  }
};

}  // namespace plastifem
