/// Tests of mesh/tet_mesh.cpp: faces, incidence, signs, neighbours, geometry and dual lengths
/// of TetMesh, as invariants over box meshes (plain and jittered) and hand-made cases.
#include <doctest/doctest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <random>
#include <set>
#include <string>
#include <utility>

#include "core/error.hpp"
#include "mesh/generate.hpp"
#include "mesh/io.hpp"
#include "mesh/tet_mesh.hpp"
#include "mesh/tetrahedralize.hpp"
#include "tests/test_util.hpp"

using tetfsi::test::message_of;
using namespace tetfsi;
using namespace tetfsi::mesh;

namespace {

/// make_box with its interior vertices moved by up to `amount` × cell size per axis (fixed
/// seed): every tet stays positive for amount ≤ 0.15, the outer box is unchanged, and the
/// mesh is no longer Delaunay or structured.
VolumeMesh jittered_box(const Vec3& lo, const Vec3& hi, const Vec3i& cells, double amount,
                        unsigned seed = 7) {
  VolumeMesh m = make_box(lo, hi, cells);
  const Vec3 h = (hi - lo).cwiseQuotient(cells.cast<double>());
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-amount, amount);
  for (Index v = 0; v < m.num_vertices(); ++v) {
    for (int a = 0; a < 3; ++a) {
      const double x = m.vertices(v, a);
      if (x > lo(a) + 1e-9 && x < hi(a) - 1e-9) m.vertices(v, a) = x + u(rng) * h(a);
    }
  }
  return m;
}

TetMesh build(const VolumeMesh& v) {
  return build_tet_mesh(v.vertices, v.tets);
}

/// The meshes every invariant is checked on.
std::vector<std::pair<std::string, TetMesh>> test_meshes() {
  std::vector<std::pair<std::string, TetMesh>> out;
  out.emplace_back("unit cube 1 cell",
                   build(make_box(Vec3(0, 0, 0), Vec3(1, 1, 1), Vec3i(1, 1, 1))));
  out.emplace_back("box 4x3x5",
                   build(make_box(Vec3(-0.3, 0.1, 2.0), Vec3(0.9, 0.35, 2.7), Vec3i(4, 3, 5))));
  out.emplace_back("jittered box 6x5x4",
                   build(jittered_box(Vec3(0, 0, 0), Vec3(1.2, 1.0, 0.8), Vec3i(6, 5, 4), 0.15)));
  return out;
}

}  // namespace

