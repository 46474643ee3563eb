/// @file vtu_check.cpp
/// What VTK's XML reader (9.1) trusts in a .vtu and we check first (check_vtk_xml_header):
/// the Piece counts and component numbers it loops over or allocates for, the appended block
/// headers, and the appended data itself: every array decoded (raw, zlib or LZ4), its size
/// equal to what its Piece announces, the cells' offsets non-decreasing and their
/// connectivity within the points. On a damaged file VTK otherwise spins, allocates without
/// bound, or reads past its buffers (a segfault in ReadArrayForCells on a zlib file with
/// bytes inserted into its data).
#include <lz4.h>
#include <zlib.h>

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <iterator>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <fmt/format.h>

#include "core/error.hpp"
#include "mesh/io.hpp"

namespace fs = std::filesystem;

namespace tetfsi::mesh {

namespace {

/// The value of attribute `name` in the XML start tag `tag`, or nothing.
std::optional<std::string> xml_attribute(std::string_view tag, std::string_view name) {
  for (std::size_t at = tag.find(name); at != std::string_view::npos; at = tag.find(name, at + 1)) {
    const std::size_t eq = at + name.size();
    const bool word_start = at > 0 && std::isspace(static_cast<unsigned char>(tag[at - 1]));
    if (!word_start || eq + 1 >= tag.size() || tag[eq] != '=') continue;
    const char quote = tag[eq + 1];
    if (quote != '"' && quote != '\'') continue;
    const std::size_t end = tag.find(quote, eq + 2);
    if (end == std::string_view::npos) return std::nullopt;
    return std::string(tag.substr(eq + 2, end - eq - 2));
  }
  return std::nullopt;
}

/// Bytes per value of a VTK XML DataArray type, 0 for types we do not decode (String, Bit).
std::uint64_t type_size(const std::string& type) {
  if (type == "Int8" || type == "UInt8") return 1;
  if (type == "Int16" || type == "UInt16") return 2;
  if (type == "Int32" || type == "UInt32" || type == "Float32") return 4;
  if (type == "Int64" || type == "UInt64" || type == "Float64") return 8;
  return 0;
}

/// Value i of an integer array of `type` (little-endian bytes).
std::int64_t integer_at(const std::string& bytes, std::uint64_t i, const std::string& type) {
  const std::uint64_t n = type_size(type);
  std::uint64_t u = 0;
  std::memcpy(&u, bytes.data() + i * n, n);
  if (type[0] == 'U' || n == 8) return static_cast<std::int64_t>(u);
  const std::uint64_t sign = 1ULL << (8 * n - 1);
  return static_cast<std::int64_t>((u ^ sign) - sign);  // sign-extend
}

enum class Section { Other, Points, PointData, CellData, Cells };

struct ArrayTag {
  std::string name, type;
  std::uint64_t components = 1;
  bool appended = false;  ///< format="appended": its data is decoded and checked
  std::uint64_t at = 0;   ///< byte of its appended data in the file
  Section section = Section::Other;
  int piece = 0;
  std::uint64_t points = 0, cells = 0;  ///< of its Piece
};

class VtuCheck {
 public:
  VtuCheck(const fs::path& path, std::string bytes)
      : m_path(path.string()), m_bytes(std::move(bytes)) {
    // A count beyond this cannot be stored in the file, compressed or not (zlib's best
    // ratio is about 1000:1).
    m_limit = 1100ULL * std::max<std::size_t>(m_bytes.size(), 1);
    const std::size_t appended = m_bytes.find("<AppendedData");
    m_xml_end = appended == std::string::npos ? m_bytes.size() : appended;
  }

  void run() {
    const std::string_view file_tag = tag_at(m_bytes.find("<VTKFile"));
    m_word = xml_attribute(file_tag, "header_type").value_or("UInt32") == "UInt64" ? 8 : 4;
    m_compressor = xml_attribute(file_tag, "compressor").value_or("");
    m_little = xml_attribute(file_tag, "byte_order").value_or("LittleEndian") == "LittleEndian";
    find_appended_data();
    scan_tags();
    // Per piece, the cells' offsets before their connectivity, whose length the last offset
    // gives.
    std::stable_sort(m_arrays.begin(), m_arrays.end(), [](const ArrayTag& a, const ArrayTag& b) {
      return std::pair(a.piece, a.name == "connectivity") <
             std::pair(b.piece, b.name == "connectivity");
    });
    for (const ArrayTag& a : m_arrays) check_array(a);
  }

 private:
  std::string_view tag_at(std::size_t at) const {
    if (at == std::string::npos || at >= m_bytes.size()) return {};
    const std::size_t end = m_bytes.find('>', at);
    return std::string_view(m_bytes).substr(
        at, end == std::string::npos ? m_bytes.size() - at : end - at);
  }

  [[noreturn]] void fail(const std::string& what) const {
    throw InputError(
        fmt::format("{}: {}; the file is damaged or not written by VTK", m_path, what));
  }

