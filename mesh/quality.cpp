/// @file quality.cpp
/// Per-cell and per-face mesh-quality figures, their summary and the text report.
#include "mesh/quality.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numbers>
#include <string>
#include <utility>
#include <vector>

#include <fmt/format.h>
#include <Eigen/Geometry>  // cross()

#include "core/error.hpp"
#include "core/parallel.hpp"
#include "mesh/volume_mesh.hpp"

namespace tetfsi::mesh {

namespace {

constexpr double kRadToDeg = 180.0 / std::numbers::pi;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kInf = std::numeric_limits<double>::infinity();

/// Local faces of tet (0,1,2,3) with outward right-hand normals; face k opposite vertex k.
constexpr int kOutwardFace[4][3] = {{1, 2, 3}, {0, 3, 2}, {0, 1, 3}, {0, 2, 1}};

/// The q-quantile (q in [0, 1]) of `v` by nearest rank on the sorted order, index
/// round(q (n − 1)); NaN for an empty set. Reorders `v` (nth_element).
double quantile(std::vector<double>& v, double q) {
  if (v.empty()) return kNaN;
  const auto k = static_cast<std::ptrdiff_t>(std::lround(q * static_cast<double>(v.size() - 1)));
  std::nth_element(v.begin(), v.begin() + k, v.end());
  return v[static_cast<std::size_t>(k)];
}

std::vector<double> to_vector(const VecX& x) {
  return {x.data(), x.data() + x.size()};
}

/// Fill the cell part of a summary from per-cell figures.
void summarize_cells(const TetQuality& q, QualitySummary& s) {
  const Index n = static_cast<Index>(q.volume.size());
  s.cells = n;
  s.volume = q.volume.sum();
  s.min_dihedral_hist = histogram(q.min_dihedral_deg, 0.0, 90.0, 18);
  s.max_dihedral_hist = histogram(q.max_dihedral_deg, 60.0, 180.0, 12);
  s.shape_hist = histogram(q.shape, 0.0, 1.0, 10);
  if (n == 0) {
    s.min_dihedral_deg = s.max_dihedral_deg = s.min_dihedral_p01 = s.min_dihedral_p05 =
        s.min_dihedral_p50 = s.min_dihedral_away_deg = s.min_shape = s.shape_p05 = s.shape_p50 =
            s.max_radius_edge = s.min_volume = kNaN;
    return;
  }
  s.min_dihedral_deg = q.min_dihedral_deg.minCoeff();
  s.max_dihedral_deg = q.max_dihedral_deg.maxCoeff();
  s.min_dihedral_away_deg = s.min_dihedral_deg;
  std::vector<double> v = to_vector(q.min_dihedral_deg);
  s.min_dihedral_p01 = quantile(v, 0.01);
  s.min_dihedral_p05 = quantile(v, 0.05);
  s.min_dihedral_p50 = quantile(v, 0.50);
  s.min_shape = q.shape.minCoeff();
  v = to_vector(q.shape);
  s.shape_p05 = quantile(v, 0.05);
  s.shape_p50 = quantile(v, 0.50);
  s.max_radius_edge = q.radius_edge.maxCoeff();
  s.min_volume = q.volume.minCoeff();
  s.slivers = (q.min_dihedral_deg.array() < 5.0).count();
  s.inverted = (q.volume.array() <= 0.0).count();
}

/// "  [ 10,  15)    1234   4.5% ####" lines of a histogram, bars scaled to the largest bin.
std::string format_histogram(const Histogram& h, const char* title, int precision) {
  std::string out = fmt::format("  {}\n", title);
  Index total = 0, largest = 0;
  for (const Index c : h.counts) {
    total += c;
    largest = std::max(largest, c);
  }
  const int bins = static_cast<int>(h.counts.size());
  const double w = bins > 0 ? (h.hi - h.lo) / bins : 0.0;
  constexpr int kBar = 50;
  for (int b = 0; b < bins; ++b) {
    const Index c = h.counts[static_cast<std::size_t>(b)];
    const int len = largest > 0 ? static_cast<int>(std::lround(kBar * static_cast<double>(c) /
                                                               static_cast<double>(largest)))
                                : 0;
    const double pct =
        total > 0 ? 100.0 * static_cast<double>(c) / static_cast<double>(total) : 0.0;
    out +=
        fmt::format("    [{:>6.{}f}, {:>6.{}f}{} {:>10} {:>6.2f}% {}{}\n", h.lo + b * w, precision,
                    h.lo + (b + 1) * w, precision, b + 1 == bins ? ']' : ')', c, pct,
                    std::string(static_cast<std::size_t>(len), '#'), c > 0 && len == 0 ? "." : "");
  }
  return out;
}

}  // namespace

std::pair<double, double> dihedral_range_deg(const Vec3& a, const Vec3& b, const Vec3& c,
                                             const Vec3& d) {
  const Vec3* x[4] = {&a, &b, &c, &d};
  // Outward unit normals; the dihedral angle at the edge shared by faces i and j is
  // π − ∠(n_i, n_j), i.e. the angle between n_i and −n_j.
  std::array<Vec3, 4> nrm;
  for (int k = 0; k < 4; ++k) {
    const Vec3& p = *x[kOutwardFace[k][0]];
    const Vec3& q = *x[kOutwardFace[k][1]];
    const Vec3& r = *x[kOutwardFace[k][2]];
    nrm[static_cast<std::size_t>(k)] = (q - p).cross(r - p).normalized();
  }
  double dmin = kInf, dmax = -kInf;
  for (int i = 0; i < 4; ++i) {
    for (int j = i + 1; j < 4; ++j) {
      // atan2 instead of acos: accurate near 0° and 180° (slivers), where acos of a
      // cosine near ±1 loses half the digits.
      const double e = std::atan2(nrm[i].cross(nrm[j]).norm(), -nrm[i].dot(nrm[j])) * kRadToDeg;
      dmin = std::min(dmin, e);
      dmax = std::max(dmax, e);
    }
  }
  return {dmin, dmax};
}

TetQuality tet_quality(const MatX3& vertices, const MatX4i& tets) {
  const Index n = static_cast<Index>(tets.rows());
  TetQuality q;
  q.min_dihedral_deg.resize(n);
  q.max_dihedral_deg.resize(n);
  q.radius_edge.resize(n);
  q.shape.resize(n);
  q.volume.resize(n);
  for (Index t = 0; t < n; ++t)  // checked first, serially: the error names the first bad tet
    for (int k = 0; k < 4; ++k)
      TETFSI_REQUIRE(MeshError, tets(t, k) >= 0 && tets(t, k) < vertices.rows(),
                     "tet_quality: tet {} refers to vertex {} but the mesh has {} vertices", t,
                     tets(t, k), vertices.rows());
  parallel_for_each(n, 4096, [&](Index t) {  // each tet writes its own entries
    std::array<Vec3, 4> x;
    for (int k = 0; k < 4; ++k) x[static_cast<std::size_t>(k)] = vertices.row(tets(t, k));
    const auto [dmin, dmax] = dihedral_range_deg(x[0], x[1], x[2], x[3]);
    double l2_min = kInf, l2_sum = 0.0;
    for (int i = 0; i < 4; ++i) {
      for (int j = i + 1; j < 4; ++j) {
        const double l2 = (x[i] - x[j]).squaredNorm();
        l2_min = std::min(l2_min, l2);
        l2_sum += l2;
      }
    }
    const double vol = signed_volume(x[0], x[1], x[2], x[3]);
    const double r = (circumcentre(x[0], x[1], x[2], x[3]) - x[0]).norm();
    const double l_rms = std::sqrt(l2_sum / 6.0);
    q.min_dihedral_deg(t) = dmin;
    q.max_dihedral_deg(t) = dmax;
    q.radius_edge(t) = r / std::sqrt(l2_min);  // +inf for a flat tet
    q.shape(t) = 6.0 * std::numbers::sqrt2 * vol / (l_rms * l_rms * l_rms);
    q.volume(t) = vol;
  });
  return q;
}

FaceQuality face_quality(const TetMesh& m) {
  const Index nf = m.num_faces();
  FaceQuality q;
  q.dual_length = m.dual_lengths;
  q.weight.resize(nf);
  q.relative_dual.resize(nf);
  parallel_for_each(nf, 4096, [&](Index f) {
    const Vec3 a = m.vertices.row(m.faces(f, 0)), b = m.vertices.row(m.faces(f, 1)),
               c = m.vertices.row(m.faces(f, 2));
    const double mean_edge = ((b - a).norm() + (c - b).norm() + (a - c).norm()) / 3.0;
    const double d = m.dual_lengths(f);
    q.relative_dual(f) = d / mean_edge;
    q.weight(f) = m.is_boundary(f) ? 0.0 : (d > 0.0 ? m.face_areas(f) / d : kInf);
  });
  return q;
}

Histogram histogram(const VecX& values, double lo, double hi, int bins) {
  TETFSI_CHECK(bins >= 1 && hi > lo, "histogram needs bins >= 1 and hi > lo, got {} on [{}, {}]",
               bins, lo, hi);
  Histogram h;
  h.lo = lo;
  h.hi = hi;
  h.counts.assign(static_cast<std::size_t>(bins), 0);
  const double scale = bins / (hi - lo);
  for (Index i = 0; i < values.size(); ++i) {
    const double x = values(i);
    // NaN goes to the first bin with the low outliers (it is a broken cell).
    const double b = std::isnan(x) ? 0.0 : std::floor((x - lo) * scale);
    const int k = b < 0.0 ? 0 : (b >= bins ? bins - 1 : static_cast<int>(b));
    ++h.counts[static_cast<std::size_t>(k)];
  }
  return h;
}

QualitySummary summarize_quality(const TetQuality& q) {
  QualitySummary s;
  summarize_cells(q, s);
  s.relative_dual_hist = histogram(VecX(), 0.0, 1.0, 10);
  return s;
}

QualitySummary summarize_quality(const TetMesh& m) {
  const TetQuality q = tet_quality(m.vertices, m.tets);
  QualitySummary s;
  summarize_cells(q, s);

  // Cells away from solid surfaces: no vertex with a body (when provenance is present).
  if (m.vertex_body.size() == m.num_vertices() && (m.vertex_body.array() >= 0).any()) {
    double away = kInf;
    for (Index t = 0; t < m.num_tets(); ++t) {
      bool touches = false;
      for (int k = 0; k < 4; ++k) touches = touches || m.vertex_body(m.tets(t, k)) >= 0;
      if (!touches) away = std::min(away, q.min_dihedral_deg(t));
    }
    s.min_dihedral_away_deg = std::isfinite(away) ? away : kNaN;
  }

  const FaceQuality fq = face_quality(m);
  s.faces = m.num_faces();
  std::vector<double> weights, rel;
  weights.reserve(static_cast<std::size_t>(m.num_faces()));
  rel.reserve(static_cast<std::size_t>(m.num_faces()));
  for (Index f = 0; f < m.num_faces(); ++f) {
    if (m.is_boundary(f)) continue;
    ++s.interior_faces;
    const double d = m.dual_lengths(f);
    if (d <= 0.0) {
      ++s.nonpositive_dual;
    } else if (fq.relative_dual(f) < 1e-3) {
      ++s.tiny_dual;
    }
    const double w = fq.weight(f);
    if (std::isfinite(w)) s.max_weight = std::max(s.max_weight, w);
    weights.push_back(w);
    rel.push_back(fq.relative_dual(f));
  }
  s.median_weight = quantile(weights, 0.5);
  s.relative_dual_hist =
      histogram(Eigen::Map<const VecX>(rel.data(), static_cast<Index>(rel.size())), 0.0, 1.0, 10);
  return s;
}

std::string format_quality_report(const QualitySummary& s) {
  std::string out;
  out += fmt::format("Mesh quality: {} cells, {} faces ({} interior), volume {:.6g} m^3\n", s.cells,
                     s.faces, s.interior_faces, s.volume);
  out += fmt::format(
      "  min dihedral angle   {:8.3f} deg   (1%: {:.3f}, 5%: {:.3f}, median: {:.3f}; regular "
      "tet 70.529)\n",
      s.min_dihedral_deg, s.min_dihedral_p01, s.min_dihedral_p05, s.min_dihedral_p50);
  out += fmt::format("  min dihedral away from solids {:8.3f} deg\n", s.min_dihedral_away_deg);
  out += fmt::format("  max dihedral angle   {:8.3f} deg\n", s.max_dihedral_deg);
  out += fmt::format(
      "  shape 6*sqrt(2)*V/l_rms^3  min {:.4f}, 5%: {:.4f}, median: {:.4f} (regular tet 1)\n",
      s.min_shape, s.shape_p05, s.shape_p50);
  out += fmt::format("  max radius-edge ratio {:.4g} (regular tet 0.6124)\n", s.max_radius_edge);
  out += fmt::format("  min cell volume      {:.4g} m^3\n", s.min_volume);
  out += fmt::format("  slivers (min dihedral < 5 deg): {}   inverted (volume <= 0): {}\n",
                     s.slivers, s.inverted);
  if (s.faces > 0) {
    out += fmt::format("  interior faces with d_f <= 0: {}   with 0 < d_f < 1e-3 * mean edge: {}\n",
                       s.nonpositive_dual, s.tiny_dual);
    out += fmt::format("  Laplacian weight A_f/d_f: median {:.4g} m, max finite {:.4g} m\n",
                       s.median_weight, s.max_weight);
  }
  out += format_histogram(s.min_dihedral_hist, "per-cell min dihedral angle (deg):", 0);
  out += format_histogram(s.max_dihedral_hist, "per-cell max dihedral angle (deg):", 0);
  out += format_histogram(s.shape_hist, "per-cell shape:", 1);
  if (s.faces > 0) {
    out += format_histogram(
        s.relative_dual_hist,
        "interior-face d_f / mean edge of the face (d_f <= 0 in the first bin):", 1);
  }
  return out;
}

std::vector<std::pair<std::string, double>> quality_columns(const QualitySummary& s) {
  const auto d = [](Index i) { return static_cast<double>(i); };
  return {
      {"q_cells", d(s.cells)},
      {"q_faces", d(s.faces)},
      {"q_interior_faces", d(s.interior_faces)},
      {"q_volume", s.volume},
      {"q_min_dihedral_deg", s.min_dihedral_deg},
      {"q_max_dihedral_deg", s.max_dihedral_deg},
      {"q_min_dihedral_p01", s.min_dihedral_p01},
      {"q_min_dihedral_p05", s.min_dihedral_p05},
      {"q_min_dihedral_p50", s.min_dihedral_p50},
      {"q_min_dihedral_away_deg", s.min_dihedral_away_deg},
      {"q_min_shape", s.min_shape},
      {"q_shape_p05", s.shape_p05},
      {"q_shape_p50", s.shape_p50},
      {"q_max_radius_edge", s.max_radius_edge},
      {"q_min_volume", s.min_volume},
      {"q_slivers", d(s.slivers)},
      {"q_inverted", d(s.inverted)},
      {"q_nonpositive_dual", d(s.nonpositive_dual)},
      {"q_tiny_dual", d(s.tiny_dual)},
      {"q_max_weight", s.max_weight},
      {"q_median_weight", s.median_weight},
  };
}

}  // namespace tetfsi::mesh
