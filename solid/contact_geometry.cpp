/// @file contact_geometry.cpp
/// Closest points [Ericson05, §5.1.5, §5.1.9], CCD by conservative advancement [Li21, ACCD]
/// and the box tree (see contact_geometry.hpp).
#include "solid/contact_geometry.hpp"

#include <algorithm>
#include <numeric>

#include <Eigen/Geometry>

namespace tetfsi::solid {

namespace {

PointTriangle at_weights(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c, double w0,
                         double w1, double w2) {
  PointTriangle r;
  r.w = {w0, w1, w2};
  r.closest = w0 * a + w1 * b + w2 * c;
  r.distance = (p - r.closest).norm();
  return r;
}

/// The closest of the triangle's three edges to p (degenerate triangles).
PointTriangle on_edges(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c) {
  const double s = point_segment_parameter(p, a, b);
  const double t = point_segment_parameter(p, b, c);
  const double u = point_segment_parameter(p, c, a);
  PointTriangle best = at_weights(p, a, b, c, 1 - s, s, 0);
  for (const PointTriangle& r :
       {at_weights(p, a, b, c, 0, 1 - t, t), at_weights(p, a, b, c, u, 0, 1 - u)}) {
    if (r.distance < best.distance) best = r;
  }
  return best;
}

/// The earliest t in [0, 1] with distance(t) ≤ tol, by conservative advancement with the
/// bound |d'(t)| ≤ L (see the file comment of contact_geometry.hpp).
template <class Distance>
double advance(const Distance& distance, double L, double tol, CcdReport* report) {
  CcdReport r;
  double t = 0.0;
  double d = distance(0.0);
  const double stop = tol + ccd_relative_gap * tol + 1e-12 * (d + L);
  for (;;) {
    if (d <= stop) {  // touching (within the stopping gap)
      r.t = t;
      break;
    }
    if (!(L > 0.0) || t + (d - tol) / L > 1.0) {  // d > tol on all of [t, 1]
      r.t = -1.0;
      break;
    }
    if (r.iterations == ccd_max_iterations) {  // grazing: report the (early) t
      r.t = t;
      r.capped = true;
      break;
    }
    t += 0.9 * (d - tol) / L;  // [Li21, ACCD]: stays before the first touch
    d = distance(t);
    ++r.iterations;
  }
  r.distance = d;
  if (report) *report = r;
  return r.t;
}

}  // namespace

double point_segment_parameter(const Vec3& p, const Vec3& a, const Vec3& b) {
  const Vec3 ab = b - a;
  const double l2 = ab.squaredNorm();
  if (!(l2 > 0.0)) return 0.0;
  return std::clamp((p - a).dot(ab) / l2, 0.0, 1.0);
}

PointTriangle point_triangle(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c) {
  const Vec3 ab = b - a, ac = c - a, ap = p - a;
  const double e2 = std::max({ab.squaredNorm(), ac.squaredNorm(), (c - b).squaredNorm()});
  if (ab.cross(ac).squaredNorm() <= 4e-16 * e2 * e2) return on_edges(p, a, b, c);
  // [Ericson05, §5.1.5]: the Voronoi regions of the vertices, the edges, then the face.
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0 && d2 <= 0) return at_weights(p, a, b, c, 1, 0, 0);
  const Vec3 bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0 && d4 <= d3) return at_weights(p, a, b, c, 0, 1, 0);
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) {
    const double v = d1 / (d1 - d3);
    return at_weights(p, a, b, c, 1 - v, v, 0);
  }
  const Vec3 cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0 && d5 <= d6) return at_weights(p, a, b, c, 0, 0, 1);
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) {
    const double w = d2 / (d2 - d6);
    return at_weights(p, a, b, c, 1 - w, 0, w);
  }
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && d4 - d3 >= 0 && d5 - d6 >= 0) {
    const double w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
    return at_weights(p, a, b, c, 0, 1 - w, w);
  }
  // The face: va, vb, vc > 0 in exact arithmetic; round-off otherwise falls back to the edges.
  if (!(va > 0 && vb > 0 && vc > 0)) return on_edges(p, a, b, c);
  const double sum = va + vb + vc;
  return at_weights(p, a, b, c, va / sum, vb / sum, vc / sum);
}

