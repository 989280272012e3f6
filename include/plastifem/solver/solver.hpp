#pragma once
// Solver<Element, Elastic, Plastic, Enrichment>: the one type a simulator holds. A facade over
// the parts in this folder, each with its own header and tests:
//
//   assembly/discretization.hpp  the body: mesh, dof map, per-element data, f_int and K at any u
//   system.hpp                   matrices, held dofs, linear solvers (rebuilt with the dof map)
//   boundary.hpp, loads.hpp      constraint sets and loads, each with a handle
//   state.hpp                    u, v, a, t, ...: a step is a transaction on a trial copy
//   equation_of_motion.hpp       the operator: r = M a + D v + f_int(u) - f_ext, K, Kd, A
//   newmark.hpp, newton.hpp      the formulas, and one Newton loop for every nonlinear solve
//   dynamics.hpp, statics.hpp    the integrators: Newmark steps (accurate, real time), statics
//   step_control.hpp             automatic step cutting, commit only on success
//   observables.hpp              forces, energies, reactions, tangent of a committed state
//
// A step or static solve that fails leaves the state bit for bit as it was, whatever failed
// (Newton, CG, a NaN, an inverted element, an exception thrown by a load curve or a prescribed
// path): every change is made to a working copy, committed by a swap at the very end.
//
// The plastic axis is asked through its hooks (plastic/hooks.hpp: init, sync, after a step or
// an increment, on a cut), which are empty for NoPlasticity; the enrichment's code paths are
// discarded (if constexpr) with NoEnrichment. Neither axis's headers are included for the
// inactive policies; the active ones come with <plastifem/plasticity.hpp> and
// <plastifem/cutting.hpp>.
//
// This file is the class: what a simulator calls, documented. The member functions are in
// solver_members.hpp, included at the end (out of the class, for plastifem::compiled's sake).
#include <plastifem/core/handle_owner.hpp>
#include <plastifem/core/log.hpp>
#include <plastifem/enrichment/enrichment_policy.hpp>
#include <plastifem/plastic/hooks.hpp>
#include <plastifem/solver/observables.hpp>
#include <plastifem/solver/statics.hpp>
#include <plastifem/solver/step_control.hpp>

#include <chrono>
#include <cstdint>
#include <span>

namespace plastifem {

template <FiniteElement E, class Elastic, class Plastic = NoPlasticity, class Enrich = NoEnrichment>
  requires ElasticModel<Elastic, E>
class Solver {
  static_assert(PlasticModel<Plastic>, "the plastic policy lacks what the Solver asks of it (NoPlasticity, "
                                       "VertexBlended, CellCentered or your own: plastic/plastic.hpp, the "
                                       "PlasticModel concept)");
  static_assert(EnrichmentModel<Enrich>, "the enrichment policy lacks what the Solver asks of it (NoEnrichment, "
                                         "Heaviside, ShiftedHeaviside or your own: enrichment/enrichment_policy.hpp, "
                                         "the EnrichmentModel concept)");
  static constexpr bool enriched = Enrich::active;
  using PlasticHooksType = PlasticHooks<Plastic, E, Elastic>;  // plastic/hooks.hpp
  using LoadsType = Loads<E>;

 public:
  using Element = E;
  using ElasticModel = Elastic;
  using PlasticPolicy = Plastic;
  using EnrichmentPolicy = Enrich;
  using PlasticParamsType = typename Plastic::Params;
  using StateType = State<typename PlasticHooksType::State>;
  static constexpr int N = E::num_nodes;

  /// `plastic_params`: the plastic policy's parameters (PlasticParams for VertexBlended and
  /// CellCentered; validated).
  Solver(const Mesh<E>& mesh, const Material& material, SolverSettings settings = {},
         PlasticParamsType plastic_params = {});

  // --- problem set-up ---------------------------------------------------------------------
  const Mesh<E>& mesh() const { return body_.mesh(); }
  const Material& material() const { return body_.material(); }
  const SolverSettings& settings() const { return settings_; }
  Index num_dofs() const { return body_.num_dofs(); }
  void set_settings(const SolverSettings& s);

