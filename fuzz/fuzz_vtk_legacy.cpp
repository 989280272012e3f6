// libFuzzer target: legacy .vtk text read as a Mesh<Tet4>, Mesh<Tet10> and Mesh<Hex8> with fields.
#include <plastifem/mesh/io/vtk_legacy.hpp>

#include "fuzz_common.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text = plastifem::fuzz::as_text(data, size);
  plastifem::fuzz::for_each_element([&]<class E>() {
    const auto d = plastifem::io::read_vtk_legacy_string<E>(text, "fuzz.vtk");
    plastifem::fuzz::check_mesh(d.mesh);
    for (const auto& [name, v] : d.point_data) PLASTIFEM_FUZZ_CHECK(v.cols() == d.mesh.num_nodes());
    for (const auto& [name, v] : d.cell_data) PLASTIFEM_FUZZ_CHECK(v.cols() == d.mesh.num_elements());
    plastifem::fuzz::check_dropped(d, plastifem::io::read_vtk_legacy_string<E>(text, "fuzz.vtk", {.drop_unused_nodes = true}));
  });
  return 0;
}
