// A liquid with a free surface on the MAC grid (fluid/grid/liquid.hpp): a still pool, the
// dam break against Martin & Moyce (1952), the ghost-fluid pressure and the volume.
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <memory>
#include <random>
#include <vector>

#include "core/error.hpp"
#include "core/parallel.hpp"
#include "core/timer.hpp"
#include "fluid/grid/liquid.hpp"
#include "fluid/grid/simulation.hpp"
#include "mesh/generate.hpp"

using namespace tetfsi;
using namespace tetfsi::fluid;

namespace {

constexpr double kG = 9.81;

FluidParams water(const LiquidRegion& region) {
  FluidParams p;
  p.density = 1000;
  p.gravity = Vec3(0, 0, -kG);
  p.solver = SolverKind::Cholmod;
  p.liquid.enabled = true;
  p.liquid.regions = {region};
  return p;
}

/// The cells of grid g in a closed box of its own size, without bodies.
GridCells box_cells(const GridSpec& g) {
  mesh::FluidDomain d;
  d.lo = g.lo;
  d.hi = g.hi();
  return classify_grid(g, d, {});
}

LiquidRegion box_region(const Vec3& lo, const Vec3& hi) {
  LiquidRegion r;
  r.name = "liquid";
  r.lo = lo;
  r.hi = hi;
  return r;
}

/// The surge front along the floor (m): over the bottom layer of cells (mean over y), the
/// last liquid cell in x and the zero of φ linear to the next one.
double surge_front(const GridCells& gc) {
  const GridSpec& g = gc.grid;
  double front = g.lo[0];
  for (Index j = 0; j < g.n[1]; ++j) {
    double x = g.lo[0];
    for (Index i = 0; i + 1 < g.n[0]; ++i) {
      const double a = gc.phi[g.cell(i, j, 0)], b = gc.phi[g.cell(i + 1, j, 0)];
      if (a < 0 && b >= 0) x = g.cell_centre(g.cell(i, j, 0))[0] + g.h[0] * a / (a - b);
    }
    front += (x - g.lo[0]) / static_cast<double>(g.n[1]);
  }
  return front;
}

}  // namespace

TEST_CASE("liquid: a particle half-space's surface lies on its boundary") {
  // φ at the two cell centres beside a seeded boundary is ±the same value: the linear zero
  // (the ghost fluid's surface) is on the boundary
  const GridSpec g = GridSpec::from_cells(Vec3::Zero(), Vec3(1, 1, 1), {8, 8, 8});
  GridCells gc = box_cells(g);
  LiquidParams lp;
  lp.regions = {box_region(Vec3::Zero(), Vec3(1, 1, 0.5))};
  const LiquidParticles parts = seed_liquid(gc, lp);
  CHECK(parts.size() == 8 * 8 * 4 * 8);
  const VecX phi = liquid_level_set(gc, parts.x, liquid_surface_params(g, 2));
  const double below = phi[g.cell(4, 4, 3)], above = phi[g.cell(4, 4, 4)];
  CHECK(below < 0);
  CHECK(above > 0);
  CHECK(std::abs(below + above) < 1e-12);
  set_free_surface(gc, phi);
  const LiquidMeasures m = liquid_measures(gc);
  CHECK(m.volume == doctest::Approx(0.5).epsilon(1e-12));
  CHECK(m.area == doctest::Approx(1.0).epsilon(1e-12));
}

