/// @file test_scene.cpp
/// Scene files: strict parsing with path-naming errors, defaults, the resolved scene, --set
/// overrides, and build_world (meshes, transforms, pins, loads, velocities, obstacles).
#include <doctest/doctest.h>

#include <atomic>
#include <filesystem>
#include <fstream>
#include <functional>
#include <initializer_list>
#include <string>

#include <unistd.h>

#include "core/error.hpp"
#include "core/linear_solver.hpp"
#include "tools/scene.hpp"

using nlohmann::json;
using namespace tetfsi;
using namespace tetfsi::tools;
namespace fs = std::filesystem;

namespace {

const fs::path source_dir = TETFSI_SOURCE_DIR;
const fs::path fixtures = source_dir / "tests" / "tools" / "scenes";

/// A fresh folder under the temp dir, removed at the end of the test case.
struct TempDir {
  fs::path path;
  TempDir() {
    static std::atomic<int> counter{0};
    path = fs::temp_directory_path() /
           ("tetfsi_test_scene_" + std::to_string(::getpid()) + "_" + std::to_string(counter++));
    fs::create_directories(path);
  }
  ~TempDir() {
    std::error_code ec;
    fs::remove_all(path, ec);
  }
  fs::path write(const std::string& name, const std::string& text) const {
    const fs::path p = path / name;
    fs::create_directories(p.parent_path());
    std::ofstream(p) << text;
    return p;
  }
};

/// A small valid scene: one box body, one pin, one load, one floor.
json sheet_json() {
  return json::parse(R"({
    "name": "sheet",
    "time": { "dt": 0.005, "end_time": 0.5 },
    "output": { "every": 4, "compression": "zlib" },
    "gravity": [0, 0, -9.81],
    "solver": { "linear": "umfpack", "rel_tol": 1e-10, "max_iterations": 50 },
    "bodies": [ {
      "name": "sheet",
      "mesh": { "box": { "lo": [0, 0, 0], "hi": [1, 0.5, 0.02], "cells": [4, 2, 1] } },
      "transform": { "translate": [0, 0, 1] },
      "material": { "density": 1100, "youngs_modulus": 3e5, "poisson_ratio": 0.45,
                    "rayleigh_alpha": 0.1, "rayleigh_beta": 0.001 },
      "pins": [ { "box": { "lo": [0, 0, 1], "hi": [0, 0.5, 1.02] }, "axes": "xyz" } ],
      "loads": [ { "box": { "lo": [1, 0, 1], "hi": [1, 0.5, 1.02] }, "total_force": [0, 0, -3] } ],
      "initial_velocity": [0, 0, 0.5]
    } ],
    "obstacles": [ { "type": "plane", "name": "floor", "point": [0, 0, 0], "normal": [0, 0, 2],
                     "restitution": 0.3, "friction": 0.5 } ]
  })");
}

json minimal_json() {
  return json::parse(
      R"({ "bodies": [ { "name": "b", "mesh": { "box": { "lo": [0, 0, 0], "hi": [1, 1, 1] } } } ] })");
}

/// Run `f`, expect an InputError whose message contains every one of `parts`.
void check_input_error(const std::function<void()>& f, std::initializer_list<std::string> parts) {
  std::string message;
  try {
    f();
  } catch (const InputError& e) {
    message = e.what();
  }
  INFO("message: " << message);
  REQUIRE_FALSE(message.empty());
  CHECK(message.find('\n') == std::string::npos);
  for (const std::string& p : parts) {
    INFO("expected to contain: " << p);
    CHECK(message.find(p) != std::string::npos);
  }
}

/// Parse `j` with one change made by `edit`, expect an InputError containing `parts`.
void check_edit_rejected(const std::function<void(json&)>& edit,
                         std::initializer_list<std::string> parts) {
  json j = sheet_json();
  edit(j);
  check_input_error([&] { parse_scene(j, "scene.json"); }, parts);
}

}  // namespace

TEST_CASE("a valid scene parses with the values it gives") {
  const TempDir dir;
  const Scene s = parse_scene(sheet_json(), dir.path / "scene.json");
  CHECK(s.file == dir.path / "scene.json");
  CHECK(s.name == "sheet");
  CHECK(s.mode == Mode::Dynamic);
  CHECK(s.time.dt == 0.005);
  REQUIRE(s.time.end_time);
  CHECK(*s.time.end_time == 0.5);
  CHECK_FALSE(s.time.steps);
  CHECK(s.time.num_steps() == 100);
  CHECK(s.output.every == 4);
  CHECK(s.output.compression == "zlib");
  CHECK(s.gravity.isApprox(Vec3(0, 0, -9.81)));
  CHECK(s.solver.linear == "umfpack");
  CHECK(s.solver.rel_tol == 1e-10);
  CHECK(s.solver.max_iterations == 50);
  REQUIRE(s.bodies.size() == 1);
  const BodySpec& b = s.bodies[0];
  CHECK(b.name == "sheet");
  CHECK(b.mesh.kind == MeshSpec::Kind::Box);
  CHECK(b.mesh.box.hi.isApprox(Vec3(1, 0.5, 0.02)));
  CHECK(b.mesh.cells == Vec3i(4, 2, 1));
  CHECK(b.transform.translate == Vec3(0, 0, 1));
  CHECK(b.transform.scale == 1.0);
  CHECK(b.material.density == 1100);
  CHECK(b.material.youngs_modulus == 3e5);
  CHECK(b.material.poisson_ratio == 0.45);
  CHECK(b.material.rayleigh_alpha == 0.1);
  CHECK(b.material.rayleigh_beta == 0.001);
  REQUIRE(b.pins.size() == 1);
  REQUIRE(b.pins[0].select.box);
  CHECK(b.pins[0].axes == "xyz");
  REQUIRE(b.loads.size() == 1);
  CHECK(b.loads[0].total_force == Vec3(0, 0, -3));
  CHECK(b.initial_velocity == Vec3(0, 0, 0.5));
  REQUIRE(s.obstacles.size() == 1);
  CHECK(s.obstacles[0].name == "floor");
  CHECK(s.obstacles[0].kind == solid::Obstacle::Kind::Plane);
  CHECK(s.obstacles[0].restitution == 0.3);
  CHECK(s.obstacles[0].friction == 0.5);
}

