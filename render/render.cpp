/// @file render.cpp
/// `tetfsi render`: the run's frames through VTK's OpenGL renderer, off screen (render.hpp).
#include "render/render.hpp"

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <map>
#include <memory>
#include <ostream>
#include <regex>
#include <set>
#include <sstream>

#include <fmt/format.h>
#include <sys/wait.h>
#include <unistd.h>
#include <vtkActor.h>
#include <vtkCamera.h>
#include <vtkCellArray.h>
#include <vtkCellData.h>
#include <vtkCellDataToPointData.h>
#include <vtkColorTransferFunction.h>
#include <vtkCubeSource.h>
#include <vtkCutter.h>
#include <vtkDataArray.h>
#include <vtkDataArraySelection.h>
#include <vtkDataSet.h>
#include <vtkDataSetSurfaceFilter.h>
#include <vtkErrorCode.h>
#include <vtkFloatArray.h>
#include <vtkImageData.h>
#include <vtkLookupTable.h>
#include <vtkMatrix4x4.h>
#include <vtkNew.h>
#include <vtkOutlineSource.h>
#include <vtkPNGWriter.h>
#include <vtkPiecewiseFunction.h>
#include <vtkPlane.h>
#include <vtkPlaneSource.h>
#include <vtkPointData.h>
#include <vtkPoints.h>
#include <vtkPolyData.h>
#include <vtkPolyDataMapper.h>
#include <vtkPolyDataNormals.h>
#include <vtkProperty.h>
#include <vtkRenderWindow.h>
#include <vtkRenderer.h>
#include <vtkScalarBarActor.h>
#include <vtkSmartVolumeMapper.h>
#include <vtkTextActor.h>
#include <vtkTextProperty.h>
#include <vtkUnstructuredGrid.h>
#include <vtkVolume.h>
#include <vtkVolumeProperty.h>
#include <vtkWindowToImageFilter.h>
#include <vtkXMLImageDataReader.h>
#include <vtkXMLPolyDataReader.h>
#include <vtkXMLUnstructuredGridReader.h>
#include <nlohmann/json.hpp>

#include "core/error.hpp"
#include "core/log.hpp"
#include "io/export.hpp"
#include "io/output.hpp"
#include "mesh/io.hpp"
#include "mesh/vtk_messages.hpp"
#include "render/frame_data.hpp"
#include "render/headless_display.hpp"
#include "render/run_folder.hpp"

namespace fs = std::filesystem;
using json = nlohmann::json;

namespace tetfsi::app {

namespace {

constexpr const char* kAxisNames[3] = {"x", "y", "z"};

// ---- reading frames ----------------------------------------------------------------------------

/// The arrays of a dataset's cell and point data: name → components.
struct ArrayInfo {
  std::map<std::string, int> cell, point;
  bool has(const std::string& name) const { return cell.count(name) || point.count(name); }
  std::string names() const {
    std::set<std::string> all;
    for (const auto& [n, c] : cell) all.insert(n);
    for (const auto& [n, c] : point) all.insert(n);
    std::string out;
    for (const std::string& n : all) out += (out.empty() ? "" : ", ") + n;
    return out.empty() ? "none" : out;
  }
};

ArrayInfo arrays_of(vtkDataSet* data) {
  ArrayInfo info;
  for (int i = 0; i < data->GetCellData()->GetNumberOfArrays(); ++i)
    if (vtkDataArray* a = data->GetCellData()->GetArray(i); a && a->GetName())
      info.cell[a->GetName()] = a->GetNumberOfComponents();
  for (int i = 0; i < data->GetPointData()->GetNumberOfArrays(); ++i)
    if (vtkDataArray* a = data->GetPointData()->GetArray(i); a && a->GetName())
      info.point[a->GetName()] = a->GetNumberOfComponents();
  return info;
}

/// Reads one kind of frame file (.vtu or .vti) again and again, with only the arrays asked
/// for; reports VTK's errors as one InputError naming the file.
class FrameReader {
 public:
  /// Read `file` with only `array` (all arrays if empty). The dataset stays valid until the
  /// next read.
  vtkDataSet* read(const fs::path& file, const std::string& array) {
    const std::string ext = file.extension().string();
    vtkXMLReader* reader = nullptr;
    if (ext == ".vti")
      reader = m_image;
    else
      reader = m_grid;
    if (ext != ".vti") mesh::check_vtk_xml_header(file);
    const mesh::VtkMessageCapture capture;
    reader->SetFileName(file.string().c_str());
    reader->UpdateInformation();
    for (vtkDataArraySelection* sel :
         {reader->GetCellDataArraySelection(), reader->GetPointDataArraySelection()}) {
      if (array.empty())
        sel->EnableAllArrays();
      else {
        sel->DisableAllArrays();
        sel->EnableArray(array.c_str());
      }
    }
    try {
      reader->Update();
    } catch (const std::exception& e) {
      throw InputError(
          fmt::format("{}: VTK could not read the frame ({})", file.string(), e.what()));
    }
    vtkDataSet* out = vtkDataSet::SafeDownCast(reader->GetOutputDataObject(0));
    if (!capture.first_message().empty() || out == nullptr || out->GetNumberOfPoints() == 0)
      throw InputError(
          fmt::format("{}: VTK could not read the frame: {}", file.string(),
                      capture.first_message().empty() ? "no points" : capture.first_message()));
    return out;
  }

