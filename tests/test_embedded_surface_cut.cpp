// An embedded surface cut with the tissue (embedding/embedded_surface.hpp).
//
// Facts checked, for both enrichments:
//  - before a cut the sphere is closed; a cut through it leaves an open surface whose rim
//    (edges of one triangle) lies exactly on the cut, two pieces, every edge elsewhere shared by
//    two triangles in opposite directions;
//  - a cut that ends inside the sphere (a blade in from the top) opens it only where the tissue
//    opens: the rim is on the cut plane and does not reach past the cut's elements;
//  - as the free side falls the rims separate by the fall, each side's vertices following their
//    own piece, and a cut that grows re-splits the surface.
#include "catch.hpp"

#include <plastifem/cutting.hpp>
#include <plastifem/embedding/embedded_surface.hpp>
#include <plastifem/plastifem.hpp>

#include <map>
#include <set>

using namespace plastifem;

namespace {

/// Pieces of the surface: classes of triangles joined through shared vertices.
Index count_pieces(const TriangleSurface& s) {
  std::vector<Index> parent(static_cast<size_t>(s.num_vertices()));
  for (size_t i = 0; i < parent.size(); ++i) parent[i] = static_cast<Index>(i);
  auto root = [&](Index i) {
    while (parent[static_cast<size_t>(i)] != i) i = parent[static_cast<size_t>(i)] = parent[static_cast<size_t>(parent[static_cast<size_t>(i)])];
    return i;
  };
  for (const Triangle& t : s.triangles)
    for (int k = 1; k < 3; ++k) parent[static_cast<size_t>(root(t[static_cast<size_t>(k)]))] = root(t[0]);
  std::set<Index> roots;
  for (const Triangle& t : s.triangles) roots.insert(root(t[0]));
  return static_cast<Index>(roots.size());
}

/// The vertices on the rim: those of edges that only one triangle has.
std::set<Index> rim_vertices(const TriangleSurface& s) {
  std::map<std::pair<Index, Index>, int> count;
  for (const Triangle& t : s.triangles)
    for (int k = 0; k < 3; ++k) {
      const Index a = t[static_cast<size_t>(k)], b = t[static_cast<size_t>((k + 1) % 3)];
      ++count[{std::min(a, b), std::max(a, b)}];
    }
  std::set<Index> rim;
  for (const auto& [e, n] : count)
    if (n == 1) rim.insert(e.first), rim.insert(e.second);
  return rim;
}

template <class Enrich>
void cut_sphere() {
  // bar 6 x 4 x 4 of Hex8, clamped at x = 0, a sphere of radius 1.5 about (3, 2, 2) in it.
  const Mesh<Hex8> mesh = bar_mesh<Hex8>(6, 4, 4);
  SolverSettings st;
  st.rayleigh_mass = 0.5;
  Solver<Hex8, Corotational, NoPlasticity, Enrich> s(mesh, Material{3000, 0.45, 1.0}, st);
  s.fix(mesh.node_set("xmin"));
  s.add_gravity(Vec3(0, 0, -9.81));
  EmbeddedSurface<Hex8> surface(mesh, sphere_surface(Vec3(3, 2, 2), 1.5, 4));
  surface.update(s);
  REQUIRE(surface_edges(surface.surface()).closed());
  CHECK(surface.num_crossing_vertices() == 0);

  // A blade down from the top face at x = 3.3 to z = 2.4: the sphere opens over its top only.
  auto blade = [](Scalar depth) { return CutPatch(Vec3(3.3, -0.1, 4.1), Vec3(0, 4.2, 0), Vec3(0, 0, -depth)); };
  const CutHandle h = s.cut(blade(1.7));
  surface.update(s);
  {
    const TriangleSurface& cut = surface.surface();
    const SurfaceEdges e = surface_edges(cut);
    const std::set<Index> rim = rim_vertices(cut);
    Scalar off_plane = 0, lowest = 10;
    // Above z = 3 the cut's elements have the plane's level set at every node; the element the
    // blade ends in (z in [2, 3]) has the distances to the blade's edge at its lower nodes, and
    // the surface opens along that element's own interface there.
    for (Index v : rim) {
      if (cut.vertices(2, v) >= 3) off_plane = std::max(off_plane, std::abs(cut.vertices(0, v) - 3.3));
      lowest = std::min(lowest, cut.vertices(2, v));
    }
    INFO(Enrich::name << ", partial cut: " << e.boundary << " rim edges, off the plane by " << off_plane
                      << ", lowest at z = " << lowest << ", " << surface.num_crossing_vertices() << " crossing vertices");
    CHECK(e.boundary > 0);
    CHECK(e.non_manifold == 0);
    CHECK(e.misoriented == 0);
    CHECK(off_plane < 1e-12);  // the crossings are on the cut plane (regula falsi's tolerance)
    // The tissue opens down to the cut elements' bottom (z = 2: the element the blade ends in is
    // cut whole), not below: the rim ends at most one surface edge (0.12) below it, at the
    // crossing of the last split triangle's other edge.
    CHECK(lowest > 2 - 0.15);
    CHECK(lowest < 2.4);
    CHECK(count_pieces(cut) == 1);
    // Along the opening every rim vertex is a crossing with a twin at its rest point (the other
    // side's), none a vertex of the given surface (a T-junction at the cut's tip would leave one
    // there); only the slit's two ends, crossings past the cut's end, are single.
    const Index given = cut.num_vertices() - surface.num_crossing_vertices();
    Index given_on_rim = 0;
    std::vector<Scalar> single_z;
    for (Index v : rim) {
      given_on_rim += v < given;
      bool twin = false;
      for (Index w : rim) twin = twin || (w != v && (cut.vertices.col(w) - cut.vertices.col(v)).norm() < 1e-12);
      if (!twin) single_z.push_back(cut.vertices(2, v));
    }
    CHECK(given_on_rim == 0);
    REQUIRE(single_z.size() == 2);
    CHECK(std::max(single_z[0], single_z[1]) < 2.1);  // at the slit's lower ends
  }

  // Grown through: two pieces, the rim a closed loop on each side, all on the plane (the grown
  // cut's nodal level set is the plane's at every node; the element the blade ended in keeps
  // its pieces, and its vertices move with the side the new level set gives them).
  s.grow_cut(h, blade(4.2));
  surface.update(s);
  const TriangleSurface& cut = surface.surface();
  const std::set<Index> rim = rim_vertices(cut);
  Scalar off_plane = 0;
  for (Index v : rim) off_plane = std::max(off_plane, std::abs(cut.vertices(0, v) - 3.3));
  CHECK(surface_edges(cut).misoriented == 0);
  CHECK(surface_edges(cut).non_manifold == 0);
  CHECK(off_plane < 1e-12);
  CHECK(count_pieces(cut) == 2);

  // The free side falls: rim vertices on the far side (moving with x > 3.3) drop by the damped
  // free fall, those on the clamped side stay near the sagging bar.
  for (int k = 0; k < 30; ++k) s.step(0.01), surface.update(s);
  const Scalar t = s.time(), fall = -(9.81 / 0.5) * (t - (1 - std::exp(-0.5 * t)) / 0.5);
  Scalar free_off = 0, gap = std::numeric_limits<Scalar>::infinity();
  const Eigen::Matrix3Xd& x = surface.positions();
  for (Index v = 0; v < cut.num_vertices(); ++v)
    if (cut.vertices(0, v) > 3.3 + 1e-9) free_off = std::max(free_off, std::abs((x.col(v) - cut.vertices.col(v)).z() - fall));
  // The gap across the cut: each rim vertex's twin at the same rest point.
  for (Index a : rim)
    for (Index b : rim)
      if (a < b && (cut.vertices.col(a) - cut.vertices.col(b)).norm() < 1e-12)
        gap = std::min(gap, (x.col(a) - x.col(b)).norm());
  INFO(Enrich::name << ": fall " << fall << ", the free side's vertices off it by " << free_off << ", smallest gap "
                    << gap);
  CHECK(free_off < 1e-3 * std::abs(fall));  // the trapezoidal rule's O((alpha dt)^2)
  CHECK(gap > 0.1 * std::abs(fall));  // the clamped side sags far less than the free side falls
  CHECK(x.allFinite());
}

}  // namespace

