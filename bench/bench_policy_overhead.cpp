// What the plastic and enrichment axes cost a scene that uses neither: the Solver
// Solver<E, Model, NoPlasticity, NoEnrichment> against the same elastic Newmark step composed
// by hand from the same parts without the policy parameters (Assembler, ElementDataTable,
// the model's evaluate, assemble_mass, body_force_load, ConstrainedBlocks, LinearSolver).
//
// The baseline, BareNewmark below, performs the Solver's real-time step operation for
// operation (one linearised solve per step at u_n, warm-started Jacobi CG, the same residual
// checks and commit), so both produce the same displacements bit for bit: the benchmark checks
// that, so a baseline that drifted from the Solver (and would measure something else) fails
// loudly instead of reporting a ratio. Whatever the Solver does beyond it for its policy axes
// shows as a ratio above 1; NoPlasticity / NoEnrichment must compile away: 1.00 +- 0.03.
//
// Steps of the two alternate (Solver step k, bare step k, ...), so that a change of machine
// load affects both; the ratio is the median of the per-step ratios over `--steps` steps after
// 5 warm-up steps, reported with its interquartile range.
//
// A second table gives what the plastic policies cost over the elastic Solver, with and without
// flow (measure_plastic below).
//
//   bench_policy_overhead [--scenes bar720,bar5760] [--plastic-scenes bar90,bar720,bar5760] [--threads 1]
//                         [--steps 100] [--csv FILE]
//
// A third table measures plasticity as the paper did (measure_released): the stretch scene's
// steps right after the release.
#include "bare_newmark.hpp"

#include <plastifem/plasticity.hpp>
#include <plastifem/plastifem.hpp>

#include "bench_common.hpp"

#include <fmt/core.h>

#include <algorithm>
#include <chrono>
#include <fstream>
#include <sstream>
#include <string>

#ifdef _OPENMP
#include <omp.h>
#endif

using namespace plastifem;
using plastifem::bench::split;
using plastifem::bench::BareNewmark;

using plastifem::bench::median;

