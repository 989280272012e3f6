// Plastic stretch (seed 000, Fig. 5 and 8; SCENES.md "Plastic stretch and twist"): a bar
// clamped at x = 0, pulled along +x by a force on its free end face (its resultant at the face's
// centre, spread over the face as a uniform traction), ramped over
// 1 s, held for 1 s, released, then 2 s of free relaxation with Rayleigh mass damping 1.0. The
// paper's three parameter sets per elastic model, from high to low plasticity:
//   corotational  E = 3000, nu = 0.45, force 350:  (tau, nu) = (1000, 0.4), (1500, 0.2), (1500, 0.1)
//   neohookean    E = 3000, nu = 0.45, force 1000: (tau, nu) = (1500, 0.25), (1800, 0.2), (2000, 0.15)
// with isotropic hardening kappa = 0.2.
//
// Stress scale. With the physical stress (the von Mises norm of the flow stress,
// plastic/flow.hpp) these loads stay elastic: the stress in the loaded bar is 36-39 for the
// corotational scene (force 350 on a 3 x 3 face) and 97-106 for the Neo-Hookean one (force 1000),
// against yield stresses of 1000-2000 (a point force at the face's centre raises the largest to
// 64 and 170, still far below). The example multiplies the stress by a scale
// (PlasticParams::stress_scale; --stress-scale) to put the paper's parameter sets in the regime
// its figures show: 50 for the corotational sets, 25 for the Neo-Hookean ones (printed with the
// results). Set --stress-scale 1 for the physical stress.
//
//   plastic_stretch [--model corotational|neohookean] [--element hex8|tet4|tet10]
//                   [--policy vertex-blended|cell-centered] [--set 1|2|3|all] [--level 0|1|2]
//                   [--stress-scale S] [--tolerance T] [--out DIR] [--every K]
//                   [--rotation-rate R] [--rotation-yield Y]
//
// --policy: the two plastic policies differ only in the rotational flow (eq. 5-6: per vertex of
// each element, or one per element); the paper's stretch scene has it off, and with it off the
// two policies give the same numbers. So --policy cell-centered needs --rotation-rate R > 0
// (the rotational flow rate, per second; --rotation-yield Y its threshold in rad, default 0.001).
//
// --tolerance: Newton's relative residual tolerance and CG's (defaults 1e-6 and 1e-8,
// SolverSettings): the mirror symmetry of the cross-section is only as good as the solves
// (docs/plasticity.md: the symmetry figures per level at both).
//
// --level: 0 = bar90 (10 x 3 x 3 unit cubes), 1 = 20 x 6 x 6 cubes of size 1/2, 2 = 40 x 12 x 12
// of size 1/4: the same outer bar and the same total force (the paper's Fig. 8).
//
// Writes, per parameter set, DIR/stretch_<model>_<element>_set<k>.pvd (the deformed bar, fields
// displacement, material_displacement = x - X of the material mesh, von_mises) and
// DIR/stretch_<...>_material.pvd (the material mesh itself), and a CSV of the load-unload curve
// (time, applied force, tip displacement, material tip displacement). Prints the residual tip
// displacement after relaxation, the volume ratio (deformed and material), the cross-section
// symmetry error and the time per step.
#include <plastifem/mesh/io/io.hpp>
#include <plastifem/plasticity.hpp>
#include <plastifem/plastifem.hpp>

#include <fmt/core.h>
#include <fmt/os.h>

#include <filesystem>
#include <map>
#include <string>
#include <utility>
#include <vector>

using namespace plastifem;

