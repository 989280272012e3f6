#pragma once
// VTK XML unstructured grid files (.vtu): write a Mesh<E> with named point and cell fields, and
// read such files back.
//
// Reference: "VTK File Formats", section "XML File Formats" (VTK User's Guide; online at
// docs.vtk.org, design_documents/VTKFileFormats). One <Piece>, one cell type (E::vtk_cell_type,
// whose node numbering is plastifem's), Float64 points and fields, Int64 connectivity/offsets,
// UInt8 types.
//
// Binary layout (both appended encodings): header_type="UInt64"; every array is an 8-byte byte
// count N followed by its N bytes, in this machine's byte order (declared in byte_order). With
// encoding="base64" each array is ONE base64 stream of (count + data) -- the layout VTK's own
// writer produces for uncompressed data. A DataArray's offset="..." counts bytes (raw) or base64
// characters (base64) from the first byte after the '_' that opens the appended data.
//
// The reader takes what the writer writes and most single-piece, uncompressed .vtu files of
// other tools: ascii / binary (inline base64) / appended raw or base64 arrays, header_type UInt32
// or UInt64, either byte order, any integer type for cells and Float32/Float64 (or integer)
// fields; inline base64 may also be encoded as base64(header) + base64(data). It scans tags and
// attributes, which is all a .vtu needs; it is no general XML parser. Malformed input throws
// IoError "file:line: what was expected"; every read is bounds-checked.
//
// This header also holds the small text-parsing helpers (detail::) shared by the Gmsh and legacy
// VTK readers of this directory.
#include <plastifem/mesh/mesh.hpp>

#include <fmt/format.h>

#include <algorithm>
#include <bit>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <type_traits>
#include <unordered_set>
#include <vector>

namespace plastifem::io {

/// How write_vtu stores its arrays.
enum class Encoding {
  ascii,            ///< text; doubles in shortest round-trip form, so reading back is bit-exact
  appended_raw,     ///< binary after the XML, <AppendedData encoding="raw">: smallest and fastest
  appended_base64,  ///< the same, base64-encoded: the file stays plain (valid XML) text
};

/// A named field to write: one column per node (point data) or element (cell data), one row per
/// component. A column vector (Eigen::VectorXd) is a scalar field; anything else (Matrix3Xd for
/// vectors, or a MatrixXd of components x entities as read_vtu returns it) is written as is.
struct Field {
  std::string name;
  Eigen::MatrixXd values;  ///< components x entities

  template <class Derived>
  Field(std::string field_name, const Eigen::MatrixBase<Derived>& v) : name(std::move(field_name)) {
    if constexpr (Derived::ColsAtCompileTime == 1) values = v.transpose();
    else values = v;
  }
};

/// The fields of a name -> values map (MeshData::point_data / cell_data), e.g. to write them again.
inline std::vector<Field> to_fields(const std::map<std::string, Eigen::MatrixXd>& data) {
  std::vector<Field> fields;
  for (const auto& [name, values] : data) fields.emplace_back(name, values);
  return fields;
}

struct VtuOptions {
  Encoding encoding = Encoding::appended_raw;
  /// If not empty: the name of a 3-component point field (e.g. "displacement"); points are then
  /// written at node + field, the deformed configuration, instead of at the reference nodes
  /// (read_vtu returns them as the mesh's nodes).
  std::string deform_by;
};

/// A mesh read from a file with its named fields (rows: components, columns: nodes / elements).
/// Files carry no node or face sets, so the mesh has none.
template <FiniteElement E>
struct MeshData {
  Mesh<E> mesh;
  std::map<std::string, Eigen::MatrixXd> point_data;
  std::map<std::string, Eigen::MatrixXd> cell_data;
};

/// Options of the mesh readers (read_vtu, read_vtk_legacy, read_gmsh and their *_string forms),
/// an optional last argument.
struct ReadOptions {
  /// Remove the nodes no element uses (a Gmsh file's geometry points, say): the other nodes keep
  /// their order, renumbered; node sets lose the dropped nodes, point fields their columns (see
  /// drop_unused_nodes in mesh/mesh.hpp). Off by default, so that node i is the file's i-th node;
  /// the mesh then lists such nodes in report().unused_nodes and the solver holds them fixed.
  bool drop_unused_nodes = false;
};

// =================================================================================================
// Helpers shared by the readers in this directory.
namespace detail {

[[noreturn]] inline void parse_fail(const std::string& path, size_t line, const std::string& what) {
  throw IoError(fmt::format("{}:{}: {}", path, line, what));
}

/// A token quoted for an error message: at most 40 characters, non-printable bytes as '?'.
inline std::string show(std::string_view s) {
  std::string out = "'";
  for (size_t i = 0; i < s.size() && i < 40; ++i) {
    const auto c = static_cast<unsigned char>(s[i]);
    out += (c >= 32 && c < 127) ? static_cast<char>(c) : '?';
  }
  return out + (s.size() > 40 ? "...'" : "'");
}

inline bool iequals(std::string_view a, std::string_view b) {
  return a.size() == b.size() && std::equal(a.begin(), a.end(), b.begin(), [](char x, char y) {
           return std::tolower(static_cast<unsigned char>(x)) == std::tolower(static_cast<unsigned char>(y));
         });
}

inline bool is_space(char c) { return c == ' ' || c == '\t' || c == '\n' || c == '\r' || c == '\v' || c == '\f'; }

inline std::string_view trim(std::string_view s) {
  while (!s.empty() && is_space(s.front())) s.remove_prefix(1);
  while (!s.empty() && is_space(s.back())) s.remove_suffix(1);
  return s;
}

inline std::vector<std::string_view> split(std::string_view s) {
  std::vector<std::string_view> tokens;
  size_t i = 0;
  while (i < s.size()) {
    while (i < s.size() && is_space(s[i])) ++i;
    const size_t b = i;
    while (i < s.size() && !is_space(s[i])) ++i;
    if (i > b) tokens.push_back(s.substr(b, i - b));
  }
  return tokens;
}

/// Whole-token number parse (std::from_chars: locale-independent, exact for doubles, accepts
/// "inf"/"nan"). A leading '+' is accepted, as some writers emit it.
template <class T>
bool parse_number(std::string_view s, T& v) {
  if (s.size() > 1 && s[0] == '+') s.remove_prefix(1);
  const char* end = s.data() + s.size();
  const auto [p, ec] = std::from_chars(s.data(), end, v);
  return ec == std::errc() && p == end;
}

/// The whole file, read in binary mode (appended-data offsets are byte offsets).
inline std::string read_file(const std::filesystem::path& path) {
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec)) fail<IoError>("cannot read '{}': it is a directory", path.string());
  std::ifstream in(path, std::ios::binary);
  if (!in) fail<IoError>("cannot open '{}' for reading: {}", path.string(), std::strerror(errno));
  in.seekg(0, std::ios::end);
  const std::streamoff size = in.tellg();
  if (size < 0) fail<IoError>("cannot read '{}'", path.string());
  std::string text(static_cast<size_t>(size), '\0');
  in.seekg(0, std::ios::beg);
  in.read(text.data(), size);
  if (!in) fail<IoError>("error while reading '{}'", path.string());
  return text;
}

/// Line- and token-wise reading of a text file, keeping line numbers for error messages.
class TextScanner {
 public:
  TextScanner(std::string path, std::string text) : path_(std::move(path)), text_(std::move(text)) {}

