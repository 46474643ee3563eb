/// @file tet_mesh.cpp
/// TetMesh construction: unique oriented faces, incidence, neighbours and the geometry the
/// fluid reads (volumes, circumcentres, face areas/normals/centroids, dual lengths)
/// [KFCO06, §3], [Chentanez06, §3.3]. No CGAL here.
#include "mesh/tet_mesh.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <vector>

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <Eigen/Geometry>  // cross()

#include "core/error.hpp"
#include "core/log.hpp"
#include "core/parallel.hpp"
#include "mesh/geometry.hpp"

namespace tetfsi::mesh {

namespace {

/// Local faces of a positively oriented tet (0,1,2,3), each listed so that its right-hand
/// normal points out of the tet; face k is opposite vertex k (as in volume_mesh.cpp).
constexpr int kOutwardFace[4][3] = {{1, 2, 3}, {0, 3, 2}, {0, 1, 3}, {0, 2, 1}};

/// One slot of the face table: the sorted vertex triple and the first incidence 4 t + k that
/// brought the face (−1: empty slot; after the second incidence, −2 − (4 t + k)).
struct Slot {
  int a, b, c, inc;
};

/// Open-addressing (linear probing) table of faces keyed by sorted vertex triples (a < b < c),
/// power-of-two capacity, load kept at most 1/2. (A home slot grouped by the smallest vertex
/// was tried for cache locality: no faster on make_box, and pathological when the vertex
/// numbering is shuffled, since low indices are the smallest vertex of far more faces.)
class FaceTable {
 public:
  explicit FaceTable(std::size_t expected_faces) {
    std::size_t cap = 1024;
    while (cap < 2 * expected_faces) cap *= 2;
    m_slots.assign(cap, Slot{0, 0, 0, -1});
    m_mask = cap - 1;
  }
  /// The slot for (a, b, c) (sorted): the existing face or the empty slot to fill.
  Slot& find(int a, int b, int c) {
    std::size_t s = hash_triple(a, b, c) & m_mask;
    for (;;) {
      Slot& x = m_slots[s];
      if (x.inc == -1 || (x.a == a && x.b == b && x.c == c)) return x;
      s = (s + 1) & m_mask;
    }
  }
  /// Hint that (a, b, c) (sorted) will be looked up soon: the lookups are cache misses into
  /// a table of tens of MB, so build_tet_mesh prefetches a few tets ahead.
  void prefetch(int a, int b, int c) const {
    __builtin_prefetch(&m_slots[hash_triple(a, b, c) & m_mask]);
  }
  /// Call after filling an empty slot (grows the table when the load passes 1/2).
  void inserted() {
    if (2 * ++m_size > m_slots.size()) grow();
  }

