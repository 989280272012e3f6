#pragma once
// Enrichment<E>: the cuts applied to a body and everything derived from them (seed 001,
// section 4.3.3): nodal level sets, the cut-element set (eq. 73), the enriched nodes and their
// dofs appended after the standard ones (eq. 74-75), and each enriched element's pieces and
// enrichment functions (enrichment/cut_element.hpp).
//
// Applying a cut (apply):
//  1. the level set (enrichment/level_set.hpp) at the nodes of the elements the cut surface
//     meets; a node closer to the cut than `snap` times its elements' shortest edge is moved
//     onto it (its level set set to 0): no sliver pieces, no near-singular enriched dofs;
//  2. cut elements: those the surface's interior meets whose nodes' Heaviside signs differ
//     (H = +1 for a level set >= 0, the thesis' "above the crack and on the crack line", -1
//     below; eq. 73 with that convention): an element a surface ends inside is cut whole, and
//     an element that touches a cut running along its face from below is a cut element with
//     nothing above, so that a cut along element faces (or through nodes snapped onto it)
//     separates the elements on either side exactly as duplicated nodes would;
//  3. enriched nodes: the cut elements' nodes, except a node whose support (the elements around
//     it) has less than `min_fragment` of its volume on one side of the cut: its enrichment
//     would span a sliver (this also leaves out the nodes below a cut that runs along faces);
//     and except a node at the cut's tip, whose support the surface does not cut through (the
//     front of a slit: the material stays connected there, as at a crack tip);
//  4. a new dof slot for each enriched node (dof_map.hpp: block rows after the standard ones),
//     and the elements that couple them: the cut elements, split into pieces on either side,
//     and the blending elements, uncut elements around an enriched node where its enrichment
//     function is not zero (every such element for Heaviside enrichment; for the shifted one only
//     where an enriched node lies on the cut and the element on its negative side).
// Everything is computed first and committed only if the cut is valid: a cut that meets no
// element, or an element that a second cut would cross (refused, named: one cut per element),
// leaves the body unchanged.
//
// A growing cut (a blade moved over several steps) is the same cut applied again with its grown
// surface (apply with the cut's id): elements it newly crosses are cut and their new nodes
// enriched; what was cut stays cut as it was.
#include <plastifem/assembly/dof_map.hpp>
#include <plastifem/enrichment/cut_types.hpp>
#include <plastifem/enrichment/cut_element.hpp>
#include <plastifem/enrichment/level_set.hpp>
#include <plastifem/mesh/mesh.hpp>

#include <algorithm>
#include <chrono>
#include <atomic>
#include <cstdint>
#include <limits>
#include <map>
#include <vector>

namespace plastifem {

template <FiniteElement E>
class Enrichment {
 public:
  static constexpr int N = E::num_nodes;
  using Element = CutElement<E>;

  Enrichment() = default;
  explicit Enrichment(Index num_elements) : index_(num_elements, -1) {}

  bool empty() const { return elements_.empty(); }
  /// The enriched element data of element e, or null for a standard element.
  const Element* element(Index e) const {
    if (elements_.empty()) return nullptr;
    const int k = index_[e];
    return k < 0 ? nullptr : &elements_[k];
  }
  const std::vector<Element>& elements() const { return elements_; }
  Index element_of(size_t k) const { return element_index_[k]; }
  int num_cuts() const { return static_cast<int>(cuts_.size()); }
  /// Changes with every cut applied or grown: what is derived from the cut elements (an
  /// embedded point's side) is current while it and instance() are unchanged. Drawn from one
  /// counter for the whole program, so two enrichments never share a revision but 0 (uncut).
  std::uint64_t revision() const { return revision_; }
  /// This enrichment's own number (a solver's; unique in the program, unlike its address,
  /// which a later solver may reuse).
  std::uint64_t instance() const { return instance_; }
  /// The level set of cut c at node i, snapped (NaN where it was not evaluated: away from the
  /// elements the cut meets).
  Scalar level_set(int c, Index i) const {
    const auto& phi = cuts_[checked_index(c, num_cuts(), "level_set: cut")].phi;
    return phi[checked_index(i, static_cast<Index>(phi.size()), "level_set: node")];
  }
  /// Cut c's surface (the grown one, for a grown cut).
  const Cut& geometry(int c) const { return cuts_[checked_index(c, num_cuts(), "geometry: cut")].geometry; }

