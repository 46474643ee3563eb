/// @file bench_step_liquid.cpp
/// `tetfsi bench step` on a liquid scene (bench_step_liquid.hpp).
#include "bench/bench_step_liquid.hpp"

#include <ostream>

#include <fmt/format.h>
#include <fmt/ostream.h>
#include <nlohmann/json.hpp>

#include "core/timer.hpp"
#include "fluid/grid/liquid.hpp"
#include "fluid/grid/liquid_openvdb.hpp"

namespace tetfsi::app {

namespace {

/// liquid_measures of `phi` on a copy of the cells.
LevelSetReading read_level_set(const fluid::GridCells& cells, VecX phi, double seconds) {
  fluid::GridCells gc = cells;
  fluid::set_free_surface(gc, std::move(phi));
  const fluid::LiquidMeasures m = fluid::liquid_measures(gc);
  return {seconds, m.volume, m.area};
}

}  // namespace

LiquidComparison compare_liquid_level_sets(const fluid::GridFluid& fluid, int per_axis) {
  const fluid::GridCells& cells = fluid.cells();
  const fluid::GridSpec& g = cells.grid;
  const MatX3& x = fluid.state().particles.x;
  LiquidComparison c;
  c.particles = x.rows();
  c.particle_volume =
      static_cast<double>(x.rows()) * g.cell_volume() / (per_axis * per_axis * per_axis);
  const double t0 = now_seconds();
  VecX phi = fluid::liquid_level_set(cells, x, fluid::liquid_surface_params(g, per_axis));
  c.ours = read_level_set(cells, std::move(phi), now_seconds() - t0);
  // OpenVDB skips spheres under 1.5 voxels: the particles' spacing as the radius (the
  // spheres then overlap into one closed surface) on voxels of a quarter cell
  const double h = g.h.minCoeff();
  c.openvdb_radius = h / per_axis;
  c.openvdb_voxel = h / 4;
  fluid::OpenVdbLevelSet vdb =
      fluid::openvdb_particle_level_set(g, x, c.openvdb_radius, c.openvdb_voxel, 6);
  c.openvdb_voxels = vdb.active_voxels;
  c.openvdb_skipped = vdb.skipped;
  c.openvdb = read_level_set(cells, std::move(vdb.phi), vdb.rasterize_s + vdb.sample_s);
  return c;
}

void print_liquid_header(std::ostream& out) {
  fmt::print(out,
             "\nliquid (s per step; the level sets on the last step's particles, volumes / the "
             "particles' volume):\n{:>6} {:>8} {:>8} | {:>6} {:>7} {:>6} {:>6} {:>6} | {:>7} "
             "{:>7} {:>6} | {:>6} {:>6} {:>6} {:>6}\n",
             "scale", "grid", "parts", "advect", "surface", "p2g", "solve", "su/so", "ours_s",
             "vdb_s", "vdb/us", "vol_us", "vol_vd", "area_u", "area_v");
}

void print_liquid_row(std::ostream& out, double scale, Index grid_cells, const LiquidPhases& ph,
                      double solve_s, const LiquidComparison& c) {
  fmt::print(out,
             "{:>6.3f} {:>8} {:>8} | {:>6.3f} {:>7.4f} {:>6.3f} {:>6.4f} {:>6.2f} | {:>7.4f} "
             "{:>7.3f} {:>6.1f} | {:>6.3f} {:>6.3f} {:>6.3f} {:>6.3f}\n",
             scale, grid_cells, c.particles, ph.advect + ph.p2g, ph.surface, ph.p2g, solve_s,
             ph.surface / solve_s, c.ours.seconds, c.openvdb.seconds,
             c.openvdb.seconds / c.ours.seconds, c.ours.volume / c.particle_volume,
             c.openvdb.volume / c.particle_volume, c.ours.area, c.openvdb.area);
}

nlohmann::json liquid_json(const LiquidPhases& ph, double solve_s, const LiquidComparison& c) {
  const auto reading = [&](const LevelSetReading& r) {
    return nlohmann::json{{"seconds", r.seconds},
                          {"volume", r.volume},
                          {"volume_ratio", r.volume / c.particle_volume},
                          {"area", r.area}};
  };
  return {{"advect_s", ph.advect},
          {"surface_s", ph.surface},
          {"p2g_s", ph.p2g},
          {"solve_s", solve_s},
          {"surface_over_solve", ph.surface / solve_s},
          {"particles", c.particles},
          {"particle_volume", c.particle_volume},
          {"level_set", reading(c.ours)},
          {"openvdb",
           {{"reading", reading(c.openvdb)},
            {"radius", c.openvdb_radius},
            {"voxel", c.openvdb_voxel},
            {"active_voxels", c.openvdb_voxels},
            {"skipped", c.openvdb_skipped}}}};
}

}  // namespace tetfsi::app
