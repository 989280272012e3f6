#pragma once
// System: the linear-algebra side of a solver. The matrices over the current dof map (mass M,
// tangent K, Newton matrix A, and the stiffness Kd of Rayleigh damping when it is used),
// which dofs are held (prescribed by a constraint, or in a row no element couples), and
// the linear solvers. Rebuilt when the dof map changes, and only then: pattern, matrices, the
// Dirichlet block list, the symbolic factorisation and the CG work space.
//
// Held dofs: their rows and columns of A become identity and their right-hand side zero, so a
// Newton increment is zero there (u already holds the prescribed value; an uncoupled row stays
// at zero, carrying no mass and no stiffness).
//
// Every write of the tangent K goes through assemble(), which gives K a new stamp
// (tangent_stamp()); a rebuild does too. What is derived from a K (the real-time step's
// linearisation, solver/dynamics.hpp) records the stamp and is stale when it differs: a static
// solve, an accurate step or a cut that wrote K in between is seen without being told.
#include <plastifem/assembly/discretization.hpp>
#include <plastifem/core/log.hpp>
#include <plastifem/solver/boundary.hpp>
#include <plastifem/solver/settings.hpp>

#include <algorithm>
#include <cmath>
#include <utility>

namespace plastifem {

/// Tells the user about the nodes no element uses, which the system holds fixed.
inline void note_unused_nodes(const MeshReport& report) {
  const auto& unused = report.unused_nodes;
  if (unused.empty()) return;
  std::string ids;
  for (size_t k = 0; k < unused.size() && k < 20; ++k) ids += fmt::format("{}{}", k ? ", " : "", unused[k]);
  note(fmt::format("{} node{} no element uses ({}{}) {} held fixed and left out of the solve", unused.size(),
                   unused.size() == 1 ? "" : "s", ids, unused.size() > 20 ? ", ..." : "",
                   unused.size() == 1 ? "is" : "are"));
}

/// Whether the settings damp the motion: D = alpha M + beta Kd is not zero.
inline bool has_rayleigh_damping(const SolverSettings& s) { return s.rayleigh_mass != 0 || s.rayleigh_stiffness != 0; }

/// out += factor D v with Rayleigh damping D = alpha M + beta Kd (seed 001 eq. 20; s.rayleigh_mass =
/// alpha, s.rayleigh_stiffness = beta; solver/dynamics.hpp says at which state Kd is taken).
/// The one damping product of the step, its start and the reactions. `work`: scratch, not `out`.
inline void add_rayleigh_damping(const BlockSymmetricMatrix& M, const BlockSymmetricMatrix& Kd, const SolverSettings& s,
                                 const Vector& v, Scalar factor, Vector& out, Vector& work, int threads) {
  if (s.rayleigh_mass != 0) {
    M.multiply(v, work, threads);
    out += (factor * s.rayleigh_mass) * work;
  }
  if (s.rayleigh_stiffness != 0) {
    Kd.multiply(v, work, threads);
    out += (factor * s.rayleigh_stiffness) * work;
  }
}

template <FiniteElement E, class Elastic, bool Enriched = false>
class System {
 public:
  using Body = Discretization<E, Elastic, Enriched>;

  System(const SolverSettings& s) : linear_(s.linear), static_linear_(s.static_linear) {}

  BlockSymmetricMatrix M, K, A;
  /// The stiffness of Rayleigh damping D = alpha M + beta Kd (solver/dynamics.hpp says at which
  /// state), empty if unused.
  BlockSymmetricMatrix Kd;

