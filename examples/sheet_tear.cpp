// A tissue sheet pulled until it tears (issue 34 scene d; seed 000 Fig. 3a, a peritoneal sheet):
// a 10 x 8 cm sheet, 2 mm thick (20 x 16 x 1 Hex8 of 5 mm), lying on a tray (every node held
// in z, free in the plane), attached along its lower edge, with a 1 cm nick in its left edge. A
// clamp holds its upper edge and pulls it up at 2 cm/s. When the largest principal stress ahead of
// the nick reaches the tissue's strength the sheet tears, and the crack runs across, one element
// per step, while the pull goes on (enrichment/tearing.hpp); the torn-off part goes with the
// clamp. Corotational elasticity with shifted X-FEM.
//
//   sheet_tear [--steps N] [--every K] [--out DIR] [--threads N] [--mode accurate|realtime] [--csv FILE]
//
// Writes DIR/sheet_tear.pvd (the sheet, its crack opened: each cut element written as its
// pieces) and DIR/sheet_tear_surface.pvd (its skin, embedded, split along the crack), prints the
// tear as it runs, and ends with the step times and the time the crack's growth took (cutting
// the elements and re-patterning). An exit status 1 if the sheet is not torn through.
#include "scene.hpp"

#include <plastifem/cutting.hpp>
#include <plastifem/embedding/embedded_surface.hpp>
#include <plastifem/enrichment/output.hpp>
#include <plastifem/enrichment/tearing.hpp>
#include <plastifem/mesh/io/io.hpp>

#include <chrono>
#include <filesystem>
#include <utility>

using namespace plastifem;

namespace {

constexpr Scalar height = scene::sheet_height, pull_speed = 0.02, dt = 0.01;

}  // namespace

int main(int argc, char** argv) try {
  const scene::Options o = scene::parse(argc, argv, 150,
                                        "usage: sheet_tear [options]\n"
                                        "  a nicked tissue sheet pulled at 2 cm/s until it tears through\n"
                                        "  (150 steps of 10 ms by default)\n");
  std::filesystem::create_directories(o.out);
  const Mesh<Hex8> mesh = scene::tear_sheet();

  // Soft tissue, E = 50 kPa, nu = 0.4, 1050 kg/m^3; strength 10 kPa, low for peritoneum (MPa) but
  // it makes the sheet tear within a centimetre of pull, as a training scene wants.
  using TearingSolver = Solver<Hex8, Corotational, NoPlasticity, ShiftedHeaviside>;
  // Mass damping: the torn pieces settle. Each element the crack cuts lets go of its stress at
  // once: a snap that rings in the mesh's highest modes, which the trapezoidal rule keeps (they
  // held the kinetic energy at 1e-4 J after the tear and Newton at 10-40 iterations a step).
  // Generalized-alpha's numerical damping takes them.
  SolverSettings settings = scene::tissue_settings();
  o.apply(settings);  // --threads, --mode
  TearingSolver s(mesh, Material{5e4, 0.4, 1050}, settings);
  s.fix(mesh.node_set("ymin"));
  s.grasp(mesh.node_set("ymax"), [](Scalar t) { return Vec3(0, pull_speed * t, 0); });
  // The tray: held in z, free in the plane. Unsupported, a sheet this thin wrinkles sideways as
  // the pull narrows it (Newton then needs tens of iterations a step); on the tray it stays
  // flat, and its cut pieces still part in the plane (a node's enriched dofs are held only in
  // the directions the node is).
  s.fix(select_nodes(mesh, [](const Vec3& p) { return p.y() > 1e-9 && p.y() < height - 1e-9; }),
        DofMask{false, false, true});

  TearingSettings tear;
  tear.strength = 1e4;
  Tearing<TearingSolver> tearing(s, tear);
  tearing.start(scene::sheet_nick());

  EmbeddedSurface<Hex8> skin(mesh, scene::refined_boundary(mesh, 2));
  fmt::print("sheet: {} Hex8, {} nodes on a tray; upper edge pulled at 2 cm/s, dt = 10 ms; skin of {} triangles\n",
             mesh.num_elements(), mesh.num_nodes(), skin.surface().num_triangles());

  io::PvdWriter volume(o.out, "sheet_tear");
  io::PvdWriter surface(o.out, "sheet_tear_surface");
  auto write = [&] {
    volume.write_frame(s.time(), [&](const auto& f) { io::write_cut_vtu(f, mesh, s.enrichment(), s.displacement()); });
    skin.update(s);
    surface.write_frame(s.time(), [&](const std::filesystem::path& f) { skin.write_vtu(f); });
  };
  write();

  scene::Timings timings(o, "sheet_tear", "crack growth (update() that cut)");
  bool started = false;
  bool through = false;
  Index cut = 0;  // elements the crack has cut
  for (int k = 1; k <= o.steps; ++k) {
    const StepReport r = s.step(dt);
    const auto t0 = std::chrono::steady_clock::now();
    const TearReport t = tearing.update();
    cut += t.cut_elements;
    const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    if (t.grown > 0) {  // an event: the elements cut, the new dofs, the re-patterning
      timings.event(ms);
      if (!std::exchange(started, true))
        fmt::print("  t = {:.2f} s, pull {:.1f} mm: the sheet starts to tear at the nick (sigma_1 {:.1f} kPa)\n",
                   s.time(), 1e3 * pull_speed * s.time(), t.largest_stress / 1e3);
    }
    if (!through && tearing.num_tips() == 0) {
      through = true;
      fmt::print("  t = {:.2f} s, pull {:.1f} mm: torn through, {} elements cut, {} dofs\n", s.time(),
                 1e3 * pull_speed * s.time(), cut, s.num_dofs());
    }
    if (k % o.every == 0 || k == o.steps) write();
    timings.record(k, r, fmt::format("t = {:.2f} s  cut {:3d}  kinetic {:.2e} J", s.time(), cut, s.kinetic_energy()));
  }
  timings.summary();
  fmt::print("wrote {} and {}\n", volume.pvd_path().string(), surface.pvd_path().string());
  if (!through) {
    fmt::print(stderr, "sheet_tear: not torn through after {:.2f} s\n", s.time());
    return 1;
  }
  return 0;
} catch (const std::exception& e) {
  fmt::print(stderr, "sheet_tear: {}\n", e.what());
  return 1;
}
