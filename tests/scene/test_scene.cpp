/// @file test_scene.cpp
/// Scene files: strict parsing with path-naming errors, defaults, the resolved scene, --set
/// overrides, and build_world (meshes, transforms, pins, loads, velocities, obstacles).
#include <doctest/doctest.h>

#include <atomic>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <initializer_list>
#include <string>

#include <unistd.h>

#include "core/error.hpp"
#include "core/linear_solver.hpp"
#include "scene/scene.hpp"

using nlohmann::json;
using namespace tetfsi;
using namespace tetfsi::app;
namespace fs = std::filesystem;

namespace {

const fs::path source_dir = TETFSI_SOURCE_DIR;
const fs::path fixtures = source_dir / "tests" / "scenes";

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
  CHECK(r["solid"]["integrator"] == "newton");  // trapezoid: linearized only
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
  check_edit_rejected([](json& j) { j["time"]["dt"] = 0; },
                      {"scene.json: time.dt: must be in [1e-9, 1e6]"});
  check_edit_rejected([](json& j) { j["time"]["dt"] = -0.1; },
                      {"time.dt: must be in [1e-9, 1e6]", "-0.1"});
  check_edit_rejected([](json& j) { j["time"]["steps"] = 10; },
                      {"scene.json: time: give either 'end_time' or 'steps', not both"});
  check_edit_rejected([](json& j) { j["time"]["end_time"] = 0; },
                      {"time.end_time: must be in [1e-9, 1e6]"});
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
                      {"material.density: must be in [1e-10, 1e5]"});
  check_edit_rejected([](json& j) { j["bodies"][0]["material"]["youngs_modulus"] = -1; },
                      {"material.youngs_modulus: must be in [0.01, 1e13]"});
  check_edit_rejected([](json& j) { j["bodies"][0]["material"]["rayleigh_beta"] = -1e-3; },
                      {"material.rayleigh_beta: must be in [0, 1e6]"});
  check_edit_rejected([](json& j) { j["obstacles"][0]["restitution"] = 1.5; },
                      {"obstacles[0].restitution: must be in [0, 1]"});
  check_edit_rejected([](json& j) { j["obstacles"][0]["friction"] = -0.1; },
                      {"obstacles[0].friction: must be in [0, 100]"});
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
                      {"scene.json: bodies: a scene needs at least one body"});  // no fluid
  check_edit_rejected([](json& j) { j.erase("bodies"); }, {"missing required key 'bodies'"});
  check_edit_rejected(
      [](json& j) { j["bodies"][0]["mesh"]["file"] = "x.msh"; },
      {"bodies[0].mesh: give exactly one of 'box', 'file', 'surface', 'sphere', 'shell', "
       "'hollow_box', 'tube' or 'bowl', got 'box' and 'file'"});
  check_edit_rejected([](json& j) { j["bodies"][0]["mesh"] = json::object(); },
                      {"bodies[0].mesh: give exactly one of"});
  check_edit_rejected([](json& j) { j["bodies"][0]["transform"]["scale"] = 0; },
                      {"transform.scale: must be in [1e-6, 1e6]"});
}

TEST_CASE("floors: restitution and friction and the plane refused out of range or not finite") {
  // restitution > 1 and friction < 0 are checked above (and friction > 100 in test_robustness)
  check_edit_rejected([](json& j) { j["obstacles"][0]["restitution"] = -0.1; },
                      {"obstacles[0].restitution: must be in [0, 1]", "-0.1"});
  check_edit_rejected([](json& j) { j["obstacles"][0]["restitution"] = std::nan(""); },
                      {"obstacles[0].restitution: expected a finite number"});
  check_edit_rejected([](json& j) { j["obstacles"][0]["friction"] = std::nan(""); },
                      {"obstacles[0].friction: expected a finite number"});
  check_edit_rejected([](json& j) { j["obstacles"][0]["normal"][2] = std::nan(""); },
                      {"obstacles[0].normal", "expected a finite number"});
  check_edit_rejected([](json& j) { j["obstacles"][0]["point"][2] = std::nan(""); },
                      {"obstacles[0].point", "expected a finite number"});
  check_edit_rejected([](json& j) { j["obstacles"][0]["restitution"] = "bouncy"; },
                      {"obstacles[0].restitution: expected a number"});
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
                    {"bodies[0].mesh.cell_size: must be in [1e-9, 1e6]"});
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
  // A bad token after deep, indented nesting (found by the fuzz test): the parser's "last
  // read" excerpt is kept short, its white space folded, so that the error stays one line.
  std::string deep = "{ \"gravity\": ";
  for (int k = 0; k < 40; ++k) deep.append("[\n").append(2 * static_cast<std::size_t>(k), ' ');
  deep.append("[]");
  for (int k = 39; k >= 0; --k)
    deep.append("\n").append(2 * static_cast<std::size_t>(k), ' ').append("]");
  deep.append("A }");
  const fs::path n = dir.write("deep.json", deep);
  try {
    load_scene(n);
    FAIL("no error");
  } catch (const InputError& e) {
    const std::string what = e.what();
    CHECK(what.find("deep.json: line 81, column") != std::string::npos);
    CHECK(what.find("invalid JSON") != std::string::npos);
    CHECK(what.find("last read: '...") != std::string::npos);
    CHECK(what.find("] ]A'") != std::string::npos);
    CHECK(what.size() < 300);
    CHECK(what.find('\n') == std::string::npos);
  }
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
                       {"fluid.mesh.surface_size: must be in [1e-9, 1e6] (m), got 0"});
  check_fluid_rejected([](json& j) { j["fluid"]["mesh"]["far_size"] = -0.2; },
                       {"fluid.mesh.far_size: must be in [1e-9, 1e6] (m)"});
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

namespace {

/// fluid_json() with every physics key given (and an open patch for "pressure").
json fluid_physics_json() {
  json j = fluid_json();
  auto& patches = j["fluid"]["domain"]["patches"];
  patches[0]["speed"] = 2.0;
  patches[0]["smoke"] = 0.5;
  patches[0]["temperature"] = 330.0;
  patches.push_back(json::parse(R"({ "name": "outlet", "kind": "open", "side": "+x",
                                     "lo": [-0.5, 0], "hi": [1, 2], "pressure": 5 })"));
  j["fluid"].update(json::parse(R"({
    "density": 1000,
    "gravity": true,
    "buoyancy": { "alpha": 0.08, "beta": 0.12, "ambient_temperature": 293 },
    "vorticity_confinement": 0.3,
    "decay": { "smoke": 0.05, "temperature": 0.1 },
    "reconstruction": "whitney",
    "min_dual_fraction": 0.1,
    "solver": { "linear": "cg_ic", "rel_tol": 1e-8, "max_iterations": 200 },
    "sources": [ { "name": "candle", "box": { "lo": [0, 0, 0.1], "hi": [0.2, 0.2, 0.3] },
                   "smoke": 2.0, "temperature": 350 },
                 { "box": { "lo": [1, 0, 1], "hi": [2, 2, 3] } } ],
    "refine": { "size": 0.1, "density_threshold": 0.02, "vorticity_threshold": 4 }
  })"));
  return j;
}

void check_physics_rejected(const std::function<void(json&)>& edit,
                            std::initializer_list<std::string> parts) {
  json j = fluid_physics_json();
  edit(j);
  check_input_error([&] { parse_scene(j, "scene.json"); }, parts);
}

}  // namespace

