#pragma once
// Discretization<E, Elastic, Enriched>: the discrete body a solver works on. It owns the mesh, the dof
// map, the assembler built for that dof map, and the per-element data of the elastic model
// (from the current rest shapes); it evaluates the internal force, the tangent and the strain
// energy at any displacement, element by element, in the assembler's deterministic order.
//
// Everything here is a function of (u, rest shapes): no time, no loads, no constraints. The
// plastic policy changes rest shapes through data() (copy-on-write per element, epoch), the
// enrichment policy the dof map and the enriched elements through cut() (X-FEM, seed 001:
// enrichment/enrichment.hpp); rebuild() then brings the assembler up to date. An enriched
// element is integrated over its pieces by its point law (enrichment/cut_element.hpp); with no
// cut the element loop takes one predictable branch per element.
//
// `Enriched` says whether the body can be cut (any active enrichment policy: Heaviside,
// ShiftedHeaviside, or a user's, enrichment/enrichment_policy.hpp).
// Without it every cut path is discarded by `if constexpr`: the X-FEM code is neither compiled
// nor included (its headers come with <plastifem/cutting.hpp>), and the element loop has no
// branch at all. Both enriched policies share one Discretization (they differ in the functions,
// enrichment/enrichment.hpp, not in how the body is assembled).
#include <plastifem/assembly/element_data.hpp>
#include <plastifem/assembly/mass.hpp>
#include <plastifem/enrichment/cut_types.hpp>

#include <cmath>
#include <limits>
#include <string>
#include <type_traits>

namespace plastifem {

template <FiniteElement E>
class Enrichment;  // enrichment/enrichment.hpp
template <FiniteElement E>
struct CutElement;  // enrichment/cut_element.hpp

template <FiniteElement E, class Elastic, bool Enriched = false>
  requires ElasticModel<Elastic, E>
class Discretization {
  struct NoCuts {};

 public:
  static constexpr int N = E::num_nodes;
  static constexpr bool has_exact_tangent = has_exact_tangent_v<Elastic>;
  using Data = typename Elastic::template ElementData<E>;

  Discretization(const Mesh<E>& mesh, const Material& material)
      : mesh_(mesh), dofs_(mesh.num_nodes()), assembler_(mesh_, dofs_), data_(mesh_, material), law_(make_law(material)) {
    if (mesh_.num_elements() == 0)
      fail<MeshError>("the mesh has no elements ({} nodes): nothing to simulate", mesh_.num_nodes());
    check_scale(material);
    element_energy_.assign(mesh_.num_elements(), 0.0);
    X_ = Eigen::Map<const Vector>(mesh_.nodes().data(), 3 * mesh_.num_nodes());
    size_ = (mesh_.nodes().rowwise().maxCoeff() - mesh_.nodes().rowwise().minCoeff()).norm();
  }