  /// Applies `surface` as a new cut (id < 0) or as the grown surface of cut `id` (see the file
  /// comment). Throws InvalidArgument, with nothing changed, if the cut is refused. The cut is
  /// placed in the mesh's coordinates; the new enriched elements' stiffness points are mapped
  /// with the rest positions `rest` (3 per node: the material mesh after plastic flow), or with
  /// the mesh's if null. `psi_of` is the enrichment policy's function psi(side, node).
  CutReport apply(const Mesh<E>& mesh, DofMap& dofs, const Cut& surface, const CutOptions& opt,
                  EnrichmentFunction psi_of, int id, int& applied_id, const Vector* rest = nullptr) {
    const auto t0 = std::chrono::steady_clock::now();
    opt.validate();
    if (id >= num_cuts()) fail<InvalidArgument>("cut: no cut with id {}", id);
    const Index n = mesh.num_nodes(), ne = mesh.num_elements();
    if (index_.empty()) index_.assign(ne, -1);
    CutReport rep;
    const int c = id >= 0 ? id : num_cuts();

    // 1. Level set near the surface, element sizes, snapping.
    std::vector<Scalar> phi(n, std::numeric_limits<Scalar>::quiet_NaN());
    std::vector<Scalar> h_node(n, std::numeric_limits<Scalar>::max());
    std::vector<char> meets(ne, 0);
    std::vector<Scalar> moved(n, 0);   // how far a node was snapped (0: not, or by round-off only)
    const Box bounds = cut_bounds(surface);
    for (Index e = 0; e < ne; ++e) {
      const ElementNodes<E> X = mesh.element_nodes(e);
      Box b;
      for (int a = 0; a < N; ++a) b.add(X.col(a));
      Scalar h = std::numeric_limits<Scalar>::max();
      for (const auto& ed : E::edges) h = std::min(h, (X.col(ed[0]) - X.col(ed[1])).norm());
      // Inflated by the snap distance: a node snapped onto the cut makes its neighbours on the
      // other side cut elements (a plane 1e-9 beyond a node layer cuts the layer behind it).
      const Box near = b.inflated(std::max<Scalar>(1e-12, opt.snap) * h);
      if (!near.overlaps(bounds) || !cut_meets(surface, near)) continue;
      meets[e] = 1;
      for (int a = 0; a < N; ++a) h_node[mesh.element(e)[a]] = std::min(h_node[mesh.element(e)[a]], h);
    }
    auto level_set_at = [&](Index i) {
      if (std::isnan(phi[i])) {
        phi[i] = signed_distance(surface, mesh.node(i));
        if (h_node[i] < std::numeric_limits<Scalar>::max() && std::abs(phi[i]) < opt.snap * h_node[i] && phi[i] != 0) {
          if (std::abs(phi[i]) > 1e-12 * h_node[i]) moved[i] = std::abs(phi[i]);
          phi[i] = 0, ++rep.snapped_nodes;
        }
      }
      return phi[i];
    };
    // A growing cut's surface contains the old one (the blade moved on): every element the cut
    // crosses must still meet it. A disjoint surface would leave the old cut where it was and
    // open a second one under the same id (the piece between hung on neither).
    if (id >= 0)
      for (Index e = 0; e < ne; ++e)
        if (const Element* old = element(e); old && old->cut == c && old->num_sides == 2) {
          const ElementNodes<E> X = mesh.element_nodes(e);
          Box b;
          Scalar h = std::numeric_limits<Scalar>::max();
          for (int a = 0; a < N; ++a) b.add(X.col(a));
          for (const auto& ed : E::edges) h = std::min(h, (X.col(ed[0]) - X.col(ed[1])).norm());
          if (!cut_meets(surface, b.inflated(std::max<Scalar>(1e-12, opt.snap) * h)))
            fail<InvalidArgument>("grow_cut: the grown surface does not cross element {}, which cut {} crosses: a "
                                  "growing cut's surface must contain the old one",
                                  e, c);
        }
    // 2. Cut elements.
    std::vector<Index> cut;
    for (Index e = 0; e < ne; ++e) {
      if (!meets[e]) continue;
      bool above = false, below = false;
      for (int a = 0; a < N; ++a) (level_set_at(mesh.element(e)[a]) >= 0 ? above : below) = true;
      if (!(above && below)) continue;
      // The surface must meet the element's interior; a node snapped onto it counts as on it,
      // so the box grows by (twice) the distance its nodes were moved.
      Box b;
      Scalar reach = 0;
      for (int a = 0; a < N; ++a) b.add(mesh.node(mesh.element(e)[a])), reach = std::max(reach, moved[mesh.element(e)[a]]);
      if (!cut_meets_interior(surface, reach > 0 ? b.inflated(2 * reach) : b)) continue;
      const Element* old = element(e);
      if (old && old->cut == c) continue;  // a growing cut: already cut by it
      if (old && old->cut >= 0)
        fail<InvalidArgument>("cut: element {} is already cut by cut {}; an element can be cut once (cut {} "
                              "crosses it again)",
                              e, old->cut, c);
      cut.push_back(e);
    }

    // Pieces and side volumes of each newly cut element.
    std::map<Index, std::array<std::vector<ReferenceTet>, 2>> pieces;
    std::map<Index, std::array<Scalar, 2>> side_volume;
    // A side of a cut element with (relatively) no volume: the cut runs along the element's faces.
    auto side_empty = [&](Index e, int s) {
      const Scalar V = side_volume[e][0] + side_volume[e][1];
      return V > 0 && side_volume[e][s] <= 1e-12 * V;
    };
    for (Index e : cut) {
      std::array<Scalar, N> p;
      for (int a = 0; a < N; ++a) p[a] = phi[mesh.element(e)[a]];
      pieces[e] = split_element<E>(p, sub_tetrahedra_of<E>(mesh.element(e)));
      const ElementNodes<E> X = mesh.element_nodes(e);
      for (int s = 0; s < 2; ++s) {
        const auto q = piece_quadrature<1>(pieces[e][s]);
        Scalar v = 0;
        for (size_t k = 0; k < q.xi.size(); ++k) v += q.w[k] * jacobian<E>(X, q.xi[k]).determinant();
        side_volume[e][s] = v;
      }
    }
    // 3. Enriched nodes: the new cut elements' nodes with both sides of their support above
    //    min_fragment (sides of uncut elements by their nodes' signs).
    std::vector<Index> candidates;
    for (Index e : cut)
      for (int a = 0; a < N; ++a) candidates.push_back(mesh.element(e)[a]);
    std::sort(candidates.begin(), candidates.end());
    candidates.erase(std::unique(candidates.begin(), candidates.end()), candidates.end());
    CutRecord record = id >= 0 ? cuts_[c] : CutRecord{surface, std::vector<Scalar>(n, std::numeric_limits<Scalar>::quiet_NaN()),
                                                      std::vector<Index>(n, -1), std::vector<signed char>(n, 0)};
    record.geometry = surface;
    const auto& elements_of = node_elements(mesh);
    std::vector<Index> enrich;
    std::vector<Index> cut_sorted = cut;
    std::sort(cut_sorted.begin(), cut_sorted.end());
    for (Index i : candidates) {
      if (record.row[i] >= 0) continue;  // already enriched by this cut
      std::array<Scalar, 2> v{0, 0};
      for (Index e : elements_of[i]) {
        if (auto it = side_volume.find(e); it != side_volume.end()) {
          v[0] += it->second[0], v[1] += it->second[1];
        } else {
          v[element_side(mesh, e, level_set_at)] += element_volume<E>(mesh.element_nodes(e));
        }
      }
      if (std::min(v[0], v[1]) < opt.min_fragment * (v[0] + v[1])) {
        ++rep.dropped_nodes;
        continue;
      }
      // A node whose support the surface does not cut through (an element around it with nodes
      // on both sides that the surface's interior does not meet: beyond the front of a slit) is
      // at the cut's tip: left unenriched, as a crack tip's nodes are (the material stays
      // connected there).
      if (std::any_of(elements_of[i].begin(), elements_of[i].end(), [&](Index e) {
            if (std::binary_search(cut_sorted.begin(), cut_sorted.end(), e) || (element(e) && element(e)->cut == c))
              return false;
            bool above = false, below = false;
            for (int a = 0; a < N; ++a) (level_set_at(mesh.element(e)[a]) >= 0 ? above : below) = true;
            return above && below;
          }))
        continue;
      enrich.push_back(i);
    }
    if (enrich.empty() && id < 0)
      fail<InvalidArgument>("cut: the surface separates no part of the body (it misses the mesh, or only touches it "
                            "at its boundary); nothing was cut");
    // Cut elements left with no enriched node (every node's support on one side) stay standard.
    {
      std::vector<char> enriched_node(n, 0);
      for (Index i : enrich) enriched_node[i] = 1;
      for (Index i = 0; i < n; ++i)
        if (id >= 0 && cuts_[c].row[i] >= 0) enriched_node[i] = 1;
      std::erase_if(cut, [&](Index e) {
        for (int a = 0; a < N; ++a)
          if (enriched_node[mesh.element(e)[a]]) return false;
        return true;
      });
    }
    // A cut along element faces leaves the elements on one side of them cut, with an empty
    // side; a second cut along the same faces from their other side (the same plane, its normal
    // reversed) would enrich the same discontinuity twice: a mode with no mass and no stiffness.
    {
      auto surface_face = [&](Index e, const std::vector<Scalar>& level) {
        std::vector<Index> face;
        for (Index i : mesh.element(e))
          if (level[i] == 0) face.push_back(i);  // on the surface (exactly, or snapped onto it)
        std::sort(face.begin(), face.end());
        return face;
      };
      std::vector<std::pair<std::vector<Index>, int>> faces;  // the earlier cuts' faces, and the cut
      for (size_t k = 0; k < elements_.size(); ++k) {
        const Element& el = elements_[k];
        if (el.num_sides == 2 && el.cut != c && !(el.has_material(0) && el.has_material(1)))
          faces.emplace_back(surface_face(element_index_[k], cuts_[el.cut].phi), el.cut);
      }
      std::sort(faces.begin(), faces.end());
      for (Index e : cut) {
        if (!side_empty(e, 0) && !side_empty(e, 1)) continue;
        const std::vector<Index> face = surface_face(e, phi);
        const auto it = std::lower_bound(faces.begin(), faces.end(), std::make_pair(face, -1));
        if (face.size() >= 3 && it != faces.end() && it->first == face)
          fail<InvalidArgument>("cut: the surface runs along the face of element {} that cut {} already runs along "
                                "(from its other side); a second cut there would enrich the same discontinuity "
                                "twice; nothing was cut",
                                e, it->second);
      }
    }
    // 4. Commit. The one refusal found only while committing (an element that would carry more
    //    than max_enriched dofs: crossed by too many cuts) restores the snapshot, so that a
    //    refused cut leaves the body and its dof map as they were.
    const Snapshot before{cuts_, elements_, element_index_, index_, dofs};
    try {
      // The level set wherever it was evaluated (every node of the elements the cut meets,
      // snapped), which an embedded surface splits along (embedding/embedded_surface.hpp: a
      // surface that fell back on the unsnapped distance there stayed joined across a snapped
      // cut); the signs of the candidates, which their enriched dofs' psi take. A node this cut
      // enriched before keeps its sign: the elements around it took their psi with it, and a
      // grown surface that passes the node again (a spiral's next turn) may put it on the other
      // side; its dof must keep one H_i everywhere, or the shifted enrichment leaves Heaviside's
      // space (16% of the field off, review).
      for (Index i = 0; i < n; ++i)
        if (!std::isnan(phi[i])) record.phi[i] = phi[i];
      for (Index i : candidates)
        if (!std::isnan(phi[i]) && record.row[i] < 0) record.H[i] = phi[i] >= 0 ? 1 : -1;
      const Index dofs_before = dofs.num_dofs();
      for (Index i : enrich) record.row[i] = dofs.add_slot(i);
      rep.enriched_nodes = static_cast<int>(enrich.size());
      if (id >= 0) cuts_[c] = std::move(record);
      else cuts_.push_back(std::move(record));
      const CutRecord& R = cuts_[c];
      // The cut elements' sides and pieces.
      for (Index e : cut) {
        Element& el = element_for(e);
        el.cut = c;
        el.num_sides = 2;
        const ElementNodes<E> X = mesh.element_nodes(e);
        // A cut along the element's faces leaves one side empty: the other is the whole
        // element, integrated with the element's own rules (so that such a cut gives what
        // duplicated nodes give; docs/xfem.md says for which models exactly).
        const bool whole[2] = {side_empty(e, 1), side_empty(e, 0)};
        for (int s = 0; s < 2; ++s) {
          const bool empty = whole[1 - s];
          el.pieces[s] = empty ? std::vector<ReferenceTet>{} : pieces[e][s];
          el.stiffness_rule[s] = whole[s] ? gauss_rule<E::stiffness_degree>()
                                 : empty  ? ReferencePoints{}
                                          : stiffness_points(pieces[e][s], opt.compress_quadrature);
          rep.stiffness_points += static_cast<int>(el.stiffness_rule[s].xi.size());
          set_mass_rule(el, s, X, whole[s] ? gauss_rule<E::mass_degree>() : empty ? ReferencePoints{} : mass_points(pieces[e][s]));
          el.volume[s] = side_volume[e][s];
        }
        el.set_rest_shape(rest ? mesh.element_nodes(e, *rest) : X);
        // An element this cut now splits may already carry another cut's (blending) dofs: their
        // psi is constant over the element, the same on both sides. (This cut's own older dofs,
        // from a shorter surface, are given their values per side below.)
        for (EnrichedDof& d : el.enriched) d.psi[1] = d.psi[0];
      }
      rep.cut_elements = static_cast<int>(cut.size());
      // Enriched dofs of this cut on every element around its new enriched nodes and on every
      // newly cut element (whose older dofs of this cut, from when it was a blending element of a
      // shorter cut, now take their value per side).
      std::vector<char> touched(ne, 0);
      for (Index i : enrich)
        for (Index e : elements_of[i]) touched[e] = 1;
      for (Index e : cut) touched[e] = 1;
      for (Index e = 0; e < ne; ++e) {
        if (!touched[e]) continue;
        const Element* existing = element(e);
        const bool split = existing && existing->cut == c;
        const int side = split ? 0 : element_side(mesh, e, level_set_at);
        const auto& conn = mesh.element(e);
        std::vector<EnrichedDof> add;
        std::vector<std::pair<size_t, std::array<Scalar, 2>>> update;
        for (int a = 0; a < N; ++a) {
          const Index i = conn[a];
          if (R.row[i] < 0) continue;
          EnrichedDof d{a, R.row[i], {0, 0}};
          for (int s = 0; s < 2; ++s) {
            const Scalar Hs = (split ? s : side) == 0 ? 1.0 : -1.0;
            d.psi[s] = psi_of(Hs, R.H[i]);
          }
          const auto it = existing ? std::find_if(existing->enriched.begin(), existing->enriched.end(),
                                                  [&](const EnrichedDof& x) { return x.row == d.row; })
                                   : std::vector<EnrichedDof>::const_iterator{};
          if (existing && it != existing->enriched.end()) {
            if (split) update.emplace_back(static_cast<size_t>(it - existing->enriched.begin()), d.psi);
            continue;
          }
          if (d.psi[0] == 0 && d.psi[1] == 0) continue;
          add.push_back(d);
        }
        if (add.empty() && update.empty()) continue;
        Element& el = element_for(e);
        for (const auto& [k, psi] : update) el.enriched[k].psi = psi;
        if (add.empty()) continue;
        if (!split && el.enriched.empty()) {  // a new blending element: its own Gauss rule
          const ElementNodes<E> X = mesh.element_nodes(e);
          el.num_sides = 1;
          el.stiffness_rule[0] = gauss_rule<E::stiffness_degree>();
          el.set_rest_shape(rest ? mesh.element_nodes(e, *rest) : X);
          set_mass_rule(el, 0, X, gauss_rule<E::mass_degree>());
          el.volume = {element_volume<E>(X), 0};
          ++rep.blending_elements;
        }
        if (el.num_sides == 1)
          for (EnrichedDof& d : add) d.psi[1] = d.psi[0];
        if (static_cast<int>(el.enriched.size() + add.size()) > Element::max_enriched)
          fail<InvalidArgument>("cut: element {} would carry {} enriched dofs (at most {})", e,
                                el.enriched.size() + add.size(), Element::max_enriched);
        el.enriched.insert(el.enriched.end(), add.begin(), add.end());
      }
      // The elements' spans in the dof map, in their enriched dofs' order.
      for (size_t k = 0; k < elements_.size(); ++k) {
        std::vector<Index> rows;
        for (const EnrichedDof& d : elements_[k].enriched) rows.push_back(d.row);
        if (!rows.empty() && std::vector<Index>(dofs.extension(element_index_[k]).begin(),
                                                dofs.extension(element_index_[k]).end()) != rows)
          dofs.extend_element(element_index_[k], rows);
      }
      rep.dofs_added = dofs.num_dofs() - dofs_before;
    } catch (...) {
      cuts_ = before.cuts, elements_ = before.elements, element_index_ = before.element_index, index_ = before.index;
      dofs = before.dofs;
      throw;
    }
    applied_id = c;
    revision_ = next_number();
    rep.ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    return rep;
  }