TEST_CASE("defaults are filled in, in the scene and in the resolved JSON") {
  const Scene s = parse_scene(minimal_json(), "some/where/drop_test.json");
  CHECK(s.name == "drop_test");  // the file's stem
  CHECK(s.mode == Mode::Dynamic);
  CHECK(s.time.dt == 0.01);
  CHECK(s.time.end_time == 1.0);
  CHECK(s.time.num_steps() == 100);
  CHECK(s.output.every == 1);
  CHECK(s.output.compression == "lz4");
  CHECK(s.gravity == Vec3(0, 0, -9.81));
  CHECK(s.solver.linear == "cholmod");
  CHECK(s.statics.load_steps == 1);
  CHECK(s.solid.trapezoid == "paper");
  CHECK(build_world(s).trapezoid == solid::Trapezoid::Paper);
  json mid = minimal_json();
  mid["solid"]["trapezoid"] = "midpoint";
  CHECK(build_world(parse_scene(mid, "m.json")).trapezoid == solid::Trapezoid::Midpoint);
  const solid::Material defaults;
  CHECK(s.bodies[0].material.youngs_modulus == defaults.youngs_modulus);
  CHECK(s.bodies[0].mesh.cells == Vec3i::Ones());

  const json& r = s.resolved;
  CHECK(r["name"] == "drop_test");
  CHECK(r["mode"] == "dynamic");
  CHECK(r["time"]["dt"] == 0.01);
  CHECK(r["time"]["end_time"] == 1.0);
  CHECK_FALSE(r["time"].contains("steps"));
  CHECK(r["output"]["compression"] == "lz4");
  CHECK(r["solver"]["linear"] == "cholmod");
  CHECK(r["static"]["max_iterations"] == 60);
  CHECK(r["solid"]["trapezoid"] == "paper");
  CHECK(r["bodies"][0]["material"]["density"] == defaults.density);
  CHECK(r["bodies"][0]["material"]["poisson_ratio"] == defaults.poisson_ratio);
  CHECK(r["bodies"][0]["mesh"]["box"]["cells"] == json::array({1, 1, 1}));
  CHECK(r["bodies"][0]["transform"]["scale"] == 1.0);
  CHECK(r["bodies"][0]["pins"] == json::array());
  CHECK(r["obstacles"] == json::array());
}

TEST_CASE("TimeSpec::num_steps") {
  TimeSpec t;
  t.dt = 1.0 / 120.0;
  t.end_time = 2.0;
  CHECK(t.num_steps() == 240);  // not 241 from round-off in 2 / (1/120)
  t.dt = 0.3;
  t.end_time = 1.0;
  CHECK(t.num_steps() == 4);  // the last step passes end_time
  t.end_time.reset();
  CHECK(t.num_steps() == 4);  // default end_time 1 s
  t.steps = 7;
  CHECK(t.num_steps() == 7);
}

TEST_CASE("the resolved scene parses back to the same scene") {
  const TempDir dir;
  dir.write("meshes/pair.msh", "");  // only its existence matters for parsing
  json j = sheet_json();
  json file_body = json::parse(R"({ "name": "pair", "mesh": { "file": "meshes/pair.msh" },
                                    "pins": [ { "nodes": [0, 3], "axes": "z" } ] })");
  j["bodies"].push_back(file_body);
  j["obstacles"].push_back(json::parse(R"({ "type": "box", "lo": [2, 2, 0], "hi": [3, 3, 1] })"));
  j["mode"] = "static";
  j["time"] = {{"dt", 0.1}, {"steps", 3}};

  const Scene a = parse_scene(j, dir.path / "scene.json");
  // Written elsewhere (the output folder) and parsed from there: paths are absolute.
  const TempDir elsewhere;
  const Scene b = parse_scene(a.resolved, elsewhere.path / "scene.resolved.json");
  CHECK(b.resolved == a.resolved);
  CHECK(b.name == a.name);
  CHECK(b.mode == Mode::Static);
  CHECK(b.time.steps == 3);
  CHECK_FALSE(b.time.end_time);
  CHECK(b.bodies.size() == 2);
  CHECK(b.bodies[1].mesh.kind == MeshSpec::Kind::File);
  CHECK(b.bodies[1].mesh.file == a.bodies[1].mesh.file);
  CHECK(b.bodies[1].mesh.file.is_absolute());
  CHECK(b.bodies[1].pins[0].select.nodes == std::vector<Index>{0, 3});
  CHECK(b.bodies[1].pins[0].axes == "z");
  CHECK(b.bodies[0].material.rayleigh_beta == a.bodies[0].material.rayleigh_beta);
  CHECK(b.obstacles.size() == 2);
  CHECK(b.obstacles[1].name == "box1");
  CHECK(b.obstacles[1].hi == Vec3(3, 3, 1));
  // And through text, as the output writer stores it.
  const Scene c = parse_scene(json::parse(a.resolved.dump(2)), elsewhere.path / "x.json");
  CHECK(c.resolved == a.resolved);
}

