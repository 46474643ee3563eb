/// @file test_export.cpp
/// Tests of the renderer export (io/export.hpp): PLY surfaces written and read back, the tet
/// fluid's voxel sampling (mass, volume, exact linear velocity, the same bits at any thread
/// count), `.vdb` files written and summarised by OpenVDB's reader, the grid fluid's cells as
/// voxels, one frame's files and the manifest export.json.
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "core/error.hpp"
#include "core/parallel.hpp"
#include "io/export.hpp"
#include "io/output.hpp"
#include "mesh/generate.hpp"
#include "mesh/tet_mesh.hpp"
#include "solid/solid_body.hpp"
#include "tests/test_util.hpp"

namespace fs = std::filesystem;
using namespace tetfsi;
using namespace tetfsi::app;
using tetfsi::test::message_of;
using tetfsi::test::TempDir;

namespace {

/// b within a relative tolerance: |a − b| < tol max(|a|, |b|) (doctest's Approx adds 1 to the
/// scale, which for values below 1 makes it an absolute tolerance).
doctest::Approx rel(double b, double tol) {
  return doctest::Approx(b).epsilon(tol).scale(0.0);
}

/// A block body 1.5 × 1 × 0.5 (3 × 2 × 1 cells) deformed smoothly, with a velocity.
solid::SolidBody make_block() {
  solid::Material mat;
  mat.density = 800.0;
  mat.youngs_modulus = 2e5;
  solid::SolidBody b("block", mesh::make_box(Vec3(0, 0, 0), Vec3(1.5, 1, 0.5), Vec3i(3, 2, 1)),
                     mat);
  const MatX3& X = b.rest_positions();
  for (Index i = 0; i < b.num_nodes(); ++i) {
    b.displacement.row(i) = Vec3(0.01 * X(i, 0) * X(i, 2), -0.02 * X(i, 1), 0.03 * X(i, 0));
    b.velocity.row(i) = Vec3(std::cos(0.3 * i), 1e-3 * i, -2.5 + 0.1 * X(i, 2));
  }
  return b;
}

/// Σ over the triangles of the signed volume of (origin, a, b, c): the enclosed volume when the
/// normals point out.
double enclosed_volume(const MatX3& p, const MatX3i& tr) {
  double v = 0.0;
  for (Index f = 0; f < tr.rows(); ++f) {
    const Vec3 a = p.row(tr(f, 0)), b = p.row(tr(f, 1)), c = p.row(tr(f, 2));
    v += a.dot(b.cross(c)) / 6.0;
  }
  return v;
}

/// The unit cube in n³ cells with its inner vertices moved (irregular tets), ρ_t = 1 + x of the
/// centroid, temperature 300 + 10 z, pressure 5 y, and the vertex velocity `u` of each vertex.
TetVolume jittered_cube(int n, Vec3 (*u)(const Vec3&)) {
  const mesh::VolumeMesh m = mesh::make_box(Vec3::Zero(), Vec3::Ones(), Vec3i(n, n, n));
  TetVolume f;
  f.vertices = m.vertices;
  f.tets = m.tets;
  const double e = 1.0 / n;
  for (Index v = 0; v < f.vertices.rows(); ++v) {
    const Vec3 x = f.vertices.row(v);
    const bool inner = (x.array() > 1e-9).all() && (x.array() < 1 - 1e-9).all();
    if (inner)
      f.vertices.row(v) += 0.1 * e * Vec3(std::sin(7.0 * v), std::cos(5.0 * v), std::sin(3.0 * v));
  }
  const Index nt = static_cast<Index>(f.tets.rows());
  f.density.resize(nt);
  f.temperature.resize(nt);
  f.pressure.resize(nt);
  for (Index t = 0; t < nt; ++t) {
    Vec3 c = Vec3::Zero();
    for (int k = 0; k < 4; ++k) c += f.vertices.row(f.tets(t, k)).transpose() / 4.0;
    f.density[t] = 1.0 + c[0];
    f.temperature[t] = 300.0 + 10.0 * c[2];
    f.pressure[t] = 5.0 * c[1];
  }
  f.vertex_velocity.resize(f.vertices.rows(), 3);
  for (Index v = 0; v < f.vertices.rows(); ++v)
    f.vertex_velocity.row(v) = u(f.vertices.row(v).transpose());
  return f;
}

Vec3 linear_velocity(const Vec3& x) {
  return Vec3(1.0 + 2.0 * x[0], -0.5 * x[0] + 0.25 * x[1], 3.0 * x[2] - x[0]);
}

/// Σ ρ_t V_t of a tet volume.
double tet_smoke_mass(const TetVolume& f) {
  double m = 0.0;
  for (Index t = 0; t < f.tets.rows(); ++t) {
    const Vec3 p0 = f.vertices.row(f.tets(t, 0));
    Mat3 e;
    for (int k = 0; k < 3; ++k) e.col(k) = f.vertices.row(f.tets(t, k + 1)).transpose() - p0;
    m += f.density[t] * e.determinant() / 6.0;
  }
  return m;
}

const VdbGridSummary& grid_named(const std::vector<VdbGridSummary>& grids,
                                 const std::string& name) {
  const auto it = std::find_if(grids.begin(), grids.end(),
                               [&](const VdbGridSummary& g) { return g.name == name; });
  REQUIRE(it != grids.end());
  return *it;
}

/// The grid fluid of a 4 × 3 × 2 box (spacing 0.1, 0.2, 0.25 from (1, 2, 3)) with two solid
/// cells and a liquid level set φ = z − 3.3 (the liquid below z = 3.3).
fluid::GridFrameFields small_grid() {
  fluid::GridFrameFields g;
  g.origin = Vec3(1, 2, 3);
  g.spacing = Vec3(0.1, 0.2, 0.25);
  g.cells = {4, 3, 2};
  const Index n = 24;
  g.pressure = VecX::LinSpaced(n, 0.0, 23.0);
  g.density = VecX::Zero(n);
  g.temperature = VecX::Constant(n, 295.0);
  g.velocity = MatX3::Zero(n, 3);
  g.solid.assign(n, 0);
  g.solid[5] = g.solid[17] = 1;
  g.phi.resize(n);
  for (Index c = 0; c < n; ++c) {
    g.velocity.row(c) = Vec3(c, -c, 0.5 * c);
    g.phi[c] = g.origin[2] + (c / 12 + 0.5) * g.spacing[2] - 3.3;
  }
  return g;
}

}  // namespace

