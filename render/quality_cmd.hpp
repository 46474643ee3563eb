#pragma once
/// @file quality_cmd.hpp
/// `tetfsi quality FILE.vtu [--json FILE] [--png FILE]`: the mesh-quality figures of
/// mesh/quality.hpp for any tetrahedral VTK XML unstructured grid — a tetfsi frame or a mesh
/// from any other tool.
///
/// What it does:
///  1. reads the file's points and its VTK_TETRA cells (vertex order as stored); cells of
///     other types are skipped and counted; a point-data array `vertex_body` (one integer
///     per point, −1 for fluid vertices, a body index for vertices on a solid surface) is
///     kept when present;
///  2. per-cell figures (mesh::tet_quality) for every tet; if the tets are positively
///     oriented and form a valid mesh (mesh::build_tet_mesh accepts them), also the face
///     figures — dual lengths d_f, weights A_f/d_f, faces with d_f ≤ 0 or tiny d_f — through
///     summarize_quality(TetMesh), with `vertex_body` as TetMesh::vertex_body so that "min
///     dihedral away from solids" skips cells touching a solid. Otherwise (inverted or
///     degenerate tets, a face shared by three tets, overlaps) only the cell figures, and the
///     report says why the face figures are missing;
///  3. prints a header (file, tets, points, skipped cells) and mesh::format_quality_report.
///
/// The exit code is 0 whatever the figures are (a bad mesh is a result, not an error);
/// a missing, unreadable or non-VTU file, or one without tets, is an InputError naming it.
///
/// VTK stays inside quality_cmd.cpp (reading) and raster.cpp (PNG); this header only sees
/// plain types.
#include <filesystem>
#include <iosfwd>
#include <string>
#include <utility>
#include <vector>

#include "core/types.hpp"
#include "mesh/quality.hpp"

namespace tetfsi::app {

/// The tets of a `.vtu` as stored, before any check.
struct VtuTets {
  MatX3 vertices;     ///< #V × 3 every point of the file (m), unused ones included
  MatX4i tets;        ///< #T × 4 the VTK_TETRA cells in file order, vertex order as stored
  VecXi vertex_body;  ///< #V from the point-data array `vertex_body`; empty if absent/ignored
  /// Why a `vertex_body` array in the file was not used (wrong size or components); empty
  /// if it was used or is absent.
  std::string vertex_body_note;
  Index skipped_cells = 0;  ///< cells that are not VTK_TETRA
  /// (VTK cell type id, number of cells) of the skipped cells, by increasing type id
  std::vector<std::pair<int, Index>> skipped_types;
};

/// Read the points, VTK_TETRA cells and `vertex_body` of a VTK XML unstructured grid.
/// VTK's own messages are kept off stderr.
/// @throws InputError naming the file if it is missing, unreadable, not a `.vtu`
///   (`<VTKFile type="UnstructuredGrid"`), malformed, a tet refers to a point that does not
///   exist, or it has no VTK_TETRA cell (the message then says which cell types it has).
VtuTets read_vtu_tets(const std::filesystem::path& path);

/// The figures of one mesh.
struct QualityResult {
  mesh::QualitySummary summary;
  /// true if the face figures (faces, dual lengths, weights, relative-dual histogram) were
  /// computed; false leaves them at 0 in `summary`
  bool face_figures = false;
  /// why not, when face_figures is false (build_tet_mesh's one-line message)
  std::string no_face_figures_reason;
};

/// The figures of `in`. Without face figures, `min_dihedral_away_deg` still honours
/// `in.vertex_body` (computed from the cell figures the same way summarize_quality(TetMesh)
/// does).
QualityResult analyze_quality(const VtuTets& in);

/// The report printed by `tetfsi quality`: a header naming `file` with the tet, point and
/// skipped-cell counts, the `vertex_body` status, why face figures are missing (if they
/// are), then mesh::format_quality_report.
std::string format_quality_text(const std::filesystem::path& file, const VtuTets& in,
                                const QualityResult& r);

/// The figures as pretty JSON text:
/// ```json
/// { "file": "...", "points": 27, "tets": 48, "skipped_cells": 0,
///   "skipped_cell_types": [{"type": 5, "name": "vtkTriangle", "count": 12}],
///   "vertex_body": false, "face_figures": true, "no_face_figures_reason": null,
///   "q_cells": 48, "q_min_dihedral_deg": 45.0, ... (every mesh::quality_columns entry),
///   "histograms": { "min_dihedral_deg": {"lo": 0, "hi": 90, "counts": [...]},
///                   "max_dihedral_deg": {...}, "shape": {...}, "relative_dual": {...} } }
/// ```
/// Count columns (q_cells, q_slivers, ...) are integers. A figure that is NaN or infinite
/// (e.g. min dihedral away from solids when every cell touches one) is `null`; without face
/// figures the face columns (q_faces, q_interior_faces, q_nonpositive_dual, q_tiny_dual,
/// q_max_weight, q_median_weight) and the relative-dual histogram are `null` too.
std::string quality_json(const std::filesystem::path& file, const VtuTets& in,
                         const QualityResult& r);

/// Size of the `--png` picture (px): a title strip and 2 × 2 panels of 800 × 600.
inline constexpr int kQualityPngWidth = 1600;
inline constexpr int kQualityPngHeight = 1270;

/// Draw the four histograms of `r.summary` — per-cell min dihedral, max dihedral, shape;
/// interior-face relative dual d_f / mean edge — as bar charts in 2 × 2 panels with axis
/// ticks, labels and the count above each bar, and write them as a kQualityPngWidth ×
/// kQualityPngHeight PNG (atomically). Counts use a linear axis; a bin with at least one
/// entry is drawn at least 2 px tall so that a single sliver among millions shows. A red
/// dashed line marks the summary's extreme value (min dihedral, max dihedral, min shape).
/// @param title the first line of the title strip (e.g. the file name)
/// @throws InputError naming the file if it cannot be written.
void write_quality_png(const std::filesystem::path& path, const std::string& title,
                       const VtuTets& in, const QualityResult& r);

/// The whole subcommand: read `vtu`, print format_quality_text to `out`, and write the JSON
/// and the PNG where those paths are not empty. Returns the exit code (0).
/// @throws InputError (see read_vtu_tets; or an output file that cannot be written)
int quality_command(const std::filesystem::path& vtu, const std::filesystem::path& json,
                    const std::filesystem::path& png, std::ostream& out);

}  // namespace tetfsi::app
