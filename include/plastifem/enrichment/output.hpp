#pragma once
// Output that shows a cut (seed 001, section 5.2, "Postprocessing", Fig. 7-8): a VTU file in
// which the standard elements are written as usual, on the mesh's nodes moved by their
// displacement, and every enriched element as what it is:
//  - a cut element as its pieces on either side (tetrahedra, VTK_TETRA), each with points of its
//    own, moved with its own side's displacement sum_a N_a (u_a + sum psi^s a): the cut opens up.
//    Each piece is written with positive volume at rest (vertices 2 and 3 swapped where the split
//    left it negative): ParaView draws a negative tetrahedron inside out, and VTK filters that
//    assume positive cells (volumes, normals, clipping) get it wrong;
//  - a blending element (enriched dofs, not cut) as itself, on points of its own moved by
//    u_a + sum psi a. Its side is the sign of the mean level set at its nodes (>= 0: 0, < 0: 1)
//    of the cut its enriched dofs belong to (of several, the one whose level set is known at
//    most of its nodes; the level set is evaluated only near a cut): a blending element lies
//    wholly on one side of that cut.
// One file, mixed cell types. Point data: `displacement`; cell data: `side` (0 above, 1 below the
// cut, -1 a standard element) and `element` (the mesh element each cell comes from).
#include <plastifem/enrichment/enrichment.hpp>
#include <plastifem/mesh/io/vtu.hpp>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>

