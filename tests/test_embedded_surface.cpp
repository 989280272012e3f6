// Triangle surfaces and surfaces embedded in a volume mesh (embedding/, mesh/io/surface.hpp).
//
// Facts checked:
//  - the icosphere is closed and faces out; its enclosed volume approaches 4/3 pi r^3 at the
//    rate of the inscribed polyhedron (error / 4 per subdivision); the liver-like surface is
//    closed and its volume approaches the integral of its map's Jacobian at the same rate;
//  - an affine displacement u = A X + b of the volume mesh moves an embedded surface exactly
//    (isoparametric elements reproduce it) and scales its enclosed volume by det(I + A); the
//    normals of the moved surface are those of the rest surface mapped by the cofactor of I + A;
//  - in dynamics the surface stays closed, finite, and its vertices at nodes follow the nodes;
//  - OBJ written and read back gives the same surface bit for bit; STL, binary and ASCII, merges
//    the facets' corners into a closed cube of volume 1; malformed files are refused with
//    file:line (or the facet) and the reason.
#include "catch.hpp"
#include "compositions.hpp"

#include <plastifem/embedding/embedded_surface.hpp>
#include <plastifem/mesh/io/io.hpp>
#include <plastifem/plastifem.hpp>

#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <numbers>

using namespace plastifem;
using namespace plastifem::testing;

namespace {

std::filesystem::path out_dir() {
  const std::filesystem::path d = std::filesystem::path(PLASTIFEM_TEST_OUT) / "embedded_surface";
  std::filesystem::create_directories(d);
  return d;
}

/// Gauss-Legendre nodes and weights on [-1, 1] (Newton on P_n from Chebyshev guesses).
std::vector<std::pair<Scalar, Scalar>> gauss_legendre(int n) {
  std::vector<std::pair<Scalar, Scalar>> r;
  for (int i = 1; i <= n; ++i) {
    Scalar x = std::cos(std::numbers::pi * (i - 0.25) / (n + 0.5)), dp = 1;
    for (int it = 0; it < 100; ++it) {
      Scalar p0 = 1, p1 = x;
      for (int k = 2; k <= n; ++k) {
        const Scalar p2 = ((2 * k - 1) * x * p1 - (k - 1) * p0) / k;
        p0 = p1, p1 = p2;
      }
      dp = n * (x * p1 - p0) / (x * x - 1);
      const Scalar dx = p1 / dp;
      x -= dx;
      if (std::abs(dx) < 1e-16) break;
    }
    r.emplace_back(x, 2 / ((1 - x * x) * dp * dp));
  }
  return r;
}

void write_text(const std::filesystem::path& p, const std::string& text) { std::ofstream(p) << text; }

/// The message of the IoError that reading `p` throws ("" if none).
std::string read_error(const std::filesystem::path& p) {
  try {
    io::read_surface(p);
  } catch (const IoError& e) {
    return e.what();
  }
  return "";
}

}  // namespace

TEST_CASE("sphere surface: closed, facing out, its volume converges at the polyhedron's rate", "[surface]") {
  const Scalar r = 1.5, exact = 4.0 / 3.0 * std::numbers::pi * r * r * r;
  Scalar previous = 0;
  for (int k = 0; k <= 4; ++k) {
    const TriangleSurface s = sphere_surface(Vec3(2, 2, 2), r, k);
    CHECK(s.num_triangles() == 20 * (1 << (2 * k)));
    CHECK(s.num_vertices() == 10 * (1 << (2 * k)) + 2);
    CHECK(surface_edges(s).closed());
    const Scalar error = exact - enclosed_volume(s, s.vertices);
    INFO("subdivisions " << k << ": volume error " << error);
    CHECK(error > 0);  // inscribed
    // The error of an inscribed polyhedron falls as h^2: by 4 per subdivision (3.5-4 measured
    // from the icosahedron's irregular first levels on).
    if (k >= 2) CHECK(previous / error > 3.5);
    previous = error;
  }
  CHECK_THROWS_AS(sphere_surface(Vec3::Zero(), -1, 2), InvalidArgument);
}

