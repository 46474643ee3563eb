// The MAC grid and its classification against solids (fluid/grid/grid.hpp).
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>

#include <Eigen/Geometry>

#include "core/error.hpp"
#include "fluid/grid/grid.hpp"
#include "mesh/generate.hpp"
#include "mesh/volume_mesh.hpp"

using namespace tetfsi;
using namespace tetfsi::fluid;
using mesh::FaceKind;

namespace {

mesh::SolidSurface surface_of(const mesh::VolumeMesh& v, int body) {
  return mesh::SolidSurface{body, v.vertices, mesh::boundary_triangles(v)};
}

mesh::SolidSurface sphere(const Vec3& c, double r, int body) {
  const mesh::SurfaceMesh s = mesh::make_icosphere(c, r, 3);
  return mesh::SolidSurface{body, s.vertices, s.triangles};
}

/// Signed volume of a closed triangle surface.
double enclosed_volume(const mesh::SolidSurface& s) {
  double v = 0;
  for (Index t = 0; t < s.triangles.rows(); ++t) {
    const Vec3 a = s.vertices.row(s.triangles(t, 0)), b = s.vertices.row(s.triangles(t, 1)),
               c = s.vertices.row(s.triangles(t, 2));
    v += a.dot(b.cross(c)) / 6.0;
  }
  return v;
}

}  // namespace

TEST_CASE("MAC grid: faces lie between their cells, indices round-trip") {
  const GridSpec g = GridSpec::from_cells(Vec3(0, -1, 2), Vec3(1, 1, 2.5), {4, 5, 3});
  CHECK(g.num_cells() == 60);
  CHECK(g.num_faces() == 5 * 5 * 3 + 4 * 6 * 3 + 4 * 5 * 4);
  for (Index f = 0; f < g.num_faces(); ++f) {
    const int a = g.face_axis(f);
    const auto ijk = g.face_ijk(f);
    REQUIRE(g.face(a, ijk[0], ijk[1], ijk[2]) == f);
    const auto c = g.face_cells(f);
    const Vec3 x = g.face_centre(f);
    if (c[0] >= 0 && c[1] >= 0) {
      CHECK((0.5 * (g.cell_centre(c[0]) + g.cell_centre(c[1])) - x).norm() < 1e-12);
      CHECK(g.face_side(f) == -1);
    } else {
      const Index in = c[0] >= 0 ? c[0] : c[1];
      CHECK(std::abs((g.cell_centre(in) - x)[a]) == doctest::Approx(0.5 * g.h[a]));
      CHECK(g.face_side(f) == 2 * a + (c[1] < 0 ? 1 : 0));
    }
  }
  for (Index c = 0; c < g.num_cells(); ++c) CHECK(g.cell_at(g.cell_centre(c)) == c);
}

TEST_CASE("MAC grid: a sphere's inside cells have its volume, its boundary faces are Solid") {
  const GridSpec g = GridSpec::from_cell_size(Vec3::Zero(), Vec3::Ones(), 1.0 / 40);
  const mesh::SolidSurface s = sphere(Vec3(0.45, 0.5, 0.62), 0.3, 0);
  const double volume = enclosed_volume(s);
  const GridCells gc = classify_grid(g, mesh::FluidDomain{}, {s});
  Index inside = 0;
  for (Index c = 0; c < g.num_cells(); ++c) inside += gc.cell_body[c] == 0;
  // Cell-centre sampling of a ball of 24 cells diameter: within 2 % of its volume.
  CHECK(static_cast<double>(inside) * g.cell_volume() == doctest::Approx(volume).epsilon(0.02));
  Index solid_faces = 0;
  for (Index f = 0; f < g.num_faces(); ++f) {
    const auto c = g.face_cells(f);
    if (c[0] < 0 || c[1] < 0) {
      CHECK(gc.face_kind[f] == FaceKind::Wall);
      continue;
    }
    const bool in0 = gc.cell_body[c[0]] == 0, in1 = gc.cell_body[c[1]] == 0;
    if (in0 == in1) {
      if (in0 || gc.face_kind[f] != FaceKind::Solid) {
        CHECK(gc.face_kind[f] == (in0 ? FaceKind::Wall : FaceKind::Interior));
        continue;
      }
      // Both centres outside, the segment cuts a cap of the sphere: it passes inside it.
      const Vec3 p = g.cell_centre(c[0]), q = g.cell_centre(c[1]), o(0.45, 0.5, 0.62);
      const double s_min = std::clamp((o - p).dot(q - p) / (q - p).squaredNorm(), 0.0, 1.0);
      CHECK((p + s_min * (q - p) - o).norm() < 0.3 * 1.001);
      continue;
    }
    ++solid_faces;
    REQUIRE(gc.face_kind[f] == FaceKind::Solid);
    const SurfacePoint& sp = gc.face_solid[f];
    REQUIRE(sp.body == 0);
    CHECK(sp.bary.sum() == doctest::Approx(1.0));
    CHECK(sp.bary.minCoeff() >= 0.0);
    // The crossing lies on the centre-to-centre segment, on the sphere.
    Vec3 x = Vec3::Zero();
    for (int k = 0; k < 3; ++k)
      x += sp.bary[k] * s.vertices.row(s.triangles(sp.triangle, k)).transpose();
    const Vec3 p = g.cell_centre(c[0]), q = g.cell_centre(c[1]);
    CHECK(((x - p).cross(q - p)).norm() / (q - p).squaredNorm() < 1e-9);
    CHECK((x - p).dot(q - p) >= 0.0);
    CHECK((x - q).dot(p - q) >= 0.0);
    CHECK((x - Vec3(0.45, 0.5, 0.62)).norm() == doctest::Approx(0.3).epsilon(0.01));
  }
  CHECK(solid_faces > 1000);
}

