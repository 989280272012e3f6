#pragma once
// The tests' element and composition lists, taken from the library's one list
// (solver/instantiations.hpp): a test of "every element" or "every elastic composition" names
// these, never a hand-written list, so a new entry there is tested everywhere at once.
// The lists name elements and elastic models only: a test that needs no Solver compiles none.
#include <plastifem/elastic/elastic.hpp>
#include <plastifem/element/element.hpp>
#include <plastifem/solver/instantiations.hpp>

#include <tuple>

namespace plastifem::testing {

/// An element with a model, for tests that take both (TestType::E, TestType::M).
template <class E_, class M_>
struct Combo {
  using E = E_;
  using M = M_;
};

namespace lists {
template <class T>
struct drop_first;
template <class A, class... S>
struct drop_first<std::tuple<A, S...>> {
  using type = std::tuple<S...>;
};
template <class... T>
using tuple_cat_t = decltype(std::tuple_cat(std::declval<T>()...));
// ModelsOn<std::tuple<E...>, M...>: Combo<E, M> for each element E, then for each model M.
template <class Elements, class... M>
struct ModelsOn;
template <class... E, class... M>
struct ModelsOn<std::tuple<E...>, M...> {
  template <class M1>
  using one = std::tuple<Combo<E, M1>...>;
  using type = tuple_cat_t<one<M>...>;
};
}  // namespace lists

/// A list written as "std::tuple<void, T...>" (each macro entry X(...) expanding to ", T"): its T...
template <class T>
using DropFirst = typename lists::drop_first<T>::type;

#define PLASTIFEM_TEST_ELEMENT(X, E) , plastifem::E
#define PLASTIFEM_TEST_COMBO(E, M) , plastifem::testing::Combo<plastifem::E, plastifem::M>

/// Every element.
using AllElements = DropFirst<std::tuple<void PLASTIFEM_FOR_EACH_ELEMENT(PLASTIFEM_TEST_ELEMENT, _)>>;
/// Every element with every elastic model (the list's elastic compositions, Hex8's
/// mean-dilatation models included).
using ElasticCombos = DropFirst<std::tuple<void PLASTIFEM_ELASTIC_SOLVERS(PLASTIFEM_TEST_COMBO)>>;
/// Each of the given models on every element: Combo<E, M> for every E, model by model.
template <class... M>
using OnEveryElement = typename lists::ModelsOn<AllElements, M...>::type;
/// Type lists (std::tuple), concatenated.
template <class... T>
using Concat = lists::tuple_cat_t<T...>;

}  // namespace plastifem::testing
