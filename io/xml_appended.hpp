#pragma once
/// @file xml_appended.hpp
/// VTK XML unstructured grids (.vtu) written by tetfsi itself, for the fluid mesh's frames:
/// the same file layout as VTK's own writer (appended raw data, UInt64 block headers, LZ4 /
/// zlib blocks of 32 KiB), but every block of every array compressed in parallel, and each
/// array read straight from tetfsi's buffers (VTK's writer compresses one block after another
/// on one thread and copies each array into its own). Any VTK reader (ParaView, VTK's Python)
/// reads the files; mesh/vtu_check.cpp checks them as it checks every .vtu.
#include <cstddef>
#include <filesystem>
#include <string>
#include <vector>

#include "core/types.hpp"
#include "io/output.hpp"

namespace tetfsi::app {

/// The value types the fluid frames use.
enum class XmlValueType { Int32, UInt8, Float64 };

/// One DataArray: `count` values of `type` at `data` (native little-endian, tuples of
/// `components`); the caller keeps them alive until the write returns. With `range`, the
/// RangeMin / RangeMax attributes VTK writes (the values' range, or for several components the
/// range of the tuples' Euclidean norms, as VTK does).
struct XmlArray {
  std::string name;
  XmlValueType type = XmlValueType::Float64;
  int components = 1;
  const void* data = nullptr;
  std::size_t count = 0;
  bool range = true;
};

/// An unstructured grid of one piece: `points` (Float64 × 3), the cells as VTK's connectivity
/// (Int32), end offsets (Int32, one per cell) and types (UInt8), and the point and cell data.
struct XmlUnstructuredGrid {
  std::size_t num_points = 0, num_cells = 0;
  std::vector<XmlArray> point_data, cell_data;
  XmlArray points, connectivity, offsets, types;
};

/// Write `grid` to `path` (through `<path>.tmp` and a rename, as every frame file) with
/// `compression`; the blocks are compressed in parallel (core/parallel.hpp), and the bytes are
/// the same at any thread count.
/// @throws InputError "cannot write '<path>': <reason>" (the file is then not there)
void write_vtu_appended(const std::filesystem::path& path, const XmlUnstructuredGrid& grid,
                        Compression compression);

/// `s` with the five XML special characters escaped, for an attribute value.
std::string xml_escape(const std::string& s);

}  // namespace tetfsi::app
