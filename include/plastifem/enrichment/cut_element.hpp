#pragma once
// An enriched element (seed 001, section 4.3-4.4): what is integrated over its pieces, and how.
//
// The displacement in an element with enriched nodes (eq. 42):
//     u(x) = sum_i N_i(x) u_i + sum_k N_{i(k)}(x) psi_k(x) a_k,
// with psi_k the node's enrichment function: Heaviside, psi = H(x) = +-1 (eq. 43), or shifted,
// psi_k = (H(x) - H_i) / 2 (eq. 44). On each side s of the cut psi_k is a constant psi_k^s, so
// on side s the element is a standard element with effective nodal displacements
//     u_i^s = u_i + sum_{k at node i} psi_k^s a_k.
// Every integral over side s is therefore the standard element's integral over side s's
// quadrature points with the nodes moved to x_i^s = X_i + u_i^s, and the enriched vectors and
// matrices follow by the chain rule (d u_i^s / d a_k = psi_k^s):
//     f_u_i = sum_s f_i^s,              f_a_k = sum_s psi_k^s f_{i(k)}^s,
//     K_uu = sum_s K^s,   K_ua_(i,k) = sum_s psi_k^s K^s_(i, i(k)),   K_aa_(k,l) = sum_s psi_k^s psi_l^s K^s_(i(k), i(l)).
// For the linear model this is eq. 51-57 (with Va / V, Vb / V the share of each side when B is
// constant, eq. 54-57, and its shifted form eq. 60-63); for the corotational models each side has
// its own rotation (eq. 64-71): per quadrature point for Corotational, one per side, from the
// side's mean deformation gradient, for CorotationalPerElement; the hyperelastic models use their
// point law on each side's points. The consistent mass (eq. 76-80) is the same construction with
// m^s_ab = rho sum_q N_a N_b dv_q; the X-FEM lumped mass (eq. 81-82) keeps the element's lumped
// standard diagonal and gives an enriched dof
//     m_aa_k = (V_+ / V (psi_k^+)^2 + V_- / V (psi_k^-)^2) m_uu_i(k).
//
// A cut element has two sides, each with its sub-element quadrature (enrichment/subdivision.hpp);
// an uncut element with enriched nodes (a "blending" element: with Heaviside enrichment every
// element around an enriched node; with the shifted one only where a node lies on the cut) has
// one side, the element's own Gauss rule, and constant psi.
#include <plastifem/assembly/mass.hpp>
#include <plastifem/elastic/elastic.hpp>
#include <plastifem/enrichment/subdivision.hpp>

#include <algorithm>
#include <array>
#include <limits>
#include <vector>

namespace plastifem {

/// One enriched dof block of an element: the local node it sits at, its block row in the dof
/// map, and its enrichment function's value on each side.
struct EnrichedDof {
  int node = 0;
  Index row = 0;
  std::array<Scalar, 2> psi{0, 0};
};

template <FiniteElement E>
struct CutElement {
  static constexpr int N = E::num_nodes;
  /// The most enriched dofs an element may carry: two per node (its own cut, and a neighbour's
  /// through blending).
  static constexpr int max_enriched = 2 * N;
  static constexpr int max_span = 3 * (N + max_enriched);
  using SpanVector = Eigen::Matrix<Scalar, Eigen::Dynamic, 1, 0, max_span, 1>;
  using SpanMatrix = Eigen::Matrix<Scalar, Eigen::Dynamic, Eigen::Dynamic, 0, max_span, max_span>;

  int num_sides = 1;                                   ///< 2: cut; 1: blending (one side, the element's rule)
  int cut = -1;                                        ///< the cut that splits it (-1: none)
  std::array<PointSet<E>, 2> stiffness;                ///< quadrature per side, mapped with the rest shape
  std::array<ReferencePoints, 2> stiffness_rule;       ///< the same points in reference coordinates
  std::array<std::vector<Vec3>, 2> mass_xi;            ///< mass rule per side: reference points
  std::array<std::vector<Scalar>, 2> mass_dv;          ///< and their w det J
  std::array<Scalar, 2> volume{0, 0};                  ///< rest volume of each side
  std::array<std::vector<ReferenceTet>, 2> pieces;     ///< the sides' pieces (reference coordinates): output, points, faces
  std::vector<EnrichedDof> enriched;                   ///< in the order of the element's extension rows

