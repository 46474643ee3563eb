/// @file tetrahedralize.cpp
/// Tetrahedralisation of a closed triangle surface with CGAL Mesh_3 (CGAL 5.5 API,
/// Boost.Parameter named arguments). The only Mesh_3 translation unit: ~90 s to compile.
#include "mesh/tetrahedralize.hpp"

#include <cmath>
#include <unordered_map>
#include <utility>
#include <vector>

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Mesh_complex_3_in_triangulation_3.h>
#include <CGAL/Mesh_criteria_3.h>
#include <CGAL/Mesh_triangulation_3.h>
#include <CGAL/Polygon_mesh_processing/self_intersections.h>
#include <CGAL/Polyhedral_mesh_domain_with_features_3.h>
#include <CGAL/Side_of_triangle_mesh.h>
#include <CGAL/Surface_mesh.h>
#include <CGAL/exceptions.h>
#include <CGAL/make_mesh_3.h>

#include "core/error.hpp"
#include "core/log.hpp"
#include "core/timer.hpp"

namespace tetfsi::mesh {

namespace {

using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
using Point = Kernel::Point_3;
using CgalSurface = CGAL::Surface_mesh<Point>;
using Domain = CGAL::Polyhedral_mesh_domain_with_features_3<Kernel, CgalSurface>;
// Sequential: on this machine the parallel mesher measured slower (docs/dev/architecture.md,
// measured facts).
using Triangulation = CGAL::Mesh_triangulation_3<Domain, CGAL::Default, CGAL::Sequential_tag>::type;
using C3t3 = CGAL::Mesh_complex_3_in_triangulation_3<Triangulation, Domain::Corner_index,
                                                     Domain::Curve_index>;
using Criteria = CGAL::Mesh_criteria_3<Triangulation>;

/// A surface edge whose two face normals differ by more than this angle (degrees) is a sharp
/// feature that Mesh_3 protects (CGAL's default): keeps the edges and corners of a box exact,
/// leaves a finely tessellated sphere smooth.
constexpr double kFeatureAngleDeg = 60.0;

CgalSurface to_cgal(const SurfaceMesh& s, const std::string& source) {
  CgalSurface sm;
  std::vector<CgalSurface::Vertex_index> vid;
  vid.reserve(static_cast<std::size_t>(s.num_vertices()));
  for (Index v = 0; v < s.num_vertices(); ++v) {
    vid.push_back(sm.add_vertex(Point(s.vertices(v, 0), s.vertices(v, 1), s.vertices(v, 2))));
  }
  for (Index f = 0; f < s.num_triangles(); ++f) {
    const auto r = s.triangles.row(f);
    const auto face =
        sm.add_face(vid[static_cast<std::size_t>(r(0))], vid[static_cast<std::size_t>(r(1))],
                    vid[static_cast<std::size_t>(r(2))]);
    TETFSI_REQUIRE(MeshError, face != CgalSurface::null_face(),
                   "{}: triangle {} (vertices {} {} {}) cannot be added to a manifold surface "
                   "(two sheets touch at a vertex?); separate the parts or remesh the surface",
                   source, f, r(0), r(1), r(2));
  }
  return sm;
}

/// A surface that passes through itself has no inside: Mesh_3 crashes or grows without bound
/// on one. Names the first pair of triangles that intersect.
void require_no_self_intersection(const CgalSurface& sm, const std::string& source) {
  namespace PMP = CGAL::Polygon_mesh_processing;
  if (!PMP::does_self_intersect(sm)) return;
  using Face = CgalSurface::Face_index;
  std::vector<std::pair<Face, Face>> pairs;
  PMP::self_intersections(sm, std::back_inserter(pairs));
  const auto [a, b] = pairs.empty() ? std::pair<Face, Face>() : pairs.front();
  throw MeshError(fmt::format(
      "{}: the surface intersects itself ({} pair{} of triangles, e.g. triangles {} and {}); "
      "repair it (e.g. in MeshLab or Blender) before meshing",
      source, pairs.size(), pairs.size() == 1 ? "" : "s", static_cast<std::size_t>(a),
      static_cast<std::size_t>(b)));
}

template <class... Options>
C3t3 run_mesher(const Domain& domain, const Criteria& criteria, Options... options) {
  return CGAL::make_mesh_3<C3t3>(domain, criteria, options...);
}

}  // namespace

VolumeMesh tetrahedralize_surface(const SurfaceMesh& surface, const TetrahedralizeParams& params,
                                  const std::string& source) {
  TETFSI_REQUIRE(InputError, std::isfinite(params.cell_size) && params.cell_size > 0.0,
                 "{}: tetrahedralize needs cell_size > 0 (m), got {}", source, params.cell_size);
  TETFSI_REQUIRE(InputError, std::isfinite(params.facet_distance) && params.facet_distance >= 0.0,
                 "{}: tetrahedralize needs facet_distance >= 0 (m; 0 = cell_size / 10), got {}",
                 source, params.facet_distance);
  TETFSI_REQUIRE(InputError, params.facet_angle_deg > 0.0 && params.facet_angle_deg <= 30.0,
                 "{}: facet_angle_deg must be in (0, 30] (Mesh_3 may not terminate above 30), "
                 "got {}",
                 source, params.facet_angle_deg);
  TETFSI_REQUIRE(InputError, params.cell_radius_edge >= 2.0,
                 "{}: cell_radius_edge must be >= 2 (Mesh_3 may not terminate below), got {}",
                 source, params.cell_radius_edge);
  validate_closed_surface(surface, source);

  const double t0 = now_seconds();
  const CgalSurface sm = to_cgal(surface, source);
  require_no_self_intersection(sm, source);
  Domain domain(sm);
  domain.detect_features(kFeatureAngleDeg);

  const double size = params.cell_size;
  const double distance = params.facet_distance > 0.0 ? params.facet_distance : size / 10.0;
  namespace P = CGAL::parameters;
  const Criteria criteria(P::edge_size = size, P::facet_angle = params.facet_angle_deg,
                          P::facet_size = size, P::facet_distance = distance,
                          P::cell_radius_edge_ratio = params.cell_radius_edge, P::cell_size = size);
  C3t3 c3t3;
  // The sliver perturbation and exudation get no time limit: by default CGAL stops each
  // after as many seconds as the refinement took, so a busier machine gave another mesh
  // (the bunny: 5708 or 5710 tets from one binary). Without it, the same input gives the
  // same mesh in every run (tested).
  const auto perturb = P::perturb(P::time_limit = 0);
  try {
    if (params.lloyd && params.exude) {
      c3t3 = run_mesher(domain, criteria, P::lloyd(), perturb, P::exude(P::time_limit = 0));
    } else if (params.lloyd) {
      c3t3 = run_mesher(domain, criteria, P::lloyd(), perturb, P::no_exude());
    } else if (params.exude) {
      c3t3 = run_mesher(domain, criteria, P::no_lloyd(), perturb, P::exude(P::time_limit = 0));
    } else {
      c3t3 = run_mesher(domain, criteria, P::no_lloyd(), perturb, P::no_exude());
    }
  } catch (const CGAL::Failure_exception& e) {
    throw MeshError(
        fmt::format("{}: CGAL Mesh_3 failed ({}); check that the surface does not intersect itself",
                    source, e.message()));
  }

  // Cells in the complex → tets; vertices numbered compactly in order of first use.
  const Triangulation& tr = c3t3.triangulation();
  std::unordered_map<Triangulation::Vertex_handle, Index> index;
  std::vector<Vec3> points;
  std::vector<Vec4i> tets;
  tets.reserve(static_cast<std::size_t>(c3t3.number_of_cells_in_complex()));
  for (auto c = c3t3.cells_in_complex_begin(); c != c3t3.cells_in_complex_end(); ++c) {
    Vec4i tet;
    for (int k = 0; k < 4; ++k) {
      const auto vh = c->vertex(k);
      const auto [it, inserted] = index.try_emplace(vh, static_cast<Index>(points.size()));
      if (inserted) {
        const auto& p = tr.point(vh).point();
        points.emplace_back(p.x(), p.y(), p.z());
      }
      tet(k) = it->second;
    }
    tets.push_back(tet);
  }
  TETFSI_REQUIRE(MeshError, !tets.empty(),
                 "{}: Mesh_3 produced no tets inside the surface; the surface may be smaller "
                 "than cell_size = {} m: decrease cell_size",
                 source, size);

  VolumeMesh m;
  m.vertices.resize(static_cast<Index>(points.size()), 3);
  for (std::size_t v = 0; v < points.size(); ++v) {
    m.vertices.row(static_cast<Index>(v)) = points[v].transpose();
  }
  m.tets.resize(static_cast<Index>(tets.size()), 4);
  // CGAL's cells are positively oriented by its exact predicate, whose sign is that of
  // signed_volume; a near-flat cell's floating-point volume may still disagree, so each tet
  // is checked (validate_volume_mesh then rejects any that is truly degenerate).
  Index num_swapped = 0;
  for (std::size_t t = 0; t < tets.size(); ++t) {
    Vec4i tet = tets[t];
    const double v = signed_volume(
        points[static_cast<std::size_t>(tet(0))], points[static_cast<std::size_t>(tet(1))],
        points[static_cast<std::size_t>(tet(2))], points[static_cast<std::size_t>(tet(3))]);
    if (v < 0.0) {
      std::swap(tet(2), tet(3));
      ++num_swapped;
    }
    m.tets.row(static_cast<Index>(t)) = tet.transpose();
  }
  if (num_swapped > 0) {
    logger().debug("{}: {} of {} Mesh_3 cells had negative floating-point volume; swapped", source,
                   num_swapped, m.num_tets());
  }
  logger().info("{}: Mesh_3 made {} vertices, {} tets from {} surface triangles in {:.2f} s",
                source, m.num_vertices(), m.num_tets(), surface.num_triangles(),
                now_seconds() - t0);
  validate_volume_mesh(m, source + " (tetrahedralized)");
  return m;
}

std::vector<char> inside_surface(const SurfaceMesh& surface, const std::vector<Vec3>& points,
                                 const std::string& source) {
  validate_closed_surface(surface, source);
  const CgalSurface sm = to_cgal(surface, source);
  require_no_self_intersection(sm, source);
  const CGAL::Side_of_triangle_mesh<CgalSurface, Kernel> side(sm);  // an AABB tree, built once
  std::vector<char> inside(points.size());
  for (std::size_t i = 0; i < points.size(); ++i)
    inside[i] = side(Point(points[i].x(), points[i].y(), points[i].z())) == CGAL::ON_BOUNDED_SIDE;
  return inside;
}

}  // namespace tetfsi::mesh
