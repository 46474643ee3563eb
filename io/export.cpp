/// @file export.cpp
/// The renderer export of export.hpp but for its OpenVDB side (vdb.cpp): the bodies' boundary
/// surfaces and their binary PLY files, the tet fluid's voxel sampling, one frame's files and
/// the manifest export.json.
#include "io/export.hpp"

#include <algorithm>
#include <atomic>
#include <bit>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <utility>

#include <fmt/format.h>

#include "core/error.hpp"
#include "core/parallel.hpp"
#include "io/output.hpp"
#include "mesh/volume_mesh.hpp"
#include "solid/solid_body.hpp"

namespace fs = std::filesystem;

namespace tetfsi::app {

static_assert(std::endian::native == std::endian::little,
              "the PLY writer and reader copy little-endian values as they are in memory");

namespace {

// ---- surfaces ------------------------------------------------------------------------------

/// Per node of `nv`: its index among the nodes `triangles` use (in increasing node order), or
/// −1; `used` gets how many there are.
VecXi compact_numbering(const MatX3i& triangles, Index nv, Index& used) {
  VecXi index = VecXi::Constant(nv, -1);
  for (Index f = 0; f < triangles.rows(); ++f)
    for (int c = 0; c < 3; ++c) index[triangles(f, c)] = 0;
  used = 0;
  for (Index v = 0; v < nv; ++v)
    if (index[v] == 0) index[v] = used++;
  return index;
}

/// The mean of `tet_value` over the tets that share each node of the compact numbering.
VecX node_means(const MatX4i& tets, const VecX& tet_value, const VecXi& compact, Index used) {
  VecX sum = VecX::Zero(used), count = VecX::Zero(used);
  for (Index t = 0; t < tets.rows(); ++t) {
    for (int k = 0; k < 4; ++k) {
      const Index p = compact[tets(t, k)];
      if (p < 0) continue;
      sum[p] += tet_value[t];
      count[p] += 1.0;
    }
  }
  return sum.cwiseQuotient(count.cwiseMax(1.0));
}

// ---- PLY -----------------------------------------------------------------------------------

/// What is wrong with a PLY file (read_ply adds the file's name).
struct PlyFormatError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

/// Append the bytes of `value` to `out` (little-endian, as in memory).
template <class T>
void put(std::string& out, T value) {
  char bytes[sizeof(T)];
  std::memcpy(bytes, &value, sizeof(T));
  out.append(bytes, sizeof(T));
}

/// The PLY header of `s`: the vertex properties it has, triangles as lists.
std::string ply_header(const ExportSurface& s) {
  std::string h = "ply\nformat binary_little_endian 1.0\ncomment tetfsi export: metres";
  h += s.velocity.rows() > 0 ? ", velocity m/s" : "";
  h += s.von_mises.size() > 0 ? ", von_mises Pa" : "";
  h += fmt::format("\nelement vertex {}\n", s.points.rows());
  for (const char* p : {"x", "y", "z"}) h += fmt::format("property float {}\n", p);
  if (s.velocity.rows() > 0)
    for (const char* p : {"vx", "vy", "vz"}) h += fmt::format("property float {}\n", p);
  if (s.von_mises.size() > 0) h += "property float von_mises\n";
  h += fmt::format("element face {}\nproperty list uchar int vertex_indices\nend_header\n",
                   s.triangles.rows());
  return h;
}

/// @throws InternalError if an array of `s` has the wrong size or a triangle indexes past #P.
void check_surface(const ExportSurface& s) {
  const Index np = static_cast<Index>(s.points.rows());
  TETFSI_CHECK(s.velocity.rows() == 0 || s.velocity.rows() == np,
               "surface velocity has {} rows for {} points", s.velocity.rows(), np);
  TETFSI_CHECK(s.von_mises.size() == 0 || s.von_mises.size() == np,
               "surface von_mises has {} values for {} points", s.von_mises.size(), np);
  if (s.triangles.rows() == 0) return;
  TETFSI_CHECK(s.triangles.minCoeff() >= 0 && s.triangles.maxCoeff() < np,
               "surface triangles index {} .. {}, outside the {} points", s.triangles.minCoeff(),
               s.triangles.maxCoeff(), np);
}

/// The vertex and face counts and the vertex properties of a PLY header.
struct PlyLayout {
  Index vertices = -1, faces = 0;
  std::vector<std::string> properties;  ///< the vertex properties in order (all float)
  std::size_t data_start = 0;           ///< the first byte after "end_header\n"
};

/// Parse one header line of a PLY into `layout`. `element` is the element being declared.
/// @throws PlyFormatError saying what is wrong
void parse_ply_line(const std::string& line, std::string& element, PlyLayout& layout) {
  std::istringstream in(line);
  std::string word, a, b, c, d;
  in >> word;
  if (word.empty() || word == "comment" || word == "obj_info") return;
  if (word == "format") {
    in >> a >> b;
    if (a != "binary_little_endian" || b != "1.0")
      throw PlyFormatError(fmt::format("format '{} {}', expected binary_little_endian 1.0", a, b));
  } else if (word == "element") {
    long long n = -1;
    in >> element >> n;
    if (n < 0 || n > std::numeric_limits<Index>::max())
      throw PlyFormatError(fmt::format("bad element line '{}'", line));
    if (element == "vertex" && layout.vertices < 0)
      layout.vertices = static_cast<Index>(n);
    else if (element == "face" && layout.vertices >= 0)
      layout.faces = static_cast<Index>(n);
    else
      throw PlyFormatError(fmt::format("unexpected '{}' (vertex, then face)", line));
  } else if (word == "property" && element == "vertex") {
    in >> a >> b;
    if (a != "float" && a != "float32")
      throw PlyFormatError(fmt::format("vertex property '{}' is {}, expected float", b, a));
    layout.properties.push_back(b);
  } else if (word == "property" && element == "face") {
    in >> a >> b >> c >> d;
    if (a != "list" || (b != "uchar" && b != "uint8") || (c != "int" && c != "int32"))
      throw PlyFormatError(fmt::format("face property '{}': expected list uchar int", line));
  } else {
    throw PlyFormatError(fmt::format("unexpected header line '{}'", line));
  }
}

/// The header of a PLY file's bytes.
PlyLayout parse_ply_header(const std::string& bytes) {
  const std::size_t end = bytes.find("end_header\n");
  if (bytes.rfind("ply", 0) != 0 || end == std::string::npos)
    throw PlyFormatError("not a PLY file (no 'ply' ... 'end_header')");
  PlyLayout layout;
  layout.data_start = end + 11;
  std::istringstream lines(bytes.substr(0, end));
  std::string line, element;
  std::getline(lines, line);  // "ply"
  bool format = false;
  while (std::getline(lines, line)) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    format = format || line.rfind("format", 0) == 0;
    parse_ply_line(line, element, layout);
  }
  if (!format || layout.vertices < 0)
    throw PlyFormatError("the header has no format or no vertex element");
  return layout;
}

/// The column of property `name` among `props`, or −1.
int property_column(const std::vector<std::string>& props, const char* name) {
  const auto it = std::find(props.begin(), props.end(), name);
  return it == props.end() ? -1 : static_cast<int>(it - props.begin());
}

/// The vertex block of a PLY into `s` (the columns it knows); returns the offset after it.
std::size_t read_ply_vertices(const std::string& bytes, const PlyLayout& l, ExportSurface& s) {
  const std::size_t nprop = l.properties.size(), nv = static_cast<std::size_t>(l.vertices);
  if (bytes.size() - l.data_start < nv * nprop * 4)
    throw PlyFormatError(fmt::format("truncated: {} vertices do not fit", nv));
  std::array<int, 7> col{};
  const char* names[7] = {"x", "y", "z", "vx", "vy", "vz", "von_mises"};
  for (int k = 0; k < 7; ++k) col[k] = property_column(l.properties, names[k]);
  if (col[0] < 0 || col[1] < 0 || col[2] < 0)
    throw PlyFormatError("the vertices have no x, y and z");
  const bool velocity = col[3] >= 0 && col[4] >= 0 && col[5] >= 0;
  s.points.resize(l.vertices, 3);
  if (velocity) s.velocity.resize(l.vertices, 3);
  if (col[6] >= 0) s.von_mises.resize(l.vertices);
  auto value = [&](std::size_t v, int c) {
    float f;
    std::memcpy(&f, bytes.data() + l.data_start + 4 * (v * nprop + static_cast<std::size_t>(c)), 4);
    return static_cast<double>(f);
  };
  for (std::size_t v = 0; v < nv; ++v) {
    const Index i = static_cast<Index>(v);
    for (int a = 0; a < 3; ++a) s.points(i, a) = value(v, col[a]);
    if (velocity)
      for (int a = 0; a < 3; ++a) s.velocity(i, a) = value(v, col[3 + a]);
    if (col[6] >= 0) s.von_mises[i] = value(v, col[6]);
  }
  return l.data_start + nv * nprop * 4;
}

/// The face block of a PLY from `at` into `s.triangles`.
void read_ply_faces(const std::string& bytes, std::size_t at, const PlyLayout& l,
                    ExportSurface& s) {
  s.triangles.resize(l.faces, 3);
  for (Index f = 0; f < l.faces; ++f) {
    if (bytes.size() - at < 13)
      throw PlyFormatError(fmt::format("truncated: face {} of {} is missing", f, l.faces));
    if (static_cast<unsigned char>(bytes[at]) != 3)
      throw PlyFormatError(fmt::format("face {} has {} vertices: only triangles are read", f,
                                       static_cast<int>(static_cast<unsigned char>(bytes[at]))));
    std::int32_t v[3];
    std::memcpy(v, bytes.data() + at + 1, 12);
    for (int c = 0; c < 3; ++c) {
      if (v[c] < 0 || v[c] >= l.vertices)
        throw PlyFormatError(
            fmt::format("face {} indexes vertex {}, outside 0 .. {}", f, v[c], l.vertices - 1));
      s.triangles(f, c) = v[c];
    }
    at += 13;
  }
  if (at != bytes.size())
    throw PlyFormatError(fmt::format("{} bytes after the last face", bytes.size() - at));
}

}  // namespace

