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
#include <plastifem/elastic/small_strain.hpp>

namespace plastifem {

/// Cauchy stress of the corotational models for a deformation gradient F:
/// R C(sym(R^T F) - I) R^T with R = polar(F).
inline Mat3 corotated_stress(const Material& m, const Mat3& F) {
  const Mat3 R = rotation_of(F);
  const Mat3 S = R.transpose() * F;
  return R * hooke(m, 0.5 * (S + S.transpose()) - Mat3::Identity()) * R.transpose();
}

/// Volumetric::MeanDilatation: the B-bar locking remedy (elastic/small_strain.hpp) in the
/// rotated frame.
template <Volumetric V = Volumetric::Full>
struct CorotationalPerElementT {
  static constexpr const char* name =
      V == Volumetric::Full ? "CorotationalPerElement" : "CorotationalMeanDilatation";
  static constexpr bool constant_tangent = false;

  template <FiniteElement E>
  using ElementData = SmallStrainData<E>;

  template <FiniteElement E>
  static ElementData<E> prepare(const ElementNodes<E>& X0, const Material& m) {
    return prepare_small_strain<E>(X0, m, V);
  }

  template <FiniteElement E>
  static Scalar evaluate(const ElementData<E>& d, const ElementNodes<E>& x, ElementVector<E>& f,
                         ElementMatrix<E>* K) {
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
      for (int a = 0; a < N; ++a) K->template middleRows<3>(3 * a).noalias() = R * T.template middleRows<3>(3 * a);
    }
    return 0.5 * as_vector<E>(y).dot(f0);
  }

  /// Cauchy stress at the element centre: R C(sym(R^T F) - I) R^T.
  template <FiniteElement E>
  static Mat3 cauchy_stress(const ElementData<E>& d, const ElementNodes<E>& x, const Material& m) {
    return corotated_stress(m, x * d.G_centre);
  }
};

using CorotationalPerElement = CorotationalPerElementT<>;
using CorotationalMeanDilatation = CorotationalPerElementT<Volumetric::MeanDilatation>;

template <FiniteElement E>
struct CorotationalData {
  QuadraturePoints<E> points;  ///< with L = sum_q dv_q g_qa . g_qb (rotation-free part)
  ShapeGradients<E> G_centre;
  Scalar mu, lambda;
};

struct Corotational {
  static constexpr const char* name = "Corotational";
  static constexpr bool constant_tangent = false;

  template <FiniteElement E>
  using ElementData = CorotationalData<E>;

  template <FiniteElement E>
  static ElementData<E> prepare(const ElementNodes<E>& X0, const Material& m) {
    ElementData<E> d;
    d.points = prepare_points<E>(X0);
    d.G_centre = physical_gradient<E>(X0, reference_centre<E>());
    d.mu = m.mu();
    d.lambda = m.lambda();
    return d;
  }

  /// Projected: the warped tangent R K0 R^T (positive semi-definite; the default and the
  /// fallback); Exact: the true Jacobian of the force, including the derivative of R.
  enum class TangentKind { Projected, Exact };

  template <FiniteElement E>
  static Scalar evaluate(const ElementData<E>& d, const ElementNodes<E>& x, ElementVector<E>& f,
                         ElementMatrix<E>* K) {
    return evaluate<E>(d, x, f, K, TangentKind::Projected);
  }