TEST_CASE("liquid: holding the volume shifts the surface by the missing volume over its area") {
  // the half-space z < 0.5 of the unit box on 8^3 cells: its level set holds 0.5 m^3 with a
  // 1 m^2 surface; to hold 0.48 m^3 the surface moves down 0.02 m (0.16 cell), within 1e-4 of
  // the target; a target it already holds moves nothing; a large one is capped at a quarter
  // of the particles' radius, where every deep cell stays liquid
  const GridSpec g = GridSpec::from_cells(Vec3::Zero(), Vec3(1, 1, 1), {8, 8, 8});
  LiquidParams lp;
  lp.regions = {box_region(Vec3::Zero(), Vec3(1, 1, 0.5))};
  GridCells gc = box_cells(g);
  const LiquidSurfaceParams sp = liquid_surface_params(g, 2);
  const VecX phi = liquid_level_set(gc, seed_liquid(gc, lp).x, sp);
  set_free_surface(gc, phi);
  CHECK(hold_liquid_volume(gc, 0.5, sp) == 0.0);
  CHECK(gc.phi == phi);
  const double d = hold_liquid_volume(gc, 0.48, sp) / liquid_measures(gc).area;
  const double v = liquid_measures(gc).volume;
  MESSAGE("moved " << d << " m, volume " << v << " m^3 for 0.48, phi shifted by "
                   << (gc.phi - phi).maxCoeff() << " (r = " << sp.radius << ")");
  CHECK(std::abs(v - 0.48) <= 1e-4 * 0.48);
  CHECK(d == doctest::Approx(0.02).epsilon(1e-3));
  for (Index c = 0; c < g.num_cells(); ++c) CHECK(gc.air[c] == (gc.phi[c] >= 0 ? 1 : 0));
  set_free_surface(gc, phi);
  hold_liquid_volume(gc, 0.2, sp);
  CHECK((gc.phi - phi).maxCoeff() == doctest::Approx(k_max_volume_shift * sp.radius));
  for (Index c = 0; c < g.num_cells(); ++c)
    if (g.cell_centre(c).z() < 0.5 - g.h[2]) CHECK(gc.air[c] == 0);
}

TEST_CASE("liquid: a region seeds the lattice points inside its box, sphere and surface") {
  // 10^3 cells of 0.1 m, 8 lattice points per cell at 1/4 and 3/4 of it along each axis.
  const GridSpec g = GridSpec::from_cells(Vec3::Zero(), Vec3(1, 1, 1), {10, 10, 10});
  const GridCells gc = box_cells(g);
  // A closed surface: the box [0.2, 0.6]^3's boundary (4^3 cells, 512 points inside).
  const mesh::VolumeMesh cube = mesh::make_box(Vec3::Constant(0.2), Vec3::Constant(0.6), {1, 1, 1});
  auto surface = std::make_shared<mesh::SurfaceMesh>();
  surface->vertices = cube.vertices;
  surface->triangles = mesh::boundary_triangles(cube);
  LiquidRegion r;
  r.name = "cube";
  r.surface_file = "cube";
  r.surface = surface;
  LiquidParams lp;
  lp.regions = {r};
  CHECK(seed_liquid(gc, lp).size() == 512);
  // With a box below z = 0.4 as well: the overlap, half of it.
  lp.regions[0].lo = Vec3::Zero();
  lp.regions[0].hi = Vec3(1, 1, 0.4);
  CHECK(seed_liquid(gc, lp).size() == 256);
  // A sphere (centre 0.5, radius 0.3) cut by the box z <= 0.5: the lattice points of the lower
  // half ball, every one within the radius and below 0.5, and their count about the half
  // ball's volume × 8000 points per m^3 (within 5 %).
  LiquidRegion half;
  half.centre = Vec3::Constant(0.5);
  half.radius = 0.3;
  half.lo = Vec3::Zero();
  half.hi = Vec3(1, 1, 0.5);
  lp.regions = {half};
  const LiquidParticles parts = seed_liquid(gc, lp);
  Index outside = 0;
  for (Index i = 0; i < parts.size(); ++i) {
    const Vec3 x = parts.x.row(i).transpose();
    outside += (x - half.centre).norm() > 0.3 || x.z() > 0.5;
  }
  CHECK(outside == 0);
  const double expected = 2.0 / 3.0 * M_PI * 0.027 * 8000.0;
  CHECK(std::abs(parts.size() / expected - 1.0) < 0.05);
}

