// Cost of writing and reading a VTU file, per encoding, for a mesh with a displacement field
// (what an example writes every frame). Median of `--repeat` (default 7) writes and reads.
//
//   bench_io [--cells N] [--repeat R] [--csv FILE]     N^3 Hex8 cells (default 36: 50,653 nodes)
#include <plastifem/mesh/generators.hpp>
#include <plastifem/mesh/io/io.hpp>

#include "bench_common.hpp"

#include <fmt/core.h>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <vector>

using namespace plastifem;

using plastifem::bench::median;
using plastifem::bench::ms_since;

int main(int argc, char** argv) {
  int cells = 36, repeat = 7;
  std::string csv = "bench_io.csv";
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string a = argv[i];
    if (a == "--cells") cells = std::stoi(argv[i + 1]);
    else if (a == "--repeat") repeat = std::stoi(argv[i + 1]);
    else if (a == "--csv") csv = argv[i + 1];
    else {
      fmt::print(stderr, "usage: bench_io [--cells N] [--repeat R] [--csv FILE]\n");
      return 2;
    }
  }
  if (cells < 1 || repeat < 1) {
    fmt::print(stderr, "bench_io: --cells and --repeat must be positive\n");
    return 2;
  }
  const Mesh<Hex8> mesh = bar_mesh<Hex8>(cells, cells, cells);
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> d(-1, 1);
  Eigen::Matrix3Xd u(3, mesh.num_nodes());
  for (Eigen::Index i = 0; i < u.size(); ++i) u.data()[i] = d(rng);

  std::ofstream out(csv);
  out << "encoding,nodes,cells,bytes,write_ms,read_ms\n";
  fmt::print("{:>8} {:>8} {:>8} {:>11} {:>10} {:>10}\n", "encoding", "nodes", "cells", "bytes", "write ms", "read ms");
  const std::pair<io::Encoding, const char*> encodings[] = {
      {io::Encoding::ascii, "ascii"}, {io::Encoding::appended_raw, "raw"}, {io::Encoding::appended_base64, "base64"}};
  const std::filesystem::path dir = std::filesystem::temp_directory_path();
  for (const auto& [enc, name] : encodings) {
    io::VtuOptions options;
    options.encoding = enc;
    const std::string path = (dir / fmt::format("plastifem_bench_io_{}.vtu", name)).string();
    std::vector<double> write, read;
    for (int r = 0; r < repeat; ++r) {
      auto t0 = std::chrono::steady_clock::now();
      io::write_vtu(path, mesh, {{"displacement", u}}, {}, options);
      write.push_back(ms_since(t0));
      t0 = std::chrono::steady_clock::now();
      const io::MeshData<Hex8> back = io::read_vtu<Hex8>(path);
      read.push_back(ms_since(t0));
      if (back.mesh.num_nodes() != mesh.num_nodes()) {
        fmt::print(stderr, "bench_io: {} read back {} nodes, wrote {}\n", name, back.mesh.num_nodes(), mesh.num_nodes());
        return 1;
      }
    }
    const auto bytes = std::filesystem::file_size(path);
    std::filesystem::remove(path);
    fmt::print("{:>8} {:>8} {:>8} {:>11} {:>10.1f} {:>10.1f}\n", name, mesh.num_nodes(), mesh.num_elements(), bytes,
               median(write), median(read));
    out << fmt::format("{},{},{},{},{:.2f},{:.2f}\n", name, mesh.num_nodes(), mesh.num_elements(), bytes,
                       median(write), median(read));
  }
}