TEST_CASE("unknown keys name the JSON path and suggest the nearest valid key") {
  check_edit_rejected(
      [](json& j) {
        auto& m = j["bodies"][0]["material"];
        m["poison_ratio"] = m["poisson_ratio"];
        m.erase("poisson_ratio");
      },
      {"scene.json: bodies[0].material.poison_ratio: unknown key (did you mean 'poisson_ratio'?)"});
  check_edit_rejected([](json& j) { j["time"]["dtt"] = 0.1; },
                      {"scene.json: time.dtt: unknown key", "'dt'"});
  // Nothing close: list the valid keys of that level.
  check_edit_rejected([](json& j) { j["bodies"][0]["colour"] = "red"; },
                      {"scene.json: bodies[0].colour: unknown key", "valid keys here:", "material",
                       "initial_velocity"});
  check_edit_rejected([](json& j) { j["gravty"] = 1; },
                      {"scene.json: gravty: unknown key (did you mean 'gravity'?)"});
  check_input_error([] { parse_scene(json::array(), "scene.json"); },
                    {"scene.json: (top level): expected an object, got array []"});
}

TEST_CASE("wrong types are reported with what was found") {
  check_edit_rejected([](json& j) { j["time"]["dt"] = "abc"; },
                      {"scene.json: time.dt: expected a number, got string \"abc\""});
  check_edit_rejected(
      [](json& j) {
        j["gravity"] = json::array({0, -9.81});
      },
      {"scene.json: gravity: expected an array of 3 numbers, got array [0,-9.81]"});
  check_edit_rejected([](json& j) { j["gravity"][1] = true; },
                      {"gravity[1]: expected a number, got boolean true"});
  check_edit_rejected(
      [](json& j) {
        j["bodies"][0]["mesh"]["box"]["cells"] = json::array({4, 2.5, 1});
      },
      {"bodies[0].mesh.box.cells[1]: expected an integer, got number 2.5"});
  check_edit_rejected(
      [](json& j) {
        j["bodies"][0]["mesh"]["box"]["cells"] = json::array({4, 0, 1});
      },
      {"bodies[0].mesh.box.cells[1]:", "positive"});
  check_edit_rejected([](json& j) { j["bodies"] = json::object(); }, {"bodies: expected an array"});
  check_edit_rejected([](json& j) { j["bodies"][0]["name"] = 3; },
                      {"bodies[0].name: expected a string, got number 3"});
  // JSON has no NaN, but an in-memory scene can: rejected like any non-finite value.
  check_edit_rejected([](json& j) { j["bodies"][0]["material"]["density"] = std::nan(""); },
                      {"bodies[0].material.density: expected a finite number"});
}

TEST_CASE("out-of-range values say what the range is") {
  check_edit_rejected([](json& j) { j["bodies"][0]["material"]["poisson_ratio"] = 0.5; },
                      {"scene.json: bodies[0].material.poisson_ratio:", "< 0.5",
                       "0.5 is incompressible and locks linear tets"});
  check_edit_rejected([](json& j) { j["bodies"][0]["material"]["poisson_ratio"] = -1; },
                      {"bodies[0].material.poisson_ratio:", "> -1"});
  check_edit_rejected([](json& j) { j["time"]["dt"] = 0; }, {"scene.json: time.dt: must be > 0"});
  check_edit_rejected([](json& j) { j["time"]["dt"] = -0.1; }, {"time.dt: must be > 0", "-0.1"});
  check_edit_rejected([](json& j) { j["time"]["steps"] = 10; },
                      {"scene.json: time: give either 'end_time' or 'steps', not both"});
  check_edit_rejected([](json& j) { j["time"]["end_time"] = 0; }, {"time.end_time: must be > 0"});
  check_edit_rejected(
      [](json& j) {
        j["time"].erase("end_time");
        j["time"]["steps"] = 0;
      },
      {"time.steps: must be >= 1"});
  check_edit_rejected([](json& j) { j["output"]["every"] = 0; }, {"output.every: must be >= 1"});
  check_edit_rejected([](json& j) { j["output"]["compression"] = "lz5"; },
                      {"output.compression: unknown compression 'lz5' (did you mean 'lz4'?)"});
  check_edit_rejected([](json& j) { j["mode"] = "quasi-static"; },
                      {"mode: unknown mode 'quasi-static'"});
  check_edit_rejected([](json& j) { j["solver"]["linear"] = "superlu"; },
                      {"solver.linear: unknown linear solver"});
  check_edit_rejected(
      [](json& j) { j["solid"]["trapezoid"] = "midpiont"; },
      {"solid.trapezoid: unknown trapezoid variant 'midpiont' (did you mean 'midpoint'?)"});
  check_edit_rejected([](json& j) { j["bodies"][0]["material"]["density"] = 0; },
                      {"material.density: must be > 0"});
  check_edit_rejected([](json& j) { j["bodies"][0]["material"]["youngs_modulus"] = -1; },
                      {"material.youngs_modulus: must be > 0"});
  check_edit_rejected([](json& j) { j["bodies"][0]["material"]["rayleigh_beta"] = -1e-3; },
                      {"material.rayleigh_beta: must be >= 0"});
  check_edit_rejected([](json& j) { j["obstacles"][0]["restitution"] = 1.5; },
                      {"obstacles[0].restitution: must be in [0, 1]"});
  check_edit_rejected([](json& j) { j["obstacles"][0]["friction"] = -0.1; },
                      {"obstacles[0].friction: must be >= 0"});
  check_edit_rejected(
      [](json& j) {
        j["obstacles"][0]["normal"] = json::array({0, 0, 0});
      },
      {"obstacles[0].normal: must not be zero"});
  check_edit_rejected([](json& j) { j["obstacles"][0]["type"] = "sphere"; },
                      {"obstacles[0].type: unknown obstacle type"});
  check_edit_rejected([](json& j) { j["bodies"][0]["mesh"]["box"]["hi"][0] = 0; },
                      {"bodies[0].mesh.box: lo must be < hi", "axis x"});
  check_edit_rejected([](json& j) { j["bodies"][0]["pins"][0]["axes"] = "xw"; },
                      {"bodies[0].pins[0].axes: must be a non-empty subset of \"xyz\""});
  check_edit_rejected([](json& j) { j["bodies"][0]["pins"][0]["axes"] = ""; },
                      {"pins[0].axes: must be a non-empty"});
  check_edit_rejected([](json& j) { j["bodies"][0]["pins"][0]["nodes"] = json::array({1}); },
                      {"bodies[0].pins[0]: give either 'box' or 'nodes', not both"});
  check_edit_rejected([](json& j) { j["bodies"].push_back(j["bodies"][0]); },
                      {"bodies[1].name: duplicate body name 'sheet'"});
  check_edit_rejected([](json& j) { j["bodies"] = json::array(); },
                      {"scene.json: bodies: a scene needs at least one body"});
  check_edit_rejected([](json& j) { j.erase("bodies"); }, {"missing required key 'bodies'"});
  check_edit_rejected(
      [](json& j) { j["bodies"][0]["mesh"]["file"] = "x.msh"; },
      {"bodies[0].mesh: give exactly one of 'box', 'file' or 'surface', got 'box' and 'file'"});
  check_edit_rejected([](json& j) { j["bodies"][0]["mesh"] = json::object(); },
                      {"bodies[0].mesh: give exactly one of"});
  check_edit_rejected([](json& j) { j["bodies"][0]["transform"]["scale"] = 0; },
                      {"transform.scale: must be > 0"});
}