  /// Node i's enriched block row for cut c (-1: none), and its Heaviside sign H_i (+1 on or
  /// above the cut, -1 below).
  Index row(int c, Index i) const { return cuts_[c].row[i]; }
  Scalar sign(int c, Index i) const { return cuts_[c].H[i] < 0 ? -1.0 : 1.0; }

  /// Element e has a new rest shape X (plastic flow): its stiffness points follow, if it is
  /// enriched (enrichment/cut_element.hpp).
  void set_rest_shape(Index e, const ElementNodes<E>& X) {
    if (!index_.empty() && index_[e] >= 0) elements_[index_[e]].set_rest_shape(X);
  }

  /// The enriched dofs of node i (rows), over every cut.
  std::vector<Index> rows_of(Index i) const {
    std::vector<Index> r;
    for (const CutRecord& c : cuts_)
      if (c.row[i] >= 0) r.push_back(c.row[i]);
    return r;
  }

  /// The enriched dofs of constrained nodes, in the directions they are constrained in
  /// (`constrained`: per standard dof). A constraint holds the tissue on both sides of a cut
  /// through its support (docs/xfem.md), with either enrichment; per component, so that a node
  /// held in z alone (a sheet on a tray) lets the cut open in x and y (holding every enriched
  /// component kept a crack through it shut).
  std::vector<Index> held_dofs(const std::vector<char>& constrained, Index num_nodes) const {
    std::vector<Index> held;
    for (Index i = 0; i < num_nodes; ++i)
      for (int d = 0; d < 3; ++d)
        if (3 * i + d < static_cast<Index>(constrained.size()) && constrained[3 * i + d])
          for (Index r : rows_of(i)) held.push_back(3 * r + d);
    return held;
  }

