#include "fluid/grid/liquid.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <type_traits>

#include <Eigen/Geometry>

#include "core/error.hpp"
#include "core/parallel.hpp"
#include "mesh/tetrahedralize.hpp"

namespace tetfsi::fluid {

using mesh::FaceKind;

namespace {

constexpr Index kGrain = 2048;

/// The kernel of the weighted mean, (1 − s²)³ for s = |x − x_i| / R < 1 [ZhuBridson05].
double kernel(double s2) {
  const double t = 1.0 - s2;
  return t > 0 ? t * t * t : 0.0;
}

/// |x − x̄|, x̄ the kernel-weighted mean of the points `pts` within R of x (−1 if none).
template <class Points>
double distance_to_mean(const Vec3& x, const Points& pts, double R) {
  Vec3 mean = Vec3::Zero();
  double wsum = 0;
  for (const Vec3& p : pts) {
    const double w = kernel((x - p).squaredNorm() / (R * R));
    mean += w * p;
    wsum += w;
  }
  return wsum > 0 ? (x - mean / wsum).norm() : -1.0;
}

/// The kernel radius of φ: two cells (the largest edge) [ZhuBridson05]. Measured on the dam
/// break (a/h = 16): one cell lost 13 % of the volume by T = 4, two cells 1 %.
double kernel_radius(const GridSpec& g) {
  return 2.0 * g.h.maxCoeff();
}

/// The lattice point l (0 .. per_axis³ − 1) of cell c.
Vec3 lattice_point(const GridSpec& g, Index c, int per_axis, int l) {
  const auto ijk = g.cell_ijk(c);
  Vec3 x;
  int rest = l;
  for (int a = 0; a < 3; ++a) {
    const int i = rest % per_axis;
    rest /= per_axis;
    x[a] = g.lo[a] + (static_cast<double>(ijk[a]) + (i + 0.5) / per_axis) * g.h[a];
  }
  return x;
}

void append(LiquidParticles& lp, const std::vector<Vec3>& x, const std::vector<Vec3>& v) {
  const Index n0 = lp.size(), n = static_cast<Index>(x.size());
  lp.x.conservativeResize(n0 + n, 3);
  lp.v.conservativeResize(n0 + n, 3);
  for (Index i = 0; i < n; ++i) {
    lp.x.row(n0 + i) = x[i].transpose();
    lp.v.row(n0 + i) = v[i].transpose();
  }
}

/// The index range along axis a of the lattice points of axis-`face_axis` faces (n_a + 1
/// along face_axis), or of the cell centres (face_axis −1: n_a).
Index lattice_size(const GridSpec& g, int a, int face_axis) {
  return g.n[a] + (a == face_axis ? 1 : 0);
}

/// Along axis b, the two lattice indices around coordinate xb on the lattice of axis-a faces
/// (a = −1: the cell centres), clamped to the box, and their linear weights (1 − frac, frac).
struct AxisWeights {
  std::array<Index, 2> index{};
  std::array<double, 2> w{};
};
inline AxisWeights axis_weights(const GridSpec& g, int a, int b, double xb) {
  const double s = (xb - g.lo[b]) / g.h[b] - (b == a ? 0.0 : 0.5);
  const Index top = lattice_size(g, b, a) - 1;
  const double sc = std::clamp(s, 0.0, static_cast<double>(top));
  const Index base = std::min<Index>(floor_index(sc), std::max<Index>(top - 1, 0));
  const double frac = top > 0 ? sc - static_cast<double>(base) : 0.0;
  return {{base, std::min(base + 1, top)}, {1.0 - frac, frac}};
}

/// Whether one of cell c's six faces is a Solid face (a body's surface crosses it).
bool touches_body(const GridCells& gc, Index c) {
  const GridSpec& g = gc.grid;
  const auto ijk = g.cell_ijk(c);
  for (int a = 0; a < 3; ++a)
    for (int up = 0; up < 2; ++up) {
      std::array<Index, 3> f = ijk;
      f[a] += up;
      if (gc.face_kind[g.face(a, f[0], f[1], f[2])] == FaceKind::Solid) return true;
    }
  return false;
}

/// fn(ijk, w) for the 8 lattice points around the point whose per-axis weights are s and
/// their trilinear weights (corner order; w = ((1 · w_0) · w_1) · w_2).
template <class F>
void for_each_corner(const std::array<AxisWeights, 3>& s, F&& fn) {
  for (int corner = 0; corner < 8; ++corner) {
    std::array<Index, 3> ijk{};
    double w = 1;
    for (int b = 0; b < 3; ++b) {
      const int up = (corner >> b) & 1;
      ijk[b] = s[b].index[up];
      w *= s[b].w[up];
    }
    fn(ijk, w);
  }
}

/// Σ over the 8 lattice points around a point of w · value(i, j, k), w the trilinear weights
/// from its per-axis weights s (for_each_corner's, in its order). No branch on w = 0: a zero
/// weight adds a zero term (the sum starts at +0 and is never −0), so for finite values the
/// sum is the one that leaves those terms out.
template <class V>
double trilinear(const std::array<AxisWeights, 3>& s, V&& value) {
  double sum = 0;
  for (int corner = 0; corner < 8; ++corner) {
    const int u0 = corner & 1, u1 = (corner >> 1) & 1, u2 = corner >> 2;
    const double w = s[0].w[u0] * s[1].w[u1] * s[2].w[u2];
    sum += w * value(s[0].index[u0], s[1].index[u1], s[2].index[u2]);
  }
  return sum;
}

/// fn(ijk, w) for the 8 points of the lattice of axis-a faces (a = −1: the cell centres)
/// around x (clamped to the box) and their trilinear weights (corner order).
template <class F>
void for_each_lattice_weight(const GridSpec& g, int a, const Vec3& x, F&& fn) {
  for_each_corner(
      {axis_weights(g, a, 0, x[0]), axis_weights(g, a, 1, x[1]), axis_weights(g, a, 2, x[2])}, fn);
}

/// The particles that may touch each z-slab of `size` lattice indices, listed in particle
/// order per z lattice (t = 0: the z faces', 1: the cell centres', where the x and y faces
/// lie): a particle touches the z indices [sc − 2, sc + 1] at most (sc its clamped z lattice
/// coordinate), so it is listed for the one or two slabs those reach.
struct SlabLists {
  Index slabs = 0;
  std::array<std::vector<Index>, 2> start, items;
};
SlabLists slab_particles(const GridSpec& g, const MatX3& x, Index size) {
  SlabLists sl;
  sl.slabs = (g.n[2] + size) / size;  // covers the n_z + 1 z indices of the z faces
  const Index np = x.rows();
  std::vector<std::array<Index, 2>> reach(static_cast<size_t>(np));
  for (int t = 0; t < 2; ++t) {
    const double top = static_cast<double>(lattice_size(g, 2, t == 0 ? 2 : 0) - 1);
    const auto slab = [&](double z) {
      return std::clamp<Index>(floor_index(z / size), 0, sl.slabs - 1);
    };
    std::vector<Index>& start = sl.start[t];
    start.assign(static_cast<size_t>(sl.slabs) + 1, 0);
    for (Index p = 0; p < np; ++p) {
      const double sc = std::clamp((x(p, 2) - g.lo[2]) / g.h[2] - (t == 0 ? 0.0 : 0.5), 0.0, top);
      reach[p] = std::isfinite(sc) ? std::array<Index, 2>{slab(sc - 2), slab(sc + 1)}
                                   : std::array<Index, 2>{0, sl.slabs - 1};
      for (Index k = reach[p][0]; k <= reach[p][1]; ++k) ++start[k + 1];
    }
    for (Index k = 0; k < sl.slabs; ++k) start[k + 1] += start[k];
    sl.items[t].resize(static_cast<size_t>(start[sl.slabs]));
    std::vector<Index> fill(start.begin(), start.end() - 1);
    for (Index p = 0; p < np; ++p)
      for (Index k = reach[p][0]; k <= reach[p][1]; ++k) sl.items[t][fill[k]++] = p;
  }
  return sl;
}

}  // namespace

ParticleBuckets bucket_particles(const GridSpec& g, const MatX3& x) {
  const Index nc = g.num_cells(), np = x.rows();
  ParticleBuckets b;
  std::vector<Index> cell(static_cast<size_t>(np));
  parallel_for_each(np, 4 * kGrain, [&](Index p) { cell[p] = g.cell_at(x.row(p).transpose()); });
  // each cell's particles in increasing order, as the serial counting sort gave them
  group_by_key(
      np, nc, [&](Index p, auto&& emit) { emit(cell[p]); }, b.start, b.order);
  return b;
}

LiquidSurfaceParams liquid_surface_params(const GridSpec& g, int per_axis) {
  // A half-space of lattice particles below z = 0 (axis 2, the cell size h along it), read at
  // the cell centres h/2 below and above its boundary: r = mean of the two |x − x̄|, so that
  // φ(−h/2) = −φ(+h/2) and the linear zero is on the boundary.
  const double R = kernel_radius(g);
  const Vec3 s = g.h / per_axis;
  const int reach = static_cast<int>(std::ceil(R / s.minCoeff())) + 1;
  std::vector<Vec3> pts;
  for (int i = -reach; i < reach; ++i)
    for (int j = -reach; j < reach; ++j)
      for (int k = 1; k <= reach + 1; ++k)
        pts.emplace_back((i + 0.5) * s[0], (j + 0.5) * s[1], -(k - 0.5) * s[2]);
  // cell centres sit on lattice corners when per_axis is even, on points when it is odd
  const double off = per_axis % 2 == 0 ? 0.0 : 0.5;
  const Vec3 below(off * s[0], off * s[1], -0.5 * g.h[2]),
      above(off * s[0], off * s[1], 0.5 * g.h[2]);
  const double db = distance_to_mean(below, pts, R), da = distance_to_mean(above, pts, R);
  LiquidSurfaceParams sp;
  sp.radius = 0.5 * (db + da);
  sp.face_phi = 0.5 * (da - db);
  sp.per_axis = per_axis;
  return sp;
}

LiquidParticles seed_liquid(const GridCells& gc, const LiquidParams& p) {
  const GridSpec& g = gc.grid;
  const int m = p.particles_per_axis, per_cell = m * m * m;
  std::vector<Vec3> candidates;  // the lattice points of the cells outside the bodies
  for (Index c = 0; c < g.num_cells(); ++c) {
    if (!gc.open_cell(c)) continue;
    for (int l = 0; l < per_cell; ++l) candidates.push_back(lattice_point(g, c, m, l));
  }
  std::vector<char> taken(candidates.size(), 0);  // regions may overlap: seeded once
  std::vector<Vec3> x;
  for (const LiquidRegion& r : p.regions) {
    std::vector<char> in(candidates.size(), 0);
    for (std::size_t i = 0; i < candidates.size(); ++i) in[i] = r.contains(candidates[i]);
    if (r.surface) {
      const std::vector<char> inside =
          mesh::inside_surface(*r.surface, candidates, r.surface_file.string());
      for (std::size_t i = 0; i < candidates.size(); ++i) in[i] = in[i] && inside[i];
    }
    const std::size_t before = x.size();
    for (std::size_t i = 0; i < candidates.size(); ++i) {
      if (!in[i] || taken[i]) continue;
      taken[i] = 1;
      x.push_back(candidates[i]);
    }
    TETFSI_REQUIRE(InputError, x.size() > before,
                   "fluid.liquid.regions '{}' holds no grid cell outside the bodies: move it "
                   "into fluid.domain or make it at least a cell across",
                   r.name);
  }
  LiquidParticles lp;
  append(lp, x, std::vector<Vec3>(x.size(), Vec3::Zero()));
  return lp;
}

Index emit_liquid(const GridCells& gc, const LiquidParams& p, double t, LiquidParticles& lp) {
  const GridSpec& g = gc.grid;
  const int m = p.particles_per_axis, per_cell = m * m * m;
  Index added = 0;
  for (const LiquidSource& s : p.sources) {
    if (t < s.start || t > s.stop) continue;
    const auto inside = [&](const Vec3& x) {
      return (x.array() >= s.lo.array()).all() && (x.array() <= s.hi.array()).all();
    };
    for (Index i = 0; i < lp.size(); ++i)
      if (inside(lp.x.row(i).transpose())) lp.v.row(i) = s.velocity.transpose();
    const ParticleBuckets b = bucket_particles(g, lp.x);
    std::vector<Vec3> x;
    for (Index c = 0; c < g.num_cells(); ++c) {
      if (!gc.open_cell(c) || !inside(g.cell_centre(c))) continue;
      if (2 * (b.start[c + 1] - b.start[c]) >= per_cell) continue;
      for (int l = 0; l < per_cell; ++l) x.push_back(lattice_point(g, c, m, l));
    }
    append(lp, x, std::vector<Vec3>(x.size(), s.velocity));
    added += static_cast<Index>(x.size());
  }
  return added;
}

namespace {

/// Per cell, the sum of `count` over its block within `reach` along each axis (clipped to
/// the grid): running sums along each axis, one after another. T must hold the block's sum
/// (an unsigned T: its running sums may wrap in between, the window's sum is exact). Along x
/// a line at a time; along y and z a whole row (or plane part) at a time, the running sum
/// kept per x (contiguous, vectorised).
template <class T>
std::vector<T> block_counts(const GridSpec& g, std::vector<T> count,
                            const std::array<Index, 3>& reach) {
  static_assert(std::is_unsigned_v<T>);
  std::vector<T> next(count.size());
  const Index nx = g.n[0], ny = g.n[1], nz = g.n[2], plane = nx * ny;
  parallel_for_each(ny * nz, 64, [&](Index line) {  // the x-lines, each contiguous
    const Index first = line * nx;
    unsigned s = 0;  // over the window [i − reach, i + reach] ∩ [0, nx)
    for (Index m = 0; m < std::min(nx, reach[0]); ++m) s += count[first + m];
    for (Index i = 0; i < nx; ++i) {
      if (const Index in = i + reach[0]; in < nx) s += count[first + in];
      if (const Index gone = i - reach[0] - 1; gone >= 0) s -= count[first + gone];
      next[first + i] = static_cast<T>(s);
    }
  });
  std::swap(count, next);
  // along axis a (1: y, 2: z) over `width` contiguous values from `base`, the lines of
  // length len at `stride`: one running sum per value
  const auto window = [&](int a, Index base, Index width, Index len, Index stride) {
    std::vector<T> s(static_cast<size_t>(width), T{0});
    for (Index m = 0; m < std::min(len, reach[a]); ++m)
      for (Index x = 0; x < width; ++x) s[x] += count[base + m * stride + x];
    for (Index i = 0; i < len; ++i) {
      if (const Index in = i + reach[a]; in < len)
        for (Index x = 0; x < width; ++x) s[x] += count[base + in * stride + x];
      if (const Index gone = i - reach[a] - 1; gone >= 0)
        for (Index x = 0; x < width; ++x) s[x] -= count[base + gone * stride + x];
      std::copy(s.begin(), s.end(), next.begin() + base + i * stride);
    }
  };
  parallel_for_each(nz, 1, [&](Index k) { window(1, k * plane, nx, ny, nx); });
  std::swap(count, next);
  constexpr Index kPart = 4096;  // values of a z-plane per task
  parallel_for_each(num_chunks(plane, kPart), 1, [&](Index part) {
    const Index base = part * kPart;
    window(2, base, std::min(kPart, plane - base), nz, plane);
  });
  std::swap(count, next);
  return count;
}

/// Whether `count` (of block_counts) covers every cell of cell c's block within `reach`,
/// clipped to the grid. A count of a whole block's cells does without c's indices.
inline bool whole_block(const GridSpec& g, Index c, Index count,
                        const std::array<Index, 3>& reach) {
  if (count == (2 * reach[0] + 1) * (2 * reach[1] + 1) * (2 * reach[2] + 1)) return true;
  const auto ijk = g.cell_ijk(c);
  Index size = 1;
  for (int a = 0; a < 3; ++a)
    size *= std::min(g.n[a] - 1, ijk[a] + reach[a]) - std::max<Index>(0, ijk[a] - reach[a]) + 1;
  return count == size;
}

/// The images of the particles that φ at a cell centre xc sums [ZhuBridson05]: each
/// particle itself (image 0) and, per axis with a wall within R of xc, its mirror in that
/// wall (a free-slip wall is a symmetry plane), in the order m = Σ_a im_a Π_{b<a} n_b.
struct ParticleImages {
  int count = 1;
  /// per image and axis: 0 the particle's coordinate, 1 mirrored in the low wall, 2 the high
  std::array<std::array<std::uint8_t, 3>, 27> mirror{};
  /// per image: the image of the axis-aligned box [lo, hi]
  void box(int m, const Vec3& box_lo, const Vec3& box_hi, const Vec3& lo, const Vec3& hi,
           Vec3& out_lo, Vec3& out_hi) const {
    for (int a = 0; a < 3; ++a) {
      const int k = mirror[m][a];
      const double plane = k == 1 ? box_lo[a] : box_hi[a];
      out_lo[a] = k == 0 ? lo[a] : 2 * plane - hi[a];
      out_hi[a] = k == 0 ? hi[a] : 2 * plane - lo[a];
    }
  }
};

ParticleImages particle_images(const Vec3& xc, const Vec3& box_lo, const Vec3& box_hi, double R) {
  std::array<int, 3> images{};
  for (int a = 0; a < 3; ++a) images[a] = 1 + (xc[a] - box_lo[a] < R) + (box_hi[a] - xc[a] < R);
  ParticleImages pi;
  pi.count = images[0] * images[1] * images[2];
  for (int m = 0; m < pi.count; ++m) {
    int rest = m;
    for (int a = 0; a < 3; ++a) {
      const int im = rest % images[a];
      rest /= images[a];
      if (im == 0) continue;  // the particle itself
      pi.mirror[m][a] = xc[a] - box_lo[a] < R && im == 1 ? 1 : 2;
    }
  }
  return pi;
}

/// The kernel-weighted sums Σ w p and Σ w of φ at a cell centre [ZhuBridson05].
struct KernelSums {
  Vec3 mean = Vec3::Zero();
  double wsum = 0;
};
/// The kernel-weighted sums of the points within R of a centre xc, in two passes: the points
/// are gathered in their order without a branch on their distance (each is written, the end
/// moves on for those within R: a data-dependent branch there mispredicts at every other
/// point near the kernel's edge), then their terms are added in that order, component by
/// component as KernelSums' Vec3 sums. Bit for bit the sums of adding each point's term in
/// turn and skipping those beyond R (a term whose kernel is 0 adds a zero, which changes no
/// sum: the sums start at +0 and are never −0). The buffer is the calling thread's, reused:
/// one NearPoints at a time per thread.
class NearPoints {
 public:
  NearPoints(const Vec3& xc, double R2)
      : m_xc(xc),
        m_R2(R2),
        m_bound(R2 * (1 + 1e-12)),
        m_buf(buffer()),
        m_out(m_buf.data()),
        m_cap(static_cast<Index>(m_buf.size())) {}
  /// room for `count` more points
  void reserve(Index count) {
    if (m_n + count <= m_cap) return;
    m_buf.resize(static_cast<size_t>(2 * (m_n + count)));
    m_out = m_buf.data();
    m_cap = static_cast<Index>(m_buf.size());
  }
  /// gathers p (after reserve)
  void add(const Vec3& p) {
    const double dx = m_xc[0] - p[0], dy = m_xc[1] - p[1], dz = m_xc[2] - p[2];
    const double d2 = dx * dx + dy * dy + dz * dz;  // squaredNorm()
    m_out[m_n] = {p[0], p[1], p[2], d2};
    m_n += d2 <= m_bound ? 1 : 0;  // beyond: d2 / R2 ≥ 1 whatever its rounding
  }
  KernelSums sums() const {
    double mx = 0, my = 0, mz = 0, wsum = 0;
    for (Index k = 0; k < m_n; ++k) {
      const Near& q = m_out[k];
      const double t = 1.0 - q.d2 / m_R2;
      if (!(t > 0)) continue;  // kernel() is 0
      const double w = t * t * t;
      mx += w * q.x;
      my += w * q.y;
      mz += w * q.z;
      wsum += w;
    }
    return {Vec3(mx, my, mz), wsum};
  }