TEST_CASE("mesh files resolve against the scene's folder and must exist") {
  const TempDir dir;
  dir.write("meshes/ball.off", "");
  json j = minimal_json();
  j["bodies"][0]["mesh"] = {{"file", "meshes/bar.msh"}};
  const fs::path expected = dir.path / "meshes" / "bar.msh";
  check_input_error([&] { parse_scene(j, dir.path / "scene.json"); },
                    {"scene.json: bodies[0].mesh.file: no such file '" + expected.string() + "'"});

  j["bodies"][0]["mesh"] = {{"surface", "meshes/ball.off"}};
  check_input_error([&] { parse_scene(j, dir.path / "scene.json"); },
                    {"bodies[0].mesh: a 'surface' mesh needs 'cell_size'"});
  j["bodies"][0]["mesh"]["cell_size"] = 0;
  check_input_error([&] { parse_scene(j, dir.path / "scene.json"); },
                    {"bodies[0].mesh.cell_size: must be > 0"});
  j["bodies"][0]["mesh"]["cell_size"] = 0.05;
  const Scene s = parse_scene(j, dir.path / "scene.json");
  CHECK(s.bodies[0].mesh.kind == MeshSpec::Kind::Surface);
  CHECK(s.bodies[0].mesh.file == dir.path / "meshes" / "ball.off");
  CHECK(s.bodies[0].mesh.cell_size == 0.05);

  // load_scene from another working directory: the fixture's mesh is next to it.
  const Scene f = load_scene(fixtures / "two_tets.json");
  CHECK(f.bodies[0].mesh.file == (fixtures / "two_tets.msh").lexically_normal());
  CHECK(f.name == "two_tets");
}

TEST_CASE("load_scene: missing file, JSON syntax errors with line and column") {
  check_input_error([] { load_scene("/nonexistent/folder/scene.json"); },
                    {"/nonexistent/folder/scene.json: no such scene file"});
  // The fixture's error is the missing comma on line 4, at the second string.
  check_input_error([] { load_scene(fixtures / "syntax_error.json"); },
                    {"syntax_error.json: line 4, column", "invalid JSON", "syntax error"});
  const TempDir dir;
  const fs::path p = dir.write("broken.json", "{\n  \"time\": {\n    \"dt\": 0.01,\n  }\n}\n");
  check_input_error([&] { load_scene(p); }, {"broken.json: line 4, column 3: invalid JSON"});
  const fs::path q = dir.write("truncated.json", "{ \"bodies\": [");
  check_input_error([&] { load_scene(q); }, {"truncated.json: line 1, column", "invalid JSON"});
  // A key given twice would silently keep the last value: rejected, with its path.
  const fs::path d =
      dir.write("dup.json", R"({ "bodies": [ { "name": "a", "mesh": { "box": { "lo": [0, 0, 0],
      "hi": [1, 1, 1] } } }, { "name": "b", "mesh": {}, "name": "c" } ] })");
  check_input_error([&] { load_scene(d); }, {"dup.json: bodies[1].name: duplicate key"});
  const fs::path d2 =
      dir.write("dup2.json", R"({ "time": { "dt": 0.1 }, "gravity": [0, 0, -1], "time": {} })");
  check_input_error([&] { load_scene(d2); }, {"dup2.json: time: duplicate key"});
  const fs::path d3 = dir.write(
      "dup3.json", R"({ "bodies": [ [1, 2, {}], { "mesh": { "file": "a", "file": "b" } } ] })");
  check_input_error([&] { load_scene(d3); }, {"dup3.json: bodies[1].mesh.file: duplicate key"});
}