// ---- surfaces ------------------------------------------------------------------------------

TEST_CASE("tet_boundary_surface: a one-cell box has 12 outward triangles on its 8 corners") {
  const mesh::VolumeMesh m = mesh::make_box(Vec3::Zero(), Vec3(2, 1, 0.5), Vec3i(1, 1, 1));
  const ExportSurface s = tet_boundary_surface(m.vertices, m.tets, MatX3(), VecX());
  CHECK(s.triangles.rows() == 12);
  CHECK(s.points.rows() == 8);
  CHECK(s.velocity.rows() == 0);
  CHECK(s.von_mises.size() == 0);
  CHECK(enclosed_volume(s.points, s.triangles) == rel(1.0, 1e-12));
}

TEST_CASE("body_export_surface: the deformed boundary, its velocity and node-mean von Mises") {
  const solid::SolidBody body = make_block();
  const ExportSurface s = body_export_surface(body);
  // 3 × 2 × 1 cells: 2 (6 + 3 + 2) quads of 2 triangles; all 24 nodes are on the boundary.
  CHECK(s.triangles.rows() == 44);
  REQUIRE(s.points.rows() == 24);
  const MatX3 x = body.positions();
  const VecX vm = body.elasticity().tet_fields(x).von_mises_stress;
  CHECK(vm.maxCoeff() > 0);
  // every node is on the surface: the compact numbering is the identity
  for (Index v = 0; v < 24; ++v) {
    CHECK((s.points.row(v) - x.row(v)).norm() == 0.0);
    CHECK((s.velocity.row(v) - body.velocity.row(v)).norm() == 0.0);
    double sum = 0;
    int n = 0;
    for (Index t = 0; t < body.num_tets(); ++t)
      for (int k = 0; k < 4; ++k)
        if (body.tets()(t, k) == v) {
          sum += vm[t];
          ++n;
        }
    CHECK(s.von_mises[v] == rel(sum / n, 1e-12));
  }
  CHECK(enclosed_volume(s.points, s.triangles) > 0.7);
}

