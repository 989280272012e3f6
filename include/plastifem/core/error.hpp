#pragma once
// One exception hierarchy. Every message says what was wrong, where (element, node,
// file:line) and, where it helps, what to do about it.
#include <fmt/format.h>

#include <stdexcept>
#include <string>
#include <utility>

namespace plastifem {

/// Base of every error plastifem throws.
class Error : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// The mesh is unusable: index out of range, non-finite coordinate, inverted element, ...
class MeshError : public Error {
 public:
  using Error::Error;
};

/// A file could not be read or written; parse errors are `file:line: what was expected`.
class IoError : public Error {
 public:
  using Error::Error;
};

/// A parameter is outside its admissible range (material, time step, boundary condition).
class InvalidArgument : public Error {
 public:
  using Error::Error;
};

/// A solve failed (no convergence, singular system); the state was left unchanged.
class SolverError : public Error {
 public:
  using Error::Error;
};

/// Throws `E` with a fmt-formatted message.
template <class E = Error, class... Args>
[[noreturn]] void fail(fmt::format_string<Args...> format, Args&&... args) {
  throw E(fmt::format(format, std::forward<Args>(args)...));
}

}  // namespace plastifem
