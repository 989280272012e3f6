// Accuracy against cost of the elastic models (issue 5, part 3): for every element x model x
// mesh size x solver variant, how far a quantity of interest is from a fine reference and what
// it costs, on the SCENES.md bar (10 x 3 x 3, E = 3000, nu = 0.45, rho = 1, clamped at x = 0,
// gravity -z, Newmark beta 1/4, gamma 1/2, dt = 0.01), single-threaded, on meshes of cell size
// h = 1, 0.5, 0.25 (same outer dimensions).
//
// Scenes (docs/study.md has the full definitions and the choice of references):
//   linear   discretisation only: Linear statics, reference Tet10 at h = 0.25
//   static   static bending under gravity: tip u_z at (10, 3, 3); error |q - q_ref| / |q_ref|
//   dynamic  200 Newmark steps (2 s) from rest: tip u_z history; error RMS(q - q_ref) / max|q_ref|;
//            cost = median wall ms per step over steps 6..200
//   large    static bending under 3 g (large rotations), Neo-Hookean family and corotational
// Each scene is one entry of a table (name, models, solver variants, reference case, and a
// function that runs one case and returns {quantity, history, ms}), so that plasticity and cut
// scenes can join with their own run functions. Output: a progress table on stdout, one CSV row
// per run (docs/plot_study.py draws it).
//
//   study_accuracy [--scenes linear,static,dynamic,large] [--levels 1,0.5,0.25|none]
//                  [--elements hex8,tet4,tet10] [--models Linear,...] [--quick] [--csv FILE]
//                  [--reference-h H] [--max-dofs N] [--load-steps N]
//   --quick: levels 1 and 0.5 only, every reference at h >= 0.5.
#include <plastifem/plastifem.hpp>

#include "bench_common.hpp"

#include <fmt/core.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <functional>
#include <limits>
#include <map>
#include <optional>
#include <sstream>
#include <string>

#ifdef _OPENMP
#include <omp.h>
#endif

using namespace plastifem;
using plastifem::bench::split;

namespace {

constexpr double NaN = std::numeric_limits<double>::quiet_NaN();
const Vec3 kBarSize(10, 3, 3);
const Vec3 kTip(10, 3, 3);  // the quantity of interest is u_z of the node at this corner
const Material kMaterial{3000, 0.45, 1.0};
constexpr Scalar kGravity = 9.81, kDt = 0.01;
constexpr int kSteps = 200, kWarmup = 5;

// --- cases and results ---------------------------------------------------------------------

/// How a case is solved. Dynamics: CG to `tolerance` with the Newton residual tolerance set to
/// the same value (accurate mode), or one linearised solve per step (real-time mode).
/// Statics: Newton to `tolerance` with the direct solver (CHOLMOD where built in, else Eigen's
/// simplicial LDLT) up to `direct_max_dofs`, above it Jacobi CG to `cg_tolerance`.
struct Variant {
  LinearSolverKind kind = LinearSolverKind::Direct;
  NewmarkMode mode = NewmarkMode::Accurate;
  Scalar tolerance = 1e-6;
  Scalar cg_tolerance = 1e-9;  ///< statics with CG only
  int max_cg = 1000;
  /// Statics: the direct solver up to this size, CG above. On this bar Jacobi CG to 1e-9 beats
  /// a factorisation from 20,000 dofs up (Hex8 at h = 0.25, one core: 0.19 s against 0.57 s
  /// with CHOLMOD for Linear); the references (Newton 1e-8) are faster direct where CHOLMOD is
  /// built in (Tet10 at h = 0.5: 3.4 s against 6.9 s), while Eigen's simplicial LDLT takes
  /// 10+ s per factorisation there.
  Index direct_max_dofs = 10000;

