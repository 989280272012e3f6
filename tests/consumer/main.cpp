// A downstream program built against the installed package.
#include <plastifem/plastifem.hpp>

#include <fmt/core.h>

int main() {
  const auto mesh = plastifem::bar_mesh<plastifem::Hex8>(10, 3, 3);
  fmt::print("consumer: bar90 has {} nodes and {} elements\n", mesh.num_nodes(), mesh.num_elements());
  return (mesh.num_nodes() == 176 && mesh.num_elements() == 90) ? 0 : 1;
}
