// Unstructured organ meshes for the scaling table (issue 36, docs/performance.md): the library's
// liver-like surface (liver_surface), meshed with Tet4 by Gmsh (Debian's `gmsh` package), so
// that every element differs and no per-element data is shared as on the structured bars.
//
// For each subdivision level k (the surface: the icosphere of level k mapped to the liver, 20 x 4^k
// triangles) the liver is scaled to 1.25 x 2^k units long, so its surface triangles keep the
// same size from level to level, about the bars' unit cell: each level has about 8 times the
// elements of the one before, as each bar scene has. Gmsh meshes the inside with its HXT Delaunay mesher,
// tetrahedra no larger than 1 (Mesh.CharacteristicLengthMax), keeping the surface's triangles.
// The meshes are unit-free like the bars and read by bench_step --msh with the bars' material,
// gravity and time step, clamped at their left end.
//
//   organ_mesh [--levels 3,4,5] [--out DIR]      (writes DIR/liver<k>.stl, .geo and .msh)
//
// Prints each mesh's nodes, elements and spread of element volumes.
#include <plastifem/mesh/io/io.hpp>
#include <plastifem/plastifem.hpp>

#include "bench_common.hpp"

#include <fmt/core.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

using namespace plastifem;

namespace {

/// ASCII STL of a closed, outward triangle surface (what Gmsh merges as a discrete surface).
void write_stl(const std::filesystem::path& path, const TriangleSurface& s) {
  std::ofstream out(path);
  if (!out) fail<IoError>("{}: cannot write", path.string());
  out << "solid liver\n";
  for (const auto& t : s.triangles) {
    const Vec3 a = s.vertices.col(t[0]), b = s.vertices.col(t[1]), c = s.vertices.col(t[2]);
    const Vec3 n = (b - a).cross(c - a).normalized();
    out << fmt::format("facet normal {:.17g} {:.17g} {:.17g}\n outer loop\n", n.x(), n.y(), n.z());
    for (const Vec3& p : {a, b, c}) out << fmt::format("  vertex {:.17g} {:.17g} {:.17g}\n", p.x(), p.y(), p.z());
    out << " endloop\nendfacet\n";
  }
  out << "endsolid liver\n";
}

}  // namespace

int main(int argc, char** argv) try {
  std::vector<int> levels{3, 4, 5};
  std::filesystem::path dir = "organ_meshes";
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (i + 1 < argc && a == "--levels") levels = plastifem::bench::split_ints(argv[++i]);
    else if (i + 1 < argc && a == "--out") dir = argv[++i];
    else fail<InvalidArgument>("unknown option '{}' (organ_mesh [--levels 3,4,5] [--out DIR])", a);
  }
  std::filesystem::create_directories(dir);
  if (std::system("gmsh --version > /dev/null 2>&1") != 0)
    fail<Error>("gmsh is not installed (Debian: apt-get install gmsh)");
  fmt::print("{:>5} {:>9} {:>9} {:>10} {:>14}\n", "level", "nodes", "elements", "length", "volume max/min");
  for (int k : levels) {
    if (k < 1 || k > 7) fail<InvalidArgument>("--levels: 1 to 7, got {}", k);
    const std::string name = fmt::format("liver{}", k);
    // liver_surface(size): 2 size long; 1.25 x 2^k long keeps the triangles at the same size.
    const Scalar size = 0.625 * static_cast<Scalar>(1 << k);
    const TriangleSurface liver = liver_surface(Vec3::Zero(), size, k);
    write_stl(dir / (name + ".stl"), liver);
    std::ofstream(dir / (name + ".geo")) << fmt::format(
        "Merge \"{0}.stl\";\nSurface Loop(1) = {{1}};\nVolume(1) = {{1}};\nPhysical Volume(\"organ\") = {{1}};\n"
        "Mesh.CharacteristicLengthMax = 1;\nMesh.Algorithm3D = 10;\n",
        name);
    const std::string command = fmt::format("cd '{}' && gmsh -3 -nt 2 -format msh41 -o {}.msh {}.geo > {}.log 2>&1",
                                            dir.string(), name, name, name);
    if (std::system(command.c_str()) != 0) fail<Error>("gmsh failed: see {}", (dir / (name + ".log")).string());
    const Mesh<Tet4> mesh = io::read_gmsh<Tet4>(dir / (name + ".msh"), {.drop_unused_nodes = true});
    Scalar vmin = 1e300, vmax = 0;
    for (Index e = 0; e < mesh.num_elements(); ++e) {
      const Scalar v = element_volume<Tet4>(mesh.element_nodes(e));  // the reader refuses inverted ones
      vmin = std::min(vmin, v), vmax = std::max(vmax, v);
    }
    fmt::print("{:>5} {:>9} {:>9} {:>10.1f} {:>14.1f}\n", k, mesh.num_nodes(), mesh.num_elements(), 2 * size, vmax / vmin);
    std::fflush(stdout);
  }
  fmt::print("meshes written to {}\n", dir.string());
  return 0;
} catch (const std::exception& e) {
  fmt::print(stderr, "organ_mesh: {}\n", e.what());
  return 1;
}
