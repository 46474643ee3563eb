#pragma once
/// @file grid.hpp
/// The regular-grid (MAC) discretisation of the fluid [HarlowWelch65], [Fedkiw01]: a
/// staggered grid over the fluid box, pressure at cell centres, the normal velocity u_f along
/// +e_a on every face of axis a; and the solids on it [Chentanez06, §3.4, last paragraph]:
///
///  - a cell whose centre lies inside a closed body surface is a solid cell (no fluid);
///  - a face whose centre-to-centre segment (from the cell centre to the face, for a face on
///    the box) crosses a body triangle is a Solid face: its velocity is prescribed as the
///    body's velocity at the crossing, e_a · Σ_k w_k v_k, w the barycentric weights of the
///    crossing on the triangle [GSLF05]. A face next to a solid cell is always crossed.
///    A sheet thinner than a cell still cuts every segment through it, so no fluid, smoke or
///    pressure passes it;
///  - every geometric query that reads a cell value at a point (advection, the pressure
///    samples of J) reads only cells whose centre the point sees without crossing a body
///    triangle (GridSolids::visible): a thin sheet separates its two sides.
///
/// Faces are numbered axis by axis: axis a has (n_a + 1) × n_b × n_c faces; face (i, j, k) of
/// axis 0 lies at x = lo_x + i h_x between cells (i − 1, j, k) and (i, j, k), and so on.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <vector>

#include "core/types.hpp"
#include "mesh/remesh.hpp"
#include "mesh/tet_mesh.hpp"

namespace tetfsi::fluid {

/// The grid: a box split into n[0] × n[1] × n[2] cells of size h[a] along axis a.
struct GridSpec {
  Vec3 lo = Vec3::Zero();
  std::array<Index, 3> n = {1, 1, 1};
  Vec3 h = Vec3::Ones();

  /// n cells per axis over [lo, hi]. @throws InputError if a count is < 1 or the box empty.
  static GridSpec from_cells(const Vec3& lo, const Vec3& hi, const std::array<Index, 3>& n);
  /// Cells of about `cell_size` (m): n_a = max(1, round(L_a / cell_size)), h_a = L_a / n_a.
  /// @throws InputError if cell_size ≤ 0 or not finite.
  static GridSpec from_cell_size(const Vec3& lo, const Vec3& hi, double cell_size);

  Index num_cells() const { return n[0] * n[1] * n[2]; }
  /// Faces of axis a, and the first global face index of axis a (face_offset(3) = #F).
  Index num_faces(int a) const {
    Index c = 1;
    for (int b = 0; b < 3; ++b) c *= n[b] + (b == a ? 1 : 0);
    return c;
  }
  Index face_offset(int a) const {
    Index o = 0;
    for (int b = 0; b < a; ++b) o += num_faces(b);
    return o;
  }
  Index num_faces() const { return face_offset(3); }
  double cell_volume() const { return h[0] * h[1] * h[2]; }
  double face_area(int a) const { return cell_volume() / h[a]; }
  Vec3 hi() const { return lo + Vec3(n[0] * h[0], n[1] * h[1], n[2] * h[2]); }