// ---- surfaces ------------------------------------------------------------------------------

ExportSurface tet_boundary_surface(const MatX3& positions, const MatX4i& tets,
                                   const MatX3& velocity, const VecX& tet_von_mises) {
  const Index nv = static_cast<Index>(positions.rows());
  const Index nt = static_cast<Index>(tets.rows());
  TETFSI_CHECK(velocity.rows() == 0 || velocity.rows() == nv, "velocity has {} rows for {} nodes",
               velocity.rows(), nv);
  TETFSI_CHECK(tet_von_mises.size() == 0 || tet_von_mises.size() == nt,
               "von Mises stress has {} values for {} tets", tet_von_mises.size(), nt);
  TETFSI_CHECK(nt == 0 || (tets.minCoeff() >= 0 && tets.maxCoeff() < nv),
               "tets index nodes outside 0 .. {}", nv - 1);
  const mesh::VolumeMesh m{positions, tets};
  const MatX3i boundary = mesh::boundary_triangles(m);
  Index used = 0;
  const VecXi compact = compact_numbering(boundary, nv, used);
  ExportSurface s;
  s.triangles.resize(boundary.rows(), 3);
  for (Index f = 0; f < boundary.rows(); ++f)
    for (int c = 0; c < 3; ++c) s.triangles(f, c) = compact[boundary(f, c)];
  s.points.resize(used, 3);
  if (velocity.rows() > 0) s.velocity.resize(used, 3);
  for (Index v = 0; v < nv; ++v) {
    if (compact[v] < 0) continue;
    s.points.row(compact[v]) = positions.row(v);
    if (velocity.rows() > 0) s.velocity.row(compact[v]) = velocity.row(v);
  }
  if (tet_von_mises.size() > 0) s.von_mises = node_means(tets, tet_von_mises, compact, used);
  return s;
}

