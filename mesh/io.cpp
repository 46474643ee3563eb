/// @file io.cpp
/// Mesh file readers (Gmsh ASCII 2.2/4.1, TetGen .node/.ele, VTK .vtu, OFF, OBJ, STL) and the
/// Gmsh 2.2 writer. Text formats are read line by line so that every syntax error can name
/// "path:LINE: expected ..." in one line.
#include "mesh/io.hpp"

#include <algorithm>
#include <array>
#include <bit>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <iterator>
#include <optional>
#include <string>
#include <string_view>
#include <unordered_map>
#include <vector>

#include <fmt/format.h>
#include <vtkCellType.h>
#include <vtkIdList.h>
#include <vtkNew.h>
#include <vtkPoints.h>
#include <vtkUnstructuredGrid.h>
#include <vtkXMLUnstructuredGridReader.h>

#include "core/error.hpp"
#include "core/log.hpp"
#include "mesh/vtk_messages.hpp"

namespace fs = std::filesystem;

namespace tetfsi::mesh {

namespace {

// ---------------------------------------------------------------------------------------
// Small text helpers
// ---------------------------------------------------------------------------------------

std::string lower_extension(const fs::path& path) {
  std::string ext = path.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return ext;
}

/// Throw InputError "path: no such file" unless `path` is a readable regular file.
void require_file(const fs::path& path, const std::string& hint = "") {
  std::error_code ec;
  if (!fs::exists(path, ec)) {
    throw InputError(fmt::format("{}: no such file{}", path.string(), hint));
  }
  if (fs::is_directory(path, ec)) {
    throw InputError(fmt::format("{}: is a directory, not a mesh file", path.string()));
  }
}

/// Reads a text file line by line, splitting each line into whitespace-separated tokens,
/// and produces "path:LINE: expected ..." errors.
class LineReader {
 public:
  /// @param comment character that starts a comment to the end of the line ('\0': none)
  LineReader(const fs::path& path, char comment) : m_path(path.string()), m_comment(comment) {
    require_file(path);
    m_in.open(path, std::ios::binary);
    if (!m_in) throw InputError(fmt::format("{}: cannot open the file for reading", m_path));
    std::error_code ec;
    m_bytes = static_cast<long long>(fs::file_size(path, ec));
    if (ec) m_bytes = 0;
  }

  /// Read the next line (skipping blank and comment-only lines when `skip_blank`).
  /// Returns false at end of file.
  bool next(bool skip_blank = true) {
    while (std::getline(m_in, m_line)) {
      ++m_line_no;
      if (!m_line.empty() && m_line.back() == '\r') m_line.pop_back();
      if (m_comment != '\0') {
        const auto pos = m_line.find(m_comment);
        if (pos != std::string::npos) m_line.erase(pos);
      }
      split();
      if (!skip_blank || !m_tokens.empty()) return true;
    }
    m_tokens.clear();
    m_line.clear();
    return false;
  }

  /// Read the next line or fail with "expected <what>, got end of file".
  void require_next(std::string_view what) {
    if (!next()) {
      throw InputError(
          fmt::format("{}:{}: expected {}, got end of file", m_path, m_line_no + 1, what));
    }
  }

  const std::vector<std::string_view>& tokens() const { return m_tokens; }
  std::size_t size() const { return m_tokens.size(); }
  const std::string& line() const { return m_line; }
  int line_no() const { return m_line_no; }
  const std::string& path() const { return m_path; }

  /// Throw "path:LINE: expected <what>, got '<line>'".
  [[noreturn]] void fail(std::string_view what) const {
    std::string shown = m_line;
    if (shown.size() > 60) shown = shown.substr(0, 57) + "...";
    throw InputError(fmt::format("{}:{}: expected {}, got '{}'", m_path, m_line_no, what, shown));
  }
  /// Throw "path:LINE: <message>" (for semantic errors: unknown node tags and the like).
  [[noreturn]] void fail_msg(const std::string& message) const {
    throw InputError(fmt::format("{}:{}: {}", m_path, m_line_no, message));
  }

  /// Require at least n tokens on this line.
  void need(std::size_t n, std::string_view what) const {
    if (m_tokens.size() < n) fail(what);
  }

  long long integer(std::size_t i, std::string_view what) const {
    if (i >= m_tokens.size()) fail(what);
    long long v = 0;
    const auto t = m_tokens[i];
    const auto [p, ec] = std::from_chars(t.data(), t.data() + t.size(), v);
    if (ec != std::errc() || p != t.data() + t.size()) fail(what);
    return v;
  }