 private:
  vtkNew<vtkXMLUnstructuredGridReader> m_grid;
  vtkNew<vtkXMLImageDataReader> m_image;
};

/// Values of `name` in `data` (cell data first; a vector as its magnitude).
std::vector<double> values_of(vtkDataSet* data, const std::string& name) {
  vtkDataArray* a = data->GetCellData()->GetArray(name.c_str());
  if (!a) a = data->GetPointData()->GetArray(name.c_str());
  std::vector<double> v;
  if (!a) return v;
  const int nc = a->GetNumberOfComponents();
  v.reserve(static_cast<size_t>(a->GetNumberOfTuples()));
  for (vtkIdType i = 0; i < a->GetNumberOfTuples(); ++i) {
    double s = 0.0;
    if (nc == 1)
      s = a->GetComponent(i, 0);
    else
      for (int c = 0; c < nc; ++c) s += a->GetComponent(i, c) * a->GetComponent(i, c);
    if (nc > 1) s = std::sqrt(s);
    if (std::isfinite(s)) v.push_back(s);
  }
  return v;
}

/// [p0.5, p99.5] of `v`, from 0 if v ≥ 0 and p0.5 < p99.5 / 4; never empty (a constant field
/// gets ± a little).
std::array<double, 2> robust_range(std::vector<double> v) {
  if (v.empty()) return {0.0, 1.0};
  std::sort(v.begin(), v.end());
  auto at = [&](double q) { return v[static_cast<size_t>(q * double(v.size() - 1))]; };
  std::array<double, 2> r = {at(0.005), at(0.995)};
  if (v.front() >= 0.0 && r[0] < 0.25 * r[1]) r[0] = 0.0;  // stress, smoke, speeds: from 0
  if (!(r[1] > r[0])) {
    const double pad = std::max(1e-12, 1e-3 * std::abs(r[0]));
    r = {r[0] - pad, r[1] + pad};
  }
  return r;
}

/// The unit of a frame array (io/output.hpp), for the colour bar's title.
std::string unit_of(const std::string& name, const char* separator = " ") {
  static const std::map<std::string, std::string> units = {{"smoke_density", "kg/m^3"},
                                                           {"pressure", "Pa"},
                                                           {"temperature", "K"},
                                                           {"velocity", "m/s"},
                                                           {"vorticity", "1/s"},
                                                           {"divergence", "1/s"},
                                                           {"von_mises_stress", "Pa"},
                                                           {"displacement", "m"},
                                                           {"volume", "m^3"},
                                                           {"external_force", "N"},
                                                           {"q_min_dihedral_deg", "deg"},
                                                           {"q_max_dihedral_deg", "deg"},
                                                           {"normal_velocity", "m/s"}};
  const auto it = units.find(name);
  return it == units.end() ? name : fmt::format("{}{}({})", name, separator, it->second);
}

// ---- colours -----------------------------------------------------------------------------------

/// A 256-entry lookup table through `stops` (r, g, b in [0, 1], evenly spaced).
vtkSmartPointer<vtkLookupTable> make_lut(const std::vector<std::array<double, 3>>& stops,
                                         const std::array<double, 2>& range) {
  auto lut = vtkSmartPointer<vtkLookupTable>::New();
  const int n = 256;
  lut->SetNumberOfTableValues(n);
  for (int i = 0; i < n; ++i) {
    const double s = double(i) / (n - 1) * double(stops.size() - 1);
    const size_t k = std::min(stops.size() - 2, static_cast<size_t>(s));
    const double f = s - double(k);
    std::array<double, 3> c;
    for (int j = 0; j < 3; ++j) c[j] = (1 - f) * stops[k][j] + f * stops[k + 1][j];
    lut->SetTableValue(i, c[0], c[1], c[2], 1.0);
  }
  lut->SetRange(range[0], range[1]);
  lut->SetVectorModeToMagnitude();  // a vector array is coloured by its length
  lut->Build();
  return lut;
}

/// Matplotlib's "inferno" at 9 stops: smoke bright on a dark fluid.
const std::vector<std::array<double, 3>> k_inferno = {
    {0.001, 0.000, 0.014}, {0.106, 0.047, 0.255}, {0.294, 0.047, 0.420},
    {0.472, 0.110, 0.431}, {0.647, 0.173, 0.376}, {0.812, 0.267, 0.275},
    {0.929, 0.412, 0.145}, {0.988, 0.608, 0.024}, {0.988, 1.000, 0.643}};
/// Moreland's "cool to warm" (ParaView's default): signed fields such as pressure.
const std::vector<std::array<double, 3>> k_cool_warm = {{0.230, 0.299, 0.754},
                                                        {0.552, 0.690, 0.996},
                                                        {0.865, 0.865, 0.865},
                                                        {0.958, 0.603, 0.482},
                                                        {0.706, 0.016, 0.150}};
/// Bodies: pale blue-grey rubber turning orange and red under stress.
const std::vector<std::array<double, 3>> k_body = {
    {0.78, 0.82, 0.88}, {0.96, 0.80, 0.45}, {0.90, 0.42, 0.12}, {0.62, 0.05, 0.05}};
/// The smoke's volume: thin smoke grey, the emitted density white; its opacity per
/// k_smoke_unit × the box's largest side at the top of the range (a jet of a tenth of the box
/// across at the emitted density hides most of what is behind it).
constexpr std::array<double, 3> k_smoke_grey = {0.55, 0.57, 0.62};
constexpr double k_smoke_opacity = 0.8, k_smoke_unit = 0.025;
/// The dark background behind the smoke (its bottom colour; the colour bar's 0).
constexpr std::array<double, 3> k_background_dark = {0.07, 0.08, 0.10};
/// The liquid's surface: the bodies in it show through.
constexpr double k_liquid_opacity = 0.7;

// ---- the scene's actors ----------------------------------------------------------------------

void style_text(vtkTextProperty* p, int size, bool bold = false) {
  p->SetFontFamilyToArial();
  p->SetFontSize(size);
  p->SetBold(bold);
  p->SetItalic(false);
  p->SetShadow(false);
  p->SetColor(0.12, 0.12, 0.14);
  p->SetBackgroundRGBA(1.0, 1.0, 1.0, 0.6);  // readable over the slice and the bodies
}

vtkSmartPointer<vtkScalarBarActor> make_bar(vtkLookupTable* lut, const std::string& title,
                                            bool horizontal, int height) {
  auto bar = vtkSmartPointer<vtkScalarBarActor>::New();
  bar->SetLookupTable(lut);
  bar->SetTitle(title.c_str());
  bar->SetNumberOfLabels(5);
  bar->SetLabelFormat("%.3g");
  bar->SetUnconstrainedFontSize(true);
  bar->SetVerticalTitleSeparation(6);
  bar->SetBarRatio(horizontal ? 0.35 : 0.3);
  style_text(bar->GetTitleTextProperty(), std::max(12, height / 48), true);
  style_text(bar->GetLabelTextProperty(), std::max(11, height / 56));
  bar->GetPositionCoordinate()->SetCoordinateSystemToNormalizedViewport();
  if (horizontal) {
    bar->SetOrientationToHorizontal();
    bar->SetTextPositionToPrecedeScalarBar();
    bar->SetPosition(0.25, 0.015);
    bar->SetWidth(0.42);
    bar->SetHeight(0.13);
  } else {  // beside the box, on the plain background: no backdrop behind the text
    bar->GetTitleTextProperty()->SetBackgroundOpacity(0.0);
    bar->GetLabelTextProperty()->SetBackgroundOpacity(0.0);
    bar->SetOrientationToVertical();
    bar->SetTextPositionToPrecedeScalarBar();
    bar->SetPosition(0.86, 0.16);
    bar->SetWidth(0.12);
    bar->SetHeight(0.66);
  }
  return bar;
}

/// Actors of the scene's obstacles clipped to `box`: planes as quads (axis-aligned normals),
/// boxes as boxes.
void add_obstacles(vtkRenderer* renderer, const json& scene, const Box& box) {
  for (const json& o : scene.value("obstacles", json::array())) {
    vtkSmartPointer<vtkPolyDataAlgorithm> source;
    if (o.value("type", "") == "plane") {
      const Vec3 n = o.contains("normal") ? vec3_of(o["normal"]) : Vec3(0, 0, 1);
      const Vec3 p = o.contains("point") ? vec3_of(o["point"]) : Vec3::Zero();
      int axis = -1;
      for (int a = 0; a < 3; ++a)
        if (std::abs(n(a)) > 0.999 * n.norm()) axis = a;
      if (axis < 0 || p(axis) <= box.lo(axis) || p(axis) >= box.hi(axis)) continue;
      const int u = (axis + 1) % 3, v = (axis + 2) % 3;
      Vec3 origin = box.lo, p1 = box.lo, p2 = box.lo;
      origin(axis) = p1(axis) = p2(axis) = p(axis);
      p1(u) = box.hi(u);
      p2(v) = box.hi(v);
      vtkNew<vtkPlaneSource> plane;
      plane->SetOrigin(origin.data());
      plane->SetPoint1(p1.data());
      plane->SetPoint2(p2.data());
      source = plane;
    } else if (o.value("type", "") == "box" && o.contains("lo") && o.contains("hi")) {
      const Vec3 lo = vec3_of(o["lo"]).cwiseMax(box.lo), hi = vec3_of(o["hi"]).cwiseMin(box.hi);
      if ((hi - lo).minCoeff() <= 0.0) continue;
      vtkNew<vtkCubeSource> cube;
      cube->SetBounds(lo(0), hi(0), lo(1), hi(1), lo(2), hi(2));
      source = cube;
    } else {
      continue;
    }
    vtkNew<vtkPolyDataMapper> mapper;
    mapper->SetInputConnection(source->GetOutputPort());
    vtkNew<vtkActor> actor;
    actor->SetMapper(mapper);
    actor->GetProperty()->SetColor(0.55, 0.53, 0.50);
    actor->GetProperty()->SetOpacity(0.6);
    actor->GetProperty()->SetAmbient(0.3);
    renderer->AddActor(actor);
  }
}

/// The view direction (from the focal point to the camera) for a slice normal to `axis`: an
/// oblique view from the front (−y), the slice's side, and above.
Vec3 view_direction(int axis) {
  switch (axis) {
    case 0:
      return Vec3(-1.0, -0.55, 0.45).normalized();
    case 1:
      return Vec3(-0.35, -1.0, 0.4).normalized();
    default:
      return Vec3(0.15, -1.0, 1.05).normalized();
  }
}

/// Write the window's picture as a PNG (through `<png>.tmp`, renamed).
void write_window_png(vtkRenderWindow* window, const fs::path& png) {
  vtkNew<vtkWindowToImageFilter> grab;
  grab->SetInput(window);
  grab->SetInputBufferTypeToRGB();
  grab->ReadFrontBufferOff();
  grab->Update();
  fs::path tmp = png;
  tmp += ".tmp";
  // Open it ourselves first: VTK 9.1's PNG writer leaks libpng's structs when it cannot
  // (raster.cpp), and our message names the reason.
  if (!std::ofstream(tmp, std::ios::binary))
    throw InputError(
        fmt::format("cannot write '{}': {} (check that the folder exists and is "
                    "writable)",
                    png.string(), std::strerror(errno)));
  vtkNew<vtkPNGWriter> writer;
  writer->SetCompressionLevel(6);
  std::string why;
  {
    const mesh::VtkMessageCapture capture;
    writer->SetInputConnection(grab->GetOutputPort());
    writer->SetFileName(tmp.c_str());
    writer->Write();
    why = capture.first_message();
  }
  std::error_code ec;
  if (writer->GetErrorCode() != vtkErrorCode::NoError || !why.empty()) {
    fs::remove(tmp, ec);
    throw InputError(fmt::format("cannot write '{}': {}", png.string(),
                                 why.empty() ? "the PNG writer failed" : why));
  }
  fs::rename(tmp, png, ec);
  if (ec) {
    fs::remove(tmp, ec);
    throw InputError(fmt::format("cannot write '{}': {}", png.string(), ec.message()));
  }
}

/// Choose the arrays and check they exist, from the first frame to draw.
struct ColorChoice {
  std::string fluid;    ///< the slice's or the volume's array ("" : neither)
  std::string bodies;   ///< the bodies' array ("" : plain colour)
  bool volume = false;  ///< the fluid as the smoke's volume (of `fluid`), not a slice
};

ColorChoice choose_arrays(const RunIndex& run, const RenderOptions& opt, const FrameFiles& frame,
                          FrameReader& fluid_reader, FrameReader& body_reader) {
  ArrayInfo fluid, bodies;
  if (!frame.fluid.empty()) fluid = arrays_of(fluid_reader.read(frame.fluid, ""));
  if (!frame.bodies.empty()) bodies = arrays_of(body_reader.read(frame.bodies.front(), ""));
  const bool slice = !frame.fluid.empty();
  auto listing = [&] {
    std::string s;
    if (slice)
      s += fmt::format("the fluid's ({}): {}", frame.fluid.filename().string(), fluid.names());
    if (!frame.bodies.empty())
      s += fmt::format("{}the bodies' ({}): {}", slice ? "; " : "",
                       frame.bodies.front().filename().string(), bodies.names());
    return s;
  };
  ColorChoice c;
  c.bodies = opt.body_color.empty() ? std::string("von_mises_stress") : opt.body_color;
  const bool any_deformable = std::count(run.kinematic.begin(), run.kinematic.end(), false) > 0;
  if (!opt.body_color.empty() && !bodies.has(c.bodies))
    throw InputError(fmt::format("--body-color: no array '{}' in the frame of step {}; {}",
                                 c.bodies, frame.step, listing()));
  if (!bodies.has(c.bodies) || (opt.body_color.empty() && !any_deformable)) c.bodies.clear();
  if (slice)
    c.fluid =
        opt.color.empty() ? (run.emitted_smoke > 0.0 ? "smoke_density" : "pressure") : opt.color;
  if (!opt.color.empty()) {
    if (slice && fluid.has(opt.color)) return c;
    if (bodies.has(opt.color)) {  // a body array: colours the bodies, the slice keeps its default
      c.bodies = opt.color;
      if (slice) c.fluid = run.emitted_smoke > 0.0 ? "smoke_density" : "pressure";
      if (slice && !fluid.has(c.fluid)) c.fluid.clear();
      return c;
    }
    throw InputError(fmt::format("--color: no array '{}' in the frame of step {}; arrays: {}",
                                 opt.color, frame.step, listing()));
  }
  if (slice && !fluid.has(c.fluid)) c.fluid.clear();
  // a liquid: its surface and no slice (the slice would hide it and show the air's p = 0),
  // unless --slice asks for one
  if (run.has_liquid && !opt.slice && !opt.slice_view) c.fluid.clear();
  return c;
}

/// The arrays (choose_arrays), and whether the fluid is drawn as the smoke's volume: a scene
/// that emits smoke, its smoke_density to draw, no liquid, and no slice asked for.
ColorChoice choose_colors(const RunIndex& run, const RenderOptions& opt, const FrameFiles& frame,
                          FrameReader& fluid_reader, FrameReader& body_reader) {
  ColorChoice c = choose_arrays(run, opt, frame, fluid_reader, body_reader);
  c.volume = c.fluid == "smoke_density" && run.emitted_smoke > 0.0 && !run.has_liquid &&
             !opt.slice && !opt.slice_view;
  return c;
}

/// Zoom and shift `cam` (its window centre) so that the corners of `box` fill the region
/// [x0, x1] × [y0, y1] of normalised device coordinates, as far as the aspect allows.
void fit_box(vtkCamera* cam, const Box& box, double aspect, std::array<double, 2> x,
             std::array<double, 2> y) {
  for (int pass = 0; pass < 4; ++pass) {
    vtkMatrix4x4* m = cam->GetCompositeProjectionTransformMatrix(aspect, -1, 1);
    double lo[2] = {1e300, 1e300}, hi[2] = {-1e300, -1e300};
    for (int k = 0; k < 8; ++k) {
      const double p[4] = {k & 1 ? box.hi(0) : box.lo(0), k & 2 ? box.hi(1) : box.lo(1),
                           k & 4 ? box.hi(2) : box.lo(2), 1.0};
      double q[4];
      m->MultiplyPoint(p, q);
      for (int a = 0; a < 2; ++a) {
        lo[a] = std::min(lo[a], q[a] / q[3]);
        hi[a] = std::max(hi[a], q[a] / q[3]);
      }
    }
    const double zoom = std::min((x[1] - x[0]) / (hi[0] - lo[0]), (y[1] - y[0]) / (hi[1] - lo[1]));
    double wc[2];
    cam->GetWindowCenter(wc);
    // The window centre moves the picture by −wc; a zoom scales it about the centre.
    const double shift_x = 0.5 * (lo[0] + hi[0]) - 0.5 * (x[0] + x[1]) / zoom;
    const double shift_y = 0.5 * (lo[1] + hi[1]) - 0.5 * (y[0] + y[1]) / zoom;
    cam->SetWindowCenter((wc[0] + shift_x) * zoom, (wc[1] + shift_y) * zoom);
    cam->Zoom(zoom);
  }
}

/// The sampling of a tet fluid for the smoke's volume: voxels of the scene's
/// fluid.mesh.surface_size (the mesh's finest cells), each the mean of 2³ samples.
VoxelOptions smoke_voxels(const RunIndex& run) {
  VoxelOptions v;
  const json& fl = run.scene.value("fluid", json::object());
  const json& m = fl.is_object() ? fl.value("mesh", json::object()) : json::object();
  if (m.is_object() && m.contains("surface_size") && m["surface_size"].is_number())
    v.voxel_size = m["surface_size"].get<double>();
  else if (run.domain)
    v.voxel_size = (run.domain->hi - run.domain->lo).maxCoeff() / 64.0;
  v.subsamples = 2;
  return v;
}

/// `v` (dims voxels, x fastest) filtered by [1 2 1] / 4 along each axis (the edges
/// repeated): the tet fluid's piecewise-constant cells, sampled, no longer show as blotches.
VecX smooth_121(const VecX& v, const std::array<Index, 3>& dims) {
  VecX a = v, b(v.size());
  const Index stride[3] = {1, dims[0], dims[0] * dims[1]};
  for (int axis = 0; axis < 3; ++axis) {
    for (Index c = 0; c < a.size(); ++c) {
      const Index i = (c / stride[axis]) % dims[axis];
      const Index lo = i > 0 ? c - stride[axis] : c, hi = i + 1 < dims[axis] ? c + stride[axis] : c;
      b[c] = 0.25 * a[lo] + 0.5 * a[c] + 0.25 * a[hi];
    }
    std::swap(a, b);
  }
  return a;
}

/// The smoke density of the fluid frame `file` on voxels, as VTK image data with a point at
/// each voxel's centre: a grid frame's (.vti) cells as they are, a tet frame (.vtu) sampled
/// by voxelize.
vtkSmartPointer<vtkImageData> smoke_image(const fs::path& file, FrameReader& reader,
                                          const VoxelOptions& voxels) {
  auto image = vtkSmartPointer<vtkImageData>::New();
  if (file.extension() == ".vti") {
    auto* grid = vtkImageData::SafeDownCast(reader.read(file, "smoke_density"));
    vtkDataArray* density = grid ? grid->GetCellData()->GetArray("smoke_density") : nullptr;
    if (density == nullptr)
      throw InputError(fmt::format("{}: no cell array 'smoke_density'", file.string()));
    int dims[3];
    double origin[3], spacing[3];
    grid->GetDimensions(dims);
    grid->GetOrigin(origin);
    grid->GetSpacing(spacing);
    image->SetDimensions(std::max(dims[0] - 1, 1), std::max(dims[1] - 1, 1),
                         std::max(dims[2] - 1, 1));
    image->SetOrigin(origin[0] + 0.5 * spacing[0], origin[1] + 0.5 * spacing[1],
                     origin[2] + 0.5 * spacing[2]);
    image->SetSpacing(spacing);
    image->GetPointData()->SetScalars(density);
    return image;
  }
  const VoxelFrame v = voxelize(read_tet_fluid_frame(file, true), voxels);
  const VecX smooth = smooth_121(v.density, v.dims);
  image->SetDimensions(static_cast<int>(v.dims[0]), static_cast<int>(v.dims[1]),
                       static_cast<int>(v.dims[2]));
  image->SetOrigin(v.origin.data());
  image->SetSpacing(v.spacing.data());
  vtkNew<vtkFloatArray> density;
  density->SetName("smoke_density");
  density->SetNumberOfTuples(v.size());
  for (Index i = 0; i < v.size(); ++i) density->SetValue(i, static_cast<float>(smooth[i]));
  image->GetPointData()->SetScalars(density);
  return image;
}

/// The liquid's closed surface of a grid frame (`.vti`): io's liquid_surface, the one
/// construction the export's PLY uses too (the contour φ = 0 capped on the box's walls, so that
/// the water reads as a body; the run's liquid.vtp, a free surface, is open there), with point
/// normals for the shading.
vtkSmartPointer<vtkPolyData> closed_liquid_surface(const fs::path& vti) {
  const ExportSurface s = liquid_surface(read_grid_fluid_frame(vti));
  vtkNew<vtkPoints> points;
  points->SetNumberOfPoints(static_cast<vtkIdType>(s.points.rows()));
  for (Index i = 0; i < s.points.rows(); ++i)
    points->SetPoint(i, s.points(i, 0), s.points(i, 1), s.points(i, 2));
  vtkNew<vtkCellArray> triangles;
  for (Index t = 0; t < s.triangles.rows(); ++t) {
    const vtkIdType ids[3] = {s.triangles(t, 0), s.triangles(t, 1), s.triangles(t, 2)};
    triangles->InsertNextCell(3, ids);
  }
  vtkNew<vtkPolyData> poly;
  poly->SetPoints(points);
  poly->SetPolys(triangles);
  vtkNew<vtkPolyDataNormals> normals;  // the triangles face out of the liquid already
  normals->SetInputData(poly);
  normals->SplittingOff();
  normals->ConsistencyOff();
  normals->AutoOrientNormalsOff();
  normals->Update();
  return normals->GetOutput();
}

/// Everything drawn: one window reused for every frame.
class FrameRenderer {
 public:
  FrameRenderer(const RunIndex& run, const RenderOptions& opt, const ColorChoice& colors,
                const SlicePlane& slice, const Box& view_box,
                const std::array<double, 2>& fluid_range, const std::array<double, 2>& body_range)
      : m_run(run), m_opt(opt), m_colors(colors), m_slice(slice), m_voxels(smoke_voxels(run)) {
    m_window->SetOffScreenRendering(1);
    m_window->SetSize(opt.width, opt.height);
    m_window->SetMultiSamples(0);
    m_window->AddRenderer(m_renderer);
    m_renderer->GradientBackgroundOn();
    if (colors.volume) {  // dark, so that the grey-white smoke shows
      m_renderer->SetBackground(k_background_dark[0], k_background_dark[1], k_background_dark[2]);
      m_renderer->SetBackground2(0.25, 0.27, 0.31);
    } else {
      m_renderer->SetBackground(1.0, 1.0, 1.0);
      m_renderer->SetBackground2(0.84, 0.87, 0.91);
    }
    m_renderer->SetUseFXAA(true);
    if (run.domain) add_outline(view_box);  // a scene without fluid: no box
    add_obstacles(m_renderer, run.scene, view_box);
    if (colors.volume)
      add_volume(view_box, fluid_range);
    else if (!colors.fluid.empty())
      add_slice(view_box, fluid_range);
    if (!colors.bodies.empty()) {
      m_body_lut = make_lut(k_body, body_range);
      m_renderer->AddActor2D(make_bar(m_body_lut, unit_of(colors.bodies), true, opt.height));
    }
    add_bodies();
    if (run.has_liquid) add_liquid();
    add_titles();
    place_camera(view_box);
  }

