// A downstream program built against the installed package: it includes the toolkit, links
// what the exported target brings (CHOLMOD too, where the package was built with it) and runs
// a static solve through the default direct back-end.
#include <plastifem/plastifem.hpp>

#include <fmt/core.h>

int main() {
  using namespace plastifem;
#if defined(PLASTIFEM_EXPECT_OPENMP) && !defined(_OPENMP)
  fmt::print("consumer: the package was built with OpenMP but the exported target did not carry it\n");
  return 1;
#endif
  const auto mesh = bar_mesh<Hex8>(10, 3, 3);
  Solver<Hex8, Linear> solver(mesh, Material{3000, 0.45, 1.0});
  solver.fix(mesh.node_set("xmin"));
  solver.add_gravity(Vec3(0, 0, -9.81));
  const StepReport r = solver.solve_static();
  fmt::print("consumer: bar90 has {} nodes and {} elements; static solve with {} (|r| = {:.2e}), tip z {:.4f}\n",
             mesh.num_nodes(), mesh.num_elements(), direct_solver_name(DirectSolver::Auto), r.relative_residual,
             solver.displacement().minCoeff());
  return (mesh.num_nodes() == 176 && mesh.num_elements() == 90 && r.relative_residual < 1e-10) ? 0 : 1;
}