TEST_CASE("embedded surface cut with the tissue: open exactly along the cut, each side with its piece",
          "[surface][enrichment]") {
  cut_sphere<Heaviside>();
  cut_sphere<ShiftedHeaviside>();
}

TEST_CASE("embedded surface opens with the tissue where a cut runs along a node plane or within the snap distance of one",
          "[surface][enrichment]") {
  // The bar held at z = 0 and lifted by 0.5 at z = 4, cut through at z0: the piece above moves
  // up by 0.5 as a rigid body, the one below stays. Every crossing of the surface is a pair of
  // vertices at one rest point, one moving with each piece: 0.5 apart, and no triangle is
  // stretched across the gap. Found by review (2026-11-30), for a cut along the node plane z = 2
  // with its normal down (a crossing on the shared face was located again in the uncut element
  // beside the cut one, so both copies moved together: 142 triangles across the gap), and for
  // a cut within the snap distance of it (the surface read the unsnapped distance where the
  // level set was not stored, and opened nowhere: 94 triangles across).
  auto check = [&]<class E>(E) {
    const Mesh<E> mesh = bar_mesh<E>(6, 4, 4);
    for (const Scalar z0 : {2.0, 2.003, 1.997})
      for (const Scalar normal : {1.0, -1.0}) {
        INFO(E::name << ", cut at z = " << z0 << ", normal " << normal);
        EmbeddedSurface<E> surface(mesh, sphere_surface(Vec3(3, 2, 2.05), 1.5, 3));
        Solver<E, Corotational, NoPlasticity, Heaviside> s(mesh, Material{3000, 0.45, 1.0});
        s.fix(mesh.node_set("zmin"));
        s.prescribe(mesh.node_set("zmax"), PrescribedMotion{[](Scalar, const Vec3&) { return Vec3(0, 0, 0.5); }, {}, {}});
        s.cut(CutPlane(Vec3(0, 0, z0), Vec3(0, 0, normal)));
        s.solve_static();
        surface.update(s);
        const TriangleSurface& t = surface.surface();
        const Eigen::Matrix3Xd& x = surface.positions();
        std::map<std::array<Scalar, 3>, std::vector<Index>> at;
        for (Index v = t.num_vertices() - surface.num_crossing_vertices(); v < t.num_vertices(); ++v)
          at[{t.vertices(0, v), t.vertices(1, v), t.vertices(2, v)}].push_back(v);
        int pairs = 0;
        Scalar worst = 0;
        for (const auto& [rest, vs] : at) {
          REQUIRE(vs.size() == 2);
          ++pairs;
          worst = std::max(worst, std::abs((x.col(vs[0]) - x.col(vs[1])).norm() - 0.5));
        }
        Scalar longest = 0;  // 0.247 at rest
        for (const Triangle& tri : t.triangles)
          for (int k = 0; k < 3; ++k) longest = std::max(longest, (x.col(tri[k]) - x.col(tri[(k + 1) % 3])).norm());
        CHECK(pairs > 50);
        CHECK(worst <= 1e-6);  // the solve's tolerance on a rigid lift
        CHECK(longest < 0.3);
      }
  };
  check(Hex8{});
  check(Tet4{});
}

