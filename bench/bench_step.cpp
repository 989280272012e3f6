// Cost of one Newmark step on the SCENES.md bar scenes (E = 3000, nu = 0.45, rho = 1, clamped
// at x = 0, gravity -z, beta 1/4, gamma 1/2, dt = 0.01), for every element x model x linear
// solver x mode, single-threaded and with all cores.
//
// Each row runs 100 steps (t = 0 -> 1 s): the median, min and max wall time are over steps
// 6..100 (5 warm-up steps, 95 measured), and the tip displacement at t = 1 s is printed so that
// a fast wrong answer shows; real-time rows also give their tip's relative difference from the
// accurate row of the same model. `peak MB` is the peak heap of the row's solver (element data,
// matrices, vectors, solver scratch; glibc's malloc statistics, read after construction and
// after every step: a step allocates nothing once warmed up, tests/test_allocation.cpp).
// Output: a table on stdout, a CSV, and
// with several scenes a scaling table: ms per step against element count, with the exponent p
// of a least-squares fit ms ~ elements^p.
//
// Scenes: the SCENES.md bars (bar90 ... bar46080) and bar368640 (160 x 48 x 48, the next size
// in their series of 8x: 368,640 hexes, 386,561 nodes), and Gmsh Tet4 meshes given by --msh
// (bench/organ_mesh.cpp makes unstructured liver meshes of 2.6k to 0.8M tetrahedra, every
// element different), named by their file and stepped with the bars' material, gravity and dt,
// clamped at their nodes within 2% of their length from their lowest x; their tip is the node of
// largest x.
//
//   bench_step [--scenes bar90,bar720,...] [--msh a.msh,b.msh] [--elements hex8,tet4,tet10] [--threads 1,2] [--csv FILE]
//              [--models linear,corotational,corotational-warped,corotational-element,neohookean,
//                        stable-neohookean,plastic]
//              (plastic: Corotational, CorotationalPerElement and NeoHookean with VertexBlended or
//               CellCentered, tau = 10^4, which gravity does not reach: the check's cost)
//              (corotational: the exact tangent, the default; corotational-warped: R K0 R^T)
//              [--quick]   (--quick: accurate mode only, no LDLT for nonlinear models)
//              [--cg-cap N] (real-time rows also with CG capped at N iterations; default 5, 0: none)
//              [--tangent-reach R] (the corotational and Neo-Hookean real-time rows also with
//               NewmarkSettings::tangent_reach = R, mode "rt-K<R>": the tangent kept while no edge
//               has changed by more than R of its length; its `kept` column is the fraction of
//               measured steps that kept it)
//              [--preconditioner jacobi|block] (CG's: Jacobi, the default, or 3 x 3 node blocks; the
//               solver column then says BJ-CG)
//              [--after T] (T seconds of the scene first, not timed: the 100 measured steps then
//               run from t = T, e.g. --after 3 on a bar that has sagged to 20% strain; the tip
//               column is then at t = T + 1 s)
#include <plastifem/mesh/io/io.hpp>
#include <plastifem/plasticity.hpp>
#include <plastifem/plastifem.hpp>

#include "bench_common.hpp"

#include <fmt/core.h>
#include <fmt/os.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <map>

#ifdef __GLIBC__
#include <malloc.h>
#endif
#include <fstream>
#include <sstream>
#include <string>

#ifdef _OPENMP
#include <omp.h>
#endif

using namespace plastifem;
using plastifem::bench::split;

