#pragma once
// NoPlasticity: the element's rest shape never changes. The solver's plastic hooks do nothing
// for it (plastic/hooks.hpp), so an elastic scene pays nothing for the axis.
#include <plastifem/core/types.hpp>

namespace plastifem {

struct NoPlasticity {
  static constexpr const char* name = "NoPlasticity";
  static constexpr bool active = false;
  struct Params {};
};

/// The plastic part of a State for NoPlasticity: nothing.
struct NoPlasticState {
  void resize(Index) {}
  friend bool operator==(const NoPlasticState&, const NoPlasticState&) { return true; }
};

}  // namespace plastifem