  /// Node i's physical displacement from the dofs u: u_i + sum_cuts psi(H_i, H_i) a_i (`psi`:
  /// the enrichment function, psi(H(x), H_i)).
  template <class Psi>
  Vec3 nodal_displacement(const Vector& u, Index i, Psi psi) const {
    Vec3 x = u.template segment<3>(3 * i);
    for (int c = 0; c < num_cuts(); ++c)
      if (const Index r = row(c, i); r >= 0) {
        const Scalar h = sign(c, i);
        x += psi(h, h) * u.template segment<3>(3 * r);
      }
    return x;
  }
  /// Adds the enriched dofs' share of a force f at node i to F: f psi(H_i, H_i) on each of its
  /// enriched rows, the adjoint of nodal_displacement (the force does work on the node's
  /// physical displacement, on its own side of each cut).
  template <class Psi>
  void add_nodal_force(Index i, const Vec3& f, Psi psi, Vector& F) const {
    for (int c = 0; c < num_cuts(); ++c)
      if (const Index r = row(c, i); r >= 0) {
        const Scalar h = sign(c, i);
        F.template segment<3>(3 * r) += psi(h, h) * f;
      }
  }
  /// Adds the enriched dofs' share of a force f at reference point xi of element e to F:
  /// N_a(xi) psi_k^s f on each enriched row k (at node a) of e, s the side whose piece contains
  /// xi: the adjoint of the field at a point (seed 001 eq. 42; embedding/embedded_points.hpp).
  void add_point_force(Index e, const Vec3& xi, const Vec3& f, Vector& F) const {
    const Element* el = element(e);
    if (!el) return;
    const int s = el->side_containing(xi);
    const auto Nxi = E::shape(xi);
    for (const EnrichedDof& d : el->enriched) F.template segment<3>(3 * d.row) += (Nxi[d.node] * d.psi[s]) * f;
  }