namespace {

struct Options {
  std::string model = "corotational", element = "hex8", policy = "vertex-blended", set = "all", out = "out";
  int level = 0, every = 10;
  Scalar stress_scale = -1;  // the model's default
  Scalar tolerance = -1;  // SolverSettings' defaults
  Scalar rotation_rate = 0, rotation_yield = 0.001;  // plastic rotation (off by default, as in the paper's scene)
};

Options parse(int argc, char** argv) {
  Options o;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= argc) fail<InvalidArgument>("option {} needs a value", a);
      return argv[++i];
    };
    if (a == "--model") o.model = value();
    else if (a == "--element") o.element = value();
    else if (a == "--policy") o.policy = value();
    else if (a == "--set") o.set = value();
    else if (a == "--level") o.level = std::stoi(value());
    else if (a == "--stress-scale") o.stress_scale = std::stod(value());
    else if (a == "--tolerance") o.tolerance = std::stod(value());
    else if (a == "--rotation-rate") o.rotation_rate = std::stod(value());
    else if (a == "--rotation-yield") o.rotation_yield = std::stod(value());
    else if (a == "--every") o.every = std::max(1, std::stoi(value()));
    else if (a == "--out") o.out = value();
    else if (a == "--help" || a == "-h") {
      fmt::print("usage: plastic_stretch [--model corotational|neohookean] [--element hex8|tet4|tet10]\n"
                 "                       [--policy vertex-blended|cell-centered] [--set 1|2|3|all] [--level 0|1|2]\n"
                 "                       [--stress-scale S] [--tolerance T] [--out DIR] [--every K]\n"
                 "                       [--rotation-rate R] [--rotation-yield Y]\n");
      std::exit(0);
    } else fail<InvalidArgument>("unknown option '{}' (try --help)", a);
  }
  if (o.level < 0 || o.level > 2) fail<InvalidArgument>("--level must be 0, 1 or 2");
  if (o.policy != "vertex-blended" && o.policy != "cell-centered")
    fail<InvalidArgument>("unknown policy '{}': vertex-blended or cell-centered", o.policy);
  if (o.policy == "cell-centered" && !(o.rotation_rate > 0))
    fail<InvalidArgument>("--policy cell-centered: the policies differ only in the rotational flow, which is off "
                          "here; give --rotation-rate R > 0 (and --rotation-yield Y) to compare them");
  return o;
}

struct Result {
  Scalar tip = 0, settled = 0, material_tip = 0, volume_ratio = 0, material_volume_ratio = 0, symmetry = 0, ms = 0,
         plastic_ms = 0;
};

/// The largest mismatch of mirrored node pairs (about y = 1.5 and z = 1.5) of the deformed and
/// the material mesh, relative to the largest displacement.
template <class S>
Scalar symmetry_error(const S& s) {
  const auto& mesh = s.mesh();
  const Eigen::Matrix3Xd x = s.positions(), m = s.material_positions();
  std::map<std::array<long long, 3>, Index> at;
  auto key = [](const Vec3& p) {
    return std::array<long long, 3>{std::llround(p.x() * 1e6), std::llround(p.y() * 1e6), std::llround(p.z() * 1e6)};
  };
  for (Index i = 0; i < mesh.num_nodes(); ++i) at[key(mesh.node(i))] = i;
  Scalar worst = 0, scale = 1e-300;
  for (Index i = 0; i < mesh.num_nodes(); ++i) {
    const Vec3 p = mesh.node(i);
    scale = std::max(scale, (x.col(i) - p).norm());
    for (int axis : {1, 2}) {
      Vec3 q = p;
      q[axis] = 3 - p[axis];
      const auto it = at.find(key(q));
      if (it == at.end()) return std::numeric_limits<Scalar>::quiet_NaN();  // not a mirror-symmetric mesh
      for (const Eigen::Matrix3Xd* f : {&x, &m}) {
        Vec3 a = f->col(i), b = f->col(it->second);
        b[axis] = 3 - b[axis];
        worst = std::max(worst, (a - b).norm());
      }
    }
  }
  return worst / scale;
}