  /// The next line without its end-of-line characters (possibly empty); false at end of text.
  /// After token(), returns the rest of the current line.
  bool line(std::string_view& out) {
    if (pos_ >= text_.size()) return false;
    size_t nl = text_.find('\n', pos_);
    const size_t end = nl == std::string::npos ? text_.size() : nl;
    out = std::string_view(text_).substr(pos_, end - pos_);
    if (!out.empty() && out.back() == '\r') out.remove_suffix(1);
    last_ = line_;
    pos_ = nl == std::string::npos ? text_.size() : nl + 1;
    if (nl != std::string::npos) ++line_;
    return true;
  }
  /// The next line that is not blank, trimmed; false at end of text.
  bool content_line(std::string_view& out) {
    while (line(out)) {
      out = trim(out);
      if (!out.empty()) return true;
    }
    return false;
  }
  /// The next whitespace-separated token; false at end of text.
  bool token(std::string_view& out) {
    while (pos_ < text_.size() && is_space(text_[pos_])) {
      if (text_[pos_] == '\n') ++line_;
      ++pos_;
    }
    if (pos_ >= text_.size()) return false;
    const size_t b = pos_;
    while (pos_ < text_.size() && !is_space(text_[pos_])) ++pos_;
    out = std::string_view(text_).substr(b, pos_ - b);
    last_ = line_;
    return true;
  }

  /// Line number of what was returned last (the last line at end of text).
  size_t line_number() const { return last_; }
  const std::string& path() const { return path_; }
  [[noreturn]] void fail(const std::string& what) const { parse_fail(path_, last_, what); }
  [[noreturn]] void fail_at(size_t line, const std::string& what) const { parse_fail(path_, line, what); }

  /// Saving and restoring the position allows a one-token look-ahead.
  struct State {
    size_t pos, line, last;
  };
  State save() const { return {pos_, line_, last_}; }
  void restore(State s) { pos_ = s.pos, line_ = s.line, last_ = s.last; }

 private:
  std::string path_, text_;
  size_t pos_ = 0;
  size_t line_ = 1;  // line at pos_
  size_t last_ = 1;  // line of the last returned line or token
};

/// ReadOptions::drop_unused_nodes for a mesh with point fields: their columns follow the nodes.
template <FiniteElement E>
void drop_unused_points(MeshData<E>& data) {
  if (data.mesh.report().unused_nodes.empty()) return;
  std::vector<Index> old_to_new;
  data.mesh = drop_unused_nodes(data.mesh, &old_to_new);
  for (auto& [name, values] : data.point_data) {
    Eigen::MatrixXd kept(values.rows(), data.mesh.num_nodes());
    for (size_t i = 0; i < old_to_new.size(); ++i)
      if (old_to_new[i] >= 0) kept.col(old_to_new[i]) = values.col(static_cast<Eigen::Index>(i));
    values = std::move(kept);
  }
}

/// Name of the plastifem element with this VTK cell type, for hints in error messages.
inline const char* element_of_vtk_type(std::int64_t type) {
  switch (type) {
    case Tet4::vtk_cell_type: return Tet4::name;
    case Tet10::vtk_cell_type: return Tet10::name;
    case Hex8::vtk_cell_type: return Hex8::name;
    case Wedge6::vtk_cell_type: return Wedge6::name;
    default: return nullptr;
  }
}

/// Every cell must be an E: what to say of cell `cell` if its VTK type is not E's ("cell 12 has
/// VTK type 5, expected 10 (Tet4)"), nullopt if it is. The readers prefix it with file:line.
template <FiniteElement E>
std::optional<std::string> wrong_cell_type(std::size_t cell, std::int64_t type) {
  if (type == E::vtk_cell_type) return std::nullopt;
  const char* other = element_of_vtk_type(type);
  return fmt::format("cell {} has VTK type {}, expected {} ({}){}", cell, type, E::vtk_cell_type, E::name,
                     other ? fmt::format(" -- the file holds {} cells: read it as Mesh<{}>", other, other) : "");
}