TEST_CASE("MAC grid: a sheet thinner than a cell cuts every segment across it") {
  // 20 × 10 × 10 cells of 0.05 m; the sheet is 0.3 cell thick between two cell centres and
  // spans the channel's whole cross-section.
  const GridSpec g = GridSpec::from_cells(Vec3::Zero(), Vec3(1, 0.5, 0.5), {20, 10, 10});
  const double x0 = 0.505;  // [0.505, 0.52]: between the centres 0.475 and 0.525
  const mesh::VolumeMesh sheet =
      mesh::make_box(Vec3(x0, 0.0, 0.0), Vec3(x0 + 0.015, 0.5, 0.5), Vec3i(1, 4, 4));
  const GridCells gc = classify_grid(g, mesh::FluidDomain{}, {surface_of(sheet, 0)});
  for (Index c = 0; c < g.num_cells(); ++c) CHECK(gc.cell_body[c] == -1);
  for (Index k = 0; k < 10; ++k)
    for (Index j = 0; j < 10; ++j)
      for (Index i = 1; i < 20; ++i) {
        const Index f = g.face(0, i, j, k);
        CHECK(gc.face_kind[f] == (i == 10 ? FaceKind::Solid : FaceKind::Interior));
      }
  // Faces along y and z never cross it (it is parallel to them, between their lines).
  for (Index f = g.face_offset(1); f < g.num_faces(); ++f)
    CHECK(gc.face_kind[f] != FaceKind::Solid);
  const Vec3 left = g.cell_centre(g.cell(9, 3, 4)), right = g.cell_centre(g.cell(10, 3, 4));
  CHECK_FALSE(gc.solids.visible(left, right));
  CHECK(gc.solids.visible(left, g.cell_centre(g.cell(8, 4, 5))));
  CHECK(gc.solids.near(g.cell(9, 3, 4)));
  CHECK_FALSE(gc.solids.near(g.cell(2, 3, 4)));
}

TEST_CASE("MAC grid: box patches classify the box faces") {
  const GridSpec g = GridSpec::from_cells(Vec3::Zero(), Vec3(2, 1, 1), {8, 4, 4});
  mesh::FluidDomain d;
  d.patches.push_back({"out", FaceKind::Open, 1, Vec2(0, 0), Vec2(1, 1)});
  d.patches.push_back({"jet", FaceKind::Inflow, 0, Vec2(0.25, 0.25), Vec2(0.75, 0.75)});
  const GridCells gc = classify_grid(g, d, {});
  Index open = 0, inflow = 0, wall = 0;
  for (Index f = 0; f < g.num_faces(); ++f) {
    open += gc.face_kind[f] == FaceKind::Open;
    inflow += gc.face_kind[f] == FaceKind::Inflow;
    wall += gc.face_kind[f] == FaceKind::Wall;
  }
  CHECK(open == 16);
  CHECK(inflow == 4);
  CHECK(wall == 2 * (8 * 4 + 8 * 4) + 16 - 4);
}

TEST_CASE("MAC grid: bad grids and unresolved bodies are one-line errors naming the key") {
  CHECK_THROWS_WITH_AS(GridSpec::from_cell_size(Vec3::Zero(), Vec3::Ones(), 0.0),
                       doctest::Contains("fluid.grid.cell_size"), InputError);
  CHECK_THROWS_WITH_AS(GridSpec::from_cell_size(Vec3::Zero(), Vec3::Ones(), std::nan("")),
                       doctest::Contains("fluid.grid.cell_size"), InputError);
  CHECK_THROWS_WITH_AS(GridSpec::from_cells(Vec3::Zero(), Vec3::Ones(), {4, 0, 4}),
                       doctest::Contains("fluid.grid.cells"), InputError);
  const GridSpec g = GridSpec::from_cells(Vec3::Zero(), Vec3::Ones(), {10, 10, 10});
  CHECK_THROWS_WITH_AS(classify_grid(g, {}, {sphere(Vec3(0.5, 0.5, 0.5), 0.04, 3)}),
                       doctest::Contains("body 3: smaller than a grid cell"), InputError);
  CHECK_THROWS_WITH_AS(classify_grid(g, {}, {sphere(Vec3(0.9, 0.5, 0.5), 0.2, 1)}),
                       doctest::Contains("body 1: it leaves the fluid box"), InputError);
}