TEST_CASE("embedded surface cut along element faces opens with either normal, and a new solver re-splits",
          "[surface][enrichment]") {
  // A plane cut at x = 3, a plane of nodes: the cut elements are on one side of it only, and the
  // surface's crossings lie on their shared faces. With either normal the sphere comes apart in
  // two, its rim on the plane. Then solvers built one after another in the same place (the same
  // address) with cuts at other x: the surface follows each.
  const Mesh<Hex8> mesh = bar_mesh<Hex8>(6, 4, 4);
  EmbeddedSurface<Hex8> surface(mesh, sphere_surface(Vec3(3, 2, 2), 1.5, 3));
  for (const Scalar normal : {1.0, -1.0}) {
    Solver<Hex8, Corotational, NoPlasticity, Heaviside> s(mesh, Material{3000, 0.45, 1.0});
    s.cut(CutPlane(Vec3(3, 0, 0), Vec3(normal, 0, 0)));
    surface.update(s);
    const std::set<Index> rim = rim_vertices(surface.surface());
    Scalar off_plane = 0;
    for (Index v : rim) off_plane = std::max(off_plane, std::abs(surface.surface().vertices(0, v) - 3));
    INFO("normal " << normal << ": " << rim.size() << " rim vertices, off the plane by " << off_plane);
    CHECK(count_pieces(surface.surface()) == 2);
    CHECK(!rim.empty());
    CHECK(off_plane < 1e-12);
  }
  for (const Scalar x : {2.5, 3.5}) {
    Solver<Hex8, Corotational, NoPlasticity, Heaviside> s(mesh, Material{3000, 0.45, 1.0});
    s.cut(CutPlane(Vec3(x, 0, 0), Vec3(1, 0, 0)));
    surface.update(s);
    Scalar off_plane = 0;
    for (Index v : rim_vertices(surface.surface())) off_plane = std::max(off_plane, std::abs(surface.surface().vertices(0, v) - x));
    INFO("cut at x = " << x);
    CHECK(count_pieces(surface.surface()) == 2);
    CHECK(off_plane < 1e-12);
  }
  // A field without the enriched rows, in a cut body, is refused rather than read past its end.
  Solver<Hex8, Corotational, NoPlasticity, Heaviside> s(mesh, Material{3000, 0.45, 1.0});
  s.cut(CutPlane(Vec3(3.3, 0, 0), Vec3(1, 0, 0)));
  EmbeddedPoints<Hex8> points(mesh, std::vector<Vec3>{Vec3(3.2, 2, 2)});
  points.assign_sides(s.enrichment());
  Eigen::Matrix3Xd out;
  CHECK_THROWS_AS(points.interpolate(Vector::Zero(3 * mesh.num_nodes()), out, s.enrichment()), InvalidArgument);
  // The enrichment's accessors by cut and node are checked (found by review, 2026-12-02:
  // level_set(3, 0) with one cut crashed, geometry(7) returned a corrupt variant).
  int known = 0;  // the level set is evaluated near the cut only (NaN elsewhere)
  for (Index i = 0; i < mesh.num_nodes(); ++i) known += std::isfinite(s.enrichment().level_set(0, i));
  CHECK(known > 0);
  CHECK_THROWS_AS(s.enrichment().level_set(3, 0), InvalidArgument);
  CHECK_THROWS_AS(s.enrichment().level_set(-1, 0), InvalidArgument);
  CHECK_THROWS_AS(s.enrichment().level_set(0, mesh.num_nodes()), InvalidArgument);
  CHECK_THROWS_AS(s.enrichment().geometry(7), InvalidArgument);
  CHECK_NOTHROW(s.enrichment().geometry(0));
  // The surface's VTU has its points moved already: deform_by would move them twice.
  io::VtuOptions warp;
  warp.deform_by = "displacement";
  CHECK_THROWS_AS(surface.write_vtu("unused.vtu", warp), InvalidArgument);
}
