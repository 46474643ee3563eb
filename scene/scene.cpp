#include "scene/scene.hpp"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <limits>
#include <memory>
#include <set>
#include <sstream>

#include <fmt/format.h>
#include <Eigen/Geometry>

#include "core/error.hpp"
#include "core/linear_solver.hpp"
#include "core/log.hpp"
#include "mesh/generate.hpp"
#include "mesh/io.hpp"
#include "mesh/tetrahedralize.hpp"
#include "scene/scene_keys.hpp"
#include "solid/integrator.hpp"

namespace tetfsi::app {

using nlohmann::json;
namespace fs = std::filesystem;

int TimeSpec::num_steps() const {
  if (steps) return *steps;
  const double n = std::ceil(end_time.value_or(1.0) / dt - 1e-9);
  return static_cast<int>(std::clamp(n, 1.0, static_cast<double>(std::numeric_limits<int>::max())));
}

namespace {

// ---------------------------------------------------------------------------------------------
// Small helpers shared by parsing and building.

/// The name a scene goes by in messages: the path as the caller gave it.
std::string display_name(const fs::path& file) {
  return file.empty() ? std::string("<scene>") : file.string();
}

/// Levenshtein distance (for "did you mean").
std::size_t edit_distance(const std::string& a, const std::string& b) {
  std::vector<std::size_t> prev(b.size() + 1), cur(b.size() + 1);
  for (std::size_t j = 0; j <= b.size(); ++j) prev[j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i) {
    cur[0] = i;
    for (std::size_t j = 1; j <= b.size(); ++j) {
      const std::size_t subst = prev[j - 1] + (a[i - 1] == b[j - 1] ? 0 : 1);
      cur[j] = std::min({prev[j] + 1, cur[j - 1] + 1, subst});
    }
    std::swap(prev, cur);
  }
  return prev[b.size()];
}

/// The closest of `candidates` to `word`, if close enough to be a likely typo.
std::optional<std::string> closest(const std::string& word,
                                   const std::vector<std::string>& candidates) {
  std::optional<std::string> best;
  std::size_t best_d = std::max<std::size_t>(1, word.size() / 3) + 1;
  for (const auto& c : candidates) {
    const std::size_t d = edit_distance(word, c);
    if (d < best_d) {
      best_d = d;
      best = c;
    }
  }
  return best;
}

std::string join(const std::vector<std::string>& v, const std::string& sep = ", ") {
  std::string out;
  for (std::size_t i = 0; i < v.size(); ++i) out += (i ? sep : "") + v[i];
  return out;
}

/// "string \"abc\"", "number 3", "array [1,2]": what a value is, for "expected X, got Y".
std::string describe(const json& j) {
  std::string text = j.dump();
  if (text.size() > 40) text = text.substr(0, 37) + "...";
  switch (j.type()) {
    case json::value_t::null:
      return "null";
    case json::value_t::boolean:
      return "boolean " + text;
    case json::value_t::string:
      return "string " + text;
    case json::value_t::array:
      return "array " + text;
    case json::value_t::object:
      return "object " + text;
    case json::value_t::number_float:
      if (!std::isfinite(j.get<double>())) return fmt::format("number {}", j.get<double>());
      return "number " + text;
    default:
      return "number " + text;
  }
}

std::string fmt_vec2(const Vec2& v) {
  return fmt::format("[{:.6g}, {:.6g}]", v.x(), v.y());
}

/// The two axes of a box side's plane, in increasing order (side ±y: x, z).
std::pair<int, int> side_axes(int side) {
  const int a = side / 2;
  return {a == 0 ? 1 : 0, a == 2 ? 1 : 2};
}

json to_json(const Vec3& v) {
  return json::array({v.x(), v.y(), v.z()});
}

// ---------------------------------------------------------------------------------------------
// The parser: a JSON value plus its path, typed getters that throw InputError naming both, and
// `read`, which checks an object against its section of scene_keys.hpp and stores its values.

class Parser {
 public:
  explicit Parser(const fs::path& file) : m_file(display_name(file)) {
    m_folder = file.empty() ? fs::current_path() : fs::absolute(file).parent_path();
  }

  struct Node {
    const json& j;
    std::string path;  ///< "bodies[0].material"; empty for the top level
  };

  [[noreturn]] void fail(const std::string& path, const std::string& problem) const {
    throw InputError(
        fmt::format("{}: {}: {}", m_file, path.empty() ? "(top level)" : path, problem));
  }

  static std::string child_path(const std::string& path, const std::string& key) {
    return path.empty() ? key : path + "." + key;
  }
  static std::string index_path(const std::string& path, std::size_t i) {
    return fmt::format("{}[{}]", path, i);
  }

  /// Check `n` is an object whose keys are all in `allowed`.
  void expect_object(const Node& n, const std::vector<std::string>& allowed) const {
    if (!n.j.is_object()) fail(n.path, "expected an object, got " + describe(n.j));
    for (const auto& [key, value] : n.j.items()) {
      if (std::find(allowed.begin(), allowed.end(), key) != allowed.end()) continue;
      if (auto guess = closest(key, allowed)) {
        fail(child_path(n.path, key), fmt::format("unknown key (did you mean '{}'?)", *guess));
      }
      fail(child_path(n.path, key),
           fmt::format("unknown key (valid keys here: {})", join(allowed)));
    }
  }

  static bool has(const Node& n, const std::string& key) { return n.j.contains(key); }
  static Node child(const Node& n, const std::string& key) {
    return {n.j.at(key), child_path(n.path, key)};
  }

  /// Check `n` against `section` (unknown keys, types, ranges, required keys) and store the
  /// values of the rows that have a `set` in `t`; the Object / Array rows are the caller's.
  template <class T>
  void read(const Node& n, const Section<T>& section, T& t) const {
    expect_object(n, section.keys());
    for (const Field<T>& f : section.fields) {
      if (!has(n, f.spec.key)) {
        if (f.spec.required && f.set)
          fail(n.path, fmt::format("missing required key '{}'", f.spec.key));
        continue;
      }
      if (f.set) f.set(t, value(child(n, f.spec.key), f.spec));
    }
  }

  /// The value at `n` checked against its row: type, choices, non-empty, range or check.
  json value(const Node& n, const KeySpec& k) const {
    json v;
    switch (k.type) {
      case KeyType::Number:
        v = number(n);
        break;
      case KeyType::Integer:
        v = integer(n);
        break;
      case KeyType::Boolean:
        if (!n.j.is_boolean()) fail(n.path, "expected true or false, got " + describe(n.j));
        v = n.j.get<bool>();
        break;
      case KeyType::String:
        v = k.choices.empty() ? string(n) : choice(n, k.choices, k.choice_what);
        if (k.non_empty && v.get<std::string>().empty()) fail(n.path, "must not be empty");
        break;
      case KeyType::Vec2: {
        const Vec2 x = vec2(n);
        v = json::array({x.x(), x.y()});
        break;
      }
      case KeyType::Vec3:
        v = to_json(vec3(n));
        break;
      case KeyType::Cells: {
        const Vec3i c = cells(n);
        v = json::array({c.x(), c.y(), c.z()});
        break;
      }
      case KeyType::Nodes:
        v = node_list(n);
        break;
      case KeyType::Names:
        v = name_list(n, k);
        break;
      case KeyType::File:
        v = existing_file(n).string();
        break;
      case KeyType::Object:
      case KeyType::Array:
        throw InternalError(fmt::format("{}: read by its own section", n.path));
    }
    if (k.check) {
      const std::string problem = k.check(v);
      if (!problem.empty()) fail(n.path, problem);
    } else if (v.is_number()) {
      check_range(n.path, k, v);
    } else if (v.is_array() && (k.type == KeyType::Vec2 || k.type == KeyType::Vec3)) {
      for (size_t a = 0; a < v.size(); ++a) check_range(index_path(n.path, a), k, v[a]);
    }
    return v;
  }

  /// A number within the row's limits (its range within what its unit allows).
  void check_range(const std::string& path, const KeySpec& k, const json& v) const {
    const Range r = k.limits();
    if (r.contains(v.get<double>())) return;
    const std::string note = k.note.empty() ? k.unit : k.note;
    const std::string got = k.type == KeyType::Integer ? fmt::format("{}", v.get<int>())
                                                       : fmt::format("{}", v.get<double>());
    fail(path, fmt::format("must be {}{}, got {}", r.text(k.type == KeyType::Integer),
                           note.empty() ? "" : " (" + note + ")", got));
  }

