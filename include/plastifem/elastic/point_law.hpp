#pragma once
// The point-wise side of the elastic models, beside their fused element kernels:
//
//  - kinematics: the deformation gradient F = x dN/dX at any reference point of an element
//    (its centre, its vertices, its quadrature points), for a rest shape X and current nodes x;
//  - PointSet: an element's own list of integration points, each a rest-space shape gradient
//    dN/dX and a weight dv = w det J. The fused kernels integrate over the element's fixed
//    Gauss rule; a cut element integrates over the sub-tetrahedra on either side of the cut
//    (seed 001 section 4), a list whose length is known only at run time;
//  - a point law per model (Model::Law): the energy density psi(F), the first Piola-Kirchhoff
//    stress P = dpsi/dF and the tangent A = dP/dF (9 x 9, index i + 3 j of F_ij), exact or
//    projected to positive semi-definite; the corotational laws also give the rotation and
//    stretch F = R S at a point;
//  - Model::evaluate_points, the element integral over a PointSet built from the law:
//        W = sum_q dv_q psi(F_q),  f_a = sum_q dv_q P_q g_qa,
//        K_ab(i, k) = sum_q dv_q sum_jl A_q(i + 3j, k + 3l) g_qa[j] g_qb[l].
//    Over the element's own Gauss rule it equals the fused kernel to round-off
//    (tests/test_point_law.cpp), which is what makes the fused kernels safe to keep for speed.
#include <plastifem/core/polar.hpp>
#include <plastifem/core/symmetric_eigen.hpp>
#include <plastifem/elastic/small_strain.hpp>

#include <vector>