inline void base64_append(std::string& out, const unsigned char* p, size_t n) {
  static constexpr char digits[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  out.reserve(out.size() + (n + 2) / 3 * 4);
  size_t i = 0;
  for (; i + 3 <= n; i += 3) {
    const std::uint32_t v = (std::uint32_t{p[i]} << 16) | (std::uint32_t{p[i + 1]} << 8) | p[i + 2];
    out += digits[v >> 18], out += digits[(v >> 12) & 63], out += digits[(v >> 6) & 63], out += digits[v & 63];
  }
  if (i < n) {
    const std::uint32_t v = (std::uint32_t{p[i]} << 16) | (i + 1 < n ? std::uint32_t{p[i + 1]} << 8 : 0);
    out += digits[v >> 18], out += digits[(v >> 12) & 63];
    out += i + 1 < n ? digits[(v >> 6) & 63] : '=';
    out += '=';
  }
}

/// Decodes base64 text whose length is a multiple of 4; nullopt if it is not valid base64.
inline std::optional<std::vector<unsigned char>> base64_decode(std::string_view s) {
  auto value = [](char c) -> int {
    if (c >= 'A' && c <= 'Z') return c - 'A';
    if (c >= 'a' && c <= 'z') return c - 'a' + 26;
    if (c >= '0' && c <= '9') return c - '0' + 52;
    if (c == '+') return 62;
    if (c == '/') return 63;
    return -1;
  };
  if (s.size() % 4 != 0) return std::nullopt;
  std::vector<unsigned char> out;
  out.reserve(s.size() / 4 * 3);
  for (size_t i = 0; i < s.size(); i += 4) {
    const bool last = i + 4 == s.size();
    const int pad = (last && s[i + 3] == '=') ? (s[i + 2] == '=' ? 2 : 1) : 0;
    int v[4];
    for (int k = 0; k < 4 - pad; ++k)
      if ((v[k] = value(s[i + k])) < 0) return std::nullopt;
    for (int k = 4 - pad; k < 4; ++k) v[k] = 0;
    const std::uint32_t w = (std::uint32_t(v[0]) << 18) | (std::uint32_t(v[1]) << 12) | (std::uint32_t(v[2]) << 6) |
                            std::uint32_t(v[3]);
    out.push_back(static_cast<unsigned char>(w >> 16));
    if (pad < 2) out.push_back(static_cast<unsigned char>((w >> 8) & 255));
    if (pad < 1) out.push_back(static_cast<unsigned char>(w & 255));
  }
  return out;
}

/// Text for an attribute value. Tab, LF and CR are written as character references: a parser
/// normalises them to spaces in an attribute value when raw, so a name holding one would read
/// back changed.
inline std::string xml_escape(std::string_view s) {
  std::string out;
  for (char c : s) switch (c) {
      case '&': out += "&amp;"; break;
      case '<': out += "&lt;"; break;
      case '>': out += "&gt;"; break;
      case '"': out += "&quot;"; break;
      case '\'': out += "&apos;"; break;
      case '\t': out += "&#9;"; break;
      case '\n': out += "&#10;"; break;
      case '\r': out += "&#13;"; break;
      default: out += c;
    }
  return out;
}

/// Whether an XML 1.0 document can hold s (escaped): valid UTF-8 (no overlong form, surrogate or
/// code point beyond U+10FFFF) of characters XML allows -- no control character but tab, LF and
/// CR, no U+FFFE or U+FFFF. A parser refuses a file with anything else, even as a reference.
inline bool xml_writable(std::string_view s) {
  static constexpr char32_t least[] = {0, 0, 0x80, 0x800, 0x10000};  // shortest form's first code point, by length
  for (size_t i = 0; i < s.size();) {
    const auto b = static_cast<unsigned char>(s[i]);
    const size_t n = b < 0x80 ? 1 : (b >> 5) == 6 ? 2 : (b >> 4) == 14 ? 3 : (b >> 3) == 30 ? 4 : 0;
    if (n == 0 || n > s.size() - i) return false;  // a continuation or invalid lead byte; cut short
    char32_t c = n == 1 ? b : static_cast<char32_t>(b & (0x7F >> n));
    for (size_t k = 1; k < n; ++k) {
      const auto t = static_cast<unsigned char>(s[i + k]);
      if ((t & 0xC0) != 0x80) return false;
      c = (c << 6) | (t & 0x3Fu);
    }
    if (c < least[n] || c > 0x10FFFF || (c >= 0xD800 && c <= 0xDFFF) || c == 0xFFFE || c == 0xFFFF ||
        (c < 0x20 && c != '\t' && c != '\n' && c != '\r'))
      return false;
    i += n;
  }
  return true;
}

// --- writing -------------------------------------------------------------------------------------

enum class OutType { f64, i64, u8 };

struct OutArray {
  std::string name;
  OutType type;
  int components;  ///< 0: no NumberOfComponents attribute (cell arrays)
  std::vector<unsigned char> bytes;
};

template <class T>
OutArray out_array(std::string name, OutType type, int components, const T* data, size_t count) {
  OutArray a{std::move(name), type, components, std::vector<unsigned char>(count * sizeof(T))};
  if (count) std::memcpy(a.bytes.data(), data, count * sizeof(T));
  return a;
}

inline const char* type_name(OutType t) { return t == OutType::f64 ? "Float64" : t == OutType::i64 ? "Int64" : "UInt8"; }

/// Text values, one tuple per line. `{}` is fmt's shortest representation that reads back to the
/// same double, so ascii files round-trip bit for bit.
inline void append_ascii(fmt::memory_buffer& buf, const OutArray& a) {
  const size_t size = a.type == OutType::u8 ? 1 : 8;
  const size_t n = a.bytes.size() / size, per_line = a.components > 0 ? a.components : 1;
  auto out = std::back_inserter(buf);
  for (size_t i = 0; i < n; ++i) {
    const unsigned char* p = a.bytes.data() + i * size;
    if (i % per_line == 0) fmt::format_to(out, "          ");
    if (a.type == OutType::f64) {
      double v;
      std::memcpy(&v, p, 8);
      fmt::format_to(out, "{}", v);
    } else if (a.type == OutType::i64) {
      std::int64_t v;
      std::memcpy(&v, p, 8);
      fmt::format_to(out, "{}", v);
    } else {
      fmt::format_to(out, "{}", unsigned{*p});
    }
    buf.push_back(i % per_line == per_line - 1 ? '\n' : ' ');
  }
}

inline void check_fields(const std::vector<Field>& fields, Index count, const char* kind) {
  for (size_t i = 0; i < fields.size(); ++i) {
    const Field& f = fields[i];
    if (f.name.empty()) fail<InvalidArgument>("{} field {} has an empty name", kind, i);
    if (!xml_writable(f.name))  // the file would not open in ParaView or any XML reader
      fail<InvalidArgument>("{} field {} has a name XML cannot hold (invalid UTF-8, or a control character other "
                            "than tab, LF, CR): {}", kind, i, show(f.name));
    if (f.values.rows() < 1 || f.values.cols() != count)
      fail<InvalidArgument>("{} field '{}' is {} x {}; expected components x {} (one column per {})", kind, f.name,
                            f.values.rows(), f.values.cols(), count,
                            std::string_view(kind) == "point" ? "node" : "element");
    for (size_t j = 0; j < i; ++j)
      if (fields[j].name == f.name) fail<InvalidArgument>("two {} fields are named '{}'", kind, f.name);
  }
}

}  // namespace detail

// =================================================================================================

