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

/// Scalar, named through a template parameter. A function that few files call is written as
/// a template of an unused parameter, `template <class L = void>`, with its types spelled
/// Lazy<L> (Eigen::Matrix<Lazy<L>, 3, 3> is Mat3): its code then depends on L, so a file that
/// does not call it compiles none of it. (Without the dependence, g++ still instantiates every
/// Eigen expression type the body names when it parses the template; with it, 44 MB of the
/// header-only Solver file's compiler memory went.) The mesh generators are still plain
/// `template <class = void>`: mostly standard containers, with a few small Eigen expressions.
template <class L>
struct LazyScalar {
  using type = Scalar;
};
template <class L>
using Lazy = typename LazyScalar<L>::type;

}  // namespace plastifem