  double number(const Node& n) const {
    if (!n.j.is_number()) fail(n.path, "expected a number, got " + describe(n.j));
    const double v = n.j.get<double>();
    if (!std::isfinite(v)) fail(n.path, "expected a finite number, got " + describe(n.j));
    return v;
  }

  int integer(const Node& n) const {
    if (!n.j.is_number()) fail(n.path, "expected an integer, got " + describe(n.j));
    const double v = n.j.get<double>();
    if (!std::isfinite(v) || v != std::floor(v))
      fail(n.path, "expected an integer, got " + describe(n.j));
    if (std::abs(v) > std::numeric_limits<int>::max())
      fail(n.path, "integer out of range: " + n.j.dump());
    return static_cast<int>(v);
  }

  std::string string(const Node& n) const {
    if (!n.j.is_string()) fail(n.path, "expected a string, got " + describe(n.j));
    return n.j.get<std::string>();
  }

  /// A string that must be one of `choices`.
  std::string choice(const Node& n, const std::vector<std::string>& choices,
                     const std::string& what) const {
    const std::string s = string(n);
    if (std::find(choices.begin(), choices.end(), s) != choices.end()) return s;
    std::string problem = fmt::format("unknown {} '{}'", what, s);
    if (auto guess = closest(s, choices))
      problem += fmt::format(" (did you mean '{}'?)", *guess);
    else
      problem += fmt::format(" (valid: {})", join(choices));
    fail(n.path, problem);
  }

  Vec3 vec3(const Node& n) const {
    if (!n.j.is_array() || n.j.size() != 3)
      fail(n.path, "expected an array of 3 numbers, got " + describe(n.j));
    Vec3 v;
    for (int a = 0; a < 3; ++a) v[a] = number({n.j[a], index_path(n.path, a)});
    return v;
  }

  Vec2 vec2(const Node& n) const {
    if (!n.j.is_array() || n.j.size() != 2)
      fail(n.path, "expected an array of 2 numbers, got " + describe(n.j));
    Vec2 v;
    for (int a = 0; a < 2; ++a) v[a] = number({n.j[a], index_path(n.path, a)});
    return v;
  }

  /// An array of 3 positive integers (cell counts).
  Vec3i cells(const Node& c) const {
    if (!c.j.is_array() || c.j.size() != 3)
      fail(c.path, "expected an array of 3 positive integers, got " + describe(c.j));
    Vec3i out;
    for (int a = 0; a < 3; ++a) {
      const Node e{c.j[a], index_path(c.path, a)};
      out[a] = integer(e);
      if (out[a] < 1)
        fail(e.path, fmt::format("cell counts must be positive integers, got {}", out[a]));
    }
    return out;
  }

  /// A non-empty array of node indices >= 0.
  json node_list(const Node& list) const {
    if (!list.j.is_array() || list.j.empty())
      fail(list.path, "expected a non-empty array of node indices, got " + describe(list.j));
    json out = json::array();
    for (std::size_t i = 0; i < list.j.size(); ++i) {
      const Node e{list.j[i], index_path(list.path, i)};
      const int v = integer(e);
      if (v < 0) fail(e.path, fmt::format("node indices are >= 0, got {}", v));
      out.push_back(v);
    }
    return out;
  }

  /// An array of distinct strings, each one of the row's choices.
  json name_list(const Node& list, const KeySpec& k) const {
    if (!list.j.is_array())
      fail(list.path, fmt::format("expected an array of names ({}), got {}", join(k.choices),
                                  describe(list.j)));
    json out = json::array();
    for (std::size_t i = 0; i < list.j.size(); ++i) {
      const Node e{list.j[i], index_path(list.path, i)};
      const std::string v = choice(e, k.choices, k.choice_what);
      if (std::find(out.begin(), out.end(), json(v)) != out.end())
        fail(e.path, fmt::format("'{}' is listed twice", v));
      out.push_back(v);
    }
    return out;
  }

  Node require(const Node& n, const std::string& key) const {
    if (!has(n, key)) fail(n.path, fmt::format("missing required key '{}'", key));
    return child(n, key);
  }

  /// An array (the value of an Array row): `n` checked, each element passed to `each`.
  template <class Each>
  void for_each(const Node& list, const char* expected, Each each) const {
    if (!list.j.is_array()) fail(list.path, std::string(expected) + ", got " + describe(list.j));
    for (std::size_t i = 0; i < list.j.size(); ++i)
      each(Node{list.j[i], index_path(list.path, i)}, i);
  }

  /// A file path resolved against the scene's folder; it must exist.
  fs::path existing_file(const Node& n) const {
    const std::string s = string(n);
    if (s.empty()) fail(n.path, "expected a file name, got an empty string");
    fs::path p = fs::path(s);
    if (p.is_relative()) p = m_folder / p;
    p = p.lexically_normal();
    std::error_code ec;
    if (!fs::exists(p, ec)) fail(n.path, fmt::format("no such file '{}'", p.string()));
    if (fs::is_directory(p, ec))
      fail(n.path, fmt::format("'{}' is a folder, not a file", p.string()));
    return p;
  }

  // ---- scene parts: the sections, and the rules that tie their keys together ----

  /// lo/hi of the box at `n`: `strict`: lo < hi (a solid box), else lo <= hi (a selection box
  /// may be flat, e.g. to pick the nodes of one face).
  void check_box(const Node& n, const Vec3& lo, const Vec3& hi, bool strict) const {
    for (int a = 0; a < 3; ++a) {
      const bool bad = strict ? lo[a] >= hi[a] : lo[a] > hi[a];
      if (bad) {
        fail(n.path, fmt::format("lo must be {} hi in every axis, got lo = {}, hi = {} (axis {})",
                                 strict ? "<" : "<=", fmt_vec(lo), fmt_vec(hi), "xyz"[a]));
      }
    }
  }

  /// A box object of `section` (lo, hi) at `n`.
  BoxSpec box(const Node& n, const Section<BoxSpec>& section, bool strict) const {
    BoxSpec b;
    read(n, section, b);
    check_box(n, b.lo, b.hi, strict);
    return b;
  }

  void inner_below_outer(const Node& n, const MeshSpec& m, bool name_key) const {
    if (m.inner_radius < m.outer_radius) return;
    if (name_key) {
      fail(child_path(n.path, "inner_radius"),
           fmt::format("must be < outer_radius, got inner_radius {} and outer_radius {}",
                       m.inner_radius, m.outer_radius));
    }
    fail(n.path, fmt::format("need inner_radius < outer_radius, got {} and {}; for a solid ball "
                             "use 'sphere'",
                             m.inner_radius, m.outer_radius));
  }

  MeshSpec mesh(const Node& n) const {
    const std::vector<std::string> kinds = {"box",   "file",       "surface", "sphere",
                                            "shell", "hollow_box", "tube",    "bowl"};
    expect_object(n, mesh_keys().keys());
    std::vector<std::string> given;
    for (const std::string& k : kinds) {
      if (has(n, k)) given.push_back(fmt::format("'{}'", k));
    }
    if (given.size() != 1) {
      const std::string what =
          "give exactly one of 'box', 'file', 'surface', 'sphere', 'shell', 'hollow_box', "
          "'tube' or 'bowl'";
      fail(n.path, given.empty() ? what : what + ", got " + join(given, " and "));
    }
    MeshSpec m;
    read(n, mesh_keys(), m);  // file, surface (with their kinds), cell_size
    if (has(n, "box")) {
      m.kind = MeshSpec::Kind::Box;
      const Node b = child(n, "box");
      read(b, mesh_box_keys(), m);
      check_box(b, m.box.lo, m.box.hi, true);
    } else if (has(n, "sphere")) {
      m.kind = MeshSpec::Kind::Sphere;
      read(child(n, "sphere"), mesh_sphere_keys(), m);
    } else if (has(n, "shell")) {
      m.kind = MeshSpec::Kind::Shell;
      const Node b = child(n, "shell");
      read(b, mesh_shell_keys(), m);
      inner_below_outer(b, m, false);
    } else if (has(n, "tube")) {
      m.kind = MeshSpec::Kind::Tube;
      const Node b = child(n, "tube");
      read(b, mesh_tube_keys(), m);
      inner_below_outer(b, m, true);
      if (m.cells[1] < 6) {
        fail(index_path(child_path(b.path, "cells"), 1),
             fmt::format("must be >= 6 (sectors around the axis), got {}", m.cells[1]));
      }
    } else if (has(n, "bowl")) {
      m.kind = MeshSpec::Kind::Bowl;
      const Node b = child(n, "bowl");
      read(b, mesh_bowl_keys(), m);
      inner_below_outer(b, m, true);
      if (m.meridian_cells % 2 != 0)
        fail(child_path(b.path, "cells"),
             fmt::format("must be even (the cube sphere's face is cut in two), got {}",
                         m.meridian_cells));
    } else if (has(n, "hollow_box")) {
      m.kind = MeshSpec::Kind::HollowBox;
      const Node b = child(n, "hollow_box");
      read(b, mesh_hollow_box_keys(), m);
      check_box(b, m.box.lo, m.box.hi, true);
      for (int a = 0; a < 3; ++a) {
        if (2 * m.thickness >= m.box.hi[a] - m.box.lo[a]) {
          fail(child_path(b.path, "thickness"),
               fmt::format("two walls of {} m leave no cavity in {} (the box is {} m wide "
                           "there); use a thinner wall or a larger box",
                           m.thickness, "xyz"[a], m.box.hi[a] - m.box.lo[a]));
        }
      }
    }
    if (m.kind == MeshSpec::Kind::Surface && !has(n, "cell_size"))
      fail(n.path, "a 'surface' mesh needs 'cell_size' (> 0, m): the target tet size");
    if (m.kind != MeshSpec::Kind::Surface && has(n, "cell_size"))
      fail(child_path(n.path, "cell_size"), "cell_size applies only to a 'surface' mesh");
    return m;
  }

