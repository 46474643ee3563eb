/// @file test_sim_checkpoint.cpp
/// FsiSimulation::save_state / load_state on the shipped scenes (small variants): a simulation
/// stepped N times, saved to a file, loaded into a fresh simulation of the same scene and
/// stepped N more is, bit for bit, the one stepped 2N times straight — bodies, fluid fields
/// and mesh (tet or grid), for every kind of run: one-way with a kinematic body, the
/// simultaneous scheme with an enclosed liquid and floor contacts, splitting (held forces),
/// BFGS with the matrix kept for the run (kept blocks and updates), solid-only nonlinear.
/// And the records refuse a simulation of another scene.
#include <doctest/doctest.h>

#include <cstring>
#include <filesystem>
#include <string>
#include <vector>

#include "core/checkpoint.hpp"
#include "coupling/grid_fluid.hpp"
#include "coupling/tet_fluid.hpp"
#include "run/run.hpp"
#include "scene/scene.hpp"
#include "tests/test_util.hpp"

namespace fs = std::filesystem;
using namespace tetfsi;
using namespace tetfsi::app;

namespace {

/// Bitwise equality of two arrays (NaN payloads and −0 included).
template <class A>
bool same_bits(const A& a, const A& b) {
  return a.rows() == b.rows() && a.cols() == b.cols() &&
         (a.size() == 0 ||
          std::memcmp(a.data(), b.data(), sizeof(typename A::Scalar) * a.size()) == 0);
}

coupling::FsiSimulation make(const Scene& s) {
  coupling::FsiSimulation sim = make_simulation(s, build_world(s));
  return sim;
}

void advance(coupling::FsiSimulation& sim, double dt, int steps) {
  PhaseTimes phases;
  for (int i = 0; i < steps; ++i) sim.step(dt, phases);
}

void check_same(const coupling::FsiSimulation& a, const coupling::FsiSimulation& b) {
  CHECK(a.world().time == b.world().time);
  for (size_t i = 0; i < a.world().bodies.size(); ++i) {
    CAPTURE(a.world().bodies[i].name());
    CHECK(same_bits(a.world().bodies[i].displacement, b.world().bodies[i].displacement));
    CHECK(same_bits(a.world().bodies[i].velocity, b.world().bodies[i].velocity));
  }
  if (const fluid::FluidSimulation* fa = coupling::tet_fluid(a.fluid())) {
    const fluid::FluidSimulation* fb = coupling::tet_fluid(b.fluid());
    REQUIRE(fb);
    CHECK(same_bits(fa->mesh().vertices, fb->mesh().vertices));
    CHECK(same_bits(fa->mesh().tets, fb->mesh().tets));
    const fluid::FluidState &x = fa->state(), &y = fb->state();
    CHECK(same_bits(x.u, y.u));
    CHECK(same_bits(x.p, y.p));
    CHECK(same_bits(x.density, y.density));
    CHECK(same_bits(x.temperature, y.temperature));
    CHECK(fa->time() == fb->time());
  }
  if (const fluid::GridFluid* ga = coupling::grid_fluid(a.fluid())) {
    const fluid::GridFluid* gb = coupling::grid_fluid(b.fluid());
    REQUIRE(gb);
    CHECK(same_bits(ga->state().u, gb->state().u));
    CHECK(same_bits(ga->state().p, gb->state().p));
    CHECK(same_bits(ga->state().density, gb->state().density));
    CHECK(same_bits(ga->cells().cell_body, gb->cells().cell_body));
  }
}

/// Every array of two meshes equal, bit for bit.
void check_same_mesh(const mesh::TetMesh& a, const mesh::TetMesh& b) {
  CHECK(same_bits(a.vertices, b.vertices));
  CHECK(same_bits(a.tets, b.tets));
  CHECK(same_bits(a.tet_faces, b.tet_faces));
  CHECK(same_bits(a.tet_face_signs, b.tet_face_signs));
  CHECK(same_bits(a.neighbours, b.neighbours));
  CHECK(same_bits(a.volumes, b.volumes));
  CHECK(same_bits(a.circumcentres, b.circumcentres));
  CHECK(same_bits(a.faces, b.faces));
  CHECK(same_bits(a.face_tets, b.face_tets));
  CHECK(same_bits(a.face_areas, b.face_areas));
  CHECK(same_bits(a.face_normals, b.face_normals));
  CHECK(same_bits(a.face_centroids, b.face_centroids));
  CHECK(same_bits(a.dual_lengths, b.dual_lengths));
  CHECK(a.face_kind == b.face_kind);
  CHECK(same_bits(a.face_patch, b.face_patch));
  CHECK(same_bits(a.face_body, b.face_body));
  CHECK(same_bits(a.face_triangle, b.face_triangle));
  CHECK(same_bits(a.face_bary, b.face_bary));
  CHECK(same_bits(a.vertex_body, b.vertex_body));
  CHECK(same_bits(a.vertex_triangle, b.vertex_triangle));
  CHECK(same_bits(a.vertex_bary, b.vertex_bary));
}

struct Case {
  const char* scene;
  std::vector<std::string> overrides;
  int n;  ///< steps before and after the checkpoint
};

void check_restart(const Case& c) {
  CAPTURE(c.scene);
  const Scene s =
      load_scene(fs::path(TETFSI_SOURCE_DIR) / "data" / "scenes" / (std::string(c.scene) + ".json"),
                 c.overrides);
  const double dt = s.time.dt;
  PhaseTimes phases;
  coupling::FsiSimulation straight = make(s);
  if (straight.has_fluid()) straight.start(phases);
  advance(straight, dt, 2 * c.n);

  coupling::FsiSimulation first = make(s);
  if (first.has_fluid()) first.start(phases);
  advance(first, dt, c.n);
  test::TempDir dir(std::string("sim_checkpoint_") + c.scene);
  const fs::path file = dir.path / "step.tfck";
  CheckpointWriter w;
  first.save_state(w);
  w.write(file);
  const CheckpointReader r(file);
  if (const fluid::FluidSimulation* f = coupling::tet_fluid(first.fluid()))
    check_same_mesh(f->mesh(), mesh::load_mesh(r, "sim/fluid/mesh/"));

  coupling::FsiSimulation resumed = make(s);
  resumed.load_state(r);
  check_same(first, resumed);
  advance(resumed, dt, c.n);
  check_same(straight, resumed);
}

const std::vector<std::string> k_coarse = {"fluid.mesh.surface_size=0.08",
                                           "fluid.mesh.far_size=0.25"};

std::vector<std::string> coarse(std::vector<std::string> more) {
  more.insert(more.begin(), k_coarse.begin(), k_coarse.end());
  return more;
}

}  // namespace

