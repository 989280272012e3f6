#pragma once
// Gmsh mesh files (.msh), ASCII formats 2.2 and 4.1.
//
// Reference: Gmsh reference manual, section "MSH file format" (4.1) and its appendix "MSH file
// format version 2 (Legacy)". What is read:
//   - $MeshFormat (version 2.2 or 4.1, ASCII only), $PhysicalNames, $Entities (4.1), $Nodes,
//     $Elements; any other section ($Periodic, $NodeData, ...) is skipped.
//   - Nodes: renumbered 0..n-1 in the order of the file, whatever their tags (4.1 tags may be
//     sparse and spread over entity blocks). Nodes no volume element uses are KEPT by default, so
//     that every node of the file has an index; the mesh lists them in report().unused_nodes.
//   - Volume elements: all must be of E's type (E::gmsh_type: Tet4 4, Tet10 11, Hex8 5, Wedge6 6); another
//     volume type is an error, lower-dimensional elements are only used for physical groups.
//     Nodes are taken into plastifem's (VTK's) order by E::gmsh_nodes: Gmsh's Tet10 numbers its
//     last two mid-edge nodes the other way round (Gmsh node 8 is on edge (2,3), node 9 on edge
//     (1,3)), and its prism's bottom triangle the other way round.
//   - A volume element listed several times is one element: lines with its tag, or with its
//     nodes in the same order, are merged and their groups all kept. 2.2 lists an element once
//     per physical group (Gmsh's writer under a new tag each time, other tools under the same
//     tag); 4.1 lists it once, in its entity's block, with the entity's groups in $Entities, but
//     converted files may still repeat it.
//   - Physical groups (2.2: the element's first tag; 4.1: the physical tags of its entity in
//     $Entities): each becomes a node set (all nodes of its elements), named by $PhysicalNames or
//     "physical_<tag>". Groups of different dimensions with the same name share one set. A 2D
//     group (triangles, quadrangles) also becomes a face set: each surface element is matched by
//     its corner nodes to a boundary face of the volume mesh. A surface element on a face inside
//     the mesh (an interface between two volumes) is in the node set only: a face set holds
//     boundary faces, where tractions act (a group of interior faces alone has no face set). A
//     surface element that is no face of the mesh at all is an error.
//   - ReadOptions{.drop_unused_nodes = true} removes the nodes no volume element uses (geometry
//     points, nodes of surface elements only); node sets lose them.
// Malformed input throws IoError "file:line: what was expected"; the mesh constructor's
// MeshError (inverted element, ...) propagates with the file's name before its message.
#include <plastifem/mesh/io/vtu.hpp>  // detail::TextScanner, parse_number
#include <plastifem/mesh/selection.hpp>

#include <cmath>
#include <set>
#include <tuple>
#include <unordered_map>

