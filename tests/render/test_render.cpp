// `tetfsi render`, `tetfsi plot` and `tetfsi run --preview` (render/render.hpp, render/plot.hpp)
// on coarse runs of the shipped scenes: the PNG's size, that it is not blank, that the smoke's
// volume is grey-white at the inflow on the dark background and the slice's colours change
// where the smoke is (through the picture's own world-to-pixel map), one PNG per frame with
// --all, the --movie hint without ffmpeg and ffmpeg's command line with it, grid (.vti)
// frames, plots with the columns a run has, and one-line errors.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <doctest/doctest.h>
#include <fmt/format.h>
#include <vtkImageData.h>
#include <vtkNew.h>
#include <vtkPNGReader.h>
#include <vtkPointData.h>
#include <vtkUnsignedCharArray.h>

#include "core/error.hpp"
#include "render/render.hpp"
#include "tests/test_util.hpp"

namespace fs = std::filesystem;
using namespace tetfsi;
using tetfsi::test::contains;
using tetfsi::test::shipped_scene;
using tetfsi::test::TempDir;
using Result = tetfsi::test::CliResult;

namespace {

/// At most 4 GB of address space and 2 minutes per run (as the other scene tests).
const std::string kLimits = "ulimit -v 4000000; timeout 120";

/// A coarse smoke_jet run (the jet patch: y, z in [0.4, 0.6] on the -x wall, 2 m/s, smoke 1).
const std::string kCoarseJet =
    "--set fluid.mesh.surface_size=0.1 --set fluid.mesh.far_size=0.2 --set fluid.refine.size=0";

/// `tetfsi run <scene> --out o --progress off <extra>` in `dir`; REQUIREs exit code 0.
Result run_scene(const fs::path& dir, const std::string& scene, const std::string& extra) {
  return tetfsi::test::run_shipped_scene(dir, scene, extra, kLimits);
}

/// An 8-bit RGB(A) PNG read back: width, height and RGB per pixel, rows from the top.
struct Picture {
  int width = 0, height = 0;
  std::vector<std::array<double, 3>> rgb;
  std::array<double, 3> at(int x, int y) const { return rgb[static_cast<size_t>(y) * width + x]; }
  /// Mean colour of the (2r+1)² pixels around (x, y).
  std::array<double, 3> mean(double xf, double yf, int r = 2) const {
    std::array<double, 3> m = {0, 0, 0};
    int n = 0;
    for (int y = int(yf) - r; y <= int(yf) + r; ++y)
      for (int x = int(xf) - r; x <= int(xf) + r; ++x) {
        if (x < 0 || y < 0 || x >= width || y >= height) continue;
        for (int c = 0; c < 3; ++c) m[c] += at(x, y)[c];
        ++n;
      }
    for (double& v : m) v /= std::max(n, 1);
    return m;
  }
  /// Variance of the grey level over the picture.
  double variance() const {
    double s = 0, s2 = 0;
    for (const auto& p : rgb) {
      const double g = (p[0] + p[1] + p[2]) / 3.0;
      s += g;
      s2 += g * g;
    }
    const double n = double(rgb.size());
    return s2 / n - (s / n) * (s / n);
  }
};

Picture read_png(const fs::path& p) {
  REQUIRE(fs::exists(p));
  vtkNew<vtkPNGReader> reader;
  reader->SetFileName(p.string().c_str());
  reader->Update();
  vtkImageData* img = reader->GetOutput();
  int dims[3];
  img->GetDimensions(dims);
  Picture pic;
  pic.width = dims[0];
  pic.height = dims[1];
  auto* data = vtkUnsignedCharArray::SafeDownCast(img->GetPointData()->GetScalars());
  REQUIRE(data != nullptr);
  const int nc = data->GetNumberOfComponents();
  REQUIRE(nc >= 3);
  pic.rgb.resize(static_cast<size_t>(pic.width) * pic.height);
  for (int y = 0; y < pic.height; ++y)  // vtkImageData's first row is the bottom one
    for (int x = 0; x < pic.width; ++x)
      for (int c = 0; c < 3; ++c)
        pic.rgb[static_cast<size_t>(pic.height - 1 - y) * pic.width + x][c] =
            data->GetComponent(static_cast<vtkIdType>(y) * pic.width + x, c);
  return pic;
}

double grey(const std::array<double, 3>& c) {
  return (c[0] + c[1] + c[2]) / 3.0;
}

}  // namespace