 private:
  void grow() {
    std::vector<Slot> old(2 * m_slots.size(), Slot{0, 0, 0, -1});
    old.swap(m_slots);
    m_mask = m_slots.size() - 1;
    for (const Slot& x : old) {
      if (x.inc != -1) find(x.a, x.b, x.c) = x;
    }
  }
  std::vector<Slot> m_slots;
  std::size_t m_mask = 0;
  std::size_t m_size = 0;
};

/// Error path of build_tet_mesh: face (a, b, c) (sorted) met a third time at tet t.
[[noreturn]] void throw_shared_by_three(const TetMesh& m, int a, int b, int c, Index t) {
  std::vector<Index> sharing;
  for (Index u = 0; u <= t; ++u) {
    int in = 0;
    for (int k = 0; k < 4; ++k) in += m.tets(u, k) == a || m.tets(u, k) == b || m.tets(u, k) == c;
    if (in == 3) sharing.push_back(u);
  }
  throw MeshError(fmt::format(
      "build_tet_mesh: face (vertices {} {} {}) is shared by tets {}; a face may belong to at "
      "most two tets (non-manifold or overlapping mesh): remove the overlapping tets or remesh",
      a, b, c, fmt::join(sharing, ", ")));
}

}  // namespace

const char* to_string(FaceKind k) {
  return k_face_kind_names.name(k);
}

Vec3 circumcentre(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d) {
  // Relative to a: x = [|u|² (v × w) + |v|² (w × u) + |w|² (u × v)] / (2 u · (v × w)), the
  // solution of 2 [u v w]ᵀ x = (|u|², |v|², |w|²) by Cramer's rule (e.g. J. R. Shewchuk,
  // "Lecture notes on geometric robustness", 2013, §6).
  const Vec3 u = b - a, v = c - a, w = d - a;
  const Vec3 vw = v.cross(w), wu = w.cross(u), uv = u.cross(v);
  const double det2 = 2.0 * u.dot(vw);
  return a + (u.squaredNorm() * vw + v.squaredNorm() * wu + w.squaredNorm() * uv) / det2;
}

namespace {

/// What is wrong with tet t of m, if anything: a vertex index out of range (`vertex` its
/// slot) or a signed volume (`vol6`: six times it) that is not positive.
enum class TetFault { None, Index, Orientation };
TetFault tet_fault(const TetMesh& m, Index t, int& vertex, double& vol6) {
  const Index nv = m.num_vertices();
  const auto r = m.tets.row(t);
  for (int k = 0; k < 4; ++k)
    if (!(r(k) >= 0 && r(k) < nv)) {
      vertex = k;
      return TetFault::Index;
    }
  const Vec3 a = m.vertices.row(r(0));
  vol6 = (Vec3(m.vertices.row(r(1))) - a)
             .dot((Vec3(m.vertices.row(r(2))) - a).cross(Vec3(m.vertices.row(r(3))) - a));
  return vol6 > 0.0 ? TetFault::None : TetFault::Orientation;
}

/// The start of build_tet_mesh: the arrays moved in, indices in range and every tet
/// positively oriented (everything after relies on both).
TetMesh start_tet_mesh(MatX3 vertices, MatX4i tets) {
  TetMesh m;
  m.vertices = std::move(vertices);
  m.tets = std::move(tets);
  const Index nv = m.num_vertices();
  const Index nt = m.num_tets();

  TETFSI_REQUIRE(MeshError, nt < (1 << 29),
                 "build_tet_mesh: {} tets is more than the 2^29 the face table can index; use a "
                 "coarser mesh",
                 nt);
  // Indices in range and positive orientation first: everything below relies on both. The
  // chunks look in parallel; the first bad tet in index order is named.
  constexpr Index kGrain = 16384;
  std::vector<Index> first(static_cast<std::size_t>(num_chunks(nt, kGrain)), -1);
  parallel_for_chunks(nt, kGrain, [&](Index begin, Index end) {
    int vertex = 0;
    double vol6 = 0.0;
    for (Index t = begin; t < end && first[begin / kGrain] < 0; ++t)
      if (tet_fault(m, t, vertex, vol6) != TetFault::None) first[begin / kGrain] = t;
  });
  for (const Index t : first) {
    if (t < 0) continue;
    const auto r = m.tets.row(t);
    int k = 0;
    double vol6 = 0.0;
    const TetFault fault = tet_fault(m, t, k, vol6);
    TETFSI_REQUIRE(MeshError, fault != TetFault::Index,
                   "build_tet_mesh: tet {} (vertices {} {} {} {}) refers to vertex {} but the "
                   "mesh has {} vertices; fix the tet's vertex indices",
                   t, r(0), r(1), r(2), r(3), r(k), nv);
    TETFSI_REQUIRE(MeshError, fault != TetFault::Orientation,
                   "build_tet_mesh: tet {} (vertices {} {} {} {}) is not positively oriented "
                   "(signed volume {:.3g} m^3); swap two of its vertices or remesh",
                   t, r(0), r(1), r(2), r(3), vol6 / 6.0);
  }
  return m;
}

/// The end of build_tet_mesh, once tet_faces, tet_face_signs and neighbours are set for nf
/// faces: the face arrays (a face's stored order is its first tet's outward order), the
/// default tags and the geometry.
void finish_tet_mesh(TetMesh& m, int nf) {
  const Index nv = m.num_vertices();
  const Index nt = m.num_tets();
  m.faces.resize(nf, 3);
  m.face_tets.resize(nf, 2);
  constexpr Index kGrain = 16384;
  parallel_for_each(nt, kGrain, [&](Index t) {  // each face is written by its first tet only
    for (int k = 0; k < 4; ++k) {
      const Index f = m.tet_faces(t, k);
      if (m.tet_face_signs(t, k) > 0) {
        m.faces.row(f) << m.tets(t, kOutwardFace[k][0]), m.tets(t, kOutwardFace[k][1]),
            m.tets(t, kOutwardFace[k][2]);
        m.face_tets.row(f) << t, m.neighbours(t, k);
      }
    }
  });

  // Tags and provenance: everything on the boundary is a wall until the remesher says more.
  // Filled in parallel (a million cells' face arrays are first touched here: page faults).
  m.face_kind.resize(static_cast<std::size_t>(nf));
  m.face_patch.resize(nf);
  m.face_body.resize(nf);
  m.face_triangle.resize(nf);
  m.face_bary.resize(nf, 3);
  parallel_for_each(nf, kGrain, [&](Index f) {
    m.face_kind[static_cast<std::size_t>(f)] =
        m.face_tets(f, 1) < 0 ? FaceKind::Wall : FaceKind::Interior;
    m.face_patch(f) = m.face_body(f) = m.face_triangle(f) = -1;
    m.face_bary.row(f).setZero();
  });
  m.vertex_body.setConstant(nv, -1);
  m.vertex_triangle.setConstant(nv, -1);
  m.vertex_bary.setZero(nv, 3);

  update_geometry(m);
  logger().debug("build_tet_mesh: {} vertices, {} tets, {} faces", nv, nt, nf);
}

}  // namespace

TetMesh build_tet_mesh(MatX3 vertices, MatX4i tets) {
  TetMesh m = start_tet_mesh(std::move(vertices), std::move(tets));
  const Index nt = m.num_tets();
  // Unique faces in order of first appearance (tets in increasing index), so t1 < t2 and the
  // stored order is t1's outward order: n_f points out of t1 into t2, and outward on the
  // boundary. Pass 1 numbers the faces and links neighbours; pass 2 writes the face arrays.
  m.tet_faces.resize(nt, 4);
  m.tet_face_signs.resize(nt, 4);
  m.neighbours.resize(nt, 4);
  FaceTable table(2 * static_cast<std::size_t>(nt) + 64);
  int nf = 0;
  constexpr Index kAhead = 8;  // prefetch distance in tets: 0.37 -> 0.29 s at 1M tets
  for (Index t = 0; t < nt; ++t) {
    const int* r = m.tets.data() + 4 * static_cast<std::ptrdiff_t>(t);
    if (t + kAhead < nt) {
      const int* ra = r + 4 * kAhead;
      for (int k = 0; k < 4; ++k) {
        int a = ra[kOutwardFace[k][0]], b = ra[kOutwardFace[k][1]], c = ra[kOutwardFace[k][2]];
        sort3(a, b, c);
        table.prefetch(a, b, c);
      }
    }
    for (int k = 0; k < 4; ++k) {
      const int p = r[kOutwardFace[k][0]], q = r[kOutwardFace[k][1]], s = r[kOutwardFace[k][2]];
      int a = p, b = q, c = s;
      sort3(a, b, c);
      Slot& slot = table.find(a, b, c);
      if (slot.inc == -1) {
        slot = Slot{a, b, c, 4 * t + k};
        m.tet_faces(t, k) = nf++;
        m.tet_face_signs(t, k) = 1;
        m.neighbours(t, k) = -1;
        table.inserted();
        continue;
      }
      if (slot.inc <= -2) throw_shared_by_three(m, a, b, c, t);
      const Index t1 = slot.inc / 4;
      const int k1 = slot.inc % 4;
      // The second tet must see the face in the opposite order (it lies on the other side);
      // the same order means the two tets overlap on one side of the face.
      const int* r1 = m.tets.data() + 4 * static_cast<std::ptrdiff_t>(t1);
      const int g0 = r1[kOutwardFace[k1][0]], g1 = r1[kOutwardFace[k1][1]],
                g2 = r1[kOutwardFace[k1][2]];
      const int after_p = g0 == p ? g2 : (g1 == p ? g0 : g1);  // predecessor of p in (g0 g1 g2)
      TETFSI_REQUIRE(MeshError, after_p == q,
                     "build_tet_mesh: tets {} and {} lie on the same side of their common face "
                     "(vertices {} {} {}), so they overlap; remesh",
                     t1, t, a, b, c);
      slot.inc = -2 - slot.inc;
      m.tet_faces(t, k) = m.tet_faces(t1, k1);
      m.tet_face_signs(t, k) = -1;
      m.neighbours(t, k) = t1;
      m.neighbours(t1, k1) = t;
    }
  }
  finish_tet_mesh(m, nf);
  return m;
}

TetMesh build_tet_mesh(MatX3 vertices, MatX4i tets, const MatX4i& neighbours) {
  TetMesh m = start_tet_mesh(std::move(vertices), std::move(tets));
  const Index nt = m.num_tets();
  TETFSI_REQUIRE(MeshError, neighbours.rows() == nt,
                 "build_tet_mesh: {} neighbour rows for {} tets", neighbours.rows(), nt);
  // The faces numbered as the hash version numbers them: at (t, k) in increasing order, a
  // face is new unless its other tet u < t brought it.
  m.tet_faces.setConstant(nt, 4, -1);
  m.tet_face_signs.resize(nt, 4);
  m.neighbours = neighbours;
  int nf = 0;
  for (Index t = 0; t < nt; ++t) {
    for (int k = 0; k < 4; ++k) {
      const Index u = neighbours(t, k);
      TETFSI_REQUIRE(MeshError, u >= -1 && u < nt && u != t,
                     "build_tet_mesh: tet {} has neighbour {} across face {} ({} tets)", t, u, k,
                     nt);
      if (u >= 0 && u < t) {
        TETFSI_REQUIRE(MeshError, m.tet_faces(t, k) >= 0,
                       "build_tet_mesh: tet {} names tet {} across face {}, which does not name "
                       "it back",
                       t, u, k);
        continue;
      }
      m.tet_faces(t, k) = nf;
      m.tet_face_signs(t, k) = 1;
      if (u >= 0) {
        int j = 0;
        while (j < 4 && neighbours(u, j) != t) ++j;
        TETFSI_REQUIRE(MeshError, j < 4,
                       "build_tet_mesh: tet {} names tet {} across face {}, which does not name "
                       "it back",
                       t, u, k);
        // The face's three vertices are u's but its vertex j (a face shared, not a guess).
        bool shared = true;
        for (int i = 0; i < 3; ++i) {
          const int v = m.tets(t, kOutwardFace[k][i]);
          shared &= v != m.tets(u, j) && (m.tets(u, 0) == v || m.tets(u, 1) == v ||
                                          m.tets(u, 2) == v || m.tets(u, 3) == v);
        }
        TETFSI_REQUIRE(MeshError, shared,
                       "build_tet_mesh: tets {} and {} are named neighbours but do not share "
                       "face {} of tet {}",
                       t, u, k, t);
        m.tet_faces(u, j) = nf;
        m.tet_face_signs(u, j) = -1;
      }
      ++nf;
    }
  }
  finish_tet_mesh(m, nf);
  return m;
}

void update_geometry(TetMesh& m) {
  const Index nt = m.num_tets();
  const Index nf = m.num_faces();
  m.volumes.resize(nt);
  m.circumcentres.resize(nt, 3);
  // Per cell, then per face, in parallel: each item writes its own rows.
  parallel_for_each(nt, 4096, [&](Index t) {
    const auto r = m.tets.row(t);
    const Vec3 a = m.vertices.row(r(0)), b = m.vertices.row(r(1)), c = m.vertices.row(r(2)),
               d = m.vertices.row(r(3));
    const Vec3 u = b - a, v = c - a, w = d - a;
    const Vec3 vw = v.cross(w), wu = w.cross(u), uv = u.cross(v);
    const double vol6 = u.dot(vw);
    m.volumes(t) = vol6 / 6.0;
    m.circumcentres.row(t) =
        a + (u.squaredNorm() * vw + v.squaredNorm() * wu + w.squaredNorm() * uv) / (2.0 * vol6);
  });
  m.face_areas.resize(nf);
  m.face_normals.resize(nf, 3);
  m.face_centroids.resize(nf, 3);
  m.dual_lengths.resize(nf);
  parallel_for_each(nf, 4096, [&](Index f) {
    const auto r = m.faces.row(f);
    const Vec3 a = m.vertices.row(r(0)), b = m.vertices.row(r(1)), c = m.vertices.row(r(2));
    const Vec3 cr = (b - a).cross(c - a);
    const double twice_area = cr.norm();
    const Vec3 n = cr / twice_area;
    const Vec3 x = (a + b + c) / 3.0;
    m.face_areas(f) = 0.5 * twice_area;
    m.face_normals.row(f) = n;
    m.face_centroids.row(f) = x;
    const Vec3 c1 = m.circumcentres.row(m.face_tets(f, 0));
    const Index t2 = m.face_tets(f, 1);
    // d_f = (c_t2 − c_t1)·n_f inside, (x_f − c_t1)·n_f on the boundary [KFCO06, §3].
    m.dual_lengths(f) = t2 >= 0 ? (Vec3(m.circumcentres.row(t2)) - c1).dot(n) : (x - c1).dot(n);
  });
}

double total_volume(const TetMesh& m) {
  return m.volumes.sum();
}

Vec3 boundary_area_vector(const TetMesh& m) {
  Vec3 s = Vec3::Zero();
  for (Index f = 0; f < m.num_faces(); ++f) {
    if (m.is_boundary(f)) s += m.face_areas(f) * Vec3(m.face_normals.row(f));
  }
  return s;
}

VecXi cospherical_groups(const TetMesh& m, double rel_tol, Index* num_groups) {
  const Index nT = m.num_tets();
  std::vector<Index> parent(nT);
  for (Index t = 0; t < nT; ++t) parent[t] = t;
  auto find = [&](Index t) {
    while (parent[t] != t) t = parent[t] = parent[parent[t]];
    return t;
  };
  for (Index f = 0; f < m.num_faces(); ++f) {
    if (m.is_boundary(f)) continue;
    const Vec3 a = m.vertices.row(m.faces(f, 0)), b = m.vertices.row(m.faces(f, 1)),
               c = m.vertices.row(m.faces(f, 2));
    const double edge = ((b - a).norm() + (c - b).norm() + (a - c).norm()) / 3.0;
    if (!(std::abs(m.dual_lengths(f)) <= rel_tol * edge)) continue;
    const Index r1 = find(m.face_tets(f, 0)), r2 = find(m.face_tets(f, 1));
    if (r1 != r2) parent[std::max(r1, r2)] = std::min(r1, r2);
  }
  VecXi id = VecXi::Constant(nT, -1);
  Index n = 0;
  for (Index t = 0; t < nT; ++t) {
    const Index r = find(t);
    if (id(r) < 0) id(r) = n++;
    id(t) = id(r);
  }
  if (num_groups) *num_groups = n;
  return id;
}

void save_mesh(const TetMesh& m, CheckpointWriter& w, const std::string& prefix) {
  w.put(prefix + "vertices", m.vertices);
  w.put(prefix + "tets", m.tets);
  std::vector<std::uint8_t> kind(m.face_kind.size());
  for (size_t f = 0; f < kind.size(); ++f) kind[f] = static_cast<std::uint8_t>(m.face_kind[f]);
  w.put(prefix + "face_kind", kind);
  // Mostly −1 (the interior): only the other entries, as (index, value) pairs.
  auto put_tags = [&](const std::string& key, const VecXi& v) {
    std::vector<Index> at, value;
    for (Index i = 0; i < v.size(); ++i)
      if (v[i] != -1) at.push_back(i), value.push_back(v[i]);
    w.put(prefix + key + "/at", at);
    w.put(prefix + key + "/value", value);
  };
  put_tags("face_patch", m.face_patch);
  put_tags("face_body", m.face_body);
  put_tags("face_triangle", m.face_triangle);
  put_tags("vertex_body", m.vertex_body);
  put_tags("vertex_triangle", m.vertex_triangle);
  // The barycentric rows only where a body is named (build_tet_mesh zeroes the rest).
  auto rows_on_bodies = [](const MatX3& bary, const VecXi& body) {
    MatX3 out((body.array() >= 0).count(), 3);
    Index k = 0;
    for (Index i = 0; i < body.size(); ++i)
      if (body[i] >= 0) out.row(k++) = bary.row(i);
    return out;
  };
  w.put(prefix + "face_bary", rows_on_bodies(m.face_bary, m.face_body));
  w.put(prefix + "vertex_bary", rows_on_bodies(m.vertex_bary, m.vertex_body));
}

TetMesh load_mesh(const CheckpointReader& r, const std::string& prefix) {
  TetMesh m;
  try {
    m = build_tet_mesh(r.get<MatX3>(prefix + "vertices"), r.get<MatX4i>(prefix + "tets"));
  } catch (const CheckpointError&) {
    throw;
  } catch (const Error& e) {
    r.fail(fmt::format("its mesh '{}' is invalid: {}", prefix, e.what()));
  }
  auto sized = [&](const std::string& key, Index got, Index want) {
    if (got != want)
      r.fail(fmt::format("record '{}{}' has {} rows for {}", prefix, key, got, want));
  };
  const std::vector<std::uint8_t> kind = r.get_vector<std::uint8_t>(prefix + "face_kind");
  sized("face_kind", static_cast<Index>(kind.size()), m.num_faces());
  for (size_t f = 0; f < kind.size(); ++f) {
    if (kind[f] > static_cast<std::uint8_t>(FaceKind::Solid))
      r.fail(fmt::format("record '{}face_kind' has kind {} at face {}", prefix, kind[f], f));
    m.face_kind[f] = static_cast<FaceKind>(kind[f]);
  }
  auto get_tags = [&](const std::string& key, Index n) {
    const std::vector<Index> at = r.get_vector<Index>(prefix + key + "/at");
    const std::vector<Index> value = r.get_vector<Index>(prefix + key + "/value");
    sized(key + "/value", static_cast<Index>(value.size()), static_cast<Index>(at.size()));
    VecXi v = VecXi::Constant(n, -1);
    for (size_t k = 0; k < at.size(); ++k) {
      if (at[k] < 0 || at[k] >= n)
        r.fail(fmt::format("record '{}{}/at' names entry {} of {}", prefix, key, at[k], n));
      v[at[k]] = value[k];
    }
    return v;
  };
  m.face_patch = get_tags("face_patch", m.num_faces());
  m.face_body = get_tags("face_body", m.num_faces());
  m.face_triangle = get_tags("face_triangle", m.num_faces());
  m.vertex_body = get_tags("vertex_body", m.num_vertices());
  m.vertex_triangle = get_tags("vertex_triangle", m.num_vertices());
  auto scatter = [&](const std::string& key, const VecXi& body, MatX3& bary) {
    const MatX3 rows = r.get<MatX3>(prefix + key);
    sized(key, static_cast<Index>(rows.rows()), static_cast<Index>((body.array() >= 0).count()));
    Index k = 0;
    for (Index i = 0; i < body.size(); ++i)
      if (body[i] >= 0) bary.row(i) = rows.row(k++);
  };
  scatter("face_bary", m.face_body, m.face_bary);
  scatter("vertex_bary", m.vertex_body, m.vertex_bary);
  return m;
}

}  // namespace tetfsi::mesh
