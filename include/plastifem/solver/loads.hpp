#pragma once
// External loads with handles: nodal forces (one force for many nodes, or one per node), point
// forces, body forces per unit mass (gravity) and surface tractions, each scaled by a load curve.
//
// Each load keeps its definition and a force vector at curve value 1, recomputed when what it
// depends on changes: the dof map (the vector grows with it) and, for body forces, the mass
// kind, since a body force must pair with the mass matrix for a free body to fall at exactly g
// (assembly/mass.hpp: consistent loads with the consistent mass, M_L g with the lumped one).
// In a cut body (X-FEM) every load also loads the enriched dofs, as the force's work on the
// field at its point asks (EnrichedLoads): a traction on a face the cut crosses is integrated
// over each piece of the face on its own side.
#include <plastifem/assembly/mass.hpp>
#include <plastifem/mesh/selection.hpp>
#include <plastifem/solver/boundary.hpp>

#include <functional>
#include <string>
#include <variant>

namespace plastifem {

/// A cut body's share of the loads on its enriched dofs, added to a load vector F (its rows
/// after the nodes'); empty functions for a body without cuts.
struct EnrichedLoads {
  std::function<void(const Vec3& g, MassKind, Vector& F)> body;          ///< gravity g, integrated per piece
  std::function<void(Index node, const Vec3& f, Vector& F)> node;        ///< f at a node, on its own side
  std::function<void(Index e, const Vec3& xi, const Vec3& f, Vector& F)> point;  ///< f at xi in element e
  std::function<void(FaceRef face, const Vec3& t, Vector& F)> traction;         ///< t on a face, per piece
  explicit operator bool() const { return bool(body); }
};

/// Names a load for Solver::remove_load, of the solver that issued it only
/// (core/handle_owner.hpp).
struct LoadHandle {
  std::uint32_t id = 0;     ///< 0: none
  std::uint32_t owner = 0;  ///< the issuing Loads' HandleOwner number
  explicit operator bool() const { return id != 0; }
  friend bool operator==(LoadHandle, LoadHandle) = default;
};

template <FiniteElement E>
class Loads {
 public:
  struct NodalForces {
    std::vector<Index> nodes;
    std::vector<Vec3> forces;  ///< one per node
  };
  /// A force at a point of element `element`, reference coordinates xi.
  struct PointForce {
    Index element;
    Vec3 xi;
    Vec3 f;
  };
  struct BodyForce {
    Vec3 g;  ///< per unit mass
  };
  struct Traction {
    std::vector<FaceRef> faces;
    Vec3 t;  ///< per unit reference area
  };
  using Definition = std::variant<NodalForces, PointForce, BodyForce, Traction>;

  // The definitions, from a user's input checked against the mesh (InvalidArgument says what is
  // wrong, `what` naming the load).
  static NodalForces nodal_force(const Mesh<E>& mesh, std::span<const Index> nodes, const Vec3& f) {
    check_node_ids(nodes, mesh.num_nodes(), "nodal force");
    check_finite(f, "nodal force");
    return {{nodes.begin(), nodes.end()}, std::vector<Vec3>(nodes.size(), f)};
  }
  static NodalForces nodal_forces(const Mesh<E>& mesh, std::span<const Index> nodes, std::span<const Vec3> forces) {
    const char* what = "nodal forces";
    check_node_ids(nodes, mesh.num_nodes(), what);
    if (forces.size() != nodes.size()) fail<InvalidArgument>("{}: {} forces for {} nodes", what, forces.size(), nodes.size());
    for (const Vec3& f : forces) check_finite(f, "nodal force");
    return {{nodes.begin(), nodes.end()}, {forces.begin(), forces.end()}};
  }
  /// A point force f at the rest position X: the consistent nodal loads f N_a(xi) of the element
  /// containing X.
  static PointForce point_force(const Mesh<E>& mesh, const Vec3& X, const Vec3& f) {
    check_finite(X, "point force position");
    check_finite(f, "point force");
    const auto where = locate_point(mesh, X);
    if (!where)
      fail<InvalidArgument>("point force: ({}, {}, {}) is in no element of the mesh (rest configuration)", X.x(), X.y(),
                            X.z());
    return {where->element, where->xi, f};
  }
  static BodyForce body_force(const Vec3& g) {
    check_finite(g, "gravity");
    return {g};
  }
  static Traction traction(const Mesh<E>& mesh, const std::vector<FaceRef>& faces, const Vec3& t) {
    check_finite(t, "traction");
    for (const FaceRef& f : faces)
      if (f.element < 0 || f.element >= mesh.num_elements() || f.face < 0 || f.face >= E::num_faces)
        fail<InvalidArgument>("traction: face (element {}, local face {}) out of range", f.element, f.face);
    check_boundary_faces(mesh, faces, "traction");  // (inside the body, or counted twice)
    return {faces, t};
  }