TEST_CASE(
    "tetfsi render --slice: a coarse smoke_jet frame has its size, is not blank, and its slice "
    "is bright where the smoke is") {
  TempDir dir("render_jet");
  // 10 steps of 0.02 s at 2 m/s: the smoke reaches ~0.4 m into the box; --preview renders the
  // last frame at the end of the run.
  const Result run = run_scene(dir.path, "smoke_jet.json",
                               "--steps 10 --set output.every=5 --preview " + kCoarseJet);
  CHECK(contains(run.out, "preview: o/preview.png"));
  const Picture preview = read_png(dir.path / "o" / "preview.png");
  CHECK(preview.width == 1280);
  CHECK(preview.height == 720);

  app::RenderOptions opt;
  opt.width = 640;
  opt.height = 360;
  opt.step = 10;
  opt.slice_view = true;
  opt.output = dir.path / "f10.png";
  const app::RenderReport r10 = app::render_output(dir.path / "o", opt);
  opt.step = 0;
  opt.output = dir.path / "f0.png";
  const app::RenderReport r0 = app::render_output(dir.path / "o", opt);
  REQUIRE(r10.frames.size() == 1);
  REQUIRE(r0.frames.size() == 1);
  CHECK(r10.scene_name == "smoke_jet");
  CHECK(r10.has_slice);
  CHECK_FALSE(r10.has_volume);
  CHECK(r10.color == "smoke_density");
  CHECK(r10.body_color.empty());  // the paddle is kinematic: no stress to colour
  // The slice: normal z through the jet patch's centre, coloured 0..1 (the emitted smoke).
  CHECK(r10.slice.axis == 2);
  CHECK(r10.slice.value == doctest::Approx(0.5));
  CHECK(r10.color_range[0] == 0.0);
  CHECK(r10.color_range[1] == doctest::Approx(1.0));
  CHECK(r10.frames[0].time == doctest::Approx(0.2));

  const Picture f10 = read_png(dir.path / "f10.png"), f0 = read_png(dir.path / "f0.png");
  CHECK(f10.width == 640);
  CHECK(f10.height == 360);
  CHECK(f10.variance() > 100.0);  // not blank: a uniform picture has 0
  CHECK(f0.variance() > 100.0);

  // In the jet (x = 0.15 m, y = z = 0.5 m) the smoke is near 1 at step 10 and 0 at step 0;
  // beside it (y = 0.1 m) there is none at either step. Same camera: same pixels.
  const Vec3 in_jet(0.15, 0.5, 0.5), beside(0.15, 0.1, 0.5);
  const auto p_jet = app::pixel_of(r10.frames[0], in_jet, 640, 360);
  const auto p_beside = app::pixel_of(r10.frames[0], beside, 640, 360);
  const auto q_jet = app::pixel_of(r0.frames[0], in_jet, 640, 360);
  CHECK(p_jet[0] == doctest::Approx(q_jet[0]));
  CHECK(p_jet[1] == doctest::Approx(q_jet[1]));
  for (const auto& p : {p_jet, p_beside}) {
    CHECK(p[0] > 0);
    CHECK(p[0] < 640);
    CHECK(p[1] > 0);
    CHECK(p[1] < 360);
  }
  const double jet10 = grey(f10.mean(p_jet[0], p_jet[1])), jet0 = grey(f0.mean(p_jet[0], p_jet[1]));
  const double beside10 = grey(f10.mean(p_beside[0], p_beside[1]));
  const double beside0 = grey(f0.mean(p_beside[0], p_beside[1]));
  INFO("grey in the jet " << jet10 << " (step 0: " << jet0 << "), beside it " << beside10
                          << " (step 0: " << beside0 << ")");
  // Inferno: near black at 0, purple at 0.3 (the coarse mesh smears the jet), yellow at 1.
  CHECK(jet0 < 20.0);
  CHECK(jet10 > jet0 + 50.0);
  CHECK(std::abs(beside10 - beside0) < 30.0);
  CHECK(jet10 - jet0 > 3.0 * std::abs(beside10 - beside0));
}