 private:
  struct CutRecord {
    Cut geometry;
    std::vector<Scalar> phi;         ///< per node (NaN: not needed)
    std::vector<Index> row;          ///< per node: its enriched block row, -1 if none
    std::vector<signed char> H;      ///< per node: the Heaviside sign (0: not computed)
  };
  /// What a cut changes, kept while it commits (apply).
  struct Snapshot {
    std::vector<CutRecord> cuts;
    std::vector<Element> elements;
    std::vector<Index> element_index;
    std::vector<int> index;
    DofMap dofs;
  };

  /// The pieces' mass rule: of the element's mass integrand degree on a piece (exact on affine
  /// elements; docs/xfem.md).
  static ReferencePoints mass_points(const std::vector<ReferenceTet>& p) {
    return piece_quadrature<E::piece_mass_degree>(p);
  }
  /// A side's stiffness rule: the pieces' rules, compressed (CutOptions::compress_quadrature) to
  /// at most as many points as the integrand of linear elasticity has polynomials, with the same
  /// integrals of them (subdivision.hpp, compress_rule; kept whole if compression fails).
  static ReferencePoints stiffness_points(const std::vector<ReferenceTet>& p, bool compress) {
    ReferencePoints r = piece_quadrature<E::piece_stiffness_degree>(p);
    static const std::vector<std::array<int, 3>> exponents = stiffness_exponents<E>();
    if (!compress || r.xi.size() <= exponents.size()) return r;
    ReferencePoints c = compress_rule(r, exponents);
    return c.xi.empty() ? r : c;
  }