namespace {

double quantile(std::vector<double> v, double q) {
  std::sort(v.begin(), v.end());
  return v[static_cast<size_t>(q * static_cast<double>(v.size() - 1))];
}

struct Row {
  std::string scene, element, model;
  int threads;
  double solver_ms, bare_ms, ratio, ratio_q1, ratio_q3;
  Scalar max_difference;
};

template <class E, class Model>
Row measure(const std::string& scene, int threads, int steps) {
  const auto [nx, ny, nz] = bar_scene_cells(scene);
  const auto mesh = bar_mesh<E>(nx, ny, nz);
  const Material material{3000, 0.45, 1.0};
  const LinearSolverSettings cg{LinearSolverKind::ConjugateGradient, 1e-6, 1000};
#ifdef _OPENMP
  omp_set_num_threads(threads);
#endif
  SolverSettings st;
  st.linear = cg;
  st.newmark.mode = NewmarkMode::RealTime;
  st.threads = threads;
  Solver<E, Model, NoPlasticity, NoEnrichment> solver(mesh, material, st);
  solver.fix(mesh.node_set("xmin"));
  solver.add_gravity(Vec3(0, 0, -9.81));
  BareNewmark<E, Model> bare(mesh, material, mesh.node_set("xmin"), Vec3(0, 0, -9.81), cg, threads);
  using clock = std::chrono::steady_clock;
  auto ms = [](clock::time_point t0) { return std::chrono::duration<double, std::milli>(clock::now() - t0).count(); };
  std::vector<double> ts, tb, ratio;
  for (int k = 1; k <= steps + 5; ++k) {
    auto t0 = clock::now();
    solver.step(0.01);
    const double a = ms(t0);
    t0 = clock::now();
    bare.step(0.01);
    const double b = ms(t0);
    if (k > 5) ts.push_back(a), tb.push_back(b), ratio.push_back(a / b);
  }
  if (!(bare.force_scale() > 0)) fail<Error>("bare step: no force scale");
  const Scalar diff = (solver.displacement() - bare.displacement()).cwiseAbs().maxCoeff();
  if (diff != 0)
    fail<Error>("{} {} {}: the bare baseline no longer reproduces the Solver's step (max |u difference| {:.3g} "
                "after {} steps); it must mirror Solver::newmark_attempt's real-time branch",
                scene, E::name, Model::name, diff, steps + 5);
  return {scene, E::name, Model::name, threads, median(ts), median(tb), median(ratio), quantile(ratio, 0.25),
          quantile(ratio, 0.75), diff};
}

/// The plastic rows' settings: accurate mode, CG 1e-6, `threads` (OpenMP's too).
SolverSettings plastic_settings(int threads) {
#ifdef _OPENMP
  omp_set_num_threads(threads);
#endif
  SolverSettings st;
  st.linear = {LinearSolverKind::ConjugateGradient, 1e-6, 1000};
  st.threads = threads;
  return st;
}

/// Steps of a plastic Solver and an elastic one alternating (`warmup` untimed first), timed:
/// a row with the medians and the per-step ratio's quartiles; `yielded` gets the flow points
/// that yielded in the timed steps.
template <class Plastic, class Elastic>
Row time_alternating(Plastic& plastic, Elastic& elastic, int warmup, int steps, long& yielded) {
  using clock = std::chrono::steady_clock;
  auto ms = [](clock::time_point t0) { return std::chrono::duration<double, std::milli>(clock::now() - t0).count(); };
  std::vector<double> tp, te, ratio;
  yielded = 0;
  for (int k = 1; k <= warmup + steps; ++k) {
    auto t0 = clock::now();
    const int y = plastic.step(0.01).plastic.points_yielded;
    const double a = ms(t0);
    t0 = clock::now();
    elastic.step(0.01);
    const double b = ms(t0);
    if (k > warmup) tp.push_back(a), te.push_back(b), ratio.push_back(a / b), yielded += y;
  }
  Row r;
  r.solver_ms = median(tp), r.bare_ms = median(te), r.ratio = median(ratio);
  r.ratio_q1 = quantile(ratio, 0.25), r.ratio_q3 = quantile(ratio, 0.75);
  r.max_difference = (plastic.displacement() - elastic.displacement()).cwiseAbs().maxCoeff();
  return r;
}

/// What a plastic policy costs: Solver<E, Model, P> against Solver<E, Model> on the same scene
/// (accurate mode, CG 1e-6), steps alternating. `flowing`: yield stress 0, so that every flow
/// point yields in every step (the worst case: flow, fusion and re-prepared element data every
/// step); else tau = 10^4 with the physical stress, which the gravity load does not reach (the
/// check alone; the paper's tau = 1000 is reached by the Neo-Hookean bar90 under gravity, whose
/// clamp sees a bending stress of ~1000 and twice that in the first swing).
template <class E, class Model, class P>
Row measure_plastic(const std::string& scene, int threads, int steps, bool flowing) {
  const auto [nx, ny, nz] = bar_scene_cells(scene);
  const auto mesh = bar_mesh<E>(nx, ny, nz);
  const Material material{3000, 0.45, 1.0};
  SolverSettings st = plastic_settings(threads);
  PlasticParams pp;
  pp.yield_stress = flowing ? 0 : 1e4;
  pp.flow_rate = 0.4;
  Solver<E, Model> elastic(mesh, material, st);
  Solver<E, Model, P> plastic(mesh, material, st, pp);
  elastic.fix(mesh.node_set("xmin"));
  elastic.add_gravity(Vec3(0, 0, -9.81));
  plastic.fix(mesh.node_set("xmin"));
  plastic.add_gravity(Vec3(0, 0, -9.81));
  long yielded = 0;
  Row r = time_alternating(plastic, elastic, 5, steps, yielded);
  if (flowing && yielded == 0) fail<Error>("{} {} {}: the flowing configuration did not flow", scene, E::name, P::name);
  if (!flowing && yielded != 0) fail<Error>("{} {} {}: the check-only configuration flowed", scene, E::name, P::name);
  r.scene = scene, r.element = E::name, r.threads = threads;
  r.model = fmt::format("{}+{}{}", Model::name, P::name, flowing ? " flowing" : "");
  return r;
}

/// The paper's own figure (seed 000, section 4: "the time steps immediately after release are
/// the most expensive, adding ca 20% to SOFA's run time for elastic-only co-rotational FEM"):
/// the stretch scene of SCENES.md (the 10 x 3 x 3 bar at the scene's resolution, force 350
/// along +x spread over the end face, ramped over 1 s, held 1 s, released; Rayleigh mass
/// damping 1.0; parameter set 1, tau = 1000, nu = 0.4, kappa = 0.2, with the stress scale 50 of
/// examples/plastic_stretch.cpp, without which the physical stress stays elastic), run to the
/// release untimed, then `steps` steps after it timed against the elastic Solver on the same
/// scene (accurate, CG 1e-6), alternating. `flowing_points`: the mean number of flow points
/// that yielded per measured step.
template <class E, class Model, class P>
Row measure_released(const std::string& scene, int threads, int steps, double& flowing_points, int& points) {
  const auto [nx, ny, nz] = bar_scene_cells(scene);
  const auto mesh = bar_mesh<E>(BoxSpec{nx, ny, nz, Vec3(10, 3, 3)});
  const Material material{3000, 0.45, 1.0};
  SolverSettings st = plastic_settings(threads);
  st.rayleigh_mass = 1.0;
  PlasticParams pp;
  pp.yield_stress = 1000;
  pp.flow_rate = 0.4;
  pp.hardening = 0.2;
  pp.stress_scale = 50;
  Solver<E, Model> elastic(mesh, material, st);
  Solver<E, Model, P> plastic(mesh, material, st, pp);
  elastic.fix(mesh.node_set("xmin"));
  plastic.fix(mesh.node_set("xmin"));
  elastic.add_traction(mesh.face_set("xmax"), Vec3(350.0 / 9, 0, 0), ramp_hold_release(1.0, 2.0));
  plastic.add_traction(mesh.face_set("xmax"), Vec3(350.0 / 9, 0, 0), ramp_hold_release(1.0, 2.0));
  for (int k = 0; k < 200; ++k) plastic.step(0.01), elastic.step(0.01);  // to the release at t = 2 s
  long yielded = 0;
  Row r = time_alternating(plastic, elastic, 0, steps, yielded);
  flowing_points = static_cast<double>(yielded) / steps;
  points = static_cast<int>(mesh.num_elements()) * plastifem::plastic::ElementFlow<E, Model, P::per_vertex_rotation>::P;
  if (yielded == 0) fail<Error>("{} {} {}: nothing flowed after the release", scene, E::name, P::name);
  r.scene = scene, r.element = E::name, r.threads = threads;
  r.model = fmt::format("{}+{} released", Model::name, P::name);
  return r;
}

}  // namespace

