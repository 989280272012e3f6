// A step's matrix work against what this machine's memory can do (issue 36's roofline).
//
// First the bandwidth the machine gives: STREAM-style copy (a = b) and triad (a = b + s c) over
// 3 x 128 MB arrays, far beyond any cache, on 1 and 2 threads. Then, for the Newmark matrix
// A = c0 M + K0 of each bar scene (SCENES.md material, dt = 0.01, Linear K0: the pattern and the
// bytes are those of every model), the passes over the matrix a step makes:
//
//   product   y = A x, the CG's product (BlockSymmetricMatrix::multiply): streams each stored
//             block once, 72 bytes of values + 4 of column index, and x and y (24 bytes per
//             node each way) - the least a product can move;
//   zero      the tangent set to zero before its assembly: writes 72 bytes per block;
//   scatter   every element's 24 x 24 matrix added into the blocks it touches
//             (Assembler::add_element_matrix, colour by colour as the step assembles): reads and
//             writes 72 bytes per element block (Hex8: 36, Tet4: 10 per element) and reads the
//             element matrix (one shared here: it stays in cache);
//   form      A = cm M + K (System::form's pass): reads two matrices, writes one.
//
// The zeroing and the form run on all threads, each writing the blocks its product reads
// (BlockSymmetricMatrix::for_value_ranges). Two more rows per scene time them as a step chains
// them, zero + scatter and form + 7 products (a real-time step's CG), and again with the first
// pass on one thread (as they were): the difference is the cost of values written by one core
// and read by another.
//
// For each: median ms over 30 runs, the bytes it must move, the GB/s that makes, and that as a
// share of the triad bandwidth on as many threads. A share near 1 is memory-bound: only fewer
// bytes make it faster; a share well below 1 with the matrix far larger than the caches means
// the pass is bound by its instructions (loads, stores, the scattered adds), not by memory.
//
//   bench_memory [--scenes bar720,bar5760,bar46080] [--elements hex8,tet4] [--threads 1,2] [--csv FILE]
#include <plastifem/plastifem.hpp>

#include "bench_common.hpp"

#include <fmt/core.h>

#include <chrono>
#include <fstream>
#include <string>
#include <vector>

#ifdef _OPENMP
#include <omp.h>
#endif

using namespace plastifem;
using plastifem::bench::median_ms;
using plastifem::bench::split;

namespace {

struct Row {
  std::string pass, scene, element;
  int threads;
  Index blocks, nodes, elements;
  double mb, ms;
};

/// STREAM's copy and triad (McCalpin): bytes counted as STREAM counts them (each array read or
/// written once; the write-allocate reads of a cached store are not counted).
std::vector<Row> stream_rows(int threads) {
  const Index n = 16 * 1024 * 1024;  // 128 MB per array
  std::vector<double> a(n, 1.0), b(n, 2.0), c(n, 3.0);
  double* pa = a.data();
  const double *pb = b.data(), *pc = c.data();
  const double copy = median_ms([&] {
#ifdef _OPENMP
#pragma omp parallel for schedule(static) num_threads(threads)
#endif
    for (Index i = 0; i < n; ++i) pa[i] = pb[i];
  });
  const double triad = median_ms([&] {
#ifdef _OPENMP
#pragma omp parallel for schedule(static) num_threads(threads)
#endif
    for (Index i = 0; i < n; ++i) pa[i] = pb[i] + 3.0 * pc[i];
  });
  const double mb = 8.0 * static_cast<double>(n) / 1e6;
  return {{"stream copy", "-", "-", threads, 0, 0, 0, 2 * mb, copy},
          {"stream triad", "-", "-", threads, 0, 0, 0, 3 * mb, triad}};
}

template <class E>
std::vector<Row> matrix_rows(const std::string& scene, int threads) {
  const auto [nx, ny, nz] = bar_scene_cells(scene);
  const Mesh<E> mesh = bar_mesh<E>(nx, ny, nz);
  const Material material{3000, 0.45, 1.0};
  const Assembler<E> assembler(mesh);
  BlockSymmetricMatrix M = assembler.zero_matrix(), K = assembler.zero_matrix(), A = assembler.zero_matrix();
  assemble_mass(mesh, assembler, material.density, MassKind::Consistent, M);
  // One element's K0 scattered everywhere: the same bytes as each element's own, and the
  // element matrix stays in cache as a step's freshly computed one does.
  const ElementNodes<E> X = mesh.element_nodes(0);
  ElementVector<E> f;
  ElementMatrix<E> Ke;
  Linear::evaluate<E>(Linear::prepare<E>(X, material), X, f, &Ke);
  const Scalar cm = 1 / (0.25 * 0.01 * 0.01);

  const Index nb = A.pattern().num_blocks(), nodes = mesh.num_nodes(), ne = mesh.num_elements();
  constexpr Index element_blocks = E::num_nodes * (E::num_nodes + 1) / 2;
  const double block_mb = 72e-6 * static_cast<double>(nb);
  std::vector<Row> rows;
  auto row = [&](const std::string& pass, double mb, double ms) {
    rows.push_back({pass, scene, E::name, threads, nb, nodes, ne, mb, ms});
  };

  const double zero = median_ms([&] { K.set_zero(threads); });
  row("zero", block_mb, zero);
  auto scatter_pass = [&] {
    assembler.for_each_element([&](Index e) { assembler.add_element_matrix(e, Ke, K.values()); }, threads);
  };
  const double scatter = median_ms(scatter_pass);
  const double scatter_mb = 144e-6 * static_cast<double>(element_blocks * ne);
  row("scatter", scatter_mb, scatter);
  auto form_pass = [&](int form_threads) { A.set_combination(cm, M, K, 0, nullptr, form_threads); };  // System::form's
  row("form", 3 * block_mb, median_ms([&] { form_pass(threads); }));
  Vector x = Vector::Random(A.rows()), y(A.rows());
  const double product_mb = 76e-6 * static_cast<double>(nb) + 72e-6 * static_cast<double>(nodes);
  row("product", product_mb, median_ms([&] { A.multiply(x, y, threads); }));
  // As a step runs them: the zeroing then the scatter, the form then a real-time step's CG
  // (7 products); with the first pass on all threads (the library's) and on one thread, which
  // leaves the values in one core's cache for the other thread to fetch.
  for (int first : {threads, 1}) {
    if (first == 1 && threads == 1) break;
    const std::string on = first == 1 ? " (1st on 1 thread)" : "";
    rows.push_back({"zero+scatter" + on, scene, E::name, threads, nb, nodes, ne, block_mb + scatter_mb,
                    median_ms([&] { K.set_zero(first), scatter_pass(); })});
    rows.push_back({"form+7 products" + on, scene, E::name, threads, nb, nodes, ne, 3 * block_mb + 7 * product_mb,
                    median_ms([&] {
                      form_pass(first);
                      for (int j = 0; j < 7; ++j) A.multiply(x, y, threads);
                    })});
  }
  return rows;
}

}  // namespace