TEST_CASE("the fluid physics keys parse into fluid::FluidParams and resolve back") {
  const Scene s = parse_scene(fluid_physics_json(), "scene.json");
  REQUIRE(s.fluid);
  const fluid::FluidParams& p = s.fluid->params;
  // One PatchConditions per domain patch, in order.
  REQUIRE(p.patches.size() == 3);
  REQUIRE(s.fluid->domain.patches.size() == 3);
  CHECK(p.patches[0].inflow_speed == 2.0);
  CHECK(p.patches[0].smoke_density == 0.5);
  CHECK(p.patches[0].temperature == 330.0);
  CHECK(p.patches[0].emits_temperature);
  CHECK(p.patches[1].inflow_speed == 0.0);  // the wall
  CHECK_FALSE(p.patches[1].emits_temperature);
  CHECK(s.fluid->domain.patches[2].kind == mesh::FaceKind::Open);
  CHECK(p.patches[2].pressure == 5.0);
  CHECK(p.density == 1000.0);
  CHECK(s.fluid->gravity);
  CHECK(p.gravity == s.gravity);
  CHECK(p.up == Vec3(0, 0, 1));
  CHECK(p.buoyancy_alpha == 0.08);
  CHECK(p.buoyancy_beta == 0.12);
  CHECK(p.ambient_temperature == 293.0);
  CHECK(p.vorticity_confinement == 0.3);
  CHECK(p.smoke_decay == 0.05);
  CHECK(p.temperature_decay == 0.1);
  CHECK(p.reconstruction == fluid::Reconstruction::Whitney);
  CHECK(p.min_dual_fraction == 0.1);
  CHECK(p.solver == SolverKind::CgIc);
  CHECK(p.solver_rel_tol == 1e-8);
  CHECK(p.solver_max_iterations == 200);
  REQUIRE(p.sources.size() == 2);
  CHECK(p.sources[0].name == "candle");
  CHECK(p.sources[0].lo == Vec3(0, 0, 0.1));
  CHECK(p.sources[0].hi == Vec3(0.2, 0.2, 0.3));
  CHECK(p.sources[0].smoke_density == 2.0);
  CHECK(p.sources[0].temperature == 350.0);
  CHECK(p.sources[0].emits_temperature);
  CHECK(p.sources[1].name == "source1");  // default name: its index
  CHECK(p.sources[1].smoke_density == fluid::SmokeSource{}.smoke_density);
  CHECK_FALSE(p.sources[1].emits_temperature);
  CHECK(p.refine.size == 0.1);
  CHECK(p.refine.density_threshold == 0.02);
  CHECK(p.refine.vorticity_threshold == 4.0);
  CHECK_FALSE(s.fluid->sizing.refine);  // still never set from a scene

  // "up" is against gravity, whether or not the fluid feels it; +z without gravity.
  json j = fluid_physics_json();
  j["gravity"] = {0, -2, 0};
  j["fluid"]["gravity"] = false;
  const Scene sideways = parse_scene(j, "scene.json");
  CHECK(sideways.fluid->params.up == Vec3(0, 1, 0));
  CHECK(sideways.fluid->params.gravity == Vec3::Zero());
  CHECK_FALSE(sideways.fluid->gravity);
  j["gravity"] = {0, 0, 0};
  CHECK(parse_scene(j, "scene.json").fluid->params.up == Vec3(0, 0, 1));

  // Every solver name but the grid's structured multigrid is accepted for the tet mesh's
  // pressure solve; pfmg there is a one-line error naming the key.
  for (const std::string& name : solver_names()) {
    CAPTURE(name);
    json k = fluid_physics_json();
    k["fluid"]["solver"]["linear"] = name;
    if (name == "pfmg") {
      CHECK_THROWS_WITH_AS(parse_scene(k, "scene.json"), doctest::Contains("fluid.solver.linear"),
                           InputError);
      continue;
    }
    CHECK(to_string(parse_scene(k, "scene.json").fluid->params.solver) == name);
  }

  // The resolved scene holds every key and parses back to the same.
  const json& r = s.resolved["fluid"];
  CHECK(r["domain"]["patches"][0]["speed"] == 2.0);
  CHECK(r["domain"]["patches"][0]["smoke"] == 0.5);
  CHECK(r["domain"]["patches"][0]["temperature"] == 330.0);
  CHECK_FALSE(r["domain"]["patches"][1].contains("speed"));  // a wall has no conditions
  CHECK_FALSE(r["domain"]["patches"][1].contains("pressure"));
  CHECK(r["domain"]["patches"][2]["pressure"] == 5.0);
  CHECK_FALSE(r["domain"]["patches"][2].contains("speed"));
  CHECK(r["density"] == 1000.0);
  CHECK(r["gravity"] == true);
  CHECK(r["buoyancy"] == json({{"alpha", 0.08}, {"beta", 0.12}, {"ambient_temperature", 293.0}}));
  CHECK(r["vorticity_confinement"] == 0.3);
  CHECK(r["decay"] == json({{"smoke", 0.05}, {"temperature", 0.1}}));
  CHECK(r["reconstruction"] == "whitney");
  CHECK(r["min_dual_fraction"] == 0.1);
  CHECK(r["solver"] == json({{"linear", "cg_ic"}, {"rel_tol", 1e-8}, {"max_iterations", 200}}));
  REQUIRE(r["sources"].size() == 2);
  CHECK(r["sources"][0]["name"] == "candle");
  CHECK(r["sources"][0]["box"]["hi"] == json::array({0.2, 0.2, 0.3}));
  CHECK(r["sources"][0]["temperature"] == 350.0);
  CHECK(r["sources"][1]["name"] == "source1");
  CHECK(r["sources"][1]["smoke"] == 1.0);
  CHECK_FALSE(r["sources"][1].contains("temperature"));
  CHECK(r["refine"] ==
        json({{"size", 0.1}, {"density_threshold", 0.02}, {"vorticity_threshold", 4.0}}));
  const Scene b = parse_scene(json::parse(s.resolved.dump(2)), "back.json");
  CHECK(b.resolved == s.resolved);
  REQUIRE(b.fluid);
  CHECK(b.fluid->params.patches[0].emits_temperature);
  CHECK(b.fluid->params.sources[1].name == "source1");
  CHECK(b.fluid->params.solver == SolverKind::CgIc);
}

TEST_CASE("the fluid physics keys default to the FluidParams defaults") {
  // fluid_json(): an inflow, a wall patch and no physics key.
  const Scene s = parse_scene(fluid_json(), "scene.json");
  REQUIRE(s.fluid);
  const fluid::FluidParams& p = s.fluid->params;
  const fluid::FluidParams d;
  const fluid::PatchConditions pc;
  REQUIRE(p.patches.size() == 2);
  for (const fluid::PatchConditions& c : p.patches) {
    CHECK(c.inflow_speed == pc.inflow_speed);
    CHECK(c.smoke_density == pc.smoke_density);
    CHECK(c.pressure == pc.pressure);
    CHECK_FALSE(c.emits_temperature);
  }
  CHECK(p.density == d.density);
  CHECK_FALSE(s.fluid->gravity);
  CHECK(p.gravity == Vec3::Zero());
  CHECK(p.up == Vec3(0, 0, 1));
  CHECK(p.buoyancy_alpha == d.buoyancy_alpha);
  CHECK(p.buoyancy_beta == d.buoyancy_beta);
  CHECK(p.ambient_temperature == d.ambient_temperature);
  CHECK(p.vorticity_confinement == d.vorticity_confinement);
  CHECK(p.smoke_decay == d.smoke_decay);
  CHECK(p.temperature_decay == d.temperature_decay);
  CHECK(p.reconstruction == fluid::Reconstruction::Whitney);
  CHECK(p.min_dual_fraction == d.min_dual_fraction);
  CHECK(p.solver == SolverKind::Amg);
  CHECK(p.solver_rel_tol == d.solver_rel_tol);
  CHECK(p.solver_max_iterations == d.solver_max_iterations);
  CHECK(p.sources.empty());
  CHECK(p.refine.size == 0.0);
  CHECK(p.refine.density_threshold == d.refine.density_threshold);
  CHECK(p.refine.vorticity_threshold == d.refine.vorticity_threshold);

  const json& r = s.resolved["fluid"];
  CHECK(r["domain"]["patches"][0]["speed"] == 0.0);
  CHECK(r["domain"]["patches"][0]["smoke"] == 0.0);
  CHECK_FALSE(r["domain"]["patches"][0].contains("temperature"));  // ambient
  CHECK(r["density"] == 1.2);
  CHECK(r["gravity"] == false);
  CHECK(r["buoyancy"] == json({{"alpha", 0.0}, {"beta", 0.0}, {"ambient_temperature", 0.0}}));
  CHECK(r["vorticity_confinement"] == 0.0);
  CHECK(r["decay"] == json({{"smoke", 0.0}, {"temperature", 0.0}}));
  CHECK(r["reconstruction"] == "whitney");
  CHECK(r["min_dual_fraction"] == 1e-6);
  CHECK(r["solver"] == json({{"linear", "amg"}, {"rel_tol", 1e-8}, {"max_iterations", 500}}));
  CHECK(r["sources"] == json::array());
  CHECK(r["refine"] ==
        json({{"size", 0.0}, {"density_threshold", 0.01}, {"vorticity_threshold", 0.0}}));
  CHECK(parse_scene(s.resolved, "back.json").resolved == s.resolved);
}