 private:
  struct Near {
    double x, y, z, d2;
  };
  static std::vector<Near>& buffer() {
    thread_local std::vector<Near> buf(1024);
    return buf;
  }
  const Vec3 m_xc;
  const double m_R2, m_bound;
  std::vector<Near>& m_buf;
  Near* m_out;
  Index m_cap, m_n = 0;
};

/// The cells within `reach` of a cell whose boxes come within R of its centre (widened for
/// round-off), by offset: the others hold no particle within R of it.
struct ReachMask {
  std::array<Index, 3> reach{};
  std::vector<std::uint8_t> near;  ///< by (o_x + r_x) + (2 r_x + 1)((o_y + r_y) + ...)
  /// `widen`: the share of a cell each box is widened by; `slack`: the share of R² the gap
  /// may exceed it by (a looser mask holds every offset of a tighter one)
  ReachMask(const GridSpec& g, const std::array<Index, 3>& r, double R, double widen = 1e-6,
            double slack = 1e-9)
      : reach(r) {
    const std::array<Index, 3> w{2 * r[0] + 1, 2 * r[1] + 1, 2 * r[2] + 1};
    near.resize(static_cast<size_t>(w[0] * w[1] * w[2]));
    for (Index o = 0; o < w[0] * w[1] * w[2]; ++o) {
      const std::array<Index, 3> off{o % w[0] - r[0], (o / w[0]) % w[1] - r[1],
                                     o / (w[0] * w[1]) - r[2]};
      double gap2 = 0;
      for (int a = 0; a < 3; ++a) {
        const double gap =
            std::max(0.0, static_cast<double>(std::abs(off[a])) - 0.5 - widen) * g.h[a];
        gap2 += gap * gap;
      }
      near[o] = gap2 < R * R * (1 + slack);
    }
    // per row (o_y, o_z): the greatest |o_x| near, −1 if none (near is symmetric and its
    // offsets along a row an interval: the gap grows with |o_x|)
    half.assign(static_cast<size_t>(w[1] * w[2]), -1);
    for (Index o = 0; o < w[0] * w[1] * w[2]; ++o)
      if (near[o]) half[o / w[0]] = std::max(half[o / w[0]], std::abs(o % w[0] - r[0]));
  }
  /// half's entry of row (oj, ok)
  Index half_width(Index oj, Index ok) const {
    return half[(oj + reach[1]) + (2 * reach[1] + 1) * (ok + reach[2])];
  }
  std::vector<Index> half;  ///< per row of the block: how far along x it is near
  /// operator() for any offset (beyond reach: not near)
  bool near_at(const std::array<Index, 3>& o) const {
    for (int a = 0; a < 3; ++a)
      if (std::abs(o[a]) > reach[a]) return false;
    return (*this)(o[0], o[1], o[2]);
  }
  bool operator()(Index oi, Index oj, Index ok) const {
    return near[(oi + reach[0]) +
                (2 * reach[0] + 1) * ((oj + reach[1]) + (2 * reach[1] + 1) * (ok + reach[2]))];
  }
};

/// kernel_sums' masks: the cells' own, and a looser one for the walls' images of the inner
/// cells (wider than any round-off of their mirrored boxes: it holds every (cell, image) pair
/// the boxes would, and a few more whose terms are zero).
struct ReachMasks {
  ReachMask cells, images;
  ReachMasks(const GridSpec& g, const std::array<Index, 3>& r, double R)
      : cells(g, r, R), images(g, r, R, 1e-4, 1e-6) {}
};

/// kernel_sums where no wall lies within R of cell c's centre: the particles themselves, in
/// the cells whose boxes come within R of it (a cell on the grid's boundary always: the
/// bucketing clamps to it). A row of cells (i, j, k) over an interval of i holds one range of
/// the buckets: each row is read as that range, from its first near cell to its last (those
/// between add no term: the order of the terms is the cells' own).
KernelSums kernel_sums_inner(const GridSpec& g, Index c, const ReachMask& mask,
                             const ParticleBuckets& b, const std::vector<Vec3>& xs, double R) {
  const auto ijk = g.cell_ijk(c);
  const auto& reach = mask.reach;
  const Vec3 xc = g.cell_centre(c);
  const Index nx = g.n[0], row_lo = ijk[0] - reach[0], row_hi = ijk[0] + reach[0];
  NearPoints s(xc, R * R);
  for (Index k = std::max<Index>(0, ijk[2] - reach[2]);
       k <= std::min(g.n[2] - 1, ijk[2] + reach[2]); ++k)
    for (Index j = std::max<Index>(0, ijk[1] - reach[1]);
         j <= std::min(g.n[1] - 1, ijk[1] + reach[1]); ++j) {
      Index lo = row_lo, hi = row_hi;  // a row on the grid's boundary: all of it
      if (!(k == 0 || k == g.n[2] - 1 || j == 0 || j == g.n[1] - 1)) {
        const Index w = mask.half_width(j - ijk[1], k - ijk[2]);
        if (row_lo > 0) lo = ijk[0] - w;  // else from the boundary cell i = 0
        if (row_hi < nx - 1) hi = ijk[0] + w;
      }
      lo = std::max<Index>(lo, 0);
      hi = std::min(hi, nx - 1);
      if (lo > hi) continue;
      const Index e0 = b.start[g.cell(lo, j, k)], e1 = b.start[g.cell(hi, j, k) + 1];
      s.reserve(e1 - e0);
      for (Index e = e0; e < e1; ++e) s.add(xs[e]);
    }
  return s.sums();
}

/// The kernel-weighted sums over the images of the particles of the cells within `reach` of
/// cell c [ZhuBridson05], in the order cells (k, j, i), particles (bucket order), images. A
/// (cell, image) pair whose box lies beyond R of the centre is skipped, as is every term of
/// zero weight: the sums are the full sums' bit for bit (the terms left out are zeros).
KernelSums kernel_sums(const GridSpec& g, Index c, const ReachMasks& masks,
                       const ParticleBuckets& b, const std::vector<Vec3>& xs, double R) {
  const ReachMask& mask = masks.cells;
  const auto ijk = g.cell_ijk(c);
  const auto& reach = mask.reach;
  const Vec3 xc = g.cell_centre(c), box_lo = g.lo, box_hi = g.hi();
  const ParticleImages pi = particle_images(xc, box_lo, box_hi, R);
  if (pi.count == 1) return kernel_sums_inner(g, c, mask, b, xs, R);
  const double R2 = R * R, prune = R2 * (1 + 1e-9);
  const double inf = std::numeric_limits<double>::infinity();
  NearPoints s(xc, R2);
  std::array<std::uint8_t, 27> active{};
  for (Index k = std::max<Index>(0, ijk[2] - reach[2]);
       k <= std::min(g.n[2] - 1, ijk[2] + reach[2]); ++k)
    for (Index j = std::max<Index>(0, ijk[1] - reach[1]);
         j <= std::min(g.n[1] - 1, ijk[1] + reach[1]); ++j)
      for (Index i = std::max<Index>(0, ijk[0] - reach[0]);
           i <= std::min(g.n[0] - 1, ijk[0] + reach[0]); ++i) {
        const Index d = g.cell(i, j, k);
        const Index e0 = b.start[d], e1 = b.start[d + 1];
        if (e0 == e1) continue;
        const std::array<Index, 3> dijk{i, j, k};
        bool any = false;
        if (i > 0 && i < g.n[0] - 1 && j > 0 && j < g.n[1] - 1 && k > 0 && k < g.n[2] - 1) {
          // an inner cell's image in a wall is the cell mirrored in it (index −1 − i at the
          // low wall, 2n − 1 − i at the high): near if its offset is near in the looser mask
          for (int m = 0; m < pi.count; ++m) {
            std::array<Index, 3> off{};
            for (int a = 0; a < 3; ++a) {
              const int w = pi.mirror[m][a];
              off[a] = (w == 0   ? dijk[a]
                        : w == 1 ? -1 - dijk[a]
                                 : 2 * g.n[a] - 1 - dijk[a]) -
                       ijk[a];
            }
            active[m] = masks.images.near_at(off);
            any = any || active[m];
          }
        } else {
          // the cell's box (open where bucketing clamps to the grid), widened for round-off
          Vec3 lo, hi;
          for (int a = 0; a < 3; ++a) {
            lo[a] = dijk[a] == 0 ? -inf : box_lo[a] + (dijk[a] - 1e-6) * g.h[a];
            hi[a] = dijk[a] == g.n[a] - 1 ? inf : box_lo[a] + (dijk[a] + 1 + 1e-6) * g.h[a];
          }
          for (int m = 0; m < pi.count; ++m) {
            Vec3 ilo, ihi;
            pi.box(m, box_lo, box_hi, lo, hi, ilo, ihi);
            const Vec3 gap = (ilo - xc).cwiseMax(xc - ihi).cwiseMax(0.0);
            active[m] = gap.squaredNorm() < prune;
            any = any || active[m];
          }
        }
        if (!any) continue;
        s.reserve((e1 - e0) * pi.count);
        for (Index e = e0; e < e1; ++e) {
          const Vec3& p0 = xs[e];
          for (int m = 0; m < pi.count; ++m) {
            if (!active[m]) continue;
            Vec3 p = p0;
            for (int a = 0; a < 3; ++a)
              if (pi.mirror[m][a] != 0)
                p[a] = pi.mirror[m][a] == 1 ? 2 * box_lo[a] - p0[a] : 2 * box_hi[a] - p0[a];
            s.add(p);
          }
        }
      }
  return s.sums();
}

}  // namespace

VecX liquid_level_set(const GridCells& gc, const MatX3& x, const LiquidSurfaceParams& sp) {
  const GridSpec& g = gc.grid;
  const double R = kernel_radius(g);
  const ParticleBuckets b = bucket_particles(g, x);
  // the particles' positions in bucket order (each cell's together)
  std::vector<Vec3> xs(b.order.size());
  parallel_for_each(static_cast<Index>(xs.size()), 4 * kGrain,
                    [&](Index e) { xs[e] = x.row(b.order[e]).transpose(); });
  const Index full = sp.per_axis * sp.per_axis * sp.per_axis;
  std::array<Index, 3> reach{};
  for (int a = 0; a < 3; ++a) reach[a] = static_cast<Index>(std::ceil(R / g.h[a]));
  // A cell whose block of cells within the kernel radius all hold particles is deep inside
  // the liquid: its mean is itself to within the particles' spacing, φ = −r (the sum over
  // its ~1000 neighbours is what φ costs; only cells near the surface need it). Beside a wall
  // the block is clipped to the box: the walls' mirror images fill the rest alike. A cell
  // whose block holds no particle has no term: φ = R.
  std::vector<std::uint8_t> occupied(static_cast<size_t>(g.num_cells()));
  parallel_for_each(g.num_cells(), 4 * kGrain,
                    [&](Index c) { occupied[c] = b.start[c + 1] > b.start[c]; });
  TETFSI_CHECK((2 * reach[0] + 1) * (2 * reach[1] + 1) * (2 * reach[2] + 1) <= 255,
               "liquid_level_set: a kernel block of {} {} {} cells each way has over 255 cells",
               reach[0], reach[1], reach[2]);
  const std::vector<std::uint8_t> occupied_near = block_counts(g, std::move(occupied), reach);
  const ReachMasks masks(g, reach, R);
  VecX phi(g.num_cells());
  parallel_for_each(g.num_cells(), kGrain, [&](Index c) {
    if (occupied_near[c] == 0) {
      phi[c] = R;
      return;
    }
    if (gc.open_cell(c) && whole_block(g, c, occupied_near[c], reach)) {  // deep
      phi[c] = -sp.radius;
      return;
    }
    const KernelSums s = kernel_sums(g, c, masks, b, xs, R);
    // see [ZhuBridson05]: φ(x) = |x − x̄| − r, x̄ the kernel-weighted mean of the particles
    const Vec3 xc = g.cell_centre(c);
    phi[c] = s.wsum > 0 ? std::min((xc - s.mean / s.wsum).norm() - sp.radius, R) : R;
    if (gc.open_cell(c) && 2 * (b.start[c + 1] - b.start[c]) >= full && touches_body(gc, c))
      phi[c] = std::min(phi[c], -sp.face_phi);
  });
  return phi;
}

void set_free_surface(GridCells& gc, VecX phi) {
  const Index nc = gc.grid.num_cells();
  TETFSI_CHECK(phi.size() == nc, "φ has {} entries for {} cells", phi.size(), nc);
  gc.air.resize(static_cast<size_t>(nc));
  parallel_for_each(nc, 4 * kGrain,
                    [&](Index c) { gc.air[c] = gc.cell_body[c] < 0 && phi[c] >= 0 ? 1 : 0; });
  gc.phi = std::move(phi);
}

namespace {

/// The per-axis weights of a point x for face_velocity_at: along each axis b, those of the
/// cell centres' lattice (which the faces of the other two axes share) and of the axis-b
/// faces' lattice.
struct FaceStencil {
  std::array<AxisWeights, 3> centre, face;
};
FaceStencil face_stencil(const GridSpec& g, const Vec3& x) {
  FaceStencil s;
  for (int b = 0; b < 3; ++b) {
    s.centre[b] = axis_weights(g, -1, b, x[b]);
    s.face[b] = axis_weights(g, b, b, x[b]);
  }
  return s;
}

/// face_velocity_at from the point's stencil.
Vec3 face_velocity_from(const GridSpec& g, const VecX& u, const FaceStencil& st) {
  Vec3 v;
  for (int a = 0; a < 3; ++a) {
    std::array<AxisWeights, 3> s = st.centre;
    s[a] = st.face[a];
    v[a] = trilinear(s, [&](Index i, Index j, Index k) { return u[g.face(a, i, j, k)]; });
  }
  return v;
}

}  // namespace

Vec3 face_velocity_at(const GridSpec& g, const VecX& u, const Vec3& x) {
  return face_velocity_from(g, u, face_stencil(g, x));
}

VecX particles_to_faces(const GridSpec& g, const LiquidParticles& lp,
                        std::vector<std::uint8_t>& known) {
  const Index nf = g.num_faces();
  VecX num = VecX::Zero(nf), den = VecX::Zero(nf);
  // Scatter in particle order, in parallel over (axis, z-slab of its faces) tasks: each task
  // owns its faces and adds to them in particle order, so every face's sums are those of the
  // serial scatter, bit for bit at any thread count.
  constexpr Index kSlab = 8;
  const SlabLists sl = slab_particles(g, lp.x, kSlab);
  const Index slabs = sl.slabs;
  const auto& start = sl.start;
  const auto& items = sl.items;
  parallel_for_each(3 * slabs, 1, [&](Index task) {
    const int a = static_cast<int>(task % 3), t = a == 2 ? 0 : 1;
    const Index slab = task / 3, k0 = slab * kSlab, k1 = k0 + kSlab;
    for (Index e = start[t][slab]; e < start[t][slab + 1]; ++e) {
      const Index p = items[t][e];
      for_each_lattice_weight(g, a, lp.x.row(p).transpose(),
                              [&](const std::array<Index, 3>& ijk, double w) {
                                if (w <= 0 || ijk[2] < k0 || ijk[2] >= k1) return;
                                const Index f = g.face(a, ijk[0], ijk[1], ijk[2]);
                                num[f] += w * lp.v(p, a);
                                den[f] += w;
                              });
    }
  });
  known.assign(static_cast<size_t>(nf), 0);
  VecX u = VecX::Zero(nf);
  for (Index f = 0; f < nf; ++f)
    if (den[f] > 1e-12) {  // a particle on the face's far corner adds no information
      u[f] = num[f] / den[f];
      known[f] = 1;
    }
  return u;
}

std::vector<std::uint8_t> liquid_faces(const GridCells& gc) {
  const Index nf = gc.grid.num_faces();
  std::vector<std::uint8_t> known(static_cast<size_t>(nf), 0);
  for (Index f = 0; f < nf; ++f) {
    const FaceKind k = gc.face_kind[f];
    if (k != FaceKind::Interior && k != FaceKind::Open) {
      known[f] = 1;
      continue;
    }
    for (Index c : gc.grid.face_cells(f)) known[f] = known[f] || gc.fluid(c);
  }
  return known;
}

namespace {

/// The faces of face f's axis beside it (−1 where the lattice ends), in the order (axis b,
/// direction) = (0, −1), (0, +1), (1, −1), (1, +1), (2, −1), (2, +1).
std::array<Index, 6> face_neighbours(const GridSpec& g, Index f) {
  const int a = g.face_axis(f);
  const auto ijk = g.face_ijk(f);
  std::array<Index, 6> out{};
  for (int b = 0; b < 3; ++b)
    for (int side = 0; side < 2; ++side) {
      std::array<Index, 3> q = ijk;
      q[b] += side == 0 ? -1 : 1;
      out[2 * b + side] =
          q[b] < 0 || q[b] >= lattice_size(g, b, a) ? -1 : g.face(a, q[0], q[1], q[2]);
    }
  return out;
}

/// The faces not `known` with a known neighbour of their axis (face_neighbours'), in index
/// order: per axis and z layer of its lattice in parallel, the neighbours by index strides.
std::vector<Index> unknown_beside_known(const GridSpec& g, const std::vector<std::uint8_t>& known) {
  std::array<std::vector<std::vector<Index>>, 3> found;
  for (int a = 0; a < 3; ++a) {
    const std::array<Index, 3> d{lattice_size(g, 0, a), lattice_size(g, 1, a),
                                 lattice_size(g, 2, a)};
    const std::array<Index, 3> stride{1, d[0], d[0] * d[1]};
    found[a].resize(static_cast<size_t>(d[2]));
    parallel_for_each(d[2], 1, [&](Index k) {
      std::vector<Index>& out = found[a][k];
      for (Index j = 0; j < d[1]; ++j) {
        const Index row = g.face(a, 0, j, k);
        for (Index i = 0; i < d[0]; ++i) {
          const Index f = row + i;
          if (known[f]) continue;
          const std::array<Index, 3> ijk{i, j, k};
          bool beside = false;
          for (int b = 0; b < 3 && !beside; ++b)
            beside =
                (ijk[b] > 0 && known[f - stride[b]]) || (ijk[b] + 1 < d[b] && known[f + stride[b]]);
          if (beside) out.push_back(f);
        }
      }
    });
  }
  std::vector<Index> out;
  for (const auto& axis : found)
    for (const auto& layer : axis) out.insert(out.end(), layer.begin(), layer.end());
  return out;
}

}  // namespace

void extrapolate_faces(const GridSpec& g, std::vector<std::uint8_t> known, int layers, VecX& u) {
  const Index nf = g.num_faces();
  // Each layer fills the unknown faces beside a known one with the mean of their known
  // neighbours (Jacobi: from the faces known before the layer). Only those faces can change,
  // so a layer visits them alone: at first every unknown face beside a known one, then the
  // unknown neighbours of the faces the last layer filled.
  std::vector<Index> front = unknown_beside_known(g, known);
  std::vector<Index> mark(static_cast<size_t>(nf), -1);  // the layer that listed a face
  for (int layer = 0; layer < layers && !front.empty(); ++layer) {
    std::vector<double> value(front.size());
    std::vector<std::uint8_t> has(front.size(), 0);
    parallel_for_each(static_cast<Index>(front.size()), 1024, [&](Index k) {
      double s = 0;
      int n = 0;
      for (const Index e : face_neighbours(g, front[k]))
        if (e >= 0 && known[e]) {
          s += u[e];
          ++n;
        }
      if (n == 0) return;
      value[k] = s / n;
      has[k] = 1;
    });
    std::vector<Index> filled;
    for (size_t k = 0; k < front.size(); ++k)
      if (has[k]) {
        u[front[k]] = value[k];
        filled.push_back(front[k]);
      }
    for (const Index f : filled) known[f] = 1;
    front.clear();
    for (const Index f : filled)
      for (const Index e : face_neighbours(g, f))
        if (e >= 0 && !known[e] && mark[e] != layer) {
          mark[e] = layer;
          front.push_back(e);
        }
  }
  parallel_for_each(nf, 4 * kGrain, [&](Index f) {
    if (!known[f]) u[f] = 0.0;
  });
}

namespace {

/// Whether the move a → b enters a body: its first crossing is against that triangle's
/// outward normal. `t` is the crossing's fraction of the move.
bool enters_body(const GridSolids& solids, const Vec3& a, const Vec3& b, double& t) {
  SurfacePoint sp;
  if (!solids.first_crossing(a, b, &sp, &t) || sp.body < 0) return false;
  for (const mesh::SolidSurface& s : solids.surfaces()) {
    if (s.body != sp.body) continue;
    const Vec3 p0 = s.vertices.row(s.triangles(sp.triangle, 0)).transpose();
    const Vec3 p1 = s.vertices.row(s.triangles(sp.triangle, 1)).transpose();
    const Vec3 p2 = s.vertices.row(s.triangles(sp.triangle, 2)).transpose();
    return (p1 - p0).cross(p2 - p0).dot(b - a) < 0;
  }
  return false;
}

}  // namespace

Index advect_particles(const GridCells& gc, const VecX& u, double h, LiquidParticles& lp) {
  const GridSpec& g = gc.grid;
  const double eps = 1e-3 * g.h.minCoeff();
  const Vec3 lo = g.lo.array() + eps, hi = g.hi().array() - eps;
  std::vector<std::uint8_t> gone(static_cast<size_t>(lp.size()), 0);
  parallel_for_each(lp.size(), kGrain, [&](Index p) {
    const Vec3 x = lp.x.row(p).transpose();
    const Vec3 mid = x + 0.5 * h * face_velocity_at(g, u, x);
    Vec3 y = x + h * face_velocity_at(g, u, mid);
    double t = 1;
    if (enters_body(gc.solids, x, y, t)) {
      const double len = (y - x).norm();
      y = x + std::max(0.0, t - eps / std::max(len, 1e-300)) * (y - x);
    }
    for (int a = 0; a < 3; ++a) {
      if (y[a] >= lo[a] && y[a] <= hi[a]) continue;
      Vec3 inside = y.cwiseMax(lo).cwiseMin(hi);
      const auto ijk = g.cell_ijk(g.cell_at(inside));
      std::array<Index, 3> fi = ijk;
      fi[a] = y[a] < lo[a] ? 0 : g.n[a];
      if (gc.face_kind[g.face(a, fi[0], fi[1], fi[2])] == FaceKind::Open) gone[p] = 1;
      y = inside;
    }
    lp.x.row(p) = y.transpose();
  });
  Index kept = 0;
  for (Index p = 0; p < lp.size(); ++p)
    if (!gone[p]) {
      lp.x.row(kept) = lp.x.row(p);
      lp.v.row(kept) = lp.v.row(p);
      ++kept;
    }
  const Index removed = lp.size() - kept;
  lp.x.conservativeResize(kept, 3);
  lp.v.conservativeResize(kept, 3);
  return removed;
}

Index separate_particles(const GridCells& gc, int per_axis, LiquidParticles& lp) {
  const GridSpec& g = gc.grid;
  const double reach = k_separation * g.h.minCoeff() / per_axis;
  const ParticleBuckets b = bucket_particles(g, lp.x);
  std::vector<Vec3> xs(b.order.size());  // the positions in bucket order
  parallel_for_each(static_cast<Index>(xs.size()), 4 * kGrain,
                    [&](Index e) { xs[e] = lp.x.row(b.order[e]).transpose(); });
  const double eps = 1e-3 * g.h.minCoeff(), far2 = reach * reach * (1 + 1e-12);
  const Vec3 lo = g.lo.array() + eps, hi = g.hi().array() - eps;
  MatX3 moved = lp.x;
  std::vector<std::uint8_t> pushed(static_cast<size_t>(lp.size()), 0);
  // one Jacobi sweep from the old positions (bit for bit at any thread count)
  parallel_for_each(lp.size(), kGrain, [&](Index p) {
    const Vec3 x = lp.x.row(p).transpose();
    // the cells that the ball of radius `reach` about x overlaps (at most 2 per axis)
    const auto lo_ijk = g.cell_ijk(g.cell_at(x.array() - reach));
    const auto hi_ijk = g.cell_ijk(g.cell_at(x.array() + reach));
    Vec3 dx = Vec3::Zero();
    for (Index k = lo_ijk[2]; k <= hi_ijk[2]; ++k)
      for (Index j = lo_ijk[1]; j <= hi_ijk[1]; ++j)
        for (Index i = lo_ijk[0]; i <= hi_ijk[0]; ++i) {
          const Index d = g.cell(i, j, k);
          for (Index e = b.start[d]; e < b.start[d + 1]; ++e) {
            if (b.order[e] == p) continue;
            const Vec3 r = x - xs[e];
            if (r.squaredNorm() > far2) continue;  // dist > reach whatever its rounding
            const double dist = r.norm();
            // half the overlap each (the other half moves the other particle), relaxed by 1/2
            if (dist < reach && dist > 0) dx += 0.25 * (reach - dist) / dist * r;
          }
        }
    if (dx.squaredNorm() == 0) return;
    Vec3 y = (x + dx).cwiseMax(lo).cwiseMin(hi);
    double t = 1;
    if (enters_body(gc.solids, x, y, t)) return;
    moved.row(p) = y.transpose();
    pushed[p] = 1;
  });
  lp.x = std::move(moved);
  Index n = 0;
  for (std::uint8_t v : pushed) n += v;
  return n;
}

VecX liquid_volume_source(const GridCells& gc, const MatX3& x, int per_axis, double rate,
                          double h) {
  const GridSpec& g = gc.grid;
  const Index nc = g.num_cells();
  const ParticleBuckets b = bucket_particles(g, x);
  const double n0 = static_cast<double>(per_axis * per_axis * per_axis);
  VecX source = VecX::Zero(nc);
  parallel_for_each(nc, kGrain, [&](Index c) {
    if (!gc.fluid(c)) return;
    const auto ijk = g.cell_ijk(c);
    double count = 0.0;
    int cells = 0;
    for (Index dk = -1; dk <= 1; ++dk) {
      for (Index dj = -1; dj <= 1; ++dj) {
        for (Index di = -1; di <= 1; ++di) {
          const Index i = ijk[0] + di, j = ijk[1] + dj, k = ijk[2] + dk;
          if (i < 0 || j < 0 || k < 0 || i >= g.n[0] || j >= g.n[1] || k >= g.n[2]) continue;
          const Index e = g.cell(i, j, k);
          if (!gc.fluid(e)) return;  // beside air or a body: a partly filled cell
          count += static_cast<double>(b.start[e + 1] - b.start[e]);
          ++cells;
        }
      }
    }
    const double error = count / (cells * n0) - 1.0;
    const double beyond = std::max(0.0, std::abs(error) - k_density_tolerance);
    source[c] = rate * std::copysign(beyond, error) * g.cell_volume() / h;
  });
  return source;
}

void faces_to_particles(const GridSpec& g, const VecX& u, const VecX& u_old, double flip,
                        LiquidParticles& lp) {
  parallel_for_each(lp.size(), kGrain, [&](Index p) {
    const Vec3 x = lp.x.row(p).transpose();
    const FaceStencil st = face_stencil(g, x);
    const Vec3 un = face_velocity_from(g, u, st), uo = face_velocity_from(g, u_old, st);
    // see [ZhuBridson05]: FLIP adds the grid's change, PIC takes the grid's value
    const Vec3 v = lp.v.row(p).transpose();
    lp.v.row(p) = (flip * (v + un - uo) + (1.0 - flip) * un).transpose();
  });
}

namespace {

/// φ trilinear between the cell centres, from the point's per-axis weights
/// (axis_weights(g, −1, ...)).
double phi_from(const GridCells& gc, const std::array<AxisWeights, 3>& s) {
  const GridSpec& g = gc.grid;
  return trilinear(s, [&](Index i, Index j, Index k) { return gc.phi[g.cell(i, j, k)]; });
}

/// φ's least and greatest over cell c's 3 × 3 × 3 block (clipped to the grid).
std::array<double, 2> block_range(const GridCells& gc, Index c) {
  const GridSpec& g = gc.grid;
  const auto ijk = g.cell_ijk(c);
  double lo = gc.phi[c], hi = lo;
  for (Index k = std::max<Index>(0, ijk[2] - 1); k <= std::min(g.n[2] - 1, ijk[2] + 1); ++k)
    for (Index j = std::max<Index>(0, ijk[1] - 1); j <= std::min(g.n[1] - 1, ijk[1] + 1); ++j)
      for (Index i = std::max<Index>(0, ijk[0] - 1); i <= std::min(g.n[0] - 1, ijk[0] + 1); ++i) {
        lo = std::min(lo, gc.phi[g.cell(i, j, k)]);
        hi = std::max(hi, gc.phi[g.cell(i, j, k)]);
      }
  return {lo, hi};
}

/// Whether φ, shifted by d, changes sign within a block of range r (the surface may cross
/// its cell).
bool sign_change(const std::array<double, 2>& r, double d = 0.0) {
  return r[0] + d < 0 && r[1] + d >= 0;
}

/// The length of [0, len] where f, linear from f0 to f1, is negative.
double negative_length(double f0, double f1, double len) {
  if (f0 < 0 && f1 < 0) return len;
  if (f0 >= 0 && f1 >= 0) return 0.0;
  return len * (f0 < 0 ? -f0 : -f1) / std::abs(f1 - f0);
}

/// The axis along which φ changes most from cell c to a neighbour (the surface's normal's
/// nearest axis; on either side, so that a sheet one cell thick finds its normal).
int steepest_axis(const GridCells& gc, Index c) {
  const GridSpec& g = gc.grid;
  const auto ijk = g.cell_ijk(c);
  int best = 2;
  double most = -1;
  for (int a = 0; a < 3; ++a) {
    auto lo = ijk, hi = ijk;
    lo[a] = std::max<Index>(0, ijk[a] - 1);
    hi[a] = std::min(g.n[a] - 1, ijk[a] + 1);
    const double f = gc.phi[c];
    const double d = std::max(std::abs(gc.phi[g.cell(hi[0], hi[1], hi[2])] - f),
                              std::abs(f - gc.phi[g.cell(lo[0], lo[1], lo[2])])) /
                     g.h[a];
    // a clear margin, so that round-off in a shifted φ never flips a tie
    if (d > most * (1 + 1e-6)) {
      most = d;
      best = a;
    }
  }
  return best;
}

/// φ at the start, middle and end of m × m lines through cell c along the axis nearest the
/// surface's normal (steepest_axis), 3 m² values into f: φ is linear along an axis on either
/// side of the cell centre's plane.
void line_values(const GridCells& gc, Index c, int m, double* f) {
  const GridSpec& g = gc.grid;
  TETFSI_CHECK(m >= 1 && m <= 4, "line_values: 1 to 4 lines per axis, got {}", m);
  const Vec3 lo = g.cell_centre(c) - 0.5 * g.h;
  const int a = steepest_axis(gc, c), b = (a + 1) % 3, d = (a + 2) % 3;
  // the weights along each axis of the lines' coordinates, each computed once
  std::array<AxisWeights, 4> along_b{}, along_d{};
  std::array<AxisWeights, 3> along_a{};
  for (int i = 0; i < m; ++i) {
    along_b[i] = axis_weights(g, -1, b, lo[b] + (i + 0.5) / m * g.h[b]);
    along_d[i] = axis_weights(g, -1, d, lo[d] + (i + 0.5) / m * g.h[d]);
  }
  double xa = lo[a];
  for (int k = 0; k < 3; ++k, xa += 0.5 * g.h[a]) along_a[k] = axis_weights(g, -1, a, xa);
  for (int l = 0; l < m * m; ++l)
    for (int k = 0; k < 3; ++k) {
      std::array<AxisWeights, 3> s;
      s[a] = along_a[k];
      s[b] = along_b[l % m];
      s[d] = along_d[l / m];
      f[3 * l + k] = phi_from(gc, s);
    }
}

/// The share of a cell where φ + d is negative, from line_values' values f on its m × m
/// lines, each exactly.
double lines_share(const double* f, int m, double d) {
  double len = 0;
  for (int l = 0; l < m * m; ++l)
    len += negative_length(f[3 * l] + d, f[3 * l + 1] + d, 1.0) +
           negative_length(f[3 * l + 1] + d, f[3 * l + 2] + d, 1.0);
  return len / (2 * m * m);
}

/// The share of cell c where φ, trilinear, is negative: on line_values' m × m lines, each
/// exactly, so the share moves continuously with the surface.
double negative_share(const GridCells& gc, Index c, int m) {
  std::array<double, 3 * 16> f{};
  TETFSI_CHECK(m <= 4, "negative_share: at most 4 x 4 lines, got {}", m);
  line_values(gc, c, m, f.data());
  return lines_share(f.data(), m, 0.0);
}

/// The area of the surface in cell c: on m³ samples, m = 4, a sign change of φ to the next
/// sample along axis a is a surface element of projected area ΔA_a = (h_b h_c / m²), and
/// Σ_a ΔA_a |n_a| over the crossings is the area, n = ∇φ/|∇φ| by central differences at the
/// crossing's midpoint. Every coordinate is computed per axis as the plain point arithmetic
/// would (x = x0 + s h, y = x + Δ, the midpoint 0.5 (x + y), its neighbours ∓ Δ), so each
/// axis' weights are computed once per value: the same φ values, bit for bit.
double cell_area(const GridCells& gc, Index c) {
  constexpr int m = 4;
  const GridSpec& g = gc.grid;
  const Vec3 step = g.h / m, x0 = g.cell_centre(c) - 0.5 * g.h;
  // per axis and sample index: x, x + Δ, x − Δ; the midpoint along a crossing, and it ∓ Δ
  enum Kind { kX, kXp, kXm, kMid, kMidm, kMidp, kKinds };
  std::array<std::array<std::array<AxisWeights, m>, kKinds>, 3> w;
  std::array<std::array<double, m>, 3> y;
  for (int q = 0; q < 3; ++q)
    for (int i = 0; i < m; ++i) {
      const double x = x0[q] + (i + 0.5) / m * g.h[q];
      y[q][i] = x + step[q];
      const double mid = 0.5 * (x + y[q][i]), self = 0.5 * (x + x);  // self == x
      w[q][kX][i] = axis_weights(g, -1, q, x);
      w[q][kXp][i] = axis_weights(g, -1, q, self + step[q]);  // also x + Δ: y
      w[q][kXm][i] = axis_weights(g, -1, q, self - step[q]);
      w[q][kMid][i] = axis_weights(g, -1, q, mid);
      w[q][kMidm][i] = axis_weights(g, -1, q, mid - step[q]);
      w[q][kMidp][i] = axis_weights(g, -1, q, mid + step[q]);
    }
  double area = 0;
  for (int l = 0; l < m * m * m; ++l) {
    const std::array<int, 3> i{l % m, (l / m) % m, l / (m * m)};
    const auto at = [&](const std::array<int, 3>& kind) {
      return phi_from(gc, {w[0][kind[0]][i[0]], w[1][kind[1]][i[1]], w[2][kind[2]][i[2]]});
    };
    const double f = at({kX, kX, kX});
    for (int a = 0; a < 3; ++a) {
      std::array<int, 3> ky{kX, kX, kX};
      ky[a] = kXp;
      if (y[a][i[a]] > g.hi()[a] || (at(ky) < 0) == (f < 0)) continue;
      Vec3 grad;
      for (int b = 0; b < 3; ++b) {
        std::array<int, 3> lo{kX, kX, kX}, hi{kX, kX, kX};
        lo[a] = hi[a] = kMid;
        lo[b] = b == a ? kMidm : kXm;
        hi[b] = b == a ? kMidp : kXp;
        grad[b] = (at(hi) - at(lo)) / (2 * step[b]);
      }
      const double gn = grad.norm();
      if (gn > 0) area += g.cell_volume() / g.h[a] / (m * m) * std::abs(grad[a]) / gn;
    }
  }
  return area;
}

/// liquid_measures, its area only `with_area` (the volume alone costs a fifth).
LiquidMeasures measure_liquid(const GridCells& gc, bool with_area) {
  const GridSpec& g = gc.grid;
  LiquidMeasures out;
  if (gc.phi.size() != g.num_cells()) return out;
  constexpr int m = 4;
  VecX vol = VecX::Zero(g.num_cells()), area = VecX::Zero(g.num_cells());
  // per cell, how many cells of its 3 × 3 × 3 block have φ < 0
  const std::array<Index, 3> one{1, 1, 1};
  std::vector<std::uint8_t> negative(static_cast<size_t>(g.num_cells()));
  parallel_for_each(g.num_cells(), 4 * kGrain, [&](Index c) { negative[c] = gc.phi[c] < 0; });
  negative = block_counts(g, std::move(negative), one);
  parallel_for_each(g.num_cells(), kGrain, [&](Index c) {
    if (!gc.open_cell(c)) return;
    if (negative[c] == 0 || whole_block(g, c, negative[c], one)) {
      // φ has one sign over the block: the surface does not cross the cell
      vol[c] = gc.phi[c] < 0 ? 1.0 : 0.0;
      return;
    }
    if (with_area) area[c] = cell_area(gc, c);
    vol[c] = negative_share(gc, c, m);
  });
  out.volume = vol.sum() * g.cell_volume();
  out.area = area.sum();
  return out;
}

}  // namespace

LiquidMeasures liquid_measures(const GridCells& gc) {
  return measure_liquid(gc, true);
}

namespace {

/// The level set's volume (liquid_measures' rule) as a function of a shift d of φ for |d| ≤
/// cap, from one pass: the cells of one sign for every such d are counted once, and each cell
/// the surface may cross keeps φ on its lines (negative_share's), so a shift costs a sum.
/// (φ trilinear shifted by d is the same trilinear plus d: its weights sum to one.)
class ShiftedVolume {
 public:
  ShiftedVolume(const GridCells& gc, double cap) : m_cell_volume(gc.grid.cell_volume()) {
    const GridSpec& g = gc.grid;
    const Index nc = g.num_cells();
    // per cell, how many cells of its 3 × 3 × 3 block are liquid whatever the shift (φ <
    // −cap, counted in the low 5 bits) and air whatever the shift (φ ≥ cap, the bits above)
    const std::array<Index, 3> one{1, 1, 1};
    std::vector<std::uint16_t> tag(static_cast<size_t>(nc));
    parallel_for_each(nc, 4 * kGrain, [&](Index c) {
      tag[c] = gc.phi[c] < -cap ? 1 : (gc.phi[c] >= cap ? 32 : 0);
    });
    tag = block_counts(g, std::move(tag), one);
    // per chunk in parallel, joined in chunk order: the cells in index order (the count of
    // fixed cells is exact in any order)
    std::vector<std::vector<Cell>> found(static_cast<size_t>(num_chunks(nc, kGrain)));
    std::vector<Index> fixed(found.size(), 0);
    parallel_for_chunks(nc, kGrain, [&](Index begin, Index end) {
      const Index k = begin / kGrain;
      for (Index c = begin; c < end; ++c) {
        if (!gc.open_cell(c)) continue;
        // the block's least φ ≥ cap: air whatever the shift
        if (whole_block(g, c, tag[c] >> 5, one)) continue;
        if (whole_block(g, c, tag[c] & 31, one)) {  // its greatest < −cap: liquid whatever
          ++fixed[k];
          continue;
        }
        found[k].push_back({block_range(gc, c), gc.phi[c], c});
      }
    });
    for (size_t k = 0; k < found.size(); ++k) {
      m_fixed += static_cast<double>(fixed[k]);
      m_cells.insert(m_cells.end(), found[k].begin(), found[k].end());
    }
    m_f.resize(m_cells.size() * kValues);
    parallel_for_each(static_cast<Index>(m_cells.size()), 256, [&](Index k) {
      line_values(gc, m_cells[k].cell, kLines, &m_f[k * kValues]);
    });
  }

