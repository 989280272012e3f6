// A vessel twisted and released (issue 34 scene b): a tube of inner radius 3 mm, outer 4 mm,
// 4 cm long (Hex8: 24 around, 20 along, 1 through the wall), clamped at x = 0; the end x = L is
// turned about the axis by a prescribed rotation ramped smoothly to 90 degrees over 1 s, held
// 0.5 s, then let go: the tube unwinds, with mass damping, for 1.5 s. Elastic, Neo-Hookean;
// E = 500 kPa, nu = 0.45, 1060 kg/m^3 (an artery's wall, order of magnitude).
//
//   vessel_twist [--steps N] [--every K] [--out DIR] [--threads N] [--mode accurate|realtime] [--csv FILE]
//
// Writes DIR/vessel_twist.pvd (the tube: displacement, von_mises per element) and
// DIR/vessel_twist_surface.pvd (a smooth tube surface, 96 around, embedded in the mesh and moved
// with it), and prints the twist angle of the end and the torque the rotation takes (from the
// reaction forces), with the small-strain torque G J theta / L for comparison.
#include "scene.hpp"

#include <plastifem/embedding/embedded_surface.hpp>
#include <plastifem/mesh/io/io.hpp>

#include <cmath>
#include <filesystem>
#include <numbers>

using namespace plastifem;

namespace {

constexpr Scalar r_in = 0.003, r_out = 0.004, length = 0.04, dt = 0.01;
constexpr int n_circ = 24;
constexpr Scalar t_twist = 1.0, t_release = 1.5, max_angle = std::numbers::pi / 2;

/// The end's prescribed angle: a smooth ramp (zero velocity at both ends), then held.
Scalar angle(Scalar t) {
  const Scalar s = std::clamp(t / t_twist, 0.0, 1.0);
  return max_angle * s * s * (3 - 2 * s);
}

/// A smooth closed tube surface, just inside the meshed wall (whose faces are the chords of a
/// 24-gon: the outer radius shrinks by cos(pi / 24), the inner grows by a hair), as the surface
/// of revolution of its wall's section: outer line, end ring, inner line, end ring.
TriangleSurface smooth_tube(int around, int along) {
  const Scalar ro = r_out * std::cos(std::numbers::pi / n_circ) * (1 - 1e-6), ri = r_in * (1 + 1e-6);
  std::vector<std::array<Scalar, 2>> section;  // (x, r), a closed polygon
  for (int k = 0; k <= along; ++k) section.push_back({length * k / along, ro});
  section.push_back({length, (ro + ri) / 2});
  for (int k = along; k >= 0; --k) section.push_back({length * k / along, ri});
  section.push_back({0, (ro + ri) / 2});
  const Index np = static_cast<Index>(section.size());
  TriangleSurface s;
  s.vertices.resize(3, np * around);
  for (Index p = 0; p < np; ++p)
    for (int j = 0; j < around; ++j) {
      const Scalar phi = 2 * std::numbers::pi * j / around;
      s.vertices.col(p * around + j) = Vec3(section[p][0], section[p][1] * std::cos(phi), section[p][1] * std::sin(phi));
    }
  for (Index p = 0; p < np; ++p)
    for (int j = 0; j < around; ++j) {
      const Index a = p * around + j, b = p * around + (j + 1) % around, c = ((p + 1) % np) * around + j,
                  d = ((p + 1) % np) * around + (j + 1) % around;
      s.triangles.push_back({a, c, d});
      s.triangles.push_back({a, d, b});
    }
  if (enclosed_volume(s, s.vertices) < 0)  // face out
    for (Triangle& t : s.triangles) std::swap(t[1], t[2]);
  return s;
}

}  // namespace

