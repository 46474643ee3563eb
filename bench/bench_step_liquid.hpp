#pragma once
/// @file bench_step_liquid.hpp
/// `tetfsi bench step` on a liquid scene (fluid.liquid on the grid): the liquid's phases per
/// step and, on the last step's particles, its level set [ZhuBridson05] against OpenVDB's
/// particles → level set (fluid/grid/liquid_openvdb.hpp) on the same particles.
#include <iosfwd>

#include <nlohmann/json_fwd.hpp>

#include "fluid/grid/simulation.hpp"

namespace tetfsi::app {

/// Mean seconds per timed step of the liquid's phases (FluidStepReport's liquid_*_s).
struct LiquidPhases {
  double advect = 0, surface = 0, p2g = 0;
};

/// One particles → level set on the last step's particles: its seconds and what it reads.
struct LevelSetReading {
  double seconds = 0;  ///< the level set (OpenVDB: rasterization + sampling at the cells)
  double volume = 0;   ///< m³ where φ < 0 (fluid::liquid_measures)
  double area = 0;     ///< m² of its surface
};

struct LiquidComparison {
  Index particles = 0;
  double particle_volume = 0;  ///< m³: what the particles carry (the seeding's share each)
  LevelSetReading ours, openvdb;
  double openvdb_radius = 0, openvdb_voxel = 0;
  Index openvdb_voxels = 0, openvdb_skipped = 0;
};

/// The comparison on the grid fluid's present particles and cells: its own level set
/// (fluid::liquid_level_set, without the volume hold) and OpenVDB's union of spheres of
/// radius the particles' spacing on voxels of a quarter cell, a band of 1.5 cells each side.
LiquidComparison compare_liquid_level_sets(const fluid::GridFluid& fluid, int per_axis);

/// Print the liquid table's header, one case's row, and its JSON.
void print_liquid_header(std::ostream& out);
void print_liquid_row(std::ostream& out, double scale, Index grid_cells, const LiquidPhases& ph,
                      double solve_s, const LiquidComparison& c);
nlohmann::json liquid_json(const LiquidPhases& ph, double solve_s, const LiquidComparison& c);

}  // namespace tetfsi::app
