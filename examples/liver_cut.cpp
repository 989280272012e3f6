// A liver's left lobe cut off by a blade moving along a curved path (seed 001 Fig. 11; issue 34
// scene e). The organ is liver_cage's: the library's liver-like surface (20,480 triangles)
// embedded in a cage of 1 cm Hex8 cells weighted by their inside fractions; corotational,
// E = 5 kPa, nu = 0.45, 1070 kg/m^3, under gravity, resting on a table (the lowest cage node of
// every column; left of the middle the table bears the weight but lets the tissue slide).
// After 0.3 s of settling a grasper takes the left lobe (at a point on its upper slope, about
// 6 cm left of the middle: scene::left_lobe_top) and retracts it, 15 mm left and 8 mm up over
// 1 s, as a surgeon holds tissue under tension; from t = 0.5 s a blade crosses the organ through
// its whole depth along a curve in plan, at 8 cm/s across (in y). The cut grows with the blade
// (Solver::grow_cut: shifted X-FEM, the cage is not remeshed) and the smooth surface opens along
// it; the lobe, cut off, stays in the grasper.
//
//   liver_cut [--steps N] [--every K] [--out DIR] [--threads N] [--mode accurate|realtime] [--csv FILE]
//
// Writes DIR/liver_cut.pvd (the cage, each cut cell written as its pieces) and
// DIR/liver_cut_surface.pvd (the smooth surface, split along the cut, with normals), prints
// each growth of the cut as it goes and the step times at the end.
#include "scene.hpp"

#include <plastifem/cutting.hpp>
#include <plastifem/embedding/cage.hpp>
#include <plastifem/embedding/embedded_surface.hpp>
#include <plastifem/enrichment/output.hpp>
#include <plastifem/mesh/io/io.hpp>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <numbers>
#include <optional>

using namespace plastifem;

namespace {

constexpr Scalar cell = 0.01, dt = 0.01;
constexpr Scalar t_grasp = 0.3, t_retract = 1.0, t_blade = 0.5, blade_speed = 0.08;
const Vec3 retraction(-0.015, 0, 0.008);

/// The blade's path in plan: x = -0.035 + 0.012 sin(pi s), y = -0.065 + 0.13 s for s in [0, 1],
/// across the organ (it is 9-10 cm wide there) left of its middle, bowed away from the lobe,
/// towards the middle (x = -0.035 at both ends, -0.023 halfway). 0.1327 m long.
Vec3 path(Scalar s, Scalar z) {
  return Vec3(-0.035 + 0.012 * std::sin(std::numbers::pi * s), -0.065 + 0.13 * s, z);
}
constexpr int columns = 52;  // the path's pieces: 2.5 mm in y (0.13 m / 52), 2.50-2.60 mm along it

/// The cut the blade has made when it has gone `n` pieces along its path: a sheet from 6 cm
/// below to 6 cm above the organ's middle (through its whole depth), 4 rows high.
CutSurface blade_sheet(int n) {
  std::vector<Vec3> v;
  std::vector<std::array<Index, 3>> t;
  constexpr int rows = 4;
  for (int r = 0; r <= rows; ++r)
    for (int i = 0; i <= n; ++i) v.push_back(path(Scalar(i) / columns, -0.06 + 0.12 * r / rows));
  for (int r = 0; r < rows; ++r)
    for (int i = 0; i < n; ++i) {
      const Index a = r * (n + 1) + i, b = a + 1, c = a + n + 1, d = c + 1;
      t.push_back({a, b, d});
      t.push_back({a, d, c});
    }
  return CutSurface(v, t);
}

/// The retraction so far: a smooth ramp (zero velocity at both ends) from t_grasp on, then held.
Vec3 grasper_offset(Scalar t) {
  const Scalar s = std::clamp((t - t_grasp) / t_retract, 0.0, 1.0);
  return retraction * (s * s * (3 - 2 * s));
}

}  // namespace