namespace plastifem::io {
namespace detail {

struct GmshTypeInfo {
  int nodes, dim;
  const char* name;
};

/// Gmsh element types (Gmsh manual, "MSH file format": elm-type list).
inline std::optional<GmshTypeInfo> gmsh_type_info(int type) {
  static const std::map<int, GmshTypeInfo> table{
      {1, {2, 1, "2-node line"}},           {2, {3, 2, "3-node triangle"}},       {3, {4, 2, "4-node quadrangle"}},
      {4, {4, 3, "4-node tetrahedron"}},    {5, {8, 3, "8-node hexahedron"}},     {6, {6, 3, "6-node prism"}},
      {7, {5, 3, "5-node pyramid"}},        {8, {3, 1, "3-node line"}},           {9, {6, 2, "6-node triangle"}},
      {10, {9, 2, "9-node quadrangle"}},    {11, {10, 3, "10-node tetrahedron"}}, {12, {27, 3, "27-node hexahedron"}},
      {13, {18, 3, "18-node prism"}},       {14, {14, 3, "14-node pyramid"}},     {15, {1, 0, "point"}},
      {16, {8, 2, "8-node quadrangle"}},    {17, {20, 3, "20-node hexahedron"}},  {18, {15, 3, "15-node prism"}},
      {19, {13, 3, "13-node pyramid"}},     {20, {9, 2, "9-node triangle"}},      {21, {10, 2, "10-node triangle"}},
      {22, {12, 2, "12-node triangle"}},    {23, {15, 2, "15-node triangle"}},    {24, {15, 2, "15-node triangle"}},
      {25, {21, 2, "21-node triangle"}},    {26, {4, 1, "4-node line"}},          {27, {5, 1, "5-node line"}},
      {28, {6, 1, "6-node line"}},          {29, {20, 3, "20-node tetrahedron"}}, {30, {35, 3, "35-node tetrahedron"}},
      {31, {56, 3, "56-node tetrahedron"}}, {92, {64, 3, "64-node hexahedron"}},  {93, {125, 3, "125-node hexahedron"}}};
  const auto it = table.find(type);
  if (it == table.end()) return std::nullopt;
  return it->second;
}

/// Corner count of a surface element type (its corners come first): 3, 4, or 0 if not a
/// triangle or quadrangle of a known type.
inline int gmsh_surface_corners(int type) {
  switch (type) {
    case 2: case 9: case 20: case 21: case 22: case 23: case 24: case 25: return 3;
    case 3: case 10: case 16: return 4;
    default: return 0;
  }
}

/// Whether some face of E has `corners` corners.
template <FiniteElement E>
constexpr bool has_face_with_corners(int corners) {
  for (int f = 0; f < E::num_faces; ++f)
    if (face_corners(E::face_shape(f)) == corners) return true;
  return false;
}

/// The contents of a .msh file, before it becomes a Mesh.
struct GmshFile {
  struct Element {
    int type, dim;
    long long tag;
    size_t line;
    size_t first_node, num_nodes;  ///< range in node_tags
    int groups;                    ///< index in group_lists, -1: in no physical group
  };
  std::map<std::pair<int, int>, std::string> names;                 ///< (dim, physical tag) -> name
  std::map<std::pair<int, int>, std::vector<int>> entity_physicals;  ///< 4.1: (dim, entity) -> physical tags
  bool has_entities = false, has_nodes = false, has_elements = false;
  std::vector<double> xyz;
  std::unordered_map<long long, Index> node_index;  ///< file tag -> index
  std::vector<Element> elements;
  std::vector<long long> node_tags;
  std::vector<std::vector<int>> group_lists;  ///< physical tags shared by elements
  size_t elements_line = 0;
};

class GmshParser {
 public:
  GmshParser(std::string path, std::string text) : s_(std::move(path), std::move(text)) {}

  GmshFile parse() {
    std::string_view line;
    if (!s_.content_line(line)) s_.fail("expected $MeshFormat, got an empty file");
    if (line != "$MeshFormat") s_.fail(fmt::format("expected $MeshFormat (is this a Gmsh .msh file?), got {}", show(line)));
    parse_format();
    while (s_.content_line(line)) {
      if (line[0] != '$') s_.fail(fmt::format("expected a section header such as $Nodes, got {}", show(line)));
      const std::string_view name = line.substr(1);
      if (name == "PhysicalNames") parse_names();
      else if (name == "Entities" && v41_) parse_entities();
      else if (name == "Nodes") v41_ ? parse_nodes41() : parse_nodes22();
      else if (name == "Elements") v41_ ? parse_elements41() : parse_elements22();
      else if (name.substr(0, 3) == "End") s_.fail(fmt::format("unexpected {}: no such section is open", show(line)));
      else {
        partitioned_ = partitioned_ || name == "PartitionedEntities";
        skip_section(name);
      }
    }
    if (!f_.has_nodes) s_.fail("expected a $Nodes section, got end of file");
    if (!f_.has_elements) s_.fail("expected an $Elements section, got end of file");
    return std::move(f_);
  }

  [[noreturn]] void fail_at(size_t line, const std::string& what) const { s_.fail_at(line, what); }