TEST_CASE("--set overrides change values, create allowed keys and reject malformed ones") {
  const TempDir dir;
  const fs::path file = dir.write("scene.json", sheet_json().dump(2));
  const Scene s = load_scene(
      file, {"time.dt=0.001", "bodies.0.material.density=500", "name=renamed", "gravity=[0, -1, 0]",
             "static.load_steps=4", "bodies.0.pins.0.axes=z", "solver.linear=cholmod"});
  CHECK(s.time.dt == 0.001);
  CHECK(s.bodies[0].material.density == 500);
  CHECK(s.name == "renamed");  // not valid JSON: taken as a string
  CHECK(s.gravity == Vec3(0, -1, 0));
  CHECK(s.statics.load_steps == 4);  // "static" did not exist: created
  CHECK(s.bodies[0].pins[0].axes == "z");
  CHECK(s.solver.linear == "cholmod");
  CHECK(s.resolved["bodies"][0]["material"]["density"] == 500);

  // Replacing end_time by steps needs both changes; steps alone collides with end_time.
  check_input_error([&] { load_scene(file, {"time.steps=10"}); },
                    {"time: give either 'end_time' or 'steps'"});
  // A new key the schema lacks is reported by the parser as usual.
  check_input_error([&] { load_scene(file, {"time.dtt=0.1"}); },
                    {"time.dtt: unknown key (did you mean 'dt'?)"});
  // A non-number string (e.g. nan) where a number belongs.
  check_input_error([&] { load_scene(file, {"time.dt=nan"}); },
                    {"time.dt: expected a number, got string \"nan\""});
  check_input_error([&] { load_scene(file, {"time.dt=abc"}); },
                    {"time.dt: expected a number, got string \"abc\""});
  // Malformed overrides name themselves.
  check_input_error([&] { load_scene(file, {"time.dt"}); },
                    {"scene.json: --set 'time.dt':", "key.path=value"});
  check_input_error([&] { load_scene(file, {"=3"}); }, {"--set '=3':", "empty key"});
  check_input_error([&] { load_scene(file, {"bodies.3.name=x"}); },
                    {"--set 'bodies.3.name=x': index 3 is out of range ('bodies' has 1 element)"});
  check_input_error([&] { load_scene(file, {"bodies.first.name=x"}); }, {"'bodies' is an array"});
  check_input_error([&] { load_scene(file, {"time.dt.x=1"}); },
                    {"'time.dt' is number 0.005, not an object"});
  check_input_error([&] { load_scene(file, {"time..dt=1"}); }, {"empty component"});
}

namespace {

/// sheet_json() with a fluid box around the sheet, one inflow patch and every mesh key.
json fluid_json() {
  json j = sheet_json();
  j["fluid"] = json::parse(R"({
    "domain": { "lo": [-0.5, -0.5, 0], "hi": [1.5, 1, 2], "default": "open",
                "patches": [ { "name": "jet", "kind": "inflow", "side": "-y",
                               "lo": [0.2, 0.5], "hi": [0.4, 0.7] },
                             { "kind": "wall", "side": "+z", "lo": [-1, -1], "hi": [3, 3] } ] },
    "mesh": { "surface_size": 0.04, "far_size": 0.3, "grading": 0.7, "max_cells": 20000 }
  })");
  return j;
}

void check_fluid_rejected(const std::function<void(json&)>& edit,
                          std::initializer_list<std::string> parts) {
  json j = fluid_json();
  edit(j);
  check_input_error([&] { parse_scene(j, "scene.json"); }, parts);
}

}  // namespace

