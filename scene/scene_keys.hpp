#pragma once
/// @file scene_keys.hpp
/// Every scene key, declared once: one table per scene section (key, type, default, range,
/// unit, one-line doc, and where the value lives in the structs of scene.hpp). From these
/// tables come the parser's unknown-key check with its "did you mean", the type and range
/// checks with their one-line errors, the defaults, the write-back of scene.resolved.json,
/// `tetfsi scene --keys [--markdown]` and the key tables of README.md ("Scene files"; the test
/// tests/scene/test_scene_keys.cpp keeps them equal).
///
/// A row whose value is a sub-object or an array of objects (a body's "mesh", "pins") has no
/// get/set: its own section reads and writes it, and scene.cpp walks between sections. Rules
/// that tie several keys together (lo < hi, "give exactly one of", inner_radius <
/// outer_radius) are in scene.cpp too; the row's doc states them.
#include <cmath>
#include <functional>
#include <limits>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "core/enum_names.hpp"
#include "fluid/params.hpp"
#include "mesh/remesh.hpp"
#include "scene/scene.hpp"
#include "solid/material.hpp"
#include "solid/obstacles.hpp"

namespace tetfsi::app {

/// The JSON type of a key's value.
enum class KeyType {
  Number,   ///< a finite number
  Integer,  ///< a whole number that fits an int
  Boolean,
  String,  ///< with `choices`: one of them
  Vec2,    ///< [a, b]
  Vec3,    ///< [x, y, z]
  Cells,   ///< [nx, ny, nz], positive integers
  Nodes,   ///< [i, ...], a non-empty array of node indices >= 0
  Names,   ///< ["a", ...], an array of distinct strings, each one of `choices` (may be empty)
  File,    ///< a file name, resolved against the scene's folder; it must exist
  Object,  ///< a sub-section (its own table)
  Array,   ///< an array of sub-sections (their own table)
};

/// "number", "[x, y, z]", ...: the type column of the tables.
const char* to_string(KeyType t);

/// The allowed values of a number or integer: lo <(=) v <(=) hi; infinite ends are open.
struct Range {
  double lo = -std::numeric_limits<double>::infinity();
  double hi = std::numeric_limits<double>::infinity();
  bool lo_open = false;
  bool hi_open = false;
  bool bounded() const { return std::isfinite(lo) || std::isfinite(hi); }
  bool contains(double v) const;
  /// "> 0", ">= 1", "< 0.5", "in (0, 1)", "in [0, 1]"; integers with both ends "0..6".
  std::string text(bool integer) const;
};
inline Range greater(double lo) {
  return {lo, std::numeric_limits<double>::infinity(), true};
}
inline Range at_least(double lo) {
  return {lo, std::numeric_limits<double>::infinity()};
}
inline Range between(double lo, double hi, bool lo_open = false, bool hi_open = false) {
  return {lo, hi, lo_open, hi_open};
}

/// One key of a section: what it is, what it may be, what it means.
struct KeySpec {
  std::string key;
  KeyType type = KeyType::Number;
  std::string doc;                   ///< one line (markdown allowed: `code`)
  std::string unit;                  ///< SI unit, "" for none
  Range range;                       ///< Number / Integer
  std::vector<std::string> choices;  ///< String: the allowed values (empty: any string)
  std::string choice_what;           ///< String with choices: "unknown <what> 'v'"
  bool required = false;
  bool non_empty = false;    ///< String: "" is an error
  std::string note;          ///< the range error's parenthesis (default: the unit)
  std::string default_text;  ///< the default column when it is not the structs' (context)
  /// An extra check of a valid-typed value: a problem, or "" if fine. It replaces the range
  /// check's message (the range is still shown).
  std::function<std::string(const nlohmann::json&)> check;
  /// The range checked and shown: `range` within what a user could mean in `unit` (every
  /// coordinate and length within 1e6 m, speeds within 1e5 m/s, absolute temperatures
  /// 0..1e6 K, ...; see k_unit_limits in scene_keys.cpp). Vec2 / Vec3 rows: each component.
  Range limits() const;
};

/// A row of a section whose values live in a T: `get` gives the resolved value (null: not
/// written, e.g. a key of another mesh kind), `set` stores a checked value. Both empty for
/// Object / Array rows.
template <class T>
struct Field {
  KeySpec spec;
  std::function<nlohmann::json(const T&)> get;
  std::function<void(T&, const nlohmann::json&)> set;
};

/// One scene section: its JSON path (as in the docs: "bodies[].material") and its rows.
template <class T>
struct Section {
  std::string path;
  std::string title;  ///< one line: what the section is
  std::vector<Field<T>> fields;
  std::string variant;  ///< of one path with several sections ("plane", "box"), else ""