TEST_CASE("liver surface: closed, facing out, its volume converges to the map's integral", "[surface]") {
  // The volume inside size * liver_map(unit ball) is size^3 times the integral over the ball of
  // det Df = 0.6 (0.7 + 0.3 u) (0.18 + 0.32 u^2) g'(z); integrated in z in closed form (g(s) -
  // g(-s), s = sqrt(1 - x^2 - y^2)) and in x = sin a, y = cos a sin b by Gauss-Legendre (a
  // smooth integrand: 1e-12 with 48 x 48 points).
  auto g = [](Scalar z) { return z * (0.775 + 0.225 * std::tanh(3 * z)); };
  const auto rule = gauss_legendre(48);
  Scalar exact = 0;
  for (size_t i = 0; i < rule.size(); ++i)
    for (size_t j = 0; j < rule.size(); ++j) {
      const Scalar a = std::numbers::pi / 2 * rule[i].first, b = std::numbers::pi / 2 * rule[j].first;
      const Scalar x = std::sin(a), s = std::cos(a) * std::cos(b), u = (1 + x) / 2;  // det Df has no y
      const Scalar w = 0.6 * (0.7 + 0.3 * u) * (0.18 + 0.32 * u * u) * (g(s) - g(-s));
      exact += rule[i].second * rule[j].second * (std::numbers::pi / 2) * (std::numbers::pi / 2) * w * std::cos(a) *
               std::cos(a) * std::cos(b);
    }
  const Scalar size = 2.5;
  exact *= size * size * size;
  Scalar previous = 0;
  for (int k = 2; k <= 6; ++k) {
    const TriangleSurface s = liver_surface(Vec3(1, 2, 3), size, k);
    CHECK(surface_edges(s).closed());
    const Scalar error = std::abs(enclosed_volume(s, s.vertices) - exact) / exact;
    INFO("subdivisions " << k << ": relative volume error " << error << " (exact " << exact << ")");
    if (k >= 3) CHECK(previous / error > 3.5);  // second order in the edge length, as the sphere
    if (k == 6) CHECK(error < 1e-3);
    previous = error;
  }
  // g is increasing (the map is one-to-one): its slope is at least 0.505.
  Scalar slope = 1;
  for (int i = 0; i <= 2000; ++i) {
    const Scalar z = -1 + i / 1000.0;
    slope = std::min(slope, (g(z + 1e-6) - g(z - 1e-6)) / 2e-6);
  }
  CHECK(slope > 0.5);
  // Refused: a size that is not > 0, a centre that is not finite (found by review, 2026-12-01:
  // the centre was not checked, and a NaN one gave NaN vertices).
  const Scalar nan = std::numeric_limits<Scalar>::quiet_NaN();
  CHECK_THROWS_AS(liver_surface(Vec3(1, 2, 3), 0, 3), InvalidArgument);
  CHECK_THROWS_AS(liver_surface(Vec3(nan, 0, 0), 1, 3), InvalidArgument);
  CHECK_THROWS_AS(liver_surface(Vec3(0, 0, std::numeric_limits<Scalar>::infinity()), 1, 3), InvalidArgument);
}

TEMPLATE_LIST_TEST_CASE("embedded surface: an affine motion moves it exactly, its volume by det(I + A)",
                        "[surface]", AllElements) {
  using E = TestType;
  const Mesh<E> mesh = bar_mesh<E>(4, 4, 4);
  const TriangleSurface sphere = sphere_surface(Vec3(2, 2, 2), 1.5, 3);
  EmbeddedSurface<E> surface(mesh, sphere);
  const Scalar V0 = enclosed_volume(sphere, sphere.vertices);
  // At rest the normals face out: along x - c, to the polyhedron's faceting.
  Scalar worst_cos = 1;
  for (Index i = 0; i < sphere.num_vertices(); ++i)
    worst_cos = std::min(worst_cos, surface.normals().col(i).dot((sphere.vertices.col(i) - Vec3(2, 2, 2)).normalized()));
  CHECK(worst_cos > 0.99);

  Solver<E, Corotational> s(mesh, Material{3000, 0.45, 1.0});
  Mat3 A;
  A << 0.1, -0.3, 0.2, 0.05, 0.4, -0.1, 0.3, 0.0, -0.2;
  const Vec3 b(1, -2, 0.5);
  Vector u(s.num_dofs());
  for (Index i = 0; i < mesh.num_nodes(); ++i) u.template segment<3>(3 * i) = A * mesh.node(i) + b;
  s.set_state(u, Vector::Zero(s.num_dofs()));
  surface.update(s);
  const Mat3 F = Mat3::Identity() + A, cofactor = F.determinant() * F.inverse().transpose();
  Eigen::Matrix3Xd n0;
  vertex_normals(sphere, sphere.vertices, n0);
  Scalar position_error = 0, normal_error = 0;
  for (Index i = 0; i < sphere.num_vertices(); ++i) {
    position_error = std::max(position_error, (surface.positions().col(i) - (F * sphere.vertices.col(i) + b)).norm());
    normal_error = std::max(normal_error, (surface.normals().col(i) - (cofactor * n0.col(i)).normalized()).norm());
  }
  const Scalar V = enclosed_volume(sphere, surface.positions());
  INFO("position error " << position_error << ", normal error " << normal_error << ", volume ratio " << V / V0
                         << " against det " << F.determinant());
  CHECK(position_error < 1e-12);  // the locator's Newton tolerance on xi (1e-9 of a cell) times |A|
  // Area-weighted normals are a sum of face normals, each mapped by the cofactor exactly:
  CHECK(normal_error < 1e-10);
  CHECK(std::abs(V / V0 - F.determinant()) < 1e-12);
}

