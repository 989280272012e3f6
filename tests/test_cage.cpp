// The cage around a closed surface (embedding/cage.hpp).
//
// Facts checked:
//  - a box whose faces lie inside cells in z and on the grid in x and y: every cell's fraction is
//    exact (the inside along each vertical line is exact), 0.6 in the partial layers, 1 inside;
//  - the cage of a sphere represents the enclosed volume, sum fraction x cell volume, within the
//    line sampling's error, which falls under refinement; deep cells have fraction 1; Tet4 and
//    Tet10 cages have the Hex8 cage's inside volume to round-off;
//  - every vertex of the surface lies in the cage (it embeds), for every element;
//  - open or inward-facing surfaces and bad cell sizes are refused.
#include "catch.hpp"

#include <plastifem/embedding/cage.hpp>
#include <plastifem/embedding/embedded_points.hpp>

#include <numbers>

using namespace plastifem;

namespace {

/// The box [lo, hi] as 12 outward triangles.
TriangleSurface box_surface(const Vec3& lo, const Vec3& hi) {
  TriangleSurface b;
  b.vertices.resize(3, 8);
  for (int i = 0; i < 8; ++i) b.vertices.col(i) = Vec3(i & 1 ? hi.x() : lo.x(), i & 2 ? hi.y() : lo.y(), i & 4 ? hi.z() : lo.z());
  b.triangles = {{0, 2, 1}, {1, 2, 3}, {4, 5, 6}, {5, 7, 6}, {0, 1, 4}, {1, 5, 4},
                 {2, 6, 3}, {3, 6, 7}, {0, 4, 2}, {2, 4, 6}, {1, 3, 5}, {3, 7, 5}};
  return b;
}

}  // namespace

TEST_CASE("cage: exact fractions of a box cut by cell layers", "[cage]") {
  // [0, 1] x [0, 1] x [0.1, 0.9] with cells of 0.25: the grid is centred on the box, so x and y
  // fill 4 cells each and z spans 4 layers [0, 0.25] ... [0.75, 1] with 0.15 / 0.25 = 0.6 of the
  // end layers inside.
  const Cage<Hex8> cage = cage_around<Hex8>(box_surface(Vec3(0, 0, 0.1), Vec3(1, 1, 0.9)), 0.25);
  CHECK(cage.cells == std::array<int, 3>{4, 4, 4});
  CHECK(cage.mesh.num_elements() == 64);
  Scalar worst = 0;
  for (size_t e = 0; e < cage.fraction.size(); ++e) {
    const int k = cage.cell[e][2];
    worst = std::max(worst, std::abs(cage.fraction[e] - (k == 0 || k == 3 ? 0.6 : 1.0)));
  }
  INFO("largest fraction error " << worst);
  CHECK(worst < 1e-14);
  CHECK(std::abs(cage.inside_volume() - 0.8) < 1e-14);
}

TEMPLATE_TEST_CASE("cage: a sphere's volume under refinement, every vertex embedded", "[cage]", Hex8, Tet4, Tet10) {
  using E = TestType;
  const TriangleSurface sphere = sphere_surface(Vec3(0.3, -0.2, 0.1), 1.0, 4);
  const Scalar V = enclosed_volume(sphere, sphere.vertices);
  std::vector<Scalar> errors;
  for (const Scalar h : {0.5, 0.25, 0.125}) {
    const Cage<E> cage = cage_around<E>(sphere, h);
    const Scalar error = std::abs(cage.inside_volume() - V) / V;
    const Scalar added = (cage.weighted_volume() - cage.inside_volume()) / V;
    INFO("h = " << h << ": " << cage.mesh.num_elements() << " elements, volume error " << error
                << ", the floor weight adds " << added);
    // The midpoint rule over 8 x 8 lines per cell: O((h / 8)^2) times the surface's curvature.
    CHECK(error < 0.005);
    errors.push_back(error);
    CHECK(added >= 0);
    CHECK(added < 0.01);
    // The cell at the centre is wholly inside.
    Scalar largest = 0;
    for (Scalar f : cage.fraction) largest = std::max(largest, f);
    CHECK(largest == 1.0);
    if (h == 0.25) {
      const Cage<Hex8> hex = cage_around<Hex8>(sphere, h);
      CHECK(std::abs(cage.inside_volume() - hex.inside_volume()) < 1e-12 * V);
      CHECK_NOTHROW(EmbeddedPoints<E>(cage.mesh, sphere.vertices));  // every vertex in an element
    }
  }
  CHECK(errors.back() < errors.front() / 2);  // converging (not monotonically: cancellation)
}

TEST_CASE("cage: open or inward surfaces and bad cell sizes are refused", "[cage]") {
  TriangleSurface box = box_surface(Vec3::Zero(), Vec3::Ones());
  CHECK_THROWS_AS(cage_around<Hex8>(box, 0), InvalidArgument);
  CHECK_THROWS_AS(cage_around<Hex8>(box, std::numeric_limits<Scalar>::quiet_NaN()), InvalidArgument);
  CHECK_THROWS_AS(cage_around<Hex8>(box, 1e-6), InvalidArgument);  // 1e6 cells a side
  TriangleSurface open = box;
  open.triangles.pop_back();
  CHECK_THROWS_AS(cage_around<Hex8>(open, 0.25), InvalidArgument);
  TriangleSurface inward = box;
  for (Triangle& t : inward.triangles) std::swap(t[1], t[2]);
  CHECK_THROWS_AS(cage_around<Hex8>(inward, 0.25), InvalidArgument);
}