TEST_CASE("fluid physics errors are one line naming the JSON path") {
  // Patch conditions.
  check_physics_rejected([](json& j) { j["fluid"]["domain"]["patches"][0]["speed"] = -1; },
                         {"scene.json: fluid.domain.patches[0].speed: must be in [0, 1e5] (m/s "
                          "into the domain), got -1"});
  check_physics_rejected(
      [](json& j) { j["fluid"]["domain"]["patches"][2]["speed"] = 1; },
      {"scene.json: fluid.domain.patches[2].speed: applies only to an inflow patch (this one is "
       "open)"});
  check_physics_rejected([](json& j) { j["fluid"]["domain"]["patches"][1]["smoke"] = 1; },
                         {"fluid.domain.patches[1].smoke: applies only to an inflow patch (this "
                          "one is wall)"});
  check_physics_rejected([](json& j) { j["fluid"]["domain"]["patches"][2]["temperature"] = 300; },
                         {"fluid.domain.patches[2].temperature: applies only to an inflow patch"});
  check_physics_rejected([](json& j) { j["fluid"]["domain"]["patches"][0]["pressure"] = 0; },
                         {"fluid.domain.patches[0].pressure: applies only to an open patch (this "
                          "one is inflow)"});
  check_physics_rejected([](json& j) { j["fluid"]["domain"]["patches"][0]["smoke"] = -0.1; },
                         {"fluid.domain.patches[0].smoke: must be in [0, 1e5]"});
  check_physics_rejected([](json& j) { j["fluid"]["domain"]["patches"][0]["temperature"] = "hot"; },
                         {"fluid.domain.patches[0].temperature: expected a number, got string"});
  check_physics_rejected([](json& j) { j["fluid"]["domain"]["patches"][0]["sped"] = 1; },
                         {"fluid.domain.patches[0].sped: unknown key (did you mean 'speed'?)"});
  // Physics.
  check_physics_rejected([](json& j) { j["fluid"]["density"] = 0; },
                         {"scene.json: fluid.density: must be in [1e-10, 1e5] (kg/m^3), got 0"});
  check_physics_rejected([](json& j) { j["fluid"]["gravity"] = "yes"; },
                         {"fluid.gravity: expected true", "got string \"yes\""});
  check_physics_rejected(
      [](json& j) {
        j["fluid"]["gravity"] = json::array({0, 0, -9.81});
      },
      {"fluid.gravity: expected true", "got array"});
  check_physics_rejected([](json& j) { j["fluid"]["buoyancy"]["alpa"] = 0.1; },
                         {"scene.json: fluid.buoyancy.alpa: unknown key (did you mean 'alpha'?)"});
  check_physics_rejected([](json& j) { j["fluid"]["buoyancy"]["alpha"] = -0.1; },
                         {"fluid.buoyancy.alpha: must be in [0, 1e6]"});
  check_physics_rejected([](json& j) { j["fluid"]["buoyancy"]["beta"] = -1; },
                         {"fluid.buoyancy.beta: must be in [0, 1e6]"});
  check_physics_rejected([](json& j) { j["fluid"]["buoyancy"] = 1; },
                         {"fluid.buoyancy: expected an object, got number 1"});
  check_physics_rejected([](json& j) { j["fluid"]["vorticity_confinement"] = -0.5; },
                         {"fluid.vorticity_confinement: must be in [0, 1000], got -0.5"});
  check_physics_rejected([](json& j) { j["fluid"]["decay"]["smoke"] = -1; },
                         {"fluid.decay.smoke: must be in [0, 1e6] (1/s)"});
  check_physics_rejected([](json& j) { j["fluid"]["decay"]["temprature"] = 1; },
                         {"fluid.decay.temprature: unknown key (did you mean 'temperature'?)"});
  check_physics_rejected(
      [](json& j) { j["fluid"]["reconstruction"] = "whitny"; },
      {"scene.json: fluid.reconstruction: unknown velocity reconstruction 'whitny' (did you mean "
       "'whitney'?)"});
  check_physics_rejected(
      [](json& j) { j["fluid"]["reconstruction"] = "spline"; },
      {"fluid.reconstruction: unknown velocity reconstruction 'spline'", "vertex_ls", "whitney"});
  for (double bad : {0.0, 0.2, 1.0, -0.1, 2.0}) {
    CAPTURE(bad);
    check_physics_rejected([&](json& j) { j["fluid"]["min_dual_fraction"] = bad; },
                           {"fluid.min_dual_fraction: must be in (0, 0.1]"});
  }
  check_physics_rejected([](json& j) { j["fluid"]["solver"]["linear"] = "amgg"; },
                         {"fluid.solver.linear: unknown linear solver 'amgg' (did you mean"});
  check_physics_rejected([](json& j) { j["fluid"]["solver"]["rel_tol"] = 0; },
                         {"fluid.solver.rel_tol: must be > 0"});
  check_physics_rejected([](json& j) { j["fluid"]["solver"]["max_iterations"] = 0; },
                         {"fluid.solver.max_iterations: must be >= 1"});
  check_physics_rejected([](json& j) { j["fluid"]["vorticity_confinment"] = 1; },
                         {"fluid.vorticity_confinment: unknown key (did you mean "
                          "'vorticity_confinement'?)"});
  check_physics_rejected([](json& j) { j["fluid"]["viscosity"] = 1; },
                         {"fluid.viscosity: unknown key (valid keys here:", "buoyancy"});
  // Sources.
  check_physics_rejected([](json& j) { j["fluid"]["sources"] = json::object(); },
                         {"fluid.sources: expected an array"});
  check_physics_rejected([](json& j) { j["fluid"]["sources"][0].erase("box"); },
                         {"fluid.sources[0]: missing required key 'box'"});
  check_physics_rejected([](json& j) { j["fluid"]["sources"][0]["box"]["hi"][2] = 0.1; },
                         {"fluid.sources[0].box: lo must be < hi", "axis z"});
  check_physics_rejected(
      [](json& j) {
        j["fluid"]["sources"][1]["box"] = {{"lo", {5, 5, 5}}, {"hi", {6, 6, 6}}};
      },
      {"fluid.sources[1].box: the box [5, 5, 5]..[6, 6, 6] misses the fluid box "
       "[-0.5, -0.5, 0]..[1.5, 1, 2]"});
  check_physics_rejected([](json& j) { j["fluid"]["sources"][1]["name"] = "candle"; },
                         {"fluid.sources[1].name: duplicate source name 'candle' (also "
                          "fluid.sources[0])"});
  check_physics_rejected([](json& j) { j["fluid"]["sources"][0]["smoke"] = -1; },
                         {"fluid.sources[0].smoke: must be in [0, 1e5]"});
  check_physics_rejected([](json& j) { j["fluid"]["sources"][0]["density"] = 1; },
                         {"fluid.sources[0].density: unknown key"});
  // Refinement.
  check_physics_rejected(
      [](json& j) { j["fluid"]["refine"]["size"] = 0.5; },
      {"scene.json: fluid.refine.size: must be <= fluid.mesh.far_size (0.3 m), got 0.5 m"});
  check_physics_rejected([](json& j) { j["fluid"]["refine"]["size"] = -0.1; },
                         {"fluid.refine.size: must be in [0, 1e6]"});
  check_physics_rejected([](json& j) { j["fluid"]["refine"]["density_threshold"] = -1; },
                         {"fluid.refine.density_threshold: must be in [0, 1e5]"});
  check_physics_rejected([](json& j) { j["fluid"]["refine"]["sise"] = 0.1; },
                         {"fluid.refine.sise: unknown key (did you mean 'size'?)"});
  // refine.size is checked against the far_size the scene gives, default included.
  json j = fluid_physics_json();
  j["fluid"].erase("mesh");
  j["fluid"]["refine"]["size"] = mesh::Sizing{}.far_size;
  CHECK(parse_scene(j, "scene.json").fluid->params.refine.size == mesh::Sizing{}.far_size);
}

TEST_CASE("a scene with a fluid may have no body - without one it needs a body") {
  json j = fluid_physics_json();
  j["bodies"] = json::array();
  const Scene empty = parse_scene(j, "scene.json");
  CHECK(empty.bodies.empty());
  CHECK(empty.resolved["bodies"] == json::array());
  CHECK(parse_scene(empty.resolved, "back.json").resolved == empty.resolved);
  CHECK(build_world(empty).bodies.empty());
  j.erase("bodies");
  CHECK(parse_scene(j, "scene.json").bodies.empty());
  CHECK(parse_scene(j, "scene.json").resolved == empty.resolved);

  check_edit_rejected([](json& j) { j["bodies"] = json::array(); },
                      {"scene.json: bodies: a scene needs at least one body (or a 'fluid' "
                       "section)"});
  check_edit_rejected([](json& j) { j.erase("bodies"); },
                      {"scene.json: (top level): missing required key 'bodies'"});
  // With a fluid, "bodies" must still be an array when given.
  j["bodies"] = 3;
  check_input_error([&] { parse_scene(j, "scene.json"); },
                    {"scene.json: bodies: expected an array of bodies, got number 3"});
}