ExportSurface body_export_surface(const solid::SolidBody& body) {
  const MatX3 x = body.positions();
  const VecX von_mises = body.elasticity().tet_fields(x).von_mises_stress;
  return tet_boundary_surface(x, body.tets(), body.velocity, von_mises);
}

void write_ply(const fs::path& path, const ExportSurface& s) {
  check_surface(s);
  const bool velocity = s.velocity.rows() > 0, von_mises = s.von_mises.size() > 0;
  std::string out = ply_header(s);
  const auto np = static_cast<std::size_t>(s.points.rows());
  out.reserve(out.size() + np * (12 + (velocity ? 12 : 0) + (von_mises ? 4 : 0)) +
              13 * static_cast<std::size_t>(s.triangles.rows()));
  for (Index i = 0; i < s.points.rows(); ++i) {
    for (int a = 0; a < 3; ++a) put(out, static_cast<float>(s.points(i, a)));
    if (velocity)
      for (int a = 0; a < 3; ++a) put(out, static_cast<float>(s.velocity(i, a)));
    if (von_mises) put(out, static_cast<float>(s.von_mises[i]));
  }
  for (Index f = 0; f < s.triangles.rows(); ++f) {
    put(out, static_cast<std::uint8_t>(3));
    for (int c = 0; c < 3; ++c) put(out, static_cast<std::int32_t>(s.triangles(f, c)));
  }
  write_text_file_atomic(path, out);  // binary-safe: the bytes as they are
}

ExportSurface read_ply(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in)
    throw InputError(fmt::format("cannot read PLY '{}': {}", path.string(), std::strerror(errno)));
  std::ostringstream ss;
  ss << in.rdbuf();
  const std::string bytes = ss.str();
  try {
    const PlyLayout layout = parse_ply_header(bytes);
    ExportSurface s;
    const std::size_t faces = read_ply_vertices(bytes, layout, s);
    read_ply_faces(bytes, faces, layout, s);
    return s;
  } catch (const PlyFormatError& e) {
    throw InputError(fmt::format("cannot read PLY '{}': {}", path.string(), e.what()));
  }
}