TEST_CASE("embedded surface in dynamics: closed, finite, its vertices at nodes on the nodes, written as PVD",
          "[surface]") {
  const Mesh<Hex8> mesh = bar_mesh<Hex8>(4, 4, 4);
  // The sphere touches nothing; a second surface, the box's own boundary (its vertices are
  // nodes), is written beside it.
  TriangleSurface box;
  box.vertices.resize(3, 8);
  for (int i = 0; i < 8; ++i) box.vertices.col(i) = Vec3(4 * (i & 1), 4 * ((i >> 1) & 1), 4 * ((i >> 2) & 1));
  box.triangles = {{0, 2, 1}, {1, 2, 3}, {4, 5, 6}, {5, 7, 6}, {0, 1, 4}, {1, 5, 4},
                   {2, 6, 3}, {3, 6, 7}, {0, 4, 2}, {2, 4, 6}, {1, 3, 5}, {3, 7, 5}};
  REQUIRE(surface_edges(box).closed());
  CHECK(enclosed_volume(box, box.vertices) == Approx(64).epsilon(1e-14));
  EmbeddedSurface<Hex8> sphere(mesh, sphere_surface(Vec3(2, 2, 2), 1.5, 3)), hull(mesh, box);
  SolverSettings st;
  st.rayleigh_mass = 0.5;
  Solver<Hex8, Corotational> s(mesh, Material{3000, 0.45, 1.0}, st);
  s.fix(mesh.node_set("xmin"));
  s.add_gravity(Vec3(0, 0, -9.81));
  io::PvdWriter pvd(out_dir(), "sphere");
  for (int k = 0; k < 20; ++k) {
    s.step(0.01);
    sphere.update(s), hull.update(s);
    pvd.write_frame(s.time(), [&](const std::filesystem::path& p) { sphere.write_vtu(p); });
  }
  CHECK(sphere.positions().allFinite());
  CHECK(sphere.normals().allFinite());
  CHECK(surface_edges(sphere.surface()).closed());
  const Eigen::Matrix3Xd x = s.positions();
  Index off_node = 0;
  for (int i = 0; i < 8; ++i) {
    Index node = -1;
    for (Index j = 0; j < mesh.num_nodes(); ++j)
      if (mesh.node(j) == box.vertices.col(i)) node = j;
    off_node += hull.positions().col(i) != x.col(node);
  }
  CHECK(off_node == 0);
  CHECK(sphere.positions().row(2).minCoeff() < 0.5 - 1e-3);  // it sagged with the bar
  CHECK(pvd.num_frames() == 20);
  std::ifstream frame(out_dir() / "sphere_0019.vtu");
  std::string head(400, '\0');
  frame.read(head.data(), 400);
  CHECK(head.find("NumberOfCells=\"1280\"") != std::string::npos);
  sphere.write_obj(out_dir() / "sphere.obj");
  const TriangleSurface back = io::read_obj(out_dir() / "sphere.obj");
  CHECK(back.vertices == sphere.positions());  // shortest round-trip decimal: bit for bit
  CHECK(back.triangles == sphere.surface().triangles);
  // A surface outside the mesh, or a broken one, is refused by name.
  CHECK_THROWS_AS(EmbeddedSurface<Hex8>(mesh, sphere_surface(Vec3(2, 2, 2), 3, 1)), InvalidArgument);
  TriangleSurface broken = box;
  broken.triangles[3] = {5, 9, 6};
  CHECK_THROWS_AS(EmbeddedSurface<Hex8>(mesh, broken), MeshError);
}