  /// Fixes the given nodes (all components, or those in `mask`).
  ConstraintHandle fix(std::span<const Index> nodes, DofMask mask = {}) { return prescribe(nodes, PrescribedMotion{}, mask); }
  /// Prescribes u(t, X) on the given nodes (components in `mask`); e.g. a grasper pull.
  ConstraintHandle prescribe(std::span<const Index> nodes, PrescribedDisplacement u, DofMask mask = {}) {
    return prescribe(nodes, PrescribedMotion{std::move(u), {}, {}}, mask);
  }
  /// Prescribes a path with (optionally) its exact velocity and acceleration.
  ConstraintHandle prescribe(std::span<const Index> nodes, PrescribedMotion motion, DofMask mask = {});
  /// Attaches a grasper to `nodes` where they are now: from now on each follows the grasper's
  /// translation, u_i(t) = u_i(now) + path(t) - path(now) (all components).
  ConstraintHandle grasp(std::span<const Index> nodes, std::function<Vec3(Scalar)> path);
  /// Lets go of a constraint set: its nodes move freely from their current displacement and
  /// velocity (where an earlier set constrains the same dofs, that one applies again).
  void release(ConstraintHandle h);
  /// Gives a constraint set a new motion (a grasper that changes direction). A grasp's nodes keep
  /// their offsets u_i - path at the grasp: its new path goes on from the old one's position.
  void replace(ConstraintHandle h, PrescribedMotion motion);

  /// Force `f` on each of the given nodes, scaled by `curve(t)`.
  LoadHandle add_nodal_force(std::span<const Index> nodes, const Vec3& f, LoadCurve curve = {});
  /// forces[k] on nodes[k], scaled by `curve(t)`.
  LoadHandle add_nodal_forces(std::span<const Index> nodes, std::span<const Vec3> forces, LoadCurve curve = {});
  /// A point force f at the rest position X (inside the body or on its surface), as the
  /// consistent nodal loads f N_a(xi) of the element containing X: e.g. a force at the centre
  /// of a face. Throws InvalidArgument if no element contains X.
  LoadHandle add_point_force(const Vec3& X, const Vec3& f, LoadCurve curve = {});
  /// Body force per unit mass (gravity): the consistent nodal loads rho int N_a g dV with the
  /// consistent mass, m_aa g with the lumped one, so that a free body falls at exactly g.
  LoadHandle add_gravity(const Vec3& g, LoadCurve curve = {});
  /// Traction t (force per unit reference area) on boundary faces, as consistent nodal loads.
  LoadHandle add_traction(const std::vector<FaceRef>& faces, const Vec3& t, LoadCurve curve = {});
  void remove_load(LoadHandle h);
  /// Removes every load (constraints stay).
  void clear_loads();

  /// The dof map (assembly/dof_map.hpp): block rows per (node, slot).
  const DofMap& dof_map() const { return body_.dof_map(); }

  // --- cutting (X-FEM, seed 001; enrichment/) ----------------------------------------------
  /// Cuts the body along `surface` (a CutPlane, CutPatch or CutSurface) now, at any step: the
  /// cut elements' nodes get enriched dofs (appended after the existing ones), which start at
  /// zero, so the displacement, velocity and acceleration fields are unchanged at this instant;
  /// the system is rebuilt once. Throws InvalidArgument, with the solver unchanged, for a cut
  /// that crosses no element, or that crosses an element another cut already crosses.
  CutHandle cut(const Cut& surface, CutOptions options = {})
    requires Enrich::active;
  /// Grows cut `h` to `surface` (a blade moved on: the grown surface, which contains the old
  /// one): the elements it newly crosses are cut, what was cut stays cut.
  void grow_cut(CutHandle h, const Cut& surface, CutOptions options = {})
    requires Enrich::active;
  /// What the last cut or growth did.
  const CutReport& last_cut_report() const { return cut_report_; }
  /// The cuts and the enriched elements (for output: io::write_cut_vtu, enrichment/output.hpp).
  const Enrichment<E>& enrichment() const
    requires Enrich::active
  {
    return body_.enrichment();
  }
  /// Every node's physical displacement, one node per column: u_i + sum_cuts psi(H_i, H_i) a_i
  /// (Heaviside: u_i + H_i a_i, so its standard dofs alone are not the node's displacement;
  /// with shifted enrichment, whose psi vanishes at the nodes, they are).
  Eigen::Matrix3Xd nodal_displacements() const;
  /// Adds a dof slot to a node (the enrichment policies' entry point): the system is rebuilt,
  /// the state grows with zeros in the new rows. A slot no element couples is held at zero.
  Index add_dof_slot(Index node);