template <FiniteElement E, class Model, class Policy>
Result run(const Options& o, int set, Scalar force, Scalar tau, Scalar rate, Scalar scale) {
  const int n = 1 << o.level;
  const Mesh<E> mesh = bar_mesh<E>(BoxSpec{10 * n, 3 * n, 3 * n, Vec3(10, 3, 3)});
  PlasticParams p;
  p.yield_stress = tau;
  p.flow_rate = rate;
  p.hardening = 0.2;
  p.stress_scale = scale;
  p.rotation_flow_rate = o.rotation_rate;
  p.rotation_yield = o.rotation_yield;
  SolverSettings st;
  st.rayleigh_mass = 1.0;
  if (o.tolerance > 0) st.newton.residual_tolerance = st.linear.tolerance = o.tolerance;
  Solver<E, Model, Policy> s(mesh, Material{3000, 0.45, 1.0}, st, p);
  s.fix(mesh.node_set("xmin"));
  const LoadCurve curve = ramp_hold_release(1.0, 2.0);
  // The force spread over the end face as a uniform traction (its consistent nodal loads): the
  // same resultant at the face's centre on every mesh, without a point load's singularity,
  // which would make the plastic zone shrink with the mesh instead of converging.
  s.add_traction(mesh.face_set("xmax"), Vec3(force / 9, 0, 0), curve);
  // The end face's mean x displacement, of the bar and of its material mesh: the tip
  // displacement, independent of where the mesh has nodes.
  const std::vector<Index> face = mesh.node_set("xmax");
  auto tip_of = [&](const Eigen::Matrix3Xd& x) {
    Scalar sum = 0;
    for (Index i : face) sum += x(0, i) - mesh.node(i).x();
    return sum / static_cast<Scalar>(face.size());
  };
  const std::string name = fmt::format("stretch_{}_{}_{}_L{}_set{}", o.model, E::name, Policy::name, o.level, set);
  io::PvdWriter world(o.out, name, {io::Encoding::appended_raw, "displacement"});
  io::PvdWriter material(o.out, name + "_material", {io::Encoding::appended_raw, "material_displacement"});
  auto write = [&] {
    const Eigen::Matrix3Xd mat = s.material_positions() - mesh.nodes();
    const Eigen::Map<const Eigen::Matrix3Xd> u(s.displacement().data(), 3, mesh.num_nodes());
    world.write(s.time(), mesh, {io::Field("displacement", u), io::Field("material_displacement", mat)},
                {io::Field("von_mises", s.von_mises_stress())});
    material.write(s.time(), mesh, {io::Field("material_displacement", mat)});
  };
  auto csv = fmt::output_file(fmt::format("{}/{}.csv", o.out, name));
  csv.print("time,force,tip_ux,material_tip_ux\n");
  fmt::print("{} {} {} level {} ({} elements), set {}: tau = {}, nu = {}, kappa = 0.2, force {}, stress scale {}, "
             "plastic rotation {}\n",
             E::name, Model::name, Policy::name, o.level, mesh.num_elements(), set, tau, rate, force, scale,
             o.rotation_rate > 0 ? fmt::format("rate {} yield {}", o.rotation_rate, o.rotation_yield) : "off");
  write();
  Result r;
  const int steps = 400;
  for (int k = 1; k <= steps; ++k) {
    const StepReport rep = s.step(0.01);
    r.ms += rep.wall_ms / steps;
    r.plastic_ms += rep.plastic.wall_ms / steps;
    const Scalar tip = tip_of(s.positions()), material_tip = tip_of(s.material_positions());
    csv.print("{},{},{},{}\n", s.time(), force * curve(s.time()), tip, material_tip);
    if (k % o.every == 0) write();
    if (k % 50 == 0)
      fmt::print("  t = {:4.2f} s  force {:6.1f}  tip u_x = {:7.4f}  material tip {:7.4f}  yielding points {:4d}  "
                 "Newton {}  {:.2f} ms\n",
                 s.time(), force * curve(s.time()), tip, material_tip, rep.plastic.points_yielded, rep.newton_iterations,
                 rep.wall_ms);
  }
  Scalar material_volume = 0;
  const Eigen::Matrix3Xd m = s.material_positions();
  for (Index e = 0; e < mesh.num_elements(); ++e) {
    ElementNodes<E> X;
    for (int a = 0; a < E::num_nodes; ++a) X.col(a) = m.col(mesh.element(e)[a]);
    material_volume += element_volume<E>(X);
  }
  r.tip = tip_of(s.positions());
  r.material_tip = tip_of(m);
  r.volume_ratio = s.volume() / 90;
  r.material_volume_ratio = material_volume / 90;
  r.symmetry = symmetry_error(s);
  // Mass damping 1.0 leaves e^-1 of the release's vibration after 2 s; a static solve gives
  // the state the bar settles to.
  s.solve_static();
  r.settled = tip_of(s.positions());
  fmt::print("  at t = 4 s: tip displacement (end face mean) {:.5f}, settled {:.5f} (material mesh {:.5f}); volume "
             "ratio {:.6f} (material {:.6f}); mirror symmetry error {:.2e}; {:.3f} ms/step ({:.3f} in the plastic "
             "update)\n",
             r.tip, r.settled, r.material_tip, r.volume_ratio, r.material_volume_ratio, r.symmetry, r.ms, r.plastic_ms);
  return r;
}