  /// Draw `frame` and write it to `png`.
  RenderedFrame draw(const FrameFiles& frame, const fs::path& png) {
    if (m_colors.volume)
      update_volume(frame);
    else if (!m_colors.fluid.empty())
      update_slice(frame);
    update_liquid(frame);
    update_bodies(frame);
    m_title->SetInput(
        fmt::format("{}    t = {:.3f} s    step {}", m_run.name, frame.time, frame.step).c_str());
    m_window->Render();
    if (m_colors.volume)
      logger().debug("smoke volume: vtkSmartVolumeMapper render mode {} (1 ray cast, 2 GPU)",
                     m_volume_mapper->GetLastUsedRenderMode());
    write_window_png(m_window, png);

    RenderedFrame out;
    out.step = frame.step;
    out.time = frame.time;
    out.png = png;
    vtkMatrix4x4* m = m_renderer->GetActiveCamera()->GetCompositeProjectionTransformMatrix(
        double(m_opt.width) / m_opt.height, -1, 1);
    for (int i = 0; i < 4; ++i)
      for (int j = 0; j < 4; ++j) out.world_to_ndc(i, j) = m->GetElement(i, j);
    return out;
  }

 private:
  /// The slice of `frame`'s fluid (hidden if the frame has none).
  void update_slice(const FrameFiles& frame) {
    if (frame.fluid.empty()) {
      m_slice_actor->VisibilityOff();
      return;
    }
    vtkDataSet* fluid = m_fluid_reader.read(frame.fluid, m_colors.fluid);
    const bool on_cells = fluid->GetCellData()->GetArray(m_colors.fluid.c_str()) != nullptr;
    if (on_cells) {
      m_to_points->SetInputData(fluid);
      m_to_points->PassCellDataOff();
      m_cutter->SetInputConnection(m_to_points->GetOutputPort());
    } else {
      m_cutter->SetInputData(fluid);
    }
    m_slice_actor->VisibilityOn();
  }

