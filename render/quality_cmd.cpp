/// @file quality_cmd.cpp
/// `tetfsi quality`: read a .vtu with VTK, summarise its quality, print / JSON / PNG.
#include "render/quality_cmd.hpp"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <map>
#include <ostream>
#include <set>
#include <string_view>

#include <fmt/format.h>
#include <vtkCellTypes.h>
#include <vtkDataArray.h>
#include <vtkIdList.h>
#include <vtkNew.h>
#include <vtkPointData.h>
#include <vtkUnstructuredGrid.h>
#include <vtkXMLUnstructuredGridReader.h>
#include <nlohmann/json.hpp>

#include "core/error.hpp"
#include "io/output.hpp"
#include "mesh/io.hpp"
#include "mesh/tet_mesh.hpp"
#include "mesh/vtk_messages.hpp"
#include "render/raster.hpp"

namespace fs = std::filesystem;

namespace tetfsi::app {

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

/// "vtkTriangle" for VTK_TRIANGLE; "type 77" for ids VTK does not name.
std::string cell_type_name(int type) {
  const char* name = vtkCellTypes::GetClassNameFromTypeId(type);
  return name && std::strcmp(name, "UnknownClass") != 0 ? std::string(name)
                                                        : fmt::format("type {}", type);
}

/// "12 vtkTriangle (type 5), 3 vtkLine (type 3)"; "2 of type 77" for types VTK does not name.
std::string describe_types(const std::vector<std::pair<int, Index>>& types) {
  std::string s;
  for (const auto& [type, count] : types) {
    if (!s.empty()) s += ", ";
    const std::string name = cell_type_name(type);
    s += name.rfind("type ", 0) == 0 ? fmt::format("{} of {}", count, name)
                                     : fmt::format("{} {} (type {})", count, name, type);
  }
  return s;
}

/// Fill `out.vertex_body` from a point-data array, or say in `vertex_body_note` why not.
void read_vertex_body(vtkUnstructuredGrid* grid, VtuTets& out) {
  vtkDataArray* a = grid->GetPointData()->GetArray("vertex_body");
  if (a == nullptr) {
    if (grid->GetPointData()->GetAbstractArray("vertex_body") != nullptr)
      out.vertex_body_note = "it is not a numeric array";
    return;
  }
  const vtkIdType np = grid->GetNumberOfPoints();
  if (a->GetNumberOfComponents() != 1) {
    out.vertex_body_note =
        fmt::format("it has {} components, expected 1", a->GetNumberOfComponents());
    return;
  }
  if (a->GetNumberOfTuples() != np) {
    out.vertex_body_note =
        fmt::format("it has {} values for {} points", a->GetNumberOfTuples(), np);
    return;
  }
  VecXi body(static_cast<Index>(np));
  for (vtkIdType i = 0; i < np; ++i) {
    const double v = a->GetTuple1(i);
    if (!std::isfinite(v) || v != std::round(v) || v < -1.0 || v > 1e9) {
      out.vertex_body_note =
          fmt::format("point {} has value {}, expected -1 (fluid) or a body index >= 0", i, v);
      return;
    }
    body(static_cast<Index>(i)) = static_cast<int>(v);
  }
  out.vertex_body = std::move(body);
}

/// Min of the per-cell min dihedral over cells with no vertex on a solid (vertex_body < 0
/// at all four), as summarize_quality(TetMesh) computes it; NaN if every cell touches one.
double min_dihedral_away(const mesh::TetQuality& q, const MatX4i& tets, const VecXi& body) {
  double away = std::numeric_limits<double>::infinity();
  for (Index t = 0; t < tets.rows(); ++t) {
    bool touches = false;
    for (int k = 0; k < 4; ++k) touches = touches || body(tets(t, k)) >= 0;
    if (!touches) away = std::min(away, q.min_dihedral_deg(t));
  }
  return std::isfinite(away) ? away : kNaN;
}

/// The columns that count things (written as JSON integers).
bool is_count_column(const std::string& name) {
  static const std::set<std::string> counts = {"q_cells",    "q_faces",    "q_interior_faces",
                                               "q_slivers",  "q_inverted", "q_nonpositive_dual",
                                               "q_tiny_dual"};
  return counts.count(name) > 0;
}

/// The columns that need face figures (null without them).
bool is_face_column(const std::string& name) {
  static const std::set<std::string> face = {
      "q_faces",     "q_interior_faces", "q_nonpositive_dual",
      "q_tiny_dual", "q_max_weight",     "q_median_weight"};
  return face.count(name) > 0;
}

nlohmann::ordered_json histogram_json(const mesh::Histogram& h) {
  nlohmann::ordered_json j;
  j["lo"] = h.lo;
  j["hi"] = h.hi;
  j["counts"] = h.counts;
  return j;
}

/// Lines of at most `width` characters, broken at spaces.
std::vector<std::string> wrap(const std::string& text, std::size_t width) {
  std::vector<std::string> lines;
  std::string line;
  std::size_t i = 0;
  while (i < text.size()) {
    const std::size_t j = std::min(text.find(' ', i), text.size());
    const std::string word = text.substr(i, j - i);
    if (!line.empty() && line.size() + 1 + word.size() > width) {
      lines.push_back(line);
      line.clear();
    }
    line += (line.empty() ? "" : " ") + word;
    i = j + 1;
  }
  if (!line.empty()) lines.push_back(line);
  return lines;
}

// ---- the PNG -------------------------------------------------------------------------------

constexpr Rgb kWhite{255, 255, 255};
constexpr Rgb kInk{34, 34, 34};        // titles
constexpr Rgb kMuted{95, 95, 95};      // subtitles, tick labels
constexpr Rgb kAxis{70, 70, 70};       // axes and tick marks
constexpr Rgb kGrid{228, 228, 228};    // horizontal grid lines
constexpr Rgb kPlotBg{250, 250, 251};  // inside the axes
constexpr Rgb kSeparator{210, 210, 214};
constexpr Rgb kMarker{214, 39, 40};  // the extreme-value line
constexpr int kPanelW = kQualityPngWidth / 2;
constexpr int kStripH = 70;  // title strip above the panels
constexpr int kPanelH = (kQualityPngHeight - kStripH) / 2;
static_assert(kStripH + 2 * kPanelH == kQualityPngHeight);

Rgb darker(Rgb c, double f) {
  const auto d = [f](std::uint8_t v) { return static_cast<std::uint8_t>(std::lround(v * f)); };
  return {d(c.r), d(c.g), d(c.b)};
}

/// 987, 9876, 98.8k, 988k, 9.88M: at most 5 characters.
std::string compact_count(Index c) {
  if (c < 10000) return fmt::format("{}", c);
  const double v = static_cast<double>(c);
  if (c < 1000000) return fmt::format("{:.{}f}k", v / 1e3, v < 1e5 ? 1 : 0);
  return fmt::format("{:.{}f}M", v / 1e6, v < 1e7 ? 2 : (v < 1e8 ? 1 : 0));
}

/// Tick label of count `v` on an axis whose top is `top`: 0, 5k, 10k or 0, 2.5M, 5M, 7.5M
/// (as few decimals as the value needs) once the top reaches 10000, so that the labels match.
std::string axis_count(Index v, Index top) {
  if (top < 10000 || v == 0) return fmt::format("{}", v);
  const bool mega = top >= 10000000;
  return fmt::format("{:g}{}", static_cast<double>(v) / (mega ? 1e6 : 1e3), mega ? "M" : "k");
}

/// A round step (1, 2 or 5 × 10^k, at least 1) giving about five ticks up to `top`.
Index nice_step(Index top) {
  const double raw = std::max(1.0, static_cast<double>(top) / 5.0);
  const double mag = std::pow(10.0, std::floor(std::log10(raw)));
  for (const double m : {1.0, 2.0, 5.0, 10.0})
    if (m * mag >= raw) return static_cast<Index>(std::llround(m * mag));
  return static_cast<Index>(std::llround(10.0 * mag));
}

/// One bar chart.
struct Panel {
  const mesh::Histogram* hist = nullptr;
  std::string title, subtitle, x_label, y_label;
  Rgb colour;
  double marker = kNaN;  ///< value to mark with a dashed line (NaN: none)
  std::string marker_label;
  /// shown instead of bars when there is nothing to count (first line large, then wrapped)
  std::vector<std::string> empty_message;
};

/// `s` cut to at most `max_px` wide at `scale`, with "..." where it was cut.
std::string fit(std::string s, int scale, int max_px) {
  if (Image::text_width(s, scale) <= max_px) return s;
  while (!s.empty() && Image::text_width(s + "...", scale) > max_px) s.pop_back();
  return s + "...";
}

/// How the counts above the bars are written.
struct BarLabels {
  int scale = 0;        ///< font scale; 0: no labels
  bool upright = true;  ///< false: turned 90° (reads bottom to top)
  int height = 0;       ///< px the labels need above a bar
};

/// The largest labels that fit their bars (`pitch` px per bin): level at scale 2, turned at
/// scale 2, level at scale 1, or none.
BarLabels choose_bar_labels(const mesh::Histogram& h, int pitch) {
  int widest = 0;
  for (const Index c : h.counts)
    if (c > 0) widest = std::max(widest, Image::text_width(compact_count(c), 1));
  if (2 * widest <= pitch - 4) return {2, true, 7 * 2 + 6};
  if (Image::text_height(2) <= pitch - 6) return {2, false, 2 * widest + 6};
  if (widest <= pitch - 2) return {1, true, 7 + 5};
  return {};
}

constexpr int kLabel = 2;  // font scale of tick and axis labels

/// A panel's plot area (px) and the ranges its axes map onto it.
struct Axes {
  int left = 0, right = 0, top = 0, bottom = 0;
  double lo = 0.0, hi = 1.0;  ///< x: the histogram's range
  Index y_top = 1;            ///< y: the count at the top
  int pw() const { return right - left; }
  int ph() const { return bottom - top; }
  int x_of(double v) const {
    return left + static_cast<int>(std::lround((v - lo) / (hi - lo) * pw()));
  }
  int y_of(double c) const {
    return bottom - static_cast<int>(std::lround(c / static_cast<double>(y_top) * ph()));
  }
};

/// A count to write above its bar: (x, y) is the middle of the bar's top edge less 5 px.
struct CountLabel {
  int x, y;
  std::string text;
};

/// The panel's title and subtitle, and the background of its axes.
void draw_titles(Image& img, int ox, int oy, const Panel& p, const Axes& ax) {
  img.text(ox + 30, oy + 22, fit(p.title, 3, kPanelW - 50), 3, kInk);
  img.text(ox + 30, oy + 58, fit(p.subtitle, 2, kPanelW - 50), 2, kMuted);
  img.fill_rect(ax.left, ax.top, ax.right, ax.bottom, kPlotBg);
}

/// The count at the top of the y axis: a multiple of `step` that leaves `label_height` px for
/// the labels above the bars.
Index y_axis_top(Index largest, Index step, int ph, int label_height) {
  const double needed = static_cast<double>(largest) * ph / std::max(ph / 2, ph - label_height);
  return std::max<Index>(step,
                         step * static_cast<Index>(std::ceil(needed / static_cast<double>(step))));
}

/// y axis: counts from 0 to the top every `step`, with grid lines, and its label.
void draw_y_axis(Image& img, const Axes& ax, Index step, int ox, const std::string& y_label) {
  for (Index v = 0; v <= ax.y_top; v += step) {
    const int y = ax.y_of(static_cast<double>(v));
    if (v > 0) img.hline(ax.left + 1, ax.right - 1, y, kGrid);
    img.hline(ax.left - 6, ax.left - 1, y, kAxis);
    img.text(ax.left - 12, y - 7, axis_count(v, ax.y_top), kLabel, kMuted, Align::Right);
  }
  img.text_up(ox + 22, (ax.top + ax.bottom) / 2, y_label, kLabel, kMuted, Align::Center);
}

/// As few decimals (at most 3) as the bin edges of `h` need.
int edge_decimals(const mesh::Histogram& h) {
  const int bins = static_cast<int>(h.counts.size());
  const double bin_w = (h.hi - h.lo) / bins;
  int decimals = 0;
  while (decimals < 3) {
    bool exact = true;
    for (int b = 0; b <= bins; ++b) {
      const double v = (h.lo + b * bin_w) * std::pow(10.0, decimals);
      exact = exact && std::abs(v - std::round(v)) < 1e-6;
    }
    if (exact) break;
    ++decimals;
  }
  return decimals;
}

/// x axis: a tick at every bin edge, labelled every k bins so that labels keep apart, and its
/// label.
void draw_x_axis(Image& img, const Axes& ax, const mesh::Histogram& h, const std::string& x_label) {
  const int bins = static_cast<int>(h.counts.size());
  const int pw = ax.pw();
  const double bin_w = (h.hi - h.lo) / bins;
  const int decimals = edge_decimals(h);
  const auto tick_text = [&](int b) { return fmt::format("{:.{}f}", h.lo + b * bin_w, decimals); };
  int widest = 0;
  for (int b = 0; b <= bins; ++b)
    widest = std::max(widest, Image::text_width(tick_text(b), kLabel));
  int every = bins;
  for (int k = 1; k <= bins; ++k) {
    if (bins % k == 0 && pw * k / bins >= widest + 24) {
      every = k;
      break;
    }
  }
  for (int b = 0; b <= bins; ++b) {
    const int x = ax.x_of(h.lo + b * bin_w);
    const bool labelled = b % every == 0;
    img.vline(x, ax.bottom + 1, ax.bottom + (labelled ? 6 : 3), kAxis);
    if (labelled) img.text(x, ax.bottom + 12, tick_text(b), kLabel, kMuted, Align::Center);
  }
  img.text((ax.left + ax.right) / 2, ax.bottom + 44, fit(x_label, kLabel, pw + 60), kLabel, kMuted,
           Align::Center);
}

/// Nothing counted: say why in the middle of the axes (first line large, then smaller).
void draw_empty_message(Image& img, const Axes& ax, const std::vector<std::string>& message) {
  int y = ax.top + ax.ph() / 2 - 40;
  for (std::size_t i = 0; i < message.size(); ++i) {
    const int scale = i == 0 ? 3 : 2;
    img.text((ax.left + ax.right) / 2, y, message[i], scale, i == 0 ? kInk : kMuted, Align::Center);
    y += Image::text_height(scale) + (i == 0 ? 14 : 6);
  }
}

/// The bars of the nonzero bins; returns their counts to write (none without `labelled`).
std::vector<CountLabel> draw_bars(Image& img, const Axes& ax, const mesh::Histogram& h, Rgb colour,
                                  bool labelled) {
  const int bins = static_cast<int>(h.counts.size());
  const double bin_w = (h.hi - h.lo) / bins;
  std::vector<CountLabel> counts;
  const int gap = ax.pw() / bins >= 24 ? 3 : 1;
  const Rgb edge = darker(colour, 0.72);
  for (int b = 0; b < bins; ++b) {
    const Index c = h.counts[static_cast<std::size_t>(b)];
    if (c == 0) continue;
    const int x0 = ax.x_of(h.lo + b * bin_w) + gap, x1 = ax.x_of(h.lo + (b + 1) * bin_w) - gap + 1;
    const int y0 = std::min(ax.y_of(static_cast<double>(c)), ax.bottom - 2);  // >= 2 px tall
    img.fill_rect(x0, y0, x1, ax.bottom, colour);
    img.frame_rect(x0, y0, x1, ax.bottom + 1, edge);
    if (labelled) counts.push_back({(x0 + x1) / 2, y0 - 5, compact_count(c)});
  }
  return counts;
}

/// The dashed marker line at `p.marker` (2 px wide, kept inside the axes at the ends of the
/// range) and its label, right of it if it fits in the panel, else left.
void draw_marker(Image& img, const Axes& ax, int ox, const Panel& p) {
  const int x = std::clamp(ax.x_of(std::clamp(p.marker, ax.lo, ax.hi)), ax.left, ax.right - 2);
  img.vline(x, ax.top - 6, ax.bottom - 1, kMarker, 6);
  img.vline(x + 1, ax.top - 6, ax.bottom - 1, kMarker, 6);
  const int w = Image::text_width(p.marker_label, 2);
  if (x + 10 + w <= ox + kPanelW - 10)
    img.text(x + 10, ax.top - 22, p.marker_label, 2, kMarker);
  else
    img.text(x - 8, ax.top - 22, p.marker_label, 2, kMarker, Align::Right);
}

/// The counts above the bars, each on a patch of background so that the marker does not run
/// through them.
void draw_counts(Image& img, const std::vector<CountLabel>& counts, const BarLabels& labels) {
  const int sc = labels.scale;
  for (const CountLabel& l : counts) {
    const int len = Image::text_width(l.text, sc);
    if (labels.upright) {
      img.fill_rect(l.x - len / 2 - 2, l.y - 7 * sc - 2, l.x - len / 2 + len + 2, l.y + 2, kPlotBg);
      img.text(l.x, l.y - 7 * sc, l.text, sc, kInk, Align::Center);
    } else {
      const int x = l.x - 7 * sc / 2 - 1;
      img.fill_rect(x - 2, l.y - len - 2, x + 7 * sc + 2, l.y + 2, kPlotBg);
      img.text_up(x, l.y, l.text, sc, kInk);
    }
  }
}

/// One bar chart in the panel whose top left corner is (ox, oy).
void draw_panel(Image& img, int ox, int oy, const Panel& p) {
  const mesh::Histogram& h = *p.hist;
  Axes ax;
  ax.left = ox + 110;
  ax.right = ox + kPanelW - 36;
  ax.top = oy + 104;
  ax.bottom = oy + kPanelH - 92;
  ax.lo = h.lo;
  ax.hi = h.hi;
  draw_titles(img, ox, oy, p, ax);

  const int bins = static_cast<int>(h.counts.size());
  Index largest = 0;
  for (const Index c : h.counts) largest = std::max(largest, c);
  const BarLabels labels = choose_bar_labels(h, ax.pw() / bins);

  // y axis: counts from 0 to a round top that leaves room for the labels above the bars.
  const Index step = nice_step(largest);
  ax.y_top = y_axis_top(largest, step, ax.ph(), labels.height);
  draw_y_axis(img, ax, step, ox, p.y_label);
  draw_x_axis(img, ax, h, p.x_label);

  // Bars (after the marker line's dashes would hide them), then the marker, then the counts
  // on a patch of background so that the marker does not run through them.
  std::vector<CountLabel> counts;
  if (largest == 0)
    draw_empty_message(img, ax, p.empty_message);
  else
    counts = draw_bars(img, ax, h, p.colour, labels.scale > 0);

  // Axes over the bars' bottom edges.
  img.hline(ax.left - 1, ax.right, ax.bottom, kAxis);
  img.vline(ax.left - 1, ax.top, ax.bottom, kAxis);

  if (std::isfinite(p.marker)) draw_marker(img, ax, ox, p);
  draw_counts(img, counts, labels);
}

std::string fixed(double v, int decimals) {
  return std::isfinite(v) ? fmt::format("{:.{}f}", v, decimals) : std::string("n/a");
}

}  // namespace

