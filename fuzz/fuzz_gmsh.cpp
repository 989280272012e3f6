// libFuzzer target: Gmsh .msh text (2.2 and 4.1) read as a Mesh<Tet4>, Mesh<Tet10> and Mesh<Hex8>.
#include <plastifem/mesh/io/gmsh.hpp>

#include "fuzz_common.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text = plastifem::fuzz::as_text(data, size);
  plastifem::fuzz::for_each_element([&]<class E>() {
    const plastifem::Mesh<E> mesh = plastifem::io::read_gmsh_string<E>(text, "fuzz.msh");
    plastifem::fuzz::check_mesh(mesh);
    plastifem::fuzz::check_dropped(mesh, plastifem::io::read_gmsh_string<E>(text, "fuzz.msh", {.drop_unused_nodes = true}));
  });
  return 0;
}
