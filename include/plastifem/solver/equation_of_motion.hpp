#pragma once
// The operator every solve balances: the semi-discrete equation of motion (seed 001 eq. 20)
//   r(u, v, a; t) = M a + D v + f_int(u) - f_ext(t) = 0  at the free dofs,
//   D = alpha M + beta Kd (Rayleigh; Kd the projected tangent where the integrator takes it),
// with its derivatives K = df_int/du (exact or projected) and Kd. The integrators beside it
// choose where it is evaluated and solve r = 0: solver/dynamics.hpp (Newmark, generalized-alpha:
// a and v from u, and the balance weighted between t_n and t_{n+1}, solver/newmark.hpp),
// solver/statics.hpp (a = v = 0). observables::reaction_forces evaluates it at a committed
// state. The split is MFEM's TimeDependentOperator / ODESolver one: a new implicit scheme is a
// new integrator, the residual and its matrices stay here.
#include <plastifem/solver/loads.hpp>
#include <plastifem/solver/state.hpp>
#include <plastifem/solver/system.hpp>

#include <algorithm>

namespace plastifem {

/// What a solve works with: the parts of a Solver, by reference.
template <FiniteElement E, class Elastic, bool Enriched = false>
struct SolverParts {
  Discretization<E, Elastic, Enriched>& body;
  System<E, Elastic, Enriched>& system;
  const Constraints& constraints;
  const Loads<E>& loads;
  const SolverSettings& settings;
  int threads;

  /// What an acceleration solved now balances (MotionState::balance).
  Balance balance() const {
    return {loads.version(), constraints.version(), settings.mass, settings.rayleigh_mass, settings.rayleigh_stiffness};
  }
};

template <FiniteElement E, class Elastic, bool Enriched = false>
class EquationOfMotion {
 public:
  using Parts = SolverParts<E, Elastic, Enriched>;
  static constexpr bool constant_tangent = Elastic::constant_tangent;

  /// The inertia and damping terms of one evaluation; a null pointer leaves its term out
  /// (statics: a and v, `Motion{}`). The generalized-alpha balance, divided by 1 - alpha_f,
  /// weights the inertia and adds the step's fixed history term (only with an inertia term):
  ///   r = w_m M a + h_n + f_int - f_ext + D v   (solver/newmark.hpp: w_m, h_n).
  struct Motion {
    const Vector* a = nullptr;
    const Vector* v = nullptr;
    const Vector* history = nullptr;
    Scalar mass_weight = 1;
  };
  /// |r| at the free dofs, and the largest of the balance's other terms there (|f_int|, the
  /// inertia's, the damping's): with |f_ext| the scale Newton's relative tolerance refers to.
  struct Norms {
    Scalar residual = 0, largest_term = 0;
  };

  /// Sizes the scratch vectors (no allocation per evaluation afterwards).
  void resize(Index n) {
    for (Vector* x : {&damping_, &work_, &u_rel_}) x->setZero(n);
  }

  /// f = f_int(u), and K(u) into the system's K when asked. Constant-tangent models: K
  /// assembled once per rest-shape epoch, f_int = K (u - u_rest) (Linear: K0 (x - X0) = K u
  /// while the rest shapes are the mesh's; u_rest = x - X after plastic flow). false if some
  /// element cannot be evaluated.
  bool internal_force(Parts& p, const Vector& u, Vector& f, bool with_tangent, TangentKind kind) {
    if constexpr (constant_tangent) {
      const auto epoch = p.body.data().epoch();
      if (!p.system.constant_tangent_current(epoch)) {
        if (!p.system.assemble(p.body, u, f, true, kind, p.threads)) return false;  // not recorded: assembled again
        p.system.set_constant_tangent_current(epoch);
      }
      if (p.body.has_rest_displacement()) {  // plastic flow moved the rest shapes: f = K (u - u_rest)
        u_rel_ = u - p.body.rest_displacement();
        p.system.K.multiply(u_rel_, f, p.threads);
      } else {
        p.system.K.multiply(u, f, p.threads);
      }
      return f.allFinite();
    } else {
      return p.system.assemble(p.body, u, f, with_tangent, kind, p.threads);
    }
  }

  /// The system's Kd = K_proj(u) (System::damping_stiffness_at). false if some element cannot be
  /// evaluated at u (inverted, for an energy with ln J).
  static bool damping_stiffness_at(Parts& p, const Vector& u) {
    if (p.settings.rayleigh_stiffness == 0) return true;
    return p.system.damping_stiffness_at(p.body, u, constant_tangent, p.threads);
  }

  /// out += factor D v with the system's Kd. `out` must not be this operator's scratch.
  void add_damping(Parts& p, const Vector& v, Scalar factor, Vector& out) {
    add_rayleigh_damping(p.system.M, p.system.Kd, p.settings, v, factor, out, work_, p.threads);
  }

  /// r = the residual of the equation of motion for `m`, given f_int(u) (internal_force) and
  /// f_ext, with the system's M and Kd.
  Norms residual(Parts& p, const Motion& m, const Vector& f_int, const Vector& f_ext, Vector& r) {
    return residual(p.system, p.system.Kd, p.settings, m, f_int, f_ext, r, damping_, work_, p.threads);
  }

  /// The residual, r = [w_m M a] [+ h_n] + f_int - f_ext [+ D v] over all dofs, with the damping
  /// stiffness Kd given (the reactions take it at their own state). `damping`, `work`: scratch,
  /// distinct from r; all three sized here (once: no allocation in a step loop afterwards). The
  /// terms are added in the order the Newmark step always added them, so its results keep their
  /// bits. (Formed elsewhere: generalized-alpha's h_n, Dynamics::weighted_history, and the real-
  /// time step's K (g - u_n), the prescribed motion through its linearisation.)
  template <class SystemT>
  static Norms residual(const SystemT& system, const BlockSymmetricMatrix& Kd, const SolverSettings& s, const Motion& m,
                        const Vector& f_int, const Vector& f_ext, Vector& r, Vector& damping, Vector& work,
                        int threads) {
    Norms norms;
    const Index n = f_int.size();
    r.resize(n), work.resize(n);
    eigen_assert((m.a || !m.history) && "EquationOfMotion::residual: a history term weights an inertia term");
    if (m.a) {
      system.M.multiply(*m.a, r, threads);
      if (m.mass_weight != 1) r *= m.mass_weight;
      if (m.history) r += *m.history;
      norms.largest_term = system.free_norm(r);
      r += f_int - f_ext;
    } else {
      r = f_int - f_ext;
    }
    if (m.v && has_rayleigh_damping(s)) {
      damping.setZero(n);
      add_rayleigh_damping(system.M, Kd, s, *m.v, 1.0, damping, work, threads);
      norms.largest_term = std::max(norms.largest_term, system.free_norm(damping));
      r += damping;
    }
    norms.largest_term = std::max(norms.largest_term, system.free_norm(f_int));
    norms.residual = system.free_norm(r);
    return norms;
  }

  /// Forms the Newton matrix A = cm M + K + cd Kd in the system unless it holds that matrix
  /// already: a constant tangent (Linear) formed with the same coefficients, or `current` (the
  /// tangent has not changed since it was formed). Returns whether the matrix was kept (the
  /// linear solver then reuses its factorisation or preconditioner).
  static bool form_matrix(Parts& p, Scalar cm, Scalar cd, bool current) {
    bool same = current;
    if constexpr (constant_tangent) same = p.system.same_coefficients(cm, cd);
    if (!same) p.system.form(cm, cd, p.threads);
    return same;
  }

 private:
  Vector damping_, work_, u_rel_;
};

}  // namespace plastifem
