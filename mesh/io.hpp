#pragma once
/// @file io.hpp
/// Readers for the mesh files users bring.
///
/// Volume meshes: Gmsh `.msh` (ASCII v2.2 and v4.1; tets = element type 4, other element
/// types ignored), TetGen `.node` + `.ele` (give either file; 0- or 1-based numbering as the
/// file says), VTK `.vtu` (cells of type VTK_TETRA; others ignored).
/// Surface meshes: `.off`, `.obj` (v/f lines; polygons fan-triangulated), `.stl` (ASCII and
/// binary).
/// Every reader throws `InputError` for a missing/unreadable file or a syntax error, naming
/// the file and line, and `MeshError` for bad geometry (via validate_volume_mesh). Messages
/// are one line:
///   "<path>: no such file"
///   "<path>:<line>: expected <what>, got '<line text>'"   (or "..., got end of file")
///   "<path>:<line>: element 7 refers to node 9, which $Nodes does not define"
///   "<path>: binary .msh is not supported; re-save as ASCII (...)"
///   "<path>: element 26 (nodes 3 9 12 40) is inverted (signed volume -0.000167 m^3); fix the
///    element's vertex order or remesh"   (file's element and node ids)
/// Node and element ids in messages are the file's own (Gmsh tags, TetGen numbers, VTK
/// zero-based point and cell ids).
#include <filesystem>

#include "mesh/volume_mesh.hpp"

namespace tetfsi::mesh {

/// Read a tet mesh by extension (.msh, .node, .ele, .vtu), fix a globally flipped
/// orientation, drop unused vertices and validate it.
VolumeMesh read_volume_mesh(const std::filesystem::path& path);

/// Read a triangle surface by extension (.off, .obj, .stl), merging duplicate vertices
/// (STL). Does not check closedness: see validate_closed_surface.
SurfaceMesh read_surface_mesh(const std::filesystem::path& path);

/// Check a VTK XML file before VTK reads it (vtu_check.cpp): piece counts the file cannot
/// hold, component numbers outside 1..4096, appended (raw) block headers past the end of the
/// file, and every appended array of a known type decoded (raw, zlib, LZ4) to exactly the
/// bytes its Piece announces, the cells' offsets non-decreasing and their connectivity within
/// the points. VTK's reader loops, allocates without bound or reads out of bounds on those. @throws
/// InputError naming the file
void check_vtk_xml_header(const std::filesystem::path& path);

/// Write a tet mesh as Gmsh ASCII v2.2 (for tests and for users converting meshes).
void write_msh(const VolumeMesh& m, const std::filesystem::path& path);

}  // namespace tetfsi::mesh