  std::uint64_t number(std::string_view tag, std::string_view name, const std::string& text) const {
    std::uint64_t v = 0;
    const auto [p, ec] = std::from_chars(text.data(), text.data() + text.size(), v);
    if (ec != std::errc() || p != text.data() + text.size())
      fail(fmt::format("{} {}=\"{}\" is not a non-negative integer", tag.substr(0, tag.find(' ')),
                       name, text));
    return v;
  }

  std::uint64_t count(std::string_view tag, std::string_view name) const {
    const auto text = xml_attribute(tag, name);
    if (!text) return 0;
    const std::uint64_t n = number(tag, name, *text);
    if (n > m_limit)
      fail(fmt::format("<Piece {}=\"{}\"> is more than a {}-byte file can hold", name, n,
                       m_bytes.size()));
    return n;
  }

  /// The XML part: counts, component numbers, and the appended arrays to decode.
  void scan_tags() {
    Section section = Section::Other;
    std::uint64_t points = 0, cells = 0;
    int piece = -1;
    for (std::size_t at = m_bytes.find('<'); at < m_xml_end; at = m_bytes.find('<', at + 1)) {
      const std::string_view tag = tag_at(at);
      if (tag.rfind("<Piece", 0) == 0) {
        points = count(tag, "NumberOfPoints");
        cells = count(tag, "NumberOfCells");
        ++piece;
      } else if (tag.rfind("<DataArray", 0) == 0) {
        data_array(tag, section, piece, points, cells);
      } else if (tag.rfind("</", 0) == 0) {
        section = Section::Other;
      } else {
        for (const auto& [open, s] : {std::pair{"<PointData", Section::PointData},
                                      {"<CellData", Section::CellData},
                                      {"<Points", Section::Points},
                                      {"<Cells", Section::Cells}}) {
          if (tag.rfind(open, 0) == 0) section = s;
        }
      }
    }
  }

  void data_array(std::string_view tag, Section section, int piece, std::uint64_t points,
                  std::uint64_t cells) {
    ArrayTag a;
    a.piece = piece;
    a.name = xml_attribute(tag, "Name").value_or("(unnamed)");
    a.type = xml_attribute(tag, "type").value_or("");
    a.section = section;
    a.points = points;
    a.cells = cells;
    for (const ArrayTag& b : m_arrays) {
      if (b.piece == piece && b.section == section && b.name == a.name && section != Section::Other)
        fail(fmt::format("piece {} has two DataArrays named '{}' in one section", piece, a.name));
    }
    if (const auto k = xml_attribute(tag, "NumberOfComponents")) {
      a.components = number(tag, "NumberOfComponents", *k);
      if (a.components < 1 || a.components > 4096)
        fail(fmt::format("DataArray '{}' has NumberOfComponents=\"{}\", expected 1 to 4096", a.name,
                         a.components));
    }
    a.appended =
        xml_attribute(tag, "format").value_or("") == "appended" && m_data != std::string::npos;
    if (a.appended) {
      const auto offset = xml_attribute(tag, "offset");
      if (!offset) fail(fmt::format("appended DataArray '{}' has no offset", a.name));
      a.at = m_data + number(tag, "offset", *offset);
      block_header(a.name, a.at);
    }
    m_arrays.push_back(std::move(a));
  }

  /// The appended data starts after the '_' that follows <AppendedData encoding="raw">.
  void find_appended_data() {
    if (m_xml_end == m_bytes.size()) return;
    const std::string_view tag = tag_at(m_xml_end);
    if (xml_attribute(tag, "encoding").value_or("") != "raw" || !m_little) return;
    const std::size_t underscore = m_bytes.find('_', m_xml_end + tag.size());
    if (underscore != std::string::npos) m_data = underscore + 1;
  }

  std::uint64_t word(std::size_t at) const {
    std::uint64_t v = 0;
    std::memcpy(&v, m_bytes.data() + at, m_word);  // little-endian host and file
    return v;
  }

  /// [size] raw, or [#blocks, block size, last block size, compressed sizes...] compressed.
  void block_header(const std::string& name, std::uint64_t at) const {
    const std::uint64_t size = m_bytes.size();
    const auto need = [&](std::uint64_t end, const char* what) {
      if (end > size || end < at)
        fail(fmt::format("the appended data of DataArray '{}' ({}) runs past the end of the file",
                         name, what));
    };
    need(at + m_word, "its header");
    if (m_compressor.empty()) {
      need(at + m_word + word(at), "its byte count");
      return;
    }
    const std::uint64_t blocks = word(at);
    if (blocks > size / m_word) need(size + 1, "its block count");
    const std::uint64_t head = at + m_word * (3 + blocks);
    need(head, "its block count");
    std::uint64_t total = 0;
    for (std::uint64_t b = 0; b < blocks; ++b) {
      total += word(at + m_word * (3 + b));
      if (total > size) need(size + 1, "its compressed block sizes");
    }
    need(head + total, "its compressed block sizes");
    if (blocks > 0 && word(at + m_word) > m_limit) need(size + 1, "its block size");
  }

