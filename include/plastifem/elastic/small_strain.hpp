#pragma once
// What the small-strain models (Linear, Corotational) precompute per element: the rest shape,
// its stiffness K0 = sum_q w_q det J_q B_q^T C B_q (full Gauss integration) and the shape
// gradients at the element centre (where Corotational extracts its rotation and where stress
// is reported).
//
// K0 is built block-wise from seed 001 eq. (30): for nodes a, b with physical gradients g_a, g_b
//   K0_ab(p, q) = mu g_a[q] g_b[p] + mu delta_pq (g_a . g_b) + lambda g_a[p] g_b[q].
//
// Volumetric locking remedy (Volumetric::MeanDilatation, the B-bar method of Hughes 1980 in
// its mean-dilatation form, equivalent to the Q1/P0 mixed element on Hex8): with
// C = kappa 1(x)1 + 2 mu (I - 1(x)1 / 3), kappa = lambda + 2 mu / 3, the deviatoric part is
// integrated at every point and the volumetric part with the element-mean divergence
//   gbar_a = (1/V) sum_q dv_q g_qa:
//   K0_ab = sum_q dv_q [mu g_b g_a^T + mu (g_a . g_b) I - 2 mu / 3 g_a g_b^T] + kappa V gbar_a gbar_b^T.
// One volumetric constraint per element instead of one per point, so a Hex8 near nu = 0.5
// bends instead of locking. Identical to full integration for Tet4 (one point).
#include <plastifem/elastic/material.hpp>
#include <plastifem/element/element.hpp>

#include <array>

