#pragma once
// What a simulator reads off a committed state: forces, energies, reactions, the tangent. Each
// is a function of the parts the Solver holds (the body, assembly/discretization.hpp; the system,
// system.hpp; the loads) and of a state, so that the Solver only forwards to it.
#include <plastifem/solver/loads.hpp>
#include <plastifem/solver/system.hpp>

#include <vector>

namespace plastifem::observables {

/// Internal elastic forces f_int(u).
template <class Body>
Vector internal_force(const Body& body, const Vector& u, int threads) {
  Vector f(body.num_dofs());
  body.assemble(u, f, nullptr, TangentKind::Projected, threads);
  return f;
}

/// The tangent stiffness at u, of the given kind, in full symmetric storage.
template <class Body>
SparseMatrix tangent(const Body& body, const Vector& u, TangentKind kind, int threads) {
  BlockSymmetricMatrix K = body.assembler().zero_matrix();
  Vector f(body.num_dofs());
  body.assemble(u, f, &K, kind, threads);
  return K.to_sparse();
}

/// Kinetic energy v^T M v / 2 (`work`: any vector, resized as needed).
template <class System>
Scalar kinetic_energy(const System& system, const Vector& v, Vector& work, int threads) {
  work.resize(v.size());
  system.M.multiply(v, work, threads);
  return 0.5 * v.dot(work);
}

/// Work potential of the external loads at time t: f_ext(t) . u.
template <class Loads>
Scalar external_work_potential(const Loads& loads, Scalar t, const Vector& u) {
  Vector f(u.size());
  loads.assemble(t, f);
  return f.dot(u);
}

/// Reaction forces at the system's constrained dofs of state s (zero elsewhere):
/// f_int(u) + M a + D v - f_ext(t), D = alpha M + beta Kd with Kd the projected tangent at u
/// (the damping of solver/dynamics.hpp, taken at the state itself: there is no step to predict).
template <class Body, class System, class Loads, class State>
Vector reaction_forces(const Body& body, const System& system, const Loads& loads, const SolverSettings& settings,
                       const State& s, int threads) {
  const Index n = body.num_dofs();
  Vector f(n), fe(n), r(n), w(n);
  const bool stiffness_damping = settings.rayleigh_stiffness != 0;
  BlockSymmetricMatrix Kd;
  if (stiffness_damping) Kd = body.assembler().zero_matrix();
  body.assemble(s.u, f, stiffness_damping ? &Kd : nullptr, TangentKind::Projected, threads);
  loads.assemble(s.t, fe);
  system.M.multiply(s.a, r, threads);
  r += f - fe;
  add_rayleigh_damping(system.M, Kd, settings, s.v, 1.0, r, w, threads);
  for (Index i = 0; i < n; ++i)
    if (!system.constrained(i)) r[i] = 0;
  return r;
}

/// The von Mises stress of each stress tensor.
inline Vector von_mises_stress(const std::vector<Mat3>& stress) {
  Vector vm(static_cast<Index>(stress.size()));
  for (size_t e = 0; e < stress.size(); ++e) vm[static_cast<Index>(e)] = von_mises(stress[e]);
  return vm;
}

}  // namespace plastifem::observables
