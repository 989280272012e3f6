#pragma once
// Linear tetrahedron, 4 nodes.
//
//            z
//            3
//            |\`.
//            | \  `.            reference nodes:
//            |  \    `.           0 (0,0,0)   1 (1,0,0)
//            |   \     `.         2 (0,1,0)   3 (0,0,1)
//            0----\------2 y
//             `.   \   .'       VTK_TETRA (10), Gmsh type 4: same numbering.
//               `.  \.'
//                  1
//                 x
//
// Shape functions are the barycentric coordinates: N = (1 - x - y - z, x, y, z).
#include <plastifem/element/face.hpp>
#include <plastifem/element/quadrature.hpp>

#include <array>

namespace plastifem {

struct Tet4 : TetrahedronQuadrature {
  static constexpr const char* name = "Tet4";
  static constexpr int num_nodes = 4;
  static constexpr int num_vertices = 4;  ///< corner nodes (the first ones)
  static constexpr int order = 1;         ///< polynomial order of the shape functions
  static constexpr int vtk_cell_type = 10, gmsh_type = 4;
  static constexpr std::array<int, 4> gmsh_nodes{0, 1, 2, 3};  ///< Gmsh's order is VTK's
  static constexpr Scalar reference_volume = 1.0 / 6.0;

  /// Faces with outward normals by the right-hand rule; Tri3.
  static constexpr int num_faces = 4, nodes_per_face = 3;
  static constexpr FaceShape face_shape(int /*face*/) { return FaceShape::triangle3; }
  static constexpr std::array<std::array<int, 3>, 4> faces{{{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}}};
  static constexpr std::array<std::array<int, 2>, 6> edges{{{0, 1}, {1, 2}, {0, 2}, {0, 3}, {1, 3}, {2, 3}}};

  using ShapeVector = Eigen::Matrix<Scalar, num_nodes, 1>;
  using ShapeGradient = Eigen::Matrix<Scalar, num_nodes, 3>;
  using NodeMatrix = Eigen::Matrix<Scalar, 3, num_nodes>;

  template <class L = void>  // see Lazy (core/types.hpp)
  static Eigen::Matrix<Lazy<L>, 3, num_nodes> reference_nodes() {
    Eigen::Matrix<Lazy<L>, 3, num_nodes> X;
    X << 0, 1, 0, 0,
         0, 0, 1, 0,
         0, 0, 0, 1;
    return X;
  }

  template <class L = void>  // see Lazy (core/types.hpp)
  static Eigen::Matrix<Lazy<L>, num_nodes, 1> shape(const Vec3& p_) {
    const Eigen::Matrix<Lazy<L>, 3, 1>& p = p_;
    return {1.0 - p.x() - p.y() - p.z(), p.x(), p.y(), p.z()};
  }

  template <class L = void>  // see Lazy (core/types.hpp)
  static Eigen::Matrix<Lazy<L>, num_nodes, 3> gradient(const Vec3& /*p*/) {
    Eigen::Matrix<Lazy<L>, num_nodes, 3> G;
    G << -1, -1, -1,
          1,  0,  0,
          0,  1,  0,
          0,  0,  1;
    return G;
  }

  /// Full integration: exact stiffness (constant gradients) and exact consistent mass.
  static constexpr int stiffness_degree = 0, mass_degree = 2;
  /// det J is constant: one point gives the exact volume.
  static constexpr int volume_degree = 0;

  /// Whether reference coordinates lie in the element (within tol).
  static bool contains(const Vec3& xi, Scalar tol) { return (xi.array() >= -tol).all() && xi.sum() <= 1 + tol; }

  static constexpr std::array<std::array<int, 4>, 1> sub_tetrahedra{{{0, 1, 2, 3}}};
  /// Degrees of the integrands on a tetrahedral piece (the X-FEM pieces' rules): the stiffness
  /// integrand is constant (degree <= 1 keeps one point per piece), the mass N_a N_b degree 2.
  static constexpr int piece_stiffness_degree = 1, piece_stiffness_variable_degree = 1, piece_mass_degree = 2;
};

}  // namespace plastifem
