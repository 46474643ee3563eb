#pragma once
/// @file generate.hpp
/// Meshes generated in code: boxes (and thin boxes = sheets), hollow boxes, balls, spherical
/// shells, bowls, icospheres, tubes. Every volume mesh is conforming with positively oriented
/// tets.
#include "mesh/volume_mesh.hpp"

namespace tetfsi::mesh {

/// An axis-aligned box [lo, hi] cut into cells.x × cells.y × cells.z hexahedra, each split
/// into 6 tets around its main diagonal (Kuhn/Freudenthal split: conforming, no flips
/// needed, all positive). Vertex (i, j, k) has index i + (cells.x+1)(j + (cells.y+1) k).
/// @throws InputError if lo ≥ hi in any axis or any cell count < 1.
VolumeMesh make_box(const Vec3& lo, const Vec3& hi, const Vec3i& cells);

/// A closed, outward-oriented icosphere: the icosahedron with each triangle split into 4
/// `subdivisions` times, vertices projected on the sphere (20·4^s triangles, 10·4^s + 2
/// vertices).
/// @throws InputError if radius ≤ 0 or not finite, or subdivisions outside 0..7.
SurfaceMesh make_icosphere(const Vec3& centre, double radius, int subdivisions);

/// A spherical shell: the icosphere of `subdivisions` (make_icosphere) extruded radially into
/// `layers` equal layers between the two radii; each prism (triangle × layer) is cut into 3
/// tets by the index order of its triangle's vertices (the quad over edge (vi, vj), vi < vj, gets
/// the diagonal from vi's inner to vj's outer corner), so neighbouring prisms conform. Vertex
/// v of layer k (k = 0 at inner_radius … layers at outer_radius) has index v + k·(10·4^s + 2),
/// at centre + r_k · (unit icosphere vertex v); 3·layers·20·4^s tets. Boundary: the outer
/// icosphere (normals outward) and the inner one (normals toward the centre, out of the solid
/// into the cavity). Volume: (R_o³ − R_i³) × the unit icosphere's.
/// @param centre (m), @param inner_radius, outer_radius 0 < R_i < R_o (m)
/// @throws InputError for non-finite values, R_i ≤ 0, R_i ≥ R_o, subdivisions outside 0..7,
///   layers outside 1..10000.
VolumeMesh make_spherical_shell(const Vec3& centre, double inner_radius, double outer_radius,
                                int subdivisions, int layers);

/// A solid ball whose boundary is make_icosphere(centre, radius, subdivisions): concentric
/// icospheres, the coarsest (the icosahedron, at radius / 2^s) coned to the centre (20 tets),
/// each level l = 1..s taking the radii [R 2^(l−1−s), R 2^(l−s)] in round(0.825 · 2^l)
/// layers of geometric thickness (about 0.8 × the local edge, so edges stay ≈ R / 2^s
/// throughout): the first layer of a level a transition (7 tets per coarse triangle, under
/// its 4 children), the others prisms split like make_spherical_shell's (conforming).
/// Min dihedral 29.5° and max ≤ 140.3° for s = 1..4 (tests/mesh/test_generate.cpp).
/// s = 2: 162 surface vertices, 2 880 tets.
/// @throws InputError if radius ≤ 0 or anything is not finite, or subdivisions outside 0..6.
VolumeMesh make_ball(const Vec3& centre, double radius, int subdivisions);

/// A box [lo, hi] with one closed box-shaped cavity [lo + t, hi − t] (t = wall_thickness on
/// all six sides): the tensor grid with lines lo, lo + t, hi − t, hi in each axis, the cavity
/// span cut into `cells` equal cells and each wall into round(t / cavity cell size) (at least
/// one) equal cells, Kuhn-split like make_box, the cavity's cells dropped and their unused
/// vertices removed. Boundary: the outer box (normals outward) and the cavity's box (normals
/// into the cavity). Walls much thinner than the cavity cells give flat wall cells (one
/// cell across the wall, cavity-sized along it); give more cells to keep them shapely.
/// @throws InputError for non-finite values, lo ≥ hi, t ≤ 0, 2 t ≥ hi − lo in any axis (no
///   cavity), a cell count < 1, or a mesh too large for int indices.
VolumeMesh make_hollow_box(const Vec3& lo, const Vec3& hi, double wall_thickness,
                           const Vec3i& cells);

/// A tube: the hollow cylinder inner_radius ≤ r ≤ outer_radius around the line through
/// `centre` along axis `axis` (0, 1, 2 = x, y, z), spanning centre ± length/2 along it, open
/// at both ends. A structured (r, θ, s) grid: radial_cells equal layers between the radii,
/// around_cells equal sectors θ_j = 2π j / around_cells, axial_cells equal slices; each
/// curved cell Kuhn-split into 6 tets like make_box's in index space (i, j, k) = (r, θ, s),
/// which is conforming, also across the seam θ = 2π ≡ 0 (the split is the same in every
/// cell, so it is periodic in j), and positive (with the right-handed frame (u, v, w) =
/// (e_(axis+1), e_(axis+2), e_axis), the map (r, θ, s) ↦ centre + r (cos θ u + sin θ v) + s w
/// is orientation-preserving and each cell's cross-section a convex trapezoid). Vertex (i, j, k)
/// (i = 0 at inner_radius … radial_cells at outer_radius, j = 0 … around_cells − 1 with θ = 0
/// along u, k = 0 at centre − length/2 along the axis) has index
/// i + (radial_cells + 1)(j + around_cells k); 6 · radial_cells · around_cells · axial_cells
/// tets. Boundary (one closed surface, a torus: Euler characteristic 0): the outer
/// around_cells-gon prism (normals outward), the inner one (normals toward the axis, out of
/// the solid into the bore) and the two annular ends (normals ∓axis). Volume: the polygonal
/// annulus × length, ½ n sin(2π/n)(R_o² − R_i²) · length with n = around_cells (inscribed:
/// below π (R_o² − R_i²) · length by 1 − sin(2π/n) / (2π/n), 1.1 % for n = 24). Cells are
/// (R_o − R_i)/radial_cells × about 2π R / n × length/axial_cells; the tets are as flat as that
/// aspect: 2 × 24 × 16 cells at R 0.08 / 0.1, length 0.8 (1 : 2.5 : 5) give min dihedral 11.2°,
/// max 97.5° (tests/mesh/test_generate.cpp).
/// @param centre (m), @param inner_radius, outer_radius 0 < R_i < R_o (m), @param length > 0 (m)
/// @throws InputError for non-finite values, R_i ≤ 0, R_i ≥ R_o, length ≤ 0, axis outside
///   0..2, around_cells < 6, radial_cells or axial_cells < 1, or a mesh too large for int
///   indices.
VolumeMesh make_tube(const Vec3& centre, int axis, double inner_radius, double outer_radius,
                     double length, int radial_cells, int around_cells, int axial_cells);

/// A bowl: the lower half (z ≤ centre.z) of the spherical shell inner_radius ≤ |x − centre| ≤
/// outer_radius, open upward, its rim the annulus on the plane z = centre.z. The unit
/// hemisphere is an equiangular cube sphere (the bottom face of the cube [−m, m]³, m =
/// cells / 2, and the lower halves of its four sides, lattice squares cut along the shorter
/// diagonal: `cells` edges from the bottom to the rim along the meridians through the side
/// faces' centres, 4·cells around the rim), extruded radially into `layers` equal layers and
/// each prism cut into 3 tets by vertex index order (as make_spherical_shell: conforming,
/// positive). Boundary (one closed surface): the outer hemisphere (normals outward), the inner
/// one (normals toward the centre, into the bowl) and the rim (normals +z). 6·cells²
/// triangles per layer, 18·layers·cells² tets. Turn it with bodies[].transform.
/// @param centre the centre of the spheres, on the rim's plane (m)
/// @param inner_radius, outer_radius 0 < R_i < R_o (m)
/// @throws InputError for non-finite values, R_i ≤ 0, R_i ≥ R_o, cells odd or outside 2..512,
///   layers outside 1..10000.
VolumeMesh make_bowl(const Vec3& centre, double inner_radius, double outer_radius, int cells,
                     int layers);

}  // namespace tetfsi::mesh