  /// Token i as a count of `items` announced by a header, each taking at least
  /// `min_bytes` bytes of the file: a negative count, or one the file is too small to hold,
  /// is an error naming the header (before anything is allocated for it).
  long long count(std::size_t i, std::string_view what, std::string_view items,
                  long long min_bytes) const {
    const long long n = integer(i, what);
    if (n < 0) fail_msg(fmt::format("{} is negative ({}); fix the header", what, n));
    if (n > m_bytes / std::max(1LL, min_bytes)) {
      fail_msg(fmt::format(
          "{} announces {} {}, but the whole file is {} bytes (each takes at least {}); fix the "
          "header",
          what, n, items, m_bytes, min_bytes));
    }
    return n;
  }

  double real(std::size_t i, std::string_view what) const {
    if (i >= m_tokens.size()) fail(what);
    const auto t = m_tokens[i];
    const char* b = t.data();
    if (*b == '+') ++b;  // from_chars rejects a leading '+'
    double v = 0.0;
    const auto [p, ec] = std::from_chars(b, t.data() + t.size(), v);
    if (ec != std::errc() || p != t.data() + t.size()) fail(what);
    return v;
  }

 private:
  void split() {
    m_tokens.clear();
    const char* s = m_line.data();
    const std::size_t n = m_line.size();
    std::size_t i = 0;
    while (i < n) {
      while (i < n && std::isspace(static_cast<unsigned char>(s[i]))) ++i;
      const std::size_t b = i;
      while (i < n && !std::isspace(static_cast<unsigned char>(s[i]))) ++i;
      if (i > b) m_tokens.emplace_back(s + b, i - b);
    }
  }

  std::string m_path;
  char m_comment;
  std::ifstream m_in;
  std::string m_line;
  std::vector<std::string_view> m_tokens;
  int m_line_no = 0;
  long long m_bytes = 0;  ///< the file's size
};

/// A volume mesh as read, with the file's own ids for messages.
struct RawVolume {
  std::vector<Vec3> points;
  std::vector<long long> point_ids;
  std::vector<Vec4i> tets;
  std::vector<long long> tet_ids;
};

/// Map from a file's node ids to zero-based indices; duplicate ids are errors.
class IdMap {
 public:
  void add(long long id, Index index, const LineReader& r, std::string_view what) {
    if (!m_map.emplace(id, index).second) {
      r.fail_msg(fmt::format("{} {} is defined twice", what, id));
    }
  }
  Index at(long long id, const LineReader& r, std::string_view what,
           std::string_view section) const {
    const auto it = m_map.find(id);
    if (it == m_map.end()) {
      r.fail_msg(fmt::format("{} refers to node {}, which {} does not define", what, id, section));
    }
    return it->second;
  }
  void reserve(std::size_t n) { m_map.reserve(n); }