TEST_CASE("the fluid section parses into the remesher's structs and resolves back") {
  const Scene s = parse_scene(fluid_json(), "scene.json");
  REQUIRE(s.fluid);
  const mesh::FluidDomain& d = s.fluid->domain;
  CHECK(d.lo == Vec3(-0.5, -0.5, 0));
  CHECK(d.hi == Vec3(1.5, 1, 2));
  CHECK(d.default_kind == mesh::FaceKind::Open);
  REQUIRE(d.patches.size() == 2);
  CHECK(d.patches[0].name == "jet");
  CHECK(d.patches[0].kind == mesh::FaceKind::Inflow);
  CHECK(d.patches[0].side == 2);  // -y
  CHECK(d.patches[0].lo == Vec2(0.2, 0.5));
  CHECK(d.patches[0].hi == Vec2(0.4, 0.7));
  CHECK(d.patches[1].name == "patch1");  // default name: its index
  CHECK(d.patches[1].kind == mesh::FaceKind::Wall);
  CHECK(d.patches[1].side == 5);  // +z
  const mesh::Sizing& z = s.fluid->sizing;
  CHECK(z.surface_size == 0.04);
  CHECK(z.far_size == 0.3);
  CHECK(z.grading == 0.7);
  CHECK(z.max_cells == 20000);
  CHECK_FALSE(z.refine);

  // Every side string maps to its index 0..5.
  const char* sides[] = {"-x", "+x", "-y", "+y", "-z", "+z"};
  for (int k = 0; k < 6; ++k) {
    CAPTURE(sides[k]);
    json j = fluid_json();
    j["fluid"]["domain"]["patches"][1]["side"] = sides[k];
    CHECK(parse_scene(j, "scene.json").fluid->domain.patches[1].side == k);
  }

  // The resolved scene holds the section with its defaults and parses back to the same.
  const json& r = s.resolved;
  CHECK(r["fluid"]["domain"]["default"] == "open");
  CHECK(r["fluid"]["domain"]["patches"][0]["side"] == "-y");
  CHECK(r["fluid"]["domain"]["patches"][0]["kind"] == "inflow");
  CHECK(r["fluid"]["domain"]["patches"][1]["name"] == "patch1");
  CHECK(r["fluid"]["mesh"]["max_cells"] == 20000);
  const Scene b = parse_scene(json::parse(r.dump(2)), "back.json");
  CHECK(b.resolved == r);
  REQUIRE(b.fluid);
  CHECK(b.fluid->domain.patches[0].lo == d.patches[0].lo);

  // Only "domain" with lo / hi is required; the rest has the remesher's defaults.
  json minimal = sheet_json();
  minimal["fluid"] = {{"domain", {{"lo", {-1, -1, -1}}, {"hi", {2, 2, 2}}}}};
  const Scene m = parse_scene(minimal, "scene.json");
  REQUIRE(m.fluid);
  const mesh::Sizing defaults;
  CHECK(m.fluid->domain.default_kind == mesh::FaceKind::Wall);
  CHECK(m.fluid->domain.patches.empty());
  CHECK(m.fluid->sizing.surface_size == defaults.surface_size);
  CHECK(m.fluid->sizing.far_size == defaults.far_size);
  CHECK(m.fluid->sizing.grading == defaults.grading);
  CHECK(m.fluid->sizing.max_cells == 0);
  CHECK(m.resolved["fluid"]["domain"]["default"] == "wall");
  CHECK(m.resolved["fluid"]["domain"]["patches"] == json::array());
  CHECK(m.resolved["fluid"]["mesh"]["far_size"] == defaults.far_size);

  // Without a fluid section there is none, in the scene or in the resolved JSON.
  const Scene none = parse_scene(sheet_json(), "scene.json");
  CHECK_FALSE(none.fluid);
  CHECK_FALSE(none.resolved.contains("fluid"));
}

TEST_CASE("fluid section errors name the JSON path and the problem") {
  // Unknown keys, at every level, with the nearest valid key.
  check_fluid_rejected([](json& j) { j["fluid"]["meshes"] = json::object(); },
                       {"scene.json: fluid.meshes: unknown key (did you mean 'mesh'?)"});
  check_fluid_rejected([](json& j) { j["fluid"]["domain"]["defualt"] = "wall"; },
                       {"fluid.domain.defualt: unknown key (did you mean 'default'?)"});
  check_fluid_rejected([](json& j) { j["fluid"]["domain"]["patches"][0]["sides"] = "-x"; },
                       {"fluid.domain.patches[0].sides: unknown key (did you mean 'side'?)"});
  check_fluid_rejected([](json& j) { j["fluid"]["mesh"]["surface"] = 0.1; },
                       {"fluid.mesh.surface: unknown key", "surface_size"});
  // Missing pieces.
  check_fluid_rejected([](json& j) { j["fluid"].erase("domain"); },
                       {"scene.json: fluid: missing required key 'domain'"});
  check_fluid_rejected([](json& j) { j["fluid"]["domain"].erase("hi"); },
                       {"fluid.domain: missing required key 'hi'"});
  check_fluid_rejected([](json& j) { j["fluid"]["domain"]["patches"][0].erase("side"); },
                       {"fluid.domain.patches[0]: missing required key 'side'"});
  check_fluid_rejected([](json& j) { j["fluid"]["domain"]["patches"][0].erase("kind"); },
                       {"fluid.domain.patches[0]: missing required key 'kind'"});
  // Choices.
  check_fluid_rejected([](json& j) { j["fluid"]["domain"]["patches"][0]["side"] = "x"; },
                       {"fluid.domain.patches[0].side: unknown side 'x'", "'-x'"});
  check_fluid_rejected([](json& j) { j["fluid"]["domain"]["patches"][0]["side"] = "+w"; },
                       {"fluid.domain.patches[0].side: unknown side '+w'"});
  check_fluid_rejected([](json& j) { j["fluid"]["domain"]["patches"][0]["side"] = 2; },
                       {"fluid.domain.patches[0].side: expected a string, got number 2"});
  check_fluid_rejected(
      [](json& j) { j["fluid"]["domain"]["patches"][0]["kind"] = "solid"; },
      {"fluid.domain.patches[0].kind: unknown boundary kind 'solid'", "wall", "inflow", "open"});
  check_fluid_rejected(
      [](json& j) { j["fluid"]["domain"]["default"] = "wal"; },
      {"fluid.domain.default: unknown boundary kind 'wal' (did you mean 'wall'?)"});
  // Boxes and rectangles.
  check_fluid_rejected([](json& j) { j["fluid"]["domain"]["hi"][2] = 0; },
                       {"scene.json: fluid.domain: lo must be < hi", "axis z"});
  check_fluid_rejected([](json& j) { j["fluid"]["domain"]["lo"][0] = 3; },
                       {"fluid.domain: lo must be < hi", "axis x"});
  check_fluid_rejected([](json& j) { j["fluid"]["domain"]["patches"][0]["hi"][1] = 0.5; },
                       {"fluid.domain.patches[0]: lo must be < hi", "(x, z) of side -y"});
  check_fluid_rejected(
      [](json& j) {
        j["fluid"]["domain"]["patches"][0]["lo"] = json::array({0.2, 0.5, 0});
      },
      {"fluid.domain.patches[0].lo: expected an array of 2 numbers, got array [0.2,0.5,0]"});
  check_fluid_rejected(
      [](json& j) {
        auto& p = j["fluid"]["domain"]["patches"][0];
        p["lo"] = json::array({5, 0});
        p["hi"] = json::array({6, 1});
      },
      {"fluid.domain.patches[0]: the rectangle [5, 0]..[6, 1] misses side -y of the fluid box",
       "(x, z) [-0.5, 0]..[1.5, 2]"});
  check_fluid_rejected([](json& j) { j["fluid"]["domain"]["patches"][1]["name"] = "jet"; },
                       {"fluid.domain.patches[1].name: duplicate patch name 'jet'"});
  check_fluid_rejected([](json& j) { j["fluid"]["domain"]["patches"] = json::object(); },
                       {"fluid.domain.patches: expected an array"});
  // Sizes.
  check_fluid_rejected([](json& j) { j["fluid"]["mesh"]["surface_size"] = 0; },
                       {"fluid.mesh.surface_size: must be > 0 (m), got 0"});
  check_fluid_rejected([](json& j) { j["fluid"]["mesh"]["far_size"] = -0.2; },
                       {"fluid.mesh.far_size: must be > 0 (m)"});
  check_fluid_rejected([](json& j) { j["fluid"]["mesh"]["surface_size"] = 0.5; },
                       {"fluid.mesh.surface_size: must be <= far_size (0.3 m), got 0.5 m"});
  check_fluid_rejected([](json& j) { j["fluid"]["mesh"]["grading"] = 0; },
                       {"fluid.mesh.grading: must be > 0"});
  check_fluid_rejected([](json& j) { j["fluid"]["mesh"]["max_cells"] = -1; },
                       {"fluid.mesh.max_cells: must be >= 0"});
  check_fluid_rejected([](json& j) { j["fluid"]["mesh"]["max_cells"] = 2.5; },
                       {"fluid.mesh.max_cells: expected an integer, got number 2.5"});
  check_fluid_rejected([](json& j) { j["fluid"]["mesh"]["surface_size"] = "nan"; },
                       {"fluid.mesh.surface_size: expected a number, got string \"nan\""});
  check_fluid_rejected([](json& j) { j["fluid"]["mesh"]["far_size"] = std::nan(""); },
                       {"fluid.mesh.far_size: expected a finite number"});
  check_fluid_rejected([](json& j) { j["fluid"] = 1; },
                       {"scene.json: fluid: expected an object, got number 1"});

  // Through --set, as a user types it: "nan" is not JSON, so it arrives as a string.
  const TempDir dir;
  const fs::path file = dir.write("scene.json", fluid_json().dump());
  check_input_error([&] { load_scene(file, {"fluid.mesh.surface_size=nan"}); },
                    {"fluid.mesh.surface_size: expected a number, got string \"nan\""});
  CHECK(load_scene(file, {"fluid.mesh.far_size=0.5"}).fluid->sizing.far_size == 0.5);
}