 private:
  template <class T>
  T number(std::string_view tok, const char* what) {
    T v{};
    if (!parse_number(tok, v)) s_.fail(fmt::format("expected {}, got {}", what, show(tok)));
    return v;
  }
  size_t count(std::string_view tok, const char* what) {
    const long long n = number<long long>(tok, what);
    if (n < 0) s_.fail(fmt::format("expected {} (a count >= 0), got {}", what, n));
    return static_cast<size_t>(n);
  }

  /// The tokens of the next data line of `section`; `what` describes the expected line.
  std::vector<std::string_view> data_line(std::string_view section, const std::string& what) {
    std::string_view line;
    if (!s_.content_line(line)) s_.fail(fmt::format("expected {}, got end of file (no $End{})", what, section));
    if (line[0] == '$')
      s_.fail(fmt::format("expected {}, got {}: the section holds fewer entries than its header announces", what,
                          show(line)));
    return split(line);
  }
  void expect_size(const std::vector<std::string_view>& t, size_t n, const std::string& what) {
    if (t.size() != n) s_.fail(fmt::format("expected {} ({} numbers), got {}", what, n, t.size()));
  }
  void end_section(std::string_view section) {
    std::string_view line;
    if (!s_.content_line(line)) s_.fail(fmt::format("expected $End{}, got end of file", section));
    if (line.substr(0, 1) != "$" || line.substr(1) != fmt::format("End{}", section))
      s_.fail(fmt::format("expected $End{}, got {}{}", section, show(line),
                          line[0] == '$' ? "" : " (more entries than the section header announces?)"));
  }
  void skip_section(std::string_view name) {  // sections this reader does not need
    const std::string end = fmt::format("$End{}", name);
    const size_t start = s_.line_number();
    std::string_view line;
    while (s_.content_line(line))
      if (line == end) return;
    s_.fail_at(start, fmt::format("expected {} closing the section, got end of file", end));
  }

  void parse_format() {
    const auto t = data_line("MeshFormat", "'version file-type data-size'");
    expect_size(t, 3, "'version file-type data-size'");
    if (t[0] != "2.2" && t[0] != "4.1")
      s_.fail(fmt::format("unsupported MSH version {}: this reader takes ASCII 2.2 and 4.1 (Gmsh: File > Export, "
                          "'Version 4 ASCII' or 'Version 2 ASCII', or the option Mesh.MshFileVersion)",
                          show(t[0])));
    v41_ = t[0] == "4.1";
    if (t[1] == "1")
      s_.fail("binary MSH files are not supported; export the mesh as ASCII (Gmsh: File > Export with the binary "
              "option unchecked, or set the option Mesh.Binary = 0)");
    if (t[1] != "0") s_.fail(fmt::format("expected file-type 0 (ASCII), got {}", show(t[1])));
    end_section("MeshFormat");
  }

  void parse_names() {
    const auto h = data_line("PhysicalNames", "the number of physical names");
    expect_size(h, 1, "the number of physical names");
    const size_t n = count(h[0], "the number of physical names");
    for (size_t i = 0; i < n; ++i) {
      const auto t = data_line("PhysicalNames", "'dimension tag \"name\"'");
      if (t.size() < 3) s_.fail(fmt::format("expected 'dimension tag \"name\"', got {} tokens", t.size()));
      const int dim = number<int>(t[0], "a dimension"), tag = number<int>(t[1], "a physical tag");
      // The name is the rest of the line, quoted; it may contain spaces.
      std::string_view rest = trim(std::string_view(t[2].data(), static_cast<size_t>(t.back().data() + t.back().size() - t[2].data())));
      if (rest.size() < 2 || rest.front() != '"' || rest.back() != '"')
        s_.fail(fmt::format("expected a quoted physical name, got {}", show(rest)));
      f_.names[{dim, tag}] = std::string(rest.substr(1, rest.size() - 2));
    }
    end_section("PhysicalNames");
  }

