/// @file frame_data.cpp
/// A run's frame files read back into plain arrays with VTK's XML readers (frame_data.hpp).
#include "render/frame_data.hpp"

#include <string>
#include <utility>

#include <fmt/format.h>
#include <vtkCellArray.h>
#include <vtkCellData.h>
#include <vtkCellType.h>
#include <vtkDataArray.h>
#include <vtkIdList.h>
#include <vtkImageData.h>
#include <vtkNew.h>
#include <vtkPointData.h>
#include <vtkPoints.h>
#include <vtkPolyData.h>
#include <vtkSmartPointer.h>
#include <vtkUnstructuredGrid.h>
#include <vtkXMLImageDataReader.h>
#include <vtkXMLUnstructuredGridReader.h>
#include <Eigen/Geometry>

#include "core/error.hpp"
#include "mesh/io.hpp"
#include "mesh/vtk_messages.hpp"

namespace fs = std::filesystem;

namespace tetfsi::app {

namespace {

/// `file` read by a new `Reader`; its output stays valid as long as the reader. A file without
/// points is an error.
/// @throws InputError naming the file if it is missing or VTK cannot read it.
template <class Reader>
vtkSmartPointer<Reader> read_xml(const fs::path& file) {
  std::error_code ec;
  if (!fs::is_regular_file(file, ec))
    throw InputError(
        fmt::format("{}: the frame file is missing (the run's .pvd lists it)", file.string()));
  if (file.extension() == ".vtu") mesh::check_vtk_xml_header(file);
  auto reader = vtkSmartPointer<Reader>::New();
  const mesh::VtkMessageCapture capture;
  reader->SetFileName(file.string().c_str());
  try {
    reader->Update();
  } catch (const std::exception& e) {
    throw InputError(fmt::format("{}: VTK could not read the frame ({})", file.string(), e.what()));
  }
  vtkDataSet* out = reader->GetOutput();
  if (!capture.first_message().empty() || out == nullptr || out->GetNumberOfPoints() == 0)
    throw InputError(
        fmt::format("{}: VTK could not read the frame: {}", file.string(),
                    capture.first_message().empty() ? "no points" : capture.first_message()));
  return reader;
}

/// The array `name` of `data` with `components` components: empty if absent.
/// @throws InputError naming the file if it has other components or not `n` tuples.
vtkDataArray* array_of(vtkDataSetAttributes* data, const char* name, int components, Index n,
                       const fs::path& file) {
  vtkDataArray* a = data->GetArray(name);
  if (a == nullptr) return nullptr;
  if (a->GetNumberOfComponents() != components || a->GetNumberOfTuples() != n)
    throw InputError(fmt::format("{}: array '{}' has {} × {} values, expected {} × {}",
                                 file.string(), name, a->GetNumberOfTuples(),
                                 a->GetNumberOfComponents(), n, components));
  return a;
}

/// A scalar array as a VecX (empty if absent).
VecX scalars(vtkDataSetAttributes* data, const char* name, Index n, const fs::path& file) {
  vtkDataArray* a = array_of(data, name, 1, n, file);
  if (a == nullptr) return VecX();
  VecX v(n);
  for (Index i = 0; i < n; ++i) v[i] = a->GetComponent(i, 0);
  return v;
}

/// A 3-vector array as a MatX3 (empty if absent).
MatX3 vectors(vtkDataSetAttributes* data, const char* name, Index n, const fs::path& file) {
  vtkDataArray* a = array_of(data, name, 3, n, file);
  if (a == nullptr) return MatX3();
  MatX3 v(n, 3);
  for (Index i = 0; i < n; ++i)
    for (int c = 0; c < 3; ++c) v(i, c) = a->GetComponent(i, c);
  return v;
}

MatX3 points_of(vtkPointSet* data) {
  const Index n = static_cast<Index>(data->GetNumberOfPoints());
  MatX3 x(n, 3);
  for (Index i = 0; i < n; ++i) {
    double p[3];
    data->GetPoint(i, p);
    x.row(i) << p[0], p[1], p[2];
  }
  return x;
}

/// The cells of `grid`, every one a VTK_TETRA. @throws InputError naming the file otherwise.
MatX4i tets_of(vtkUnstructuredGrid* grid, const fs::path& file) {
  const Index n = static_cast<Index>(grid->GetNumberOfCells());
  if (n == 0) throw InputError(fmt::format("{}: the frame has no cells", file.string()));
  MatX4i tets(n, 4);
  vtkNew<vtkIdList> ids;
  for (Index t = 0; t < n; ++t) {
    if (grid->GetCellType(t) != VTK_TETRA)
      throw InputError(fmt::format("{}: cell {} is not a tetrahedron (VTK cell type {})",
                                   file.string(), t, grid->GetCellType(t)));
    grid->GetCellPoints(t, ids);
    for (int k = 0; k < 4; ++k) tets(t, k) = static_cast<int>(ids->GetId(k));
  }
  return tets;
}

/// A required cell array of a grid frame. @throws InputError naming the file if absent.
VecX required(vtkDataSetAttributes* data, const char* name, Index n, const fs::path& file) {
  VecX v = scalars(data, name, n, file);
  if (v.size() == 0)
    throw InputError(
        fmt::format("{}: no cell array '{}' (not a tetfsi grid frame?)", file.string(), name));
  return v;
}

}  // namespace

TetBodyFrame read_body_frame(const fs::path& vtu) {
  const auto reader = read_xml<vtkXMLUnstructuredGridReader>(vtu);
  vtkUnstructuredGrid* grid = reader->GetOutput();
  TetBodyFrame f;
  f.points = points_of(grid);
  f.tets = tets_of(grid, vtu);
  f.velocity = vectors(grid->GetPointData(), "velocity", f.points.rows(), vtu);
  f.von_mises = scalars(grid->GetCellData(), "von_mises_stress", f.tets.rows(), vtu);
  return f;
}

TetVolume read_tet_fluid_frame(const fs::path& vtu, bool only_density) {
  const auto reader = read_xml<vtkXMLUnstructuredGridReader>(vtu);
  vtkUnstructuredGrid* grid = reader->GetOutput();
  TetVolume v;
  v.vertices = points_of(grid);
  v.tets = tets_of(grid, vtu);
  const Index nt = static_cast<Index>(v.tets.rows());
  v.density = scalars(grid->GetCellData(), "smoke_density", nt, vtu);
  if (only_density) return v;
  v.temperature = scalars(grid->GetCellData(), "temperature", nt, vtu);
  v.pressure = scalars(grid->GetCellData(), "pressure", nt, vtu);
  v.vertex_velocity = vectors(grid->GetPointData(), "velocity", v.vertices.rows(), vtu);
  return v;
}

fluid::GridFrameFields read_grid_fluid_frame(const fs::path& vti) {
  const auto reader = read_xml<vtkXMLImageDataReader>(vti);
  vtkImageData* image = reader->GetOutput();
  fluid::GridFrameFields g;
  int dims[3];
  image->GetDimensions(dims);
  double origin[3], spacing[3];
  image->GetOrigin(origin);
  image->GetSpacing(spacing);
  for (int a = 0; a < 3; ++a) {
    g.cells[a] = std::max(dims[a] - 1, 1);
    g.origin[a] = origin[a];
    g.spacing[a] = spacing[a];
  }
  const Index nc = g.cells[0] * g.cells[1] * g.cells[2];
  vtkCellData* cd = image->GetCellData();
  g.pressure = required(cd, "pressure", nc, vti);
  g.density = required(cd, "smoke_density", nc, vti);
  g.temperature = required(cd, "temperature", nc, vti);
  const VecX solid = required(cd, "solid", nc, vti);
  g.velocity = vectors(cd, "velocity", nc, vti);
  if (g.velocity.rows() == 0)
    throw InputError(
        fmt::format("{}: no cell array 'velocity' (not a tetfsi grid frame?)", vti.string()));
  g.divergence = scalars(cd, "divergence", nc, vti);
  if (g.divergence.size() == 0) g.divergence = VecX::Zero(nc);
  g.vorticity = scalars(cd, "vorticity", nc, vti);
  if (g.vorticity.size() == 0) g.vorticity = VecX::Zero(nc);
  g.solid.resize(static_cast<size_t>(nc));
  for (Index c = 0; c < nc; ++c) g.solid[static_cast<size_t>(c)] = solid[c] != 0.0 ? 1 : 0;
  g.phi = scalars(cd, "phi", nc, vti);
  return g;
}

}  // namespace tetfsi::app