TEST_CASE("the shipped scenes parse") {
  for (const char* name : {"sheet_sag.json", "csm1.json", "remesh_sheet.json"}) {
    INFO(name);
    const Scene s = load_scene(source_dir / "data" / "scenes" / name);
    CHECK_FALSE(s.bodies.empty());
    CHECK(s.time.num_steps() >= 1);
  }
  const Scene sag = load_scene(source_dir / "data" / "scenes" / "sheet_sag.json");
  CHECK(sag.mode == Mode::Dynamic);
  CHECK(sag.time.num_steps() == 240);
  const Scene csm = load_scene(source_dir / "data" / "scenes" / "csm1.json");
  CHECK(csm.mode == Mode::Static);
  CHECK(csm.gravity == Vec3(0, -2, 0));
  CHECK(csm.bodies[0].material.youngs_modulus == 1.4e6);
  CHECK(csm.bodies[0].material.poisson_ratio == 0.4);
  // remesh_sheet: sheet_sag's sheet, inside a fluid box with >= 0.2 m clearance around it.
  const Scene rs = load_scene(source_dir / "data" / "scenes" / "remesh_sheet.json");
  CHECK(rs.time.num_steps() == 240);
  CHECK(rs.output.every == 4);
  CHECK(rs.resolved["bodies"] == sag.resolved["bodies"]);
  REQUIRE(rs.fluid);
  const MatX3& X = build_world(rs).bodies[0].rest_positions();
  const Vec3 lo = X.colwise().minCoeff().transpose(), hi = X.colwise().maxCoeff().transpose();
  CHECK(((lo - rs.fluid->domain.lo).array() >= 0.2 - 1e-12).all());
  CHECK(((rs.fluid->domain.hi - hi).array() >= 0.2 - 1e-12).all());
  CHECK(rs.fluid->sizing.surface_size == 0.05);
  CHECK(rs.fluid->sizing.far_size == 0.2);
}

// ---- build_world (needs mesh/ and solid/) ----

