// libFuzzer target: a triangle surface, read as Wavefront OBJ text and as STL (ASCII, or binary
// when the size says so). What reads must be a surface check_surface accepts (finite vertices,
// indices in range, no repeated vertex in a triangle), with at least one triangle.
#include <plastifem/mesh/io/surface.hpp>

#include "fuzz_common.hpp"

namespace {
template <class Read>
void read_and_check(Read&& read) {
  plastifem::TriangleSurface s;
  try {
    s = read();
  } catch (const plastifem::Error&) {
    return;  // bad input, refused
  }
  PLASTIFEM_FUZZ_CHECK(s.num_triangles() > 0);
  try {
    plastifem::check_surface(s);
  } catch (const plastifem::Error&) {
    __builtin_trap();  // a reader returned a surface it should have refused
  }
}
}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text = plastifem::fuzz::as_text(data, size);
  read_and_check([&] { return plastifem::io::read_obj_string(text, "fuzz.obj"); });
  read_and_check([&] { return plastifem::io::read_stl_string(text, "fuzz.stl"); });
  return 0;
}