/// Writes an unstructured grid of one cell type: `points` (one column per point), `connectivity`
/// (nodes_per_cell point indices per cell), point fields (one column per point) and cell fields
/// (one column per cell). What write_vtu and io::write_surface_vtu write. Throws as write_vtu.
inline void write_vtu_cells(const std::filesystem::path& path, Eigen::Matrix3Xd points,
                            const std::vector<std::int64_t>& connectivity, int nodes_per_cell, int vtk_type,
                            const std::vector<Field>& point_data = {}, const std::vector<Field>& cell_data = {},
                            const VtuOptions& options = {}) {
  using detail::OutType;
  const Index num_points = points.cols();
  if (nodes_per_cell < 1 || connectivity.size() % static_cast<size_t>(nodes_per_cell) != 0)
    fail<InvalidArgument>("write_vtu_cells: {} connectivity entries are not cells of {} points", connectivity.size(),
                          nodes_per_cell);
  for (size_t k = 0; k < connectivity.size(); ++k)
    if (connectivity[k] < 0 || connectivity[k] >= num_points)
      fail<InvalidArgument>("write_vtu_cells: cell {} refers to point {} of {}", k / static_cast<size_t>(nodes_per_cell),
                            connectivity[k], num_points);
  const size_t ne = connectivity.size() / static_cast<size_t>(nodes_per_cell);
  detail::check_fields(point_data, num_points, "point");
  detail::check_fields(cell_data, static_cast<Index>(ne), "cell");

  std::vector<detail::OutArray> arrays;  // in file order: point data, cell data, points, cells
  for (const Field& f : point_data)
    arrays.push_back(detail::out_array(f.name, OutType::f64, static_cast<int>(f.values.rows()), f.values.data(),
                                       static_cast<size_t>(f.values.size())));
  for (const Field& f : cell_data)
    arrays.push_back(detail::out_array(f.name, OutType::f64, static_cast<int>(f.values.rows()), f.values.data(),
                                       static_cast<size_t>(f.values.size())));
  const size_t n_point_fields = point_data.size(), n_cell_fields = cell_data.size();

  if (!options.deform_by.empty()) {
    auto it = std::find_if(point_data.begin(), point_data.end(), [&](const Field& f) { return f.name == options.deform_by; });
    if (it == point_data.end() || it->values.rows() != 3)
      fail<InvalidArgument>("deform_by = '{}' names no 3-component point field", options.deform_by);
    points += it->values;
  }
  for (Index k = 0; k < num_points; ++k)  // the readers refuse such a file: say so here, with the point
    if (!points.col(k).allFinite())
      fail<InvalidArgument>("write_vtu: point {} is not finite ({}, {}, {}){}", k, points(0, k), points(1, k),
                            points(2, k),
                            options.deform_by.empty() ? std::string()
                                                      : fmt::format(" after adding point field '{}'", options.deform_by));
  arrays.push_back(detail::out_array("Points", OutType::f64, 3, points.data(), static_cast<size_t>(points.size())));

  std::vector<std::int64_t> offsets(ne);
  for (size_t e = 0; e < ne; ++e) offsets[e] = static_cast<std::int64_t>((e + 1) * static_cast<size_t>(nodes_per_cell));
  const std::vector<std::uint8_t> types(ne, static_cast<std::uint8_t>(vtk_type));
  arrays.push_back(detail::out_array("connectivity", OutType::i64, 0, connectivity.data(), connectivity.size()));
  arrays.push_back(detail::out_array("offsets", OutType::i64, 0, offsets.data(), offsets.size()));
  arrays.push_back(detail::out_array("types", OutType::u8, 0, types.data(), types.size()));

  const bool ascii = options.encoding == Encoding::ascii;
  const bool base64 = options.encoding == Encoding::appended_base64;
  fmt::memory_buffer xml;
  auto out = std::back_inserter(xml);
  fmt::format_to(out,
                 "<?xml version=\"1.0\"?>\n"
                 "<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" byte_order=\"{}\" header_type=\"UInt64\">\n"
                 "  <UnstructuredGrid>\n"
                 "    <Piece NumberOfPoints=\"{}\" NumberOfCells=\"{}\">\n",
                 std::endian::native == std::endian::little ? "LittleEndian" : "BigEndian", num_points, ne);
  std::uint64_t offset = 0;  // of the next array in the appended data
  auto data_array = [&](const detail::OutArray& a) {
    fmt::format_to(out, "        <DataArray type=\"{}\" Name=\"{}\"", detail::type_name(a.type), detail::xml_escape(a.name));
    if (a.components > 0) fmt::format_to(out, " NumberOfComponents=\"{}\"", a.components);
    if (ascii) {
      fmt::format_to(out, " format=\"ascii\">\n");
      detail::append_ascii(xml, a);
      fmt::format_to(out, "        </DataArray>\n");
    } else {
      fmt::format_to(out, " format=\"appended\" offset=\"{}\"/>\n", offset);
      const std::uint64_t n = sizeof(std::uint64_t) + a.bytes.size();
      offset += base64 ? (n + 2) / 3 * 4 : n;
    }
  };
  auto section = [&](const char* tag, size_t begin, size_t end) {
    fmt::format_to(out, "      <{}>\n", tag);
    for (size_t i = begin; i < end; ++i) data_array(arrays[i]);
    fmt::format_to(out, "      </{}>\n", tag);
  };
  const size_t p = n_point_fields + n_cell_fields;  // index of Points
  section("PointData", 0, n_point_fields);
  section("CellData", n_point_fields, p);
  section("Points", p, p + 1);
  section("Cells", p + 1, p + 4);
  fmt::format_to(out, "    </Piece>\n  </UnstructuredGrid>\n");

  std::ofstream file(path, std::ios::binary | std::ios::trunc);
  if (!file) fail<IoError>("cannot open '{}' for writing: {}", path.string(), std::strerror(errno));
  if (!ascii) fmt::format_to(out, "  <AppendedData encoding=\"{}\">\n   _", base64 ? "base64" : "raw");
  file.write(xml.data(), static_cast<std::streamsize>(xml.size()));
  if (!ascii) {
    std::string encoded;
    for (const auto& a : arrays) {
      const std::uint64_t n = a.bytes.size();
      if (base64) {
        std::vector<unsigned char> block(sizeof n + a.bytes.size());
        std::memcpy(block.data(), &n, sizeof n);
        if (n) std::memcpy(block.data() + sizeof n, a.bytes.data(), a.bytes.size());
        encoded.clear();
        detail::base64_append(encoded, block.data(), block.size());
        file.write(encoded.data(), static_cast<std::streamsize>(encoded.size()));
      } else {
        file.write(reinterpret_cast<const char*>(&n), sizeof n);
        file.write(reinterpret_cast<const char*>(a.bytes.data()), static_cast<std::streamsize>(a.bytes.size()));
      }
    }
    file << "\n  </AppendedData>\n";
  }
  file << "</VTKFile>\n";
  file.close();
  if (!file) fail<IoError>("error while writing '{}' (disk full?)", path.string());
}

/// Writes `mesh` with optional point fields (one column per node) and cell fields (one column per
/// element). Throws IoError if the file cannot be written, InvalidArgument on a field of the
/// wrong size, a duplicate name, a deform_by that names no 3-component point field, or points
/// that are not finite (after adding the deform_by field).
template <FiniteElement E>
void write_vtu(const std::filesystem::path& path, const Mesh<E>& mesh, const std::vector<Field>& point_data = {},
               const std::vector<Field>& cell_data = {}, const VtuOptions& options = {}) {
  std::vector<std::int64_t> connectivity;
  connectivity.reserve(static_cast<size_t>(mesh.num_elements()) * E::num_nodes);
  for (const auto& c : mesh.elements()) connectivity.insert(connectivity.end(), c.begin(), c.end());
  write_vtu_cells(path, mesh.nodes(), connectivity, E::num_nodes, E::vtk_cell_type, point_data, cell_data, options);
}

// =================================================================================================
namespace detail {

/// One element of the tag scan: name, attributes, and the text between its tags.
struct XmlElement {
  std::string name;
  std::vector<std::pair<std::string, std::string>> attributes;
  size_t line = 0;                              ///< line of the start tag
  size_t content_begin = 0, content_end = 0;    ///< its text: up to its end tag or first child
  bool content_done = false;
  int parent = -1;
  std::vector<int> children;

