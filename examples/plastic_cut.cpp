// Cutting plastic tissue: plasticity (seed 000) and X-FEM cutting (seed 001) in one Solver.
// The plastic stretch scene (SCENES.md: bar90, 10 x 3 x 3, clamped at x = 0, a force of 350
// along +x on the end face ramped over 1 s, held to 2 s, released, relaxed with mass damping 1;
// the corotational parameter set 1 of examples/plastic_stretch.cpp) is cut through at x = 5.5
// at t = 4 s with gravity switched on: the free half falls and keeps the length the flow gave
// it (its material shape), while the clamped half stays stretched.
//
//   plastic_cut [--policy vertex|cell] [--steps N] [--every K] [--out DIR]
//
// Hex8 (the tests run Tet4 and Tet10, tests/test_plastic_cut.cpp). Writes
// DIR/plastic_cut_<policy>_Hex8.pvd (the body with the cut opened,
// enrichment/output.hpp) and prints the residual elongation before the cut, then the free
// half's drop, its volume against its rest (material) volume, and its length as it falls: the
// distance between the nodes (6, 0, 0) and (10, 0, 0), 4 in the mesh, in the world and in the
// material mesh.
#include <plastifem/enrichment/output.hpp>
#include <plastifem/mesh/io/pvd.hpp>
#include <plastifem/cutting.hpp>
#include <plastifem/plasticity.hpp>
#include <plastifem/plastifem.hpp>

#include <fmt/core.h>

#include <filesystem>
#include <string>

using namespace plastifem;