// ---- the projection (fluid/grid/projection.hpp) -------------------------------------------

#include <random>

#include "fluid/grid/projection.hpp"

TEST_CASE("MAC grid projection: a random field around a sphere becomes divergence-free") {
  const GridSpec g = GridSpec::from_cells(Vec3::Zero(), Vec3(1.5, 1, 1), {24, 16, 16});
  mesh::FluidDomain d;
  d.patches.push_back({"out", FaceKind::Open, 1, Vec2(0, 0), Vec2(1, 1)});
  d.patches.push_back({"jet", FaceKind::Inflow, 0, Vec2(0.3, 0.3), Vec2(0.7, 0.7)});
  const GridCells gc = classify_grid(g, d, {sphere(Vec3(0.7, 0.5, 0.5), 0.2, 0)});
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> U(-1, 1);
  VecX u(g.num_faces());
  for (Index f = 0; f < g.num_faces(); ++f) {
    const FaceKind k = gc.face_kind[f];
    u[f] = k == FaceKind::Interior || k == FaceKind::Open ? U(rng)
           : k == FaceKind::Inflow                        ? 2.0
                                                          : 0.0;
  }
  const VecX u_star = u;
  VecX q;
  auto solver = make_linear_solver(SolverKind::Amg, SolverOptions{.rel_tol = 1e-12});
  const ProjectionReport rep = grid_project(gc, VecX(), u, q, *solver);
  REQUIRE(rep.converged);
  CHECK(rep.pinned_regions == 0);
  CHECK(rep.divergence_after <= 1e-8 * rep.divergence_before);
  // Prescribed faces keep their values; the correction is a gradient (curl-free on a plaquette).
  for (Index f = 0; f < g.num_faces(); ++f)
    if (gc.face_kind[f] != FaceKind::Interior && gc.face_kind[f] != FaceKind::Open)
      CHECK(u[f] == u_star[f]);
  for (Index c = 0; c < g.num_cells(); ++c)
    if (!gc.fluid(c)) CHECK(q[c] == 0.0);
}

namespace {

/// The pressure matrix as the faces' triplets summed by setFromTriplets (the assembly before
/// grid_pressure_matrix built its columns directly), with the same pins.
SparseMatrix triplet_pressure_matrix(const GridCells& gc, const GridNumbering& n,
                                     const Regions& r) {
  const GridSpec& g = gc.grid;
  Triplets t;
  for (Index f = 0; f < g.num_faces(); ++f) {
    const FaceKind k = gc.face_kind[f];
    if (k != FaceKind::Interior && k != FaceKind::Open) continue;
    const double w = g.face_area(g.face_axis(f)) / grid_face_dual(gc, f);
    if (k == FaceKind::Open) {
      const Index in = grid_inner_cell(gc, f);
      if (in >= 0) t.emplace_back(n.unknown[in], n.unknown[in], w);
      continue;
    }
    const auto c = g.face_cells(f);
    const Index a = n.unknown[c[0]], b = n.unknown[c[1]];
    if (a < 0 || b < 0) {
      if (a >= 0 || b >= 0) t.emplace_back(std::max(a, b), std::max(a, b), w);
      continue;
    }
    t.emplace_back(a, a, w);
    t.emplace_back(b, b, w);
    t.emplace_back(a, b, -w);
    t.emplace_back(b, a, -w);
  }
  SparseMatrix M(static_cast<Index>(n.cell.size()), static_cast<Index>(n.cell.size()));
  M.setFromTriplets(t.begin(), t.end());
  for (Index reg = 0; reg < r.count(); ++reg)
    if (!r.has_open[reg])
      M.coeffRef(n.unknown[r.first_cell[reg]], n.unknown[r.first_cell[reg]]) *= 2.0;
  return M;
}

/// A sphere in a box with an open side, a sealed shell's cavity (a second, pinned region)
/// and a free surface: air above z = 0.62 with φ placing the surface inside the cells.
GridCells mixed_grid() {
  const GridSpec g = GridSpec::from_cells(Vec3::Zero(), Vec3(1.5, 1, 1), {24, 16, 16});
  mesh::FluidDomain d;
  d.patches.push_back({"out", FaceKind::Open, 1, Vec2(0, 0), Vec2(1, 0.5)});
  mesh::SurfaceMesh outer = mesh::make_icosphere(Vec3(1.05, 0.5, 0.4), 0.3, 3);
  mesh::SurfaceMesh inner = mesh::make_icosphere(Vec3(1.05, 0.5, 0.4), 0.2, 3);
  for (Index t = 0; t < inner.triangles.rows(); ++t)
    std::swap(inner.triangles(t, 1), inner.triangles(t, 2));  // inward: a shell
  mesh::SolidSurface shell{1, MatX3(outer.vertices.rows() + inner.vertices.rows(), 3),
                           MatX3i(outer.triangles.rows() + inner.triangles.rows(), 3)};
  shell.vertices << outer.vertices, inner.vertices;
  shell.triangles << outer.triangles,
      (inner.triangles.array() + static_cast<int>(outer.vertices.rows())).matrix();
  GridCells gc = classify_grid(g, d, {sphere(Vec3(0.35, 0.5, 0.4), 0.15, 0), shell});
  gc.air.assign(g.num_cells(), 0);
  gc.phi = VecX(g.num_cells());
  for (Index c = 0; c < g.num_cells(); ++c) {
    gc.phi[c] = g.cell_centre(c).z() - 0.62;
    if (gc.phi[c] > 0 && gc.cell_body[c] < 0) gc.air[c] = 1;
  }
  return gc;
}

}  // namespace

