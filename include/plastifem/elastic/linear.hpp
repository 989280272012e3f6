#pragma once
// Linear elasticity: f = K0 (x - X0), tangent K0 (seed 001 sections 3.5-3.6).
// Not invariant under rotation: a rigidly rotated element feels "ghost" forces, which is why
// Corotational exists (tests/test_elastic.cpp measures them).
#include <plastifem/elastic/small_strain_law.hpp>

namespace plastifem {

/// Volumetric::MeanDilatation: the B-bar locking remedy (elastic/small_strain.hpp).
template <Volumetric V = Volumetric::Full>
struct LinearElastic {
  static constexpr const char* name = V == Volumetric::Full ? "Linear" : "LinearMeanDilatation";
  static constexpr bool constant_tangent = true;  ///< K does not depend on x: assemble once
  static constexpr bool defined_when_inverted = true;

  template <FiniteElement E>
  using ElementData = SmallStrainDataOf<E, V>;

  template <FiniteElement E>
  static ElementData<E> prepare(const ElementNodes<E>& X0, const Material& m) {
    return prepare_small_strain_data<E, V>(X0, m);
  }

  /// Internal force f and (optionally) tangent K at current positions x; returns strain energy.
  template <FiniteElement E>
  static Scalar evaluate(const ElementData<E>& d, const ElementNodes<E>& x, ElementVector<E>& f,
                         ElementMatrix<E>* K) {
    // u relative to node 0's displacement: K0 annihilates translations, so f and W are those
    // of x - X0.
    const ElementNodes<E> xr = relative_to_first_node<E>(x);
    const ElementVector<E> u = as_vector<E>(xr) - as_vector<E>(d.X0);
    f.noalias() = d.K0 * u;
    if (K) *K = d.K0;
    return 0.5 * u.dot(f);
  }
  /// The solver's signature (tangent kind and lower-blocks-only: the same K0 either way).
  template <FiniteElement E>
  static Scalar evaluate(const ElementData<E>& d, const ElementNodes<E>& x, ElementVector<E>& f, ElementMatrix<E>* K,
                         TangentKind, bool) {
    return evaluate<E>(d, x, f, K);
  }

  /// The point law (elastic/small_strain_law.hpp) and the element integral over any point set
  /// (a cut element's sub-tetrahedra); over the Gauss rule it equals evaluate().
  using Law = SmallStrainLaw;
  template <FiniteElement E>
  static Scalar evaluate_points(const Law& law, const PointSet<E>& ps, const ElementNodes<E>& x, ElementVector<E>& f,
                                ElementMatrix<E>* K, TangentKind = TangentKind::Projected) {
    return detail::small_strain_points<E>(law, V == Volumetric::MeanDilatation, ps, x, Mat3::Identity(), f, K);
  }

  /// Cauchy stress at the element centre: sigma = C sym(grad u); with MeanDilatation the
  /// strain's trace is the element's mean dilatation tr(u gbar), the one its forces use (the
  /// centre's own trace differs on a non-affine element, times kappa near nu = 0.5); given a
  /// cut element's `piece`, the piece's mean dilatation, as its forces take it.
  template <FiniteElement E>
  static Mat3 cauchy_stress(const ElementData<E>& d, const ElementNodes<E>& x, const Material& m,
                            const PointSet<E>* piece = nullptr) {
    const ElementNodes<E> u = relative_to_first_node<E>(x) - d.X0;
    const Mat3 H = u * d.G_centre;
    Mat3 eps = 0.5 * (H + H.transpose());
    if constexpr (V == Volumetric::MeanDilatation)
      eps.diagonal().array() += ((u * (piece ? piece->mean_gradient() : d.G_mean)).trace() - eps.trace()) / 3;
    return hooke(m, eps);
  }
};

using Linear = LinearElastic<>;
using LinearMeanDilatation = LinearElastic<Volumetric::MeanDilatation>;

}  // namespace plastifem