// ---- voxels --------------------------------------------------------------------------------

double VoxelFrame::smoke_mass() const {
  return density.sum() * spacing.prod();
}

TetVolume tet_volume_of(const mesh::TetMesh& mesh, const fluid::MeshFrameFields& fields) {
  TetVolume v;
  v.vertices = mesh.vertices;
  v.tets = mesh.tets;
  v.density = fields.density;
  v.temperature = fields.temperature;
  v.pressure = fields.pressure;
  v.vertex_velocity = fields.vertex_velocity;
  return v;
}

TetVolume tet_volume_of(const fluid::MeshFrame& frame) {
  TETFSI_CHECK(frame.mesh != nullptr, "tet_volume_of: the frame has no mesh");
  return tet_volume_of(*frame.mesh, frame.fields);
}

namespace {

/// No tet contains the sub-sample (the largest int32, so that the smallest owner wins).
constexpr std::int32_t k_no_tet = std::numeric_limits<std::int32_t>::max();
/// A point is in a tet if none of its barycentric coordinates is below −this.
constexpr double k_bary_tolerance = 1e-10;

/// The sub-sample points of voxelize: n[a] = dims[a] s per axis, point g at lo + (g + ½) h / s
/// (= the voxel's centre + ((a + ½) / s − ½) h for sub-sample a of voxel g / s).
struct Lattice {
  Vec3 lo = Vec3::Zero();
  double step = 1.0;  ///< h / s
  int s = 1;
  std::array<Index, 3> n = {0, 0, 0};
  std::int64_t size() const { return std::int64_t{n[0]} * n[1] * n[2]; }
  std::int64_t index(Index gx, Index gy, Index gz) const {
    return gx + std::int64_t{n[0]} * (gy + std::int64_t{n[1]} * gz);
  }
  Vec3 point(Index gx, Index gy, Index gz) const {
    return lo + step * Vec3(gx + 0.5, gy + 0.5, gz + 0.5);
  }
};

/// Tet t's corner p0 and the inverse of its edge matrix [p1 − p0, p2 − p0, p3 − p0]: the
/// barycentric coordinates of x are (1 − Σλ, λ) with λ = inv (x − p0).
struct TetFrame {
  Vec3 p0 = Vec3::Zero();
  Mat3 inv = Mat3::Zero();
  bool ok = false;  ///< false for a flat tet (no point is in it)
};

TetFrame tet_frame(const TetVolume& f, Index t) {
  TetFrame tf;
  tf.p0 = f.vertices.row(f.tets(t, 0));
  Mat3 e;
  for (int k = 0; k < 3; ++k) e.col(k) = f.vertices.row(f.tets(t, k + 1)).transpose() - tf.p0;
  const double det = e.determinant();
  tf.ok = det != 0.0 && std::isfinite(det);
  if (tf.ok) tf.inv = e.inverse();
  return tf;
}

Vec4 barycentric(const TetFrame& tf, const Vec3& x) {
  const Vec3 l = tf.inv * (x - tf.p0);
  return Vec4(1.0 - l.sum(), l[0], l[1], l[2]);
}

/// @throws InternalError if a field of `f` does not fit its mesh
void check_tet_volume(const TetVolume& f) {
  const Index nv = static_cast<Index>(f.vertices.rows()), nt = static_cast<Index>(f.tets.rows());
  auto fits = [](Index size, Index n) { return size == 0 || size == n; };
  TETFSI_CHECK(fits(static_cast<Index>(f.density.size()), nt) &&
                   fits(static_cast<Index>(f.temperature.size()), nt) &&
                   fits(static_cast<Index>(f.pressure.size()), nt),
               "tet fields have {} / {} / {} values (density, temperature, pressure) for {} tets",
               f.density.size(), f.temperature.size(), f.pressure.size(), nt);
  TETFSI_CHECK(fits(static_cast<Index>(f.vertex_velocity.rows()), nv),
               "vertex velocity has {} rows for {} vertices", f.vertex_velocity.rows(), nv);
  TETFSI_CHECK(nt == 0 || (f.tets.minCoeff() >= 0 && f.tets.maxCoeff() < nv),
               "tets index vertices outside 0 .. {}", nv - 1);
  TETFSI_CHECK(f.vertices.allFinite(), "the fluid's vertices are not all finite");
}

/// The voxels over the vertices' bounding box (into v's origin, spacing and dims) and their
/// sub-sample lattice. @throws InputError beyond 2^31 sub-samples
Lattice voxel_box(const TetVolume& f, const VoxelOptions& o, VoxelFrame& v) {
  const Vec3 lo = f.vertices.colwise().minCoeff(), hi = f.vertices.colwise().maxCoeff();
  const double h = o.voxel_size;
  std::array<double, 3> n{};
  for (int a = 0; a < 3; ++a)  // a whole number of voxels is not one more for a rounding
    n[a] = std::max(1.0, std::ceil((hi[a] - lo[a]) / h * (1.0 - 1e-12)));
  const double total = n[0] * n[1] * n[2] * std::pow(o.subsamples, 3);
  TETFSI_REQUIRE(InputError, total <= 2147483648.0,
                 "voxelize: a voxel size of {} m over the fluid's box ({}, {}, {}) .. ({}, {}, {}) "
                 "m makes {} x {} x {} voxels of {}^3 sub-samples, {:.3g} > 2^31: choose a "
                 "larger voxel size",
                 h, lo[0], lo[1], lo[2], hi[0], hi[1], hi[2], n[0], n[1], n[2], o.subsamples,
                 total);
  // Centred on the box: the voxels stick out of it by at most h/2 on each side.
  Vec3 start = lo;
  for (int a = 0; a < 3; ++a) start[a] -= 0.5 * (n[a] * h - (hi[a] - lo[a]));
  v.origin = start + Vec3::Constant(h / 2);
  v.spacing = Vec3::Constant(h);
  Lattice l;
  l.lo = start;
  l.step = h / o.subsamples;
  l.s = o.subsamples;
  for (int a = 0; a < 3; ++a) {
    v.dims[a] = static_cast<Index>(n[a]);
    l.n[a] = v.dims[a] * o.subsamples;
  }
  return l;
}

/// The lattice points [g0, g1] along axis a that may lie in [x0, x1].
std::pair<Index, Index> lattice_range(const Lattice& l, int a, double x0, double x1) {
  const double q0 = (x0 - l.lo[a]) / l.step - 0.5, q1 = (x1 - l.lo[a]) / l.step - 0.5;
  const Index g0 = -floor_index(-(q0 - 1e-9)), g1 = floor_index(q1 + 1e-9);
  return {std::max<Index>(0, g0), std::min<Index>(l.n[a] - 1, g1)};
}

/// Per sub-sample: the smallest tet containing it, or k_no_tet (in parallel over the tets,
/// the same at any thread count).
UnfilledVector<std::int32_t> locate_subsamples(const TetVolume& f, const Lattice& l) {
  UnfilledVector<std::int32_t> owner(static_cast<std::size_t>(l.size()));
  parallel_fill(owner, k_no_tet);
  parallel_for_chunks(static_cast<Index>(f.tets.rows()), 512, [&](Index begin, Index end) {
    for (Index t = begin; t < end; ++t) {
      const TetFrame tf = tet_frame(f, t);
      if (!tf.ok) continue;
      Vec3 b0 = tf.p0, b1 = tf.p0;
      for (int k = 1; k < 4; ++k) {
        b0 = b0.cwiseMin(f.vertices.row(f.tets(t, k)).transpose());
        b1 = b1.cwiseMax(f.vertices.row(f.tets(t, k)).transpose());
      }
      const auto [x0, x1] = lattice_range(l, 0, b0[0], b1[0]);
      const auto [y0, y1] = lattice_range(l, 1, b0[1], b1[1]);
      const auto [z0, z1] = lattice_range(l, 2, b0[2], b1[2]);
      for (Index gz = z0; gz <= z1; ++gz)
        for (Index gy = y0; gy <= y1; ++gy)
          for (Index gx = x0; gx <= x1; ++gx) {
            if (barycentric(tf, l.point(gx, gy, gz)).minCoeff() < -k_bary_tolerance) continue;
            std::atomic_ref<std::int32_t> o(owner[static_cast<std::size_t>(l.index(gx, gy, gz))]);
            std::int32_t cur = o.load(std::memory_order_relaxed);
            while (t < cur && !o.compare_exchange_weak(cur, t, std::memory_order_relaxed)) {
            }
          }
    }
  });
  return owner;
}

/// The sums of one voxel's sub-samples that lie in the fluid.
struct VoxelSums {
  int count = 0;
  double density = 0, temperature = 0, pressure = 0;
  Vec3 velocity = Vec3::Zero();
};

/// The frame of the tet last asked for (a voxel's sub-samples mostly lie in one tet).
struct TetFrameCache {
  Index tet = -1;
  TetFrame frame;
  const TetFrame& of(const TetVolume& f, Index t) {
    if (t != tet) {
      frame = tet_frame(f, t);
      tet = t;
    }
    return frame;
  }
};

VoxelSums sum_voxel(const TetVolume& f, const Lattice& l, const UnfilledVector<std::int32_t>& owner,
                    const VecX& point_density, Index i, Index j, Index k, double ambient,
                    TetFrameCache& cache) {
  VoxelSums sum;
  for (int c = 0; c < l.s; ++c)
    for (int b = 0; b < l.s; ++b)
      for (int a = 0; a < l.s; ++a) {
        const Index gx = i * l.s + a, gy = j * l.s + b, gz = k * l.s + c;
        const std::int32_t t = owner[static_cast<std::size_t>(l.index(gx, gy, gz))];
        if (t == k_no_tet) continue;
        ++sum.count;
        sum.density += point_density.size() > 0 ? point_density[t] : 0.0;
        sum.temperature += f.temperature.size() > 0 ? f.temperature[t] : ambient;
        sum.pressure += f.pressure.size() > 0 ? f.pressure[t] : 0.0;
        if (f.vertex_velocity.rows() == 0) continue;
        const Vec4 w = barycentric(cache.of(f, t), l.point(gx, gy, gz));
        for (int q = 0; q < 4; ++q)
          sum.velocity += w[q] * f.vertex_velocity.row(f.tets(t, q)).transpose();
      }
  return sum;
}

/// |volume| of every tet (m³), in parallel.
VecX tet_volumes(const TetVolume& f) {
  VecX vol(f.tets.rows());
  parallel_for_chunks(static_cast<Index>(f.tets.rows()), 4096, [&](Index begin, Index end) {
    for (Index t = begin; t < end; ++t) {
      const Vec3 p0 = f.vertices.row(f.tets(t, 0));
      Mat3 e;
      for (int k = 0; k < 3; ++k) e.col(k) = f.vertices.row(f.tets(t, k + 1)).transpose() - p0;
      vol[t] = std::abs(e.determinant()) / 6.0;
    }
  });
  return vol;
}

/// The smoke mass of the tets as densities of the sub-samples: each tet's mass ρ_t V_t shared
/// equally among the sub-samples it owns, as a density over a sub-sample's cell (step³), so
/// that the voxels carry Σ ρ_t V_t exactly. A tet that owns none is left out here (its mass:
/// deposit_unsampled_mass). Empty without a density field.
VecX point_densities(const TetVolume& f, const Lattice& l,
                     const UnfilledVector<std::int32_t>& owner, const VecX& volume) {
  if (f.density.size() == 0) return {};
  std::vector<std::int64_t> points(static_cast<std::size_t>(f.tets.rows()), 0);
  for (std::size_t p = 0; p < owner.size(); ++p)
    if (owner[p] != k_no_tet) ++points[static_cast<std::size_t>(owner[p])];
  VecX d = VecX::Zero(f.tets.rows());
  const double cell = std::pow(l.step, 3);
  for (Index t = 0; t < d.size(); ++t) {
    const auto n = points[static_cast<std::size_t>(t)];
    if (n > 0) d[t] = f.density[t] * volume[t] / (static_cast<double>(n) * cell);
  }
  return d;
}

/// The smoke mass of the tets that own no sub-sample (smaller than the lattice's spacing),
/// added to the voxel of their centroid.
void deposit_unsampled_mass(const TetVolume& f, const UnfilledVector<std::int32_t>& owner,
                            const VecX& volume, VoxelFrame& v) {
  if (f.density.size() == 0) return;
  std::vector<char> sampled(static_cast<std::size_t>(f.tets.rows()), 0);
  for (std::size_t p = 0; p < owner.size(); ++p)
    if (owner[p] != k_no_tet) sampled[static_cast<std::size_t>(owner[p])] = 1;
  const double voxel = v.spacing.prod();
  for (Index t = 0; t < f.tets.rows(); ++t) {
    if (sampled[static_cast<std::size_t>(t)] || f.density[t] == 0.0) continue;
    Vec3 x = Vec3::Zero();
    for (int k = 0; k < 4; ++k) x += 0.25 * f.vertices.row(f.tets(t, k)).transpose();
    Index c = 0, stride = 1;
    for (int a = 0; a < 3; ++a) {
      const double u = (x[a] - v.origin[a]) / v.spacing[a] + 0.5;
      c += stride * std::clamp<Index>(static_cast<Index>(std::floor(u)), 0, v.dims[a] - 1);
      stride *= v.dims[a];
    }
    v.density[c] += f.density[t] * volume[t] / voxel;
  }
}

/// Every voxel's fields from its sub-samples' owners (in parallel over z-slabs).
void average_voxels(const TetVolume& f, const Lattice& l, const UnfilledVector<std::int32_t>& owner,
                    VoxelFrame& v) {
  const VecX volume = tet_volumes(f);
  const VecX point_density = point_densities(f, l, owner, volume);
  const double per_voxel = std::pow(l.s, 3);
  const Index nx = v.dims[0], ny = v.dims[1], nz = v.dims[2];
  parallel_for_chunks(nz, 1, [&](Index k0, Index k1) {
    TetFrameCache cache;
    for (Index k = k0; k < k1; ++k)
      for (Index j = 0; j < ny; ++j)
        for (Index i = 0; i < nx; ++i) {
          const Index c = i + nx * (j + ny * k);
          const VoxelSums s =
              sum_voxel(f, l, owner, point_density, i, j, k, v.ambient_temperature, cache);
          v.fluid_fraction[c] = s.count / per_voxel;
          v.density[c] = s.density / per_voxel;
          v.temperature[c] = s.count > 0 ? s.temperature / s.count : v.ambient_temperature;
          v.pressure[c] = s.count > 0 ? s.pressure / s.count : 0.0;
          v.velocity.row(c) = s.count > 0 ? Vec3(s.velocity / s.count) : Vec3::Zero();
        }
  });
  deposit_unsampled_mass(f, owner, volume, v);
}

}  // namespace

