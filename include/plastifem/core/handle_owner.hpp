#pragma once
// HandleOwner: a process-wide unique number for each object that hands out handles (a
// solver's constraint sets, its loads, its cuts). A handle carries its issuer's number next to
// its own id, so that a handle of one solver is refused by another instead of naming whatever
// that one numbered the same (issue 33: release() with another solver's first clamp released
// this solver's first clamp). Handles stay small value types: two 32-bit numbers.
//
// The number moves with the object (a moved-to solver answers to the handles it was given), and
// the moved-from object draws a new one, so two live objects never share a number; a copy, or
// an object assigned a copy, draws a new one too (the handles it gave out named its old
// contents). 0 is no owner (a default handle).
#include <atomic>
#include <cstdint>

namespace plastifem {

class HandleOwner {
 public:
  HandleOwner() : id_(next()) {}
  HandleOwner(const HandleOwner&) : id_(next()) {}
  HandleOwner(HandleOwner&& o) noexcept : id_(o.id_) { o.id_ = next(); }
  HandleOwner& operator=(const HandleOwner&) {  // new contents: the handles of the old ones name nothing
    id_ = next();
    return *this;
  }
  HandleOwner& operator=(HandleOwner&& o) noexcept {
    if (this != &o) id_ = o.id_, o.id_ = next();
    return *this;
  }
  std::uint32_t id() const { return id_; }

 private:
  static std::uint32_t next() {
    static std::atomic<std::uint32_t> counter{0};
    std::uint32_t n;
    do n = ++counter;
    while (n == 0);  // after 2^32 owners: skip "no owner"
    return n;
  }
  std::uint32_t id_;
};

/// Whether an object still holds its contents: true when constructed or copied, false once it
/// has been moved from (its members then hold no body, no dofs). The Solver refuses to be
/// changed or stepped when moved from, with a message, instead of reading empty members (a
/// step on a moved-from solver crashed).
class MovedFromFlag {
 public:
  MovedFromFlag() = default;
  MovedFromFlag(const MovedFromFlag&) = default;
  MovedFromFlag(MovedFromFlag&& o) noexcept : moved_from_(o.moved_from_) { o.moved_from_ = true; }
  MovedFromFlag& operator=(const MovedFromFlag&) = default;
  MovedFromFlag& operator=(MovedFromFlag&& o) noexcept {
    if (this != &o) moved_from_ = o.moved_from_, o.moved_from_ = true;
    return *this;
  }
  bool moved_from() const { return moved_from_; }

 private:
  bool moved_from_ = false;
};

}  // namespace plastifem
