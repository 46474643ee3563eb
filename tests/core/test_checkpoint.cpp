// Tests of core/checkpoint.hpp: exact round trips, atomic writes, and every way a file can be
// unusable giving a CheckpointError that names the file and the record.
#include <doctest/doctest.h>

#include <cmath>
#include <fstream>
#include <limits>

#include "core/checkpoint.hpp"
#include "tests/test_util.hpp"

using namespace tetfsi;
namespace fs = std::filesystem;

namespace {

std::string bytes_of(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

void put_bytes(const fs::path& p, const std::string& s) {
  std::ofstream out(p, std::ios::binary | std::ios::trunc);
  out << s;
}

/// A writer with one of everything; odd doubles whose bits must survive.
CheckpointWriter sample() {
  CheckpointWriter w;
  MatX3 x(3, 3);
  x << 1.0 / 3.0, -0.0, std::numeric_limits<double>::denorm_min(), 1e308, -1e-308, M_PI, 4, 5,
      std::nextafter(1.0, 2.0);
  w.put("solid/x", x);
  MatX4i t(2, 4);
  t << 0, 1, 2, 3, -1, 7, 8, 2147483647;
  w.put("mesh/tets", t);
  VecX empty;
  w.put("empty", empty);
  w.put("flags", std::vector<std::uint8_t>{0, 1, 255});
  w.put("time", 0.1 + 0.2);
  w.put("step", 123);
  w.put("scene", std::string("{\"name\": \"π\"}\n"));
  SparseMatrix a(4, 3);
  a.insert(0, 0) = 2.5;
  a.insert(3, 1) = -1.0 / 7.0;
  a.insert(1, 2) = 1e-300;
  a.makeCompressed();
  w.put("K", a);
  return w;
}

}  // namespace

TEST_SUITE("unit") {
  TEST_CASE("crc32 is the IEEE CRC-32 (zlib's): the standard check value of '123456789'") {
    CHECK(crc32("123456789", 9) == 0xCBF43926u);
    CHECK(crc32("", 0) == 0u);
    // continuing from a partial CRC is the CRC of the whole
    CHECK(crc32("6789", 4, crc32("12345", 5)) == 0xCBF43926u);
  }

  TEST_CASE("a checkpoint reads back bit for bit, every record type") {
    test::TempDir dir("checkpoint_roundtrip");
    const fs::path p = dir.path / "a.tfck";
    const CheckpointWriter w = sample();
    w.write(p);
    CHECK(fs::file_size(p) == w.bytes());
    CHECK_FALSE(fs::exists(p.string() + ".tmp"));
    const CheckpointReader r(p);
    CHECK(r.entries().size() == 8);
    const MatX3 x = r.get<MatX3>("solid/x");
    REQUIRE(x.rows() == 3);
    CHECK(std::signbit(x(0, 1)));  // −0 stays −0
    CHECK(x(0, 2) == std::numeric_limits<double>::denorm_min());
    CHECK(x(2, 2) == std::nextafter(1.0, 2.0));
    CHECK(x(0, 0) == 1.0 / 3.0);
    const MatX4i t = r.get<MatX4i>("mesh/tets");
    CHECK(t(1, 3) == 2147483647);
    CHECK(t(1, 0) == -1);
    CHECK(r.get<VecX>("empty").size() == 0);
    CHECK(r.get_vector<std::uint8_t>("flags") == std::vector<std::uint8_t>{0, 1, 255});
    CHECK(r.get_double("time") == 0.1 + 0.2);
    CHECK(r.get_int("step") == 123);
    CHECK(r.get_text("scene") == "{\"name\": \"π\"}\n");
    const SparseMatrix a = r.get_sparse("K");
    CHECK(a.rows() == 4);
    CHECK(a.cols() == 3);
    CHECK(a.nonZeros() == 3);
    CHECK(a.coeff(3, 1) == -1.0 / 7.0);
    CHECK(a.coeff(1, 2) == 1e-300);
    // a column vector written from a VecX reads back as one
    CheckpointWriter v;
    VecX y = VecX::LinSpaced(5, 0.0, 1.0);
    v.put("y", y);
    v.write(p);
    CHECK(CheckpointReader(p).get<VecX>("y") == y);
  }

  TEST_CASE("a missing key, a wrong type or shape is an error naming the file and the record") {
    test::TempDir dir("checkpoint_keys");
    const fs::path p = dir.path / "a.tfck";
    sample().write(p);
    const CheckpointReader r(p);
    const std::string missing = test::message_of<CheckpointError>([&] { r.get<VecX>("nope"); });
    CHECK(missing.find("a.tfck") != std::string::npos);
    CHECK(missing.find("'nope'") != std::string::npos);
    const std::string type = test::message_of<CheckpointError>([&] { r.get<MatX4i>("solid/x"); });
    CHECK(type.find("'solid/x' is f64, expected i32") != std::string::npos);
    const std::string shape =
        test::message_of<CheckpointError>([&] { r.get<MatX3i>("mesh/tets"); });
    CHECK(shape.find("'mesh/tets' has 4 columns, expected 3") != std::string::npos);
    CHECK(test::message_of<CheckpointError>([&] {
            r.get_double("solid/x");
          }).find("has 3 columns, expected 1") != std::string::npos);
  }

  TEST_CASE("a truncated, corrupt, foreign or other-version file is refused, naming the fault") {
    test::TempDir dir("checkpoint_bad");
    const fs::path good = dir.path / "good.tfck";
    sample().write(good);
    const std::string bytes = bytes_of(good);
    const fs::path p = dir.path / "bad.tfck";
    auto error_of = [&](const std::string& content) {
      put_bytes(p, content);
      return test::message_of<CheckpointError>([&] { CheckpointReader r(p); });
    };
    // cut at every length: never accepted, always "truncated" (or, in the end marker, corrupt)
    for (std::size_t n = 0; n < bytes.size(); n += 7) {
      const std::string e = error_of(bytes.substr(0, n));
      CAPTURE(n);
      REQUIRE_FALSE(e.empty());
      CHECK(e.find("bad.tfck") != std::string::npos);
      CHECK((e.find("truncated") != std::string::npos || e.find("corrupt") != std::string::npos));
    }
    // one flipped bit in a payload: the record's CRC names it
    std::string flipped = bytes;
    const std::size_t at = bytes.find("solid/x") + 7 + 28 + 5;
    flipped[at] = static_cast<char>(flipped[at] ^ 0x10);
    CHECK(error_of(flipped).find("record 'solid/x' is corrupt (CRC-32 mismatch)") !=
          std::string::npos);
    // another version
    std::string v2 = bytes;
    v2[8] = 2;
    CHECK(error_of(v2).find("format version 2, this tetfsi reads version 1") != std::string::npos);
    // not a checkpoint at all
    CHECK(error_of("{\"scene\": 1}" + std::string(40, ' ')).find("not a tetfsi checkpoint") !=
          std::string::npos);
    // bytes after the end marker
    CHECK(error_of(bytes + "x").find("follow its end marker") != std::string::npos);
    // a record length far beyond the file: refused before allocating
    std::string huge = bytes;
    const std::size_t len_at = bytes.find("solid/x") + 7 + 20;
    for (int k = 0; k < 8; ++k) huge[len_at + k] = static_cast<char>(0xFF);
    CHECK(error_of(huge).find("truncated") != std::string::npos);
    CHECK(test::message_of<CheckpointError>([&] {
            CheckpointReader r(dir.path / "none.tfck");
          }).find("no such file") != std::string::npos);
  }

  TEST_CASE("a failed write leaves the previous file and no temporary behind") {
    test::TempDir dir("checkpoint_atomic");
    const fs::path p = dir.path / "a.tfck";
    sample().write(p);
    const std::string before = bytes_of(p);
    // a folder where the temporary file should go makes the open fail
    fs::create_directories(p.string() + ".tmp");
    CheckpointWriter w;
    w.put("x", 1.0);
    const std::string e = test::message_of<Error>([&] { w.write(p); });
    CHECK(e.find("cannot write checkpoint") != std::string::npos);
    CHECK(e.find("previous checkpoints are kept") != std::string::npos);
    CHECK(bytes_of(p) == before);
  }

  TEST_CASE("scripts/read_checkpoint.py reads the format as documented: every record and CRC") {
    test::TempDir dir("checkpoint_python");
    const fs::path p = dir.path / "a.tfck";
    sample().write(p);
    const fs::path out = dir.path / "out.txt";
    const std::string script = std::string(TETFSI_SOURCE_DIR) + "/scripts/read_checkpoint.py";
    auto run = [&](const std::string& args) {
      const std::string cmd = fmt::format("/usr/bin/python3 '{}' '{}' {} > '{}' 2>&1", script,
                                          p.string(), args, out.string());
      const int rc = std::system(cmd.c_str());
      return std::make_pair(rc, bytes_of(out));
    };
    const auto [rc, listing] = run("");
    INFO(listing);
    REQUIRE(rc == 0);
    for (const char* line : {"solid/x", "float64 3 x 3", "mesh/tets", "int32 2 x 4",
                             "sparse 4 x 3, 3", "text, 14 chars", "uint8 3"})
      CHECK(listing.find(line) != std::string::npos);
    // the values, as numpy prints them
    CHECK(run("mesh/tets").second.find("2147483647") != std::string::npos);
    CHECK(run("step").second.find("[123]") != std::string::npos);
    // and a flipped bit is caught by zlib's CRC-32 too
    std::string bad = bytes_of(p);
    bad[bad.find("mesh/tets") + 9 + 28] ^= 1;
    put_bytes(p, bad);
    const auto [rc_bad, msg] = run("");
    CHECK(rc_bad != 0);
    CHECK(msg.find("record 'mesh/tets' is corrupt") != std::string::npos);
  }
}
