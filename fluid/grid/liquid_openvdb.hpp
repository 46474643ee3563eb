#pragma once
/// @file grid/liquid_openvdb.hpp
/// OpenVDB's particles → level set (openvdb::tools::ParticlesToLevelSet [Museth13]), beside
/// the liquid's own [ZhuBridson05] level set (grid/liquid.hpp), for `tetfsi bench step` to
/// compare the two on the same particles. OpenVDB stays inside the .cpp.
#include "core/types.hpp"
#include "fluid/grid/grid.hpp"

namespace tetfsi::fluid {

struct OpenVdbLevelSet {
  VecX phi;                  ///< #C at the cell centres (m; < 0 inside), trilinear in the voxels
  double rasterize_s = 0.0;  ///< seconds of the rasterization (and its finalize)
  double sample_s = 0.0;     ///< seconds of the sampling at the cell centres
  Index active_voxels = 0;   ///< the narrow band's voxels
  Index skipped = 0;         ///< particles OpenVDB left out (radius under 1.5 voxels)
};

/// The union of the spheres of radius `radius` (m) about the particles x, rasterized by
/// openvdb::tools::ParticlesToLevelSet into a float level set of voxel size `voxel` (m; the
/// rasterizer skips spheres under 1.5 voxels) with a narrow band of `half_width` voxels each
/// side, then sampled trilinearly at g's cell centres (±half_width · voxel beyond the band).
/// Voxel centres lie on the cell centres when h / voxel is a whole number.
/// @throws InputError for a radius, voxel or half width that is not positive and finite
OpenVdbLevelSet openvdb_particle_level_set(const GridSpec& g, const MatX3& x, double radius,
                                           double voxel, int half_width);

}  // namespace tetfsi::fluid
