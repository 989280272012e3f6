#pragma once
// Trilinear hexahedron, 8 nodes, on the reference cube [-1, 1]^3.
//
//        7-----------6          reference nodes (xi, eta, zeta):
//       /|          /|            0 (-1,-1,-1)  1 ( 1,-1,-1)  2 ( 1, 1,-1)  3 (-1, 1,-1)
//      / |         / |            4 (-1,-1, 1)  5 ( 1,-1, 1)  6 ( 1, 1, 1)  7 (-1, 1, 1)
//     4-----------5  |
//     |  3--------|--2          VTK_HEXAHEDRON (12), Gmsh type 5: same numbering.
//     | /  zeta   | /
//     |/   | eta  |/            N_i = (1 + xi xi_i)(1 + eta eta_i)(1 + zeta zeta_i) / 8
//     0----+-- xi-1
#include <plastifem/element/face.hpp>
#include <plastifem/element/quadrature.hpp>

#include <array>

namespace plastifem {

struct Hex8 {
  static constexpr const char* name = "Hex8";
  static constexpr int num_nodes = 8;
  static constexpr int num_vertices = 8;
  static constexpr int order = 1;
  static constexpr int vtk_cell_type = 12, gmsh_type = 5;
  static constexpr std::array<int, 8> gmsh_nodes{0, 1, 2, 3, 4, 5, 6, 7};  ///< Gmsh's order is VTK's
  static constexpr Scalar reference_volume = 8.0;

  /// Faces with outward normals by the right-hand rule; Quad4.
  static constexpr int num_faces = 6, nodes_per_face = 4;
  static constexpr FaceShape face_shape(int /*face*/) { return FaceShape::quadrilateral4; }
  static constexpr std::array<std::array<int, 4>, 6> faces{
      {{0, 3, 2, 1}, {4, 5, 6, 7}, {0, 1, 5, 4}, {1, 2, 6, 5}, {2, 3, 7, 6}, {3, 0, 4, 7}}};
  static constexpr std::array<std::array<int, 2>, 12> edges{{{0, 1}, {1, 2}, {2, 3}, {3, 0},
                                                             {4, 5}, {5, 6}, {6, 7}, {7, 4},
                                                             {0, 4}, {1, 5}, {2, 6}, {3, 7}}};

  using ShapeVector = Eigen::Matrix<Scalar, num_nodes, 1>;
  using ShapeGradient = Eigen::Matrix<Scalar, num_nodes, 3>;
  using NodeMatrix = Eigen::Matrix<Scalar, 3, num_nodes>;

  static constexpr Scalar sign[8][3] = {{-1, -1, -1}, {1, -1, -1}, {1, 1, -1}, {-1, 1, -1},
                                        {-1, -1, 1},  {1, -1, 1},  {1, 1, 1},  {-1, 1, 1}};

  static NodeMatrix reference_nodes() {
    NodeMatrix X;
    for (int i = 0; i < 8; ++i) X.col(i) = Vec3(sign[i][0], sign[i][1], sign[i][2]);
    return X;
  }

  static ShapeVector shape(const Vec3& p) {
    ShapeVector N;
    for (int i = 0; i < 8; ++i)
      N[i] = 0.125 * (1 + sign[i][0] * p.x()) * (1 + sign[i][1] * p.y()) * (1 + sign[i][2] * p.z());
    return N;
  }

  static ShapeGradient gradient(const Vec3& p) {
    ShapeGradient G;
    for (int i = 0; i < 8; ++i) {
      const Scalar a = 1 + sign[i][0] * p.x(), b = 1 + sign[i][1] * p.y(), c = 1 + sign[i][2] * p.z();
      G(i, 0) = 0.125 * sign[i][0] * b * c;
      G(i, 1) = 0.125 * a * sign[i][1] * c;
      G(i, 2) = 0.125 * a * b * sign[i][2];
    }
    return G;
  }

  /// Smallest tensor Gauss rule exact for per-variable degree `Degree`.
  template <int Degree>
  static auto quadrature() {
    static_assert(Degree >= 0 && Degree <= 5, "hexahedron rules are tabulated up to 3x3x3 (degree 5)");
    return hex_gauss<(Degree + 2) / 2>();
  }
  /// Full integration: stiffness 2x2x2 (the textbook rule, exact for the stiffness of a
  /// parallelepiped); mass 3x3x3, exact for trilinear geometry: N_a N_b has per-variable degree
  /// 2 and det J of a distorted (non-parallelepiped) hex degree 2 more. 2x2x2 was exact for
  /// parallelepipeds only, and the thick shells and tubes plasticity targets are not.
  static constexpr int stiffness_degree = 2, mass_degree = 4;
  /// det J of a trilinear hex has per-variable degree 2: 2x2x2 Gauss gives the exact volume.
  static constexpr int volume_degree = 2;

  /// Whether reference coordinates lie in the element (within tol).
  static bool contains(const Vec3& xi, Scalar tol) { return (xi.array().abs() <= 1 + tol).all(); }

  /// Six tetrahedra on the nodes, all around the diagonal 0-6 (X-FEM cuts split these).
  static constexpr std::array<std::array<int, 4>, 6> sub_tetrahedra{
      {{0, 1, 2, 6}, {0, 1, 5, 6}, {0, 3, 2, 6}, {0, 3, 7, 6}, {0, 4, 5, 6}, {0, 4, 7, 6}}};
  /// Degrees of the integrands on a tetrahedral piece of the element, in reference coordinates
  /// (the X-FEM pieces' rules): linear elasticity's B^T D B det J on an affine hex has degree
  /// <= 2 in each variable and <= 4 in all (dN/dxi is bilinear in the other two coordinates);
  /// the mass N_a N_b det J total degree 6.
  static constexpr int piece_stiffness_degree = 4, piece_stiffness_variable_degree = 2, piece_mass_degree = 6;
};

}  // namespace plastifem
