// Mesh validation, selections, boundary extraction and the generators.
#include "catch.hpp"
#include "compositions.hpp"

#include <plastifem/plastifem.hpp>

#include <random>
#include <set>
#include <type_traits>

using namespace plastifem;
using namespace plastifem::testing;

namespace {

std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const Error& e) {
    return e.what();
  }
  return "(no error)";
}

bool contains(const std::string& s, const std::string& part) { return s.find(part) != std::string::npos; }

Scalar total_volume(const auto& mesh) {
  using E = typename std::decay_t<decltype(mesh)>::Element;
  Scalar v = 0;
  for (Index e = 0; e < mesh.num_elements(); ++e) v += element_volume<E>(mesh.element_nodes(e));
  return v;
}

}  // namespace

TEST_CASE("bar scene generators match SCENES.md counts", "[generators]") {
  // SCENES.md table: (nx, ny, nz) -> hexes, nodes.
  struct Row { int nx, ny, nz, hexes, nodes; };
  for (Row r : {Row{10, 3, 3, 90, 176}, Row{20, 6, 6, 720, 1029}, Row{40, 12, 12, 5760, 6929}}) {
    const auto hex = bar_mesh<Hex8>(r.nx, r.ny, r.nz);
    REQUIRE(hex.num_elements() == r.hexes);
    REQUIRE(hex.num_nodes() == r.nodes);
    const auto tet = bar_mesh<Tet4>(r.nx, r.ny, r.nz);
    REQUIRE(tet.num_elements() == 6 * r.hexes);
    REQUIRE(tet.num_nodes() == r.nodes);
    // Summing n element volumes (1/6 is inexact in binary) loses up to n * eps relative:
    // 34,560 tets * 1.1e-16 = 3.8e-12.
    REQUIRE(total_volume(hex) == Approx(r.nx * r.ny * r.nz).epsilon(4e-12));
    REQUIRE(total_volume(tet) == Approx(r.nx * r.ny * r.nz).epsilon(4e-12));
    const auto wedge = bar_mesh<Wedge6>(r.nx, r.ny, r.nz);
    REQUIRE(wedge.num_elements() == 2 * r.hexes);
    REQUIRE(wedge.num_nodes() == r.nodes);
    REQUIRE(total_volume(wedge) == Approx(r.nx * r.ny * r.nz).epsilon(4e-12));
    // Box sides: one quadrilateral per cell on the x and y sides, two triangles on the z sides.
    REQUIRE(wedge.face_set("xmax").size() == static_cast<size_t>(r.ny * r.nz));
    REQUIRE(wedge.face_set("ymin").size() == static_cast<size_t>(r.nx * r.nz));
    REQUIRE(wedge.face_set("zmin").size() == static_cast<size_t>(2 * r.nx * r.ny));
  }
}

TEST_CASE("Tet10 mid-edge nodes are shared between neighbours", "[generators]") {
  const auto tet4 = bar_mesh<Tet4>(10, 3, 3);
  std::set<std::pair<Index, Index>> edges;
  for (const auto& t : tet4.elements())
    for (const auto& e : Tet4::edges) edges.insert(std::minmax(t[e[0]], t[e[1]]));
  const auto tet10 = bar_mesh<Tet10>(10, 3, 3);
  REQUIRE(tet10.num_nodes() == tet4.num_nodes() + static_cast<Index>(edges.size()));
  // Unique edges of the Kuhn-split grid: the 3 axis directions, 3 face diagonals (1,1,0)-type
  // and the cube diagonal. Counted independently: 1029 edges... for bar90 it is:
  const int nx = 10, ny = 3, nz = 3;
  const int axis = nx * (ny + 1) * (nz + 1) + (nx + 1) * ny * (nz + 1) + (nx + 1) * (ny + 1) * nz;
  const int face_diagonals = nx * ny * (nz + 1) + nx * (ny + 1) * nz + (nx + 1) * ny * nz;
  const int body_diagonals = nx * ny * nz;
  REQUIRE(static_cast<int>(edges.size()) == axis + face_diagonals + body_diagonals);
  REQUIRE(total_volume(tet10) == Approx(90).epsilon(1e-13));
  // The node sets of the box sides gain the mid-edge nodes that lie on them.
  for (Index i : tet10.node_set("xmin")) REQUIRE(tet10.node(i).x() == 0);
  REQUIRE(tet10.node_set("xmin").size() == 4 * 4 + (3 * 4 * 2 + 3 * 3));  // vertices + edges on x=0
}

