#pragma once
// The ElasticModel concept: what the solver needs from an elastic policy.
#include <plastifem/elastic/corotational.hpp>
#include <plastifem/elastic/hyperelastic.hpp>
#include <plastifem/elastic/linear.hpp>
#include <plastifem/elastic/mooney_rivlin.hpp>

#include <utility>

namespace plastifem {

/// An elastic policy: per-element data prepared once from the rest shape and material, then
/// internal force, tangent and strain energy at any current configuration, and the stress for
/// output. All static: no virtual calls in the element loop. The concept lists the calls the
/// library makes (assembly/discretization.hpp, enrichment/cut_element.hpp, plastic/flow.hpp).
template <class M, class E>
concept ElasticModel =
    FiniteElement<E> &&
    requires(const typename M::template ElementData<E>& data, const ElementNodes<E>& x, ElementVector<E>& f,
             ElementMatrix<E>* K, const Material& m, TangentKind kind, bool lower, const PointSet<E>& points) {
      { M::name } -> std::convertible_to<const char*>;
      { M::constant_tangent } -> std::convertible_to<bool>;
      { M::template prepare<E>(x, m) } -> std::same_as<typename M::template ElementData<E>>;
      // Energy W_e and force f_e at x; with K, the tangent of the kind asked for (the projected
      // one, positive semi-definite, where the model has no exact one), its lower triangle only
      // if `lower` (the assembly's block storage); without, forces and energy only.
      { M::template evaluate<E>(data, x, f, K, kind, lower) } -> std::same_as<Scalar>;
      { M::template evaluate<E>(data, x, f, K) } -> std::same_as<Scalar>;
      { M::template cauchy_stress<E>(data, x, m) } -> std::same_as<Mat3>;
      // A cut element's piece's stress: an element-mean term (MeanDilatation) over its points.
      { M::template cauchy_stress<E>(data, x, m, &points) } -> std::same_as<Mat3>;
      // The point-wise interface (elastic/point_law.hpp): a point law built from the material,
      // and the element integral over any point set (a cut element's pieces).
      typename M::Law;
      requires std::constructible_from<typename M::Law, const Material&>;
      { M::template evaluate_points<E>(std::declval<const typename M::Law&>(), points, x, f, K, kind) }
          -> std::same_as<Scalar>;
    };

/// Whether a model has an exact tangent besides its projected (positive semi-definite) one.
template <class M>
constexpr bool has_exact_tangent_v = [] {
  if constexpr (requires { M::has_exact_tangent; }) return bool(M::has_exact_tangent);
  else return false;
}();

/// Whether a model is defined at inverted points (det F <= 0), as it says by
/// `defined_when_inverted = true` (Linear, the corotational models, StableNeoHookean). A model
/// that does not say is taken to be undefined there (an energy with ln J): only messages read it.
template <class M>
constexpr bool defined_when_inverted_v = requires { requires bool(M::defined_when_inverted); };

// Every model meets the concept on every element: tests/test_elastic.cpp (checked there, not
// here, so that a file pays only for the compositions it uses; each Solver checks its own).

}  // namespace plastifem
