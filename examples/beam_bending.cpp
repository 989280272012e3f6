// Static bending of the bar scene (10 x 3 x 3, clamped at x = 0, gravity along -z) compared
// with Timoshenko beam theory, for each element under mesh refinement, printed as a table.
//
// Beam theory for a cantilever of length L under a uniform load q = rho g A per length:
//   delta = q L^4 / (8 E I) + q L^2 / (2 kappa G A),   I = b h^3 / 12, kappa = 5/6.
// With nu = 0 the 3D clamp adds no Poisson constraint and the solid converges to within a
// fraction of a percent of this value; with nu = 0.45 the clamp stiffens the root (the section
// cannot contract there), so the 3D answer is a few percent below beam theory.
//
//   beam_bending [--nu 0|0.45] [--model linear|corotational] [--levels N]
#include <plastifem/plastifem.hpp>

#include <fmt/core.h>

#include <string>

using namespace plastifem;

namespace {

template <class E, class Model>
void study(Scalar nu, int levels, Scalar exact) {
  Scalar previous = 0;
  for (int r = 1; r <= levels; ++r) {
    const auto mesh = bar_mesh<E>(BoxSpec{10 * r, 3 * r, 3 * r, Vec3(10, 3, 3)});
    Solver<E, Model> s(mesh, Material{3000, nu, 1.0});
    s.fix(mesh.node_set("xmin"));
    s.add_gravity(Vec3(0, 0, -9.81));
    const StepReport rep = s.solve_static(Model::constant_tangent ? 1 : 4);
    // Deflection of the axis at the free end: mean uz over the end face's nodes.
    Scalar uz = 0;
    for (Index i : mesh.node_set("xmax")) uz += s.displacement(i).z();
    uz /= static_cast<Scalar>(mesh.node_set("xmax").size());
    fmt::print("{:6} {:13} {:>9} {:8} {:12.6f} {:+9.3f}% {:>12} {:9.1f}\n", E::name, Model::name,
               fmt::format("{}x{}x{}", 10 * r, 3 * r, 3 * r), s.num_dofs(), -uz, 100 * (-uz / exact - 1),
               r > 1 ? fmt::format("{:+.3e}", -uz - previous) : std::string("-"), rep.wall_ms);
    previous = -uz;
  }
}

}  // namespace

int main(int argc, char** argv) try {
  Scalar nu = 0;
  int levels = 3;
  std::string model = "linear";
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string a = argv[i];
    if (a == "--nu") nu = std::stod(argv[i + 1]);
    else if (a == "--levels") levels = std::stoi(argv[i + 1]);
    else if (a == "--model") model = argv[i + 1];
    else fail<InvalidArgument>("unknown option '{}'", a);
  }
  const Scalar L = 10, b = 3, h = 3, E = 3000, rho = 1, g = 9.81;
  const Scalar A = b * h, I = b * h * h * h / 12, G = E / (2 * (1 + nu)), q = rho * g * A, kappa = 5.0 / 6.0;
  const Scalar bending = q * L * L * L * L / (8 * E * I), shear = q * L * L / (2 * kappa * G * A);
  fmt::print("Cantilever 10 x 3 x 3 under gravity, E = {}, nu = {}: Timoshenko tip deflection {:.6f} "
             "(bending {:.6f} + shear {:.6f})\n\n",
             E, nu, bending + shear, bending, shear);
  fmt::print("{:6} {:13} {:>9} {:>8} {:>12} {:>10} {:>12} {:>9}\n", "elem", "model", "cells", "dofs", "tip defl.",
             "vs beam", "change", "ms");
  auto run = [&]<class M>() {
    study<Hex8, M>(nu, levels, bending + shear);
    study<Tet4, M>(nu, levels, bending + shear);
    study<Tet10, M>(nu, std::max(1, levels - 1), bending + shear);
    study<Wedge6, M>(nu, levels, bending + shear);
  };
  if (model == "linear") run.operator()<Linear>();
  else run.operator()<Corotational>();
  return 0;
} catch (const std::exception& e) {
  fmt::print(stderr, "beam_bending: {}\n", e.what());
  return 1;
}
