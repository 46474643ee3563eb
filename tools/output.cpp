#include "tools/output.hpp"

#include <cerrno>
#include <cstring>
#include <fstream>
#include <system_error>

#include <vtkCellArray.h>
#include <vtkCellData.h>
#include <vtkCommand.h>
#include <vtkDoubleArray.h>
#include <vtkErrorCode.h>
#include <vtkLogger.h>
#include <vtkNew.h>
#include <vtkObjectFactory.h>
#include <vtkOutputWindow.h>
#include <vtkPointData.h>
#include <vtkPoints.h>
#include <vtkTypeInt32Array.h>
#include <vtkUnsignedCharArray.h>
#include <vtkUnstructuredGrid.h>
#include <vtkXMLUnstructuredGridWriter.h>

#include "core/error.hpp"
#include "core/log.hpp"
#include "solid/world.hpp"
#include "tools/scene.hpp"

namespace fs = std::filesystem;

namespace tetfsi::tools {

namespace {

/// Routes VTK's own messages (normally multi-line dumps on stderr) to the tetfsi logger at
/// debug level; failures are reported through our exceptions instead.
class LoggerOutputWindow : public vtkOutputWindow {
 public:
  static LoggerOutputWindow* New();
  vtkTypeMacro(LoggerOutputWindow, vtkOutputWindow);
  void DisplayText(const char* text) override {
    std::string s = text ? text : "";
    for (char& c : s)
      if (c == '\n') c = ' ';
    logger().debug("VTK: {}", s);
  }
};
vtkStandardNewMacro(LoggerOutputWindow);

void install_vtk_output_window() {
  static const bool done = [] {
    vtkNew<LoggerOutputWindow> w;
    vtkOutputWindow::SetInstance(w);
    // VTK 9 also sends errors to its own logger (loguru) on stderr: keep stderr ours.
    vtkLogger::SetStderrVerbosity(vtkLogger::VERBOSITY_OFF);
    return true;
  }();
  (void)done;
}

/// Collects the text of VTK error events of one object.
class ErrorCollector : public vtkCommand {
 public:
  static ErrorCollector* New() { return new ErrorCollector; }
  void Execute(vtkObject*, unsigned long, void* data) override {
    if (data && message.empty()) message = static_cast<const char*>(data);
  }
  std::string message;
};

/// A VTK error message ("ERROR: In <file>, line <n>\n<class> (0x...): <text>\n\n") reduced
/// to one line of <text>.
std::string short_vtk_message(const std::string& m) {
  std::string s = m;
  if (const auto p = s.find("): "); p != std::string::npos) s = s.substr(p + 3);
  for (char& c : s)
    if (c == '\n' || c == '\r') c = ' ';
  while (!s.empty() && s.back() == ' ') s.pop_back();
  return s;
}

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
  std::memcpy(a->GetPointer(0), data, sizeof(double) * 3 * static_cast<size_t>(n));
  return a;
}

vtkNew<vtkDoubleArray> scalar_array(const char* name, const VecX& v) {
  vtkNew<vtkDoubleArray> a;
  a->SetName(name);
  a->SetNumberOfComponents(1);
  a->SetNumberOfTuples(v.size());
  std::memcpy(a->GetPointer(0), v.data(), sizeof(double) * static_cast<size_t>(v.size()));
  return a;
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

/// Escape the five XML special characters for an attribute value.
std::string xml_escape(const std::string& s) {
  std::string out;
  out.reserve(s.size());
  for (char c : s) {
    switch (c) {
      case '&':
        out += "&amp;";
        break;
      case '<':
        out += "&lt;";
        break;
      case '>':
        out += "&gt;";
        break;
      case '"':
        out += "&quot;";
        break;
      case '\'':
        out += "&apos;";
        break;
      default:
        out += c;
    }
  }
  return out;
}

}  // namespace

// ---------------------------------------------------------------------------------------------

Compression parse_compression(const std::string& name) {
  if (name == "none") return Compression::None;
  if (name == "lz4") return Compression::LZ4;
  if (name == "zlib") return Compression::ZLib;
  throw InputError(fmt::format("unknown compression '{}': use 'lz4', 'zlib' or 'none'", name));
}

std::string to_string(Compression c) {
  switch (c) {
    case Compression::None:
      return "none";
    case Compression::LZ4:
      return "lz4";
    case Compression::ZLib:
      return "zlib";
  }
  return "?";
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
  install_vtk_output_window();
  const Index nv = body.num_nodes();
  const Index nt = body.num_tets();

  vtkNew<vtkUnstructuredGrid> grid;

  // Points: deformed positions x = X + d.
  const MatX3 x = body.positions();
  vtkNew<vtkPoints> points;
  points->SetData(vector_array("Points", x.data(), nv));
  grid->SetPoints(points);

  // Cells: VTK_TETRA from offsets + connectivity, stored (and written) as Int32, which is
  // what Index is: the tets are copied in one block and the files are ~20% smaller than
  // with VTK's default 64-bit ids.
  static_assert(sizeof(Index) == sizeof(vtkTypeInt32), "Index must be 32-bit");
  vtkNew<vtkTypeInt32Array> offsets;
  offsets->SetNumberOfValues(nt + 1);
  for (Index t = 0; t <= nt; ++t) offsets->SetValue(t, 4 * t);
  vtkNew<vtkTypeInt32Array> connectivity;
  connectivity->SetNumberOfValues(4 * static_cast<vtkIdType>(nt));
  std::memcpy(connectivity->GetPointer(0), body.tets().data(),
              sizeof(Index) * 4 * static_cast<size_t>(nt));
  vtkNew<vtkCellArray> cells;
  cells->SetData(offsets, connectivity);
  grid->SetCells(VTK_TETRA, cells);

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

  // Write to a temporary name, then rename into place.
  const fs::path tmp = tmp_path(path);
  vtkNew<vtkXMLUnstructuredGridWriter> writer;
  vtkNew<ErrorCollector> errors;
  writer->AddObserver(vtkCommand::ErrorEvent, errors);
  writer->SetInputData(grid);
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
    std::string why = errors->message.empty() ? vtk_error_text(writer->GetErrorCode())
                                              : short_vtk_message(errors->message);
    throw InputError(fmt::format("cannot write '{}': {}", path.string(), why));
  }
  rename_into_place(tmp, path);
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

// ---- stats.csv -----------------------------------------------------------------------------

const std::vector<std::string>& StatsWriter::phase_columns() {
  static const std::vector<std::string> p = {"assemble", "solve", "update", "output", "total"};
  return p;
}

const std::vector<std::string>& StatsWriter::columns() {
  static const std::vector<std::string> c = [] {
    std::vector<std::string> v = {"step", "time", "dt"};
    for (const auto& p : phase_columns()) v.push_back(p);
    for (const char* s : {"solver_iterations", "solver_residual", "contacts", "kinetic_energy",
                          "elastic_energy", "gravity_potential", "total_energy"})
      v.emplace_back(s);
    return v;
  }();
  return c;
}

StatsWriter::StatsWriter(const fs::path& path) : m_path(path) {
  m_file = std::fopen(path.c_str(), "w");
  if (!m_file)
    throw InputError(fmt::format("cannot write '{}': {}", path.string(), std::strerror(errno)));
  std::string header;
  for (const auto& c : columns()) {
    if (!header.empty()) header += ',';
    header += c;
  }
  header += '\n';
  std::fputs(header.c_str(), m_file);
  std::fflush(m_file);
}

StatsWriter::~StatsWriter() {
  if (m_file) std::fclose(m_file);
}

void StatsWriter::write(const StepStats& r) {
  std::string line = fmt::format("{},{:.17g},{:.17g}", r.step, r.time, r.dt);
  for (const auto& p : phase_columns()) line += fmt::format(",{:.6g}", r.phases.get(p));
  line += fmt::format(",{},{:.17g},{},{:.17g},{:.17g},{:.17g},{:.17g}\n", r.solver_iterations,
                      r.solver_residual, r.contacts, r.kinetic_energy, r.elastic_energy,
                      r.gravity_potential, r.total_energy());
  if (std::fputs(line.c_str(), m_file) < 0 || std::fflush(m_file) != 0)
    throw InputError(fmt::format("cannot write '{}': {}", m_path.string(), std::strerror(errno)));
}

// ---- output folder -------------------------------------------------------------------------

namespace {

/// Create the folder and warn about an earlier run in it; returns the path.
fs::path prepare_out_dir(const fs::path& out) {
  std::error_code ec;
  fs::create_directories(out, ec);
  if (ec || !fs::is_directory(out))
    throw InputError(fmt::format("cannot create output folder '{}': {}", out.string(),
                                 ec ? ec.message() : "not a folder"));
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

OutputWriter::OutputWriter(const fs::path& out_dir, const Scene& scene,
                           const solid::SolidWorld& world)
    : m_out(prepare_out_dir(out_dir)),
      m_compression(parse_compression(scene.output.compression)),
      m_stats(m_out / "stats.csv") {
  write_text_file_atomic(
      m_out / "scene.resolved.json",
      (scene.resolved.is_null() ? nlohmann::json::object() : scene.resolved).dump(2) + "\n");
  for (const solid::SolidBody& b : world.bodies) {
    std::string name = file_safe_name(b.name());
    for (const std::string& other : m_file_names) {
      if (other == name)
        throw InputError(
            fmt::format("bodies '{}' and another body share the output file name '{}': rename one",
                        b.name(), name));
    }
    std::error_code ec;
    fs::create_directories(m_out / name, ec);
    if (ec)
      throw InputError(fmt::format("cannot create output folder '{}': {}", (m_out / name).string(),
                                   ec.message()));
    m_pvd.emplace_back(m_out / (name + ".pvd"));
    m_file_names.push_back(std::move(name));
  }
}

void OutputWriter::write_frame(const solid::SolidWorld& world, int step, double time) {
  TETFSI_CHECK(world.bodies.size() == m_pvd.size(), "world has {} bodies, output has {}",
               world.bodies.size(), m_pvd.size());
  for (size_t i = 0; i < world.bodies.size(); ++i) {
    const std::string& name = m_file_names[i];
    const std::string rel = fmt::format("{}/{}_{:06d}.vtu", name, name, step);
    write_body_vtu(m_out / rel, world.bodies[i], world.gravity, m_compression);
    m_pvd[i].add(time, rel);
  }
  ++m_frames;
}

void OutputWriter::write_summary(const std::string& json_text) {
  write_text_file_atomic(m_out / "summary.json", json_text);
}

std::vector<fs::path> OutputWriter::pvd_paths() const {
  std::vector<fs::path> p;
  for (const auto& w : m_pvd) p.push_back(w.path());
  return p;
}

}  // namespace tetfsi::tools