TEST_CASE("5-tet split is conforming", "[generators]") {
  const auto m = box_tet4_five({4, 3, 2});
  REQUIRE(m.num_elements() == 5 * 24);
  REQUIRE(total_volume(m) == Approx(24).epsilon(1e-13));
  // Conforming: the boundary consists only of the box's outer faces (2 triangles per cell face).
  const auto boundary = boundary_faces(m);
  REQUIRE(boundary.size() == 2u * 2 * (4 * 3 + 4 * 2 + 3 * 2));
  // Same for the Kuhn split.
  REQUIRE(boundary_faces(box_tet4_kuhn({4, 3, 2})).size() == boundary.size());
}

TEST_CASE("box side sets and boundary surface", "[mesh]") {
  const auto m = box_hex8({3, 2, 2, Vec3(3.0, 1.0, 1.0), Vec3(-1, 0, 0)});
  REQUIRE(m.node_set("xmin").size() == 9);
  REQUIRE(m.face_set("xmax").size() == 4);
  for (const FaceRef& f : m.face_set("xmax"))
    for (Index i : m.face_nodes(f)) REQUIRE(m.node(i).x() == Approx(2.0));
  const auto s = extract_surface(m);
  REQUIRE(s.faces.size() == 2u * (3 * 2 + 3 * 2 + 2 * 2));
  // Outward normals: the surface encloses the volume (divergence theorem with x: V = 1/3 sum x.n A).
  Scalar v = 0;
  for (const auto& q : s.connectivity) {
    const Vec3 a = m.node(q[0]), b = m.node(q[1]), c = m.node(q[2]), d = m.node(q[3]);
    const Vec3 area = 0.5 * (c - a).cross(d - b);
    v += (a + b + c + d).dot(area) / 4 / 3;
  }
  REQUIRE(v == Approx(3.0).epsilon(1e-13));
  REQUIRE(select_nodes_in_box(m, Vec3(-1, 0, 0), Vec3(-1, 1, 1)).size() == 9);
  REQUIRE(contains(error_of([&] { (void)m.node_set("clamp"); }), "no node set named 'clamp'"));
}