  std::string mode_name(bool dynamic) const {
    return !dynamic ? "static" : mode == NewmarkMode::Accurate ? "accurate" : "realtime";
  }
};

constexpr Index kCostlyDofs = 10000;     ///< meshes above this size run the scene's reduced model/variant lists

struct Case {
  std::string element, model;
  Scalar h = 1;
  Variant variant;
};

struct Result {
  bool ok = true;
  std::string failure;
  std::string solver;  ///< CHOLMOD, LDLT or CG (what was used)
  Scalar cg_tolerance = NaN;
  Index cells = 0, elements = 0, dofs = 0;
  Scalar quantity = NaN;        ///< static: tip u_z; dynamic: tip u_z at t = 2 s
  std::vector<Scalar> history;  ///< dynamic: tip u_z after every step
  double ms_per_step = NaN;     ///< dynamic: median step wall time over steps 6..200
  double total_ms = NaN;        ///< static: the solve; dynamic: all 200 steps
  double newton = NaN, cg = NaN;  ///< per step (dynamic, mean over steps 6..200) or per solve (static)
  int load_steps = 0;
  double peak_kinetic_energy = NaN;  ///< dynamic: max over the 200 steps (an unstable run shows here first)
};

/// A scene: what it runs, on which models and solver variants, against which reference.
struct Scene {
  std::string name, description;
  bool dynamic = false;
  std::vector<std::string> models;         ///< the models it admits (in this order)
  std::vector<std::string> costly_models;  ///< on meshes above kCostlyDofs (h = 0.25; Tet10 at h = 0.5)
  std::vector<std::string> flagged;        ///< admitted, but physically wrong for the scene (marked in the CSV)
  std::vector<Variant> variants, costly_variants;
  Case reference;
  std::function<Result(const Case&)> run;
  std::function<double(const Result&, const Result& ref)> error;
  /// Optional: which (element, model, h) the scene runs at all (default: every one).
  std::function<bool(const std::string& element, const std::string& model, Scalar h)> admits = {};
};

// --- element x model dispatch --------------------------------------------------------------

/// Models per element: the mean-dilatation variants are the Hex8 locking remedy;
/// CorotationalPerElement is Corotational on Tet4 (one quadrature point), so it is not repeated.
bool element_has_model(const std::string& element, const std::string& model) {
  if (model.ends_with("MeanDilatation")) return element == "Hex8";
  if (model == "CorotationalPerElement") return element != "Tet4";
  return true;
}

template <class F>
Result with_types(const std::string& element, const std::string& model, F&& f) {
  auto by_model = [&]<class E>() -> Result {
    if (model == "Linear") return f.template operator()<E, Linear>();
    if (model == "Corotational") return f.template operator()<E, Corotational>();
    if (model == "NeoHookean") return f.template operator()<E, NeoHookean>();
    if (model == "StableNeoHookean") return f.template operator()<E, StableNeoHookean>();
    if constexpr (!std::is_same_v<E, Tet4>)
      if (model == "CorotationalPerElement") return f.template operator()<E, CorotationalPerElement>();
    if constexpr (std::is_same_v<E, Hex8>) {
      if (model == "LinearMeanDilatation") return f.template operator()<E, LinearMeanDilatation>();
      if (model == "CorotationalMeanDilatation") return f.template operator()<E, CorotationalMeanDilatation>();
      if (model == "NeoHookeanMeanDilatation") return f.template operator()<E, NeoHookeanMeanDilatation>();
      if (model == "StableNeoHookeanMeanDilatation") return f.template operator()<E, StableNeoHookeanMeanDilatation>();
    }
    fail<InvalidArgument>("model '{}' is not part of the study for {}", model, E::name);
  };
  if (element == "Hex8") return by_model.template operator()<Hex8>();
  if (element == "Tet4") return by_model.template operator()<Tet4>();
  if (element == "Tet10") return by_model.template operator()<Tet10>();
  fail<InvalidArgument>("unknown element '{}'", element);
}

// --- the bar scenes ------------------------------------------------------------------------

BoxSpec bar_box(Scalar h) {
  return {static_cast<int>(std::lround(kBarSize.x() / h)), static_cast<int>(std::lround(kBarSize.y() / h)),
          static_cast<int>(std::lround(kBarSize.z() / h)), kBarSize};
}

/// Degrees of freedom of the bar at cell size h, without building it.
Index bar_dofs(const std::string& element, Scalar h) {
  const BoxSpec b = bar_box(h);
  const int k = element == "Tet10" ? 2 : 1;
  return 3 * (k * b.nx + 1) * (k * b.ny + 1) * (k * b.nz + 1);
}

struct BarLoad {
  Scalar gravity_scale = 1;
  bool dynamic = false;
  /// Statics: load increments for the hyperelastic models (the corotational ones converge best
  /// in one; the solver halves a failing increment itself, up to 10 times).
  int hyperelastic_load_steps = 1;
};

/// The bar with cells of size h (same outer dimensions), clamped, under gravity; static solve or
/// 200 Newmark steps.
template <class E, class M>
Result run_bar(const Case& c, const BarLoad& load) {
  const BoxSpec box = bar_box(c.h);
  const Mesh<E> mesh = bar_mesh<E>(box);
  const Index dofs = 3 * mesh.num_nodes();
  SolverSettings st;
  st.threads = 1;
  st.newton.residual_tolerance = c.variant.tolerance;
  Result res;
  if (load.dynamic) {
    st.linear = {c.variant.kind, c.variant.tolerance, c.variant.max_cg};
    st.newmark.mode = c.variant.mode;
    res.solver = c.variant.kind == LinearSolverKind::Direct ? direct_solver_name(DirectSolver::Auto) : "CG";
    if (c.variant.kind != LinearSolverKind::Direct) res.cg_tolerance = c.variant.tolerance;
  } else {
    // The static line search (Armijo on the energy, or a decrease of |r|) shortens the first
    // Newton step of each load step, whose linear prediction over-stretches the bent bar
    // (Hex8 Corotational at h = 1, 1 g in one load step: 10 Newton iterations with it, 4
    // without); full Newton steps with the solver's automatic load cutting are faster here.
    st.newton.line_search = false;
    if (c.variant.kind == LinearSolverKind::Direct && dofs <= c.variant.direct_max_dofs) {
      st.static_linear = {LinearSolverKind::Direct};
      res.solver = direct_solver_name(DirectSolver::Auto);
    } else {
      st.static_linear = {LinearSolverKind::ConjugateGradient, c.variant.cg_tolerance, 50000};
      res.solver = "CG";
      res.cg_tolerance = c.variant.cg_tolerance;
    }
  }
  res.cells = box.nx * box.ny * box.nz;
  res.elements = mesh.num_elements();
  Solver<E, M> s(mesh, kMaterial, st);
  res.dofs = s.num_dofs();
  s.fix(mesh.node_set("xmin"));
  s.add_gravity(Vec3(0, 0, -kGravity * load.gravity_scale));
  Index tip = 0;
  for (Index i = 0; i < mesh.num_nodes(); ++i)
    if ((mesh.node(i) - kTip).norm() < (mesh.node(tip) - kTip).norm()) tip = i;
  if ((mesh.node(tip) - kTip).norm() > 1e-9) fail<MeshError>("no node at the tip (10, 3, 3)");
  try {
    if (!load.dynamic) {
      constexpr bool hyperelastic = requires { M::TangentKind::Exact; };
      const StepReport r = s.solve_static(hyperelastic ? load.hyperelastic_load_steps : 1);
      res.quantity = s.displacement(tip).z();
      res.total_ms = r.wall_ms;
      res.newton = r.newton_iterations;
      res.cg = r.linear_iterations;
      res.load_steps = r.load_steps;
    } else {
      std::vector<double> ms;
      double newton = 0, cg = 0, total = 0;
      for (int k = 1; k <= kSteps; ++k) {
        const StepReport r = s.step(kDt);
        total += r.wall_ms;
        res.history.push_back(s.displacement(tip).z());
        res.peak_kinetic_energy = std::max(k == 1 ? 0.0 : res.peak_kinetic_energy, s.kinetic_energy());
        if (k > kWarmup) {
          ms.push_back(r.wall_ms);
          newton += r.newton_iterations;
          cg += r.linear_iterations;
        }
      }
      std::sort(ms.begin(), ms.end());
      res.ms_per_step = ms[ms.size() / 2];
      res.total_ms = total;
      res.newton = newton / static_cast<double>(ms.size());
      res.cg = cg / static_cast<double>(ms.size());
      res.quantity = res.history.back();
    }
  } catch (const SolverError& e) {
    res.ok = false;
    res.failure = e.what();
  }
  return res;
}

std::function<Result(const Case&)> bar_runner(BarLoad load) {
  return [load](const Case& c) {
    return with_types(c.element, c.model, [&]<class E, class M>() { return run_bar<E, M>(c, load); });
  };
}

double relative_error(const Result& r, const Result& ref) {
  return std::abs(r.quantity - ref.quantity) / std::abs(ref.quantity);
}

/// RMS over the history of (q - q_ref), divided by max |q_ref|.
double history_error(const Result& r, const Result& ref) {
  if (r.history.size() != ref.history.size()) return NaN;
  double sum = 0, peak = 0;
  for (size_t k = 0; k < r.history.size(); ++k) {
    sum += (r.history[k] - ref.history[k]) * (r.history[k] - ref.history[k]);
    peak = std::max(peak, std::abs(ref.history[k]));
  }
  return std::sqrt(sum / static_cast<double>(r.history.size())) / peak;
}

constexpr auto CG = LinearSolverKind::ConjugateGradient, LDLT = LinearSolverKind::Direct;
constexpr auto accurate = NewmarkMode::Accurate, realtime = NewmarkMode::RealTime;

/// The scenes, in the order they run. A new scene (plasticity, cutting) is one more entry with
/// its own run function (any callable Case -> Result) and error measure.
std::vector<Scene> scene_table(int load_steps_override) {
  auto steps = [&](int n) { return load_steps_override > 0 ? load_steps_override : n; };
  const std::vector<std::string> all{"Linear",
                                     "LinearMeanDilatation",
                                     "Corotational",
                                     "CorotationalPerElement",
                                     "CorotationalMeanDilatation",
                                     "NeoHookean",
                                     "NeoHookeanMeanDilatation"};
  const std::vector<std::string> costly{"Linear", "LinearMeanDilatation", "Corotational", "CorotationalMeanDilatation",
                                        "NeoHookean", "NeoHookeanMeanDilatation"};
  const std::vector<Variant> direct{{LDLT, accurate, 1e-6, 1e-9}};
  // References: Newton to 1e-8 (CG 1e-10 where CG is used): their own solver error stays three
  // orders below the smallest differences they measure.
  // Direct up to 60k dofs with CHOLMOD: below the 152k-dof linear reference (minutes and
  // gigabytes of fill), above the 20,787-dof Tet10 h = 0.5 ones.
  const Variant ref_static{LDLT, accurate, 1e-8, 1e-10, 50000, cholmod_available() ? Index{60000} : Index{10000}};
  std::vector<Scene> t;
  t.push_back({"linear", "discretisation only: Linear statics under gravity, tip u_z (reference on the finest mesh)",
               false, {"Linear", "LinearMeanDilatation"}, {"Linear", "LinearMeanDilatation"}, {}, direct, direct,
               {"Tet10", "Linear", 0.25, ref_static}, bar_runner({1, false, 1}), relative_error});
  t.push_back({"static", "static bending under gravity, tip u_z at (10,3,3)", false, all, costly, {}, direct, direct,
               {"Tet10", "Corotational", 0.5, ref_static}, bar_runner({1, false, steps(2)}), relative_error});
  t.push_back({"dynamic", "200 Newmark steps from rest under gravity, tip u_z history", true, all,
               {"Linear", "LinearMeanDilatation", "Corotational", "CorotationalMeanDilatation", "NeoHookeanMeanDilatation"},
               {},
               {{CG, accurate, 1e-3}, {CG, accurate, 1e-6}, {CG, accurate, 1e-9}, {CG, realtime, 1e-6}},
               {{CG, accurate, 1e-6}, {CG, realtime, 1e-6}},
               {"Tet10", "Corotational", 0.5, {CG, accurate, 1e-10, 0, 5000}}, bar_runner({1, true, 1}), history_error});
  t.push_back({"large", "static bending under 3 g (large rotations), tip u_z at (10,3,3)", false,
               {"Linear", "Corotational", "CorotationalPerElement", "CorotationalMeanDilatation", "NeoHookean",
                "NeoHookeanMeanDilatation", "StableNeoHookean", "StableNeoHookeanMeanDilatation"},
               {"Linear", "NeoHookean", "NeoHookeanMeanDilatation"}, {"Linear"}, direct, direct,
               {"Tet10", "NeoHookean", 0.5, ref_static}, bar_runner({3, false, steps(8)}), relative_error,
               // Static Newton with the warped tangent R K0 R^T (the per-element models) diverges
               // beyond about 1.2-1.9 g on this bar whatever the load stepping (measured: Hex8 at
               // load fraction 0.63 of 3 g, Tet10 at 0.41); each failure costs 11 load cuts of 50
               // iterations, so those run once, on the cheapest meshes, to show it. Per-point
               // Corotational has the exact tangent and converges (Hex8 h = 1: 32 iterations in 8 steps).
               [](const std::string& element, const std::string& model, Scalar h) {
                 return model == "Corotational" || !model.starts_with("Corotational") || (h >= 1 && element != "Tet10");
               }});
  return t;
}

// --- command line and output ---------------------------------------------------------------

std::string lower(std::string s) {
  for (char& ch : s) ch = static_cast<char>(std::tolower(static_cast<unsigned char>(ch)));
  return s;
}

std::string num(double v, const char* f = "{:.6g}") { return std::isfinite(v) ? fmt::format(fmt::runtime(f), v) : ""; }

std::string describe(const Case& c, const Result& r, bool dynamic) {
  std::string s = fmt::format("{} {} h={:g} {}", c.element, c.model, c.h, r.solver);
  if (r.solver == "CG") s += fmt::format(" {:g}", r.cg_tolerance);
  if (dynamic) s += " " + c.variant.mode_name(true);
  else s += fmt::format(" Newton {:g}", c.variant.tolerance);
  return s;
}

}  // namespace