  LoadHandle add(Definition def, LoadCurve curve, std::string what) {
    loads_.push_back({++next_id_, std::move(def), std::move(curve), std::move(what), Vector()});
    ++version_;
    return {next_id_, owner_.id()};
  }
  void remove(LoadHandle h) {
    if (h.owner != owner_.id())
      fail<InvalidArgument>("load handle {} {}", h.id,
                            h.owner == 0 ? "was never issued (a default handle names no load)"
                                         : "belongs to another solver: a handle names a load of the solver that issued it");
    auto it = std::find_if(loads_.begin(), loads_.end(), [&](const Load& l) { return l.id == h.id; });
    if (it == loads_.end()) fail<InvalidArgument>("load handle {} names no current load (removed already?)", h.id);
    loads_.erase(it);
    ++version_;
  }
  void clear() {
    loads_.clear();
    ++version_;
  }
  bool empty() const { return loads_.empty(); }
  /// Changes whenever a load is added or removed.
  std::uint64_t version() const { return version_; }

  /// Recomputes every load's force vector for num_dofs dofs (standard dofs first), with a cut
  /// body's enriched share (`enriched`, not kept).
  void build(const Mesh<E>& mesh, Scalar density, MassKind mass, Index num_dofs, const EnrichedLoads& enriched = {}) {
    for (Load& l : loads_) compute(l, mesh, density, mass, num_dofs, enriched);
    built_ = {density, mass, num_dofs};
  }
  /// f = sum of curve(t) x load vector. Throws InvalidArgument if a curve gives a non-finite value.
  void assemble(Scalar t, Vector& f) const {
    f.setZero();
    for (const Load& l : loads_) {
      const Scalar c = l.curve ? l.curve(t) : 1.0;
      if (!std::isfinite(c)) fail<InvalidArgument>("load curve of the {} gives {} at t = {}", l.what, c, t);
      if (c != 0) f += c * l.force;
    }
  }
  /// A newly added load's vector needs build_one before use (cheap: that load only).
  void build_last(const Mesh<E>& mesh, const EnrichedLoads& enriched = {}) {
    if (!loads_.empty()) compute(loads_.back(), mesh, built_.density, built_.mass, built_.num_dofs, enriched);
  }

 private:
  static void check_finite(const Vec3& v, const char* what) {
    if (!v.allFinite()) fail<InvalidArgument>("{} must be finite, got ({}, {}, {})", what, v.x(), v.y(), v.z());
  }

  struct Load {
    std::uint32_t id;
    Definition def;
    LoadCurve curve;
    std::string what;
    Vector force;  ///< at curve value 1
  };
  struct Built {
    Scalar density = 1;
    MassKind mass = MassKind::Consistent;
    Index num_dofs = 0;
  };

  static void compute(Load& l, const Mesh<E>& mesh, Scalar density, MassKind mass, Index num_dofs,
                      const EnrichedLoads& enriched) {
    Vector F = Vector::Zero(num_dofs);
    if (const auto* n = std::get_if<NodalForces>(&l.def)) {
      for (size_t k = 0; k < n->nodes.size(); ++k) {
        F.segment<3>(3 * n->nodes[k]) += n->forces[k];
        if (enriched) enriched.node(n->nodes[k], n->forces[k], F);
      }
    } else if (const auto* p = std::get_if<PointForce>(&l.def)) {
      const auto Nxi = E::shape(p->xi);  // the consistent nodal loads f N_a(xi)
      const auto& c = mesh.element(p->element);
      for (int a = 0; a < E::num_nodes; ++a)
        if (Nxi[a] != 0) F.segment<3>(3 * c[a]) += Nxi[a] * p->f;
      if (enriched) enriched.point(p->element, p->xi, p->f, F);
    } else if (const auto* b = std::get_if<BodyForce>(&l.def)) {
      F.head(3 * mesh.num_nodes()) = body_force_load(mesh, density, b->g, mass);
      if (enriched) enriched.body(b->g, mass, F);
    } else if (const auto* tr = std::get_if<Traction>(&l.def)) {
      F.head(3 * mesh.num_nodes()) = traction_load(mesh, tr->faces, tr->t);
      if (enriched)
        for (const FaceRef& f : tr->faces) enriched.traction(f, tr->t, F);
    }
    l.force = std::move(F);
  }

 public:
  /// Consistent nodal loads int_face N_a t dA of a traction t (force per unit reference area) on
  /// boundary faces. Faces are integrated with the element's own shape functions on the face
  /// (the reference face is mapped into the reference element), with a rule exact for the
  /// face's N_a times its area element on flat faces.
  static Vector traction_load(const Mesh<E>& mesh, const std::vector<FaceRef>& faces, const Vec3& t) {
    Vector F = Vector::Zero(3 * mesh.num_nodes());
    for (const FaceRef& f : faces) {
      const ElementNodes<E> X = mesh.element_nodes(f.element);
      for_each_face_point<E>(f.face, [&](const Vec3& xi, const Vec3& dxi_ds, const Vec3& dxi_dt, Scalar w) {
        const Scalar dA = face_area_element<E>(X, xi, dxi_ds, dxi_dt);
        const auto Nf = E::shape(xi);
        for (int a = 0; a < E::num_nodes; ++a) F.segment<3>(3 * mesh.element(f.element)[a]) += w * dA * Nf[a] * t;
      });
    }
    return F;
  }

 private:
  std::vector<Load> loads_;
  std::uint32_t next_id_ = 0;
  std::uint64_t version_ = 0;
  Built built_;
  HandleOwner owner_;
};

}  // namespace plastifem