VoxelFrame voxelize(const TetVolume& fluid, const VoxelOptions& options) {
  TETFSI_REQUIRE(InputError, std::isfinite(options.voxel_size) && options.voxel_size > 0,
                 "voxelize: the voxel size must be positive and finite, got {}",
                 options.voxel_size);
  TETFSI_REQUIRE(InputError, options.subsamples >= 1 && options.subsamples <= 16,
                 "voxelize: the sub-samples per axis must be 1 .. 16, got {}", options.subsamples);
  check_tet_volume(fluid);
  VoxelFrame v;
  v.ambient_temperature = options.ambient_temperature;
  v.spacing = Vec3::Constant(options.voxel_size);
  if (fluid.vertices.rows() == 0) return v;  // no fluid: no voxels
  const Lattice l = voxel_box(fluid, options, v);
  const Index n = v.size();
  v.fluid_fraction.resize(n);
  v.density.resize(n);
  v.temperature.resize(n);
  v.pressure.resize(n);
  v.velocity.resize(n, 3);
  const UnfilledVector<std::int32_t> owner = locate_subsamples(fluid, l);
  average_voxels(fluid, l, owner, v);
  return v;
}

VoxelFrame voxel_frame_of(const fluid::GridFrameFields& g, double ambient_temperature) {
  VoxelFrame v;
  v.origin = g.origin + g.spacing / 2;
  v.spacing = g.spacing;
  v.dims = g.cells;
  v.ambient_temperature = ambient_temperature;
  const Index n = v.size();
  auto scalar = [n](const VecX& field, double empty, const char* name) {
    TETFSI_CHECK(field.size() == 0 || field.size() == n,
                 "grid field '{}' has {} values for {} cells", name, field.size(), n);
    return field.size() == 0 ? VecX(VecX::Constant(n, empty)) : field;
  };
  v.density = scalar(g.density, 0.0, "density");
  v.temperature = scalar(g.temperature, ambient_temperature, "temperature");
  v.pressure = scalar(g.pressure, 0.0, "pressure");
  TETFSI_CHECK(g.velocity.rows() == 0 || g.velocity.rows() == n,
               "grid velocity has {} rows for {} cells", g.velocity.rows(), n);
  v.velocity = g.velocity.rows() == 0 ? MatX3(MatX3::Zero(n, 3)) : g.velocity;
  TETFSI_CHECK(g.solid.empty() || static_cast<Index>(g.solid.size()) == n,
               "grid solid flags: {} for {} cells", g.solid.size(), n);
  v.fluid_fraction = VecX::Ones(n);
  for (std::size_t c = 0; c < g.solid.size(); ++c)
    if (g.solid[c]) v.fluid_fraction[static_cast<Index>(c)] = 0.0;
  if (g.phi.size() > 0) v.phi = scalar(g.phi, 0.0, "phi");
  return v;
}