TEST_CASE("kinematic bodies: keys, defaults, resolved scene, errors and build_world") {
  json j = sheet_json();
  auto& body = j["bodies"][0];
  body["pins"] = json::array();
  body["loads"] = json::array();
  body.erase("initial_velocity");
  body["kinematic"] = {{"velocity", {0.1, 0, 0}}, {"angular_velocity_deg", {0, 0, 90}}};
  const Scene s = parse_scene(j, "scene.json");
  REQUIRE(s.bodies[0].kinematic);
  CHECK(s.bodies[0].kinematic->velocity == Vec3(0.1, 0, 0));
  CHECK(s.bodies[0].kinematic->angular_velocity_deg == Vec3(0, 0, 90));
  CHECK_FALSE(s.bodies[0].kinematic->center);
  const json& r = s.resolved["bodies"][0]["kinematic"];
  CHECK(r["velocity"] == json::array({0.1, 0.0, 0.0}));
  CHECK(r["angular_velocity_deg"] == json::array({0.0, 0.0, 90.0}));
  CHECK_FALSE(r.contains("center"));  // the rest centroid, known once the mesh is built
  CHECK(parse_scene(s.resolved, "back.json").resolved == s.resolved);
  CHECK_FALSE(parse_scene(sheet_json(), "scene.json").bodies[0].kinematic);
  CHECK_FALSE(parse_scene(sheet_json(), "scene.json").resolved["bodies"][0].contains("kinematic"));

  // build_world: degrees become rad/s, the centre defaults to the mean of the rest nodes, and
  // the state at t = 0 is on the path (d = 0, u = v + ω × (X − c)).
  const solid::SolidWorld w = build_world(s);
  const solid::SolidBody& b = w.bodies[0];
  REQUIRE(b.is_kinematic());
  CHECK(b.num_fixed_dofs() == 0);
  CHECK(b.kinematic->linear_velocity == Vec3(0.1, 0, 0));
  CHECK((b.kinematic->angular_velocity - Vec3(0, 0, M_PI / 2)).norm() < 1e-15);
  const Vec3 centroid = b.rest_positions().colwise().mean().transpose();
  CHECK((b.kinematic->center - centroid).norm() < 1e-15);
  CHECK((centroid - Vec3(0.5, 0.25, 1.01)).norm() < 1e-12);
  CHECK(b.displacement.isZero(0.0));
  CHECK((b.velocity - b.kinematic->velocity(b.rest_positions(), 0.0)).norm() == 0.0);
  // An explicit centre; every key is optional.
  j["bodies"][0]["kinematic"] = {{"center", {1, 2, 3}}};
  const solid::SolidWorld w2 = build_world(parse_scene(j, "scene.json"));
  CHECK(w2.bodies[0].kinematic->center == Vec3(1, 2, 3));
  CHECK(w2.bodies[0].kinematic->linear_velocity == Vec3::Zero());
  CHECK(w2.bodies[0].velocity.isZero(0.0));
  CHECK(parse_scene(j, "scene.json").resolved["bodies"][0]["kinematic"]["center"] ==
        json::array({1.0, 2.0, 3.0}));

  // Errors: pins, loads or an initial velocity on a kinematic body; unknown keys; types.
  const json kin = {{"velocity", {0, 0, 1}}};
  check_edit_rejected([&](json& e) { e["bodies"][0]["kinematic"] = kin; },
                      {"scene.json: bodies[0].pins: body 'sheet' is kinematic (moved by its "
                       "'kinematic' motion): it cannot have pins"});
  check_edit_rejected(
      [&](json& e) {
        e["bodies"][0]["kinematic"] = kin;
        e["bodies"][0]["pins"] = json::array();
      },
      {"scene.json: bodies[0].loads: body 'sheet' is kinematic", "cannot have loads"});
  check_edit_rejected(
      [&](json& e) {
        e["bodies"][0]["kinematic"] = kin;
        e["bodies"][0]["pins"] = json::array();
        e["bodies"][0]["loads"] = json::array();
      },
      {"scene.json: bodies[0].initial_velocity: body 'sheet' is kinematic",
       "give kinematic.velocity"});
  check_input_error(
      [&] {
        json e = j;
        e["bodies"][0]["kinematic"] = {{"angular_velocity", {0, 0, 1}}};
        parse_scene(e, "scene.json");
      },
      {"scene.json: bodies[0].kinematic.angular_velocity: unknown key (did you mean "
       "'angular_velocity_deg'?)"});
  check_input_error(
      [&] {
        json e = j;
        e["bodies"][0]["kinematic"] = {{"velocity", {0, 1}}};
        parse_scene(e, "scene.json");
      },
      {"bodies[0].kinematic.velocity: expected an array of 3 numbers"});
  check_input_error(
      [&] {
        json e = j;
        e["bodies"][0]["kinematic"] = true;
        parse_scene(e, "scene.json");
      },
      {"bodies[0].kinematic: expected an object, got boolean true"});
  // Its material must still be valid (mass and energies use it).
  check_input_error(
      [&] {
        json e = j;
        e["bodies"][0]["material"]["density"] = -1;
        parse_scene(e, "scene.json");
      },
      {"bodies[0].material.density: must be in [1e-10, 1e5]"});
}

TEST_CASE("coupling: defaults by the bodies and the mode, keys, resolved scene") {
  // A fluid and a deformable body: simultaneous two-way coupling with the solve's defaults.
  const Scene s = parse_scene(fluid_json(), "scene.json");
  REQUIRE(s.coupling);
  const coupling::CoupledOptions defaults;
  CHECK(s.coupling->two_way);
  CHECK(s.coupling->params.scheme == coupling::Scheme::Simultaneous);
  CHECK(s.coupling->params.solve.solver == defaults.solver);
  CHECK(s.coupling->params.solve.rel_tol == defaults.rel_tol);
  CHECK(s.coupling->params.solve.max_iterations == defaults.max_iterations);
  CHECK(s.coupling->params.solve.conserve_volume == defaults.conserve_volume);
  CHECK(s.two_way());
  CHECK(s.fluid->params.enclosed_density == 0.0);
  CHECK(s.resolved["fluid"]["enclosed_density"] == 0.0);
  CHECK(s.resolved["coupling"] == json::parse(R"({ "scheme": "simultaneous",
      "solver": "schur_amg", "rel_tol": 1e-10, "max_iterations": 500,
      "conserve_volume": true, "interface_mass": true, "grid_multigrid": false })"));

  // Only kinematic bodies (or none): one-way; a static scene: one-way too.
  json k = fluid_json();
  k["bodies"][0].erase("pins");
  k["bodies"][0].erase("loads");
  k["bodies"][0].erase("initial_velocity");
  k["bodies"][0]["kinematic"] = {{"velocity", {0, 0, 1}}};
  const Scene ks = parse_scene(k, "scene.json");
  REQUIRE(ks.coupling);
  CHECK_FALSE(ks.coupling->two_way);
  CHECK_FALSE(ks.two_way());
  CHECK(ks.resolved["coupling"]["scheme"] == "none");
  json st = fluid_json();
  st["mode"] = "static";
  CHECK(parse_scene(st, "scene.json").resolved["coupling"]["scheme"] == "none");
  st["coupling"] = {{"scheme", "splitting"}};  // given: kept, the run ignores it (a warning)
  const Scene sts = parse_scene(st, "scene.json");
  CHECK(sts.coupling->two_way);
  CHECK_FALSE(sts.two_way());
  // Without a fluid: no coupling at all.
  CHECK_FALSE(parse_scene(sheet_json(), "scene.json").coupling);
  CHECK_FALSE(parse_scene(sheet_json(), "scene.json").resolved.contains("coupling"));

  // Every key given, resolved back and parsed again to the same.
  json j = fluid_json();
  j["fluid"]["density"] = 1.2;
  j["fluid"]["enclosed_density"] = 1000;
  j["coupling"] = json::parse(R"({ "scheme": "splitting", "solver": "bicgstab_ilut",
      "rel_tol": 1e-9, "max_iterations": 80, "conserve_volume": false,
      "interface_mass": false, "grid_multigrid": true })");
  const Scene c = parse_scene(j, "scene.json");
  CHECK(c.fluid->params.enclosed_density == 1000.0);
  CHECK(c.coupling->two_way);
  CHECK(c.coupling->params.scheme == coupling::Scheme::Splitting);
  CHECK(c.coupling->params.solve.solver == coupling::CoupledSolverKind::BiCgStabIlut);
  CHECK(c.coupling->params.solve.rel_tol == 1e-9);
  CHECK(c.coupling->params.solve.max_iterations == 80);
  CHECK_FALSE(c.coupling->params.solve.conserve_volume);
  CHECK_FALSE(c.coupling->params.solve.interface_mass);
  CHECK(c.coupling->params.solve.grid_multigrid);
  CHECK(c.resolved["coupling"] == j["coupling"]);
  CHECK(c.resolved["fluid"]["enclosed_density"] == 1000.0);
  const Scene back = parse_scene(c.resolved, "scene.json");
  CHECK(back.resolved == c.resolved);
  for (const std::string& name : coupling::k_coupled_solver_names.names()) {
    j["coupling"]["solver"] = name;
    CHECK(coupling::to_string(parse_scene(j, "scene.json").coupling->params.solve.solver) == name);
  }
  // "none" with a deformable body: one-way, the other keys still checked and kept.
  j["coupling"]["scheme"] = "none";
  const Scene none = parse_scene(j, "scene.json");
  CHECK_FALSE(none.two_way());
  CHECK(none.resolved["coupling"]["scheme"] == "none");
  CHECK(none.resolved["coupling"]["max_iterations"] == 80);
}

TEST_CASE("coupling and enclosed_density errors name the JSON path and the problem") {
  check_fluid_rejected(
      [](json& j) {
        j["coupling"] = {{"scheme", "simultanous"}};
      },
      {"scene.json: coupling.scheme: unknown coupling scheme 'simultanous' "
       "(did you mean 'simultaneous'?)"});
  check_fluid_rejected(
      [](json& j) {
        j["coupling"] = {{"scheme", "monolithic"}};
      },
      {"coupling.scheme: unknown coupling scheme 'monolithic'", "simultaneous", "splitting",
       "none"});
  check_fluid_rejected(
      [](json& j) {
        j["coupling"] = {{"solver", "cg"}};
      },
      {"scene.json: coupling.solver: unknown coupled solver 'cg'", "schur_amg", "umfpack",
       "bicgstab_ilut", "symmetric_umfpack"});
  check_fluid_rejected(
      [](json& j) {
        j["coupling"] = {{"solver", "umfpak"}};
      },
      {"coupling.solver: unknown coupled solver 'umfpak' (did you mean "
       "'umfpack'?)"});
  check_fluid_rejected(
      [](json& j) {
        j["coupling"] = {{"rel_tol", 0}};
      },
      {"scene.json: coupling.rel_tol: must be > 0, got 0"});
  check_fluid_rejected(
      [](json& j) {
        j["coupling"] = {{"max_iterations", 0}};
      },
      {"scene.json: coupling.max_iterations: must be >= 1, got 0"});
  check_fluid_rejected(
      [](json& j) {
        j["coupling"] = {{"max_iterations", 2.5}};
      },
      {"coupling.max_iterations: expected an integer, got number 2.5"});
  check_fluid_rejected(
      [](json& j) {
        j["coupling"] = {{"conserve_volume", 1}};
      },
      {"scene.json: coupling.conserve_volume: expected true", "got number 1"});
  check_fluid_rejected(
      [](json& j) {
        j["coupling"] = {{"shceme", "splitting"}};
      },
      {"scene.json: coupling.shceme: unknown key (did you mean 'scheme'?)"});
  check_fluid_rejected([](json& j) { j["coupling"] = "simultaneous"; },
                       {"scene.json: coupling: expected an object, got string"});
  check_fluid_rejected(
      [](json& j) { j["fluid"]["enclosed_density"] = -1; },
      {"scene.json: fluid.enclosed_density: must be in [0, 1e5] (kg/m^3; 0: the same "
       "as density), got -1"});
  check_fluid_rejected([](json& j) { j["fluid"]["enclosed_density"] = "water"; },
                       {"fluid.enclosed_density: expected a number, got string \"water\""});
  check_fluid_rejected([](json& j) { j["fluid"]["enclosed_densty"] = 1000; },
                       {"fluid.enclosed_densty: unknown key (did you mean 'enclosed_density'?)"});
  // Without a fluid there is nothing to couple to.
  check_edit_rejected(
      [](json& j) {
        j["coupling"] = {{"scheme", "simultaneous"}};
      },
      {"scene.json: coupling: a scene without a 'fluid' section has nothing to "
       "couple the bodies to"});
}

