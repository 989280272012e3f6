#pragma once
// Triangle surfaces in and out: Wavefront OBJ and STL (ASCII and binary) read, OBJ and VTU
// written (embedding/triangle_surface.hpp).
//
// OBJ: `v x y z [w]` vertices and `f` faces of 1-based (or negative, relative) indices written
// i, i/t, i//n or i/t/n; a polygon of k vertices becomes k - 2 triangles (a fan); other
// statements (vn, vt, o, g, s, usemtl, ...) are skipped. STL: binary when the file is exactly
// 84 + 50 n bytes for the n its header gives, else ASCII, where several solids one after the
// other (as CAD exporters write the parts of one body) are one surface; facets carry their corners, so
// corners with identical coordinates are merged into one vertex, and a facet that collapses to a
// repeated vertex (a zero-area sliver of the exporter) is dropped with a note.
// Malformed input throws IoError "file:line: what was expected" (binary STL: the facet number).
// The `*_string` readers take a file's text (bytes) and the name its messages give.
#include <plastifem/core/log.hpp>
#include <plastifem/embedding/triangle_surface.hpp>
#include <plastifem/mesh/io/vtu.hpp>

#include <cstring>
#include <map>
#include <string>
#include <string_view>

namespace plastifem::io {

namespace detail {

/// "v 1 2 3" -> the numbers after the keyword; refuses a token that is not a finite number.
inline Vec3 parse_point(const std::vector<std::string_view>& tok, size_t first, const std::string& where) {
  if (tok.size() < first + 3) fail<IoError>("{}: expected three coordinates", where);
  Vec3 p;
  for (int k = 0; k < 3; ++k)
    if (!parse_number(tok[first + static_cast<size_t>(k)], p[k]) || !std::isfinite(p[k]))
      fail<IoError>("{}: {} is not a finite number", where, show(tok[first + static_cast<size_t>(k)]));
  return p;
}

}  // namespace detail

/// Reads a Wavefront OBJ surface from its text; `path` names it in messages (see the file comment).
inline TriangleSurface read_obj_string(const std::string& text, const std::string& path) {
  std::vector<Vec3> v;
  std::vector<Triangle> tris;
  size_t line_no = 0, pos = 0;
  std::vector<Index> face;
  while (pos <= text.size()) {
    const size_t eol = std::min(text.find('\n', pos), text.size());
    const std::string_view line = detail::trim(std::string_view(text).substr(pos, eol - pos));
    pos = eol + 1, ++line_no;
    if (line.empty() || line[0] == '#') continue;
    const auto tok = detail::split(line);
    const std::string where = fmt::format("{}:{}", path, line_no);
    if (tok[0] == "v") {
      v.push_back(detail::parse_point(tok, 1, where));
    } else if (tok[0] == "f") {
      face.clear();
      for (size_t k = 1; k < tok.size(); ++k) {
        const std::string_view index = tok[k].substr(0, tok[k].find('/'));
        long long i = 0;
        if (!detail::parse_number(index, i) || i == 0)
          fail<IoError>("{}: {} is not a vertex index (1-based, or negative to count back)", where, detail::show(tok[k]));
        const long long n = static_cast<long long>(v.size()), j = i > 0 ? i - 1 : n + i;
        if (j < 0 || j >= n)
          fail<IoError>("{}: vertex index {} out of range: {} vertices so far", where, i, n);
        face.push_back(static_cast<Index>(j));
      }
      if (face.size() < 3) fail<IoError>("{}: a face needs at least 3 vertices, got {}", where, face.size());
      for (size_t k = 1; k + 1 < face.size(); ++k) {
        const Triangle t{face[0], face[k], face[k + 1]};
        if (t[0] == t[1] || t[1] == t[2] || t[0] == t[2])
          fail<IoError>("{}: the face repeats vertex {} (a triangle of no area)", where,
                        (t[0] == t[1] || t[0] == t[2] ? t[0] : t[1]) + 1);
        tris.push_back(t);
      }
    }
  }
  if (tris.empty()) fail<IoError>("{}: no faces ('f' lines)", path);
  TriangleSurface s;
  s.vertices.resize(3, static_cast<Index>(v.size()));
  for (size_t i = 0; i < v.size(); ++i) s.vertices.col(static_cast<Index>(i)) = v[i];
  s.triangles = std::move(tris);
  check_surface(s, path.c_str());
  return s;
}

/// Reads an STL surface, binary or ASCII, from its bytes; `path` names it in messages (see the
/// file comment).
inline TriangleSurface read_stl_string(const std::string& text, const std::string& path) {
  std::vector<std::array<Vec3, 3>> facets;
  std::uint32_t n = 0;
  if (text.size() >= 84) std::memcpy(&n, text.data() + 80, sizeof n);
  if (text.size() >= 84 && text.size() == 84 + 50 * static_cast<size_t>(n)) {  // binary
    for (std::uint32_t f = 0; f < n; ++f) {
      std::array<Vec3, 3> c;
      for (int k = 0; k < 3; ++k)
        for (int j = 0; j < 3; ++j) {
          float x;
          std::memcpy(&x, text.data() + 84 + 50 * static_cast<size_t>(f) + 12 * static_cast<size_t>(k + 1) +
                              4 * static_cast<size_t>(j),
                      sizeof x);
          if (!std::isfinite(x)) fail<IoError>("{}: facet {} has a non-finite coordinate", path, f);
          c[static_cast<size_t>(k)][j] = x;
        }
      facets.push_back(c);
    }
  } else {  // ASCII: solids of facets of "outer loop", three "vertex" lines, "endloop"
    size_t line_no = 0, pos = 0;
    bool solid = false, solids = false;
    std::array<Vec3, 3> c;
    int corners = -1;  // -1: outside a loop
    while (pos <= text.size()) {
      const size_t eol = std::min(text.find('\n', pos), text.size());
      const std::string_view line = detail::trim(std::string_view(text).substr(pos, eol - pos));
      pos = eol + 1, ++line_no;
      if (line.empty()) continue;
      const auto tok = detail::split(line);
      const std::string where = fmt::format("{}:{}", path, line_no);
      if (!solid) {
        if (tok[0] != "solid")
          fail<IoError>("{}: expected 'solid'{}", where, solids ? " after 'endsolid'" : " (or a binary STL of 84 + 50 n bytes)");
        solid = solids = true;
      } else if (tok[0] == "solid") {
        fail<IoError>("{}: 'solid' inside a solid (the last one's 'endsolid' is missing)", where);
      } else if (tok[0] == "endsolid") {
        if (corners >= 0) fail<IoError>("{}: 'endsolid' inside a facet", where);
        solid = false;
      } else if (tok[0] == "outer") {
        if (corners >= 0) fail<IoError>("{}: 'outer loop' inside a loop", where);
        corners = 0;
      } else if (tok[0] == "vertex") {
        if (corners < 0) fail<IoError>("{}: 'vertex' outside 'outer loop' ... 'endloop'", where);
        if (corners == 3) fail<IoError>("{}: a facet with more than 3 vertices", where);
        c[static_cast<size_t>(corners++)] = detail::parse_point(tok, 1, where);
      } else if (tok[0] == "endloop") {
        if (corners != 3) fail<IoError>("{}: a facet needs 3 vertices, got {}", where, std::max(corners, 0));
        facets.push_back(c), corners = -1;
      } else if (tok[0] != "facet" && tok[0] != "endfacet") {
        fail<IoError>("{}: unexpected {} (facet, outer loop, vertex, endloop, endfacet or endsolid)", where,
                      detail::show(tok[0]));
      }
    }
    if (corners >= 0) fail<IoError>("{}:{}: the file ends inside a facet", path, line_no);
  }
  if (facets.empty()) fail<IoError>("{}: no facets", path);
  // Corners with identical coordinates are one vertex.
  TriangleSurface s;
  std::map<std::array<Scalar, 3>, Index> vertex_of;
  std::vector<Vec3> v;
  Index dropped = 0;
  for (const auto& f : facets) {
    Triangle t;
    for (int k = 0; k < 3; ++k) {
      const Vec3& p = f[static_cast<size_t>(k)];
      const auto [it, added] = vertex_of.try_emplace({p.x(), p.y(), p.z()}, static_cast<Index>(v.size()));
      if (added) v.push_back(p);
      t[static_cast<size_t>(k)] = it->second;
    }
    if (t[0] == t[1] || t[1] == t[2] || t[0] == t[2]) ++dropped;
    else s.triangles.push_back(t);
  }
  if (dropped > 0) note(fmt::format("{}: {} of {} facets dropped (two corners at one point)", path, dropped, facets.size()));
  s.vertices.resize(3, static_cast<Index>(v.size()));
  for (size_t i = 0; i < v.size(); ++i) s.vertices.col(static_cast<Index>(i)) = v[i];
  if (s.triangles.empty()) fail<IoError>("{}: every facet has two corners at one point", path);
  return s;
}

/// Reads a Wavefront OBJ surface file (see the file comment).
inline TriangleSurface read_obj(const std::filesystem::path& file) {
  return read_obj_string(detail::read_file(file), file.string());
}

/// Reads an STL surface file, binary or ASCII (see the file comment).
inline TriangleSurface read_stl(const std::filesystem::path& file) {
  return read_stl_string(detail::read_file(file), file.string());
}

/// read_obj or read_stl, by the file's extension (.obj, .stl; any case).
inline TriangleSurface read_surface(const std::filesystem::path& file) {
  const std::string ext = file.extension().string();
  if (detail::iequals(ext, ".obj")) return read_obj(file);
  if (detail::iequals(ext, ".stl")) return read_stl(file);
  fail<IoError>("{}: unknown surface format '{}' (.obj or .stl)", file.string(), ext);
}

/// Writes the surface at positions x (one column per vertex; the surface's own vertices if
/// empty) as OBJ, with vertex normals n if given.
inline void write_obj(const std::filesystem::path& path, const TriangleSurface& s, const Eigen::Matrix3Xd& x = {},
                      const Eigen::Matrix3Xd& n = {}) {
  const Eigen::Matrix3Xd& p = x.cols() ? x : s.vertices;
  if (p.cols() != s.num_vertices() || (n.cols() && n.cols() != s.num_vertices()))
    fail<InvalidArgument>("write_obj: {} positions and {} normals for {} vertices", p.cols(), n.cols(), s.num_vertices());
  fmt::memory_buffer buf;
  auto out = std::back_inserter(buf);
  fmt::format_to(out, "# plastifem surface: {} vertices, {} triangles\n", s.num_vertices(), s.num_triangles());
  for (Index i = 0; i < p.cols(); ++i) fmt::format_to(out, "v {} {} {}\n", p(0, i), p(1, i), p(2, i));
  for (Index i = 0; i < n.cols(); ++i) fmt::format_to(out, "vn {} {} {}\n", n(0, i), n(1, i), n(2, i));
  for (const Triangle& t : s.triangles) {
    if (n.cols()) fmt::format_to(out, "f {0}//{0} {1}//{1} {2}//{2}\n", t[0] + 1, t[1] + 1, t[2] + 1);
    else fmt::format_to(out, "f {} {} {}\n", t[0] + 1, t[1] + 1, t[2] + 1);
  }
  std::ofstream file(path, std::ios::binary | std::ios::trunc);
  if (!file) fail<IoError>("cannot open '{}' for writing: {}", path.string(), std::strerror(errno));
  file.write(buf.data(), static_cast<std::streamsize>(buf.size()));
  file.close();
  if (!file) fail<IoError>("error while writing '{}' (disk full?)", path.string());
}

/// Writes the surface at positions x (its own vertices if empty) as a VTU of triangles, with
/// point fields (one column per vertex: "normal" from embedded_surface.hpp, say) and cell fields
/// (one per triangle).
inline void write_surface_vtu(const std::filesystem::path& path, const TriangleSurface& s, const Eigen::Matrix3Xd& x = {},
                              const std::vector<Field>& point_data = {}, const std::vector<Field>& cell_data = {},
                              const VtuOptions& options = {}) {
  const Eigen::Matrix3Xd& p = x.cols() ? x : s.vertices;
  if (p.cols() != s.num_vertices())
    fail<InvalidArgument>("write_surface_vtu: {} positions for {} vertices", p.cols(), s.num_vertices());
  std::vector<std::int64_t> connectivity;
  connectivity.reserve(3 * s.triangles.size());
  for (const Triangle& t : s.triangles) connectivity.insert(connectivity.end(), t.begin(), t.end());
  constexpr int vtk_triangle = 5;
  write_vtu_cells(path, p, connectivity, 3, vtk_triangle, point_data, cell_data, options);
}

}  // namespace plastifem::io