  void parse_entities() {  // 4.1 only: which physical groups each geometric entity belongs to
    const auto h = data_line("Entities", "'numPoints numCurves numSurfaces numVolumes'");
    expect_size(h, 4, "'numPoints numCurves numSurfaces numVolumes'");
    f_.has_entities = true;
    for (int dim = 0; dim < 4; ++dim) {
      const size_t n = count(h[static_cast<size_t>(dim)], "an entity count");
      const char* what = dim == 0 ? "a point entity 'tag x y z numPhysicalTags physicalTag...'"
                                  : "an entity 'tag minX minY minZ maxX maxY maxZ numPhysicalTags physicalTag... "
                                    "numBounding boundingTag...'";
      for (size_t i = 0; i < n; ++i) {
        const auto t = data_line("Entities", what);
        const size_t at = dim == 0 ? 4 : 7;  // index of numPhysicalTags
        if (t.size() <= at) s_.fail(fmt::format("expected {}, got {} tokens", what, t.size()));
        const int tag = number<int>(t[0], "an entity tag");
        for (size_t k = 1; k < at; ++k) number<double>(t[k], "a coordinate");
        const size_t np = count(t[at], "numPhysicalTags");
        if (t.size() < at + 1 + np) s_.fail(fmt::format("expected {} physical tags, got {}", np, t.size() - at - 1));
        std::vector<int> phys;
        for (size_t k = 0; k < np; ++k) phys.push_back(number<int>(t[at + 1 + k], "a physical tag"));
        size_t expected = at + 1 + np;
        if (dim > 0) {
          if (t.size() <= expected) s_.fail(fmt::format("expected {}, got {} tokens", what, t.size()));
          expected += 1 + count(t[expected], "the number of bounding entities");
        }
        if (t.size() != expected) s_.fail(fmt::format("expected {} tokens for {}, got {}", expected, what, t.size()));
        std::sort(phys.begin(), phys.end());  // a tag listed twice is one group
        phys.erase(std::unique(phys.begin(), phys.end()), phys.end());
        f_.entity_physicals[{dim, tag}] = std::move(phys);
      }
    }
    end_section("Entities");
  }

  void add_node(std::string_view tag_tok, std::string_view x, std::string_view y, std::string_view z) {
    const long long tag = number<long long>(tag_tok, "a node tag");
    const Index index = static_cast<Index>(f_.xyz.size() / 3);
    if (!f_.node_index.emplace(tag, index).second) s_.fail(fmt::format("node tag {} appears twice", tag));
    if (index == std::numeric_limits<Index>::max()) s_.fail("too many nodes");
    for (auto c : {x, y, z}) {
      const double v = number<double>(c, "a coordinate");  // from_chars reads nan and inf too
      if (!std::isfinite(v)) s_.fail(fmt::format("node {} has a non-finite coordinate, {}", tag, c));
      f_.xyz.push_back(v);
    }
  }

  void begin_unique(bool& seen, const char* name) {
    if (seen) s_.fail(fmt::format("a second ${} section (only one is supported)", name));
    seen = true;
  }

  void parse_nodes22() {
    begin_unique(f_.has_nodes, "Nodes");
    const auto h = data_line("Nodes", "the number of nodes");
    expect_size(h, 1, "the number of nodes");
    const size_t n = count(h[0], "the number of nodes");
    for (size_t i = 0; i < n; ++i) {
      const auto t = data_line("Nodes", fmt::format("node {} of {} 'tag x y z'", i + 1, n));
      expect_size(t, 4, "a node 'tag x y z'");
      add_node(t[0], t[1], t[2], t[3]);
    }
    end_section("Nodes");
  }