TEST_CASE(
    "tetfsi render: a smoke scene's frame is a volume of grey-white smoke at the inflow on a "
    "dark background away from it, and --slice still gives the slice") {
  TempDir dir("render_volume");
  run_scene(dir.path, "smoke_jet.json", "--steps 10 --set output.every=10 " + kCoarseJet);
  app::RenderOptions opt;
  opt.width = 640;
  opt.height = 360;
  opt.output = dir.path / "v10.png";
  const app::RenderReport r10 = app::render_output(dir.path / "o", opt);
  opt.step = 0;
  opt.output = dir.path / "v0.png";
  const app::RenderReport r0 = app::render_output(dir.path / "o", opt);
  REQUIRE(r10.frames.size() == 1);
  CHECK(r10.frames[0].step == 10);
  CHECK(r10.has_volume);
  CHECK_FALSE(r10.has_slice);
  CHECK(r10.color == "smoke_density");
  CHECK(r10.color_range[0] == 0.0);
  CHECK(r10.color_range[1] == doctest::Approx(1.0));  // the smoke the jet emits

  // In the jet near the inflow (y = z = 0.5 m on the -x wall, 2 m/s for 0.2 s) the smoke is
  // dense at step 10: a light, unsaturated grey; at step 0 the same pixel is the dark
  // background. Far from it (low, near the outlet) both frames show the background.
  const Picture v10 = read_png(dir.path / "v10.png"), v0 = read_png(dir.path / "v0.png");
  const Vec3 inflow(0.1, 0.5, 0.5), far(1.6, 0.6, 0.15);
  const auto p_in = app::pixel_of(r10.frames[0], inflow, 640, 360);
  const auto p_far = app::pixel_of(r10.frames[0], far, 640, 360);
  const auto smoke = v10.mean(p_in[0], p_in[1]), clear = v0.mean(p_in[0], p_in[1]);
  const auto far10 = v10.mean(p_far[0], p_far[1]), far0 = v0.mean(p_far[0], p_far[1]);
  INFO("at the inflow: step 10 " << smoke[0] << " " << smoke[1] << " " << smoke[2]
                                 << ", step 0 grey " << grey(clear) << "; far: " << grey(far10)
                                 << " and " << grey(far0));
  CHECK(grey(smoke) > grey(clear) + 60.0);  // 145 against 47 (10 cm voxels blur the jet)
  CHECK(*std::max_element(smoke.begin(), smoke.end()) -
            *std::min_element(smoke.begin(), smoke.end()) <
        25.0);  // grey-white, not coloured
  CHECK(grey(clear) < 90.0);
  CHECK(grey(far10) < 90.0);
  CHECK(std::abs(grey(far10) - grey(far0)) < 8.0);

  // --slice (no plane): the slice picture of before; --slice z=0.4 the plane asked for.
  const Result s =
      tetfsi::test::run_tetfsi(dir.path, "render o --slice --size 320x180 -o s.png", kLimits);
  INFO("stdout: " << s.out << "\nstderr: " << s.err);
  CHECK(s.code == 0);
  CHECK(contains(s.out, "slice z = 0.5 m by smoke_density in [0, 1]"));
  const Result z =
      tetfsi::test::run_tetfsi(dir.path, "render o -o z.png --size 320x180 --slice z=0.4", kLimits);
  CHECK(contains(z.out, "slice z = 0.4 m by smoke_density"));
  const Result v = tetfsi::test::run_tetfsi(dir.path, "render o --size 320x180 -o v.png", kLimits);
  CHECK(contains(v.out, "smoke volume of smoke_density (opacity from 0 to 1)"));
  // Another fluid array than the smoke is drawn on the slice.
  const Result p = tetfsi::test::run_tetfsi(
      dir.path, "render o --color pressure --size 320x180 -o p.png", kLimits);
  CHECK(contains(p.out, "slice z = 0.5 m by pressure"));
}