  Index cell(Index i, Index j, Index k) const { return i + n[0] * (j + n[1] * k); }
  std::array<Index, 3> cell_ijk(Index c) const {
    return {c % n[0], (c / n[0]) % n[1], c / (n[0] * n[1])};
  }
  Vec3 cell_centre(Index c) const { return cell_centre(cell_ijk(c)); }
  /// The centre of cell (i, j, k).
  Vec3 cell_centre(const std::array<Index, 3>& ijk) const {
    Vec3 x;
    for (int a = 0; a < 3; ++a) x[a] = lo[a] + (static_cast<double>(ijk[a]) + 0.5) * h[a];
    return x;
  }
  /// Face (i, j, k) of axis a: (i, j, k) are x, y, z indices, the a-th in [0, n_a].
  Index face(int a, Index i, Index j, Index k) const {
    const Index d0 = n[0] + (a == 0), d1 = n[1] + (a == 1);
    return face_offset(a) + i + d0 * (j + d1 * k);
  }
  /// Axis and (i, j, k) of a global face.
  int face_axis(Index f) const { return f < face_offset(1) ? 0 : (f < face_offset(2) ? 1 : 2); }
  std::array<Index, 3> face_ijk(Index f) const {
    const int a = face_axis(f);
    const Index l = f - face_offset(a);
    const Index d0 = n[0] + (a == 0), d1 = n[1] + (a == 1);
    return {l % d0, (l / d0) % d1, l / (d0 * d1)};
  }
  Vec3 face_centre(Index f) const { return face_centre(face_axis(f), face_ijk(f)); }
  /// The centre of face (i, j, k) of axis a.
  Vec3 face_centre(int a, const std::array<Index, 3>& ijk) const {
    Vec3 x;
    for (int b = 0; b < 3; ++b)
      x[b] = lo[b] + (static_cast<double>(ijk[b]) + (b == a ? 0.0 : 0.5)) * h[b];
    return x;
  }
  /// The cells on the two sides of face f: (below along the axis, above); −1 outside the box.
  std::array<Index, 2> face_cells(Index f) const {
    const int a = face_axis(f);
    auto ijk = face_ijk(f);
    const Index i = ijk[a];
    std::array<Index, 2> c{-1, -1};
    if (i > 0) {
      ijk[a] = i - 1;
      c[0] = cell(ijk[0], ijk[1], ijk[2]);
    }
    if (i < n[a]) {
      ijk[a] = i;
      c[1] = cell(ijk[0], ijk[1], ijk[2]);
    }
    return c;
  }
  /// The box side (0..5 = −x, +x, −y, +y, −z, +z) of a face on the box, −1 for inner faces.
  int face_side(Index f) const;
  /// The index along axis a of the cell layer holding coordinate v (clamped to the box).
  Index axis_index(int a, double v) const {
    return std::clamp<Index>(floor_index((v - lo[a]) / h[a]), 0, n[a] - 1);
  }
  /// The cell containing x (clamped to the box).
  Index cell_at(const Vec3& x) const {
    return cell(axis_index(0, x[0]), axis_index(1, x[1]), axis_index(2, x[2]));
  }
};

/// A triangle crossing: body, triangle of its surface, barycentric weights of the point.
struct SurfacePoint {
  Index body = -1;
  Index triangle = -1;
  Vec3 bary = Vec3::Zero();
};

/// The bodies' surfaces on the grid: their triangles bucketed by cell for segment queries.
class GridSolids {
 public:
  GridSolids() = default;
  /// @param surfaces closed, outward-oriented body surfaces (mesh::SolidSurface::body is the
  ///   body index used by SurfacePoint)
  GridSolids(const GridSpec& g, std::vector<mesh::SolidSurface> surfaces);

  const std::vector<mesh::SolidSurface>& surfaces() const { return m_surfaces; }
  /// The first triangle the segment a → b crosses (nearest to a), if any; `t` its fraction.
  bool first_crossing(const Vec3& a, const Vec3& b, SurfacePoint* hit = nullptr,
                      double* t = nullptr) const;
  /// No triangle between a and b.
  bool visible(const Vec3& a, const Vec3& b) const { return !first_crossing(a, b); }
  /// Whether a triangle's bucket is within one cell of cell c (else every query near c is
  /// trivially free).
  bool near(Index c) const { return !m_near.empty() && m_near[c] != 0; }
  /// No triangle's box reaches the cells within `reach` (0, 1 or 2) cells of cell c.
  bool clear(Index c, int reach) const {
    const std::vector<Index>& start = m_start[static_cast<size_t>(reach)];
    return start.empty() || start[c] == start[c + 1];
  }

  /// Many visibility queries from one point x: the triangles bucketed in the cells within
  /// `reach` (0, 1 or 2) cells of x's cell, each once (lists kept per cell), and each query
  /// tests only those. A query to a point outside that block falls back to first_crossing;
  /// either way the answer is visible(x, b)'s.
  class Probe {
   public:
    Probe(const GridSolids& solids, const Vec3& x, int reach);
    /// The same for queries that mostly end in the box [qlo, qhi] (which holds x): only the
    /// block's triangles whose box meets it are kept, and queries outside it fall back.
    Probe(const GridSolids& solids, const Vec3& x, int reach, const Vec3& qlo, const Vec3& qhi);
    bool visible(const Vec3& b) const;

   private:
    const GridSolids* m_solids;
    Vec3 m_x;
    Vec3 m_box_lo, m_box_hi;  ///< the block's box, unbounded where it reaches the grid's side
    /// Per kept list entry: the triangle (index into m_tris), its unit normal and x's signed
    /// distance to its plane.
    std::vector<Index> m_idx;
    std::vector<Eigen::Vector4d> m_side;
    /// The list entry that hid the last hidden query: tested first, as the next query that
    /// is hidden is most often hidden by the same triangle.
    mutable size_t m_last = 0;
  };