  int span() const { return N + static_cast<int>(enriched.size()); }

  /// Maps the stiffness rules with rest shape X (the mesh's element, or its plastic rest shape:
  /// the cut stays where it is in reference coordinates, a material surface).
  void set_rest_shape(const ElementNodes<E>& X) {
    for (int s = 0; s < num_sides; ++s) {
      PointSet<E>& ps = stiffness[s];
      ps.G.clear(), ps.dv.clear();
      for (size_t k = 0; k < stiffness_rule[s].xi.size(); ++k) ps.add(X, stiffness_rule[s].xi[k], stiffness_rule[s].w[k]);
    }
  }

  /// Whether side s has material (stiffness points): a cut along the element's face, or
  /// through nodes snapped onto it, leaves nothing on one side.
  bool has_material(int s) const { return stiffness[s].size() > 0; }

  /// The side whose pieces contain the reference point xi (0 in a blending element); on the
  /// interface (round-off), the one it is least outside of.
  int side_containing(const Vec3& xi) const {
    if (num_sides == 1) return 0;
    int best = 0;
    Scalar best_outside = std::numeric_limits<Scalar>::infinity();
    for (int s = 0; s < 2; ++s)
      for (const auto& t : pieces[s]) {
        Mat3 A;
        for (int j = 0; j < 3; ++j) A.col(j) = t[j + 1] - t[0];
        const Vec3 b = A.partialPivLu().solve(Vec3(xi - t[0]));
        const Scalar outside = std::max({Scalar(0), -b.minCoeff(), b.sum() - 1});
        if (outside < best_outside) best_outside = outside, best = s;
        if (outside == 0) return s;
      }
    return best;
  }

  /// Effective nodes of side s: x + sum psi^s a at the enriched dofs' nodes (a read from u).
  ElementNodes<E> side_nodes(const ElementNodes<E>& x, const Vector& u, int s) const {
    return side_nodes(x, s, [&](Index row) { return u.template segment<3>(3 * row); });
  }
  /// The same with a_k = `dof(row)` (e.g. an increment u1 - u0 read in place).
  template <class Dof>
  ElementNodes<E> side_nodes(const ElementNodes<E>& x, int s, const Dof& dof) const {
    ElementNodes<E> y = x;
    for (const EnrichedDof& d : enriched) y.col(d.node) += d.psi[s] * dof(d.row);
    return y;
  }

  /// Internal force (span vector) and tangent (span matrix, full) at current nodes x (X + u at
  /// the element's nodes) and system displacement u (for the enriched dofs); returns the strain
  /// energy, non-finite if a side cannot be evaluated.
  template <class Model>
  Scalar evaluate(const typename Model::Law& law, const ElementNodes<E>& x, const Vector& u, SpanVector& f,
                  SpanMatrix* K, TangentKind kind) const {
    const int S = span();
    f.setZero(3 * S);
    if (K) K->setZero(3 * S, 3 * S);
    Scalar W = 0;
    ElementVector<E> fs;
    ElementMatrix<E> Ks;
    for (int s = 0; s < num_sides; ++s) {
      if (!has_material(s)) continue;
      W += Model::template evaluate_points<E>(law, stiffness[s], side_nodes(x, u, s), fs, K ? &Ks : nullptr, kind);
      scatter(fs, K ? &Ks : nullptr, s, f, K);
    }
    return W;
  }