  /// The smoke of `frame` on voxels, handed to the volume's mapper (hidden without a fluid).
  void update_volume(const FrameFiles& frame) {
    m_volume->SetVisibility(!frame.fluid.empty());
    if (!frame.fluid.empty())
      m_volume_mapper->SetInputData(smoke_image(frame.fluid, m_fluid_reader, m_voxels));
  }

  /// The liquid's surface of `frame` (hidden if the frame has none).
  void update_liquid(const FrameFiles& frame) {
    if (!m_run.has_liquid) return;
    m_liquid_actor->SetVisibility(!frame.liquid.empty());
    if (frame.fluid.extension() == ".vti") {  // closed along the walls: see the water's body
      m_liquid_mapper->SetInputData(closed_liquid_surface(frame.fluid));
    } else if (!frame.liquid.empty()) {
      m_liquid_reader->SetFileName(frame.liquid.string().c_str());
      m_liquid_reader->Update();
      m_liquid_mapper->SetInputConnection(m_liquid_reader->GetOutputPort());
    }
  }

  /// The bodies' surfaces of `frame`, coloured by their array.
  void update_bodies(const FrameFiles& frame) {
    for (size_t b = 0; b < m_bodies.size(); ++b) {
      Body& body = *m_bodies[b];
      vtkDataSet* data = body.reader.read(frame.bodies[b], m_colors.bodies);
      body.surface->SetInputData(data);
      if (!m_colors.bodies.empty()) {
        const bool on_cells = data->GetCellData()->GetArray(m_colors.bodies.c_str()) != nullptr;
        if (on_cells)
          body.mapper->SetScalarModeToUseCellFieldData();
        else
          body.mapper->SetScalarModeToUsePointFieldData();
      }
    }
  }

