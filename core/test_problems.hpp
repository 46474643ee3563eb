#pragma once
/// @file test_problems.hpp
/// Standard sparse test matrices for solver tests and benchmarks, on the interior nodes of
/// an nx × ny × nz grid (unknown (i, j, k) has index i + nx (j + ny k)), in units where the
/// grid spacing is 1, with homogeneous Dirichlet boundary values (boundary neighbours
/// dropped).
#include "core/types.hpp"

namespace tetfsi {

/// 7-point Laplacian −Δ: 6 on the diagonal, −1 per grid neighbour. Symmetric positive
/// definite, (nx ny nz) × (nx ny nz). @throws InputError unless nx, ny, nz ≥ 1.
SparseMatrix poisson3d(int nx, int ny, int nz);

/// −Δu + β·∇u with first-order upwind convection, β = peclet · (1, 1/2, 1/4) (so `peclet`
/// is the cell Péclet number in x). Nonsymmetric for peclet > 0, an irreducibly diagonally
/// dominant M-matrix, hence nonsingular. @throws InputError unless nx, ny, nz ≥ 1 and
/// peclet ≥ 0.
SparseMatrix convection_diffusion3d(int nx, int ny, int nz, double peclet);

}  // namespace tetfsi
