/// @file remesh.cpp
/// The fluid remesher (remesh.hpp): the driver, which runs the stages of RemeshContext
/// (remesh_stages.hpp) in order and times them, and stage 0, the validation of the inputs.
/// The stages: graded BCC vertex placement on a balanced octree and solid surface vertices
/// refined until their triangles are Gabriel (remesh_lattice.cpp, remesh_surface.cpp),
/// Delaunay with CGAL (delaunay.cpp), conformity recovery by Steiner points on the solid
/// surface (remesh_recovery.cpp), removal of the cells inside solids by flood fill + winding
/// number and face tagging (remesh_classify.cpp). No CGAL here: this file compiles in seconds.
#include "mesh/remesh.hpp"

#include <array>
#include <string>

#include <fmt/format.h>

#include "core/error.hpp"
#include "core/log.hpp"
#include "core/timer.hpp"
#include "mesh/delaunay.hpp"
#include "mesh/remesh_stages.hpp"
#include "mesh/volume_mesh.hpp"

namespace tetfsi::mesh {

namespace detail {

namespace {

void check_sizing(const Sizing& s) {
  TETFSI_REQUIRE(InputError, std::isfinite(s.surface_size) && s.surface_size > 0,
                 "remesh: sizing.surface_size must be a positive number of metres, got {}",
                 s.surface_size);
  TETFSI_REQUIRE(InputError, std::isfinite(s.far_size) && s.far_size >= s.surface_size,
                 "remesh: sizing.far_size must be finite and at least surface_size ({}), got {}",
                 s.surface_size, s.far_size);
  TETFSI_REQUIRE(InputError, std::isfinite(s.grading) && s.grading > 0,
                 "remesh: sizing.grading must be a positive number, got {}", s.grading);
  TETFSI_REQUIRE(InputError, s.max_cells >= 0, "remesh: sizing.max_cells must be >= 0, got {}",
                 s.max_cells);
}

void check_domain(const FluidDomain& d) {
  TETFSI_REQUIRE(InputError,
                 d.lo.allFinite() && d.hi.allFinite() && (d.lo.array() < d.hi.array()).all(),
                 "remesh: fluid domain needs finite lo < hi in every axis, got [{} {} {}]..[{} {} "
                 "{}]",
                 d.lo.x(), d.lo.y(), d.lo.z(), d.hi.x(), d.hi.y(), d.hi.z());
  TETFSI_REQUIRE(InputError,
                 d.default_kind != FaceKind::Interior && d.default_kind != FaceKind::Solid,
                 "remesh: the domain's default kind must be wall, inflow or open");
  for (std::size_t i = 0; i < d.patches.size(); ++i) {
    const DomainPatch& p = d.patches[i];
    TETFSI_REQUIRE(InputError, p.side >= 0 && p.side < 6,
                   "remesh: patch {} '{}': side must be 0..5 (-x +x -y +y -z +z), got {}", i,
                   p.name, p.side);
    TETFSI_REQUIRE(InputError, p.kind != FaceKind::Interior && p.kind != FaceKind::Solid,
                   "remesh: patch {} '{}': kind must be wall, inflow or open", i, p.name);
    TETFSI_REQUIRE(InputError,
                   p.lo.allFinite() && p.hi.allFinite() && (p.lo.array() < p.hi.array()).all(),
                   "remesh: patch {} '{}': rectangle needs lo < hi, got [{} {}]..[{} {}]", i,
                   p.name, p.lo.x(), p.lo.y(), p.hi.x(), p.hi.y());
  }
}

/// Validate the solids (closed, inside the box, no intersections, no nesting) and gather
/// their triangles.
SolidSet gather_solids(const FluidDomain& domain, const std::vector<SolidSurface>& solids,
                       const std::string& stage = "remesh") {
  SolidSet set;
  set.solids = &solids;
  set.tri_offset.push_back(0);
  for (std::size_t b = 0; b < solids.size(); ++b) {
    const SolidSurface& s = solids[b];
    const std::string who = fmt::format("{}: body {}", stage, s.body);
    validate_closed_surface(SurfaceMesh{s.vertices, s.triangles}, who);
    Vec3 lo = Vec3::Constant(kInf), hi = Vec3::Constant(-kInf);
    for (Index t = 0; t < s.triangles.rows(); ++t) {
      std::array<Vec3, 3> c;
      for (int k = 0; k < 3; ++k) {
        const int v = s.triangles(t, k);
        c[k] = s.vertices.row(v).transpose();
        if (!((c[k].array() > domain.lo.array()).all() &&
              (c[k].array() < domain.hi.array()).all())) {
          throw MeshError(fmt::format(
              "{}: vertex {} of triangle {} at ({:.6g}, {:.6g}, {:.6g}) is not inside the fluid "
              "domain [{:.6g} {:.6g} {:.6g}]..[{:.6g} {:.6g} {:.6g}]: move the body inside or "
              "enlarge the domain",
              who, v, t, c[k].x(), c[k].y(), c[k].z(), domain.lo.x(), domain.lo.y(), domain.lo.z(),
              domain.hi.x(), domain.hi.y(), domain.hi.z()));
        }
      }
      const Vec3 tlo = c[0].cwiseMin(c[1]).cwiseMin(c[2]), thi = c[0].cwiseMax(c[1]).cwiseMax(c[2]);
      lo = lo.cwiseMin(tlo);
      hi = hi.cwiseMax(thi);
      set.corners.push_back(c);
      set.box_lo.push_back(tlo);
      set.box_hi.push_back(thi);
      set.tri_body.push_back(static_cast<int>(b));
    }
    set.body_lo.push_back(lo);
    set.body_hi.push_back(hi);
    set.tri_offset.push_back(static_cast<int>(set.corners.size()));
  }

  // Intersections: self-intersections and overlapping bodies.
  std::vector<TriangleRef> refs(set.corners.size());
  for (std::size_t g = 0; g < refs.size(); ++g) {
    const int b = set.tri_body[g];
    refs[g].group = b;
    for (int k = 0; k < 3; ++k) {
      refs[g].p[k] = set.corners[g][k];
      refs[g].v[k] = solids[b].triangles(set.local(static_cast<int>(g)), k);
    }
  }
  if (auto hit = find_intersecting_triangles(refs)) {
    const int g = hit->first, h = hit->second;
    const int bg = set.tri_body[g], bh = set.tri_body[h];
    if (bg == bh) {
      throw MeshError(fmt::format(
          "{}: body {}: its surface intersects itself (triangles {} and {}): fix the solid "
          "(a fold or an inverted element) or take a smaller time step",
          stage, solids[bg].body, set.local(g), set.local(h)));
    }
    throw MeshError(fmt::format(
        "{}: bodies {} and {} overlap: triangle {} of body {} intersects triangle {} of body "
        "{}; separate them (or add collisions between the bodies)",
        stage, solids[bg].body, solids[bh].body, set.local(g), solids[bg].body, set.local(h),
        solids[bh].body));
  }
  // Nesting without intersection: one body wholly inside another.
  for (std::size_t b = 0; b < solids.size(); ++b) {
    const Vec3 p = solids[b].vertices.row(solids[b].triangles(0, 0)).transpose();
    for (std::size_t c = 0; c < solids.size(); ++c) {
      if (c == b || !((p.array() >= set.body_lo[c].array()).all() &&
                      (p.array() <= set.body_hi[c].array()).all()))
        continue;
      if (winding_number(p, solids[c].vertices, solids[c].triangles) > 0.5) {
        throw MeshError(fmt::format(
            "{}: body {} lies inside body {} (vertex {} is enclosed by it): bodies may not "
            "overlap; move it out (a body inside another's fluid-filled cavity is fine)",
            stage, solids[b].body, solids[c].body, solids[b].triangles(0, 0)));
      }
    }
  }
  return set;
}

}  // namespace

void RemeshContext::check_inputs() {
  check_sizing(sizing);
  check_domain(domain);
  set = gather_solids(domain, solids);
}

void RemeshContext::build_delaunay(IncrementalState* state) {
  bool reuse = state && state->valid && sizing.incremental && state->isotropic == lat.isotropic &&
               state->unit == lat.unit && state->lo == domain.lo;
  if (state && sizing.incremental && !reuse)
    logger().debug("remesh: a full Delaunay: {}",
                   !state->valid ? "no triangulation kept"
                                 : "the lattice's frame changed (cell budget, box or spacing)");
  if (reuse && state->skip > 0) {
    --state->skip;
    reuse = false;
    logger().debug("remesh: a full Delaunay: the last update cost too much ({} more to skip)",
                   state->skip);
  }
  if (state) state->valid = false;  // the triangulation is this remesh's from here on
  if (!reuse) {
    dt.build(dt_pts, sizing.parallel_insertion);
    report.vertices_inserted = static_cast<Index>(dt_pts.size());
    return;
  }
  dt = std::move(state->dt);
  Index removed = 0, inserted = 0;
  report.incremental = dt.update(dt_pts, sizing.incremental_max_cost, removed, inserted);
  report.vertices_removed = report.incremental ? removed : 0;
  report.vertices_inserted = report.incremental ? inserted : static_cast<Index>(dt_pts.size());
  state->backoff = report.incremental ? 0 : std::min(8, std::max(1, 2 * state->backoff));
  state->skip = state->backoff;
  if (!report.incremental)
    logger().debug(
        "remesh: a full Delaunay: {} vertices to remove and {} to insert of {} cost more than "
        "incremental_max_cost = {} of a rebuild (the next {} rebuild without trying)",
        removed, inserted, dt_pts.size(), sizing.incremental_max_cost, state->skip);
}

/// The stages in order, timed (mesh::remesh, Remesher::remesh); `state` (may be null) is the
/// Remesher's.
TetMesh run_stages(RemeshContext& ctx, IncrementalState* state) {
  const double t_start = now_seconds();
  RemeshReport& report = ctx.report;
  ctx.check_inputs();

  // 1–2. Vertex placement and the refined surfaces; coarsen everything if over budget.
  ctx.place_vertices();
  ctx.collect_points();
  report.seconds_placement = now_seconds() - t_start;

  // 3. Delaunay, or the last one updated.
  double t0 = now_seconds();
  ctx.build_delaunay(state);
  report.seconds_delaunay = now_seconds() - t0;

  // 4. Conformity: every solid triangle must be covered by Delaunay faces lying on it.
  t0 = now_seconds();
  ctx.recover_conformity();
  report.seconds_recovery = now_seconds() - t0;

  // 5. Cells inside solids: flood fill between solid faces, one winding number per region.
  t0 = now_seconds();
  ctx.classify_cells();
  ctx.collect_fluid_cells();
  ctx.check_fluid_volume();
  report.seconds_classify = now_seconds() - t0;

  // 6. The TetMesh, tags and provenance.
  t0 = now_seconds();
  TetMesh m = ctx.build_fluid_mesh();
  report.seconds_build = now_seconds() - t0;
  report.seconds_total = now_seconds() - t_start;
  logger().debug(
      "remesh: {} cells in {:.3f} s: placement {:.3f}, Delaunay {:.3f} ({}: {} vertices "
      "removed, {} inserted), recovery {:.3f} ({} + {} rounds: checks {:.3f}, Steiner points "
      "{:.3f}, slivers {:.3f}), classification {:.3f}, TetMesh {:.3f}",
      m.num_tets(), report.seconds_total, report.seconds_placement, report.seconds_delaunay,
      report.incremental ? "incremental" : "full", report.vertices_removed,
      report.vertices_inserted, report.seconds_recovery, report.recovery_rounds,
      report.cleanup_rounds, report.seconds_recovery_check, report.seconds_recovery_insert,
      report.seconds_recovery_slivers, report.seconds_classify, report.seconds_build);
  if (state && ctx.sizing.incremental) {
    state->dt = std::move(ctx.dt);
    state->valid = true;
    state->isotropic = ctx.lat.isotropic;
    state->unit = ctx.lat.unit;
    state->lo = ctx.domain.lo;
  }
  return m;
}

}  // namespace detail

void check_solid_surfaces(const FluidDomain& domain, const std::vector<SolidSurface>& solids,
                          const std::string& stage) {
  detail::gather_solids(domain, solids, stage);
}

// ---------------------------------------------------------------------------------------
// remesh
// ---------------------------------------------------------------------------------------

TetMesh remesh(const FluidDomain& domain, const std::vector<SolidSurface>& solids,
               const Sizing& sizing, RemeshReport* report_out, const RemeshOptions& options) {
  detail::RemeshContext ctx(domain, solids, sizing, options);
  TetMesh m = detail::run_stages(ctx, nullptr);
  if (report_out) *report_out = ctx.report;
  return m;
}

Remesher::Remesher() : m_state(std::make_unique<detail::IncrementalState>()) {}
Remesher::~Remesher() = default;
Remesher::Remesher(Remesher&&) noexcept = default;
Remesher& Remesher::operator=(Remesher&&) noexcept = default;

TetMesh Remesher::remesh(const FluidDomain& domain, const std::vector<SolidSurface>& solids,
                         const Sizing& sizing, RemeshReport* report_out,
                         const RemeshOptions& options) {
  detail::RemeshContext ctx(domain, solids, sizing, options);
  TetMesh m = detail::run_stages(ctx, m_state.get());
  if (report_out) *report_out = ctx.report;
  return m;
}

void Remesher::reset() {
  m_state = std::make_unique<detail::IncrementalState>();
}

MatX4i delaunay_tets(const MatX3& points) {
  std::vector<Vec3> p(points.rows());
  for (Index i = 0; i < points.rows(); ++i) p[i] = points.row(i).transpose();
  return delaunay_of(p);
}

}  // namespace tetfsi::mesh
