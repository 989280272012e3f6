// What a cut costs (seed 001): the Newmark step of a cut body against the same body uncut, and
// the time to apply a cut to a running simulation (classification, sub-elements, enriched
// dofs, and the solver's rebuild of pattern, colouring, matrices and solvers).
//
// Scenes: bar5760 (Hex8 and Tet4, clamped, gravity; cut through at x = 20.5, through a row of
// elements), and the cut beam of SCENES.md (Hex8 2 x 4 x 13 and 4 x 8 x 27 cells, the slit).
// Corotational, shifted and Heaviside enrichment, accurate mode, CG 1e-6, 1 thread; medians of
// `--steps` steps after 5 warm-up steps, the cut applied after step 5 of the cut run; the mean
// Newton and CG iterations per step of both runs (a cut body is another structure: where it
// needs more iterations, the ratio says so, not the cut elements' cost); the cut elements'
// stiffness points, with the compressed rule (the default) and, for bar5760 Hex8, without.
//
// With --realtime R every row runs in real-time mode instead, keeping its tangent within a reach
// of R (NewmarkSettings::tangent_reach; 0: a tangent assembled every step), cut and uncut
// alike: what a kept tangent saves in a cut body, whose cut elements cost the most to assemble.
//
//   bench_cut [--steps 50] [--csv FILE] [--realtime R]
#include <plastifem/cutting.hpp>
#include <plastifem/plastifem.hpp>

#include "bench_common.hpp"

#include <fmt/core.h>

#include <algorithm>
#include <chrono>
#include <fstream>
#include <string>

using namespace plastifem;

using plastifem::bench::median;

namespace {

/// --realtime: real-time rows with this tangent_reach (negative: accurate rows, the default).
Scalar realtime_reach_of_rows = -1;


struct Row {
  std::string scene, element, enrichment;
  Index dofs_uncut, dofs_cut;
  double uncut_ms, cut_ms, ratio, apply_ms, classify_ms;
  double newton_uncut, newton_cut, cg_uncut, cg_cut;  // mean iterations per step
  int points;                                         // stiffness points of the cut elements
};

template <FiniteElement E, class X>
Row measure(const std::string& scene, const Mesh<E>& mesh, const Material& mat, const Cut& cut, const Vec3& g, int steps,
            bool clamp_x, CutOptions options = {}) {
  SolverSettings st;
  st.linear = {LinearSolverKind::ConjugateGradient, 1e-6, 1000};
  if (realtime_reach_of_rows >= 0) {
    st.newmark.mode = NewmarkMode::RealTime;
    st.newmark.tangent_reach = realtime_reach_of_rows;
  }
  Solver<E, Corotational, NoPlasticity, X> plain(mesh, mat, st), cut_run(mesh, mat, st);
  for (auto* s : {&plain, &cut_run}) {
    s->fix(clamp_x ? mesh.node_set("xmin") : select_nodes(mesh, [](const Vec3& p) { return p.z() < 1e-12; }));
    s->add_gravity(g);
  }
  std::vector<double> a, b;
  double apply = 0, na = 0, nb = 0, la = 0, lb = 0;
  for (int k = 1; k <= steps + 5; ++k) {
    if (k == 6) {
      const auto t0 = std::chrono::steady_clock::now();
      cut_run.cut(cut, options);
      apply = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    }
    const StepReport ra = plain.step(0.01), rb = cut_run.step(0.01);
    if (k > 5) {
      a.push_back(ra.wall_ms), b.push_back(rb.wall_ms);
      na += ra.newton_iterations, nb += rb.newton_iterations, la += ra.linear_iterations, lb += rb.linear_iterations;
    }
  }
  const std::string label =
      realtime_reach_of_rows < 0 ? scene : fmt::format("{} (real time K{:g})", scene, realtime_reach_of_rows);
  return {label, E::name, X::name, plain.num_dofs(), cut_run.num_dofs(), median(a), median(b), median(b) / median(a),
          apply, cut_run.last_cut_report().ms, na / steps, nb / steps, la / steps, lb / steps,
          cut_run.last_cut_report().stiffness_points};
}

}  // namespace