  /// New pattern (the dof map changed): every matrix is rebuilt, the linear solvers forget
  /// their analysis.
  void rebuild(const Body& body, const SolverSettings& s, const std::vector<char>& constrained,
               const std::vector<Index>& also_held = {}) {
    const Assembler<E>& asm_ = body.assembler();
    M = asm_.zero_matrix();
    K = asm_.zero_matrix();
    A = asm_.zero_matrix();
    Kd = BlockSymmetricMatrix();
    linear_.set_settings(s.linear);
    static_linear_.set_settings(s.static_linear);
    // Each enriched node's rows, solved together by the CG preconditioner: its standard row and
    // the added rows an element couples (a slot no element couples is an identity row, and a
    // node with none keeps Jacobi: its steps stay bit for bit those without the slot).
    const DofMap& dofs = body.dof_map();
    const auto& coupled = asm_.coupled_rows();
    std::vector<std::vector<Index>> groups;
    std::vector<int> group_of(dofs.num_nodes(), -1);
    for (Index r = dofs.num_nodes(); r < dofs.num_block_rows(); ++r) {
      const Index node = dofs.node_of(r);
      if (!coupled[r] || !coupled[node]) continue;
      if (group_of[node] < 0) group_of[node] = static_cast<int>(groups.size()), groups.push_back({node});
      groups[group_of[node]].push_back(r);
    }
    linear_.set_coupled_rows(groups);
    static_linear_.set_coupled_rows(std::move(groups));
    Kd_current_ = false;
    ++tangent_stamp_;
    coefficients_ = {0, 0, 0};
    build_mass(body, s.mass);
    set_constrained(body, constrained, also_held);
  }
  /// New settings (mass kind, solver settings): same pattern.
  void set_settings(const Body& body, const SolverSettings& s) {
    linear_.set_settings(s.linear);
    static_linear_.set_settings(s.static_linear);
    build_mass(body, s.mass);
    coefficients_ = {0, 0, 0};
  }
  void set_threads(int threads) {
    linear_.set_threads(threads);
    static_linear_.set_threads(threads);
  }

  /// Which standard dofs users constrain (3 x nodes); rows no element couples are held too, and
  /// the dofs in `also_held` (Heaviside enrichment: the enriched dofs of constrained nodes).
  void set_constrained(const Body& body, const std::vector<char>& constrained, const std::vector<Index>& also_held = {}) {
    const Index n = body.num_dofs();
    const auto& coupled = body.assembler().coupled_rows();
    held_.assign(n, 0);
    constrained_.assign(n, 0);
    for (size_t d = 0; d < constrained.size(); ++d) held_[d] = constrained_[d] = constrained[d];
    for (Index d : also_held) held_[d] = 1;
    for (Index r = 0; r < n / 3; ++r)
      if (!coupled[r]) held_[3 * r] = held_[3 * r + 1] = held_[3 * r + 2] = 1;
    blocks_ = ConstrainedBlocks(M.pattern(), held_);
    prescribed_dofs_.clear(), held_dofs_.clear();
    for (Index d = 0; d < n; ++d) {
      if (constrained_[d]) prescribed_dofs_.push_back(d);
      if (held_[d]) held_dofs_.push_back(d);
    }
    coefficients_ = {0, 0, 0};  // the held rows of A change
  }

  Index num_dofs() const { return static_cast<Index>(held_.size()); }
  /// Held: constrained by the user, or in a row no element couples.
  bool held(Index dof) const { return held_[dof] != 0; }
  bool constrained(Index dof) const { return constrained_[dof] != 0; }
  bool any_constrained() const { return !prescribed_dofs_.empty(); }
  const std::vector<Index>& constrained_dofs() const { return prescribed_dofs_; }
  /// Every held dof: the constrained ones, which follow their path, and the others (the
  /// enriched dofs of constrained nodes, rows no element couples), which stay where they are.
  const std::vector<Index>& held_dofs() const { return held_dofs_; }

  /// |v| over the free dofs. A plain loop in index order: zeros appended to v add nothing.
  Scalar free_norm(const Vector& v) const {
    Scalar s = 0;
    const Index n = num_dofs();
    for (Index i = 0; i < n; ++i)
      if (!held_[i]) s += v[i] * v[i];
    return std::sqrt(s);
  }
  void zero_held(Vector& v) const { blocks_.zero(v); }

