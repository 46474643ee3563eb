// The liquid's level set from its particles (fluid/grid/liquid.hpp) against a plain
// evaluation of its definition, and OpenVDB's particles → level set (fluid/grid/liquid_openvdb.hpp)
// against the exact union of spheres.
#include <doctest/doctest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <random>
#include <vector>

#include "core/error.hpp"
#include "fluid/grid/liquid.hpp"
#include "fluid/grid/liquid_openvdb.hpp"

using namespace tetfsi;
using namespace tetfsi::fluid;

namespace {

GridCells box_cells(const GridSpec& g) {
  mesh::FluidDomain d;
  d.lo = g.lo;
  d.hi = g.hi();
  return classify_grid(g, d, {});
}

/// φ at every cell by the definition [ZhuBridson05], the plain way: for each cell, every
/// particle of the cells within two cell sizes (bucket order) and, per axis with a wall
/// within R, its mirror images in the walls, each term (1 − s²)³ added whatever its size.
VecX plain_level_set(const GridCells& gc, const MatX3& x, const LiquidSurfaceParams& sp) {
  const GridSpec& g = gc.grid;
  const double R = 2.0 * g.h.maxCoeff();
  const Vec3 lo = g.lo, hi = g.hi();
  const ParticleBuckets b = bucket_particles(g, x);
  std::array<Index, 3> reach{};
  for (int a = 0; a < 3; ++a) reach[a] = static_cast<Index>(std::ceil(R / g.h[a]));
  VecX phi(g.num_cells());
  for (Index c = 0; c < g.num_cells(); ++c) {
    const auto ijk = g.cell_ijk(c);
    const Vec3 xc = g.cell_centre(c);
    bool deep = true;  // every cell of the block holds a particle: φ = −r
    std::array<int, 3> images{};
    for (int a = 0; a < 3; ++a) images[a] = 1 + (xc[a] - lo[a] < R) + (hi[a] - xc[a] < R);
    Vec3 mean = Vec3::Zero();
    double wsum = 0;
    for (Index k = std::max<Index>(0, ijk[2] - reach[2]);
         k <= std::min(g.n[2] - 1, ijk[2] + reach[2]); ++k)
      for (Index j = std::max<Index>(0, ijk[1] - reach[1]);
           j <= std::min(g.n[1] - 1, ijk[1] + reach[1]); ++j)
        for (Index i = std::max<Index>(0, ijk[0] - reach[0]);
             i <= std::min(g.n[0] - 1, ijk[0] + reach[0]); ++i) {
          const Index d = g.cell(i, j, k);
          deep = deep && b.start[d + 1] > b.start[d];
          for (Index e = b.start[d]; e < b.start[d + 1]; ++e) {
            const Vec3 p0 = x.row(b.order[e]).transpose();
            for (int m = 0; m < images[0] * images[1] * images[2]; ++m) {
              Vec3 p = p0;
              int rest = m;
              for (int a = 0; a < 3; ++a) {
                const int im = rest % images[a];
                rest /= images[a];
                if (im == 0) continue;
                p[a] = xc[a] - lo[a] < R && im == 1 ? 2 * lo[a] - p0[a] : 2 * hi[a] - p0[a];
              }
              const double t = 1.0 - (xc - p).squaredNorm() / (R * R);
              const double w = t > 0 ? t * t * t : 0.0;
              mean += w * p;
              wsum += w;
            }
          }
        }
    if (deep) {
      phi[c] = -sp.radius;
      continue;
    }
    phi[c] = wsum > 0 ? std::min((xc - mean / wsum).norm() - sp.radius, R) : R;
  }
  return phi;
}

/// A jittered lattice block against the low walls, a sparse cloud and a few lone particles.
MatX3 test_particles(const GridSpec& g) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> jitter(-0.2, 0.2), uni(0.0, 1.0);
  std::vector<Vec3> pts;
  const double s = g.h[0] / 2;
  for (int i = 0; i < 10; ++i)
    for (int j = 0; j < 16; ++j)
      for (int k = 0; k < 8; ++k)
        pts.emplace_back(g.lo[0] + (i + 0.5 + jitter(rng)) * s,
                         g.lo[1] + (j + 0.5 + jitter(rng)) * s,
                         g.lo[2] + (k + 0.5 + jitter(rng)) * s);
  for (int n = 0; n < 300; ++n) {  // a splash: sparse, some against the high walls
    const Vec3 u(0.4 + 0.6 * uni(rng), uni(rng), 0.3 + 0.7 * uni(rng));
    pts.push_back(g.lo + u.cwiseProduct(g.hi() - g.lo));
  }
  MatX3 x(static_cast<Index>(pts.size()), 3);
  for (Index p = 0; p < x.rows(); ++p) x.row(p) = pts[static_cast<size_t>(p)].transpose();
  return x;
}

}  // namespace