TEST_CASE("write_ply and read_ply: a surface round trips within float precision") {
  TempDir dir("export_ply");
  const solid::SolidBody body = make_block();
  ExportSurface s = body_export_surface(body);
  const fs::path p = dir.path / "block_000000.ply";
  write_ply(p, s);
  CHECK(fs::exists(p));
  CHECK(!fs::exists(dir.path / "block_000000.ply.tmp"));
  // 24 points × (x y z vx vy vz von_mises) floats, 44 faces of 1 + 12 bytes, after the header
  const std::string bytes = test::read_text(p);
  CHECK(bytes.rfind("ply\nformat binary_little_endian 1.0\n", 0) == 0);
  const std::size_t header = bytes.find("end_header\n") + 11;
  CHECK(bytes.size() - header == 24 * 7 * 4 + 44 * 13);
  const ExportSurface r = read_ply(p);
  CHECK(r.triangles == s.triangles);
  auto float_close = [](const auto& a, const auto& b) {
    return ((a - b).array().abs() <= 1e-6 * (1.0 + b.array().abs())).all();
  };
  CHECK(float_close(r.points, s.points));
  CHECK(float_close(r.velocity, s.velocity));
  CHECK(float_close(r.von_mises, s.von_mises));
  // positions only
  s.velocity.resize(0, 3);
  s.von_mises.resize(0);
  write_ply(p, s);
  const ExportSurface q = read_ply(p);
  CHECK(q.velocity.rows() == 0);
  CHECK(q.von_mises.size() == 0);
  CHECK(float_close(q.points, s.points));
  CHECK(q.triangles == s.triangles);
}

TEST_CASE("write_ply: wrong sizes and a triangle past the points are InternalErrors") {
  TempDir dir("export_ply_bad");
  const mesh::VolumeMesh m = mesh::make_box(Vec3::Zero(), Vec3::Ones(), Vec3i(1, 1, 1));
  ExportSurface s = tet_boundary_surface(m.vertices, m.tets, MatX3(), VecX());
  ExportSurface past = s;
  past.triangles(3, 1) = 8;
  CHECK_THROWS_AS(write_ply(dir.path / "a.ply", past), InternalError);
  ExportSurface short_velocity = s;
  short_velocity.velocity = MatX3::Zero(7, 3);
  CHECK_THROWS_AS(write_ply(dir.path / "a.ply", short_velocity), InternalError);
  CHECK(!fs::exists(dir.path / "a.ply"));
}

TEST_CASE("read_ply: a missing, foreign or damaged file is an InputError naming it") {
  TempDir dir("export_ply_read");
  const mesh::VolumeMesh m = mesh::make_box(Vec3::Zero(), Vec3::Ones(), Vec3i(1, 1, 1));
  const fs::path good = dir.path / "good.ply";
  write_ply(good, tet_boundary_surface(m.vertices, m.tets, MatX3(), VecX()));
  const std::string bytes = test::read_text(good);
  auto write = [&](const std::string& name, const std::string& text) {
    std::ofstream(dir.path / name, std::ios::binary) << text;
    return dir.path / name;
  };
  auto error = [](const fs::path& p) { return message_of<InputError>([&] { read_ply(p); }); };
  CHECK(error(dir.path / "missing.ply").find("missing.ply") != std::string::npos);
  const std::string ascii = error(
      write("ascii.ply", "ply\nformat ascii 1.0\nelement vertex 0\nelement face 0\nend_header\n"));
  CHECK(ascii.find("ascii.ply") != std::string::npos);
  CHECK(ascii.find("binary_little_endian") != std::string::npos);
  CHECK(error(write("short.ply", bytes.substr(0, bytes.size() - 5))).find("truncated") !=
        std::string::npos);
  std::string quad = bytes;
  quad[bytes.find("end_header\n") + 11 + 8 * 12] = 4;  // the first face's vertex count
  CHECK(error(write("quad.ply", quad)).find("only triangles") != std::string::npos);
  std::string past = bytes;
  const std::int32_t nine = 9;
  std::memcpy(&past[bytes.find("end_header\n") + 11 + 8 * 12 + 1], &nine, 4);
  const std::string past_error = error(write("past.ply", past));
  CHECK(past_error.find("past.ply") != std::string::npos);
  CHECK(past_error.find("vertex 9") != std::string::npos);
}

// ---- voxels --------------------------------------------------------------------------------

TEST_CASE("voxelize: a meshed unit cube keeps its smoke mass and volume, and the box's voxels") {
  const TetVolume f = jittered_cube(6, linear_velocity);
  const double edge = 1.0 / 6;
  VoxelOptions o;
  o.voxel_size = edge / 2;
  o.subsamples = 2;
  const VoxelFrame v = voxelize(f, o);
  CHECK(v.dims == std::array<Index, 3>{12, 12, 12});
  CHECK((v.origin - Vec3::Constant(edge / 4)).norm() < 1e-12);
  CHECK(v.spacing == Vec3::Constant(edge / 2));
  // the cube fills the box: every voxel is fluid
  const double h3 = std::pow(o.voxel_size, 3);
  CHECK(v.fluid_fraction.sum() * h3 == rel(1.0, 1e-12));
  const double mass = tet_smoke_mass(f);
  CHECK(mass == rel(1.5, 1e-12));  // the centroid rule is exact for ρ linear
  // each tet's mass shared among its sub-samples: exact (to rounding)
  CHECK(v.smoke_mass() == rel(mass, 1e-12));
  CHECK(v.density.minCoeff() > 0.0);
  // and local: the mean over each slab x = const is ρ = 1 + x there, within 5 %
  for (Index i = 0; i < 12; ++i) {
    double slab = 0.0;
    for (Index k = 0; k < 12; ++k)
      for (Index j = 0; j < 12; ++j) slab += v.density[i + 12 * (j + 12 * k)];
    CAPTURE(i);
    CHECK(slab / 144 == rel(1.0 + (i + 0.5) / 12, 0.05));
  }
  CHECK(v.temperature.minCoeff() >= 300.0 - 1e-9);
  CHECK(v.temperature.maxCoeff() <= 310.0 + 1e-9);
  CHECK(v.pressure.maxCoeff() <= 5.0 + 1e-9);
}