namespace {

/// A scene's mesh, its clamped nodes and the node whose displacement is printed.
template <class E>
struct Scene {
  std::string name;
  Mesh<E> mesh;
  std::vector<Index> clamped;
  Index tip = 0;
};

/// A bar: SCENES.md's sizes and bar368640, clamped at x = 0, the tip at its far top corner.
template <class E>
Scene<E> bar_scene(const std::string& name) {
  const auto [nx, ny, nz] = name == "bar368640" ? std::array<int, 3>{160, 48, 48} : bar_scene_cells(name);
  Scene<E> s{name, bar_mesh<E>(nx, ny, nz), {}, 0};
  s.clamped = s.mesh.node_set("xmin");
  for (Index i : s.mesh.node_set("xmax"))
    if (s.mesh.node(i).y() == ny && s.mesh.node(i).z() == nz) s.tip = i;
  return s;
}

/// A Gmsh mesh of Tet4 (the organ meshes): clamped within 2% of its length from its lowest x,
/// the tip at its largest x.
Scene<Tet4> msh_scene(const std::string& file) {
  Scene<Tet4> s{std::filesystem::path(file).stem().string(), io::read_gmsh<Tet4>(file, {.drop_unused_nodes = true}), {}, 0};
  const auto x = s.mesh.nodes().row(0);
  const Scalar x0 = x.minCoeff(), length = x.maxCoeff() - x0;
  for (Index i = 0; i < s.mesh.num_nodes(); ++i) {
    if (x[i] <= x0 + 0.02 * length) s.clamped.push_back(i);
    if (x[i] > x[s.tip]) s.tip = i;
  }
  return s;
}

struct Row {
  std::string scene, element, model, solver, mode;
  int threads;
  Index dofs, elements;
  double heap_mb;  ///< peak heap of the row's solver: the largest of its heap after construction and after each step
  double median_ms, min_ms, max_ms, newton, linear;
  Scalar tip_uz;
  double kept = 0;  ///< fraction of the measured steps that kept their tangent (NewmarkSettings::tangent_reach)
};

/// Heap memory in use, in MB (glibc's allocator statistics; 0 elsewhere).
double heap_mb() {
#if defined(__GLIBC__) && (__GLIBC__ > 2 || (__GLIBC__ == 2 && __GLIBC_MINOR__ >= 33))
  const struct mallinfo2 m = mallinfo2();
  return static_cast<double>(m.uordblks + m.hblkhd) / (1024.0 * 1024.0);
#else
  return 0;
#endif
}

/// Seconds of each scene run before the measured steps (--after).
Scalar after_seconds = 0;
/// CG's preconditioner (--preconditioner).
CgPreconditioner preconditioner = CgPreconditioner::Jacobi;

/// cg_cap > 0: real-time mode with CG stopped after cg_cap iterations (or at 1e-6, if sooner).
/// tangent_reach > 0: real-time mode keeping its tangent within that reach.
/// P: a plastic policy, with tau = 10^4, nu = 0.4, kappa = 0.2 and the physical stress, which
/// the gravity load does not reach: the cost of carrying plasticity in a scene that stays
/// elastic (bench_policy_overhead also measures it flowing).
template <class E, class Model, class P = NoPlasticity>
Row measure(const Scene<E>& scene, LinearSolverKind kind, NewmarkMode mode, int threads, bool exact_tangent = true,
            int cg_cap = 0, Scalar tangent_reach = 0) {
  const Mesh<E>& mesh = scene.mesh;
  SolverSettings st;
  st.newton.exact_tangent = exact_tangent;
  st.linear = {kind, 1e-6, cg_cap > 0 ? cg_cap : 1000};  // CG to 1e-6 relative, warm-started (SCENES / issue targets)
  st.linear.accept_capped = cg_cap > 0;                   // a fixed-cost step: the cap is meant
  st.linear.preconditioner = preconditioner;
  st.newmark.mode = mode;
  st.newmark.tangent_reach = tangent_reach;
  st.threads = threads;
#ifdef _OPENMP
  omp_set_num_threads(threads);
#endif
  const double heap0 = heap_mb();
  typename P::Params pp{};
  if constexpr (P::active) pp.yield_stress = 1e4, pp.flow_rate = 0.4, pp.hardening = 0.2;
  Solver<E, Model, P> s(mesh, Material{3000, 0.45, 1.0}, st, pp);
  s.fix(scene.clamped);
  s.add_gravity(Vec3(0, 0, -9.81));
  const Index tip = scene.tip;
  for (long k = std::lround(after_seconds / 0.01); k > 0; --k) s.step(0.01);
  std::vector<double> ms;
  double newton = 0, lin = 0, kept = 0;
  double peak = heap_mb();
  for (int k = 1; k <= 100; ++k) {
    const StepReport r = s.step(0.01);
    peak = std::max(peak, heap_mb());  // outside the timed step
    if (k > 5) {
      ms.push_back(r.wall_ms);
      newton += r.newton_iterations;
      lin += r.linear_iterations;
      kept += r.tangents_kept;
    }
  }
  std::sort(ms.begin(), ms.end());
  const double n = static_cast<double>(ms.size());
  std::string model = exact_tangent ? Model::name : fmt::format("{} (warped)", Model::name);
  if constexpr (P::active) model += P::per_vertex_rotation ? "+VB" : "+CC";
  return {scene.name, E::name, model,
          kind == LinearSolverKind::Direct ? std::string(direct_solver_name(DirectSolver::Auto))
          : fmt::format("{}{}", preconditioner == CgPreconditioner::BlockJacobi ? "BJ-" : "",
                        cg_cap > 0 ? fmt::format("CG<={}", cg_cap) : std::string("CG-1e-6")),
          mode == NewmarkMode::Accurate ? "accurate"
          : tangent_reach > 0           ? fmt::format("rt-K{:g}", tangent_reach)
                                        : std::string("realtime"),
          threads, s.num_dofs(), mesh.num_elements(), peak - heap0, ms[ms.size() / 2], ms.front(), ms.back(), newton / n, lin / n, s.displacement(tip).z(),
          kept / n};
}

}  // namespace

