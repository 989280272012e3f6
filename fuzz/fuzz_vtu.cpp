// libFuzzer target: .vtu bytes (XML with ascii, base64 or raw binary arrays) read as a Mesh<Tet4>,
// Mesh<Tet10> and Mesh<Hex8> with fields. What reads is written back in one of the three
// encodings (chosen by the input) and must read back to the same bits.
#include <plastifem/mesh/io/vtu.hpp>

#include <unistd.h>

#include <cmath>
#include <cstring>

#include "fuzz_common.hpp"

namespace {

/// Same shape and bits; any two NaNs match (ascii keeps no NaN payload).
bool same_bits(const Eigen::MatrixXd& a, const Eigen::MatrixXd& b) {
  if (a.rows() != b.rows() || a.cols() != b.cols()) return false;
  for (Eigen::Index i = 0; i < a.size(); ++i) {
    const double x = a.data()[i], y = b.data()[i];
    if (std::memcmp(&x, &y, sizeof x) != 0 && !(std::isnan(x) && std::isnan(y))) return false;
  }
  return true;
}

bool same_fields(const std::map<std::string, Eigen::MatrixXd>& a, const std::map<std::string, Eigen::MatrixXd>& b) {
  if (a.size() != b.size()) return false;
  for (const auto& [name, v] : a)
    if (!b.count(name) || !same_bits(v, b.at(name))) return false;
  return true;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace plastifem;
  static const std::string scratch = "/tmp/plastifem_fuzz_vtu_" + std::to_string(::getpid()) + ".vtu";
  const std::string text = fuzz::as_text(data, size);
  fuzz::for_each_element([&]<class E>() {
    const io::MeshData<E> d = io::read_vtu_string<E>(text, "fuzz.vtu");
    fuzz::check_mesh(d.mesh);
    fuzz::check_dropped(d, io::read_vtu_string<E>(text, "fuzz.vtu", {.drop_unused_nodes = true}));
    io::VtuOptions options;
    options.encoding = static_cast<io::Encoding>(size % 3);
    try {  // fields with names the writer refuses (empty, duplicated after unescaping) are no finding
      io::write_vtu(scratch, d.mesh, io::to_fields(d.point_data), io::to_fields(d.cell_data), options);
    } catch (const InvalidArgument&) {
      return;
    }
    const io::MeshData<E> again = io::read_vtu<E>(scratch);
    PLASTIFEM_FUZZ_CHECK(same_bits(again.mesh.nodes(), d.mesh.nodes()));
    PLASTIFEM_FUZZ_CHECK(again.mesh.elements() == d.mesh.elements());
    PLASTIFEM_FUZZ_CHECK(same_fields(again.point_data, d.point_data));
    PLASTIFEM_FUZZ_CHECK(same_fields(again.cell_data, d.cell_data));
  });
  return 0;
}
