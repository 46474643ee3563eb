#include "io/output.hpp"

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <limits>
#include <map>
#include <system_error>

#include <vtkCellArray.h>
#include <vtkCellData.h>
#include <vtkContourFilter.h>
#include <vtkDoubleArray.h>
#include <vtkErrorCode.h>
#include <vtkImageData.h>
#include <vtkNew.h>
#include <vtkPointData.h>
#include <vtkPoints.h>
#include <vtkPolyData.h>
#include <vtkRectilinearGrid.h>
#include <vtkTypeInt32Array.h>
#include <vtkUnsignedCharArray.h>
#include <vtkUnstructuredGrid.h>
#include <vtkXMLImageDataWriter.h>
#include <vtkXMLPolyDataWriter.h>
#include <vtkXMLUnstructuredGridWriter.h>

#include "core/error.hpp"
#include "core/log.hpp"
#include "core/parallel.hpp"
#include "core/ranks.hpp"
#include "io/state_io.hpp"
#include "io/stats_columns.hpp"
#include "io/xml_appended.hpp"
#include "mesh/quality.hpp"
#include "mesh/vtk_messages.hpp"
#include "solid/world.hpp"

namespace fs = std::filesystem;

namespace tetfsi::app {

namespace {

/// Text for a vtkErrorCode (vtkErrorCode::GetStringFromErrorCode lives in VTK::CommonMisc,
/// which tetfsi does not link).
std::string vtk_error_text(unsigned long code) {
  switch (code) {
    case vtkErrorCode::NoError:
      return "no error";
    case vtkErrorCode::FileNotFoundError:
      return "file not found";
    case vtkErrorCode::CannotOpenFileError:
      return "cannot open file";
    case vtkErrorCode::OutOfDiskSpaceError:
      return "out of disk space";
    case vtkErrorCode::NoFileNameError:
      return "no file name";
    default:
      return fmt::format("VTK error code {}", code);
  }
}

/// A 3-component Float64 array copied from n × 3 row-major data.
vtkNew<vtkDoubleArray> vector_array(const char* name, const double* data, Index n) {
  vtkNew<vtkDoubleArray> a;
  a->SetName(name);
  a->SetNumberOfComponents(3);
  a->SetNumberOfTuples(n);
  if (n > 0) std::memcpy(a->GetPointer(0), data, sizeof(double) * 3 * static_cast<size_t>(n));
  return a;
}

vtkNew<vtkDoubleArray> scalar_array(const char* name, const VecX& v) {
  vtkNew<vtkDoubleArray> a;
  a->SetName(name);
  a->SetNumberOfComponents(1);
  a->SetNumberOfTuples(v.size());
  if (v.size() > 0)
    std::memcpy(a->GetPointer(0), v.data(), sizeof(double) * static_cast<size_t>(v.size()));
  return a;
}

/// An Int32 array copied from a vector of Index.
vtkNew<vtkTypeInt32Array> int_array(const char* name, const VecXi& v) {
  static_assert(sizeof(Index) == sizeof(vtkTypeInt32), "Index must be 32-bit");
  vtkNew<vtkTypeInt32Array> a;
  a->SetName(name);
  a->SetNumberOfComponents(1);
  a->SetNumberOfTuples(v.size());
  if (v.size() > 0)
    std::memcpy(a->GetPointer(0), v.data(), sizeof(Index) * static_cast<size_t>(v.size()));
  return a;
}

/// Cells of `per_cell` points each from n × per_cell row-major indices, as offsets +
/// connectivity stored (and written) as Int32, which is what Index is: the indices are
/// copied in one block and the files are ~20% smaller than with VTK's default 64-bit ids.
vtkNew<vtkCellArray> int32_cells(const Index* indices, Index n, int per_cell) {
  static_assert(sizeof(Index) == sizeof(vtkTypeInt32), "Index must be 32-bit");
  vtkNew<vtkTypeInt32Array> offsets;
  offsets->SetNumberOfValues(n + 1);
  for (Index c = 0; c <= n; ++c) offsets->SetValue(c, per_cell * c);
  vtkNew<vtkTypeInt32Array> connectivity;
  connectivity->SetNumberOfValues(per_cell * static_cast<vtkIdType>(n));
  if (n > 0)
    std::memcpy(connectivity->GetPointer(0), indices,
                sizeof(Index) * static_cast<size_t>(per_cell) * static_cast<size_t>(n));
  vtkNew<vtkCellArray> cells;
  cells->SetData(offsets, connectivity);
  return cells;
}

fs::path tmp_path(const fs::path& p) {
  fs::path t = p;
  t += ".tmp";
  return t;
}

void rename_into_place(const fs::path& from, const fs::path& to) {
  std::error_code ec;
  fs::rename(from, to, ec);
  if (ec) {
    fs::remove(from, ec);
    throw InputError(
        fmt::format("cannot write '{}': rename failed: {}", to.string(), ec.message()));
  }
}

/// Write `data` with `writer` as appended raw binary (UInt64 headers, `compression`) to
/// `<path>.tmp`, then rename it to `path`.
/// @throws InputError naming `path` with VTK's reason on one line.
void write_xml_atomic(vtkXMLWriter* writer, vtkDataObject* data, const fs::path& path,
                      Compression compression) {
  const fs::path tmp = tmp_path(path);
  const mesh::VtkErrorObserver errors(writer);
  writer->SetInputData(data);
  writer->SetFileName(tmp.c_str());
  writer->SetDataModeToAppended();
  writer->EncodeAppendedDataOff();  // raw binary
  writer->SetHeaderTypeToUInt64();
  switch (compression) {
    case Compression::None:
      writer->SetCompressorTypeToNone();
      break;
    case Compression::LZ4:
      writer->SetCompressorTypeToLZ4();
      writer->SetCompressionLevel(1);
      break;
    case Compression::ZLib:
      writer->SetCompressorTypeToZLib();
      writer->SetCompressionLevel(1);
      break;
  }
  const int ok = writer->Write();
  if (!ok || writer->GetErrorCode() != vtkErrorCode::NoError) {
    std::error_code ec;
    fs::remove(tmp, ec);
    std::string why = errors.first_message();
    if (why.empty()) why = vtk_error_text(writer->GetErrorCode());
    throw InputError(fmt::format("cannot write '{}': {}", path.string(), why));
  }
  rename_into_place(tmp, path);
}

}  // namespace

// ---------------------------------------------------------------------------------------------

Compression parse_compression(const std::string& name) {
  return k_compression_names.parse(name);
}

std::string to_string(Compression c) {
  return k_compression_names.name(c);
}

std::string file_safe_name(const std::string& name) {
  if (name.empty()) return "body";
  std::string s = name;
  for (char& c : s) {
    const bool ok = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') ||
                    c == '_' || c == '-' || c == '.';
    if (!ok) c = '_';
  }
  if (s == "." || s == "..") s = "body" + s;
  return s;
}

std::string column_safe_name(const std::string& name) {
  if (name.empty()) return "body";
  std::string s = name;
  for (char& c : s) {
    const bool ok =
        (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_';
    if (!ok) c = '_';
  }
  return s;
}

std::string one_line(std::string s) {
  for (char& c : s)
    if (c == '\n' || c == '\r') c = ' ';
  // A run of more than 240 characters without a space (a pasted value, a path of 5000
  // 'a's) keeps its first 160 and last 40, so that the line stays readable.
  std::string out;
  std::size_t start = 0;
  while (start < s.size()) {
    std::size_t end = s.find(' ', start);
    if (end == std::string::npos) end = s.size();
    const std::size_t n = end - start;
    if (n > 240)
      out += fmt::format("{}...({} characters)...{}", s.substr(start, 160), n - 200,
                         s.substr(end - 40, 40));
    else
      out.append(s, start, n);
    if (end < s.size()) out += ' ';
    start = end + 1;
  }
  return out;
}

void write_text_file_atomic(const fs::path& path, const std::string& text) {
  const fs::path tmp = tmp_path(path);
  {
    std::ofstream f(tmp, std::ios::binary | std::ios::trunc);
    if (!f)
      throw InputError(fmt::format("cannot write '{}': {}", tmp.string(), std::strerror(errno)));
    f.write(text.data(), static_cast<std::streamsize>(text.size()));
    f.flush();
    if (!f) throw InputError(fmt::format("cannot write '{}': write failed", tmp.string()));
  }
  rename_into_place(tmp, path);
}

// ---- .vtu ----------------------------------------------------------------------------------

void write_body_vtu(const fs::path& path, const solid::SolidBody& body, const Vec3& gravity,
                    Compression compression) {
  mesh::route_vtk_messages_to_log();
  const Index nv = body.num_nodes();
  const Index nt = body.num_tets();

  vtkNew<vtkUnstructuredGrid> grid;

  // Points: deformed positions x = X + d.
  const MatX3 x = body.positions();
  vtkNew<vtkPoints> points;
  points->SetData(vector_array("Points", x.data(), nv));
  grid->SetPoints(points);

  // Cells: VTK_TETRA, Int32 offsets + connectivity.
  grid->SetCells(VTK_TETRA, int32_cells(body.tets().data(), nt, 4));

  // Point data.
  vtkPointData* pd = grid->GetPointData();
  pd->AddArray(vector_array("displacement", body.displacement.data(), nv));
  pd->AddArray(vector_array("velocity", body.velocity.data(), nv));
  const VecX fe = body.external_forces(gravity);
  TETFSI_CHECK(fe.size() == 3 * nv, "external_forces has size {}, expected {}", fe.size(), 3 * nv);
  pd->AddArray(vector_array("external_force", fe.data(), nv));
  pd->AddArray(vector_array("rest_position", body.rest_positions().data(), nv));
  vtkNew<vtkUnsignedCharArray> fixed;
  fixed->SetName("fixed");
  fixed->SetNumberOfComponents(1);
  fixed->SetNumberOfTuples(nv);
  const auto& fixed_dofs = body.fixed_dofs();
  for (Index i = 0; i < nv; ++i) {
    const bool any = fixed_dofs[3 * i] || fixed_dofs[3 * i + 1] || fixed_dofs[3 * i + 2];
    fixed->SetValue(i, any ? 1 : 0);
  }
  pd->AddArray(fixed);

  // Cell data.
  const solid::TetFields fields = body.elasticity().tet_fields(x);
  vtkCellData* cd = grid->GetCellData();
  cd->AddArray(scalar_array("green_strain_norm", fields.green_strain_norm));
  cd->AddArray(scalar_array("von_mises_stress", fields.von_mises_stress));
  cd->AddArray(scalar_array("volume_ratio", fields.volume_ratio));

  vtkNew<vtkXMLUnstructuredGridWriter> writer;
  write_xml_atomic(writer, grid, path, compression);
}

// ---- fluid mesh and interface ----------------------------------------------------------

void write_fluid_vtu(const fs::path& path, const mesh::TetMesh& m, Compression compression,
                     const FluidFrameFields* fields) {
  const Index nv = m.num_vertices();
  const Index nt = m.num_tets();
  TETFSI_CHECK(m.volumes.size() == nt, "fluid mesh: {} volumes for {} tets", m.volumes.size(), nt);
  TETFSI_CHECK(m.vertex_body.size() == nv, "fluid mesh: {} vertex_body entries for {} vertices",
               m.vertex_body.size(), nv);
  static_assert(sizeof(Index) == sizeof(std::int32_t), "Index must be 32-bit");
  constexpr Index grain = 16384;
  // The arrays tetfsi does not hold: VTK's end offsets and cell types, and touches_solid.
  std::vector<std::int32_t> offsets(static_cast<std::size_t>(nt));
  std::vector<std::uint8_t> types(static_cast<std::size_t>(nt)), touches(offsets.size());
  parallel_for_each(nt, grain, [&](Index t) {
    offsets[t] = 4 * (t + 1);
    types[t] = 10;  // VTK_TETRA
    bool any = false;
    for (int k = 0; k < 4; ++k) any = any || m.vertex_body[m.tets(t, k)] >= 0;
    touches[t] = any ? 1 : 0;
  });
  const mesh::TetQuality q = mesh::tet_quality(m.vertices, m.tets);
  using T = XmlValueType;
  auto n = [](Index k) { return static_cast<std::size_t>(k); };
  XmlUnstructuredGrid g;
  g.num_points = n(nv);
  g.num_cells = n(nt);
  g.points = {"Points", T::Float64, 3, m.vertices.data(), 3 * n(nv)};
  g.connectivity = {"connectivity", T::Int32, 1, m.tets.data(), 4 * n(nt), false};
  g.offsets = {"offsets", T::Int32, 1, offsets.data(), n(nt), false};
  g.types = {"types", T::UInt8, 1, types.data(), n(nt), false};
  g.point_data.push_back({"vertex_body", T::Int32, 1, m.vertex_body.data(), n(nv)});
  auto cell_scalar = [&](const char* name, const VecX& v) {
    TETFSI_CHECK(v.size() == nt, "fluid field '{}' has {} values for {} cells", name, v.size(), nt);
    g.cell_data.push_back({name, T::Float64, 1, v.data(), n(nt)});
  };
  cell_scalar("volume", m.volumes);
  cell_scalar("q_min_dihedral_deg", q.min_dihedral_deg);
  cell_scalar("q_max_dihedral_deg", q.max_dihedral_deg);
  cell_scalar("q_radius_edge", q.radius_edge);
  cell_scalar("q_shape", q.shape);
  g.cell_data.push_back({"touches_solid", T::UInt8, 1, touches.data(), n(nt)});
  if (fields) {
    const FluidFrameFields& f = *fields;
    cell_scalar("pressure", f.pressure);
    cell_scalar("smoke_density", f.density);
    cell_scalar("temperature", f.temperature);
    cell_scalar("vorticity", f.vorticity);
    cell_scalar("divergence", f.divergence);
    TETFSI_CHECK(f.cell_velocity.rows() == nt && f.vertex_velocity.rows() == nv,
                 "fluid velocity fields have {} / {} rows for {} cells / {} vertices",
                 f.cell_velocity.rows(), f.vertex_velocity.rows(), nt, nv);
    g.cell_data.push_back({"velocity", T::Float64, 3, f.cell_velocity.data(), 3 * n(nt)});
    g.point_data.push_back({"velocity", T::Float64, 3, f.vertex_velocity.data(), 3 * n(nv)});
  }
  const fs::path tmp = tmp_path(path);
  write_vtu_appended(tmp, g, compression);
  rename_into_place(tmp, path);
}

void write_interface_vtp(const fs::path& path, const mesh::TetMesh& m, Compression compression,
                         const FluidFrameFields* fields) {
  mesh::route_vtk_messages_to_log();
  const Index nf = m.num_faces();
  TETFSI_CHECK(m.face_kind.size() == static_cast<size_t>(nf),
               "fluid mesh: {} face kinds for {} faces", m.face_kind.size(), nf);

  // The Solid faces, and their vertices numbered in order of first use.
  std::vector<Index> faces;
  for (Index f = 0; f < nf; ++f)
    if (m.face_kind[static_cast<size_t>(f)] == mesh::FaceKind::Solid) faces.push_back(f);
  const Index n = static_cast<Index>(faces.size());
  VecXi local = VecXi::Constant(m.num_vertices(), -1);
  std::vector<Index> used;  // local point → fluid vertex
  MatX3i tris(n, 3);
  for (Index i = 0; i < n; ++i) {
    for (int k = 0; k < 3; ++k) {
      const Index v = m.faces(faces[static_cast<size_t>(i)], k);
      if (local[v] < 0) {
        local[v] = static_cast<Index>(used.size());
        used.push_back(v);
      }
      tris(i, k) = local[v];
    }
  }
  const Index np = static_cast<Index>(used.size());
  MatX3 x(np, 3);
  VecXi fluid_vertex(np);
  for (Index p = 0; p < np; ++p) {
    x.row(p) = m.vertices.row(used[static_cast<size_t>(p)]);
    fluid_vertex[p] = used[static_cast<size_t>(p)];
  }

  VecXi body(n), triangle(n);
  VecX area(n), dual(n);
  MatX3 normal(n, 3), bary(n, 3);
  for (Index i = 0; i < n; ++i) {
    const Index f = faces[static_cast<size_t>(i)];
    body[i] = m.face_body[f];
    triangle[i] = m.face_triangle[f];
    area[i] = m.face_areas[f];
    dual[i] = m.dual_lengths[f];
    normal.row(i) = m.face_normals.row(f);
    bary.row(i) = m.face_bary.row(f);
  }

  vtkNew<vtkPolyData> poly;
  vtkNew<vtkPoints> points;
  points->SetData(vector_array("Points", x.data(), np));
  poly->SetPoints(points);
  poly->SetPolys(int32_cells(tris.data(), n, 3));
  poly->GetPointData()->AddArray(int_array("fluid_vertex", fluid_vertex));
  vtkCellData* cd = poly->GetCellData();
  cd->AddArray(int_array("body", body));
  cd->AddArray(int_array("triangle", triangle));
  cd->AddArray(scalar_array("area", area));
  cd->AddArray(scalar_array("dual_length", dual));
  cd->AddArray(vector_array("normal", normal.data(), n));
  cd->AddArray(vector_array("bary", bary.data(), n));
  if (fields) {
    TETFSI_CHECK(fields->pressure.size() == m.num_tets() && fields->face_velocity.size() == nf,
                 "interface fields have {} pressures / {} face velocities for {} cells / {} faces",
                 fields->pressure.size(), fields->face_velocity.size(), m.num_tets(), nf);
    VecX pressure(n), normal_velocity(n);
    for (Index i = 0; i < n; ++i) {
      const Index f = faces[static_cast<size_t>(i)];
      pressure[i] = fields->pressure[m.face_tets(f, 0)];  // the fluid cell: n_f points out of it
      normal_velocity[i] = fields->face_velocity[f];
    }
    cd->AddArray(scalar_array("pressure", pressure));
    cd->AddArray(scalar_array("normal_velocity", normal_velocity));
  }

  vtkNew<vtkXMLPolyDataWriter> writer;
  write_xml_atomic(writer, poly, path, compression);
}

// ---- grid fluid ----------------------------------------------------------------------------

namespace {

/// #C of a grid frame. @throws InternalError if a cell count is < 1 or #C overflows Index, or
/// the origin or a spacing is not finite (a spacing also not positive).
Index grid_num_cells(const GridFrameFields& g) {
  const auto& n = g.cells;
  std::int64_t nc = 1;
  for (int a = 0; a < 3; ++a) {
    TETFSI_CHECK(n[a] >= 1, "grid frame: cells = {} × {} × {}, each must be ≥ 1", n[0], n[1], n[2]);
    TETFSI_CHECK(std::isfinite(g.spacing[a]) && g.spacing[a] > 0.0,
                 "grid frame: spacing = ({}, {}, {}), each must be positive and finite",
                 g.spacing[0], g.spacing[1], g.spacing[2]);
    nc *= n[a];
  }
  TETFSI_CHECK(g.origin.allFinite(), "grid frame: origin = ({}, {}, {}) is not finite", g.origin[0],
               g.origin[1], g.origin[2]);
  TETFSI_CHECK(nc <= std::numeric_limits<Index>::max(), "grid frame: {} × {} × {} cells overflow",
               n[0], n[1], n[2]);
  return static_cast<Index>(nc);
}

/// #C. @throws InternalError naming the first cell array of `g` that is not #C long.
Index check_grid_cells(const GridFrameFields& g) {
  const Index nc = grid_num_cells(g);
  auto check = [&](const char* name, Index size) {
    TETFSI_CHECK(size == nc, "grid frame: '{}' has {} entries for {} cells ({} × {} × {})", name,
                 size, nc, g.cells[0], g.cells[1], g.cells[2]);
  };
  check("pressure", static_cast<Index>(g.pressure.size()));
  check("density", static_cast<Index>(g.density.size()));
  check("temperature", static_cast<Index>(g.temperature.size()));
  check("divergence", static_cast<Index>(g.divergence.size()));
  check("vorticity", static_cast<Index>(g.vorticity.size()));
  check("velocity", static_cast<Index>(g.velocity.rows()));
  check("solid", static_cast<Index>(g.solid.size()));
  return nc;
}

/// @throws InternalError naming the first surface array of `g` of the wrong size, or the
/// first triangle with a point index outside [0, #P).
void check_grid_surface(const GridFrameFields& g) {
  const Index np = static_cast<Index>(g.surface_points.rows());
  const Index nt = static_cast<Index>(g.surface_triangles.rows());
  auto check = [&](const char* name, Index size, Index expected, const char* of) {
    TETFSI_CHECK(size == expected, "grid frame: '{}' has {} rows for {} {}", name, size, expected,
                 of);
  };
  check("surface_body", static_cast<Index>(g.surface_body.size()), nt, "surface_triangles");
  check("surface_pressure", static_cast<Index>(g.surface_pressure.size()), nt, "surface_triangles");
  check("surface_pressure_jump", static_cast<Index>(g.surface_pressure_jump.size()), nt,
        "surface_triangles");
  check("surface_force", static_cast<Index>(g.surface_force.rows()), np, "surface_points");
  for (Index t = 0; t < nt; ++t) {
    const auto tri = g.surface_triangles.row(t);
    TETFSI_CHECK(tri.minCoeff() >= 0 && tri.maxCoeff() < np,
                 "grid frame: surface_triangles row {} = ({}, {}, {}) indexes past {} "
                 "surface_points",
                 t, tri[0], tri[1], tri[2], np);
  }
}

}  // namespace

void write_grid_vti(const fs::path& path, const GridFrameFields& g, Compression compression) {
  mesh::route_vtk_messages_to_log();
  const Index nc = check_grid_cells(g);

  vtkNew<vtkImageData> image;
  image->SetDimensions(g.cells[0] + 1, g.cells[1] + 1, g.cells[2] + 1);  // points
  image->SetOrigin(g.origin[0], g.origin[1], g.origin[2]);
  image->SetSpacing(g.spacing[0], g.spacing[1], g.spacing[2]);

  // Cell data: GridSpec::cell's x-fastest numbering is ImageData's, so copied as they are.
  vtkCellData* cd = image->GetCellData();
  cd->AddArray(scalar_array("pressure", g.pressure));
  cd->AddArray(scalar_array("smoke_density", g.density));
  cd->AddArray(scalar_array("temperature", g.temperature));
  cd->AddArray(scalar_array("divergence", g.divergence));
  cd->AddArray(scalar_array("vorticity", g.vorticity));
  cd->AddArray(vector_array("velocity", g.velocity.data(), nc));
  vtkNew<vtkUnsignedCharArray> solid;
  solid->SetName("solid");
  solid->SetNumberOfComponents(1);
  solid->SetNumberOfTuples(nc);
  std::memcpy(solid->GetPointer(0), g.solid.data(), static_cast<size_t>(nc));
  cd->AddArray(solid);
  if (g.phi.size() == nc) cd->AddArray(scalar_array("phi", g.phi));

  vtkNew<vtkXMLImageDataWriter> writer;
  write_xml_atomic(writer, image, path, compression);
}

namespace {

/// The liquid's surface: VTK's contour of φ = 0 on the cell centres and the box's walls. A
/// wall point takes φ of the centre beside it (the surface meets the wall: open there), or
/// with `closed` air where that centre is liquid (the surface closes on the wall).
vtkSmartPointer<vtkPolyData> liquid_surface_polydata(const GridFrameFields& g, bool closed) {
  mesh::route_vtk_messages_to_log();
  const Index nc = check_grid_cells(g);
  TETFSI_CHECK(g.phi.size() == nc, "liquid surface: phi has {} values for {} cells", g.phi.size(),
               nc);
  // The cell centres and the box's walls as the points of a rectilinear grid: φ and the
  // velocity are point data there, a wall point taking the value of the centre beside it (a
  // free-slip wall mirrors the liquid), so that the surface meets the walls.
  vtkNew<vtkRectilinearGrid> grid;
  std::array<Index, 3> np{};
  for (int a = 0; a < 3; ++a) np[a] = g.cells[a] + 2;
  grid->SetDimensions(static_cast<int>(np[0]), static_cast<int>(np[1]), static_cast<int>(np[2]));
  for (int a = 0; a < 3; ++a) {
    vtkNew<vtkDoubleArray> c;
    c->SetNumberOfTuples(np[a]);
    c->SetValue(0, g.origin[a]);
    for (Index i = 0; i < g.cells[a]; ++i)
      c->SetValue(i + 1, g.origin[a] + (static_cast<double>(i) + 0.5) * g.spacing[a]);
    c->SetValue(np[a] - 1, g.origin[a] + static_cast<double>(g.cells[a]) * g.spacing[a]);
    if (a == 0) grid->SetXCoordinates(c);
    if (a == 1) grid->SetYCoordinates(c);
    if (a == 2) grid->SetZCoordinates(c);
  }
  const Index npts = np[0] * np[1] * np[2];
  VecX phi(npts);
  MatX3 vel(npts, 3);
  for (Index k = 0; k < np[2]; ++k)
    for (Index j = 0; j < np[1]; ++j)
      for (Index i = 0; i < np[0]; ++i) {
        const auto in = [&](Index v, int a) { return std::clamp<Index>(v - 1, 0, g.cells[a] - 1); };
        const Index c = in(i, 0) + g.cells[0] * (in(j, 1) + g.cells[1] * in(k, 2));
        const Index p = i + np[0] * (j + np[1] * k);
        const bool wall =
            i == 0 || j == 0 || k == 0 || i == np[0] - 1 || j == np[1] - 1 || k == np[2] - 1;
        phi[p] = closed && wall ? std::max(g.phi[c], 0.0) + 1e-3 * g.spacing.minCoeff() : g.phi[c];
        vel.row(p) = g.velocity.row(c);
      }
  grid->GetPointData()->SetScalars(scalar_array("phi", phi));
  grid->GetPointData()->AddArray(vector_array("velocity", vel.data(), npts));
  vtkNew<vtkContourFilter> contour;
  contour->SetInputData(grid);
  contour->SetValue(0, 0.0);
  contour->ComputeNormalsOn();
  contour->ComputeScalarsOff();
  contour->Update();
  vtkSmartPointer<vtkPolyData> surface = contour->GetOutput();
  surface->GetPointData()->RemoveArray("phi");
  return surface;
}

/// Orient the closed surface `s` out of the liquid. VTK's contour does not orient its
/// triangles consistently, so each connected piece is made consistent from one triangle
/// (across a shared edge two triangles run it in opposite directions), then turned as a
/// whole if the volume it encloses (Σ a·(b × c) / 6, the divergence theorem) is negative.
void orient_out_of_liquid(ExportSurface& s) {
  const Index nt = static_cast<Index>(s.triangles.rows());
  std::map<std::pair<int, int>, std::vector<Index>> edge_triangles;
  for (Index t = 0; t < nt; ++t)
    for (int e = 0; e < 3; ++e) {
      const int a = s.triangles(t, e), b = s.triangles(t, (e + 1) % 3);
      edge_triangles[{std::min(a, b), std::max(a, b)}].push_back(t);
    }
  const auto runs = [&](Index t, int a, int b) {  // does triangle t run the edge a → b?
    for (int e = 0; e < 3; ++e)
      if (s.triangles(t, e) == a && s.triangles(t, (e + 1) % 3) == b) return true;
    return false;
  };
  std::vector<char> seen(static_cast<std::size_t>(nt), 0);
  for (Index t0 = 0; t0 < nt; ++t0) {
    if (seen[static_cast<std::size_t>(t0)]) continue;
    std::vector<Index> piece{t0};
    seen[static_cast<std::size_t>(t0)] = 1;
    for (std::size_t q = 0; q < piece.size(); ++q)
      for (int e = 0; e < 3; ++e) {
        const Index t = piece[q];
        const int a = s.triangles(t, e), b = s.triangles(t, (e + 1) % 3);
        for (const Index u : edge_triangles[{std::min(a, b), std::max(a, b)}]) {
          if (seen[static_cast<std::size_t>(u)]) continue;
          if (runs(u, a, b)) std::swap(s.triangles(u, 1), s.triangles(u, 2));
          seen[static_cast<std::size_t>(u)] = 1;
          piece.push_back(u);
        }
      }
    double volume = 0.0;
    for (const Index t : piece) {
      const Vec3 a = s.points.row(s.triangles(t, 0)), b = s.points.row(s.triangles(t, 1)),
                 c = s.points.row(s.triangles(t, 2));
      volume += a.dot(b.cross(c)) / 6.0;
    }
    if (volume < 0.0)
      for (const Index t : piece) std::swap(s.triangles(t, 1), s.triangles(t, 2));
  }
}

}  // namespace

void write_liquid_surface_vtp(const fs::path& path, const GridFrameFields& g,
                              Compression compression) {
  const vtkSmartPointer<vtkPolyData> surface = liquid_surface_polydata(g, false);
  vtkNew<vtkXMLPolyDataWriter> writer;
  write_xml_atomic(writer, surface, path, compression);
}

ExportSurface liquid_surface(const GridFrameFields& g) {
  const vtkSmartPointer<vtkPolyData> poly = liquid_surface_polydata(g, true);
  ExportSurface s;
  const Index np = static_cast<Index>(poly->GetNumberOfPoints());
  s.points.resize(np, 3);
  s.velocity.resize(np, 3);
  vtkDataArray* vel = poly->GetPointData()->GetArray("velocity");
  for (Index i = 0; i < np; ++i) {
    poly->GetPoint(i, &s.points(i, 0));
    for (int a = 0; a < 3; ++a) s.velocity(i, a) = vel ? vel->GetComponent(i, a) : 0.0;
  }
  std::vector<std::array<int, 3>> tris;
  vtkCellArray* polys = poly->GetPolys();
  vtkIdType n = 0;
  const vtkIdType* ids = nullptr;
  for (polys->InitTraversal(); polys->GetNextCell(n, ids);) {
    for (vtkIdType k = 1; k + 1 < n; ++k)  // a fan: the contour gives triangles
      tris.push_back(
          {static_cast<int>(ids[0]), static_cast<int>(ids[k]), static_cast<int>(ids[k + 1])});
  }
  s.triangles.resize(static_cast<Index>(tris.size()), 3);
  for (size_t t = 0; t < tris.size(); ++t)
    for (int a = 0; a < 3; ++a) s.triangles(static_cast<Index>(t), a) = tris[t][a];
  orient_out_of_liquid(s);
  return s;
}

void write_grid_interface_vtp(const fs::path& path, const GridFrameFields& g,
                              Compression compression) {
  mesh::route_vtk_messages_to_log();
  check_grid_surface(g);
  const Index np = static_cast<Index>(g.surface_points.rows());
  const Index nt = static_cast<Index>(g.surface_triangles.rows());

  VecX area(nt);
  MatX3 normal(nt, 3);
  for (Index t = 0; t < nt; ++t) {
    const Vec3 a = g.surface_points.row(g.surface_triangles(t, 0));
    const Vec3 b = g.surface_points.row(g.surface_triangles(t, 1));
    const Vec3 c = g.surface_points.row(g.surface_triangles(t, 2));
    const Vec3 n = (b - a).cross(c - a);  // outward: the triangles are outward-oriented
    const double len = n.norm();
    area[t] = 0.5 * len;
    normal.row(t) = len > 0.0 ? Vec3(n / len) : Vec3::Zero();
  }

  vtkNew<vtkPolyData> poly;
  vtkNew<vtkPoints> points;
  points->SetData(vector_array("Points", g.surface_points.data(), np));
  poly->SetPoints(points);
  poly->SetPolys(int32_cells(g.surface_triangles.data(), nt, 3));
  poly->GetPointData()->AddArray(vector_array("fluid_force", g.surface_force.data(), np));
  vtkCellData* cd = poly->GetCellData();
  cd->AddArray(int_array("body", g.surface_body));
  cd->AddArray(scalar_array("pressure", g.surface_pressure));
  cd->AddArray(scalar_array("pressure_jump", g.surface_pressure_jump));
  cd->AddArray(scalar_array("area", area));
  cd->AddArray(vector_array("normal", normal.data(), nt));

  vtkNew<vtkXMLPolyDataWriter> writer;
  write_xml_atomic(writer, poly, path, compression);
}

// ---- .pvd ----------------------------------------------------------------------------------

PvdWriter::PvdWriter(fs::path pvd_path) : m_path(std::move(pvd_path)) {}

std::string PvdWriter::to_xml(const std::vector<PvdEntry>& entries) {
  std::string s =
      "<?xml version=\"1.0\"?>\n"
      "<VTKFile type=\"Collection\" version=\"0.1\" byte_order=\"LittleEndian\">\n"
      "  <Collection>\n";
  for (const PvdEntry& e : entries) {
    s += fmt::format("    <DataSet timestep=\"{:.17g}\" group=\"\" part=\"0\" file=\"{}\"/>\n",
                     e.time, xml_escape(e.file));
  }
  s += "  </Collection>\n</VTKFile>\n";
  return s;
}

void PvdWriter::add(double time, const std::string& relative_file) {
  m_entries.push_back({time, relative_file});
  write_text_file_atomic(m_path, to_xml(m_entries));
}

void PvdWriter::reset(std::vector<PvdEntry> entries) {
  m_entries = std::move(entries);
  write_text_file_atomic(m_path, to_xml(m_entries));
}

// ---- stats.csv -----------------------------------------------------------------------------

const std::vector<std::string>& StatsWriter::phase_columns(bool fluid, bool coupled) {
  auto names = [](bool f, bool c) {
    std::vector<std::string> v;
    for (const PhaseColumn& p : app::phase_columns(f, c)) v.emplace_back(p.name);
    return v;
  };
  static const std::vector<std::string> p = names(false, false), pf = names(true, false),
                                        pc = names(true, true);
  return fluid ? (coupled ? pc : pf) : p;
}

namespace {

template <class R>
void append_names(std::vector<std::string>& v, const std::vector<StatsColumn<R>>& table,
                  const std::string& prefix = "") {
  for (const StatsColumn<R>& c : table) v.push_back(prefix + c.name);
}

/// Number of quality columns (mesh::quality_columns has a fixed length).
size_t num_quality_columns() {
  static const size_t n = mesh::quality_columns(mesh::QualitySummary{}).size();
  return n;
}

}  // namespace

std::vector<std::string> StatsWriter::columns(bool fluid, bool coupled,
                                              const std::vector<std::string>& bodies, bool contact,
                                              bool liquid) {
  coupled = fluid && coupled;
  std::vector<std::string> v;
  append_names(v, step_head_columns());
  for (const auto& p : phase_columns(fluid, coupled)) v.push_back(p);
  append_names(v, step_columns());
  if (fluid) {
    append_names(v, fluid_mesh_columns());
    for (const auto& [name, value] : mesh::quality_columns(mesh::QualitySummary{}))
      v.push_back(name);
    append_names(v, fluid_step_columns());
  }
  if (coupled) append_names(v, coupled_columns());
  for (const std::string& b : bodies) append_names(v, body_columns(), b);
  if (contact) append_names(v, contact_columns());
  if (liquid) append_names(v, liquid_columns());
  return v;
}

namespace {

/// stats.csv of a resumed run: its header (which must be `header`) and its rows of steps
/// 1..last, in order, rewritten atomically without any later row.
void truncate_stats(const fs::path& path, const std::string& header, int last) {
  std::ifstream in(path, std::ios::binary);
  if (!in)
    throw InputError(fmt::format("cannot continue '{}': {}", path.string(),
                                 fs::exists(path) ? std::strerror(errno) : "no such file"));
  std::string line, kept;
  if (!std::getline(in, line) || line + '\n' != header)
    throw InputError(
        fmt::format("cannot continue '{}': its header is not this run's columns", path.string()));
  kept = header;
  int expected = 1;
  while (expected <= last && std::getline(in, line)) {
    const std::string first = line.substr(0, line.find(','));
    if (first != std::to_string(expected) || line.find(',') == std::string::npos) break;
    kept += line + '\n';
    ++expected;
  }
  if (expected <= last)
    throw InputError(fmt::format(
        "cannot continue '{}': it has the rows of steps 1..{} only, the checkpoint is at step {}",
        path.string(), expected - 1, last));
  write_text_file_atomic(path, kept);
}

}  // namespace

StatsWriter::StatsWriter(const fs::path& path, bool fluid, bool coupled,
                         std::optional<int> continue_after, std::vector<std::string> bodies,
                         bool contact, bool liquid)
    : m_path(path),
      m_fluid(fluid),
      m_coupled(fluid && coupled),
      m_bodies(std::move(bodies)),
      m_contact(contact),
      m_liquid(fluid && liquid) {
  std::string header;
  for (const auto& c : columns(m_fluid, m_coupled, m_bodies, m_contact, m_liquid)) {
    if (!header.empty()) header += ',';
    header += c;
  }
  header += '\n';
  if (continue_after) {
    truncate_stats(path, header, *continue_after);
    m_file = std::fopen(path.c_str(), "a");
  } else {
    m_file = std::fopen(path.c_str(), "w");
  }
  if (!m_file)
    throw InputError(fmt::format("cannot write '{}': {}", path.string(), std::strerror(errno)));
  if (!continue_after) std::fputs(header.c_str(), m_file);
  std::fflush(m_file);
}

StatsWriter::~StatsWriter() {
  if (m_file) std::fclose(m_file);
}

void StatsWriter::write(const StepStats& r) {
  std::string line;
  append_stats(line, step_head_columns(), r);
  line.erase(0, 1);  // the row's first column has no ',' before it
  for (const auto& p : phase_columns(m_fluid, m_coupled))
    line += fmt::format(",{:.6g}", r.phases.get(p));
  append_stats(line, step_columns(), r);
  if (m_fluid) {
    const size_t nq = num_quality_columns();
    if (r.fluid) {
      const FluidStepStats& f = *r.fluid;
      TETFSI_CHECK(f.quality.size() == nq, "stats row has {} quality columns, expected {}",
                   f.quality.size(), nq);
      append_stats(line, fluid_mesh_columns(), f);
      for (const auto& [name, value] : f.quality) line += fmt::format(",{:.17g}", value);
      append_stats(line, fluid_step_columns(), f);
    } else {
      append_nan(line, fluid_mesh_columns());
      for (size_t k = 0; k < nq; ++k) line += ",nan";
      append_nan(line, fluid_step_columns());
    }
  }
  if (m_coupled) {
    if (r.coupled)
      append_stats(line, coupled_columns(), *r.coupled);
    else
      append_nan(line, coupled_columns());
  }
  if (r.bodies.empty()) {
    for (size_t k = 0; k < m_bodies.size(); ++k) append_nan(line, body_columns());
  } else {
    TETFSI_CHECK(r.bodies.size() == m_bodies.size(), "stats row has {} body poses, expected {}",
                 r.bodies.size(), m_bodies.size());
    for (const solid::BodyPose& p : r.bodies) append_stats(line, body_columns(), p);
  }
  if (m_contact) {
    if (r.contact)
      append_stats(line, contact_columns(), *r.contact);
    else
      append_nan(line, contact_columns());
  }
  if (m_liquid) {
    if (r.fluid)
      append_stats(line, liquid_columns(), *r.fluid);
    else
      append_nan(line, liquid_columns());
  }
  line += '\n';
  if (std::fputs(line.c_str(), m_file) < 0 || std::fflush(m_file) != 0)
    throw InputError(fmt::format("cannot write '{}': {}", m_path.string(), std::strerror(errno)));
}

// ---- output folder -------------------------------------------------------------------------

namespace {

/// Create the folder and warn about an earlier run in it (unless `resume`); returns the path.
fs::path prepare_out_dir(const fs::path& out, bool resume) {
  std::error_code ec;
  fs::create_directories(out, ec);
  if (ec || !fs::is_directory(out))
    throw InputError(fmt::format("cannot create output folder '{}': {}", out.string(),
                                 ec ? ec.message() : "not a folder"));
  if (resume) return out;
  for (const char* f : {"stats.csv", "summary.json", "scene.resolved.json"}) {
    if (fs::exists(out / f)) {
      logger().warn("output folder '{}' holds an earlier run: its files are overwritten",
                    out.string());
      break;
    }
  }
  return out;
}

}  // namespace

std::vector<std::string> output_file_names(const OutputPlan& plan, const solid::SolidWorld& world) {
  stats_body_names(world);  // the stats.csv columns, before anything is created
  std::vector<std::string> names;
  for (const solid::SolidBody& b : world.bodies) {
    std::string name = file_safe_name(b.name());
    for (const std::string& other : names) {
      if (other == name)
        throw InputError(
            fmt::format("bodies '{}' and another body share the output file name '{}': rename one",
                        b.name(), name));
    }
    if (plan.fluid) {
      for (const char* stream : {"fluid", "interface", "liquid"}) {
        if (name == stream)
          throw InputError(fmt::format(
              "body '{}' would be written to '{}.pvd', which holds the {} mesh in a scene with "
              "a fluid: rename the body",
              b.name(), stream, stream));
      }
    }
    names.push_back(std::move(name));
  }
  return names;
}

std::vector<std::string> stats_body_names(const solid::SolidWorld& world) {
  std::vector<std::string> names;
  for (const solid::SolidBody& b : world.bodies) {
    std::string name = column_safe_name(b.name());
    for (size_t k = 0; k < names.size(); ++k) {
      if (names[k] == name)
        throw InputError(fmt::format(
            "bodies '{}' and '{}' share the stats.csv column name '{}' (characters other than "
            "letters, digits and '_' become '_'): rename one",
            world.bodies[k].name(), b.name(), name));
    }
    names.push_back(std::move(name));
  }
  return names;
}

OutputWriter::OutputWriter(const fs::path& out_dir, const OutputPlan& plan,
                           const solid::SolidWorld& world, std::optional<int> resume_step)
    : m_file_names(output_file_names(plan, world)),
      m_out(is_root_rank() ? prepare_out_dir(out_dir, resume_step.has_value()) : out_dir),
      m_compression(parse_compression(plan.compression)),
      m_quiet(!is_root_rank()) {
  if (!m_quiet) {
    m_stats.emplace(m_out / "stats.csv", plan.fluid, plan.two_way, resume_step,
                    stats_body_names(world), world.contact.enabled, plan.liquid);
    write_text_file_atomic(
        m_out / "scene.resolved.json",
        (plan.resolved.is_null() ? nlohmann::json::object() : plan.resolved).dump(2) + "\n");
  }
  // One folder and one collection per stream; quiet (a rank but 0), the collection only.
  auto stream = [&](const std::string& name) {
    if (!m_quiet) {
      std::error_code ec;
      fs::create_directories(m_out / name, ec);
      if (ec)
        throw InputError(fmt::format("cannot create output folder '{}': {}",
                                     (m_out / name).string(), ec.message()));
    }
    return PvdWriter(m_out / (name + ".pvd"));
  };
  for (const std::string& name : m_file_names) m_pvd.push_back(stream(name));
  if (plan.fluid) {
    m_fluid_pvd.emplace(stream("fluid"));
    m_interface_pvd.emplace(stream("interface"));
    if (plan.liquid) m_liquid_pvd.emplace(stream("liquid"));
  }
  m_export = plan.exports;
  m_export.vdb = m_export.vdb && plan.fluid;
  if (m_export.vdb || m_export.ply) m_manifest.emplace(m_out / "export.json", m_export.scene);
}

std::optional<ExportedFrame> OutputWriter::export_files(const solid::SolidWorld& world, int step,
                                                        double time, const VoxelFrame* fluid,
                                                        const ExportSurface* liquid) {
  if (!m_manifest) return std::nullopt;
  std::vector<NamedSurface> surfaces;
  if (m_export.ply) {
    for (size_t i = 0; i < world.bodies.size(); ++i)
      surfaces.push_back({m_file_names[i], body_export_surface(world.bodies[i])});
    if (liquid) surfaces.push_back({"liquid", *liquid});
  }
  return export_frame(m_out, m_frames, step, time, surfaces, m_export.vdb ? fluid : nullptr,
                      m_export);
}

std::vector<std::string> OutputWriter::write_bodies(const solid::SolidWorld& world, int step) {
  TETFSI_CHECK(world.bodies.size() == m_pvd.size(), "world has {} bodies, output has {}",
               world.bodies.size(), m_pvd.size());
  std::vector<std::string> rel(world.bodies.size());
  for (size_t i = 0; i < world.bodies.size(); ++i) {
    const std::string& name = m_file_names[i];
    rel[i] = fmt::format("{}/{}_{:06d}.vtu", name, name, step);
    write_body_vtu(m_out / rel[i], world.bodies[i], world.gravity, m_compression);
  }
  return rel;
}

void OutputWriter::add_bodies_to_pvds(const std::vector<std::string>& rel, double time) {
  for (size_t i = 0; i < rel.size(); ++i) m_pvd[i].add(time, rel[i]);
}

void OutputWriter::write_frame(const solid::SolidWorld& world, int step, double time,
                               const mesh::TetMesh* fluid, const FluidFrameFields* fluid_fields) {
  if (m_quiet) return count_frame(step);
  // Every file first, then the collections: a frame that fails half-way is in none of them.
  const std::vector<std::string> rel = write_bodies(world, step);
  const bool with_fluid = m_fluid_pvd && fluid;
  const std::string rel_f = fmt::format("fluid/fluid_{:06d}.vtu", step);
  const std::string rel_i = fmt::format("interface/interface_{:06d}.vtp", step);
  if (with_fluid) {
    write_fluid_vtu(m_out / rel_f, *fluid, m_compression, fluid_fields);
    write_interface_vtp(m_out / rel_i, *fluid, m_compression, fluid_fields);
  }
  std::optional<VoxelFrame> voxels;
  if (with_fluid && fluid_fields && m_manifest && m_export.vdb)
    voxels = voxelize(tet_volume_of(*fluid, *fluid_fields), m_export.voxels);
  std::optional<ExportedFrame> exported =
      export_files(world, step, time, voxels ? &*voxels : nullptr, nullptr);
  add_bodies_to_pvds(rel, time);
  if (with_fluid) {
    m_fluid_pvd->add(time, rel_f);
    m_interface_pvd->add(time, rel_i);
  }
  if (exported) m_manifest->add(std::move(*exported));
  count_frame(step);
}

void OutputWriter::write_grid_frame(const solid::SolidWorld& world, int step, double time,
                                    const GridFrameFields& grid) {
  TETFSI_CHECK(m_fluid_pvd && m_interface_pvd,
               "write_grid_frame: the scene has no fluid (no fluid.pvd, interface.pvd)");
  // The grid's sizes before any file, then every file, then the collections.
  check_grid_cells(grid);
  check_grid_surface(grid);
  if (m_quiet) return count_frame(step);
  const std::vector<std::string> rel = write_bodies(world, step);
  const std::string rel_f = fmt::format("fluid/fluid_{:06d}.vti", step);
  const std::string rel_i = fmt::format("interface/interface_{:06d}.vtp", step);
  write_grid_vti(m_out / rel_f, grid, m_compression);
  write_grid_interface_vtp(m_out / rel_i, grid, m_compression);
  const std::string rel_l = fmt::format("liquid/liquid_{:06d}.vtp", step);
  if (m_liquid_pvd) write_liquid_surface_vtp(m_out / rel_l, grid, m_compression);
  std::optional<ExportedFrame> exported;
  if (m_manifest) {
    const VoxelFrame voxels = voxel_frame_of(grid, m_export.voxels.ambient_temperature);
    std::optional<ExportSurface> liquid;
    if (m_liquid_pvd && m_export.ply) liquid = liquid_surface(grid);
    exported = export_files(world, step, time, &voxels, liquid ? &*liquid : nullptr);
  }
  add_bodies_to_pvds(rel, time);
  m_fluid_pvd->add(time, rel_f);
  m_interface_pvd->add(time, rel_i);
  if (m_liquid_pvd) m_liquid_pvd->add(time, rel_l);
  if (exported) m_manifest->add(std::move(*exported));
  count_frame(step);
}

void OutputWriter::count_frame(int step) {
  ++m_frames;
  m_frame_steps.push_back(step);
}

void OutputWriter::write_summary(const std::string& json_text) {
  if (m_quiet) return;
  write_text_file_atomic(m_out / "summary.json", json_text);
}

std::vector<const PvdWriter*> OutputWriter::streams() const {
  std::vector<const PvdWriter*> s;
  for (const PvdWriter& p : m_pvd) s.push_back(&p);
  if (m_fluid_pvd) s.push_back(&*m_fluid_pvd);
  if (m_interface_pvd) s.push_back(&*m_interface_pvd);
  if (m_liquid_pvd) s.push_back(&*m_liquid_pvd);
  return s;
}

std::vector<PvdWriter*> OutputWriter::streams() {
  std::vector<PvdWriter*> s;
  for (PvdWriter& p : m_pvd) s.push_back(&p);
  if (m_fluid_pvd) s.push_back(&*m_fluid_pvd);
  if (m_interface_pvd) s.push_back(&*m_interface_pvd);
  if (m_liquid_pvd) s.push_back(&*m_liquid_pvd);
  return s;
}

namespace {

/// The step of a frame file "sheet/sheet_000050.vtu" (the digits after its last '_'), or -1.
long frame_step_of(const std::string& file) {
  const std::string stem = fs::path(file).stem().string();
  const auto u = stem.rfind('_');
  if (u == std::string::npos || u + 1 == stem.size()) return -1;
  const std::string digits = stem.substr(u + 1);
  if (digits.size() > 9 ||
      !std::all_of(digits.begin(), digits.end(), [](unsigned char c) { return std::isdigit(c); }))
    return -1;
  return std::stol(digits);
}

}  // namespace

void OutputWriter::save_state(CheckpointWriter& w, int through_step) const {
  int frames = 0;
  std::vector<int> steps;
  for (const int s : m_frame_steps) {
    if (s > through_step) continue;
    ++frames;
    steps.push_back(s);
  }
  w.put("run/output/frames", frames);
  w.put("run/output/frame_steps", steps);
  const std::vector<const PvdWriter*> st = streams();
  w.put("run/output/streams", static_cast<int>(st.size()));
  for (size_t i = 0; i < st.size(); ++i) {
    std::vector<double> times;
    std::vector<std::string> files;
    for (const PvdEntry& e : st[i]->entries()) {
      if (frame_step_of(e.file) > through_step) continue;
      times.push_back(e.time);
      files.push_back(e.file);
    }
    const std::string key = fmt::format("run/output/pvd/{}/", i);
    w.put(key + "name", st[i]->path().filename().string());
    w.put(key + "times", times);
    put_lines(w, key + "files", files);
  }
  if (m_manifest) {
    nlohmann::json frames = nlohmann::json::array();
    for (const ExportedFrame& f : m_manifest->frames())
      if (f.step <= through_step) frames.push_back(to_json(f));
    w.put("run/output/export", frames.dump());
  }
}

void OutputWriter::load_state(const CheckpointReader& r) {
  const std::vector<PvdWriter*> st = streams();
  const auto n = r.get_int("run/output/streams");
  if (n != static_cast<std::int64_t>(st.size()))
    r.fail(fmt::format("run/output/streams: {} collections, this scene writes {}", n, st.size()));
  m_frames = static_cast<int>(r.get_int("run/output/frames"));
  m_frame_steps = r.get_vector<int>("run/output/frame_steps");
  if (m_quiet) return;  // rank 0 rewrites the collections and removes the later frames
  const int last = m_frame_steps.empty() ? -1 : m_frame_steps.back();
  for (size_t i = 0; i < st.size(); ++i) {
    const std::string key = fmt::format("run/output/pvd/{}/", i);
    const std::string name = r.get_text(key + "name");
    if (name != st[i]->path().filename().string())
      r.fail(fmt::format("{}name: '{}', this scene writes '{}'", key, name,
                         st[i]->path().filename().string()));
    const std::vector<double> times = r.get_vector<double>(key + "times");
    const std::vector<std::string> files = get_lines(r, key + "files");
    if (times.size() != files.size())
      r.fail(fmt::format("{}: {} times for {} files", key, times.size(), files.size()));
    std::vector<PvdEntry> entries;
    for (size_t k = 0; k < times.size(); ++k) entries.push_back({times[k], files[k]});
    // The frames the stopped run wrote after the checkpoint: listed in the collection on disk
    // or not (a frame is listed only once all its files exist), they are ours to remove.
    const fs::path folder = m_out / st[i]->path().stem();
    std::error_code ec;
    for (const auto& f : fs::directory_iterator(folder, ec)) {
      const std::string stem = st[i]->path().stem().string();
      const std::string fname = f.path().filename().string();
      if (fname.rfind(stem + "_", 0) != 0) continue;
      const std::string ext = f.path().extension().string();
      if (ext != ".vtu" && ext != ".vtp" && ext != ".vti") continue;
      if (frame_step_of(fname) > last) fs::remove(f.path(), ec);
    }
    st[i]->reset(std::move(entries));
  }
  load_export_state(r);
}

void OutputWriter::load_export_state(const CheckpointReader& r) {
  if (!m_manifest) return;
  if (!r.has("run/output/export"))
    r.fail("run/output/export: missing, and the scene writes renderer files (output.export)");
  std::vector<ExportedFrame> frames;
  try {
    for (const auto& j : nlohmann::json::parse(r.get_text("run/output/export")))
      frames.push_back(exported_frame_from_json(j));
  } catch (const nlohmann::json::exception& e) {
    r.fail(fmt::format("run/output/export: not the manifest's frames ({})", e.what()));
  }
  m_manifest->reset(std::move(frames));
  // The files of the frames the stopped run wrote after the checkpoint: ours to remove.
  for (const char* folder : {"vdb", "ply"}) {
    std::error_code ec;
    for (const auto& f : fs::directory_iterator(m_out / folder, ec)) {
      const std::string ext = f.path().extension().string();
      if (ext != ".vdb" && ext != ".ply") continue;
      if (frame_step_of(f.path().filename().string()) >= m_frames) fs::remove(f.path(), ec);
    }
  }
}

std::vector<fs::path> OutputWriter::pvd_paths() const {
  std::vector<fs::path> p;
  for (const auto& w : m_pvd) p.push_back(w.path());
  return p;
}

}  // namespace tetfsi::app