  /// The fluid box's outline.
  void add_outline(const Box& box) {
    vtkNew<vtkOutlineSource> outline;
    outline->SetBounds(box.lo(0), box.hi(0), box.lo(1), box.hi(1), box.lo(2), box.hi(2));
    vtkNew<vtkPolyDataMapper> mapper;
    mapper->SetInputConnection(outline->GetOutputPort());
    vtkNew<vtkActor> actor;
    actor->SetMapper(mapper);
    if (m_colors.volume)
      actor->GetProperty()->SetColor(0.62, 0.64, 0.68);  // on the dark background
    else
      actor->GetProperty()->SetColor(0.25, 0.25, 0.28);
    actor->GetProperty()->SetLineWidth(1.5);
    m_renderer->AddActor(actor);
  }

  /// The slice pipeline (cell data to points, cutter, mapper) and its colour bar.
  void add_slice(const Box& box, const std::array<double, 2>& range) {
    const std::string& array = m_colors.fluid;
    const bool signed_map = array == "pressure" || array == "divergence";
    m_fluid_lut = make_lut(signed_map ? k_cool_warm : k_inferno, range);
    m_plane->SetNormal(m_slice.axis == 0, m_slice.axis == 1, m_slice.axis == 2);
    Vec3 origin = box.center();
    origin(m_slice.axis) = m_slice.value;
    m_plane->SetOrigin(origin.data());
    m_cutter->SetCutFunction(m_plane);
    m_cutter->SetInputConnection(m_to_points->GetOutputPort());
    m_slice_mapper->SetInputConnection(m_cutter->GetOutputPort());
    m_slice_mapper->SetLookupTable(m_fluid_lut);
    m_slice_mapper->SetScalarModeToUsePointFieldData();
    m_slice_mapper->SelectColorArray(array.c_str());
    m_slice_mapper->SetUseLookupTableScalarRange(true);
    m_slice_mapper->ScalarVisibilityOn();
    m_slice_actor->SetMapper(m_slice_mapper);
    // Unlit: the slice's colours are the colour bar's exactly.
    m_slice_actor->GetProperty()->SetAmbient(1.0);
    m_slice_actor->GetProperty()->SetDiffuse(0.0);
    m_renderer->AddActor(m_slice_actor);
    m_renderer->AddActor2D(make_bar(m_fluid_lut, unit_of(array, "\n"), false, m_opt.height));
  }

