// Cost of one element evaluation, per element type and elastic model: internal force only,
// force + projected tangent, and force + exact tangent (where the model has one), in ns per
// element. The element loop of a step is this times the element count plus the scatter, so
// this is where kernel work is measured without the matrix and solver around it.
//
// Each element is evaluated at its own deformed state: a bar-scene element (unit cube, or one
// of its Kuhn tets) under a random rotation and a random strain (5% by default, `--strain`;
// soft tissue goes to 20% and beyond), 256 states in turn (so branch predictors and caches see
// varied input, as in a bending bar). Median of
// `--repeat` (default 9) passes over 20,000 evaluations, and the minimum (the kernel's cost
// undisturbed: on a shared machine the median moves by +-30% between runs).
//
//   bench_kernels [--repeat N] [--elements hex8,tet4,tet10] [--models linear,corotational,
//                 corotational-element,neohookean,stable-neohookean] [--strain S] [--csv FILE]
#include <plastifem/plastifem.hpp>

#include "bench_common.hpp"

#include <fmt/core.h>

#include <algorithm>
#include <chrono>
#include <fstream>
#include <random>
#include <sstream>
#include <string>

using namespace plastifem;
using plastifem::bench::split;

namespace {

volatile Scalar sink;  // keeps results alive
std::vector<std::string> models{"linear", "corotational", "corotational-element", "neohookean", "stable-neohookean"};
bool want(const char* m) { return std::find(models.begin(), models.end(), m) != models.end(); }

template <class E>
Mesh<E> one_cell() {
  if constexpr (std::is_same_v<E, Hex8>) return bar_mesh<Hex8>(1, 1, 1);
  else if constexpr (std::is_same_v<E, Tet4>) return bar_mesh<Tet4>(1, 1, 1);
  else return bar_mesh<Tet10>(1, 1, 1);
}

template <class E, class Model>
void measure(std::ofstream& out, int repeat, Scalar strain) {
  const Mesh<E> mesh = one_cell<E>();
  const ElementNodes<E> X = mesh.element_nodes(0);
  const Material material{3000, 0.45, 1.0};
  const auto data = Model::template prepare<E>(X, material);
  std::mt19937 rng(5);
  std::uniform_real_distribution<Scalar> u(-1, 1);
  std::vector<ElementNodes<E>> states(256);
  for (auto& x : states) {
    Mat3 D;
    for (int i = 0; i < 9; ++i) D(i / 3, i % 3) = strain * u(rng);
    const Vec3 axis = Vec3(u(rng), u(rng), u(rng)).normalized();
    const Mat3 R = Eigen::AngleAxisd(3 * u(rng), axis).toRotationMatrix();
    x = R * (Mat3::Identity() + D) * X;
    for (int a = 0; a < E::num_nodes; ++a) x.col(a) += 1e-3 * Vec3(u(rng), u(rng), u(rng));  // non-affine part
  }
  constexpr bool has_exact = requires { Model::TangentKind::Exact; };
  enum What { Force, Projected, Exact };
  auto run = [&](What what) {
    ElementVector<E> f;
    ElementMatrix<E> K;
    std::vector<double> ns;
    for (int r = 0; r < repeat; ++r) {
      const int n = 20000;
      Scalar acc = 0;
      const auto t0 = std::chrono::steady_clock::now();
      for (int k = 0; k < n; ++k) {
        const auto& x = states[k & 255];
        Scalar w;
        if constexpr (has_exact)
          w = Model::template evaluate<E>(data, x, f, what == Force ? nullptr : &K,
                                          what == Exact ? Model::TangentKind::Exact : Model::TangentKind::Projected);
        else
          w = Model::template evaluate<E>(data, x, f, what == Force ? nullptr : &K);
        acc += w + f[k % f.size()] + (what == Force ? 0.0 : K(k % K.rows(), 0));
      }
      ns.push_back(std::chrono::duration<double, std::nano>(std::chrono::steady_clock::now() - t0).count() / n);
      sink = acc;
    }
    std::sort(ns.begin(), ns.end());
    return std::pair{ns[ns.size() / 2], ns.front()};
  };
  const auto f = run(Force), fk = run(Projected);
  const auto fe = has_exact ? run(Exact) : std::pair{0.0, 0.0};
  auto cell = [](std::pair<double, double> t) { return fmt::format("{:.0f} ({:.0f})", t.first, t.second); };
  const std::string exact = has_exact ? cell(fe) : "";
  fmt::print("{:6} {:28} {:>14} {:>16} {:>14}\n", E::name, Model::name, cell(f), cell(fk), exact);
  out << fmt::format("{},{},{:.1f},{:.1f},{:.1f},{:.1f},{},{}\n", E::name, Model::name, f.first, f.second, fk.first,
                     fk.second, has_exact ? fmt::format("{:.1f},{:.1f}", fe.first, fe.second) : ",", strain);
  std::fflush(stdout);
}

template <class E>
void element_rows(std::ofstream& out, int repeat, Scalar strain) {
  if (want("linear")) measure<E, Linear>(out, repeat, strain);
  if (want("corotational")) measure<E, Corotational>(out, repeat, strain);
  if constexpr (!std::is_same_v<E, Tet4>)
    if (want("corotational-element")) measure<E, CorotationalPerElement>(out, repeat, strain);
  if (want("neohookean")) measure<E, NeoHookean>(out, repeat, strain);
  if (want("stable-neohookean")) measure<E, StableNeoHookean>(out, repeat, strain);
}

}  // namespace

int main(int argc, char** argv) try {
  int repeat = 9;
  Scalar strain = 0.05;
  std::string csv = "kernels.csv";
  std::vector<std::string> elements{"hex8", "tet4", "tet10"};
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (i + 1 < argc && a == "--repeat") repeat = std::max(1, std::stoi(argv[++i]));
    else if (i + 1 < argc && a == "--csv") csv = argv[++i];
    else if (i + 1 < argc && a == "--strain") strain = std::stod(argv[++i]);
    else if (i + 1 < argc && a == "--models") models = split(argv[++i]);
    else if (i + 1 < argc && a == "--elements") elements = split(argv[++i]);
    else fail<InvalidArgument>("unknown option '{}'", a);
  }
  std::ofstream out(csv);
  out << "element,model,force_ns,force_min_ns,force_projected_tangent_ns,force_projected_tangent_min_ns,"
         "force_exact_tangent_ns,force_exact_tangent_min_ns,strain\n";
  if (!(strain >= 0 && strain < 0.9)) fail<InvalidArgument>("--strain {}: give a strain amplitude in [0, 0.9)", strain);
  fmt::print("ns per element evaluation: median (min) of {} passes; strain amplitude {}, random rotations\n\n", repeat,
             strain);
  fmt::print("{:6} {:28} {:>14} {:>16} {:>14}\n", "elem", "model", "force", "+ projected K", "+ exact K");
  auto wanted = [&](const char* e) { return std::find(elements.begin(), elements.end(), e) != elements.end(); };
  if (wanted("hex8")) element_rows<Hex8>(out, repeat, strain);
  if (wanted("tet4")) element_rows<Tet4>(out, repeat, strain);
  if (wanted("tet10")) element_rows<Tet10>(out, repeat, strain);
  fmt::print("CSV written to {}\n", csv);
  return 0;
} catch (const std::exception& e) {
  fmt::print(stderr, "bench_kernels: {}\n", e.what());
  return 1;
}
