#pragma once
/// @file geometry.hpp
/// Small geometric kernels shared inside tetfsi::mesh (plain Eigen, header only): the
/// closest point of a triangle, and the sorted-triple hash of the face tables.
#include <cstdint>
#include <utility>

#include "core/types.hpp"

namespace tetfsi::mesh {

/// Closest point of triangle (a, b, c) to p, and its barycentric coordinates in `bc`
/// [Ericson05, §5.1.5, ClosestPtPointTriangle].
inline Vec3 closest_on_triangle(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c,
                                Vec3& bc) {
  const Vec3 ab = b - a, ac = c - a, ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0.0 && d2 <= 0.0) {
    bc = Vec3(1, 0, 0);
    return a;
  }
  const Vec3 bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0.0 && d4 <= d3) {
    bc = Vec3(0, 1, 0);
    return b;
  }
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0) {
    const double v = d1 / (d1 - d3);
    bc = Vec3(1 - v, v, 0);
    return a + v * ab;
  }
  const Vec3 cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0.0 && d5 <= d6) {
    bc = Vec3(0, 0, 1);
    return c;
  }
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0) {
    const double w = d2 / (d2 - d6);
    bc = Vec3(1 - w, 0, w);
    return a + w * ac;
  }
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0.0 && d4 - d3 >= 0.0 && d5 - d6 >= 0.0) {
    const double w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
    bc = Vec3(0, 1 - w, w);
    return b + w * (c - b);
  }
  const double denom = 1.0 / (va + vb + vc);
  const double v = vb * denom, w = vc * denom;
  bc = Vec3(1 - v - w, v, w);
  return a + v * ab + w * ac;
}

/// Closest point of triangle (a, b, c) to p.
inline Vec3 closest_on_triangle(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c) {
  Vec3 bc;
  return closest_on_triangle(p, a, b, c, bc);
}

/// Hash of a sorted vertex triple (face tables).
inline std::uint64_t hash_triple(int a, int b, int c) {
  std::uint64_t h = static_cast<std::uint32_t>(a) * 0x9E3779B97F4A7C15ULL;
  h ^= static_cast<std::uint32_t>(b) * 0xC2B2AE3D27D4EB4FULL;
  h ^= static_cast<std::uint32_t>(c) * 0x165667B19E3779F9ULL;
  return h ^ (h >> 29);
}

/// Sort three indices ascending.
inline void sort3(int& a, int& b, int& c) {
  if (a > b) std::swap(a, b);
  if (b > c) std::swap(b, c);
  if (a > b) std::swap(a, b);
}

}  // namespace tetfsi::mesh