int main(int argc, char** argv) try {
  std::vector<std::string> scenes_wanted, elements{"hex8", "tet4", "tet10"}, models_wanted;
  std::vector<Scalar> levels{1, 0.5, 0.25};
  std::string csv = "study_accuracy.csv";
  std::optional<Scalar> reference_h;
  bool quick = false, levels_given = false;
  int load_steps = 0;
  Index max_dofs = 30000;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--quick") quick = true;
    else if (i + 1 < argc && a == "--scenes") scenes_wanted = split(argv[++i]);
    else if (i + 1 < argc && a == "--csv") csv = argv[++i];
    else if (i + 1 < argc && a == "--elements") elements = split(lower(argv[++i]));
    else if (i + 1 < argc && a == "--models") models_wanted = split(argv[++i]);
    else if (i + 1 < argc && a == "--load-steps") load_steps = std::stoi(argv[++i]);
    else if (i + 1 < argc && a == "--reference-h") reference_h = std::stod(argv[++i]);
    else if (i + 1 < argc && a == "--max-dofs") max_dofs = std::stoi(argv[++i]);
    else if (i + 1 < argc && a == "--levels") {
      levels.clear();
      for (const auto& l : split(argv[++i]))
        if (l != "none") levels.push_back(std::stod(l));
      levels_given = true;
    } else if (a == "--help" || a == "-h") {
      fmt::print(
          "study_accuracy [--scenes linear,static,dynamic,large] [--levels 1,0.5,0.25|none] [--quick]\n"
          "               [--elements hex8,tet4,tet10] [--models Linear,Corotational,...] [--csv FILE]\n"
          "               [--reference-h H] [--max-dofs N (default 30000)] [--load-steps N]\n"
          "--quick: levels 1 and 0.5, every reference at h >= 0.5. See docs/study.md.\n");
      return 0;
    } else fail<InvalidArgument>("unknown option '{}' (--help lists them)", a);
  }
  if (quick && !levels_given) levels = {1, 0.5};
