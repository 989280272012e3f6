#pragma once
// Scalar, index and small fixed-size vector types used everywhere in plastifem.
#include <Eigen/Dense>
#include <cstdint>

namespace plastifem {

using Scalar = double;
/// Index of a node, element or degree of freedom. Signed, as Eigen's sparse module expects.
using Index = std::int32_t;

using Vec3 = Eigen::Matrix<Scalar, 3, 1>;
using Mat3 = Eigen::Matrix<Scalar, 3, 3>;
/// A system vector: one entry per degree of freedom.
using Vector = Eigen::Matrix<Scalar, Eigen::Dynamic, 1>;

}  // namespace plastifem