// ---- one frame and the manifest ------------------------------------------------------------

namespace {

/// Create `folder` and its parents if missing. @throws InputError naming it
void make_folder(const fs::path& folder) {
  std::error_code ec;
  fs::create_directories(folder, ec);
  if (ec)
    throw InputError(
        fmt::format("cannot create export folder '{}': {}", folder.string(), ec.message()));
}

nlohmann::json grid_json(const VdbGridSummary& g) {
  return {{"name", g.name},        {"type", g.type},
          {"class", g.grid_class}, {"active_voxels", g.active_voxels},
          {"min", g.min},          {"max", g.max},
          {"bounds", g.bounds},    {"unit", g.unit}};
}

VdbGridSummary grid_from_json(const nlohmann::json& j) {
  VdbGridSummary g;
  g.name = j.at("name").get<std::string>();
  g.type = j.at("type").get<std::string>();
  g.grid_class = j.at("class").get<std::string>();
  g.active_voxels = j.at("active_voxels").get<std::int64_t>();
  g.min = j.at("min").get<double>();
  g.max = j.at("max").get<double>();
  g.bounds = j.at("bounds").get<std::array<double, 6>>();
  g.unit = j.at("unit").get<std::string>();
  return g;
}

}  // namespace

ExportedFrame export_frame(const fs::path& folder, int frame, int step, double time,
                           const std::vector<NamedSurface>& surfaces, const VoxelFrame* fluid,
                           const ExportRequest& request) {
  ExportedFrame out;
  out.frame = frame;
  out.step = step;
  out.time = time;
  if (fluid) {
    out.voxel_size = fluid->spacing;
    out.smoke_mass = fluid->smoke_mass();
  }
  if (fluid && request.vdb) {
    make_folder(folder / "vdb");
    out.vdb_file = fmt::format("vdb/fluid_{:06d}.vdb", frame);
    const VdbFrameInfo info{step, time, request.scene, request.smoke_threshold};
    out.grids = write_vdb(folder / out.vdb_file, *fluid, info);
  }
  if (request.ply && !surfaces.empty()) {
    make_folder(folder / "ply");
    for (const NamedSurface& s : surfaces) {
      ExportedFrame::Mesh m;
      m.name = s.name;
      m.file = fmt::format("ply/{}_{:06d}.ply", s.name, frame);
      m.vertices = static_cast<Index>(s.surface.points.rows());
      m.triangles = static_cast<Index>(s.surface.triangles.rows());
      write_ply(folder / m.file, s.surface);
      out.meshes.push_back(std::move(m));
    }
  }
  return out;
}