#ifdef _OPENMP
  omp_set_num_threads(1);
#endif
  const auto t_start = std::chrono::steady_clock::now();
  auto elapsed_s = [&] { return std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count(); };

  std::ofstream out(csv);
  if (!out) fail<IoError>("cannot write {}", csv);
  out << "scene,element,model,h,cells,elements,dofs,solver,mode,tolerance,cg_tolerance,ms_per_step,total_ms,"
         "newton_per_step,cg_per_step,load_steps,quantity,peak_kinetic_energy,error,reference,note\n";
  fmt::print("{:8} {:6} {:30} {:>5} {:>6} {:>9} {:>8} {:>9} {:>10} {:>7} {:>9} {:>10} {:>9}  {}\n", "scene", "elem",
             "model", "h", "dofs", "solver", "mode", "ms/step", "total ms", "Newton", "CG", "quantity", "error",
             "note [elapsed]");

  auto emit = [&](const Scene& sc, const Case& c, const Result& r, double err, const std::string& ref,
                  std::string note) {
    if (!r.ok) note = note.empty() ? "failed: " + r.failure : note + "; failed: " + r.failure;
    std::string csv_note = note;
    for (char& ch : csv_note)
      if (ch == ',' || ch == '\n' || ch == '"') ch = ch == '"' ? '\'' : ' ';
    const std::string solver = r.solver + (r.solver == "CG" ? fmt::format(" {:g}", r.cg_tolerance) : "");
    out << fmt::format("{},{},{},{:g},{},{},{},{},{},{:g},{},{},{},{},{},{},{},{},{},{},{}\n", sc.name, c.element,
                       c.model, c.h, r.cells, r.elements, r.dofs, r.solver, c.variant.mode_name(sc.dynamic),
                       c.variant.tolerance, num(r.cg_tolerance, "{:g}"), num(r.ms_per_step), num(r.total_ms),
                       num(r.newton, "{:.3f}"), num(r.cg, "{:.2f}"), r.load_steps, num(r.quantity, "{:.9g}"),
                       num(r.peak_kinetic_energy, "{:.6g}"), num(err, "{:.4e}"), ref, csv_note);
    out.flush();
    fmt::print("{:8} {:6} {:30} {:>5g} {:>6} {:>9} {:>8} {:>9} {:>10} {:>7} {:>9} {:>10} {:>9}  {}[{:.0f} s]\n", sc.name,
               c.element, c.model, c.h, r.dofs, solver, c.variant.mode_name(sc.dynamic), num(r.ms_per_step, "{:.3f}"),
               num(r.total_ms, "{:.1f}"), num(r.newton, "{:.2f}"), num(r.cg, "{:.1f}"), num(r.quantity, "{:.5f}"),
               num(err, "{:.2e}"), note.empty() ? "" : note.substr(0, 70) + " ", elapsed_s());
    std::fflush(stdout);
  };

  auto wanted = [](const std::vector<std::string>& list, const std::string& v) {
    return list.empty() || std::find(list.begin(), list.end(), v) != list.end();
  };

  for (const Scene& sc : scene_table(load_steps)) {
    if (!wanted(scenes_wanted, sc.name)) continue;
    fmt::print("# scene {}: {}\n", sc.name, sc.description);
    Case ref_case = sc.reference;
    if (quick) ref_case.h = std::max<Scalar>(ref_case.h, 0.5);
    if (reference_h) ref_case.h = *reference_h;
    fmt::print("# reference: {} {} at h = {:g} ...\n", ref_case.element, ref_case.model, ref_case.h);
    std::fflush(stdout);
    const Result ref = sc.run(ref_case);
    const std::string ref_label = describe(ref_case, ref, sc.dynamic);
    if (!ref.ok) fail<SolverError>("reference {} failed: {}", ref_label, ref.failure);
    emit(sc, ref_case, ref, 0.0, ref_label, "reference");

    for (Scalar h : levels)
      for (const std::string element : {"Hex8", "Tet4", "Tet10"}) {
        if (!wanted(elements, lower(element))) continue;
        const Index dofs = bar_dofs(element, h);
        if (dofs > max_dofs) continue;  // Tet10 at h = 0.25 (152k dofs): only ever a reference
        const bool costly = dofs > kCostlyDofs;
        for (const std::string& model : costly ? sc.costly_models : sc.models) {
          if (!element_has_model(element, model) || !wanted(models_wanted, model)) continue;
          if (sc.admits && !sc.admits(element, model, h)) continue;
          const bool is_linear = model.starts_with("Linear");
          for (const Variant& v : costly ? sc.costly_variants : sc.variants) {
            // Real-time and accurate coincide for a linear model (one exact solve per step).
            if (is_linear && sc.dynamic && v.mode == realtime) continue;
            const Case c{element, model, h, v};
            // The reference row is already written (at its tighter tolerance).
            if (!sc.dynamic && c.element == ref_case.element && c.model == ref_case.model && c.h == ref_case.h)
              continue;
            const Result r = sc.run(c);
            std::string note;
            if (std::find(sc.flagged.begin(), sc.flagged.end(), model) != sc.flagged.end())
              note = "wrong kinematics for this scene (small strain)";
            // Newmark (beta 1/4, gamma 1/2) conserves energy: a run whose kinetic energy peaks at
            // 5 times the reference's has gained energy (gone unstable), whatever its error says
            // (a softer model or mesh legitimately reaches up to about 1.5 times).
            if (r.ok && r.peak_kinetic_energy > 5 * ref.peak_kinetic_energy)
              note = fmt::format("unstable: peak kinetic energy {:.3g} x the reference's",
                                 r.peak_kinetic_energy / ref.peak_kinetic_energy);
            emit(sc, c, r, r.ok ? sc.error(r, ref) : NaN, ref_label, note);
          }
        }
      }
  }
  fmt::print("CSV written to {} ({:.0f} s)\n", csv, elapsed_s());
  return 0;
} catch (const std::exception& e) {
  fmt::print(stderr, "study_accuracy: {}\n", e.what());
  return 1;
}
