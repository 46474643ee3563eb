#pragma once
/// @file body_interface.hpp
/// How every discretisation of the fluid numbers a body's surface and its DOFs: the interface
/// operators H, J of the tet mesh (tet/interface.hpp) and of the MAC grid (grid/interface.hpp)
/// stack the bodies the same way (body b's node i is DOF block 3 (offset_b + i)).
#include "core/types.hpp"

namespace tetfsi::fluid {

/// How a fluid's Solid faces (a tet mesh's, a grid's) refer to one body: the surface the mesh was
/// built from (triangles in its compact vertex numbering, as in mesh::SolidSurface) and the body
/// node of each compact vertex.
struct BodyInterface {
  MatX3i triangles;     ///< #Ts × 3, compact surface vertex indices
  VecXi surface_node;   ///< #Vs: body node of each compact surface vertex
  Index num_nodes = 0;  ///< nodes of the body (its DOF block is 3 × this)
};

}  // namespace tetfsi::fluid
