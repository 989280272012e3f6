#pragma once
// A mesh with every node moved by a round-off-sized amount: the same problem to the eye, a
// different input to the floating point. Tests that a result is no accident of one mesh's
// round-off run on both (test_extremes.cpp, test_hyperelastic.cpp).
#include <plastifem/plastifem.hpp>

#include <cmath>

/// `mesh` with node i moved by `amplitude` (sin 7.1 i, cos 3.3 i, sin 1.7 i): deterministic,
/// different for every node; the node and face sets are kept.
template <class E>
plastifem::Mesh<E> moved_mesh(const plastifem::Mesh<E>& mesh, plastifem::Scalar amplitude) {
  using namespace plastifem;
  Eigen::Matrix3Xd X = mesh.nodes();
  for (Index i = 0; i < X.cols(); ++i)
    X.col(i) += amplitude * Vec3(std::sin(7.1 * i), std::cos(3.3 * i), std::sin(1.7 * i));
  Mesh<E> moved(X, mesh.elements());
  for (const auto& [name, ids] : mesh.node_sets()) moved.add_node_set(name, ids);
  for (const auto& [name, faces] : mesh.face_sets()) moved.add_face_set(name, faces);
  return moved;
}