TEST_SUITE("unit") {
  TEST_CASE("a resumed simulation is the straight one bit for bit: smoke_sheets (simultaneous)") {
    check_restart({"smoke_sheets", coarse({}), 3});
  }

  TEST_CASE("a resumed simulation is the straight one bit for bit: toy (enclosed liquid, floor)") {
    check_restart({"toy", {"fluid.mesh.surface_size=0.05"}, 7});
  }

  TEST_CASE("a resumed simulation is the straight one bit for bit: bar (splitting)") {
    check_restart({"bar", {"coupling.scheme=splitting"}, 3});
  }

  TEST_CASE("a resumed simulation is the straight one bit for bit: shell_step (BFGS, reform run)") {
    check_restart({"shell_step", {"fluid.mesh.surface_size=0.06", "fluid.mesh.far_size=0.2"}, 3});
  }

  TEST_CASE(
      "a resumed simulation is the straight one bit for bit: smoke_jet (one-way, kinematic)") {
    check_restart({"smoke_jet", coarse({"fluid.mesh.max_cells=0"}), 3});
  }

  TEST_CASE("a resumed simulation is the straight one bit for bit: smoke_sheets_grid (grid)") {
    check_restart({"smoke_sheets_grid", {"fluid.grid.cell_size=0.05"}, 3});
  }

  TEST_CASE("a resumed simulation is the straight one bit for bit: sheet_sag (solid-only BFGS)") {
    check_restart({"sheet_sag", {"solid.integrator=bfgs", "solid.reform=run"}, 4});
  }

  TEST_CASE("a simulation's records refuse a simulation of another scene, naming the record") {
    const fs::path scenes = fs::path(TETFSI_SOURCE_DIR) / "data" / "scenes";
    const Scene bar = load_scene(scenes / "bar.json", coarse({}));
    PhaseTimes phases;
    coupling::FsiSimulation a = make(bar);
    a.start(phases);
    test::TempDir dir("sim_checkpoint_other");
    CheckpointWriter w;
    a.save_state(w);
    w.write(dir.path / "a.tfck");
    const CheckpointReader r(dir.path / "a.tfck");
    auto error_loading = [&](const Scene& other) {
      coupling::FsiSimulation b = make(other);
      return test::message_of<CheckpointError>([&] { b.load_state(r); });
    };
    CHECK(error_loading(load_scene(scenes / "bar.json", coarse({"coupling.scheme=splitting"})))
              .find("'simultaneous' coupling scheme, the scene's is 'splitting'") !=
          std::string::npos);
    CHECK(error_loading(load_scene(scenes / "toy.json")).find("from another scene") !=
          std::string::npos);
    CHECK(error_loading(load_scene(scenes / "smoke_sheets_grid.json"))
              .find("a tet simulation, the scene is a grid one") != std::string::npos);
  }
}
