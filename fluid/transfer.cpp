#include "fluid/transfer.hpp"

#include <Eigen/Dense>
#include <algorithm>

#include "core/error.hpp"
#include "fluid/reconstruct.hpp"

namespace tetfsi::fluid {

using mesh::TetMesh;

Barycentrics::Barycentrics(const TetMesh& m)
    : m_mesh(&m), m_inv(static_cast<size_t>(m.num_tets())) {
  for (Index t = 0; t < m.num_tets(); ++t) {
    const Vec3 x0 = m.vertices.row(m.tets(t, 0)).transpose();
    Mat3 E;
    for (int i = 0; i < 3; ++i) E.col(i) = m.vertices.row(m.tets(t, i + 1)).transpose() - x0;
    m_inv[t] = E.inverse();
  }
}

Vec4 Barycentrics::operator()(Index t, const Vec3& x) const {
  const Vec3 l = m_inv[t] * (x - m_mesh->vertices.row(m_mesh->tets(t, 0)).transpose());
  return Vec4(1.0 - l.sum(), l[0], l[1], l[2]);
}

Vec3 position(const TetMesh& m, const TracePoint& p) {
  Vec3 x = Vec3::Zero();
  for (int i = 0; i < 4; ++i) x += p.bary[i] * m.vertices.row(m.tets(p.tet, i)).transpose();
  return x;
}

TracePoint walk_segment(const Barycentrics& bary, const TracePoint& from, const Vec3& x1) {
  const TetMesh& m = bary.mesh();
  TracePoint cur = from;
  Vec4 b0 = from.bary;  // where the walk is now, in cur.tet
  constexpr double eps = 1e-12;
  const int max_steps = 10000;
  int prev_face = -1;
  for (int step = 0; step < max_steps; ++step) {
    const Vec4 b1 = bary(cur.tet, x1);
    if (b1.minCoeff() >= -eps) {
      cur.bary = b1;
      return cur;
    }
    // Leave through the face k whose coordinate reaches 0 first along b0 → b1.
    double s_best = 2.0;
    int k_best = -1;
    for (int k = 0; k < 4; ++k) {
      if (b1[k] >= -eps) continue;
      if (m.tet_faces(cur.tet, k) == prev_face) continue;  // the face we entered through
      const double denom = b0[k] - b1[k];
      const double s = denom > 0 ? std::max(0.0, b0[k]) / denom : 0.0;
      if (s < s_best) {
        s_best = s;
        k_best = k;
      }
    }
    if (k_best < 0) {  // only the entry face is "behind": x1 is on it up to round-off
      cur.bary = b1.cwiseMax(0.0) / b1.cwiseMax(0.0).sum();
      return cur;
    }
    Vec4 bx = b0 + s_best * (b1 - b0);
    bx[k_best] = 0.0;
    bx = bx.cwiseMax(0.0);
    bx /= bx.sum();
    const Index n = m.neighbours(cur.tet, k_best);
    if (n < 0) {  // the path leaves the fluid: stop on the boundary face
      cur.bary = bx;
      cur.clamped = true;
      cur.exit_face = m.tet_faces(cur.tet, k_best);
      return cur;
    }
    const Vec3 xe = position(m, TracePoint{cur.tet, bx, false});
    prev_face = m.tet_faces(cur.tet, k_best);
    cur.tet = n;
    b0 = bary(n, xe).cwiseMax(0.0);
    b0 /= b0.sum();
  }
  cur.bary = b0;  // the step limit (never seen): stay where the walk got to
  return cur;
}

TransferOutput transfer(const TransferInput& in, const TetMesh& nm, double h) {
  TETFSI_CHECK(in.old_mesh && in.old_u, "transfer needs the old mesh and velocity");
  const TetMesh& om = *in.old_mesh;
  TETFSI_CHECK(in.old_u->size() == om.num_faces(), "old u has {} entries for {} faces",
               in.old_u->size(), om.num_faces());
  const VelocityField field(om, *in.old_u, in.reconstruction);
  const mesh::PointLocator locator(om);
  const Barycentrics bary(om);
  TransferOutput out;
  const Index nf = nm.num_faces(), nt = nm.num_tets();
  out.u.resize(nf);
  out.density.resize(nt);
  out.temperature.resize(nt);

  // Locate x in the old fluid: walk there from a nearby point already located (`from`: the
  // previous cell's point, or a face's cell); if that walk is stopped by the boundary, ask
  // the locator whether x is inside after all (e.g. behind a thin solid); if it is not (x lies
  // where a solid was, or a new region opened), start from the boundary point where the walk
  // stopped — the fluid next to x on the way from its neighbours — or, without a `from`, the
  // nearest tet. `inside` tells whether the result is x itself.
  auto start_at = [&](const Vec3& x, const TracePoint& from, bool& inside) {
    TracePoint p;
    inside = true;
    if (from.tet >= 0) {
      p = walk_segment(bary, TracePoint{from.tet, from.bary, false}, x);
      if (!p.clamped) return p;
    }
    const mesh::Location loc = locator.locate(x, from.tet, /*nearest_if_outside=*/from.tet < 0);
    if (loc.inside || from.tet < 0) {
      inside = loc.inside;
      return TracePoint{loc.tet, loc.bary, false};
    }
    inside = false;
    p.clamped = false;
    return p;  // the walk's boundary point
  };
  // The Inflow patch a back-trace was stopped at (−1 if none).
  auto inflow_patch = [&](const TracePoint& p) -> Index {
    if (!p.clamped || p.exit_face < 0 || om.face_kind[p.exit_face] != mesh::FaceKind::Inflow)
      return -1;
    return om.face_patch[p.exit_face];
  };
  // RK2 (midpoint) back-trace from x [KFCO06, §4]: x_mid = x − h/2 u(x), x_back = x − h u(x_mid).
  // Returns where it ended and the Inflow patch either half was stopped at (−1 if none).
  struct Trace {
    TracePoint end;
    Index inflow = -1;
  };
  auto trace_back = [&](const TracePoint& p0) {
    const Vec3 u0 = field.at(p0.tet, p0.bary);
    const Vec3 x0 = position(om, p0);
    const TracePoint pm = walk_segment(bary, p0, x0 - 0.5 * h * u0);
    const Vec3 um = field.at(pm.tet, pm.bary);
    // x_back lies beyond x_mid along about the same path: walk on from there.
    TracePoint pb = walk_segment(bary, pm.clamped ? p0 : pm, x0 - h * um);
    if (pm.clamped || pb.clamped) ++out.clamped;
    Trace tr{pb, inflow_patch(pb)};
    if (tr.inflow < 0) tr.inflow = inflow_patch(pm);
    return tr;
  };

  // Cells first, each located from the previous one (the cells of a CGAL mesh come in
  // spatially sorted order); then each face from its first cell's point, a fraction of a
  // cell away.
  std::vector<TracePoint> cell_start(static_cast<size_t>(nt));
  const bool has_d = in.old_density != nullptr, has_T = in.old_temperature != nullptr;
  const VecX dv = has_d ? cell_to_vertex_linear(om, *in.old_density) : VecX();
  const VecX tv = has_T ? cell_to_vertex_linear(om, *in.old_temperature) : VecX();
  auto sample = [&](const VecX& vv, const TracePoint& p) {
    double s = 0.0;
    for (int i = 0; i < 4; ++i) s += p.bary[i] * vv[om.tets(p.tet, i)];
    return s;
  };
  TracePoint prev;
  for (Index t = 0; t < nt; ++t) {
    const Vec3 x = mesh::tet_centroid(nm, t);
    bool inside = false;
    const TracePoint p0 = start_at(x, prev, inside);
    if (inside) prev = p0;
    cell_start[t] = inside ? p0 : prev;  // a face of this cell starts from a point inside
    if (!has_d && !has_T) continue;
    const Trace tr = trace_back(p0);
    out.density[t] = has_d ? sample(dv, tr.end) : 0.0;
    out.temperature[t] = has_T ? sample(tv, tr.end) : 0.0;
    const auto ip = static_cast<size_t>(tr.inflow);
    if (tr.inflow >= 0 && ip < in.inflow_density.size()) out.density[t] = in.inflow_density[ip];
    if (tr.inflow >= 0 && ip < in.inflow_temperature.size())
      out.temperature[t] = in.inflow_temperature[ip];
  }
  for (Index f = 0; f < nf; ++f) {
    const Vec3 x = nm.face_centroids.row(f).transpose();
    bool inside = false;
    const TracePoint p0 = start_at(x, cell_start[nm.face_tets(f, 0)], inside);
    const TracePoint pb = trace_back(p0).end;
    out.u[f] = field.normal_at(pb.tet, pb.bary, nm.face_normals.row(f).transpose());
  }
  if (!in.old_density) out.density.setZero();
  if (!in.old_temperature) out.temperature.setZero();
  return out;
}

}  // namespace tetfsi::fluid
