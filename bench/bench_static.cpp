// Cost of a static solve on the SCENES.md bar scenes (E = 3000, nu = 0.45, rho = 1, clamped at
// x = 0, gravity 9.81 along -z) for each linear solver: Eigen's SimplicialLDLT, CHOLMOD's
// supernodal LL^T (where the build has it) and Jacobi CG. Statics are where a direct solver
// earns its place: Newton on the stiffness alone, no mass term to make CG converge fast.
//
// Each row: the median of `--repeat` (default 3) full solve_static() calls from rest on a new
// solver (symbolic analysis included: a static solve pays it once), Newton iterations, and
// the tip displacement so that a fast wrong answer shows. Output: a table and a CSV.
//
//   bench_static [--scenes bar90,bar720,bar5760] [--elements hex8,tet4,tet10]
//                [--models linear,neohookean] [--repeat N] [--csv FILE]
// LDLT rows are skipped above 60k dofs, and for NeoHookean (one factorisation per Newton
// iteration) above 10k dofs: bar5760 Hex8 took 224 s there against 19 s with CHOLMOD.
// CG runs to 1e-10.
#include <plastifem/plastifem.hpp>

#include "bench_common.hpp"

#include <fmt/core.h>

#include <algorithm>
#include <chrono>
#include <fstream>
#include <sstream>
#include <string>

using namespace plastifem;
using plastifem::bench::split;

namespace {

struct Row {
  std::string scene, element, model, solver;
  Index dofs = 0;
  double median_ms = 0;
  int newton = 0, linear = 0;
  Scalar tip_uz = 0;
};

template <class E, class Model>
Row measure(const std::string& scene, const Mesh<E>& mesh, LinearSolverSettings linear, int repeat) {
  const auto [nx, ny, nz] = bar_scene_cells(scene);
  Index tip = 0;
  for (Index i : mesh.node_set("xmax"))
    if (mesh.node(i).y() == ny && mesh.node(i).z() == nz) tip = i;
  std::vector<double> ms;
  Row row{scene, E::name, Model::name,
          linear.kind == LinearSolverKind::Direct ? direct_solver_name(linear.direct) : "CG-1e-10"};
  for (int k = 0; k < repeat; ++k) {
    SolverSettings st;
    st.static_linear = linear;
    Solver<E, Model> s(mesh, Material{3000, 0.45, 1.0}, st);
    s.fix(mesh.node_set("xmin"));
    s.add_gravity(Vec3(0, 0, -9.81));
    const auto t0 = std::chrono::steady_clock::now();
    const StepReport r = s.solve_static();
    ms.push_back(plastifem::bench::ms_since(t0));
    row.dofs = s.num_dofs();
    row.newton = r.newton_iterations;
    row.linear = r.linear_iterations;
    row.tip_uz = s.displacement(tip).z();
  }
  row.median_ms = plastifem::bench::median(ms);
  return row;
}

}  // namespace

int main(int argc, char** argv) try {
  std::vector<std::string> scenes{"bar90", "bar720", "bar5760"}, elements{"hex8", "tet4"},
      models{"linear", "neohookean"};
  std::string csv = "bench_static.csv";
  int repeat = 3;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (i + 1 < argc && a == "--scenes") scenes = split(argv[++i]);
    else if (i + 1 < argc && a == "--elements") elements = split(argv[++i]);
    else if (i + 1 < argc && a == "--models") models = split(argv[++i]);
    else if (i + 1 < argc && a == "--repeat") repeat = std::max(1, std::stoi(argv[++i]));
    else if (i + 1 < argc && a == "--csv") csv = argv[++i];
    else fail<InvalidArgument>("unknown option '{}'", a);
  }
  std::ofstream out(csv);
  out << "scene,element,model,solver,dofs,median_ms,newton,linear_iterations,tip_uz\n";
  fmt::print("{:9} {:6} {:12} {:9} {:>7} {:>11} {:>7} {:>8} {:>11}\n", "scene", "elem", "model", "solver", "dofs",
             "median ms", "Newton", "lin.it", "tip uz");
  auto emit = [&](const Row& r) {
    fmt::print("{:9} {:6} {:12} {:9} {:>7} {:>11.1f} {:>7} {:>8} {:>11.6f}\n", r.scene, r.element, r.model, r.solver,
               r.dofs, r.median_ms, r.newton, r.linear, r.tip_uz);
    out << fmt::format("{},{},{},{},{},{:.3f},{},{},{:.9g}\n", r.scene, r.element, r.model, r.solver, r.dofs,
                       r.median_ms, r.newton, r.linear, r.tip_uz);
    out.flush();
    std::fflush(stdout);
  };
  auto want = [&](const char* m) { return std::find(models.begin(), models.end(), m) != models.end(); };
  auto scene_rows = [&]<class E>(const std::string& scene) {
    const auto [nx, ny, nz] = bar_scene_cells(scene);
    const auto mesh = bar_mesh<E>(nx, ny, nz);
    const Index dofs = 3 * mesh.num_nodes();
    const LinearSolverSettings ldlt{LinearSolverKind::Direct, 0, 1, DirectSolver::SimplicialLDLT},
        cholmod{LinearSolverKind::Direct, 0, 1, DirectSolver::CholmodSupernodal},
        cg{LinearSolverKind::ConjugateGradient, 1e-10, 100000};
    if (want("linear")) {
      if (dofs <= 60000) emit(measure<E, Linear>(scene, mesh, ldlt, repeat));
      if (cholmod_available()) emit(measure<E, Linear>(scene, mesh, cholmod, repeat));
      emit(measure<E, Linear>(scene, mesh, cg, repeat));
    }
    if (want("neohookean")) {
      if (dofs <= 10000) emit(measure<E, NeoHookean>(scene, mesh, ldlt, repeat));
      if (cholmod_available()) emit(measure<E, NeoHookean>(scene, mesh, cholmod, repeat));
      emit(measure<E, NeoHookean>(scene, mesh, cg, repeat));
    }
  };
  for (const auto& scene : scenes) {
    auto wanted = [&](const char* e) { return std::find(elements.begin(), elements.end(), e) != elements.end(); };
    if (wanted("hex8")) scene_rows.operator()<Hex8>(scene);
    if (wanted("tet4")) scene_rows.operator()<Tet4>(scene);
    if (wanted("tet10")) scene_rows.operator()<Tet10>(scene);
  }
  fmt::print("CSV written to {}\n", csv);
  return 0;
} catch (const std::exception& e) {
  fmt::print(stderr, "bench_static: {}\n", e.what());
  return 1;
}