  /// A pin's or a load's selection: exactly one of "box" / "nodes" (the nodes are read with
  /// the rest of `n`'s section).
  void selection(const Node& n, NodeSelection& s) const {
    const bool b = has(n, "box"), l = has(n, "nodes");
    if (b == l)
      fail(n.path,
           b ? "give either 'box' or 'nodes', not both" : "give 'box' or 'nodes' to select nodes");
    if (b) s.box = box(child(n, "box"), selection_box_keys(), false);
  }

  BodySpec body(const Node& n) const {
    BodySpec b;
    read(n, body_keys(), b);  // name, initial_velocity
    b.mesh = mesh(require(n, "mesh"));
    if (has(n, "transform")) read(child(n, "transform"), transform_keys(), b.transform);
    if (has(n, "material")) read(child(n, "material"), material_keys(), b.material);
    if (has(n, "pins")) {
      for_each(child(n, "pins"), "expected an array", [&](const Node& e, std::size_t) {
        PinSpec p;
        read(e, pin_keys(), p);
        selection(e, p.select);
        b.pins.push_back(std::move(p));
      });
    }
    if (has(n, "loads")) {
      for_each(child(n, "loads"), "expected an array", [&](const Node& e, std::size_t) {
        LoadSpec l;
        read(e, load_keys(), l);
        selection(e, l.select);
        b.loads.push_back(std::move(l));
      });
    }
    if (has(n, "kinematic")) {
      read(child(n, "kinematic"), kinematic_keys(), b.kinematic.emplace());
      // Its motion is prescribed: anything that would act on it through the FEM is a mistake.
      const auto reject = [&](const char* key, const char* what) {
        fail(child_path(n.path, key),
             fmt::format("body '{}' is kinematic (moved by its 'kinematic' motion): it cannot "
                         "have {}; remove '{}' or 'kinematic'",
                         b.name, what, key));
      };
      if (!b.pins.empty()) reject("pins", "pins");
      if (!b.loads.empty()) reject("loads", "loads");
      if (!b.initial_velocity.isZero(0.0))
        reject("initial_velocity", "an initial velocity (give kinematic.velocity)");
    }
    return b;
  }

  solid::Obstacle obstacle(const Node& n, std::size_t index) const {
    if (!n.j.is_object()) fail(n.path, "expected an object, got " + describe(n.j));
    const std::string type =
        choice(require(n, "type"), k_obstacle_type_names.names(), k_obstacle_type_names.what);
    solid::Obstacle o;
    o.name = fmt::format("{}{}", type, index);
    if (type == "plane") {
      read(n, plane_obstacle_keys(), o);
    } else {
      read(n, box_obstacle_keys(), o);
      check_box(n, o.lo, o.hi, true);
    }
    return o;
  }

  /// A patch of the fluid box and what happens on it; `box` is the domain, for the overlap
  /// check.
  PatchKeys patch(const Node& n, std::size_t index, const mesh::FluidDomain& box) const {
    PatchKeys p;
    p.patch.name = fmt::format("patch{}", index);
    read(n, patch_keys(), p);
    mesh::DomainPatch& pa = p.patch;
    // Conditions: each key belongs to one kind of patch.
    const std::string kind = mesh::to_string(pa.kind);
    const auto only_on = [&](const char* key, mesh::FaceKind k) {
      if (has(n, key) && pa.kind != k)
        fail(child_path(n.path, key),
             fmt::format("applies only to an {} patch (this one is {})", mesh::to_string(k), kind));
    };
    for (const char* key : {"speed", "smoke", "temperature"}) only_on(key, mesh::FaceKind::Inflow);
    only_on("pressure", mesh::FaceKind::Open);
    const std::string side = k_side_names.name(pa.side);
    const auto [b, c] = side_axes(pa.side);
    const std::string axes = fmt::format("({}, {})", "xyz"[b], "xyz"[c]);
    for (int k = 0; k < 2; ++k) {
      if (pa.lo[k] >= pa.hi[k]) {
        fail(n.path, fmt::format("lo must be < hi in both coordinates {} of side {}, got lo = {}, "
                                 "hi = {}",
                                 axes, side, fmt_vec2(pa.lo), fmt_vec2(pa.hi)));
      }
    }
    const Vec2 face_lo(box.lo[b], box.lo[c]), face_hi(box.hi[b], box.hi[c]);
    const bool overlaps =
        (pa.lo.array() < face_hi.array()).all() && (pa.hi.array() > face_lo.array()).all();
    if (!overlaps) {
      fail(n.path, fmt::format("the rectangle {}..{} misses side {} of the fluid box, which spans "
                               "{} {}..{}",
                               fmt_vec2(pa.lo), fmt_vec2(pa.hi), side, axes, fmt_vec2(face_lo),
                               fmt_vec2(face_hi)));
    }
    // The nominal area: the rectangle clipped to the box side. The fluid scales the inflow so
    // that the flux is speed × this area whatever faces the mesh puts on the patch.
    p.conditions.area = (pa.hi.cwiseMin(face_hi) - pa.lo.cwiseMax(face_lo)).prod();
    return p;
  }

  /// A volume source of smoke and heat; `domain` is the fluid box, for the overlap check.
  fluid::SmokeSource source(const Node& n, std::size_t index,
                            const mesh::FluidDomain& domain) const {
    fluid::SmokeSource src;
    src.name = fmt::format("source{}", index);
    read(n, source_keys(), src);
    const Node bn = require(n, "box");
    const BoxSpec b = box(bn, source_box_keys(), true);
    const bool overlaps =
        (b.lo.array() < domain.hi.array()).all() && (b.hi.array() > domain.lo.array()).all();
    if (!overlaps)
      fail(bn.path, fmt::format("the box {}..{} misses the fluid box {}..{}", fmt_vec(b.lo),
                                fmt_vec(b.hi), fmt_vec(domain.lo), fmt_vec(domain.hi)));
    src.lo = b.lo;
    src.hi = b.hi;
    return src;
  }

  /// Names in a list must be unique: the error names both places.
  template <class Item>
  void unique_name(const std::vector<Item>& items, const std::string& name, const char* what,
                   const Node& list, std::size_t i) const {
    for (std::size_t k = 0; k < items.size(); ++k) {
      if (items[k].name == name)
        fail(index_path(list.path, i) + ".name",
             fmt::format("duplicate {} name '{}' (also {}[{}])", what, name, list.path, k));
    }
  }