// (No ';' in test names: ctest's discovery cuts them there and then runs no case.)
TEST_CASE(
    "tetfsi render --all: one PNG per frame, and --movie gives a one-line hint without "
    "ffmpeg or ffmpeg the frames with it") {
  TempDir dir("render_all");
  run_scene(dir.path, "smoke_jet.json", "--steps 4 --set output.every=2 " + kCoarseJet);

  // No ffmpeg on the PATH (Xvfb is still found in /usr/bin).
  fs::create_directories(dir.path / "empty_bin");
  const Result r =
      tetfsi::test::run_tetfsi(dir.path, "render o --all --size 320x180 --movie jet.mp4",
                               fmt::format("ulimit -v 4000000; PATH='{}' /usr/bin/timeout 120",
                                           (dir.path / "empty_bin").string()));
  INFO("stdout: " << r.out << "\nstderr: " << r.err);
  CHECK(r.code == 0);
  CHECK(contains(r.out, "3 frames (steps 0 to 4)"));
  for (int step : {0, 2, 4})
    CHECK(read_png(dir.path / "o" / "pictures" / fmt::format("smoke_jet_{:06d}.png", step)).width ==
          320);
  REQUIRE(r.err_lines().size() == 1);
  CHECK(r.err_lines()[0].rfind("hint: --movie: ffmpeg is not installed", 0) == 0);
  CHECK_FALSE(fs::exists(dir.path / "jet.mp4"));

  // A stand-in ffmpeg that records its arguments and writes the movie file.
  fs::create_directories(dir.path / "bin");
  {
    std::ofstream f(dir.path / "bin" / "ffmpeg");
    f << "#!/bin/sh\necho \"$@\" > \"$(dirname \"$0\")/args.txt\"\nfor last; do :; done\n"
         "echo movie > \"$last\"\n";
  }
  fs::permissions(dir.path / "bin" / "ffmpeg", fs::perms::owner_all);
  const Result m =
      tetfsi::test::run_tetfsi(dir.path, "render o --all --size 320x180 -o frames --movie jet.mp4",
                               fmt::format("ulimit -v 4000000; PATH='{}':/usr/bin:/bin timeout 120",
                                           (dir.path / "bin").string()));
  INFO("stdout: " << m.out << "\nstderr: " << m.err);
  CHECK(m.code == 0);
  CHECK(m.err.empty());
  CHECK(contains(m.out, "movie: jet.mp4"));
  CHECK(fs::exists(dir.path / "jet.mp4"));
  const std::string args = tetfsi::test::read_text(dir.path / "bin" / "args.txt");
  CHECK(contains(args, "-framerate 25"));  // a frame every 2 steps of 0.02 s: real time
  CHECK(contains(args, "frames/smoke_jet_*.png"));
  CHECK(fs::exists(dir.path / "frames" / "smoke_jet_000004.png"));
}

TEST_CASE("tetfsi render: a grid run's .vti frames are sliced too") {
  TempDir dir("render_grid");
  run_scene(dir.path, "smoke_sheets_grid.json",
            "--steps 4 --set output.every=2 --set fluid.grid.cell_size=0.1");
  app::RenderOptions opt;
  opt.width = 480;
  opt.height = 270;
  opt.color = "pressure";
  opt.output = dir.path / "grid.png";
  const app::RenderReport r = app::render_output(dir.path / "o", opt);
  REQUIRE(r.frames.size() == 1);
  CHECK(r.frames[0].step == 4);
  CHECK(r.color == "pressure");
  CHECK(r.color_range[1] > r.color_range[0]);
  CHECK(r.slice.value == doctest::Approx(0.45));  // through the jet: z in [0.35, 0.55]
  const Picture p = read_png(dir.path / "grid.png");
  CHECK(p.width == 480);
  CHECK(p.variance() > 100.0);
}

TEST_CASE(
    "tetfsi render and plot: a missing folder, an unknown array, a step not written and bad "
    "options are one-line errors") {
  TempDir dir("render_errors");
  run_scene(dir.path, "smoke_jet.json", "--steps 2 --set output.every=2 " + kCoarseJet);
  auto cli = [&](const std::string& args) {
    return tetfsi::test::run_tetfsi(dir.path, args, kLimits);
  };
  tetfsi::test::check_one_line_error(cli("render no_such_run"),
                                     {"no such output folder 'no_such_run'", "tetfsi run"});
  tetfsi::test::check_one_line_error(cli("plot no_such_run"),
                                     {"no such output folder 'no_such_run'"});
  tetfsi::test::check_one_line_error(
      cli("render o --color nope"),
      {"--color: no array 'nope'", "smoke_density", "pressure", "von_mises_stress"});
  tetfsi::test::check_one_line_error(cli("render o --body-color nope"),
                                     {"--body-color: no array 'nope'"});
  tetfsi::test::check_one_line_error(cli("render o --step 1"),
                                     {"no frame of step 1 was written", "steps 0, 2", "--all"});
  tetfsi::test::check_one_line_error(cli("render o --slice w=3"),
                                     {"--slice", "AXIS=VALUE", "'w=3'"});
  tetfsi::test::check_one_line_error(cli("render o --slice z=7"),
                                     {"outside the fluid box", "[0, 1]"});
  tetfsi::test::check_one_line_error(cli("render o --movie m.mp4"), {"--movie needs --all"});
  tetfsi::test::check_one_line_error(cli("render o -o no_such_folder/x.png"),
                                     {"cannot write 'no_such_folder/x.png'"});
  tetfsi::test::check_one_line_error(cli("render o/fluid"),
                                     {"holds no run", "scene.resolved.json"});

  // An array of the bodies colours them (the slice keeps smoke_density).
  const Result ok = cli("render o --color volume_ratio --size 320x180 -o v.png");
  INFO("stderr: " << ok.err);
  CHECK(ok.code == 0);
  CHECK(contains(ok.out, "bodies by volume_ratio"));
  CHECK(contains(ok.out, "smoke volume of smoke_density"));
}

