#pragma once
/// @file quality.hpp
/// Mesh-quality diagnostics for tet meshes: per-cell shape figures, per-face dual lengths
/// and Laplacian weights A_f/d_f, and a summary with percentiles and histograms. A
/// Laplacian with weights A_f/d_f on nearly co-spherical cells is badly conditioned
/// (docs/dev/architecture.md, measured facts), so these figures are what a user checks to trust a
/// dynamic mesh.
///
/// Reference values: a regular tet has every dihedral angle acos(1/3) = 70.529°,
/// radius–edge ratio R / l_min = sqrt(6)/4 = 0.6124 and shape measure 1.
#include <string>
#include <utility>
#include <vector>

#include "core/types.hpp"
#include "mesh/tet_mesh.hpp"

namespace tetfsi::mesh {

/// Per-cell figures, each #T.
struct TetQuality {
  VecX min_dihedral_deg;  ///< smallest of the six dihedral angles (degrees)
  VecX max_dihedral_deg;  ///< largest (degrees)
  VecX radius_edge;  ///< circumradius / shortest edge (regular: 0.6124; slivers can be small too)
  VecX shape;   ///< 6√2 V / l_rms³ (1 for a regular tet, → 0 for flat ones; < 0 if inverted)
  VecX volume;  ///< signed volume (m³)
};

/// The smallest and largest of the six dihedral angles (degrees) of the tet (a, b, c, d),
/// as tet_quality computes them.
std::pair<double, double> dihedral_range_deg(const Vec3& a, const Vec3& b, const Vec3& c,
                                             const Vec3& d);

/// Per-cell figures of any tet mesh (no connectivity needed).
/// @param vertices #V × 3, @param tets #T × 4
TetQuality tet_quality(const MatX3& vertices, const MatX4i& tets);

/// Per-face figures, each #F.
struct FaceQuality {
  VecX dual_length;  ///< d_f (m), as TetMesh::dual_lengths
  VecX weight;       ///< A_f / d_f (m) on interior faces with d_f > 0; +inf for d_f ≤ 0; 0 on the
                     ///< boundary
  VecX relative_dual;  ///< d_f / (mean edge length of the face)
};

FaceQuality face_quality(const TetMesh& m);

/// Equal-width histogram on [lo, hi]; values outside are counted in the end bins (NaN in the
/// first), so the counts sum to values.size(). Bin b is [lo + b w, lo + (b+1) w), the last
/// one closed.
struct Histogram {
  double lo = 0.0, hi = 0.0;
  std::vector<Index> counts;
};

Histogram histogram(const VecX& values, double lo, double hi, int bins);

/// The summary written to stats.csv each step and printed by `tetfsi quality`. Figures over
/// an empty set (no cells, no interior faces) are NaN.
struct QualitySummary {
  Index cells = 0, faces = 0, interior_faces = 0;
  double volume = 0.0;  ///< Σ V_t (m³)
  double min_dihedral_deg = 0.0, max_dihedral_deg = 0.0;
  /// percentiles of per-cell min dihedral, by nearest rank: the value at sorted index
  /// round(p (n − 1))
  double min_dihedral_p01 = 0.0, min_dihedral_p05 = 0.0, min_dihedral_p50 = 0.0;
  /// min dihedral over cells with no vertex on a solid surface (TetMesh::vertex_body < 0 for
  /// all four); equals min_dihedral_deg when there is no solid or no provenance, NaN if every
  /// cell touches a solid
  double min_dihedral_away_deg = 0.0;
  double min_shape = 0.0, shape_p05 = 0.0, shape_p50 = 0.0;
  double max_radius_edge = 0.0;
  double min_volume = 0.0;
  Index slivers = 0;             ///< cells with min dihedral < 5°
  Index inverted = 0;            ///< cells with volume ≤ 0
  Index nonpositive_dual = 0;    ///< interior faces with d_f ≤ 0
  Index tiny_dual = 0;           ///< interior faces with 0 < d_f < 1e-3 × mean edge of the face
  double max_weight = 0.0;       ///< max finite A_f/d_f over interior faces (m)
  double median_weight = 0.0;    ///< median A_f/d_f over interior faces (m), +inf ones included
  Histogram min_dihedral_hist;   ///< per-cell min dihedral on [0, 90]°, 18 bins of 5°
  Histogram max_dihedral_hist;   ///< per-cell max dihedral on [60, 180]°, 12 bins of 10°
  Histogram shape_hist;          ///< shape on [0, 1], 10 bins
  Histogram relative_dual_hist;  ///< interior-face d_f / mean edge on [0, 1], 10 bins
};

/// Summary of a fluid mesh (cells and faces).
QualitySummary summarize_quality(const TetMesh& m);

/// Summary from cell figures only (faces left at 0), for meshes without connectivity.
QualitySummary summarize_quality(const TetQuality& q);

/// Multi-line text report with the figures above and text histograms (bars of '#').
std::string format_quality_report(const QualitySummary& s);

/// The summary's scalar figures as (column name, value) pairs, in a fixed order, for
/// stats.csv ("q_min_dihedral_deg", "q_slivers", ...).
std::vector<std::pair<std::string, double>> quality_columns(const QualitySummary& s);

}  // namespace tetfsi::mesh