// ---- reading -------------------------------------------------------------------------------

VtuTets read_vtu_tets(const fs::path& path) {
  const std::string name = path.string();
  std::error_code ec;
  if (!fs::exists(path, ec)) throw InputError(fmt::format("{}: no such file", name));
  if (fs::is_directory(path, ec))
    throw InputError(fmt::format("{}: is a folder; give a .vtu file", name));
  if (!std::ifstream(path, std::ios::binary))
    throw InputError(fmt::format("{}: cannot read the file: {}", name, std::strerror(errno)));

  const mesh::VtkMessageCapture capture;
  vtkNew<vtkXMLUnstructuredGridReader> reader;
  const mesh::VtkErrorObserver errors(reader);
  if (!reader->CanReadFile(path.c_str())) {
    throw InputError(fmt::format(
        "{}: not a VTK XML unstructured grid (.vtu); expected '<VTKFile type=\"UnstructuredGrid\"'",
        name));
  }
  mesh::check_vtk_xml_header(path);
  reader->SetFileName(path.c_str());
  try {
    reader->Update();
  } catch (const std::exception& e) {  // e.g. a length_error on corrupt compressed data
    throw InputError(
        fmt::format("{}: VTK could not read the file ({}): its data is corrupt", name, e.what()));
  }
  vtkUnstructuredGrid* grid = reader->GetOutput();
  const std::string vtk_message =
      !capture.first_message().empty() ? capture.first_message() : errors.first_message();
  if (!vtk_message.empty() || grid == nullptr) {
    throw InputError(fmt::format("{}: VTK could not read the file: {}", name,
                                 vtk_message.empty() ? "unknown error" : vtk_message));
  }

  VtuTets out;
  const vtkIdType np = grid->GetNumberOfPoints();
  TETFSI_REQUIRE(InputError, np < std::numeric_limits<Index>::max(),
                 "{}: {} points is more than tetfsi can index", name, np);
  out.vertices.resize(static_cast<Index>(np), 3);
  for (vtkIdType i = 0; i < np; ++i) {
    double p[3];
    grid->GetPoint(i, p);
    out.vertices.row(static_cast<Index>(i)) << p[0], p[1], p[2];
  }

  const vtkIdType nc = grid->GetNumberOfCells();
  std::map<int, Index> skipped;
  std::vector<Vec4i> tets;
  tets.reserve(static_cast<std::size_t>(nc));
  vtkNew<vtkIdList> ids;
  for (vtkIdType c = 0; c < nc; ++c) {
    const int type = grid->GetCellType(c);
    if (type != VTK_TETRA) {
      ++skipped[type];
      continue;
    }
    grid->GetCellPoints(c, ids);
    TETFSI_REQUIRE(InputError, ids->GetNumberOfIds() == 4,
                   "{}: cell {} is a VTK_TETRA with {} points, expected 4", name, c,
                   ids->GetNumberOfIds());
    Vec4i t;
    for (int k = 0; k < 4; ++k) {
      const vtkIdType v = ids->GetId(k);
      TETFSI_REQUIRE(InputError, v >= 0 && v < np,
                     "{}: cell {} refers to point {}, but the file has {} points", name, c, v, np);
      t(k) = static_cast<Index>(v);
    }
    tets.push_back(t);
  }
  for (const auto& [type, count] : skipped) {
    out.skipped_types.emplace_back(type, count);
    out.skipped_cells += count;
  }
  if (tets.empty()) {
    throw InputError(
        fmt::format("{}: no tetrahedra (VTK_TETRA cells) in the file; it has {}", name,
                    nc == 0 ? std::string("no cells")
                            : fmt::format("{} cells: {}", nc, describe_types(out.skipped_types))));
  }
  out.tets.resize(static_cast<Index>(tets.size()), 4);
  for (std::size_t t = 0; t < tets.size(); ++t) out.tets.row(static_cast<Index>(t)) = tets[t];
  read_vertex_body(grid, out);
  return out;
}

