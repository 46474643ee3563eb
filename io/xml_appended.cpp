/// @file xml_appended.cpp
/// The .vtu writer of xml_appended.hpp: the arrays' ranges and their blocks' compression in
/// parallel, then the XML head (whose offsets need every compressed size) and the appended
/// data written in order.
#include "io/xml_appended.hpp"

#include <lz4.h>
#include <zlib.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <limits>
#include <utility>

#include <fmt/format.h>

#include "core/error.hpp"
#include "core/parallel.hpp"

namespace fs = std::filesystem;

namespace tetfsi::app {

namespace {

/// VTK's block size: each block of an array's bytes is compressed on its own.
constexpr std::size_t kBlock = 32768;
/// VTK's LZ4 compressor at compression level 1 calls LZ4 with acceleration 10 − 1.
constexpr int kLz4Acceleration = 9;

std::size_t value_size(XmlValueType t) {
  switch (t) {
    case XmlValueType::Int32:
      return 4;
    case XmlValueType::UInt8:
      return 1;
    case XmlValueType::Float64:
      return 8;
  }
  return 0;
}

const char* type_name(XmlValueType t) {
  switch (t) {
    case XmlValueType::Int32:
      return "Int32";
    case XmlValueType::UInt8:
      return "UInt8";
    case XmlValueType::Float64:
      return "Float64";
  }
  return "";
}

/// The least and greatest value over the tuples [begin, end) of `data` (`comps` values each),
/// or of the tuples' Euclidean norms for several components.
template <class V>
std::pair<double, double> value_range(const V* data, Index begin, Index end, std::size_t comps) {
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  for (Index t = begin; t < end; ++t) {
    const V* x = data + static_cast<std::size_t>(t) * comps;
    double v = static_cast<double>(x[0]);
    if (comps > 1) {
      double s = 0.0;
      for (std::size_t c = 0; c < comps; ++c) {
        const double y = static_cast<double>(x[c]);
        s += y * y;
      }
      v = std::sqrt(s);
    }
    lo = std::min(lo, v);
    hi = std::max(hi, v);
  }
  return {lo, hi};
}

/// The RangeMin / RangeMax attributes of `a` (empty without `range` or values): value_range
/// per chunk in parallel, each chunk read at its own type.
std::string range_attributes(const XmlArray& a) {
  const auto comps = static_cast<std::size_t>(std::max(1, a.components));
  const auto tuples = static_cast<Index>(a.count / comps);
  if (!a.range || tuples == 0) return "";
  constexpr Index grain = 65536;
  std::vector<std::pair<double, double>> part(static_cast<std::size_t>(num_chunks(tuples, grain)));
  parallel_for_chunks(tuples, grain, [&](Index begin, Index end) {
    auto& p = part[static_cast<std::size_t>(begin / grain)];
    switch (a.type) {
      case XmlValueType::Int32:
        p = value_range(static_cast<const std::int32_t*>(a.data), begin, end, comps);
        break;
      case XmlValueType::UInt8:
        p = value_range(static_cast<const std::uint8_t*>(a.data), begin, end, comps);
        break;
      case XmlValueType::Float64:
        p = value_range(static_cast<const double*>(a.data), begin, end, comps);
        break;
    }
  });
  double lo = part[0].first, hi = part[0].second;
  for (const auto& [l, h] : part) {
    lo = std::min(lo, l);
    hi = std::max(hi, h);
  }
  return fmt::format(" RangeMin=\"{:.11g}\" RangeMax=\"{:.11g}\"", lo, hi);
}

/// One array's appended bytes: its UInt64 header ([byte count] raw, or [#blocks, block size,
/// size of a partial last block (0: full), compressed sizes...]) and its compressed blocks.
struct Encoded {
  std::vector<std::uint64_t> header;
  std::vector<std::vector<char>> blocks;
  std::size_t raw_bytes = 0;  ///< raw: the array's bytes follow the header as they are
  std::size_t size() const {
    std::size_t s = header.size() * sizeof(std::uint64_t) + raw_bytes;
    for (const std::vector<char>& b : blocks) s += b.size();
    return s;
  }
};

/// Compress `n` bytes at `src` into `dst` as one block.
void compress_block(const char* src, std::size_t n, Compression c, std::vector<char>& dst) {
  if (c == Compression::LZ4) {
    dst.resize(static_cast<std::size_t>(LZ4_compressBound(static_cast<int>(n))));
    const int cs = LZ4_compress_fast(src, dst.data(), static_cast<int>(n),
                                     static_cast<int>(dst.size()), kLz4Acceleration);
    if (cs <= 0) throw InternalError("LZ4 could not compress a block");
    dst.resize(static_cast<std::size_t>(cs));
    return;
  }
  uLongf len = compressBound(static_cast<uLong>(n));
  dst.resize(len);
  if (compress2(reinterpret_cast<Bytef*>(dst.data()), &len, reinterpret_cast<const Bytef*>(src),
                static_cast<uLong>(n), 1) != Z_OK)
    throw InternalError("zlib could not compress a block");
  dst.resize(len);
}

/// Every array's appended bytes; the blocks of all arrays compressed in parallel.
std::vector<Encoded> encode(const std::vector<const XmlArray*>& arrays, Compression c) {
  std::vector<Encoded> out(arrays.size());
  std::vector<std::pair<std::size_t, std::size_t>> jobs;  // (array, block)
  for (std::size_t i = 0; i < arrays.size(); ++i) {
    const std::size_t bytes = arrays[i]->count * value_size(arrays[i]->type);
    if (c == Compression::None) {
      out[i].header = {bytes};
      out[i].raw_bytes = bytes;
      continue;
    }
    const std::size_t nb = (bytes + kBlock - 1) / kBlock;
    out[i].header = {nb, kBlock, bytes % kBlock};
    out[i].header.resize(3 + nb);
    out[i].blocks.resize(nb);
    for (std::size_t b = 0; b < nb; ++b) jobs.emplace_back(i, b);
  }
  parallel_for_each(static_cast<Index>(jobs.size()), 4, [&](Index j) {
    const auto [i, b] = jobs[static_cast<std::size_t>(j)];
    const std::size_t bytes = arrays[i]->count * value_size(arrays[i]->type);
    const char* src = static_cast<const char*>(arrays[i]->data) + b * kBlock;
    std::vector<char>& dst = out[i].blocks[b];
    compress_block(src, std::min(kBlock, bytes - b * kBlock), c, dst);
    out[i].header[3 + b] = dst.size();
  });
  return out;
}

/// The XML from the file's start to the appended data's '_' marker.
std::string xml_head(const XmlUnstructuredGrid& g, const std::vector<const XmlArray*>& arrays,
                     const std::vector<Encoded>& enc, Compression c) {
  std::vector<std::string> ranges(arrays.size());
  for (std::size_t i = 0; i < arrays.size(); ++i) ranges[i] = range_attributes(*arrays[i]);
  std::size_t offset = 0, next = 0;
  auto data_array = [&](std::string& s) {
    const XmlArray& a = *arrays[next];
    s += fmt::format("        <DataArray type=\"{}\" Name=\"{}\"", type_name(a.type),
                     xml_escape(a.name));
    if (a.components > 1) s += fmt::format(" NumberOfComponents=\"{}\"", a.components);
    s += fmt::format(" format=\"appended\"{} offset=\"{}\"/>\n", ranges[next], offset);
    offset += enc[next++].size();
  };
  const char* compressor = c == Compression::LZ4    ? " compressor=\"vtkLZ4DataCompressor\""
                           : c == Compression::ZLib ? " compressor=\"vtkZLibDataCompressor\""
                                                    : "";
  std::string s = fmt::format(
      "<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" byte_order=\"LittleEndian\" "
      "header_type=\"UInt64\"{}>\n  <UnstructuredGrid>\n"
      "    <Piece NumberOfPoints=\"{}\" NumberOfCells=\"{}\">\n",
      compressor, g.num_points, g.num_cells);
  s += "      <PointData>\n";
  for (std::size_t k = 0; k < g.point_data.size(); ++k) data_array(s);
  s += "      </PointData>\n      <CellData>\n";
  for (std::size_t k = 0; k < g.cell_data.size(); ++k) data_array(s);
  s += "      </CellData>\n      <Points>\n";
  data_array(s);
  s += "      </Points>\n      <Cells>\n";
  for (int k = 0; k < 3; ++k) data_array(s);
  s += "      </Cells>\n    </Piece>\n  </UnstructuredGrid>\n  <AppendedData encoding=\"raw\">\n   "
       "_";
  return s;
}

/// Closes a FILE on every path out.
struct File {
  std::FILE* f;
  ~File() {
    if (f) std::fclose(f);
  }
};

}  // namespace

std::string xml_escape(const std::string& s) {
  std::string out;
  out.reserve(s.size());
  for (char c : s) {
    switch (c) {
      case '&':
        out += "&amp;";
        break;
      case '<':
        out += "&lt;";
        break;
      case '>':
        out += "&gt;";
        break;
      case '"':
        out += "&quot;";
        break;
      case '\'':
        out += "&apos;";
        break;
      default:
        out += c;
    }
  }
  return out;
}

void write_vtu_appended(const fs::path& path, const XmlUnstructuredGrid& g,
                        Compression compression) {
  std::vector<const XmlArray*> arrays;  // in the file's order
  for (const XmlArray& a : g.point_data) arrays.push_back(&a);
  for (const XmlArray& a : g.cell_data) arrays.push_back(&a);
  for (const XmlArray* a : {&g.points, &g.connectivity, &g.offsets, &g.types}) arrays.push_back(a);
  for (const XmlArray* a : arrays)
    TETFSI_CHECK(a->data || a->count == 0, "array '{}' of {} values has no data", a->name,
                 a->count);
  const std::vector<Encoded> enc = encode(arrays, compression);
  const std::string head = xml_head(g, arrays, enc, compression);
  File file{std::fopen(path.c_str(), "wb")};
  if (!file.f)
    throw InputError(fmt::format("cannot write '{}': {}", path.string(), std::strerror(errno)));
  bool ok = std::fwrite(head.data(), 1, head.size(), file.f) == head.size();
  for (std::size_t i = 0; ok && i < arrays.size(); ++i) {
    const std::vector<std::uint64_t>& h = enc[i].header;
    ok = std::fwrite(h.data(), sizeof(std::uint64_t), h.size(), file.f) == h.size();
    if (enc[i].raw_bytes)
      ok = ok && std::fwrite(arrays[i]->data, 1, enc[i].raw_bytes, file.f) == enc[i].raw_bytes;
    for (const std::vector<char>& b : enc[i].blocks)
      ok = ok && std::fwrite(b.data(), 1, b.size(), file.f) == b.size();
  }
  const std::string tail = "\n  </AppendedData>\n</VTKFile>\n";
  ok = ok && std::fwrite(tail.data(), 1, tail.size(), file.f) == tail.size();
  int err = ok ? 0 : errno;  // the failed write's reason, else the close's
  if (std::fclose(std::exchange(file.f, nullptr)) != 0 && ok) {
    ok = false;
    err = errno;
  }
  if (!ok) {
    std::error_code ec;
    fs::remove(path, ec);
    throw InputError(
        fmt::format("cannot write '{}': {}", path.string(), std::strerror(err ? err : EIO)));
  }
}

}  // namespace tetfsi::app
