#include "core/test_problems.hpp"

#include "core/error.hpp"

namespace tetfsi {

namespace {

/// Diffusion (6, −1) plus upwind convection with velocity `beta` (all components ≥ 0):
/// row of (i, j, k) gets +β_d on the diagonal and −β_d on its lower neighbour in d.
SparseMatrix grid_operator(int nx, int ny, int nz, const Vec3& beta) {
  TETFSI_REQUIRE(InputError, nx >= 1 && ny >= 1 && nz >= 1,
                 "test problem grid must be at least 1 x 1 x 1, got {} x {} x {}", nx, ny, nz);
  const long long n64 = static_cast<long long>(nx) * ny * nz;
  TETFSI_REQUIRE(InputError, n64 * 7 < (1LL << 31),
                 "test problem grid {} x {} x {} is too large for 32-bit indices", nx, ny, nz);
  const Index n = static_cast<Index>(n64);
  const int dims[3] = {nx, ny, nz};
  const Index stride[3] = {1, nx, nx * ny};
  Triplets t;
  t.reserve(static_cast<std::size_t>(n) * 7);
  for (int k = 0; k < nz; ++k)
    for (int j = 0; j < ny; ++j)
      for (int i = 0; i < nx; ++i) {
        const Index row = i + nx * (j + ny * k);
        const int c[3] = {i, j, k};
        t.emplace_back(row, row, 6.0 + beta.sum());
        for (int d = 0; d < 3; ++d) {
          if (c[d] > 0) t.emplace_back(row, row - stride[d], -1.0 - beta[d]);  // upwind side
          if (c[d] + 1 < dims[d]) t.emplace_back(row, row + stride[d], -1.0);
        }
      }
  SparseMatrix A(n, n);
  A.setFromTriplets(t.begin(), t.end());
  A.makeCompressed();
  return A;
}

}  // namespace

SparseMatrix poisson3d(int nx, int ny, int nz) {
  return grid_operator(nx, ny, nz, Vec3::Zero());
}

SparseMatrix convection_diffusion3d(int nx, int ny, int nz, double peclet) {
  TETFSI_REQUIRE(InputError, peclet >= 0.0, "convection_diffusion3d: need peclet ≥ 0, got {}",
                 peclet);
  return grid_operator(nx, ny, nz, peclet * Vec3(1.0, 0.5, 0.25));
}

}  // namespace tetfsi
