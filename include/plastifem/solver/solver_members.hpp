#pragma once
// The member functions of Solver (solver.hpp, which includes this file at its end). They are
// defined out of the class on purpose: a file built against plastifem::compiled declares the
// common Solver types `extern template`, and an extern template does not keep a compiler from
// instantiating members defined in the class (those are inline) to inline them, which would
// undo the compiled library's build-time saving (docs/build_time.md). The extern declarations
// come last, after every definition. Most members are one call into the part that owns the
// work; the transactions (settings, state, cuts, step, static solve) are at the end.
#include <plastifem/solver/solver.hpp>

namespace plastifem {

template <FiniteElement E, class Elastic, class Plastic, class Enrich>
  requires ElasticModel<Elastic, E>
Solver<E, Elastic, Plastic, Enrich>::Solver(const Mesh<E>& mesh, const Material& material, SolverSettings settings,
                                            PlasticParamsType plastic_params)
    : settings_(validated(settings)), body_(mesh, material.validated()), system_(settings_),
      constraints_(mesh.num_nodes()), plastic_(plastic_params) {
  note_unused_nodes(body_.mesh().report());
  current_.reset(body_.num_dofs());
  current_.serial = ++serial_;
  current_.lineage = cut_owner_.id();
  plastic_.init(body_, current_.plastic);
  rebuild();
}

// --- set-up: each change through the part it changes, then what depends on it ----------------

template <FiniteElement E, class Elastic, class Plastic, class Enrich>
  requires ElasticModel<Elastic, E>
template <class Change>
ConstraintHandle Solver<E, Elastic, Plastic, Enrich>::constrain(const char* what, Change&& change) {
  check_not_solving(what);
  const ConstraintHandle h = change();
  system_.set_constrained(body_, constraints_.constrained_dofs(), held_enriched_dofs());
  plastic_.constraints_changed(mesh().num_nodes(), [this](Index d) { return system_.constrained(d); });
  return h;
}

template <FiniteElement E, class Elastic, class Plastic, class Enrich>
  requires ElasticModel<Elastic, E>
ConstraintHandle Solver<E, Elastic, Plastic, Enrich>::prescribe(std::span<const Index> nodes, PrescribedMotion motion, DofMask mask) {
  return constrain("prescribe", [&] { return constraints_.add(nodes, std::move(motion), mask); });
}

template <FiniteElement E, class Elastic, class Plastic, class Enrich>
  requires ElasticModel<Elastic, E>
ConstraintHandle Solver<E, Elastic, Plastic, Enrich>::grasp(std::span<const Index> nodes, std::function<Vec3(Scalar)> path) {
  return constrain("grasp", [&] { return constraints_.grasp(nodes, std::move(path), time(), current_.u); });
}

template <FiniteElement E, class Elastic, class Plastic, class Enrich>
  requires ElasticModel<Elastic, E>
void Solver<E, Elastic, Plastic, Enrich>::release(ConstraintHandle h) {
  constrain("release", [&] {
    constraints_.remove(h);
    return h;
  });
}

template <FiniteElement E, class Elastic, class Plastic, class Enrich>
  requires ElasticModel<Elastic, E>
void Solver<E, Elastic, Plastic, Enrich>::replace(ConstraintHandle h, PrescribedMotion motion) {
  constrain("replace", [&] {
    constraints_.replace(h, std::move(motion));
    return h;
  });
}

template <FiniteElement E, class Elastic, class Plastic, class Enrich>
  requires ElasticModel<Elastic, E>
LoadHandle Solver<E, Elastic, Plastic, Enrich>::add_load(typename LoadsType::Definition def, LoadCurve curve, std::string what) {
  check_not_solving("adding a load");
  const LoadHandle h = loads_.add(std::move(def), std::move(curve), std::move(what));
  loads_.build_last(mesh(), enriched_loads());
  return h;
}

template <FiniteElement E, class Elastic, class Plastic, class Enrich>
  requires ElasticModel<Elastic, E>
LoadHandle Solver<E, Elastic, Plastic, Enrich>::add_nodal_force(std::span<const Index> nodes, const Vec3& f, LoadCurve curve) {
  return add_load(LoadsType::nodal_force(mesh(), nodes, f), std::move(curve), "nodal force");
}

template <FiniteElement E, class Elastic, class Plastic, class Enrich>
  requires ElasticModel<Elastic, E>
LoadHandle Solver<E, Elastic, Plastic, Enrich>::add_nodal_forces(std::span<const Index> nodes, std::span<const Vec3> forces, LoadCurve curve) {
  return add_load(LoadsType::nodal_forces(mesh(), nodes, forces), std::move(curve), "nodal forces");
}

template <FiniteElement E, class Elastic, class Plastic, class Enrich>
  requires ElasticModel<Elastic, E>
LoadHandle Solver<E, Elastic, Plastic, Enrich>::add_point_force(const Vec3& X, const Vec3& f, LoadCurve curve) {
  return add_load(LoadsType::point_force(mesh(), X, f), std::move(curve), "point force");
}

template <FiniteElement E, class Elastic, class Plastic, class Enrich>
  requires ElasticModel<Elastic, E>
LoadHandle Solver<E, Elastic, Plastic, Enrich>::add_gravity(const Vec3& g, LoadCurve curve) {
  return add_load(LoadsType::body_force(g), std::move(curve), "gravity");
}

template <FiniteElement E, class Elastic, class Plastic, class Enrich>
  requires ElasticModel<Elastic, E>
LoadHandle Solver<E, Elastic, Plastic, Enrich>::add_traction(const std::vector<FaceRef>& faces, const Vec3& t, LoadCurve curve) {
  return add_load(LoadsType::traction(mesh(), faces, t), std::move(curve), "traction");
}

template <FiniteElement E, class Elastic, class Plastic, class Enrich>
  requires ElasticModel<Elastic, E>
void Solver<E, Elastic, Plastic, Enrich>::remove_load(LoadHandle h) {
  check_not_solving("remove_load");
  loads_.remove(h);
}

template <FiniteElement E, class Elastic, class Plastic, class Enrich>
  requires ElasticModel<Elastic, E>
void Solver<E, Elastic, Plastic, Enrich>::clear_loads() {
  check_not_solving("clear_loads");
  loads_.clear();
}

// --- cutting, state, plasticity -------------------------------------------------------------

template <FiniteElement E, class Elastic, class Plastic, class Enrich>
  requires ElasticModel<Elastic, E>
Eigen::Matrix3Xd Solver<E, Elastic, Plastic, Enrich>::nodal_displacements() const {
  Eigen::Matrix3Xd x(3, mesh().num_nodes());
  for (Index i = 0; i < mesh().num_nodes(); ++i) x.col(i) = displacement(i);
  return x;
}

template <FiniteElement E, class Elastic, class Plastic, class Enrich>
  requires ElasticModel<Elastic, E>
std::vector<Index> Solver<E, Elastic, Plastic, Enrich>::held_enriched_dofs() const {
  if constexpr (enriched) return body_.enrichment().held_dofs(constraints_.constrained_dofs(), mesh().num_nodes());
  return {};
}

template <FiniteElement E, class Elastic, class Plastic, class Enrich>
  requires ElasticModel<Elastic, E>
Index Solver<E, Elastic, Plastic, Enrich>::add_dof_slot(Index node) {
  check_not_solving("add_dof_slot");
  const Index row = body_.dof_map().add_slot(node);
  rebuild();
  return row;
}

template <FiniteElement E, class Elastic, class Plastic, class Enrich>
  requires ElasticModel<Elastic, E>
Eigen::Matrix3Xd Solver<E, Elastic, Plastic, Enrich>::positions() const {
  return mesh().nodes() + nodal_displacements();
}

template <FiniteElement E, class Elastic, class Plastic, class Enrich>
  requires ElasticModel<Elastic, E>
Vec3 Solver<E, Elastic, Plastic, Enrich>::displacement(Index node) const {
  const Index i = mesh().checked_node(node);
  if constexpr (enriched) {
    if constexpr (!vanishes_at_nodes<Enrich>())
      return body_.enrichment().nodal_displacement(current_.u, i, &Enrich::psi);
  }
  return current_.u.template segment<3>(3 * i);
}

template <FiniteElement E, class Elastic, class Plastic, class Enrich>
  requires ElasticModel<Elastic, E>
void Solver<E, Elastic, Plastic, Enrich>::set_acceleration(const Vector& a) {
  check_not_solving("set_acceleration");
  if (a.size() != num_dofs() || !a.allFinite()) fail<InvalidArgument>("acceleration needs {} finite entries", num_dofs());
  current_.a = a;
  current_.balance = parts().balance();
  current_.force_scale = -1;  // the step that made it measured another acceleration
}

template <FiniteElement E, class Elastic, class Plastic, class Enrich>
  requires ElasticModel<Elastic, E>
void Solver<E, Elastic, Plastic, Enrich>::set_plastic_params(const PlasticParamsType& p) {
  check_not_solving("set_plastic_params");
  plastic_.set_params(p, current_.plastic);
}

template <FiniteElement E, class Elastic, class Plastic, class Enrich>
  requires ElasticModel<Elastic, E>
Eigen::Matrix3Xd Solver<E, Elastic, Plastic, Enrich>::material_positions() const {
  return PlasticHooksType::material_positions(current_.plastic, mesh().nodes());
}

// --- observables (solver/observables.hpp) ------------------------------------------------------

template <FiniteElement E, class Elastic, class Plastic, class Enrich>
  requires ElasticModel<Elastic, E>
Scalar Solver<E, Elastic, Plastic, Enrich>::kinetic_energy() const {
  return observables::kinetic_energy(system_, current_.v, scratch_, threads());
}

template <FiniteElement E, class Elastic, class Plastic, class Enrich>
  requires ElasticModel<Elastic, E>
Scalar Solver<E, Elastic, Plastic, Enrich>::strain_energy() const {
  return body_.strain_energy(current_.u);
}

template <FiniteElement E, class Elastic, class Plastic, class Enrich>
  requires ElasticModel<Elastic, E>
Scalar Solver<E, Elastic, Plastic, Enrich>::external_work_potential() const {
  return observables::external_work_potential(loads_, time(), current_.u);
}

template <FiniteElement E, class Elastic, class Plastic, class Enrich>
  requires ElasticModel<Elastic, E>
Scalar Solver<E, Elastic, Plastic, Enrich>::volume() const {
  return body_.volume(current_.u);
}

template <FiniteElement E, class Elastic, class Plastic, class Enrich>
  requires ElasticModel<Elastic, E>
Vector Solver<E, Elastic, Plastic, Enrich>::reaction_forces() const {
  return observables::reaction_forces(body_, system_, loads_, settings_, current_, threads());
}

template <FiniteElement E, class Elastic, class Plastic, class Enrich>
  requires ElasticModel<Elastic, E>
Vector Solver<E, Elastic, Plastic, Enrich>::internal_force() const {
  return observables::internal_force(body_, current_.u, threads());
}

template <FiniteElement E, class Elastic, class Plastic, class Enrich>
  requires ElasticModel<Elastic, E>
SparseMatrix Solver<E, Elastic, Plastic, Enrich>::tangent() const {
  const bool exact = has_exact_tangent_v<Elastic> && settings_.newton.exact_tangent;
  return observables::tangent(body_, current_.u, exact ? TangentKind::Exact : TangentKind::Projected, threads());
}

template <FiniteElement E, class Elastic, class Plastic, class Enrich>
  requires ElasticModel<Elastic, E>
std::vector<Mat3> Solver<E, Elastic, Plastic, Enrich>::element_stress() const {
  return body_.element_stress(current_.u);
}

template <FiniteElement E, class Elastic, class Plastic, class Enrich>
  requires ElasticModel<Elastic, E>
Vector Solver<E, Elastic, Plastic, Enrich>::von_mises_stress() const {
  return observables::von_mises_stress(element_stress());
}

// --- the changes of the whole simulation (settings, state, dof map, cuts) and the two ways of
// solving, each a transaction on a working copy of the state ----------------------------------

template <FiniteElement E, class Elastic, class Plastic, class Enrich>
  requires ElasticModel<Elastic, E>
void Solver<E, Elastic, Plastic, Enrich>::set_settings(const SolverSettings& s) {
  check_not_solving("set_settings");
  validate_settings(s);
  settings_ = s;  // a new mass or damping: the committed acceleration's balance is not the current one
  system_.set_settings(body_, settings_);
  system_.set_threads(threads());
  loads_.build(mesh(), material().density, settings_.mass, num_dofs(), enriched_loads());
}

template <FiniteElement E, class Elastic, class Plastic, class Enrich>
  requires ElasticModel<Elastic, E>
void Solver<E, Elastic, Plastic, Enrich>::set_state(const Vector& u, const Vector& v, Scalar time) {
  check_not_solving("set_state");
  if (u.size() != num_dofs() || v.size() != num_dofs())
    fail<InvalidArgument>("state vectors need {} entries, got {} and {}", num_dofs(), u.size(), v.size());
  if (!u.allFinite() || !v.allFinite()) fail<InvalidArgument>("state vectors must be finite");
  if (!std::isfinite(time)) fail<InvalidArgument>("time must be finite, got {}", time);
  StateType s;
  s.reset(num_dofs());
  s.u = u, s.v = v, s.t = time;
  s.plastic = current_.plastic;
  Vector f(num_dofs());
  // A u the model is undefined at (an inverted element of a ln J model) or whose forces
  // overflow would give NaN observables until a step refused it: refused here.
  if (!body_.assemble(u, f, nullptr, TangentKind::Projected, threads()))
    fail<InvalidArgument>("set_state: the model cannot be evaluated at u{}", body_.locate_invalid(u));
  s.load = f;
  s.serial = ++serial_;
  s.lineage = cut_owner_.id();
  current_.swap(s);
}

template <FiniteElement E, class Elastic, class Plastic, class Enrich>
  requires ElasticModel<Elastic, E>
void Solver<E, Elastic, Plastic, Enrich>::restore(const StateType& s) {
  check_not_solving("restore");
  // Sizes say little: another solver's state of the same mesh holds other cuts' enriched dofs
  // and other plastic rest shapes.
  if (s.lineage != cut_owner_.id())
    fail<InvalidArgument>("restore: the state is another solver's; a state is restored into the solver it came "
                          "from (or the solver that solver was moved into)");
  if (s.num_dofs() != num_dofs() || s.v.size() != num_dofs() || s.a.size() != num_dofs())
    fail<InvalidArgument>("restore: the state has {} dofs, the solver {} (a state from before a cut cannot be "
                          "restored after it)",
                          s.num_dofs(), num_dofs());
  // A cut that added no dofs (one grown through enriched nodes) still changed the cut elements
  // and, in a plastic body, which elements flow: a state from before it is not this body's.
  if (s.serial < cut_serial_) fail<InvalidArgument>("restore: the state is from before a cut; a cut cannot be undone");
  if (!s.u.allFinite() || !s.v.allFinite() || !s.a.allFinite() || !std::isfinite(s.t))
    fail<InvalidArgument>("restore: the state is not finite");
  if constexpr (requires { s.plastic.rest.size(); s.plastic.off.size(); }) {
    if (s.plastic.rest.size() != 3 * mesh().num_nodes() || s.plastic.off.size() != static_cast<size_t>(mesh().num_elements()))
      fail<InvalidArgument>("restore: the state's plastic table is not this mesh's");
  }
  StateType copy = s;
  plastic_.restored(copy.plastic);  // checked, and under the current plastic parameters
  sync_rest_shapes(copy);  // the element data at its rest shapes (shapes that were valid then)
  current_.swap(copy);
}

template <FiniteElement E, class Elastic, class Plastic, class Enrich>
  requires ElasticModel<Elastic, E>
void Solver<E, Elastic, Plastic, Enrich>::rebuild() {
  plastic_.pattern_changed();
  body_.rebuild();
  const Index n = body_.num_dofs();
  system_.rebuild(body_, settings_, constraints_.constrained_dofs(), held_enriched_dofs());
  system_.set_threads(threads());
  loads_.build(mesh(), material().density, settings_.mass, n, enriched_loads());
  current_.grow(n);
  work_.reset(n), trial_.reset(n);
  dynamics_.resize(n);
  scratch_.resize(n);
}

template <FiniteElement E, class Elastic, class Plastic, class Enrich>
  requires ElasticModel<Elastic, E>
CutHandle Solver<E, Elastic, Plastic, Enrich>::cut(const Cut& surface, CutOptions options)
  requires Enrich::active
{
  check_not_solving("cut");
  int id = -1;
  cut_report_ = body_.cut(surface, options, &Enrich::psi, -1, id, PlasticHooksType::rest_positions(current_.plastic));
  cut_applied();
  return CutHandle{id, cut_owner_.id()};
}

template <FiniteElement E, class Elastic, class Plastic, class Enrich>
  requires ElasticModel<Elastic, E>
void Solver<E, Elastic, Plastic, Enrich>::grow_cut(CutHandle h, const Cut& surface, CutOptions options)
  requires Enrich::active
{
  check_not_solving("grow_cut");
  if (h.id < 0 || h.owner == 0) fail<InvalidArgument>("grow_cut: an invalid cut handle (a default handle names no cut)");
  if (h.owner != cut_owner_.id())
    fail<InvalidArgument>("grow_cut: cut handle {} belongs to another solver: a handle names a cut of the solver that "
                          "issued it",
                          h.id);
  int id = -1;
  cut_report_ = body_.cut(surface, options, &Enrich::psi, h.id, id, PlasticHooksType::rest_positions(current_.plastic));
  if (cut_report_.dofs_added > 0 || cut_report_.cut_elements > 0) cut_applied();
}

template <FiniteElement E, class Elastic, class Plastic, class Enrich>
  requires ElasticModel<Elastic, E>
StepReport Solver<E, Elastic, Plastic, Enrich>::solve_static(int load_steps) {
  check_not_solving("solve_static");
  const Solving solving(solving_);
  auto p = parts();
  work_.assign(current_);
  PlasticReport flow;
  StepReport r;
  try {
    // After each converged increment the plastic flow, over the share of static_time its load
    // fraction stands for; the element data then follow the working state.
    r = statics_.solve(p, work_, load_steps, [&](MotionState& s, Scalar fraction) {
      const auto before = PlasticHooksType::version(work_.plastic);
      flow.add(plastic_.after_increment(body_, s.u, fraction, work_.plastic, serial_, threads()));
      sync_rest_shapes(work_);
      return PlasticHooksType::version(work_.plastic) != before;
    });
  } catch (...) {
    sync_rest_shapes(current_);  // the element data back to the committed rest shapes
    throw;
  }
  r.plastic = flow;
  work_.serial = ++serial_;
  current_.swap(work_);
  note_switched_off(r.plastic, time(), mesh().num_elements());
  return r;
}

template <FiniteElement E, class Elastic, class Plastic, class Enrich>
  requires ElasticModel<Elastic, E>
StepReport Solver<E, Elastic, Plastic, Enrich>::step(Scalar dt) {
  check_not_solving("step");
  const auto t0 = std::chrono::steady_clock::now();
  check_time_step(dt, current_.t, settings_.newmark);
  const Solving solving(solving_);
  auto p = parts();
  StepReport r;
  try {
    r = advance(current_, work_, trial_, dt, settings_.max_step_cuts, [&](const StateType& from, StateType& to, Scalar h) {
      sync_rest_shapes(from);
      StepReport sr = dynamics_.attempt(p, from, to, h, ++serial_);
      sr.plastic = plastic_.after_step(body_, to.u, h, from.plastic, to.plastic, serial_, threads());
      // Moved rest shapes make the tangent kept at the step's end stale: the next step assembles
      // one at its start, so this step saved no assembly.
      if (sr.plastic.elements_changed > 0) sr.tangents_kept = 0;
      return sr;
    });
  } catch (...) {
    sync_rest_shapes(current_);  // a sub-step may have moved the element data: back to the committed state
    throw;
  }
  const auto t_sync = std::chrono::steady_clock::now();
  sync_rest_shapes(current_);
  r.plastic.wall_ms += std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t_sync).count();
  r.wall_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  note_switched_off(r.plastic, time(), mesh().num_elements());
  note_path_jumps(r, time());
  return r;
}

}  // namespace plastifem

// With plastifem::compiled, the elastic compositions of the one list (solver/instantiations.hpp)
// are linked from it, not instantiated here; the plastic and cut ones are declared in
// <plastifem/plasticity.hpp> and <plastifem/cutting.hpp>, which define those policies.
#ifdef PLASTIFEM_USE_COMPILED
#include <plastifem/solver/instantiations.hpp>
#define PLASTIFEM_EXTERN_SOLVER(E, M) extern template class plastifem::Solver<plastifem::E, plastifem::M>;
PLASTIFEM_ELASTIC_SOLVERS(PLASTIFEM_EXTERN_SOLVER)
#undef PLASTIFEM_EXTERN_SOLVER
#endif