nlohmann::json to_json(const ExportedFrame& f) {
  nlohmann::json grids = nlohmann::json::array(), meshes = nlohmann::json::array();
  for (const VdbGridSummary& g : f.grids) grids.push_back(grid_json(g));
  for (const ExportedFrame::Mesh& m : f.meshes)
    meshes.push_back(
        {{"name", m.name}, {"file", m.file}, {"vertices", m.vertices}, {"triangles", m.triangles}});
  return {{"frame", f.frame},
          {"step", f.step},
          {"time", f.time},
          {"vdb_file", f.vdb_file},
          {"grids", grids},
          {"voxel_size", {f.voxel_size[0], f.voxel_size[1], f.voxel_size[2]}},
          {"smoke_mass", f.smoke_mass},
          {"meshes", meshes}};
}

ExportedFrame exported_frame_from_json(const nlohmann::json& j) {
  try {
    ExportedFrame f;
    f.frame = j.at("frame").get<int>();
    f.step = j.at("step").get<int>();
    f.time = j.at("time").get<double>();
    f.vdb_file = j.at("vdb_file").get<std::string>();
    for (const nlohmann::json& g : j.at("grids")) f.grids.push_back(grid_from_json(g));
    const auto h = j.at("voxel_size").get<std::array<double, 3>>();
    f.voxel_size = Vec3(h[0], h[1], h[2]);
    f.smoke_mass = j.at("smoke_mass").get<double>();
    for (const nlohmann::json& m : j.at("meshes"))
      f.meshes.push_back({m.at("name").get<std::string>(), m.at("file").get<std::string>(),
                          m.at("vertices").get<Index>(), m.at("triangles").get<Index>()});
    return f;
  } catch (const nlohmann::json::exception& e) {
    throw InputError(fmt::format("export manifest: a frame that cannot be read: {}", e.what()));
  }
}

ExportManifest::ExportManifest(fs::path path, std::string scene)
    : m_path(std::move(path)), m_scene(std::move(scene)) {}

void ExportManifest::add(ExportedFrame f) {
  const auto same = std::find_if(m_frames.begin(), m_frames.end(),
                                 [&](const ExportedFrame& g) { return g.frame == f.frame; });
  if (same != m_frames.end())
    *same = std::move(f);
  else
    m_frames.push_back(std::move(f));
  write();
}

void ExportManifest::truncate(int frames) {
  std::erase_if(m_frames, [frames](const ExportedFrame& f) { return f.frame >= frames; });
  write();
}

void ExportManifest::reset(std::vector<ExportedFrame> frames) {
  m_frames = std::move(frames);
  write();
}

nlohmann::json ExportManifest::to_json() const {
  nlohmann::json frames = nlohmann::json::array();
  for (const ExportedFrame& f : m_frames) frames.push_back(app::to_json(f));
  return {{"format", "tetfsi-export 1"},
          {"scene", m_scene},
          {"axes", k_export_axes},
          {"frames", frames}};
}

void ExportManifest::write() const {
  write_text_file_atomic(m_path, to_json().dump(2) + "\n");
}

}  // namespace tetfsi::app
