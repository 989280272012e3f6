#pragma once
// Newmark's method (beta, gamma), seed 001 section 3.5 and Newmark (1959), and its
// generalized-alpha extension (Chung and Hulbert 1993), which weights the balance between t_n
// and t_{n+1}. From t_n to t_{n+1} = t_n + dt, with u the unknown displacement at t_{n+1}:
//   predictor  u* = u_n + dt v_n + dt^2 / 2 a_n                      (constant acceleration)
//   a(u) = c0 (u - u_n - dt v_n) - (1 / (2 beta) - 1) a_n,           c0 = 1 / (beta dt^2)
//   v(u) = v_n + dt ((1 - gamma) a_n + gamma a(u))
// and the balance, with g(u) = f_int(u) + D v(u) - f_ext(t_{n+1}) and g_n its value at t_n:
//   (1 - alpha_m) M a(u) + alpha_m M a_n + (1 - alpha_f) g(u) + alpha_f g_n = 0
// at the free dofs (Chung-Hulbert eq. 3, with the forces weighted as in HHT, so that a
// nonlinear f_int is evaluated only at the states themselves). Divided by (1 - alpha_f):
//   r(u) = w_m M a(u) + f_int(u) + D v(u) - f_ext(t_{n+1}) + h_n = 0,
//   w_m = (1 - alpha_m) / (1 - alpha_f),  h_n = (alpha_m M a_n + alpha_f g_n) / (1 - alpha_f),
// whose Newton matrix is dr/du = (w_m c0 + alpha c1) M + K(u) + beta_R c1 Kd, c1 = gamma / (beta dt),
// for Rayleigh damping D = alpha M + beta_R Kd (Kd: the projected tangent at the step's
// predicted end, fixed within the step; solver/dynamics.hpp). alpha_m = alpha_f = 0 is
// Newmark's method itself (w_m = 1, h_n = 0), computed with the same arithmetic.
// At constrained dofs u, v and a are the prescribed path's (solver/boundary.hpp), not these
// formulas.
#include <plastifem/assembly/block_matrix.hpp>

#include <cmath>

namespace plastifem {

/// Whether the clock can take a step of dt from t: t + dt rounds to a time dt away to 1e-4.
/// The Newmark formulas use dt while the loads and paths are evaluated at fl(t + dt); at a
/// large t (an ulp of 1e9 is 1.2e-7) the two differ, and a step whose clock is off by more
/// than 1e-4 of dt is refused rather than integrated against a different time.
inline bool clock_represents(Scalar t, Scalar dt) {
  const Scalar end = t + dt;
  return std::isfinite(end) && std::abs((end - t) - dt) <= 1e-4 * dt;
}

struct Newmark {
  Scalar beta = 0.25, gamma = 0.5, dt = 0;
  Scalar alpha_m = 0, alpha_f = 0;  ///< generalized-alpha weights (0, 0: Newmark)

  Scalar c0() const { return 1 / (beta * dt * dt); }
  Scalar c1() const { return gamma / (beta * dt); }
  /// Whether the balance is weighted (generalized-alpha, HHT) rather than taken at t_{n+1}.
  bool weighted() const { return alpha_m != 0 || alpha_f != 0; }
  /// w_m = (1 - alpha_m) / (1 - alpha_f): the inertia's weight in the scaled residual.
  Scalar mass_weight() const { return (1 - alpha_m) / (1 - alpha_f); }
  /// The Newton matrix dr/du = mass M + K(u) + damping_stiffness Kd for Rayleigh damping
  /// D = alpha M + beta_R Kd: mass = w_m c0 + alpha c1, damping_stiffness = beta_R c1.
  struct MatrixCoefficients {
    Scalar mass, damping_stiffness;
  };
  MatrixCoefficients matrix(Scalar rayleigh_mass, Scalar rayleigh_stiffness) const {
    return {mass_weight() * c0() + rayleigh_mass * c1(), rayleigh_stiffness * c1()};
  }

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
