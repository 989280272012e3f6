// Cost of fields at embedded points (embedding/embedded_points.hpp): a visual surface's
// vertices located once, then their deformed positions asked every step. Points spread over the
// bar's boundary (as a surface's vertices are), on bar5760 and bar46080, uncut and cut across
// by a plane (Heaviside: the points of the cut elements read their side's enriched dofs).
// Median of `--repeat` calls after a solver step has set a field. Then an embedded surface: an
// icosphere of `--subdivisions` (6: 40,962 vertices, 81,920 triangles) inside the bar, its
// update (positions and normals) uncut and after the cut, and the split along the cut itself.
//
//   bench_points [--points N] [--repeat R] [--threads 1,2] [--scenes bar5760,bar46080] [--csv FILE]
#include <plastifem/cutting.hpp>
#include <plastifem/embedding/embedded_points.hpp>
#include <plastifem/embedding/embedded_surface.hpp>
#include <plastifem/plastifem.hpp>

#include "bench_common.hpp"

#include <fmt/core.h>

#include <chrono>
#include <fstream>
#include <random>
#include <string>
#include <vector>

using namespace plastifem;
using plastifem::bench::median;
using plastifem::bench::ms_since;
using plastifem::bench::split;

namespace {

/// n points uniformly over the boundary of the box [0, a] x [0, b] x [0, c], by area.
std::vector<Vec3> boundary_points(Vec3 box, int n, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<Scalar> u01(0, 1);
  const Scalar a = box.x(), b = box.y(), c = box.z();
  const Scalar areas[3] = {b * c, a * c, a * b};  // faces normal to x, y, z
  std::discrete_distribution<int> face({areas[0], areas[0], areas[1], areas[1], areas[2], areas[2]});
  std::vector<Vec3> X;
  for (int k = 0; k < n; ++k) {
    Vec3 p(a * u01(rng), b * u01(rng), c * u01(rng));
    const int f = face(rng);
    p[f / 2] = f % 2 ? box[f / 2] : 0;
    X.push_back(p);
  }
  return X;
}

}  // namespace

