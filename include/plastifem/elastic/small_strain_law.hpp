#pragma once
// The point law of the small-strain models (Linear, CorotationalPerElement and their
// mean-dilatation variants) and their element integral over a PointSet.
//
// In a frame rotated by R (R = I for Linear; for the per-element corotational models the
// polar rotation of the set's mean deformation gradient, F_m = x (1/V) sum_q dv_q g_q, which is
// F at the centre of a parallelepiped, tetrahedron or straight-edged Tet10):
//   eps = sym(R^T F) - I,   psi = mu eps:eps + lambda/2 tr(eps)^2,   P = R (2 mu eps + lambda tr(eps) I)
//   A (with R held fixed) = R C R^T:  dP = mu (dF + R dF^T R) + lambda tr(R^T dF) R.
// Mean dilatation (B-bar): the deviatoric part at every point, the volumetric part once with
// the set's mean trace, trbar = tr(R^T F_m) - 3:
//   W = sum_q dv_q mu dev(eps_q):dev(eps_q) + kappa/2 V trbar^2,  kappa = lambda + 2 mu / 3,
//   f_a = sum_q dv_q R 2 mu dev(eps_q) g_qa + kappa V trbar R gbar_a,
//   K = sum_q [deviatoric A] + kappa V (R gbar)(R gbar)^T.
// Over the element's Gauss rule this is f = R K0 (R^T x - X0) and K = R K0 R^T, the fused
// kernels' formulas (elastic/small_strain.hpp, seed 001 eq. 30).
#include <plastifem/elastic/point_law.hpp>

namespace plastifem {

struct SmallStrainLaw {
  Scalar mu = 0, lambda = 0;
  SmallStrainLaw() = default;
  explicit SmallStrainLaw(const Material& m) : mu(m.mu()), lambda(m.lambda()) {}

  /// The small strain in the frame rotated by R: eps = sym(R^T F) - I.
  template <class L = void>  // see Lazy (core/types.hpp)
  static Eigen::Matrix<Lazy<L>, 3, 3> strain(const Mat3& F_, const Mat3& R_) {
    using M3 = Eigen::Matrix<Lazy<L>, 3, 3>;
    const M3 &F = F_, &R = R_;
    const M3 S = R.transpose() * F;
    return 0.5 * (S + S.transpose()) - M3::Identity();
  }
  /// psi, P and A at F in the frame rotated by R (R = I: plain small strain).
  template <class L = void>  // see Lazy (core/types.hpp)
  Scalar evaluate(const Mat3& F, const Mat3& R_, Mat3& P_, Eigen::Matrix<Lazy<L>, 9, 9>* A) const {
    using M3 = Eigen::Matrix<Lazy<L>, 3, 3>;
    const M3& R = R_;
    M3& P = P_;
    const M3 eps = strain<L>(F, R);
    const Scalar tr = eps.trace();
    P = R * (2 * mu * eps + lambda * tr * M3::Identity());
    if (A) *A = detail::rotated_hooke_tangent<L>(R, mu, lambda);
    return mu * eps.squaredNorm() + 0.5 * lambda * tr * tr;
  }
  /// The deviatoric part alone (mean-dilatation models): psi = mu dev(eps):dev(eps).
  template <class L = void>  // see Lazy (core/types.hpp)
  Scalar evaluate_deviatoric(const Mat3& F, const Mat3& R_, Mat3& P_, Eigen::Matrix<Lazy<L>, 9, 9>* A) const {
    using M3 = Eigen::Matrix<Lazy<L>, 3, 3>;
    const M3& R = R_;
    M3& P = P_;
    const M3 eps = strain<L>(F, R);
    const M3 dev = eps - eps.trace() / 3 * M3::Identity();
    P = R * (2 * mu * dev);
    if (A) *A = detail::rotated_hooke_tangent<L>(R, mu, -2 * mu / 3);
    return mu * dev.squaredNorm();
  }
};

namespace detail {

/// The small-strain element integral over a point set in the frame R (see the file comment).
template <FiniteElement E>
Scalar small_strain_points(const SmallStrainLaw& law, bool mean_dilatation, const PointSet<E>& ps,
                           const ElementNodes<E>& x, const Mat3& R, ElementVector<E>& f, ElementMatrix<E>* K) {
  constexpr int N = E::num_nodes;
  f.setZero();
  if (K) K->setZero();
  const ElementNodes<E> xr = relative_to_first_node<E>(x);  // shape gradients sum to zero
  Scalar W = 0;
  Mat3 P;
  Matrix9 A;
  for (int q = 0; q < ps.size(); ++q) {
    const Mat3 F = xr * ps.G[q];
    W += ps.dv[q] * (mean_dilatation ? law.evaluate_deviatoric(F, R, P, K ? &A : nullptr)
                                     : law.evaluate(F, R, P, K ? &A : nullptr));
    add_point_contribution<E>(ps.G[q], ps.dv[q], P, K ? &A : nullptr, f, K);
  }
  if (mean_dilatation) {
    const Scalar V = ps.volume(), kappa = law.lambda + 2 * law.mu / 3;
    const ShapeGradients<E> gbar = ps.mean_gradient();
    const Scalar trbar = (R.transpose() * xr * gbar).trace() - 3;
    W += 0.5 * kappa * V * trbar * trbar;
    ElementVector<E> b;  // b_a = R gbar_a: d trbar / dx_a
    for (int a = 0; a < N; ++a) b.template segment<3>(3 * a) = R * gbar.row(a).transpose();
    f += (kappa * V * trbar) * b;
    if (K) K->noalias() += (kappa * V) * b * b.transpose();
  }
  return W;
}

}  // namespace detail
}  // namespace plastifem
