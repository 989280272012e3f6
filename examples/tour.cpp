// The README's short tour, as a program: a bar720 cantilever under gravity, grasped at the
// centre of its free end, pulled up over 1 s, held, and released at t = 2 s. Writes
// out/run.pvd for ParaView.
#include <plastifem/plastifem.hpp>
#include <plastifem/mesh/io/io.hpp>

#include <fmt/core.h>

#include <algorithm>

int main() try {
  using namespace plastifem;
  // --- as in the README ---
  auto mesh = bar_mesh<Hex8>(20, 6, 6);                 // bar720 (docs/scenes.md); or io::read_gmsh<Tet10>("organ.msh")
  Solver<Hex8, Corotational> solver(mesh, Material{3000, 0.45, 1.0});   // E, nu, density (validated)
  solver.fix(mesh.node_set("xmin"));                   // clamp x = 0
  solver.add_gravity(Vec3(0, 0, -9.81));               // nodal loads paired with the mass matrix
  auto grasped_nodes = select_nodes_in_box(mesh, Vec3(20, 2, 2), Vec3(20, 4, 4));   // the free end's centre
  ConstraintHandle grasp = solver.grasp(grasped_nodes,  // a grasper attaches where the nodes are and
      [](Scalar t) { return Vec3(0, 0, 0.5 * std::min(t, 1.0)); });   // pulls them 0.5 up over 1 s

  io::PvdWriter pvd("out", "run", {io::Encoding::appended_raw, "displacement"});
  for (int k = 0; k < 300; ++k) {
    if (k == 200) solver.release(grasp);               // lets go at t = 2 s: the nodes move on freely
    StepReport r = solver.step(0.01);                  // throws SolverError and keeps the state if it fails
    fmt::print("t={} Newton={} CG={} {:.2f} ms\n", solver.time(), r.newton_iterations, r.linear_iterations, r.wall_ms);
    pvd.write(solver.time(), mesh, {io::Field("displacement",
              Eigen::Map<const Eigen::Matrix3Xd>(solver.displacement().data(), 3, mesh.num_nodes()))});
  }
  return 0;
} catch (const std::exception& e) {
  fmt::print(stderr, "tour: {}\n", e.what());
  return 1;
}