TEST_CASE("thick shell and tube generators", "[generators]") {
  SECTION("tube volume converges to the annulus volume") {
    // Polygonal cross-section with n sides inscribed at r_in, offset radially: area of the
    // polygonal annulus = n/2 sin(2 pi/n) (r_out^2 - r_in^2), exact for the straight-sided hexes.
    const Scalar ri = 1.0, ro = 1.5, L = 4.0;
    const int n = 24;
    const auto m = tube_hex8(ri, ro, L, n, 8, 2);
    REQUIRE(m.num_elements() == n * 8 * 2);
    REQUIRE(m.num_nodes() == n * 9 * 3);
    const Scalar area = n / 2.0 * std::sin(2 * std::numbers::pi / n) * (ro * ro - ri * ri);
    REQUIRE(total_volume(m) == Approx(area * L).epsilon(1e-12));
    for (Index i : m.node_set("outer")) REQUIRE(std::hypot(m.node(i).y(), m.node(i).z()) == Approx(ro).epsilon(1e-14));
    for (Index i : m.node_set("inner")) REQUIRE(std::hypot(m.node(i).y(), m.node(i).z()) == Approx(ri).epsilon(1e-14));
    REQUIRE(m.face_set("xmin").size() == static_cast<size_t>(n * 2));
    REQUIRE(boundary_faces(m).size() == static_cast<size_t>(2 * n * 8 + 2 * n * 2));
  }
  SECTION("thick shell of a flat quad grid is a box, either offset direction") {
    QuadSurface s;
    s.nodes.resize(3, 9);
    for (int j = 0; j < 3; ++j)
      for (int i = 0; i < 3; ++i) s.nodes.col(i + 3 * j) = Vec3(i, j, 0);
    for (int j = 0; j < 2; ++j)
      for (int i = 0; i < 2; ++i) s.quads.push_back({i + 3 * j, i + 1 + 3 * j, i + 1 + 3 * (j + 1), i + 3 * (j + 1)});
    for (Scalar t : {0.5, -0.5}) {
      const auto m = thick_shell_hex8(s, t, 3);
      REQUIRE(m.num_elements() == 12);
      REQUIRE(total_volume(m) == Approx(4 * 0.5).epsilon(1e-14));
      for (Index i : m.node_set("top")) REQUIRE(m.node(i).z() == Approx(t));
    }
  }
  SECTION("thick shell of prisms from a flat triangulated grid is a box, either offset direction") {
    TriangleSurface s;
    s.vertices.resize(3, 9);
    for (int j = 0; j < 3; ++j)
      for (int i = 0; i < 3; ++i) s.vertices.col(i + 3 * j) = Vec3(i, j, 0);
    for (int j = 0; j < 2; ++j)
      for (int i = 0; i < 2; ++i) {
        const Index a = i + 3 * j, b = a + 1, c = a + 4, d = a + 3;  // counter-clockwise from +z
        s.triangles.push_back({a, b, c});
        s.triangles.push_back({a, c, d});
      }
    for (Scalar t : {0.5, -0.5}) {
      const auto m = thick_shell_wedge6(s, t, 3);
      REQUIRE(m.num_elements() == 24);
      REQUIRE(total_volume(m) == Approx(4 * 0.5).epsilon(1e-14));
      for (Index i : m.node_set("top")) REQUIRE(m.node(i).z() == Approx(t));
      for (Index i : m.node_set("bottom")) REQUIRE(m.node(i).z() == 0);
      // The face sets are boundary faces on their planes, facing out of the shell.
      for (const char* name : {"bottom", "top"}) {
        const auto& faces = m.face_set(name);
        REQUIRE(faces.size() == 8);
        const Scalar z = std::string(name) == "top" ? t : 0.0;
        REQUIRE(faces == select_boundary_faces(m, [&](const Vec3& p) { return std::abs(p.z() - z) < 1e-12; }));
        for (const FaceRef& f : faces) {
          const auto n = m.face_nodes(f);
          const Vec3 normal = (m.node(n[1]) - m.node(n[0])).cross(m.node(n[2]) - m.node(n[0]));
          REQUIRE(normal.z() * (z == 0 ? -t : t) > 0);
        }
      }
    }
  }
  SECTION("bad arguments") {
    REQUIRE(contains(error_of([] { tube_hex8(1.0, 0.5, 1.0, 8, 2, 1); }), "r_in < r_out"));
    TriangleSurface s{Tet4::reference_nodes().leftCols<3>(), {{0, 1, 2}}};
    REQUIRE(contains(error_of([&] { thick_shell_wedge6(s, 0.1, 0); }), "at least one layer"));
    REQUIRE(contains(error_of([&] { thick_shell_wedge6(s, 0.0, 1); }), "finite and non-zero"));
    s.triangles[0][2] = 5;
    REQUIRE(contains(error_of([&] { thick_shell_wedge6(s, 0.1, 1); }), "triangle 0 has vertex 5 out of range [0, 3)"));
    REQUIRE(contains(error_of([] { box_hex8({0, 1, 1}); }), "at least one cell"));
  }
  SECTION("meshes larger than 32-bit indices hold are refused before they are built") {
    // Each would overflow an int count (UB) or try to allocate tens of GB; the refusal comes
    // before any allocation, so the test takes no memory.
    CHECK(contains(error_of([] { bar_mesh<Hex8>(2000, 2000, 2000); }),
                     "a 2000 x 2000 x 2000 box would have 8.012e+09 nodes and 8e+09 elements; a mesh holds at "
                     "most 715827882 nodes and 2147483647 elements"));
    // 720^3 cells: 3.7e8 grid nodes fit, 6 tetrahedra per cell do not.
    CHECK(contains(error_of([] { bar_mesh<Tet4>(720, 720, 720); }), "2.239e+09 elements"));
    // 450^3 cells: the Tet4 mesh would fit (9.2e7 nodes, 5.5e8 elements), with its mid-edge nodes 7.3e8 do not.
    CHECK(contains(error_of([] { bar_mesh<Tet10>(450, 450, 450); }), "a 450 x 450 x 450 box of Tet10 would have 7.314e+08 nodes"));
    CHECK(contains(error_of([] { bar_mesh<Wedge6>(1, 1, 1 << 30); }), "would have 4.295e+09 nodes"));
    CHECK(contains(error_of([] { tube_hex8(1.0, 2.0, 1.0, 100000, 100000, 1); }), "a tube of 100000 x 100000 x 1 cells"));
    TriangleSurface s{Tet4::reference_nodes().leftCols<3>(), {{0, 1, 2}}};
    CHECK(contains(error_of([&] { thick_shell_wedge6(s, 0.1, 1 << 30); }), "a thick shell of 1073741824 layers on 1 faces"));
  }
}

