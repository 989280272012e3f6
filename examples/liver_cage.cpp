// A liver in a hex cage, grasped at a lobe, lifted and released (seed 000 Fig. 3b; issue 34
// scene c). The organ is the library's liver-like surface (liver_surface: 20 cm long, 20,480
// triangles); the simulation runs on the cage of 1 cm cells around it (cage_around: each cell's
// mass and stiffness weighted by the fraction of it inside), and the smooth surface, embedded
// in the cage, follows it. Corotational, E = 5 kPa, nu = 0.45, 1070 kg/m^3, under gravity,
// resting on a table: the lowest cage node of every column is held, except under the left
// lobe. The organ settles on the table for 0.5 s; then a grasper takes the cage nodes within
// 12 mm of a point high on the lobe (on its upper slope, about 6 cm left of the middle:
// scene::left_lobe_top), lifts them 25 mm over 1 s, holds 0.5 s and lets go; 1.5 s of damped
// relaxation follow.
//
//   liver_cage [--steps N] [--every K] [--out DIR] [--threads N] [--mode accurate|realtime] [--csv FILE]
//
// Writes DIR/liver_cage.pvd (the cage: displacement, its cells' inside fraction),
// DIR/liver_cage_surface.pvd (the smooth surface, with normals) and DIR/liver_cage_force.csv
// (the grasper's lift and the force it exerts on the organ, the sum of the reactions at its
// nodes, over time; plot it with docs/plot_liver_force.py).
#include "scene.hpp"

#include <plastifem/embedding/cage.hpp>
#include <plastifem/embedding/embedded_surface.hpp>
#include <plastifem/mesh/io/io.hpp>

#include <fmt/os.h>

#include <cmath>
#include <filesystem>

using namespace plastifem;

namespace {

constexpr Scalar cell = 0.01, lift = 0.025, dt = 0.01;
constexpr Scalar t_grasp = 0.5, t_lift = 1.0, t_release = 2.0;

/// The grasper's height above where it took hold: a smooth ramp to `lift` from t_grasp on,
/// then held.
Scalar grasper_height(Scalar t) {
  const Scalar s = std::clamp((t - t_grasp) / t_lift, 0.0, 1.0);
  return lift * s * s * (3 - 2 * s);
}

}  // namespace