  std::vector<std::string> keys() const {
    std::vector<std::string> out;
    for (const auto& f : fields) out.push_back(f.spec.key);
    return out;
  }
  /// The resolved values of `t` (rows without get, and null values, left out).
  nlohmann::json write(const T& t) const {
    nlohmann::json j = nlohmann::json::object();
    for (const auto& f : fields) {
      if (!f.get) continue;
      nlohmann::json v = f.get(t);
      if (!v.is_null()) j[f.spec.key] = std::move(v);
    }
    return j;
  }
};

/// A fluid patch as the scene describes it: the remesher's rectangle and the fluid's
/// conditions on it (FluidSpec keeps them in two parallel lists).
struct PatchKeys {
  mesh::DomainPatch patch;
  fluid::PatchConditions conditions;
};

/// The scene modes, the obstacle types, the box sides, the boundary kinds a box face may
/// have, the tube axes, and solid.reform's two values.
inline constexpr EnumNames<Mode, 2> k_mode_names{
    "mode", {{{Mode::Dynamic, "dynamic"}, {Mode::Static, "static"}}}};
inline constexpr EnumNames<solid::Obstacle::Kind, 2> k_obstacle_type_names{
    "obstacle type",
    {{{solid::Obstacle::Kind::Plane, "plane"}, {solid::Obstacle::Kind::Box, "box"}}}};
inline constexpr EnumNames<int, 6> k_side_names{
    "side", {{{0, "-x"}, {1, "+x"}, {2, "-y"}, {3, "+y"}, {4, "-z"}, {5, "+z"}}}};
inline constexpr EnumNames<mesh::FaceKind, 3> k_boundary_kind_names{
    "boundary kind",
    {{{mesh::FaceKind::Wall, "wall"},
      {mesh::FaceKind::Inflow, "inflow"},
      {mesh::FaceKind::Open, "open"}}}};
inline constexpr EnumNames<int, 3> k_axis_names{"axis", {{{0, "x"}, {1, "y"}, {2, "z"}}}};
inline constexpr EnumNames<bool, 2> k_reform_names{"reform", {{{false, "step"}, {true, "run"}}}};

// ---- the sections (scene_keys.cpp) ----
const Section<Scene>& top_level_keys();
const Section<TimeSpec>& time_keys();
const Section<OutputSpec>& output_keys();
const Section<SolverSpec>& solver_keys();
const Section<SolidSpec>& solid_keys();
const Section<StaticSpec>& static_keys();
const Section<ContactSpec>& contact_keys();
const Section<BodySpec>& body_keys();
const Section<MeshSpec>& mesh_keys();
const Section<MeshSpec>& mesh_box_keys();
const Section<MeshSpec>& mesh_sphere_keys();
const Section<MeshSpec>& mesh_shell_keys();
const Section<MeshSpec>& mesh_hollow_box_keys();
const Section<MeshSpec>& mesh_tube_keys();
const Section<MeshSpec>& mesh_bowl_keys();
const Section<TransformSpec>& transform_keys();
const Section<solid::Material>& material_keys();
const Section<PinSpec>& pin_keys();
const Section<LoadSpec>& load_keys();
const Section<BoxSpec>& selection_box_keys();
const Section<KinematicSpec>& kinematic_keys();
const Section<solid::Obstacle>& plane_obstacle_keys();
const Section<solid::Obstacle>& box_obstacle_keys();
const Section<FluidSpec>& fluid_keys();
const Section<mesh::FluidDomain>& domain_keys();
const Section<PatchKeys>& patch_keys();
const Section<mesh::Sizing>& fluid_mesh_keys();
const Section<GridKeys>& fluid_grid_keys();
const Section<fluid::FluidParams>& buoyancy_keys();
const Section<fluid::FluidParams>& decay_keys();
const Section<fluid::FluidParams>& transfer_keys();
const Section<fluid::FluidParams>& fluid_solver_keys();
const Section<fluid::SmokeSource>& source_keys();
const Section<BoxSpec>& source_box_keys();
const Section<fluid::RefineParams>& refine_keys();
const Section<fluid::LiquidParams>& liquid_keys();
const Section<fluid::LiquidRegion>& liquid_region_keys();
const Section<fluid::LiquidRegion>& liquid_sphere_keys();
/// fluid.liquid.regions[].box, or fluid.liquid.sources[].box (`source`).
const Section<BoxSpec>& liquid_box_keys(bool source);
const Section<fluid::LiquidSource>& liquid_source_keys();
const Section<CouplingSpec>& coupling_keys();

// ---- the tables as documentation ----

/// A row as the tables show it: the default is the structs' (a default-constructed T) unless
/// the row gives a default_text.
struct KeyRow {
  KeySpec spec;
  std::string default_text;  ///< "0.01", "`lz4`", "required", "-"
};
struct KeySection {
  std::string path;  ///< "" for the top level
  std::string title;
  std::vector<KeyRow> rows;
  std::string variant;  ///< Section::variant
};

/// What the tables and README.md's markers call a section: "time", "(top level)",
/// "obstacles[] (plane)".
std::string section_name(const KeySection& s);

/// A value as the default column shows it: "0.01", "1e-8", "`lz4`", "[0, 0, -9.81]", "-" (null).
std::string key_value_text(const nlohmann::json& v);

/// Every section, in the order of the README.
const std::vector<KeySection>& scene_key_sections();

/// One section as markdown, between its markers:
///   <!-- keys:begin PATH -->
///   **`PATH`**: TITLE
///   (blank line) | key | type | default | range | unit | meaning | ... (blank line)
///   <!-- keys:end -->
std::string section_markdown(const KeySection& s);
/// Every section's markdown, separated by blank lines (what README.md holds).
std::string scene_keys_markdown();
/// Every section as plain text with aligned columns (`tetfsi scene --keys`).
std::string scene_keys_text();

}  // namespace tetfsi::app