  const Mesh<E>& mesh() const { return mesh_; }
  const DofMap& dof_map() const { return dofs_; }
  DofMap& dof_map() { return dofs_; }
  const Assembler<E>& assembler() const { return assembler_; }
  const ElementDataTable<E, Elastic>& data() const { return data_; }
  ElementDataTable<E, Elastic>& data() { return data_; }
  const Material& material() const { return data_.material(); }
  /// The cuts and the enriched elements (empty without a cut).
  const Enrichment<E>& enrichment() const
    requires Enriched
  {
    return enrichment_;
  }
  /// Whether some element is cut.
  bool has_cuts() const {
    if constexpr (Enriched) return !enrichment_.empty();
    else return false;
  }
  /// Applies a cut (enrichment/enrichment.hpp); the caller then rebuilds what depends on the dof
  /// map. Throws InvalidArgument, with nothing changed, if the cut is refused. `rest` (3 per
  /// node, or null for the mesh): the nodes' rest positions after plastic flow, which the
  /// enriched elements' stiffness points are mapped with (the cut itself is placed in the
  /// mesh's coordinates).
  CutReport cut(const Cut& surface, const CutOptions& options, EnrichmentFunction psi, int id, int& applied_id,
                const Vector* rest = nullptr)
    requires Enriched
  {
    return enrichment_.apply(mesh_, dofs_, surface, options, psi, id, applied_id, rest);
  }
  /// Gives element e the rest shape X (plastic flow): its elastic data and, if it is enriched,
  /// its pieces' stiffness points. Throws InvalidArgument, with nothing changed, if X fails the
  /// rest-shape test (unless the caller has `checked` it).
  void set_rest_shape(Index e, const ElementNodes<E>& X, bool checked = false) {
    data_.set_rest_shape(e, X, checked);
    if constexpr (Enriched) enrichment_.set_rest_shape(e, X);
  }
  /// set_rest_shape(e, rest_of(e), checked = true) for the distinct elements `elements`, the
  /// element data prepared on `threads` threads (ElementDataTable::set_rest_shapes).
  template <class RestOf>
  void set_rest_shapes(const std::vector<Index>& elements, RestOf&& rest_of, int threads) {
    data_.set_rest_shapes(elements, rest_of, threads);
    if constexpr (Enriched)
      for (Index e : elements)
        if (enrichment_.element(e)) enrichment_.set_rest_shape(e, rest_of(e));
  }
  Index num_dofs() const { return assembler_.num_dofs(); }
  /// Diameter of the mesh's bounding box (the length scale of increment tests).
  Scalar size() const { return size_; }

  /// Whether the assembler is behind the dof map.
  bool stale() const { return assembler_.dof_version() != dofs_.version(); }
  /// Rebuilds the assembler (pattern, tables, colouring) for the current dof map.
  void rebuild() {
    if (stale()) assembler_ = Assembler<E>(mesh_, dofs_);
  }

  /// Current positions of element e's nodes: X + u.
  ElementNodes<E> current_nodes(Index e, const Vector& u) const {
    ElementNodes<E> x;
    const auto& c = mesh_.element(e);
    for (int a = 0; a < N; ++a) x.col(a) = X_.segment<3>(3 * c[a]) + u.segment<3>(3 * c[a]);
    return x;
  }

  /// f = f_int(u) (the vector's entries beyond the nodes' are zero); with K: also the tangent,
  /// written into K's values (the pattern is the assembler's). Returns false if some element
  /// could not be evaluated (a non-finite energy or force: an element inverted for an energy
  /// with ln J, or a non-finite u); locate_invalid() then says which.
  bool assemble(const Vector& u, Vector& f, BlockSymmetricMatrix* K, TangentKind kind, int threads) const {
    f.setZero();
    Scalar* values = K ? K->values() : nullptr;
    if (K) K->set_zero(threads);
    [[maybe_unused]] const bool cuts = has_cuts();
    const bool weighted = mesh_.weighted();
    assembler_.for_each_element(
        [&](Index e) {
          if constexpr (Enriched) {
            if (cuts)
              if (const auto* c = enrichment_.element(e)) return assemble_enriched(*c, e, u, f, K, kind);
          }
          ElementVector<E> fe;
          ElementMatrix<E> Ke;
          // Only Ke's lower blocks are read by the scatter (assembly/assembler.hpp).
          element_energy_[e] =
              Elastic::template evaluate<E>(data_[e], current_nodes(e, u), fe, K ? &Ke : nullptr, kind, true);
          if (weighted) weigh(e, fe, K ? &Ke : nullptr);
          const auto& c = mesh_.element(e);
          for (int a = 0; a < N; ++a) f.segment<3>(3 * c[a]) += fe.template segment<3>(3 * a);
          if (K) assembler_.add_element_matrix(e, Ke, values);
        },
        threads);
    return std::isfinite(energy()) && f.allFinite();
  }
  /// The tangent at rest (u = the rest displacement): K0, positive semi-definite.
  void assemble_rest_stiffness(BlockSymmetricMatrix& K0) const {
    Vector f(num_dofs());
    assemble(rest_displacement(), f, &K0, TangentKind::Projected, 1);
  }
  /// The displacement at which the body is at rest: zero, or x - X once plastic flow has moved
  /// the rest shapes to a material mesh x (plastic/plasticity.hpp). Constant-tangent models use
  /// it (f = K (u - u_rest)).
  const Vector& rest_displacement() const {
    if (rest_u_.size() != num_dofs()) {
      const Index old = static_cast<Index>(rest_u_.size());
      rest_u_.conservativeResize(num_dofs());
      rest_u_.tail(num_dofs() - old).setZero();
    }
    return rest_u_;
  }
  bool has_rest_displacement() const { return has_rest_u_; }
  void set_rest_displacement(const Vector& u) {
    rest_u_.setZero(num_dofs());
    rest_u_.head(u.size()) = u;
    has_rest_u_ = true;
  }
  /// Strain energy of the last assembly.
  Scalar energy() const {
    Scalar w = 0;
    for (Scalar we : element_energy_) w += we;
    return w;
  }
  /// Strain energy at u (a force evaluation).
  Scalar strain_energy(const Vector& u) const {
    Scalar w = 0;
    ElementVector<E> fe;
    for (Index e = 0; e < mesh_.num_elements(); ++e) {
      if constexpr (Enriched) {
        if (const auto* c = enrichment_.element(e)) {
          typename CutElement<E>::SpanVector fx;
          w += mesh_.weight(e) *
               c->template evaluate<Elastic>(law_, current_nodes(e, u), u, fx, nullptr, TangentKind::Projected);
          continue;
        }
      }
      w += mesh_.weight(e) * Elastic::template evaluate<E>(data_[e], current_nodes(e, u), fe, nullptr);
    }
    return w;
  }