// ---- figures -------------------------------------------------------------------------------

QualityResult analyze_quality(const VtuTets& in) {
  QualityResult r;
  const bool has_body = in.vertex_body.size() == in.vertices.rows();
  try {
    mesh::TetMesh m = mesh::build_tet_mesh(in.vertices, in.tets);
    if (has_body) m.vertex_body = in.vertex_body;
    r.summary = mesh::summarize_quality(m);
    r.face_figures = true;
  } catch (const MeshError& e) {
    const mesh::TetQuality q = mesh::tet_quality(in.vertices, in.tets);
    r.summary = mesh::summarize_quality(q);
    if (has_body && (in.vertex_body.array() >= 0).any())
      r.summary.min_dihedral_away_deg = min_dihedral_away(q, in.tets, in.vertex_body);
    std::string why = e.what();
    constexpr std::string_view kPrefix = "build_tet_mesh: ";
    if (why.rfind(kPrefix, 0) == 0) why = why.substr(kPrefix.size());
    r.no_face_figures_reason = why;
  }
  return r;
}

// ---- text ----------------------------------------------------------------------------------

std::string format_quality_text(const fs::path& file, const VtuTets& in, const QualityResult& r) {
  std::string s = fmt::format("tetfsi quality: {}\n", file.string());
  s += fmt::format("  {} {}, {} points\n", in.tets.rows(),
                   in.tets.rows() == 1 ? "tet (VTK_TETRA cell)" : "tets (VTK_TETRA cells)",
                   in.vertices.rows());
  if (in.skipped_cells > 0) {
    s += fmt::format("  skipped {} {} not tets: {}\n", in.skipped_cells,
                     in.skipped_cells == 1 ? "cell that is" : "cells that are",
                     describe_types(in.skipped_types));
  }
  if (in.vertex_body.size() > 0) {
    s += fmt::format("  vertex_body: {} of {} points on a solid surface\n",
                     (in.vertex_body.array() >= 0).count(), in.vertex_body.size());
  } else if (!in.vertex_body_note.empty()) {
    s += fmt::format("  vertex_body ignored: {} (every vertex counts as fluid)\n",
                     in.vertex_body_note);
  } else {
    s += "  vertex_body: not in the file (every vertex counts as fluid)\n";
  }
  if (!r.face_figures) {
    s += fmt::format(
        "  face figures (dual lengths, A_f/d_f) not computed: the tets are not a valid, "
        "positively oriented mesh: {}\n",
        r.no_face_figures_reason);
  }
  s += mesh::format_quality_report(r.summary);
  return s;
}

