#pragma once
/// @file generate.hpp
/// Meshes generated in code: boxes (and thin boxes = sheets), icospheres.
#include "mesh/volume_mesh.hpp"

namespace tetfsi::mesh {

/// An axis-aligned box [lo, hi] cut into cells.x × cells.y × cells.z hexahedra, each split
/// into 6 tets around its main diagonal (Kuhn/Freudenthal split: conforming, no flips
/// needed, all positive). Vertex (i, j, k) has index i + (cells.x+1)(j + (cells.y+1) k).
/// @throws InputError if lo ≥ hi in any axis or any cell count < 1.
VolumeMesh make_box(const Vec3& lo, const Vec3& hi, const Vec3i& cells);

/// A closed, outward-oriented icosphere: the icosahedron with each triangle split into 4
/// `subdivisions` times, vertices projected on the sphere (20·4^s triangles, 10·4^s + 2
/// vertices).
/// @throws InputError if radius ≤ 0 or not finite, or subdivisions outside 0..7.
SurfaceMesh make_icosphere(const Vec3& centre, double radius, int subdivisions);

}  // namespace tetfsi::mesh
