#include "fluid/grid_liquid.hpp"

#include <algorithm>
#include <array>
#include <cmath>

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

/// The trilinear stencil of point x (clamped to the box) on the lattice of axis-a faces, or
/// of the cell centres for a = −1: base index and fractions.
void lattice_stencil(const GridSpec& g, int a, const Vec3& x, std::array<Index, 3>& base,
                     Vec3& frac) {
  for (int b = 0; b < 3; ++b) {
    const double s = (x[b] - g.lo[b]) / g.h[b] - (b == a ? 0.0 : 0.5);
    const Index top = lattice_size(g, b, a) - 1;
    const double sc = std::clamp(s, 0.0, static_cast<double>(top));
    base[b] = std::min<Index>(static_cast<Index>(std::floor(sc)), std::max<Index>(top - 1, 0));
    frac[b] = top > 0 ? sc - static_cast<double>(base[b]) : 0.0;
  }
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

/// fn(ijk, w) for the 8 lattice points of lattice_stencil(g, a, x) and their trilinear
/// weights (corner order).
template <class F>
void for_each_lattice_weight(const GridSpec& g, int a, const Vec3& x, F&& fn) {
  std::array<Index, 3> base{};
  Vec3 frac;
  lattice_stencil(g, a, x, base, frac);
  for (int corner = 0; corner < 8; ++corner) {
    std::array<Index, 3> ijk{};
    double w = 1;
    for (int b = 0; b < 3; ++b) {
      const int up = (corner >> b) & 1;
      ijk[b] = std::min(base[b] + up, lattice_size(g, b, a) - 1);
      w *= up ? frac[b] : 1.0 - frac[b];
    }
    fn(ijk, w);
  }
}

/// fn(face, w) for the 8 faces of axis a around x and their trilinear weights (corner order).
template <class F>
void for_each_face_weight(const GridSpec& g, int a, const Vec3& x, F&& fn) {
  for_each_lattice_weight(g, a, x, [&](const std::array<Index, 3>& ijk, double w) {
    fn(g.face(a, ijk[0], ijk[1], ijk[2]), w);
  });
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
      return std::clamp<Index>(static_cast<Index>(std::floor(z / size)), 0, sl.slabs - 1);
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
  b.start.assign(static_cast<size_t>(nc) + 1, 0);
  std::vector<Index> cell(static_cast<size_t>(np));
  for (Index p = 0; p < np; ++p) {
    cell[p] = g.cell_at(x.row(p).transpose());
    ++b.start[cell[p] + 1];
  }
  for (Index c = 0; c < nc; ++c) b.start[c + 1] += b.start[c];
  b.order.resize(static_cast<size_t>(np));
  std::vector<Index> fill(b.start.begin(), b.start.end() - 1);
  for (Index p = 0; p < np; ++p) b.order[fill[cell[p]]++] = p;
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

VecX liquid_level_set(const GridCells& gc, const MatX3& x, const LiquidSurfaceParams& sp) {
  const GridSpec& g = gc.grid;
  const double R = kernel_radius(g);
  const Vec3 box_lo = g.lo, box_hi = g.hi();
  const ParticleBuckets b = bucket_particles(g, x);
  const Index full = sp.per_axis * sp.per_axis * sp.per_axis;
  std::array<Index, 3> reach{};
  for (int a = 0; a < 3; ++a) reach[a] = static_cast<Index>(std::ceil(R / g.h[a]));
  // A cell whose block of cells within the kernel radius all hold particles is deep inside
  // the liquid: its mean is itself to within the particles' spacing, φ = −r (the sum over
  // its ~1000 neighbours is what φ costs; only cells near the surface need it). Beside a wall
  // the block is clipped to the box: the walls' mirror images fill the rest alike.
  std::vector<std::uint8_t> occupied(static_cast<size_t>(g.num_cells()));
  for (Index c = 0; c < g.num_cells(); ++c) occupied[c] = b.start[c + 1] > b.start[c];
  const auto deep = [&](const std::array<Index, 3>& ijk) {
    std::array<Index, 3> lo{}, hi{};
    for (int a = 0; a < 3; ++a) {
      lo[a] = std::max<Index>(0, ijk[a] - reach[a]);
      hi[a] = std::min<Index>(g.n[a] - 1, ijk[a] + reach[a]);
    }
    for (Index k = lo[2]; k <= hi[2]; ++k)
      for (Index j = lo[1]; j <= hi[1]; ++j)
        for (Index i = lo[0]; i <= hi[0]; ++i)
          if (!occupied[g.cell(i, j, k)]) return false;
    return true;
  };
  VecX phi(g.num_cells());
  parallel_for_each(g.num_cells(), kGrain, [&](Index c) {
    const auto ijk = g.cell_ijk(c);
    const Vec3 xc = g.cell_centre(c);
    if (gc.open_cell(c) && deep(ijk)) {
      phi[c] = -sp.radius;
      return;
    }
    // per axis, the particle's images: itself, and its mirrors in the walls within R
    std::array<int, 3> images{};
    for (int a = 0; a < 3; ++a) images[a] = 1 + (xc[a] - box_lo[a] < R) + (box_hi[a] - xc[a] < R);
    Vec3 mean = Vec3::Zero();
    double wsum = 0;
    for (Index k = std::max<Index>(0, ijk[2] - reach[2]);
         k <= std::min(g.n[2] - 1, ijk[2] + reach[2]); ++k)
      for (Index j = std::max<Index>(0, ijk[1] - reach[1]);
           j <= std::min(g.n[1] - 1, ijk[1] + reach[1]); ++j)
        for (Index i = std::max<Index>(0, ijk[0] - reach[0]);
             i <= std::min(g.n[0] - 1, ijk[0] + reach[0]); ++i) {
          const Index d = g.cell(i, j, k);
          for (Index e = b.start[d]; e < b.start[d + 1]; ++e) {
            const Vec3 p0 = x.row(b.order[e]).transpose();
            for (int m = 0; m < images[0] * images[1] * images[2]; ++m) {
              Vec3 p = p0;
              int rest = m;
              for (int a = 0; a < 3; ++a) {
                const int im = rest % images[a];
                rest /= images[a];
                if (im == 0) continue;  // the particle itself
                const bool lo_wall = xc[a] - box_lo[a] < R && im == 1;
                p[a] = lo_wall ? 2 * box_lo[a] - p0[a] : 2 * box_hi[a] - p0[a];
              }
              const double w = kernel((xc - p).squaredNorm() / (R * R));
              mean += w * p;
              wsum += w;
            }
          }
        }
    // see [ZhuBridson05]: φ(x) = |x − x̄| − r, x̄ the kernel-weighted mean of the particles
    phi[c] = wsum > 0 ? std::min((xc - mean / wsum).norm() - sp.radius, R) : R;
    if (gc.open_cell(c) && 2 * (b.start[c + 1] - b.start[c]) >= full && touches_body(gc, c))
      phi[c] = std::min(phi[c], -sp.face_phi);
  });
  return phi;
}

void set_free_surface(GridCells& gc, VecX phi) {
  const Index nc = gc.grid.num_cells();
  TETFSI_CHECK(phi.size() == nc, "φ has {} entries for {} cells", phi.size(), nc);
  gc.air.assign(static_cast<size_t>(nc), 0);
  for (Index c = 0; c < nc; ++c) gc.air[c] = gc.cell_body[c] < 0 && phi[c] >= 0 ? 1 : 0;
  gc.phi = std::move(phi);
}

Vec3 face_velocity_at(const GridSpec& g, const VecX& u, const Vec3& x) {
  Vec3 v;
  for (int a = 0; a < 3; ++a) {
    double s = 0;
    for_each_face_weight(g, a, x, [&](Index f, double w) {
      if (w != 0) s += w * u[f];
    });
    v[a] = s;
  }
  return v;
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

void extrapolate_faces(const GridSpec& g, std::vector<std::uint8_t> known, int layers, VecX& u) {
  const Index nf = g.num_faces();
  std::vector<std::uint8_t> next;
  for (int layer = 0; layer < layers; ++layer) {
    next = known;
    bool grew = false;
    parallel_for_each(nf, kGrain, [&](Index f) {
      if (known[f]) return;
      const int a = g.face_axis(f);
      const auto ijk = g.face_ijk(f);
      double s = 0;
      int n = 0;
      for (int b = 0; b < 3; ++b)
        for (int dir = -1; dir <= 1; dir += 2) {
          std::array<Index, 3> q = ijk;
          q[b] += dir;
          if (q[b] < 0 || q[b] >= lattice_size(g, b, a)) continue;
          const Index e = g.face(a, q[0], q[1], q[2]);
          if (!known[e]) continue;
          s += u[e];
          ++n;
        }
      if (n == 0) return;
      u[f] = s / n;  // reads only known faces, which this layer does not write
      next[f] = 1;
    });
    for (Index f = 0; f < nf && !grew; ++f) grew = next[f] != known[f];
    known.swap(next);
    if (!grew) break;
  }
  for (Index f = 0; f < nf; ++f)
    if (!known[f]) u[f] = 0.0;
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
  const double eps = 1e-3 * g.h.minCoeff();
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
            const Index q = b.order[e];
            if (q == p) continue;
            const Vec3 r = x - lp.x.row(q).transpose();
            const double dist = r.norm();
            // half the overlap each (the pair's other half moves q), relaxed by 1/2
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
    const Vec3 un = face_velocity_at(g, u, x), uo = face_velocity_at(g, u_old, x);
    // see [ZhuBridson05]: FLIP adds the grid's change, PIC takes the grid's value
    const Vec3 v = lp.v.row(p).transpose();
    lp.v.row(p) = (flip * (v + un - uo) + (1.0 - flip) * un).transpose();
  });
}

namespace {

/// φ trilinear between the cell centres at x (clamped to the box; solid cells read as their
/// nearest values would: the caller only samples non-solid cells).
double phi_at(const GridCells& gc, const Vec3& x) {
  const GridSpec& g = gc.grid;
  double v = 0;
  for_each_lattice_weight(g, -1, x, [&](const std::array<Index, 3>& ijk, double w) {
    if (w != 0) v += w * gc.phi[g.cell(ijk[0], ijk[1], ijk[2])];
  });
  return v;
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

/// Whether cell c's φ changes sign within its 3 × 3 × 3 block (the surface may cross it).
bool near_surface(const GridCells& gc, Index c) {
  return sign_change(block_range(gc, c));
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
  const Vec3 lo = g.cell_centre(c) - 0.5 * g.h;
  const int a = steepest_axis(gc, c), b = (a + 1) % 3, d = (a + 2) % 3;
  for (int l = 0; l < m * m; ++l) {
    Vec3 x = lo;
    x[b] += (l % m + 0.5) / m * g.h[b];
    x[d] += (l / m + 0.5) / m * g.h[d];
    for (int k = 0; k < 3; ++k) {
      f[3 * l + k] = phi_at(gc, x);
      x[a] += 0.5 * g.h[a];
    }
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

/// liquid_measures, its area only `with_area` (the volume alone costs a fifth).
LiquidMeasures measure_liquid(const GridCells& gc, bool with_area) {
  const GridSpec& g = gc.grid;
  LiquidMeasures out;
  if (gc.phi.size() != g.num_cells()) return out;
  constexpr int m = 4;
  const Vec3 step = g.h / m;
  VecX vol = VecX::Zero(g.num_cells()), area = VecX::Zero(g.num_cells());
  parallel_for_each(g.num_cells(), kGrain, [&](Index c) {
    if (!gc.open_cell(c)) return;
    if (!near_surface(gc, c)) {
      vol[c] = gc.phi[c] < 0 ? 1.0 : 0.0;
      return;
    }
    const Vec3 x0 = g.cell_centre(c) - 0.5 * g.h;
    for (int l = 0; with_area && l < m * m * m; ++l) {
      const Vec3 s((l % m + 0.5) / m, ((l / m) % m + 0.5) / m, (l / (m * m) + 0.5) / m);
      const Vec3 x = x0 + s.cwiseProduct(g.h);
      const double f = phi_at(gc, x);
      // a sign change to the next sample along axis a: a surface element of projected area
      // ΔA_a = (h_b h_c / m²) there; Σ_a ΔA_a |n_a| over the crossings is the area
      for (int a = 0; a < 3; ++a) {
        Vec3 y = x;
        y[a] += step[a];
        if (y[a] > g.hi()[a] || (phi_at(gc, y) < 0) == (f < 0)) continue;
        Vec3 grad;
        for (int b = 0; b < 3; ++b) {
          Vec3 lo = 0.5 * (x + y), hi = lo;
          lo[b] -= step[b];
          hi[b] += step[b];
          grad[b] = (phi_at(gc, hi) - phi_at(gc, lo)) / (2 * step[b]);
        }
        const double gn = grad.norm();
        if (gn > 0) area[c] += g.cell_volume() / g.h[a] / (m * m) * std::abs(grad[a]) / gn;
      }
    }
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
    std::vector<std::array<double, 2>> range(static_cast<size_t>(nc));
    parallel_for_each(nc, kGrain, [&](Index c) { range[c] = block_range(gc, c); });
    for (Index c = 0; c < nc; ++c) {
      if (!gc.open_cell(c)) continue;
      if (range[c][0] >= cap) continue;  // air whatever the shift
      if (range[c][1] < -cap) {          // liquid whatever the shift
        m_fixed += 1.0;
        continue;
      }
      m_cells.push_back({range[c], gc.phi[c], c});
    }
    m_f.resize(m_cells.size() * kValues);
    parallel_for_each(static_cast<Index>(m_cells.size()), 256, [&](Index k) {
      line_values(gc, m_cells[k].cell, kLines, &m_f[k * kValues]);
    });
  }

  double operator()(double d) const {
    double cells = m_fixed;
    for (size_t k = 0; k < m_cells.size(); ++k) {
      const Cell& c = m_cells[k];
      cells += sign_change(c.range, d) ? lines_share(&m_f[k * kValues], kLines, d)
                                       : (c.centre + d < 0 ? 1.0 : 0.0);
    }
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