// ---- validation errors name the element / node -------------------------------------------
TEST_CASE("mesh validation gives clear errors", "[mesh][errors]") {
  Eigen::Matrix3Xd X = Tet4::reference_nodes();
  SECTION("index out of range") {
    const auto msg = error_of([&] { Mesh<Tet4>(X, {{0, 1, 2, 7}}); });
    REQUIRE(contains(msg, "element 0, local node 3: node index 7 out of range [0, 4)"));
  }
  SECTION("negative index") {
    REQUIRE(contains(error_of([&] { Mesh<Tet4>(X, {{0, 1, -2, 3}}); }), "node index -2 out of range"));
  }
  SECTION("repeated node") {
    REQUIRE(contains(error_of([&] { Mesh<Tet4>(X, {{0, 1, 1, 3}}); }), "element 0 is degenerate"));
  }
  SECTION("non-finite coordinate") {
    X(1, 2) = std::numeric_limits<Scalar>::quiet_NaN();
    REQUIRE(contains(error_of([&] { Mesh<Tet4>(X, {{0, 1, 2, 3}}); }), "node 2 has a non-finite coordinate"));
    X(1, 2) = std::numeric_limits<Scalar>::infinity();
    REQUIRE(contains(error_of([&] { Mesh<Tet4>(X, {{0, 1, 2, 3}}); }), "node 2 has a non-finite coordinate"));
  }
  SECTION("inverted element") {
    Eigen::Matrix3Xd Y(3, 5);
    Y << X, Vec3(1, 1, 1);
    const auto msg = error_of([&] { Mesh<Tet4>(Y, {{0, 1, 2, 3}, {1, 2, 3, 4}, {0, 2, 1, 3}}); });
    REQUIRE(contains(msg, "element 2 is inverted"));
  }
  SECTION("flat element") {
    X.col(3) = Vec3(0.3, 0.3, 0.0);
    REQUIRE(contains(error_of([&] { Mesh<Tet4>(X, {{0, 1, 2, 3}}); }), "element 0 is degenerate: scaled det J"));
  }
  SECTION("Hex8 inverted at one corner only (non-convex)") {
    // Push node 6 through the opposite face: det J < 0 near corner 6 while the centre may be fine.
    auto H = Hex8::reference_nodes();
    H.col(6) = Vec3(-0.8, -0.8, -0.8);
    REQUIRE(contains(error_of([&] { Mesh<Hex8>(H, {{0, 1, 2, 3, 4, 5, 6, 7}}); }), "element 0 is inverted"));
  }
  SECTION("Tet10 with a mid-edge node pushed past the opposite edge") {
    auto T = Tet10::reference_nodes();
    T.col(4) = Vec3(0.5, 0.9, 0.0);  // far outside the valid region for the (0,1) mid-node
    const auto msg = error_of([&] { Mesh<Tet10>(T, {{0, 1, 2, 3, 4, 5, 6, 7, 8, 9}}); });
    REQUIRE((contains(msg, "element 0 is inverted") || contains(msg, "element 0 is degenerate")));
  }
  SECTION("unused nodes are reported, not fatal") {
    Eigen::Matrix3Xd Y(3, 6);
    Y << X, Vec3(5, 5, 5), Vec3(6, 6, 6);
    const Mesh<Tet4> m(Y, {{0, 1, 2, 3}});
    REQUIRE(m.report().unused_nodes == std::vector<Index>{4, 5});
  }
  SECTION("node and face sets are checked") {
    Mesh<Tet4> m(X, {{0, 1, 2, 3}});
    REQUIRE(contains(error_of([&] { m.add_node_set("s", {0, 9}); }), "node set 's': node 9 out of range"));
    REQUIRE(contains(error_of([&] { m.add_face_set("f", {{0, 4}}); }), "local face 4"));
  }
}