  /// A = cm M + K + cd Kd (same pattern: one pass over the values, split between `threads` as
  /// the CG's products split A: assembly/block_matrix.hpp's for_value_ranges says why), then
  /// the held rows and columns become identity.
  void form(Scalar cm, Scalar cd, int threads) {
    A.set_combination(cm, M, K, cd, cd != 0 ? &Kd : nullptr, threads);
    blocks_.apply(A);
  }
  /// A = M with held rows as identity (the initial acceleration solve).
  void form_mass(int threads) {
    A.copy_values(M, threads);
    blocks_.apply(A);
    coefficients_ = {0, 0, 0};
  }
  /// A = K with held rows as identity (statics).
  void form_stiffness(int threads) {
    A.copy_values(K, threads);
    blocks_.apply(A);
    coefficients_ = {0, 0, 0};
  }
  /// Whether A already holds cm M + K + cd Kd of the current K (then the direct solver reuses
  /// its factorisation); records it as holding them after the call. For a constant tangent, and
  /// for a real-time step whose tangent was kept (NewmarkSettings::tangent_reach; undamped only:
  /// Kd's changes are not tracked here).
  bool same_coefficients(Scalar cm, Scalar cd) {
    const std::array<Scalar, 3> c{cm, cd, 1};
    const bool same = coefficients_ == c;
    coefficients_ = c;
    return same;
  }

  /// K of a constant-tangent model, assembled once per rest-shape epoch: current while no
  /// rebuild and no other assembly has written K since (EquationOfMotion::internal_force
  /// assembles it only when it is not).
  bool constant_tangent_current(std::uint64_t epoch) const {
    return K_constant_stamp_ == tangent_stamp_ && K_epoch_ == epoch;
  }
  void set_constant_tangent_current(std::uint64_t epoch) {
    K_epoch_ = epoch;
    K_constant_stamp_ = tangent_stamp_;
  }

  /// f = f_int(u) of the body, and its tangent of the given kind into K when asked. false if
  /// some element cannot be evaluated at u.
  bool assemble(const Body& body, const Vector& u, Vector& f, bool with_tangent, TangentKind kind, int threads) {
    if (!with_tangent) return body.assemble(u, f, nullptr, kind, threads);
    ++tangent_stamp_;
    coefficients_ = {0, 0, 0};  // A no longer holds cm M + K + cd Kd of this K
    return body.assemble(u, f, &K, kind, threads);
  }
  /// Names what K holds: it changes with every assemble() of a tangent and every rebuild, never
  /// returns to an earlier value, and is never 0.
  std::uint64_t tangent_stamp() const { return tangent_stamp_; }

  /// Kd = the projected tangent K_proj(u) of the body at u (Rayleigh damping's stiffness),
  /// assembled into a matrix of the current pattern. A constant tangent's (`constant`) is K0 of
  /// the current rest shapes at every u: assembled once per rest-shape epoch and dof map.
  /// false if some element cannot be evaluated at u (Kd is then incomplete).
  bool damping_stiffness_at(const Body& body, const Vector& u, bool constant, int threads) {
    const auto epoch = body.data().epoch();
    if (constant && Kd_current_ && Kd_epoch_ == epoch) return true;
    if (Kd.num_values() != K.num_values()) Kd = body.assembler().zero_matrix();
    damping_force_.resize(u.size());
    Kd_current_ = body.assemble(u, damping_force_, &Kd, TangentKind::Projected, threads);
    Kd_epoch_ = epoch;
    return Kd_current_;
  }

