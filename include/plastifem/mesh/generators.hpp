#pragma once
// Structured mesh generators: the bar scenes of SCENES.md (Hex8 grid, Tet4 by the 6-tet Kuhn
// split or the 5-tet split, Tet10 by mid-edge nodes) and the seed-000 thick shells: a quad
// surface offset along its normals into Hex8 layers, and the cylindrical tube built that way.
//
// Every generator names the node sets and boundary-face sets a scene needs:
//   box:         xmin xmax ymin ymax zmin zmax
//   thick shell: bottom (the given surface) top (its offset)
//   tube:        inner outer xmin xmax
//
// The generators are function templates (of an unused parameter) only so that a file compiles
// the ones it calls: each instantiates its element type's Mesh, whose validation is most of the
// 2 s this header cost every file that included it when they were plain inline functions.
#include <plastifem/embedding/triangle_surface.hpp>
#include <plastifem/mesh/selection.hpp>

#include <numbers>
#include <string_view>
#include <unordered_map>

namespace plastifem {

/// A box [origin, origin + size] divided into nx x ny x nz cells. Defaults: unit cells at 0.
struct BoxSpec {
  int nx = 1, ny = 1, nz = 1;
  Vec3 size = Vec3::Constant(-1);  ///< negative: (nx, ny, nz), i.e. unit cubes as in SCENES.md
  Vec3 origin = Vec3::Zero();
};

namespace detail {

inline Vec3 box_size(const BoxSpec& b) { return b.size.x() < 0 ? Vec3(b.nx, b.ny, b.nz) : b.size; }

/// Refuses, before anything is allocated, a mesh larger than a Mesh can index. Counts in double:
/// products of three ints overflow even 64 bits.
inline void check_mesh_size(double nodes, double elements, std::string_view what) {
  if (nodes > static_cast<double>(max_mesh_nodes) || elements > static_cast<double>(max_mesh_elements))
    fail<InvalidArgument>("{} would have {:.4g} nodes and {:.4g} elements; a mesh holds at most {} nodes and {} "
                          "elements (32-bit indices)", what, nodes, elements, max_mesh_nodes, max_mesh_elements);
}

inline void check_box(const BoxSpec& b, int elements_per_cell) {
  if (b.nx < 1 || b.ny < 1 || b.nz < 1)
    fail<InvalidArgument>("box needs at least one cell per direction, got {} x {} x {}", b.nx, b.ny, b.nz);
  check_mesh_size((b.nx + 1.0) * (b.ny + 1.0) * (b.nz + 1.0), elements_per_cell * (1.0 * b.nx * b.ny * b.nz),
                  fmt::format("a {} x {} x {} box", b.nx, b.ny, b.nz));
  const Vec3 s = box_size(b);
  if (!(s.array() > 0).all() || !s.allFinite() || !b.origin.allFinite())
    fail<InvalidArgument>("box size must be finite and positive, got ({}, {}, {})", s.x(), s.y(), s.z());
}

/// Grid nodes of a box, numbered i + (nx+1) (j + (ny+1) k).
inline Eigen::Matrix3Xd box_nodes(const BoxSpec& b) {
  const Vec3 s = box_size(b);
  Eigen::Matrix3Xd X(3, (b.nx + 1) * (b.ny + 1) * (b.nz + 1));
  Index n = 0;
  for (int k = 0; k <= b.nz; ++k)
    for (int j = 0; j <= b.ny; ++j)
      for (int i = 0; i <= b.nx; ++i)
        X.col(n++) = b.origin + Vec3(s.x() * i / b.nx, s.y() * j / b.ny, s.z() * k / b.nz);
  return X;
}

/// The 8 grid nodes of cell (i, j, k), indexed by local bits c = di + 2 dj + 4 dk.
inline std::array<Index, 8> cell_corners(const BoxSpec& b, int i, int j, int k) {
  std::array<Index, 8> c;
  for (int bits = 0; bits < 8; ++bits) {
    const int ii = i + (bits & 1), jj = j + ((bits >> 1) & 1), kk = k + ((bits >> 2) & 1);
    c[bits] = ii + (b.nx + 1) * (jj + (b.ny + 1) * kk);
  }
  return c;
}

/// Swaps two nodes of a tetrahedron with negative volume so that det J > 0.
inline void orient_tet(const Eigen::Matrix3Xd& X, std::array<Index, 4>& t) {
  const Mat3 J = (Mat3() << X.col(t[1]) - X.col(t[0]), X.col(t[2]) - X.col(t[0]), X.col(t[3]) - X.col(t[0]))
                     .finished();
  if (J.determinant() < 0) std::swap(t[1], t[2]);
}

/// Names the six sides of a box as node sets and boundary-face sets.
template <FiniteElement E>
void name_box_sides(Mesh<E>& mesh, const BoxSpec& b) {
  const Vec3 lo = b.origin, hi = b.origin + box_size(b);
  const Scalar tol = 1e-9 * (hi - lo).norm();
  const char* names[3][2] = {{"xmin", "xmax"}, {"ymin", "ymax"}, {"zmin", "zmax"}};
  for (int d = 0; d < 3; ++d)
    for (int side = 0; side < 2; ++side) {
      const Scalar v = side ? hi[d] : lo[d];
      auto on_side = [&](const Vec3& p) { return std::abs(p[d] - v) <= tol; };
      mesh.add_node_set(names[d][side], select_nodes(mesh, on_side));
      mesh.add_face_set(names[d][side], select_boundary_faces(mesh, on_side));
    }
}

}  // namespace detail

/// Hex8 grid, one element per cell.
template <class = void>
Mesh<Hex8> box_hex8(const BoxSpec& b) {
  detail::check_box(b, 1);
  std::vector<Mesh<Hex8>::Connectivity> cells;
  cells.reserve(static_cast<size_t>(b.nx) * b.ny * b.nz);
  for (int k = 0; k < b.nz; ++k)
    for (int j = 0; j < b.ny; ++j)
      for (int i = 0; i < b.nx; ++i) {
        const auto c = detail::cell_corners(b, i, j, k);
        // local bits -> Hex8 numbering: 0 (000) 1 (100) 2 (110) 3 (010), then the top layer.
        cells.push_back({c[0], c[1], c[3], c[2], c[4], c[5], c[7], c[6]});
      }
  Mesh<Hex8> mesh(detail::box_nodes(b), std::move(cells));
  detail::name_box_sides(mesh, b);
  return mesh;
}

/// Wedge6 grid: each cell split into 2 prisms along the diagonal of its z faces from (0,0) to
/// (1,1), the same in every cell, so neighbours' faces match. (The sub-tetrahedra the X-FEM
/// integrates on split a shared quadrilateral face through its lowest global node, alike from
/// both sides: Wedge6::conforming_sub_tetrahedra, docs/xfem.md.)
template <class = void>
Mesh<Wedge6> box_wedge6(const BoxSpec& b) {
  detail::check_box(b, 2);
  std::vector<Mesh<Wedge6>::Connectivity> prisms;
  prisms.reserve(static_cast<size_t>(b.nx) * b.ny * b.nz * 2);
  for (int k = 0; k < b.nz; ++k)
    for (int j = 0; j < b.ny; ++j)
      for (int i = 0; i < b.nx; ++i) {
        const auto c = detail::cell_corners(b, i, j, k);  // local bits di + 2 dj + 4 dk
        prisms.push_back({c[0], c[3], c[1], c[4], c[7], c[5]});  // triangles clockwise from +z (VTK)
        prisms.push_back({c[0], c[2], c[3], c[4], c[6], c[7]});
      }
  Mesh<Wedge6> mesh(detail::box_nodes(b), std::move(prisms));
  detail::name_box_sides(mesh, b);
  return mesh;
}

/// Tet4 grid: each cell split into 6 tetrahedra around its diagonal (0,0,0)-(1,1,1) (Kuhn /
/// Freudenthal). Every cell is split the same way, so neighbours' face diagonals match.
template <class = void>
Mesh<Tet4> box_tet4_kuhn(const BoxSpec& b) {
  detail::check_box(b, 6);
  const Eigen::Matrix3Xd X = detail::box_nodes(b);
  // Path 0 -> e_a -> e_a + e_b -> (1,1,1) for each permutation (a, b, c) of the axes.
  static constexpr int paths[6][2] = {{1, 3}, {1, 5}, {2, 3}, {2, 6}, {4, 5}, {4, 6}};
  std::vector<Mesh<Tet4>::Connectivity> tets;
  tets.reserve(static_cast<size_t>(b.nx) * b.ny * b.nz * 6);
  for (int k = 0; k < b.nz; ++k)
    for (int j = 0; j < b.ny; ++j)
      for (int i = 0; i < b.nx; ++i) {
        const auto c = detail::cell_corners(b, i, j, k);
        for (const auto& p : paths) {
          std::array<Index, 4> t{c[0], c[p[0]], c[p[1]], c[7]};
          detail::orient_tet(X, t);
          tets.push_back(t);
        }
      }
  Mesh<Tet4> mesh(X, std::move(tets));
  detail::name_box_sides(mesh, b);
  return mesh;
}

/// Tet4 grid: each cell split into 5 tetrahedra (one central, four corners), mirrored on
/// alternate cells (parity of i + j + k) so that face diagonals match across neighbours.
template <class = void>
Mesh<Tet4> box_tet4_five(const BoxSpec& b) {
  detail::check_box(b, 5);
  const Eigen::Matrix3Xd X = detail::box_nodes(b);
  static constexpr int even[5][4] = {{1, 2, 4, 7}, {0, 1, 2, 4}, {3, 1, 2, 7}, {5, 1, 4, 7}, {6, 2, 4, 7}};
  static constexpr int odd[5][4] = {{0, 3, 5, 6}, {1, 0, 3, 5}, {2, 0, 3, 6}, {4, 0, 5, 6}, {7, 3, 5, 6}};
  std::vector<Mesh<Tet4>::Connectivity> tets;
  tets.reserve(static_cast<size_t>(b.nx) * b.ny * b.nz * 5);
  for (int k = 0; k < b.nz; ++k)
    for (int j = 0; j < b.ny; ++j)
      for (int i = 0; i < b.nx; ++i) {
        const auto c = detail::cell_corners(b, i, j, k);
        const auto& split = ((i + j + k) % 2 == 0) ? even : odd;
        for (const auto& s : split) {
          std::array<Index, 4> t{c[s[0]], c[s[1]], c[s[2]], c[s[3]]};
          detail::orient_tet(X, t);
          tets.push_back(t);
        }
      }
  Mesh<Tet4> mesh(X, std::move(tets));
  detail::name_box_sides(mesh, b);
  return mesh;
}

/// Tet10 from Tet4: one new node at the middle of every edge, shared by all tets around it.
/// Node sets keep their nodes plus the mid-edge nodes whose two ends are both in the set;
/// face sets carry over unchanged (same element and local face numbers).
template <class = void>
Mesh<Tet10> promote_to_tet10(const Mesh<Tet4>& tet4) {
  std::unordered_map<std::uint64_t, Index> mid;
  mid.reserve(static_cast<size_t>(tet4.num_elements()) * 2);
  std::vector<Vec3> extra;
  std::vector<std::array<Index, 2>> ends;
  std::vector<Mesh<Tet10>::Connectivity> tets;
  tets.reserve(tet4.elements().size());
  const Index n0 = tet4.num_nodes();
  for (const auto& t : tet4.elements()) {
    Mesh<Tet10>::Connectivity c;
    std::copy(t.begin(), t.end(), c.begin());
    for (int k = 0; k < 6; ++k) {
      Index a = t[Tet10::edges[k][0]], b = t[Tet10::edges[k][1]];
      if (a > b) std::swap(a, b);
      const std::uint64_t key = (static_cast<std::uint64_t>(a) << 32) | static_cast<std::uint32_t>(b);
      auto [it, inserted] = mid.try_emplace(key, n0 + static_cast<Index>(extra.size()));
      if (inserted) {
        if (n0 + static_cast<std::int64_t>(extra.size()) >= max_mesh_nodes)  // before the next id overflows
          fail<InvalidArgument>("promote_to_tet10: the Tet10 mesh of {} tetrahedra would have more than {} nodes "
                                "(32-bit indices)", tet4.num_elements(), max_mesh_nodes);
        extra.push_back(0.5 * (tet4.node(a) + tet4.node(b)));
        ends.push_back({a, b});
      }
      c[4 + k] = it->second;
    }
    tets.push_back(c);
  }
  Eigen::Matrix3Xd X(3, n0 + static_cast<Index>(extra.size()));
  X.leftCols(n0) = tet4.nodes();
  for (size_t k = 0; k < extra.size(); ++k) X.col(n0 + static_cast<Index>(k)) = extra[k];
  Mesh<Tet10> mesh(std::move(X), std::move(tets));
  for (const auto& [name, ids] : tet4.node_sets()) {
    std::vector<char> in(n0, 0);
    for (Index i : ids) in[i] = 1;
    std::vector<Index> out = ids;
    for (size_t k = 0; k < ends.size(); ++k)
      if (in[ends[k][0]] && in[ends[k][1]]) out.push_back(n0 + static_cast<Index>(k));
    mesh.add_node_set(name, std::move(out));
  }
  for (const auto& [name, faces] : tet4.face_sets()) mesh.add_face_set(name, faces);
  return mesh;
}

/// A box meshed as the bar scenes mesh it: Hex8 grid, Kuhn-split Tet4, its Tet10, or prisms.
/// (A new element type adds its box here.)
template <FiniteElement E>
Mesh<E> bar_mesh(const BoxSpec& b) {
  if constexpr (std::is_same_v<E, Hex8>) return box_hex8(b);
  else if constexpr (std::is_same_v<E, Tet4>) return box_tet4_kuhn(b);
  else if constexpr (std::is_same_v<E, Wedge6>) return box_wedge6(b);
  else {
    static_assert(std::is_same_v<E, Tet10>, "bar_mesh: no box generator for this element type");
    // Refused before the Tet4 mesh is built: one mid-edge node per grid edge (along the axes),
    // per face diagonal and per cell's body diagonal of the Kuhn split.
    const double x = b.nx, y = b.ny, z = b.nz;
    const double grid = (x + 1) * (y + 1) * (z + 1);
    const double axis_edges = x * (y + 1) * (z + 1) + (x + 1) * y * (z + 1) + (x + 1) * (y + 1) * z;
    const double face_diagonals = x * y * (z + 1) + x * (y + 1) * z + (x + 1) * y * z;
    detail::check_mesh_size(grid + axis_edges + face_diagonals + x * y * z, 6 * x * y * z,
                            fmt::format("a {} x {} x {} box of Tet10", b.nx, b.ny, b.nz));
    return promote_to_tet10(box_tet4_kuhn(b));
  }
}

/// The bar scenes of SCENES.md: nx x ny x nz unit cubes.
template <FiniteElement E>
Mesh<E> bar_mesh(int nx, int ny, int nz) {
  return bar_mesh<E>(BoxSpec{nx, ny, nz});
}

/// Cells of a named bar scene of SCENES.md: bar90, bar720, bar5760 or bar46080.
inline std::array<int, 3> bar_scene_cells(std::string_view name) {
  if (name == "bar90") return {10, 3, 3};
  if (name == "bar720") return {20, 6, 6};
  if (name == "bar5760") return {40, 12, 12};
  if (name == "bar46080") return {80, 24, 24};
  fail<InvalidArgument>("unknown bar scene '{}': bar90, bar720, bar5760 or bar46080", name);
}

/// A quad surface mesh: nodes and quads (4 node ids, counter-clockwise seen from the side the
/// normal points to).
struct QuadSurface {
  Eigen::Matrix3Xd nodes;
  std::vector<std::array<Index, 4>> quads;
};

namespace detail {

inline void check_shell(Scalar thickness, int layers) {
  if (layers < 1) fail<InvalidArgument>("thick shell needs at least one layer, got {}", layers);
  if (!(std::abs(thickness) > 0) || !std::isfinite(thickness))
    fail<InvalidArgument>("thick shell thickness must be finite and non-zero, got {}", thickness);
}

/// A thick shell's cells: `layers + 1` copies of the surface's nodes offset along their unit
/// normals by `thickness * l / layers`, and over each surface face f one cell per layer,
/// `cell(f, a, b)`, whose face 0 lies on the node layer starting at id a and face 1 on the one at
/// b. The surface is face 0 of the first layer when the offset follows the normals, face 1
/// otherwise (the cell's bottom is then the offset side). Node and face sets "bottom" (the
/// surface) and "top" (its offset).
template <FiniteElement E, class Face, class Cell>
Mesh<E> stack_shell_layers(const Eigen::Matrix3Xd& surface, const Eigen::Matrix3Xd& normal,
                           const std::vector<Face>& faces, Scalar thickness, int layers, Cell cell) {
  const Index n = static_cast<Index>(surface.cols());
  check_mesh_size(static_cast<double>(n) * (layers + 1.0), static_cast<double>(faces.size()) * layers,
                  fmt::format("a thick shell of {} layers on {} faces", layers, faces.size()));
  Eigen::Matrix3Xd X(3, n * (layers + 1));
  for (int l = 0; l <= layers; ++l) X.middleCols(l * n, n) = surface + normal * (thickness * l / layers);
  std::vector<typename Mesh<E>::Connectivity> cells;
  cells.reserve(faces.size() * static_cast<size_t>(layers));
  for (int l = 0; l < layers; ++l)
    for (const Face& f : faces) {
      const Index lo = l * n, hi = (l + 1) * n;
      cells.push_back(thickness > 0 ? cell(f, lo, hi) : cell(f, hi, lo));
    }
  Mesh<E> mesh(std::move(X), std::move(cells));
  std::vector<Index> bottom(static_cast<size_t>(n)), top(static_cast<size_t>(n));
  for (Index v = 0; v < n; ++v) bottom[static_cast<size_t>(v)] = v, top[static_cast<size_t>(v)] = layers * n + v;
  const int bottom_face = thickness > 0 ? 0 : 1, top_face = 1 - bottom_face;
  std::vector<FaceRef> fb, ft;
  const Index nf = static_cast<Index>(faces.size());
  for (Index f = 0; f < nf; ++f) {
    fb.push_back({f, bottom_face});
    ft.push_back({(layers - 1) * nf + f, top_face});
  }
  mesh.add_node_set("bottom", std::move(bottom));
  mesh.add_node_set("top", std::move(top));
  mesh.add_face_set("bottom", std::move(fb));
  mesh.add_face_set("top", std::move(ft));
  return mesh;
}

}  // namespace detail

/// Thick shell: the surface offset along its (area-weighted, averaged) vertex normals by
/// `thickness` in `layers` Hex8 layers. Negative thickness offsets against the normals.
template <class = void>
Mesh<Hex8> thick_shell_hex8(const QuadSurface& s, Scalar thickness, int layers) {
  detail::check_shell(thickness, layers);
  const Index n = static_cast<Index>(s.nodes.cols());
  Eigen::Matrix3Xd normal = Eigen::Matrix3Xd::Zero(3, n);
  for (size_t q = 0; q < s.quads.size(); ++q) {
    const auto& f = s.quads[q];
    for (Index v : f)
      if (v < 0 || v >= n) fail<MeshError>("surface quad {}: node {} out of range [0, {})", q, v, n);
    // Twice the area vector of a (possibly non-planar) quad: cross product of its diagonals.
    const Vec3 a = (s.nodes.col(f[2]) - s.nodes.col(f[0])).cross(s.nodes.col(f[3]) - s.nodes.col(f[1]));
    for (Index v : f) normal.col(v) += a;
  }
  for (Index v = 0; v < n; ++v) {
    const Scalar len = normal.col(v).norm();
    if (!(len > 0)) fail<MeshError>("surface node {} belongs to no quad or has no defined normal", v);
    normal.col(v) /= len;
  }
  // Hex8's faces 0 and 1 are its bottom 0-1-2-3 and top 4-5-6-7.
  return detail::stack_shell_layers<Hex8>(s.nodes, normal, s.quads, thickness, layers,
                                          [](const std::array<Index, 4>& f, Index a, Index b) {
                                            return Mesh<Hex8>::Connectivity{f[0] + a, f[1] + a, f[2] + a, f[3] + a,
                                                                            f[0] + b, f[1] + b, f[2] + b, f[3] + b};
                                          });
}

/// Thick shell of prisms: the triangulated surface offset along its (area-weighted, averaged)
/// vertex normals by `thickness` in `layers` Wedge6 layers; negative thickness offsets against
/// the normals. Membranes and capsules come as triangle surfaces. Node and face sets "bottom"
/// (the surface itself) and "top" (its offset), as thick_shell_hex8.
template <class = void>
Mesh<Wedge6> thick_shell_wedge6(const TriangleSurface& s, Scalar thickness, int layers) {
  detail::check_shell(thickness, layers);
  check_surface(s, "thick shell surface");
  const Index n = s.num_vertices();
  Eigen::Matrix3Xd normal;
  vertex_normals(s, s.vertices, normal);
  for (Index v = 0; v < n; ++v)
    if (!(normal.col(v).norm() > 0)) fail<MeshError>("surface vertex {} belongs to no triangle or has no defined normal", v);
  // Wedge6's faces 0 and 1 are its triangles; each is the surface triangle reversed, because a
  // prism's bottom triangle faces away from its top (VTK's order).
  return detail::stack_shell_layers<Wedge6>(s.vertices, normal, s.triangles, thickness, layers,
                                            [](const Triangle& t, Index a, Index b) {
                                              return Mesh<Wedge6>::Connectivity{t[0] + a, t[2] + a, t[1] + a,
                                                                                t[0] + b, t[2] + b, t[1] + b};
                                            });
}

/// Cylindrical tube along x (a vessel): inner radius r_in, outer r_out, length L; n_circ cells
/// around, n_axial along, n_radial through the wall. Built as the thick shell of the inner
/// cylinder (whose vertex normals are exactly radial, so the outer radius is exact).
template <class = void>
Mesh<Hex8> tube_hex8(Scalar r_in, Scalar r_out, Scalar length, int n_circ, int n_axial, int n_radial) {
  if (!(r_in > 0) || !(r_out > r_in) || !(length > 0))
    fail<InvalidArgument>("tube needs 0 < r_in < r_out and length > 0, got r_in={}, r_out={}, length={}", r_in,
                          r_out, length);
  if (n_circ < 3 || n_axial < 1 || n_radial < 1)
    fail<InvalidArgument>("tube needs n_circ >= 3, n_axial >= 1, n_radial >= 1, got {}, {}, {}", n_circ, n_axial,
                          n_radial);
  detail::check_mesh_size(1.0 * n_circ * (n_axial + 1.0) * (n_radial + 1.0), 1.0 * n_circ * n_axial * n_radial,
                          fmt::format("a tube of {} x {} x {} cells", n_circ, n_axial, n_radial));
  QuadSurface s;
  s.nodes.resize(3, static_cast<Index>(n_circ) * (n_axial + 1));
  for (int a = 0; a <= n_axial; ++a)
    for (int c = 0; c < n_circ; ++c) {
      const Scalar t = 2 * std::numbers::pi * c / n_circ;
      s.nodes.col(a * n_circ + c) = Vec3(length * a / n_axial, r_in * std::cos(t), r_in * std::sin(t));
    }
  // Counter-clockwise seen from outside (normal pointing away from the axis).
  for (int a = 0; a < n_axial; ++a)
    for (int c = 0; c < n_circ; ++c) {
      const Index c1 = (c + 1) % n_circ;
      s.quads.push_back({a * n_circ + c, a * n_circ + c1, (a + 1) * n_circ + c1, (a + 1) * n_circ + c});
    }
  // Averaged normals of a regular polygon are radial; if this winding points inwards, flip.
  const Vec3 n0 = (s.nodes.col(s.quads[0][2]) - s.nodes.col(s.quads[0][0]))
                      .cross(s.nodes.col(s.quads[0][3]) - s.nodes.col(s.quads[0][1]));
  if (n0.dot(s.nodes.col(s.quads[0][0]) - Vec3(s.nodes(0, s.quads[0][0]), 0, 0)) < 0)
    for (auto& q : s.quads) std::swap(q[1], q[3]);
  Mesh<Hex8> mesh = thick_shell_hex8(s, r_out - r_in, n_radial);
  // The offset moves vertices radially by exactly (r_out - r_in): the outer radius is exact.
  const Scalar L = length, tol = 1e-9 * (length + r_out);
  mesh.add_node_set("inner", mesh.node_set("bottom"));
  mesh.add_node_set("outer", mesh.node_set("top"));
  mesh.add_face_set("inner", mesh.face_set("bottom"));
  mesh.add_face_set("outer", mesh.face_set("top"));
  auto at = [&](Scalar x) { return [=](const Vec3& p) { return std::abs(p.x() - x) <= tol; }; };
  mesh.add_node_set("xmin", select_nodes(mesh, at(0)));
  mesh.add_node_set("xmax", select_nodes(mesh, at(L)));
  mesh.add_face_set("xmin", select_boundary_faces(mesh, at(0)));
  mesh.add_face_set("xmax", select_boundary_faces(mesh, at(L)));
  return mesh;
}

#ifdef PLASTIFEM_USE_COMPILED  // plastifem::compiled holds these (solver/instantiations.hpp)
extern template Mesh<Hex8> box_hex8<void>(const BoxSpec&);
extern template Mesh<Tet4> box_tet4_kuhn<void>(const BoxSpec&);
extern template Mesh<Tet4> box_tet4_five<void>(const BoxSpec&);
extern template Mesh<Tet10> promote_to_tet10<void>(const Mesh<Tet4>&);
extern template Mesh<Hex8> thick_shell_hex8<void>(const QuadSurface&, Scalar, int);
extern template Mesh<Hex8> tube_hex8<void>(Scalar, Scalar, Scalar, int, int, int);
extern template Mesh<Tet4> bar_mesh<Tet4>(const BoxSpec&);
extern template Mesh<Tet10> bar_mesh<Tet10>(const BoxSpec&);
extern template Mesh<Hex8> bar_mesh<Hex8>(const BoxSpec&);
extern template Mesh<Tet4> bar_mesh<Tet4>(int, int, int);
extern template Mesh<Tet10> bar_mesh<Tet10>(int, int, int);
extern template Mesh<Hex8> bar_mesh<Hex8>(int, int, int);
extern template Mesh<Wedge6> box_wedge6<void>(const BoxSpec&);
extern template Mesh<Wedge6> thick_shell_wedge6<void>(const TriangleSurface&, Scalar, int);
extern template Mesh<Wedge6> bar_mesh<Wedge6>(const BoxSpec&);
extern template Mesh<Wedge6> bar_mesh<Wedge6>(int, int, int);
#endif

}  // namespace plastifem
