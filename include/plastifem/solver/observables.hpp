#pragma once
// What a simulator reads off a committed state: forces, energies, reactions, the tangent. Each
// is a function of the parts the Solver holds (the body, assembly/discretization.hpp; the system,
// system.hpp; the loads) and of a state, so that the Solver only forwards to it.
#include <plastifem/solver/equation_of_motion.hpp>

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

/// Reaction forces at the system's constrained dofs of state s (zero elsewhere): the equation of
/// motion's residual there, f_int(u) + M a + D v - f_ext(t) (solver/equation_of_motion.hpp), with
/// D = alpha M + beta Kd and Kd the projected tangent at u (the step takes it at its predicted
/// end; here there is no step to predict, so at the state itself).
/// The residual is the committed body's at t_{n+1}, so the reactions balance the loads and the
/// inertia exactly where the step balanced that body there: after a step in which the material
/// flowed, the element data are the flowed rest shapes (the plastic update follows the step,
/// seed 000) and the reactions carry that change's imbalance (0.1% of the total on a clamped
/// bar in which 590 points yielded in one step); with generalized-alpha the free dofs balance at
/// the weighted instant, not at t_{n+1}, and the reactions miss their imbalance there (0.5-2%
/// on a damped bar at rho_inf = 0.8). A state whose acceleration balances nothing yet (before the
/// first step, or after the loads, constraints or inertia settings changed: MotionState::balance)
/// is taken with the acceleration it holds, which the next step replaces by equilibrium's; with
/// the consistent mass its inertia coupling M_cf a_f is then missing from the reactions.
template <FiniteElement E, class Elastic, bool Enriched, class State>
Vector reaction_forces(const Discretization<E, Elastic, Enriched>& body, const System<E, Elastic, Enriched>& system,
                       const Loads<E>& loads, const SolverSettings& settings, const State& s, int threads) {
  using Equation = EquationOfMotion<E, Elastic, Enriched>;
  const Index n = body.num_dofs();
  Vector f(n), fe(n), r(n), damping(n), work(n);
  const bool stiffness_damping = settings.rayleigh_stiffness != 0;
  BlockSymmetricMatrix Kd;
  if (stiffness_damping) Kd = body.assembler().zero_matrix();
  body.assemble(s.u, f, stiffness_damping ? &Kd : nullptr, TangentKind::Projected, threads);
  loads.assemble(s.t, fe);
  Equation::residual(system, Kd, settings, {&s.a, &s.v, nullptr, 1}, f, fe, r, damping, work, threads);
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