TEST_CASE("point location: a point inside a curved Tet10 past its nodes' box is found", "[mesh][locate]") {
  // The face (0, 2, 3) on x = 0 with its three mid-edge nodes pushed out to x = -0.04: the face
  // bulges to x = -4/3 0.04 at its centre, past every node (found by review on a curved mesh,
  // where EmbeddedPoints refused such a point as in no element). Points x(xi) at reference
  // coordinates inside, near that face, must be found at the same xi (Newton's 1e-14 relative
  // residual: a few 1e-15 of xi).
  Eigen::Matrix3Xd X(3, 10);
  X.leftCols<4>() << 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1;
  for (int k = 0; k < 6; ++k) {
    const auto [i, j] = Tet10::edges[static_cast<size_t>(k)];
    X.col(4 + k) = 0.5 * (X.col(i) + X.col(j));
  }
  for (int node : {6, 7, 9}) X(0, node) = -0.04;  // edges (0, 2), (0, 3), (2, 3)
  const Mesh<Tet10> mesh(X, {{0, 1, 2, 3, 4, 5, 6, 7, 8, 9}});
  const PointLocator<Tet10> locator(mesh);
  const ElementNodes<Tet10> Xe = mesh.element_nodes(0);
  int outside_nodes_box = 0;
  for (const Vec3& xi : {Vec3(0.01, 1.0 / 3, 1.0 / 3), Vec3(0.002, 0.3, 0.4), Vec3(0.05, 0.2, 0.2), Vec3(0.25, 0.25, 0.25)}) {
    const Vec3 p = Xe * Tet10::shape(xi);
    outside_nodes_box += p.x() < -0.04;
    for (const auto& found : {locate_point(mesh, p), locator.locate(p)}) {
      INFO("xi " << xi.transpose() << " at " << p.transpose());
      CHECK(found.has_value());
      if (found) CHECK((found->xi - xi).norm() <= 1e-13);
    }
  }
  CHECK(outside_nodes_box == 2);
  // A point just outside the bulging face is still refused.
  CHECK_FALSE(locate_point(mesh, Vec3(Xe * Tet10::shape(Vec3(0, 1.0 / 3, 1.0 / 3)) - Vec3(1e-3, 0, 0))).has_value());
}

TEMPLATE_LIST_TEST_CASE("point locator: the answers of testing every element, at a fraction of the elements",
                        "[mesh][locate]", AllElements) {
  // Random points in and around the bounding box, points exactly on nodes and edges (shared by
  // several elements: the lowest-numbered one is the answer either way) and element centres,
  // on a bar and (Hex8) a curved tube whose elements all differ.
  auto check = [](const Mesh<TestType>& mesh) {
    const PointLocator<TestType> locator(mesh);
    const Vec3 lo = mesh.nodes().rowwise().minCoeff(), hi = mesh.nodes().rowwise().maxCoeff();
    std::mt19937 rng(11);
    std::uniform_real_distribution<Scalar> u(-0.1, 1.1);
    std::vector<Vec3> points;
    for (int k = 0; k < 2000; ++k) points.push_back(lo.array() + (hi - lo).array() * Eigen::Array3d(u(rng), u(rng), u(rng)));
    for (Index i = 0; i < mesh.num_nodes(); i += 7) points.push_back(mesh.node(i));
    for (Index e = 0; e < mesh.num_elements(); e += 5) {
      const ElementNodes<TestType> X = mesh.element_nodes(e);
      points.push_back(0.5 * (X.col(0) + X.col(1)));                        // on an edge
      points.push_back(X * TestType::shape(reference_centre<TestType>()));  // inside
    }
    int inside = 0;
    for (const Vec3& p : points) {
      const auto slow = locate_point(mesh, p);
      const auto fast = locator.locate(p);
      REQUIRE(slow.has_value() == fast.has_value());
      if (!slow) continue;
      ++inside;
      REQUIRE(fast->element == slow->element);
      REQUIRE(fast->xi == slow->xi);
    }
    INFO(mesh.num_elements() << " elements: grid " << locator.grid().transpose() << ", "
                             << locator.elements_per_cell() << " elements per cell, " << inside << " of "
                             << points.size() << " points inside");
    CHECK(inside > 500);  // bar: 1260-1735 of ~2100-2600 points; tube (an annulus in its box): 728 of 2247
    CHECK(locator.elements_per_cell() < 30);  // a query tests these, not the hundreds of the mesh
    CHECK_FALSE(locator.locate(Vec3(std::nan(""), 0, 0)).has_value());
    CHECK_FALSE(locator.locate(Vec3(1e300, 0, 0)).has_value());
  };
  check(bar_mesh<TestType>(BoxSpec{12, 4, 3, Vec3(6, 2, 1.5)}));
  if constexpr (std::is_same_v<TestType, Hex8>) check(tube_hex8(1.0, 1.5, 4.0, 24, 8, 2));
}