  /// The mass's share beyond the standard assembly's (span matrix), given `own`, the element's
  /// own mass of that kind as the standard assembly has it (element_mass). Lumped: the X-FEM
  /// lumped enriched diagonal (eq. 81-82), from own's diagonal. Consistent: every block from the
  /// sides' rules, m^s = rho sum_q N N^T dv_q, the standard one too in a cut element: its u-u
  /// block gets sum_s m^s - own, replacing the element's own rule. On a non-affine element the
  /// two rules differ (1e-4 of the mass on distorted Hex8 and Wedge6, 3e-3 on curved Tet10), and
  /// with Heaviside enrichment a node's fields on a small side are u +- a, whose masses the rules
  /// must cancel: mixed, the element's mass was indefinite (-1.4e-5 of its scale on Hex8, -4e-4
  /// on Tet10) and the next step could not be solved (review). From one rule of positive
  /// weights it is a Gram matrix: semi-definite.
  SpanMatrix enriched_mass(Scalar density, MassKind kind, const ElementScalarMatrix<E>& own) const {
    const int S = span();
    SpanMatrix M = SpanMatrix::Zero(3 * S, 3 * S);
    const int n = static_cast<int>(enriched.size());
    if (kind == MassKind::Lumped) {
      const Scalar V = volume[0] + volume[1];
      for (int k = 0; k < n; ++k) {
        const EnrichedDof& d = enriched[k];
        Scalar share = 0;
        for (int s = 0; s < num_sides; ++s) share += (num_sides == 1 ? 1 : volume[s] / V) * d.psi[s] * d.psi[s];
        M.template block<3, 3>(3 * (N + k), 3 * (N + k)) = share * own(d.node, d.node) * Mat3::Identity();
      }
      return M;
    }
    for (int s = 0; s < num_sides; ++s) {
      const ElementScalarMatrix<E> m = side_mass(s, density);
      if (num_sides == 2)  // (a blending element's one side is the element's own rule)
        for (int a = 0; a < N; ++a)
          for (int b = 0; b < N; ++b) M.template block<3, 3>(3 * a, 3 * b).diagonal().array() += m(a, b) - (s == 0 ? own(a, b) : 0);
      for (int k = 0; k < n; ++k) {
        const EnrichedDof& dk = enriched[k];
        for (int b = 0; b < N; ++b) {  // a-u blocks and their transposes
          const Scalar v = dk.psi[s] * m(dk.node, b);
          M.template block<3, 3>(3 * (N + k), 3 * b) += v * Mat3::Identity();
          M.template block<3, 3>(3 * b, 3 * (N + k)) += v * Mat3::Identity();
        }
        for (int l = 0; l < n; ++l) {
          const EnrichedDof& dl = enriched[l];
          M.template block<3, 3>(3 * (N + k), 3 * (N + l)) += dk.psi[s] * dl.psi[s] * m(dk.node, dl.node) * Mat3::Identity();
        }
      }
    }
    return M;
  }

  /// Side s's consistent mass m^s = rho sum_q N N^T dv_q over its mass rule.
  ElementScalarMatrix<E> side_mass(int s, Scalar density) const {
    ElementScalarMatrix<E> m = ElementScalarMatrix<E>::Zero();
    for (size_t q = 0; q < mass_xi[s].size(); ++q) {
      const auto Nq = E::shape(mass_xi[s][q]);
      m += (density * mass_dv[s][q]) * Nq * Nq.transpose();
    }
    return m;
  }

  /// The body force per unit mass g's share beyond the standard load's (span vector) with the
  /// consistent mass (the lumped mass has none: its loads are M_L times the field g, represented
  /// by u = g, a = 0, so that the body falls at exactly g). Per side, v^s_a = rho int_s N_a dv
  /// over its mass rule: rho sum_s psi^s v^s_node g on the enriched dofs, and on a cut element's
  /// standard ones (sum_s v^s - v) g, v the element's own (element_nodal_mass at rest nodes X,
  /// as body_force_load has it): the standard load from the sides' rules, as the mass is, so
  /// that M r g is the load of a rigid translation r and a body falls at g.
  SpanVector body_force(const ElementNodes<E>& X, Scalar density, const Vec3& g) const {
    SpanVector F = SpanVector::Zero(3 * span());
    Eigen::Matrix<Scalar, N, 1> standard = Eigen::Matrix<Scalar, N, 1>::Zero();
    if (num_sides == 2) standard = -element_nodal_mass<E>(X, density);  // (a blending element's one side is its own rule)
    for (int s = 0; s < num_sides; ++s) {
      Eigen::Matrix<Scalar, N, 1> v = Eigen::Matrix<Scalar, N, 1>::Zero();
      for (size_t q = 0; q < mass_xi[s].size(); ++q) v += (density * mass_dv[s][q]) * E::shape(mass_xi[s][q]);
      if (num_sides == 2) standard += v;
      for (size_t k = 0; k < enriched.size(); ++k)
        F.template segment<3>(3 * (N + static_cast<int>(k))) += enriched[k].psi[s] * v[enriched[k].node] * g;
    }
    for (int a = 0; a < N; ++a) F.template segment<3>(3 * a) = standard[a] * g;
    return F;
  }

