#pragma once
// Legacy VTK files (.vtk): ASCII DATASET UNSTRUCTURED_GRID of one cell type.
//
// Reference: "VTK File Formats", section "Simple Legacy Formats" (VTK User's Guide; online at
// docs.vtk.org, design_documents/VTKFileFormats). Read:
//   - POINTS n type;
//   - CELLS in both layouts: the classic "CELLS n size" followed by "k i_1 ... i_k" per cell, and
//     the one of file version 5.1, "CELLS n_offsets n_connectivity" followed by the arrays
//     "OFFSETS type" and "CONNECTIVITY type";
//   - CELL_TYPES n;
//   - POINT_DATA n / CELL_DATA n with SCALARS (with or without LOOKUP_TABLE), VECTORS, NORMALS,
//     TENSORS, TENSORS6, TEXTURE_COORDINATES, COLOR_SCALARS, GLOBAL_IDS, PEDIGREE_IDS, EDGE_FLAGS,
//     TANGENTS, RATIONAL_WEIGHTS, HIGHER_ORDER_DEGREES and FIELD arrays, all into
//     MeshData::point_data / cell_data (rows: components); LOOKUP_TABLE data, dataset-level FIELD
//     data (e.g. TIME), string arrays (which a matrix of numbers cannot hold) and METADATA blocks
//     are skipped.
// Keywords are case-insensitive, values may be spread over lines in any way, as in VTK's reader.
// BINARY files are rejected with an IoError. Malformed input throws IoError "file:line: what was
// expected"; a cell of another type than E "file: cell 12 has VTK type 5, expected 10 (Tet4)".
#include <plastifem/mesh/io/vtu.hpp>  // MeshData, detail::TextScanner, assemble_mesh

#include <cmath>

namespace plastifem::io {
namespace detail {

class LegacyVtkParser {
 public:
  LegacyVtkParser(std::string path, std::string text) : s_(std::move(path), std::move(text)) {}