  /// The enriched elements' share of the mass matrix beyond the standard assembly's
  /// (assemble_mass: each element's own, `own_mass(e)`, which the caller keeps), added into M
  /// (assembly/mass.hpp's pattern for this dof map; enrichment/cut_element.hpp).
  template <class OwnMass>
  void add_enriched_mass(BlockSymmetricMatrix& M, MassKind kind, OwnMass&& own_mass) const
    requires Enriched
  {
    for (size_t k = 0; k < enrichment_.elements().size(); ++k) {
      const Index e = enrichment_.element_of(k);
      const Scalar rho = material().density * mesh_.weight(e);
      assembler_.add_extended_matrix(e, enrichment_.elements()[k].enriched_mass(rho, kind, own_mass(e)), M.values());
    }
  }
  /// The enriched elements' share of a body force per unit mass g beyond the standard load's
  /// (body_force_load; enrichment/cut_element.hpp), added into F; none with the lumped mass.
  void add_enriched_body_force(const Vec3& g, MassKind kind, Vector& F) const
    requires Enriched
  {
    if (kind == MassKind::Lumped) return;
    for (size_t k = 0; k < enrichment_.elements().size(); ++k) {
      const CutElement<E>& c = enrichment_.elements()[k];
      const Index e = enrichment_.element_of(k);
      const auto f = c.body_force(mesh_.element_nodes(e), material().density * mesh_.weight(e), g);
      for (int a = 0; a < N; ++a) F.template segment<3>(3 * mesh_.element(e)[a]) += f.template segment<3>(3 * a);
      for (size_t j = 0; j < c.enriched.size(); ++j)
        F.template segment<3>(3 * c.enriched[j].row) += f.template segment<3>(3 * (N + static_cast<int>(j)));
    }
  }
  /// The enriched dofs' share of a traction t on a face (enrichment/cut_element.hpp), added
  /// into F; nothing if the face's element has no enriched dofs.
  void add_enriched_traction(FaceRef face, const Vec3& t, Vector& F) const
    requires Enriched
  {
    const CutElement<E>* c = enrichment_.element(face.element);
    if (!c) return;
    const auto f = c->enriched_traction(mesh_.element_nodes(face.element), face.face, t);
    for (size_t j = 0; j < f.size(); ++j) F.template segment<3>(3 * c->enriched[j].row) += f[j];
  }