TEST_CASE("liquid: the density correction leaves a lattice alone and draws a thinned block in") {
  // 12^3 cells of 0.1 m with a box of liquid [0, 1.2] x [0, 1.2] x [0, 0.8]: 8 cells deep.
  const GridSpec g = GridSpec::from_cells(Vec3::Zero(), Vec3(1.2, 1.2, 1.2), {12, 12, 12});
  GridCells gc = box_cells(g);
  LiquidParams lp;
  lp.regions = {box_region(Vec3::Zero(), Vec3(1.2, 1.2, 0.8))};
  LiquidParticles parts = seed_liquid(gc, lp);
  set_free_surface(gc, liquid_level_set(gc, parts.x, liquid_surface_params(g, 2)));
  const double dt = 0.01, rate = 0.2, V = g.cell_volume();
  // The seeded lattice: 8 per cell everywhere, no correction at all.
  CHECK(liquid_volume_source(gc, parts.x, 2, rate, dt).cwiseAbs().maxCoeff() == 0.0);
  // Remove half the particles of the cells with k = 2..4: a deep cell of k = 3 has a block of
  // 4 per cell (error −0.5), one of k = 5 a block of two thinned layers and one full (−1/3).
  std::vector<Vec3> kept;
  for (Index i = 0; i < parts.size(); ++i) {
    const Vec3 x = parts.x.row(i).transpose();
    const Index k = static_cast<Index>(x.z() / 0.1);
    if (k >= 2 && k <= 4 && static_cast<Index>(x.x() / 0.05) % 2 == 1) continue;
    kept.push_back(x);
  }
  MatX3 x(static_cast<Index>(kept.size()), 3);
  for (std::size_t i = 0; i < kept.size(); ++i) x.row(static_cast<Index>(i)) = kept[i].transpose();
  const VecX s = liquid_volume_source(gc, x, 2, rate, dt);
  const auto expect = [&](double error) {
    return rate * std::copysign(std::max(0.0, std::abs(error) - k_density_tolerance), error) * V /
           dt;
  };
  CHECK(s[g.cell(5, 5, 3)] == doctest::Approx(expect(-0.5)).epsilon(1e-12));
  CHECK(s[g.cell(5, 5, 5)] == doctest::Approx(expect(-1.0 / 6.0)).epsilon(1e-12));
  CHECK(s[g.cell(5, 5, 6)] == 0.0);  // its block (k = 5..7) is full
  CHECK(s[g.cell(5, 5, 7)] == 0.0);  // beside the air (k = 8): not deep
  CHECK(s[g.cell(5, 5, 1)] == doctest::Approx(expect(-1.0 / 6.0)).epsilon(1e-12));
  CHECK(s.maxCoeff() <= 0.0);  // nothing is crowded
}

TEST_CASE("liquid: a still pool in a closed tank stays still and flat") {
  // 100 steps of a pool 0.3 m deep in a closed 0.4 m tank: max speed <= 1e-6 sqrt(g h) and the
  // surface (the zero of φ in every column) flat to 1e-3 of a cell
  const double depth = 0.3;
  const GridSpec g = GridSpec::from_cells(Vec3::Zero(), Vec3(0.4, 0.4, 0.4), {16, 16, 16});
  mesh::FluidDomain d;
  d.lo = g.lo;
  d.hi = g.hi();
  FluidParams p = water(box_region(Vec3::Zero(), Vec3(0.4, 0.4, depth)));
  p.solver_rel_tol = 1e-12;
  GridFluid fluid(p, g, d);
  fluid.initialize({});
  PhaseTimes phases;
  double speed = 0;
  for (int step = 0; step < 100; ++step)
    speed = std::max(speed, fluid.step({}, {}, 0.01, phases).max_speed);
  const GridCells& gc = fluid.cells();
  double lo = 1e9, hi = -1e9;
  for (Index j = 0; j < g.n[1]; ++j)
    for (Index i = 0; i < g.n[0]; ++i)
      for (Index k = 0; k + 1 < g.n[2]; ++k) {
        const double a = gc.phi[g.cell(i, j, k)], b = gc.phi[g.cell(i, j, k + 1)];
        if (a < 0 && b >= 0) {
          const double z = g.cell_centre(g.cell(i, j, k))[2] + g.h[2] * a / (a - b);
          lo = std::min(lo, z);
          hi = std::max(hi, z);
        }
      }
  MESSAGE("still pool: max speed " << speed << " m/s (limit " << 1e-6 * std::sqrt(kG * depth)
                                   << "), surface " << lo << " .. " << hi << " m");
  CHECK(speed <= 1e-6 * std::sqrt(kG * depth));
  CHECK(hi - lo <= 1e-3 * g.h[2]);
  CHECK(lo == doctest::Approx(depth).epsilon(1e-9));
  // the pressure is hydrostatic: rho g (surface - z) at the bottom cells' centres, to 1e-6
  const double p_bottom = 1000 * kG * (depth - 0.5 * g.h[2]);
  CHECK(fluid.state().p[g.cell(5, 7, 0)] == doctest::Approx(p_bottom).epsilon(1e-6));
  CHECK(fluid.state().p[g.cell(5, 7, 15)] == 0.0);  // an air cell
}