TEST_CASE("MAC grid projection: the pressure matrix is the faces' triplets summed, bit for bit") {
  const GridCells gc = mixed_grid();
  const GridNumbering n = number_fluid_cells(gc);
  const Regions r = grid_regions(gc);
  Index pinned = 0, surface = 0;
  for (Index reg = 0; reg < r.count(); ++reg) pinned += !r.has_open[reg];
  for (Index f = 0; f < gc.grid.num_faces(); ++f) surface += gc.surface_face(f);
  REQUIRE(pinned >= 1);  // the shell's cavity
  REQUIRE(surface > 100);
  const SparseMatrix M = grid_pressure_matrix(gc, n, r);
  const SparseMatrix R = triplet_pressure_matrix(gc, n, r);
  REQUIRE(M.nonZeros() == R.nonZeros());
  REQUIRE(M.rows() == R.rows());
  Index differ = 0;
  for (Index j = 0; j < M.cols(); ++j) {
    SparseMatrix::InnerIterator a(M, j), b(R, j);
    for (; a && b; ++a, ++b) differ += a.row() != b.row() || a.value() != b.value();
    differ += static_cast<bool>(a) != static_cast<bool>(b);
  }
  CHECK(differ == 0);
}

TEST_CASE("MAC grid projection: pfmg projects like amg, on open, pinned and free-surface cells") {
  const GridCells gc = mixed_grid();
  const GridSpec& g = gc.grid;
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> U(-1, 1);
  VecX u0(g.num_faces());
  for (Index f = 0; f < g.num_faces(); ++f)
    u0[f] =
        gc.face_kind[f] == FaceKind::Interior || gc.face_kind[f] == FaceKind::Open ? U(rng) : 0.0;
  VecX u_amg = u0, u_pfmg = u0, q_amg, q_pfmg;
  auto amg = make_linear_solver(SolverKind::Amg, SolverOptions{.rel_tol = 1e-12});
  auto pfmg = make_linear_solver(SolverKind::Pfmg, SolverOptions{.rel_tol = 1e-12});
  const ProjectionReport ra = grid_project(gc, VecX(), u_amg, q_amg, *amg);
  const ProjectionReport rp = grid_project(gc, VecX(), u_pfmg, q_pfmg, *pfmg);
  REQUIRE(ra.converged);
  REQUIRE(rp.converged);
  CHECK(rp.pinned_regions == ra.pinned_regions);
  CHECK(rp.pinned_regions >= 1);
  CHECK(rp.divergence_after <= 1e-8 * rp.divergence_before);
  CHECK(rp.iterations <= 40);
  // Both to 1e-12 of the right-hand side: the pressures agree to ~1e-9 of their range.
  CHECK((q_pfmg - q_amg).lpNorm<Eigen::Infinity>() <= 1e-8 * q_amg.lpNorm<Eigen::Infinity>());
  CHECK((u_pfmg - u_amg).lpNorm<Eigen::Infinity>() <= 1e-8 * u0.lpNorm<Eigen::Infinity>());
}

TEST_CASE("MAC grid projection: a thin sheet across a channel holds a pressure difference") {
  // Open ends at q = Δq (−x) and 0 (+x); a sheet 0.3 cell thick across the whole channel.
  const GridSpec g = GridSpec::from_cells(Vec3::Zero(), Vec3(1, 0.5, 0.5), {20, 10, 10});
  mesh::FluidDomain d;
  d.patches.push_back({"in", FaceKind::Open, 0, Vec2(0, 0), Vec2(0.5, 0.5)});
  d.patches.push_back({"out", FaceKind::Open, 1, Vec2(0, 0), Vec2(0.5, 0.5)});
  const mesh::VolumeMesh sheet =
      mesh::make_box(Vec3(0.505, 0.0, 0.0), Vec3(0.52, 0.5, 0.5), Vec3i(1, 4, 4));
  const GridCells gc = classify_grid(g, d, {surface_of(sheet, 0)});
  const double dq = 0.01;  // (h/ρ) Δp, m²/s
  VecX q_open = VecX::Zero(g.num_faces());
  for (Index f = 0; f < g.num_faces(); ++f)
    if (gc.face_kind[f] == FaceKind::Open && g.face_side(f) == 0) q_open[f] = dq;
  VecX u = VecX::Zero(g.num_faces()), q;
  auto solver = make_linear_solver(SolverKind::Amg, SolverOptions{.rel_tol = 1e-12});
  const ProjectionReport rep = grid_project(gc, q_open, u, q, *solver);
  REQUIRE(rep.converged);
  // Without the sheet the channel would carry u = Δq / L (1e-2 m/s); with it nothing moves.
  const double driving = dq / 1.0;
  CHECK(u.cwiseAbs().maxCoeff() <= 1e-10 * driving);
  for (Index c = 0; c < g.num_cells(); ++c) {
    const bool left = g.cell_ijk(c)[0] < 10;
    CHECK(q[c] == doctest::Approx(left ? dq : 0.0).epsilon(1e-9).scale(dq));
  }
}