TEST_CASE("build_world: box body with transform, pins, loads, velocity and obstacles") {
  const Scene s = parse_scene(sheet_json(), "scene.json");
  solid::SolidWorld w = build_world(s);
  CHECK(w.gravity == s.gravity);
  CHECK(w.linear_solver == SolverKind::Umfpack);
  CHECK(w.solver_options.rel_tol == 1e-10);
  CHECK(w.solver_options.max_iterations == 50);
  REQUIRE(w.bodies.size() == 1);
  const solid::SolidBody& b = w.bodies[0];
  CHECK(b.name() == "sheet");
  CHECK(b.num_nodes() == 5 * 3 * 2);
  CHECK(b.num_tets() == 6 * 4 * 2);
  // Translated by +1 in z.
  CHECK(b.rest_positions().col(2).minCoeff() == doctest::Approx(1.0));
  CHECK(b.rest_positions().col(2).maxCoeff() == doctest::Approx(1.02));
  CHECK(b.total_mass() == doctest::Approx(1100 * 1.0 * 0.5 * 0.02));
  // Pinned: the x = 0 edge face, 3 × 2 nodes, all axes.
  CHECK(b.num_fixed_dofs() == 3 * 6);
  for (Index v = 0; v < b.num_nodes(); ++v) {
    const bool on_edge = std::abs(b.rest_positions()(v, 0)) < 1e-12;
    for (int a = 0; a < 3; ++a) CHECK(b.is_fixed(3 * v + a) == on_edge);
    // Initial velocity on free DOFs only.
    CHECK(b.velocity(v, 2) == (on_edge ? 0.0 : 0.5));
    CHECK(b.velocity(v, 0) == 0.0);
  }
  // Load spread over the 6 nodes of the x = 1 face; it sums to total_force.
  CHECK(b.applied_force.colwise().sum().transpose().isApprox(Vec3(0, 0, -3)));
  Index loaded = 0;
  for (Index v = 0; v < b.num_nodes(); ++v) {
    if (b.applied_force.row(v).norm() > 0) {
      ++loaded;
      CHECK(b.applied_force(v, 2) == doctest::Approx(-0.5));
    }
  }
  CHECK(loaded == 6);
  REQUIRE(w.obstacles.size() == 1);
  CHECK(w.obstacles[0].normal.isApprox(Vec3::UnitZ()));  // normalised from [0, 0, 2]
}

TEST_CASE("build_world: scale, then rotate Rz·Ry·Rx, then translate") {
  json j = minimal_json();
  j["bodies"][0]["transform"] = {
      {"scale", 2.0}, {"rotate_deg", {0, 0, 90}}, {"translate", {10, 0, 0}}};
  const solid::SolidWorld w = build_world(parse_scene(j, "scene.json"));
  const MatX3& x = w.bodies[0].rest_positions();
  // [0,1]³ scaled to [0,2]³, rotated 90° about z to x ∈ [−2,0], y ∈ [0,2], then x += 10.
  CHECK(x.col(0).minCoeff() == doctest::Approx(8.0));
  CHECK(x.col(0).maxCoeff() == doctest::Approx(10.0));
  CHECK(x.col(1).minCoeff() == doctest::Approx(0.0).epsilon(1e-9));
  CHECK(x.col(1).maxCoeff() == doctest::Approx(2.0));
  CHECK(w.bodies[0].total_mass() == doctest::Approx(1000.0 * 8.0));
}

TEST_CASE("build_world: selections that pick nothing or out-of-range nodes are input errors") {
  json j = sheet_json();
  j["bodies"][0]["pins"].push_back({{"box", {{"lo", {5, 5, 5}}, {"hi", {6, 6, 6}}}}});
  check_input_error([&] { build_world(parse_scene(j, "scene.json")); },
                    {"scene.json: bodies[0].pins[1]: the box",
                     "selects no node; the body spans [0, 0, 1]..[1, 0.5, 1.02]"});
  j = sheet_json();
  j["bodies"][0]["loads"][0] = {{"nodes", {0, 30}}, {"total_force", {1, 0, 0}}};
  check_input_error(
      [&] { build_world(parse_scene(j, "scene.json")); },
      {"scene.json: bodies[0].loads[0].nodes[1]: node 30 is out of range (the body has 30 nodes"});
}

TEST_CASE("build_world: a mesh file with an inverted tet names the scene, the body and the tet") {
  const Scene s = load_scene(fixtures / "inverted_tet.json");
  std::string message;
  try {
    build_world(s);
  } catch (const MeshError& e) {
    message = e.what();
  }
  INFO(message);
  CHECK(message.find("inverted_tet.json: bodies[1] 'flag': ") != std::string::npos);
  CHECK(message.find("inverted_tet.msh") != std::string::npos);
  CHECK(message.find("inverted") != std::string::npos);

  // The valid fixture builds, with node 0 pinned.
  const solid::SolidWorld w = build_world(load_scene(fixtures / "two_tets.json"));
  REQUIRE(w.bodies.size() == 1);
  CHECK(w.bodies[0].num_tets() == 2);
  CHECK(w.bodies[0].num_fixed_dofs() == 3);
}

TEST_CASE("build_world: a closed surface is tetrahedralised at the requested cell size") {
  json j = minimal_json();
  j["bodies"][0]["mesh"] = {{"surface", "cube.off"}, {"cell_size", 0.25}};
  j["bodies"][0]["material"] = {{"density", 500.0}};
  const Scene s = parse_scene(j, fixtures / "surface_scene.json");  // in-memory, anchored there
  CHECK(s.bodies[0].mesh.file == fixtures / "cube.off");
  const solid::SolidWorld w = build_world(s);
  const solid::SolidBody& b = w.bodies[0];
  CHECK(b.num_tets() > 12);
  // Mesh_3 approximates the cube's volume (sharp edges are not protected): mass ≈ ρ · 1 m³.
  CHECK(b.total_mass() == doctest::Approx(500.0).epsilon(0.15));
  CHECK(b.rest_positions().minCoeff() >= -1e-6);
  CHECK(b.rest_positions().maxCoeff() <= 1.0 + 1e-6);
}