TEST_CASE("surface files: STL binary and ASCII, malformed OBJ and STL named by line", "[surface][io]") {
  const std::filesystem::path d = out_dir();
  // The unit cube's 12 facets, outward.
  const Vec3 c[8] = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {1, 1, 0}, {0, 0, 1}, {1, 0, 1}, {0, 1, 1}, {1, 1, 1}};
  const int f[12][3] = {{0, 2, 1}, {1, 2, 3}, {4, 5, 6}, {5, 7, 6}, {0, 1, 4}, {1, 5, 4},
                        {2, 6, 3}, {3, 6, 7}, {0, 4, 2}, {2, 4, 6}, {1, 3, 5}, {3, 7, 5}};
  std::string ascii = "solid cube\n";
  std::string binary(80, ' ');
  const std::uint32_t n = 12;
  binary.append(reinterpret_cast<const char*>(&n), 4);
  for (const auto& t : f) {
    ascii += "  facet normal 0 0 0\n    outer loop\n";
    binary.append(12, '\0');  // the normal (unused)
    for (int k : t) {
      ascii += fmt::format("      vertex {} {} {}\n", c[k].x(), c[k].y(), c[k].z());
      for (int j = 0; j < 3; ++j) {
        const float x = static_cast<float>(c[k][j]);
        binary.append(reinterpret_cast<const char*>(&x), 4);
      }
    }
    ascii += "    endloop\n  endfacet\n";
    binary.append(2, '\0');
  }
  ascii += "endsolid cube\n";
  write_text(d / "cube_ascii.stl", ascii);
  write_text(d / "cube_binary.STL", binary);
  // Two solids, the cube's bottom half of the facets and its top half (as a CAD exporter writes
  // the parts of one body): one surface, the shared corners merged.
  std::string two_solids = ascii;
  size_t split = 0;
  for (int k = 0; k < 6; ++k) split = two_solids.find("endfacet\n", split) + 9;  // after the 6th facet
  two_solids.insert(split, "endsolid bottom\nsolid top\n");
  write_text(d / "cube_two_solids.stl", two_solids);
  for (const char* name : {"cube_ascii.stl", "cube_binary.STL", "cube_two_solids.stl"}) {
    const TriangleSurface s = io::read_surface(d / name);
    INFO(name);
    CHECK(s.num_vertices() == 8);
    CHECK(s.num_triangles() == 12);
    CHECK(surface_edges(s).closed());
    CHECK(enclosed_volume(s, s.vertices) == Approx(1).epsilon(1e-15));
  }
  // Malformed files: the message names the file and line (or facet) and what was expected.
  write_text(d / "bad_index.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n");
  CHECK(read_error(d / "bad_index.obj").find("bad_index.obj:4: vertex index 9 out of range") != std::string::npos);
  write_text(d / "bad_number.obj", "# a comment\nv 0 0 zero\n");
  CHECK(read_error(d / "bad_number.obj").find("bad_number.obj:2: 'zero' is not a finite number") != std::string::npos);
  write_text(d / "short_face.obj", "v 0 0 0\nv 1 0 0\nf 1 2\n");
  CHECK(read_error(d / "short_face.obj").find("short_face.obj:3: a face needs at least 3 vertices") != std::string::npos);
  write_text(d / "repeated.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 2 2\n");
  CHECK(read_error(d / "repeated.obj").find("repeated.obj:5: the face repeats vertex 2") != std::string::npos);
  write_text(d / "no_faces.obj", "v 0 0 0\n");
  CHECK(read_error(d / "no_faces.obj").find("no faces") != std::string::npos);
  write_text(d / "short_facet.stl", "solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nendloop\n");
  CHECK(read_error(d / "short_facet.stl").find("short_facet.stl:6: a facet needs 3 vertices, got 2") != std::string::npos);
  const std::string facet = "facet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\nendloop\nendfacet\n";
  write_text(d / "nested.stl", "solid a\n" + facet + "solid b\n" + facet + "endsolid b\n");
  CHECK(read_error(d / "nested.stl").find("nested.stl:9: 'solid' inside a solid (the last one's 'endsolid' is missing)") !=
        std::string::npos);
  write_text(d / "after_end.stl", "solid a\n" + facet + "endsolid a\n" + facet);
  CHECK(read_error(d / "after_end.stl").find("after_end.stl:10: expected 'solid' after 'endsolid'") != std::string::npos);
  write_text(d / "end_in_facet.stl", "solid a\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nendsolid a\n");
  CHECK(read_error(d / "end_in_facet.stl").find("end_in_facet.stl:5: 'endsolid' inside a facet") != std::string::npos);
  write_text(d / "unclosed.stl", "solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\n");
  CHECK(read_error(d / "unclosed.stl").find("ends inside a facet") != std::string::npos);
  std::string nan_binary = binary;
  const float nan = std::numeric_limits<float>::quiet_NaN();
  std::memcpy(nan_binary.data() + 84 + 50 * 5 + 12 + 4, &nan, 4);
  write_text(d / "nan.stl", nan_binary);
  CHECK(read_error(d / "nan.stl").find("facet 5 has a non-finite coordinate") != std::string::npos);
  write_text(d / "surface.ply", "ply\n");
  CHECK(read_error(d / "surface.ply").find("unknown surface format '.ply'") != std::string::npos);
  CHECK(read_error(d / "missing.obj") != "");
  // The cell writer refuses connectivity that is not whole cells of existing points.
  const Eigen::Matrix3Xd pts = Eigen::Matrix3Xd::Zero(3, 3);
  CHECK_THROWS_AS(io::write_vtu_cells(d / "bad.vtu", pts, {0, 1, 2, 0}, 3, 5), InvalidArgument);
  CHECK_THROWS_AS(io::write_vtu_cells(d / "bad.vtu", pts, {0, 1, 3}, 3, 5), InvalidArgument);
}