  /// The enriched dofs' share of a traction t (per unit reference area) on local face `face` of
  /// rest shape X: int_face N_a psi_k t dA per enriched dof k (at node a), over each side's part
  /// of the face with that side's psi (for_each_face_point_by_side).
  std::vector<Vec3> enriched_traction(const ElementNodes<E>& X, int face, const Vec3& t) const {
    std::vector<Vec3> F(enriched.size(), Vec3::Zero());
    for_each_face_point_by_side(face, [&](int s, const Vec3& xi, const Vec3& ds, const Vec3& dt, Scalar w) {
      const Scalar dA = face_area_element<E>(X, xi, ds, dt);
      const auto Nxi = E::shape(xi);
      for (size_t k = 0; k < enriched.size(); ++k) F[k] += (w * dA * Nxi[enriched[k].node] * enriched[k].psi[s]) * t;
    });
    return F;
  }

  /// Calls f(s, xi, dxi/ds, dxi/dt, weight) at quadrature points of local face `face` (reference
  /// coordinates), each on its side s. A blending element's face is one side, with the face's
  /// own rule; a cut element's face is split where the cut crosses it, into the triangles of
  /// its sides' pieces that lie on it (the pieces partition the element, so these partition
  /// the face), each with the degree-4 triangle rule.
  template <class F>
  void for_each_face_point_by_side(int face, F&& f) const {
    if (num_sides == 1)
      return for_each_face_point<E>(face, [&](const Vec3& xi, const Vec3& ds, const Vec3& dt, Scalar w) { f(0, xi, ds, dt, w); });
    // The reference face's plane n . xi = c (reference faces are flat); a piece's vertex on it
    // is a corner or lies on an edge of the face, off it by round-off only.
    const auto Xref = E::reference_nodes();
    const auto& fn = E::faces[static_cast<size_t>(face)];
    const Vec3 n = (Xref.col(fn[1]) - Xref.col(fn[0])).cross(Xref.col(fn[2]) - Xref.col(fn[0])).normalized();
    const Scalar c = n.dot(Xref.col(fn[0]));
    const auto on_face = [&](const Vec3& xi) { return std::abs(n.dot(xi) - c) <= 1e-12; };
    for (int s = 0; s < num_sides; ++s)
      for (const ReferenceTet& p : pieces[s])
        for (int skip = 0; skip < 4; ++skip) {  // the piece's face opposite vertex `skip`
          std::array<Vec3, 3> v;
          for (int k = 0, j = 0; k < 4; ++k)
            if (k != skip) v[static_cast<size_t>(j++)] = p[static_cast<size_t>(k)];
          if (!on_face(v[0]) || !on_face(v[1]) || !on_face(v[2])) continue;
          for_each_triangle_point(v[0], Vec3(v[1] - v[0]), Vec3(v[2] - v[0]),
                                  [&](const Vec3& xi, const Vec3& ds, const Vec3& dt, Scalar w) { f(s, xi, ds, dt, w); });
        }
  }

 private:
  /// Adds side s's standard-element force and tangent to the span's (see the file comment).
  void scatter(const ElementVector<E>& fs, const ElementMatrix<E>* Ks, int s, SpanVector& f, SpanMatrix* K) const {
    const int n = static_cast<int>(enriched.size());
    f.template head<3 * N>() += fs;
    for (int k = 0; k < n; ++k) f.template segment<3>(3 * (N + k)) += enriched[k].psi[s] * fs.template segment<3>(3 * enriched[k].node);
    if (!K) return;
    K->template topLeftCorner<3 * N, 3 * N>() += *Ks;
    for (int k = 0; k < n; ++k) {
      const EnrichedDof& dk = enriched[k];
      K->block(3 * (N + k), 0, 3, 3 * N) += dk.psi[s] * Ks->template middleRows<3>(3 * dk.node);
      K->block(0, 3 * (N + k), 3 * N, 3) += dk.psi[s] * Ks->template middleCols<3>(3 * dk.node);
      for (int l = 0; l < n; ++l) {
        const EnrichedDof& dl = enriched[l];
        K->template block<3, 3>(3 * (N + k), 3 * (N + l)) +=
            dk.psi[s] * dl.psi[s] * Ks->template block<3, 3>(3 * dk.node, 3 * dl.node);
      }
    }
  }
};

}  // namespace plastifem