  void parse_nodes41() {
    begin_unique(f_.has_nodes, "Nodes");
    const char* header = "'numEntityBlocks numNodes minNodeTag maxNodeTag'";
    const auto h = data_line("Nodes", header);
    expect_size(h, 4, header);
    const size_t header_line = s_.line_number();
    const size_t blocks = count(h[0], "numEntityBlocks"), n = count(h[1], "numNodes");
    for (size_t k = 2; k < 4; ++k) number<long long>(h[k], "a node tag");
    size_t total = 0;
    for (size_t b = 0; b < blocks; ++b) {
      const char* bh = "a node block header 'entityDim entityTag parametric numNodesInBlock'";
      const auto t = data_line("Nodes", bh);
      expect_size(t, 4, bh);
      const int dim = number<int>(t[0], "an entity dimension");
      number<int>(t[1], "an entity tag");
      const int parametric = number<int>(t[2], "parametric (0 or 1)");
      if (dim < 0 || dim > 3 || (parametric != 0 && parametric != 1))
        s_.fail(fmt::format("expected entityDim in 0..3 and parametric 0 or 1, got {} and {}", dim, parametric));
      const size_t m = count(t[3], "numNodesInBlock");
      // Tags first, one per line, then the coordinates (plus u, v, w for parametric nodes).
      std::vector<std::string_view> tags;
      for (size_t i = 0; i < m; ++i) {
        const auto tt = data_line("Nodes", fmt::format("node tag {} of {} in this block", i + 1, m));
        expect_size(tt, 1, "a node tag");
        tags.push_back(tt[0]);
      }
      const size_t values = 3 + (parametric ? static_cast<size_t>(dim) : 0);
      for (size_t i = 0; i < m; ++i) {
        const auto c = data_line("Nodes", fmt::format("the coordinates of node {} of {} in this block", i + 1, m));
        expect_size(c, values, parametric ? "'x y z' and the parametric coordinates" : "coordinates 'x y z'");
        add_node(tags[i], c[0], c[1], c[2]);
      }
      total += m;
    }
    if (total != n) s_.fail_at(header_line, fmt::format("the $Nodes header announces {} nodes, its blocks hold {}", n, total));
    end_section("Nodes");
  }

  void add_element(int type, int dim, long long tag, const std::vector<std::string_view>& t, size_t first, int groups) {
    GmshFile::Element el{type, dim, tag, s_.line_number(), f_.node_tags.size(), t.size() - first, groups};
    for (size_t k = first; k < t.size(); ++k) f_.node_tags.push_back(number<long long>(t[k], "a node tag"));
    f_.elements.push_back(el);
  }

  void parse_elements22() {
    begin_unique(f_.has_elements, "Elements");
    f_.elements_line = s_.line_number();
    const auto h = data_line("Elements", "the number of elements");
    expect_size(h, 1, "the number of elements");
    const size_t n = count(h[0], "the number of elements");
    std::map<int, int> list_of;  // physical tag -> index in group_lists
    for (size_t i = 0; i < n; ++i) {
      const auto t = data_line("Elements", fmt::format("element {} of {} 'tag type numTags tags... nodes...'", i + 1, n));
      if (t.size() < 3) s_.fail(fmt::format("expected an element 'tag type numTags tags... nodes...', got {} tokens", t.size()));
      const long long tag = number<long long>(t[0], "an element tag");
      const int type = number<int>(t[1], "an element type");
      const size_t ntags = count(t[2], "the number of tags");
      const auto info = gmsh_type_info(type);
      if (!info) s_.fail(fmt::format("element {}: unknown Gmsh element type {}", tag, type));
      if (t.size() < 3 + ntags || t.size() - 3 - ntags != static_cast<size_t>(info->nodes))
        s_.fail(fmt::format("element {}: a {} (type {}) has {} tags and {} nodes, expected {} tokens, got {}", tag,
                            info->name, type, ntags, info->nodes, 3 + ntags + static_cast<size_t>(info->nodes), t.size()));
      // Tags: physical group, then elementary entity (then partitions); 0 = no physical group.
      const int physical = ntags > 0 ? number<int>(t[3], "a physical tag") : 0;
      for (size_t k = 4; k < 3 + ntags; ++k) number<long long>(t[k], "an element tag");
      int groups = -1;
      if (physical != 0) {
        auto [it, inserted] = list_of.try_emplace(physical, static_cast<int>(f_.group_lists.size()));
        if (inserted) f_.group_lists.push_back({physical});
        groups = it->second;
      }
      add_element(type, info->dim, tag, t, 3 + ntags, groups);
    }
    end_section("Elements");
  }