namespace {

/// Martin & Moyce (1952), Phil. Trans. R. Soc. A 244, 312-324, Fig. 3: a column of width a
/// and height 2a (n^2 = 2, a = 2.25 in) collapsing onto a dry floor; the surge front Z = x/a
/// against T = t sqrt(2 g / a). Points as tabulated from the figure in PySPH's
/// pysph/examples/db_exp_data.py (mm_data_2).
const std::vector<std::pair<double, double>> k_martin_moyce = {
    {1.219, 1.474}, {1.997, 2.292}, {2.547, 2.995}, {3.345, 4.134}, {4.034, 4.944},
    {4.418, 5.881}, {5.091, 6.980}, {5.685, 7.945}, {6.306, 8.966}, {6.822, 9.986}};

struct DamBreak {
  std::vector<double> Z;  ///< the front at each tabulated T
  double drift = 0;       ///< the worst |liquid_volume_drift|
  double shift = 0;       ///< the worst |liquid_shift| (m)
};

/// The dam break in a tank 12 a long (4 cells deep, free-slip walls) at a / h = per_a, until
/// the last tabulated time, the volume held (fluid.liquid.hold_volume) or not.
DamBreak dam_break(int per_a, bool hold) {
  const double a = 0.05715, h = a / per_a;
  const GridSpec g = GridSpec::from_cells(Vec3::Zero(), Vec3(12 * a, 4 * h, 2.5 * a),
                                          {12 * per_a, 4, static_cast<Index>(2.5 * per_a)});
  mesh::FluidDomain d;
  d.lo = g.lo;
  d.hi = g.hi();
  FluidParams p = water(box_region(Vec3::Zero(), Vec3(a, 4 * h, 2 * a)));
  p.liquid.hold_volume = hold;
  GridFluid fluid(p, g, d);
  fluid.initialize({});
  const double dt = 0.25 * h / std::sqrt(2 * kG * a), t_scale = std::sqrt(2 * kG / a);
  PhaseTimes phases;
  DamBreak out;
  std::vector<double>& Z = out.Z;
  while (Z.size() < k_martin_moyce.size()) {
    const FluidStepReport r = fluid.step({}, {}, dt, phases);
    out.drift = std::max(out.drift, std::abs(r.liquid_volume_drift));
    out.shift = std::max(out.shift, std::abs(r.liquid_shift));
    const auto [T_ref, Z_ref] = k_martin_moyce[Z.size()];
    if (fluid.time() * t_scale < T_ref) continue;
    Z.push_back(surge_front(fluid.cells()) / a);
    MESSAGE("a/h = " << per_a << (hold ? "" : ", volume not held")
                     << "  T = " << fluid.time() * t_scale << "  Z = " << Z.back()
                     << "  Martin & Moyce " << Z_ref << "  (" << 100 * (Z.back() / Z_ref - 1)
                     << " %)  volume drift so far " << 100 * out.drift << " %, shift "
                     << out.shift / h << " cell");
  }
  return out;
}

/// The front within 10 % of the experiment at T = 4.42, 5.09, 5.69 (earlier, the inviscid front
/// leads the experiment by 13-19 %: the measured front is slowed by the gate's opening and the
/// floor's friction, which the model does not have), and the volume within `max_drift`.
/// With the volume held, the surface moves at most `max_shift` cells from where the
/// particles put it.
void check_dam_break(int per_a, bool hold, double max_drift, double max_shift) {
  const DamBreak r = dam_break(per_a, hold);
  for (size_t k : {5, 6, 9}) {
    CAPTURE(k_martin_moyce[k].first);
    CHECK(r.Z[k] == doctest::Approx(k_martin_moyce[k].second).epsilon(0.10));
  }
  CHECK(r.Z[1] > k_martin_moyce[1].second);  // the early lead, as stated above
  CHECK(r.drift < max_drift);
  CHECK(r.shift <= max_shift * 0.05715 / per_a);
}

}  // namespace

