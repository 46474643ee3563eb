/// Tests of mesh/quality.cpp: per-cell figures against hand values (regular tet, right-corner
/// tet, a sliver, the Kuhn tet of make_box), face figures, summaries, histograms, report and
/// stats columns.
#include <doctest/doctest.h>

#include <cmath>
#include <numbers>
#include <numeric>
#include <set>
#include <string>

#include "mesh/generate.hpp"
#include "mesh/quality.hpp"
#include "mesh/tet_mesh.hpp"

using namespace tetfsi;
using namespace tetfsi::mesh;

namespace {

constexpr double kDeg = 180.0 / std::numbers::pi;

/// Quality of the single tet (a, b, c, d).
TetQuality one(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d) {
  MatX3 x(4, 3);
  x.row(0) = a;
  x.row(1) = b;
  x.row(2) = c;
  x.row(3) = d;
  MatX4i t(1, 4);
  t << 0, 1, 2, 3;
  return tet_quality(x, t);
}

Index total(const Histogram& h) {
  return std::accumulate(h.counts.begin(), h.counts.end(), Index{0});
}

}  // namespace

TEST_SUITE("unit") {
  TEST_CASE("tet_quality: regular tet") {
    // Alternate corners of a cube: edge 2√2, volume 8/3.
    const TetQuality q = one(Vec3(1, 1, 1), Vec3(-1, 1, -1), Vec3(1, -1, -1), Vec3(-1, -1, 1));
    const double dihedral = std::acos(1.0 / 3.0) * kDeg;  // 70.528779...
    CHECK(std::abs(q.min_dihedral_deg(0) - dihedral) <= 1e-9);
    CHECK(std::abs(q.max_dihedral_deg(0) - dihedral) <= 1e-9);
    CHECK(std::abs(dihedral - 70.52877936550931) <= 1e-12);
    CHECK(q.radius_edge(0) == doctest::Approx(std::sqrt(6.0) / 4.0).epsilon(1e-12));
    CHECK(q.shape(0) == doctest::Approx(1.0).epsilon(1e-12));
    CHECK(q.volume(0) == doctest::Approx(8.0 / 3.0).epsilon(1e-12));
  }

  TEST_CASE("tet_quality: right-corner tet") {
    const TetQuality q = one(Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0), Vec3(0, 0, 1));
    // Three 90° angles at the legs, three of acos(1/√3) = 54.7356° at the slanted face.
    CHECK(std::abs(q.min_dihedral_deg(0) - std::acos(1.0 / std::sqrt(3.0)) * kDeg) <= 1e-9);
    CHECK(std::abs(q.max_dihedral_deg(0) - 90.0) <= 1e-9);
    // R = √3/2 (circumcentre (½,½,½)), shortest edge 1.
    CHECK(q.radius_edge(0) == doctest::Approx(std::sqrt(3.0) / 2.0).epsilon(1e-12));
    // Edges 1,1,1,√2,√2,√2: l_rms² = 3/2, shape = 6√2 (1/6) / (3/2)^{3/2} = 4 / (3√3).
    CHECK(q.shape(0) == doctest::Approx(4.0 / (3.0 * std::sqrt(3.0))).epsilon(1e-12));
    CHECK(q.volume(0) == doctest::Approx(1.0 / 6.0).epsilon(1e-12));
  }

  TEST_CASE("tet_quality: a sliver of four nearly coplanar square corners") {
    // a, b, c in z = 0 and d = (1, 1, ε): the diagonals ad and bc nearly cross.
    for (const double eps : {1e-1, 1e-3, 1e-6}) {
      CAPTURE(eps);
      const TetQuality q = one(Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0), Vec3(1, 1, eps));
      // Hand values (normals of the four faces): the smallest angle is at edges bd and cd,
      // between abd (normal (0, −ε, 1)) and bcd (normal (ε, ε, −1)): atan(ε / √(1 + ε²)); the
      // largest at the diagonal bc, between abc (z = 0) and bcd: 180° − atan(√2 ε).
      CHECK(std::abs(q.min_dihedral_deg(0) - std::atan(eps / std::sqrt(1 + eps * eps)) * kDeg) <=
            1e-9);
      CHECK(std::abs(q.max_dihedral_deg(0) - (180.0 - std::atan(std::sqrt(2.0) * eps) * kDeg)) <=
            1e-9);
      // V = ε/6; Σ l² = 8 + 3ε²; shape = √2 ε / ((8 + 3ε²)/6)^{3/2} → 0.
      const double l2 = (8.0 + 3.0 * eps * eps) / 6.0;
      CHECK(q.shape(0) ==
            doctest::Approx(std::sqrt(2.0) * eps / (l2 * std::sqrt(l2))).epsilon(1e-9));
      // Circumcentre (½, ½, ε/2): R = √(½ + ε²/4), shortest edge 1 — a sliver has a good
      // radius–edge ratio, which is why the dihedral angles are reported too.
      CHECK(q.radius_edge(0) == doctest::Approx(std::sqrt(0.5 + eps * eps / 4)).epsilon(1e-9));
      CHECK(q.volume(0) == doctest::Approx(eps / 6.0).epsilon(1e-9));
    }
    const TetQuality q = one(Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0), Vec3(1, 1, 1e-3));
    const QualitySummary s = summarize_quality(q);
    CHECK(s.slivers == 1);
    CHECK(s.inverted == 0);
    CHECK(s.shape_hist.counts[0] == 1);
    CHECK(s.max_dihedral_hist.counts.back() == 1);
  }

  TEST_CASE("tet_quality: inverted and flat tets") {
    const TetQuality inv = one(Vec3(0, 0, 0), Vec3(0, 1, 0), Vec3(1, 0, 0), Vec3(0, 0, 1));
    CHECK(inv.volume(0) == doctest::Approx(-1.0 / 6.0).epsilon(1e-12));
    CHECK(inv.shape(0) == doctest::Approx(-4.0 / (3.0 * std::sqrt(3.0))).epsilon(1e-12));
    const QualitySummary s = summarize_quality(inv);
    CHECK(s.inverted == 1);
    const TetQuality flat = one(Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0), Vec3(1, 1, 0));
    CHECK(flat.volume(0) == 0.0);
    CHECK(flat.shape(0) == 0.0);
    CHECK(summarize_quality(flat).inverted == 1);  // volume ≤ 0
  }

  TEST_CASE("summarize_quality of a make_box mesh: Kuhn tets") {
    const Vec3i cells(4, 3, 5);
    const TetMesh m = build_tet_mesh(make_box(Vec3(0, 0, 0), Vec3(0.4, 0.3, 0.5), cells).vertices,
                                     make_box(Vec3(0, 0, 0), Vec3(0.4, 0.3, 0.5), cells).tets);
    const QualitySummary s = summarize_quality(m);
    const Index cubes = cells.prod();
    CHECK(s.cells == 6 * cubes);
    CHECK(s.faces == m.num_faces());
    CHECK(s.volume == doctest::Approx(0.06).epsilon(1e-12));
    // Every tet is the orthoscheme 0 → e_i → e_i + e_j → (1,1,1) of a cube: dihedral angles
    // 45, 45, 60, 90, 90, 90; R = √3/2 h, shortest edge h; edges h (×3), √2 h (×2), √3 h:
    // shape = 6√2 (h³/6) / (10/6)^{3/2} h³.
    CHECK(s.min_dihedral_deg == doctest::Approx(45.0).epsilon(1e-10));
    CHECK(s.max_dihedral_deg == doctest::Approx(90.0).epsilon(1e-10));
    CHECK(s.min_dihedral_p01 == doctest::Approx(45.0).epsilon(1e-10));
    CHECK(s.min_dihedral_p50 == doctest::Approx(45.0).epsilon(1e-10));
    CHECK(s.min_dihedral_away_deg == s.min_dihedral_deg);  // no provenance
    const double shape = std::sqrt(2.0) / std::pow(10.0 / 6.0, 1.5);
    CHECK(s.min_shape == doctest::Approx(shape).epsilon(1e-10));
    CHECK(s.shape_p50 == doctest::Approx(shape).epsilon(1e-10));
    CHECK(s.max_radius_edge == doctest::Approx(std::sqrt(3.0) / 2.0).epsilon(1e-10));
    CHECK(s.min_volume == doctest::Approx(0.001 / 6).epsilon(1e-10));
    CHECK(s.slivers == 0);
    CHECK(s.inverted == 0);
    // The 6 faces inside each cube have d_f = 0 up to rounding (co-spherical tets): each lands
    // in "≤ 0" or "tiny"; faces between cubes have d_f = h.
    CHECK(s.nonpositive_dual + s.tiny_dual == 6 * cubes);
    Index interior = 0;
    for (Index f = 0; f < m.num_faces(); ++f) interior += !m.is_boundary(f);
    CHECK(s.interior_faces == interior);
    CHECK(s.max_weight > 0.0);
    // Histograms count every cell / interior face once.
    CHECK(total(s.min_dihedral_hist) == s.cells);
    CHECK(total(s.max_dihedral_hist) == s.cells);
    CHECK(total(s.shape_hist) == s.cells);
    CHECK(total(s.relative_dual_hist) == s.interior_faces);
    // 45° sits on the edge between [40, 45) and [45, 50): rounding puts each cell in either.
    CHECK(s.min_dihedral_hist.counts[8] + s.min_dihedral_hist.counts[9] == s.cells);
    CHECK(s.max_dihedral_hist.counts[3] == s.cells);  // 90 is the first value of [90, 100)
    CHECK(s.relative_dual_hist.counts[0] == 6 * cubes);
  }

  TEST_CASE("summarize_quality: non-Delaunay pair gives a nonpositive dual and an inf weight") {
    // Tet 0: the right-corner tet (circumcentre (½,½,½), R = √3/2). Tet 1 below the face z = 0
    // with apex (½, ½, −h): for h = 0.2 the apex is inside tet 0's circumsphere, so
    // d_f = ½ − z_1 < 0 with z_1 = (½ − h²)/(2h) = 1.15; for h = 2, z_1 = −0.875, d_f = 1.375.
    for (const double h : {0.2, 2.0}) {
      CAPTURE(h);
      MatX3 x(5, 3);
      x << 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 0.5, 0.5, -h;
      MatX4i t(2, 4);
      t << 0, 1, 2, 3, 0, 2, 1, 4;
      const TetMesh m = build_tet_mesh(x, t);
      const double z1 = (0.5 - h * h) / (2 * h);
      const double d = 0.5 - z1;
      const FaceQuality fq = face_quality(m);
      const QualitySummary s = summarize_quality(m);
      CHECK(s.interior_faces == 1);
      for (Index f = 0; f < m.num_faces(); ++f) {
        if (m.is_boundary(f)) {
          CHECK(fq.weight(f) == 0.0);
          continue;
        }
        CHECK(fq.dual_length(f) == doctest::Approx(d).epsilon(1e-12));
        // Face (0,1,2): edges 1, 1, √2.
        CHECK(fq.relative_dual(f) ==
              doctest::Approx(d / ((2 + std::sqrt(2.0)) / 3)).epsilon(1e-12));
        if (d > 0) {
          CHECK(fq.weight(f) == doctest::Approx(0.5 / d).epsilon(1e-12));
        } else {
          CHECK(std::isinf(fq.weight(f)));
        }
      }
      CHECK(s.nonpositive_dual == (d <= 0 ? 1 : 0));
      CHECK(s.tiny_dual == 0);
      CHECK(s.max_weight ==
            (d > 0 ? doctest::Approx(0.5 / d).epsilon(1e-12) : doctest::Approx(0.0)));
    }
  }

  TEST_CASE("summarize_quality: min dihedral away from solids skips cells touching a body") {
    const VolumeMesh v = make_box(Vec3(0, 0, 0), Vec3(1, 1, 1), Vec3i(3, 3, 3));
    MatX3 x = v.vertices;
    x(0, 2) += 0.2;  // bend the corner cells: their angles drop below 45°
    TetMesh m = build_tet_mesh(x, v.tets);
    const TetQuality q = tet_quality(m.vertices, m.tets);
    CHECK(summarize_quality(m).min_dihedral_away_deg == summarize_quality(m).min_dihedral_deg);
    m.vertex_body(0) = 0;  // vertex 0 is on a solid
    const QualitySummary s = summarize_quality(m);
    double away = 1e300;
    for (Index t = 0; t < m.num_tets(); ++t) {
      if ((m.tets.row(t).array() != 0).all()) away = std::min(away, q.min_dihedral_deg(t));
    }
    CHECK(s.min_dihedral_deg < 44.0);
    CHECK(s.min_dihedral_away_deg == away);
    CHECK(s.min_dihedral_away_deg > s.min_dihedral_deg);
  }

  TEST_CASE("percentiles by nearest rank") {
    TetQuality q;
    const Index n = 100;
    q.min_dihedral_deg = VecX::LinSpaced(n, 100.0, 1.0);  // 100, 99, ..., 1 (unsorted input)
    q.max_dihedral_deg = VecX::Constant(n, 100.0);
    q.radius_edge = VecX::Constant(n, 1.0);
    q.shape = VecX::LinSpaced(n, 0.01, 1.0);
    q.volume = VecX::Constant(n, 1.0);
    const QualitySummary s = summarize_quality(q);
    // Index round(p (n − 1)) of the sorted values 1..100.
    CHECK(s.min_dihedral_p01 == 2.0);
    CHECK(s.min_dihedral_p05 == 6.0);
    CHECK(s.min_dihedral_p50 == 51.0);
    CHECK(s.min_dihedral_deg == 1.0);
    CHECK(s.slivers == 4);  // 1, 2, 3, 4 < 5°
    CHECK(s.shape_p05 == doctest::Approx(0.06).epsilon(1e-12));
    CHECK(s.faces == 0);
    CHECK(total(s.relative_dual_hist) == 0);
  }

  TEST_CASE("histogram: equal bins with outliers in the end bins") {
    VecX v(8);
    v << -5.0, 0.0, 0.99, 1.0, 2.5, 3.999, 4.0, 100.0;
    const Histogram h = histogram(v, 0.0, 4.0, 4);
    REQUIRE(h.counts.size() == 4);
    CHECK(h.counts[0] == 3);  // −5 (below), 0, 0.99
    CHECK(h.counts[1] == 1);  // 1.0
    CHECK(h.counts[2] == 1);  // 2.5
    CHECK(h.counts[3] == 3);  // 3.999, 4 (upper end), 100 (above)
    CHECK(total(h) == 8);
  }

  TEST_CASE("format_quality_report: figures and text histograms") {
    const VolumeMesh v = make_box(Vec3(0, 0, 0), Vec3(1, 1, 1), Vec3i(2, 2, 2));
    const QualitySummary s = summarize_quality(build_tet_mesh(v.vertices, v.tets));
    const std::string r = format_quality_report(s);
    CHECK(r.find("48 cells") != std::string::npos);
    CHECK(r.find("45.000") != std::string::npos);  // min dihedral
    CHECK(r.find("slivers") != std::string::npos);
    CHECK(r.find("100.00%") != std::string::npos);  // every cell in one bin
    CHECK(r.find("##########") != std::string::npos);
    // 4 histograms: 18 + 12 + 10 + 10 bin lines.
    std::size_t bins = 0;
    for (std::size_t p = r.find("    ["); p != std::string::npos; p = r.find("    [", p + 1))
      ++bins;
    CHECK(bins == 50);
  }

  TEST_CASE("quality_columns: fixed order and q_ names") {
    const VolumeMesh v = make_box(Vec3(0, 0, 0), Vec3(1, 1, 1), Vec3i(2, 2, 2));
    const QualitySummary s = summarize_quality(build_tet_mesh(v.vertices, v.tets));
    const auto cols = quality_columns(s);
    REQUIRE(cols.size() == 21);
    std::set<std::string> names;
    for (const auto& [name, value] : cols) {
      CHECK(name.rfind("q_", 0) == 0);
      names.insert(name);
    }
    CHECK(names.size() == cols.size());
    CHECK(cols[0].first == "q_cells");
    CHECK(cols[0].second == 48.0);
    CHECK(cols[4].first == "q_min_dihedral_deg");
    CHECK(cols[4].second == doctest::Approx(45.0).epsilon(1e-10));
    CHECK(cols[15].first == "q_slivers");
    CHECK(cols[17].first == "q_nonpositive_dual");
    CHECK(cols.back().first == "q_median_weight");
  }

}  // TEST_SUITE