 private:
  /// A triangle as the segment test reads it: corner, edges, |e1| |e2|, bounding box.
  struct Packed {
    Vec3 p0, e1, e2, lo, hi;
    double e12 = 0;
    Index body = -1, tri = -1;
  };
  /// Whether signed plane distances da and db lie strictly on one side, both farther than
  /// the margin (then the segment cannot cross the plane's triangle).
  static bool one_side(double da, double db, double margin) {
    return ((da > margin) & (db > margin)) | ((da < -margin) & (db < -margin));
  }
  /// Whether a and b lie strictly on one side of triangle t's plane (one_side): a test that
  /// rejects before the box and crossing tests.
  bool one_side(Index t, const Vec3& a, const Vec3& b) const {
    const Eigen::Vector4d& P = m_planes[t];
    const double da = P[0] * a[0] + P[1] * a[1] + P[2] * a[2] - P[3];
    const double db = P[0] * b[0] + P[1] * b[1] + P[2] * b[2] - P[3];
    return one_side(da, db, m_margin);
  }
  /// Whether T's bounding box misses the box [lo, hi].
  static bool box_misses(const Packed& T, const Vec3& lo, const Vec3& hi) {
    return (hi.array() < T.lo.array()).any() || (lo.array() > T.hi.array()).any();
  }
  bool crosses(const Packed& T, const Vec3& a, const Vec3& d, double dn, double& s,
               Vec3& bary) const;

  GridSpec m_grid;
  std::vector<mesh::SolidSurface> m_surfaces;
  std::vector<Packed> m_tris;
  /// Per packed triangle its plane (unit normal, offset n·p0; 0 for a degenerate triangle),
  /// apart from m_tris so that the plane test, which rejects most, reads 32 bytes.
  std::vector<Eigen::Vector4d> m_planes;
  /// Per reach r = 0, 1, 2: the triangles whose box meets the cells within r cells of cell c
  /// are m_items[r][m_start[r][c] .. m_start[r][c + 1]) (indices into m_tris, ascending).
  std::array<std::vector<Index>, 3> m_start;
  std::array<std::vector<Index>, 3> m_items;
  std::vector<std::uint8_t> m_near;
  double m_margin = 0;  ///< bounding-box slack of the segment test (1e-9 of a cell)
};

/// The classification of the grid's cells and faces against the box patches and the solids.
struct GridCells {
  GridSpec grid;
  VecXi cell_body;  ///< #C: the body whose inside holds the cell centre, −1 for fluid cells
  std::vector<mesh::FaceKind> face_kind;  ///< #F: Interior, Wall, Inflow, Open or Solid
  VecXi face_patch;                       ///< #F: domain patch of a box face, −1 otherwise
  std::vector<SurfacePoint> face_solid;   ///< #F: the crossing of a Solid face (body −1: none)
  GridSolids solids;
  /// A free surface (grid/liquid.hpp; both empty without one): #C, 1 for an air cell (a
  /// non-solid cell outside the liquid: p = 0, no unknown), and the liquid's level set φ at
  /// the cell centres (m, < 0 in the liquid) that places the surface between them.
  std::vector<std::uint8_t> air;
  VecX phi;
  /// #C or empty: the net outflow (m³/s) the projection gives each fluid cell instead of zero
  /// (liquid_volume_source, the liquid's density correction; 0 in every other cell).
  VecX volume_source;

  /// A cell with a pressure unknown: not inside a body, not air.
  bool fluid(Index c) const { return c >= 0 && cell_body[c] < 0 && (air.empty() || !air[c]); }
  /// Not inside a body (fluid or air).
  bool open_cell(Index c) const { return c >= 0 && cell_body[c] < 0; }
  bool air_cell(Index c) const { return c >= 0 && !air.empty() && air[c] != 0; }
  /// An Interior face between a fluid cell and an air cell: the free surface crosses it.
  bool surface_face(Index f) const {
    if (air.empty() || face_kind[f] != mesh::FaceKind::Interior) return false;
    const auto c = grid.face_cells(f);
    return air_cell(c[0]) != air_cell(c[1]);
  }
  /// An open (pressure-coupled) face between two fluid cells, or a box Open face.
  bool interior(Index f) const { return face_kind[f] == mesh::FaceKind::Interior; }
};

/// Classify: box faces by the domain's patches (later patches win), then the solids: cells
/// inside a body, faces crossed by a triangle or next to a solid cell → Solid.
/// @throws InputError naming the body if a body lies outside the box, or is smaller than a
///   cell on two axes (a grain or a rod the grid cannot resolve; a sheet is thin on one).
GridCells classify_grid(const GridSpec& g, const mesh::FluidDomain& domain,
                        std::vector<mesh::SolidSurface> surfaces);

}  // namespace tetfsi::fluid