  // --- state ------------------------------------------------------------------------------
  Scalar time() const { return current_.t; }
  const Vector& displacement() const { return current_.u; }
  const Vector& velocity() const { return current_.v; }
  const Vector& acceleration() const { return current_.a; }
  Vec3 displacement(Index node) const;  ///< the node's physical displacement (nodal_displacements)
  /// The committed state (every field a step changes).
  const StateType& state() const { return current_; }
  /// Current positions X + nodal_displacements(), one node per column.
  Eigen::Matrix3Xd positions() const;
  /// Sets u, v and t (refused where the model cannot be evaluated); the acceleration is then
  /// solved from equilibrium at the next step, and the state is balanced with f_int(u) for statics.
  void set_state(const Vector& u, const Vector& v, Scalar time = 0);
  /// Goes back to a state() taken earlier (undo): every field, the plastic table and its rest
  /// shapes with it; refused for a state from before a cut or of another solver.
  void restore(const StateType& s);
  /// Uses `a` as the acceleration at the current time instead of solving for equilibrium, until
  /// the loads, constraints, mass kind or damping change (MotionState::balance).
  void set_acceleration(const Vector& a);

  // --- plasticity (seed 000; plastic/) -----------------------------------------------------
  const PlasticParamsType& plastic_params() const { return plastic_.params(); }
  /// New plastic parameters mid-run: thresholds keep their hardening, shifted by the change of
  /// the initial yield values (plastic/plasticity.hpp).
  void set_plastic_params(const PlasticParamsType& p);
  /// The material mesh: every node's rest position, one node per column (the mesh itself
  /// without plasticity, or before any flow). Write x - X as a point field to see it in
  /// ParaView (examples/plastic_stretch.cpp).
  Eigen::Matrix3Xd material_positions() const;

  // --- solving ----------------------------------------------------------------------------
  /// Static equilibrium f_int(u) = f_ext(t) at the current time, by Newton in `load_steps`
  /// increments from the current state and load (solver/statics.hpp); velocity and
  /// acceleration are then zero.
  StepReport solve_static(int load_steps = 1);
  /// Advances by dt with Newmark's method (solver/dynamics.hpp). If a step fails it is redone
  /// as two half steps, recursively, up to settings().max_step_cuts times; throws SolverError,
  /// with the state unchanged, if even the smallest sub-step fails.
  StepReport step(Scalar dt);

  // --- observables (solver/observables.hpp) -------------------------------------------------
  Scalar kinetic_energy() const;
  /// Elastic strain energy summed over elements.
  Scalar strain_energy() const;
  /// Work potential of the external loads at the current time: f_ext . u.
  Scalar external_work_potential() const;
  /// Deformed volume.
  Scalar volume() const;
  /// Total mass, r^T M r per direction, r a rigid translation (the standard dofs; a cut's zero).
  Scalar mass() const { return system_.M.sum(mesh().num_nodes()) / 3; }
  /// Reaction forces at constrained dofs: f_int + M a + D v - f_ext (zero elsewhere), with the
  /// path's v and a at the constrained dofs and D's stiffness the projected tangent at the
  /// current state.
  Vector reaction_forces() const;
  /// Internal elastic forces at the current state.
  Vector internal_force() const;
  /// Tangent stiffness at the current state (the exact one where the model and the settings
  /// use it; full symmetric storage).
  SparseMatrix tangent() const;
  /// Mass matrix (full symmetric storage).
  SparseMatrix mass_matrix() const { return system_.M.to_sparse(); }
  /// Cauchy stress per element at its centre (a cut element's: its side 0's).
  std::vector<Mat3> element_stress() const;
  /// Cauchy stress of element e at its centre; of side s's piece if e is cut (s in {0, 1}).
  Mat3 stress(Index e, int side = 0) const {
    if (e < 0 || e >= mesh().num_elements() || side < 0 || side > 1)
      fail<InvalidArgument>("stress: element {} side {} out of range ([0, {}), 0 or 1)", e, side, mesh().num_elements());
    return body_.stress(e, current_.u, side);
  }
  Vector von_mises_stress() const;
  /// Whether a user constraint holds this dof.
  bool is_constrained(Index dof) const { return system_.constrained(checked_index(dof, num_dofs(), "dof")); }
  /// Number of distinct element shapes (elements that are translated copies share their
  /// precomputed data: one for a structured Hex8 grid, six for its Kuhn Tet4 split).
  Index num_element_shapes() const { return body_.data().num_shapes(); }