  /// The element's own (Gauss) rule of that degree.
  template <int Degree>
  static ReferencePoints gauss_rule() {
    ReferencePoints r;
    const auto q = E::template quadrature<Degree>();
    for (int k = 0; k < q.size; ++k) r.xi.push_back(q.points[k]), r.w.push_back(q.weights[k]);
    return r;
  }
  /// Side s's mass rule: reference points r mapped with the mesh's element X (the mass stays
  /// the mesh's, under plasticity too).
  static void set_mass_rule(Element& el, int s, const ElementNodes<E>& X, const ReferencePoints& r) {
    el.mass_xi[s] = r.xi;
    el.mass_dv[s].resize(r.xi.size());
    for (size_t k = 0; k < r.xi.size(); ++k) el.mass_dv[s][k] = r.w[k] * jacobian<E>(X, r.xi[k]).determinant();
  }

  /// The side of an uncut element: 0 if all its nodes are on or above the cut, else 1.
  template <class LevelSet>
  static int element_side(const Mesh<E>& mesh, Index e, LevelSet& level_set_at) {
    for (int a = 0; a < N; ++a)
      if (level_set_at(mesh.element(e)[a]) < 0) return 1;
    return 0;
  }

  /// The elements around each node: built on the first cut, kept (the mesh does not change).
  const std::vector<std::vector<Index>>& node_elements(const Mesh<E>& mesh) {
    if (elements_of_.empty()) {
      elements_of_.resize(mesh.num_nodes());
      for (Index e = 0; e < mesh.num_elements(); ++e)
        for (int a = 0; a < N; ++a) elements_of_[mesh.element(e)[a]].push_back(e);
    }
    return elements_of_;
  }

  Element& element_for(Index e) {
    if (index_[e] < 0) {
      index_[e] = static_cast<int>(elements_.size());
      elements_.emplace_back();
      element_index_.push_back(e);
    }
    return elements_[index_[e]];
  }

  std::vector<int> index_;             ///< per element: into elements_, -1 for a standard one
  std::vector<Element> elements_;
  std::vector<Index> element_index_;   ///< elements_[k] is element element_index_[k]
  std::vector<CutRecord> cuts_;
  std::vector<std::vector<Index>> elements_of_;  ///< node -> elements around it (node_elements)
  static std::uint64_t next_number() {
    static std::atomic<std::uint64_t> counter{0};
    return ++counter;
  }
  std::uint64_t revision_ = 0;
  std::uint64_t instance_ = next_number();
};

}  // namespace plastifem
