#pragma once
// PlasticHooks<Policy, E, Elastic>: everything the Solver asks of its plastic policy, in one
// type per policy. The Solver calls the same hooks whatever the policy; NoPlasticity's do
// nothing and hold nothing (the calls inline to nothing), an active policy's own its engine
// (`Policy::Engine<E, Elastic>`, plastic/plasticity.hpp), its parameters and the anchor nodes
// (those with a constrained dof: the material mesh stays put there, plastic/fusion.hpp).
//
//   init              the plastic part of the first state (material mesh = the mesh)
//   sync              the element data to a state's rest shapes; true if they changed
//   after_step        the flow after a converged Newmark (sub-)step of dt, into the trial state
//                     (a flow stamps the table with the next of the Solver's serial numbers)
//   after_increment   the flow after a converged static load increment (its share of static_time)
//   on_cut            a cut's enriched elements stop flowing (docs/xfem.md)
//   restored          a state handed to Solver::restore: checked, and given the current parameters
//   constraints_changed, pattern_changed, set_params, rest_positions, material_positions
//
// The hooks see the body and the state only through their arguments, so a policy written in
// a user's file composes with the Solver: it gives the State, Params and Engine that the
// PlasticModel and PlasticEngine concepts state (plastic/plastic.hpp; tests/test_plastic_policy.cpp
// composes a nodal creep so), or a specialisation of PlasticHooks of its own.
#include <plastifem/element/element.hpp>
#include <plastifem/plastic/params.hpp>
#include <plastifem/core/log.hpp>
#include <plastifem/plastic/plastic.hpp>

#include <chrono>
#include <cstdint>
#include <vector>

namespace plastifem {

/// After a committed step or static solve: a note (core/log.hpp) when the shape safeguard
/// switched elements' plasticity off, so that a body that stops flowing says so.
inline void note_switched_off(const PlasticReport& r, Scalar t, Index num_elements) {
  if (r.switched_off == 0) return;
  note(fmt::format("t = {}: plasticity switched off in {} element{} whose rest shape would degenerate "
                   "(PlasticParams::min_rest_quality); {} of {} elements no longer flow{}",
                   t, r.switched_off, r.switched_off == 1 ? "" : "s", r.elements_off, num_elements,
                   r.elements_off >= num_elements ? ": the body is elastic from here" : ""));
}

/// NoPlasticity (and any inactive policy): rest shapes never change.
template <class Policy, FiniteElement E, class Elastic, bool = Policy::active>
class PlasticHooks {
 public:
  using State = NoPlasticState;
  using Params = typename Policy::Params;

  explicit PlasticHooks(const Params& p) : params_(p) {}
  const Params& params() const { return params_; }
  void set_params(const Params& p, State&) { params_ = p; }
  template <class Body>
  void init(const Body&, State&) {}
  template <class Body>
  bool sync(Body&, const State&, int) { return false; }
  template <class Body>
  PlasticReport after_step(const Body&, const Vector&, Scalar, const State&, State&, std::uint64_t&, int) { return {}; }
  template <class Body>
  PlasticReport after_increment(const Body&, const Vector&, Scalar, State&, std::uint64_t&, int) { return {}; }
  template <class Enrichment>
  int on_cut(const Enrichment&, State&) { return 0; }
  void restored(State&) {}
  template <class IsConstrained>
  void constraints_changed(Index, IsConstrained&&) {}
  void pattern_changed() {}
  static std::uint64_t version(const State&) { return 0; }
  /// The rest positions cut elements' points are mapped with: the mesh's (null).
  static const Vector* rest_positions(const State&) { return nullptr; }
  static Eigen::Matrix3Xd material_positions(const State&, const Eigen::Matrix3Xd& mesh_nodes) { return mesh_nodes; }

 private:
  [[no_unique_address]] Params params_;
};

/// An active policy: the engine's update after each converged (sub-)step or increment.
template <class Policy, FiniteElement E, class Elastic>
class PlasticHooks<Policy, E, Elastic, true> {
 public:
  using State = typename Policy::State;  // PlasticTable for the library's policies
  using Params = typename Policy::Params;
  using Engine = typename Policy::template Engine<E, Elastic>;