// ---- the interface operators (fluid/grid/interface.hpp) -----------------------------------

#include "fluid/grid/interface.hpp"

namespace {

BodyInterface whole_body(const mesh::SolidSurface& s) {
  BodyInterface b;
  b.triangles = s.triangles;
  b.surface_node =
      VecXi::LinSpaced(s.vertices.rows(), 0, static_cast<Index>(s.vertices.rows()) - 1);
  b.num_nodes = static_cast<Index>(s.vertices.rows());
  return b;
}

/// Σ over nodes of a per-DOF force vector.
Vec3 net_force(const VecX& F) {
  Vec3 s = Vec3::Zero();
  for (Index i = 0; i < F.size() / 3; ++i) s += F.segment<3>(3 * i);
  return s;
}

}  // namespace

TEST_CASE("MAC grid interface: the sheet in the channel feels Δp·A with both forms of J") {
  const GridSpec g = GridSpec::from_cells(Vec3::Zero(), Vec3(1, 0.5, 0.5), {20, 10, 10});
  mesh::FluidDomain d;
  d.patches.push_back({"in", FaceKind::Open, 0, Vec2(0, 0), Vec2(0.5, 0.5)});
  d.patches.push_back({"out", FaceKind::Open, 1, Vec2(0, 0), Vec2(0.5, 0.5)});
  const mesh::VolumeMesh sheet =
      mesh::make_box(Vec3(0.505, 0.0, 0.0), Vec3(0.52, 0.5, 0.5), Vec3i(1, 4, 4));
  const mesh::SolidSurface surf = surface_of(sheet, 0);
  const GridCells gc = classify_grid(g, d, {surf});
  const double dp = 250.0;  // Pa; q = p here (h/ρ = 1)
  VecX q_open = VecX::Zero(g.num_faces());
  for (Index f = 0; f < g.num_faces(); ++f)
    if (gc.face_kind[f] == FaceKind::Open && g.face_side(f) == 0) q_open[f] = dp;
  VecX u = VecX::Zero(g.num_faces()), p;
  auto solver = make_linear_solver(SolverKind::Amg, SolverOptions{.rel_tol = 1e-12});
  REQUIRE(grid_project(gc, q_open, u, p, *solver).converged);
  const GridInterface ops(gc, {whole_body(surf)});
  CHECK(ops.faces().size() == 100);
  const double area = 0.5 * 0.5;
  const Vec3 Fc = net_force(ops.J_consistent() * p), Fp = net_force(ops.J_paper() * p);
  MESSAGE("net force on the sheet: consistent ", Fc.transpose(), ", paper ", Fp.transpose(),
          " (Δp·A = ", dp * area, " N along x)");
  CHECK(Fc[0] == doctest::Approx(dp * area).epsilon(0.05));
  CHECK(Fp[0] == doctest::Approx(dp * area).epsilon(0.05));
  CHECK(std::abs(Fp[1]) + std::abs(Fp[2]) < 0.01 * dp * area);
}

TEST_CASE("MAC grid interface: H moves with the body, J_consistent = (V D1 H)ᵀ, J_paper is ∫ p n") {
  // A linear pressure p = G·x on the fluid cells around a sphere: the force is −∮ p n dA = −V G.
  // The paper's J fits a linear field where a trilinear corner is solid, so it is exact up to
  // the sphere's faceting; the consistent J pushes each face with its cell's pressure, half
  // a cell out: O(h / R), measured 11 % at R = 6 cells, 6.7 % at 12.
  const Vec3 o(0.48, 0.53, 0.5), G(100.0, -40.0, 250.0);
  const mesh::SolidSurface s = sphere(o, 0.25, 0);
  const Vec3 expect = -enclosed_volume(s) * G;
  double err_prev[2] = {0, 0};
  for (Index n : {24, 48}) {
    const GridSpec g = GridSpec::from_cells(Vec3::Zero(), Vec3::Ones(), {n, n, n});
    const GridCells gc = classify_grid(g, {}, {s});
    const GridInterface ops(gc, {whole_body(s)});
    // A rigid translation v: every Solid face gets v's component along its axis.
    const Vec3 v(0.3, -0.2, 0.7);
    VecX ub(3 * s.vertices.rows());
    for (Index i = 0; i < s.vertices.rows(); ++i) ub.segment<3>(3 * i) = v;
    VecX uf = VecX::Zero(g.num_faces());
    ops.apply_H({ub}, uf);
    CHECK((ops.H() * ub - uf).cwiseAbs().maxCoeff() < 1e-15);
    for (const GridInterfaceFace& i : ops.faces()) CHECK(uf[i.face] == doctest::Approx(v[i.axis]));
    VecX p = VecX::Zero(g.num_cells());
    for (Index c = 0; c < g.num_cells(); ++c)
      if (gc.fluid(c)) p[c] = G.dot(g.cell_centre(c));
    const Vec3 Fc = net_force(ops.J_consistent() * p), Fp = net_force(ops.J_paper() * p);
    const double err[2] = {(Fp - expect).norm() / expect.norm(),
                           (Fc - expect).norm() / expect.norm()};
    MESSAGE(n, " cells: relative force error paper ", err[0], ", consistent ", err[1]);
    CHECK(err[0] < 1e-5);  // measured 1.7e-7 and 8.4e-8
    CHECK(err[1] < 0.15);
    if (n == 48) {
      CHECK(err[1] < 0.65 * err_prev[1]);
    }
    err_prev[0] = err[0];
    err_prev[1] = err[1];
    // Energy: the fluid's power on the body equals the body's on the fluid (consistent J).
    const SparseMatrix VD1H = (g.cell_volume() * ops.D1()) * ops.H();
    CHECK(std::abs(p.dot(VD1H * ub) - (ops.J_consistent() * p).dot(ub)) <
          1e-12 * std::abs(p.dot(VD1H * ub)));
  }
}