int main(int argc, char** argv) try {
  const scene::Options o = scene::parse(argc, argv, 350,
                                        "usage: liver_cage [options]\n"
                                        "  a liver-like organ in a hex cage, grasped at its left lobe, lifted 25 mm and "
                                        "released\n"
                                        "  (350 steps of 10 ms by default: settle 0.5 s, lift 1 s, hold 0.5 s, relax 1.5 s)\n");
  std::filesystem::create_directories(o.out);
  const scene::CagedLiver organ = scene::caged_liver(cell);
  const TriangleSurface& liver = organ.surface;
  const Cage<Hex8>& cage = organ.cage;
  const Mesh<Hex8>& mesh = cage.mesh;

  // The grasp: a point on the left lobe's upper slope (scene::left_lobe_top, about 6 cm left of
  // the middle) and the cage nodes within 12 mm of it.
  const Vec3 grasped = scene::left_lobe_top(liver);
  const std::vector<Index> jaws = select_nodes(mesh, [&](const Vec3& p) { return (p - grasped).norm() < 0.012; });

  // The table: the lowest node of each column of the cage, except within 2 cm (in plan) of
  // the grasp, where the lobe may lift off (a wider free patch sags well below the table under
  // gravity: there is no contact to hold it).
  std::vector<Index> table;
  for (Index i : scene::lowest_of_columns(mesh, cell))
    if ((mesh.node(i) - grasped).head<2>().norm() > 0.02) table.push_back(i);

  // Mass damping settles the organ's sway after the release, generalized-alpha its snap.
  SolverSettings st = scene::tissue_settings();
  o.apply(st);  // --threads, --mode
  Solver<Hex8, Corotational> s(mesh, Material{5e3, 0.45, 1070}, st);
  s.fix(table);
  s.add_gravity(Vec3(0, 0, -9.81));
  // The organ settles on the table dynamically before the grasp. (A static start converges
  // too, with the default direct solver: 4 Newton iterations; docs/scenes.md.)

  EmbeddedSurface<Hex8> skin(mesh, liver);
  fmt::print("liver: {} triangles, {:.0f} cm^3; cage of {} mm cells: {} Hex8, {} nodes, {:.0f} cm^3 inside, mass "
             "{:.3f} kg; {} table nodes, {} grasped\n",
             liver.num_triangles(), 1e6 * enclosed_volume(liver, liver.vertices), 1e3 * cell, mesh.num_elements(),
             mesh.num_nodes(), 1e6 * cage.inside_volume(), s.mass(), table.size(), jaws.size());

  ConstraintHandle grasp;
  // The force the grasper exerts on the organ: the reactions at its nodes (their sum), zero
  // once it has let go.
  auto grasp_force = [&] {
    const Vector f = s.reaction_forces();
    Vec3 sum = Vec3::Zero();
    for (Index i : jaws) sum += f.segment<3>(3 * i);
    return sum;
  };

  const Eigen::Map<const Eigen::VectorXd> fraction(cage.fraction.data(), static_cast<Index>(cage.fraction.size()));
  io::PvdWriter volume(o.out, "liver_cage", {io::Encoding::appended_raw, "displacement"});
  io::PvdWriter surface(o.out, "liver_cage_surface");
  auto write = [&] {
    const Eigen::Map<const Eigen::Matrix3Xd> u(s.displacement().data(), 3, mesh.num_nodes());
    volume.write(s.time(), mesh, {io::Field("displacement", u)}, {io::Field("inside_fraction", fraction)});
    skin.update(s);
    surface.write_frame(s.time(), [&](const std::filesystem::path& f) { skin.write_vtu(f); });
  };
  write();
  auto csv = fmt::output_file((std::filesystem::path(o.out) / "liver_cage_force.csv").string());
  csv.print("time,lift,force_x,force_y,force_z\n");

  scene::Timings timings(o, "liver_cage");
  Scalar peak = 0, peak_time = 0;
  for (int k = 1; k <= o.steps; ++k) {
    if (k == static_cast<int>(std::lround(t_grasp / dt)) + 1)  // settled: the grasper takes hold
      grasp = s.grasp(jaws, [](Scalar t) { return Vec3(0, 0, grasper_height(t)); });
    const StepReport r = s.step(dt);
    const Vec3 f = grasp ? grasp_force() : Vec3::Zero();  // read before letting go
    csv.print("{},{},{},{},{}\n", s.time(), grasp ? grasper_height(s.time()) : 0.0, f.x(), f.y(), f.z());
    if (f.norm() > peak) peak = f.norm(), peak_time = s.time();
    if (grasp && s.time() >= t_release - 1e-9) {  // let go: the lobe falls back onto the table
      s.release(grasp);
      grasp = {};
    }
    if (k % o.every == 0 || k == o.steps) write();
    timings.record(k, r, fmt::format("t = {:.2f} s  grasper force ({:6.3f}, {:6.3f}, {:6.3f}) N", s.time(), f.x(), f.y(), f.z()));
  }
  timings.summary();
  fmt::print("peak grasper force {:.3f} N at t = {:.2f} s (the organ weighs {:.3f} N)\n", peak, peak_time, 9.81 * s.mass());
  fmt::print("wrote {}, {} and {}\n", volume.pvd_path().string(), surface.pvd_path().string(),
             (std::filesystem::path(o.out) / "liver_cage_force.csv").string());
  return 0;
} catch (const std::exception& e) {
  fmt::print(stderr, "liver_cage: {}\n", e.what());
  return 1;
}