/// The sub-sample points along an axis (n of them at start + (g + ½) step) with x0 ≤ x ≤ x1
/// (closed) or x0 < x < x1 (open), up to 1e-9.
double points_in(Index n, double start, double step, double x0, double x1, bool closed) {
  const double tol = closed ? 1e-9 : -1e-9;
  double count = 0;
  for (Index g = 0; g < n; ++g) {
    const double x = start + (g + 0.5) * step;
    count += x >= x0 - tol && x <= x1 + tol ? 1 : 0;
  }
  return count;
}

TEST_CASE("voxelize: a hollow box's cavity and the box's margin are outside the fluid") {
  // outer [0, 1] × [0, 1] × [0, 0.7], cavity [0.2, 0.8]² × [0.2, 0.5] inside walls of 0.2
  const mesh::VolumeMesh m =
      mesh::make_hollow_box(Vec3::Zero(), Vec3(1, 1, 0.7), 0.2, Vec3i(3, 3, 2));
  TetVolume f;
  f.vertices = m.vertices;
  f.tets = m.tets;
  f.density = VecX::Constant(m.num_tets(), 2.0);
  const double volume = 0.7 - 0.6 * 0.6 * 0.3;
  VoxelOptions o;
  o.ambient_temperature = 280.0;
  // walls between the sub-samples' slabs (h = 0.1, s = 2): the volume and mass exactly
  o.voxel_size = 0.1;
  o.subsamples = 2;
  const VoxelFrame aligned = voxelize(f, o);
  CHECK(aligned.dims == std::array<Index, 3>{10, 10, 7});
  CHECK(aligned.fluid_fraction.sum() * 1e-3 == rel(volume, 1e-12));
  CHECK(aligned.smoke_mass() == rel(2.0 * volume, 1e-12));
  // h = 0.08, s = 3: 13 × 13 × 9 voxels centred on the box (sticking out by 0.02 in x and y,
  // 0.01 in z on each side); the fluid fraction counts exactly the sub-samples in the box but
  // not strictly in the cavity (point sampling of walls along the axes: within 4 % of the
  // volume), the smoke mass is the tets' exactly
  o.voxel_size = 0.08;
  o.subsamples = 3;
  const VoxelFrame v = voxelize(f, o);
  CHECK(v.dims == std::array<Index, 3>{13, 13, 9});
  CHECK((v.origin - Vec3(-0.02 + 0.04, -0.02 + 0.04, -0.01 + 0.04)).norm() < 1e-12);
  const double step = o.voxel_size / 3;
  const double inside =
      points_in(39, -0.02, step, 0, 1, true) * points_in(39, -0.02, step, 0, 1, true) *
          points_in(27, -0.01, step, 0, 0.7, true) -
      points_in(39, -0.02, step, 0.2, 0.8, false) * points_in(39, -0.02, step, 0.2, 0.8, false) *
          points_in(27, -0.01, step, 0.2, 0.5, false);
  CHECK(v.fluid_fraction.sum() * 27 == rel(inside, 1e-12));
  CHECK(v.smoke_mass() == rel(2.0 * volume, 1e-12));
  CHECK(v.fluid_fraction.sum() * std::pow(o.voxel_size, 3) == rel(volume, 0.04));
  // the voxel at the cavity's centre is empty: ambient temperature, no density, no velocity
  const Index c = 6 + 13 * (6 + 13 * 4);
  CHECK(v.fluid_fraction[c] == 0.0);
  CHECK(v.density[c] == 0.0);
  CHECK(v.temperature[c] == 280.0);
  CHECK(v.velocity.row(c).norm() == 0.0);
  // a corner voxel is part outside the box; the next one in is all fluid, with smoke and the
  // tets' (missing) temperature: the ambient
  CHECK(v.fluid_fraction[0] == rel(4.0 / 9, 1e-12));
  const Index w = 1 + 13 * (1 + 13 * 1);
  CHECK(v.fluid_fraction[w] == 1.0);
  CHECK(v.density[w] > 0.0);
  CHECK(v.temperature[w] == 280.0);
}

