#pragma once
/// @file generate.hpp
/// Tet meshes generated in code: boxes (and thin boxes = sheets).
#include "mesh/volume_mesh.hpp"

namespace tetfsi::mesh {

/// An axis-aligned box [lo, hi] cut into cells.x × cells.y × cells.z hexahedra, each split
/// into 6 tets around its main diagonal (Kuhn/Freudenthal split: conforming, no flips
/// needed, all positive). Vertex (i, j, k) has index i + (cells.x+1)(j + (cells.y+1) k).
/// @throws InputError if lo ≥ hi in any axis or any cell count < 1.
VolumeMesh make_box(const Vec3& lo, const Vec3& hi, const Vec3i& cells);

}  // namespace tetfsi::mesh