  explicit PlasticHooks(const Params& p) : params_(p) { params_.validate(); }
  const Params& params() const { return params_; }
  /// New parameters mid-run: thresholds keep their hardening, shifted by the change of the
  /// initial yield values (plastic/plasticity.hpp).
  void set_params(const Params& p, State& s) {
    p.validate();
    engine_.change_params(params_, p, s);
    params_ = p;
  }
  template <class Body>
  void init(const Body& body, State& s) {
    static_assert(PlasticEngine<Engine, Policy, Body>, "the plastic policy's Engine lacks what the Solver calls "
                                                       "(plastic/plastic.hpp: the PlasticEngine concept)");
    engine_.init(body, params_, s);
  }
  template <class Body>
  bool sync(Body& body, const State& s, int threads) {
    return engine_.sync(body, s, threads);
  }
  /// The flow after a converged (sub-)step of dt from state `from` to displacement u: `to`
  /// gets from's table, flowed. The report says how long it took.
  template <class Body>
  PlasticReport after_step(const Body& body, const Vector& u, Scalar dt, const State& from, State& to,
                           std::uint64_t& serial, int threads) {
    const auto t0 = std::chrono::steady_clock::now();
    to = from;  // (reuses to's storage)
    PlasticReport r = engine_.update(body, u, dt, params_, to, ++serial, threads, anchor_);
    r.wall_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    return r;
  }
  /// A static increment that covered `fraction` of the load flows over that share of
  /// Params::static_time.
  template <class Body>
  PlasticReport after_increment(const Body& body, const Vector& u, Scalar fraction, State& s, std::uint64_t& serial,
                                int threads) {
    return engine_.update(body, u, fraction * params_.static_time, params_, s, ++serial, threads, anchor_);
  }
  /// Every element the enrichment cuts stops flowing (docs/xfem.md, "Cutting plastic
  /// tissue"): the flow's deformation gradient is the standard element's, which the enrichment
  /// makes discontinuous; its rest shape still follows the material mesh. Returns how many
  /// flowing elements it stopped (one the shape safeguard stopped is not counted).
  template <class Enrichment>
  int on_cut(const Enrichment& enrichment, State& s) {
    int frozen = 0;
    for (size_t k = 0; k < enrichment.elements().size(); ++k) {
      const Index e = enrichment.element_of(k);
      if (s.off[e] == 0) ++frozen;
      s.off[e] = State::cut;
    }
    return frozen;
  }
  /// A state handed to Solver::restore: refused (InvalidArgument) if its table is not one this
  /// engine keeps, where the engine says (an optional `check_table`: a state of another policy
  /// on the same mesh has the same type); then the current parameters apply to it as
  /// set_params applies new ones, so that a table saved before rotation or kinematic hardening
  /// was switched on gets their entries (the flow would skip them) and thresholds saved under
  /// another yield value shift to the current one.
  void restored(State& s) {
    if constexpr (requires { engine_.check_table(s); }) engine_.check_table(s);
    engine_.change_params(params_, params_, s);
  }
  /// The anchor nodes: those with a constrained dof.
  template <class IsConstrained>
  void constraints_changed(Index num_nodes, IsConstrained&& constrained) {
    anchor_.assign(num_nodes, 0);
    for (Index i = 0; i < num_nodes; ++i)
      anchor_[i] = constrained(3 * i) || constrained(3 * i + 1) || constrained(3 * i + 2);
  }
  void pattern_changed() { engine_.pattern_changed(); }
  static std::uint64_t version(const State& s) { return s.version; }
  /// The material mesh, which cut elements' points are mapped with.
  static const Vector* rest_positions(const State& s) { return &s.rest; }
  static Eigen::Matrix3Xd material_positions(const State& s, const Eigen::Matrix3Xd& mesh_nodes) {
    return Eigen::Map<const Eigen::Matrix3Xd>(s.rest.data(), 3, mesh_nodes.cols());
  }

 private:
  Params params_;
  Engine engine_;
  std::vector<char> anchor_;
};

}  // namespace plastifem