TEST_CASE("voxelize: a linear velocity is exact at the voxel centres inside the fluid") {
  const TetVolume f = jittered_cube(5, linear_velocity);
  for (const int s : {1, 2}) {
    CAPTURE(s);
    VoxelOptions o;
    o.voxel_size = 0.07;
    o.subsamples = s;
    const VoxelFrame v = voxelize(f, o);
    Index inside = 0;
    double worst = 0.0;
    for (Index k = 0; k < v.dims[2]; ++k)
      for (Index j = 0; j < v.dims[1]; ++j)
        for (Index i = 0; i < v.dims[0]; ++i) {
          const Index c = i + v.dims[0] * (j + v.dims[1] * k);
          if (v.fluid_fraction[c] < 1.0) continue;
          ++inside;
          const Vec3 x = v.origin + o.voxel_size * Vec3(i, j, k);
          worst = std::max(worst, (v.velocity.row(c).transpose() - linear_velocity(x)).norm());
        }
    CHECK(inside > 2000);  // 15³ voxels, the last layer of each axis partly outside
    CHECK(worst < 1e-12);
  }
}

TEST_CASE("voxelize: the same bits at 1 and 2 threads") {
  const TetVolume f = jittered_cube(8, linear_velocity);
  VoxelOptions o;
  o.voxel_size = 0.045;
  o.subsamples = 2;
  const int saved = thread_count();
  set_thread_count(1);
  const VoxelFrame a = voxelize(f, o);
  set_thread_count(2);
  const VoxelFrame b = voxelize(f, o);
  set_thread_count(saved);
  CHECK(a.fluid_fraction == b.fluid_fraction);
  CHECK(a.density == b.density);
  CHECK(a.temperature == b.temperature);
  CHECK(a.pressure == b.pressure);
  CHECK(a.velocity == b.velocity);
}

TEST_CASE("tet_volume_of: the run's frame as plain arrays") {
  const mesh::VolumeMesh box = mesh::make_box(Vec3::Zero(), Vec3::Ones(), Vec3i(2, 1, 1));
  const mesh::TetMesh m = mesh::build_tet_mesh(box.vertices, box.tets);
  fluid::MeshFrame frame{&m, {}};
  frame.fields.density = VecX::LinSpaced(m.num_tets(), 0.0, 1.0);
  frame.fields.vertex_velocity = MatX3::Ones(m.num_vertices(), 3);
  const TetVolume v = tet_volume_of(frame);
  CHECK(v.vertices == m.vertices);
  CHECK(v.tets == m.tets);
  CHECK(v.density == frame.fields.density);
  CHECK(v.temperature.size() == 0);
  CHECK(v.vertex_velocity == frame.fields.vertex_velocity);
  CHECK_THROWS_AS(tet_volume_of(fluid::MeshFrame{}), InternalError);
}

TEST_CASE("voxelize: a bad voxel size or too many sub-samples is an InputError") {
  const TetVolume f = jittered_cube(2, linear_velocity);
  VoxelOptions o;
  for (const double h : {0.0, -1.0, std::nan("")}) {
    o.voxel_size = h;
    CHECK_THROWS_AS(voxelize(f, o), InputError);
  }
  o.voxel_size = 1e-3;  // 1000³ voxels × 8 sub-samples
  const std::string msg = message_of<InputError>([&] { voxelize(f, o); });
  CHECK(msg.find("voxel size of 0.001 m") != std::string::npos);
  CHECK(msg.find("(0, 0, 0) .. (1, 1, 1)") != std::string::npos);
  CHECK(msg.find("2^31") != std::string::npos);
  TetVolume bad = f;
  bad.density.resize(3);
  o.voxel_size = 0.25;
  CHECK_THROWS_AS(voxelize(bad, o), InternalError);
}

