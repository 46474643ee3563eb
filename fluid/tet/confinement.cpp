#include "fluid/tet/confinement.hpp"

#include <cmath>

#include <Eigen/Geometry>

#include "core/parallel.hpp"
#include "fluid/tet/reconstruct.hpp"

namespace tetfsi::fluid {

using mesh::FaceKind;
using mesh::TetMesh;

namespace {
/// Cells or faces per chunk of the parallel loops (each writes its own slot).
constexpr Index kGrain = 4096;
}  // namespace

VecX cell_sizes(const TetMesh& m) {
  // The mean of the 6 edges: unlike the cube root of the volume it does not vanish for the
  // flat cells a remesh can leave against a solid.
  VecX e(m.num_tets());
  parallel_for_each(m.num_tets(), kGrain, [&](Index t) {
    double s = 0;
    for (int i = 0; i < 4; ++i)
      for (int j = i + 1; j < 4; ++j)
        s += (m.vertices.row(m.tets(t, i)) - m.vertices.row(m.tets(t, j))).norm();
    e[t] = s / 6.0;
  });
  return e;
}

MatX3 vorticity_confinement(const TetMesh& m, const MatX3& U, double epsilon) {
  const Index nt = m.num_tets();
  MatX3 a = MatX3::Zero(nt, 3);
  if (epsilon <= 0) return a;
  const MatX3 w = cell_vorticity(m, U);
  const VecX wn = w.rowwise().norm();
  const VecX wv = cell_to_vertex(m, wn);
  const VecX dx = cell_sizes(m);
  parallel_for_each(nt, kGrain, [&](Index t) {
    const auto g = barycentric_gradients(m, t);
    Vec3 grad = Vec3::Zero();
    for (int i = 0; i < 4; ++i) grad += wv[m.tets(t, i)] * g.row(i).transpose();
    const double gn = grad.norm();
    if (gn < 1e-12 * (wn[t] / dx[t] + 1e-300)) return;
    const Vec3 N = grad / gn;
    // [Fedkiw01, Eq. (11)] f_conf = ε h (N × ω)
    a.row(t) = epsilon * dx[t] * N.cross(w.row(t).transpose()).transpose();
  });
  return a;
}

void add_cell_acceleration(const TetMesh& m, const MatX3& accel, double h, VecX& u) {
  const Index nf = m.num_faces();
  parallel_for_each(nf, kGrain, [&](Index f) {
    const Index t1 = m.face_tets(f, 0), t2 = m.face_tets(f, 1);
    Vec3 a;
    if (t2 >= 0)
      a = 0.5 * (accel.row(t1) + accel.row(t2)).transpose();
    else if (m.face_kind[f] == FaceKind::Open)
      a = accel.row(t1).transpose();
    else
      return;
    u[f] += h * m.face_normals.row(f).dot(a.transpose());
  });
}

}  // namespace tetfsi::fluid
