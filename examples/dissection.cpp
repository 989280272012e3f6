// Dissection of a beam (seed 001, Fig. 4; SCENES.md "Cut beam"): the cut beam clamped at z = 0
// under gravity along +x bends; at t = 0.2 s a complete cut through all of it at z = 0.1 is
// applied, mid-run, and the upper part falls away, turning as it goes. With the corotational
// model it stays intact for thousands of steps (its volume and strain energy stay put); with
// the linear model its rotation produces ghost forces that inflate it (the thesis: "disturbing
// ghost forces would blow up the dissected parts").
//
//   dissection [--model corotational|linear|both] [--steps N] [--dt DT] [--element hex8|tet4] [--every K] [--out DIR]
//
// Writes DIR/dissection_<model>.pvd: the body with the cut opened (enrichment/output.hpp), and
// prints the falling part's volume ratio, strain energy and centre-of-mass drop as it goes.
#include <plastifem/enrichment/output.hpp>
#include <plastifem/mesh/io/io.hpp>
#include <plastifem/cutting.hpp>
#include <plastifem/plastifem.hpp>

#include <fmt/core.h>

#include <filesystem>
#include <string>

using namespace plastifem;

namespace {

struct Options {
  std::string model = "both", element = "hex8", out = "out";
  int steps = 2000, every = 50;
  Scalar dt = 0.002;
};

template <FiniteElement E, class Model>
void run(const Options& o) {
  const Mesh<E> mesh = bar_mesh<E>(BoxSpec{2, 4, 13, Vec3(0.03, 0.06, 0.2)});
  SolverSettings st;
  st.rayleigh_mass = 0.5;  // a little air
  Solver<E, Model, NoPlasticity, ShiftedHeaviside> s(mesh, Material{3e5, 0.35, 1070}, st);
  s.fix(mesh.node_set("zmin"));
  s.add_gravity(Vec3(9.81, 0, 0));
  const std::string name = fmt::format("dissection_{}_{}", Model::name, E::name);
  io::PvdWriter pvd(o.out, name);
  auto write = [&] {
    pvd.write_frame(s.time(), [&](const auto& file) { io::write_cut_vtu(file, mesh, s.enrichment(), s.displacement()); });
  };

  // The falling part's volume and strain energy: its pieces and whole elements above z = 0.1.
  auto falling = [&](Scalar& volume, Scalar& energy) {
    volume = energy = 0;
    const Vector& u = s.displacement();
    for (Index e = 0; e < mesh.num_elements(); ++e) {
      ElementNodes<E> x;
      for (int a = 0; a < E::num_nodes; ++a) x.col(a) = mesh.node(mesh.element(e)[a]) + u.template segment<3>(3 * mesh.element(e)[a]);
      if (const CutElement<E>* c = s.enrichment().element(e)) {
        if (c->num_sides != 2) continue;
        const ElementNodes<E> y = c->side_nodes(x, u, 0);
        for (int q = 0; q < c->stiffness[0].size(); ++q) volume += c->stiffness[0].dv[q] * (y * c->stiffness[0].G[q]).determinant();
        continue;
      }
      if (mesh.element_nodes(e).row(2).mean() > 0.1) volume += element_volume<E>(x);
    }
    energy = s.strain_energy();
  };
  fmt::print("{} {}: {} elements, cut at t = 0.2 s, {} steps of {} s\n", E::name, Model::name, mesh.num_elements(), o.steps, o.dt);
  write();
  Scalar V0 = 0, W0 = 0;
  for (int k = 1; k <= o.steps; ++k) {
    if (std::abs(s.time() - 0.2) < 0.5 * o.dt) {
      s.cut(CutPlane(Vec3(0, 0, 0.1), Vec3(0, 0, 1)));
      falling(V0, W0);
      fmt::print("  t = {:.3f} s: cut ({} elements, {} enriched nodes, {:.2f} ms); the falling part: volume {:.6e}\n",
                 s.time(), s.last_cut_report().cut_elements, s.last_cut_report().enriched_nodes, s.last_cut_report().ms, V0);
    }
    const StepReport r = s.step(o.dt);
    if (k % o.every == 0) write();
    if (k % (o.steps / 10) == 0 && V0 > 0) {
      Scalar V, W;
      falling(V, W);
      fmt::print("  t = {:6.3f} s  falling part: volume ratio {:.6f}, strain energy {:.4e} J, top drop {:8.3f} m, Newton {}, "
                 "{:.2f} ms\n",
                 s.time(), V / V0, W, s.displacement()(3 * (mesh.num_nodes() - 1)), r.newton_iterations, r.wall_ms);
    }
  }
}

template <FiniteElement E>
void run_models(const Options& o) {
  if (o.model == "both" || o.model == "corotational") run<E, Corotational>(o);
  if (o.model == "both" || o.model == "linear") run<E, Linear>(o);
}

}  // namespace

int main(int argc, char** argv) try {
  Options o;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= argc) fail<InvalidArgument>("option {} needs a value", a);
      return argv[++i];
    };
    if (a == "--model") o.model = value();
    else if (a == "--element") o.element = value();
    else if (a == "--steps") o.steps = std::max(10, std::stoi(value()));
    else if (a == "--dt") o.dt = std::stod(value());
    else if (a == "--every") o.every = std::max(1, std::stoi(value()));
    else if (a == "--out") o.out = value();
    else {
      fmt::print("usage: dissection [--model corotational|linear|both] [--steps N] [--dt DT] [--element hex8|tet4] "
                 "[--every K] [--out DIR]\n");
      return a == "--help" || a == "-h" ? 0 : 2;
    }
  }
  std::filesystem::create_directories(o.out);
  if (o.element == "hex8") run_models<Hex8>(o);
  else if (o.element == "tet4") run_models<Tet4>(o);
  else fail<InvalidArgument>("unknown element '{}'", o.element);
  return 0;
} catch (const std::exception& e) {
  fmt::print(stderr, "dissection: {}\n", e.what());
  return 1;
}