TEST_CASE("liquid_surface: closed on the box's walls, facing out of the liquid; none without") {
  // A pool: 20 × 20 × 10 cells of 0.05 m, the liquid below z = 0.3 (φ = z − 0.3 at the
  // centres), so the surface is the pool's top capped on the floor and the four walls.
  fluid::GridFrameFields g;
  g.spacing = Vec3::Constant(0.05);
  g.cells = {20, 20, 10};
  const Index n = 4000;
  g.pressure = g.density = g.divergence = g.vorticity = VecX::Zero(n);
  g.temperature = VecX::Constant(n, 293.0);
  g.velocity = MatX3::Zero(n, 3);
  g.solid.assign(n, 0);
  g.phi.resize(n);
  for (Index c = 0; c < n; ++c) g.phi[c] = (c / 400 + 0.5) * 0.05 - 0.3;
  const ExportSurface s = liquid_surface(g);
  REQUIRE(s.triangles.rows() > 0);
  CHECK(s.velocity.rows() == s.points.rows());
  // closed: every edge in two triangles, run in opposite directions (consistently oriented)
  std::map<std::pair<int, int>, int> directed;
  double volume = 0.0;
  for (Index t = 0; t < s.triangles.rows(); ++t) {
    for (int e = 0; e < 3; ++e) ++directed[{s.triangles(t, e), s.triangles(t, (e + 1) % 3)}];
    const Vec3 p0 = s.points.row(s.triangles(t, 0)), p1 = s.points.row(s.triangles(t, 1)),
               p2 = s.points.row(s.triangles(t, 2));
    volume += p0.dot(p1.cross(p2)) / 6.0;  // > 0 for normals out of the enclosed liquid
  }
  for (const auto& [edge, count] : directed) {
    CHECK(count == 1);
    CHECK(directed.count({edge.second, edge.first}) == 1);
  }
  // the pool's 1 × 1 × 0.3 m³, less the contour's chamfers along the walls' edges (< 1 %)
  CHECK(volume == rel(0.3, 0.01));
  // no liquid yet (a stream still to arrive): no surface, and its PLY round trips empty
  g.phi = VecX::Constant(n, 0.1);
  const ExportSurface none = liquid_surface(g);
  CHECK(none.points.rows() == 0);
  CHECK(none.triangles.rows() == 0);
  TempDir dir("export_liquid_none");
  write_ply(dir.path / "liquid.ply", none);
  CHECK(read_ply(dir.path / "liquid.ply").triangles.rows() == 0);
}

TEST_CASE("voxel_frame_of: the grid's cells are the voxels") {
  const fluid::GridFrameFields g = small_grid();
  const VoxelFrame v = voxel_frame_of(g, 290.0);
  CHECK(v.dims == g.cells);
  CHECK((v.origin - Vec3(1.05, 2.1, 3.125)).norm() < 1e-12);
  CHECK(v.spacing == g.spacing);
  CHECK(v.fluid_fraction.sum() == 22.0);
  CHECK(v.fluid_fraction[5] == 0.0);
  CHECK(v.pressure == g.pressure);
  CHECK(v.velocity == g.velocity);
  CHECK(v.temperature == g.temperature);
  CHECK(v.phi == g.phi);
  CHECK(v.ambient_temperature == 290.0);
}

// ---- OpenVDB -------------------------------------------------------------------------------

TEST_CASE("write_vdb and read_vdb_summary: grids, active voxels, ranges, bounds, metadata") {
  TempDir dir("export_vdb");
  const TetVolume f = jittered_cube(6, linear_velocity);
  VoxelOptions o;
  o.voxel_size = 1.0 / 12;
  const VoxelFrame v = voxelize(f, o);
  for (const double threshold : {0.0, 1.5}) {
    CAPTURE(threshold);
    const fs::path p = dir.path / "fluid_000007.vdb";
    const std::vector<VdbGridSummary> written = write_vdb(p, v, {42, 0.125, "cube", threshold});
    CHECK(!fs::exists(dir.path / "fluid_000007.vdb.tmp"));
    const VdbFileSummary r = read_vdb_summary(p);
    CHECK(r.step == 42);
    CHECK(r.time == 0.125);
    REQUIRE(r.grids.size() == 4);
    std::set<std::string> names;
    for (const VdbGridSummary& g : r.grids) names.insert(g.name);
    CHECK(names == std::set<std::string>{"density", "temperature", "velocity", "pressure"});
    Index above = 0;
    for (Index c = 0; c < v.size(); ++c) above += v.density[c] > threshold ? 1 : 0;
    CHECK(above > 100);
    const VdbGridSummary& d = grid_named(r.grids, "density");
    CHECK(d.type == "float");
    CHECK(d.grid_class == "fog volume");
    CHECK(d.unit == "kg/m^3");
    CHECK(d.active_voxels == above);
    CHECK(d.max == rel(v.density.maxCoeff(), 1e-7));
    const VdbGridSummary& u = grid_named(r.grids, "velocity");
    CHECK(u.type == "vec3s");
    CHECK(u.unit == "m/s");
    CHECK(u.active_voxels == above);
    CHECK(u.max == rel(v.velocity.rowwise().norm().maxCoeff(), 1e-6));
    CHECK(grid_named(r.grids, "temperature").unit == "K");
    CHECK(grid_named(r.grids, "pressure").unit == "Pa");
    // the bounds: the outer faces of the voxels above the threshold (the unit cube with 0)
    std::array<double, 6> box = {1e9, 1e9, 1e9, -1e9, -1e9, -1e9};
    for (Index c = 0; c < v.size(); ++c) {
      if (v.density[c] <= threshold) continue;
      const Index ijk[3] = {c % 12, (c / 12) % 12, c / 144};
      for (std::size_t a = 0; a < 3; ++a) {
        box[a] = std::min(box[a], (static_cast<double>(ijk[a]) / 12));
        box[a + 3] = std::max(box[a + 3], (static_cast<double>(ijk[a]) + 1) / 12);
      }
    }
    if (threshold == 0.0) CHECK(box == std::array<double, 6>{0, 0, 0, 1, 1, 1});
    for (std::size_t a = 0; a < 6; ++a) CHECK(std::abs(d.bounds[a] - box[a]) < 1e-12);
    // what write_vdb returns is what the reader sees
    REQUIRE(written.size() == 4);
    for (const VdbGridSummary& w : written) {
      const VdbGridSummary& g = grid_named(r.grids, w.name);
      CHECK(g.active_voxels == w.active_voxels);
      CHECK(g.min == w.min);
      CHECK(g.max == w.max);
      CHECK(g.bounds == w.bounds);
    }
    if (threshold == 0.0) {
      CHECK(d.active_voxels == v.size());
      CHECK(vdb_grid_integral(p, "density") == rel(v.smoke_mass(), 1e-6));
    }
  }
}