 private:
  std::unordered_map<long long, Index> m_map;
};

// ---------------------------------------------------------------------------------------
// Gmsh
// ---------------------------------------------------------------------------------------

/// Nodes per element of the Gmsh element types up to 31 (0 = unknown), used to skip
/// elements we do not keep in v2 files (v4 lines are self-delimiting).
int gmsh_nodes_per_element(long long type) {
  static constexpr int kNodes[] = {0, 2,  3,  4,  4, 8,  6,  5,  3,  6,  9, 10, 27, 18, 14, 1,
                                   8, 20, 15, 13, 9, 10, 12, 15, 15, 21, 4, 5,  6,  20, 35, 56};
  return type >= 0 && type < static_cast<long long>(std::size(kNodes))
             ? kNodes[static_cast<std::size_t>(type)]
             : 0;
}

constexpr long long kGmshTet4 = 4;

/// Skip to the line "$End<name>".
void skip_section(LineReader& r, const std::string& name) {
  const std::string end = "$End" + name;
  while (true) {
    r.require_next(end);
    if (r.tokens()[0] == end) return;
  }
}

void expect_end(LineReader& r, std::string_view end) {
  r.require_next(end);
  if (r.tokens()[0] != end) r.fail(end);
}

void read_gmsh_nodes_v2(LineReader& r, RawVolume& raw, IdMap& ids) {
  r.require_next("the number of nodes");
  const long long n = r.count(0, "the number of nodes", "nodes", 8);
  raw.points.reserve(static_cast<std::size_t>(n));
  ids.reserve(static_cast<std::size_t>(n));
  for (long long i = 0; i < n; ++i) {
    r.require_next("a node line 'tag x y z'");
    r.need(4, "a node line 'tag x y z'");
    const long long tag = r.integer(0, "a node line 'tag x y z'");
    ids.add(tag, static_cast<Index>(raw.points.size()), r, "node");
    raw.point_ids.push_back(tag);
    raw.points.emplace_back(r.real(1, "x y z coordinates"), r.real(2, "x y z coordinates"),
                            r.real(3, "x y z coordinates"));
  }
  expect_end(r, "$EndNodes");
}

void read_gmsh_elements_v2(LineReader& r, RawVolume& raw, const IdMap& ids) {
  r.require_next("the number of elements");
  const long long n = r.count(0, "the number of elements", "elements", 8);
  constexpr std::string_view what = "an element line 'tag type num-tags tags... nodes...'";
  for (long long i = 0; i < n; ++i) {
    r.require_next(what);
    r.need(3, what);
    const long long tag = r.integer(0, what);
    const long long type = r.integer(1, what);
    const long long ntags = r.integer(2, what);
    if (ntags < 0) r.fail(what);
    const int nodes = gmsh_nodes_per_element(type);
    if (type != kGmshTet4) {
      if (nodes > 0 && r.size() != static_cast<std::size_t>(3 + ntags + nodes)) {
        r.fail(fmt::format("{} tags and {} nodes for an element of type {}", ntags, nodes, type));
      }
      continue;  // not a linear tet: ignored
    }
    if (r.size() != static_cast<std::size_t>(3 + ntags + 4)) {
      r.fail(fmt::format("{} tags and 4 node tags for a tet (type 4)", ntags));
    }
    Vec4i tet;
    for (int k = 0; k < 4; ++k) {
      const long long node = r.integer(static_cast<std::size_t>(3 + ntags + k), "a node tag");
      tet(k) = ids.at(node, r, fmt::format("element {}", tag), "$Nodes");
    }
    raw.tets.push_back(tet);
    raw.tet_ids.push_back(tag);
  }
  expect_end(r, "$EndElements");
}

void read_gmsh_nodes_v4(LineReader& r, RawVolume& raw, IdMap& ids) {
  constexpr std::string_view head = "'numEntityBlocks numNodes minNodeTag maxNodeTag'";
  r.require_next(head);
  r.need(4, head);
  const long long blocks = r.count(0, "numEntityBlocks", "node blocks", 8);
  const long long total = r.count(1, "numNodes", "nodes", 8);
  raw.points.reserve(static_cast<std::size_t>(total));
  ids.reserve(static_cast<std::size_t>(total));
  constexpr std::string_view bhead = "'entityDim entityTag parametric numNodesInBlock'";
  std::vector<long long> tags;
  for (long long b = 0; b < blocks; ++b) {
    r.require_next(bhead);
    r.need(4, bhead);
    const long long entity_dim = r.integer(0, bhead);
    const long long parametric = r.integer(2, bhead);
    const long long n = r.count(3, "numNodesInBlock", "nodes", 8);
    if (parametric < 0 || parametric > 1) r.fail(bhead);
    tags.clear();
    for (long long i = 0; i < n; ++i) {
      r.require_next("a node tag");
      tags.push_back(r.integer(0, "a node tag"));
    }
    // Coordinates "x y z" then, for parametric nodes, entityDim parametric coordinates.
    const std::size_t ncoord = 3 + (parametric ? static_cast<std::size_t>(entity_dim) : 0);
    for (long long i = 0; i < n; ++i) {
      r.require_next("node coordinates 'x y z'");
      if (r.size() != ncoord) r.fail(fmt::format("{} coordinates", ncoord));
      ids.add(tags[static_cast<std::size_t>(i)], static_cast<Index>(raw.points.size()), r, "node");
      raw.point_ids.push_back(tags[static_cast<std::size_t>(i)]);
      raw.points.emplace_back(r.real(0, "x y z coordinates"), r.real(1, "x y z coordinates"),
                              r.real(2, "x y z coordinates"));
    }
  }
  if (static_cast<long long>(raw.points.size()) != total) {
    r.fail_msg(
        fmt::format("$Nodes announced {} nodes but its blocks hold {}", total, raw.points.size()));
  }
  expect_end(r, "$EndNodes");
}

void read_gmsh_elements_v4(LineReader& r, RawVolume& raw, const IdMap& ids) {
  constexpr std::string_view head = "'numEntityBlocks numElements minElementTag maxElementTag'";
  r.require_next(head);
  r.need(4, head);
  const long long blocks = r.count(0, "numEntityBlocks", "element blocks", 8);
  constexpr std::string_view bhead = "'entityDim entityTag elementType numElementsInBlock'";
  for (long long b = 0; b < blocks; ++b) {
    r.require_next(bhead);
    r.need(4, bhead);
    const long long type = r.integer(2, bhead);
    const long long n = r.count(3, "numElementsInBlock", "elements", 4);
    const int nodes = gmsh_nodes_per_element(type);
    for (long long i = 0; i < n; ++i) {
      r.require_next("an element line 'tag nodes...'");
      if (type != kGmshTet4) {
        if (nodes > 0 && r.size() != static_cast<std::size_t>(1 + nodes)) {
          r.fail(fmt::format("an element tag and {} node tags (element type {})", nodes, type));
        }
        continue;  // not a linear tet: ignored
      }
      if (r.size() != 5) r.fail("an element tag and 4 node tags (tet, type 4)");
      const long long tag = r.integer(0, "an element tag");
      Vec4i tet;
      for (int k = 0; k < 4; ++k) {
        tet(k) = ids.at(r.integer(static_cast<std::size_t>(1 + k), "a node tag"), r,
                        fmt::format("element {}", tag), "$Nodes");
      }
      raw.tets.push_back(tet);
      raw.tet_ids.push_back(tag);
    }
  }
  expect_end(r, "$EndElements");
}

RawVolume read_gmsh(const fs::path& path) {
  LineReader r(path, '\0');
  RawVolume raw;
  IdMap ids;
  int major = 0;
  bool have_nodes = false;
  while (r.next()) {
    const std::string_view key = r.tokens()[0];
    if (key.empty() || key[0] != '$') r.fail("a section header such as $MeshFormat");
    const std::string name(key.substr(1));
    if (major == 0 && (name == "NOD" || name == "ELM")) {
      throw InputError(fmt::format(
          "{}:{}: Gmsh format version 1 is not supported; re-save as ASCII version 2.2 or 4.1",
          r.path(), r.line_no()));
    }
    if (name == "MeshFormat") {
      r.require_next("'version file-type data-size'");
      r.need(3, "'version file-type data-size'");
      const double version = r.real(0, "a version number such as 2.2 or 4.1");
      const long long file_type = r.integer(1, "file-type 0 (ASCII) or 1 (binary)");
      if (file_type == 1) {
        throw InputError(fmt::format(
            "{}: binary .msh is not supported; re-save as ASCII (gmsh option Mesh.Binary = 0, "
            "format 2.2 or 4.1)",
            r.path()));
      }
      if (file_type != 0) r.fail("file-type 0 (ASCII) or 1 (binary)");
      major = static_cast<int>(version);
      const bool supported = major == 2 || (major == 4 && version >= 4.1 - 1e-9);
      if (!supported) {
        throw InputError(fmt::format(
            "{}:{}: Gmsh format version {} is not supported; re-save as ASCII version 2.2 or "
            "4.1",
            r.path(), r.line_no(), r.tokens()[0]));
      }
      expect_end(r, "$EndMeshFormat");
    } else if (name == "Nodes" || name == "Elements") {
      if (major == 0) r.fail_msg(fmt::format("${} before $MeshFormat", name));
      if (name == "Nodes") {
        if (major == 2)
          read_gmsh_nodes_v2(r, raw, ids);
        else
          read_gmsh_nodes_v4(r, raw, ids);
        have_nodes = true;
      } else {
        if (!have_nodes) r.fail_msg("$Elements before $Nodes");
        if (major == 2)
          read_gmsh_elements_v2(r, raw, ids);
        else
          read_gmsh_elements_v4(r, raw, ids);
      }
    } else {
      skip_section(r, name);  // $PhysicalNames, $Entities, $NodeData, ...: not needed
    }
  }
  if (major == 0) {
    throw InputError(
        fmt::format("{}:1: expected $MeshFormat; is this a Gmsh .msh file?", r.path()));
  }
  return raw;
}

// ---------------------------------------------------------------------------------------
// TetGen
// ---------------------------------------------------------------------------------------

RawVolume read_tetgen(const fs::path& path) {
  fs::path node_path = path, ele_path = path;
  node_path.replace_extension(".node");
  ele_path.replace_extension(".ele");
  const std::string hint = " (a TetGen mesh needs both the .node and the .ele file)";
  require_file(node_path, hint);
  require_file(ele_path, hint);
  RawVolume raw;
  IdMap ids;
  {
    LineReader r(node_path, '#');
    constexpr std::string_view head =
        "a header '<#points> <dimension 3> <#attributes> <boundary markers 0/1>'";
    r.require_next(head);
    const long long dim = r.size() > 1 ? r.integer(1, head) : 3;
    if (dim != 3) r.fail_msg(fmt::format("expected dimension 3, got {}", dim));
    const long long n = r.count(0, "the point count", "points", 8);
    const long long nattr = r.size() > 2 ? r.integer(2, head) : 0;
    const long long nmark = r.size() > 3 ? r.integer(3, head) : 0;
    if (nattr < 0 || nmark < 0 || nmark > 1) r.fail(head);
    raw.points.reserve(static_cast<std::size_t>(n));
    const std::size_t cols = static_cast<std::size_t>(4 + nattr + nmark);
    for (long long i = 0; i < n; ++i) {
      r.require_next("a point line '<index> <x> <y> <z> ...'");
      if (r.size() != cols) {
        r.fail(fmt::format("{} numbers: index, x, y, z, {} attributes, {} markers", cols, nattr,
                           nmark));
      }
      const long long id = r.integer(0, "a point index");
      ids.add(id, static_cast<Index>(raw.points.size()), r, "point");
      raw.point_ids.push_back(id);
      raw.points.emplace_back(r.real(1, "x y z coordinates"), r.real(2, "x y z coordinates"),
                              r.real(3, "x y z coordinates"));
    }
  }
  {
    LineReader r(ele_path, '#');
    constexpr std::string_view head =
        "a header '<#tetrahedra> <nodes per tet 4 or 10> <#attributes>'";
    r.require_next(head);
    const long long n = r.count(0, "the tetrahedron count", "tetrahedra", 10);
    const long long per = r.size() > 1 ? r.integer(1, head) : 4;
    const long long nattr = r.size() > 2 ? r.integer(2, head) : 0;
    if (nattr < 0 || (per != 4 && per != 10)) r.fail(head);
    const std::size_t cols = static_cast<std::size_t>(1 + per + nattr);
    for (long long i = 0; i < n; ++i) {
      r.require_next("a tet line '<index> <n1> <n2> <n3> <n4> ...'");
      if (r.size() != cols) {
        r.fail(fmt::format("{} numbers: index, {} nodes, {} attributes", cols, per, nattr));
      }
      const long long id = r.integer(0, "a tet index");
      Vec4i tet;
      for (int k = 0; k < 4; ++k) {  // corners first; quadratic tets' mid-edge nodes dropped
        tet(k) = ids.at(r.integer(static_cast<std::size_t>(1 + k), "a point index"), r,
                        fmt::format("tet {}", id), node_path.filename().string());
      }
      raw.tets.push_back(tet);
      raw.tet_ids.push_back(id);
    }
  }
  return raw;
}

// ---------------------------------------------------------------------------------------
// VTK .vtu
// ---------------------------------------------------------------------------------------

RawVolume read_vtu(const fs::path& path) {
  require_file(path);
  check_vtk_xml_header(path);
  const VtkMessageCapture capture;  // VTK's messages off stderr, first one kept
  vtkNew<vtkXMLUnstructuredGridReader> reader;
  const VtkErrorObserver errors(reader);
  if (!reader->CanReadFile(path.string().c_str())) {
    throw InputError(fmt::format(
        "{}: not a VTK XML UnstructuredGrid file; expected '<VTKFile type=\"UnstructuredGrid\"'",
        path.string()));
  }
  reader->SetFileName(path.string().c_str());
  try {
    reader->Update();
  } catch (const std::exception& e) {  // e.g. a length_error on corrupt compressed data
    throw InputError(fmt::format("{}: VTK could not read the file ({}): its data is corrupt",
                                 path.string(), e.what()));
  }
  vtkUnstructuredGrid* grid = reader->GetOutput();
  if (!errors.first_message().empty() || !capture.first_message().empty() || grid == nullptr) {
    // The parser's own message (line, column) is the useful one; the reader's comes second.
    const std::string detail =
        !capture.first_message().empty() ? capture.first_message() : errors.first_message();
    throw InputError(fmt::format("{}: VTK could not read the file: {}", path.string(),
                                 detail.empty() ? "unknown error" : detail));
  }
  RawVolume raw;
  const vtkIdType np = grid->GetNumberOfPoints();
  raw.points.reserve(static_cast<std::size_t>(np));
  for (vtkIdType i = 0; i < np; ++i) {
    double p[3];
    grid->GetPoint(i, p);
    raw.points.emplace_back(p[0], p[1], p[2]);
    raw.point_ids.push_back(i);
  }
  vtkNew<vtkIdList> ids;
  for (vtkIdType c = 0; c < grid->GetNumberOfCells(); ++c) {
    if (grid->GetCellType(c) != VTK_TETRA) continue;  // other cell types ignored
    grid->GetCellPoints(c, ids);
    if (ids->GetNumberOfIds() != 4) {
      throw InputError(fmt::format("{}: cell {} is a VTK_TETRA with {} points, expected 4",
                                   path.string(), c, ids->GetNumberOfIds()));
    }
    Vec4i tet;
    for (int k = 0; k < 4; ++k) {
      const vtkIdType v = ids->GetId(k);
      if (v < 0 || v >= np) {
        throw InputError(fmt::format("{}: cell {} refers to point {}, but the file has {} points",
                                     path.string(), c, v, np));
      }
      tet(k) = static_cast<Index>(v);
    }
    raw.tets.push_back(tet);
    raw.tet_ids.push_back(c);
  }
  return raw;
}

// ---------------------------------------------------------------------------------------
// Surfaces
// ---------------------------------------------------------------------------------------

struct RawSurface {
  std::vector<Vec3> points;
  std::vector<Vec3i> triangles;
};

/// Append the fan triangulation (v0, v_i, v_i+1) of a polygon.
void add_polygon(RawSurface& s, const std::vector<Index>& poly) {
  for (std::size_t i = 1; i + 1 < poly.size(); ++i) {
    s.triangles.emplace_back(poly[0], poly[i], poly[i + 1]);
  }
}

RawSurface read_off(const fs::path& path) {
  LineReader r(path, '#');
  RawSurface s;
  r.require_next("the header 'OFF'");
  const std::string magic(r.tokens()[0]);
  if (magic != "OFF" && magic != "COFF" && magic != "NOFF" && magic != "CNOFF") {
    r.fail("the header 'OFF'");
  }
  std::size_t base = 1;  // the counts may follow "OFF" on the same line
  if (r.size() == 1) {
    r.require_next("'#vertices #faces #edges'");
    base = 0;
  }
  r.need(base + 2, "'#vertices #faces #edges'");
  const long long nv = r.count(base, "#vertices", "vertices", 6);
  const long long nf = r.count(base + 1, "#faces", "faces", 8);
  s.points.reserve(static_cast<std::size_t>(nv));
  for (long long i = 0; i < nv; ++i) {
    r.require_next("a vertex line 'x y z'");
    r.need(3, "a vertex line 'x y z'");
    s.points.emplace_back(r.real(0, "x y z coordinates"), r.real(1, "x y z coordinates"),
                          r.real(2, "x y z coordinates"));
  }
  std::vector<Index> poly;
  for (long long f = 0; f < nf; ++f) {
    r.require_next("a face line 'n v1 ... vn'");
    const long long n = r.integer(0, "a face line 'n v1 ... vn'");
    if (n < 3) r.fail("a face with at least 3 vertices");
    r.need(static_cast<std::size_t>(1 + n), fmt::format("a face with {} vertex indices", n));
    poly.clear();
    for (long long k = 0; k < n; ++k) {
      const long long v = r.integer(static_cast<std::size_t>(1 + k), "a vertex index");
      if (v < 0 || v >= nv) {
        r.fail_msg(
            fmt::format("face {} refers to vertex {}, but the file has {} vertices "
                        "(zero-based 0..{})",
                        f, v, nv, nv - 1));
      }
      poly.push_back(static_cast<Index>(v));
    }
    add_polygon(s, poly);
  }
  return s;
}

RawSurface read_obj(const fs::path& path) {
  LineReader r(path, '#');
  RawSurface s;
  std::vector<Index> poly;
  while (r.next()) {
    const std::string_view key = r.tokens()[0];
    if (key == "v") {
      r.need(4, "a vertex line 'v x y z'");
      s.points.emplace_back(r.real(1, "x y z coordinates"), r.real(2, "x y z coordinates"),
                            r.real(3, "x y z coordinates"));
    } else if (key == "f") {
      if (r.size() < 4) r.fail("a face line 'f a b c ...' with at least 3 vertices");
      poly.clear();
      const long long nv = static_cast<long long>(s.points.size());
      for (std::size_t k = 1; k < r.size(); ++k) {
        // "a", "a/b", "a/b/c" or "a//c": the vertex index is the part before the first '/'.
        const std::string_view t = r.tokens()[k];
        const std::string_view head = t.substr(0, t.find('/'));
        long long v = 0;
        const auto [p, ec] = std::from_chars(head.data(), head.data() + head.size(), v);
        if (ec != std::errc() || p != head.data() + head.size() || v == 0) {
          r.fail("face vertices 'a', 'a/b', 'a/b/c' or 'a//c' with a non-zero index");
        }
        const long long index = v > 0 ? v - 1 : nv + v;  // negative: relative to the end
        if (index < 0 || index >= nv) {
          r.fail_msg(
              fmt::format("face vertex {} refers to vertex {}, but only {} vertices are "
                          "defined so far",
                          t, v, nv));
        }
        poly.push_back(static_cast<Index>(index));
      }
      add_polygon(s, poly);
    }
    // vt, vn, o, g, s, usemtl, mtllib, l, p...: not geometry of the surface; ignored.
  }
  return s;
}

/// Merges bit-identical points (−0 and +0 are the same point) into one index.
class PointMerger {
 public:
  Index add(double x, double y, double z, RawSurface& s) {
    const std::array<double, 3> key = {x + 0.0, y + 0.0, z + 0.0};
    const auto [it, inserted] = m_map.try_emplace(key, static_cast<Index>(s.points.size()));
    if (inserted) s.points.emplace_back(key[0], key[1], key[2]);
    return it->second;
  }