namespace plastifem::io {

/// Writes the body with its cuts opened (see the file comment), ASCII VTU.
template <FiniteElement E>
void write_cut_vtu(const std::filesystem::path& path, const Mesh<E>& mesh, const Enrichment<E>& enrichment,
                   const Vector& u) {
  constexpr int N = E::num_nodes;
  std::vector<Vec3> points, displacement;
  std::vector<std::int64_t> connectivity, offsets;
  std::vector<int> types, side, element;
  for (Index i = 0; i < mesh.num_nodes(); ++i) {
    points.push_back(mesh.node(i));
    displacement.push_back(u.template segment<3>(3 * i));
  }
  auto close_cell = [&](int type, int s, Index e) {  // after the cell's connectivity
    offsets.push_back(static_cast<std::int64_t>(connectivity.size()));
    types.push_back(type), side.push_back(s), element.push_back(static_cast<int>(e));
  };
  // A blending element's side (file comment).
  auto blending_side = [&](const auto& c, const CutElement<E>& el) {
    int best = -1, best_known = -1;
    for (int k = 0; k < enrichment.num_cuts(); ++k) {
      const bool carries = std::any_of(el.enriched.begin(), el.enriched.end(),
                                       [&](const EnrichedDof& d) { return enrichment.row(k, c[d.node]) == d.row; });
      int known = 0;
      for (int a = 0; a < N; ++a) known += std::isfinite(enrichment.level_set(k, c[a]));
      if (carries && known > best_known) best = k, best_known = known;
    }
    if (best < 0) return 0;
    Scalar sum = 0;
    for (int a = 0; a < N; ++a)
      if (const Scalar phi = enrichment.level_set(best, c[a]); std::isfinite(phi)) sum += phi;
    return sum >= 0 ? 0 : 1;
  };
  for (Index e = 0; e < mesh.num_elements(); ++e) {
    const auto& c = mesh.element(e);
    const CutElement<E>* cut = enrichment.element(e);
    if (!cut) {
      for (int a = 0; a < N; ++a) connectivity.push_back(c[a]);
      close_cell(E::vtk_cell_type, -1, e);
      continue;
    }
    const ElementNodes<E> X = mesh.element_nodes(e);
    ElementNodes<E> U;
    for (int a = 0; a < N; ++a) U.col(a) = u.template segment<3>(3 * c[a]);
    for (int s = 0; s < cut->num_sides; ++s) {
      ElementNodes<E> Us = U;  // effective nodal displacements of side s
      for (const EnrichedDof& d : cut->enriched) Us.col(d.node) += d.psi[s] * u.template segment<3>(3 * d.row);
      if (cut->num_sides == 1) {  // a blending element: itself, on points of its own
        for (int a = 0; a < N; ++a) {
          connectivity.push_back(static_cast<std::int64_t>(points.size()));
          points.push_back(X.col(a));
          displacement.push_back(Us.col(a));
        }
        close_cell(E::vtk_cell_type, blending_side(c, *cut), e);
        continue;
      }
      for (const ReferenceTet& t : cut->pieces[s]) {
        std::array<Vec3, 4> x, d;
        for (int k = 0; k < 4; ++k) {
          const auto Nxi = E::shape(t[static_cast<size_t>(k)]);
          x[static_cast<size_t>(k)] = X * Nxi, d[static_cast<size_t>(k)] = Us * Nxi;
        }
        // Written with positive volume: a piece inverted by the element's map swaps two nodes.
        std::array<int, 4> order{0, 1, 2, 3};
        if ((x[1] - x[0]).cross(x[2] - x[0]).dot(x[3] - x[0]) < 0) std::swap(order[2], order[3]);
        for (int k : order) {
          connectivity.push_back(static_cast<std::int64_t>(points.size()));
          points.push_back(x[static_cast<size_t>(k)]);
          displacement.push_back(d[static_cast<size_t>(k)]);
        }
        close_cell(10, s, e);  // VTK_TETRA
      }
    }
  }
  fmt::memory_buffer b;
  auto out = std::back_inserter(b);
  fmt::format_to(out, "<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" "
                      "byte_order=\"LittleEndian\" header_type=\"UInt64\">\n<UnstructuredGrid>\n"
                      "<Piece NumberOfPoints=\"{}\" NumberOfCells=\"{}\">\n",
                 points.size(), types.size());
  fmt::format_to(out, "<Points><DataArray type=\"Float64\" NumberOfComponents=\"3\" format=\"ascii\">\n");
  for (size_t k = 0; k < points.size(); ++k) {
    const Vec3 x = points[k] + displacement[k];
    fmt::format_to(out, "{} {} {}\n", x.x(), x.y(), x.z());
  }
  fmt::format_to(out, "</DataArray></Points>\n<Cells>\n<DataArray type=\"Int64\" Name=\"connectivity\" format=\"ascii\">\n");
  for (std::int64_t v : connectivity) fmt::format_to(out, "{} ", v);
  fmt::format_to(out, "\n</DataArray>\n<DataArray type=\"Int64\" Name=\"offsets\" format=\"ascii\">\n");
  for (std::int64_t o : offsets) fmt::format_to(out, "{} ", o);  // each cell's end in connectivity
  fmt::format_to(out, "\n</DataArray>\n<DataArray type=\"UInt8\" Name=\"types\" format=\"ascii\">\n");
  for (int t : types) fmt::format_to(out, "{} ", t);
  fmt::format_to(out, "\n</DataArray>\n</Cells>\n<PointData Vectors=\"displacement\">\n"
                      "<DataArray type=\"Float64\" Name=\"displacement\" NumberOfComponents=\"3\" format=\"ascii\">\n");
  for (const Vec3& d : displacement) fmt::format_to(out, "{} {} {}\n", d.x(), d.y(), d.z());
  fmt::format_to(out, "</DataArray>\n</PointData>\n<CellData>\n<DataArray type=\"Int32\" Name=\"side\" format=\"ascii\">\n");
  for (int s : side) fmt::format_to(out, "{} ", s);
  fmt::format_to(out, "\n</DataArray>\n<DataArray type=\"Int32\" Name=\"element\" format=\"ascii\">\n");
  for (int e : element) fmt::format_to(out, "{} ", e);
  fmt::format_to(out, "\n</DataArray>\n</CellData>\n</Piece>\n</UnstructuredGrid>\n</VTKFile>\n");
  std::ofstream f(path, std::ios::binary | std::ios::trunc);
  if (!f) fail<IoError>("cannot open '{}' for writing", path.string());
  f.write(b.data(), static_cast<std::streamsize>(b.size()));
  if (!f) fail<IoError>("error while writing '{}'", path.string());
}

}  // namespace plastifem::io