namespace plastifem {

/// Projected: a positive semi-definite tangent (the warped R K0 R^T for the corotational
/// models, per-point eigenvalue clamping for the hyperelastic ones): what CG and Cholesky
/// need far from rest, and what the solver falls back to. Exact: the true Jacobian of the
/// force (quadratic Newton; indefinite under compression).
enum class TangentKind { Projected, Exact };

using Matrix9 = Eigen::Matrix<Scalar, 9, 9>;  // index (i, j) of F_ij -> i + 3 j (column-major)

// --- kinematics --------------------------------------------------------------------------------

/// F = x dN/dX at reference point xi of an element with rest shape X and current nodes x.
template <FiniteElement E>
Mat3 deformation_gradient(const ElementNodes<E>& X, const ElementNodes<E>& x, const Vec3& xi) {
  return x * physical_gradient<E>(X, xi);
}

/// F at the element centre (the mean of the corners in reference coordinates).
template <FiniteElement E>
Mat3 centre_deformation_gradient(const ElementNodes<E>& X, const ElementNodes<E>& x) {
  return deformation_gradient<E>(X, x, reference_centre<E>());
}

/// F at each vertex (corner node) of the element.
template <FiniteElement E>
std::array<Mat3, E::num_vertices> vertex_deformation_gradients(const ElementNodes<E>& X, const ElementNodes<E>& x) {
  std::array<Mat3, E::num_vertices> F;
  const auto Xref = E::reference_nodes();
  for (int a = 0; a < E::num_vertices; ++a) F[a] = deformation_gradient<E>(X, x, Xref.col(a));
  return F;
}

/// F at each point of the element's stiffness (full Gauss) rule.
template <FiniteElement E>
std::array<Mat3, QuadraturePoints<E>::size> gauss_deformation_gradients(const ElementNodes<E>& X,
                                                                         const ElementNodes<E>& x) {
  std::array<Mat3, QuadraturePoints<E>::size> F;
  const auto q = E::template quadrature<E::stiffness_degree>();
  for (int k = 0; k < q.size; ++k) F[k] = deformation_gradient<E>(X, x, q.points[k]);
  return F;
}

// --- point sets --------------------------------------------------------------------------------

/// Integration points of one element: rest-space shape gradients and weights.
template <FiniteElement E>
struct PointSet {
  std::vector<ShapeGradients<E>> G;  ///< dN/dX at each point
  std::vector<Scalar> dv;            ///< w det J at each point
  int size() const { return static_cast<int>(dv.size()); }
  Scalar volume() const {
    Scalar v = 0;
    for (Scalar w : dv) v += w;
    return v;
  }
  /// (1 / V) sum_q dv_q dN/dX_q: the gradient whose F is the set's mean deformation gradient.
  ShapeGradients<E> mean_gradient() const {
    ShapeGradients<E> g = ShapeGradients<E>::Zero();
    for (int q = 0; q < size(); ++q) g += dv[q] * G[q];
    return g / volume();
  }
  /// Appends the point at reference coordinates xi with reference weight w, for rest shape X.
  void add(const ElementNodes<E>& X, const Vec3& xi, Scalar w) {
    G.push_back(physical_gradient<E>(X, xi));
    dv.push_back(w * jacobian<E>(X, xi).determinant());
  }
};

/// The element's own full Gauss (stiffness) rule as a PointSet.
template <FiniteElement E>
PointSet<E> gauss_point_set(const ElementNodes<E>& X) {
  PointSet<E> p;
  const auto q = E::template quadrature<E::stiffness_degree>();
  for (int k = 0; k < q.size; ++k) p.add(X, q.points[k], q.weights[k]);
  return p;
}

namespace detail {

/// f_a += dv P g_a, and K_ab(i, k) += dv sum_jl A(i + 3j, k + 3l) g_a[j] g_b[l].
template <FiniteElement E>
void add_point_contribution(const ShapeGradients<E>& G, Scalar dv, const Mat3& P, const Matrix9* A,
                            ElementVector<E>& f, ElementMatrix<E>* K) {
  constexpr int N = E::num_nodes;
  Eigen::Map<ElementNodes<E>>(f.data()).noalias() += (dv * P) * G.transpose();
  if (!K || !A) return;
  Eigen::Matrix<Scalar, 9, 3 * N> T;  // T(ij, 3b + k) = sum_l A_ijkl g_b[l]
  for (int b = 0; b < N; ++b)
    for (int k = 0; k < 3; ++k)
      T.col(3 * b + k) = A->col(k) * G(b, 0) + A->col(k + 3) * G(b, 1) + A->col(k + 6) * G(b, 2);
  for (int a = 0; a < N; ++a)
    K->template middleRows<3>(3 * a).noalias() +=
        dv * (G(a, 0) * T.template topRows<3>() + G(a, 1) * T.template middleRows<3>(3) +
              G(a, 2) * T.template bottomRows<3>());
}

/// dP/dF of the isotropic linear law P = 2 mu sym(H) + lambda tr(H) I in the frame rotated by R:
/// P = R C(sym(R^T F) - I) with R held fixed (the warped corotational tangent; R = I: Hooke):
///   dP = mu (dF + R dF^T R) + lambda tr(R^T dF) R.
template <class L = void>  // see Lazy (core/types.hpp)
Eigen::Matrix<Lazy<L>, 9, 9> rotated_hooke_tangent(const Mat3& R_, Scalar mu, Scalar lambda) {
  using M3 = Eigen::Matrix<Lazy<L>, 3, 3>;
  const M3& R = R_;
  Eigen::Matrix<Lazy<L>, 9, 9> A;
  for (int l = 0; l < 3; ++l)
    for (int k = 0; k < 3; ++k) {
      M3 dF = M3::Zero();
      dF(k, l) = 1;
      const M3 dP = mu * (dF + R * dF.transpose() * R) + lambda * (R.transpose() * dF).trace() * R;
      A.col(k + 3 * l) = Eigen::Map<const Eigen::Matrix<Lazy<L>, 9, 1>>(dP.data());
    }
  return A;
}

}  // namespace detail

}  // namespace plastifem
