#pragma once
// Corotational elasticity (seed 001 eq. 31-40): the element's rotation R is factored out of
// the deformation, the linear element works in the rotated frame, and its forces are rotated
// back:
//   f = R K0 (R^T x - X0),      K = R K0 R^T  (block-wise: K_ab = R K0_ab R^T).
//
// One rotation per element, from the deformation gradient at the element centre
// F = sum_a x_a (dN_a/dX)^T, by polar decomposition (core/polar.hpp: robust to near-degenerate
// and inverted F). For Tet4 F is constant, so this is exact. For Hex8 and Tet10 it is SOFA's
// and VegaFEM's choice ("polar" hexahedron, one R per element): one polar decomposition and one
// rotation of K0 per element, instead of one per quadrature point (8x and 4x the cost); the
// price is that a strongly bent single element is rotated on average.
//
// Tangent: R K0 R^T omits the derivative of R with respect to x (VegaFEM's warp=1, SOFA's
// choice). It is symmetric positive semi-definite, so CG and LDLT apply; Newton then converges
// linearly rather than quadratically at large rotation rates (tests report the iterations).
#include <plastifem/core/polar.hpp>
#include <plastifem/elastic/small_strain.hpp>

namespace plastifem {

struct Corotational {
  static constexpr const char* name = "Corotational";
  static constexpr bool constant_tangent = false;

  template <FiniteElement E>
  using ElementData = SmallStrainData<E>;

  template <FiniteElement E>
  static ElementData<E> prepare(const ElementNodes<E>& X0, const Material& m) {
    return prepare_small_strain<E>(X0, m);
  }

  template <FiniteElement E>
  static Scalar evaluate(const ElementData<E>& d, const ElementNodes<E>& x, ElementVector<E>& f,
                         ElementMatrix<E>* K) {
    constexpr int N = E::num_nodes;
    const Mat3 R = rotation_of(x * d.G_centre);
    const ElementNodes<E> y = R.transpose() * x - d.X0;  // displacement in the rotated frame
    const ElementVector<E> f0 = d.K0 * as_vector<E>(y);
    Eigen::Map<ElementNodes<E>>(f.data()) = R * Eigen::Map<const ElementNodes<E>>(f0.data());
    if (K) {
      for (int b = 0; b < N; ++b)
        for (int a = 0; a < N; ++a)
          K->template block<3, 3>(3 * a, 3 * b).noalias() =
              R * (d.K0.template block<3, 3>(3 * a, 3 * b) * R.transpose());
    }
    return 0.5 * as_vector<E>(y).dot(f0);
  }

  /// Cauchy stress at the element centre: R C(sym(R^T F) - I) R^T.
  template <FiniteElement E>
  static Mat3 cauchy_stress(const ElementData<E>& d, const ElementNodes<E>& x, const Material& m) {
    const Mat3 F = x * d.G_centre;
    const Mat3 R = rotation_of(F);
    const Mat3 S = R.transpose() * F;
    return R * hooke(m, 0.5 * (S + S.transpose()) - Mat3::Identity()) * R.transpose();
  }
};

}  // namespace plastifem
