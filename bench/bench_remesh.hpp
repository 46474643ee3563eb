#pragma once
/// @file bench_remesh.hpp
/// `tetfsi bench remesh`: the fluid remesher against its floor, the bare CGAL Delaunay
/// tetrahedralisation of the same vertex set, at about 30k, 250k and 1M cells.
#include <iosfwd>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "mesh/remesh.hpp"

namespace tetfsi::app {

/// The solids of the benchmark: a 0.6 × 0.6 × 0.01 m sheet (24 × 24 cells) tilted 10°
/// about (1, 1, 0), centred at (0.45, 0.5, 0.62), body 0; an icosphere (4 subdivisions,
/// 5120 triangles) of radius 0.12 m at (0.5, 0.5, 0.28), body 1.
std::vector<mesh::SolidSurface> bench_remesh_solids();

/// Mesh the unit box around a rubber sheet (0.6 × 0.6 × 0.01 m, tilted 10°) and a sphere
/// (radius 0.12 m) at three sizes; for each print remesh seconds (with its phases), the
/// seconds of mesh::delaunay_tets on the final mesh's vertices, their ratio, cells per
/// second and the quality summary (min dihedral overall and away from the solids, slivers,
/// interior faces with d_f ≤ 0 and tiny d_f).
/// @param json_path if nonempty, also write `{"cases": [{"cells", "remesh_s", "delaunay_s",
///   "ratio", "min_dihedral_deg", "min_dihedral_away_deg", "slivers", "nonpositive_dual",
///   "tiny_dual", "steiner_points", "recovery_rounds", "phases": {...}}]}` (atomically)
/// @param max_cells skip cases whose target exceeds this (for quick runs)
/// @param repeat time each remesh and each floor this many times; the fastest of each (and
///   that remesh's phases) are reported
/// @return 0
/// @param moving_scene, moving_steps if moving_steps ≥ 2, also the moving case
///   (bench_remesh_moving), written to the JSON as "moving"
int bench_remesh(const std::string& json_path, long max_cells, std::ostream& out, int repeat = 1,
                 const std::string& moving_scene = "data/scenes/remesh_sheet.json",
                 int moving_steps = 20);

/// The bodies of a one-way scene (remesh_sheet: a sagging, swinging sheet) at each of `steps`
/// steps of its solid dynamics, with its fluid domain and sizing.
struct MovingSheet {
  mesh::FluidDomain domain;
  mesh::Sizing sizing;
  double dt = 0;
  std::vector<std::vector<mesh::SolidSurface>> frames;  ///< per step, per body
};
/// @throws InputError naming the file if the scene has no tet fluid (and load_scene's errors)
MovingSheet moving_sheet(const std::string& scene_path, int steps);

/// Remesh every frame of moving_sheet(scene_path, steps) with a mesh::Remesher, on the full
/// path (Sizing::incremental false) and the incremental one, alternating, `repeat` times,
/// keeping the fastest of each; print per path the remesh and Delaunay seconds per step
/// (after the first, always full), the fraction of vertices the incremental path touched
/// (removed + inserted over the vertices) and whether every mesh is the same bit for bit.
/// @return {"scene", "steps", "cells", "full": {...}, "incremental": {...}, "same"}
nlohmann::json bench_remesh_moving(const std::string& scene_path, int steps, int repeat,
                                   std::ostream& out);

}  // namespace tetfsi::app
