#pragma once
// Notes: what the toolkit tells its user that is worth knowing but not an error (a node no
// element uses is held fixed, ...). They go to a handler, by default one line on stderr; a
// simulator routes them to its own log with set_note_handler.
#include <fmt/format.h>

#include <cstdio>
#include <functional>
#include <string>
#include <utility>

namespace plastifem {

using NoteHandler = std::function<void(const std::string&)>;

namespace detail {
inline NoteHandler& note_handler() {
  static NoteHandler handler = [](const std::string& s) { std::fprintf(stderr, "plastifem: %s\n", s.c_str()); };
  return handler;
}
}  // namespace detail

/// Routes notes to `handler` (an empty handler silences them); returns the previous one.
inline NoteHandler set_note_handler(NoteHandler handler) {
  return std::exchange(detail::note_handler(), std::move(handler));
}

/// Sends a note to the handler.
inline void note(const std::string& message) {
  if (const auto& h = detail::note_handler()) h(message);
}

}  // namespace plastifem