 private:
  struct Hash {
    std::size_t operator()(const std::array<double, 3>& p) const {
      std::size_t h = 0;
      for (double d : p) {
        h ^= std::hash<std::uint64_t>()(std::bit_cast<std::uint64_t>(d)) + 0x9E3779B97F4A7C15ULL +
             (h << 6) + (h >> 2);
      }
      return h;
    }
  };
  std::unordered_map<std::array<double, 3>, Index, Hash> m_map;
};

RawSurface read_stl_ascii(const fs::path& path) {
  LineReader r(path, '\0');
  RawSurface s;
  PointMerger merger;
  std::vector<Index> corners;
  bool in_solid = false;
  while (r.next()) {
    const std::string_view key = r.tokens()[0];
    if (key == "solid") {
      in_solid = true;
    } else if (key == "endsolid") {
      in_solid = false;
    } else if (key == "facet") {
      if (!in_solid) r.fail("'solid <name>' before the first facet");
      if (r.size() != 5 || r.tokens()[1] != "normal") r.fail("'facet normal nx ny nz'");
      r.require_next("'outer loop'");
      if (r.size() != 2 || r.tokens()[0] != "outer" || r.tokens()[1] != "loop") {
        r.fail("'outer loop'");
      }
      corners.clear();
      while (true) {
        r.require_next("'vertex x y z' or 'endloop'");
        if (r.tokens()[0] == "endloop") break;
        if (r.size() != 4 || r.tokens()[0] != "vertex") r.fail("'vertex x y z' or 'endloop'");
        corners.push_back(merger.add(r.real(1, "'vertex x y z'"), r.real(2, "'vertex x y z'"),
                                     r.real(3, "'vertex x y z'"), s));
      }
      if (corners.size() < 3) r.fail("at least 3 vertices before 'endloop'");
      add_polygon(s, corners);
      r.require_next("'endfacet'");
      if (r.tokens()[0] != "endfacet") r.fail("'endfacet'");
    } else {
      r.fail("'solid', 'facet normal ...' or 'endsolid'");
    }
  }
  return s;
}

RawSurface read_stl_binary(const fs::path& path, const std::string& bytes) {
  static_assert(std::endian::native == std::endian::little,
                "binary STL reader assumes a little-endian host");
  RawSurface s;
  PointMerger merger;
  std::uint32_t n = 0;
  std::memcpy(&n, bytes.data() + 80, 4);
  s.triangles.reserve(n);
  for (std::uint32_t f = 0; f < n; ++f) {
    const char* rec = bytes.data() + 84 + 50 * static_cast<std::size_t>(f);
    float v[12];
    std::memcpy(v, rec, sizeof v);  // normal, then three corners
    Vec3i tri;
    for (int k = 0; k < 3; ++k) {
      tri(k) = merger.add(v[3 + 3 * k], v[4 + 3 * k], v[5 + 3 * k], s);
    }
    s.triangles.push_back(tri);
  }
  logger().debug("{}: binary STL, {} triangles, {} distinct vertices", path.string(), n,
                 s.points.size());
  return s;
}

RawSurface read_stl(const fs::path& path) {
  require_file(path);
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(fmt::format("{}: cannot open the file for reading", path.string()));
  const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  // Binary: 80-byte header, uint32 count, 50 bytes per triangle — the size must match.
  // The header of a binary file may itself begin with "solid", so that word alone does not
  // make a file ASCII: a file of the right size is binary unless it starts with "solid" and
  // is all text.
  bool size_matches = false;
  if (bytes.size() >= 84) {
    std::uint32_t n = 0;
    std::memcpy(&n, bytes.data() + 80, 4);
    size_matches = bytes.size() == 84 + 50 * static_cast<std::size_t>(n);
  }
  std::size_t start = 0;
  while (start < bytes.size() && std::isspace(static_cast<unsigned char>(bytes[start]))) ++start;
  const bool starts_solid = bytes.compare(start, 5, "solid") == 0;
  const bool all_text = std::all_of(bytes.begin(), bytes.end(), [](char c) {
    const auto u = static_cast<unsigned char>(c);
    return u == '\n' || u == '\r' || u == '\t' || (u >= 32 && u < 127);
  });
  if (size_matches && !(starts_solid && all_text)) return read_stl_binary(path, bytes);
  if (starts_solid) return read_stl_ascii(path);
  throw InputError(fmt::format(
      "{}: not an STL file: it does not start with 'solid' (ASCII) and its size {} bytes is not "
      "84 + 50 * (triangle count) (binary)",
      path.string(), bytes.size()));
}

}  // namespace

// ---------------------------------------------------------------------------------------
// Public entry points
// ---------------------------------------------------------------------------------------

VolumeMesh read_volume_mesh(const fs::path& path) {
  const std::string ext = lower_extension(path);
  RawVolume raw;
  if (ext == ".msh") {
    raw = read_gmsh(path);
  } else if (ext == ".node" || ext == ".ele") {
    raw = read_tetgen(path);
  } else if (ext == ".vtu") {
    raw = read_vtu(path);
  } else {
    require_file(path);
    throw InputError(fmt::format(
        "{}: unknown volume mesh extension '{}'; use .msh (Gmsh), .node/.ele (TetGen) or .vtu",
        path.string(), path.extension().string()));
  }
  const std::string source = path.string();
  VolumeMesh m;
  m.vertices.resize(static_cast<Index>(raw.points.size()), 3);
  for (std::size_t v = 0; v < raw.points.size(); ++v) {
    m.vertices.row(static_cast<Index>(v)) = raw.points[v].transpose();
  }
  m.tets.resize(static_cast<Index>(raw.tets.size()), 4);
  for (std::size_t t = 0; t < raw.tets.size(); ++t) {
    m.tets.row(static_cast<Index>(t)) = raw.tets[t].transpose();
  }
  if (m.num_tets() == 0) {
    throw MeshError(fmt::format(
        "{}: the file has no tetrahedra ({} nodes); mesh the volume (Gmsh: 'Mesh 3D', element "
        "type 4)",
        source, m.num_vertices()));
  }
  const bool flipped = fix_global_orientation(m);
  VecXi old_index;
  const Index removed = remove_unused_vertices(m, &old_index);
  MeshLabels labels;
  labels.tet_ids = std::move(raw.tet_ids);
  labels.vertex_ids.resize(static_cast<std::size_t>(m.num_vertices()));
  for (Index v = 0; v < m.num_vertices(); ++v) {
    labels.vertex_ids[static_cast<std::size_t>(v)] =
        raw.point_ids[static_cast<std::size_t>(old_index(v))];
  }
  validate_volume_mesh(m, source, labels);
  logger().info("{}: {} vertices, {} tets, volume {:.6g} m^3{}{}", source, m.num_vertices(),
                m.num_tets(), total_volume(m), flipped ? ", orientation flipped" : "",
                removed > 0 ? fmt::format(", {} unused nodes dropped", removed) : "");
  return m;
}

SurfaceMesh read_surface_mesh(const fs::path& path) {
  const std::string ext = lower_extension(path);
  RawSurface raw;
  if (ext == ".off") {
    raw = read_off(path);
  } else if (ext == ".obj") {
    raw = read_obj(path);
  } else if (ext == ".stl") {
    raw = read_stl(path);
  } else {
    require_file(path);
    throw InputError(fmt::format("{}: unknown surface mesh extension '{}'; use .off, .obj or .stl",
                                 path.string(), path.extension().string()));
  }
  SurfaceMesh s;
  s.vertices.resize(static_cast<Index>(raw.points.size()), 3);
  for (std::size_t v = 0; v < raw.points.size(); ++v) {
    s.vertices.row(static_cast<Index>(v)) = raw.points[v].transpose();
  }
  s.triangles.resize(static_cast<Index>(raw.triangles.size()), 3);
  for (std::size_t f = 0; f < raw.triangles.size(); ++f) {
    s.triangles.row(static_cast<Index>(f)) = raw.triangles[f].transpose();
  }
  logger().info("{}: surface with {} vertices, {} triangles", path.string(), s.num_vertices(),
                s.num_triangles());
  return s;
}

void write_msh(const VolumeMesh& m, const fs::path& path) {
  fmt::memory_buffer out;
  auto it = std::back_inserter(out);
  fmt::format_to(it, "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n{}\n", m.num_vertices());
  for (Index v = 0; v < m.num_vertices(); ++v) {
    // "{}" is the shortest representation that reads back to the same double.
    fmt::format_to(it, "{} {} {} {}\n", v + 1, m.vertices(v, 0), m.vertices(v, 1),
                   m.vertices(v, 2));
  }
  fmt::format_to(it, "$EndNodes\n$Elements\n{}\n", m.num_tets());
  for (Index t = 0; t < m.num_tets(); ++t) {
    // tag, type 4 (tet), 2 tags (physical 1, elementary 1), node tags (1-based).
    fmt::format_to(it, "{} 4 2 1 1 {} {} {} {}\n", t + 1, m.tets(t, 0) + 1, m.tets(t, 1) + 1,
                   m.tets(t, 2) + 1, m.tets(t, 3) + 1);
  }
  fmt::format_to(it, "$EndElements\n");
  std::ofstream file(path, std::ios::binary);
  if (file) file.write(out.data(), static_cast<std::streamsize>(out.size()));
  if (!file) {
    throw InputError(
        fmt::format("{}: cannot write the file (does the directory exist?)", path.string()));
  }
}

}  // namespace tetfsi::mesh