  /// The fluid section; `gravity` is the scene's (for FluidParams::gravity and ::up).
  FluidSpec fluid(const Node& n, const Vec3& gravity) const {
    FluidSpec f;
    fluid::FluidParams& fp = f.params;
    read(n, fluid_keys(), f);
    const Node d = require(n, "domain");
    read(d, domain_keys(), f.domain);
    check_box(d, f.domain.lo, f.domain.hi, true);
    if (has(d, "patches")) {
      const Node list = child(d, "patches");
      for_each(list, "expected an array", [&](const Node& e, std::size_t i) {
        PatchKeys p = patch(e, i, f.domain);
        unique_name(f.domain.patches, p.patch.name, "patch", list, i);
        f.domain.patches.push_back(std::move(p.patch));
        fp.patches.push_back(p.conditions);
      });
    }
    if (has(n, "mesh")) {
      const Node m = child(n, "mesh");
      mesh::Sizing& z = f.sizing;
      read(m, fluid_mesh_keys(), z);
      if (z.surface_size > z.far_size)
        fail(child_path(m.path, "surface_size"),
             fmt::format("must be <= far_size ({} m), got {} m", z.far_size, z.surface_size));
    }
    // fluid.mesh and fluid.grid are the two discretisations' sections: a scene may carry
    // both, fluid.discretization picks one
    if (f.discretization == Discretization::Grid)
      grid(n, f);
    else if (has(n, "grid"))
      read(child(n, "grid"), fluid_grid_keys(), f.grid);
    fp.gravity = f.gravity ? gravity : Vec3::Zero();
    for (int a = 0; a < 3; ++a)  // the box corner highest against gravity
      fp.hydrostatic_origin[a] = fp.gravity[a] < 0 ? f.domain.hi[a] : f.domain.lo[a];
    const double g_norm = gravity.norm();
    fp.up = g_norm > 0 ? Vec3(-gravity / g_norm) : Vec3(Vec3::UnitZ());
    if (has(n, "buoyancy")) read(child(n, "buoyancy"), buoyancy_keys(), fp);
    if (has(n, "decay")) read(child(n, "decay"), decay_keys(), fp);
    if (has(n, "transfer")) read(child(n, "transfer"), transfer_keys(), fp);
    if (has(n, "solver")) read(child(n, "solver"), fluid_solver_keys(), fp);
    pressure_solver(n, f);
    if (has(n, "sources")) {
      const Node list = child(n, "sources");
      for_each(list, "expected an array", [&](const Node& e, std::size_t i) {
        fluid::SmokeSource src = source(e, i, f.domain);
        unique_name(fp.sources, src.name, "source", list, i);
        fp.sources.push_back(std::move(src));
      });
    }
    if (has(n, "liquid")) liquid(child(n, "liquid"), f);
    if (has(n, "refine")) {
      const Node r = child(n, "refine");
      read(r, refine_keys(), fp.refine);
      if (fp.refine.size > f.sizing.far_size)
        fail(child_path(r.path, "size"),
             fmt::format("must be <= fluid.mesh.far_size ({} m), got {} m", f.sizing.far_size,
                         fp.refine.size));
    }
    return f;
  }

  /// A box or sphere of fluid.liquid that must overlap the fluid box (`where` names it).
  void overlap_domain(const Node& where, const Vec3& lo, const Vec3& hi,
                      const mesh::FluidDomain& d) const {
    if ((lo.array() < d.hi.array()).all() && (hi.array() > d.lo.array()).all()) return;
    fail(where.path, fmt::format("{}..{} lies outside the fluid box {}..{}; move it inside",
                                 fmt_vec(lo), fmt_vec(hi), fmt_vec(d.lo), fmt_vec(d.hi)));
  }

  /// The box of a liquid region or (`source`) source, lo < hi, overlapping the fluid box.
  BoxSpec liquid_box(const Node& n, bool source, const mesh::FluidDomain& d) const {
    const BoxSpec b = box(n, liquid_box_keys(source), true);
    overlap_domain(n, b.lo, b.hi, d);
    return b;
  }

  /// fluid.liquid: regions (a box, a sphere, a closed surface, or their overlap) and sources,
  /// on the grid only.
  void liquid(const Node& n, FluidSpec& f) const {
    fluid::LiquidParams& lq = f.params.liquid;
    read(n, liquid_keys(), lq);
    lq.enabled = true;
    if (f.discretization != Discretization::Grid)
      fail(n.path,
           "a free surface lives on the regular grid: set fluid.discretization to \"grid\" "
           "and give fluid.grid");
    if (has(n, "regions")) {
      const Node list = child(n, "regions");
      for_each(list, "expected an array", [&](const Node& e, std::size_t i) {
        fluid::LiquidRegion r;
        r.name = fmt::format("region{}", i);
        read(e, liquid_region_keys(), r);
        if (!has(e, "box") && !has(e, "sphere") && !has(e, "surface"))
          fail(e.path,
               "give a box, a sphere or a surface (or several: the liquid fills where "
               "they overlap)");
        if (has(e, "box")) {
          const BoxSpec b = liquid_box(child(e, "box"), false, f.domain);
          r.lo = b.lo;
          r.hi = b.hi;
        }
        if (has(e, "sphere")) {
          const Node sn = child(e, "sphere");
          read(sn, liquid_sphere_keys(), r);
          overlap_domain(sn, r.centre.array() - r.radius, r.centre.array() + r.radius, f.domain);
        }
        if (has(e, "surface")) {
          const Node sn = child(e, "surface");
          auto s = std::make_shared<mesh::SurfaceMesh>();
          try {
            *s = mesh::read_surface_mesh(r.surface_file);
            mesh::validate_closed_surface(*s, r.surface_file.filename().string());
          } catch (const Error& err) {
            fail(sn.path, err.what());
          }
          overlap_domain(sn, s->vertices.colwise().minCoeff().transpose(),
                         s->vertices.colwise().maxCoeff().transpose(), f.domain);
          r.surface = std::move(s);
        }
        unique_name(lq.regions, r.name, "liquid region", list, i);
        lq.regions.push_back(std::move(r));
      });
    }
    if (has(n, "sources")) {
      const Node list = child(n, "sources");
      for_each(list, "expected an array", [&](const Node& e, std::size_t i) {
        fluid::LiquidSource src;
        src.name = fmt::format("source{}", i);
        read(e, liquid_source_keys(), src);
        const BoxSpec b = liquid_box(require(e, "box"), true, f.domain);
        src.lo = b.lo;
        src.hi = b.hi;
        if (!(src.stop > src.start))
          fail(child_path(e.path, "stop"),
               fmt::format("must be > start ({} s), got {} s: the source would emit nothing",
                           src.start, src.stop));
        unique_name(lq.sources, src.name, "liquid source", list, i);
        lq.sources.push_back(std::move(src));
      });
    }
    if (lq.regions.empty() && lq.sources.empty())
      fail(n.path, "has neither regions nor sources: give the liquid somewhere to start");
  }

  /// fluid.solver.linear: pfmg, the structured multigrid, is the grid's default and the
  /// grid's alone.
  void pressure_solver(const Node& n, FluidSpec& f) const {
    const bool given = has(n, "solver") && has(child(n, "solver"), "linear");
    if (f.discretization == Discretization::Grid) {
      if (!given) f.params.solver = SolverKind::Pfmg;
    } else if (f.params.solver == SolverKind::Pfmg) {
      fail(child_path(child(n, "solver").path, "linear"),
           "pfmg is the regular grid's structured multigrid (fluid.discretization \"grid\"); "
           "the tet mesh's pressure needs amg (the default) or another backend");
    }
  }

  /// fluid.grid of a grid scene: the grid's cells from cell_size or cells, within max_cells;
  /// the tet mesh's keys refused.
  void grid(const Node& n, FluidSpec& f) const {
    for (const char* key : {"refine", "reconstruction", "transfer", "min_dual_fraction"})
      if (has(n, key))
        fail(child_path(n.path, key),
             "is a key of the tet mesh, not of fluid.discretization \"grid\"; remove it");
    if (!has(n, "grid"))
      fail(n.path,
           "fluid.discretization \"grid\" needs fluid.grid with cell_size (m) or cells "
           "[nx, ny, nz]");
    const Node g = child(n, "grid");
    GridKeys& k = f.grid;
    read(g, fluid_grid_keys(), k);
    const bool by_size = has(g, "cell_size"), by_cells = has(g, "cells");
    if (!by_size && !by_cells) fail(g.path, "give cell_size (m) or cells [nx, ny, nz]");
    const Vec3 lo = f.domain.lo, hi = f.domain.hi;
    fluid::GridSpec spec;
    if (by_size) {
      spec = fluid::GridSpec::from_cell_size(lo, hi, k.cell_size);
      const Vec3i n_size(static_cast<int>(spec.n[0]), static_cast<int>(spec.n[1]),
                         static_cast<int>(spec.n[2]));
      if (by_cells && n_size != k.cells)
        fail(child_path(g.path, "cells"),
             fmt::format("[{}, {}, {}] disagrees with cell_size {} m, which gives [{}, {}, {}]; "
                         "give one of them",
                         k.cells.x(), k.cells.y(), k.cells.z(), k.cell_size, n_size.x(), n_size.y(),
                         n_size.z()));
      k.cells = n_size;
    } else {
      spec = fluid::GridSpec::from_cells(lo, hi, {k.cells.x(), k.cells.y(), k.cells.z()});
    }
    if (spec.num_cells() > k.max_cells)
      fail(child_path(g.path, by_size ? "cell_size" : "cells"),
           fmt::format("gives {} x {} x {} = {} cells, more than fluid.grid.max_cells ({}); "
                       "use larger cells or raise max_cells",
                       spec.n[0], spec.n[1], spec.n[2], spec.num_cells(), k.max_cells));
    f.grid_spec = spec;
  }

