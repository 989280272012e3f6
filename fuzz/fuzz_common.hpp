#pragma once
// Shared by the fuzz targets: run a reader on the input as a mesh of each element type, accept
// plastifem::Error (bad input is expected), and check what a successful read returns. Anything
// else -- another exception, a crash, a sanitizer report, a broken invariant (__builtin_trap) --
// is a finding for libFuzzer.
#include <plastifem/mesh/io/vtu.hpp>  // MeshData, ReadOptions
#include <plastifem/mesh/mesh.hpp>

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <string>

namespace plastifem::fuzz {

#define PLASTIFEM_FUZZ_CHECK(cond) \
  do {                             \
    if (!(cond)) __builtin_trap(); \
  } while (0)

/// read<E>() for Tet4, Tet10 and Hex8 in turn, ignoring plastifem::Error.
template <class Read>
void for_each_element(Read&& read) {
  auto one = [&]<class E>() {
    try {
      read.template operator()<E>();
    } catch (const Error&) {
    }
  };
  one.template operator()<Tet4>();
  one.template operator()<Tet10>();
  one.template operator()<Hex8>();
}

/// A mesh a reader returned is valid, and drop_unused_nodes keeps every element and set.
template <FiniteElement E>
void check_mesh(const Mesh<E>& mesh) {
  PLASTIFEM_FUZZ_CHECK(mesh.num_elements() > 0);
  std::vector<Index> old_to_new;
  const Mesh<E> compact = drop_unused_nodes(mesh, &old_to_new);
  PLASTIFEM_FUZZ_CHECK(compact.num_elements() == mesh.num_elements());
  PLASTIFEM_FUZZ_CHECK(compact.report().unused_nodes.empty());
  PLASTIFEM_FUZZ_CHECK(compact.num_nodes() + static_cast<Index>(mesh.report().unused_nodes.size()) == mesh.num_nodes());
  PLASTIFEM_FUZZ_CHECK(old_to_new.size() == static_cast<size_t>(mesh.num_nodes()));
  for (Index e = 0; e < mesh.num_elements(); ++e)
    for (int a = 0; a < E::num_nodes; ++a)
      PLASTIFEM_FUZZ_CHECK(compact.node(compact.element(e)[a]) == mesh.node(mesh.element(e)[a]));
  PLASTIFEM_FUZZ_CHECK(compact.node_sets().size() == mesh.node_sets().size());
  PLASTIFEM_FUZZ_CHECK(compact.face_sets() == mesh.face_sets());
}

/// What a reader returns with ReadOptions::drop_unused_nodes is what drop_unused_nodes makes of
/// what it returns without.
template <FiniteElement E>
void check_dropped(const Mesh<E>& mesh, const Mesh<E>& dropped) {
  const Mesh<E> expected = drop_unused_nodes(mesh);
  PLASTIFEM_FUZZ_CHECK(dropped.num_nodes() == expected.num_nodes() && dropped.nodes() == expected.nodes());
  PLASTIFEM_FUZZ_CHECK(dropped.elements() == expected.elements());
  PLASTIFEM_FUZZ_CHECK(dropped.node_sets() == expected.node_sets());
  PLASTIFEM_FUZZ_CHECK(dropped.face_sets() == expected.face_sets());
}

/// The same for a reader with fields: the dropped read's point fields are the kept nodes' columns.
template <FiniteElement E>
void check_dropped(const io::MeshData<E>& all, const io::MeshData<E>& dropped) {
  check_dropped(all.mesh, dropped.mesh);
  std::vector<Index> old_to_new;
  drop_unused_nodes(all.mesh, &old_to_new);
  PLASTIFEM_FUZZ_CHECK(all.point_data.size() == dropped.point_data.size());
  for (const auto& [name, v] : all.point_data) {
    const Eigen::MatrixXd& d = dropped.point_data.at(name);
    PLASTIFEM_FUZZ_CHECK(d.rows() == v.rows() && d.cols() == dropped.mesh.num_nodes());
    for (size_t i = 0; i < old_to_new.size(); ++i)
      if (old_to_new[i] >= 0)
        for (Eigen::Index r = 0; r < v.rows(); ++r) {
          const double x = v(r, static_cast<Eigen::Index>(i)), y = d(r, old_to_new[i]);
          PLASTIFEM_FUZZ_CHECK(x == y || (std::isnan(x) && std::isnan(y)));
        }
  }
  PLASTIFEM_FUZZ_CHECK(all.cell_data.size() == dropped.cell_data.size());
}

inline std::string as_text(const std::uint8_t* data, std::size_t size) {
  return std::string(reinterpret_cast<const char*>(data), size);
}

}  // namespace plastifem::fuzz