  const std::string* attribute(std::string_view key) const {
    for (const auto& [k, v] : attributes)
      if (k == key) return &v;
    return nullptr;
  }
};

struct XmlDocument {
  std::vector<XmlElement> elements;      ///< elements[0] is the root
  size_t appended = std::string::npos;   ///< first byte after the '_' of <AppendedData>
  int appended_element = -1;
};

inline size_t line_at(const std::string& text, size_t pos) {
  return 1 + static_cast<size_t>(std::count(text.begin(), text.begin() + static_cast<std::ptrdiff_t>(std::min(pos, text.size())), '\n'));
}

inline bool is_name_char(char c) {
  return std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == ':' || c == '.' || c == '-';
}

/// Appends the UTF-8 encoding of code point `c` (at most 0x10FFFF).
inline void append_utf8(std::string& out, unsigned c) {
  auto byte = [&](unsigned v) { out += static_cast<char>(static_cast<unsigned char>(v)); };
  if (c < 0x80) {
    byte(c);
  } else if (c < 0x800) {
    byte(0xC0 | (c >> 6)), byte(0x80 | (c & 0x3F));
  } else if (c < 0x10000) {
    byte(0xE0 | (c >> 12)), byte(0x80 | ((c >> 6) & 0x3F)), byte(0x80 | (c & 0x3F));
  } else {
    byte(0xF0 | (c >> 18)), byte(0x80 | ((c >> 12) & 0x3F)), byte(0x80 | ((c >> 6) & 0x3F)), byte(0x80 | (c & 0x3F));
  }
}

inline std::string xml_unescape(std::string_view s, const std::string& path, size_t line) {
  std::string out;
  for (size_t i = 0; i < s.size(); ++i) {
    if (s[i] != '&') {
      out += s[i];
      continue;
    }
    const size_t semi = s.find(';', i);
    if (semi == std::string_view::npos) parse_fail(path, line, "expected ';' ending an entity like &amp;");
    const std::string_view ent = s.substr(i + 1, semi - i - 1);
    if (ent == "amp") out += '&';
    else if (ent == "lt") out += '<';
    else if (ent == "gt") out += '>';
    else if (ent == "quot") out += '"';
    else if (ent == "apos") out += '\'';
    else if (ent.size() > 1 && ent[0] == '#') {
      unsigned code = 0;
      const bool hex = ent[1] == 'x' || ent[1] == 'X';
      const std::string_view digits = ent.substr(hex ? 2 : 1);
      const auto [p, ec] = std::from_chars(digits.data(), digits.data() + digits.size(), code, hex ? 16 : 10);
      if (ec != std::errc() || p != digits.data() + digits.size() || code == 0 || code > 0x10FFFF ||
          (code >= 0xD800 && code <= 0xDFFF))
        parse_fail(path, line, fmt::format("expected a character reference to a Unicode character, got {}", show(ent)));
      append_utf8(out, code);
    } else {
      parse_fail(path, line, fmt::format("unknown entity &{};", ent));
    }
    i = semi;
  }
  return out;
}

/// Scans start tags, end tags and their text; stops at the '_' of <AppendedData> (what follows
/// may be raw bytes).
inline XmlDocument scan_xml(const std::string& text, const std::string& path) {
  XmlDocument doc;
  std::vector<int> open;
  std::unordered_set<std::string_view> keys;
  size_t p = 0, line = 1, counted = 0;  // line number at position `counted`
  auto line_of = [&](size_t pos) {
    if (pos < counted) line = 1, counted = 0;  // error paths may look back
    line += static_cast<size_t>(std::count(text.begin() + static_cast<std::ptrdiff_t>(counted), text.begin() + static_cast<std::ptrdiff_t>(pos), '\n'));
    counted = pos;
    return line;
  };
  auto fail_at = [&](size_t pos, const std::string& what) { parse_fail(path, line_of(pos), what); };
  if (text.compare(0, 3, "\xEF\xBB\xBF") == 0) p = 3;  // UTF-8 byte order mark
  bool root_closed = false;
  while (true) {
    const size_t lt = text.find('<', p);
    const size_t stop = lt == std::string::npos ? text.size() : lt;
    if (open.empty())  // outside the root: only white space
      for (size_t i = p; i < stop; ++i)
        if (!is_space(text[i]))
          fail_at(i, doc.elements.empty() ? "expected '<' (this is not an XML file)"
                                           : "expected nothing after the end of the root element");
    if (lt == std::string::npos) break;
    if (!open.empty()) {  // the text of an element ends at its first markup (e.g. <InformationKey>)
      XmlElement& top = doc.elements[static_cast<size_t>(open.back())];
      if (!top.content_done) top.content_end = lt, top.content_done = true;
    }
    if (text.compare(lt, 2, "<?") == 0) {
      const size_t e = text.find("?>", lt);
      if (e == std::string::npos) fail_at(lt, "expected '?>' closing '<?'");
      p = e + 2;
      continue;
    }
    if (text.compare(lt, 4, "<!--") == 0) {
      const size_t e = text.find("-->", lt + 4);
      if (e == std::string::npos) fail_at(lt, "expected '-->' closing the comment");
      p = e + 3;
      continue;
    }
    if (text.compare(lt, 2, "<!") == 0) {
      if (text.compare(lt, 9, "<![CDATA[") == 0) fail_at(lt, "CDATA sections are not supported");
      const size_t e = text.find('>', lt);
      if (e == std::string::npos) fail_at(lt, "expected '>' closing '<!'");
      p = e + 1;
      continue;
    }
    if (root_closed) fail_at(lt, "expected nothing after the end of the root element");
    size_t i = lt + 1;
    const bool closing = i < text.size() && text[i] == '/';
    if (closing) ++i;
    const size_t name_begin = i;
    while (i < text.size() && is_name_char(text[i])) ++i;
    const std::string name = text.substr(name_begin, i - name_begin);
    if (name.empty()) fail_at(lt, fmt::format("expected an element name after '{}'", closing ? "</" : "<"));
    if (closing) {
      while (i < text.size() && is_space(text[i])) ++i;
      if (i >= text.size() || text[i] != '>') fail_at(lt, fmt::format("expected '>' closing </{}", name));
      if (open.empty()) fail_at(lt, fmt::format("unexpected </{}>: no element is open", name));
      XmlElement& top = doc.elements[static_cast<size_t>(open.back())];
      if (top.name != name) fail_at(lt, fmt::format("expected </{}> (opened on line {}), got </{}>", top.name, top.line, name));
      open.pop_back();
      root_closed = open.empty();
      p = i + 1;
      continue;
    }
    XmlElement el;
    el.name = name;
    el.line = line_of(lt);
    bool self_closing = false;
    keys.clear();  // this element's attribute names (views into text), for repeats in O(1) each
    while (true) {
      while (i < text.size() && is_space(text[i])) ++i;
      if (i >= text.size()) fail_at(lt, fmt::format("expected '>' closing <{}, got end of file", name));
      if (text[i] == '>') break;
      if (text[i] == '/') {
        if (i + 1 >= text.size() || text[i + 1] != '>') fail_at(i, fmt::format("expected '/>' closing <{}", name));
        self_closing = true;
        ++i;
        break;
      }
      const size_t ab = i;
      while (i < text.size() && is_name_char(text[i])) ++i;
      if (i == ab) fail_at(i, fmt::format("expected an attribute name or '>' in <{}, got {}", name, show(text.substr(i, 1))));
      std::string key = text.substr(ab, i - ab);
      while (i < text.size() && is_space(text[i])) ++i;
      if (i >= text.size() || text[i] != '=') fail_at(i, fmt::format("expected '=' after attribute {} of <{}>", key, name));
      ++i;
      while (i < text.size() && is_space(text[i])) ++i;
      if (i >= text.size() || (text[i] != '"' && text[i] != '\''))
        fail_at(i, fmt::format("expected a quoted value for attribute {} of <{}>", key, name));
      const size_t close = text.find(text[i], i + 1);
      if (close == std::string::npos) fail_at(i, fmt::format("expected the closing quote of attribute {} of <{}>", key, name));
      if (!keys.insert(std::string_view(text).substr(ab, key.size())).second)
        fail_at(i, fmt::format("attribute {} appears twice in <{}>", key, name));
      el.attributes.emplace_back(std::move(key), xml_unescape(std::string_view(text).substr(i + 1, close - i - 1), path, line_of(i)));
      i = close + 1;
    }
    const int id = static_cast<int>(doc.elements.size());
    if (!open.empty()) {
      el.parent = open.back();
      doc.elements[static_cast<size_t>(open.back())].children.push_back(id);
    } else if (!doc.elements.empty()) {
      fail_at(lt, "expected a single root element");
    }
    el.content_begin = el.content_end = i + 1;
    doc.elements.push_back(std::move(el));
    p = i + 1;
    if (self_closing) {
      root_closed = open.empty();
      continue;
    }
    open.push_back(id);
    if (name == "AppendedData") {  // "_" then binary or base64 data up to the end of the file
      size_t u = p;
      while (u < text.size() && is_space(text[u])) ++u;
      if (u >= text.size() || text[u] != '_') fail_at(u, "expected '_' at the start of the appended data");
      doc.appended = u + 1;
      doc.appended_element = id;
      return doc;
    }
  }
  if (doc.elements.empty()) parse_fail(path, line_at(text, text.size()), "expected an XML element, got end of file");
  if (!open.empty())
    parse_fail(path, line_at(text, text.size()),
               fmt::format("expected </{}> before end of file", doc.elements[static_cast<size_t>(open.back())].name));
  return doc;
}

enum class VtkType { i8, u8, i16, u16, i32, u32, i64, u64, f32, f64 };

inline std::optional<VtkType> vtk_type(std::string_view s) {
  static constexpr std::pair<std::string_view, VtkType> names[] = {
      {"Int8", VtkType::i8},   {"UInt8", VtkType::u8},   {"Int16", VtkType::i16}, {"UInt16", VtkType::u16},
      {"Int32", VtkType::i32}, {"UInt32", VtkType::u32}, {"Int64", VtkType::i64}, {"UInt64", VtkType::u64},
      {"Float32", VtkType::f32}, {"Float64", VtkType::f64}, {"Char", VtkType::i8}, {"UChar", VtkType::u8}};
  for (const auto& [n, t] : names)
    if (n == s) return t;
  return std::nullopt;
}

inline size_t type_size(VtkType t) {
  switch (t) {
    case VtkType::i8: case VtkType::u8: return 1;
    case VtkType::i16: case VtkType::u16: return 2;
    case VtkType::i32: case VtkType::u32: case VtkType::f32: return 4;
    default: return 8;
  }
}

/// Reads the DataArrays of one scanned .vtu file.
class VtuArrays {
 public:
  VtuArrays(const std::string& path, const std::string& text, const XmlDocument& doc)
      : path_(path), text_(text), doc_(doc) {
    const XmlElement& root = doc.elements[0];
    if (const std::string* bo = root.attribute("byte_order")) {
      if (*bo != "LittleEndian" && *bo != "BigEndian")
        fail(root, fmt::format("expected byte_order=\"LittleEndian\" or \"BigEndian\", got {}", show(*bo)));
      swap_ = (*bo == "LittleEndian") != (std::endian::native == std::endian::little);
    } else {
      swap_ = std::endian::native != std::endian::little;
    }
    if (const std::string* ht = root.attribute("header_type")) {
      if (*ht != "UInt32" && *ht != "UInt64") fail(root, fmt::format("expected header_type=\"UInt32\" or \"UInt64\", got {}", show(*ht)));
      header_size_ = *ht == "UInt64" ? 8 : 4;
    }
    // VTK names its compressor on ASCII files too, where nothing is compressed: refused only
    // when binary data is read.
    if (const std::string* c = root.attribute("compressor"); c && !c->empty()) compressor_ = c;
    if (doc.appended_element >= 0) {
      const XmlElement& ad = doc.elements[static_cast<size_t>(doc.appended_element)];
      const std::string* enc = ad.attribute("encoding");
      if (!enc || (*enc != "raw" && *enc != "base64"))
        fail(ad, "expected <AppendedData encoding=\"raw\"> or encoding=\"base64\"");
      appended_base64_ = *enc == "base64";
    }
  }