int main(int argc, char** argv) try {
  std::vector<std::string> scenes{"bar720", "bar5760"}, plastic_scenes{"bar90", "bar720", "bar5760"};
  std::vector<int> threads{1};
  int steps = 100;
  std::string csv = "policy_overhead.csv";
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (i + 1 < argc && a == "--scenes") scenes = plastic_scenes = split(argv[++i]);
    else if (i + 1 < argc && a == "--plastic-scenes") plastic_scenes = split(argv[++i]);
    else if (i + 1 < argc && a == "--steps") steps = std::max(10, std::stoi(argv[++i]));
    else if (i + 1 < argc && a == "--csv") csv = argv[++i];
    else if (i + 1 < argc && a == "--threads") threads = plastifem::bench::split_ints(argv[++i]);
    else fail<InvalidArgument>("unknown option '{}'", a);
  }
  std::ofstream out(csv);
  out << "scene,element,model,threads,solver_ms,bare_ms,ratio_median,ratio_q1,ratio_q3,max_u_difference\n";
  fmt::print("Solver<E, Model, NoPlasticity, NoEnrichment> against the same step without policy parameters\n"
             "(real time, CG 1e-6; ratio = median of per-step ratios over {} alternating steps, [q1, q3])\n\n",
             steps);
  fmt::print("{:9} {:5} {:24} {:>3} {:>10} {:>10} {:>7} {:>16} {:>9}\n", "scene", "elem", "model", "thr", "Solver ms",
             "bare ms", "ratio", "[q1, q3]", "|du|max");
  auto emit = [&](const Row& r) {
    fmt::print("{:9} {:5} {:24} {:>3} {:>10.3f} {:>10.3f} {:>7.3f}   [{:.3f}, {:.3f}] {:>9.1e}\n", r.scene, r.element,
               r.model, r.threads, r.solver_ms, r.bare_ms, r.ratio, r.ratio_q1, r.ratio_q3, r.max_difference);
    out << fmt::format("{},{},{},{},{:.6f},{:.6f},{:.4f},{:.4f},{:.4f},{:.3g}\n", r.scene, r.element, r.model, r.threads,
                       r.solver_ms, r.bare_ms, r.ratio, r.ratio_q1, r.ratio_q3, r.max_difference);
    out.flush();
    std::fflush(stdout);
  };
  for (const auto& scene : scenes)
    for (int t : threads) {
      emit(measure<Hex8, CorotationalPerElement>(scene, t, steps));
      emit(measure<Hex8, Corotational>(scene, t, steps));
      emit(measure<Tet4, Corotational>(scene, t, steps));
    }
  fmt::print("\nSolver<E, Model, VertexBlended or CellCentered> against Solver<E, Model> (accurate, CG 1e-6; 'bare ms'\n"
             "is the elastic Solver's; |du|max: how far plasticity moved the answer). Without 'flowing':\n"
             "tau = 10^4, which gravity does not reach (the check alone); 'flowing': tau = 0, every\n"
             "point flows in every step (flow, fusion, element data re-prepared every step)\n\n");
  for (const auto& scene : plastic_scenes)
    for (int t : threads)
      for (bool flowing : {false, true}) {
        emit(measure_plastic<Hex8, Corotational, VertexBlended>(scene, t, steps, flowing));
        emit(measure_plastic<Hex8, Corotational, CellCentered>(scene, t, steps, flowing));
        emit(measure_plastic<Hex8, CorotationalPerElement, VertexBlended>(scene, t, steps, flowing));
        emit(measure_plastic<Hex8, NeoHookean, VertexBlended>(scene, t, steps, flowing));
        emit(measure_plastic<Tet4, Corotational, VertexBlended>(scene, t, steps, flowing));
      }
  fmt::print("\nThe paper's measure: the stretch scene (SCENES.md, set 1 with stress scale 50), the {} steps right\n"
             "after the release at t = 2 s, against the elastic Solver on the same scene (accurate, CG 1e-6)\n\n",
             steps);
  for (const auto& scene : plastic_scenes)
    for (int t : threads) {
      auto released = [&](auto measured) {
        double flowing = 0;
        int points = 0;
        const Row r = measured(flowing, points);
        emit(r);
        fmt::print("{:>44} flow points yielding per step: {:.0f} of {} ({:.0f}%)\n", "", flowing, points,
                   100 * flowing / points);
      };
      released([&](double& f, int& p) { return measure_released<Hex8, Corotational, VertexBlended>(scene, t, steps, f, p); });
      released([&](double& f, int& p) { return measure_released<Hex8, Corotational, CellCentered>(scene, t, steps, f, p); });
      released([&](double& f, int& p) { return measure_released<Tet4, Corotational, VertexBlended>(scene, t, steps, f, p); });
    }
  fmt::print("CSV written to {}\n", csv);
  return 0;
} catch (const std::exception& e) {
  fmt::print(stderr, "bench_policy_overhead: {}\n", e.what());
  return 1;
}