  template <FiniteElement E>
  static Scalar evaluate(const ElementData<E>& d, const ElementNodes<E>& x, ElementVector<E>& f, ElementMatrix<E>* K,
                         TangentKind tangent) {
    constexpr int N = E::num_nodes, Q = QuadraturePoints<E>::size;
    const auto& G = d.points.G;
    const auto& dv = d.points.dv;
    Eigen::Map<ElementNodes<E>> fm(f.data());
    fm.setZero();
    // Rotated gradients h_qa = R_q g_qa, scaled by sqrt(dv_q), one column per point, so that
    // M = Hs Hs^T = sum_q dv_q vec(h_q) vec(h_q)^T in one matrix product.
    Eigen::Matrix<Scalar, 3 * N, Q> Hs;
    // Exact tangent, written as K_ab = sum_q dv_q [2 mu (g_a.g_b) I + lambda h_a h_b^T
    // + hat(h_a) D'~_q hat(h_b)^T] with D' = c Z^{-1} = D - mu I (the warped tangent's
    // mu h_b h_a^T - mu (g_a.g_b) I is hat(h_a) (-mu I) hat(h_b)^T) and D'~ = R D' R^T, kept as
    // its 6 components per point (columns 00 11 22 01 02 12).
    const bool exact = K && tangent == TangentKind::Exact;
    Eigen::Matrix<Scalar, Q, 6> Dp;
    Eigen::Matrix<Scalar, Q, 3 * N> Ht;  // Ht(q, 3a + i) = hs_qa[i]: points along columns
    Scalar W = 0;
    std::array<Mat3, Q> Fq, Rq;
    for (int k = 0; k < Q; ++k) Fq[k].noalias() = x * G[k];
    rotations_of<Q>(Fq, Rq);  // all points at once: vectorised across points
    for (int k = 0; k < Q; ++k) {
      const Mat3& F = Fq[k];
      const Mat3& R = Rq[k];
      const Mat3 S = R.transpose() * F;
      const Mat3 eps = 0.5 * (S + S.transpose()) - Mat3::Identity();
      const Scalar tr = eps.trace();
      Mat3 sigma = 2 * d.mu * eps;
      sigma.diagonal().array() += d.lambda * tr;
      W += dv[k] * (d.mu * eps.squaredNorm() + 0.5 * d.lambda * tr * tr);
      fm.noalias() += (dv[k] * R * sigma) * G[k].transpose();
      if (!K) continue;
      Eigen::Map<Eigen::Matrix<Scalar, 3, N>> hs(Hs.col(k).data());
      hs.noalias() = std::sqrt(dv[k]) * R * G[k].transpose();
      if (!exact) continue;
      Mat3 Dt = -d.mu * Mat3::Identity();  // R D' R^T; -mu I: the warped tangent's point contribution
      Mat3 Z = -(eps + Mat3::Identity());
      Z.diagonal().array() += tr + 3;  // tr(S) I - sym(S)
      const Scalar detZ = Z.determinant(), z = (tr + 3) * 2 / 3;  // z: Z's mean eigenvalue
      // Z is SPD iff its leading minors are positive; 1e-8 z^3 keeps Z^{-1} (and with it the
      // correction) below 1e8 / z, far from the non-differentiable inverted states.
      if (Z(0, 0) > 0 && Z(0, 0) * Z(1, 1) > Z(0, 1) * Z(0, 1) && detZ > 1e-8 * z * z * z) {
        const Mat3 D = ((d.lambda * tr - 2 * d.mu) / detZ) * detail::cofactor(Z);  // c Z^{-1} (Z symmetric)
        Dt.noalias() = R * D * R.transpose();
      }
      Ht.row(k) = Hs.col(k).transpose();
      Dp.row(k) << Dt(0, 0), Dt(1, 1), Dt(2, 2), Dt(0, 1), Dt(0, 2), Dt(1, 2);
    }
    if (exact) {
      // The quadrature points are the SIMD dimension: every quantity is a Q-array, and each
      // entry of K_ab is one sum over points (Q = 8 on Hex8: two AVX registers per array).
      using PointArray = Eigen::Array<Scalar, Q, 1>;
      auto h = [&](int a, int i) { return Ht.col(3 * a + i).array(); };
      auto dp = [&](int m, int l) {  // D'~(m, l)
        constexpr int column[3][3] = {{0, 3, 4}, {3, 1, 5}, {4, 5, 2}};
        return Dp.col(column[m][l]).array();
      };
      // Y_a = hat(h_a) D'~, column l = h_a x D'~(:, l): Y(q, 9a + 3i + l).
      Eigen::Matrix<Scalar, Q, 9 * N> Y;
      for (int a = 0; a < N; ++a)
        for (int l = 0; l < 3; ++l) {
          Y.col(9 * a + 0 + l) = h(a, 1) * dp(2, l) - h(a, 2) * dp(1, l);
          Y.col(9 * a + 3 + l) = h(a, 2) * dp(0, l) - h(a, 0) * dp(2, l);
          Y.col(9 * a + 6 + l) = h(a, 0) * dp(1, l) - h(a, 1) * dp(0, l);
        }
      auto y = [&](int a, int i, int l) { return Y.col(9 * a + 3 * i + l).array(); };
      for (int b = 0; b < N; ++b)
        for (int a = b; a < N; ++a) {
          Mat3 Kab;
          for (int i = 0; i < 3; ++i) {
            // (Y_a hat(h_b)^T)(i, j) = sum_l Y_a(i, l) hat(h_b)(j, l)
            const PointArray k0 = d.lambda * h(a, i) * h(b, 0) - y(a, i, 1) * h(b, 2) + y(a, i, 2) * h(b, 1);
            const PointArray k1 = d.lambda * h(a, i) * h(b, 1) + y(a, i, 0) * h(b, 2) - y(a, i, 2) * h(b, 0);
            const PointArray k2 = d.lambda * h(a, i) * h(b, 2) - y(a, i, 0) * h(b, 1) + y(a, i, 1) * h(b, 0);
            Kab(i, 0) = k0.sum(), Kab(i, 1) = k1.sum(), Kab(i, 2) = k2.sum();
          }
          Kab.diagonal().array() += 2 * d.mu * d.points.L(a, b);
          K->template block<3, 3>(3 * a, 3 * b) = Kab;
          if (a != b) K->template block<3, 3>(3 * b, 3 * a) = Kab.transpose();
        }
    } else if (K) {
      // Blocks a >= b from small fixed-size products M_ab = Hs_a Hs_b^T (3 x Q times Q x 3),
      // the others by symmetry: half the work of the full 3N x 3N product, and no general
      // matrix-product dispatch (which costs more than the arithmetic at these sizes).
      for (int b = 0; b < N; ++b)
        for (int a = b; a < N; ++a) {
          const Mat3 M = Hs.template middleRows<3>(3 * a).lazyProduct(Hs.template middleRows<3>(3 * b).transpose());
          Mat3 Kab = d.lambda * M + d.mu * M.transpose();
          Kab.diagonal().array() += d.mu * d.points.L(a, b);
          K->template block<3, 3>(3 * a, 3 * b) = Kab;
          if (a != b) K->template block<3, 3>(3 * b, 3 * a) = Kab.transpose();
        }
    }
    return W;
  }

  /// Cauchy stress at the element centre: R C(sym(R^T F) - I) R^T.
  template <FiniteElement E>
  static Mat3 cauchy_stress(const ElementData<E>& d, const ElementNodes<E>& x, const Material& m) {
    return corotated_stress(m, x * d.G_centre);
  }
};

}  // namespace plastifem