TEST_CASE("write_vdb: a grid fluid's liquid as a level set, velocity on the liquid's voxels") {
  TempDir dir("export_vdb_liquid");
  const VoxelFrame v = voxel_frame_of(small_grid(), 290.0);
  const fs::path p = dir.path / "liquid.vdb";
  write_vdb(p, v, {3, 0.5, "grid", 1e-4});
  const VdbFileSummary r = read_vdb_summary(p);
  REQUIRE(r.grids.size() == 5);
  // no smoke: density and temperature are empty
  CHECK(grid_named(r.grids, "density").active_voxels == 0);
  CHECK(grid_named(r.grids, "temperature").active_voxels == 0);
  // the liquid is the lower layer (φ = −0.175 there, 0.075 above) but its solid cell 5
  const VdbGridSummary& u = grid_named(r.grids, "velocity");
  CHECK(u.active_voxels == 11);
  CHECK(u.max == rel(Vec3(11, -11, 5.5).norm(), 1e-6));
  CHECK(grid_named(r.grids, "pressure").active_voxels == 11);
  // world bounds: the lower layer of cells, [1, 1.4] × [2, 2.6] × [3, 3.25]
  const std::array<double, 6> lower = {1, 2, 3, 1.4, 2.6, 3.25};
  for (int a = 0; a < 6; ++a) CHECK(u.bounds[static_cast<std::size_t>(a)] == rel(lower[a], 1e-12));
  // surface: every cell is within 3 h = 0.75 of the surface, and the layer of voxels around
  // the box is air (h/2 = 0.125, h the largest spacing): 6 × 5 × 4 − 24 = 96 more voxels, one
  // beyond each side
  const VdbGridSummary& s = grid_named(r.grids, "surface");
  CHECK(s.grid_class == "level set");
  CHECK(s.unit == "m");
  CHECK(s.active_voxels == 24 + 96);
  CHECK(s.min == rel(-0.175, 1e-6));
  CHECK(s.max == rel(0.125, 1e-6));
  CHECK(s.bounds[2] == rel(3.0 - 0.25, 1e-12));
  CHECK(s.bounds[5] == rel(3.5 + 0.25, 1e-12));
  CHECK_THROWS_AS(vdb_grid_integral(p, "velocity"), InputError);
  CHECK(message_of<InputError>([&] { vdb_grid_integral(p, "smoke"); }).find("smoke") !=
        std::string::npos);
}

TEST_CASE("read_vdb_summary: a missing or foreign file is an InputError naming it") {
  TempDir dir("export_vdb_read");
  const fs::path text = dir.path / "not_a.vdb";
  std::ofstream(text) << "hello\n";
  CHECK(message_of<InputError>([&] { read_vdb_summary(text); }).find("not_a.vdb") !=
        std::string::npos);
  CHECK(message_of<InputError>([&] { read_vdb_summary(dir.path / "gone.vdb"); }).find("gone.vdb") !=
        std::string::npos);
}