  double operator()(double d) const {
    // each cell's share in parallel, summed in cell order
    const Index n = static_cast<Index>(m_cells.size());
    m_share.resize(m_cells.size());
    parallel_for_each(n, 1024, [&](Index k) {
      const Cell& c = m_cells[k];
      m_share[k] = sign_change(c.range, d) ? lines_share(&m_f[k * kValues], kLines, d)
                                           : (c.centre + d < 0 ? 1.0 : 0.0);
    });
    double cells = m_fixed;
    for (Index k = 0; k < n; ++k) cells += m_share[k];
    return cells * m_cell_volume;
  }

 private:
  static constexpr int kLines = 4, kValues = 3 * kLines * kLines;
  struct Cell {
    std::array<double, 2> range;  ///< block_range
    double centre;                ///< its own φ
    Index cell;
  };
  double m_cell_volume, m_fixed = 0;
  std::vector<Cell> m_cells;
  std::vector<double> m_f;  ///< kValues per cell: per line, φ at its start, middle and end
  mutable std::vector<double> m_share;  ///< operator()'s per-cell shares
};

}  // namespace

double hold_liquid_volume(GridCells& gc, double target, const LiquidSurfaceParams& sp) {
  const double cap = k_max_volume_shift * sp.radius, tol = 1e-4 * target;
  const ShiftedVolume volume(gc, cap);
  const auto excess_at = [&](double d) { return volume(d) - target; };
  const double f0 = excess_at(0.0);
  double b = 0.0, fb = f0;
  if (target > 0 && std::abs(fb) > tol) {
    // a secant from d = 0 and a tenth of the cap towards the target, then the Illinois false
    // position: the sampled volume has small steps (lines along a surface), which the
    // bracket converges through
    double a = 0.0, fa = fb;
    b = std::copysign(0.1 * cap, fb);
    fb = excess_at(b);
    for (int it = 0; it < 30 && std::abs(fb) > tol && fb != fa; ++it) {
      const double c = std::clamp(b - fb * (b - a) / (fb - fa), -cap, cap);
      if (c == b) break;
      const double fc = excess_at(c);
      if (fc * fb < 0) {  // the root lies between b and c
        a = b;
        fa = fb;
      } else if (fa * fc < 0) {  // still between a and c: halve a's weight
        fa *= 0.5;
      } else {  // no bracket yet: a secant step
        a = b;
        fa = fb;
      }
      b = c;
      fb = fc;
    }
  }
  if (b != 0.0) gc.phi.array() += b;
  set_free_surface(gc, std::move(gc.phi));
  return b != 0.0 ? f0 - fb : 0.0;
}

}  // namespace tetfsi::fluid