  [[noreturn]] void fail(const XmlElement& el, const std::string& what) const { parse_fail(path_, el.line, what); }

  std::string name(const XmlElement& a) const {
    const std::string* n = a.attribute("Name");
    return n ? *n : std::string("(unnamed)");
  }

  int components(const XmlElement& a) const {
    const std::string* s = a.attribute("NumberOfComponents");
    if (!s) return 1;
    int n = 0;
    if (!parse_number(*s, n) || n < 1 || n > 1000)
      fail(a, fmt::format("expected NumberOfComponents between 1 and 1000, got {}", show(*s)));
    return n;
  }

  /// The `count` values of DataArray `a`, converted to T (integer T only from integer types).
  template <class T>
  std::vector<T> read(const XmlElement& a, size_t count) const {
    const std::string* ts = a.attribute("type");
    if (!ts) fail(a, fmt::format("DataArray '{}' has no type attribute", name(a)));
    const auto type = vtk_type(*ts);
    if (!type) fail(a, fmt::format("DataArray '{}': unsupported type {}", name(a), show(*ts)));
    const bool floating = *type == VtkType::f32 || *type == VtkType::f64;
    if (std::is_integral_v<T> && floating)
      fail(a, fmt::format("DataArray '{}' must have an integer type, got {}", name(a), *ts));
    const std::string* format = a.attribute("format");
    if (!format) fail(a, fmt::format("DataArray '{}' has no format attribute", name(a)));
    if (*format == "ascii") return read_ascii<T>(a, count, floating);
    if (compressor_)
      fail(doc_.elements[0], fmt::format("compressed data (compressor=\"{}\") is not supported; write the file without "
                                         "compression (ParaView: Save Data, Compressor Type: None)", *compressor_));
    std::vector<unsigned char> bytes;
    if (*format == "binary") {
      std::string b64;
      for (size_t i = a.content_begin; i < a.content_end; ++i)
        if (!is_space(text_[i])) b64 += text_[i];
      bytes = block(a, b64, 0);
    } else if (*format == "appended") {
      if (doc_.appended == std::string::npos) fail(a, fmt::format("DataArray '{}' is appended, but the file has no <AppendedData>", name(a)));
      const std::string* os = a.attribute("offset");
      std::uint64_t offset = 0;
      if (!os || !parse_number(*os, offset)) fail(a, fmt::format("DataArray '{}': expected an offset=\"...\" attribute", name(a)));
      if (offset > text_.size() - doc_.appended) fail(a, fmt::format("DataArray '{}': offset {} is beyond the end of the file (truncated?)", name(a), offset));
      bytes = appended_base64_ ? block(a, text_, doc_.appended + offset) : raw_block(a, doc_.appended + offset);
    } else {
      fail(a, fmt::format("DataArray '{}': expected format \"ascii\", \"binary\" or \"appended\", got {}", name(a), show(*format)));
    }
    // Distinct blocks decode to less than the file holds; arrays sharing one block (offsets
    // alike) would each decode it again, a small file claiming gigabytes.
    decoded_ += bytes.size();
    if (decoded_ > text_.size())
      fail(a, fmt::format("DataArray '{}': the binary arrays read so far decode to {} bytes, more than the file's {} "
                          "(arrays sharing one block of data?)", name(a), decoded_, text_.size()));
    const size_t size = type_size(*type);
    if (bytes.size() != count * size)
      fail(a, fmt::format("DataArray '{}' holds {} bytes, expected {} ({} values of type {})", name(a), bytes.size(),
                          count * size, count, *ts));
    return convert<T>(bytes, *type, count);
  }

 private:
  template <class T>
  std::vector<T> read_ascii(const XmlElement& a, size_t count, bool floating) const {
    std::vector<T> values;
    values.reserve(std::min(count, (a.content_end - a.content_begin) / 2 + 1));
    const std::string_view s = std::string_view(text_).substr(a.content_begin, a.content_end - a.content_begin);
    size_t i = 0;
    while (true) {
      while (i < s.size() && is_space(s[i])) ++i;
      if (i >= s.size()) break;
      const size_t b = i;
      while (i < s.size() && !is_space(s[i])) ++i;
      const std::string_view tok = s.substr(b, i - b);
      if (values.size() == count)
        parse_fail(path_, line_at(text_, a.content_begin + b),
                   fmt::format("DataArray '{}' has more than the expected {} values", name(a), count));
      bool ok;
      if (floating) {
        double v = 0;
        ok = parse_number(tok, v);
        values.push_back(static_cast<T>(v));
      } else {
        std::int64_t v = 0;
        ok = parse_number(tok, v);
        values.push_back(static_cast<T>(v));
      }
      if (!ok)
        parse_fail(path_, line_at(text_, a.content_begin + b),
                   fmt::format("expected {} (value {} of DataArray '{}'), got {}", floating ? "a number" : "an integer",
                               values.size() - 1, name(a), show(tok)));
    }
    if (values.size() != count)
      parse_fail(path_, line_at(text_, a.content_end),
                 fmt::format("DataArray '{}' has {} values, expected {}", name(a), values.size(), count));
    return values;
  }