// ---- frames and the manifest -----------------------------------------------------------------

TEST_CASE("export_frame and ExportManifest: the files, the JSON round trip, truncate") {
  TempDir dir("export_frame");
  const TetVolume f = jittered_cube(3, linear_velocity);
  VoxelOptions o;
  o.voxel_size = 0.2;
  const VoxelFrame v = voxelize(f, o);
  const std::vector<NamedSurface> surfaces = {{"block", body_export_surface(make_block())}};
  ExportRequest request;
  request.vdb = request.ply = true;
  request.scene = "cube";
  ExportManifest manifest(dir.path / "export.json", "cube");
  for (int frame = 0; frame < 3; ++frame)
    manifest.add(export_frame(dir.path, frame, 10 * frame, 0.1 * frame, surfaces, &v, request));
  CHECK(fs::exists(dir.path / "vdb/fluid_000002.vdb"));
  CHECK(fs::exists(dir.path / "ply/block_000002.ply"));
  const ExportedFrame& last = manifest.frames().back();
  CHECK(last.vdb_file == "vdb/fluid_000002.vdb");
  CHECK(last.step == 20);
  CHECK(last.grids.size() == 4);
  CHECK(last.smoke_mass == v.smoke_mass());
  REQUIRE(last.meshes.size() == 1);
  CHECK(last.meshes[0].file == "ply/block_000002.ply");
  CHECK(last.meshes[0].triangles == 44);
  // export.json reads back to the same frames
  const nlohmann::json j = nlohmann::json::parse(test::read_text(dir.path / "export.json"));
  CHECK(j.at("format") == "tetfsi-export 1");
  CHECK(j.at("scene") == "cube");
  REQUIRE(j.at("frames").size() == 3);
  const ExportedFrame back = exported_frame_from_json(j.at("frames")[2]);
  CHECK(to_json(back) == to_json(last));
  CHECK(back.voxel_size == last.voxel_size);
  CHECK(back.grids[0].bounds == last.grids[0].bounds);
  // a frame of the same number replaces it; truncate keeps the frames before
  ExportedFrame again = last;
  again.step = 21;
  manifest.add(again);
  CHECK(manifest.frames().size() == 3);
  CHECK(manifest.frames().back().step == 21);
  manifest.truncate(1);
  const nlohmann::json t = nlohmann::json::parse(test::read_text(dir.path / "export.json"));
  REQUIRE(t.at("frames").size() == 1);
  CHECK(t.at("frames")[0].at("frame") == 0);
  CHECK(!fs::exists(dir.path / "export.json.tmp"));
  CHECK_THROWS_AS(exported_frame_from_json(nlohmann::json{{"frame", 1}}), InputError);
  // ply only, no fluid
  request.vdb = false;
  const ExportedFrame p = export_frame(dir.path, 5, 50, 0.5, surfaces, nullptr, request);
  CHECK(p.vdb_file.empty());
  CHECK(p.grids.empty());
  CHECK(!fs::exists(dir.path / "vdb/fluid_000005.vdb"));
}

TEST_CASE("export: an unwritable folder is an InputError naming the file") {
  TempDir dir("export_unwritable");
  const mesh::VolumeMesh m = mesh::make_box(Vec3::Zero(), Vec3::Ones(), Vec3i(1, 1, 1));
  const ExportSurface s = tet_boundary_surface(m.vertices, m.tets, MatX3(), VecX());
  const fs::path nowhere = "/nonexistent_tetfsi_dir/sub";
  auto one_line_naming = [](const std::string& msg, const std::string& name) {
    CAPTURE(msg);
    CHECK(msg.find(name) != std::string::npos);
    CHECK(msg.find('\n') == std::string::npos);
  };
  one_line_naming(message_of<InputError>([&] { write_ply(nowhere / "s.ply", s); }), "s.ply");
  const VoxelFrame v = voxel_frame_of(small_grid(), 290.0);
  one_line_naming(message_of<InputError>([&] { write_vdb(nowhere / "f.vdb", v, {}); }), "f.vdb");
  ExportManifest manifest(nowhere / "export.json", "x");
  one_line_naming(message_of<InputError>([&] { manifest.add(ExportedFrame{}); }), "export.json");
  // a folder that is a file
  std::ofstream(dir.path / "file") << "x";
  ExportRequest request;
  request.ply = true;
  one_line_naming(message_of<InputError>([&] {
                    export_frame(dir.path / "file", 0, 0, 0.0, {{"s", s}}, nullptr, request);
                  }),
                  "file/ply");
}
