#pragma once
// Quadratic tetrahedron, 10 nodes: the Tet4 corners and one node at the middle of each edge.
//
//            3                  corners as Tet4; mid-edge nodes:
//           /|\                   4 (0,1)   5 (1,2)   6 (0,2)
//          7 | 9                  7 (0,3)   8 (1,3)   9 (2,3)
//         /  8  \            (node 8 sits on the back edge 1-3)
//        0 --|6-- 2             VTK_QUADRATIC_TETRA (24). Gmsh type 11 numbers the last
//         \  |  /               two the other way round (Gmsh 8 = edge (2,3), 9 = (1,3));
//          4 | 5                the Gmsh reader swaps them.
//            1
//
// With barycentric L = (1 - x - y - z, x, y, z): corner i: L_i (2 L_i - 1); edge (i, j): 4 L_i L_j.
#include <plastifem/element/face.hpp>
#include <plastifem/element/quadrature.hpp>

#include <array>

namespace plastifem {

struct Tet10 : TetrahedronQuadrature {
  static constexpr const char* name = "Tet10";
  static constexpr int num_nodes = 10;
  static constexpr int num_vertices = 4;
  static constexpr int order = 2;
  static constexpr int vtk_cell_type = 24, gmsh_type = 11;
  /// Local node k is Gmsh's node gmsh_nodes[k]: Gmsh numbers the last two mid-edge nodes the
  /// other way round (its 8 on edge (2,3), 9 on (1,3)).
  static constexpr std::array<int, 10> gmsh_nodes{0, 1, 2, 3, 4, 5, 6, 7, 9, 8};
  static constexpr Scalar reference_volume = 1.0 / 6.0;

  /// Faces with outward normals: three corners, then the mid-edge nodes between them; Tri6.
  static constexpr int num_faces = 4, nodes_per_face = 6;
  static constexpr FaceShape face_shape(int /*face*/) { return FaceShape::triangle6; }
  static constexpr std::array<std::array<int, 6>, 4> faces{{{0, 2, 1, 6, 5, 4},
                                                            {0, 1, 3, 4, 8, 7},
                                                            {0, 3, 2, 7, 9, 6},
                                                            {1, 2, 3, 5, 9, 8}}};
  /// Edges as (corner, corner); the node on edge k is 4 + k.
  static constexpr std::array<std::array<int, 2>, 6> edges{{{0, 1}, {1, 2}, {0, 2}, {0, 3}, {1, 3}, {2, 3}}};

  using ShapeVector = Eigen::Matrix<Scalar, num_nodes, 1>;
  using ShapeGradient = Eigen::Matrix<Scalar, num_nodes, 3>;
  using NodeMatrix = Eigen::Matrix<Scalar, 3, num_nodes>;

  template <class L = void>  // see Lazy (core/types.hpp)
  static Eigen::Matrix<Lazy<L>, 3, num_nodes> reference_nodes() {
    Eigen::Matrix<Lazy<L>, 3, num_nodes> X;
    X.template leftCols<4>() << 0, 1, 0, 0,
                       0, 0, 1, 0,
                       0, 0, 0, 1;
    for (int k = 0; k < 6; ++k) X.col(4 + k) = 0.5 * (X.col(edges[k][0]) + X.col(edges[k][1]));
    return X;
  }

  template <class L = void>  // see Lazy (core/types.hpp)
  static Eigen::Matrix<Lazy<L>, num_nodes, 1> shape(const Vec3& p_) {
    const Eigen::Matrix<Lazy<L>, 3, 1>& p = p_;
    const Scalar l[4] = {1.0 - p.x() - p.y() - p.z(), p.x(), p.y(), p.z()};
    Eigen::Matrix<Lazy<L>, num_nodes, 1> N;
    for (int i = 0; i < 4; ++i) N[i] = l[i] * (2.0 * l[i] - 1.0);
    for (int k = 0; k < 6; ++k) N[4 + k] = 4.0 * l[edges[k][0]] * l[edges[k][1]];
    return N;
  }

  template <class L = void>  // see Lazy (core/types.hpp)
  static Eigen::Matrix<Lazy<L>, num_nodes, 3> gradient(const Vec3& p_) {
    const Eigen::Matrix<Lazy<L>, 3, 1>& p = p_;
    const Scalar l[4] = {1.0 - p.x() - p.y() - p.z(), p.x(), p.y(), p.z()};
    // dL_i/dx: rows of the Tet4 gradient.
    const Scalar dL[4][3] = {{-1, -1, -1}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
    Eigen::Matrix<Lazy<L>, num_nodes, 3> G;
    for (int i = 0; i < 4; ++i)
      for (int d = 0; d < 3; ++d) G(i, d) = (4.0 * l[i] - 1.0) * dL[i][d];
    for (int k = 0; k < 6; ++k) {
      const int i = edges[k][0], j = edges[k][1];
      for (int d = 0; d < 3; ++d) G(4 + k, d) = 4.0 * (dL[i][d] * l[j] + l[i] * dL[j][d]);
    }
    return G;
  }

  /// Full integration: gradients are linear (stiffness degree 2), mass is quadratic^2.
  static constexpr int stiffness_degree = 2, mass_degree = 4;
  /// det J of a quadratic tet (curved edges) has degree 3.
  static constexpr int volume_degree = 3;

  /// Whether reference coordinates lie in the element (within tol).
  static bool contains(const Vec3& xi, Scalar tol) { return (xi.array() >= -tol).all() && xi.sum() <= 1 + tol; }

  /// Eight tetrahedra on the nodes: one at each corner, four around the diagonal 6-8.
  static constexpr std::array<std::array<int, 4>, 8> sub_tetrahedra{{{0, 4, 6, 7}, {4, 1, 5, 8}, {6, 5, 2, 9}, {7, 8, 9, 3},
                                                                    {6, 8, 4, 5}, {6, 8, 5, 9}, {6, 8, 9, 7}, {6, 8, 7, 4}}};
  /// Degrees of the integrands on a tetrahedral piece of an affine Tet10 (the X-FEM pieces'
  /// rules): stiffness (linear gradients) 2, mass N_a N_b 4.
  static constexpr int piece_stiffness_degree = 2, piece_stiffness_variable_degree = 2, piece_mass_degree = 4;
};

}  // namespace plastifem
