#pragma once
/// @file frame.hpp
/// A frame of the fluid as plain data, whatever the discretisation: the geometry the state
/// lives on with its fields, for the output (VTK files) and anyone else who reads a frame. A
/// frame is either an unstructured tet mesh with its cell, point and face arrays (MeshFrame)
/// or a regular grid with its cell arrays and the bodies' surface (GridFrameFields); a reader
/// may branch on the geometry type, never on which fluid produced it.
#include <array>
#include <cstdint>
#include <variant>

#include "core/types.hpp"
#include "mesh/tet_mesh.hpp"

namespace tetfsi::fluid {

/// The fluid's fields on the tet mesh of a frame, each sized for it.
struct MeshFrameFields {
  VecX pressure;          ///< #T, Pa at the circumcentres
  VecX density;           ///< #T smoke density (kg/m³)
  VecX temperature;       ///< #T (K)
  VecX vorticity;         ///< #T |curl u| (1/s)
  VecX divergence;        ///< #T (D u)_t (1/s)
  MatX3 cell_velocity;    ///< #T × 3 reconstructed at the centroids (m/s)
  MatX3 vertex_velocity;  ///< #V × 3 reconstructed at the vertices (m/s)
  VecX face_velocity;     ///< #F u_f, the normal velocity along n_f (m/s)
};

/// An unstructured frame: the fluid's tet mesh (owned by the fluid, valid until its next step)
/// and the fields on it.
struct MeshFrame {
  const mesh::TetMesh* mesh = nullptr;
  MeshFrameFields fields;
};

/// One frame of a regular-grid fluid (grid/grid.hpp): plain data, filled from fluid::GridFluid
/// (grid_frame_fields) and the bodies (the simulation's grid fluid). Cell c = i + nx (j + ny k), x
/// fastest (GridSpec::cell, VTK ImageData's order); #C = nx ny nz.
struct GridFrameFields {
  Vec3 origin = Vec3::Zero();              ///< lower corner of the fluid box (m)
  Vec3 spacing = Vec3::Ones();             ///< cell size per axis (m)
  std::array<Index, 3> cells = {1, 1, 1};  ///< nx, ny, nz
  // ---- per cell (#C) ----
  VecX pressure;                    ///< Pa (total; 0 in solid cells)
  VecX density;                     ///< smoke density (kg/m³)
  VecX temperature;                 ///< K
  VecX divergence;                  ///< 1/s
  VecX vorticity;                   ///< |curl u| (1/s)
  MatX3 velocity;                   ///< #C × 3 at the cell centres (m/s)
  std::vector<std::uint8_t> solid;  ///< #C: 1 where the cell is inside a body
  VecX phi;  ///< #C the liquid's level set (m, < 0 in the liquid); empty without a free surface
  // ---- the bodies' boundary triangles at the frame (the grid's solid interface) ----
  MatX3 surface_points;        ///< #P × 3 (m)
  MatX3i surface_triangles;    ///< #Tr × 3 into surface_points, outward-oriented
  VecXi surface_body;          ///< #Tr body index
  VecX surface_pressure;       ///< #Tr Pa, the pressure the fluid exerts on the outer side
  VecX surface_pressure_jump;  ///< #Tr Pa, outer − inner side (NaN/0 where a side has no fluid)
  MatX3 surface_force;         ///< #P × 3 N, the fluid's nodal force on each surface point
};

/// One frame of the fluid: none (no fluid, or none started yet), a tet mesh, or a grid.
struct FluidFrame {
  std::variant<std::monostate, MeshFrame, GridFrameFields> geometry;
  /// The unstructured frame, or nullptr.
  const MeshFrame* mesh() const { return std::get_if<MeshFrame>(&geometry); }
  /// The regular-grid frame, or nullptr.
  const GridFrameFields* grid() const { return std::get_if<GridFrameFields>(&geometry); }
};

}  // namespace tetfsi::fluid