TEST_CASE("solid: integrator and equilibrium keys, defaults, build_world, resolved scene") {
  // Defaults: the Newton-iterated trapezoid in a solid-only dynamic scene (chosen by
  // `tetfsi bench integrators`), core/equilibrium.hpp's options.
  const Scene d = parse_scene(minimal_json(), "scene.json");
  const EquilibriumOptions defaults;
  CHECK(d.solid.integrator == solid::Integrator::Newton);
  CHECK(d.solid.equilibrium.rtol == 1e-3);
  CHECK(d.solid.equilibrium.etol == 1e-5);
  CHECK(d.solid.equilibrium.stol == 0.5);
  CHECK(d.solid.equilibrium.max_iterations == 30);
  CHECK(d.solid.equilibrium.max_updates == 20);
  CHECK(d.solid.equilibrium.line_search);
  CHECK_FALSE(d.solid.equilibrium.keep_matrix);
  CHECK(d.resolved["solid"] == json::parse(R"({ "integrator": "newton",
      "rtol": 1e-3, "etol": 1e-5, "stol": 0.5, "max_iterations": 30, "max_updates": 20,
      "line_search": true, "reform": "step", "starting_matrix": "bodies",
      "tangent": "exact" })"));
  const solid::SolidWorld dw = build_world(d);
  CHECK(dw.integrator == solid::Integrator::Newton);
  // A given solid.trapezoid asks for the linearized rule; so does a static scene (unused).
  json tz = minimal_json();
  tz["solid"] = {{"trapezoid", "midpoint"}};
  const Scene t = parse_scene(tz, "scene.json");
  CHECK(t.solid.integrator == solid::Integrator::Linearized);
  CHECK(t.resolved["solid"]["integrator"] == "linearized");
  CHECK(t.resolved["solid"]["trapezoid"] == "midpoint");
  json st = minimal_json();
  st["mode"] = "static";
  CHECK(parse_scene(st, "scene.json").solid.integrator == solid::Integrator::Linearized);
  CHECK(dw.equilibrium.rtol == defaults.rtol);
  CHECK(dw.equilibrium.max_iterations == defaults.max_iterations);
  CHECK(dw.equilibrium.max_line_search == defaults.max_line_search);  // not a scene key

  // Every key given: into the world, resolved back (without trapezoid) and parsed again.
  json j = minimal_json();
  j["solid"] = json::parse(R"({ "integrator": "bfgs", "rtol": 1e-4, "etol": 1e-6,
      "stol": 0.25, "max_iterations": 12, "max_updates": 7, "line_search": false,
      "reform": "run",
      "starting_matrix": "bodies", "tangent": "definite" })");
  const Scene s = parse_scene(j, "scene.json");
  CHECK(s.solid.integrator == solid::Integrator::Bfgs);
  CHECK(s.resolved["solid"] == j["solid"]);
  CHECK_FALSE(s.resolved["solid"].contains("trapezoid"));
  const solid::SolidWorld w = build_world(s);
  CHECK(w.integrator == solid::Integrator::Bfgs);
  for (const solid::SolidBody& b : w.bodies)
    CHECK(b.elasticity().tangent() == solid::Tangent::Definite);
  CHECK(w.equilibrium.rtol == 1e-4);
  CHECK(w.equilibrium.etol == 1e-6);
  CHECK(w.equilibrium.stol == 0.25);
  CHECK(w.equilibrium.max_iterations == 12);
  CHECK(w.equilibrium.max_updates == 7);
  CHECK_FALSE(w.equilibrium.line_search);
  CHECK(w.equilibrium.keep_matrix);
  const Scene back = parse_scene(s.resolved, "scene.json");
  CHECK(back.resolved == s.resolved);
  CHECK(back.solid.equilibrium.keep_matrix);
  CHECK(parse_scene(json::parse(d.resolved.dump(2)), "x.json").resolved == d.resolved);

  for (const char* name : {"linearized", "newton", "modified_newton", "bfgs"}) {
    INFO(name);
    j["solid"]["integrator"] = name;
    const Scene n = parse_scene(j, "scene.json");
    CHECK(solid::to_string(n.solid.integrator) == std::string(name));
    CHECK(build_world(n).integrator == n.solid.integrator);
    CHECK(parse_scene(n.resolved, "scene.json").resolved == n.resolved);
  }
  // The linearized integrator keeps its trapezoid variant.
  json lin = minimal_json();
  lin["solid"] = {{"integrator", "linearized"}, {"trapezoid", "midpoint"}};
  const Scene ls = parse_scene(lin, "scene.json");
  CHECK(ls.resolved["solid"]["trapezoid"] == "midpoint");
  CHECK(build_world(ls).trapezoid == solid::Trapezoid::Midpoint);
}

TEST_CASE("solid: bad integrator and tolerance values are one-line errors naming the key") {
  check_edit_rejected([](json& j) { j["solid"]["integrator"] = "bfg"; },
                      {"scene.json: solid.integrator: unknown solid integrator 'bfg' (did you "
                       "mean 'bfgs'?)"});
  check_edit_rejected([](json& j) { j["solid"]["integrator"] = "implicit_euler"; },
                      {"solid.integrator: unknown solid integrator 'implicit_euler'", "linearized",
                       "modified_newton"});
  for (const char* integrator : {"newton", "modified_newton", "bfgs"}) {
    INFO(integrator);
    check_edit_rejected(
        [&](json& j) {
          j["solid"] = {{"integrator", integrator}, {"trapezoid", "paper"}};
        },
        {"scene.json: solid.trapezoid: applies only to solid.integrator 'linearized'",
         std::string("the '") + integrator + "' integrator",
         "remove it or set solid.integrator to 'linearized'"});
  }
  check_edit_rejected([](json& j) { j["solid"]["rtol"] = 0; },
                      {"scene.json: solid.rtol: must be > 0", "got 0"});
  check_edit_rejected([](json& j) { j["solid"]["rtol"] = -1e-3; },
                      {"solid.rtol: must be > 0", "got -0.001"});
  check_edit_rejected([](json& j) { j["solid"]["rtol"] = NAN; },
                      {"solid.rtol: expected a finite number, got number nan"});
  check_edit_rejected([](json& j) { j["solid"]["etol"] = -1e-5; },
                      {"scene.json: solid.etol: must be > 0", "Eq. (13)"});
  check_edit_rejected([](json& j) { j["solid"]["etol"] = "small"; },
                      {"solid.etol: expected a number, got string \"small\""});
  for (double stol : {0.0, 1.0, 1.5, -0.5}) {
    INFO(stol);
    check_edit_rejected([&](json& j) { j["solid"]["stol"] = stol; },
                        {"scene.json: solid.stol: must be in (0, 1)"});
  }
  check_edit_rejected([](json& j) { j["solid"]["max_iterations"] = 0; },
                      {"scene.json: solid.max_iterations: must be >= 1", "got 0"});
  check_edit_rejected([](json& j) { j["solid"]["max_iterations"] = 2.5; },
                      {"solid.max_iterations: expected an integer, got number 2.5"});
  check_edit_rejected([](json& j) { j["solid"]["max_updates"] = 0; },
                      {"scene.json: solid.max_updates: must be >= 1", "got 0"});
  check_edit_rejected([](json& j) { j["solid"]["line_search"] = 1; },
                      {"scene.json: solid.line_search: expected true", "got number 1"});
  check_edit_rejected([](json& j) { j["solid"]["reform"] = "always"; },
                      {"scene.json: solid.reform: unknown reform 'always'", "step", "run"});
  check_edit_rejected([](json& j) { j["solid"]["rtl"] = 1e-3; },
                      {"scene.json: solid.rtl: unknown key (did you mean 'rtol'?)"});
  check_edit_rejected([](json& j) { j["solid"] = "bfgs"; },
                      {"scene.json: solid: expected an object, got string"});
}

