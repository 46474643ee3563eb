#pragma once
/// @file frame_data.hpp
/// A run's frame files read back into plain arrays (the files io/output.hpp writes): a body's
/// `.vtu`, the tet fluid's `.vtu` and the grid fluid's `.vti`. For `tetfsi export`
/// (render/export_cmd.hpp) and the pictures of `tetfsi render` (the smoke volume, a liquid's
/// closed surface through io's liquid_surface).
///
/// Every reader checks the file first as the other readers do (a `.vtu` through
/// mesh::check_vtk_xml_header), keeps VTK's messages off stderr, and throws one InputError
/// naming the file and what is wrong. VTK stays in frame_data.cpp.
#include <filesystem>

#include "core/types.hpp"
#include "fluid/frame.hpp"
#include "io/export.hpp"

namespace tetfsi::app {

/// A tet body's frame: its current positions and tets with the arrays the export carries.
struct TetBodyFrame {
  MatX3 points;    ///< #V × 3 deformed positions (m)
  MatX4i tets;     ///< #T × 4
  MatX3 velocity;  ///< #V × 3 point `velocity` (m/s), empty if the file has none
  VecX von_mises;  ///< #T cell `von_mises_stress` (Pa), empty if the file has none
};

/// A body's `.vtu` (every cell a VTK_TETRA). @throws InputError naming the file if it is
/// missing or unreadable, has no tets, a cell that is not a tet, or an array of the wrong size.
TetBodyFrame read_body_frame(const std::filesystem::path& vtu);

/// The tet fluid's `.vtu`: points, tets, cell `smoke_density`, `temperature`, `pressure` and
/// point `velocity` (each left empty if the file lacks it; `only_density` reads the density
/// alone). @throws InputError as read_body_frame.
TetVolume read_tet_fluid_frame(const std::filesystem::path& vtu, bool only_density = false);

/// The grid fluid's `.vti`: its box and cells with the cell arrays `pressure`,
/// `smoke_density`, `temperature`, `velocity`, `solid` (required), `divergence`, `vorticity`
/// (0 if absent) and `phi` (empty if absent); no bodies' surface (the `.vti` has none).
/// @throws InputError naming the file if it is missing or unreadable or lacks an array.
fluid::GridFrameFields read_grid_fluid_frame(const std::filesystem::path& vti);

}  // namespace tetfsi::app