TEST_SUITE("unit") {
  TEST_CASE("build_tet_mesh: face count and Euler characteristic of a ball") {
    for (const auto& [name, m] : test_meshes()) {
      CAPTURE(name);
      Index boundary = 0;
      for (Index f = 0; f < m.num_faces(); ++f) boundary += m.is_boundary(f);
      // Every tet has 4 faces; interior faces are counted twice, boundary faces once.
      CHECK(2 * m.num_faces() == 4 * m.num_tets() + boundary);
      std::set<std::pair<int, int>> edges;
      for (Index t = 0; t < m.num_tets(); ++t) {
        for (int i = 0; i < 4; ++i) {
          for (int j = i + 1; j < 4; ++j) {
            edges.insert(std::minmax(m.tets(t, i), m.tets(t, j)));
          }
        }
      }
      // A tetrahedralised ball: V − E + F − T = 1.
      const long long euler = static_cast<long long>(m.num_vertices()) -
                              static_cast<long long>(edges.size()) + m.num_faces() - m.num_tets();
      CHECK(euler == 1);
      // Faces are unique as vertex sets.
      std::set<std::array<int, 3>> unique;
      for (Index f = 0; f < m.num_faces(); ++f) {
        std::array<int, 3> k = {m.faces(f, 0), m.faces(f, 1), m.faces(f, 2)};
        std::sort(k.begin(), k.end());
        unique.insert(k);
      }
      CHECK(static_cast<Index>(unique.size()) == m.num_faces());
    }
  }

  TEST_CASE("build_tet_mesh: incidence signs neighbours and tags are consistent") {
    for (const auto& [name, m] : test_meshes()) {
      CAPTURE(name);
      std::vector<int> uses(static_cast<std::size_t>(m.num_faces()), 0);
      for (Index t = 0; t < m.num_tets(); ++t) {
        for (int k = 0; k < 4; ++k) {
          const Index f = m.tet_faces(t, k);
          ++uses[static_cast<std::size_t>(f)];
          // Local face k is opposite local vertex k: the face's vertices are the other three.
          std::array<int, 3> fv = {m.faces(f, 0), m.faces(f, 1), m.faces(f, 2)};
          std::array<int, 3> tv{};
          for (int i = 0, j = 0; i < 4; ++i) {
            if (i != k) tv[static_cast<std::size_t>(j++)] = m.tets(t, i);
          }
          std::sort(fv.begin(), fv.end());
          std::sort(tv.begin(), tv.end());
          CHECK(fv == tv);
          // Sign +1 exactly when t is t1 (n_f points out of t).
          const int s = m.tet_face_signs(t, k);
          CHECK((s == 1 || s == -1));
          CHECK(m.face_tets(f, s > 0 ? 0 : 1) == t);
          // Neighbours are the other tet of the face, and symmetric.
          const Index nb = m.neighbours(t, k);
          CHECK(nb == m.face_tets(f, s > 0 ? 1 : 0));
          if (nb >= 0) {
            int back = 0;
            for (int j = 0; j < 4; ++j) back += m.neighbours(nb, j) == t;
            CHECK(back == 1);
            CHECK(m.tet_faces(nb, [&] {
              for (int j = 0; j < 4; ++j) {
                if (m.neighbours(nb, j) == t) return j;
              }
              return 0;
            }()) == f);
          }
        }
      }
      for (Index f = 0; f < m.num_faces(); ++f) {
        const bool boundary = m.is_boundary(f);
        CHECK(uses[static_cast<std::size_t>(f)] == (boundary ? 1 : 2));
        // Interior faces are oriented from the smaller tet index to the larger.
        if (!boundary) CHECK(m.face_tets(f, 0) < m.face_tets(f, 1));
        CHECK(m.face_kind[static_cast<std::size_t>(f)] ==
              (boundary ? FaceKind::Wall : FaceKind::Interior));
        CHECK(m.face_patch(f) == -1);
        CHECK(m.face_body(f) == -1);
        CHECK(m.face_triangle(f) == -1);
        CHECK(m.face_bary.row(f).isZero(0.0));
      }
      CHECK((m.vertex_body.array() == -1).all());
      CHECK((m.vertex_triangle.array() == -1).all());
      CHECK(m.vertex_bary.isZero(0.0));
    }
  }

  TEST_CASE("build_tet_mesh: cells are closed and the boundary normals point outward") {
    for (const auto& [name, m] : test_meshes()) {
      CAPTURE(name);
      for (Index t = 0; t < m.num_tets(); ++t) {
        Vec3 sum = Vec3::Zero();
        double area = 0.0;
        for (int k = 0; k < 4; ++k) {
          const Index f = m.tet_faces(t, k);
          sum += m.tet_face_signs(t, k) * m.face_areas(f) * Vec3(m.face_normals.row(f));
          area += m.face_areas(f);
          // s_tk n_f points away from the tet: from its centroid towards the face centroid.
          const Vec3 out = m.tet_face_signs(t, k) * Vec3(m.face_normals.row(f));
          CHECK(out.dot(Vec3(m.face_centroids.row(f)) - tet_centroid(m, t)) > 0.0);
        }
        // Σ_k s_tk A_f n_f = 0 for a closed cell (rounding ~1e-16 relative).
        CHECK(sum.norm() <= 1e-12 * area);
      }
      double boundary_area = 0.0;
      for (Index f = 0; f < m.num_faces(); ++f) {
        CHECK(m.face_normals.row(f).norm() == doctest::Approx(1.0).epsilon(1e-14));
        if (m.is_boundary(f)) boundary_area += m.face_areas(f);
      }
      CHECK(boundary_area_vector(m).norm() <= 1e-12 * boundary_area);
    }
  }

  TEST_CASE("build_tet_mesh: volumes sum to the box volume and are positive") {
    const Vec3 lo(-0.3, 0.1, 2.0), hi(0.9, 0.35, 2.7);
    const TetMesh a = build(make_box(lo, hi, Vec3i(4, 3, 5)));
    const TetMesh b = build(jittered_box(lo, hi, Vec3i(4, 3, 5), 0.15));
    const double box = (hi - lo).prod();
    CHECK(std::abs(total_volume(a) - box) <= 1e-12 * box);
    CHECK(std::abs(total_volume(b) - box) <= 1e-12 * box);
    CHECK(a.volumes.minCoeff() > 0.0);
    CHECK(b.volumes.minCoeff() > 0.0);
    // Box cells are split into 6 equal tets.
    CHECK(a.volumes.maxCoeff() == doctest::Approx(box / 360.0).epsilon(1e-12));
    CHECK(a.volumes.minCoeff() == doctest::Approx(box / 360.0).epsilon(1e-12));
  }

  TEST_CASE("build_tet_mesh: circumcentres are equidistant from the four vertices") {
    for (const auto& [name, m] : test_meshes()) {
      CAPTURE(name);
      for (Index t = 0; t < m.num_tets(); ++t) {
        const Vec3 c = m.circumcentres.row(t);
        const double r0 = (c - Vec3(m.vertices.row(m.tets(t, 0)))).norm();
        for (int k = 1; k < 4; ++k) {
          const double rk = (c - Vec3(m.vertices.row(m.tets(t, k)))).norm();
          CHECK(std::abs(rk - r0) <= 1e-12 * r0);
        }
      }
    }
    // The free function on a hand case: the corner tet of the unit cube lies on the cube's
    // circumsphere, centred at (1/2, 1/2, 1/2).
    const Vec3 c = circumcentre(Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0), Vec3(0, 0, 1));
    CHECK((c - Vec3(0.5, 0.5, 0.5)).norm() <= 1e-15);
    // Degenerate (coplanar) tet: not finite, as documented.
    const Vec3 flat = circumcentre(Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0), Vec3(1, 1, 0));
    CHECK_FALSE(flat.allFinite());
  }

  TEST_CASE(
      "build_tet_mesh: dual lengths follow the definition and are nonnegative on box meshes") {
    for (const auto& [name, m] : test_meshes()) {
      CAPTURE(name);
      for (Index f = 0; f < m.num_faces(); ++f) {
        const Vec3 n = m.face_normals.row(f);
        const Vec3 c1 = m.circumcentres.row(m.face_tets(f, 0));
        const double expected = m.is_boundary(f)
                                    ? (Vec3(m.face_centroids.row(f)) - c1).dot(n)
                                    : (Vec3(m.circumcentres.row(m.face_tets(f, 1))) - c1).dot(n);
        CHECK(m.dual_lengths(f) == doctest::Approx(expected).epsilon(1e-14));
      }
    }
    // The Kuhn split of cubes is Delaunay with every cube's tets sharing one circumsphere, so
    // d_f = 0 inside cubes and > 0 between them: check d_f ≥ −1e-12 h (rounding).
    const double h = 0.1;
    const TetMesh m = build(make_box(Vec3(0, 0, 0), Vec3(0.4, 0.3, 0.5), Vec3i(4, 3, 5)));
    Index zero = 0, positive = 0;
    for (Index f = 0; f < m.num_faces(); ++f) {
      CHECK(m.dual_lengths(f) >= -1e-12 * h);
      if (m.is_boundary(f)) {
        // Boundary faces: the circumcentre (the cube centre) is h/2 inside the wall.
        CHECK(m.dual_lengths(f) == doctest::Approx(h / 2).epsilon(1e-12));
      } else if (std::abs(m.dual_lengths(f)) <= 1e-12 * h) {
        ++zero;
      } else {
        // Between two cubes: the distance between their centres along the face normal.
        ++positive;
      }
    }
    CHECK(zero == 6 * 4 * 3 * 5);  // 6 faces inside each cube (Kuhn split)
    CHECK(positive > 0);
  }

  TEST_CASE("build_tet_mesh: a Delaunay mesh of a sphere has d_f >= 0 on every interior face") {
    // CGAL Mesh_3 without exudation (which would add weights) and without Lloyd keeps a plain
    // Delaunay triangulation, of which the mesh is a subset of cells: every interior face has
    // an empty circumsphere on both sides, so c_t2 is not behind c_t1 along n_f.
    const SurfaceMesh ico =
        read_surface_mesh(std::string(TETFSI_SOURCE_DIR) + "/data/meshes/icosphere.off");
    TetrahedralizeParams params;
    params.cell_size = 0.1;
    params.facet_distance = 0.01;
    params.exude = false;
    const VolumeMesh v = tetrahedralize_surface(ico, params, "icosphere.off");
    const TetMesh m = build_tet_mesh(v.vertices, v.tets);
    REQUIRE(m.num_tets() > 500);
    CHECK(total_volume(m) == doctest::Approx(total_volume(v)).epsilon(1e-13));
    double h = 0.0;  // mean edge length, for the rounding tolerance
    for (Index f = 0; f < m.num_faces(); ++f) {
      h += (Vec3(m.vertices.row(m.faces(f, 0))) - Vec3(m.vertices.row(m.faces(f, 1)))).norm();
    }
    h /= m.num_faces();
    Index interior = 0, positive = 0;
    for (Index f = 0; f < m.num_faces(); ++f) {
      if (m.is_boundary(f)) continue;
      ++interior;
      CHECK(m.dual_lengths(f) >= -1e-12 * h);
      positive += m.dual_lengths(f) > 1e-9 * h;
    }
    INFO(m.num_tets(), " tets, ", interior, " interior faces, ", positive, " with d_f > 0");
    // Unstructured: co-spherical ties are rare, nearly every face has a positive dual length.
    CHECK(positive >= interior * 9 / 10);
    for (Index t = 0; t < m.num_tets(); ++t) {
      Vec3 sum = Vec3::Zero();
      for (int k = 0; k < 4; ++k) {
        const Index f = m.tet_faces(t, k);
        sum += m.tet_face_signs(t, k) * m.face_areas(f) * Vec3(m.face_normals.row(f));
      }
      CHECK(sum.norm() <= 1e-12 * h * h);
    }
    std::set<std::pair<int, int>> edges;
    for (Index t = 0; t < m.num_tets(); ++t) {
      for (int i = 0; i < 4; ++i) {
        for (int j = i + 1; j < 4; ++j) edges.insert(std::minmax(m.tets(t, i), m.tets(t, j)));
      }
    }
    CHECK(static_cast<long long>(m.num_vertices()) - static_cast<long long>(edges.size()) +
              m.num_faces() - m.num_tets() ==
          1);
  }

  TEST_CASE("build_tet_mesh: discrete divergence of constant and linear fields is exact") {
    for (const auto& [name, m] : test_meshes()) {
      CAPTURE(name);
      // u(x) = U + A x; face values u_f = n_f · u(x_f) (centroid: exact for linear fields).
      const Vec3 U(0.3, -1.2, 0.7);
      Mat3 A;
      A << 0.5, -0.2, 0.1, 0.3, 1.5, -0.7, 0.2, 0.4, -0.9;
      VecX u_const(m.num_faces()), u_lin(m.num_faces());
      for (Index f = 0; f < m.num_faces(); ++f) {
        const Vec3 n = m.face_normals.row(f), x = m.face_centroids.row(f);
        u_const(f) = n.dot(U);
        u_lin(f) = n.dot(U + A * x);
      }
      double sum_vdiv = 0.0, scale = 0.0;
      for (Index t = 0; t < m.num_tets(); ++t) {
        double flux_c = 0.0, flux_l = 0.0, area = 0.0;
        for (int k = 0; k < 4; ++k) {
          const Index f = m.tet_faces(t, k);
          flux_c += m.tet_face_signs(t, k) * m.face_areas(f) * u_const(f);
          flux_l += m.tet_face_signs(t, k) * m.face_areas(f) * u_lin(f);
          area += m.face_areas(f);
        }
        // (D u)_t = (1/V_t) Σ_k s_tk A_f u_f: 0 for a constant field, tr(A) for a linear one.
        CHECK(std::abs(flux_c) <= 1e-12 * area * U.norm());
        const double div = flux_l / m.volumes(t);
        CHECK(div == doctest::Approx(A.trace()).epsilon(1e-9));
        sum_vdiv += flux_l;
        scale += area * (U.norm() + A.norm());
      }
      // Σ_t V_t (D u)_t telescopes to the boundary flux.
      double boundary_flux = 0.0;
      for (Index f = 0; f < m.num_faces(); ++f) {
        if (m.is_boundary(f)) boundary_flux += m.face_areas(f) * u_lin(f);
      }
      CHECK(std::abs(sum_vdiv - boundary_flux) <= 1e-12 * scale);
      CHECK(sum_vdiv == doctest::Approx(A.trace() * total_volume(m)).epsilon(1e-10));
    }
  }

  TEST_CASE("update_geometry after moving vertices equals a fresh build") {
    const VolumeMesh v = jittered_box(Vec3(0, 0, 0), Vec3(1, 1, 1), Vec3i(4, 4, 4), 0.1);
    TetMesh m = build(v);
    // A smooth map that keeps every tet positive: a shear plus a gentle bulge.
    MatX3 moved = v.vertices;
    for (Index i = 0; i < moved.rows(); ++i) {
      const Vec3 x = moved.row(i);
      moved.row(i) = Vec3(x.x() + 0.2 * x.y(), x.y() + 0.05 * std::sin(3 * x.z()),
                          1.1 * x.z() + 0.03 * x.x() * x.x());
    }
    m.vertices = moved;
    update_geometry(m);
    const TetMesh fresh = build_tet_mesh(moved, v.tets);
    CHECK(m.faces == fresh.faces);
    CHECK(m.face_tets == fresh.face_tets);
    CHECK(m.tet_faces == fresh.tet_faces);
    CHECK(m.tet_face_signs == fresh.tet_face_signs);
    CHECK(m.neighbours == fresh.neighbours);
    // Same arithmetic on the same data: identical to the last bit.
    CHECK(m.volumes == fresh.volumes);
    CHECK(m.circumcentres == fresh.circumcentres);
    CHECK(m.face_areas == fresh.face_areas);
    CHECK(m.face_normals == fresh.face_normals);
    CHECK(m.face_centroids == fresh.face_centroids);
    CHECK(m.dual_lengths == fresh.dual_lengths);
    // And it really moved (the map stretches z by about 1.1).
    CHECK(total_volume(m) > 1.05);
  }

  TEST_CASE("build_tet_mesh: a single tet") {
    MatX3 x(4, 3);
    x << 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1;
    MatX4i t(1, 4);
    t << 0, 1, 2, 3;
    const TetMesh m = build_tet_mesh(x, t);
    CHECK(m.num_faces() == 4);
    CHECK(m.volumes(0) == doctest::Approx(1.0 / 6.0).epsilon(1e-15));
    CHECK((m.neighbours.array() == -1).all());
    CHECK((m.tet_face_signs.array() == 1).all());
    // Face 0 is opposite vertex 0: the slanted face with area √3/2 and normal (1,1,1)/√3.
    CHECK(m.face_areas(m.tet_faces(0, 0)) == doctest::Approx(std::sqrt(3.0) / 2).epsilon(1e-15));
    CHECK((Vec3(m.face_normals.row(m.tet_faces(0, 0))) - Vec3(1, 1, 1) / std::sqrt(3.0)).norm() <=
          1e-15);
    // Face 3 (opposite vertex 3) lies in z = 0 with outward normal −z.
    CHECK((Vec3(m.face_normals.row(m.tet_faces(0, 3))) - Vec3(0, 0, -1)).norm() <= 1e-15);
    // Boundary dual length: circumcentre (½,½,½) is ½ inside the face z = 0.
    CHECK(m.dual_lengths(m.tet_faces(0, 3)) == doctest::Approx(0.5).epsilon(1e-15));
  }

  TEST_CASE("build_tet_mesh: an empty mesh") {
    const TetMesh m = build_tet_mesh(MatX3(0, 3), MatX4i(0, 4));
    CHECK(m.num_tets() == 0);
    CHECK(m.num_faces() == 0);
    CHECK(total_volume(m) == 0.0);
  }

  TEST_CASE("build_tet_mesh with the neighbours given is the hashed build, face numbers too") {
    auto meshes = test_meshes();
    // Vertices and tets shuffled, so that faces do not come in lattice order.
    VolumeMesh j = jittered_box(Vec3(0, 0, 0), Vec3(1, 1, 1), Vec3i(5, 4, 6), 0.1, 3);
    std::vector<Index> order(static_cast<std::size_t>(j.num_tets()));
    for (std::size_t i = 0; i < order.size(); ++i) order[i] = static_cast<Index>(i);
    std::shuffle(order.begin(), order.end(), std::mt19937(11));
    MatX4i shuffled(j.num_tets(), 4);
    for (Index t = 0; t < j.num_tets(); ++t) shuffled.row(t) = j.tets.row(order[t]);
    meshes.emplace_back("shuffled jittered box", build_tet_mesh(j.vertices, shuffled));
    for (const auto& [name, a] : meshes) {
      CAPTURE(name);
      const TetMesh b = build_tet_mesh(a.vertices, a.tets, a.neighbours);
      CHECK(b.tet_faces == a.tet_faces);
      CHECK(b.tet_face_signs == a.tet_face_signs);
      CHECK(b.neighbours == a.neighbours);
      CHECK(b.faces == a.faces);
      CHECK(b.face_tets == a.face_tets);
      CHECK(b.face_kind == a.face_kind);
      CHECK(b.dual_lengths == a.dual_lengths);
      CHECK(b.face_normals == a.face_normals);
    }
    // Neighbours that do not describe the tets are errors naming them.
    MatX3 x(5, 3);
    x << 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, -1;
    MatX4i t(2, 4);
    t << 0, 1, 2, 3, 0, 2, 1, 4;  // they share face (0 1 2), opposite vertex 3 and vertex 4
    MatX4i nb = MatX4i::Constant(2, 4, -1);
    nb(0, 3) = 1;
    nb(1, 3) = 0;
    CHECK_NOTHROW(build_tet_mesh(x, t, nb));
    MatX4i one_way = nb;
    one_way(1, 3) = -1;
    CHECK(message_of<MeshError>([&] {
            build_tet_mesh(x, t, one_way);
          }).find("tet 0 names tet 1 across face 3, which does not name it back") !=
          std::string::npos);
    MatX4i wrong_face = MatX4i::Constant(2, 4, -1);
    wrong_face(0, 0) = 1;
    wrong_face(1, 0) = 0;
    CHECK(message_of<MeshError>([&] {
            build_tet_mesh(x, t, wrong_face);
          }).find("do not share face 0 of tet 0") != std::string::npos);
    MatX4i out_of_range = nb;
    out_of_range(0, 1) = 7;
    CHECK(message_of<MeshError>([&] {
            build_tet_mesh(x, t, out_of_range);
          }).find("tet 0 has neighbour 7 across face 1") != std::string::npos);
  }

  TEST_CASE("build_tet_mesh: bad meshes are MeshErrors naming the culprit") {
    MatX3 x(6, 3);
    x << 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, -1, 0.2, 0.2, 1.5;
    SUBCASE("inverted tet") {
      MatX4i t(2, 4);
      t << 0, 1, 2, 3, 0, 1, 2, 4;  // the second lies below z = 0 with this order: negative
      const std::string msg = message_of<MeshError>([&] { build_tet_mesh(x, t); });
      CHECK(msg.find("tet 1 (vertices 0 1 2 4)") != std::string::npos);
      CHECK(msg.find("not positively oriented") != std::string::npos);
    }
    SUBCASE("flat tet") {
      MatX4i t(1, 4);
      t << 0, 1, 2, 2;
      CHECK(message_of<MeshError>([&] { build_tet_mesh(x, t); }).find("tet 0") !=
            std::string::npos);
    }
    SUBCASE("face shared by three tets") {
      MatX4i t(3, 4);
      t << 0, 1, 2, 3, 0, 2, 1, 4, 0, 1, 2, 5;  // above, below, above again
      const std::string msg = message_of<MeshError>([&] { build_tet_mesh(x, t); });
      CHECK(msg.find("face (vertices 0 1 2) is shared by tets 0, 1, 2") != std::string::npos);
    }
    SUBCASE("two tets on the same side of a face") {
      MatX4i t(2, 4);
      t << 0, 1, 2, 3, 0, 1, 2, 5;
      const std::string msg = message_of<MeshError>([&] { build_tet_mesh(x, t); });
      CHECK(msg.find("tets 0 and 1 lie on the same side") != std::string::npos);
    }
    SUBCASE("index out of range") {
      MatX4i t(1, 4);
      t << 0, 1, 2, 6;
      CHECK(message_of<MeshError>([&] { build_tet_mesh(x, t); }).find("refers to vertex 6") !=
            std::string::npos);
    }
  }

  TEST_CASE("to_string of FaceKind") {
    CHECK(std::string(to_string(FaceKind::Interior)) == "interior");
    CHECK(std::string(to_string(FaceKind::Wall)) == "wall");
    CHECK(std::string(to_string(FaceKind::Inflow)) == "inflow");
    CHECK(std::string(to_string(FaceKind::Open)) == "open");
    CHECK(std::string(to_string(FaceKind::Solid)) == "solid");
  }

}  // TEST_SUITE