EdgeEdge edge_edge(const Vec3& p0, const Vec3& p1, const Vec3& q0, const Vec3& q1) {
  // [Ericson05, §5.1.9], the closest points of the two lines clamped to the segments.
  const Vec3 u = p1 - p0, v = q1 - q0, r = p0 - q0;
  const double a = u.squaredNorm(), e = v.squaredNorm(), f = v.dot(r);
  double s = 0.0, t = 0.0;
  if (!(a > 0.0)) {
    t = e > 0.0 ? std::clamp(f / e, 0.0, 1.0) : 0.0;  // p a point
  } else {
    const double c = u.dot(r);
    if (!(e > 0.0)) {
      s = std::clamp(-c / a, 0.0, 1.0);  // q a point
    } else {
      const double b = u.dot(v), denom = a * e - b * b;
      // Parallel (sin² of the angle below 1e-14): any s; take 0, then the closest t.
      s = denom > 1e-14 * a * e ? std::clamp((b * f - c * e) / denom, 0.0, 1.0) : 0.0;
      t = (b * s + f) / e;
      if (t < 0.0) {
        t = 0.0;
        s = std::clamp(-c / a, 0.0, 1.0);
      } else if (t > 1.0) {
        t = 1.0;
        s = std::clamp((b - c) / a, 0.0, 1.0);
      }
    }
  }
  return {(p0 + s * u - q0 - t * v).norm(), s, t};
}

double ccd_point_triangle(const Vec3& p0, const Vec3& a0, const Vec3& b0, const Vec3& c0,
                          const Vec3& p1, const Vec3& a1, const Vec3& b1, const Vec3& c1,
                          double tol, CcdReport* report) {
  const Vec3 dp = p1 - p0, da = a1 - a0, db = b1 - b0, dc = c1 - c0;
  const Vec3 mean = 0.25 * (dp + da + db + dc);  // a common translation leaves d unchanged
  const double L = (dp - mean).norm() + std::max({(da - mean).norm(), (db - mean).norm(),
                                                  (dc - mean).norm()});  // [Li21, ACCD]
  const auto distance = [&](double t) {
    return point_triangle(p0 + t * dp, a0 + t * da, b0 + t * db, c0 + t * dc).distance;
  };
  return advance(distance, L, tol, report);
}

double ccd_edge_edge(const Vec3& p0, const Vec3& p1, const Vec3& q0, const Vec3& q1,
                     const Vec3& p0e, const Vec3& p1e, const Vec3& q0e, const Vec3& q1e, double tol,
                     CcdReport* report) {
  const Vec3 dp0 = p0e - p0, dp1 = p1e - p1, dq0 = q0e - q0, dq1 = q1e - q1;
  const Vec3 mean = 0.25 * (dp0 + dp1 + dq0 + dq1);
  const double L = std::max((dp0 - mean).norm(), (dp1 - mean).norm()) +
                   std::max((dq0 - mean).norm(), (dq1 - mean).norm());  // [Li21, ACCD]
  const auto distance = [&](double t) {
    return edge_edge(p0 + t * dp0, p1 + t * dp1, q0 + t * dq0, q1 + t * dq1).distance;
  };
  return advance(distance, L, tol, report);
}

void Box::extend(const Vec3& x) {
  lo = lo.cwiseMin(x);
  hi = hi.cwiseMax(x);
}

void Box::inflate(double r) {
  lo.array() -= r;
  hi.array() += r;
}

bool Box::overlaps(const Box& o) const {
  return lo.x() <= o.hi.x() && o.lo.x() <= hi.x() && lo.y() <= o.hi.y() && o.lo.y() <= hi.y() &&
         lo.z() <= o.hi.z() && o.lo.z() <= hi.z();
}

void BoxTree::build(const std::vector<Box>& boxes) {
  const Index n = static_cast<Index>(boxes.size());
  m_nodes.clear();
  m_index.resize(n);
  std::iota(m_index.begin(), m_index.end(), 0);
  std::vector<Vec3> centre(n);
  for (Index i = 0; i < n; ++i) centre[i] = 0.5 * (boxes[i].lo + boxes[i].hi);
  if (n > 0) {
    m_nodes.reserve(2 * (n / leaf_size + 1));
    build_node(0, n, boxes, centre);
  }
  m_boxes.resize(n);
  for (Index k = 0; k < n; ++k) m_boxes[k] = boxes[m_index[k]];
}

