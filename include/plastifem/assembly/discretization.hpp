#pragma once
// Discretization<E, Elastic>: the discrete body a solver works on. It owns the mesh, the dof
// map, the assembler built for that dof map, and the per-element data of the elastic model
// (from the current rest shapes); it evaluates the internal force, the tangent and the strain
// energy at any displacement, element by element, in the assembler's deterministic order.
//
// Everything here is a function of (u, rest shapes): no time, no loads, no constraints. The
// plastic policy changes rest shapes through data() (copy-on-write per element, epoch), the
// enrichment policy the dof map through dof_map(); rebuild() then brings the assembler up to
// date. Both compile to nothing for NoPlasticity / NoEnrichment.
#include <plastifem/assembly/element_data.hpp>
#include <plastifem/assembly/mass.hpp>

#include <limits>
#include <string>

namespace plastifem {

template <FiniteElement E, class Elastic>
  requires ElasticModel<Elastic, E>
class Discretization {
 public:
  static constexpr int N = E::num_nodes;
  static constexpr bool has_exact_tangent = has_exact_tangent_v<Elastic>;
  using Data = typename Elastic::template ElementData<E>;

  Discretization(const Mesh<E>& mesh, const Material& material)
      : mesh_(mesh), dofs_(mesh.num_nodes()), assembler_(mesh_, dofs_), data_(mesh_, material) {
    if (mesh_.num_elements() == 0)
      fail<MeshError>("the mesh has no elements ({} nodes): nothing to simulate", mesh_.num_nodes());
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
    if (K) K->set_zero();
    assembler_.for_each_element(
        [&](Index e) {
          ElementVector<E> fe;
          ElementMatrix<E> Ke;
          // Only Ke's lower blocks are read by the scatter (assembly/assembler.hpp).
          element_energy_[e] =
              Elastic::template evaluate<E>(data_[e], current_nodes(e, u), fe, K ? &Ke : nullptr, kind, true);
          const auto& c = mesh_.element(e);
          for (int a = 0; a < N; ++a) f.segment<3>(3 * c[a]) += fe.template segment<3>(3 * a);
          if (K) assembler_.add_element_matrix(e, Ke, values);
        },
        threads);
    return std::isfinite(energy()) && f.allFinite();
  }
  /// The tangent at rest (u = the rest displacement): K0, positive semi-definite, for Rayleigh
  /// damping.
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
    for (Index e = 0; e < mesh_.num_elements(); ++e)
      w += Elastic::template evaluate<E>(data_[e], current_nodes(e, u), fe, nullptr);
    return w;
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
      const Scalar w = Elastic::template evaluate<E>(data_[e], x, fe, nullptr);
      if (std::isfinite(w) && fe.allFinite()) continue;
      for (int k = 0; k < q.size; ++k)
        if (!(jacobian<E>(x, q.points[k]).determinant() > 0))
          return fmt::format(" (element {} is inverted at quadrature point {}: det F <= 0; {} is undefined there, "
                             "StableNeoHookean is not)",
                             e, k, Elastic::name);
      return fmt::format(" (element {} has a non-finite internal force)", e);
    }
    return "";
  }

  /// Deformed volume at u.
  Scalar volume(const Vector& u) const {
    Scalar v = 0;
    for (Index e = 0; e < mesh_.num_elements(); ++e) v += element_volume<E>(current_nodes(e, u));
    return v;
  }
  /// Cauchy stress per element at its centre.
  std::vector<Mat3> element_stress(const Vector& u) const {
    std::vector<Mat3> s(mesh_.num_elements());
    for (Index e = 0; e < mesh_.num_elements(); ++e)
      s[e] = Elastic::template cauchy_stress<E>(data_[e], current_nodes(e, u), material());
    return s;
  }

 private:
  Mesh<E> mesh_;  // a copy: the solver stays valid whatever happens to the caller's mesh
  DofMap dofs_;
  Assembler<E> assembler_;
  ElementDataTable<E, Elastic> data_;
  Vector X_;  ///< rest positions of the nodes
  Scalar size_ = 1;
  mutable std::vector<Scalar> element_energy_;  ///< W_e of the last assembly (line search, validity)
  mutable Vector rest_u_;                       ///< rest displacement (zero without plastic flow)
  bool has_rest_u_ = false;
};

}  // namespace plastifem
