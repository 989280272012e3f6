#pragma once
// The kinds of element faces. An element names the kind of each of its faces (E::face_shape(f));
// the surface code (boundary search, face loads, Gmsh face groups, VTK surface output) reads
// what it needs of a face from its kind: corners, node count, VTK type, quadrature.

namespace plastifem {

enum class FaceShape {
  triangle3,      ///< 3 corners (Tet4)
  triangle6,      ///< 3 corners, then the 3 mid-edge nodes (Tet10)
  quadrilateral4  ///< 4 corners, counter-clockwise seen from outside (Hex8)
};

/// Corner nodes of a face: the first entries of its node list.
constexpr int face_corners(FaceShape s) { return s == FaceShape::quadrilateral4 ? 4 : 3; }

/// Nodes of a face.
constexpr int face_node_count(FaceShape s) {
  return s == FaceShape::triangle3 ? 3 : (s == FaceShape::triangle6 ? 6 : 4);
}

/// VTK cell type of a face: VTK_TRIANGLE (5), VTK_QUADRATIC_TRIANGLE (22), VTK_QUAD (9).
constexpr int face_vtk_type(FaceShape s) {
  return s == FaceShape::triangle3 ? 5 : (s == FaceShape::triangle6 ? 22 : 9);
}

}  // namespace plastifem