// ---- JSON ----------------------------------------------------------------------------------

std::string quality_json(const fs::path& file, const VtuTets& in, const QualityResult& r) {
  nlohmann::ordered_json j;
  j["file"] = file.string();
  j["points"] = in.vertices.rows();
  j["tets"] = in.tets.rows();
  j["skipped_cells"] = in.skipped_cells;
  j["skipped_cell_types"] = nlohmann::ordered_json::array();
  for (const auto& [type, count] : in.skipped_types) {
    nlohmann::ordered_json t;
    t["type"] = type;
    t["name"] = cell_type_name(type);
    t["count"] = count;
    j["skipped_cell_types"].push_back(t);
  }
  j["vertex_body"] = in.vertex_body.size() > 0;
  j["face_figures"] = r.face_figures;
  j["no_face_figures_reason"] = r.face_figures ? nlohmann::ordered_json(nullptr)
                                               : nlohmann::ordered_json(r.no_face_figures_reason);
  for (const auto& [name, value] : mesh::quality_columns(r.summary)) {
    if (!std::isfinite(value) || (!r.face_figures && is_face_column(name)))
      j[name] = nullptr;  // JSON has no NaN or infinity
    else if (is_count_column(name))
      j[name] = static_cast<long long>(std::llround(value));
    else
      j[name] = value;
  }
  nlohmann::ordered_json& h = j["histograms"];
  h["min_dihedral_deg"] = histogram_json(r.summary.min_dihedral_hist);
  h["max_dihedral_deg"] = histogram_json(r.summary.max_dihedral_hist);
  h["shape"] = histogram_json(r.summary.shape_hist);
  h["relative_dual"] = r.face_figures ? histogram_json(r.summary.relative_dual_hist)
                                      : nlohmann::ordered_json(nullptr);
  return j.dump(2) + "\n";
}