int main(int argc, char** argv) try {
  std::vector<std::string> scenes{"bar720", "bar5760", "bar46080"}, elements{"hex8", "tet4"};
  std::vector<int> threads{1, 2};
  std::string csv = "bench_memory.csv";
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (i + 1 < argc && a == "--scenes") scenes = split(argv[++i]);
    else if (i + 1 < argc && a == "--elements") elements = split(argv[++i]);
    else if (i + 1 < argc && a == "--csv") csv = argv[++i];
    else if (i + 1 < argc && a == "--threads") threads = plastifem::bench::split_ints(argv[++i]);
    else fail<InvalidArgument>("unknown option '{}'", a);
  }
  std::ofstream out(csv);
  out << "pass,scene,element,threads,blocks,nodes,elements,mb_moved,median_ms,gb_per_s,share_of_triad,ns_per_block,"
         "bytes_per_element\n";
  fmt::print("{:33} {:9} {:5} {:>3} {:>8} {:>9} {:>9} {:>7} {:>6} {:>8} {:>8}\n", "pass", "scene", "elem", "thr", "blocks",
             "MB moved", "median ms", "GB/s", "share", "ns/block", "B/elem");
  for (int t : threads) {
    const std::vector<Row> stream = stream_rows(t);
    const double triad = stream[1].mb / stream[1].ms;  // MB/ms = GB/s
    std::vector<Row> rows = stream;
    for (const auto& scene : scenes)
      for (const auto& e : elements) {
        std::vector<Row> r;
        if (e == "hex8") r = matrix_rows<Hex8>(scene, t);
        else if (e == "tet4") r = matrix_rows<Tet4>(scene, t);
        else fail<InvalidArgument>("--elements: hex8 or tet4, got '{}'", e);
        rows.insert(rows.end(), r.begin(), r.end());
      }
    for (const Row& r : rows) {
      const double gbs = r.mb / r.ms;
      const double ns_block = r.blocks ? 1e6 * r.ms / static_cast<double>(r.blocks) : 0;
      const double per_element = r.elements ? 1e6 * r.mb / static_cast<double>(r.elements) : 0;
      fmt::print("{:33} {:9} {:5} {:>3} {:>8} {:>9.1f} {:>9.3f} {:>7.1f} {:>6.2f} {:>8.2f} {:>8.0f}\n", r.pass, r.scene,
                 r.element, r.threads, r.blocks, r.mb, r.ms, gbs, gbs / triad, ns_block, per_element);
      out << fmt::format("{},{},{},{},{},{},{},{:.3f},{:.6f},{:.2f},{:.3f},{:.3f},{:.0f}\n", r.pass, r.scene, r.element,
                         r.threads, r.blocks, r.nodes, r.elements, r.mb, r.ms, gbs, gbs / triad, ns_block, per_element);
    }
    std::fflush(stdout);
  }
  fmt::print("CSV written to {}\n", csv);
  return 0;
} catch (const std::exception& e) {
  fmt::print(stderr, "bench_memory: {}\n", e.what());
  return 1;
}