namespace plastifem {

template <FiniteElement E>
using ElementVector = Eigen::Matrix<Scalar, 3 * E::num_nodes, 1>;
template <FiniteElement E>
using ElementMatrix = Eigen::Matrix<Scalar, 3 * E::num_nodes, 3 * E::num_nodes>;
template <FiniteElement E>
using ShapeGradients = Eigen::Matrix<Scalar, E::num_nodes, 3>;

/// Positions relative to node 0: what the small-strain models difference against their rest
/// shape, so that elements which are translated copies of each other share one ElementData
/// (the solver stores each distinct shape once) without cancellation error from the offset.
template <FiniteElement E>
ElementNodes<E> relative_to_first_node(const ElementNodes<E>& x) {
  return x.colwise() - x.col(0);
}

/// The element's nodal vector view of a 3 x N node matrix (dof 3a + d, as ElementNodes stores it).
template <FiniteElement E>
Eigen::Map<const ElementVector<E>> as_vector(const ElementNodes<E>& X) {
  return Eigen::Map<const ElementVector<E>>(X.data());
}

template <FiniteElement E>
struct SmallStrainData {
  ElementNodes<E> X0;          ///< rest positions relative to node 0 (shared by translated copies)
  ElementMatrix<E> K0;         ///< small-strain stiffness in the rest frame
  ShapeGradients<E> G_centre;  ///< dN/dX at the element centre
};

/// How the volumetric part of the small-strain stiffness is integrated.
enum class Volumetric { Full, MeanDilatation };

/// The mean-dilatation variants' data also keep the element-mean gradient gbar, whose
/// tr((x - X0) gbar) is the dilatation their volumetric force and reported stress use (the
/// centre's own differs on a non-affine element).
template <FiniteElement E>
struct MeanDilatationData : SmallStrainData<E> {
  ShapeGradients<E> G_mean;  ///< gbar = (1/V) sum_q dv_q dN/dX_q
};
template <FiniteElement E, Volumetric V>
using SmallStrainDataOf = std::conditional_t<V == Volumetric::MeanDilatation, MeanDilatationData<E>, SmallStrainData<E>>;

/// `mean_gradient`: receives gbar (formed with the mean-dilatation stiffness, or for it).
template <FiniteElement E>
SmallStrainData<E> prepare_small_strain(const ElementNodes<E>& X0, const Material& m,
                                        Volumetric volumetric = Volumetric::Full,
                                        ShapeGradients<E>* mean_gradient = nullptr) {
  SmallStrainData<E> d;
  d.X0 = X0.colwise() - X0.col(0);
  d.K0.setZero();
  const bool mean = volumetric == Volumetric::MeanDilatation;
  const Scalar mu = m.mu(), la = mean ? -2 * m.mu() / 3 : m.lambda();  // volumetric part added below
  const auto q = E::template quadrature<E::stiffness_degree>();
  constexpr int N = E::num_nodes, Q = decltype(q)::size;
  // T = sum_q dv_q vec(G_q^T) vec(G_q^T)^T, i.e. T_ab = sum_q dv_q g_qa g_qb^T for every node
  // pair, as one product (3N x Q times its transpose: SIMD, 3-4 times faster than a 3 x 3 block
  // per pair and point; plasticity re-prepares every flowing element), then eq. (30) per block:
  //   K0_ab = mu T_ab^T + lambda T_ab + mu tr(T_ab) I.
  Eigen::Matrix<Scalar, 3 * N, Q> U;
  Eigen::Matrix<Scalar, Q, 1> w;
  ShapeGradients<E> Gbar = ShapeGradients<E>::Zero();
  Scalar V = 0;
  for (int k = 0; k < Q; ++k) {
    const Scalar dv = q.weights[k] * jacobian<E>(X0, q.points[k]).determinant();
    const ShapeGradients<E> G = physical_gradient<E>(X0, q.points[k]);
    Gbar += dv * G;
    V += dv;
    w[k] = dv;
    for (int a = 0; a < N; ++a) U.template block<3, 1>(3 * a, k) = G.row(a).transpose();
  }
  // The blocks a >= b, mirrored: K0 is symmetric bit for bit.
  const ElementMatrix<E> T = U * w.asDiagonal() * U.transpose();
  for (int b = 0; b < N; ++b)
    for (int a = b; a < N; ++a) {
      const Mat3 Tab = T.template block<3, 3>(3 * a, 3 * b);
      Mat3 block = mu * Tab.transpose() + la * Tab;
      block.diagonal().array() += mu * Tab.trace();
      if (a == b) block = Mat3(0.5 * (block + block.transpose()));
      d.K0.template block<3, 3>(3 * a, 3 * b) = block;
      if (a != b) d.K0.template block<3, 3>(3 * b, 3 * a) = block.transpose();
    }
  Gbar /= V;
  if (mean_gradient) *mean_gradient = Gbar;
  if (mean) {
    const Scalar kappa = m.lambda() + 2 * m.mu() / 3;
    for (int a = 0; a < E::num_nodes; ++a)
      for (int b = 0; b < E::num_nodes; ++b)
        d.K0.template block<3, 3>(3 * a, 3 * b) += (kappa * V) * Gbar.row(a).transpose() * Gbar.row(b);
  }
  d.G_centre = physical_gradient<E>(X0, reference_centre<E>());
  return d;
}

/// The data of a small-strain model with volumetric integration V.
template <FiniteElement E, Volumetric V>
SmallStrainDataOf<E, V> prepare_small_strain_data(const ElementNodes<E>& X0, const Material& m) {
  if constexpr (V == Volumetric::MeanDilatation) {
    MeanDilatationData<E> d;
    static_cast<SmallStrainData<E>&>(d) = prepare_small_strain<E>(X0, m, V, &d.G_mean);
    return d;
  } else {
    return prepare_small_strain<E>(X0, m, V);
  }
}

/// Per-point data of the full-integration (stiffness) rule, for models evaluated point by
/// point (the hyperelastic family): dN/dX and w_q det J_q at each point.
template <FiniteElement E>
struct QuadraturePoints {
  static constexpr int size = decltype(E::template quadrature<E::stiffness_degree>())::size;
  std::array<ShapeGradients<E>, size> G;  ///< dN/dX at each point
  std::array<Scalar, size> dv;            ///< w_q det J_q
  /// L_ab = sum_q dv_q g_qa . g_qb: the rotation-free part of the corotational and Neo-Hookean
  /// tangents, a rest-shape quantity.
  Eigen::Matrix<Scalar, E::num_nodes, E::num_nodes> L;
};

/// The same, point-major, for kernels batched over the points (SIMD lanes: the corotational
/// model). Each model keeps only its own layout: a plastic or unstructured body has one entry
/// per element, which every assembly streams from memory (Hex8 corotational 3.9 -> 2.3 KB).
template <FiniteElement E>
struct PointMajorQuadraturePoints {
  static constexpr int size = QuadraturePoints<E>::size;
  /// GT(q, 3a + j) = dN_a/dX_j at point q
  Eigen::Matrix<Scalar, size, 3 * E::num_nodes> GT;
  Eigen::Array<Scalar, size, 1> dv;                   ///< w_q det J_q
  Eigen::Matrix<Scalar, E::num_nodes, E::num_nodes> L;  ///< as QuadraturePoints::L
};

/// L_ab = sum_q dv_q g_qa . g_qb from the point-major gradients GT (PointMajorQuadraturePoints::GT),
/// symmetric bit for bit (the lower triangle mirrored). Loops over contiguous point columns:
/// Eigen's scaled outer-product expression cost more to compile than the rest of the
/// preparation, and ran no faster.
template <FiniteElement E, int Q>
Eigen::Matrix<Scalar, E::num_nodes, E::num_nodes> rotation_free_tangent(
    const Eigen::Matrix<Scalar, Q, 3 * E::num_nodes>& GT, const Eigen::Array<Scalar, Q, 1>& dv) {
  constexpr int N = E::num_nodes;
  Eigen::Matrix<Scalar, N, N> L;
  for (int b = 0; b < N; ++b) {
    const Scalar *bx = &GT(0, 3 * b), *by = bx + Q, *bz = by + Q;
    for (int a = b; a < N; ++a) {
      const Scalar *ax = &GT(0, 3 * a), *ay = ax + Q, *az = ay + Q;
      Scalar s = 0;
      for (int k = 0; k < Q; ++k) s += dv[k] * (ax[k] * bx[k] + ay[k] * by[k] + az[k] * bz[k]);
      L(a, b) = L(b, a) = s;
    }
  }
  return L;
}

/// The point-major data of rest shape X0 (PointMajorQuadraturePoints).
template <FiniteElement E>
PointMajorQuadraturePoints<E> prepare_point_major(const ElementNodes<E>& X0) {
  PointMajorQuadraturePoints<E> p;
  const auto q = E::template quadrature<E::stiffness_degree>();
  const auto& dN = quadrature_gradients<E, E::stiffness_degree>();
  for (int k = 0; k < q.size; ++k) {
    Scalar det_J;
    const ShapeGradients<E> G = physical_gradient_at<E>(X0, dN[k], &det_J);
    p.dv(k) = q.weights[k] * det_J;
    for (int a = 0; a < E::num_nodes; ++a)
      for (int j = 0; j < 3; ++j) p.GT(k, 3 * a + j) = G(a, j);
  }
  p.L = rotation_free_tangent<E>(p.GT, p.dv);
  return p;
}

/// The per-point data of rest shape X0 (QuadraturePoints): prepare_point_major's, laid out per
/// point.
template <FiniteElement E>
QuadraturePoints<E> prepare_points(const ElementNodes<E>& X0) {
  const PointMajorQuadraturePoints<E> m = prepare_point_major<E>(X0);
  QuadraturePoints<E> p;
  for (int k = 0; k < QuadraturePoints<E>::size; ++k) {
    p.dv[k] = m.dv(k);
    for (int a = 0; a < E::num_nodes; ++a)
      for (int j = 0; j < 3; ++j) p.G[k](a, j) = m.GT(k, 3 * a + j);
  }
  p.L = m.L;
  return p;
}

}  // namespace plastifem