template <FiniteElement E, class Model>
void run_sets(const Options& o) {
  const bool neo = o.model == "neohookean";
  const Scalar force = neo ? 1000 : 350;
  const Scalar scale = o.stress_scale > 0 ? o.stress_scale : (neo ? 25 : 50);
  const Scalar taus[3] = {neo ? 1500.0 : 1000.0, neo ? 1800.0 : 1500.0, neo ? 2000.0 : 1500.0};
  const Scalar rates[3] = {neo ? 0.25 : 0.4, 0.2, neo ? 0.15 : 0.1};
  std::vector<std::pair<int, Result>> results;
  for (int k = 1; k <= 3; ++k) {
    if (o.set != "all" && o.set != std::to_string(k)) continue;
    const Result r = o.policy == "cell-centered"
                         ? run<E, Model, CellCentered>(o, k, force, taus[k - 1], rates[k - 1], scale)
                         : run<E, Model, VertexBlended>(o, k, force, taus[k - 1], rates[k - 1], scale);
    results.emplace_back(k, r);
  }
  fmt::print("\nset,tip_at_4s,settled_tip,material_tip,volume_ratio,material_volume_ratio,symmetry,ms_per_step,"
             "plastic_ms_per_step\n");
  for (const auto& [k, r] : results)
    fmt::print("{},{:.6f},{:.6f},{:.6f},{:.6f},{:.6f},{:.3g},{:.3f},{:.3f}\n", k, r.tip, r.settled, r.material_tip,
               r.volume_ratio, r.material_volume_ratio, r.symmetry, r.ms, r.plastic_ms);
}

template <FiniteElement E>
void run_model(const Options& o) {
  if (o.model == "corotational") run_sets<E, Corotational>(o);
  else if (o.model == "neohookean") run_sets<E, NeoHookean>(o);
  else fail<InvalidArgument>("unknown model '{}': corotational or neohookean", o.model);
}

}  // namespace

int main(int argc, char** argv) try {
  const Options o = parse(argc, argv);
  std::filesystem::create_directories(o.out);
  if (o.element == "hex8") run_model<Hex8>(o);
  else if (o.element == "tet4") run_model<Tet4>(o);
  else if (o.element == "tet10") run_model<Tet10>(o);
  else fail<InvalidArgument>("unknown element '{}': hex8, tet4 or tet10", o.element);
  return 0;
} catch (const std::exception& e) {
  fmt::print(stderr, "plastic_stretch: {}\n", e.what());
  return 1;
}