// ---- advection (fluid/grid/advect.hpp) ----------------------------------------------------

#include "fluid/grid/advect.hpp"

TEST_CASE("MAC grid advection: a free stream stays exact, a sealed shell stays smoke-free") {
  const GridSpec g = GridSpec::from_cells(Vec3::Zero(), Vec3(1.5, 1, 1), {24, 16, 16});
  SUBCASE("free stream, no solids") {
    const GridCells gc = classify_grid(g, {}, {});
    const Vec3 U(0.8, -0.3, 0.5);
    VecX u(g.num_faces());
    for (Index f = 0; f < g.num_faces(); ++f) u[f] = U[g.face_axis(f)];
    const Eigen::MatrixXd s = Eigen::MatrixXd::Constant(g.num_cells(), 1, 2.5);
    const GridAdvected a = grid_advect(gc, gc, u, s, 0.1, Eigen::VectorXd::Zero(1));
    for (Index f = 0; f < g.num_faces(); ++f)
      if (gc.face_kind[f] == FaceKind::Interior) CHECK(std::abs(a.u[f] - u[f]) < 1e-14);
    CHECK((a.scalars.array() - 2.5).abs().maxCoeff() < 1e-14);
  }
  SUBCASE("a shell 0.4 cell thick in a flow of smoke") {
    const Vec3 o(0.62, 0.5, 0.47);
    const double hc = g.h[0], r_in = 0.25, r_out = 0.25 + 0.4 * hc;
    const mesh::VolumeMesh shell = mesh::make_spherical_shell(o, r_in, r_out, 3, 1);
    const GridCells gc = classify_grid(g, {}, {surface_of(shell, 0)});
    // A swirling field that crosses the shell everywhere (the shell is kinematic here).
    VecX u(g.num_faces());
    for (Index f = 0; f < g.num_faces(); ++f) {
      const Vec3 x = g.face_centre(f) - o;
      const Vec3 v(1.0 - x[1], 0.5 + x[0], 0.7 * std::sin(6 * x[0]));
      u[f] = v[g.face_axis(f)];
    }
    Eigen::MatrixXd s(g.num_cells(), 1);
    Index inside = 0;
    for (Index c = 0; c < g.num_cells(); ++c) {
      const bool in = (g.cell_centre(c) - o).norm() < r_in;
      s(c, 0) = in ? 0.0 : 1.0;
      inside += in && gc.fluid(c);
    }
    REQUIRE(inside > 100);
    Index clamped = 0;
    for (int step = 0; step < 10; ++step) {
      const GridAdvected a = grid_advect(gc, gc, u, s, 0.05, Eigen::VectorXd::Zero(1));
      s = a.scalars;
      clamped += a.traces_clamped;
    }
    double inside_max = 0, outside_min = 1;
    for (Index c = 0; c < g.num_cells(); ++c) {
      if (!gc.fluid(c)) continue;
      if ((g.cell_centre(c) - o).norm() < r_in)
        inside_max = std::max(inside_max, s(c, 0));
      else
        outside_min = std::min(outside_min, s(c, 0));
    }
    CHECK(inside_max == 0.0);  // exactly: nothing is read through the shell
    CHECK(outside_min == doctest::Approx(1.0).epsilon(1e-12));
    CHECK(clamped > 0);
  }
}

// ---- the grid fluid's step (fluid/grid/simulation.hpp) ------------------------------------

#include "fluid/grid/simulation.hpp"

