#pragma once
// NoPlasticity: the element's rest shape never changes. The solver's plastic hooks compile to
// nothing for it (if constexpr on `active`), so an elastic scene pays nothing for the axis.
namespace plastifem {

struct NoPlasticity {
  static constexpr const char* name = "NoPlasticity";
  static constexpr bool active = false;
  struct Params {};
};

}  // namespace plastifem