TEST_CASE("coupling: the iterated schemes bfgs, modified_newton, newton are two-way") {
  for (const char* name : {"bfgs", "modified_newton", "newton"}) {
    INFO(name);
    json j = fluid_json();
    j["coupling"] = {{"scheme", name}};
    j["solid"] = {{"rtol", 1e-4}, {"max_iterations", 8}};  // the iteration's tolerances
    const Scene s = parse_scene(j, "scene.json");
    REQUIRE(s.coupling);
    CHECK(s.two_way());
    CHECK(coupling::is_iterated(s.coupling->params.scheme));
    CHECK(s.coupling->scheme_name() == name);
    CHECK(s.resolved["coupling"]["scheme"] == name);
    CHECK(parse_scene(s.resolved, "scene.json").resolved == s.resolved);
    CHECK_FALSE(s.resolved["solid"].contains("trapezoid"));  // the full rule, no variant
    const solid::SolidWorld w = build_world(s);
    CHECK(w.equilibrium.rtol == 1e-4);
    CHECK(w.equilibrium.max_iterations == 8);
  }
  // solid.trapezoid is the linearized rule's variant: an error with an iterated scheme.
  check_fluid_rejected(
      [](json& j) {
        j["coupling"] = {{"scheme", "newton"}};
        j["solid"] = {{"trapezoid", "midpoint"}};
      },
      {"scene.json: solid.trapezoid: applies to the linearized integrator only; "
       "coupling.scheme 'newton' iterates the full trapezoidal rule"});
  // A nonlinear solid.integrator in a two-way scene must name its coupling scheme.
  json same = fluid_json();
  same["coupling"] = {{"scheme", "bfgs"}};
  same["solid"] = {{"integrator", "bfgs"}};
  CHECK(parse_scene(same, "scene.json").two_way());
  check_fluid_rejected(
      [](json& j) {
        j["solid"] = {{"integrator", "bfgs"}};  // simultaneous by default
      },
      {"scene.json: solid.integrator: 'bfgs' is not used in a two-way coupled scene: its bodies "
       "step with coupling.scheme 'simultaneous'; set coupling.scheme to 'bfgs'"});
  check_fluid_rejected(
      [](json& j) {
        j["solid"] = {{"integrator", "newton"}};
        j["coupling"] = {{"scheme", "modified_newton"}};
      },
      {"solid.integrator: 'newton' is not used", "coupling.scheme 'modified_newton'"});
  json one_way = fluid_json();  // one-way: the bodies step alone, by the integrator
  one_way["solid"] = {{"integrator", "bfgs"}};
  one_way["coupling"] = {{"scheme", "none"}};
  CHECK(parse_scene(one_way, "scene.json").solid.integrator == solid::Integrator::Bfgs);
  check_fluid_rejected(
      [](json& j) {
        j["coupling"] = {{"scheme", "bfg"}};
      },
      {"scene.json: coupling.scheme: unknown coupling scheme 'bfg' (did you mean 'bfgs'?)"});
}

TEST_CASE(
    "solid.starting_matrix: added_mass and coupled only for a two-way bfgs or modified_newton "
    "- coupled only with solid.reform step") {
  for (const char* scheme : {"bfgs", "modified_newton"})
    for (const char* start : {"bodies", "added_mass", "coupled"}) {
      INFO(scheme << " " << start);
      json j = fluid_json();
      j["coupling"] = {{"scheme", scheme}};
      j["solid"] = {{"starting_matrix", start}};
      const Scene s = parse_scene(j, "scene.json");
      CHECK(s.resolved["solid"]["starting_matrix"] == start);
      CHECK(parse_scene(s.resolved, "scene.json").resolved == s.resolved);
      CHECK(build_world(s).equilibrium.starting_matrix == k_starting_matrix_names.parse(start));
    }
  check_fluid_rejected(
      [](json& j) {
        j["coupling"] = {{"scheme", "bfgs"}};
        j["solid"] = {{"starting_matrix", "coupled"}, {"reform", "run"}};
      },
      {"scene.json: solid.reform: 'run' keeps the starting matrix from step to step, but "
       "solid.starting_matrix 'coupled' is formed on each step's fluid mesh: set solid.reform "
       "to 'step'"});
  check_fluid_rejected(
      [](json& j) {
        j["coupling"] = {{"scheme", "newton"}};
        j["solid"] = {{"starting_matrix", "added_mass"}};
      },
      {"scene.json: solid.starting_matrix: 'added_mass' adds the fluid to the starting matrix "
       "of coupling.scheme 'bfgs' or 'modified_newton' in a two-way scene; this scene has "
       "coupling.scheme 'newton': remove it"});
  check_edit_rejected(
      [](json& j) {
        j["solid"] = {{"integrator", "bfgs"}, {"starting_matrix", "coupled"}};
      },
      {"scene.json: solid.starting_matrix: 'coupled'", "this scene has no two-way coupling"});
  check_fluid_rejected(
      [](json& j) {
        j["coupling"] = {{"scheme", "bfgs"}};
        j["solid"] = {{"starting_matrix", "exact"}};
      },
      {"scene.json: solid.starting_matrix: unknown starting matrix 'exact' (valid: bodies, "
       "added_mass, coupled)"});
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
  const MatX3 X = build_world(rs).bodies[0].rest_positions();  // a copy: the world is a temporary
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

TEST_CASE("generated meshes: sphere, shell, hollow_box parse, resolve back and build") {
  json j = minimal_json();
  json& bodies = j["bodies"];
  bodies[0]["mesh"] = json::parse(R"({ "sphere": { "center": [0, 0, 0.5], "radius": 0.1 } })");
  bodies.push_back(json::parse(R"({ "name": "balloon", "mesh": { "shell": {
      "center": [1, 0, 0], "inner_radius": 0.08, "outer_radius": 0.1, "subdivisions": 1,
      "layers": 2 } } })"));
  bodies.push_back(json::parse(R"({ "name": "tank", "mesh": { "hollow_box": {
      "lo": [0, 0, 0], "hi": [0.4, 0.3, 0.2], "thickness": 0.05, "cells": [3, 2, 1] } },
      "transform": { "translate": [0, 0, 2] },
      "pins": [ { "box": { "lo": [0, 0, 2], "hi": [0.4, 0.3, 2] } } ] })"));
  const Scene s = parse_scene(j, "scene.json");
  const MeshSpec& ball = s.bodies[0].mesh;
  CHECK(ball.kind == MeshSpec::Kind::Sphere);
  CHECK(ball.center == Vec3(0, 0, 0.5));
  CHECK(ball.radius == 0.1);
  CHECK(ball.subdivisions == 2);  // default
  const MeshSpec& shell = s.bodies[1].mesh;
  CHECK(shell.kind == MeshSpec::Kind::Shell);
  CHECK(shell.inner_radius == 0.08);
  CHECK(shell.outer_radius == 0.1);
  CHECK(shell.subdivisions == 1);
  CHECK(shell.layers == 2);
  const MeshSpec& tank = s.bodies[2].mesh;
  CHECK(tank.kind == MeshSpec::Kind::HollowBox);
  CHECK(tank.box.hi == Vec3(0.4, 0.3, 0.2));
  CHECK(tank.thickness == 0.05);
  CHECK(tank.cells == Vec3i(3, 2, 1));

  // The resolved scene writes every key back, defaults included, and parses to the same.
  const json& r = s.resolved["bodies"];
  CHECK(r[0]["mesh"] == json::parse(R"({ "sphere": { "center": [0.0, 0.0, 0.5], "radius": 0.1,
                                          "subdivisions": 2 } })"));
  CHECK(r[1]["mesh"]["shell"]["layers"] == 2);
  CHECK(r[2]["mesh"]["hollow_box"]["thickness"] == 0.05);
  CHECK(r[2]["mesh"]["hollow_box"]["cells"] == json::array({3, 2, 1}));
  const Scene back = parse_scene(json::parse(s.resolved.dump(2)), "scene.resolved.json");
  CHECK(back.resolved == s.resolved);

  // build_world: masses are ρ × the generators' polyhedral volumes; transform and pins work.
  const solid::SolidWorld w = build_world(s);
  REQUIRE(w.bodies.size() == 3);
  // Inscribed icospheres: the ball's volume is within its 3.4 % deficit at s = 2 (below),
  // the s = 1 shell's within 13 %.
  const double ball_mass = 1000.0 * 4.0 / 3.0 * M_PI * 1e-3;
  CHECK(w.bodies[0].total_mass() < ball_mass);
  CHECK(w.bodies[0].total_mass() > 0.965 * ball_mass);
  const double shell_mass = 1000.0 * 4.0 / 3.0 * M_PI * (1e-3 - 0.512e-3);
  CHECK(w.bodies[1].total_mass() < shell_mass);
  CHECK(w.bodies[1].total_mass() > 0.87 * shell_mass);
  CHECK(w.bodies[1].num_tets() == 2 * 3 * 80);
  // Hollow box: exact volume 0.4·0.3·0.2 − 0.3·0.2·0.1, translated to z ∈ [2, 2.2], its
  // bottom face (the z = 2 grid plane, selected after the transform) pinned.
  const solid::SolidBody& t = w.bodies[2];
  CHECK(t.total_mass() == doctest::Approx(1000.0 * (0.024 - 0.006)).epsilon(1e-12));
  CHECK(t.rest_positions().col(2).minCoeff() == doctest::Approx(2.0));
  CHECK(t.rest_positions().col(2).maxCoeff() == doctest::Approx(2.2));
  // Grid lines: x: 1 wall + 3 + 1 wall cells → 6 lines; y: 1 + 2 + 1 → 5; all on z = 2.
  CHECK(t.num_fixed_dofs() == 3 * 6 * 5);
}