// ---- PNG -----------------------------------------------------------------------------------

void write_quality_png(const fs::path& path, const std::string& title, const VtuTets& in,
                       const QualityResult& r) {
  const mesh::QualitySummary& s = r.summary;
  Image img(kQualityPngWidth, kQualityPngHeight, kWhite);

  // Title strip.
  img.text(30, 14, fit(title, 3, kQualityPngWidth - 60), 3, kInk);
  std::string line = fmt::format("{} tet{}, {} points, volume {:.4g} m^3", in.tets.rows(),
                                 in.tets.rows() == 1 ? "" : "s", in.vertices.rows(), s.volume);
  if (in.skipped_cells > 0) line += fmt::format(" ({} other cells skipped)", in.skipped_cells);
  line += fmt::format("   slivers (< 5 deg): {}   inverted: {}", s.slivers, s.inverted);
  if (r.face_figures)
    line +=
        fmt::format("   faces with d_f <= 0: {}, tiny d_f: {}", s.nonpositive_dual, s.tiny_dual);
  else
    line += "   no face figures";
  img.text(30, 46, fit(line, 2, kQualityPngWidth - 60), 2, kMuted);
  img.hline(0, kQualityPngWidth - 1, kStripH - 1, kSeparator);
  img.vline(kPanelW, kStripH, kQualityPngHeight - 1, kSeparator);
  img.hline(0, kQualityPngWidth - 1, kStripH + kPanelH, kSeparator);

  Panel p[4];
  p[0].hist = &s.min_dihedral_hist;
  p[0].title = "Min dihedral angle per cell";
  p[0].subtitle = fmt::format("min {}   1%: {}   5%: {}   median {}", fixed(s.min_dihedral_deg, 2),
                              fixed(s.min_dihedral_p01, 2), fixed(s.min_dihedral_p05, 2),
                              fixed(s.min_dihedral_p50, 2));
  p[0].x_label = "degrees (regular tet 70.53)";
  p[0].y_label = "cells";
  p[0].colour = {78, 121, 167};
  p[0].marker = s.min_dihedral_deg;
  p[0].marker_label = "min " + fixed(s.min_dihedral_deg, 2);

  p[1].hist = &s.max_dihedral_hist;
  p[1].title = "Max dihedral angle per cell";
  p[1].subtitle = fmt::format("max {}   max radius-edge ratio {:.4g} (regular 0.6124)",
                              fixed(s.max_dihedral_deg, 2), s.max_radius_edge);
  p[1].x_label = "degrees (regular tet 70.53, the least possible)";
  p[1].y_label = "cells";
  p[1].colour = {242, 142, 43};
  p[1].marker = s.max_dihedral_deg;
  p[1].marker_label = "max " + fixed(s.max_dihedral_deg, 2);

  p[2].hist = &s.shape_hist;
  p[2].title = "Shape 6*sqrt(2)*V / l_rms^3 per cell";
  p[2].subtitle = fmt::format("min {}   5%: {}   median {}", fixed(s.min_shape, 4),
                              fixed(s.shape_p05, 4), fixed(s.shape_p50, 4));
  p[2].x_label = "shape (regular tet 1; inverted, < 0, in the first bin)";
  p[2].y_label = "cells";
  p[2].colour = {89, 161, 79};
  p[2].marker = s.min_shape;
  p[2].marker_label = "min " + fixed(s.min_shape, 4);

  p[3].hist = &s.relative_dual_hist;
  p[3].title = "Dual length per interior face";
  p[3].x_label = "d_f / mean edge of the face (<= 0: first bin, > 1: last)";
  p[3].y_label = "faces";
  p[3].colour = {176, 122, 161};
  if (r.face_figures) {
    p[3].subtitle = fmt::format("{} interior faces   d_f <= 0: {}   tiny (< 1e-3): {}",
                                s.interior_faces, s.nonpositive_dual, s.tiny_dual);
    p[3].empty_message = {"no interior faces"};
  } else {
    p[3].subtitle = "not computed";
    p[3].empty_message = {"no face figures"};
    for (const std::string& l : wrap(
             "the tets are not a valid, positively oriented mesh: " + r.no_face_figures_reason, 52))
      p[3].empty_message.push_back(l);
    if (p[3].empty_message.size() > 7) {
      p[3].empty_message.resize(7);
      p[3].empty_message.back() += " ...";
    }
  }

  draw_panel(img, 0, kStripH, p[0]);
  draw_panel(img, kPanelW, kStripH, p[1]);
  draw_panel(img, 0, kStripH + kPanelH, p[2]);
  draw_panel(img, kPanelW, kStripH + kPanelH, p[3]);
  write_png(path, img);
}

// ---- the subcommand ------------------------------------------------------------------------

int quality_command(const fs::path& vtu, const fs::path& json, const fs::path& png,
                    std::ostream& out) {
  const VtuTets in = read_vtu_tets(vtu);
  const QualityResult r = analyze_quality(in);
  out << format_quality_text(vtu, in, r);
  if (!json.empty()) write_text_file_atomic(json, quality_json(vtu, in, r));
  if (!png.empty()) write_quality_png(png, "tetfsi quality: " + vtu.filename().string(), in, r);
  return 0;
}

}  // namespace tetfsi::app