  /// The bytes an array must decode to, from its Piece (connectivity: the last offset).
  std::optional<std::uint64_t> expected_values(const ArrayTag& a) const {
    switch (a.section) {
      case Section::Points:
      case Section::PointData:
        return a.points * a.components;
      case Section::CellData:
        return a.cells * a.components;
      case Section::Cells:
        if (a.name == "offsets" || a.name == "types") return a.cells;
        if (a.name == "connectivity") return m_last_offset;
        return std::nullopt;
      default:
        return std::nullopt;
    }
  }

  /// Decode the appended data of `a` (after block_header checked its headers), having first
  /// checked that the announced size is `bytes`.
  std::string decode(const ArrayTag& a, std::uint64_t bytes) const {
    const auto wrong_size = [&](std::uint64_t got) {
      fail(
          fmt::format("DataArray '{}' holds {} bytes, but its Piece needs {} ({} values of {} "
                      "bytes)",
                      a.name, got, bytes, bytes / type_size(a.type), type_size(a.type)));
    };
    if (m_compressor.empty()) {
      if (word(a.at) != bytes) wrong_size(word(a.at));
      return m_bytes.substr(a.at + m_word, bytes);
    }
    const std::uint64_t blocks = word(a.at), block = word(a.at + m_word);
    const std::uint64_t last = word(a.at + 2 * m_word) == 0 ? block : word(a.at + 2 * m_word);
    const std::uint64_t total = blocks == 0 ? 0 : (blocks - 1) * block + last;
    if (total != bytes) wrong_size(total);
    std::string out(bytes, '\0');
    std::uint64_t src = a.at + m_word * (3 + blocks), dst = 0;
    for (std::uint64_t b = 0; b < blocks; ++b) {
      const std::uint64_t csize = word(a.at + m_word * (3 + b)),
                          usize = b + 1 < blocks ? block : last;
      if (!inflate_block(m_bytes.data() + src, csize, out.data() + dst, usize))
        fail(fmt::format("block {} of DataArray '{}' does not decompress ({}) to its {} bytes", b,
                         a.name, m_compressor, usize));
      src += csize;
      dst += usize;
    }
    return out;
  }

  bool inflate_block(const char* src, std::uint64_t csize, char* dst, std::uint64_t usize) const {
    if (csize > 0x7fffffff || usize > 0x7fffffff) return false;
    if (m_compressor == "vtkZLibDataCompressor") {
      uLongf n = static_cast<uLongf>(usize);
      return uncompress(reinterpret_cast<Bytef*>(dst), &n, reinterpret_cast<const Bytef*>(src),
                        static_cast<uLong>(csize)) == Z_OK &&
             n == usize;
    }
    return LZ4_decompress_safe(src, dst, static_cast<int>(csize), static_cast<int>(usize)) ==
           static_cast<int>(usize);
  }

  void check_array(const ArrayTag& a) {
    const std::uint64_t size = type_size(a.type);
    const std::optional<std::uint64_t> values = expected_values(a);
    const bool decodable = m_compressor.empty() || m_compressor == "vtkZLibDataCompressor" ||
                           m_compressor == "vtkLZ4DataCompressor";
    if (!a.appended || size == 0 || !values || !decodable) return;  // VTK reads the rest
    const std::string data = decode(a, *values * size);
    if (a.section != Section::Cells || a.name == "types") return;
    const bool is_integer = a.type.find("Int") != std::string::npos;
    if (!is_integer)
      fail(fmt::format("the cells' '{}' are of type {}, not integers", a.name, a.type));
    std::int64_t prev = 0;
    for (std::uint64_t i = 0; i < *values; ++i) {
      const std::int64_t v = integer_at(data, i, a.type);
      if (a.name == "offsets" && v < prev)
        fail(fmt::format("cell {}'s offset {} is below the previous cell's ({})", i, v, prev));
      if (a.name == "connectivity" && (v < 0 || static_cast<std::uint64_t>(v) >= a.points))
        fail(fmt::format("connectivity entry {} is point {}, but the piece has {} points", i, v,
                         a.points));
      prev = v;
    }
    if (a.name == "offsets") {
      if (prev > static_cast<std::int64_t>(m_limit))
        fail(fmt::format("the last cell's offset {} is more than the file can hold", prev));
      m_last_offset = static_cast<std::uint64_t>(prev);
    }
  }

  std::string m_path, m_bytes, m_compressor;
  std::uint64_t m_limit = 0, m_last_offset = 0;
  std::size_t m_xml_end = 0, m_data = std::string::npos, m_word = 4;
  bool m_little = true;
  /// Every DataArray: the appended ones are decoded; a name twice in a section is refused
  /// (VTK's reader crashes on it).
  std::vector<ArrayTag> m_arrays;
};

}  // namespace

void check_vtk_xml_header(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(fmt::format("{}: cannot open the file for reading", path.string()));
  VtuCheck(path,
           std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>()))
      .run();
}

}  // namespace tetfsi::mesh