TEST_CASE("generated meshes: a bowl parses, resolves back and builds, bad values name the key") {
  json j = minimal_json();
  j["bodies"][0]["mesh"] = json::parse(R"({ "bowl": { "center": [0.5, 0, 0.2],
      "inner_radius": 0.08, "outer_radius": 0.1, "cells": 8, "layers": 2 } })");
  const Scene s = parse_scene(j, "scene.json");
  const MeshSpec& bowl = s.bodies[0].mesh;
  CHECK(bowl.kind == MeshSpec::Kind::Bowl);
  CHECK(bowl.meridian_cells == 8);
  CHECK(bowl.layers == 2);
  CHECK(s.resolved["bodies"][0]["mesh"] ==
        json::parse(R"({ "bowl": { "center": [0.5, 0.0, 0.2], "inner_radius": 0.08,
                         "outer_radius": 0.1, "cells": 8, "layers": 2 } })"));
  const Scene back = parse_scene(json::parse(s.resolved.dump(2)), "scene.resolved.json");
  CHECK(back.resolved == s.resolved);
  // make_bowl's counts; the rim on z = 0.2, the bottom at 0.2 - outer_radius.
  const solid::SolidWorld w = build_world(s);
  const solid::SolidBody& b = w.bodies[0];
  CHECK(b.num_tets() == 18 * 2 * 8 * 8);
  CHECK(b.rest_positions().col(2).maxCoeff() == doctest::Approx(0.2));
  CHECK(b.rest_positions().col(2).minCoeff() == doctest::Approx(0.1));
  const auto rejected = [](const char* mesh, std::initializer_list<std::string> parts) {
    json jj = minimal_json();
    jj["bodies"][0]["mesh"] = json::parse(mesh);
    check_input_error([&] { parse_scene(jj, "scene.json"); }, parts);
  };
  rejected(R"({ "bowl": { "center": [0, 0, 0], "inner_radius": 0.1, "outer_radius": 0.1 } })",
           {"bodies[0].mesh.bowl.inner_radius", "must be < outer_radius"});
  rejected(R"({ "bowl": { "center": [0, 0, 0], "inner_radius": 0.1, "outer_radius": 0.2,
                "cells": 7 } })",
           {"bodies[0].mesh.bowl.cells", "must be even"});
  rejected(R"({ "bowl": { "center": [0, 0, 0], "inner_radius": 0.1, "outer_radius": 0.2,
                "cells": 1024 } })",
           {"bodies[0].mesh.bowl.cells"});
  rejected(R"({ "bowl": { "center": [0, 0, 0], "inner_radius": 0.1, "outer_radius": 0.2,
                "depth": 1 } })",
           {"bodies[0].mesh.bowl", "depth"});
}

TEST_CASE("generated meshes: a tube parses, resolves back and builds, bad values name the key") {
  json j = minimal_json();
  j["bodies"][0]["mesh"] = json::parse(R"({ "tube": { "center": [0.5, 0, 0.2], "axis": "x",
      "inner_radius": 0.08, "outer_radius": 0.1, "length": 0.8, "cells": [2, 24, 16] } })");
  j["bodies"][0]["pins"] =
      json::parse(R"([ { "box": { "lo": [0.1, -1, -1], "hi": [0.1, 1, 1] } } ])");
  const Scene s = parse_scene(j, "scene.json");
  const MeshSpec& tube = s.bodies[0].mesh;
  CHECK(tube.kind == MeshSpec::Kind::Tube);
  CHECK(tube.center == Vec3(0.5, 0, 0.2));
  CHECK(tube.axis == 0);
  CHECK(tube.inner_radius == 0.08);
  CHECK(tube.outer_radius == 0.1);
  CHECK(tube.length == 0.8);
  CHECK(tube.cells == Vec3i(2, 24, 16));
  const json& r = s.resolved["bodies"][0]["mesh"];
  CHECK(r == json::parse(R"({ "tube": { "center": [0.5, 0.0, 0.2], "axis": "x",
      "inner_radius": 0.08, "outer_radius": 0.1, "length": 0.8, "cells": [2, 24, 16] } })"));
  const Scene back = parse_scene(json::parse(s.resolved.dump(2)), "scene.resolved.json");
  CHECK(back.resolved == s.resolved);

  // build_world: make_tube's counts, mass ρ × the 24-gon annulus × length, along x from
  // 0.1 to 0.9, the x = 0.1 end's ring of (2 + 1) × 24 nodes pinned.
  const solid::SolidWorld w = build_world(s);
  REQUIRE(w.bodies.size() == 1);
  const solid::SolidBody& b = w.bodies[0];
  CHECK(b.num_tets() == 6 * 2 * 24 * 16);
  CHECK(b.rest_positions().rows() == 3 * 24 * 17);
  const double volume = 0.5 * 24 * std::sin(2 * M_PI / 24) * (0.01 - 0.0064) * 0.8;
  CHECK(b.total_mass() == doctest::Approx(1000.0 * volume).epsilon(1e-12));
  CHECK(b.rest_positions().col(0).minCoeff() == doctest::Approx(0.1));
  CHECK(b.rest_positions().col(0).maxCoeff() == doctest::Approx(0.9));
  CHECK(b.num_fixed_dofs() == 3 * 3 * 24);

  // The default axis is z.
  j["bodies"][0]["mesh"]["tube"].erase("axis");
  j["bodies"][0].erase("pins");
  CHECK(parse_scene(j, "scene.json").bodies[0].mesh.axis == 2);

  const auto rejected = [](const char* mesh, std::initializer_list<std::string> parts) {
    json jj = minimal_json();
    jj["bodies"][0]["mesh"] = json::parse(mesh);
    check_input_error([&] { parse_scene(jj, "scene.json"); }, parts);
  };
  rejected(R"({ "tube": { "center": [0, 0, 0], "inner_radius": 0.1, "outer_radius": 0.1,
                "length": 1, "cells": [1, 12, 4] } })",
           {"scene.json: bodies[0].mesh.tube.inner_radius: must be < outer_radius, got "
            "inner_radius 0.1 and outer_radius 0.1"});
  rejected(R"({ "tube": { "center": [0, 0, 0], "inner_radius": 0.2, "outer_radius": 0.1,
                "length": 1, "cells": [1, 12, 4] } })",
           {"bodies[0].mesh.tube.inner_radius: must be < outer_radius"});
  rejected(R"({ "tube": { "center": [0, 0, 0], "axis": "w", "inner_radius": 0.05,
                "outer_radius": 0.1, "length": 1, "cells": [1, 12, 4] } })",
           {"bodies[0].mesh.tube.axis: unknown axis 'w'"});
  rejected(R"({ "tube": { "center": [0, 0, 0], "axis": 2, "inner_radius": 0.05,
                "outer_radius": 0.1, "length": 1, "cells": [1, 12, 4] } })",
           {"bodies[0].mesh.tube.axis: expected a string"});
  rejected(R"({ "tube": { "center": [0, 0, 0], "inner_radius": 0, "outer_radius": 0.1,
                "length": 1, "cells": [1, 12, 4] } })",
           {"bodies[0].mesh.tube.inner_radius: must be in [1e-9, 1e6] (m), got 0"});
  rejected(R"({ "tube": { "center": [0, 0, 0], "inner_radius": 0.05, "outer_radius": 0.1,
                "length": -1, "cells": [1, 12, 4] } })",
           {"bodies[0].mesh.tube.length: must be in [1e-9, 1e6]", "got -1"});
  rejected(R"({ "tube": { "center": [0, 0, 0], "inner_radius": 0.05, "outer_radius": 0.1,
                "length": 1, "cells": [1, 5, 4] } })",
           {"bodies[0].mesh.tube.cells[1]: must be >= 6 (sectors around the axis), got 5"});
  rejected(R"({ "tube": { "center": [0, 0, 0], "inner_radius": 0.05, "outer_radius": 0.1,
                "length": 1, "cells": [0, 12, 4] } })",
           {"bodies[0].mesh.tube.cells[0]: cell counts must be positive integers, got 0"});
  rejected(R"({ "tube": { "center": [0, 0, 0], "inner_radius": 0.05, "outer_radius": 0.1,
                "length": 1 } })",
           {"bodies[0].mesh.tube: missing required key 'cells'"});
  rejected(R"({ "tube": { "center": [0, 0, 0], "inner_radius": 0.05, "outer_radius": 0.1,
                "lenght": 1, "cells": [1, 12, 4] } })",
           {"bodies[0].mesh.tube.lenght: unknown key (did you mean 'length'?)"});
  rejected(R"({ "tube": { "center": [0, 0, 0], "inner_radius": 0.05, "outer_radius": 0.1,
                "length": 1, "cells": [1, 12, 4] }, "sphere": { "center": [0, 0, 0],
                "radius": 1 } })",
           {"bodies[0].mesh: give exactly one of", "got 'sphere' and 'tube'"});
}