int main(int argc, char** argv) try {
  const scene::Options o = scene::parse(argc, argv, 250,
                                        "usage: liver_cut [options]\n"
                                        "  a liver's left lobe, held by a grasper, cut off by a blade along a curved path\n"
                                        "  (250 steps of 10 ms by default: settle 0.3 s, retract 1 s, the blade from 0.5 s "
                                        "to 2.1 s)\n");
  std::filesystem::create_directories(o.out);
  const scene::CagedLiver organ = scene::caged_liver(cell);
  const TriangleSurface& liver = organ.surface;
  const Mesh<Hex8>& mesh = organ.cage.mesh;

  // The grasp: a point on the left lobe's upper slope (scene::left_lobe_top, about 6 cm left of
  // the middle) and the cage nodes within 15 mm of it.
  const Vec3 grasped = scene::left_lobe_top(liver);
  const std::vector<Index> jaws = select_nodes(mesh, [&](const Vec3& p) { return (p - grasped).norm() < 0.015; });

  // The table: the lowest node of each column. Right of x = 0, well clear of the cut, it holds
  // the organ (friction); left of it the table only bears the organ's weight (held in z, free
  // in the plane: wet tissue on tissue), so the retracted lobe slides and the cut gapes; none
  // within 2 cm (in plan) of the grasp, where the lobe lifts off.
  std::vector<Index> held, bearing;
  for (Index i : scene::lowest_of_columns(mesh, cell))
    if (mesh.node(i).x() > 0) held.push_back(i);
    else if ((mesh.node(i) - grasped).head<2>().norm() > 0.02) bearing.push_back(i);

  using CuttingSolver = Solver<Hex8, Corotational, NoPlasticity, ShiftedHeaviside>;
  SolverSettings st = scene::tissue_settings();  // the sway settles; each cut cell's snap is damped
  o.apply(st);  // --threads, --mode
  CuttingSolver s(mesh, Material{5e3, 0.45, 1070}, st);
  s.fix(held);
  s.fix(bearing, DofMask{false, false, true});
  s.add_gravity(Vec3(0, 0, -9.81));

  EmbeddedSurface<Hex8> skin(mesh, liver);
  fmt::print("liver: {} triangles; cage of {} mm cells: {} Hex8, {} nodes, mass {:.3f} kg; {} table nodes, {} grasped; "
             "blade at {:.0f} cm/s from t = {:.1f} s\n",
             liver.num_triangles(), 1e3 * cell, mesh.num_elements(), mesh.num_nodes(), s.mass(), held.size() + bearing.size(), jaws.size(),
             1e2 * blade_speed, t_blade);

  io::PvdWriter volume(o.out, "liver_cut");
  io::PvdWriter surface(o.out, "liver_cut_surface");
  auto write = [&] {
    volume.write_frame(s.time(), [&](const auto& f) { io::write_cut_vtu(f, mesh, s.enrichment(), s.displacement()); });
    skin.update(s);
    surface.write_frame(s.time(), [&](const std::filesystem::path& f) { skin.write_vtu(f); });
  };
  write();

  scene::Timings timings(o, "liver_cut", "cut growth (cut or grow_cut)");
  std::optional<CutHandle> cut;
  int reached = 0;             // path pieces the blade has gone
  for (int k = 1; k <= o.steps; ++k) {
    if (k == static_cast<int>(std::lround(t_grasp / dt)) + 1)
      s.grasp(jaws, [](Scalar t) { return grasper_offset(t); });
    // The blade's progress at this step's start, in whole pieces of its path. It is measured in
    // y: 8 cm/s across, 2.5 mm of y a piece; along the bowed path that is 8.17 cm/s on average
    // and 2.50-2.60 mm a piece. (The "mm along its path" printed below is the progress in y.)
    const int n = std::clamp(static_cast<int>((s.time() - t_blade) * blade_speed / (0.13 / columns)), 0, columns);
    if (n > reached) {
      reached = n;
      const auto t0 = std::chrono::steady_clock::now();
      if (!cut) {
        try {
          cut = s.cut(blade_sheet(n));
        } catch (const InvalidArgument&) {  // not into the organ yet
        }
      } else {
        s.grow_cut(*cut, blade_sheet(n));
      }
      if (cut) timings.event(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
      if (cut && s.last_cut_report().cut_elements > 0 && n % 8 == 0)
        fmt::print("  t = {:.2f} s: the blade {:.0f} mm along its path, {} dofs\n", s.time(), 1e3 * 0.13 * n / columns,
                   s.num_dofs());
    }
    const StepReport r = s.step(dt);
    if (k % o.every == 0 || k == o.steps) write();
    timings.record(k, r, fmt::format("t = {:.2f} s  blade {:3.0f} mm  dofs {}", s.time(), 1e3 * 0.13 * reached / columns,
                                     s.num_dofs()));
  }
  timings.summary();
  fmt::print("wrote {} and {}\n", volume.pvd_path().string(), surface.pvd_path().string());
  return 0;
} catch (const std::exception& e) {
  fmt::print(stderr, "liver_cut: {}\n", e.what());
  return 1;
}