  /// The solid section: the integrator of bodies that step alone and the equilibrium
  /// iteration's options (scene.hpp).
  SolidSpec solid(const Node& n) const {
    SolidSpec s;
    read(n, solid_keys(), s);
    if (has(n, "trapezoid") && s.integrator != solid::Integrator::Linearized) {
      fail(child_path(n.path, "trapezoid"),
           fmt::format("applies only to solid.integrator 'linearized' (the '{}' integrator "
                       "iterates the full trapezoidal rule); remove it or set solid.integrator "
                       "to 'linearized'",
                       solid::to_string(s.integrator)));
    }
    return s;
  }

  /// The coupling section (`n` may be null: not given). `deformable`: the scene has a
  /// non-kinematic body; `dynamic`: its mode. Only called for a scene with a fluid.
  CouplingSpec coupling_spec(const Node* n, bool deformable, bool dynamic) const {
    CouplingSpec c;
    c.two_way =
        deformable && dynamic;  // the default, docs/dev/architecture.md: the simultaneous solve
    if (n) read(*n, coupling_keys(), c);
    return c;
  }

 private:
  std::string m_file;
  fs::path m_folder;
};

// ---------------------------------------------------------------------------------------------
// Scene → JSON with every default filled in: each section's `write`, nested as in the file.

json mesh_json(const MeshSpec& m) {
  json j = mesh_keys().write(m);  // file, surface + cell_size
  switch (m.kind) {
    case MeshSpec::Kind::Box:
      j["box"] = mesh_box_keys().write(m);
      break;
    case MeshSpec::Kind::Sphere:
      j["sphere"] = mesh_sphere_keys().write(m);
      break;
    case MeshSpec::Kind::Shell:
      j["shell"] = mesh_shell_keys().write(m);
      break;
    case MeshSpec::Kind::HollowBox:
      j["hollow_box"] = mesh_hollow_box_keys().write(m);
      break;
    case MeshSpec::Kind::Tube:
      j["tube"] = mesh_tube_keys().write(m);
      break;
    case MeshSpec::Kind::Bowl:
      j["bowl"] = mesh_bowl_keys().write(m);
      break;
    case MeshSpec::Kind::File:
    case MeshSpec::Kind::Surface:
      break;
  }
  return j;
}

/// A pin's or a load's section, with its selection box if it has one.
template <class T>
json selection_json(const Section<T>& section, const T& t) {
  json j = section.write(t);
  if (t.select.box) j["box"] = selection_box_keys().write(*t.select.box);
  return j;
}

json body_json(const BodySpec& b) {
  json j = body_keys().write(b);  // name, initial_velocity
  j["mesh"] = mesh_json(b.mesh);
  j["transform"] = transform_keys().write(b.transform);
  j["material"] = material_keys().write(b.material);
  j["pins"] = json::array();
  for (const PinSpec& p : b.pins) j["pins"].push_back(selection_json(pin_keys(), p));
  j["loads"] = json::array();
  for (const LoadSpec& l : b.loads) j["loads"].push_back(selection_json(load_keys(), l));
  if (b.kinematic) j["kinematic"] = kinematic_keys().write(*b.kinematic);
  return j;
}

json fluid_json(const FluidSpec& f) {
  const fluid::FluidParams& fp = f.params;
  json j = fluid_keys().write(f);
  json domain = domain_keys().write(f.domain);
  domain["patches"] = json::array();
  for (std::size_t i = 0; i < f.domain.patches.size(); ++i)
    domain["patches"].push_back(patch_keys().write({f.domain.patches[i], fp.patches.at(i)}));
  j["domain"] = domain;
  if (f.grid_spec) {  // the tet mesh's keys are refused on the grid
    j.erase("reconstruction");
    j.erase("min_dual_fraction");
    j["grid"] = fluid_grid_keys().write(f.grid);
  }
  j["mesh"] = fluid_mesh_keys().write(f.sizing);
  j["buoyancy"] = buoyancy_keys().write(fp);
  j["decay"] = decay_keys().write(fp);
  if (!f.grid_spec) j["transfer"] = transfer_keys().write(fp);
  j["solver"] = fluid_solver_keys().write(fp);
  j["sources"] = json::array();
  for (const fluid::SmokeSource& src : fp.sources) {
    json js = source_keys().write(src);
    js["box"] = source_box_keys().write({src.lo, src.hi});
    j["sources"].push_back(js);
  }
  if (!f.grid_spec) j["refine"] = refine_keys().write(fp.refine);
  if (fp.liquid.enabled) {
    json lq = liquid_keys().write(fp.liquid);
    lq["regions"] = json::array();
    for (const fluid::LiquidRegion& r : fp.liquid.regions) {
      json jr = liquid_region_keys().write(r);
      if (r.radius > 0) jr["sphere"] = liquid_sphere_keys().write(r);
      if (r.has_box()) jr["box"] = liquid_box_keys(false).write({r.lo, r.hi});
      lq["regions"].push_back(jr);
    }
    lq["sources"] = json::array();
    for (const fluid::LiquidSource& src : fp.liquid.sources) {
      json js = liquid_source_keys().write(src);
      js["box"] = liquid_box_keys(true).write({src.lo, src.hi});
      lq["sources"].push_back(js);
    }
    j["liquid"] = lq;
  }
  return j;
}

json resolve(const Scene& s) {
  json j = top_level_keys().write(s);  // name, description, mode, gravity
  j["time"] = time_keys().write(s.time);
  j["output"] = output_keys().write(s.output);
  j["solver"] = solver_keys().write(s.solver);
  j["solid"] = solid_keys().write(s.solid);
  // only the linearized integrator has variants (and takes the key); the iterated coupled
  // schemes take the full trapezoidal rule
  if (s.solid.integrator != solid::Integrator::Linearized ||
      (s.two_way() && coupling::is_iterated(s.coupling->params.scheme)))
    j["solid"].erase("trapezoid");
  j["static"] = static_keys().write(s.statics);
  j["bodies"] = json::array();
  for (const BodySpec& b : s.bodies) j["bodies"].push_back(body_json(b));
  j["obstacles"] = json::array();
  for (const solid::Obstacle& o : s.obstacles) {
    const bool plane = o.kind == solid::Obstacle::Kind::Plane;
    j["obstacles"].push_back((plane ? plane_obstacle_keys() : box_obstacle_keys()).write(o));
  }
  if (s.fluid) j["fluid"] = fluid_json(*s.fluid);
  if (s.coupling) j["coupling"] = coupling_keys().write(*s.coupling);
  if (s.contact) j["contact"] = contact_keys().write(*s.contact);
  return j;
}

/// The keys of how the bodies are integrated, against the coupling scheme that steps them.
/// @throws InputError naming the key.
void check_integration_keys(const Parser& p, const Parser::Node& root, const Scene& s) {
  // A two-way coupled step integrates the bodies itself, as its scheme says.
  if (s.two_way() && s.solid.integrator != solid::Integrator::Linearized &&
      s.coupling->scheme_name() != solid::to_string(s.solid.integrator)) {
    const std::string i = solid::to_string(s.solid.integrator);
    p.fail("solid.integrator",
           fmt::format("'{}' is not used in a two-way coupled scene: its bodies step with "
                       "coupling.scheme '{}'; set coupling.scheme to '{}' to iterate the coupled "
                       "step to equilibrium, or remove solid.integrator",
                       i, s.coupling->scheme_name(), i));
  }

  // The same for solid.trapezoid: the iterated coupled schemes take the full trapezoidal rule.
  if (s.two_way() && coupling::is_iterated(s.coupling->params.scheme) &&
      Parser::has(root, "solid") && Parser::has(Parser::child(root, "solid"), "trapezoid")) {
    p.fail("solid.trapezoid",
           fmt::format("applies to the linearized integrator only; coupling.scheme '{}' "
                       "iterates the full trapezoidal rule: remove solid.trapezoid",
                       s.coupling->scheme_name()));
  }

  // The starting matrix is that of the coupled iterations bfgs and modified_newton.
  if (s.solid.equilibrium.starting_matrix != StartingMatrix::Bodies) {
    const char* name = k_starting_matrix_names.name(s.solid.equilibrium.starting_matrix);
    const bool iterated_start =
        s.two_way() && (s.coupling->params.scheme == coupling::Scheme::Bfgs ||
                        s.coupling->params.scheme == coupling::Scheme::ModifiedNewton);
    if (!iterated_start)
      p.fail(
          "solid.starting_matrix",
          fmt::format("'{}' adds the fluid to the starting matrix of coupling.scheme 'bfgs' "
                      "or 'modified_newton' in a two-way scene; this scene has {}: remove it",
                      name,
                      s.two_way() ? fmt::format("coupling.scheme '{}'", s.coupling->scheme_name())
                                  : std::string("no two-way coupling")));
    if (s.solid.equilibrium.starting_matrix == StartingMatrix::Coupled &&
        s.solid.equilibrium.keep_matrix)
      p.fail("solid.reform",
             "'run' keeps the starting matrix from step to step, but "
             "solid.starting_matrix 'coupled' is formed on each step's fluid "
             "mesh: set solid.reform to 'step'");
  }
}

}  // namespace

// ---------------------------------------------------------------------------------------------

namespace {

using Node = Parser::Node;

/// The scene's `time` section and its consistency (end_time or steps, a sane step count).
void parse_time(const Parser& p, const Node& root, Scene& s) {
  if (Parser::has(root, "time")) {
    const Node t = Parser::child(root, "time");
    if (t.j.is_object() && Parser::has(t, "end_time") && Parser::has(t, "steps"))
      p.fail("time", "give either 'end_time' or 'steps', not both");
    p.read(t, time_keys(), s.time);
  }
  if (!s.time.steps && !s.time.end_time) s.time.end_time = 1.0;
  if (!s.time.steps && *s.time.end_time / s.time.dt > 1e9) {
    p.fail("time", fmt::format("end_time / dt = {:.3g} steps is more than 1e9: check the units",
                               *s.time.end_time / s.time.dt));
  }
}

/// The bodies; a fluid-only scene (smoke in a box) needs none, otherwise there is nothing to
/// simulate.
void parse_bodies(const Parser& p, const Node& root, bool has_fluid, Scene& s) {
  static const json no_bodies = json::array();
  const Node bodies = has_fluid && !Parser::has(root, "bodies") ? Node{no_bodies, "bodies"}
                                                                : p.require(root, "bodies");
  p.for_each(bodies, "expected an array of bodies", [&](const Node& e, std::size_t i) {
    BodySpec b = p.body(e);
    p.unique_name(s.bodies, b.name, "body", bodies, i);
    s.bodies.push_back(std::move(b));
  });
  if (bodies.j.empty() && !has_fluid)
    p.fail("bodies", "a scene needs at least one body (or a 'fluid' section)");
}

/// The coupling of a fluid scene: the given `coupling` section or the default for its bodies.
void parse_coupling(const Parser& p, const Node& root, bool has_fluid, Scene& s) {
  const bool has_coupling = Parser::has(root, "coupling");
  if (has_coupling && !has_fluid)
    p.fail("coupling",
           "a scene without a 'fluid' section has nothing to couple the bodies to: add 'fluid' "
           "or remove 'coupling'");
  if (has_fluid) {
    const bool deformable = std::any_of(s.bodies.begin(), s.bodies.end(),
                                        [](const BodySpec& b) { return !b.kinematic; });
    const bool dynamic = s.mode == Mode::Dynamic;
    if (has_coupling) {
      const Node c = Parser::child(root, "coupling");
      s.coupling = p.coupling_spec(&c, deformable, dynamic);
    } else {
      s.coupling = p.coupling_spec(nullptr, deformable, dynamic);
    }
  }
}

/// The defaults that depend on the rest of the scene: the integrator and the tangent.
void default_integrator(const Node& root, Scene& s) {
  // The default integrator, chosen by measurement (`tetfsi bench integrators`, docs/method/solid.md
  // "Choosing integrators"): the Newton-iterated trapezoidal rule keeps a swing's energy to 1e-3
  // where the paper's linearisation damps it away. Two-way scenes step their bodies with
  // coupling.scheme; a given solid.trapezoid asks for the linearized rule.
  const bool given_solid = Parser::has(root, "solid");
  const auto given = [&](const char* key) {
    return given_solid && Parser::has(Parser::child(root, "solid"), key);
  };
  if (!given("integrator") && !given("trapezoid") && !s.contact && !s.two_way() &&
      s.mode == Mode::Dynamic)
    s.solid.integrator = solid::Integrator::Newton;
  // Bodies in contact are crushed where they meet: the exact K' is then indefinite and the
  // ball of ball_block diverged (at h = 0.005 s as at 1/30 s); see StvkElasticity.
  if (!given("tangent") && s.contact) s.solid.tangent = solid::Tangent::Definite;
}

/// Contact between bodies acts inside the linearised step's solve (solid/contact.hpp): the
/// scheme and the integrator must allow it.
void check_contact(const Parser& p, const Scene& s) {
  if (s.contact && s.mode == Mode::Dynamic) {
    if (s.two_way() && s.coupling->params.scheme != coupling::Scheme::Simultaneous)
      p.fail("contact", fmt::format("contact between bodies works with coupling.scheme "
                                    "'simultaneous' (or 'none'), not '{}'",
                                    s.coupling->scheme_name()));
    if (!s.two_way() && s.solid.integrator != solid::Integrator::Linearized)
      p.fail("contact", fmt::format("contact between bodies needs solid.integrator 'linearized' "
                                    "(the default with contact), not '{}'",
                                    solid::to_string(s.solid.integrator)));
  }
}

}  // namespace

Scene parse_scene(const json& j, const fs::path& file) {
  const Parser p(file);
  using Node = Parser::Node;
  const Node root{j, ""};
  Scene s;
  s.file = file.empty() ? fs::path() : fs::absolute(file).lexically_normal();
  s.name = file.empty() ? std::string("scene") : file.stem().string();
  p.read(root, top_level_keys(), s);  // name, description, mode, gravity

  parse_time(p, root, s);
  if (Parser::has(root, "output")) p.read(Parser::child(root, "output"), output_keys(), s.output);
  if (Parser::has(root, "solver")) p.read(Parser::child(root, "solver"), solver_keys(), s.solver);
  if (Parser::has(root, "solid")) s.solid = p.solid(Parser::child(root, "solid"));
  if (Parser::has(root, "static")) p.read(Parser::child(root, "static"), static_keys(), s.statics);
  if (Parser::has(root, "contact")) {
    s.contact.emplace();
    p.read(Parser::child(root, "contact"), contact_keys(), *s.contact);
  }

  const bool has_fluid = Parser::has(root, "fluid");
  parse_bodies(p, root, has_fluid, s);

  if (Parser::has(root, "obstacles")) {
    p.for_each(Parser::child(root, "obstacles"), "expected an array",
               [&](const Node& e, std::size_t i) { s.obstacles.push_back(p.obstacle(e, i)); });
  }

  if (has_fluid) s.fluid = p.fluid(Parser::child(root, "fluid"), s.gravity);
  const auto& formats = s.output.export_formats;
  if (!has_fluid && std::find(formats.begin(), formats.end(), "vdb") != formats.end())
    p.fail("output.export",
           "'vdb' writes the fluid's volumes and this scene has no fluid: "
           "remove it (`ply` writes the bodies' surfaces)");

  parse_coupling(p, root, has_fluid, s);

  default_integrator(root, s);
  check_contact(p, s);

  check_integration_keys(p, root, s);

  s.resolved = resolve(s);
  return s;
}

// ---------------------------------------------------------------------------------------------

namespace {

/// Scenes nest a few levels deep (bodies[0].mesh.box.lo); deeper input is not a scene, and
/// nlohmann's DOM of a deeply nested text takes time and memory out of all proportion.
constexpr int k_max_json_depth = 64;

/// Reject nesting deeper than k_max_json_depth before parsing, naming the line.
void check_nesting(const std::string& text, const std::string& where) {
  int depth = 0, line = 1;
  bool in_string = false, escaped = false;
  for (const char c : text) {
    if (c == '\n') ++line;
    if (in_string) {
      if (escaped)
        escaped = false;
      else if (c == '\\')
        escaped = true;
      else if (c == '"')
        in_string = false;
      continue;
    }
    if (c == '"')
      in_string = true;
    else if (c == ']' || c == '}')
      --depth;
    else if ((c == '[' || c == '{') && ++depth > k_max_json_depth) {
      throw InputError(
          fmt::format("{}: line {}: JSON nested more than {} levels deep; a scene needs a handful",
                      where, line, k_max_json_depth));
    }
  }
}

/// Set `root[path] = value` for a dotted path; numeric components index arrays.
void apply_override(json& root, const std::string& text, const std::string& scene_name) {
  auto bad = [&](const std::string& why) {
    throw InputError(fmt::format("{}: --set '{}': {}", scene_name, text, why));
  };
  const auto eq = text.find('=');
  if (eq == std::string::npos) bad("expected key.path=value (no '=')");
  const std::string key = text.substr(0, eq);
  const std::string value_text = text.substr(eq + 1);
  if (key.empty()) bad("empty key path before '='");

  std::vector<std::string> parts;
  std::stringstream ss(key);
  for (std::string part; std::getline(ss, part, '.');) parts.push_back(part);
  if (key.back() == '.') parts.emplace_back();

  json* cur = &root;
  std::string walked;
  for (std::size_t i = 0; i < parts.size(); ++i) {
    const std::string& part = parts[i];
    if (part.empty()) bad("empty component in the key path");
    const bool numeric =
        std::all_of(part.begin(), part.end(), [](unsigned char c) { return std::isdigit(c); });
    if (cur->is_array()) {
      if (!numeric)
        bad(fmt::format("'{}' is an array: index it with a number, not '{}'", walked, part));
      // More than 9 digits is beyond any array here (and beyond stoul's range at 20).
      const std::size_t idx = part.size() > 9 ? cur->size() : std::stoul(part);
      if (idx >= cur->size()) {
        bad(fmt::format("index {} is out of range ('{}' has {} element{})", part, walked,
                        cur->size(), cur->size() == 1 ? "" : "s"));
      }
      cur = &(*cur)[idx];
    } else if (cur->is_object() || cur->is_null()) {
      cur = &(*cur)[part];  // creates the key; parse_scene rejects keys the schema lacks
    } else {
      bad(fmt::format("'{}' is {}, not an object", walked, describe(*cur)));
    }
    walked += (walked.empty() ? "" : ".") + part;
  }
  check_nesting(value_text, fmt::format("{}: --set '{}'", scene_name, key));
  json value = json::parse(value_text, nullptr, /*allow_exceptions=*/false);
  if (value.is_discarded()) value = value_text;
  *cur = std::move(value);
}

/// A parser callback that rejects a key given twice in one object (nlohmann would silently
/// keep the last), naming the JSON path.
json::parser_callback_t duplicate_key_check(const std::string& scene_name) {
  struct Frame {
    bool is_object;
    std::string path;
    std::set<std::string> keys;
    std::string last_key;
    std::size_t next_index = 0;
  };
  auto stack = std::make_shared<std::vector<Frame>>();
  // The path of a value starting now, as a child of the innermost open container.
  auto child_here = [stack]() -> std::string {
    if (stack->empty()) return "";
    Frame& f = stack->back();
    if (f.is_object) return Parser::child_path(f.path, f.last_key);
    return Parser::index_path(f.path, f.next_index++);
  };
  return [stack, child_here, scene_name](int /*depth*/, json::parse_event_t event, json& parsed) {
    switch (event) {
      case json::parse_event_t::object_start:
      case json::parse_event_t::array_start:
        stack->push_back({event == json::parse_event_t::object_start, child_here(), {}, {}, 0});
        break;
      case json::parse_event_t::key: {
        Frame& f = stack->back();
        f.last_key = parsed.get<std::string>();
        if (!f.keys.insert(f.last_key).second) {
          throw InputError(
              fmt::format("{}: {}: duplicate key (JSON keeps only the last value; remove one)",
                          scene_name, Parser::child_path(f.path, f.last_key)));
        }
        break;
      }
      case json::parse_event_t::value:
        if (!stack->empty() && !stack->back().is_object) ++stack->back().next_index;
        break;
      case json::parse_event_t::object_end:
      case json::parse_event_t::array_end:
        stack->pop_back();
        break;
    }
    return true;
  };
}

}  // namespace

Scene load_scene(const fs::path& file, const std::vector<std::string>& overrides) {
  const std::string name = display_name(file);
  std::error_code ec;
  if (!fs::exists(file, ec)) {
    throw InputError(fmt::format("{}: no such scene file ('{}')", name,
                                 fs::absolute(file).lexically_normal().string()));
  }
  if (fs::is_directory(file, ec))
    throw InputError(fmt::format("{}: is a folder, not a scene file", name));
  std::ifstream in(file, std::ios::binary);
  if (!in) throw InputError(fmt::format("{}: cannot open the scene file for reading", name));
  std::stringstream buffer;
  buffer << in.rdbuf();
  return parse_scene_text(buffer.str(), file, overrides);
}

namespace {

/// nlohmann's parse error `reason` with its "last read: '…'" excerpt kept to one short line:
/// runs of white space (and the escaped newlines "<U+000A>") as one space, at most the last
/// 80 characters (a deeply nested or long token would otherwise fill screens).
std::string short_parse_reason(std::string reason) {
  const std::string tag = "last read: '";
  const auto begin = reason.find(tag);
  if (begin == std::string::npos) return reason;
  const auto from = begin + tag.size();
  auto end = reason.find("'; ", from);
  if (end == std::string::npos) end = reason.rfind('\'');
  if (end == std::string::npos || end < from) return reason;
  std::string excerpt = reason.substr(from, end - from), out;
  for (std::size_t pos = 0; (pos = excerpt.find("<U+000A>", pos)) != std::string::npos;)
    excerpt.replace(pos, 8, " ");
  for (const char c : excerpt) {
    const bool space = c == ' ' || c == '\t' || c == '\r' || c == '\n';
    if (space && !out.empty() && out.back() == ' ') continue;
    out += space ? ' ' : c;
  }
  if (out.size() > 80) out = "..." + out.substr(out.size() - 80);
  return reason.substr(0, from) + out + reason.substr(end);
}

}  // namespace

Scene parse_scene_text(const std::string& text, const fs::path& file,
                       const std::vector<std::string>& overrides) {
  const std::string name = display_name(file);
  check_nesting(text, name);
  json j;
  try {
    j = json::parse(text, duplicate_key_check(name));
  } catch (const json::parse_error& e) {
    // e.byte is 1-based (the last byte read); turn it into a line and column.
    const std::size_t byte = std::min<std::size_t>(e.byte == 0 ? 1 : e.byte, text.size() + 1);
    std::size_t line = 1, line_start = 0;
    for (std::size_t i = 0; i + 1 < byte; ++i) {
      if (text[i] == '\n') {
        ++line;
        line_start = i + 1;
      }
    }
    const std::size_t column = byte - line_start;
    std::string reason = e.what();
    const auto colon = reason.find(": ", reason.find("parse error"));
    if (colon != std::string::npos) reason = reason.substr(colon + 2);
    reason = short_parse_reason(reason);
    throw InputError(
        fmt::format("{}: line {}, column {}: invalid JSON: {}", name, line, column, reason));
  }
  for (const std::string& o : overrides) apply_override(j, o, name);
  return parse_scene(j, file);
}

// ---------------------------------------------------------------------------------------------

namespace {

/// x ↦ translate + R (scale · x), R = Rz · Ry · Rx.
void apply_transform(const TransformSpec& t, MatX3& x) {
  constexpr double deg = M_PI / 180.0;
  const Mat3 R = (Eigen::AngleAxisd(t.rotate_deg.z() * deg, Vec3::UnitZ()) *
                  Eigen::AngleAxisd(t.rotate_deg.y() * deg, Vec3::UnitY()) *
                  Eigen::AngleAxisd(t.rotate_deg.x() * deg, Vec3::UnitX()))
                     .toRotationMatrix();
  for (Index i = 0; i < x.rows(); ++i) {
    x.row(i) = (t.translate + R * (t.scale * x.row(i).transpose())).transpose();
  }
}

mesh::VolumeMesh make_mesh(const MeshSpec& m) {
  switch (m.kind) {
    case MeshSpec::Kind::Box:
      return mesh::make_box(m.box.lo, m.box.hi, m.cells);
    case MeshSpec::Kind::File:
      return mesh::read_volume_mesh(m.file);
    case MeshSpec::Kind::Surface: {
      const mesh::SurfaceMesh surface = mesh::read_surface_mesh(m.file);
      mesh::TetrahedralizeParams params;
      params.cell_size = m.cell_size;
      return mesh::tetrahedralize_surface(surface, params, m.file.string());
    }
    case MeshSpec::Kind::Sphere:
      return mesh::make_ball(m.center, m.radius, m.subdivisions);
    case MeshSpec::Kind::Shell:
      return mesh::make_spherical_shell(m.center, m.inner_radius, m.outer_radius, m.subdivisions,
                                        m.layers);
    case MeshSpec::Kind::HollowBox:
      return mesh::make_hollow_box(m.box.lo, m.box.hi, m.thickness, m.cells);
    case MeshSpec::Kind::Tube:
      return mesh::make_tube(m.center, m.axis, m.inner_radius, m.outer_radius, m.length,
                             m.cells.x(), m.cells.y(), m.cells.z());
    case MeshSpec::Kind::Bowl:
      return mesh::make_bowl(m.center, m.inner_radius, m.outer_radius, m.meridian_cells, m.layers);
  }
  throw InternalError("unknown mesh kind");
}

/// The nodes a selection picks, checked against the body; `where` is "<file>: bodies[0].pins[1]".
std::vector<Index> select_nodes(const NodeSelection& sel, const MatX3& rest,
                                const std::string& where) {
  const Index n = static_cast<Index>(rest.rows());
  std::vector<Index> out;
  if (sel.box) {
    for (Index i = 0; i < n; ++i) {
      if (sel.box->contains(rest.row(i).transpose())) out.push_back(i);
    }
    if (out.empty()) {
      throw InputError(fmt::format("{}: the box {}..{} selects no node; the body spans {}..{}",
                                   where, fmt_vec(sel.box->lo), fmt_vec(sel.box->hi),
                                   fmt_vec(rest.colwise().minCoeff().transpose()),
                                   fmt_vec(rest.colwise().maxCoeff().transpose())));
    }
  } else {
    for (std::size_t k = 0; k < sel.nodes.size(); ++k) {
      const Index v = sel.nodes[k];
      if (v < 0 || v >= n) {
        throw InputError(
            fmt::format("{}.nodes[{}]: node {} is out of range (the body has {} nodes, 0..{})",
                        where, k, v, n, n - 1));
      }
      out.push_back(v);
    }
    std::sort(out.begin(), out.end());
    out.erase(std::unique(out.begin(), out.end()), out.end());
    if (out.empty()) throw InputError(fmt::format("{}: selects no node", where));
  }
  return out;
}

}  // namespace

namespace {

/// The scene's contact section with its gap resolved (the default from the fluid's surface
/// cell size, the grid's cell, or the bodies' median surface edge) and validated.
solid::ContactParams contact_params(const Scene& scene, const std::vector<solid::SolidBody>& bodies,
                                    const std::string& file) {
  const ContactSpec& c = *scene.contact;
  solid::ContactParams p;
  p.enabled = true;
  p.friction = c.friction;
  p.restitution = c.restitution;
  p.self = c.self;
  p.stiffness = c.stiffness;
  double size = solid::median_surface_edge(bodies);
  if (scene.fluid)
    size = scene.fluid->grid_spec ? scene.fluid->grid_spec->h.minCoeff()
                                  : scene.fluid->sizing.surface_size;
  p.gap = c.gap.value_or(solid::default_contact_gap(bodies, size));
  solid::validate(p, bodies, file);
  return p;
}

}  // namespace

solid::SolidWorld build_world(const Scene& scene) {
  const std::string file = display_name(scene.file);
  solid::SolidWorld world;
  world.gravity = scene.gravity;
  world.linear_solver = parse_solver_kind(scene.solver.linear);
  world.solver_options.rel_tol = scene.solver.rel_tol;
  world.solver_options.max_iterations = scene.solver.max_iterations;
  world.trapezoid = solid::parse_trapezoid(scene.solid.trapezoid);
  world.integrator = scene.solid.integrator;
  world.equilibrium = scene.solid.equilibrium;  // its method: SolidWorld takes the integrator's
  world.bodies.reserve(scene.bodies.size());

  for (std::size_t bi = 0; bi < scene.bodies.size(); ++bi) {
    const BodySpec& spec = scene.bodies[bi];
    const std::string body_where = fmt::format("{}: bodies[{}] '{}'", file, bi, spec.name);
    // Mesh and body construction: wrap errors so they name the scene and the body.
    try {
      mesh::VolumeMesh m = make_mesh(spec.mesh);
      apply_transform(spec.transform, m.vertices);
      world.bodies.emplace_back(spec.name, std::move(m), spec.material);
      world.bodies.back().set_tangent(scene.solid.tangent);
    } catch (const MeshError& e) {
      throw MeshError(fmt::format("{}: {}", body_where, e.what()));
    } catch (const InputError& e) {
      throw InputError(fmt::format("{}: {}", body_where, e.what()));
    }
    solid::SolidBody& body = world.bodies.back();
    const MatX3& rest = body.rest_positions();
    const Index n = body.num_nodes();

    for (std::size_t k = 0; k < spec.pins.size(); ++k) {
      const PinSpec& pin = spec.pins[k];
      const auto nodes =
          select_nodes(pin.select, rest, fmt::format("{}: bodies[{}].pins[{}]", file, bi, k));
      for (Index v : nodes) {
        for (char c : pin.axes) body.fix_dof(v, c - 'x');
      }
    }
    for (std::size_t k = 0; k < spec.loads.size(); ++k) {
      const LoadSpec& load = spec.loads[k];
      const auto nodes =
          select_nodes(load.select, rest, fmt::format("{}: bodies[{}].loads[{}]", file, bi, k));
      const Vec3 per_node = load.total_force / static_cast<double>(nodes.size());
      for (Index v : nodes) body.applied_force.row(v) += per_node.transpose();
    }
    for (Index v = 0; v < n; ++v) {
      for (int a = 0; a < 3; ++a) {
        if (!body.is_fixed(3 * v + a)) body.velocity(v, a) = spec.initial_velocity[a];
      }
    }
    if (spec.kinematic) {
      constexpr double deg = M_PI / 180.0;
      solid::KinematicMotion motion;
      motion.linear_velocity = spec.kinematic->velocity;
      motion.angular_velocity = spec.kinematic->angular_velocity_deg * deg;
      motion.center = spec.kinematic->center.value_or(rest.colwise().mean().transpose());
      body.kinematic = motion;
      body.set_kinematic_state(world.time);  // t = 0: d = 0, u = v + ω × (X − c)
      logger().info("{}: body '{}': {} nodes, {} tets, kinematic, mass {:.4g} kg", file, spec.name,
                    n, body.num_tets(), body.total_mass());
      continue;
    }
    logger().info("{}: body '{}': {} nodes, {} tets, {} fixed DOFs, mass {:.4g} kg", file,
                  spec.name, n, body.num_tets(), body.num_fixed_dofs(), body.total_mass());
  }

  for (solid::Obstacle o : scene.obstacles) {
    if (o.kind == solid::Obstacle::Kind::Plane) o.normal.normalize();
    world.obstacles.push_back(o);
  }
  if (scene.contact) world.contact = contact_params(scene, world.bodies, file);
  return world;
}

std::string fmt_vec(const Vec3& v) {
  return fmt::format("[{:.6g}, {:.6g}, {:.6g}]", v.x(), v.y(), v.z());
}

OutputPlan output_plan(const Scene& scene) {
  OutputPlan plan;
  plan.compression = scene.output.compression;
  plan.fluid = scene.fluid.has_value();
  plan.two_way = scene.two_way();
  plan.liquid = scene.fluid && scene.fluid->params.liquid.enabled;
  plan.resolved = scene.resolved;
  const auto& formats = scene.output.export_formats;
  const auto has = [&](const char* f) {
    return std::find(formats.begin(), formats.end(), f) != formats.end();
  };
  plan.exports.vdb = has("vdb") && scene.fluid.has_value();
  plan.exports.ply = has("ply");
  plan.exports.voxels.voxel_size = scene.output.voxel_size > 0.0 ? scene.output.voxel_size
                                   : scene.fluid                 ? scene.fluid->sizing.surface_size
                                                                 : 0.05;
  plan.exports.voxels.subsamples = scene.output.voxel_subsamples;
  if (scene.fluid)
    plan.exports.voxels.ambient_temperature = scene.fluid->params.ambient_temperature;
  plan.exports.smoke_threshold = scene.output.smoke_threshold;
  plan.exports.scene = scene.name;
  return plan;
}

}  // namespace tetfsi::app