int main(int argc, char** argv) try {
  int steps = 50;
  std::string csv = "cut.csv";
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--steps" && i + 1 < argc) steps = std::max(5, std::stoi(argv[++i]));
    else if (a == "--csv" && i + 1 < argc) csv = argv[++i];
    else if (a == "--realtime" && i + 1 < argc) {
      realtime_reach_of_rows = std::stod(argv[++i]);
      if (!(realtime_reach_of_rows >= 0 && realtime_reach_of_rows <= 1))
        fail<InvalidArgument>("--realtime {}: give a tangent reach in [0, 1]", realtime_reach_of_rows);
    }
    else fail<InvalidArgument>("unknown option '{}'", a);
  }
  std::ofstream out(csv);
  out << "scene,element,enrichment,dofs_uncut,dofs_cut,uncut_ms,cut_ms,ratio,apply_cut_ms,classify_ms,newton_uncut,"
         "newton_cut,cg_uncut,cg_cut,cut_element_points\n";
  fmt::print("{:36} {:5} {:17} {:>8} {:>8} {:>9} {:>9} {:>6} {:>11} {:>11} {:>13} {:>13} {:>7}\n", "scene", "elem",
             "enrichment", "dofs", "cut dofs", "uncut ms", "cut ms", "ratio", "cut() ms", "classify ms", "Newton u/c",
             "CG u/c", "points");
  auto emit = [&](const Row& r) {
    fmt::print("{:36} {:5} {:17} {:>8} {:>8} {:>9.3f} {:>9.3f} {:>6.3f} {:>11.2f} {:>11.2f} {:>6.2f}/{:<6.2f} {:>6.1f}/{:<6.1f} {:>7}\n",
               r.scene, r.element, r.enrichment, r.dofs_uncut, r.dofs_cut, r.uncut_ms, r.cut_ms, r.ratio, r.apply_ms,
               r.classify_ms, r.newton_uncut, r.newton_cut, r.cg_uncut, r.cg_cut, r.points);
    out << fmt::format("\"{}\",{},{},{},{},{:.4f},{:.4f},{:.4f},{:.3f},{:.3f},{:.3f},{:.3f},{:.2f},{:.2f},{}\n", r.scene, r.element,
                       r.enrichment, r.dofs_uncut, r.dofs_cut, r.uncut_ms, r.cut_ms, r.ratio, r.apply_ms, r.classify_ms,
                       r.newton_uncut, r.newton_cut, r.cg_uncut, r.cg_cut, r.points);
    out.flush();
    std::fflush(stdout);
  };
  const Material bar{3000, 0.45, 1.0}, tissue{3e5, 0.35, 1070};
  const CutPlane through(Vec3(20.5, 0, 0), Vec3(1, 0, 0));
  const CutPatch slit(Vec3(-0.001, -0.001, 0.1), Vec3(0.016, 0, 0), Vec3(0, 0.062, 0));
  for (int n : {2, 4}) {
    const auto hex = bar_mesh<Hex8>(BoxSpec{n, 2 * n, 7 * n - 1, Vec3(0.03, 0.06, 0.2)});
    const std::string name = fmt::format("cut beam {}x{}x{}", n, 2 * n, 7 * n - 1);
    emit(measure<Hex8, ShiftedHeaviside>(name, hex, tissue, slit, Vec3(9.81, 0, 0), steps, false));
  }
  const auto hex = bar_mesh<Hex8>(40, 12, 12);
  emit(measure<Hex8, ShiftedHeaviside>("bar5760", hex, bar, through, Vec3(0, 0, -9.81), steps, true));
  emit(measure<Hex8, Heaviside>("bar5760", hex, bar, through, Vec3(0, 0, -9.81), steps, true));
  CutOptions full;  // every sub-tetrahedron's points, as the thesis integrates
  full.compress_quadrature = false;
  emit(measure<Hex8, ShiftedHeaviside>("bar5760, full rule", hex, bar, through, Vec3(0, 0, -9.81), steps, true, full));
  const auto tet = bar_mesh<Tet4>(40, 12, 12);
  emit(measure<Tet4, ShiftedHeaviside>("bar5760", tet, bar, through, Vec3(0, 0, -9.81), steps, true));
  fmt::print("CSV written to {}\n", csv);
  return 0;
} catch (const std::exception& e) {
  fmt::print(stderr, "bench_cut: {}\n", e.what());
  return 1;
}