  void parse_elements41() {
    begin_unique(f_.has_elements, "Elements");
    f_.elements_line = s_.line_number();
    const char* header = "'numEntityBlocks numElements minElementTag maxElementTag'";
    const auto h = data_line("Elements", header);
    expect_size(h, 4, header);
    const size_t header_line = s_.line_number();
    const size_t blocks = count(h[0], "numEntityBlocks"), n = count(h[1], "numElements");
    for (size_t k = 2; k < 4; ++k) number<long long>(h[k], "an element tag");
    size_t total = 0;
    std::map<std::pair<int, int>, int> list_of;  // entity -> index in group_lists: one list per entity
    for (size_t b = 0; b < blocks; ++b) {
      const char* bh = "an element block header 'entityDim entityTag elementType numElementsInBlock'";
      const auto t = data_line("Elements", bh);
      expect_size(t, 4, bh);
      const int dim = number<int>(t[0], "an entity dimension"), entity = number<int>(t[1], "an entity tag");
      const int type = number<int>(t[2], "an element type");
      const size_t m = count(t[3], "numElementsInBlock");
      if (dim < 0 || dim > 3) s_.fail(fmt::format("expected entityDim in 0..3, got {}", dim));
      int groups = -1;
      if (f_.has_entities) {
        const auto it = f_.entity_physicals.find({dim, entity});
        if (it == f_.entity_physicals.end())
          s_.fail(fmt::format("element block of entity (dim {}, tag {}), which $Entities does not list{}", dim, entity,
                              partitioned_ ? " (a partitioned file, whose blocks belong to $PartitionedEntities: "
                                             "save the mesh without partitions, or as format 2.2)"
                                           : ""));
        if (!it->second.empty()) {
          auto [at, inserted] = list_of.try_emplace({dim, entity}, static_cast<int>(f_.group_lists.size()));
          if (inserted) f_.group_lists.push_back(it->second);
          groups = at->second;
        }
      }
      const auto info = gmsh_type_info(type);
      // A block's entityDim decides whether its elements are cells or boundary parts: a known
      // type of another dimension would be skipped (or taken as a face) silently.
      if (info && info->dim != dim)
        s_.fail(fmt::format("element block of entity dimension {} holds {} elements (Gmsh type {}), which are {}D",
                            dim, info->name, type, info->dim));
      for (size_t i = 0; i < m; ++i) {
        const auto e = data_line("Elements", fmt::format("element {} of {} in this block 'tag nodes...'", i + 1, m));
        if (e.size() < 2 || (info && e.size() != 1 + static_cast<size_t>(info->nodes)))
          s_.fail(fmt::format("expected an element 'tag nodes...'{}, got {} tokens",
                              info ? fmt::format(" of a {} ({} tokens)", info->name, 1 + info->nodes) : "", e.size()));
        add_element(type, dim, number<long long>(e[0], "an element tag"), e, 1, groups);
      }
      total += m;
    }
    if (total != n) s_.fail_at(header_line, fmt::format("the $Elements header announces {} elements, its blocks hold {}", n, total));
    end_section("Elements");
  }

