#include "fluid/grid/liquid_openvdb.hpp"

#include <cmath>

#include <openvdb/openvdb.h>
#include <openvdb/tools/Interpolation.h>
#include <openvdb/tools/ParticlesToLevelSet.h>

#include "core/error.hpp"
#include "core/parallel.hpp"
#include "core/timer.hpp"

namespace tetfsi::fluid {

namespace {

/// The particle list ParticlesToLevelSet reads: positions, one radius, no velocity.
class ParticleList {
 public:
  using PosType = openvdb::Vec3R;
  ParticleList(const MatX3& x, double radius) : m_x(x), m_radius(radius) {}
  size_t size() const { return static_cast<size_t>(m_x.rows()); }
  void getPos(size_t n, openvdb::Vec3R& p) const {
    const Index i = static_cast<Index>(n);
    p = openvdb::Vec3R(m_x(i, 0), m_x(i, 1), m_x(i, 2));
  }
  void getPosRad(size_t n, openvdb::Vec3R& p, openvdb::Real& r) const {
    getPos(n, p);
    r = m_radius;
  }
  void getPosRadVel(size_t n, openvdb::Vec3R& p, openvdb::Real& r, openvdb::Vec3R& v) const {
    getPosRad(n, p, r);
    v = openvdb::Vec3R(0.0);
  }

 private:
  const MatX3& m_x;
  double m_radius;
};

}  // namespace

OpenVdbLevelSet openvdb_particle_level_set(const GridSpec& g, const MatX3& x, double radius,
                                           double voxel, int half_width) {
  TETFSI_REQUIRE(
      InputError,
      std::isfinite(radius) && radius > 0 && std::isfinite(voxel) && voxel > 0 && half_width > 0,
      "openvdb_particle_level_set: radius {}, voxel {} and half width {} must be "
      "positive and finite",
      radius, voxel, half_width);
  openvdb::initialize();
  OpenVdbLevelSet out;
  double t0 = now_seconds();
  // voxel (0, 0, 0) on the first cell centre: the voxel centres lie on the cell centres
  // when h / voxel is a whole number
  openvdb::math::Transform::Ptr xform = openvdb::math::Transform::createLinearTransform(voxel);
  const Vec3 c0 = g.cell_centre(0);
  xform->postTranslate(openvdb::Vec3d(c0[0], c0[1], c0[2]));
  openvdb::FloatGrid::Ptr grid =
      openvdb::createLevelSet<openvdb::FloatGrid>(voxel, static_cast<float>(half_width));
  grid->setTransform(xform);
  openvdb::tools::ParticlesToLevelSet<openvdb::FloatGrid> raster(*grid);
  const ParticleList particles(x, radius);
  raster.rasterizeSpheres(particles);
  raster.finalize(/*prune=*/true);
  out.rasterize_s = now_seconds() - t0;
  out.skipped = static_cast<Index>(raster.getMinCount());
  out.active_voxels = static_cast<Index>(grid->activeVoxelCount());
  t0 = now_seconds();
  out.phi.resize(g.num_cells());
  parallel_for_chunks(g.num_cells(), 4096, [&](Index begin, Index end) {
    // one sampler (and its value accessor's cache) per chunk
    const openvdb::tools::GridSampler<openvdb::FloatGrid, openvdb::tools::BoxSampler> sampler(
        *grid);
    for (Index c = begin; c < end; ++c) {
      const Vec3 xc = g.cell_centre(c);
      out.phi[c] = sampler.wsSample(openvdb::Vec3R(xc[0], xc[1], xc[2]));
    }
  });
  out.sample_s = now_seconds() - t0;
  return out;
}

}  // namespace tetfsi::fluid