  /// The byte count at the start of `bytes` (header_size_ bytes, which the caller must have).
  std::uint64_t header_value(const XmlElement& a, const std::vector<unsigned char>& bytes) const {
    if (bytes.size() < header_size_)  // never read past a short block
      fail(a, fmt::format("data of '{}' is too short for its {}-byte header (truncated?)", name(a), header_size_));
    return header_value(bytes.data());
  }
  std::uint64_t header_value(const unsigned char* p) const {
    // Byte by byte, in the host's order (header_size_ is 4 or 8): GCC 12 at -O3 -march=native
    // warned that std::reverse on b wrote past it (-Wstringop-overflow, a false positive).
    const size_t n = header_size_ == 4 ? 4 : 8;
    unsigned char b[8] = {};
    for (size_t i = 0; i < n; ++i) b[i] = p[swap_ ? n - 1 - i : i];
    if (n == 4) {
      std::uint32_t v;
      std::memcpy(&v, b, 4);
      return v;
    }
    std::uint64_t v;
    std::memcpy(&v, b, 8);
    return v;
  }

  /// Appended raw: byte count, then the bytes.
  std::vector<unsigned char> raw_block(const XmlElement& a, size_t pos) const {
    if (text_.size() - pos < header_size_) fail(a, fmt::format("appended data of '{}' is truncated", name(a)));
    const std::uint64_t n = header_value(reinterpret_cast<const unsigned char*>(text_.data() + pos));
    pos += header_size_;
    if (n > text_.size() - pos)
      fail(a, fmt::format("appended data of '{}' is truncated: {} bytes announced, {} left in the file", name(a), n, text_.size() - pos));
    const auto* p = reinterpret_cast<const unsigned char*>(text_.data() + pos);
    return std::vector<unsigned char>(p, p + n);
  }

  /// Base64 starting at `pos` of `s`: either base64(header + data) (VTK's layout) or
  /// base64(header) + base64(data); the header's characters decoded tell which (below).
  std::vector<unsigned char> block(const XmlElement& a, std::string_view s, size_t pos) const {
    const size_t enc_header = (header_size_ + 2) / 3 * 4;  // 8 characters (UInt32), 12 (UInt64)
    auto decode = [&](size_t at, size_t length) {
      if (at > s.size() || length > s.size() - at)
        fail(a, fmt::format("base64 data of '{}' is truncated", name(a)));
      auto bytes = base64_decode(s.substr(at, length));
      if (!bytes) fail(a, fmt::format("base64 data of '{}' is not valid base64", name(a)));
      return *bytes;
    };
    // The header's characters decode to header_size_ bytes plus 0 to 2 of the data, or to fewer
    // than header_size_ if they end in more padding than the header needs ("...==" for UInt64:
    // 7 bytes); header_value checks. Exactly header_size_ bytes: the header was encoded alone
    // (or with no data, where both layouts agree). Padding alone does not tell: a one-byte array
    // (one cell's types) after a 4-byte header is 5 bytes, which VTK encodes as "xxxxxxx=".
    const std::vector<unsigned char> head = decode(pos, enc_header);
    const std::uint64_t n = header_value(a, head);
    if (n > s.size()) fail(a, fmt::format("base64 data of '{}' is truncated: {} bytes announced", name(a), n));
    if (head.size() == header_size_) return decode(pos + enc_header, static_cast<size_t>((n + 2) / 3 * 4));
    const std::vector<unsigned char> all = decode(pos, static_cast<size_t>((header_size_ + n + 2) / 3 * 4));
    if (all.size() < header_size_) fail(a, fmt::format("base64 data of '{}' is shorter than its header", name(a)));
    return std::vector<unsigned char>(all.begin() + static_cast<std::ptrdiff_t>(header_size_), all.end());
  }

  template <class T>
  std::vector<T> convert(const std::vector<unsigned char>& bytes, VtkType type, size_t count) const {
    std::vector<T> out(count);
    auto run = [&]<class S>(S*) {
      for (size_t i = 0; i < count; ++i) {
        unsigned char b[sizeof(S)];
        std::memcpy(b, bytes.data() + i * sizeof(S), sizeof(S));
        if (swap_) std::reverse(b, b + sizeof(S));
        S v;
        std::memcpy(&v, b, sizeof(S));
        out[i] = static_cast<T>(v);
      }
    };
    switch (type) {
      case VtkType::i8: run(static_cast<std::int8_t*>(nullptr)); break;
      case VtkType::u8: run(static_cast<std::uint8_t*>(nullptr)); break;
      case VtkType::i16: run(static_cast<std::int16_t*>(nullptr)); break;
      case VtkType::u16: run(static_cast<std::uint16_t*>(nullptr)); break;
      case VtkType::i32: run(static_cast<std::int32_t*>(nullptr)); break;
      case VtkType::u32: run(static_cast<std::uint32_t*>(nullptr)); break;
      case VtkType::i64: run(static_cast<std::int64_t*>(nullptr)); break;
      case VtkType::u64: run(static_cast<std::uint64_t*>(nullptr)); break;
      case VtkType::f32: if constexpr (!std::is_integral_v<T>) run(static_cast<float*>(nullptr)); break;
      case VtkType::f64: if constexpr (!std::is_integral_v<T>) run(static_cast<double*>(nullptr)); break;
    }
    return out;
  }

  const std::string& path_;
  const std::string& text_;
  const XmlDocument& doc_;
  bool swap_ = false;
  size_t header_size_ = 4;  // VTK's default when header_type is absent
  bool appended_base64_ = false;
  const std::string* compressor_ = nullptr;  ///< the root's compressor="..." attribute, if not empty
  mutable size_t decoded_ = 0;               ///< bytes decoded from binary and appended arrays
};

/// The mesh of `cells` over `nodes`, read from file `path`: the constructor's MeshError
/// (inverted or degenerate element, ...) names the file before its message.
template <FiniteElement E>
Mesh<E> mesh_from_file(const std::string& path, Eigen::Matrix3Xd nodes, std::vector<typename Mesh<E>::Connectivity> cells) {
  try {
    return Mesh<E>(std::move(nodes), std::move(cells));
  } catch (const MeshError& e) {
    throw MeshError(fmt::format("{}: {}", path, e.what()));
  }
}

/// Checks cell offsets and connectivity and builds the mesh (whose constructor validates the
/// geometry and throws MeshError).
template <FiniteElement E>
Mesh<E> assemble_mesh(const std::string& path, Eigen::Matrix3Xd nodes, const std::vector<std::int64_t>& offsets,
                      const std::vector<std::int64_t>& connectivity, const std::vector<size_t>& cell_lines) {
  const std::int64_t np = nodes.cols();
  std::vector<typename Mesh<E>::Connectivity> cells(offsets.size());
  std::int64_t begin = 0;
  for (size_t c = 0; c < offsets.size(); ++c) {
    const size_t line = cell_lines.empty() ? 0 : cell_lines[std::min(c, cell_lines.size() - 1)];
    if (offsets[c] - begin != E::num_nodes || offsets[c] > static_cast<std::int64_t>(connectivity.size()))
      parse_fail(path, line, fmt::format("cell {} has {} nodes, expected {} for a {}", c, offsets[c] - begin, E::num_nodes, E::name));
    for (int k = 0; k < E::num_nodes; ++k) {
      const std::int64_t v = connectivity[static_cast<size_t>(begin + k)];
      if (v < 0 || v >= np) parse_fail(path, line, fmt::format("cell {} refers to point {}, outside [0, {})", c, v, np));
      cells[c][static_cast<size_t>(k)] = static_cast<Index>(v);
    }
    begin = offsets[c];
  }
  return mesh_from_file<E>(path, std::move(nodes), std::move(cells));
}

}  // namespace detail

