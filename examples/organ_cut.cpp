// A progressive cut through an organ-like body (SCENES.md cut scenes, seed 001 extended): an
// ellipsoidal organ meshed with Tet4 (the Kuhn-split tetrahedra of a box whose centres lie
// inside the ellipsoid: a voxelised surface, as from a segmentation), resting on its lowest
// layer under gravity, cut by a scalpel that moves down along a curved path: the cut surface is
// a triangulated sheet that grows by one row of triangles every few steps, applied to the
// running simulation (Solver::grow_cut). Corotational X-FEM with shifted enrichment.
//
//   organ_cut [--steps N] [--every K] [--out DIR]
//
// Writes DIR/organ_cut.pvd, the organ with the cut opened, and prints each growth's cost.
#include <plastifem/enrichment/output.hpp>
#include <plastifem/mesh/io/io.hpp>
#include <plastifem/cutting.hpp>
#include <plastifem/plastifem.hpp>

#include <fmt/core.h>

#include <cmath>
#include <filesystem>
#include <numbers>
#include <optional>
#include <string>

using namespace plastifem;

namespace {

/// The organ: Tet4s of a box (0.12 x 0.08 x 0.06 m on 24 x 16 x 12 cells) whose centres lie in
/// the ellipsoid inscribed in it.
Mesh<Tet4> organ() {
  const Vec3 size(0.12, 0.08, 0.06), c = 0.5 * size;
  const Mesh<Tet4> box = bar_mesh<Tet4>(BoxSpec{24, 16, 12, size});
  std::vector<Mesh<Tet4>::Connectivity> kept;
  for (Index e = 0; e < box.num_elements(); ++e) {
    const Vec3 m = box.element_nodes(e).rowwise().mean();
    if (((m - c).array() / (0.5 * size).array()).matrix().squaredNorm() <= 1) kept.push_back(box.element(e));
  }
  return drop_unused_nodes(Mesh<Tet4>(box.nodes(), kept));
}

/// The scalpel's sheet down to `rows` rows of 2.5 mm: a curve across the organ in plane view,
/// (x, y) = (0.01 + 0.1 s, 0.04 + 0.015 sin(pi s)), swept down from above the top.
CutSurface blade(int rows) {
  const int ns = 40;
  std::vector<Vec3> v;
  std::vector<std::array<Index, 3>> t;
  for (int r = 0; r <= rows; ++r)
    for (int i = 0; i <= ns; ++i) {
      const Scalar s = Scalar(i) / ns;
      v.emplace_back(0.01 + 0.1 * s, 0.04 + 0.015 * std::sin(std::numbers::pi * s), 0.065 - 0.0025 * r);
    }
  for (int r = 0; r < rows; ++r)
    for (int i = 0; i < ns; ++i) {
      const Index a = r * (ns + 1) + i, b = a + 1, c = a + ns + 1, d = c + 1;
      t.push_back({a, b, d});
      t.push_back({a, d, c});
    }
  return CutSurface(v, t);
}

}  // namespace

int main(int argc, char** argv) try {
  int steps = 400, every = 10;
  std::string out = "out";
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--steps" && i + 1 < argc) steps = std::stoi(argv[++i]);
    else if (a == "--every" && i + 1 < argc) every = std::max(1, std::stoi(argv[++i]));
    else if (a == "--out" && i + 1 < argc) out = argv[++i];
    else {
      fmt::print("usage: organ_cut [--steps N] [--every K] [--out DIR]\n");
      return a == "--help" || a == "-h" ? 0 : 2;
    }
  }
  std::filesystem::create_directories(out);
  const Mesh<Tet4> mesh = organ();
  SolverSettings st;
  st.rayleigh_mass = 2;
  Solver<Tet4, Corotational, NoPlasticity, ShiftedHeaviside> s(mesh, Material{3e4, 0.45, 1050}, st);
  const Scalar z_min = mesh.nodes().row(2).minCoeff();
  s.fix(select_nodes(mesh, [&](const Vec3& p) { return p.z() < z_min + 0.006; }));  // resting on a table
  s.add_gravity(Vec3(0, 0, -9.81));
  fmt::print("organ: {} Tet4, {} nodes; scalpel down 2.5 mm every 10 steps (dt = 1 ms)\n", mesh.num_elements(),
             mesh.num_nodes());
  io::PvdWriter pvd(out, "organ_cut");
  auto write = [&] {
    pvd.write_frame(s.time(), [&](const auto& file) { io::write_cut_vtu(file, mesh, s.enrichment(), s.displacement()); });
  };
  write();
  std::optional<CutHandle> cut;
  int rows = 2;
  for (int k = 1; k <= steps; ++k) {
    if (k % 10 == 1 && rows <= 22) {  // the blade moves down 2.5 mm
      const Index before = s.num_dofs();
      if (!cut) {
        try {
          cut = s.cut(blade(rows));
        } catch (const InvalidArgument&) {  // still above the organ
        }
      } else {
        s.grow_cut(*cut, blade(rows));
      }
      if (cut)
        fmt::print("  t = {:.3f} s: blade {} mm deep: {} elements newly cut, {} dofs added ({} in all), {:.2f} ms\n",
                   s.time(), 2.5 * rows - 5, s.last_cut_report().cut_elements, s.num_dofs() - before, s.num_dofs(),
                   s.last_cut_report().ms);
      ++rows;
    }
    const StepReport r = s.step(0.001);
    if (k % every == 0) write();
    if (k % 100 == 0)
      fmt::print("  t = {:.3f} s: Newton {}, CG {}, {:.2f} ms/step, kinetic energy {:.3e} J\n", s.time(), r.newton_iterations,
                 r.linear_iterations, r.wall_ms, s.kinetic_energy());
  }
  fmt::print("done: {} frames in {}\n", pvd.num_frames(), pvd.pvd_path().string());
  return 0;
} catch (const std::exception& e) {
  fmt::print(stderr, "organ_cut: {}\n", e.what());
  return 1;
}
