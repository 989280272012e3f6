#pragma once
// Newmark's method (beta, gamma), seed 001 section 3.5 and Newmark (1959). From t_n to
// t_{n+1} = t_n + dt, with u the unknown displacement at t_{n+1}:
//   predictor  u* = u_n + dt v_n + dt^2 / 2 a_n                      (constant acceleration)
//   a(u) = c0 (u - u_n - dt v_n) - (1 / (2 beta) - 1) a_n,           c0 = 1 / (beta dt^2)
//   v(u) = v_n + dt ((1 - gamma) a_n + gamma a(u))
//   r(u) = M a(u) + D v(u) + f_int(u) - f_ext(t_{n+1}) = 0 at the free dofs,
// and the Newton matrix dr/du = (c0 + alpha c1) M + K(u) + beta_R c1 K0, c1 = gamma / (beta dt),
// for Rayleigh damping D = alpha M + beta_R K0.
// At constrained dofs u, v and a are the prescribed path's (solver/boundary.hpp), not these
// formulas.
#include <plastifem/assembly/block_matrix.hpp>

namespace plastifem {

struct Newmark {
  Scalar beta = 0.25, gamma = 0.5, dt = 0;

  Scalar c0() const { return 1 / (beta * dt * dt); }
  Scalar c1() const { return gamma / (beta * dt); }

  /// u = u_n + dt v_n + dt^2 / 2 a_n.
  void predictor(const Vector& un, const Vector& vn, const Vector& an, Vector& u) const {
    u = un + dt * vn + (0.5 * dt * dt) * an;
  }
  /// a = a(u).
  void acceleration(const Vector& u, const Vector& un, const Vector& vn, const Vector& an, Vector& a) const {
    const Scalar c = c0();
    a = c * (u - un) - c * dt * vn - (1 / (2 * beta) - 1) * an;
  }
  /// v = v(a).
  void velocity(const Vector& a, const Vector& vn, const Vector& an, Vector& v) const {
    v = vn + dt * ((1 - gamma) * an + gamma * a);
  }
};

}  // namespace plastifem
