/// @file volume_mesh.cpp
/// Geometric checks and small repairs of tet and triangle meshes (no CGAL here).
#include "mesh/volume_mesh.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "core/error.hpp"
#include "core/log.hpp"

namespace tetfsi::mesh {

namespace {

/// Local faces of a positively oriented tet (0,1,2,3), each listed so that its right-hand
/// normal points out of the tet; face f is opposite vertex f.
constexpr int kOutwardFace[4][3] = {{1, 2, 3}, {0, 3, 2}, {0, 1, 3}, {0, 2, 1}};

/// The id to print for vertex v / tet t: the file's id when known, else the index.
long long vertex_label(const MeshLabels* labels, Index v) {
  if (labels && v >= 0 && static_cast<std::size_t>(v) < labels->vertex_ids.size()) {
    return labels->vertex_ids[static_cast<std::size_t>(v)];
  }
  return v;
}

/// "tet 17 (vertices 3 9 12 40)" or, with file labels, "element 18 (nodes 4 10 13 41)".
std::string describe_tet(const VolumeMesh& m, Index t, const MeshLabels* labels) {
  const bool file_ids = labels && !labels->tet_ids.empty();
  const bool file_nodes = labels && !labels->vertex_ids.empty();
  const long long tid = file_ids && static_cast<std::size_t>(t) < labels->tet_ids.size()
                            ? labels->tet_ids[static_cast<std::size_t>(t)]
                            : t;
  const auto r = m.tets.row(t);
  return fmt::format("{} {} ({} {} {} {} {})", file_ids ? "element" : "tet", tid,
                     file_nodes ? "nodes" : "vertices", vertex_label(labels, r(0)),
                     vertex_label(labels, r(1)), vertex_label(labels, r(2)),
                     vertex_label(labels, r(3)));
}

/// Mean of the six edge lengths of tet (a, b, c, d).
double mean_edge(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d) {
  return ((b - a).norm() + (c - a).norm() + (d - a).norm() + (c - b).norm() + (d - b).norm() +
          (d - c).norm()) /
         6.0;
}

bool indices_in_range(const VolumeMesh& m) {
  const Index nv = m.num_vertices();
  for (Index t = 0; t < m.num_tets(); ++t) {
    for (int k = 0; k < 4; ++k) {
      const Index v = m.tets(t, k);
      if (v < 0 || v >= nv) return false;
    }
  }
  return true;
}

void validate_impl(const VolumeMesh& m, const std::string& source, const MeshLabels* labels) {
  const Index nv = m.num_vertices();
  const Index nt = m.num_tets();
  TETFSI_REQUIRE(MeshError, nt > 0,
                 "{}: the mesh has no tetrahedra ({} vertices); give a file with tet "
                 "elements (Gmsh type 4, VTK_TETRA)",
                 source, nv);
  for (Index v = 0; v < nv; ++v) {
    const auto p = m.vertices.row(v);
    TETFSI_REQUIRE(MeshError, p.allFinite(),
                   "{}: vertex {} has a non-finite coordinate ({} {} {}); fix the file", source,
                   vertex_label(labels, v), p(0), p(1), p(2));
  }
  Index num_inverted = 0;
  Index first_inverted = -1;
  double first_inverted_volume = 0.0;
  for (Index t = 0; t < nt; ++t) {
    const auto r = m.tets.row(t);
    for (int k = 0; k < 4; ++k) {
      TETFSI_REQUIRE(MeshError, r(k) >= 0 && r(k) < nv,
                     "{}: tet {} refers to vertex index {} but the mesh has {} vertices "
                     "(zero-based 0..{}); fix the element's vertex indices",
                     source, t, r(k), nv, nv - 1);
    }
    for (int a = 0; a < 4; ++a) {
      for (int b = a + 1; b < 4; ++b) {
        TETFSI_REQUIRE(MeshError, r(a) != r(b),
                       "{}: {} uses a vertex twice; remove the collapsed element or remesh", source,
                       describe_tet(m, t, labels));
      }
    }
    const Vec3 p0 = m.vertices.row(r(0)), p1 = m.vertices.row(r(1)), p2 = m.vertices.row(r(2)),
               p3 = m.vertices.row(r(3));
    const double vol = signed_volume(p0, p1, p2, p3);
    const double h = mean_edge(p0, p1, p2, p3);
    const double vmin = 1e-12 * h * h * h;
    TETFSI_REQUIRE(MeshError, std::abs(vol) > vmin,
                   "{}: {} is degenerate (signed volume {:.3g} m^3, below 1e-12 * mean edge^3 "
                   "= {:.3g} m^3); remove the flat element or remesh",
                   source, describe_tet(m, t, labels), vol, vmin);
    if (vol < 0.0) {
      if (num_inverted == 0) {
        first_inverted = t;
        first_inverted_volume = vol;
      }
      ++num_inverted;
    }
  }
  if (num_inverted > 0) {
    const std::string more =
        num_inverted > 1 ? fmt::format(" ({} of {} tets are inverted)", num_inverted, nt) : "";
    throw MeshError(fmt::format(
        "{}: {} is inverted (signed volume {:.3g} m^3){}; fix the element's vertex order or "
        "remesh",
        source, describe_tet(m, first_inverted, labels), first_inverted_volume, more));
  }
}

/// 64-bit hash of a sorted vertex triple (splitmix64 finaliser over a packed key).
std::uint64_t hash_triple(int a, int b, int c) {
  std::uint64_t x = static_cast<std::uint64_t>(static_cast<std::uint32_t>(a));
  x = x * 0x9E3779B97F4A7C15ULL ^ static_cast<std::uint32_t>(b);
  x = x * 0x9E3779B97F4A7C15ULL ^ static_cast<std::uint32_t>(c);
  x ^= x >> 30;
  x *= 0xBF58476D1CE4E5B9ULL;
  x ^= x >> 27;
  x *= 0x94D049BB133111EBULL;
  x ^= x >> 31;
  return x;
}

}  // namespace

double tet_volume(const VolumeMesh& m, Index t) {
  const auto r = m.tets.row(t);
  return signed_volume(m.vertices.row(r(0)), m.vertices.row(r(1)), m.vertices.row(r(2)),
                       m.vertices.row(r(3)));
}

double total_volume(const VolumeMesh& m) {
  double sum = 0.0;
  for (Index t = 0; t < m.num_tets(); ++t) sum += tet_volume(m, t);
  return sum;
}

void validate_volume_mesh(const VolumeMesh& m, const std::string& source) {
  validate_impl(m, source, nullptr);
}

void validate_volume_mesh(const VolumeMesh& m, const std::string& source,
                          const MeshLabels& labels) {
  validate_impl(m, source, &labels);
}

bool fix_global_orientation(VolumeMesh& m) {
  if (m.num_tets() == 0 || !indices_in_range(m)) return false;
  Index num_positive = 0, num_negative = 0;
  for (Index t = 0; t < m.num_tets(); ++t) {
    const double v = tet_volume(m, t);
    num_positive += v > 0.0;
    num_negative += v < 0.0;
  }
  if (num_positive > 0 || num_negative == 0) return false;
  m.tets.col(2).swap(m.tets.col(3));
  logger().info("mesh: all {} tets were negatively oriented; swapped two vertices of each",
                m.num_tets());
  return true;
}

Index remove_unused_vertices(VolumeMesh& m, VecXi* old_index) {
  const Index nv = m.num_vertices();
  if (!indices_in_range(m)) {
    if (old_index) *old_index = VecXi::LinSpaced(nv, 0, nv - 1);
    return 0;
  }
  std::vector<Index> new_index(static_cast<std::size_t>(nv), -1);
  for (Index t = 0; t < m.num_tets(); ++t) {
    for (int k = 0; k < 4; ++k) new_index[static_cast<std::size_t>(m.tets(t, k))] = 0;
  }
  Index kept = 0;
  for (auto& n : new_index) {
    if (n == 0) n = kept++;
  }
  if (old_index) old_index->resize(kept);
  if (kept == nv) {
    if (old_index) *old_index = VecXi::LinSpaced(nv, 0, nv - 1);
    return 0;
  }
  MatX3 vertices(kept, 3);
  for (Index v = 0; v < nv; ++v) {
    const Index n = new_index[static_cast<std::size_t>(v)];
    if (n < 0) continue;
    vertices.row(n) = m.vertices.row(v);
    if (old_index) (*old_index)(n) = v;
  }
  for (Index t = 0; t < m.num_tets(); ++t) {
    for (int k = 0; k < 4; ++k) m.tets(t, k) = new_index[static_cast<std::size_t>(m.tets(t, k))];
  }
  m.vertices = std::move(vertices);
  return nv - kept;
}

MatX3i boundary_triangles(const VolumeMesh& m, VecXi* owner_tet) {
  const Index nt = m.num_tets();
  const std::size_t num_faces = 4 * static_cast<std::size_t>(nt);
  // Open-addressing hash table keyed by the sorted vertex triple; a slot stores the first
  // face (4 t + f) that hashed there and how many tets share it.
  std::size_t capacity = 16;
  while (capacity < 2 * num_faces) capacity *= 2;
  const std::size_t mask = capacity - 1;
  std::vector<std::array<int, 3>> key(num_faces);
  std::vector<int> slot_face(capacity, -1);
  std::vector<std::uint8_t> slot_count(capacity, 0);
  std::vector<std::uint32_t> face_slot(num_faces);
  TETFSI_CHECK(indices_in_range(m),
               "boundary_triangles needs tet indices in 0..{} (call "
               "validate_volume_mesh first)",
               m.num_vertices() - 1);
  for (Index t = 0; t < nt; ++t) {
    for (int f = 0; f < 4; ++f) {
      const std::size_t id = 4 * static_cast<std::size_t>(t) + static_cast<std::size_t>(f);
      std::array<int, 3> k = {m.tets(t, kOutwardFace[f][0]), m.tets(t, kOutwardFace[f][1]),
                              m.tets(t, kOutwardFace[f][2])};
      std::sort(k.begin(), k.end());
      key[id] = k;
      std::size_t s = hash_triple(k[0], k[1], k[2]) & mask;
      while (slot_face[s] >= 0 && key[static_cast<std::size_t>(slot_face[s])] != k) {
        s = (s + 1) & mask;
      }
      if (slot_face[s] < 0) slot_face[s] = static_cast<int>(id);
      if (slot_count[s] == 2) {
        // Error path only: find the two earlier tets with this face for the message.
        std::vector<Index> sharing;
        for (std::size_t j = 0; j < id; ++j) {
          if (key[j] == k) sharing.push_back(static_cast<Index>(j / 4));
        }
        sharing.push_back(t);
        throw MeshError(fmt::format(
            "mesh: face (vertices {} {} {}) is shared by tets {}; a face may belong to at most "
            "two tets (non-manifold mesh): remove the overlapping tets or remesh",
            k[0], k[1], k[2], fmt::join(sharing, ", ")));
      }
      ++slot_count[s];
      face_slot[id] = static_cast<std::uint32_t>(s);
    }
  }
  std::size_t num_boundary = 0;
  for (std::size_t id = 0; id < num_faces; ++id) num_boundary += slot_count[face_slot[id]] == 1;
  MatX3i tris(static_cast<Index>(num_boundary), 3);
  if (owner_tet) owner_tet->resize(static_cast<Index>(num_boundary));
  Index b = 0;
  for (std::size_t id = 0; id < num_faces; ++id) {
    if (slot_count[face_slot[id]] != 1) continue;
    const Index t = static_cast<Index>(id / 4);
    const int f = static_cast<int>(id % 4);
    for (int k = 0; k < 3; ++k) tris(b, k) = m.tets(t, kOutwardFace[f][k]);
    if (owner_tet) (*owner_tet)(b) = t;
    ++b;
  }
  return tris;
}

void validate_closed_surface(const SurfaceMesh& s, const std::string& source) {
  const Index nv = s.num_vertices();
  const Index nf = s.num_triangles();
  TETFSI_REQUIRE(MeshError, nf > 0, "{}: the surface has no triangles; give a closed surface",
                 source);
  for (Index v = 0; v < nv; ++v) {
    const auto p = s.vertices.row(v);
    TETFSI_REQUIRE(MeshError, p.allFinite(),
                   "{}: vertex {} has a non-finite coordinate ({} {} {}); fix the file", source, v,
                   p(0), p(1), p(2));
  }
  double volume6 = 0.0;
  for (Index f = 0; f < nf; ++f) {
    const auto r = s.triangles.row(f);
    for (int k = 0; k < 3; ++k) {
      TETFSI_REQUIRE(MeshError, r(k) >= 0 && r(k) < nv,
                     "{}: triangle {} refers to vertex index {} but the surface has {} vertices "
                     "(zero-based 0..{}); fix the triangle's vertex indices",
                     source, f, r(k), nv, nv - 1);
    }
    const Vec3 a = s.vertices.row(r(0)), b = s.vertices.row(r(1)), c = s.vertices.row(r(2));
    const double twice_area = (b - a).cross(c - a).norm();
    const double longest = std::max({(b - a).norm(), (c - b).norm(), (a - c).norm()});
    TETFSI_REQUIRE(
        MeshError,
        r(0) != r(1) && r(1) != r(2) && r(2) != r(0) && twice_area > 1e-12 * longest * longest,
        "{}: triangle {} (vertices {} {} {}) is degenerate (area {:.3g} m^2); remove "
        "it and close the gap or remesh the surface",
        source, f, r(0), r(1), r(2), 0.5 * twice_area);
    volume6 += a.dot(b.cross(c));
  }
  // Directed edges a→b packed as a 64-bit key with the triangle that owns them, sorted.
  struct Edge {
    std::uint64_t key;
    Index tri;
  };
  auto pack = [](Index a, Index b) {
    return (static_cast<std::uint64_t>(static_cast<std::uint32_t>(a)) << 32) |
           static_cast<std::uint32_t>(b);
  };
  std::vector<Edge> edges;
  edges.reserve(3 * static_cast<std::size_t>(nf));
  for (Index f = 0; f < nf; ++f) {
    for (int k = 0; k < 3; ++k) {
      edges.push_back({pack(s.triangles(f, k), s.triangles(f, (k + 1) % 3)), f});
    }
  }
  std::sort(edges.begin(), edges.end(), [](const Edge& x, const Edge& y) {
    return x.key < y.key || (x.key == y.key && x.tri < y.tri);
  });
  auto find = [&](std::uint64_t k) {
    const auto it = std::lower_bound(edges.begin(), edges.end(), k,
                                     [](const Edge& e, std::uint64_t v) { return e.key < v; });
    return it != edges.end() && it->key == k ? it : edges.end();
  };
  // Report the first offending edge in triangle order.
  for (Index f = 0; f < nf; ++f) {
    for (int k = 0; k < 3; ++k) {
      const Index a = s.triangles(f, k), b = s.triangles(f, (k + 1) % 3);
      const auto same = find(pack(a, b));
      TETFSI_CHECK(same != edges.end(), "edge {} {} of triangle {} not in the edge list", a, b, f);
      if (same + 1 != edges.end() && (same + 1)->key == same->key) {
        const Index other = same->tri == f ? (same + 1)->tri : same->tri;
        const auto opposite = find(pack(b, a));
        if (opposite != edges.end()) {
          throw MeshError(fmt::format(
              "{}: edge ({} {}) is shared by more than two triangles (e.g. {}, {} and {}); the "
              "surface is non-manifold: separate the touching parts or remesh",
              source, a, b, f, other, opposite->tri));
        }
        throw MeshError(fmt::format(
            "{}: edge ({} {}) is used in the same direction by triangles {} and {}; the "
            "triangles are inconsistently oriented: reverse the vertex order of one of them",
            source, a, b, f, other));
      }
      const auto opposite = find(pack(b, a));
      if (opposite == edges.end()) {
        throw MeshError(fmt::format(
            "{}: edge ({} {}) belongs to only one triangle ({}); the surface is open (has a "
            "hole or a crack): close it before meshing",
            source, a, b, f));
      }
      if (opposite + 1 != edges.end() && (opposite + 1)->key == opposite->key) {
        throw MeshError(fmt::format(
            "{}: edge ({} {}) is shared by more than two triangles (e.g. {}, {} and {}); the "
            "surface is non-manifold: separate the touching parts or remesh",
            source, a, b, f, opposite->tri, (opposite + 1)->tri));
      }
    }
  }
  const double volume = volume6 / 6.0;
  const double scale = (s.vertices.colwise().maxCoeff() - s.vertices.colwise().minCoeff()).norm();
  TETFSI_REQUIRE(MeshError, volume > 1e-12 * scale * scale * scale,
                 "{}: the surface encloses non-positive volume ({:.3g} m^3); its normals point "
                 "inward: reverse the vertex order of every triangle",
                 source, volume);
}

}  // namespace tetfsi::mesh
