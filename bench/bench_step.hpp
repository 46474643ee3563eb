#pragma once
/// @file bench_step.hpp
/// `tetfsi bench step`: the whole step of a fluid scene (solid step, fluid remesh, transfer,
/// forces, pressure assembly and solve, one fluid frame) against its floor measured in the
/// same run on the same mesh: the bare CGAL Delaunay of the mesh's vertices
/// (mesh::delaunay_tets) plus one AMG-preconditioned pressure solve (setup + solve) on it.
/// A grid scene (fluid.discretization "grid") is timed on its grid (scales divide the cells
/// per axis), against one AMG Poisson solve of the same grid, and per case against the same
/// scene on the tet mesh at about the grid's fluid cells, in the same run (the JSON then has
/// "discretization": "grid" and per case "grid_cells", "solve_ratio", "tet": {"scale",
/// "cells", "step_s"}, "grid_over_tet").
#include <filesystem>
#include <iosfwd>
#include <vector>

namespace tetfsi::app {

struct BenchStepOptions {
  /// If nonempty, also write the results here (atomically) as
  /// `{"scene", "steps", "cases": [{"cells", "step_s", "floor_s", "ratio", "phases": {"remesh",
  /// "transfer", "forces", "assembly", "solve", "output", "solid", "other"}, "iterations",
  /// "scale", "vertices", "delaunay_s", "poisson_s", "poisson_setup_s", "remesh_delaunay_s"
  /// (the remesher's own Delaunay, RemeshReport::seconds_delaunay), "floor_iterations",
  /// "warmup_s"}]}` (seconds; phases and iterations are means per timed step).
  std::filesystem::path json_path;
  /// Steps per case (≥ 2); the first is a warm-up, the figures are means over the others.
  int steps = 3;
  /// Factors applied to the scene's fluid.mesh surface_size, far_size and refine.size (grid
  /// scenes: to the cell size), one case each, in this order. Empty: chosen from one remesh
  /// of the scene at scale 1 (grid scenes: from its grid) so the fluid has about
  /// `target_cells` cells (cells ∝ scale⁻³).
  std::vector<double> scales;
  std::vector<double> target_cells = {30000, 100000, 250000};
};

/// Run the benchmark on a fluid scene and print a table to `out`: per case the cells of the
/// last mesh, the mean step (s), the floor (s), their ratio, the mean seconds of each phase
/// and the mean pressure iterations. Frames go to a temporary folder that is removed.
/// The scene's fluid cell budget (fluid.mesh.max_cells) is ignored: the sizes are the point.
/// @throws InputError if the scene has no fluid section, is static, or an option is out of
///   range; MeshError / SolverError as the run would.
/// @return 0
int bench_step(const std::filesystem::path& scene, const BenchStepOptions& opt, std::ostream& out);

}  // namespace tetfsi::app
