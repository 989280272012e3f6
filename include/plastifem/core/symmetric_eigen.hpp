#pragma once
// Eigen-decomposition of small symmetric matrices (Householder tridiagonalisation, then the
// implicit QL iteration with Wilkinson-like shifts: Golub and Van Loan, Matrix Computations,
// sections 8.3; the classic tred2/tqli pair), and the projection onto the positive
// semi-definite cone built on it.
//
// Why not Eigen::SelfAdjointEigenSolver: for the 9x9 per-point tangents of the hyperelastic
// models it instantiates Householder sequences, block reflectors and its own QR, which cost
// 3.2 s of compile time in every translation unit that included the elastic models (g++ 12
// -O2; clang's -ftime-trace put it first of all instantiations). These sixty lines compile in
// a blink and run as fast (the projected Neo-Hookean Hex8 tangent, 8 decompositions: 18.7 us
// with Eigen's solver). A cyclic Jacobi tried first was twice as slow.
#include <plastifem/core/types.hpp>

#include <cmath>
#include <limits>

namespace plastifem {

namespace detail {

/// sqrt(a^2 + b^2): the plain formula, std::hypot only where it over- or underflows (glibc's
/// correctly rounded hypot cost a fifth of a plastic update's flow, on 3x3 decompositions).
inline Scalar pythag(Scalar a, Scalar b) {
  const Scalar r = std::sqrt(a * a + b * b);
  if (std::isfinite(r) && (r > 1e-150 || (a == 0 && b == 0))) return r;
  return std::hypot(a, b);
}

}  // namespace detail

/// Eigenvalues and orthonormal eigenvectors (columns) of the symmetric matrix A.
template <int N>
void symmetric_eigen(const Eigen::Matrix<Scalar, N, N>& A, Eigen::Matrix<Scalar, N, 1>& values,
                     Eigen::Matrix<Scalar, N, N>& vectors) {
  // Row-major working copy a[i][j] = A(i, j); on exit of the reduction it holds Q.
  Scalar a[N][N], d[N], e[N];
  for (int i = 0; i < N; ++i)
    for (int j = 0; j < N; ++j) a[i][j] = A(i, j);
  // Householder reduction to tridiagonal form: d the diagonal, e the sub-diagonal (e[i]
  // couples i - 1 and i).
  for (int i = N - 1; i > 0; --i) {
    const int l = i - 1;
    Scalar h = 0, scale = 0;
    if (l > 0) {
      for (int k = 0; k < i; ++k) scale += std::abs(a[i][k]);
      if (scale == 0) {
        e[i] = a[i][l];
      } else {
        for (int k = 0; k < i; ++k) {
          a[i][k] /= scale;
          h += a[i][k] * a[i][k];
        }
        Scalar f = a[i][l];
        Scalar g = f >= 0 ? -std::sqrt(h) : std::sqrt(h);
        e[i] = scale * g;
        h -= f * g;
        a[i][l] = f - g;
        f = 0;
        for (int j = 0; j < i; ++j) {
          a[j][i] = a[i][j] / h;
          g = 0;
          for (int k = 0; k <= j; ++k) g += a[j][k] * a[i][k];
          for (int k = j + 1; k < i; ++k) g += a[k][j] * a[i][k];
          e[j] = g / h;
          f += e[j] * a[i][j];
        }
        const Scalar hh = f / (h + h);
        for (int j = 0; j < i; ++j) {
          f = a[i][j];
          e[j] = g = e[j] - hh * f;
          for (int k = 0; k <= j; ++k) a[j][k] -= f * e[k] + g * a[i][k];
        }
      }
    } else {
      e[i] = a[i][l];
    }
    d[i] = h;
  }
  d[0] = 0;
  e[0] = 0;
  // Accumulate the transformations into Q (in a).
  for (int i = 0; i < N; ++i) {
    if (d[i] != 0) {
      for (int j = 0; j < i; ++j) {
        Scalar g = 0;
        for (int k = 0; k < i; ++k) g += a[i][k] * a[k][j];
        for (int k = 0; k < i; ++k) a[k][j] -= g * a[k][i];
      }
    }
    d[i] = a[i][i];
    a[i][i] = 1;
    for (int j = 0; j < i; ++j) a[j][i] = a[i][j] = 0;
  }
  // Implicit QL on the tridiagonal matrix, rotating Q's columns along.
  for (int i = 1; i < N; ++i) e[i - 1] = e[i];
  e[N - 1] = 0;
  for (int l = 0; l < N; ++l) {
    for (int iter = 0; iter < 60; ++iter) {
      int m = l;
      for (; m < N - 1; ++m) {
        const Scalar dd = std::abs(d[m]) + std::abs(d[m + 1]);
        if (std::abs(e[m]) <= std::numeric_limits<Scalar>::epsilon() * dd) break;
      }
      if (m == l) break;
      Scalar g = (d[l + 1] - d[l]) / (2 * e[l]);
      Scalar r = detail::pythag(g, Scalar(1));
      g = d[m] - d[l] + e[l] / (g + (g >= 0 ? std::abs(r) : -std::abs(r)));
      Scalar s = 1, c = 1, p = 0;
      int i = m - 1;
      bool underflow = false;
      for (; i >= l; --i) {
        const Scalar f = s * e[i], b = c * e[i];
        e[i + 1] = r = detail::pythag(f, g);
        if (r == 0) {  // recover from underflow
          d[i + 1] -= p;
          e[m] = 0;
          underflow = true;
          break;
        }
        s = f / r;
        c = g / r;
        g = d[i + 1] - p;
        r = (d[i] - g) * s + 2 * c * b;
        p = s * r;
        d[i + 1] = g + p;
        g = c * r - b;
        for (int k = 0; k < N; ++k) {
          const Scalar t = a[k][i + 1];
          a[k][i + 1] = s * a[k][i] + c * t;
          a[k][i] = c * a[k][i] - s * t;
        }
      }
      if (underflow) continue;
      d[l] -= p;
      e[l] = g;
      e[m] = 0;
    }
  }
  for (int i = 0; i < N; ++i) {
    values[i] = d[i];
    for (int j = 0; j < N; ++j) vectors(i, j) = a[i][j];
  }
}

/// true when the symmetric A is positive definite (a Cholesky factorisation succeeds).
template <int N>
bool is_positive_definite(const Eigen::Matrix<Scalar, N, N>& A) {
  Eigen::Matrix<Scalar, N, N> L = A;
  for (int j = 0; j < N; ++j) {
    Scalar d = L(j, j);
    for (int k = 0; k < j; ++k) d -= L(j, k) * L(j, k);
    if (!(d > 0)) return false;
    d = std::sqrt(d);
    L(j, j) = d;
    for (int i = j + 1; i < N; ++i) {
      Scalar v = L(i, j);
      for (int k = 0; k < j; ++k) v -= L(i, k) * L(j, k);
      L(i, j) = v / d;
    }
  }
  return true;
}

/// A <- its projection onto the positive semi-definite matrices (negative eigenvalues clamped
/// to zero); A unchanged, and cheap, when it is already positive definite.
template <int N>
void project_psd(Eigen::Matrix<Scalar, N, N>& A) {
  if (is_positive_definite<N>(A)) return;
  Eigen::Matrix<Scalar, N, 1> values;
  Eigen::Matrix<Scalar, N, N> V;
  symmetric_eigen<N>(A, values, V);
  A = V * values.cwiseMax(0.0).asDiagonal() * V.transpose();
}

}  // namespace plastifem