int main(int argc, char** argv) {
  int num_points = 20000, repeat = 201, subdivisions = 6;
  std::vector<std::string> scenes{"bar5760", "bar46080"}, thread_list{"1", "2"};
  std::string csv = "bench_points.csv";
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string a = argv[i];
    if (a == "--points") num_points = std::stoi(argv[i + 1]);
    else if (a == "--repeat") repeat = std::stoi(argv[i + 1]);
    else if (a == "--threads") thread_list = split(argv[i + 1]);
    else if (a == "--scenes") scenes = split(argv[i + 1]);
    else if (a == "--csv") csv = argv[i + 1];
    else if (a == "--subdivisions") subdivisions = std::stoi(argv[i + 1]);
    else {
      fmt::print(stderr, "usage: bench_points [--points N] [--repeat R] [--threads 1,2] [--scenes ...] [--subdivisions K] [--csv FILE]\n");
      return 2;
    }
  }
  if (num_points < 1 || repeat < 1 || subdivisions < 0 || subdivisions > 8) {
    fmt::print(stderr, "bench_points: --points and --repeat must be positive\n");
    return 2;
  }
  std::ofstream out(csv);
  out << "scene,element,cut,threads,points,locate_ms,positions_median_ms,positions_min_ms\n";
  fmt::print("{:>9} {:>7} {:>5} {:>7} {:>7} {:>10} {:>13} {:>10}\n", "scene", "element", "cut", "threads", "points",
             "locate ms", "positions ms", "min ms");
  auto run = [&]<class E>(const std::string& scene, bool cut, int threads) {
    const auto [nx, ny, nz] = bar_scene_cells(scene);
    const Mesh<E> mesh = bar_mesh<E>(nx, ny, nz);
    const std::vector<Vec3> X = boundary_points(Vec3(nx, ny, nz), num_points, 7);
    auto t0 = std::chrono::steady_clock::now();
    EmbeddedPoints<E> points(mesh, X);
    const double locate_ms = ms_since(t0);
    SolverSettings st;
    st.threads = threads;
    Solver<E, Corotational, NoPlasticity, Heaviside> s(mesh, Material{3000, 0.45, 1.0}, st);
    s.fix(mesh.node_set("xmin"));
    s.add_gravity(Vec3(0, 0, -9.81));
    if (cut) s.cut(CutPlane(Vec3(0.55 * nx, 0, 0), Vec3(1, 0, 0)));
    s.step(0.01);
    Eigen::Matrix3Xd x;
    points.positions(s, x);  // sides assigned, storage sized
    std::vector<double> ms;
    for (int r = 0; r < repeat; ++r) {
      t0 = std::chrono::steady_clock::now();
      points.positions(s, x);
      ms.push_back(ms_since(t0));
    }
    const double med = median(ms), lo = *std::min_element(ms.begin(), ms.end());
    const char* name = E::num_nodes == 8 ? "Hex8" : E::num_nodes == 4 ? "Tet4" : "Tet10";
    fmt::print("{:>9} {:>7} {:>5} {:>7} {:>7} {:>10.2f} {:>13.4f} {:>10.4f}\n", scene, name, cut ? "yes" : "no", threads,
               num_points, locate_ms, med, lo);
    out << fmt::format("{},{},{},{},{},{:.3f},{:.5f},{:.5f}\n", scene, name, cut ? 1 : 0, threads, num_points, locate_ms,
                       med, lo);
    out.flush();
    std::fflush(stdout);
  };
  for (const std::string& scene : scenes)
    for (const std::string& t : thread_list)
      for (bool cut : {false, true}) {
        run.operator()<Hex8>(scene, cut, std::stoi(t));
        run.operator()<Tet4>(scene, cut, std::stoi(t));
      }

  // The embedded surface: update uncut, the split along a new cut, update after it.
  const std::string surface_csv = csv.substr(0, csv.rfind('.')) + "_surface.csv";
  std::ofstream sout(surface_csv);
  sout << "scene,element,threads,vertices,triangles,update_uncut_ms,first_split_ms,second_split_ms,vertices_after_cuts,update_cut_ms\n";
  fmt::print("\n{:>9} {:>7} {:>7} {:>8} {:>9} {:>15} {:>13} {:>14} {:>13}\n", "scene", "element", "threads", "vertices",
             "triangles", "update ms uncut", "1st split ms", "2nd split ms", "update ms cut");
  auto surface_run = [&]<class E>(const std::string& scene, int threads) {
    const auto [nx, ny, nz] = bar_scene_cells(scene);
    const Mesh<E> mesh = bar_mesh<E>(nx, ny, nz);
    const Vec3 centre(0.5 * nx, 0.5 * ny, 0.5 * nz);
    EmbeddedSurface<E> surface(mesh, sphere_surface(centre, 0.45 * std::min(ny, nz), subdivisions));
    SolverSettings st;
    st.threads = threads;
    Solver<E, Corotational, NoPlasticity, Heaviside> s(mesh, Material{3000, 0.45, 1.0}, st);
    s.fix(mesh.node_set("xmin"));
    s.add_gravity(Vec3(0, 0, -9.81));
    s.step(0.01);
    auto median_update = [&] {
      std::vector<double> ms;
      for (int r = 0; r < repeat; ++r) {
        const auto t0 = std::chrono::steady_clock::now();
        surface.update(s);
        ms.push_back(ms_since(t0));
      }
      return median(ms);
    };
    surface.update(s);
    const Index vertices = surface.surface().num_vertices();
    const double uncut = median_update();
    s.cut(CutPlane(centre + Vec3(0.05, 0, 0), Vec3(1, 0, 0)));
    const auto t0 = std::chrono::steady_clock::now();
    surface.update(s);  // splits, then updates
    const double split = ms_since(t0);
    const double cut = median_update();
    // A second cut, across the other end: the split again, the locator kept.
    s.cut(CutPlane(centre + Vec3(-0.3 * nx, 0, 0), Vec3(1, 0, 0)));
    const auto t1 = std::chrono::steady_clock::now();
    surface.update(s);
    const double second_split = ms_since(t1) - cut;
    const char* name = E::num_nodes == 8 ? "Hex8" : "Tet4";
    fmt::print("{:>9} {:>7} {:>7} {:>8} {:>9} {:>15.4f} {:>13.2f} {:>14.2f} {:>13.4f}\n", scene, name, threads, vertices,
               surface.surface().num_triangles(), uncut, split - cut, second_split, cut);
    sout << fmt::format("{},{},{},{},{},{:.5f},{:.3f},{:.3f},{},{:.5f}\n", scene, name, threads, vertices,
                        surface.surface().num_triangles(), uncut, split - cut, second_split,
                        surface.surface().num_vertices(), cut);
    sout.flush();
    std::fflush(stdout);
  };
  for (const std::string& scene : scenes)
    for (const std::string& t : thread_list) {
      surface_run.operator()<Hex8>(scene, std::stoi(t));
      surface_run.operator()<Tet4>(scene, std::stoi(t));
    }
}