TEST_CASE(
    "tetfsi plot: a page of plots from a short run's stats.csv, panels without columns "
    "left out") {
  TempDir dir("plot");
  run_scene(dir.path, "smoke_jet.json", "--steps 3 " + kCoarseJet);
  const Result r = tetfsi::test::run_tetfsi(dir.path, "plot o", kLimits);
  INFO("stdout: " << r.out << "\nstderr: " << r.err);
  CHECK(r.code == 0);
  CHECK(contains(r.out, "o/stats.png: "));
  for (const char* panel : {"energy budget", "solver iterations", "divergence",
                            "fluid mesh quality", "seconds per phase"})
    CHECK(contains(r.out, panel));
  CHECK(contains(r.out, "left out (no data): enclosed volume drift"));  // one-way, no liquid
  const Picture p = read_png(dir.path / "o" / "stats.png");
  CHECK(p.width > 800);
  CHECK(p.variance() > 50.0);

  // A solid-only run has no fluid columns: their panels are left out, the rest drawn.
  TempDir solid("plot_solid");
  run_scene(solid.path, "sheet_sag.json", "--steps 3");
  const Result s = tetfsi::test::run_tetfsi(solid.path, "plot o -o sag.png", kLimits);
  INFO("stdout: " << s.out << "\nstderr: " << s.err);
  CHECK(s.code == 0);
  CHECK(contains(s.out, "energy budget"));
  CHECK(contains(s.out, "left out (no data): "));
  CHECK(contains(s.out, "fluid mesh quality"));
  CHECK(fs::exists(solid.path / "sag.png"));

  // --panels keeps the panels whose titles contain one of its words (docs/results/solid.md's motion
  // figures); none matching is a one-line error.
  const std::string script = std::string(TETFSI_SOURCE_DIR) + "/scripts/plot_stats.py";
  const fs::path csv = solid.path / "o" / "stats.csv", log = solid.path / "panels.log";
  const std::string cmd = "/usr/bin/python3 " + script + " " + csv.string() + " -o " +
                          (solid.path / "pose.png").string() + " --panels height,rotation > " +
                          log.string() + " 2>&1";
  CHECK(std::system(cmd.c_str()) == 0);
  CHECK(contains(tetfsi::test::read_text(log),
                 "2 panels (bodies: height, bodies: rotation from rest)"));
  CHECK(read_png(solid.path / "pose.png").variance() > 50.0);
  const std::string bad = "/usr/bin/python3 " + script + " " + csv.string() + " -o " +
                          (solid.path / "x.png").string() + " --panels nothing > " + log.string() +
                          " 2>&1";
  CHECK(std::system(bad.c_str()) != 0);
  CHECK(contains(tetfsi::test::read_text(log), "error: no panel of"));
  CHECK_FALSE(fs::exists(solid.path / "x.png"));
}

TEST_CASE("tetfsi render: a liquid's surface is drawn, and no slice unless asked") {
  TempDir dir("render_liquid");
  run_scene(dir.path, "dam_break.json",
            "--steps 20 --set output.every=10 --set fluid.grid.cells=[36,12,15]");
  app::RenderOptions opt;
  opt.width = 480;
  opt.height = 270;
  opt.output = dir.path / "liquid.png";
  const app::RenderReport r = app::render_output(dir.path / "o", opt);
  REQUIRE(r.frames.size() == 1);
  CHECK_FALSE(r.has_slice);
  // the water's blue: 2.7 % of the picture at step 20 (the column, just starting to fall, at
  // one end of the tank); without the surface the picture has no blue pixel (grey and white)
  const Picture p = read_png(dir.path / "liquid.png");
  size_t blue = 0;
  for (const auto& c : p.rgb) blue += c[2] > c[0] + 60 ? 1 : 0;
  MESSAGE("blue pixels: " << blue << " of " << p.rgb.size());
  CHECK(blue > p.rgb.size() / 100);
  opt.slice = app::SlicePlane{1, 0.05};
  opt.output = dir.path / "slice.png";
  const app::RenderReport s = app::render_output(dir.path / "o", opt);
  CHECK(s.has_slice);
  CHECK(s.color == "pressure");
}