Index BoxTree::build_node(Index begin, Index end, const std::vector<Box>& boxes,
                          const std::vector<Vec3>& centre) {
  const Index id = static_cast<Index>(m_nodes.size());
  m_nodes.emplace_back();
  Box box;
  for (Index k = begin; k < end; ++k) {
    box.extend(boxes[m_index[k]].lo);
    box.extend(boxes[m_index[k]].hi);
  }
  m_nodes[id].box = box;
  m_nodes[id].begin = begin;
  m_nodes[id].end = end;
  if (end - begin <= leaf_size) return id;
  int axis = 0;
  (box.hi - box.lo).maxCoeff(&axis);
  const Index mid = begin + (end - begin) / 2;
  std::nth_element(m_index.begin() + begin, m_index.begin() + mid, m_index.begin() + end,
                   [&](Index i, Index j) {  // a strict total order: deterministic halves
                     const double ci = centre[i][axis], cj = centre[j][axis];
                     return ci < cj || (ci == cj && i < j);
                   });
  const Index left = build_node(begin, mid, boxes, centre);
  const Index right = build_node(mid, end, boxes, centre);
  m_nodes[id].left = left;
  m_nodes[id].right = right;
  return id;
}

void BoxTree::query(const Box& q, std::vector<Index>& out) const {
  if (m_nodes.empty()) return;
  const std::size_t first = out.size();
  std::vector<Index> stack{0};
  while (!stack.empty()) {
    const Node& node = m_nodes[stack.back()];
    stack.pop_back();
    if (!node.box.overlaps(q)) continue;
    if (!node.leaf()) {
      stack.push_back(node.right);
      stack.push_back(node.left);
      continue;
    }
    for (Index k = node.begin; k < node.end; ++k) {
      if (m_boxes[k].overlaps(q)) out.push_back(m_index[k]);
    }
  }
  std::sort(out.begin() + static_cast<std::ptrdiff_t>(first), out.end());
}

void BoxTree::leaf_pairs(const Node& a, const BoxTree& other, const Node& b, bool self, bool same,
                         std::vector<std::pair<Index, Index>>& out) const {
  for (Index i = a.begin; i < a.end; ++i) {
    for (Index j = same ? i + 1 : b.begin; j < b.end; ++j) {
      if (!m_boxes[i].overlaps(other.m_boxes[j])) continue;
      const Index u = m_index[i], v = other.m_index[j];
      out.emplace_back(self ? std::min(u, v) : u, self ? std::max(u, v) : v);
    }
  }
}

/// Simultaneous descent of both trees; with self, node pairs (a, a) split into their
/// children's three pairs and the pairs come out as (min, max).
void BoxTree::traverse(const BoxTree& other, bool self,
                       std::vector<std::pair<Index, Index>>& out) const {
  if (m_nodes.empty() || other.m_nodes.empty()) return;
  const std::size_t first = out.size();
  std::vector<std::pair<Index, Index>> stack{{0, 0}};
  while (!stack.empty()) {
    const auto [a, b] = stack.back();
    stack.pop_back();
    const Node& A = m_nodes[a];
    const Node& B = other.m_nodes[b];
    if (self && a == b) {
      if (A.leaf()) {
        leaf_pairs(A, other, B, true, true, out);
      } else {
        stack.insert(stack.end(), {{A.left, A.right}, {A.right, A.right}, {A.left, A.left}});
      }
    } else if (!A.box.overlaps(B.box)) {
      continue;
    } else if (A.leaf() && B.leaf()) {
      leaf_pairs(A, other, B, self, false, out);
    } else if (B.leaf() || (!A.leaf() && A.end - A.begin >= B.end - B.begin)) {
      stack.insert(stack.end(), {{A.right, b}, {A.left, b}});
    } else {
      stack.insert(stack.end(), {{a, B.right}, {a, B.left}});
    }
  }
  std::sort(out.begin() + static_cast<std::ptrdiff_t>(first), out.end());
}

void BoxTree::pairs(const BoxTree& other, std::vector<std::pair<Index, Index>>& out) const {
  traverse(other, false, out);
}

void BoxTree::self_pairs(std::vector<std::pair<Index, Index>>& out) const {
  traverse(*this, true, out);
}

}  // namespace tetfsi::solid