TEST_CASE("generated meshes: missing keys, bad values and two kinds are one-line errors") {
  const auto rejected = [](const char* mesh, std::initializer_list<std::string> parts) {
    json j = minimal_json();
    j["bodies"][0]["mesh"] = json::parse(mesh);
    check_input_error([&] { parse_scene(j, "scene.json"); }, parts);
  };
  rejected(R"({ "sphere": { "center": [0, 0, 0] } })",
           {"scene.json: bodies[0].mesh.sphere: missing required key 'radius'"});
  rejected(R"({ "sphere": { "radius": 1 } })",
           {"bodies[0].mesh.sphere: missing required key 'center'"});
  rejected(R"({ "sphere": { "center": [0, 0, 0], "radius": -1 } })",
           {"bodies[0].mesh.sphere.radius: must be in [1e-9, 1e6] (m), got -1"});
  rejected(R"({ "sphere": { "center": [0, 0, 0], "radius": 1, "subdivisions": 9 } })",
           {"bodies[0].mesh.sphere.subdivisions: must be 0..6", "got 9"});
  rejected(R"({ "sphere": { "center": [0, 0, 0], "radius": 1, "subdivision": 2 } })",
           {"bodies[0].mesh.sphere.subdivision: unknown key (did you mean 'subdivisions'?)"});
  rejected(
      R"({ "shell": { "center": [0, 0, 0], "inner_radius": 0.2, "outer_radius": 0.2 } })",
      {"bodies[0].mesh.shell: need inner_radius < outer_radius, got 0.2 and 0.2", "use 'sphere'"});
  rejected(R"({ "shell": { "center": [0, 0, 0], "outer_radius": 0.2 } })",
           {"bodies[0].mesh.shell: missing required key 'inner_radius'"});
  rejected(R"({ "shell": { "center": [0, 0, 0], "inner_radius": 0.1, "outer_radius": 0.2,
                "layers": 0 } })",
           {"bodies[0].mesh.shell.layers: must be 1..10000", "got 0"});
  rejected(R"({ "hollow_box": { "lo": [0, 0, 0], "hi": [1, 1, 0.2], "thickness": 0.1 } })",
           {"bodies[0].mesh.hollow_box.thickness: two walls of 0.1 m leave no cavity in z",
            "use a thinner wall or a larger box"});
  rejected(R"({ "hollow_box": { "lo": [0, 0, 0], "hi": [1, 1, 1] } })",
           {"bodies[0].mesh.hollow_box: missing required key 'thickness'"});
  rejected(R"({ "hollow_box": { "lo": [0, 0, 0], "hi": [1, 1, 1], "thickness": 0.1,
                "cells": [2, 0, 2] } })",
           {"bodies[0].mesh.hollow_box.cells[1]: cell counts must be positive integers, got 0"});
  rejected(R"({ "sphere": { "center": [0, 0, 0], "radius": 1 },
                "box": { "lo": [0, 0, 0], "hi": [1, 1, 1] } })",
           {"scene.json: bodies[0].mesh: give exactly one of 'box', 'file', 'surface', 'sphere', "
            "'shell', 'hollow_box', 'tube' or 'bowl', got 'box' and 'sphere'"});
  rejected(R"({ "sphere": { "center": [0, 0, 0], "radius": 1 }, "cell_size": 0.1 })",
           {"bodies[0].mesh.cell_size: cell_size applies only to a 'surface' mesh"});
  rejected(R"({ "ball": { "center": [0, 0, 0], "radius": 1 } })",
           {"bodies[0].mesh.ball: unknown key"});
}

namespace {

/// fluid_json on the grid with a liquid column.
json liquid_json() {
  json j = fluid_json();
  j["fluid"]["discretization"] = "grid";
  j["fluid"]["grid"] = json::parse(R"({ "cell_size": 0.1 })");
  j["fluid"]["gravity"] = true;
  j["fluid"]["liquid"] = json::parse(R"({
    "flip": 0.9,
    "regions": [ { "name": "column", "box": { "lo": [-0.5, -0.5, 0], "hi": [0, 1, 1] } },
                 { "sphere": { "center": [1, 0.5, 1.5], "radius": 0.2 } } ],
    "sources": [ { "name": "tap", "box": { "lo": [1, 0, 1.8], "hi": [1.2, 0.2, 2] },
                   "velocity": [0, 0, -1], "stop": 0.5 } ]
  })");
  return j;
}

void check_liquid_rejected(const std::function<void(json&)>& edit,
                           std::initializer_list<std::string> parts) {
  json j = liquid_json();
  edit(j);
  check_input_error([&] { parse_scene(j, "scene.json"); }, parts);
}

}  // namespace

TEST_CASE("fluid.liquid parses regions and sources and resolves back") {
  const Scene s = parse_scene(liquid_json(), "scene.json");
  const fluid::LiquidParams& lq = s.fluid->params.liquid;
  CHECK(lq.enabled);
  CHECK(lq.flip == 0.9);
  CHECK(lq.particles_per_axis == 2);
  REQUIRE(lq.regions.size() == 2);
  CHECK(lq.regions[0].name == "column");
  CHECK(lq.regions[0].hi == Vec3(0, 1, 1));
  CHECK(lq.regions[1].name == "region1");
  CHECK(lq.regions[1].radius == 0.2);
  CHECK(lq.regions[1].contains(Vec3(1, 0.5, 1.6)));
  REQUIRE(lq.sources.size() == 1);
  CHECK(lq.sources[0].velocity == Vec3(0, 0, -1));
  CHECK(lq.sources[0].stop == 0.5);
  const Scene back = parse_scene(s.resolved, "scene.json");
  CHECK(back.resolved == s.resolved);
  CHECK(back.fluid->params.liquid.regions[1].centre == Vec3(1, 0.5, 1.5));
}

TEST_CASE("fluid.liquid regions: a box and a sphere together are their overlap; a surface") {
  json j = liquid_json();
  // A half ball: the sphere cut by a box below its centre (a bowl's filling).
  j["fluid"]["liquid"]["regions"][1]["box"] = {{"lo", {0, 0, 0}}, {"hi", {2, 1, 1.5}}};
  // The unit cube of data/meshes/cube.obj, moved nowhere: [0, 1]^3 in the scene's coordinates.
  j["fluid"]["liquid"]["regions"].push_back(
      {{"name", "cube"}, {"surface", (source_dir / "data" / "meshes" / "cube.obj").string()}});
  const Scene s = parse_scene(j, "scene.json");
  const fluid::LiquidParams& lq = s.fluid->params.liquid;
  REQUIRE(lq.regions.size() == 3);
  CHECK(lq.regions[1].contains(Vec3(1, 0.5, 1.4)));
  CHECK_FALSE(lq.regions[1].contains(Vec3(1, 0.5, 1.6)));    // in the sphere, above the box
  CHECK_FALSE(lq.regions[1].contains(Vec3(1.5, 0.5, 1.4)));  // in the box, out of the sphere
  REQUIRE(lq.regions[2].surface);
  CHECK(lq.regions[2].surface->num_triangles() == 12);
  const Scene back = parse_scene(s.resolved, "scene.json");
  CHECK(back.resolved == s.resolved);
  CHECK(back.fluid->params.liquid.regions[1].has_box());
  CHECK(back.fluid->params.liquid.regions[1].radius == 0.2);
}

TEST_CASE("fluid.liquid errors name the key") {
  check_liquid_rejected([](json& j) { j["fluid"]["discretization"] = "tet"; },
                        {"fluid.liquid", "fluid.discretization to \"grid\""});
  check_liquid_rejected(
      [](json& j) {
        j["fluid"]["liquid"]["regions"][0]["box"]["lo"] = {5, 5, 5};
      },
      {"fluid.liquid.regions[0].box"});
  check_liquid_rejected(
      [](json& j) {
        j["fluid"]["liquid"]["regions"][0]["box"] = {{"lo", {2, 2, 3}}, {"hi", {3, 3, 4}}};
      },
      {"fluid.liquid.regions[0].box", "outside the fluid box"});
  check_liquid_rejected([](json& j) { j["fluid"]["liquid"]["regions"][1] = json::object(); },
                        {"fluid.liquid.regions[1]", "give a box, a sphere or a surface"});
  check_liquid_rejected(
      [](json& j) { j["fluid"]["liquid"]["regions"][1]["surface"] = "no_such.off"; },
      {"fluid.liquid.regions[1].surface", "no_such.off"});
  check_liquid_rejected(
      [&](json& j) {
        j["fluid"]["liquid"]["regions"][1]["surface"] =
            (source_dir / "data" / "meshes" / "open_cube.off").string();
      },
      {"fluid.liquid.regions[1].surface", "open"});
  check_liquid_rejected([](json& j) { j["fluid"]["liquid"]["sources"][0]["stop"] = 0; },
                        {"fluid.liquid.sources[0].stop", "emit nothing"});
  check_liquid_rejected([](json& j) { j["fluid"]["liquid"]["flip"] = 1.5; }, {"fluid.liquid.flip"});
  check_liquid_rejected([](json& j) { j["fluid"]["liquid"]["volume"] = 1; },
                        {"fluid.liquid", "volume"});
  check_liquid_rejected(
      [](json& j) {
        j["fluid"]["liquid"].erase("regions");
        j["fluid"]["liquid"].erase("sources");
      },
      {"fluid.liquid", "neither regions nor sources"});
}
