#pragma once
/// @file types.hpp
/// Vector, matrix and index types shared by every tetfsi module.
///
/// Conventions used throughout the code base:
///  - positions and per-node vectors of n nodes are stored as `MatX3` (n × 3, row major,
///    so row i is node i) or, where a solver needs them, as a flat `VecX` of length 3n with
///    node i's components at 3i, 3i+1, 3i+2 ("interleaved");
///  - tets are `MatX4i` (m × 4, row major) of zero-based node indices;
///  - sparse matrices are Eigen column-major with `Index` = int, which is what CHOLMOD,
///    UMFPACK and PETSc take without copying indices.
#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <cstdint>
#include <limits>
#include <vector>

namespace tetfsi {

using Real = double;
using Index = int;  ///< node, element and DOF indices

using Vec2 = Eigen::Vector2d;
using Vec3 = Eigen::Vector3d;
using Vec4 = Eigen::Vector4d;
using Mat3 = Eigen::Matrix3d;
using VecX = Eigen::VectorXd;
using MatX = Eigen::MatrixXd;
using Vec3i = Eigen::Vector3i;
using Vec4i = Eigen::Vector4i;
using VecXi = Eigen::VectorXi;

/// n × 3 per-node data (row i = node i).
using MatX3 = Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>;
/// m × 3 triangles (zero-based node indices).
using MatX3i = Eigen::Matrix<int, Eigen::Dynamic, 3, Eigen::RowMajor>;
/// m × 4 tetrahedra (zero-based node indices).
using MatX4i = Eigen::Matrix<int, Eigen::Dynamic, 4, Eigen::RowMajor>;

using SparseMatrix = Eigen::SparseMatrix<double, Eigen::ColMajor, Index>;
using Triplet = Eigen::Triplet<double, Index>;
using Triplets = std::vector<Triplet>;

/// static_cast<Index>(std::floor(q)), the same value for every q whose floor an Index holds,
/// without the call to libm's floor that x86-64 code built for its baseline (no SSE4.1
/// rounding) makes: the truncation, one less where it rounded a negative q up. (Beyond an
/// Index, where the cast is undefined, the same as x86's cast of the floor: the least Index.)
inline Index floor_index(double q) {
  const Index t = static_cast<Index>(q);
  return static_cast<double>(t) > q && t != std::numeric_limits<Index>::min() ? t - 1 : t;
}

/// View an n × 3 row-major array as a flat interleaved vector of length 3n (no copy).
inline Eigen::Map<VecX> flat(MatX3& m) {
  return {m.data(), m.size()};
}
inline Eigen::Map<const VecX> flat(const MatX3& m) {
  return {m.data(), m.size()};
}
/// View a flat interleaved vector of length 3n as n × 3 (no copy).
inline Eigen::Map<MatX3> as_nodes(VecX& v) {
  return {v.data(), v.size() / 3, 3};
}
inline Eigen::Map<const MatX3> as_nodes(const VecX& v) {
  return {v.data(), v.size() / 3, 3};
}

}  // namespace tetfsi