  template <FiniteElement E>
  MeshData<E> parse() {
    std::string_view line;
    if (!s_.line(line) || trim(line).substr(0, 22) != "# vtk DataFile Version")
      s_.fail_at(1, "expected '# vtk DataFile Version x.x' (is this a legacy .vtk file?)");
    if (!s_.line(line)) s_.fail("expected a title line, got end of file");
    const std::string_view format = token("ASCII or BINARY");
    if (iequals(format, "BINARY"))
      s_.fail("BINARY legacy .vtk files are not supported; save the data as ASCII, or as .vtu (ParaView: File > "
              "Save Data, 'VTK UnstructuredGrid Files')");
    if (!iequals(format, "ASCII")) s_.fail(fmt::format("expected ASCII or BINARY, got {}", show(format)));
    if (!iequals(token("DATASET"), "DATASET")) s_.fail(fmt::format("expected DATASET, got {}", show(last_)));
    if (!iequals(token("a dataset type"), "UNSTRUCTURED_GRID"))
      s_.fail(fmt::format("expected DATASET UNSTRUCTURED_GRID, got {} (only unstructured grids are read)", show(last_)));

    std::optional<std::vector<double>> points;
    std::optional<size_t> num_types;  // each type is checked as it is read: only the count is kept
    std::vector<std::int64_t> ends, connectivity;  // cell i: connectivity[ends[i-1] .. ends[i])
    std::vector<size_t> cell_lines;
    bool have_cells = false;
    size_t types_line = 0, cells_line = 0;
    MeshData<E> data;
    std::map<std::string, Eigen::MatrixXd>* target = nullptr;  // POINT_DATA or CELL_DATA
    size_t target_n = 0;
    const char* target_name = "";

    std::string_view kw;
    while (s_.token(kw)) {
      if (iequals(kw, "POINTS")) {
        if (points) s_.fail("a second POINTS section");
        const size_t n = count("the number of points");
        token("the point data type");
        points = values<double>(3 * n, "POINTS", true);
      } else if (iequals(kw, "CELLS")) {
        if (have_cells) s_.fail("a second CELLS section");
        have_cells = true;
        const size_t line_no = cells_line = s_.line_number();
        const size_t a = count("the number of cells"), b = count("the size of the cell list");
        const auto look = s_.save();
        std::string_view next;
        if (s_.token(next) && iequals(next, "OFFSETS")) {  // file version 5.1
          token("the offsets data type");
          std::vector<std::int64_t> offsets = values<std::int64_t>(a, "OFFSETS");
          if (!iequals(token("CONNECTIVITY"), "CONNECTIVITY")) s_.fail(fmt::format("expected CONNECTIVITY, got {}", show(last_)));
          token("the connectivity data type");
          connectivity = values<std::int64_t>(b, "CONNECTIVITY");
          if (!offsets.empty() && offsets[0] != 0) s_.fail_at(line_no, fmt::format("expected OFFSETS to start at 0, got {}", offsets[0]));
          for (size_t c = 1; c < offsets.size(); ++c)
            if (offsets[c] < offsets[c - 1] || offsets[c] > static_cast<std::int64_t>(b))
              s_.fail_at(line_no, fmt::format("OFFSETS entry {} is {}: offsets must increase up to {}", c, offsets[c], b));
          if (!offsets.empty() && offsets.back() != static_cast<std::int64_t>(b))
            s_.fail_at(line_no, fmt::format("the last offset is {}, expected {} (the connectivity size)", offsets.back(), b));
          if (!offsets.empty()) ends.assign(offsets.begin() + 1, offsets.end());
          cell_lines.assign(1, line_no);
        } else {  // classic: "k i_1 ... i_k" per cell, b numbers in all
          s_.restore(look);
          size_t used = 0;
          for (size_t c = 0; c < a; ++c) {
            const size_t k = count("the node count of a cell");
            cell_lines.push_back(s_.line_number());
            used += 1 + k;
            if (used > b) s_.fail(fmt::format("cell {} overruns the CELLS size {} (cell list of {} numbers)", c, b, used));
            const auto ids = values<std::int64_t>(k, fmt::format("cell {}", c));
            connectivity.insert(connectivity.end(), ids.begin(), ids.end());
            ends.push_back(static_cast<std::int64_t>(connectivity.size()));
          }
          if (used != b) s_.fail_at(line_no, fmt::format("CELLS announces a list of {} numbers, its {} cells hold {}", b, a, used));
        }
      } else if (iequals(kw, "CELL_TYPES")) {
        if (num_types) s_.fail("a second CELL_TYPES section");
        types_line = s_.line_number();
        const size_t n = count("the number of cell types");
        for (size_t c = 0; c < n; ++c)  // checked as read, so the error has the value's line
          if (const auto why = wrong_cell_type<E>(c, value<std::int64_t>(c, n, "CELL_TYPES"))) s_.fail(*why);
        num_types = n;
      } else if (iequals(kw, "POINT_DATA") || iequals(kw, "CELL_DATA")) {
        const bool point = iequals(kw, "POINT_DATA");
        target_n = count("the number of values");
        const size_t expected = point ? (points ? points->size() / 3 : 0) : ends.size();
        if (point ? !points : !have_cells) s_.fail(fmt::format("{} before {}", kw, point ? "POINTS" : "CELLS"));
        if (target_n != expected)
          s_.fail(fmt::format("{} {} does not match the {} {}", kw, target_n, expected, point ? "points" : "cells"));
        target = point ? &data.point_data : &data.cell_data;
        target_name = point ? "POINT_DATA" : "CELL_DATA";
      } else if (iequals(kw, "METADATA")) {
        skip_metadata_block();
      } else if (iequals(kw, "FIELD")) {
        const std::string name = decode_name(token("a field name"));
        const size_t arrays = count("the number of arrays");
        for (size_t i = 0; i < arrays; ++i) {
          skip_metadata();  // VTK 9 writes one after each array
          const std::string array = decode_name(token("an array name"));
          if (array == "NULL_ARRAY") continue;
          const size_t comps = count("the number of components"), tuples = count("the number of tuples");
          if (comps == 0 || comps > 1000) s_.fail(fmt::format("expected 1 to 1000 components, got {}", comps));
          if (target && tuples != target_n)
            s_.fail(fmt::format("FIELD array '{}' of {} has {} tuples, expected {}", array, target_name, tuples, target_n));
          const std::string_view type = token("the array data type");
          if (skip_text_values(type, comps * tuples)) continue;  // strings: not numeric data
          auto v = values<double>(comps * tuples, fmt::format("FIELD array '{}'", array));
          // Dataset-level FIELD data (e.g. TIME) belongs to no points or cells: skipped.
          if (target) store(*target, array, comps, std::move(v));
        }
      } else if (iequals(kw, "LOOKUP_TABLE")) {  // a table's colours: not needed
        token("a lookup table name");
        values<double>(4 * count("the lookup table size"), "LOOKUP_TABLE");
      } else {
        const size_t comps = attribute_components(kw);
        if (comps == 0)
          s_.fail(fmt::format("expected a keyword such as POINTS, CELLS, CELL_TYPES, POINT_DATA, CELL_DATA, SCALARS, "
                              "VECTORS or FIELD, got {}",
                              show(kw)));
        if (!target) s_.fail(fmt::format("{} before POINT_DATA or CELL_DATA", kw));
        const std::string name = decode_name(token("an array name"));
        size_t n = comps;
        if (iequals(kw, "TEXTURE_COORDINATES")) {
          n = count("the texture dimension");
          token("the data type");
        } else if (iequals(kw, "COLOR_SCALARS")) {
          n = count("the number of colour components");
        } else if (iequals(kw, "SCALARS")) {
          token("the data type");
          // "SCALARS name type [numComp]": like VTK, take numComp only from the same line.
          std::string_view rest;
          s_.line(rest);
          const auto extra = split(rest);
          long long c = 1;
          if (extra.size() > 1 || (extra.size() == 1 && (!parse_number(extra[0], c) || c < 1 || c > 4)))
            s_.fail(fmt::format("expected 'SCALARS name type [numComp]' with numComp 1 to 4, got {}", show(trim(rest))));
          n = static_cast<size_t>(c);
          const auto look = s_.save();  // LOOKUP_TABLE is optional here, as in VTK's reader
          std::string_view next;
          if (s_.token(next) && iequals(next, "LOOKUP_TABLE")) token("a lookup table name");
          else s_.restore(look);
        } else if (skip_text_values(token("the data type"), n * target_n)) {
          continue;  // string ids (PEDIGREE_IDS): not numeric data
        }
        if (n == 0 || n > 1000) s_.fail(fmt::format("expected 1 to 1000 components, got {}", n));
        store(*target, name, n, values<double>(n * target_n, fmt::format("{} '{}' of {}", kw, name, target_name)));
      }
    }
    if (!points) s_.fail("expected POINTS, got end of file");
    if (!have_cells) s_.fail("expected CELLS, got end of file");
    if (!num_types) s_.fail("expected CELL_TYPES, got end of file");
    if (*num_types != ends.size())
      s_.fail_at(types_line, fmt::format("CELL_TYPES lists {} cells, CELLS {}", *num_types, ends.size()));
    if (ends.empty())  // a Mesh needs elements; say so with the file's name rather than as a MeshError
      s_.fail_at(cells_line, fmt::format("CELLS lists no cells ({} points): no mesh to read", points->size() / 3));
    const Index np = static_cast<Index>(points->size() / 3);
    Eigen::Matrix3Xd nodes(3, np);
    std::copy(points->begin(), points->end(), nodes.data());
    data.mesh = assemble_mesh<E>(s_.path(), std::move(nodes), ends, connectivity, cell_lines);
    return data;
  }

