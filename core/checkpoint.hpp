#pragma once
/// @file checkpoint.hpp
/// A checkpoint file: named records of exact binary arrays, each with its own CRC-32, written
/// atomically (docs/dev/architecture.md; `tetfsi run --checkpoint-every`, `tetfsi resume`).
///
/// Layout (little-endian, version k_checkpoint_version):
///
///     header   "TETFSICK" | u32 version | u32 0 | u64 record count
///     record   u32 key length | key | u8 type | u8 0 | u16 0 | u64 rows | u64 cols
///              | u64 payload bytes | payload (row-major) | u32 CRC-32 of everything before it
///              in the record
///     trailer  "TETFSEND" | u64 record count | u32 CRC-32 of the records' CRCs
///
/// Keys are paths ("solid/body/0/displacement"); types are f64, i32, i8, u8, i64 arrays, UTF-8
/// text and CSC sparse matrices (rows × cols, then u64 nnz, i32 outer[cols + 1], i32 inner[nnz],
/// f64 values[nnz]). Doubles are stored as their bits, so a state read back is the state
/// written, bit for bit. `tetfsi checkpoint FILE` lists the records.
///
/// Every failure to read (a missing, truncated or corrupt file, another format version, a
/// missing key or a record of the wrong type or shape) is a CheckpointError naming the file and
/// the record; sizes are checked against the file's length before anything is allocated.
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "core/error.hpp"
#include "core/types.hpp"

namespace tetfsi {

inline constexpr std::uint32_t k_checkpoint_version = 1;

/// A checkpoint that cannot be used (message names the file and what is wrong).
class CheckpointError : public Error {
 public:
  using Error::Error;
};

/// CRC-32 (IEEE 802.3, as zlib's crc32) of `n` bytes, continuing from `crc`.
std::uint32_t crc32(const void* data, std::size_t n, std::uint32_t crc = 0);

enum class RecordType : std::uint8_t {
  F64 = 1,
  I32 = 2,
  I8 = 3,
  U8 = 4,
  I64 = 5,
  Text = 6,
  Sparse = 7
};
const char* to_string(RecordType t);

namespace detail {
template <class S>
constexpr RecordType record_type_of();
template <>
constexpr RecordType record_type_of<double>() {
  return RecordType::F64;
}
template <>
constexpr RecordType record_type_of<int>() {
  return RecordType::I32;
}
template <>
constexpr RecordType record_type_of<std::int8_t>() {
  return RecordType::I8;
}
template <>
constexpr RecordType record_type_of<std::uint8_t>() {
  return RecordType::U8;
}
template <>
constexpr RecordType record_type_of<std::int64_t>() {
  return RecordType::I64;
}
}  // namespace detail

class CheckpointWriter {
 public:
  /// A dense array: a vector is rows × 1; matrices are stored row-major whatever their layout.
  template <class Derived>
  void put(const std::string& key, const Eigen::DenseBase<Derived>& a) {
    using S = typename Derived::Scalar;
    Eigen::Matrix<S, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> rm = a;
    add(key, detail::record_type_of<S>(), static_cast<std::uint64_t>(rm.rows()),
        static_cast<std::uint64_t>(rm.cols()), rm.data(), sizeof(S) * rm.size());
  }
  template <class S>
  void put(const std::string& key, const std::vector<S>& v) {
    add(key, detail::record_type_of<S>(), v.size(), 1, v.data(), sizeof(S) * v.size());
  }
  void put(const std::string& key, double v) { put(key, std::vector<double>{v}); }
  void put(const std::string& key, std::int64_t v) { put(key, std::vector<std::int64_t>{v}); }
  void put(const std::string& key, int v) { put(key, static_cast<std::int64_t>(v)); }
  void put(const std::string& key, bool v) { put(key, static_cast<std::int64_t>(v)); }
  void put(const std::string& key, const std::string& text);
  void put(const std::string& key, const char* text) { put(key, std::string(text)); }
  void put(const std::string& key, const SparseMatrix& a);

  bool has(const std::string& key) const;
  /// Bytes the file will have.
  std::size_t bytes() const;
  /// Write to `path` atomically: `path`.tmp, fsync, rename over `path`, fsync the folder. A
  /// crash at any moment leaves either the old file or the new one, never a partial one.
  /// @throws Error naming the file on any I/O failure (the temporary file is removed).
  void write(const std::filesystem::path& path) const;

 private:
  void add(const std::string& key, RecordType type, std::uint64_t rows, std::uint64_t cols,
           const void* data, std::size_t bytes);
  std::vector<std::string> m_keys;
  std::vector<std::vector<char>> m_records;  ///< each record's bytes, CRC included
};

class CheckpointReader {
 public:
  struct Entry {
    std::string key;
    RecordType type = RecordType::F64;
    std::uint64_t rows = 0, cols = 0;
    std::size_t offset = 0, bytes = 0;  ///< the payload within the file
  };

  /// Read and verify the whole file (header, every record's CRC, trailer).
  /// @throws CheckpointError naming the file and what is wrong.
  explicit CheckpointReader(std::filesystem::path path);

  const std::filesystem::path& path() const { return m_path; }
  const std::vector<Entry>& entries() const { return m_entries; }
  bool has(const std::string& key) const;
  std::size_t file_bytes() const { return m_data.size(); }

  /// A dense array of the given Eigen type (fixed column counts are checked).
  /// @throws CheckpointError naming the file and key if absent, of another type or shape.
  template <class M>
  M get(const std::string& key) const {
    using S = typename M::Scalar;
    const Entry& e = entry(key, detail::record_type_of<S>());
    check_cols(e, M::ColsAtCompileTime);
    Eigen::Matrix<S, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> rm(
        static_cast<Index>(e.rows), static_cast<Index>(e.cols));
    copy(e, rm.data());
    if constexpr (M::ColsAtCompileTime == 1)
      return M(Eigen::Map<const Eigen::Matrix<S, Eigen::Dynamic, 1>>(rm.data(), rm.size()));
    else
      return M(rm);
  }
  template <class S>
  std::vector<S> get_vector(const std::string& key) const {
    const Entry& e = entry(key, detail::record_type_of<S>());
    check_cols(e, 1);
    std::vector<S> v(e.rows);
    copy(e, v.data());
    return v;
  }
  double get_double(const std::string& key) const;
  std::int64_t get_int(const std::string& key) const;
  bool get_bool(const std::string& key) const { return get_int(key) != 0; }
  std::string get_text(const std::string& key) const;
  /// A count (an i64 record) of at most `limit`, as a size. @throws CheckpointError otherwise.
  std::size_t get_count(const std::string& key, std::int64_t limit = 1'000'000) const;
  SparseMatrix get_sparse(const std::string& key) const;

  /// "checkpoint 'FILE': " + what: the prefix of every error about this file.
  [[noreturn]] void fail(const std::string& what) const;

 private:
  const Entry& entry(const std::string& key, RecordType type) const;
  void check_cols(const Entry& e, int cols) const;
  void copy(const Entry& e, void* out) const;

  std::filesystem::path m_path;
  std::vector<char> m_data;
  std::vector<Entry> m_entries;
};

}  // namespace tetfsi