int main(int argc, char** argv) try {
  std::vector<std::string> scenes{"bar90", "bar720"}, msh;
  std::vector<int> threads{1, 2};
  std::vector<std::string> elements{"hex8", "tet4", "tet10"};
  std::vector<std::string> models{"linear",     "corotational",      "corotational-warped", "corotational-element",
                                  "neohookean", "stable-neohookean", "plastic"};
  std::string csv = "bench_step.csv";
  bool quick = false;
  int cg_cap = 5;
  Scalar tangent_reach = 0;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--quick") quick = true;
    else if (i + 1 < argc && a == "--scenes") scenes = split(argv[++i]);
    else if (i + 1 < argc && a == "--msh") msh = split(argv[++i]);
    else if (i + 1 < argc && a == "--csv") csv = argv[++i];
    else if (i + 1 < argc && a == "--cg-cap") cg_cap = std::stoi(argv[++i]);
    else if (i + 1 < argc && a == "--tangent-reach") tangent_reach = std::stod(argv[++i]);
    else if (i + 1 < argc && a == "--after") {
      after_seconds = std::stod(argv[++i]);
      if (!(after_seconds >= 0 && after_seconds <= 1e3)) fail<InvalidArgument>("--after {}: give seconds in [0, 1000]", after_seconds);
    }
    else if (i + 1 < argc && a == "--preconditioner") {
      const std::string pc = argv[++i];
      if (pc != "jacobi" && pc != "block") fail<InvalidArgument>("--preconditioner {}: give jacobi or block", pc);
      preconditioner = pc == "block" ? CgPreconditioner::BlockJacobi : CgPreconditioner::Jacobi;
    }
    else if (i + 1 < argc && a == "--elements") elements = split(argv[++i]);
    else if (i + 1 < argc && a == "--models") models = split(argv[++i]);
    else if (i + 1 < argc && a == "--threads") threads = plastifem::bench::split_ints(argv[++i]);
    else fail<InvalidArgument>("unknown option '{}'", a);
  }
  std::ofstream out(csv);
  out << "scene,element,model,solver,mode,threads,dofs,elements,peak_heap_mb,median_ms,min_ms,max_ms,newton_per_step,"
         "linear_per_step,tip_uz_t1,realtime_vs_accurate,tangents_kept\n";
  fmt::print("{:9} {:6} {:22} {:8} {:9} {:>3} {:>7} {:>7} {:>10} {:>9} {:>9} {:>7} {:>8} {:>10} {:>9} {:>5}\n", "scene",
             "elem", "model", "solver", "mode", "thr", "dofs", "peak MB", "median ms", "min ms", "max ms", "Newton",
             "lin.it", "tip uz(1s)", "rt error", "kept");
  std::map<std::string, Scalar> accurate_tip;  // scene/element/model/threads -> tip of the accurate CG row
  std::vector<Row> rows;
  auto emit = [&](const Row& r) {
    const std::string key = fmt::format("{}/{}/{}/{}", r.scene, r.element, r.model, r.threads);
    if (r.mode == "accurate" && r.solver != direct_solver_name(DirectSolver::Auto)) accurate_tip[key] = r.tip_uz;
    std::string rt_error;
    if (r.mode != "accurate" && accurate_tip.count(key))
      rt_error = fmt::format("{:.2e}", std::abs(r.tip_uz - accurate_tip[key]) / std::abs(accurate_tip[key]));
    const std::string kept = r.mode.starts_with("rt-K") ? fmt::format("{:.2f}", r.kept) : std::string();
    fmt::print("{:9} {:6} {:22} {:8} {:9} {:>3} {:>7} {:>7.1f} {:>10.3f} {:>9.3f} {:>9.3f} {:>7.2f} {:>8.1f} {:>10.5f} {:>9} {:>5}\n",
               r.scene, r.element, r.model, r.solver, r.mode, r.threads, r.dofs, r.heap_mb, r.median_ms, r.min_ms,
               r.max_ms, r.newton, r.linear, r.tip_uz, rt_error, kept);
    out << fmt::format("{},{},{},{},{},{},{},{},{:.1f},{:.6f},{:.6f},{:.6f},{:.3f},{:.3f},{:.9g},{},{}\n", r.scene, r.element,
                       r.model, r.solver, r.mode, r.threads, r.dofs, r.elements, r.heap_mb, r.median_ms, r.min_ms,
                       r.max_ms, r.newton, r.linear, r.tip_uz, rt_error, kept);
    out.flush();
    std::fflush(stdout);  // progress is visible when the table is redirected to a file
    rows.push_back(r);
  };
  auto want = [&](const char* m) { return std::find(models.begin(), models.end(), m) != models.end(); };
  auto scene_rows = [&]<class E>(const Scene<E>& scene) {
    const auto& mesh = scene.mesh;
    // LDLT: the linear model factorises once; nonlinear models refactorise every Newton
    // iteration, which only pays on small scenes.
    const bool direct_ok = mesh.num_nodes() < 2000;
    constexpr auto CG = LinearSolverKind::ConjugateGradient, LDLT = LinearSolverKind::Direct;
    constexpr auto accurate = NewmarkMode::Accurate, realtime = NewmarkMode::RealTime;
    for (int t : threads) {
      if (want("linear")) {
        emit(measure<E, Linear>(scene, CG, accurate, t));
        emit(measure<E, Linear>(scene, LDLT, accurate, t));
      }
      if (want("corotational")) {
        emit(measure<E, Corotational>(scene, CG, accurate, t));
        if (!quick) emit(measure<E, Corotational>(scene, CG, realtime, t));
        if (!quick && cg_cap > 0) emit(measure<E, Corotational>(scene, CG, realtime, t, true, cg_cap));
        if (!quick && tangent_reach > 0) emit(measure<E, Corotational>(scene, CG, realtime, t, true, 0, tangent_reach));
        if (direct_ok && !quick) emit(measure<E, Corotational>(scene, LDLT, accurate, t));
      }
      if (want("corotational-warped")) {
        emit(measure<E, Corotational>(scene, CG, accurate, t, false));
        if (!quick) emit(measure<E, Corotational>(scene, CG, realtime, t, false));
      }
      if (!std::is_same_v<E, Tet4> && want("corotational-element")) {  // identical to Corotational on Tet4
        emit(measure<E, CorotationalPerElement>(scene, CG, accurate, t));
        if (!quick) emit(measure<E, CorotationalPerElement>(scene, CG, realtime, t));
        if (!quick && cg_cap > 0) emit(measure<E, CorotationalPerElement>(scene, CG, realtime, t, true, cg_cap));
        if (!quick && tangent_reach > 0)
          emit(measure<E, CorotationalPerElement>(scene, CG, realtime, t, true, 0, tangent_reach));
      }
      if (want("neohookean")) {
        emit(measure<E, NeoHookean>(scene, CG, accurate, t));
        if (!quick) emit(measure<E, NeoHookean>(scene, CG, realtime, t));
        if (!quick && tangent_reach > 0) emit(measure<E, NeoHookean>(scene, CG, realtime, t, true, 0, tangent_reach));
      }
      if (!quick && want("stable-neohookean")) emit(measure<E, StableNeoHookean>(scene, CG, accurate, t));
      if (want("plastic")) {  // seed 000: the plastic policies on the elastic scene
        emit(measure<E, Corotational, VertexBlended>(scene, CG, accurate, t));
        emit(measure<E, Corotational, CellCentered>(scene, CG, accurate, t));
        emit(measure<E, Corotational, VertexBlended>(scene, CG, realtime, t));
        if (!std::is_same_v<E, Tet4>) emit(measure<E, CorotationalPerElement, VertexBlended>(scene, CG, realtime, t));
        emit(measure<E, NeoHookean, VertexBlended>(scene, CG, accurate, t));
      }
    }
  };
  auto wanted = [&](const char* e) { return std::find(elements.begin(), elements.end(), e) != elements.end(); };
  for (const auto& scene : scenes) {
    if (wanted("hex8")) scene_rows(bar_scene<Hex8>(scene));
    if (wanted("tet4")) scene_rows(bar_scene<Tet4>(scene));
    if (wanted("tet10")) scene_rows(bar_scene<Tet10>(scene));
  }
  for (const auto& file : msh) scene_rows(msh_scene(file));
  // Scaling: the same configuration over several scenes, and the fitted exponent.
  std::map<std::string, std::vector<const Row*>> series;
  for (const Row& r : rows) series[fmt::format("{} {} {} {} {}t", r.element, r.model, r.solver, r.mode, r.threads)].push_back(&r);
  bool header = false;
  for (const auto& [name, rs] : series) {
    if (rs.size() < 2) continue;
    if (!header) fmt::print("\nscaling: median ms per step by element count, fitted exponent p (ms ~ elements^p)\n");
    header = true;
    double sx = 0, sy = 0, sxx = 0, sxy = 0;
    std::string cells;
    for (const Row* r : rs) {
      const double lx = std::log(static_cast<double>(r->elements)), ly = std::log(r->median_ms);
      sx += lx, sy += ly, sxx += lx * lx, sxy += lx * ly;
      cells += fmt::format("  {}: {:.3f}", r->elements, r->median_ms);
    }
    const double n = static_cast<double>(rs.size());
    fmt::print("{:48} p = {:.2f} {}\n", name, (n * sxy - sx * sy) / (n * sxx - sx * sx), cells);
  }
  fmt::print("CSV written to {}\n", csv);
  return 0;
} catch (const std::exception& e) {
  fmt::print(stderr, "bench_step: {}\n", e.what());
  return 1;
}