  /// The smoke's volume (its voxels set per frame): grey to white, its opacity rising from
  /// range[0] to range[1], in `k_smoke_opacity` per `k_smoke_unit` of the box's largest side;
  /// a grey colour bar on the right.
  void add_volume(const Box& box, const std::array<double, 2>& range) {
    vtkNew<vtkColorTransferFunction> color;
    color->AddRGBPoint(range[0], k_smoke_grey[0], k_smoke_grey[1], k_smoke_grey[2]);
    color->AddRGBPoint(range[1], 1.0, 1.0, 1.0);
    vtkNew<vtkPiecewiseFunction> opacity;  // quadratic: thin smoke lets the bodies show
    for (int i = 0; i <= 10; ++i) {
      const double u = 0.1 * i;
      opacity->AddPoint(range[0] + u * (range[1] - range[0]), k_smoke_opacity * u * u);
    }
    m_volume_property->SetColor(color);
    m_volume_property->SetScalarOpacity(opacity);
    m_volume_property->SetScalarOpacityUnitDistance(k_smoke_unit * (box.hi - box.lo).maxCoeff());
    m_volume_property->SetInterpolationTypeToLinear();
    m_volume_property->ShadeOff();
    m_volume_mapper->SetBlendModeToComposite();
    // A still picture: the same samples in every frame, whatever the time a render takes.
    m_volume_mapper->InteractiveAdjustSampleDistancesOff();
    m_volume_mapper->AutoAdjustSampleDistancesOff();
    m_volume->SetMapper(m_volume_mapper);
    m_volume->SetProperty(m_volume_property);
    m_renderer->AddVolume(m_volume);
    m_fluid_lut = make_lut({k_background_dark, {1.0, 1.0, 1.0}}, range);
    auto bar = make_bar(m_fluid_lut, unit_of(m_colors.fluid, "\n"), false, m_opt.height);
    bar->GetTitleTextProperty()->SetColor(0.9, 0.9, 0.92);
    bar->GetLabelTextProperty()->SetColor(0.9, 0.9, 0.92);
    m_renderer->AddActor2D(bar);
  }

  /// The liquid's surface (liquid/liquid_<step>.vtp): water blue, lit, a little glossy.
  void add_liquid() {
    m_liquid_mapper->ScalarVisibilityOff();
    m_liquid_actor->SetMapper(m_liquid_mapper);
    m_liquid_actor->GetProperty()->SetColor(0.22, 0.48, 0.85);
    m_liquid_actor->GetProperty()->SetAmbient(0.3);  // no black where it faces away
    m_liquid_actor->GetProperty()->SetSpecular(0.4);
    m_liquid_actor->GetProperty()->SetSpecularPower(30);
    m_liquid_actor->GetProperty()->SetOpacity(k_liquid_opacity);  // the bodies show through
    m_renderer->SetUseDepthPeeling(true);
    m_renderer->SetMaximumNumberOfPeels(8);
    m_renderer->AddActor(m_liquid_actor);
  }

  /// One surface actor per body, coloured through m_body_lut (kinematic bodies: plain).
  void add_bodies() {
    for (size_t b = 0; b < m_run.body_names.size(); ++b) {
      m_bodies.push_back(std::make_unique<Body>());
      Body& body = *m_bodies.back();
      body.surface->SetInputData(vtkSmartPointer<vtkUnstructuredGrid>::New());
      body.mapper->SetInputConnection(body.surface->GetOutputPort());
      // Kinematic bodies are rigid: their stress is round-off, drawn in the plain colour.
      if (m_body_lut && !(m_run.kinematic[b] && m_opt.body_color.empty() &&
                          m_colors.bodies == "von_mises_stress")) {
        body.mapper->SetLookupTable(m_body_lut);
        body.mapper->SelectColorArray(m_colors.bodies.c_str());
        body.mapper->SetUseLookupTableScalarRange(true);
        body.mapper->ScalarVisibilityOn();
      } else {
        body.mapper->ScalarVisibilityOff();
      }
      body.actor->SetMapper(body.mapper);
      body.actor->GetProperty()->SetColor(k_body[0][0], k_body[0][1], k_body[0][2]);
      body.actor->GetProperty()->SetOpacity(m_opt.body_opacity);
      body.actor->GetProperty()->SetSpecular(0.2);
      body.actor->GetProperty()->SetSpecularPower(20);
      m_renderer->AddActor(body.actor);
    }
    if (m_opt.body_opacity < 1.0) {
      m_renderer->SetUseDepthPeeling(true);
      m_renderer->SetMaximumNumberOfPeels(8);
    }
  }

  /// Font sizes and margins (px) of the title lines, from the picture's height.
  int title_size() const { return std::max(14, m_opt.height / 30); }
  int subtitle_size() const { return std::max(11, m_opt.height / 50); }
  int margin() const { return m_opt.height / 45; }

  /// The title (scene, time, step; set per frame) and what the slice and bodies show.
  void add_titles() {
    const int h = m_opt.height;
    style_text(m_title->GetTextProperty(), title_size(), true);
    m_title->SetDisplayPosition(margin(), h - margin() - title_size());
    m_renderer->AddActor2D(m_title);
    style_text(m_subtitle->GetTextProperty(), subtitle_size());
    m_subtitle->GetTextProperty()->SetColor(0.3, 0.3, 0.34);
    m_subtitle->SetDisplayPosition(margin(), h - 2 * margin() - title_size() - subtitle_size());
    std::string sub;
    if (m_colors.volume)
      sub = fmt::format("smoke volume: {}", m_colors.fluid);
    else if (!m_colors.fluid.empty())
      sub = fmt::format("slice {} = {:.4g} m: {}", kAxisNames[m_slice.axis], m_slice.value,
                        m_colors.fluid);
    if (!m_colors.bodies.empty())
      sub += fmt::format("{}bodies: {}", sub.empty() ? "" : "   |   ", m_colors.bodies);
    m_subtitle->SetInput(sub.c_str());
    m_renderer->AddActor2D(m_subtitle);
  }

  /// A fixed camera on the box: every frame of a run lines up. The box fills the part of the
  /// picture the title and the colour bars leave free.
  void place_camera(const Box& box) {
    vtkCamera* cam = m_renderer->GetActiveCamera();
    const Vec3 c = box.center();
    const Vec3 eye = c + view_direction(m_slice.axis);
    cam->SetFocalPoint(c.data());
    cam->SetPosition(eye.data());
    cam->SetViewUp(0, 0, 1);
    cam->SetViewAngle(30);
    double bounds[6] = {box.lo(0), box.hi(0), box.lo(1), box.hi(1), box.lo(2), box.hi(2)};
    m_renderer->ResetCamera(bounds);
    const double h = m_opt.height;
    const double title_ndc =
        2.0 * (2 * margin() + title_size() + subtitle_size() + m_opt.height / 40) / h;
    fit_box(cam, box, double(m_opt.width) / m_opt.height,
            {-0.97, m_colors.fluid.empty() ? 0.97 : 0.62},
            {m_colors.bodies.empty() ? -0.95 : -0.66, 1.0 - title_ndc});
    cam->Zoom(m_opt.zoom);
    m_renderer->ResetCameraClippingRange(bounds);
  }

