#pragma once
/// @file confinement.hpp
/// Body forces on the tet mesh's face velocities: vorticity confinement [Fedkiw01, Eq. (11)]
/// and any per-cell acceleration (buoyancy, forces.hpp) applied to a face as n_f · (mean of
/// its cells' values).
#include "core/types.hpp"
#include "mesh/tet_mesh.hpp"

namespace tetfsi::fluid {

/// Per-cell vorticity confinement acceleration (#T × 3, m/s²): ε Δx (N × ω) with
/// N = ∇|ω| / |∇|ω||, Δx the cell's size (cell_sizes); |ω| is
/// averaged to the vertices and differentiated per tet.
/// @param vertex_velocity #V × 3 reconstructed velocities
MatX3 vorticity_confinement(const mesh::TetMesh& m, const MatX3& vertex_velocity, double epsilon);

/// u_f += h n_f · ½ (a_t1 + a_t2) on interior faces and h n_f · a_t1 on Open faces
/// (prescribed-velocity faces are left alone).
void add_cell_acceleration(const mesh::TetMesh& m, const MatX3& accel, double h, VecX& u);

/// Mean edge length of each cell (#T, m).
VecX cell_sizes(const mesh::TetMesh& m);

}  // namespace tetfsi::fluid
