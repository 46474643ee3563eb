#include "scene/scene_keys.hpp"

#include <algorithm>
#include <array>
#include <set>

#include <fmt/format.h>

#include "core/linear_solver.hpp"
#include "coupling/coupled_step.hpp"
#include "coupling/coupled_system.hpp"
#include "io/output.hpp"
#include "solid/integrator.hpp"
#include "solid/nonlinear_trapezoid.hpp"

// The tables name only the KeySpec fields a row needs (designated initializers); GCC 12 warns
// about the others, which keep their defaults on purpose.
#pragma GCC diagnostic ignored "-Wmissing-field-initializers"

namespace tetfsi::app {

using nlohmann::json;

const char* to_string(KeyType t) {
  switch (t) {
    case KeyType::Number:
      return "number";
    case KeyType::Integer:
      return "integer";
    case KeyType::Boolean:
      return "boolean";
    case KeyType::String:
      return "string";
    case KeyType::Vec2:
      return "[a, b]";
    case KeyType::Vec3:
      return "[x, y, z]";
    case KeyType::Cells:
      return "[nx, ny, nz]";
    case KeyType::Nodes:
      return "[i, ...]";
    case KeyType::Names:
      return "[\"name\", ...]";
    case KeyType::File:
      return "file";
    case KeyType::Object:
      return "object";
    case KeyType::Array:
      return "array";
  }
  return "?";
}

bool Range::contains(double v) const {
  const bool above = lo_open ? v > lo : v >= lo;
  const bool below = hi_open ? v < hi : v <= hi;
  return above && below;
}

namespace {
/// 1e-08 -> 1e-8, 1000000 -> 1e6: the shorter of fmt's shortest and %g forms.
std::string bound_text(double v) {
  std::string s = fmt::format("{}", v);
  const std::string g = fmt::format("{:g}", v), x = fmt::format("{:.0e}", v);
  if (g.size() < s.size() && std::stod(g) == v) s = g;
  if (std::isfinite(v) && std::abs(v) >= 1e4 && std::stod(x) == v) s = x;  // 100000 -> 1e5
  const auto e = s.find('e');
  if (e == std::string::npos) return s;
  std::string mantissa = s.substr(0, e), exponent = s.substr(e + 1), sign;
  if (!exponent.empty() && (exponent[0] == '-' || exponent[0] == '+')) {
    if (exponent[0] == '-') sign = "-";
    exponent = exponent.substr(1);
  }
  exponent.erase(0, std::min(exponent.find_first_not_of('0'), exponent.size() - 1));
  return mantissa + "e" + sign + exponent;
}
}  // namespace

std::string Range::text(bool integer) const {
  const bool has_lo = std::isfinite(lo), has_hi = std::isfinite(hi);
  const std::string l = integer ? fmt::format("{}", lo) : bound_text(lo);
  const std::string h = integer ? fmt::format("{}", hi) : bound_text(hi);
  if (has_lo && has_hi) {
    if (integer && !lo_open && !hi_open) return fmt::format("{}..{}", l, h);
    return fmt::format("in {}{}, {}{}", lo_open ? "(" : "[", l, h, hi_open ? ")" : "]");
  }
  if (has_lo) return fmt::format("{} {}", lo_open ? ">" : ">=", l);
  if (has_hi) return fmt::format("{} {}", hi_open ? "<" : "<=", h);
  return "";
}

namespace {

/// The largest magnitude a value of each unit may have (a positive one: at least 1e-15 of it):
/// beyond it no scene a user could mean (1000 km, 1e5 m/s, 1e13 Pa is ten times diamond's modulus),
/// and the solvers' arithmetic would overflow or the meshes exhaust memory long before.
/// Temperatures are absolute.
struct UnitLimit {
  const char* unit;
  double max;
  bool non_negative;
};
constexpr UnitLimit k_unit_limits[] = {
    {"m", 1e6, false},         {"m/s", 1e5, false},    {"m/s^2", 1e4, false},
    {"K", 1e6, true},          {"kg/m^3", 1e5, false}, {"Pa", 1e13, false},
    {"s", 1e6, false},         {"1/s", 1e6, false},    {"N", 1e15, false},
    {"deg", 1e6, false},       {"deg/s", 1e8, false},  {"m^4/(kg s^2)", 1e6, false},
    {"m/(s^2 K)", 1e6, false},
};

}  // namespace

Range KeySpec::limits() const {
  Range r = range;
  for (const UnitLimit& u : k_unit_limits) {
    if (unit != u.unit) continue;
    if (r.hi > u.max) r.hi = u.max, r.hi_open = false;
    const double lo = u.non_negative ? 0.0 : -u.max;
    if (r.lo < lo) r.lo = lo, r.lo_open = false;
    // A positive quantity spans at most 15 decades below its largest value.
    if (r.lo == 0.0 && r.lo_open) r.lo = u.max * 1e-15, r.lo_open = false;
  }
  return r;
}

namespace {

// ---- values <-> JSON ----

json value_json(double v) {
  return v;
}
json value_json(int v) {
  return v;
}
json value_json(bool v) {
  return v;
}
json value_json(const std::string& v) {
  return v;
}
json value_json(const Vec3& v) {
  return json::array({v.x(), v.y(), v.z()});
}
json value_json(const Vec2& v) {
  return json::array({v.x(), v.y()});
}
json value_json(const Vec3i& v) {
  return json::array({v.x(), v.y(), v.z()});
}
json value_json(const std::vector<std::string>& v) {
  return v;
}

void assign(const json& j, double& v) {
  v = j.get<double>();
}
void assign(const json& j, int& v) {
  v = j.get<int>();
}
void assign(const json& j, bool& v) {
  v = j.get<bool>();
}
void assign(const json& j, std::string& v) {
  v = j.get<std::string>();
}
void assign(const json& j, Vec3& v) {
  for (int a = 0; a < 3; ++a) v[a] = j.at(a).get<double>();
}
void assign(const json& j, Vec2& v) {
  for (int a = 0; a < 2; ++a) v[a] = j.at(a).get<double>();
}
void assign(const json& j, std::vector<std::string>& v) {
  v = j.get<std::vector<std::string>>();
}
void assign(const json& j, Vec3i& v) {
  for (int a = 0; a < 3; ++a) v[a] = j.at(a).get<int>();
}

/// A row bound to the member `acc(t)` (a generic lambda returning a reference).
template <class T, class Acc>
Field<T> bind(KeySpec spec, Acc acc) {
  return {std::move(spec), [acc](const T& t) { return value_json(acc(t)); },
          [acc](T& t, const json& v) { assign(v, acc(t)); }};
}

/// A string row that must be one of `names`' names.
template <class E, std::size_t N>
KeySpec one_of(KeySpec spec, const EnumNames<E, N>& names) {
  spec.type = KeyType::String;
  spec.choices = names.names();
  spec.choice_what = names.what;
  return spec;
}

/// A row bound to an enum member, stored by its name in `names`.
template <class T, class E, std::size_t N, class Acc>
Field<T> bind_enum(KeySpec spec, const EnumNames<E, N>& names, Acc acc) {
  return {one_of(std::move(spec), names),
          [acc, names](const T& t) -> json { return names.name(acc(t)); },
          [acc, names](T& t, const json& v) { acc(t) = names.parse(v.get<std::string>()); }};
}

/// An Object / Array row: its own section reads and writes it.
template <class T>
Field<T> sub(KeySpec spec) {
  return {std::move(spec), nullptr, nullptr};
}

#define TETFSI_AT(member) \
  [](auto& t) -> auto& {  \
    return t.member;      \
  }

const Range k_positive = greater(0);
const Range k_non_negative = at_least(0);
const Range k_count = at_least(1);

// ---- rows shared by several sections ----

/// lo / hi of a box held by `acc(t)` (a BoxSpec, a FluidDomain, an Obstacle, ...).
template <class T, class Acc>
Field<T> lo_row(const std::string& doc, Acc acc) {
  return bind<T>(
      {.key = "lo", .type = KeyType::Vec3, .doc = doc, .unit = "m", .required = true},
      [acc](auto& t) -> auto& { return acc(t).lo; });
}
template <class T, class Acc>
Field<T> hi_row(const std::string& doc, Acc acc) {
  return bind<T>(
      {.key = "hi", .type = KeyType::Vec3, .doc = doc, .unit = "m", .required = true},
      [acc](auto& t) -> auto& { return acc(t).hi; });
}
constexpr auto k_self = [](auto& t) -> auto& {
  return t;
};
constexpr auto k_mesh_box = [](auto& t) -> auto& {
  return t.box;
};

Field<MeshSpec> cells_row(const std::string& doc, bool required) {
  return bind<MeshSpec>(
      {.key = "cells", .type = KeyType::Cells, .doc = doc, .range = k_count, .required = required},
      TETFSI_AT(cells));
}
Field<MeshSpec> center_row(const std::string& doc) {
  return bind<MeshSpec>(
      {.key = "center", .type = KeyType::Vec3, .doc = doc, .unit = "m", .required = true},
      TETFSI_AT(center));
}
Field<MeshSpec> radius_row(const char* key, const std::string& doc) {
  return bind<MeshSpec>(
      {.key = key,
       .type = KeyType::Number,
       .doc = doc,
       .unit = "m",
       .range = k_positive,
       .required = true},
      [key](auto& t) -> auto& {
        return std::string(key) == "radius"         ? t.radius
               : std::string(key) == "inner_radius" ? t.inner_radius
                                                    : t.outer_radius;
      });
}
/// Prism layers across a shell's or a bowl's wall.
Field<MeshSpec> layers_row() {
  return bind<MeshSpec>({.key = "layers",
                         .type = KeyType::Integer,
                         .doc = "prism layers across the wall (3 tets each)",
                         .range = between(1, 10000),
                         .note = "tets across the wall: 3 each"},
                        TETFSI_AT(layers));
}

Field<MeshSpec> subdivisions_row(int max) {
  return bind<MeshSpec>({.key = "subdivisions",
                         .type = KeyType::Integer,
                         .doc = "icosphere level of the surface: edges about radius / 2^s",
                         .range = between(0, max),
                         .note = "icosphere levels: surface edges about radius / 2^s"},
                        TETFSI_AT(subdivisions));
}

/// name of a list element; `pattern` its default ("patch<i>").
template <class T, class Acc>
Field<T> name_row(const std::string& doc, const std::string& pattern, bool non_empty, Acc acc) {
  return bind<T>({.key = "name",
                  .type = KeyType::String,
                  .doc = doc,
                  .non_empty = non_empty,
                  .default_text = "`" + pattern + "`"},
                 acc);
}

template <class T>
Field<T> rel_tol_row(const std::string& doc, double T::*member) {
  return {{.key = "rel_tol", .type = KeyType::Number, .doc = doc, .range = k_positive},
          [member](const T& t) { return json(t.*member); },
          [member](T& t, const json& v) { t.*member = v.get<double>(); }};
}
template <class T>
Field<T> max_iterations_row(const std::string& doc, int T::*member) {
  return {{.key = "max_iterations", .type = KeyType::Integer, .doc = doc, .range = k_count},
          [member](const T& t) { return json(t.*member); },
          [member](T& t, const json& v) { t.*member = v.get<int>(); }};
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// The sections.

const Section<Scene>& top_level_keys() {
  static const Section<Scene> s{
      "",
      "the scene file",
      {bind<Scene>({.key = "name",
                    .type = KeyType::String,
                    .doc = "names the output folder (out/NAME) and the run",
                    .non_empty = true,
                    .default_text = "the file's stem"},
                   TETFSI_AT(name)),
       {{.key = "description",
         .type = KeyType::String,
         .doc = "free text, kept in the resolved scene"},
        [](const Scene& t) { return t.description.empty() ? json() : json(t.description); },
        [](Scene& t, const json& v) { t.description = v.get<std::string>(); }},
       bind_enum<Scene>(
           {.key = "mode", .doc = "`dynamic`: time steps; `static`: equilibrium under the loads"},
           k_mode_names, TETFSI_AT(mode)),
       sub<Scene>({.key = "time", .type = KeyType::Object, .doc = "the run's length"}),
       sub<Scene>({.key = "output", .type = KeyType::Object, .doc = "the frames written"}),
       bind<Scene>({.key = "gravity",
                    .type = KeyType::Vec3,
                    .doc = "acceleration of the bodies (and of the fluid with fluid.gravity)",
                    .unit = "m/s^2"},
                   TETFSI_AT(gravity)),
       sub<Scene>({.key = "solver", .type = KeyType::Object, .doc = "the solids' linear solver"}),
       sub<Scene>({.key = "solid",
                   .type = KeyType::Object,
                   .doc = "the integrator of bodies that step alone"}),
       sub<Scene>({.key = "static", .type = KeyType::Object, .doc = "mode `static`'s solve"}),
       sub<Scene>({.key = "bodies",
                   .type = KeyType::Array,
                   .doc = "the deformable or kinematic solids; at least one without `fluid`",
                   .default_text = "required (`[]` with fluid)"}),
       sub<Scene>({.key = "obstacles",
                   .type = KeyType::Array,
                   .doc = "rigid planes and boxes the bodies collide with (not the fluid)",
                   .default_text = "`[]`"}),
       sub<Scene>({.key = "fluid",
                   .type = KeyType::Object,
                   .doc = "a fluid on a mesh rebuilt around the bodies every step",
                   .default_text = "none"}),
       sub<Scene>({.key = "coupling",
                   .type = KeyType::Object,
                   .doc = "how the fluid and the bodies interact (fluid scenes only)"}),
       sub<Scene>({.key = "contact",
                   .type = KeyType::Object,
                   .doc = "contact between the bodies and self-contact, keeping a gap",
                   .default_text = "none: bodies pass through each other"})}};
  return s;
}

const Section<TimeSpec>& time_keys() {
  static const Section<TimeSpec> s{
      "time",
      "the run's length: `end_time` or `steps`, not both (at most 1e9 steps)",
      {bind<TimeSpec>({.key = "dt",
                       .type = KeyType::Number,
                       .doc = "the time step",
                       .unit = "s",
                       .range = k_positive},
                      TETFSI_AT(dt)),
       {{.key = "end_time",
         .type = KeyType::Number,
         .doc = "simulated time: ceil(end_time / dt) steps",
         .unit = "s",
         .range = k_positive},
        [](const TimeSpec& t) { return t.steps ? json() : json(t.end_time.value_or(1.0)); },
        [](TimeSpec& t, const json& v) { t.end_time = v.get<double>(); }},
       {{.key = "steps",
         .type = KeyType::Integer,
         .doc = "the number of steps, instead of end_time",
         .range = k_count},
        [](const TimeSpec& t) { return t.steps ? json(*t.steps) : json(); },
        [](TimeSpec& t, const json& v) { t.steps = v.get<int>(); }}}};
  return s;
}

const Section<OutputSpec>& output_keys() {
  static const Section<OutputSpec> s{
      "output",
      "the frames written",
      {bind<OutputSpec>({.key = "every",
                         .type = KeyType::Integer,
                         .doc = "a frame every this many steps (and the last step)",
                         .range = k_count},
                        TETFSI_AT(every)),
       bind<OutputSpec>(one_of({.key = "compression",
                                .doc = "of the .vtu data: `zlib` is smaller and 5x slower"},
                               k_compression_names),
                        TETFSI_AT(compression)),
       bind<OutputSpec>({.key = "checkpoint_every",
                         .type = KeyType::Integer,
                         .doc = "a checkpoint every this many steps in OUT/checkpoints/ (and at "
                                "the last step), for `tetfsi resume`; 0: only when the run is "
                                "stopped (docs/user/checkpoints.md)",
                         .range = k_non_negative},
                        TETFSI_AT(checkpoint_every)),
       bind<OutputSpec>({.key = "keep_checkpoints",
                         .type = KeyType::Integer,
                         .doc = "the newest checkpoints kept; older ones are deleted once a "
                                "newer one is written",
                         .range = k_count},
                        TETFSI_AT(keep_checkpoints)),
       bind<OutputSpec>({.key = "export",
                         .type = KeyType::Names,
                         .doc = "renderer files besides the .vtu frames: `vdb` (the fluid as "
                                "OpenVDB volumes), `ply` (the surfaces as PLY meshes), in "
                                "OUT/vdb/, OUT/ply/ (docs/user/blender.md)",
                         .choices = {"vdb", "ply"},
                         .choice_what = "export format"},
                        TETFSI_AT(export_formats)),
       bind<OutputSpec>({.key = "voxel_size",
                         .type = KeyType::Number,
                         .doc = "the tet fluid's voxels in the .vdb; 0: fluid.mesh.surface_size "
                                "(a grid fluid exports its cells)",
                         .unit = "m",
                         .range = k_non_negative},
                        TETFSI_AT(voxel_size)),
       bind<OutputSpec>({.key = "voxel_subsamples",
                         .type = KeyType::Integer,
                         .doc = "each voxel averages n^3 samples of the tet fluid",
                         .range = between(1, 8)},
                        TETFSI_AT(voxel_subsamples)),
       bind<OutputSpec>({.key = "smoke_threshold",
                         .type = KeyType::Number,
                         .doc = "the .vdb's active voxels: smoke density above this (0: every "
                                "fluid voxel)",
                         .unit = "kg/m^3",
                         .range = k_non_negative},
                        TETFSI_AT(smoke_threshold))}};
  return s;
}

namespace {

/// The bodies' backends: every one but the grid fluid's structured multigrid.
KeySpec bodies_solver(KeySpec spec) {
  std::erase(spec.choices, to_string(SolverKind::Pfmg));
  return spec;
}

}  // namespace

const Section<SolverSpec>& solver_keys() {
  static const Section<SolverSpec> s{
      "solver",
      "the solids' linear solver (docs/method/linear_solvers.md)",
      {bind<SolverSpec>(
           bodies_solver(one_of({.key = "linear", .doc = "the backend"}, k_solver_kind_names)),
           TETFSI_AT(linear)),
       rel_tol_row<SolverSpec>("iterative backends: relative residual", &SolverSpec::rel_tol),
       max_iterations_row<SolverSpec>("iterative backends: iterations before the solve fails",
                                      &SolverSpec::max_iterations)}};
  return s;
}

const Section<SolidSpec>& solid_keys() {
  constexpr auto eq = [](auto& t) -> auto& {
    return t.equilibrium;
  };
  static const Section<SolidSpec> s{
      "solid",
      "the integrator of bodies that step alone and the equilibrium iteration [BatheSonnad80]",
      {bind_enum<SolidSpec>(
           {.key = "integrator",
            .doc = "solid-only or one-way scenes: `linearized` [Chentanez06, Eqs. (4)-(5)], or "
                   "the nonlinear trapezoidal rule iterated by `newton`, `modified_newton`, "
                   "`bfgs`; in a two-way scene it must equal coupling.scheme. Default: `newton` "
                   "in solid-only and one-way dynamic scenes (docs/method/solid.md), "
                   "`linearized` in two-way scenes or when solid.trapezoid is given",
            .default_text = "by scene"},
           solid::k_integrator_names, TETFSI_AT(integrator)),
       bind<SolidSpec>(one_of({.key = "trapezoid",
                               .doc = "the linearized integrator's variant (an error with "
                                      "another integrator or an iterated coupling scheme)"},
                              solid::k_trapezoid_names),
                       TETFSI_AT(trapezoid)),
       bind_enum<SolidSpec>(
           {.key = "tangent",
            .doc = "the Jacobian K' of every integrator: `exact` (d²W/dx²), or `definite`: its "
                   "initial-stress term keeps only the tensile principal stresses, so the "
                   "step's matrix stays positive definite when elements are crushed "
                   "(docs/method/contact.md "
                   "\"Bodies that touch\"). Default: `definite` with `contact`, else `exact`",
            .default_text = "by scene"},
           solid::k_tangent_names, TETFSI_AT(tangent)),
       bind<SolidSpec>(
           {.key = "rtol",
            .type = KeyType::Number,
            .doc = "out-of-balance force tolerance, Eq. (12) (against the largest "
                   "force at the start of any step so far)",
            .range = k_positive,
            .note = "out-of-balance force tolerance, [BatheSonnad80, Eq. (12)]"},
           [eq](auto& t) -> auto& { return eq(t).rtol; }),
       bind<SolidSpec>(
           {.key = "etol",
            .type = KeyType::Number,
            .doc = "energy tolerance, Eq. (13)",
            .range = k_positive,
            .note = "energy tolerance, Eq. (13)"},
           [eq](auto& t) -> auto& { return eq(t).etol; }),
       bind<SolidSpec>(
           {.key = "stol",
            .type = KeyType::Number,
            .doc = "BFGS line-search tolerance, Eq. (10)",
            .range = between(0, 1, true, true),
            .note = "line-search tolerance, Eq. (10)"},
           [eq](auto& t) -> auto& { return eq(t).stol; }),
       bind<SolidSpec>(
           {.key = "max_iterations",
            .type = KeyType::Integer,
            .doc = "iterations per step before the step fails",
            .range = k_count,
            .note = "equilibrium iterations per step"},
           [eq](auto& t) -> auto& { return eq(t).max_iterations; }),
       bind<SolidSpec>(
           {.key = "max_updates",
            .type = KeyType::Integer,
            .doc = "BFGS updates before the matrix is re-formed",
            .range = k_count,
            .note = "BFGS updates before the matrix is re-formed"},
           [eq](auto& t) -> auto& { return eq(t).max_updates; }),
       bind<SolidSpec>(
           {.key = "line_search",
            .type = KeyType::Boolean,
            .doc = "false: BFGS takes step length 1 (Newton and modified Newton are "
                   "plain, as in the seed)"},
           [eq](auto& t) -> auto& { return eq(t).line_search; }),
       bind_enum<SolidSpec>(
           {.key = "reform",
            .doc = "`run`: modified Newton and BFGS form their starting matrix once, at the "
                   "first step, and BFGS carries its updates until `max_updates`"},
           k_reform_names, [eq](auto& t) -> auto& { return eq(t).keep_matrix; }),
       bind_enum<SolidSpec>(
           {.key = "starting_matrix",
            .doc = "coupling.scheme `bfgs` or `modified_newton`: `bodies`, Eq. (15) (the "
                   "bodies' stiffness and inertia, no fluid), or `added_mass`: plus a lumped "
                   "estimate of the fluid's added mass per node (three more fluid solves when the "
                   "matrix is formed), or `coupled`: the whole added mass, the coupled system on "
                   "the increment (each iteration one coupled solve; needs `reform` `step`)"},
           k_starting_matrix_names, [eq](auto& t) -> auto& { return eq(t).starting_matrix; })}};
  return s;
}

const Section<StaticSpec>& static_keys() {
  static const Section<StaticSpec> s{
      "static",
      "mode `static`: the equilibrium solve",
      {bind<StaticSpec>({.key = "load_steps",
                         .type = KeyType::Integer,
                         .doc = "the loads applied in this many increments",
                         .range = k_count},
                        TETFSI_AT(load_steps)),
       rel_tol_row<StaticSpec>("Newton's relative residual", &StaticSpec::rel_tol),
       max_iterations_row<StaticSpec>("Newton iterations per load step",
                                      &StaticSpec::max_iterations)}};
  return s;
}

const Section<ContactSpec>& contact_keys() {
  using C = ContactSpec;
  static const Section<C> s{
      "contact",
      "contact between the bodies and each body's self-contact (docs/method/contact.md): "
      "surfaces keep at least `gap` apart, with Coulomb friction",
      {{{.key = "gap",
         .type = KeyType::Number,
         .doc = "d: the distance surfaces keep apart; less than the thinnest body is thick",
         .unit = "m",
         .range = k_positive,
         .default_text = "a fifth of fluid.mesh.surface_size (solid-only: of the median surface "
                         "edge), at most a third of the thinnest body"},
        [](const C& c) { return c.gap ? json(*c.gap) : json(); },
        [](C& c, const json& v) { c.gap = v.get<double>(); }},
       bind<C>({.key = "friction",
                .type = KeyType::Number,
                .doc = "Coulomb's coefficient between surfaces",
                .range = k_non_negative},
               TETFSI_AT(friction)),
       bind<C>({.key = "restitution",
                .type = KeyType::Number,
                .doc = "separating speed after a contact at most this times the approach speed",
                .range = between(0, 1)},
               TETFSI_AT(restitution)),
       bind<C>({.key = "self",
                .type = KeyType::Boolean,
                .doc = "each body's surface against itself (a sheet folding onto itself)"},
               TETFSI_AT(self)),
       bind<C>({.key = "stiffness",
                .type = KeyType::Number,
                .doc = "the penalty relative to the pair's inertia, k = stiffness m/h^2: the gap "
                       "closes by 2/stiffness of the step's penetration",
                .range = at_least(10)},
               TETFSI_AT(stiffness))}};
  return s;
}

const Section<BodySpec>& body_keys() {
  static const Section<BodySpec> s{
      "bodies[]",
      "a solid body: a tet mesh, its material, pins and loads, or a kinematic motion",
      {bind<BodySpec>({.key = "name",
                       .type = KeyType::String,
                       .doc = "unique; names the body's output files",
                       .required = true,
                       .non_empty = true},
                      TETFSI_AT(name)),
       sub<BodySpec>({.key = "mesh",
                      .type = KeyType::Object,
                      .doc = "where the tets come from",
                      .required = true}),
       sub<BodySpec>({.key = "transform", .type = KeyType::Object, .doc = "applied to the mesh"}),
       sub<BodySpec>({.key = "material", .type = KeyType::Object, .doc = "St. Venant-Kirchhoff"}),
       sub<BodySpec>({.key = "pins",
                      .type = KeyType::Array,
                      .doc = "fixed node components",
                      .default_text = "`[]`"}),
       sub<BodySpec>({.key = "loads",
                      .type = KeyType::Array,
                      .doc = "constant forces on nodes",
                      .default_text = "`[]`"}),
       bind<BodySpec>({.key = "initial_velocity",
                       .type = KeyType::Vec3,
                       .doc = "of every free node at t = 0",
                       .unit = "m/s"},
                      TETFSI_AT(initial_velocity)),
       sub<BodySpec>({.key = "kinematic",
                      .type = KeyType::Object,
                      .doc = "moved rigidly by the scene, not by the FEM (no pins, loads or "
                             "initial velocity)",
                      .default_text = "none"})}};
  return s;
}

const Section<MeshSpec>& mesh_keys() {
  using K = MeshSpec::Kind;
  const auto file_row = [](const char* key, K kind, const std::string& doc) -> Field<MeshSpec> {
    return {{.key = key, .type = KeyType::File, .doc = doc, .default_text = "-"},
            [kind](const MeshSpec& m) { return m.kind == kind ? json(m.file.string()) : json(); },
            [kind](MeshSpec& m, const json& v) {
              m.kind = kind;
              m.file = v.get<std::string>();
            }};
  };
  static const Section<MeshSpec> s{
      "bodies[].mesh",
      "exactly one of box, file, surface, sphere, shell, hollow_box, tube, bowl",
      {sub<MeshSpec>(
           {.key = "box", .type = KeyType::Object, .doc = "a box of hexahedra, 6 tets each"}),
       file_row("file", K::File, "a tet mesh: Gmsh .msh v2/v4 ASCII, TetGen .node/.ele, .vtu"),
       file_row("surface", K::Surface, "a closed surface (.off .obj .stl) meshed by CGAL"),
       {{.key = "cell_size",
         .type = KeyType::Number,
         .doc = "`surface` only (required there): the target tet size, in the file's units (meshed "
                "before the transform)",
         .unit = "m",
         .range = k_positive,
         .default_text = "-"},
        [](const MeshSpec& m) { return m.kind == K::Surface ? json(m.cell_size) : json(); },
        [](MeshSpec& m, const json& v) { m.cell_size = v.get<double>(); }},
       sub<MeshSpec>({.key = "sphere", .type = KeyType::Object, .doc = "a ball"}),
       sub<MeshSpec>({.key = "shell",
                      .type = KeyType::Object,
                      .doc = "a hollow ball: its cavity fills with fluid"}),
       sub<MeshSpec>({.key = "hollow_box",
                      .type = KeyType::Object,
                      .doc = "a box with one closed box cavity"}),
       sub<MeshSpec>({.key = "tube",
                      .type = KeyType::Object,
                      .doc = "a cylindrical tube, open at both ends"}),
       sub<MeshSpec>({.key = "bowl",
                      .type = KeyType::Object,
                      .doc = "a hemispherical bowl, open upward (a thick open shell)"})}};
  return s;
}

const Section<MeshSpec>& mesh_box_keys() {
  static const Section<MeshSpec> s{
      "bodies[].mesh.box",
      "a box body, lo < hi",
      {lo_row<MeshSpec>("low corner", k_mesh_box), hi_row<MeshSpec>("high corner", k_mesh_box),
       cells_row("hexahedra per axis", false)}};
  return s;
}

const Section<MeshSpec>& mesh_sphere_keys() {
  static const Section<MeshSpec> s{
      "bodies[].mesh.sphere",
      "a ball (mesh::make_ball)",
      {center_row("centre"), radius_row("radius", "radius"), subdivisions_row(6)}};
  return s;
}

const Section<MeshSpec>& mesh_shell_keys() {
  static const Section<MeshSpec> s{
      "bodies[].mesh.shell",
      "a hollow ball (mesh::make_spherical_shell), inner_radius < outer_radius",
      {center_row("centre"), radius_row("inner_radius", "radius of the cavity"),
       radius_row("outer_radius", "outer radius"), subdivisions_row(7), layers_row()}};
  return s;
}

const Section<MeshSpec>& mesh_hollow_box_keys() {
  static const Section<MeshSpec> s{
      "bodies[].mesh.hollow_box",
      "a box with a closed box cavity (mesh::make_hollow_box), lo < hi",
      {lo_row<MeshSpec>("low corner (outside)", k_mesh_box),
       hi_row<MeshSpec>("high corner (outside)", k_mesh_box),
       bind<MeshSpec>({.key = "thickness",
                       .type = KeyType::Number,
                       .doc = "the wall on all six sides; 2 thickness < hi - lo in every axis",
                       .unit = "m",
                       .range = k_positive,
                       .required = true,
                       .note = "m, the wall on each of the 6 sides"},
                      TETFSI_AT(thickness)),
       cells_row("cells across the cavity (the walls get thickness / cavity cell, at least one)",
                 false)}};
  return s;
}

const Section<MeshSpec>& mesh_tube_keys() {
  static const Section<MeshSpec> s{
      "bodies[].mesh.tube",
      "a tube (mesh::make_tube): centre +- length / 2 along the axis, inner_radius < outer_radius",
      {center_row("centre"),
       bind_enum<MeshSpec>({.key = "axis", .doc = "the tube's axis"}, k_axis_names,
                           TETFSI_AT(axis)),
       radius_row("inner_radius", "inner radius"), radius_row("outer_radius", "outer radius"),
       bind<MeshSpec>({.key = "length",
                       .type = KeyType::Number,
                       .doc = "along the axis",
                       .unit = "m",
                       .range = k_positive,
                       .required = true,
                       .note = "m, along the axis"},
                      TETFSI_AT(length)),
       cells_row("radial, around (>= 6), axial", true)}};
  return s;
}

const Section<MeshSpec>& mesh_bowl_keys() {
  static const Section<MeshSpec> s{
      "bodies[].mesh.bowl",
      "the lower half of a spherical shell (mesh::make_bowl), rim on the centre's plane z, open "
      "toward +z; inner_radius < outer_radius",
      {center_row("centre of the spheres (on the rim's plane)"),
       radius_row("inner_radius", "radius of the inside"),
       radius_row("outer_radius", "outer radius"),
       bind<MeshSpec>({.key = "cells",
                       .type = KeyType::Integer,
                       .doc = "edges from the bottom to the rim (even); 4 x cells around the rim",
                       .range = between(2, 512)},
                      TETFSI_AT(meridian_cells)),
       layers_row()}};
  return s;
}

const Section<TransformSpec>& transform_keys() {
  static const Section<TransformSpec> s{
      "bodies[].transform",
      "x -> translate + R (scale x), R = Rz Ry Rx",
      {bind<TransformSpec>({.key = "scale",
                            .type = KeyType::Number,
                            .doc = "uniform scale, first",
                            .range = between(1e-6, 1e6)},
                           TETFSI_AT(scale)),
       bind<TransformSpec>({.key = "rotate_deg",
                            .type = KeyType::Vec3,
                            .doc = "rotations about x, y, z, after the scale",
                            .unit = "deg"},
                           TETFSI_AT(rotate_deg)),
       bind<TransformSpec>({.key = "translate", .type = KeyType::Vec3, .doc = "last", .unit = "m"},
                           TETFSI_AT(translate))}};
  return s;
}

const Section<solid::Material>& material_keys() {
  const auto poisson_check = [](const json& v) -> std::string {
    const double nu = v.get<double>();
    if (nu >= 0.5)
      return fmt::format(
          "must be < 0.5, got {} (0.5 is incompressible and locks linear tets; use at most 0.49)",
          nu);
    if (nu <= -1.0)
      return fmt::format("must be > -1, got {} (-1 or less makes the material unstable)", nu);
    return "";
  };
  static const Section<solid::Material> s{
      "bodies[].material",
      "St. Venant-Kirchhoff with Rayleigh damping C = alpha M + beta K'",
      {bind<solid::Material>({.key = "density",
                              .type = KeyType::Number,
                              .doc = "mass density",
                              .unit = "kg/m^3",
                              .range = k_positive},
                             TETFSI_AT(density)),
       bind<solid::Material>({.key = "youngs_modulus",
                              .type = KeyType::Number,
                              .doc = "Young's modulus E",
                              .unit = "Pa",
                              .range = k_positive},
                             TETFSI_AT(youngs_modulus)),
       bind<solid::Material>({.key = "poisson_ratio",
                              .type = KeyType::Number,
                              .doc = "Poisson's ratio (0.5 locks linear tets: at most 0.49)",
                              .range = between(-1, 0.5, true, true),
                              .check = poisson_check},
                             TETFSI_AT(poisson_ratio)),
       bind<solid::Material>({.key = "rayleigh_alpha",
                              .type = KeyType::Number,
                              .doc = "mass-proportional damping",
                              .unit = "1/s",
                              .range = k_non_negative,
                              .note = "negative damping adds energy"},
                             TETFSI_AT(rayleigh_alpha)),
       bind<solid::Material>({.key = "rayleigh_beta",
                              .type = KeyType::Number,
                              .doc = "stiffness-proportional damping",
                              .unit = "s",
                              .range = k_non_negative,
                              .note = "negative damping adds energy"},
                             TETFSI_AT(rayleigh_beta))}};
  return s;
}

namespace {

/// box / nodes of a pin or a load: exactly one.
template <class T>
std::vector<Field<T>> selection_rows() {
  return {sub<T>({.key = "box",
                  .type = KeyType::Object,
                  .doc = "the nodes in this box (rest positions after the transform); or nodes",
                  .default_text = "-"}),
          {{.key = "nodes",
            .type = KeyType::Nodes,
            .doc = "these nodes (indices); or box",
            .range = k_non_negative,
            .default_text = "-"},
           [](const T& t) { return t.select.box ? json() : json(t.select.nodes); },
           [](T& t, const json& v) { t.select.nodes = v.get<std::vector<Index>>(); }}};
}

}  // namespace

const Section<PinSpec>& pin_keys() {
  const auto axes_check = [](const json& v) -> std::string {
    const std::string axes = v.get<std::string>();
    bool ok = !axes.empty();
    std::set<char> seen;
    for (char c : axes) ok = ok && (c == 'x' || c == 'y' || c == 'z') && seen.insert(c).second;
    return ok ? ""
              : fmt::format("must be a non-empty subset of \"xyz\" (e.g. \"xz\"), got \"{}\"",
                            axes);
  };
  static const Section<PinSpec> s = [&] {
    Section<PinSpec> p{"bodies[].pins[]", "fixed node components: box or nodes",
                       selection_rows<PinSpec>()};
    p.fields.push_back(bind<PinSpec>({.key = "axes",
                                      .type = KeyType::String,
                                      .doc = "the fixed components: a subset of `xyz`",
                                      .check = axes_check},
                                     TETFSI_AT(axes)));
    return p;
  }();
  return s;
}

const Section<LoadSpec>& load_keys() {
  static const Section<LoadSpec> s = [] {
    Section<LoadSpec> l{"bodies[].loads[]", "a constant force: box or nodes",
                        selection_rows<LoadSpec>()};
    l.fields.push_back(bind<LoadSpec>({.key = "total_force",
                                       .type = KeyType::Vec3,
                                       .doc = "spread evenly over the selected nodes",
                                       .unit = "N",
                                       .required = true},
                                      TETFSI_AT(total_force)));
    return l;
  }();
  return s;
}

const Section<BoxSpec>& selection_box_keys() {
  static const Section<BoxSpec> s{
      "bodies[].pins[].box",
      "also loads[].box: lo <= hi (may be flat); includes nodes within 1e-9 m",
      {lo_row<BoxSpec>("low corner", k_self), hi_row<BoxSpec>("high corner", k_self)}};
  return s;
}

const Section<KinematicSpec>& kinematic_keys() {
  static const Section<KinematicSpec> s{
      "bodies[].kinematic",
      "a rigid motion prescribed by the scene (solid::KinematicMotion)",
      {bind<KinematicSpec>(
           {.key = "velocity", .type = KeyType::Vec3, .doc = "linear velocity", .unit = "m/s"},
           TETFSI_AT(velocity)),
       bind<KinematicSpec>({.key = "angular_velocity_deg",
                            .type = KeyType::Vec3,
                            .doc = "about the axis through center",
                            .unit = "deg/s"},
                           TETFSI_AT(angular_velocity_deg)),
       {{.key = "center",
         .type = KeyType::Vec3,
         .doc = "of the rotation",
         .unit = "m",
         .default_text = "the mean of the rest nodes"},
        [](const KinematicSpec& k) { return k.center ? value_json(*k.center) : json(); },
        [](KinematicSpec& k, const json& v) {
          Vec3 c;
          assign(v, c);
          k.center = c;
        }}}};
  return s;
}

namespace {

/// An obstacle's rows: type and name, `own` (its geometry), restitution and friction.
Section<solid::Obstacle> obstacle_section(const char* type,
                                          std::vector<Field<solid::Obstacle>> own) {
  using O = solid::Obstacle;
  std::vector<Field<O>> rows = {
      bind_enum<O>({.key = "type", .doc = "`plane` or `box`", .required = true},
                   k_obstacle_type_names, TETFSI_AT(kind)),
      name_row<O>("names it in messages (may be empty)", fmt::format("{}<i>", type), false,
                  TETFSI_AT(name))};
  rows.insert(rows.end(), own.begin(), own.end());
  rows.push_back(bind<O>({.key = "restitution",
                          .type = KeyType::Number,
                          .doc = "outgoing normal speed / incoming",
                          .range = between(0, 1)},
                         TETFSI_AT(restitution)));
  rows.push_back(bind<O>({.key = "friction",
                          .type = KeyType::Number,
                          .doc = "Coulomb coefficient",
                          .range = between(0, 100)},
                         TETFSI_AT(friction)));
  return {"obstacles[]", "", std::move(rows), type};
}

}  // namespace

const Section<solid::Obstacle>& plane_obstacle_keys() {
  using O = solid::Obstacle;
  static const Section<O> s = [] {
    Section<O> p = obstacle_section(
        "plane",
        {bind<O>(
             {.key = "point", .type = KeyType::Vec3, .doc = "a point of the plane", .unit = "m"},
             TETFSI_AT(point)),
         bind<O>({.key = "normal",
                  .type = KeyType::Vec3,
                  .doc = "into the free side (normalised; not zero)",
                  .check = [](const json& v) -> std::string {
                    Vec3 n;
                    assign(v, n);
                    return n.norm() < 1e-12 ? "must not be zero" : "";
                  }},
                 TETFSI_AT(normal))});
    p.title = "a half-space the nodes stay out of: type `plane`";
    return p;
  }();
  return s;
}

const Section<solid::Obstacle>& box_obstacle_keys() {
  using O = solid::Obstacle;
  static const Section<O> s = [] {
    Section<O> b = obstacle_section(
        "box", {lo_row<O>("low corner", k_self), hi_row<O>("high corner", k_self)});
    b.title = "an axis-aligned box the nodes stay out of: type `box`, lo < hi";
    return b;
  }();
  return s;
}

const Section<FluidSpec>& fluid_keys() {
  constexpr auto fp = [](auto& t) -> auto& {
    return t.params;
  };
  static const Section<FluidSpec> s{
      "fluid",
      "an incompressible fluid filling a box around the bodies",
      {sub<FluidSpec>({.key = "domain",
                       .type = KeyType::Object,
                       .doc = "the box and its boundary",
                       .required = true}),
       bind_enum<FluidSpec>(
           {.key = "discretization",
            .doc = "tet: the tet mesh rebuilt every step; grid: a regular MAC grid"},
           k_discretization_names, TETFSI_AT(discretization)),
       sub<FluidSpec>(
           {.key = "mesh", .type = KeyType::Object, .doc = "the fluid mesh's sizes (tet)"}),
       sub<FluidSpec>({.key = "grid", .type = KeyType::Object, .doc = "the MAC grid (grid)"}),
       bind<FluidSpec>(
           {.key = "density",
            .type = KeyType::Number,
            .doc = "1.2 for air, 1000 for water",
            .unit = "kg/m^3",
            .range = k_positive},
           [fp](auto& t) -> auto& { return fp(t).density; }),
       bind<FluidSpec>(
           {.key = "enclosed_density",
            .type = KeyType::Number,
            .doc = "of fluid sealed inside closed bodies; 0: density",
            .unit = "kg/m^3",
            .range = k_non_negative,
            .note = "kg/m^3; 0: the same as density"},
           [fp](auto& t) -> auto& { return fp(t).enclosed_density; }),
       bind<FluidSpec>({.key = "gravity",
                        .type = KeyType::Boolean,
                        .doc = "true: the fluid feels the scene's gravity (liquids)"},
                       TETFSI_AT(gravity)),
       sub<FluidSpec>({.key = "buoyancy", .type = KeyType::Object, .doc = "smoke and heat"}),
       bind<FluidSpec>(
           {.key = "vorticity_confinement",
            .type = KeyType::Number,
            .doc = "epsilon [Fedkiw01, Eq. (11)], dimensionless; 0: off",
            .range = between(0, 1000)},
           [fp](auto& t) -> auto& { return fp(t).vorticity_confinement; }),
       sub<FluidSpec>({.key = "decay", .type = KeyType::Object, .doc = "dissipation rates"}),
       bind_enum<FluidSpec>(
           {.key = "reconstruction",
            .doc = "of the velocity inside a tet from its face components"},
           fluid::k_reconstruction_names, [fp](auto& t) -> auto& { return fp(t).reconstruction; }),
       sub<FluidSpec>({.key = "transfer",
                       .type = KeyType::Object,
                       .doc = "advection from mesh to mesh (tet mesh)"}),
       bind<FluidSpec>(
           {.key = "min_dual_fraction",
            .type = KeyType::Number,
            .doc = "co-spherical cell tolerance: a fraction of the face's mean edge",
            .range = between(0, 0.1, true, false),
            .note = "a fraction of the face's mean edge; default 1e-6"},
           [fp](auto& t) -> auto& { return fp(t).min_dual_fraction; }),
       sub<FluidSpec>({.key = "solver", .type = KeyType::Object, .doc = "the pressure solve"}),
       sub<FluidSpec>({.key = "sources",
                       .type = KeyType::Array,
                       .doc = "boxes emitting smoke and heat",
                       .default_text = "`[]`"}),
       sub<FluidSpec>(
           {.key = "refine", .type = KeyType::Object, .doc = "mesh refinement where smoke is"}),
       sub<FluidSpec>({.key = "liquid",
                       .type = KeyType::Object,
                       .doc = "a liquid with a free surface (grid)"})}};
  return s;
}

const Section<mesh::FluidDomain>& domain_keys() {
  using D = mesh::FluidDomain;
  static const Section<D> s{
      "fluid.domain",
      "the fluid's box, lo < hi; the run checks that the bodies stay inside",
      {lo_row<D>("low corner", k_self), hi_row<D>("high corner", k_self),
       bind_enum<D>({.key = "default", .doc = "the kind of the box faces not on a patch"},
                    k_boundary_kind_names, TETFSI_AT(default_kind)),
       sub<D>({.key = "patches",
               .type = KeyType::Array,
               .doc = "rectangles of the box faces; later ones win where they overlap",
               .default_text = "`[]`"})}};
  return s;
}

const Section<PatchKeys>& patch_keys() {
  using P = PatchKeys;
  using mesh::FaceKind;
  // A condition of one kind of patch: written for that kind only.
  const auto condition = [](KeySpec spec, FaceKind kind, auto acc) -> Field<P> {
    const fluid::PatchConditions defaults;
    spec.default_text = key_value_text(json(acc(defaults)));  // of any kind of patch
    return {
        std::move(spec),
        [kind, acc](const P& p) { return p.patch.kind == kind ? json(acc(p.conditions)) : json(); },
        [acc](P& p, const json& v) { acc(p.conditions) = v.get<double>(); }};
  };
  static const Section<P> s{
      "fluid.domain.patches[]",
      "a rectangle of one box side and its boundary condition",
      {name_row<P>(
           "unique", "patch<i>", true, [](auto& t) -> auto& { return t.patch.name; }),
       bind_enum<P>(
           {.key = "kind", .doc = "the boundary condition", .required = true},
           k_boundary_kind_names, [](auto& t) -> auto& { return t.patch.kind; }),
       bind_enum<P>(
           {.key = "side", .doc = "the box side", .required = true}, k_side_names,
           [](auto& t) -> auto& { return t.patch.side; }),
       bind<P>(
           {.key = "lo",
            .type = KeyType::Vec2,
            .doc = "in the side's two other coordinates in increasing axis order (side +-y: "
                   "(x, z)); lo < hi, overlapping the face",
            .unit = "m",
            .required = true},
           [](auto& t) -> auto& { return t.patch.lo; }),
       bind<P>(
           {.key = "hi",
            .type = KeyType::Vec2,
            .doc = "the rectangle's high corner",
            .unit = "m",
            .required = true},
           [](auto& t) -> auto& { return t.patch.hi; }),
       condition(
           {.key = "speed",
            .type = KeyType::Number,
            .doc = "inflow only: into the box (flux = speed x rectangle area)",
            .unit = "m/s",
            .range = k_non_negative,
            .note = "m/s into the domain"},
           FaceKind::Inflow, [](auto& c) -> auto& { return c.inflow_speed; }),
       condition(
           {.key = "smoke",
            .type = KeyType::Number,
            .doc = "inflow only: emitted smoke density",
            .unit = "kg/m^3",
            .range = k_non_negative},
           FaceKind::Inflow, [](auto& c) -> auto& { return c.smoke_density; }),
       {{.key = "temperature",
         .type = KeyType::Number,
         .doc = "inflow only: emitted temperature",
         .unit = "K",
         .default_text = "ambient"},
        [](const P& p) {
          const auto& c = p.conditions;
          return p.patch.kind == FaceKind::Inflow && c.emits_temperature ? json(c.temperature)
                                                                         : json();
        },
        [](P& p, const json& v) {
          p.conditions.temperature = v.get<double>();
          p.conditions.emits_temperature = true;
        }},
       condition(
           {.key = "pressure",
            .type = KeyType::Number,
            .doc = "open only: the pressure above the hydrostatic one",
            .unit = "Pa"},
           FaceKind::Open, [](auto& c) -> auto& { return c.pressure; })}};
  return s;
}

const Section<mesh::Sizing>& fluid_mesh_keys() {
  using Z = mesh::Sizing;
  static const Section<Z> s{
      "fluid.mesh",
      "cell size: surface_size at the solids, + grading x distance, at most far_size",
      {bind<Z>({.key = "surface_size",
                .type = KeyType::Number,
                .doc = "at the solids; <= far_size",
                .unit = "m",
                .range = k_positive},
               TETFSI_AT(surface_size)),
       bind<Z>({.key = "far_size",
                .type = KeyType::Number,
                .doc = "the largest",
                .unit = "m",
                .range = k_positive},
               TETFSI_AT(far_size)),
       bind<Z>({.key = "grading",
                .type = KeyType::Number,
                .doc = "growth of the size with the distance from the solids",
                .range = k_positive,
                .note = "m of cell size per m of distance"},
               TETFSI_AT(grading)),
       bind<Z>({.key = "max_cells",
                .type = KeyType::Integer,
                .doc = "> 0: all sizes scaled up to stay within this many cells",
                .range = k_non_negative,
                .note = "0: no budget"},
               TETFSI_AT(max_cells)),
       bind<Z>({.key = "local_recovery",
                .type = KeyType::Boolean,
                .doc = "each conformity recovery round re-examines only what the last one "
                       "changed; false: every cell at the solids (the same mesh, slower: a "
                       "cross-check)"},
               TETFSI_AT(local_recovery)),
       bind<Z>({.key = "incremental",
                .type = KeyType::Boolean,
                .doc = "each remesh starts from the last step's triangulation, removing the "
                       "vertices that moved and inserting the new ones; false: a new Delaunay "
                       "every step (the same mesh, bit for bit)"},
               TETFSI_AT(incremental)),
       bind<Z>({.key = "incremental_max_cost",
                .type = KeyType::Number,
                .doc = "the incremental path is taken while its estimated cost, (2 x "
                       "vertices removed + vertices inserted) / vertices, is at most this; a "
                       "full rebuild costs 1",
                .range = k_non_negative,
                .note = "a removal costs about 2 insertions (measured)"},
               TETFSI_AT(incremental_max_cost)),
       bind<Z>({.key = "parallel_insertion",
                .type = KeyType::Boolean,
                .doc = "a full Delaunay (the first remesh, a rebuild) inserts its points with "
                       "CGAL's parallel insertion on the threads; the same mesh, bit for bit "
                       "(off: measured slower on 2 cores)"},
               TETFSI_AT(parallel_insertion))}};
  return s;
}

const Section<GridKeys>& fluid_grid_keys() {
  using G = GridKeys;
  static const Section<G> s{
      "fluid.grid",
      "fluid.discretization grid: cells over fluid.domain; give cell_size or cells",
      {{{.key = "cell_size",
         .type = KeyType::Number,
         .doc = "about this size: round(box length / cell_size) cells per axis",
         .unit = "m",
         .range = k_positive,
         .default_text = "from cells"},
        [](const G& g) { return g.cell_size > 0 ? json(g.cell_size) : json(); },
        [](G& g, const json& v) { g.cell_size = v.get<double>(); }},
       bind<G>({.key = "cells",
                .type = KeyType::Cells,
                .doc = "per axis (with cell_size: must agree with it)",
                .range = k_count,
                .default_text = "from cell_size"},
               TETFSI_AT(cells)),
       bind<G>({.key = "max_cells",
                .type = KeyType::Integer,
                .doc = "a larger grid is refused",
                .range = k_count},
               TETFSI_AT(max_cells)),
       bind_enum<G>({.key = "pressure_forces",
                     .doc = "J: consistent (V D1 H)^T, symmetric; paper: quadrature on the "
                            "triangles [Chentanez06, S3.4]"},
                    coupling::k_grid_pressure_forces_names, TETFSI_AT(pressure_forces))}};
  return s;
}

const Section<fluid::FluidParams>& buoyancy_keys() {
  using F = fluid::FluidParams;
  static const Section<F> s{
      "fluid.buoyancy",
      "f = (-alpha smoke + beta (T - ambient_temperature)) up [Fedkiw01, Eq. (8)]",
      {bind<F>({.key = "alpha",
                .type = KeyType::Number,
                .doc = "smoke weight",
                .unit = "m^4/(kg s^2)",
                .range = k_non_negative},
               TETFSI_AT(buoyancy_alpha)),
       bind<F>({.key = "beta",
                .type = KeyType::Number,
                .doc = "heat lift",
                .unit = "m/(s^2 K)",
                .range = k_non_negative},
               TETFSI_AT(buoyancy_beta)),
       bind<F>({.key = "ambient_temperature",
                .type = KeyType::Number,
                .doc = "the temperature that neither rises nor sinks",
                .unit = "K"},
               TETFSI_AT(ambient_temperature))}};
  return s;
}

const Section<fluid::FluidParams>& decay_keys() {
  using F = fluid::FluidParams;
  static const Section<F> s{"fluid.decay",
                            "dissipation per second",
                            {bind<F>({.key = "smoke",
                                      .type = KeyType::Number,
                                      .doc = "of the smoke density",
                                      .unit = "1/s",
                                      .range = k_non_negative},
                                     TETFSI_AT(smoke_decay)),
                             bind<F>({.key = "temperature",
                                      .type = KeyType::Number,
                                      .doc = "of T - ambient",
                                      .unit = "1/s",
                                      .range = k_non_negative},
                                     TETFSI_AT(temperature_decay))}};
  return s;
}

const Section<fluid::FluidParams>& transfer_keys() {
  using F = fluid::FluidParams;
  static const Section<F> s{
      "fluid.transfer",
      "advection from mesh to mesh (docs/method/tet_fluid.md, transfer)",
      {bind_enum<F>({.key = "scalars",
                     .doc = "smoke density and temperature: first order, or second order clamped"},
                    fluid::k_transfer_scheme_names, TETFSI_AT(scalar_transfer)),
       bind_enum<F>(
           {.key = "velocity", .doc = "the face velocities: first order, or second order clamped"},
           fluid::k_transfer_scheme_names, TETFSI_AT(velocity_transfer)),
       bind_enum<F>({.key = "scalar_interpolation",
                     .doc = "how smoke and temperature are read at a traced point: linear "
                            "between fitted vertex values, or quadratic vertex jets (sharper)"},
                    fluid::k_scalar_interpolation_names, TETFSI_AT(scalar_interpolation)),
       bind<F>({.key = "pressure_along_path",
                .type = KeyType::Boolean,
                .doc = "the old pressure's acceleration at each back-trace's midpoint"},
               TETFSI_AT(pressure_along_path))}};
  return s;
}

const Section<fluid::FluidParams>& fluid_solver_keys() {
  using F = fluid::FluidParams;
  static const Section<F> s{
      "fluid.solver",
      "the pressure solve (docs/method/linear_solvers.md)",
      {bind_enum<F>({.key = "linear",
                     .doc = "the backend; `pfmg`, hypre's structured multigrid, on the grid only",
                     .default_text = "`amg`; grid: `pfmg`"},
                    k_solver_kind_names, TETFSI_AT(solver)),
       rel_tol_row<F>("relative residual", &F::solver_rel_tol),
       max_iterations_row<F>("iterations before the solve fails", &F::solver_max_iterations)}};
  return s;
}

const Section<fluid::SmokeSource>& source_keys() {
  using S = fluid::SmokeSource;
  static const Section<S> s{
      "fluid.sources[]",
      "a box whose cells are set to its smoke (and temperature) every step",
      {name_row<S>("unique", "source<i>", true, TETFSI_AT(name)),
       sub<S>({.key = "box",
               .type = KeyType::Object,
               .doc = "lo < hi, overlapping the fluid box",
               .required = true}),
       bind<S>({.key = "smoke",
                .type = KeyType::Number,
                .doc = "smoke density set",
                .unit = "kg/m^3",
                .range = k_non_negative},
               TETFSI_AT(smoke_density)),
       {{.key = "temperature",
         .type = KeyType::Number,
         .doc = "temperature set",
         .unit = "K",
         .default_text = "none (left alone)"},
        [](const S& t) { return t.emits_temperature ? json(t.temperature) : json(); },
        [](S& t, const json& v) {
          t.temperature = v.get<double>();
          t.emits_temperature = true;
        }}}};
  return s;
}

const Section<BoxSpec>& source_box_keys() {
  static const Section<BoxSpec> s{
      "fluid.sources[].box",
      "lo < hi",
      {lo_row<BoxSpec>("low corner", k_self), hi_row<BoxSpec>("high corner", k_self)}};
  return s;
}

const Section<fluid::LiquidParams>& liquid_keys() {
  using L = fluid::LiquidParams;
  static const Section<L> s{
      "fluid.liquid",
      "a liquid with a free surface (fluid.discretization grid): FLIP particles, p = 0 in the air",
      {sub<L>({.key = "regions",
               .type = KeyType::Array,
               .doc = "where the liquid is at the start: boxes and spheres",
               .default_text = "`[]`"}),
       sub<L>({.key = "sources",
               .type = KeyType::Array,
               .doc = "boxes kept full of liquid moving at a velocity",
               .default_text = "`[]`"}),
       bind<L>({.key = "flip",
                .type = KeyType::Number,
                .doc = "FLIP share of the particles' velocity update; 0: PIC (more damping)",
                .range = between(0, 1)},
               TETFSI_AT(flip)),
       bind<L>(
           {.key = "density_correction",
            .type = KeyType::Number,
            .doc = "share of a deep cell's particle-density error (beyond 10 %) the "
                   "projection corrects per step; 0: off (docs/method/liquids.md: when to use it)",
            .range = between(0, 1)},
           TETFSI_AT(density_correction)),
       bind<L>({.key = "hold_volume",
                .type = KeyType::Boolean,
                .doc = "shift the level set each step so that it holds the volume the particles "
                       "carry (stats.csv: liquid_shift); false: as the particles give it"},
               TETFSI_AT(hold_volume)),
       bind<L>({.key = "particles_per_axis",
                .type = KeyType::Integer,
                .doc = "particles seeded per cell and axis (2: 8 per cell)",
                .range = between(1, 4)},
               TETFSI_AT(particles_per_axis))}};
  return s;
}

const Section<fluid::LiquidRegion>& liquid_region_keys() {
  using R = fluid::LiquidRegion;
  static const Section<R> s{
      "fluid.liquid.regions[]",
      "liquid inside a box, a sphere or a closed surface; where two or three are given, inside "
      "all of them",
      {name_row<R>("names it in messages", "region<i>", true, TETFSI_AT(name)),
       sub<R>({.key = "box", .type = KeyType::Object, .doc = "lo < hi"}),
       sub<R>({.key = "sphere", .type = KeyType::Object, .doc = "center and radius"}),
       {{.key = "surface",
         .type = KeyType::File,
         .doc = "a closed surface (.off .obj .stl) in the scene's coordinates (m)",
         .default_text = "-"},
        [](const R& r) { return r.surface ? json(r.surface_file.string()) : json(); },
        [](R& r, const json& v) { r.surface_file = v.get<std::string>(); }}}};
  return s;
}

const Section<BoxSpec>& liquid_box_keys(bool source) {
  static const Section<BoxSpec> region{
      "fluid.liquid.regions[].box",
      "lo < hi",
      {lo_row<BoxSpec>("low corner", k_self), hi_row<BoxSpec>("high corner", k_self)}};
  static const Section<BoxSpec> nozzle{
      "fluid.liquid.sources[].box",
      "lo < hi",
      {lo_row<BoxSpec>("low corner", k_self), hi_row<BoxSpec>("high corner", k_self)}};
  return source ? nozzle : region;
}

const Section<fluid::LiquidRegion>& liquid_sphere_keys() {
  using R = fluid::LiquidRegion;
  static const Section<R> s{
      "fluid.liquid.regions[].sphere",
      "a ball of liquid",
      {bind<R>(
           {.key = "center", .type = KeyType::Vec3, .doc = "centre", .unit = "m", .required = true},
           TETFSI_AT(centre)),
       bind<R>({.key = "radius",
                .type = KeyType::Number,
                .doc = "radius",
                .unit = "m",
                .range = k_positive,
                .required = true},
               TETFSI_AT(radius))}};
  return s;
}

const Section<fluid::LiquidSource>& liquid_source_keys() {
  using S = fluid::LiquidSource;
  static const Section<S> s{
      "fluid.liquid.sources[]",
      "a nozzle: its box is kept full of liquid moving at velocity from start to stop",
      {name_row<S>("unique", "source<i>", true, TETFSI_AT(name)),
       sub<S>({.key = "box",
               .type = KeyType::Object,
               .doc = "lo < hi, inside the fluid box",
               .required = true}),
       bind<S>({.key = "velocity",
                .type = KeyType::Vec3,
                .doc = "of the emitted liquid",
                .unit = "m/s"},
               TETFSI_AT(velocity)),
       bind<S>({.key = "start",
                .type = KeyType::Number,
                .doc = "when it opens",
                .unit = "s",
                .range = k_non_negative},
               TETFSI_AT(start)),
       {{.key = "stop",
         .type = KeyType::Number,
         .doc = "when it closes; > start",
         .unit = "s",
         .range = k_non_negative,
         .default_text = "never"},
        [](const S& t) { return std::isfinite(t.stop) ? json(t.stop) : json(); },
        [](S& t, const json& v) { t.stop = v.get<double>(); }}}};
  return s;
}

const Section<fluid::RefineParams>& refine_keys() {
  using R = fluid::RefineParams;
  static const Section<R> s{
      "fluid.refine",
      "where the remesher refines for the fluid",
      {bind<R>({.key = "size",
                .type = KeyType::Number,
                .doc = "target edge where smoke or vorticity is significant; 0: off; <= "
                       "mesh.far_size",
                .unit = "m",
                .range = k_non_negative,
                .note = "m; 0: off"},
               TETFSI_AT(size)),
       bind<R>({.key = "density_threshold",
                .type = KeyType::Number,
                .doc = "smoke density above which a cell counts",
                .unit = "kg/m^3",
                .range = k_non_negative},
               TETFSI_AT(density_threshold)),
       bind<R>({.key = "vorticity_threshold",
                .type = KeyType::Number,
                .doc = "|curl u| above which a cell counts; 0: ignore",
                .unit = "1/s",
                .range = k_non_negative},
               TETFSI_AT(vorticity_threshold))}};
  return s;
}

/// coupling.scheme's values: the two-way schemes, then "none" (one-way).
std::vector<std::string> with_none(std::vector<std::string> names) {
  names.emplace_back("none");
  return names;
}

const Section<CouplingSpec>& coupling_keys() {
  using C = CouplingSpec;
  static const Section<C> s{
      "coupling",
      "fluid scenes: how the fluid and the bodies interact (a static scene ignores it)",
      {{{.key = "scheme",
         .type = KeyType::String,
         .doc = "two-way: `simultaneous` [Chentanez06], `splitting`, or the coupled step "
                "iterated with the solid.* tolerances (`bfgs`, `modified_newton`, `newton`: "
                "every fluid region a deformable body touches needs an open face); `none`: "
                "one-way",
         .choices = with_none(coupling::k_scheme_names.names()),
         .choice_what = "coupling scheme",
         .default_text = "`simultaneous` (a dynamic scene with a deformable body), else `none`"},
        [](const C& c) { return json(c.scheme_name()); },
        [](C& c, const json& v) {
          const std::string name = v.get<std::string>();
          c.two_way = name != "none";
          if (c.two_way) c.params.scheme = coupling::parse_scheme(name);
        }},
       {{.key = "solver",
         .type = KeyType::String,
         .doc = "the coupled solve",
         .choices = coupling::k_coupled_solver_names.names(),
         .choice_what = "coupled solver"},
        [](const C& c) { return json(coupling::to_string(c.params.solve.solver)); },
        [](C& c, const json& v) {
          c.params.solve.solver = coupling::parse_coupled_solver(v.get<std::string>());
        }},
       {{.key = "rel_tol",
         .type = KeyType::Number,
         .doc = "the coupled solve's relative residual",
         .range = k_positive},
        [](const C& c) { return json(c.params.solve.rel_tol); },
        [](C& c, const json& v) { c.params.solve.rel_tol = v.get<double>(); }},
       {{.key = "max_iterations",
         .type = KeyType::Integer,
         .doc = "of the coupled solve",
         .range = k_count},
        [](const C& c) { return json(c.params.solve.max_iterations); },
        [](C& c, const json& v) { c.params.solve.max_iterations = v.get<int>(); }},
       {{.key = "conserve_volume",
         .type = KeyType::Boolean,
         .doc = "enclosed liquids keep their volume exactly"},
        [](const C& c) { return json(c.params.solve.conserve_volume); },
        [](C& c, const json& v) { c.params.solve.conserve_volume = v.get<bool>(); }},
       {{.key = "interface_mass",
         .type = KeyType::Boolean,
         .doc = "tet fluid: the fluid between a body and the first circumcentres moves with the "
                "body (its kinetic energy counted, with the spreading of a curved body's "
                "normals: the added mass unbiased); false: the paper's form"},
        [](const C& c) { return json(c.params.solve.interface_mass); },
        [](C& c, const json& v) { c.params.solve.interface_mass = v.get<bool>(); }},
       {{.key = "grid_multigrid",
         .type = KeyType::Boolean,
         .doc = "grid fluid, `schur_amg`: precondition with hypre's structured multigrid "
                "(PFMG) instead of BoomerAMG"},
        [](const C& c) { return json(c.params.solve.grid_multigrid); },
        [](C& c, const json& v) { c.params.solve.grid_multigrid = v.get<bool>(); }}}};
  return s;
}

#undef TETFSI_AT

// ---------------------------------------------------------------------------------------------
// The tables as documentation.

namespace {

std::string range_text(const KeySpec& k) {
  if (!k.choices.empty()) {
    std::string out;
    for (const auto& c : k.choices) out += (out.empty() ? "" : ", ") + ("`" + c + "`");
    return out;
  }
  if (k.type == KeyType::Cells) return ">= 1 each";
  if (k.type == KeyType::Nodes) return ">= 0 each";
  if (k.non_empty) return "not empty";
  const std::string r = k.limits().text(k.type == KeyType::Integer);
  if (!r.empty() && (k.type == KeyType::Vec2 || k.type == KeyType::Vec3)) return r + " each";
  return r;
}

template <class T>
KeySection rows_of(const Section<T>& s) {
  KeySection out{s.path, s.title, {}, s.variant};
  const T defaults = T();
  for (const auto& f : s.fields) {
    std::string d = f.spec.default_text;
    if (d.empty()) d = f.spec.required ? "required" : f.get ? key_value_text(f.get(defaults)) : "";
    out.rows.push_back({f.spec, d});
  }
  return out;
}

std::string full_key(const KeySection& s, const KeyRow& r) {
  return s.path.empty() ? r.spec.key : s.path + "." + r.spec.key;
}

std::string cell(std::string s) {
  std::string out;
  for (char c : s) out += c == '|' ? std::string("\\|") : std::string(1, c);
  return out;
}

}  // namespace

std::string key_value_text(const json& v) {
  switch (v.type()) {
    case json::value_t::null:
      return "-";
    case json::value_t::string:
      return "`" + v.get<std::string>() + "`";
    case json::value_t::boolean:
      return v.get<bool>() ? "true" : "false";
    case json::value_t::array: {
      std::string out = "[";
      for (std::size_t i = 0; i < v.size(); ++i) out += (i ? ", " : "") + key_value_text(v[i]);
      return out + "]";
    }
    case json::value_t::number_float:
      return bound_text(v.get<double>());
    default:
      return v.dump();
  }
}

const std::vector<KeySection>& scene_key_sections() {
  static const std::vector<KeySection> sections = {rows_of(top_level_keys()),
                                                   rows_of(time_keys()),
                                                   rows_of(output_keys()),
                                                   rows_of(solver_keys()),
                                                   rows_of(solid_keys()),
                                                   rows_of(static_keys()),
                                                   rows_of(contact_keys()),
                                                   rows_of(body_keys()),
                                                   rows_of(mesh_keys()),
                                                   rows_of(mesh_box_keys()),
                                                   rows_of(mesh_sphere_keys()),
                                                   rows_of(mesh_shell_keys()),
                                                   rows_of(mesh_hollow_box_keys()),
                                                   rows_of(mesh_tube_keys()),
                                                   rows_of(mesh_bowl_keys()),
                                                   rows_of(transform_keys()),
                                                   rows_of(material_keys()),
                                                   rows_of(pin_keys()),
                                                   rows_of(load_keys()),
                                                   rows_of(selection_box_keys()),
                                                   rows_of(kinematic_keys()),
                                                   rows_of(plane_obstacle_keys()),
                                                   rows_of(box_obstacle_keys()),
                                                   rows_of(fluid_keys()),
                                                   rows_of(domain_keys()),
                                                   rows_of(patch_keys()),
                                                   rows_of(fluid_mesh_keys()),
                                                   rows_of(fluid_grid_keys()),
                                                   rows_of(buoyancy_keys()),
                                                   rows_of(decay_keys()),
                                                   rows_of(transfer_keys()),
                                                   rows_of(fluid_solver_keys()),
                                                   rows_of(source_keys()),
                                                   rows_of(source_box_keys()),
                                                   rows_of(refine_keys()),
                                                   rows_of(liquid_keys()),
                                                   rows_of(liquid_region_keys()),
                                                   rows_of(liquid_box_keys(false)),
                                                   rows_of(liquid_sphere_keys()),
                                                   rows_of(liquid_source_keys()),
                                                   rows_of(liquid_box_keys(true)),
                                                   rows_of(coupling_keys())};
  return sections;
}

std::string section_name(const KeySection& s) {
  const std::string name = s.path.empty() ? "(top level)" : s.path;
  return s.variant.empty() ? name : name + " (" + s.variant + ")";
}

std::string section_markdown(const KeySection& s) {
  const std::string name = section_name(s);
  std::string out = fmt::format("<!-- keys:begin {} -->\n**`{}`**: {}\n\n", name, name, s.title);
  out += "| key | type | default | range | unit | meaning |\n|---|---|---|---|---|---|\n";
  for (const KeyRow& r : s.rows) {
    out += fmt::format("| `{}` | {} | {} | {} | {} | {} |\n", full_key(s, r),
                       cell(to_string(r.spec.type)), cell(r.default_text), cell(range_text(r.spec)),
                       cell(r.spec.unit), cell(r.spec.doc));
  }
  return out + "\n<!-- keys:end -->\n";
}

std::string scene_keys_markdown() {
  std::string out;
  for (const KeySection& s : scene_key_sections()) {
    if (!out.empty()) out += '\n';
    out += section_markdown(s);
  }
  return out;
}

std::string scene_keys_text() {
  const auto plain = [](std::string t) {  // without markdown's backticks
    t.erase(std::remove(t.begin(), t.end(), '`'), t.end());
    return t;
  };
  std::string out;
  for (const KeySection& s : scene_key_sections()) {
    std::vector<std::array<std::string, 6>> lines = {
        {"key", "type", "default", "range", "unit", "meaning"}};
    for (const KeyRow& r : s.rows)
      lines.push_back({full_key(s, r), to_string(r.spec.type), plain(r.default_text),
                       plain(range_text(r.spec)), r.spec.unit, plain(r.spec.doc)});
    std::array<std::size_t, 5> width{};
    for (const auto& l : lines)
      for (std::size_t c = 0; c < width.size(); ++c) width[c] = std::max(width[c], l[c].size());
    if (!out.empty()) out += '\n';
    out += fmt::format("{}: {}\n", section_name(s), plain(s.title));
    for (const auto& l : lines) {
      std::string line = "  ";
      for (std::size_t c = 0; c < width.size(); ++c)
        line += fmt::format("{:<{}}  ", l[c], width[c]);
      out += line + l[5] + "\n";
    }
  }
  return out;
}

}  // namespace tetfsi::app
