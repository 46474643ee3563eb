#pragma once
/// @file fluid_test_utils.hpp
/// Meshes for the fluid tests: remeshed boxes (with the remesher's co-spherical cells), a
/// Delaunay mesh of random points (no co-spherical cells), surfaces of solids.
#include <random>
#include <vector>

#include "core/linear_solver.hpp"
#include "core/types.hpp"
#include "fluid/tet/operators.hpp"
#include "mesh/generate.hpp"
#include "mesh/remesh.hpp"
#include "mesh/tet_mesh.hpp"

namespace tetfsi::test {

inline mesh::FluidDomain box_domain(const Vec3& lo, const Vec3& hi,
                                    mesh::FaceKind kind = mesh::FaceKind::Wall) {
  mesh::FluidDomain d;
  d.lo = lo;
  d.hi = hi;
  d.default_kind = kind;
  return d;
}

inline mesh::Sizing sizing(double surface, double far, double grading = 0.5) {
  mesh::Sizing z;
  z.surface_size = surface;
  z.far_size = far;
  z.grading = grading;
  return z;
}

inline mesh::SolidSurface sphere_surface(const Vec3& c, double r, int levels, int body = 0) {
  const mesh::SurfaceMesh sm = mesh::make_icosphere(c, r, levels);
  mesh::SolidSurface s;
  s.body = body;
  s.vertices = sm.vertices;
  s.triangles = sm.triangles;
  return s;
}

/// A hollow shell: outer sphere r_out, inner cavity r_in (inward-facing), one body.
inline mesh::SolidSurface hollow_sphere(const Vec3& c, double r_out, double r_in, int levels,
                                        int body = 0) {
  const mesh::SurfaceMesh a = mesh::make_icosphere(c, r_out, levels);
  const mesh::SurfaceMesh b = mesh::make_icosphere(c, r_in, levels);
  mesh::SolidSurface s;
  s.body = body;
  s.vertices.resize(a.vertices.rows() + b.vertices.rows(), 3);
  s.vertices << a.vertices, b.vertices;
  s.triangles.resize(a.triangles.rows() + b.triangles.rows(), 3);
  s.triangles.topRows(a.triangles.rows()) = a.triangles;
  for (Index t = 0; t < b.triangles.rows(); ++t)
    s.triangles.row(a.triangles.rows() + t) =
        Eigen::RowVector3i(b.triangles(t, 0), b.triangles(t, 2), b.triangles(t, 1)).array() +
        static_cast<int>(a.vertices.rows());
  return s;
}

/// Delaunay mesh of the 8 corners of [0,1]³ plus n random points (no co-spherical cells
/// beyond the corners), all boundary faces Wall.
inline mesh::TetMesh random_delaunay(int n, unsigned seed = 7) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> U(0.02, 0.98);
  MatX3 p(n + 8, 3);
  for (int i = 0; i < 8; ++i) p.row(i) = Vec3(i & 1, (i >> 1) & 1, (i >> 2) & 1).transpose();
  for (int i = 0; i < n; ++i) p.row(8 + i) = Vec3(U(rng), U(rng), U(rng)).transpose();
  MatX4i t = mesh::delaunay_tets(p);
  return mesh::build_tet_mesh(p, t);
}

/// Normal components n_f · field(x_f) of a vector field at the face centroids (#F).
template <class F>
VecX face_field(const mesh::TetMesh& m, F&& field) {
  VecX u(m.num_faces());
  for (Index f = 0; f < m.num_faces(); ++f)
    u[f] = m.face_normals.row(f).dot(field(Vec3(m.face_centroids.row(f).transpose())).transpose());
  return u;
}

/// face_field with 0 on the boundary faces, projected (AMG, rel_tol 1e-12) so that it starts
/// divergence-free: the initial field of the Taylor–Green and rotation tests.
template <class F>
VecX divergence_free_field(const mesh::TetMesh& m, double min_dual_fraction, F&& field) {
  VecX u = face_field(m, field);
  for (Index f = 0; f < m.num_faces(); ++f)
    if (m.is_boundary(f)) u[f] = 0.0;
  auto solver = make_linear_solver(SolverKind::Amg, {1e-12, 500});
  VecX q;
  fluid::project(m, min_dual_fraction, VecX(), u, q, *solver);
  return u;
}

}  // namespace tetfsi::test