namespace {

/// A jet along +x: Inflow patch on −x (smoke 1), Open +x.
mesh::FluidDomain jet_domain() {
  mesh::FluidDomain d;
  d.patches.push_back({"jet", FaceKind::Inflow, 0, Vec2(0.3, 0.3), Vec2(0.7, 0.7)});
  d.patches.push_back({"out", FaceKind::Open, 1, Vec2(0, 0), Vec2(1, 1)});
  return d;
}

FluidParams jet_params() {
  FluidParams p;
  p.solver_rel_tol = 1e-10;
  PatchConditions jet;
  jet.inflow_speed = 1.0;
  jet.smoke_density = 1.0;
  jet.area = 0.16;
  p.patches = {jet, PatchConditions{}};
  return p;
}

}  // namespace

TEST_CASE(
    "grid fluid: a jet past a sphere balances its mass every step; a sealed shell stays clean") {
  const GridSpec g = GridSpec::from_cells(Vec3::Zero(), Vec3(1.5, 1, 1), {24, 16, 16});
  const Vec3 o(0.8, 0.5, 0.5);
  const mesh::VolumeMesh shell = mesh::make_spherical_shell(o, 0.2, 0.2 + 0.4 * g.h[0], 3, 1);
  const mesh::SolidSurface s = surface_of(shell, 0);
  GridFluid fluid(jet_params(), g, jet_domain());
  fluid.initialize({s});
  PhaseTimes phases;
  for (int step = 0; step < 12; ++step) {
    const FluidStepReport r = fluid.step({s}, {}, 0.05, phases);
    REQUIRE(r.converged);
    CHECK(r.inflow_flux == doctest::Approx(0.16).epsilon(1e-12));
    CHECK(std::abs(r.inflow_flux - r.outflow_flux) < 1e-8 * r.inflow_flux);
    CHECK(r.divergence_after < 1e-8 * r.divergence_before);
  }
  double inside = 0, emitted = 0;
  for (Index c = 0; c < g.num_cells(); ++c) {
    if (!fluid.cells().fluid(c)) continue;
    if ((g.cell_centre(c) - o).norm() < 0.2)
      inside = std::max(inside, fluid.state().density[c]);
    else
      emitted += fluid.state().density[c] * g.cell_volume();
  }
  CHECK(inside == 0.0);  // exactly
  CHECK(emitted > 0.05);
  CHECK(fluid.time() == doctest::Approx(0.6));
}

TEST_CASE("grid fluid: a liquid at rest around a body stays at rest, hydrostatic") {
  const GridSpec g = GridSpec::from_cells(Vec3::Zero(), Vec3::Ones(), {16, 16, 16});
  mesh::FluidDomain d;
  d.patches.push_back({"top", FaceKind::Open, 5, Vec2(0, 0), Vec2(1, 1)});
  FluidParams p;
  p.density = 1000;
  p.gravity = Vec3(0, 0, -9.81);
  p.hydrostatic_origin = Vec3(0, 0, 1);
  p.solver_rel_tol = 1e-10;
  p.patches = {PatchConditions{}};
  GridFluid fluid(p, g, d);
  const mesh::SolidSurface s = sphere(Vec3(0.45, 0.5, 0.4), 0.2, 0);
  fluid.initialize({s});
  PhaseTimes phases;
  for (int step = 0; step < 5; ++step) {
    const FluidStepReport r = fluid.step({s}, {}, 0.02, phases);
    CHECK(r.max_speed <= 1e-12);
  }
  for (Index c = 0; c < g.num_cells(); ++c)
    if (fluid.cells().fluid(c))
      CHECK(fluid.state().p[c] ==
            doctest::Approx(1000 * 9.81 * (1.0 - g.cell_centre(c)[2])).epsilon(1e-12));
}

namespace {

/// u = sin x cos y, v = −cos x sin y on the faces: Taylor–Green in [0, π]², steady for Euler.
void set_taylor_green(GridFluid& fluid) {
  const GridSpec& g = fluid.cells().grid;
  GridState s = fluid.state();
  for (Index f = 0; f < g.num_faces(); ++f) {
    const Vec3 x = g.face_centre(f);
    const int a = g.face_axis(f);
    s.u[f] = a == 0   ? std::sin(x[0]) * std::cos(x[1])
             : a == 1 ? -std::cos(x[0]) * std::sin(x[1])
                      : 0.0;
  }
  fluid.set_state(s);
}

}  // namespace

TEST_CASE("grid fluid: Taylor-Green vortex loses less energy on a finer grid") {
  // u = sin x cos y, v = −cos x sin y in [0, π]² × [0, 1], walls: an exact steady Euler flow.
  double loss[2] = {0, 0};
  const Index sizes[2] = {16, 32};
  for (int r = 0; r < 2; ++r) {
    const Index n = sizes[r];
    const GridSpec g = GridSpec::from_cells(Vec3::Zero(), Vec3(M_PI, M_PI, 1.0), {n, n, 4});
    FluidParams p;
    p.solver_rel_tol = 1e-10;
    GridFluid fluid(p, g, mesh::FluidDomain{});
    fluid.initialize({});
    set_taylor_green(fluid);
    PhaseTimes phases;
    double e0 = 0, e1 = 0;
    const double h = 0.05;
    for (int step = 0; step < 20; ++step) {
      const FluidStepReport rep = fluid.step({}, {}, h, phases);
      if (step == 0) e0 = rep.kinetic_energy;
      e1 = rep.kinetic_energy;
    }
    loss[r] = (e0 - e1) / e0 / (19 * h);
    MESSAGE("Taylor-Green on ", n, "×", n, " cells: energy loss ", loss[r], " /s");
  }
  CHECK(loss[0] > 0);
  CHECK(loss[1] > 0);
  CHECK(loss[1] < 0.6 * loss[0]);
}