 private:
  using Parts = SolverParts<E, Elastic, enriched>;
  Parts parts() { return Parts{body_, system_, constraints_, loads_, settings_, threads()}; }

  /// Everything derived from the dof map, rebuilt after it changed.
  void rebuild();
  /// A change of the constraint sets (`change()` makes it and returns the set's handle), then
  /// what depends on them: the held dofs and the plastic anchors (the state's acceleration
  /// follows their version: MotionState::balance).
  template <class Change>
  ConstraintHandle constrain(const char* what, Change&& change);
  LoadHandle add_load(typename LoadsType::Definition def, LoadCurve curve, std::string what);

  /// Threads for element loops and matrix products (settings().threads, 0: OpenMP's default).
  int threads() const { return settings_.threads > 0 ? settings_.threads : max_threads(); }
  static SolverSettings validated(const SolverSettings& s) {
    validate_settings(s);
    return s;
  }
  /// Refuses a change of the simulation made from inside step() or solve_static(), and any
  /// change or step of a solver that was moved from.
  void check_not_solving(const char* what) const {
    if (moved_.moved_from())
      fail<InvalidArgument>("{}: this Solver was moved from; use the one it was moved to", what);
    if (solving_)
      fail<InvalidArgument>("{}: called during step() or solve_static() (from a load curve or a prescribed path); "
                            "change the simulation between steps",
                            what);
  }
  /// Marks step() and solve_static() as running (solving_) for its lifetime.
  struct Solving {
    bool& flag;
    explicit Solving(bool& f) : flag(f) { flag = true; }
    ~Solving() { flag = false; }
    Solving(const Solving&) = delete;
    Solving& operator=(const Solving&) = delete;
  };

  /// Brings the element data to state s's rest shapes (plastic flow). What was derived from the
  /// old ones knows it by the element data's epoch.
  void sync_rest_shapes(const StateType& s) { plastic_.sync(body_, s.plastic, threads()); }
  /// After a cut: its enriched elements stop flowing, and what derives from the dof map is rebuilt.
  void cut_applied() {
    rebuild();
    cut_serial_ = current_.serial = ++serial_;  // restore() refuses the states from before
    if constexpr (enriched) cut_report_.plastic_frozen += plastic_.on_cut(body_.enrichment(), current_.plastic);
  }
  /// X-FEM: the enriched dofs' share of the loads (empty without a cut).
  EnrichedLoads enriched_loads() const {
    if constexpr (enriched) {
      if (const auto& en = body_.enrichment(); body_.has_cuts())
        return {[this](const Vec3& g, MassKind kind, Vector& F) { body_.add_enriched_body_force(g, kind, F); },
                [&en](Index i, const Vec3& f, Vector& F) { en.add_nodal_force(i, f, &Enrich::psi, F); },
                [&en](Index e, const Vec3& xi, const Vec3& f, Vector& F) { en.add_point_force(e, xi, f, F); },
                [this](FaceRef f, const Vec3& t, Vector& F) { body_.add_enriched_traction(f, t, F); }};
    }
    return {};
  }
  /// X-FEM: the enriched dofs of constrained nodes, held where the node is (Enrichment::held_dofs).
  std::vector<Index> held_enriched_dofs() const;

  SolverSettings settings_;
  Discretization<E, Elastic, enriched> body_;
  System<E, Elastic, enriched> system_;
  Constraints constraints_;
  LoadsType loads_;
  Dynamics<E, Elastic, enriched> dynamics_;
  Statics<E, Elastic, enriched> statics_;
  StateType current_, work_, trial_;
  PlasticHooksType plastic_;
  CutReport cut_report_;
  HandleOwner cut_owner_;  ///< the number its cut handles and states carry (another solver's are refused)
  /// True while step() or solve_static() runs. A load curve or a prescribed path is called
  /// during them; one that changes the solver (a cut, a constraint, a load, the state) would
  /// change the system under the step's feet and outlive a failed step, so it is refused.
  bool solving_ = false;
  MovedFromFlag moved_;
  std::uint64_t serial_ = 0, cut_serial_ = 0;  ///< the last state's serial; the state's at the last cut
  mutable Vector scratch_;
};

}  // namespace plastifem

#include <plastifem/solver/solver_members.hpp>