  /// Says where a non-finite force comes from: the first element whose force is not finite,
  /// and whether it is inverted (det F <= 0 at a quadrature point, outside the domain of
  /// energies with ln J).
  std::string locate_invalid(const Vector& u) const {
    if (!u.allFinite()) return " (the displacement itself is not finite)";
    const auto q = E::template quadrature<E::stiffness_degree>();
    ElementVector<E> fe;
    for (Index e = 0; e < mesh_.num_elements(); ++e) {
      const ElementNodes<E> x = current_nodes(e, u);
      if constexpr (Enriched) {
        if (const auto* c = enrichment_.element(e)) {
          typename CutElement<E>::SpanVector fx;
          const Scalar w = c->template evaluate<Elastic>(law_, x, u, fx, nullptr, TangentKind::Projected);
          if (std::isfinite(w) && fx.allFinite()) continue;
          return fmt::format(" (cut element {}: a piece is inverted or its force is not finite)", e);
        }
      }
      const Scalar w = Elastic::template evaluate<E>(data_[e], x, fe, nullptr);
      if (std::isfinite(w) && fe.allFinite()) continue;
      for (int k = 0; k < q.size; ++k)
        if (!(jacobian<E>(x, q.points[k]).determinant() > 0)) {
          if constexpr (defined_when_inverted_v<Elastic>)  // so its force overflowed
            return fmt::format(" (element {} has a non-finite internal force: it is inverted at quadrature point {}, "
                               "where {} is defined, so the force overflowed)",
                               e, k, Elastic::name);
          else
            return fmt::format(" (element {} is inverted at quadrature point {}: det F <= 0; {} is undefined there, "
                               "StableNeoHookean is not)",
                               e, k, Elastic::name);
        }
      return fmt::format(" (element {} has a non-finite internal force)", e);
    }
    return "";
  }

  /// Deformed volume at u (a cut element's pieces each moved with their own side).
  Scalar volume(const Vector& u) const {
    Scalar v = 0;
    for (Index e = 0; e < mesh_.num_elements(); ++e) {
      const ElementNodes<E> x = current_nodes(e, u);
      if constexpr (Enriched) {
        if (const auto* c = enrichment_.element(e)) {
          for (int s = 0; s < c->num_sides; ++s) {
            const ElementNodes<E> y = c->side_nodes(x, u, s);
            for (int q = 0; q < c->stiffness[s].size(); ++q)
              v += c->stiffness[s].dv[q] * (y * c->stiffness[s].G[q]).determinant();
          }
          continue;
        }
      }
      v += element_volume<E>(x);
    }
    return v;
  }
  /// Cauchy stress of element e at its centre; in an enriched element, of side s (its nodes
  /// moved by side s's field x + sum psi^s a: a blending element's one side, a cut element's
  /// piece s, whose element-mean terms are the piece's, as in its forces). The standard dofs
  /// alone are not the field there (Heaviside enrichment).
  Mat3 stress(Index e, const Vector& u, int side = 0) const {
    ElementNodes<E> x = current_nodes(e, u);
    if constexpr (Enriched)
      if (const auto* c = enrichment_.element(e)) {
        x = c->side_nodes(x, u, side);
        if (c->num_sides == 2 && c->has_material(side))
          return Elastic::template cauchy_stress<E>(data_[e], x, material(), &c->stiffness[side]);
      }
    return Elastic::template cauchy_stress<E>(data_[e], x, material());
  }
  /// Cauchy stress per element at its centre (a cut element's: side 0's, the side the level
  /// set is >= 0 on).
  std::vector<Mat3> element_stress(const Vector& u) const {
    std::vector<Mat3> s(mesh_.num_elements());
    for (Index e = 0; e < mesh_.num_elements(); ++e) s[e] = stress(e, u);
    return s;
  }