/// read_vtu of a file's contents held in memory; `file_name` is the name error messages give
/// ("file_name:line: what was expected").
template <FiniteElement E>
MeshData<E> read_vtu_string(const std::string& text, const std::string& file_name = "<string>",
                            const ReadOptions& options = {}) {
  const std::string& path = file_name;
  const detail::XmlDocument doc = detail::scan_xml(text, path);
  const auto& els = doc.elements;
  const detail::XmlElement& root = els[0];
  auto fail = [&](const detail::XmlElement& el, const std::string& what) { detail::parse_fail(path, el.line, what); };
  auto children = [&](const detail::XmlElement& parent, std::string_view name) {
    std::vector<const detail::XmlElement*> out;
    for (int c : parent.children)
      if (els[static_cast<size_t>(c)].name == name) out.push_back(&els[static_cast<size_t>(c)]);
    return out;
  };
  auto child = [&](const detail::XmlElement& parent, std::string_view name) -> const detail::XmlElement& {
    const auto found = children(parent, name);
    if (found.size() != 1)
      fail(parent, fmt::format("expected {} <{}> in <{}>, found {}", "one", name, parent.name, found.size()));
    return *found[0];
  };
  if (root.name != "VTKFile") fail(root, fmt::format("expected <VTKFile> as the root element, got <{}>", root.name));
  const std::string* type = root.attribute("type");
  if (!type || *type != "UnstructuredGrid")
    fail(root, fmt::format("expected <VTKFile type=\"UnstructuredGrid\">, got type {} (only .vtu files are read)",
                           type ? detail::show(*type) : "none"));
  const detail::VtuArrays arrays(path, text, doc);
  const detail::XmlElement& piece = child(child(root, "UnstructuredGrid"), "Piece");
  auto count = [&](const char* attr) {
    const std::string* s = piece.attribute(attr);
    std::int64_t n = -1;
    if (!s || !detail::parse_number(*s, n) || n < 0 || n > std::numeric_limits<Index>::max())
      fail(piece, fmt::format("expected <Piece {}=\"...\"> with a count in [0, 2^31)", attr));
    return static_cast<size_t>(n);
  };
  const size_t np = count("NumberOfPoints"), nc = count("NumberOfCells");
  if (nc == 0)  // a Mesh needs elements; say so with the file's name rather than as a MeshError
    fail(piece, fmt::format("the piece has no cells (NumberOfCells=\"0\", {} points): no mesh to read", np));

  Eigen::Matrix3Xd nodes;
  {  // read first, allocate after: the counts come from the file, the values prove them
    const detail::XmlElement& points = child(child(piece, "Points"), "DataArray");
    if (arrays.components(points) != 3) fail(points, "expected NumberOfComponents=\"3\" for the points");
    const std::vector<double> xyz = arrays.read<double>(points, 3 * np);
    for (size_t k = 0; k < xyz.size(); ++k)
      if (!std::isfinite(xyz[k]))
        fail(points, fmt::format("point {} has a non-finite coordinate ({}, {}, {})", k / 3, xyz[k - k % 3],
                                 xyz[k - k % 3 + 1], xyz[k - k % 3 + 2]));
    nodes.resize(3, static_cast<Index>(np));
    std::copy(xyz.begin(), xyz.end(), nodes.data());
  }

  const detail::XmlElement& cells = child(piece, "Cells");
  auto cell_array = [&](std::string_view name) -> const detail::XmlElement& {
    for (const auto* a : children(cells, "DataArray"))
      if (const std::string* n = a->attribute("Name"); n && *n == name) return *a;
    detail::parse_fail(path, cells.line, fmt::format("expected <DataArray Name=\"{}\"> in <Cells>", name));
  };
  const detail::XmlElement& types_el = cell_array("types");
  const auto types = arrays.read<std::int64_t>(types_el, nc);
  for (size_t c = 0; c < nc; ++c)
    if (const auto why = detail::wrong_cell_type<E>(c, types[c])) fail(types_el, *why);
  const detail::XmlElement& offsets_el = cell_array("offsets");
  const auto offsets = arrays.read<std::int64_t>(offsets_el, nc);
  for (size_t c = 0; c < nc; ++c)  // before sizing the connectivity by the last offset
    if (offsets[c] != static_cast<std::int64_t>((c + 1) * E::num_nodes))
      fail(offsets_el, fmt::format("cell {} ends at offset {}, expected {} ({} nodes per {})", c, offsets[c],
                                   (c + 1) * E::num_nodes, E::num_nodes, E::name));
  const detail::XmlElement& conn_el = cell_array("connectivity");
  const auto connectivity = arrays.read<std::int64_t>(conn_el, nc * E::num_nodes);

  MeshData<E> data{detail::assemble_mesh<E>(path, std::move(nodes), offsets, connectivity, {conn_el.line}), {}, {}};
  auto read_fields = [&](const char* section, size_t n, std::map<std::string, Eigen::MatrixXd>& out) {
    for (const auto* s : children(piece, section))
      for (const auto* a : children(*s, "DataArray")) {
        const std::string* name = a->attribute("Name");
        if (!name) fail(*a, fmt::format("expected a Name=\"...\" attribute for a DataArray of <{}>", section));
        if (out.count(*name)) fail(*a, fmt::format("two DataArrays of <{}> are named '{}'", section, *name));
        const int nc_ = arrays.components(*a);
        const std::vector<double> v = arrays.read<double>(*a, static_cast<size_t>(nc_) * n);
        Eigen::MatrixXd m(nc_, static_cast<Eigen::Index>(n));
        std::copy(v.begin(), v.end(), m.data());
        out.emplace(*name, std::move(m));
      }
  };
  read_fields("PointData", np, data.point_data);
  read_fields("CellData", nc, data.cell_data);
  if (options.drop_unused_nodes) detail::drop_unused_points(data);
  return data;
}

/// Reads a .vtu file of E cells (as written by write_vtu) with its point and cell data. Throws
/// IoError on malformed input ("file:line: what was expected"), a cell of another type or a file
/// without cells; the mesh constructor's MeshError (inverted element, ...) names the file.
template <FiniteElement E>
MeshData<E> read_vtu(const std::filesystem::path& file, const ReadOptions& options = {}) {
  return read_vtu_string<E>(detail::read_file(file), file.string(), options);
}

}  // namespace plastifem::io
