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
///
/// The format string is read at run time, as fmt::vformat does, unless PLASTIFEM_CHECK_FORMATS
/// is defined: then fmt checks it against the arguments at compile time (fmt::format_string).
/// That check is a constant evaluation per call site, and a file with one header-only
/// Solver<Hex8, Corotational> instantiates some hundred of them in its validation and error
/// paths: 16 MB of g++'s 981 MB for that file, paid by every user for messages they rarely
/// see. The project's own builds define it (CMakeLists.txt: plastifem::compiled carries it to
/// everything that links it, the tests too), so every message the toolkit can throw is checked
/// there; like NDEBUG, it changes no behaviour, only what the compiler verifies.
#ifdef PLASTIFEM_CHECK_FORMATS
template <class E = Error, class... Args>
[[noreturn]] void fail(fmt::format_string<Args...> format, Args&&... args) {
  throw E(fmt::format(format, std::forward<Args>(args)...));
}
#else
template <class E = Error, class... Args>
[[noreturn]] void fail(fmt::string_view format, const Args&... args) {
  throw E(fmt::vformat(format, fmt::make_format_args(args...)));
}
#endif

/// InvalidArgument "`what` i out of range [0, n)": the cold half of checked_index, out of line.
[[noreturn]] inline void index_out_of_range(const char* what, long long i, long long n) {
  fail<InvalidArgument>("{} {} out of range [0, {})", what, i, n);
}

/// i, when 0 <= i < n; else InvalidArgument naming `what` (e.g. "Mesh::node: node"). The public
/// accessors by index use it: a compare on the way, never a read out of bounds.
template <class I>
I checked_index(I i, I n, const char* what) {
  if (i < 0 || i >= n) [[unlikely]]
    index_out_of_range(what, static_cast<long long>(i), static_cast<long long>(n));
  return i;
}

}  // namespace plastifem