TEST_CASE("liquid dam break: the surge front against Martin and Moyce (1952) at 16 cells per a") {
  check_dam_break(16, true, 0.002, 0.1);  // measured: drift 0.014 %, shift 0.034 cell
}

TEST_CASE("liquid dam break: the surge front against Martin and Moyce (1952) at 24 cells per a" *
          doctest::test_suite("long")) {
  check_dam_break(24, true, 0.002, 0.1);  // measured: drift 0.010 %, shift 0.030 cell
}

TEST_CASE("liquid dam break: without the volume held - the level set's own drift" *
          doctest::test_suite("long")) {
  check_dam_break(16, false, 0.015, 0.0);  // measured 0.78 %
}

TEST_CASE("liquid: particles to faces is the serial scatter in particle order, bit for bit") {
  // 7 × 5 × 19 cells (three z-slabs of the parallel scatter and a partial one), particles
  // anywhere in the box, on its walls and on slab boundaries.
  const GridSpec g = GridSpec::from_cells(Vec3(-0.1, 0, 0.2), Vec3(0.6, 0.5, 2.1), {7, 5, 19});
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> unit(0.0, 1.0), vel(-2.0, 2.0);
  LiquidParticles lp;
  const Index np = 3000;
  lp.x.resize(np, 3);
  lp.v.resize(np, 3);
  for (Index p = 0; p < np; ++p) {
    for (int a = 0; a < 3; ++a) {
      lp.x(p, a) = g.lo[a] + unit(rng) * (g.hi()[a] - g.lo[a]);
      lp.v(p, a) = vel(rng);
    }
    if (p % 50 == 0) lp.x(p, 2) = g.lo[2] + 8.0 * g.h[2];  // on a slab boundary
    if (p % 70 == 0) lp.x(p, 0) = g.hi()[0];               // on the +x wall
  }
  // The reference: every particle in order, each axis' 8 lattice corners (trilinear weights,
  // the point clamped to the lattice), summed into numerator and denominator.
  const Index nf = g.num_faces();
  VecX num = VecX::Zero(nf), den = VecX::Zero(nf);
  for (Index p = 0; p < np; ++p)
    for (int a = 0; a < 3; ++a) {
      std::array<Index, 3> base{}, top{};
      Vec3 frac;
      for (int b = 0; b < 3; ++b) {
        top[b] = g.n[b] + (b == a ? 1 : 0) - 1;
        const double s = (lp.x(p, b) - g.lo[b]) / g.h[b] - (b == a ? 0.0 : 0.5);
        const double sc = std::clamp(s, 0.0, static_cast<double>(top[b]));
        base[b] =
            std::min<Index>(static_cast<Index>(std::floor(sc)), std::max<Index>(top[b] - 1, 0));
        frac[b] = top[b] > 0 ? sc - static_cast<double>(base[b]) : 0.0;
      }
      for (int corner = 0; corner < 8; ++corner) {
        std::array<Index, 3> ijk{};
        double w = 1;
        for (int b = 0; b < 3; ++b) {
          const int up = (corner >> b) & 1;
          ijk[b] = std::min(base[b] + up, top[b]);
          w *= up ? frac[b] : 1.0 - frac[b];
        }
        if (w <= 0) continue;
        const Index f = g.face(a, ijk[0], ijk[1], ijk[2]);
        num[f] += w * lp.v(p, a);
        den[f] += w;
      }
    }
  const int saved = thread_count();
  for (const int threads : {1, 2, 3}) {
    CAPTURE(threads);
    set_thread_count(threads);
    std::vector<std::uint8_t> known;
    const VecX u = particles_to_faces(g, lp, known);
    Index mismatches = 0, known_faces = 0;
    for (Index f = 0; f < nf; ++f) {
      const bool k = den[f] > 1e-12;
      known_faces += k;
      if (known[f] != k || u[f] != (k ? num[f] / den[f] : 0.0)) ++mismatches;
    }
    CHECK(mismatches == 0);
    CHECK(known_faces > nf / 2);
  }
  set_thread_count(saved);
}