 private:
  /// A valid mesh (Mesh checks shapes, which do not depend on the units) can still lie beyond
  /// what double precision integrates: in units of 1e200 its volumes overflow, in 1e-120 they
  /// underflow, and a step then fails naming an inverted element. Every element's volume (w det
  /// J at its centre: exact for an affine element, its order of magnitude for any other; one
  /// Jacobian: 1-2% of a Solver construction on bar46080) and mass rho V must be normal
  /// numbers, and its stiffness scale E V^(1/3) finite.
  void check_scale(const Material& m) const {
    const auto& dN = quadrature_gradients<E, 0>();
    const Scalar w = E::template quadrature<0>().weights[0];
    auto volume = [&](Index e) { return w * jacobian_at<E>(mesh_.element_nodes(e), dN[0]).determinant(); };
    auto check = [&](Index e) {
      const Scalar V = volume(e);
      if (!(V > 0) || !std::isnormal(V) || !std::isnormal(m.density * V) || !std::isfinite(m.young * std::cbrt(V)))
        fail<MeshError>("element {} has volume {} (mass {}, stiffness scale E V^(1/3) = {}): beyond what double "
                        "precision integrates; give the mesh and the material in other units",
                        e, V, m.density * V, m.young * std::cbrt(V));
    };
    Index smallest = 0, largest = 0;
    Scalar v_min = volume(0), v_max = v_min;
    for (Index e = 0; e < mesh_.num_elements(); ++e) {
      const Scalar V = volume(e);
      if (!(V > 0) || !std::isnormal(V)) check(e);  // throws
      if (V < v_min) v_min = V, smallest = e;
      if (V > v_max) v_max = V, largest = e;
    }
    check(smallest), check(largest);
  }

  static auto make_law(const Material& m) {
    if constexpr (Enriched) return typename Elastic::Law(m);
    else return (void)m, NoCuts{};
  }
  /// Element e's force, tangent and energy times its weight (Mesh::set_element_weights).
  template <class F, class K>
  void weigh(Index e, F& f, K* Ke) const {
    const Scalar w = mesh_.weight(e);
    f *= w;
    if (Ke) *Ke *= w;
    element_energy_[e] *= w;
  }
  /// An enriched element's force and tangent over its span (enrichment/cut_element.hpp).
  template <class Piecewise = CutElement<E>>
  void assemble_enriched(const Piecewise& c, Index e, const Vector& u, Vector& f, BlockSymmetricMatrix* K,
                         TangentKind kind) const {
    typename Piecewise::SpanVector fe;
    typename Piecewise::SpanMatrix Ke;
    element_energy_[e] = c.template evaluate<Elastic>(law_, current_nodes(e, u), u, fe, K ? &Ke : nullptr, kind);
    if (mesh_.weighted()) weigh(e, fe, K ? &Ke : nullptr);
    const auto& conn = mesh_.element(e);
    for (int a = 0; a < N; ++a) f.template segment<3>(3 * conn[a]) += fe.template segment<3>(3 * a);
    for (size_t k = 0; k < c.enriched.size(); ++k)
      f.template segment<3>(3 * c.enriched[k].row) += fe.template segment<3>(3 * (N + static_cast<int>(k)));
    if (K) assembler_.add_extended_matrix(e, Ke, K->values());
  }

  Mesh<E> mesh_;  // a copy: the solver stays valid whatever happens to the caller's mesh
  DofMap dofs_;
  Assembler<E> assembler_;
  ElementDataTable<E, Elastic> data_;
  [[no_unique_address]] std::conditional_t<Enriched, typename Elastic::Law, NoCuts> law_;  ///< for cut elements
  [[no_unique_address]] std::conditional_t<Enriched, Enrichment<E>, NoCuts> enrichment_;
  Vector X_;  ///< rest positions of the nodes
  Scalar size_ = 1;
  mutable std::vector<Scalar> element_energy_;  ///< W_e of the last assembly (line search, validity)
  mutable Vector rest_u_;                       ///< rest displacement (zero without plastic flow)
  bool has_rest_u_ = false;
};

}  // namespace plastifem