  TextScanner s_;
  GmshFile f_;
  bool v41_ = false;
  bool partitioned_ = false;  ///< a $PartitionedEntities section was seen (4.1)
};

}  // namespace detail

/// read_gmsh of a file's contents held in memory; `file_name` is the name error messages give
/// ("file_name:line: what was expected").
template <FiniteElement E>
Mesh<E> read_gmsh_string(std::string text, const std::string& file_name = "<string>",
                         const ReadOptions& options = {}) {
  detail::GmshParser parser(file_name, std::move(text));
  const detail::GmshFile f = parser.parse();
  using Element = detail::GmshFile::Element;
  constexpr int want = E::gmsh_type;

  auto node = [&](const Element& el, size_t k) -> Index {
    const long long tag = f.node_tags[el.first_node + k];
    const auto it = f.node_index.find(tag);
    if (it == f.node_index.end())
      parser.fail_at(el.line, fmt::format("element {} refers to node {}, which is not in $Nodes", el.tag, tag));
    return it->second;
  };
  // Format 2.2 lists an element once per physical group it is in: Gmsh's own writer gives each
  // copy a new element tag, other tools repeat the tag. Either way (a repeated tag, or the same
  // nodes in the same order) it is one element, kept once; every copy still counts for its group
  // below. A repeated tag over other nodes, or the same nodes in another order, is refused here
  // with both lines (Mesh would refuse the duplicate without them).
  using Connectivity = typename Mesh<E>::Connectivity;
  std::vector<Connectivity> cells;
  std::vector<const Element*> first_line;              // per cell: the element that defined it
  std::unordered_map<long long, size_t> cell_of_tag;   // element tag -> cell
  std::map<Connectivity, size_t> cell_of_nodes;        // sorted node indices -> cell
  for (const Element& el : f.elements) {
    for (size_t k = 0; k < el.num_nodes; ++k) node(el, k);  // every reference must resolve
    if (el.dim != 3) continue;
    if (el.type != want) {
      const auto info = detail::gmsh_type_info(el.type);
      parser.fail_at(el.line, fmt::format("element {} is a {} (Gmsh type {}), but a Mesh<{}> takes only {} elements "
                                          "(type {})",
                                          el.tag, info ? info->name : "volume element", el.type, E::name,
                                          detail::gmsh_type_info(want)->name, want));
    }
    Connectivity c;
    for (int k = 0; k < E::num_nodes; ++k)  // into VTK's order (Tet10's last two, Wedge6's triangles)
      c[static_cast<size_t>(k)] = node(el, static_cast<size_t>(E::gmsh_nodes[static_cast<size_t>(k)]));
    Connectivity sorted = c;
    std::sort(sorted.begin(), sorted.end());
    const auto by_tag = cell_of_tag.find(el.tag);
    const auto by_nodes = cell_of_nodes.find(sorted);
    if (by_tag != cell_of_tag.end() || by_nodes != cell_of_nodes.end()) {
      const size_t first = by_tag != cell_of_tag.end() ? by_tag->second : by_nodes->second;
      if (cells[first] == c) continue;  // a copy for another physical group
      const Element& other = *first_line[first];
      if (by_tag != cell_of_tag.end())
        parser.fail_at(el.line, fmt::format("element tag {} appears twice with different nodes (first on line {})",
                                            el.tag, other.line));
      parser.fail_at(el.line, fmt::format("element {} has the nodes of element {} (line {}) in another order: a "
                                          "duplicated element would count its mass and stiffness twice",
                                          el.tag, other.tag, other.line));
    }
    cell_of_tag.emplace(el.tag, cells.size());
    cell_of_nodes.emplace(sorted, cells.size());
    first_line.push_back(&el);
    cells.push_back(c);
  }
  if (cells.empty())
    parser.fail_at(f.elements_line, fmt::format("no {} elements (Gmsh type {}) in $Elements", E::name, want));
  Eigen::Matrix3Xd nodes(3, static_cast<Index>(f.xyz.size() / 3));
  std::copy(f.xyz.begin(), f.xyz.end(), nodes.data());
  Mesh<E> mesh = detail::mesh_from_file<E>(file_name, std::move(nodes), std::move(cells));

  // Physical groups: (dim, tag) -> elements.
  std::map<std::pair<int, int>, std::vector<const Element*>> groups;
  for (const Element& el : f.elements)
    if (el.groups >= 0)
      for (int phys : f.group_lists[static_cast<size_t>(el.groups)]) groups[{el.dim, phys}].push_back(&el);
  // Boundary faces by their sorted corner nodes (padded with -1 to four).
  using Key = std::array<Index, 4>;
  std::map<Key, FaceRef> faces;
  if (std::any_of(groups.begin(), groups.end(), [](const auto& g) { return g.first.first == 2; }))
    for (const FaceRef& fr : boundary_faces(mesh)) {
      const auto ids = mesh.face_nodes(fr);
      Key k{-1, -1, -1, -1};
      std::copy_n(ids.begin(), face_corners(ids.shape), k.begin());
      std::sort(k.begin(), k.end());
      faces.emplace(k, fr);
    }
  // Every face of the mesh, boundary or not, by the same key: built only if a surface element
  // matches no boundary face, to tell a face inside the mesh (an interface between two volumes)
  // from no face at all.
  std::set<Key> all_faces;
  auto is_interior_face = [&](const Key& k) {
    if (all_faces.empty())
      for (Index e = 0; e < mesh.num_elements(); ++e)
        for (int fi = 0; fi < E::num_faces; ++fi) {
          const auto ids = mesh.face_nodes(FaceRef{e, fi});
          Key key{-1, -1, -1, -1};
          std::copy_n(ids.begin(), face_corners(ids.shape), key.begin());
          std::sort(key.begin(), key.end());
          all_faces.insert(key);
        }
    return all_faces.count(k) > 0;
  };
  std::map<std::string, std::vector<Index>> node_sets;
  std::map<std::string, std::vector<FaceRef>> face_sets;
  for (const auto& [key, members] : groups) {
    const auto [dim, tag] = key;
    const auto named = f.names.find(key);
    const std::string name = named != f.names.end() ? named->second : fmt::format("physical_{}", tag);
    std::vector<Index>& ns = node_sets[name];
    for (const Element* el : members)
      for (size_t k = 0; k < el->num_nodes; ++k) ns.push_back(node(*el, k));
    if (dim != 2) continue;
    std::vector<FaceRef> fs;
    for (const Element* el : members) {
      const int nc = detail::gmsh_surface_corners(el->type);
      if (nc == 0)
        parser.fail_at(el->line, fmt::format("surface element {} of physical group '{}' is a Gmsh type {}; only "
                                             "triangles and quadrangles can be matched to mesh faces",
                                             el->tag, name, el->type));
      Key k{-1, -1, -1, -1};
      for (int c = 0; c < nc; ++c) k[static_cast<size_t>(c)] = node(*el, static_cast<size_t>(c));
      std::sort(k.begin(), k.end());
      const auto it = faces.find(k);
      if (it == faces.end() && is_interior_face(k)) continue;  // inside the mesh: in the node set only
      if (it == faces.end())
        parser.fail_at(el->line, fmt::format("surface element {} of physical group '{}' matches no face of "
                                             "the {} mesh{}",
                                             el->tag, name, E::name,
                                             !detail::has_face_with_corners<E>(nc)
                                                 ? fmt::format(" (it has {} corners, a {} face has {})", nc, E::name,
                                                               face_corners(E::face_shape(0)))
                                                 : std::string()));
      fs.push_back(it->second);
    }
    if (!fs.empty()) {
      std::vector<FaceRef>& set = face_sets[name];
      set.insert(set.end(), fs.begin(), fs.end());
    }
  }
  for (auto& [name, ids] : node_sets) {
    std::sort(ids.begin(), ids.end());
    ids.erase(std::unique(ids.begin(), ids.end()), ids.end());
    mesh.add_node_set(name, std::move(ids));
  }
  for (auto& [name, fs] : face_sets) {
    std::sort(fs.begin(), fs.end(), [](FaceRef a, FaceRef b) { return std::tie(a.element, a.face) < std::tie(b.element, b.face); });
    fs.erase(std::unique(fs.begin(), fs.end()), fs.end());
    mesh.add_face_set(name, std::move(fs));
  }
  if (options.drop_unused_nodes) return drop_unused_nodes(mesh);
  return mesh;
}

/// Reads a Gmsh ASCII .msh file (format 2.2 or 4.1) of E volume elements, with its physical
/// groups as node sets and (2D groups) face sets. See the top of this file for the rules.
template <FiniteElement E>
Mesh<E> read_gmsh(const std::filesystem::path& file, const ReadOptions& options = {}) {
  return read_gmsh_string<E>(detail::read_file(file), file.string(), options);
}

}  // namespace plastifem::io