  /// The round-off level of a force evaluation on this mesh, Newton's absolute floor (ten times
  /// this): a body in equilibrium under no load has nothing but this round-off for a force scale
  /// (an unloaded Hex8 bar failed its fourth step at |r| = 1.9e-11, "relative 0.58"; a body
  /// held by prescribed displacements alone, whose free internal forces are the residual itself,
  /// failed every solve after the one that brought it there).
  ///
  /// The larger of |f_int| at the rest state (u = the rest displacement) and at the rest state
  /// translated by 1e-3 of the body's size. A translation leaves every exact force zero, so what
  /// either evaluation returns is round-off; the translated one is that of positions that are not
  /// exactly representable, as every deformed state's are (~10 eps |x| of strain from F = x G).
  /// The rest state alone can be exact: on a Tet4 mesh with integer nodes (unit-cube cells, G in
  /// {0, +-1}) and for the Linear kernels f_int(rest) is 0 bit for bit, which made the floor 0 and
  /// a settled body unable to converge again (issue 33: a third static solve and the next step
  /// failed at |r| ~ 1e-11; measured on a 2 x 2 x 2 Kuhn box, E = 3000: rest 0, translated 1.1e-11;
  /// Hex8 bar90: rest 2.6e-11, translated 8.6e-11).
  ///
  /// Assembled once per dof map (two force evaluations). Plastic flow changes the rest shapes
  /// every step it flows, and keeps the measurement: the translated rest state already has
  /// generic, rounded positions, as the flowed shapes do, and flow changes neither the stiffness
  /// nor the size of the positions that set the round-off level. A cut recomputes it.
  Scalar rest_force_roundoff(const Body& body, int threads) {
    if (roundoff_dofs_ != body.num_dofs()) {
      Vector f(body.num_dofs());
      Vector u = body.rest_displacement();
      bool ok = body.assemble(u, f, nullptr, TangentKind::Projected, threads);
      Scalar level = ok && f.allFinite() ? f.norm() : 0;
      // 1e-3 of the size (positions keep their magnitude), in steps that are not powers of two.
      const Vec3 t = 1e-3 * body.size() * Vec3(1.0 / 3, 1.0 / 7, 1.0 / 11);
      for (Index i = 0; i < body.mesh().num_nodes(); ++i) u.segment<3>(3 * i) += t;
      ok = body.assemble(u, f, nullptr, TangentKind::Projected, threads);
      if (ok && f.allFinite()) level = std::max(level, f.norm());
      roundoff_ = level;
      roundoff_dofs_ = body.num_dofs();
    }
    return roundoff_;
  }

  LinearSolver& linear() { return linear_; }
  LinearSolver& static_linear() { return static_linear_; }

 private:
  /// M: each element's scalar mass (mass.hpp) scattered into the current pattern, then the
  /// enriched part. With enrichment the element masses are kept from the first build: each cut
  /// re-patterns M, and computing them all again was half of a tear event (sheet_tear: 4.2 ms
  /// median). Without, M is built once and keeps no copy (512 bytes per Hex8).
  void build_mass(const Body& body, MassKind kind) {
    const auto& mesh = body.mesh();
    if constexpr (!Enriched) {
      assemble_mass(mesh, body.assembler(), body.material().density, kind, M);
    } else {
      if (element_masses_.size() != static_cast<size_t>(mesh.num_elements()) || element_mass_kind_ != kind) {
        element_masses_.resize(static_cast<size_t>(mesh.num_elements()));
        for (Index e = 0; e < mesh.num_elements(); ++e)
          element_masses_[static_cast<size_t>(e)] =
              element_mass<E>(mesh.element_nodes(e), body.material().density * mesh.weight(e), kind);
        element_mass_kind_ = kind;
      }
      const auto own = [this](Index e) -> const ElementScalarMatrix<E>& { return element_masses_[static_cast<size_t>(e)]; };
      scatter_mass(mesh, body.assembler(), own, M);
      if (body.has_cuts()) body.add_enriched_mass(M, kind, own);
    }
  }

  LinearSolver linear_, static_linear_;
  std::vector<ElementScalarMatrix<E>> element_masses_;  ///< build_mass's, of element_mass_kind_
  MassKind element_mass_kind_ = MassKind::Consistent;
  std::vector<char> held_, constrained_;
  Vector damping_force_;  ///< damping_stiffness_at's force, unused
  std::vector<Index> prescribed_dofs_, held_dofs_;
  ConstrainedBlocks blocks_;
  std::array<Scalar, 3> coefficients_{0, 0, 0};
  std::uint64_t K_epoch_ = 0;
  std::uint64_t tangent_stamp_ = 1;  ///< tangent_stamp()
  std::uint64_t K_constant_stamp_ = 0;  ///< the stamp of the constant tangent's K (0: none yet)
  bool Kd_current_ = false;          ///< Kd is the damping stiffness of rest-shape epoch Kd_epoch_
  std::uint64_t Kd_epoch_ = 0;
  Index roundoff_dofs_ = -1;
  Scalar roundoff_ = 0;
};

}  // namespace plastifem