  struct Body {
    FrameReader reader;
    vtkNew<vtkDataSetSurfaceFilter> surface;
    vtkNew<vtkPolyDataMapper> mapper;
    vtkNew<vtkActor> actor;
  };
  const RunIndex& m_run;
  const RenderOptions& m_opt;
  ColorChoice m_colors;
  SlicePlane m_slice;
  VoxelOptions m_voxels;  ///< the tet fluid's sampling for the smoke's volume
  vtkNew<vtkRenderWindow> m_window;
  vtkNew<vtkRenderer> m_renderer;
  vtkSmartPointer<vtkLookupTable> m_fluid_lut, m_body_lut;
  FrameReader m_fluid_reader;
  vtkNew<vtkCellDataToPointData> m_to_points;
  vtkNew<vtkPlane> m_plane;
  vtkNew<vtkCutter> m_cutter;
  vtkNew<vtkPolyDataMapper> m_slice_mapper;
  vtkNew<vtkActor> m_slice_actor;
  vtkNew<vtkSmartVolumeMapper> m_volume_mapper;
  vtkNew<vtkVolumeProperty> m_volume_property;
  vtkNew<vtkVolume> m_volume;
  vtkNew<vtkXMLPolyDataReader> m_liquid_reader;
  vtkNew<vtkPolyDataMapper> m_liquid_mapper;
  vtkNew<vtkActor> m_liquid_actor;
  std::vector<std::unique_ptr<Body>> m_bodies;
  vtkNew<vtkTextActor> m_title, m_subtitle;
};

/// The box the camera frames: the fluid's domain, else the bodies' bounds over the first and
/// the last frame, padded by 10 %.
Box view_box_of(const RunIndex& run) {
  if (run.domain) return *run.domain;
  Box box{Vec3::Constant(std::numeric_limits<double>::infinity()),
          Vec3::Constant(-std::numeric_limits<double>::infinity())};
  FrameReader reader;
  for (const FrameFiles* f : {&run.frames.front(), &run.frames.back()})
    for (const fs::path& p : f->bodies) {
      double b[6];
      reader.read(p, "")->GetBounds(b);
      for (int a = 0; a < 3; ++a) {
        box.lo(a) = std::min(box.lo(a), b[2 * a]);
        box.hi(a) = std::max(box.hi(a), b[2 * a + 1]);
      }
    }
  const double pad = 0.1 * (box.hi - box.lo).maxCoeff() + 1e-9;
  box.lo.array() -= pad;
  box.hi.array() += pad;
  return box;
}

/// Run `ffmpeg` on the PNGs of `folder` into `movie`; "" on success, else a one-line note.
std::string make_movie(const fs::path& folder, const std::string& prefix, double fps,
                       const fs::path& movie) {
  const std::string ffmpeg = find_program("ffmpeg");
  if (ffmpeg.empty())
    return fmt::format(
        "--movie: ffmpeg is not installed (apt-get install ffmpeg), so no {}; the "
        "frames are in {}",
        movie.string(), folder.string());
  const std::string pattern = (folder / (prefix + "_*.png")).string();
  std::vector<std::string> args = {ffmpeg,          "-y",          "-loglevel",
                                   "error",         "-framerate",  fmt::format("{:.6g}", fps),
                                   "-pattern_type", "glob",        "-i",
                                   pattern,         "-vf",         "pad=ceil(iw/2)*2:ceil(ih/2)*2",
                                   "-c:v",          "libx264",     "-pix_fmt",
                                   "yuv420p",       movie.string()};
  std::vector<char*> argv;
  for (std::string& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);
  const fs::path log = folder / ".ffmpeg.log";
  const pid_t pid = fork();
  if (pid == 0) {
    if (std::FILE* f = std::freopen(log.c_str(), "w", stderr)) (void)f;
    execv(argv[0], argv.data());
    _exit(127);
  }
  int status = 0;
  if (pid < 0 || waitpid(pid, &status, 0) < 0 || !WIFEXITED(status) || WEXITSTATUS(status) != 0) {
    std::ifstream f(log);
    std::string line, last;
    while (std::getline(f, line))
      if (!line.empty()) last = line;
    std::error_code ec;
    fs::remove(log, ec);
    throw InputError(fmt::format("--movie: ffmpeg failed to write '{}'{}{}", movie.string(),
                                 last.empty() ? "" : ": ", one_line(last)));
  }
  std::error_code ec;
  fs::remove(log, ec);
  return "";
}

/// The options' own ranges. @throws InputError naming the option.
void check_options(const RenderOptions& opt) {
  if (opt.width < 16 || opt.height < 16 || opt.width > 8192 || opt.height > 8192)
    throw InputError(
        fmt::format("--size: {}x{} pixels; each side must be in 16..8192", opt.width, opt.height));
  if (!(opt.body_opacity > 0.0 && opt.body_opacity <= 1.0))
    throw InputError(fmt::format("--body-opacity: must be in (0, 1], got {}", opt.body_opacity));
  if (!(opt.zoom >= 0.1 && opt.zoom <= 20.0))
    throw InputError(fmt::format("--zoom: must be in [0.1, 20], got {}", opt.zoom));
  if (opt.range && !(opt.range->at(1) > opt.range->at(0)))
    throw InputError(fmt::format("--range: MIN must be below MAX, got {},{}", opt.range->at(0),
                                 opt.range->at(1)));
  if (!opt.movie.empty() && !opt.all)
    throw InputError("--movie needs --all (a movie of every frame)");
}

/// The frames `opt` asks for: all, the step's, or the last.
/// @throws InputError naming the steps written if the step's frame was not.
std::vector<const FrameFiles*> frames_to_draw(const RunIndex& run, const RenderOptions& opt,
                                              const fs::path& out_dir) {
  std::vector<const FrameFiles*> todo;
  if (opt.all) {
    for (const FrameFiles& f : run.frames) todo.push_back(&f);
  } else if (opt.step) {
    const FrameFiles* f = run.find(*opt.step);
    if (!f)
      throw InputError(
          fmt::format("{}: no frame of step {} was written; frames: steps {} "
                      "(pick one with --step, or --all)",
                      out_dir.string(), *opt.step, list_steps(run)));
    todo.push_back(f);
  } else {
    todo.push_back(&run.frames.back());
  }
  return todo;
}

/// --slice, checked against the box, or the default: normal z through the inflow patches'
/// mean height, else the box's centre; with a liquid (liquid.pvd), upright, normal y through
/// the box's centre (the liquid's pressure from its surface down).
SlicePlane slice_of(const RunIndex& run, const RenderOptions& opt, const Box& box) {
  if (!opt.slice && run.has_liquid) return SlicePlane{1, box.center()(1)};
  if (!opt.slice) return SlicePlane{2, run.jet_z ? *run.jet_z : box.center()(2)};
  const SlicePlane s = *opt.slice;
  if (s.value < box.lo(s.axis) || s.value > box.hi(s.axis))
    throw InputError(fmt::format("--slice {}={}: outside the fluid box ({} in [{}, {}] m)",
                                 kAxisNames[s.axis], s.value, kAxisNames[s.axis], box.lo(s.axis),
                                 box.hi(s.axis)));
  return s;
}

/// The slice's fixed colour range: --range, 0..the emitted smoke, or robust_range over the
/// last frame.
std::array<double, 2> fluid_range_of(const RunIndex& run, const RenderOptions& opt,
                                     const ColorChoice& colors, FrameReader& reader) {
  const FrameFiles& last = run.frames.back();
  if (opt.range) return *opt.range;
  if (colors.fluid == "smoke_density" && run.emitted_smoke > 0.0) return {0.0, run.emitted_smoke};
  if (last.fluid.empty()) return {0.0, 1.0};
  return robust_range(values_of(reader.read(last.fluid, colors.fluid), colors.fluid));
}

/// The bodies' fixed colour range: robust_range over the last frame's coloured bodies.
std::array<double, 2> body_range_of(const RunIndex& run, const ColorChoice& colors,
                                    FrameReader& reader) {
  const FrameFiles& last = run.frames.back();
  std::vector<double> all;
  for (size_t b = 0; b < last.bodies.size(); ++b) {
    if (run.kinematic[b] && colors.bodies == "von_mises_stress") continue;
    const std::vector<double> v =
        values_of(reader.read(last.bodies[b], colors.bodies), colors.bodies);
    all.insert(all.end(), v.begin(), v.end());
  }
  return robust_range(std::move(all));
}

}  // namespace

SlicePlane parse_slice(const std::string& text) {
  static const std::regex re(R"(^\s*([xyzXYZ])\s*=\s*(\S+)\s*$)");
  std::smatch m;
  SlicePlane s;
  if (std::regex_match(text, m, re)) {
    s.axis = std::tolower(m[1].str()[0]) - 'x';
    try {
      size_t used = 0;
      s.value = std::stod(m[2].str(), &used);
      if (used == m[2].str().size() && std::isfinite(s.value)) return s;
    } catch (const std::exception&) {
    }
  }
  throw InputError(
      fmt::format("--slice: expected AXIS=VALUE with AXIS x, y or z and VALUE in m (e.g. "
                  "z=0.45), got '{}'",
                  text));
}

std::array<double, 2> pixel_of(const RenderedFrame& frame, const Vec3& x, int width, int height) {
  const Eigen::Vector4d p = frame.world_to_ndc * Eigen::Vector4d(x(0), x(1), x(2), 1.0);
  const double nx = p(0) / p(3), ny = p(1) / p(3);
  return {0.5 * (nx + 1.0) * width, 0.5 * (1.0 - ny) * height};
}

RenderReport render_output(const fs::path& out_dir, const RenderOptions& opt) {
  const auto start = std::chrono::steady_clock::now();
  check_options(opt);
  const RunIndex run = read_run(out_dir);
  const std::vector<const FrameFiles*> todo = frames_to_draw(run, opt, out_dir);
  const Box view_box = view_box_of(run);
  const SlicePlane slice = slice_of(run, opt, view_box);

  // Arrays and their fixed ranges (from the last frame).
  FrameReader probe_fluid, probe_body;
  const ColorChoice colors = choose_colors(run, opt, *todo.front(), probe_fluid, probe_body);
  RenderReport report;
  report.scene_name = run.name;
  report.width = opt.width;
  report.height = opt.height;
  report.slice = slice;
  report.has_slice = !colors.fluid.empty() && !colors.volume;
  report.has_volume = colors.volume;
  report.color = colors.fluid;
  report.body_color = colors.bodies;
  if (!colors.fluid.empty()) report.color_range = fluid_range_of(run, opt, colors, probe_fluid);
  if (!colors.bodies.empty()) report.body_range = body_range_of(run, colors, probe_body);

  // Where the pictures go.
  const std::string prefix = file_safe_name(run.name);
  const fs::path folder = opt.all || opt.output.empty()
                              ? (opt.output.empty() ? out_dir / "pictures" : opt.output)
                              : fs::path();
  std::error_code ec;
  if (!folder.empty()) {
    fs::create_directories(folder, ec);
    if (ec)
      throw InputError(
          fmt::format("cannot create the folder '{}': {}", folder.string(), ec.message()));
  }

  const HeadlessDisplay display;
  FrameRenderer renderer(run, opt, colors, slice, view_box, report.color_range, report.body_range);
  for (const FrameFiles* f : todo) {
    const fs::path png =
        folder.empty() ? opt.output : folder / fmt::format("{}_{:06d}.png", prefix, f->step);
    report.frames.push_back(renderer.draw(*f, png));
  }

  if (!opt.movie.empty()) {
    double fps = 25.0;  // real time: one frame per output.every × dt, within 1..60 fps
    if (run.frames.size() >= 2) {
      const double dt_frame =
          (run.frames.back().time - run.frames.front().time) / double(run.frames.size() - 1);
      if (dt_frame > 0.0) fps = std::clamp(1.0 / dt_frame, 1.0, 60.0);
    }
    report.note = make_movie(folder, prefix, fps, opt.movie);
    if (report.note.empty()) report.movie = opt.movie;
  }
  report.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return report;
}

int render_command(const fs::path& out_dir, const RenderOptions& opt, std::ostream& out) {
  const RenderReport r = render_output(out_dir, opt);
  std::string what;
  if (r.has_volume)
    what = fmt::format("smoke volume of {} (opacity from {:.4g} to {:.4g})", r.color,
                       r.color_range[0], r.color_range[1]);
  if (r.has_slice)
    what = fmt::format("slice {} = {:.4g} m by {} in [{:.4g}, {:.4g}]", kAxisNames[r.slice.axis],
                       r.slice.value, r.color, r.color_range[0], r.color_range[1]);
  if (!r.body_color.empty())
    what += fmt::format("{}bodies by {} in [{:.4g}, {:.4g}]", what.empty() ? "" : "; ",
                        r.body_color, r.body_range[0], r.body_range[1]);
  if (what.empty()) what = "no slice";  // a liquid's surface alone
  if (r.frames.size() == 1) {
    out << fmt::format("{}: step {} (t = {:.6g} s), {}x{}, {}\n", r.frames[0].png.string(),
                       r.frames[0].step, r.frames[0].time, r.width, r.height, what);
  } else {
    out << fmt::format(
        "{} frames (steps {} to {}) in {}, {}x{}, {}; {:.3g} s ({:.3g} s per "
        "frame)\n",
        r.frames.size(), r.frames.front().step, r.frames.back().step,
        r.frames.front().png.parent_path().string(), r.width, r.height, what, r.seconds,
        r.seconds / double(r.frames.size()));
  }
  if (!r.movie.empty()) out << fmt::format("movie: {}\n", r.movie.string());
  out.flush();
  if (!r.note.empty()) std::fprintf(stderr, "hint: %s\n", r.note.c_str());
  return 0;
}

}  // namespace tetfsi::app
