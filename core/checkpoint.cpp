#include "core/checkpoint.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <array>
#include <cerrno>
#include <cstring>
#include <fstream>
#include <limits>

namespace tetfsi {

namespace fs = std::filesystem;

namespace {

constexpr char k_magic[8] = {'T', 'E', 'T', 'F', 'S', 'I', 'C', 'K'};
constexpr char k_end[8] = {'T', 'E', 'T', 'F', 'S', 'E', 'N', 'D'};
constexpr std::size_t k_header_bytes = 8 + 4 + 4 + 8;
constexpr std::size_t k_trailer_bytes = 8 + 8 + 4;
/// Records' fixed part after the key: type, 0, 0 (u8 u8 u16), rows, cols, bytes.
constexpr std::size_t k_record_fixed = 1 + 1 + 2 + 8 + 8 + 8;
constexpr std::size_t k_max_key = 4096;

std::array<std::uint32_t, 256> make_crc_table() {
  std::array<std::uint32_t, 256> t{};
  for (std::uint32_t i = 0; i < 256; ++i) {
    std::uint32_t c = i;
    for (int k = 0; k < 8; ++k) c = (c & 1u) ? 0xEDB88320u ^ (c >> 1) : c >> 1;
    t[i] = c;
  }
  return t;
}

template <class T>
void append(std::vector<char>& out, const T& v) {
  const char* p = reinterpret_cast<const char*>(&v);
  out.insert(out.end(), p, p + sizeof(T));
}

template <class T>
T read_at(const std::vector<char>& d, std::size_t at) {
  T v;
  std::memcpy(&v, d.data() + at, sizeof(T));
  return v;
}

std::size_t element_bytes(RecordType t) {
  switch (t) {
    case RecordType::F64:
    case RecordType::I64:
      return 8;
    case RecordType::I32:
      return 4;
    case RecordType::I8:
    case RecordType::U8:
    case RecordType::Text:
      return 1;
    case RecordType::Sparse:
      return 0;
  }
  return 0;
}

/// write(2) all of it or fail.
bool write_all(int fd, const char* p, std::size_t n) {
  while (n > 0) {
    const ssize_t w = ::write(fd, p, n);
    if (w < 0) {
      if (errno == EINTR) continue;
      return false;
    }
    p += w;
    n -= static_cast<std::size_t>(w);
  }
  return true;
}

}  // namespace

std::uint32_t crc32(const void* data, std::size_t n, std::uint32_t crc) {
  static const std::array<std::uint32_t, 256> table = make_crc_table();
  const auto* p = static_cast<const unsigned char*>(data);
  crc = ~crc;
  for (std::size_t i = 0; i < n; ++i) crc = table[(crc ^ p[i]) & 0xFFu] ^ (crc >> 8);
  return ~crc;
}

const char* to_string(RecordType t) {
  switch (t) {
    case RecordType::F64:
      return "f64";
    case RecordType::I32:
      return "i32";
    case RecordType::I8:
      return "i8";
    case RecordType::U8:
      return "u8";
    case RecordType::I64:
      return "i64";
    case RecordType::Text:
      return "text";
    case RecordType::Sparse:
      return "sparse";
  }
  return "?";
}

// ---- writer ------------------------------------------------------------------------------

void CheckpointWriter::add(const std::string& key, RecordType type, std::uint64_t rows,
                           std::uint64_t cols, const void* data, std::size_t bytes) {
  TETFSI_CHECK(!key.empty() && key.size() <= k_max_key, "checkpoint key of {} bytes", key.size());
  TETFSI_CHECK(!has(key), "checkpoint key '{}' written twice", key);
  std::vector<char> r;
  r.reserve(4 + key.size() + k_record_fixed + bytes + 4);
  append(r, static_cast<std::uint32_t>(key.size()));
  r.insert(r.end(), key.begin(), key.end());
  append(r, static_cast<std::uint8_t>(type));
  append(r, std::uint8_t{0});
  append(r, std::uint16_t{0});
  append(r, rows);
  append(r, cols);
  append(r, static_cast<std::uint64_t>(bytes));
  const char* p = static_cast<const char*>(data);
  if (bytes > 0) r.insert(r.end(), p, p + bytes);
  append(r, crc32(r.data(), r.size()));
  m_keys.push_back(key);
  m_records.push_back(std::move(r));
}

void CheckpointWriter::put(const std::string& key, const std::string& text) {
  add(key, RecordType::Text, text.size(), 1, text.data(), text.size());
}

void CheckpointWriter::put(const std::string& key, const SparseMatrix& a_in) {
  SparseMatrix a = a_in;
  a.makeCompressed();
  const std::uint64_t nnz = static_cast<std::uint64_t>(a.nonZeros());
  std::vector<char> payload;
  append(payload, nnz);
  const auto* outer = reinterpret_cast<const char*>(a.outerIndexPtr());
  payload.insert(payload.end(), outer, outer + sizeof(Index) * (a.outerSize() + 1));
  const auto* inner = reinterpret_cast<const char*>(a.innerIndexPtr());
  payload.insert(payload.end(), inner, inner + sizeof(Index) * nnz);
  const auto* values = reinterpret_cast<const char*>(a.valuePtr());
  payload.insert(payload.end(), values, values + sizeof(double) * nnz);
  add(key, RecordType::Sparse, static_cast<std::uint64_t>(a.rows()),
      static_cast<std::uint64_t>(a.cols()), payload.data(), payload.size());
}

bool CheckpointWriter::has(const std::string& key) const {
  for (const std::string& k : m_keys)
    if (k == key) return true;
  return false;
}

std::size_t CheckpointWriter::bytes() const {
  std::size_t n = k_header_bytes + k_trailer_bytes;
  for (const auto& r : m_records) n += r.size();
  return n;
}

void CheckpointWriter::write(const fs::path& path) const {
  const fs::path tmp = path.string() + ".tmp";
  std::vector<char> head;
  head.insert(head.end(), k_magic, k_magic + 8);
  append(head, k_checkpoint_version);
  append(head, std::uint32_t{0});
  append(head, static_cast<std::uint64_t>(m_records.size()));
  std::vector<char> tail(k_end, k_end + 8);
  append(tail, static_cast<std::uint64_t>(m_records.size()));
  std::vector<std::uint32_t> crcs;
  for (const auto& r : m_records) crcs.push_back(read_at<std::uint32_t>(r, r.size() - 4));
  append(tail, crc32(crcs.data(), sizeof(std::uint32_t) * crcs.size()));

  int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  // Any failure: the temporary file goes, the previous checkpoint stays.
  auto fail = [&](const char* what) {
    const std::string why = std::strerror(errno);
    if (fd >= 0) ::close(fd);
    std::error_code ec;
    fs::remove(tmp, ec);
    throw Error(
        fmt::format("cannot write checkpoint '{}' ({}: {}); the previous checkpoints are "
                    "kept",
                    path.string(), what, why));
  };
  if (fd < 0) fail("open");
  bool ok = write_all(fd, head.data(), head.size());
  for (const auto& r : m_records) ok = ok && write_all(fd, r.data(), r.size());
  ok = ok && write_all(fd, tail.data(), tail.size());
  if (!ok) fail("write");
  if (::fsync(fd) != 0) fail("fsync");
  const int closed = ::close(fd);
  fd = -1;
  if (closed != 0) fail("close");
  if (::rename(tmp.c_str(), path.c_str()) != 0) fail("rename");
  // The rename itself is durable only once the folder is synced.
  const fs::path dir = path.has_parent_path() ? path.parent_path() : fs::path(".");
  const int dfd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (dfd >= 0) {
    ::fsync(dfd);
    ::close(dfd);
  }
}

// ---- reader ------------------------------------------------------------------------------

void CheckpointReader::fail(const std::string& what) const {
  throw CheckpointError(fmt::format("checkpoint '{}': {}", m_path.string(), what));
}

CheckpointReader::CheckpointReader(fs::path path) : m_path(std::move(path)) {
  std::error_code ec;
  if (!fs::is_regular_file(m_path, ec)) fail("no such file");
  std::ifstream in(m_path, std::ios::binary | std::ios::ate);
  if (!in) fail(fmt::format("cannot open it: {}", std::strerror(errno)));
  const std::streamoff size = in.tellg();
  if (size < 0) fail("cannot read its size");
  m_data.resize(static_cast<std::size_t>(size));
  in.seekg(0);
  if (size > 0 && !in.read(m_data.data(), size)) fail("cannot read it");
  const std::size_t n = m_data.size();
  const std::string truncated = "is truncated (it was not completely written)";
  if (n < k_header_bytes) fail(fmt::format("{}: {} bytes", truncated, n));
  if (std::memcmp(m_data.data(), k_magic, 8) != 0)
    fail("is not a tetfsi checkpoint (its first bytes are not 'TETFSICK')");
  const auto version = read_at<std::uint32_t>(m_data, 8);
  if (version != k_checkpoint_version)
    fail(
        fmt::format("has format version {}, this tetfsi reads version {}; resume it with the "
                    "tetfsi that wrote it",
                    version, k_checkpoint_version));
  const auto count = read_at<std::uint64_t>(m_data, 16);
  std::size_t at = k_header_bytes;
  std::vector<std::uint32_t> crcs;
  for (std::uint64_t i = 0; i < count; ++i) {
    const std::size_t start = at;
    if (n - at < 4) fail(fmt::format("{} (record {} of {} is missing)", truncated, i + 1, count));
    const auto klen = read_at<std::uint32_t>(m_data, at);
    at += 4;
    if (klen == 0 || klen > k_max_key)
      fail(fmt::format("record {} has a corrupt key length ({})", i + 1, klen));
    if (n - at < klen + k_record_fixed)
      fail(fmt::format("{} (record {} of {} is cut short)", truncated, i + 1, count));
    Entry e;
    e.key.assign(m_data.data() + at, klen);
    at += klen;
    const auto type = read_at<std::uint8_t>(m_data, at);
    e.rows = read_at<std::uint64_t>(m_data, at + 4);
    e.cols = read_at<std::uint64_t>(m_data, at + 12);
    const auto bytes = read_at<std::uint64_t>(m_data, at + 20);
    at += k_record_fixed;
    if (bytes > n - at || n - at - bytes < 4)
      fail(fmt::format("{} (record '{}' needs {} bytes, the file has {} left)", truncated, e.key,
                       bytes, n - at));
    const auto crc = read_at<std::uint32_t>(m_data, at + bytes);
    if (crc32(m_data.data() + start, at + bytes - start) != crc)
      fail(fmt::format("record '{}' is corrupt (CRC-32 mismatch)", e.key));
    if (type < 1 || type > 7) fail(fmt::format("record '{}' has an unknown type {}", e.key, type));
    e.type = static_cast<RecordType>(type);
    const std::size_t eb = element_bytes(e.type);
    const bool empty = e.rows == 0 || e.cols == 0;
    if (eb > 0 &&
        (empty ? bytes != 0
               : bytes % eb != 0 || (bytes / eb) % e.cols != 0 || bytes / eb / e.cols != e.rows))
      fail(fmt::format("record '{}' says {} × {} {} but holds {} bytes", e.key, e.rows, e.cols,
                       to_string(e.type), bytes));
    e.offset = at;
    e.bytes = bytes;
    at += bytes + 4;
    crcs.push_back(crc);
    m_entries.push_back(std::move(e));
  }
  if (n - at < k_trailer_bytes) fail(fmt::format("{} (its end marker is missing)", truncated));
  if (std::memcmp(m_data.data() + at, k_end, 8) != 0 ||
      read_at<std::uint64_t>(m_data, at + 8) != count ||
      read_at<std::uint32_t>(m_data, at + 16) !=
          crc32(crcs.data(), sizeof(std::uint32_t) * crcs.size()))
    fail("is corrupt (its end marker does not match its records)");
  if (at + k_trailer_bytes != n)
    fail(fmt::format("is corrupt ({} bytes follow its end marker)", n - at - k_trailer_bytes));
}

bool CheckpointReader::has(const std::string& key) const {
  for (const Entry& e : m_entries)
    if (e.key == key) return true;
  return false;
}

const CheckpointReader::Entry& CheckpointReader::entry(const std::string& key,
                                                       RecordType type) const {
  for (const Entry& e : m_entries) {
    if (e.key != key) continue;
    if (e.type != type)
      fail(fmt::format("record '{}' is {}, expected {}", key, to_string(e.type), to_string(type)));
    return e;
  }
  fail(fmt::format("has no record '{}' (written by another kind of run?)", key));
}

void CheckpointReader::check_cols(const Entry& e, int cols) const {
  if (cols > 0 && e.cols != static_cast<std::uint64_t>(cols) && !(e.rows == 0 && e.cols == 0))
    fail(fmt::format("record '{}' has {} columns, expected {}", e.key, e.cols, cols));
  if (e.rows > static_cast<std::uint64_t>(std::numeric_limits<Index>::max()) ||
      e.cols > static_cast<std::uint64_t>(std::numeric_limits<Index>::max()))
    fail(fmt::format("record '{}' is too large ({} × {})", e.key, e.rows, e.cols));
}

void CheckpointReader::copy(const Entry& e, void* out) const {
  if (e.bytes > 0) std::memcpy(out, m_data.data() + e.offset, e.bytes);
}

double CheckpointReader::get_double(const std::string& key) const {
  const std::vector<double> v = get_vector<double>(key);
  if (v.size() != 1) fail(fmt::format("record '{}' has {} values, expected 1", key, v.size()));
  return v[0];
}

std::int64_t CheckpointReader::get_int(const std::string& key) const {
  const std::vector<std::int64_t> v = get_vector<std::int64_t>(key);
  if (v.size() != 1) fail(fmt::format("record '{}' has {} values, expected 1", key, v.size()));
  return v[0];
}

std::size_t CheckpointReader::get_count(const std::string& key, std::int64_t limit) const {
  const std::int64_t n = get_int(key);
  if (n < 0 || n > limit) fail(fmt::format("record '{}' is {}, expected 0..{}", key, n, limit));
  return static_cast<std::size_t>(n);
}

std::string CheckpointReader::get_text(const std::string& key) const {
  const Entry& e = entry(key, RecordType::Text);
  return std::string(m_data.data() + e.offset, e.bytes);
}

SparseMatrix CheckpointReader::get_sparse(const std::string& key) const {
  const Entry& e = entry(key, RecordType::Sparse);
  const std::string bad = fmt::format("record '{}' is not a valid sparse matrix", key);
  const std::uint64_t imax = static_cast<std::uint64_t>(std::numeric_limits<Index>::max());
  if (e.bytes < 8 || e.rows > imax || e.cols > imax) fail(bad);
  const auto nnz = read_at<std::uint64_t>(m_data, e.offset);
  const std::uint64_t need = 8 + sizeof(Index) * (e.cols + 1) + (sizeof(Index) + 8) * nnz;
  if (nnz > e.bytes || need != e.bytes) fail(bad);
  const char* p = m_data.data() + e.offset + 8;
  std::vector<Index> outer(e.cols + 1), inner(nnz);
  std::vector<double> values(nnz);
  std::memcpy(outer.data(), p, sizeof(Index) * outer.size());
  p += sizeof(Index) * outer.size();
  std::memcpy(inner.data(), p, sizeof(Index) * nnz);
  p += sizeof(Index) * nnz;
  std::memcpy(values.data(), p, 8 * nnz);
  if (outer.front() != 0 || static_cast<std::uint64_t>(outer.back()) != nnz) fail(bad);
  for (std::size_t c = 0; c + 1 < outer.size(); ++c)
    if (outer[c + 1] < outer[c]) fail(bad);
  for (Index i : inner)
    if (i < 0 || static_cast<std::uint64_t>(i) >= e.rows) fail(bad);
  SparseMatrix a(static_cast<Index>(e.rows), static_cast<Index>(e.cols));
  a.resizeNonZeros(static_cast<Index>(nnz));
  std::memcpy(a.outerIndexPtr(), outer.data(), sizeof(Index) * outer.size());
  std::memcpy(a.innerIndexPtr(), inner.data(), sizeof(Index) * nnz);
  std::memcpy(a.valuePtr(), values.data(), 8 * nnz);
  return a;
}

}  // namespace tetfsi