TEST_CASE("liquid_level_set: the plain evaluation of its definition, bit for bit") {
  // the level set skips cells and terms that add nothing, reads a row of cells as one range
  // of the buckets, gathers the points within R before summing them and finds the walls'
  // images of the inner cells from a mask of offsets; none of that may change a bit of φ.
  // Cubic cells, and cells of three sizes (the kernel reaches 3, 3 and 2 cells along x, y, z)
  for (const std::array<Index, 3> n : {std::array<Index, 3>{9, 8, 6}, {9, 7, 5}}) {
    CAPTURE(n[1]);
    const GridSpec g = GridSpec::from_cells(Vec3(0, 0, 0), Vec3(0.9, 0.8, 0.6), n);
    const GridCells gc = box_cells(g);
    const MatX3 x = test_particles(g);
    const LiquidSurfaceParams sp = liquid_surface_params(g, 2);
    const VecX fast = liquid_level_set(gc, x, sp), plain = plain_level_set(gc, x, sp);
    Index liquid = 0, differ = 0;
    for (Index c = 0; c < g.num_cells(); ++c) {
      liquid += fast[c] < 0 ? 1 : 0;
      differ += fast[c] == plain[c] ? 0 : 1;
    }
    CHECK(liquid > 20);                  // the block reads as liquid
    CHECK(liquid < g.num_cells() - 60);  // and most of the box as air
    CHECK(differ == 0);
  }
}

TEST_CASE("openvdb_particle_level_set: the union of spheres, to float precision in its band") {
  const GridSpec g = GridSpec::from_cells(Vec3(0, 0, 0), Vec3(0.9, 0.8, 0.6), {9, 8, 6});
  const MatX3 x = test_particles(g);
  const double h = 0.1, radius = h / 2, voxel = h / 4;
  const int half_width = 6;
  const OpenVdbLevelSet vdb = openvdb_particle_level_set(g, x, radius, voxel, half_width);
  CHECK(vdb.skipped == 0);
  CHECK(vdb.active_voxels > 0);
  REQUIRE(vdb.phi.size() == g.num_cells());
  Index in_band = 0;
  for (Index c = 0; c < g.num_cells(); ++c) {
    const Vec3 xc = g.cell_centre(c);
    double exact = 1e300;  // min over the spheres of |x − p| − r
    for (Index p = 0; p < x.rows(); ++p)
      exact = std::min(exact, (xc - x.row(p).transpose()).norm() - radius);
    const double band = half_width * voxel;
    if (std::abs(exact) < 0.9 * band) {  // the cell centres are voxel centres (h / voxel = 4)
      ++in_band;
      CHECK(std::abs(vdb.phi[c] - exact) <= 1e-5 * band);
    } else if (std::abs(exact) > 1.1 * band) {
      CHECK((vdb.phi[c] < 0) == (exact < 0));
    }
  }
  CHECK(in_band > 50);
  CHECK_THROWS_AS(openvdb_particle_level_set(g, x, 0.0, voxel, half_width), InputError);
  CHECK_THROWS_AS(openvdb_particle_level_set(g, x, radius, std::nan(""), half_width), InputError);
}