int main(int argc, char** argv) try {
  const scene::Options o = scene::parse(argc, argv, 300,
                                        "usage: vessel_twist [options]\n"
                                        "  a vessel twisted 90 degrees at one end and released\n"
                                        "  (300 steps of 10 ms by default: twist 1 s, hold 0.5 s, unwind 1.5 s)\n");
  std::filesystem::create_directories(o.out);
  const Mesh<Hex8> mesh = tube_hex8(r_in, r_out, length, n_circ, 20, 1);
  const Material material{5e5, 0.45, 1060};

  // Letting go releases the twist at once: generalized-alpha's numerical damping takes the
  // snap's high modes, mass damping settles the rest (scene::tissue_settings says why not
  // stiffness-proportional damping).
  SolverSettings st = scene::tissue_settings();
  o.apply(st);  // --threads, --mode
  // In real time, the one linearised step after letting go would move the end ring back along
  // chords and squash the Neo-Hookean elements beside it beyond evaluation: a step that changes
  // an edge by more than half its length is redone as an accurate one (the release step's
  // sub-steps: docs/scenes.md).
  st.newmark.realtime_reach = 0.5;
  Solver<Hex8, NeoHookean> s(mesh, material, st);
  s.fix(mesh.node_set("xmin"));
  const std::vector<Index> end = mesh.node_set("xmax");
  // The end turned rigidly about the x axis (and held at its x).
  ConstraintHandle twist = s.prescribe(end, [](Scalar t, const Vec3& X) {
    const Scalar c = std::cos(angle(t)), sn = std::sin(angle(t));
    return Vec3(0, c * X.y() - sn * X.z() - X.y(), sn * X.y() + c * X.z() - X.z());
  });

  EmbeddedSurface<Hex8> skin(mesh, smooth_tube(96, 80));
  fmt::print("vessel: {} Hex8, {} nodes; smooth surface of {} triangles\n", mesh.num_elements(), mesh.num_nodes(),
             skin.surface().num_triangles());

  // The end's turn: its nodes' mean angle about the axis; the torque about the axis of the
  // reactions at its nodes, at their current positions.
  auto end_angle = [&] {
    Scalar sum = 0;
    for (Index i : end) {
      const Vec3 X = mesh.node(i), x = X + s.displacement(i);
      sum += std::remainder(std::atan2(x.z(), x.y()) - std::atan2(X.z(), X.y()), 2 * std::numbers::pi);
    }
    return sum / static_cast<Scalar>(end.size());
  };
  auto end_torque = [&] {
    const Vector f = s.reaction_forces();
    Scalar t = 0;
    for (Index i : end) {
      const Vec3 x = mesh.node(i) + s.displacement(i);
      t += x.y() * f[3 * i + 2] - x.z() * f[3 * i + 1];
    }
    return t;
  };

  io::PvdWriter volume(o.out, "vessel_twist", {io::Encoding::appended_raw, "displacement"});
  io::PvdWriter surface(o.out, "vessel_twist_surface");
  auto write = [&] {
    const Eigen::Map<const Eigen::Matrix3Xd> u(s.displacement().data(), 3, mesh.num_nodes());
    volume.write(s.time(), mesh, {io::Field("displacement", u)}, {io::Field("von_mises", s.von_mises_stress())});
    skin.update(s);
    surface.write_frame(s.time(), [&](const std::filesystem::path& f) { skin.write_vtu(f); });
  };
  write();

  scene::Timings timings(o, "vessel_twist");
  Scalar peak_torque = 0, peak_angle = 0;
  for (int k = 1; k <= o.steps; ++k) {
    const StepReport r = s.step(dt);
    const Scalar torque = twist ? end_torque() : 0;  // read before letting go: afterwards no reaction
    if (std::abs(torque) > std::abs(peak_torque)) peak_torque = torque, peak_angle = end_angle();
    if (twist && s.time() >= t_release - 1e-9) {  // let go: the end turns back freely
      s.release(twist);
      twist = {};
    }
    if (k % o.every == 0 || k == o.steps) write();
    timings.record(k, r,
                   fmt::format("t = {:.2f} s  end at {:5.1f} deg  torque {:6.3f} N mm", s.time(),
                               end_angle() * 180 / std::numbers::pi, 1e3 * torque));
  }
  timings.summary();

  // Small strain: T = G J theta / L with J = pi (r_out^4 - r_in^4) / 2.
  const Scalar G = material.young / (2 * (1 + material.poisson));
  const Scalar J = std::numbers::pi * (std::pow(r_out, 4) - std::pow(r_in, 4)) / 2;
  fmt::print("peak torque {:.3f} N mm at {:.1f} deg (small strain G J theta / L: {:.3f} N mm); end at {:.2f} deg at "
             "t = {:.2f} s{}\n",
             1e3 * peak_torque, peak_angle * 180 / std::numbers::pi, 1e3 * G * J * peak_angle / length,
             end_angle() * 180 / std::numbers::pi, s.time(), twist ? ", still held" : " after release");
  fmt::print("wrote {} and {}\n", volume.pvd_path().string(), surface.pvd_path().string());
  return 0;
} catch (const std::exception& e) {
  fmt::print(stderr, "vessel_twist: {}\n", e.what());
  return 1;
}