TEST_CASE("grid fluid: vorticity confinement puts energy back into a decaying vortex") {
  const GridSpec g = GridSpec::from_cells(Vec3::Zero(), Vec3(M_PI, M_PI, 1.0), {16, 16, 4});
  double kept[2] = {0, 0};
  const double eps[2] = {0.0, 0.3};
  for (int r = 0; r < 2; ++r) {
    FluidParams p;
    p.solver_rel_tol = 1e-10;
    p.vorticity_confinement = eps[r];
    GridFluid fluid(p, g, mesh::FluidDomain{});
    fluid.initialize({});
    set_taylor_green(fluid);
    PhaseTimes phases;
    double e0 = 0, e1 = 0;
    for (int step = 0; step < 20; ++step) {
      const FluidStepReport rep = fluid.step({}, {}, 0.05, phases);
      REQUIRE(std::isfinite(rep.kinetic_energy));
      if (step == 0) e0 = rep.kinetic_energy;
      e1 = rep.kinetic_energy;
    }
    kept[r] = e1 / e0;
    MESSAGE("vorticity confinement ε = ", eps[r], ": energy kept over 1 s ", kept[r]);
  }
  CHECK(kept[1] > kept[0]);
  CHECK(kept[1] < 1.5);  // it sharpens, it does not blow up
  FluidParams bad;
  bad.vorticity_confinement = -1;
  CHECK_THROWS_WITH_AS(GridFluid(bad, g, mesh::FluidDomain{}),
                       doctest::Contains("fluid.vorticity_confinement"), InputError);
}

TEST_CASE("MAC grid: probes (with a query box or not) and clear() agree with first_crossing") {
  // A thin sheet tilted on two axes and a sphere, on 20 × 10 × 10 cells of 0.05 m.
  const GridSpec g = GridSpec::from_cells(Vec3::Zero(), Vec3(1, 0.5, 0.5), {20, 10, 10});
  mesh::VolumeMesh sheet =
      mesh::make_box(Vec3(-0.006, -0.15, -0.15), Vec3(0.006, 0.15, 0.15), Vec3i(1, 6, 6));
  const Eigen::Matrix3d R =
      (Eigen::AngleAxisd(0.6, Vec3::UnitZ()) * Eigen::AngleAxisd(0.3, Vec3::UnitY()))
          .toRotationMatrix();
  for (Index v = 0; v < sheet.vertices.rows(); ++v)
    sheet.vertices.row(v) =
        (R * sheet.vertices.row(v).transpose() + Vec3(0.35, 0.25, 0.25)).transpose();
  const GridCells gc = classify_grid(
      g, mesh::FluidDomain{}, {surface_of(sheet, 0), sphere(Vec3(0.75, 0.25, 0.25), 0.1, 1)});
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> unit(0.0, 1.0), step(-2.0, 2.0);
  int queries = 0, hidden = 0, clear_segments = 0;
  for (int n = 0; n < 4000; ++n) {
    const Vec3 x(unit(rng), 0.5 * unit(rng), 0.5 * unit(rng));
    const GridSolids::Probe plain1(gc.solids, x, 1), plain2(gc.solids, x, 2);
    const GridSolids::Probe boxed1(gc.solids, x, 1, x - g.h, x + g.h);
    const GridSolids::Probe boxed2(gc.solids, x, 2, x - 1.5 * g.h, x + 1.5 * g.h);
    const bool clear = gc.solids.clear(g.cell_at(x), 2);
    for (int q = 0; q < 8; ++q) {
      const Vec3 b = (x + Vec3(step(rng), step(rng), step(rng)).cwiseProduct(g.h))
                         .cwiseMax(Vec3::Zero())
                         .cwiseMin(g.hi());
      const bool seen = !gc.solids.first_crossing(x, b);
      CAPTURE(n);
      CAPTURE(q);
      CHECK(plain1.visible(b) == seen);
      CHECK(plain2.visible(b) == seen);
      CHECK(boxed1.visible(b) == seen);
      CHECK(boxed2.visible(b) == seen);
      ++queries;
      hidden += seen ? 0 : 1;
      if (clear && ((b - x).cwiseAbs().array() <= g.h.array()).all()) {
        CHECK(seen);
        ++clear_segments;
      }
    }
  }
  // both answers and the clear case were exercised
  CHECK(hidden > 300);
  CHECK(queries - hidden > 300);
  CHECK(clear_segments > 1000);
}
