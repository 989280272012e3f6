#pragma once
// Eigenvalues of a symmetric matrix, ascending, for the tests' PSD and null-space checks.
// Dynamic size on purpose: Eigen's fixed-size SelfAdjointEigenSolver for 12x12, 24x24 and 30x30
// element matrices took two of test_elastic's 2.8 minutes of compile (and most of
// test_hyperelastic's); one dynamic instantiation serves every element.
#include <plastifem/core/types.hpp>

#include <Eigen/Eigenvalues>

namespace plastifem::testing {

inline Vector symmetric_eigenvalues(const Eigen::MatrixXd& A) {
  return Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(A, Eigen::EigenvaluesOnly).eigenvalues();
}

}  // namespace plastifem::testing