namespace {

struct Options {
  std::string policy = "vertex", out = "out";
  int steps = 550, every = 10;  // of 0.01 s: the cut at step 400
};

template <FiniteElement E, class Policy>
void run(const Options& o) {
  const Mesh<E> mesh = bar_mesh<E>(10, 3, 3);
  SolverSettings st;
  st.rayleigh_mass = 1.0;  // as the plastic stretch scene's relaxation
  PlasticParams prm;
  prm.yield_stress = 1000;
  prm.flow_rate = 0.4;
  prm.stress_scale = 50;  // the stretch scene's scaling (docs/plasticity.md)
  prm.hardening = 0.2;
  Solver<E, Corotational, Policy, ShiftedHeaviside> s(mesh, Material{3000, 0.45, 1.0}, st, prm);
  s.fix(mesh.node_set("xmin"));
  s.add_traction(mesh.face_set("xmax"), Vec3(350.0 / 9, 0, 0), ramp_hold_release(1.0, 2.0));
  const std::string name = fmt::format("plastic_cut_{}_{}", Policy::name, E::name);
  io::PvdWriter pvd(o.out, name);
  auto write = [&] {
    pvd.write_frame(s.time(), [&](const auto& file) { io::write_cut_vtu(file, mesh, s.enrichment(), s.displacement()); });
  };

  const Scalar xc = 5.5;
  // The free half's deformed volume and rest volume: its pieces (side 0, x > xc), over their
  // stiffness points (mapped with the rest shapes), and its whole elements, at their current
  // and material-mesh nodes.
  auto free_half = [&](Scalar& volume, Scalar& rest) {
    volume = rest = 0;
    const Vector& u = s.displacement();
    const Eigen::Matrix3Xd material = s.material_positions();
    for (Index e = 0; e < mesh.num_elements(); ++e) {
      ElementNodes<E> x;
      for (int a = 0; a < E::num_nodes; ++a) x.col(a) = mesh.node(mesh.element(e)[a]) + u.template segment<3>(3 * mesh.element(e)[a]);
      if (const CutElement<E>* c = s.enrichment().element(e); c && c->num_sides == 2) {
        const ElementNodes<E> y = c->side_nodes(x, u, 0);
        for (int q = 0; q < c->stiffness[0].size(); ++q) {
          volume += c->stiffness[0].dv[q] * (y * c->stiffness[0].G[q]).determinant();
          rest += c->stiffness[0].dv[q];
        }
        continue;
      }
      if (mesh.element_nodes(e).row(0).mean() < xc) continue;
      ElementNodes<E> X;
      for (int a = 0; a < E::num_nodes; ++a) X.col(a) = material.col(mesh.element(e)[a]);
      volume += element_volume<E>(x), rest += element_volume<E>(X);
    }
  };
  // The end face's mean displacement along x and z (the tip).
  const std::vector<Index> tip = mesh.node_set("xmax");
  auto tip_at = [&](int d) {
    Scalar z = 0;
    for (Index i : tip) z += s.displacement()(3 * i + d);
    return z / static_cast<Scalar>(tip.size());
  };
  // The free half's length: from node (6, 0, 0) to node (10, 0, 0) at positions p.
  const Index n6 = select_nodes(mesh, [](const Vec3& q) { return (q - Vec3(6, 0, 0)).norm() < 1e-9; }).at(0);
  const Index n10 = select_nodes(mesh, [](const Vec3& q) { return (q - Vec3(10, 0, 0)).norm() < 1e-9; }).at(0);
  auto length = [&](const Eigen::Matrix3Xd& p) { return (p.col(n10) - p.col(n6)).norm(); };
  auto world = [&] { return Eigen::Matrix3Xd(mesh.nodes() + s.nodal_displacements()); };
  fmt::print("{} {} + {}: {} elements; stretched to 1 s, held to 2 s, released; cut at x = {} at t = 4 s, then gravity\n",
             E::name, Corotational::name, Policy::name, mesh.num_elements(), xc);
  write();
  Scalar z_cut = 0;
  for (int k = 1; k <= o.steps; ++k) {
    if (k == 401) {
      z_cut = tip_at(2);
      Scalar rest_tip = 0;
      for (Index i : tip) rest_tip += (s.material_positions()(0, i) - mesh.node(i).x()) / static_cast<Scalar>(tip.size());
      s.cut(CutPlane(Vec3(xc, 0, 0), Vec3(1, 0, 0)));
      s.add_gravity(Vec3(0, 0, -9.81));
      const CutReport& c = s.last_cut_report();
      fmt::print("  t = {:.2f} s: tip {:.4f} beyond the mesh (the material mesh's {:.4f}); free half's length {:.4f} "
                 "(material {:.4f}, mesh 4); cut: {} elements, {} enriched nodes, {} elements stop flowing, {:.2f} ms\n",
                 s.time(), tip_at(0), rest_tip, length(world()), length(s.material_positions()), c.cut_elements,
                 c.enriched_nodes, c.plastic_frozen, c.ms);
    }
    const StepReport r = s.step(0.01);
    if (k % o.every == 0) write();
    if (k % 25 == 0) {
      if (k <= 400) {
        fmt::print("  t = {:5.2f} s  tip {:8.4f}  flow points {:4d}  Newton {}  {:.2f} ms\n", s.time(), tip_at(0),
                   r.plastic.points_yielded, r.newton_iterations, r.wall_ms);
      } else {
        Scalar V, V0;
        free_half(V, V0);
        fmt::print("  t = {:5.2f} s  free half: dropped {:6.3f}, volume / rest volume {:.6f}, length {:.4f} (material "
                   "{:.4f})  Newton {}  {:.2f} ms\n",
                   s.time(), -(tip_at(2) - z_cut), V / V0, length(world()), length(s.material_positions()),
                   r.newton_iterations, r.wall_ms);
      }
    }
  }
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
    if (a == "--policy") o.policy = value();
    else if (a == "--steps") o.steps = std::max(410, std::stoi(value()));
    else if (a == "--every") o.every = std::max(1, std::stoi(value()));
    else if (a == "--out") o.out = value();
    else {
      fmt::print("usage: plastic_cut [--policy vertex|cell] [--steps N] [--every K] [--out DIR]\n");
      return a == "--help" || a == "-h" ? 0 : 2;
    }
  }
  std::filesystem::create_directories(o.out);
  if (o.policy == "vertex") run<Hex8, VertexBlended>(o);
  else if (o.policy == "cell") run<Hex8, CellCentered>(o);
  else fail<InvalidArgument>("unknown policy '{}' (vertex or cell)", o.policy);
  return 0;
} catch (const std::exception& e) {
  fmt::print(stderr, "plastic_cut: {}\n", e.what());
  return 1;
}