 private:
  std::string_view token(const char* what) {
    if (!s_.token(last_)) s_.fail(fmt::format("expected {}, got end of file", what));
    return last_;
  }
  size_t count(const char* what) {
    long long n = 0;
    const std::string_view t = token(what);
    if (!parse_number(t, n) || n < 0 || n > (1ll << 40))
      s_.fail(fmt::format("expected {} (a count >= 0), got {}", what, show(t)));
    return static_cast<size_t>(n);
  }
  /// Value i of n for `what`; `finite`: refuse nan and inf (coordinates), which parse_number reads.
  template <class T>
  T value(size_t i, size_t n, const std::string& what, bool finite = false) {
    std::string_view t;
    if (!s_.token(t)) s_.fail(fmt::format("expected {} values for {}, got end of file after {}", n, what, i));
    T x{};
    if (!parse_number(t, x))
      s_.fail(fmt::format("expected {} (value {} of {} for {}), got {}", std::is_integral_v<T> ? "an integer" : "a number",
                          i + 1, n, what, show(t)));
    if constexpr (std::is_floating_point_v<T>)
      if (finite && !std::isfinite(x))
        s_.fail(fmt::format("expected a finite number (value {} of {} for {}), got {}", i + 1, n, what, show(t)));
    return x;
  }
  /// n numbers, as value().
  template <class T>
  std::vector<T> values(size_t n, const std::string& what, bool finite = false) {
    std::vector<T> v;
    v.reserve(std::min<size_t>(n, 1u << 20));  // n comes from the file: do not trust it with memory
    for (size_t i = 0; i < n; ++i) v.push_back(value<T>(i, n, what, finite));
    return v;
  }
  /// Skips n values of a non-numeric array type and says so (false for a numeric type, whose
  /// values are then still to be read): VTK writes strings one per line (their spaces as %20;
  /// a line may be empty), variants as 'type value' pairs.
  bool skip_text_values(std::string_view type, size_t n) {
    std::string_view rest;
    if (iequals(type, "string") || iequals(type, "utf8_string")) {
      s_.line(rest);  // the end of the header line
      for (size_t i = 0; i < n; ++i)
        if (!s_.line(rest)) s_.fail(fmt::format("expected {} strings, got end of file after {}", n, i));
      return true;
    }
    if (iequals(type, "variant")) {
      for (size_t i = 0; i < 2 * n; ++i)
        if (!s_.token(rest)) s_.fail(fmt::format("expected {} variant values, got end of file", n));
      return true;
    }
    return false;
  }
  /// METADATA (information keys, VTK >= 9) runs from its keyword to the next blank line.
  void skip_metadata_block() {
    std::string_view rest;
    s_.line(rest);
    while (s_.line(rest) && !trim(rest).empty()) {
    }
  }
  void skip_metadata() {
    const auto look = s_.save();
    std::string_view next;
    if (s_.token(next) && iequals(next, "METADATA")) skip_metadata_block();
    else s_.restore(look);
  }
  /// Components of a data attribute keyword; 0 if `kw` is none. The per-keyword count is refined
  /// by the caller where the file gives it (SCALARS, TEXTURE_COORDINATES, COLOR_SCALARS).
  static size_t attribute_components(std::string_view kw) {
    if (iequals(kw, "SCALARS") || iequals(kw, "TEXTURE_COORDINATES") || iequals(kw, "COLOR_SCALARS")) return 1;
    if (iequals(kw, "GLOBAL_IDS") || iequals(kw, "PEDIGREE_IDS") || iequals(kw, "EDGE_FLAGS") ||
        iequals(kw, "RATIONAL_WEIGHTS"))
      return 1;
    if (iequals(kw, "VECTORS") || iequals(kw, "NORMALS") || iequals(kw, "TANGENTS") || iequals(kw, "HIGHER_ORDER_DEGREES"))
      return 3;
    if (iequals(kw, "TENSORS")) return 9;
    if (iequals(kw, "TENSORS6")) return 6;
    return 0;
  }
  /// VTK writes special characters of array names as %XX.
  static std::string decode_name(std::string_view s) {
    std::string out;
    for (size_t i = 0; i < s.size(); ++i) {
      unsigned v = 0;
      if (s[i] == '%' && i + 2 < s.size() && std::from_chars(s.data() + i + 1, s.data() + i + 3, v, 16).ptr == s.data() + i + 3) {
        out += static_cast<char>(v);
        i += 2;
      } else {
        out += s[i];
      }
    }
    return out;
  }
  void store(std::map<std::string, Eigen::MatrixXd>& target, const std::string& name, size_t comps, std::vector<double> v) {
    if (target.count(name)) s_.fail(fmt::format("a second array named '{}'", name));
    Eigen::MatrixXd m(static_cast<Eigen::Index>(comps), static_cast<Eigen::Index>(v.size() / comps));
    std::copy(v.begin(), v.end(), m.data());
    target.emplace(name, std::move(m));
  }

  TextScanner s_;
  std::string_view last_;
};

}  // namespace detail

/// read_vtk_legacy of a file's contents held in memory; `file_name` is the name error
/// messages give ("file_name:line: what was expected").
template <FiniteElement E>
MeshData<E> read_vtk_legacy_string(std::string text, const std::string& file_name = "<string>",
                                   const ReadOptions& options = {}) {
  detail::LegacyVtkParser parser(file_name, std::move(text));
  MeshData<E> data = parser.parse<E>();
  if (options.drop_unused_nodes) detail::drop_unused_points(data);
  return data;
}

/// Reads an ASCII legacy .vtk UNSTRUCTURED_GRID of E cells with its point and cell data. Throws
/// IoError on malformed input ("file:line: what was expected"), a cell of another type or a file
/// without cells; the mesh constructor's MeshError (inverted element, ...) names the file.
template <FiniteElement E>
MeshData<E> read_vtk_legacy(const std::filesystem::path& file, const ReadOptions& options = {}) {
  return read_vtk_legacy_string<E>(detail::read_file(file), file.string(), options);
}

}  // namespace plastifem::io
