/// @file vdb.cpp
/// The OpenVDB side of export.hpp: a VoxelFrame's grids written as one `.vdb`, and any `.vdb`
/// summarised as read back (grids, active voxels, value ranges, bounds, metadata). The only
/// file of io/ that includes OpenVDB.
#include "io/export.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <exception>
#include <limits>
#include <system_error>
#include <type_traits>

#include <fmt/format.h>
#include <openvdb/io/File.h>
#include <openvdb/openvdb.h>
#include <openvdb/tools/SignedFloodFill.h>

#include "core/error.hpp"
#include "io/output.hpp"

namespace fs = std::filesystem;

namespace tetfsi::app {

namespace {

/// Per voxel of a frame: 1 where a grid is active.
using VoxelMask = std::vector<std::uint8_t>;

/// The voxels of `density` / `temperature` (smoke) and of `velocity` / `pressure` (flow), as
/// write_vdb describes them.
struct ActiveVoxels {
  VoxelMask smoke, flow;
};

ActiveVoxels active_voxels(const VoxelFrame& v, double threshold) {
  const Index n = v.size();
  ActiveVoxels a;
  a.smoke.assign(static_cast<std::size_t>(n), 0);
  a.flow.assign(a.smoke.size(), 0);
  bool any_smoke = false;
  for (Index c = 0; c < n; ++c) {
    const bool smoke = v.fluid_fraction[c] > 0 && (threshold <= 0 || v.density[c] > threshold);
    a.smoke[static_cast<std::size_t>(c)] = smoke ? 1 : 0;
    any_smoke = any_smoke || smoke;
  }
  if (any_smoke) {
    a.flow = a.smoke;
    return a;
  }
  const bool liquid = v.phi.size() > 0;
  for (Index c = 0; c < n; ++c)
    a.flow[static_cast<std::size_t>(c)] = v.fluid_fraction[c] > 0 && (!liquid || v.phi[c] < 0);
  return a;
}

/// The transform voxel → world: voxel (i, j, k)'s centre at origin + (i, j, k) ∘ spacing.
openvdb::math::Transform::Ptr voxel_transform(const VoxelFrame& v) {
  openvdb::math::Mat4d m = openvdb::math::Mat4d::identity();
  for (int a = 0; a < 3; ++a) m(a, a) = v.spacing[a];
  m.setTranslation(openvdb::Vec3d(v.origin[0], v.origin[1], v.origin[2]));
  return openvdb::math::Transform::createLinearTransform(m);
}

/// A grid of `GridT` with value(c) on the voxels c of `mask`, the transform, name, class and
/// metadata `unit`. Serial, through one accessor (x fastest: mostly the cached leaf).
template <class GridT, class ValueOf>
typename GridT::Ptr make_grid(const VoxelFrame& v, const VoxelMask& mask,
                              typename GridT::ValueType background, ValueOf&& value,
                              const std::string& name, const std::string& unit) {
  typename GridT::Ptr grid = GridT::create(background);
  typename GridT::Accessor acc = grid->getAccessor();
  const Index nx = v.dims[0], ny = v.dims[1], nz = v.dims[2];
  for (Index k = 0; k < nz; ++k)
    for (Index j = 0; j < ny; ++j)
      for (Index i = 0; i < nx; ++i) {
        const Index c = i + nx * (j + ny * k);
        if (mask[static_cast<std::size_t>(c)]) acc.setValue(openvdb::Coord(i, j, k), value(c));
      }
  grid->setTransform(voxel_transform(v));
  grid->setName(name);
  grid->insertMeta("unit", openvdb::StringMetadata(unit));
  return grid;
}

/// Air (+h/2, h the largest spacing) on the layer of voxels just outside the box's six sides,
/// active: the liquid's surface closes at the walls it touches, and the flood fill finds air
/// beyond the box (not the sign of the liquid beside a wall).
void add_air_beyond_walls(const VoxelFrame& v, openvdb::FloatGrid& grid) {
  const float air = static_cast<float>(0.5 * v.spacing.maxCoeff());
  openvdb::FloatGrid::Accessor acc = grid.getAccessor();
  const std::array<Index, 3> n = v.dims;
  for (int a = 0; a < 3; ++a) {
    const int b = (a + 1) % 3, c = (a + 2) % 3;
    for (Index j = -1; j <= n[b]; ++j)
      for (Index k = -1; k <= n[c]; ++k)
        for (const Index i : {Index(-1), n[a]}) {
          openvdb::Coord x;
          x[a] = i;
          x[b] = j;
          x[c] = k;
          acc.setValue(x, air);
        }
  }
}

/// `surface`: the level set φ on the voxels with |φ| < 3h (h the largest spacing), clamped to
/// ±3h, air just beyond the box's walls (add_air_beyond_walls), inside and outside told apart
/// beyond the band (signed flood fill).
openvdb::FloatGrid::Ptr surface_grid(const VoxelFrame& v) {
  const double band = 3.0 * v.spacing.maxCoeff();
  VoxelMask mask(static_cast<std::size_t>(v.size()), 0);
  for (Index c = 0; c < v.size(); ++c)
    mask[static_cast<std::size_t>(c)] = std::abs(v.phi[c]) < band;
  auto value = [&](Index c) { return static_cast<float>(std::clamp(v.phi[c], -band, band)); };
  openvdb::FloatGrid::Ptr grid =
      make_grid<openvdb::FloatGrid>(v, mask, static_cast<float>(band), value, "surface", "m");
  grid->setGridClass(openvdb::GRID_LEVEL_SET);
  add_air_beyond_walls(v, *grid);
  openvdb::tools::signedFloodFill(grid->tree());
  return grid;
}

/// The grids of write_vdb.
openvdb::GridPtrVec frame_grids(const VoxelFrame& v, double threshold) {
  const ActiveVoxels a = active_voxels(v, threshold);
  auto f = [](double x) { return static_cast<float>(x); };
  openvdb::GridPtrVec grids;
  auto density = make_grid<openvdb::FloatGrid>(
      v, a.smoke, 0.0f, [&](Index c) { return f(v.density[c]); }, "density", "kg/m^3");
  density->setGridClass(openvdb::GRID_FOG_VOLUME);
  grids.push_back(density);
  grids.push_back(make_grid<openvdb::FloatGrid>(
      v, a.smoke, f(v.ambient_temperature), [&](Index c) { return f(v.temperature[c]); },
      "temperature", "K"));
  grids.push_back(make_grid<openvdb::Vec3SGrid>(
      v, a.flow, openvdb::Vec3s(0.0f),
      [&](Index c) {
        return openvdb::Vec3s(f(v.velocity(c, 0)), f(v.velocity(c, 1)), f(v.velocity(c, 2)));
      },
      "velocity", "m/s"));
  grids.push_back(make_grid<openvdb::FloatGrid>(
      v, a.flow, 0.0f, [&](Index c) { return f(v.pressure[c]); }, "pressure", "Pa"));
  if (v.phi.size() > 0) grids.push_back(surface_grid(v));
  return grids;
}

/// @throws InternalError if a field of `v` does not have one value per voxel
void check_frame(const VoxelFrame& v) {
  const Index n = v.size();
  TETFSI_CHECK(v.dims[0] >= 0 && v.dims[1] >= 0 && v.dims[2] >= 0, "voxel dims {} {} {}", v.dims[0],
               v.dims[1], v.dims[2]);
  TETFSI_CHECK(v.fluid_fraction.size() == n && v.density.size() == n && v.temperature.size() == n &&
                   v.pressure.size() == n && v.velocity.rows() == n,
               "voxel fields have {} / {} / {} / {} / {} values (fluid_fraction, density, "
               "temperature, pressure, velocity) for {} voxels",
               v.fluid_fraction.size(), v.density.size(), v.temperature.size(), v.pressure.size(),
               v.velocity.rows(), n);
  TETFSI_CHECK(v.phi.size() == 0 || v.phi.size() == n, "phi has {} values for {} voxels",
               v.phi.size(), n);
  TETFSI_CHECK((v.spacing.array() > 0).all() && v.spacing.allFinite(), "voxel spacing {} {} {}",
               v.spacing[0], v.spacing[1], v.spacing[2]);
}

// ---- summaries -----------------------------------------------------------------------------

template <class T>
double magnitude(const T& x) {
  if constexpr (std::is_arithmetic_v<T>)
    return static_cast<double>(x);
  else
    return std::sqrt(static_cast<double>(x[0]) * x[0] + static_cast<double>(x[1]) * x[1] +
                     static_cast<double>(x[2]) * x[2]);
}

/// min and max over the active values of a numeric or vec3 grid (vectors: of the magnitude).
struct ValueRange {
  VdbGridSummary& s;
  template <class GridT>
  void operator()(const GridT& grid) const {
    bool first = true;
    for (auto it = grid.cbeginValueOn(); it; ++it) {
      const double x = magnitude(*it);
      s.min = first ? x : std::min(s.min, x);
      s.max = first ? x : std::max(s.max, x);
      first = false;
    }
  }
};

VdbGridSummary summarise(const openvdb::GridBase& grid) {
  VdbGridSummary s;
  s.name = grid.getName();
  s.type = grid.valueType();
  s.grid_class = openvdb::GridBase::gridClassToString(grid.getGridClass());
  s.active_voxels = static_cast<std::int64_t>(grid.activeVoxelCount());
  grid.apply<openvdb::NumericGridTypes::Append<openvdb::Vec3GridTypes>>(ValueRange{s});
  const openvdb::CoordBBox box = grid.evalActiveVoxelBoundingBox();
  if (!box.empty() && s.active_voxels > 0) {
    const openvdb::BBoxd index(box.min().asVec3d() - openvdb::Vec3d(0.5),
                               box.max().asVec3d() + openvdb::Vec3d(0.5));
    const openvdb::BBoxd world = grid.transform().indexToWorld(index);
    for (int a = 0; a < 3; ++a) {
      s.bounds[static_cast<std::size_t>(a)] = world.min()[a];
      s.bounds[static_cast<std::size_t>(a) + 3] = world.max()[a];
    }
  }
  if (const auto unit = grid.getMetadata<openvdb::StringMetadata>("unit")) s.unit = unit->value();
  return s;
}

/// Write `grids` and `meta` to `<path>.tmp` and rename it to `path`.
/// @throws InputError naming `path` with OpenVDB's or the file system's reason
void write_vdb_file(const fs::path& path, const openvdb::GridPtrVec& grids,
                    const openvdb::MetaMap& meta) {
  fs::path tmp = path;
  tmp += ".tmp";
  std::error_code ec;
  try {
    openvdb::io::File file(tmp.string());
    file.write(grids, meta);
    file.close();
  } catch (const std::exception& e) {
    fs::remove(tmp, ec);
    throw InputError(fmt::format("cannot write '{}': {}", path.string(), one_line(e.what())));
  }
  fs::rename(tmp, path, ec);
  if (ec) {
    fs::remove(tmp, ec);
    throw InputError(
        fmt::format("cannot write '{}': rename failed: {}", path.string(), ec.message()));
  }
}

/// Open `path` for reading (metadata and grids read on demand). @throws InputError naming it
void open_vdb(openvdb::io::File& file, const fs::path& path) {
  openvdb::initialize();
  if (!fs::is_regular_file(path))
    throw InputError(fmt::format("cannot read '{}': no such file", path.string()));
  try {
    file.open(/*delayLoad=*/false);
  } catch (const std::exception& e) {
    throw InputError(fmt::format("cannot read '{}': not a readable .vdb: {}", path.string(),
                                 one_line(e.what())));
  }
}

}  // namespace

std::vector<VdbGridSummary> write_vdb(const fs::path& path, const VoxelFrame& v,
                                      const VdbFrameInfo& info) {
  check_frame(v);
  openvdb::initialize();
  const openvdb::GridPtrVec grids = frame_grids(v, info.smoke_threshold);
  openvdb::MetaMap meta;
  meta.insertMeta("tetfsi_step", openvdb::Int32Metadata(info.step));
  meta.insertMeta("tetfsi_time", openvdb::DoubleMetadata(info.time));
  meta.insertMeta("tetfsi_scene", openvdb::StringMetadata(info.scene));
  meta.insertMeta("tetfsi_axes", openvdb::StringMetadata(k_export_axes));
  write_vdb_file(path, grids, meta);
  std::vector<VdbGridSummary> out;
  for (const openvdb::GridBase::Ptr& g : grids) out.push_back(summarise(*g));
  return out;
}

VdbFileSummary read_vdb_summary(const fs::path& path) {
  openvdb::io::File file(path.string());
  open_vdb(file, path);
  VdbFileSummary out;
  try {
    const openvdb::MetaMap::Ptr meta = file.getMetadata();
    if (const auto step = meta->getMetadata<openvdb::Int32Metadata>("tetfsi_step"))
      out.step = step->value();
    if (const auto time = meta->getMetadata<openvdb::DoubleMetadata>("tetfsi_time"))
      out.time = time->value();
    const openvdb::GridPtrVecPtr grids = file.getGrids();
    for (const openvdb::GridBase::Ptr& g : *grids) out.grids.push_back(summarise(*g));
    file.close();
  } catch (const std::exception& e) {
    throw InputError(fmt::format("cannot read '{}': {}", path.string(), one_line(e.what())));
  }
  return out;
}

double vdb_grid_integral(const fs::path& path, const std::string& name) {
  openvdb::io::File file(path.string());
  open_vdb(file, path);
  if (!file.hasGrid(name))
    throw InputError(fmt::format("'{}' has no grid '{}'", path.string(), name));
  openvdb::GridBase::Ptr grid;
  try {
    grid = file.readGrid(name);
    file.close();
  } catch (const std::exception& e) {
    throw InputError(
        fmt::format("cannot read grid '{}' of '{}': {}", name, path.string(), one_line(e.what())));
  }
  double sum = 0.0;
  const bool real = grid->apply<openvdb::RealGridTypes>([&sum](const auto& g) {
    for (auto it = g.cbeginValueOn(); it; ++it)
      sum += static_cast<double>(*it) * static_cast<double>(it.getVoxelCount());
  });
  TETFSI_REQUIRE(InputError, real, "grid '{}' of '{}' holds {}, not float values", name,
                 path.string(), grid->valueType());
  return sum * grid->transform().voxelVolume();
}

}  // namespace tetfsi::app
