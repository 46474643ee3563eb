#include "tools/scene.hpp"

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

namespace tetfsi::tools {

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

json to_json(const Vec3& v) {
  return json::array({v.x(), v.y(), v.z()});
}

json to_json(const Vec2& v) {
  return json::array({v.x(), v.y()});
}

/// Names of the box sides in the order of DomainPatch::side (0..5).
const std::vector<std::string>& side_names() {
  static const std::vector<std::string> names = {"-x", "+x", "-y", "+y", "-z", "+z"};
  return names;
}

/// The boundary kinds a box face or patch may have.
const std::vector<std::string>& boundary_kind_names() {
  static const std::vector<std::string> names = {"wall", "inflow", "open"};
  return names;
}

mesh::FaceKind boundary_kind(const std::string& name) {
  if (name == "inflow") return mesh::FaceKind::Inflow;
  if (name == "open") return mesh::FaceKind::Open;
  return mesh::FaceKind::Wall;
}

/// The two axes of a box side's plane, in increasing order (side ±y: x, z).
std::pair<int, int> side_axes(int side) {
  const int a = side / 2;
  return {a == 0 ? 1 : 0, a == 2 ? 1 : 2};
}

// ---------------------------------------------------------------------------------------------
// The parser: a JSON value plus its path, and typed getters that throw InputError naming both.

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

  double number(const Node& n) const {
    if (!n.j.is_number()) fail(n.path, "expected a number, got " + describe(n.j));
    const double v = n.j.get<double>();
    if (!std::isfinite(v)) fail(n.path, "expected a finite number, got " + describe(n.j));
    return v;
  }
  /// Number at `key` if present, else `fallback`.
  double number(const Node& n, const std::string& key, double fallback) const {
    return has(n, key) ? number(child(n, key)) : fallback;
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
  int integer(const Node& n, const std::string& key, int fallback) const {
    return has(n, key) ? integer(child(n, key)) : fallback;
  }

  std::string string(const Node& n) const {
    if (!n.j.is_string()) fail(n.path, "expected a string, got " + describe(n.j));
    return n.j.get<std::string>();
  }
  std::string string(const Node& n, const std::string& key, const std::string& fallback) const {
    return has(n, key) ? string(child(n, key)) : fallback;
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
  Vec3 vec3(const Node& n, const std::string& key, const Vec3& fallback) const {
    return has(n, key) ? vec3(child(n, key)) : fallback;
  }

  Vec2 vec2(const Node& n) const {
    if (!n.j.is_array() || n.j.size() != 2)
      fail(n.path, "expected an array of 2 numbers, got " + describe(n.j));
    Vec2 v;
    for (int a = 0; a < 2; ++a) v[a] = number({n.j[a], index_path(n.path, a)});
    return v;
  }

  Node require(const Node& n, const std::string& key) const {
    if (!has(n, key)) fail(n.path, fmt::format("missing required key '{}'", key));
    return child(n, key);
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

  // ---- scene parts ----

  /// An object {"lo", "hi"}; `strict`: lo < hi (a solid box), else lo <= hi (a selection box
  /// may be flat, e.g. to pick the nodes of one face).
  BoxSpec box(const Node& n, bool strict) const {
    expect_object(n, {"lo", "hi"});
    return bounds(n, strict);
  }

  /// lo/hi held by `n` (which may hold other keys too).
  BoxSpec bounds(const Node& n, bool strict) const {
    BoxSpec b;
    b.lo = vec3(require(n, "lo"));
    b.hi = vec3(require(n, "hi"));
    for (int a = 0; a < 3; ++a) {
      const bool bad = strict ? b.lo[a] >= b.hi[a] : b.lo[a] > b.hi[a];
      if (bad) {
        fail(n.path, fmt::format("lo must be {} hi in every axis, got lo = {}, hi = {} (axis {})",
                                 strict ? "<" : "<=", fmt_vec(b.lo), fmt_vec(b.hi), "xyz"[a]));
      }
    }
    return b;
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

  /// An integer at `key` (default `fallback`) in lo..hi; `what` says what it counts.
  int bounded_integer(const Node& n, const std::string& key, int fallback, int lo, int hi,
                      const char* what) const {
    const int v = integer(n, key, fallback);
    if (v < lo || v > hi)
      fail(child_path(n.path, key), fmt::format("must be {}..{} ({}), got {}", lo, hi, what, v));
    return v;
  }

  /// A number > 0 at `key` (required).
  double positive(const Node& n, const std::string& key, const char* what) const {
    const Node c = require(n, key);
    const double v = number(c);
    if (v <= 0) fail(c.path, fmt::format("must be > 0 ({}), got {}", what, v));
    return v;
  }

  MeshSpec mesh(const Node& n) const {
    const std::vector<std::string> kinds = {"box",   "file",       "surface", "sphere",
                                            "shell", "hollow_box", "tube"};
    std::vector<std::string> allowed = kinds;
    allowed.push_back("cell_size");
    expect_object(n, allowed);
    std::vector<std::string> given;
    for (const std::string& k : kinds) {
      if (has(n, k)) given.push_back(fmt::format("'{}'", k));
    }
    if (given.size() != 1) {
      const std::string what =
          "give exactly one of 'box', 'file', 'surface', 'sphere', 'shell', 'hollow_box' or "
          "'tube'";
      fail(n.path, given.empty() ? what : what + ", got " + join(given, " and "));
    }
    MeshSpec m;
    if (has(n, "box")) {
      m.kind = MeshSpec::Kind::Box;
      const Node b = child(n, "box");
      expect_object(b, {"lo", "hi", "cells"});
      m.box = bounds(b, true);
      if (has(b, "cells")) m.cells = cells(child(b, "cells"));
    } else if (has(n, "file")) {
      m.kind = MeshSpec::Kind::File;
      m.file = existing_file(child(n, "file"));
    } else if (has(n, "surface")) {
      m.kind = MeshSpec::Kind::Surface;
      m.file = existing_file(child(n, "surface"));
      if (!has(n, "cell_size"))
        fail(n.path, "a 'surface' mesh needs 'cell_size' (> 0, m): the target tet size");
    } else if (has(n, "sphere")) {
      m.kind = MeshSpec::Kind::Sphere;
      const Node b = child(n, "sphere");
      expect_object(b, {"center", "radius", "subdivisions"});
      m.center = vec3(require(b, "center"));
      m.radius = positive(b, "radius", "m");
      m.subdivisions = bounded_integer(b, "subdivisions", m.subdivisions, 0, 6,
                                       "icosphere levels: surface edges about radius / 2^s");
    } else if (has(n, "shell")) {
      m.kind = MeshSpec::Kind::Shell;
      const Node b = child(n, "shell");
      expect_object(b, {"center", "inner_radius", "outer_radius", "subdivisions", "layers"});
      m.center = vec3(require(b, "center"));
      m.inner_radius = positive(b, "inner_radius", "m");
      m.outer_radius = positive(b, "outer_radius", "m");
      if (m.inner_radius >= m.outer_radius) {
        fail(b.path, fmt::format("need inner_radius < outer_radius, got {} and {}; for a solid "
                                 "ball use 'sphere'",
                                 m.inner_radius, m.outer_radius));
      }
      m.subdivisions = bounded_integer(b, "subdivisions", m.subdivisions, 0, 7,
                                       "icosphere levels: surface edges about radius / 2^s");
      m.layers = bounded_integer(b, "layers", m.layers, 1, 10000, "tets across the wall: 3 each");
    } else if (has(n, "tube")) {
      m.kind = MeshSpec::Kind::Tube;
      const Node b = child(n, "tube");
      expect_object(b, {"center", "axis", "inner_radius", "outer_radius", "length", "cells"});
      m.center = vec3(require(b, "center"));
      if (has(b, "axis")) {
        const std::string a = choice(child(b, "axis"), {"x", "y", "z"}, "axis");
        m.axis = a[0] - 'x';
      }
      m.inner_radius = positive(b, "inner_radius", "m");
      m.outer_radius = positive(b, "outer_radius", "m");
      if (m.inner_radius >= m.outer_radius) {
        fail(child_path(b.path, "inner_radius"),
             fmt::format("must be < outer_radius, got inner_radius {} and outer_radius {}",
                         m.inner_radius, m.outer_radius));
      }
      m.length = positive(b, "length", "m, along the axis");
      const Node c = require(b, "cells");
      m.cells = cells(c);
      if (m.cells[1] < 6) {
        fail(index_path(c.path, 1),
             fmt::format("must be >= 6 (sectors around the axis), got {}", m.cells[1]));
      }
    } else {
      m.kind = MeshSpec::Kind::HollowBox;
      const Node b = child(n, "hollow_box");
      expect_object(b, {"lo", "hi", "thickness", "cells"});
      m.box = bounds(b, true);
      m.thickness = positive(b, "thickness", "m, the wall on each of the 6 sides");
      for (int a = 0; a < 3; ++a) {
        if (2 * m.thickness >= m.box.hi[a] - m.box.lo[a]) {
          fail(child_path(b.path, "thickness"),
               fmt::format("two walls of {} m leave no cavity in {} (the box is {} m wide "
                           "there); use a thinner wall or a larger box",
                           m.thickness, "xyz"[a], m.box.hi[a] - m.box.lo[a]));
        }
      }
      if (has(b, "cells")) m.cells = cells(child(b, "cells"));
    }
    if (has(n, "cell_size")) {
      const Node c = child(n, "cell_size");
      if (m.kind != MeshSpec::Kind::Surface)
        fail(c.path, "cell_size applies only to a 'surface' mesh");
      m.cell_size = number(c);
      if (m.cell_size <= 0) fail(c.path, fmt::format("must be > 0 (m), got {}", m.cell_size));
    }
    return m;
  }

  TransformSpec transform(const Node& n) const {
    expect_object(n, {"scale", "rotate_deg", "translate"});
    TransformSpec t;
    t.scale = number(n, "scale", t.scale);
    if (t.scale <= 0)
      fail(child_path(n.path, "scale"), fmt::format("must be > 0, got {}", t.scale));
    t.rotate_deg = vec3(n, "rotate_deg", t.rotate_deg);
    t.translate = vec3(n, "translate", t.translate);
    return t;
  }

  solid::Material material(const Node& n) const {
    expect_object(
        n, {"density", "youngs_modulus", "poisson_ratio", "rayleigh_alpha", "rayleigh_beta"});
    solid::Material m;
    auto positive = [&](const char* key, double& v, const char* unit) {
      v = number(n, key, v);
      if (v <= 0) fail(child_path(n.path, key), fmt::format("must be > 0 ({}), got {}", unit, v));
    };
    positive("density", m.density, "kg/m^3");
    positive("youngs_modulus", m.youngs_modulus, "Pa");
    m.poisson_ratio = number(n, "poisson_ratio", m.poisson_ratio);
    const std::string nu_path = child_path(n.path, "poisson_ratio");
    if (m.poisson_ratio >= 0.5) {
      fail(nu_path,
           fmt::format("must be < 0.5, got {} (0.5 is incompressible and locks linear tets; "
                       "use at most 0.49)",
                       m.poisson_ratio));
    }
    if (m.poisson_ratio <= -1.0) {
      fail(nu_path, fmt::format("must be > -1, got {} (-1 or less makes the material unstable)",
                                m.poisson_ratio));
    }
    for (const char* key : {"rayleigh_alpha", "rayleigh_beta"}) {
      double& v = std::string(key) == "rayleigh_alpha" ? m.rayleigh_alpha : m.rayleigh_beta;
      v = number(n, key, v);
      if (v < 0)
        fail(child_path(n.path, key),
             fmt::format("must be >= 0 (negative damping adds energy), got {}", v));
    }
    return m;
  }

  /// Either "box" or "nodes" (exactly one) from an object that may hold other keys too.
  NodeSelection selection(const Node& n) const {
    const bool b = has(n, "box"), l = has(n, "nodes");
    if (b == l)
      fail(n.path,
           b ? "give either 'box' or 'nodes', not both" : "give 'box' or 'nodes' to select nodes");
    NodeSelection s;
    if (b) {
      s.box = box(child(n, "box"), false);
    } else {
      const Node list = child(n, "nodes");
      if (!list.j.is_array() || list.j.empty()) {
        fail(list.path, "expected a non-empty array of node indices, got " + describe(list.j));
      }
      for (std::size_t i = 0; i < list.j.size(); ++i) {
        const Node e{list.j[i], index_path(list.path, i)};
        const int v = integer(e);
        if (v < 0) fail(e.path, fmt::format("node indices are >= 0, got {}", v));
        s.nodes.push_back(v);
      }
    }
    return s;
  }

  PinSpec pin(const Node& n) const {
    expect_object(n, {"box", "nodes", "axes"});
    PinSpec p;
    p.select = selection(n);
    p.axes = string(n, "axes", p.axes);
    bool ok = !p.axes.empty();
    std::set<char> seen;
    for (char c : p.axes) ok = ok && (c == 'x' || c == 'y' || c == 'z') && seen.insert(c).second;
    if (!ok)
      fail(child_path(n.path, "axes"),
           fmt::format("must be a non-empty subset of \"xyz\" (e.g. \"xz\"), got \"{}\"", p.axes));
    return p;
  }

  LoadSpec load(const Node& n) const {
    expect_object(n, {"box", "nodes", "total_force"});
    LoadSpec l;
    l.select = selection(n);
    l.total_force = vec3(require(n, "total_force"));
    return l;
  }

  KinematicSpec kinematic(const Node& n) const {
    expect_object(n, {"velocity", "angular_velocity_deg", "center"});
    KinematicSpec k;
    k.velocity = vec3(n, "velocity", k.velocity);
    k.angular_velocity_deg = vec3(n, "angular_velocity_deg", k.angular_velocity_deg);
    if (has(n, "center")) k.center = vec3(child(n, "center"));
    return k;
  }

  BodySpec body(const Node& n) const {
    expect_object(n, {"name", "mesh", "transform", "material", "pins", "loads", "initial_velocity",
                      "kinematic"});
    BodySpec b;
    b.name = string(require(n, "name"));
    if (b.name.empty()) fail(child_path(n.path, "name"), "must not be empty");
    b.mesh = mesh(require(n, "mesh"));
    if (has(n, "transform")) b.transform = transform(child(n, "transform"));
    if (has(n, "material")) b.material = material(child(n, "material"));
    for (const char* key : {"pins", "loads"}) {
      if (!has(n, key)) continue;
      const Node list = child(n, key);
      if (!list.j.is_array()) fail(list.path, "expected an array, got " + describe(list.j));
      for (std::size_t i = 0; i < list.j.size(); ++i) {
        const Node e{list.j[i], index_path(list.path, i)};
        if (std::string(key) == "pins")
          b.pins.push_back(pin(e));
        else
          b.loads.push_back(load(e));
      }
    }
    b.initial_velocity = vec3(n, "initial_velocity", b.initial_velocity);
    if (has(n, "kinematic")) {
      b.kinematic = kinematic(child(n, "kinematic"));
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
    solid::Obstacle o;
    const std::string type = choice(require(n, "type"), {"plane", "box"}, "obstacle type");
    if (type == "plane") {
      expect_object(n, {"type", "name", "point", "normal", "restitution", "friction"});
      o.kind = solid::Obstacle::Kind::Plane;
      o.point = vec3(n, "point", o.point);
      o.normal = vec3(n, "normal", o.normal);
      if (o.normal.norm() < 1e-12) fail(child_path(n.path, "normal"), "must not be zero");
    } else {
      expect_object(n, {"type", "name", "lo", "hi", "restitution", "friction"});
      o.kind = solid::Obstacle::Kind::Box;
      const BoxSpec b = bounds(n, true);
      o.lo = b.lo;
      o.hi = b.hi;
    }
    o.name = string(n, "name", fmt::format("{}{}", type, index));
    o.restitution = number(n, "restitution", o.restitution);
    if (o.restitution < 0 || o.restitution > 1) {
      fail(child_path(n.path, "restitution"),
           fmt::format("must be in [0, 1], got {}", o.restitution));
    }
    o.friction = number(n, "friction", o.friction);
    if (o.friction < 0)
      fail(child_path(n.path, "friction"), fmt::format("must be >= 0, got {}", o.friction));
    return o;
  }

  /// A patch of the fluid box and what happens on it; `box` is the domain, for the overlap
  /// check.
  mesh::DomainPatch patch(const Node& n, std::size_t index, const BoxSpec& box,
                          fluid::PatchConditions& conditions) const {
    expect_object(
        n, {"name", "kind", "side", "lo", "hi", "speed", "smoke", "temperature", "pressure"});
    mesh::DomainPatch pa;
    pa.name = string(n, "name", fmt::format("patch{}", index));
    if (pa.name.empty()) fail(child_path(n.path, "name"), "must not be empty");
    pa.kind = boundary_kind(choice(require(n, "kind"), boundary_kind_names(), "boundary kind"));
    const std::string side = choice(require(n, "side"), side_names(), "side");
    pa.side = static_cast<int>(std::find(side_names().begin(), side_names().end(), side) -
                               side_names().begin());
    pa.lo = vec2(require(n, "lo"));
    pa.hi = vec2(require(n, "hi"));
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
    // Conditions: each key belongs to one kind of patch.
    fluid::PatchConditions& pc = conditions;
    const std::string kind = mesh::to_string(pa.kind);
    const auto only_on = [&](const char* key, mesh::FaceKind k) {
      if (has(n, key) && pa.kind != k)
        fail(child_path(n.path, key),
             fmt::format("applies only to an {} patch (this one is {})", mesh::to_string(k), kind));
    };
    for (const char* key : {"speed", "smoke", "temperature"}) only_on(key, mesh::FaceKind::Inflow);
    only_on("pressure", mesh::FaceKind::Open);
    pc.inflow_speed = non_negative(n, "speed", pc.inflow_speed, " (m/s into the domain)");
    pc.smoke_density = non_negative(n, "smoke", pc.smoke_density, " (kg/m^3)");
    if (has(n, "temperature")) {
      pc.temperature = number(child(n, "temperature"));
      pc.emits_temperature = true;
    }
    pc.pressure = number(n, "pressure", pc.pressure);
    // The nominal area: the rectangle clipped to the box side. The fluid scales the inflow so
    // that the flux is speed × this area whatever faces the mesh puts on the patch.
    pc.area = (pa.hi.cwiseMin(face_hi) - pa.lo.cwiseMax(face_lo)).prod();
    return pa;
  }

  /// Number at `key` (or `fallback`) that must be >= 0; `unit` is " (m)" or "".
  double non_negative(const Node& n, const std::string& key, double fallback,
                      const std::string& unit) const {
    const double v = number(n, key, fallback);
    if (v < 0) fail(child_path(n.path, key), fmt::format("must be >= 0{}, got {}", unit, v));
    return v;
  }

  /// A volume source of smoke and heat; `box` is the fluid domain, for the overlap check.
  fluid::SmokeSource source(const Node& n, std::size_t index, const BoxSpec& domain) const {
    expect_object(n, {"name", "box", "smoke", "temperature"});
    fluid::SmokeSource src;
    src.name = string(n, "name", fmt::format("source{}", index));
    if (src.name.empty()) fail(child_path(n.path, "name"), "must not be empty");
    const Node bn = require(n, "box");
    const BoxSpec b = box(bn, true);
    const bool overlaps =
        (b.lo.array() < domain.hi.array()).all() && (b.hi.array() > domain.lo.array()).all();
    if (!overlaps)
      fail(bn.path, fmt::format("the box {}..{} misses the fluid box {}..{}", fmt_vec(b.lo),
                                fmt_vec(b.hi), fmt_vec(domain.lo), fmt_vec(domain.hi)));
    src.lo = b.lo;
    src.hi = b.hi;
    src.smoke_density = non_negative(n, "smoke", src.smoke_density, " (kg/m^3)");
    if (has(n, "temperature")) {
      src.temperature = number(child(n, "temperature"));
      src.emits_temperature = true;
    }
    return src;
  }

  /// The fluid section; `gravity` is the scene's (for FluidParams::gravity and ::up).
  FluidSpec fluid(const Node& n, const Vec3& gravity) const {
    expect_object(n, {"domain", "mesh", "density", "enclosed_density", "gravity", "buoyancy",
                      "vorticity_confinement", "decay", "reconstruction", "min_dual_fraction",
                      "solver", "sources", "refine"});
    FluidSpec f;
    fluid::FluidParams& fp = f.params;
    const Node d = require(n, "domain");
    expect_object(d, {"lo", "hi", "default", "patches"});
    const BoxSpec box = bounds(d, true);
    f.domain.lo = box.lo;
    f.domain.hi = box.hi;
    if (has(d, "default"))
      f.domain.default_kind =
          boundary_kind(choice(child(d, "default"), boundary_kind_names(), "boundary kind"));
    if (has(d, "patches")) {
      const Node list = child(d, "patches");
      if (!list.j.is_array()) fail(list.path, "expected an array, got " + describe(list.j));
      for (std::size_t i = 0; i < list.j.size(); ++i) {
        const std::string where = index_path(list.path, i);
        fluid::PatchConditions pc;
        mesh::DomainPatch pa = patch({list.j[i], where}, i, box, pc);
        for (std::size_t k = 0; k < f.domain.patches.size(); ++k) {
          if (f.domain.patches[k].name == pa.name)
            fail(where + ".name",
                 fmt::format("duplicate patch name '{}' (also {}[{}])", pa.name, list.path, k));
        }
        f.domain.patches.push_back(std::move(pa));
        fp.patches.push_back(pc);
      }
    }
    if (has(n, "mesh")) {
      const Node m = child(n, "mesh");
      expect_object(m, {"surface_size", "far_size", "grading", "max_cells"});
      mesh::Sizing& z = f.sizing;
      auto positive = [&](const char* key, double& v, const char* unit) {
        v = number(m, key, v);
        if (v <= 0) fail(child_path(m.path, key), fmt::format("must be > 0{}, got {}", unit, v));
      };
      positive("surface_size", z.surface_size, " (m)");
      positive("far_size", z.far_size, " (m)");
      positive("grading", z.grading, " (m of cell size per m of distance)");
      if (z.surface_size > z.far_size)
        fail(child_path(m.path, "surface_size"),
             fmt::format("must be <= far_size ({} m), got {} m", z.far_size, z.surface_size));
      z.max_cells = integer(m, "max_cells", z.max_cells);
      if (z.max_cells < 0)
        fail(child_path(m.path, "max_cells"),
             fmt::format("must be >= 0 (0: no budget), got {}", z.max_cells));
    }

    // Physics.
    fp.density = number(n, "density", fp.density);
    if (fp.density <= 0)
      fail(child_path(n.path, "density"), fmt::format("must be > 0 (kg/m^3), got {}", fp.density));
    fp.enclosed_density = non_negative(n, "enclosed_density", fp.enclosed_density,
                                       " (kg/m^3; 0: the same as density)");
    if (has(n, "gravity")) {
      const Node g = child(n, "gravity");
      if (!g.j.is_boolean())
        fail(g.path,
             "expected true (the fluid feels the scene's gravity) or false, got " + describe(g.j));
      f.gravity = g.j.get<bool>();
    }
    fp.gravity = f.gravity ? gravity : Vec3::Zero();
    for (int a = 0; a < 3; ++a)  // the box corner highest against gravity
      fp.hydrostatic_origin[a] = fp.gravity[a] < 0 ? f.domain.hi[a] : f.domain.lo[a];
    const double g_norm = gravity.norm();
    fp.up = g_norm > 0 ? Vec3(-gravity / g_norm) : Vec3(Vec3::UnitZ());
    if (has(n, "buoyancy")) {
      const Node b = child(n, "buoyancy");
      expect_object(b, {"alpha", "beta", "ambient_temperature"});
      fp.buoyancy_alpha = non_negative(b, "alpha", fp.buoyancy_alpha, " (m^4/(kg s^2))");
      fp.buoyancy_beta = non_negative(b, "beta", fp.buoyancy_beta, " (m/(s^2 K))");
      fp.ambient_temperature = number(b, "ambient_temperature", fp.ambient_temperature);
    }
    fp.vorticity_confinement =
        non_negative(n, "vorticity_confinement", fp.vorticity_confinement, "");
    if (has(n, "decay")) {
      const Node d2 = child(n, "decay");
      expect_object(d2, {"smoke", "temperature"});
      fp.smoke_decay = non_negative(d2, "smoke", fp.smoke_decay, " (1/s)");
      fp.temperature_decay = non_negative(d2, "temperature", fp.temperature_decay, " (1/s)");
    }
    if (has(n, "reconstruction")) {
      fp.reconstruction = fluid::parse_reconstruction(
          choice(child(n, "reconstruction"), {"vertex_ls", "whitney"}, "velocity reconstruction"));
    }
    fp.min_dual_fraction = number(n, "min_dual_fraction", fp.min_dual_fraction);
    if (fp.min_dual_fraction <= 0 || fp.min_dual_fraction > 0.1)
      fail(child_path(n.path, "min_dual_fraction"),
           fmt::format(
               "must be in (0, 0.1] (a fraction of the face's mean edge; default 1e-6), got {}",
               fp.min_dual_fraction));
    if (has(n, "solver")) {
      const Node o = child(n, "solver");
      expect_object(o, {"linear", "rel_tol", "max_iterations"});
      if (has(o, "linear"))
        fp.solver = parse_solver_kind(choice(child(o, "linear"), solver_names(), "linear solver"));
      fp.solver_rel_tol = number(o, "rel_tol", fp.solver_rel_tol);
      if (fp.solver_rel_tol <= 0)
        fail(child_path(o.path, "rel_tol"), fmt::format("must be > 0, got {}", fp.solver_rel_tol));
      fp.solver_max_iterations = integer(o, "max_iterations", fp.solver_max_iterations);
      if (fp.solver_max_iterations < 1)
        fail(child_path(o.path, "max_iterations"),
             fmt::format("must be >= 1, got {}", fp.solver_max_iterations));
    }
    if (has(n, "sources")) {
      const Node list = child(n, "sources");
      if (!list.j.is_array()) fail(list.path, "expected an array, got " + describe(list.j));
      for (std::size_t i = 0; i < list.j.size(); ++i) {
        const std::string where = index_path(list.path, i);
        fluid::SmokeSource src = source({list.j[i], where}, i, box);
        for (std::size_t k = 0; k < fp.sources.size(); ++k) {
          if (fp.sources[k].name == src.name)
            fail(where + ".name",
                 fmt::format("duplicate source name '{}' (also {}[{}])", src.name, list.path, k));
        }
        fp.sources.push_back(std::move(src));
      }
    }
    if (has(n, "refine")) {
      const Node r = child(n, "refine");
      expect_object(r, {"size", "density_threshold", "vorticity_threshold"});
      fluid::RefineParams& rp = fp.refine;
      rp.size = non_negative(r, "size", rp.size, " (m; 0: off)");
      if (rp.size > f.sizing.far_size)
        fail(child_path(r.path, "size"),
             fmt::format("must be <= fluid.mesh.far_size ({} m), got {} m", f.sizing.far_size,
                         rp.size));
      rp.density_threshold =
          non_negative(r, "density_threshold", rp.density_threshold, " (kg/m^3)");
      rp.vorticity_threshold =
          non_negative(r, "vorticity_threshold", rp.vorticity_threshold, " (1/s)");
    }
    return f;
  }

  /// The solid section: the integrator of bodies that step alone and the equilibrium
  /// iteration's options (scene.hpp).
  SolidSpec solid(const Node& n) const {
    expect_object(n, {"integrator", "trapezoid", "rtol", "etol", "stol", "max_iterations",
                      "max_updates", "line_search", "reform"});
    SolidSpec s;
    if (has(n, "integrator")) {
      s.integrator = solid::parse_integrator(
          choice(child(n, "integrator"), {"linearized", "newton", "modified_newton", "bfgs"},
                 "solid integrator"));
    }
    if (has(n, "trapezoid")) {
      const Node t = child(n, "trapezoid");
      if (s.integrator != solid::Integrator::Linearized) {
        fail(t.path, fmt::format("applies only to solid.integrator 'linearized' (the '{}' "
                                 "integrator iterates the full trapezoidal rule); remove it or "
                                 "set solid.integrator to 'linearized'",
                                 solid::to_string(s.integrator)));
      }
      s.trapezoid = choice(t, {"paper", "midpoint"}, "trapezoid variant");
    }
    EquilibriumOptions& e = s.equilibrium;
    auto tolerance = [&](const char* key, double& v, const char* what) {
      v = number(n, key, v);
      if (v <= 0) fail(child_path(n.path, key), fmt::format("must be > 0 ({}), got {}", what, v));
    };
    tolerance("rtol", e.rtol, "out-of-balance force tolerance, [BatheSonnad80, Eq. (12)]");
    tolerance("etol", e.etol, "energy tolerance, Eq. (13)");
    e.stol = number(n, "stol", e.stol);
    if (!(e.stol > 0 && e.stol < 1))
      fail(child_path(n.path, "stol"),
           fmt::format("must be in (0, 1) (line-search tolerance, Eq. (10)), got {}", e.stol));
    auto count = [&](const char* key, int& v, const char* what) {
      v = integer(n, key, v);
      if (v < 1) fail(child_path(n.path, key), fmt::format("must be >= 1 ({}), got {}", what, v));
    };
    count("max_iterations", e.max_iterations, "equilibrium iterations per step");
    count("max_updates", e.max_updates, "BFGS updates before the matrix is re-formed");
    if (has(n, "line_search")) {
      const Node v = child(n, "line_search");
      if (!v.j.is_boolean())
        fail(v.path, "expected true (a line search, Eq. (9)) or false (step length 1), got " +
                         describe(v.j));
      e.line_search = v.j.get<bool>();
    }
    if (has(n, "reform")) {
      // modified Newton and BFGS: the starting matrix of every step, or the first one kept
      e.keep_matrix = choice(child(n, "reform"), {"step", "run"}, "reform") == "run";
    }
    return s;
  }

  /// The coupling section (`n` may be null: not given). `deformable`: the scene has a
  /// non-kinematic body; `dynamic`: its mode. Only called for a scene with a fluid.
  CouplingSpec coupling_spec(const Node* n, bool deformable, bool dynamic) const {
    CouplingSpec c;
    c.two_way = deformable && dynamic;  // the default, DESIGN.md §2: the simultaneous solve
    if (!n) return c;
    expect_object(*n, {"scheme", "solver", "rel_tol", "max_iterations", "conserve_volume"});
    if (has(*n, "scheme")) {
      const std::string s =
          choice(child(*n, "scheme"),
                 {"simultaneous", "splitting", "bfgs", "modified_newton", "newton", "none"},
                 "coupling scheme");
      c.two_way = s != "none";
      if (c.two_way) c.params.scheme = coupling::parse_scheme(s);
    }
    coupling::CoupledOptions& o = c.params.solve;
    if (has(*n, "solver"))
      o.solver = coupling::parse_coupled_solver(
          choice(child(*n, "solver"), coupling::coupled_solver_names(), "coupled solver"));
    o.rel_tol = number(*n, "rel_tol", o.rel_tol);
    if (o.rel_tol <= 0)
      fail(child_path(n->path, "rel_tol"), fmt::format("must be > 0, got {}", o.rel_tol));
    o.max_iterations = integer(*n, "max_iterations", o.max_iterations);
    if (o.max_iterations < 1)
      fail(child_path(n->path, "max_iterations"),
           fmt::format("must be >= 1, got {}", o.max_iterations));
    if (has(*n, "conserve_volume")) {
      const Node v = child(*n, "conserve_volume");
      if (!v.j.is_boolean())
        fail(v.path,
             "expected true (enclosed regions keep their volume) or false, got " + describe(v.j));
      o.conserve_volume = v.j.get<bool>();
    }
    return c;
  }

 private:
  std::string m_file;
  fs::path m_folder;
};

// ---------------------------------------------------------------------------------------------
// Scene → JSON with every default filled in.

json selection_json(const NodeSelection& s) {
  json j = json::object();
  if (s.box)
    j["box"] = {{"lo", to_json(s.box->lo)}, {"hi", to_json(s.box->hi)}};
  else
    j["nodes"] = s.nodes;
  return j;
}

json resolve(const Scene& s) {
  json j;
  j["name"] = s.name;
  if (!s.description.empty()) j["description"] = s.description;
  j["mode"] = s.mode == Mode::Static ? "static" : "dynamic";
  j["time"] = {{"dt", s.time.dt}};
  if (s.time.steps)
    j["time"]["steps"] = *s.time.steps;
  else
    j["time"]["end_time"] = s.time.end_time.value_or(1.0);
  j["output"] = {{"every", s.output.every}, {"compression", s.output.compression}};
  j["gravity"] = to_json(s.gravity);
  j["solver"] = {{"linear", s.solver.linear},
                 {"rel_tol", s.solver.rel_tol},
                 {"max_iterations", s.solver.max_iterations}};
  const EquilibriumOptions& e = s.solid.equilibrium;
  j["solid"] = {{"integrator", solid::to_string(s.solid.integrator)},
                {"rtol", e.rtol},
                {"etol", e.etol},
                {"stol", e.stol},
                {"max_iterations", e.max_iterations},
                {"max_updates", e.max_updates},
                {"line_search", e.line_search},
                {"reform", e.keep_matrix ? "run" : "step"}};
  // only the linearized integrator has variants (and takes the key); the iterated coupled
  // schemes take the full trapezoidal rule
  if (s.solid.integrator == solid::Integrator::Linearized &&
      !(s.two_way() && coupling::is_iterated(s.coupling->params.scheme)))
    j["solid"]["trapezoid"] = s.solid.trapezoid;
  j["static"] = {{"load_steps", s.statics.load_steps},
                 {"rel_tol", s.statics.rel_tol},
                 {"max_iterations", s.statics.max_iterations}};
  j["bodies"] = json::array();
  for (const BodySpec& b : s.bodies) {
    json jb;
    jb["name"] = b.name;
    switch (b.mesh.kind) {
      case MeshSpec::Kind::Box:
        jb["mesh"] = {{"box",
                       {{"lo", to_json(b.mesh.box.lo)},
                        {"hi", to_json(b.mesh.box.hi)},
                        {"cells", {b.mesh.cells.x(), b.mesh.cells.y(), b.mesh.cells.z()}}}}};
        break;
      case MeshSpec::Kind::File:
        jb["mesh"] = {{"file", b.mesh.file.string()}};
        break;
      case MeshSpec::Kind::Surface:
        jb["mesh"] = {{"surface", b.mesh.file.string()}, {"cell_size", b.mesh.cell_size}};
        break;
      case MeshSpec::Kind::Sphere:
        jb["mesh"] = {{"sphere",
                       {{"center", to_json(b.mesh.center)},
                        {"radius", b.mesh.radius},
                        {"subdivisions", b.mesh.subdivisions}}}};
        break;
      case MeshSpec::Kind::Shell:
        jb["mesh"] = {{"shell",
                       {{"center", to_json(b.mesh.center)},
                        {"inner_radius", b.mesh.inner_radius},
                        {"outer_radius", b.mesh.outer_radius},
                        {"subdivisions", b.mesh.subdivisions},
                        {"layers", b.mesh.layers}}}};
        break;
      case MeshSpec::Kind::HollowBox:
        jb["mesh"] = {{"hollow_box",
                       {{"lo", to_json(b.mesh.box.lo)},
                        {"hi", to_json(b.mesh.box.hi)},
                        {"thickness", b.mesh.thickness},
                        {"cells", {b.mesh.cells.x(), b.mesh.cells.y(), b.mesh.cells.z()}}}}};
        break;
      case MeshSpec::Kind::Tube:
        jb["mesh"] = {{"tube",
                       {{"center", to_json(b.mesh.center)},
                        {"axis", std::string(1, "xyz"[b.mesh.axis])},
                        {"inner_radius", b.mesh.inner_radius},
                        {"outer_radius", b.mesh.outer_radius},
                        {"length", b.mesh.length},
                        {"cells", {b.mesh.cells.x(), b.mesh.cells.y(), b.mesh.cells.z()}}}}};
        break;
    }
    jb["transform"] = {{"scale", b.transform.scale},
                       {"rotate_deg", to_json(b.transform.rotate_deg)},
                       {"translate", to_json(b.transform.translate)}};
    jb["material"] = {{"density", b.material.density},
                      {"youngs_modulus", b.material.youngs_modulus},
                      {"poisson_ratio", b.material.poisson_ratio},
                      {"rayleigh_alpha", b.material.rayleigh_alpha},
                      {"rayleigh_beta", b.material.rayleigh_beta}};
    jb["pins"] = json::array();
    for (const PinSpec& p : b.pins) {
      json jp = selection_json(p.select);
      jp["axes"] = p.axes;
      jb["pins"].push_back(jp);
    }
    jb["loads"] = json::array();
    for (const LoadSpec& l : b.loads) {
      json jl = selection_json(l.select);
      jl["total_force"] = to_json(l.total_force);
      jb["loads"].push_back(jl);
    }
    jb["initial_velocity"] = to_json(b.initial_velocity);
    if (b.kinematic) {
      jb["kinematic"] = {{"velocity", to_json(b.kinematic->velocity)},
                         {"angular_velocity_deg", to_json(b.kinematic->angular_velocity_deg)}};
      if (b.kinematic->center) jb["kinematic"]["center"] = to_json(*b.kinematic->center);
    }
    j["bodies"].push_back(jb);
  }
  j["obstacles"] = json::array();
  for (const solid::Obstacle& o : s.obstacles) {
    json jo;
    if (o.kind == solid::Obstacle::Kind::Plane) {
      jo = {{"type", "plane"}, {"point", to_json(o.point)}, {"normal", to_json(o.normal)}};
    } else {
      jo = {{"type", "box"}, {"lo", to_json(o.lo)}, {"hi", to_json(o.hi)}};
    }
    jo["name"] = o.name;
    jo["restitution"] = o.restitution;
    jo["friction"] = o.friction;
    j["obstacles"].push_back(jo);
  }
  if (s.fluid) {
    const mesh::FluidDomain& d = s.fluid->domain;
    const fluid::FluidParams& fp = s.fluid->params;
    json patches = json::array();
    for (std::size_t i = 0; i < d.patches.size(); ++i) {
      const mesh::DomainPatch& pa = d.patches[i];
      json jp = {{"name", pa.name},
                 {"kind", mesh::to_string(pa.kind)},
                 {"side", side_names().at(static_cast<std::size_t>(pa.side))},
                 {"lo", to_json(pa.lo)},
                 {"hi", to_json(pa.hi)}};
      const fluid::PatchConditions& pc = fp.patches.at(i);
      if (pa.kind == mesh::FaceKind::Inflow) {
        jp["speed"] = pc.inflow_speed;
        jp["smoke"] = pc.smoke_density;
        if (pc.emits_temperature) jp["temperature"] = pc.temperature;
      } else if (pa.kind == mesh::FaceKind::Open) {
        jp["pressure"] = pc.pressure;
      }
      patches.push_back(jp);
    }
    json sources = json::array();
    for (const fluid::SmokeSource& src : fp.sources) {
      json js = {{"name", src.name},
                 {"box", {{"lo", to_json(src.lo)}, {"hi", to_json(src.hi)}}},
                 {"smoke", src.smoke_density}};
      if (src.emits_temperature) js["temperature"] = src.temperature;
      sources.push_back(js);
    }
    const mesh::Sizing& z = s.fluid->sizing;
    j["fluid"] = {{"domain",
                   {{"lo", to_json(d.lo)},
                    {"hi", to_json(d.hi)},
                    {"default", mesh::to_string(d.default_kind)},
                    {"patches", patches}}},
                  {"mesh",
                   {{"surface_size", z.surface_size},
                    {"far_size", z.far_size},
                    {"grading", z.grading},
                    {"max_cells", z.max_cells}}},
                  {"density", fp.density},
                  {"enclosed_density", fp.enclosed_density},
                  {"gravity", s.fluid->gravity},
                  {"buoyancy",
                   {{"alpha", fp.buoyancy_alpha},
                    {"beta", fp.buoyancy_beta},
                    {"ambient_temperature", fp.ambient_temperature}}},
                  {"vorticity_confinement", fp.vorticity_confinement},
                  {"decay", {{"smoke", fp.smoke_decay}, {"temperature", fp.temperature_decay}}},
                  {"reconstruction", fluid::to_string(fp.reconstruction)},
                  {"min_dual_fraction", fp.min_dual_fraction},
                  {"solver",
                   {{"linear", to_string(fp.solver)},
                    {"rel_tol", fp.solver_rel_tol},
                    {"max_iterations", fp.solver_max_iterations}}},
                  {"sources", sources},
                  {"refine",
                   {{"size", fp.refine.size},
                    {"density_threshold", fp.refine.density_threshold},
                    {"vorticity_threshold", fp.refine.vorticity_threshold}}}};
  }
  if (s.coupling) {
    const coupling::CoupledOptions& o = s.coupling->params.solve;
    j["coupling"] = {{"scheme", s.coupling->scheme_name()},
                     {"solver", coupling::to_string(o.solver)},
                     {"rel_tol", o.rel_tol},
                     {"max_iterations", o.max_iterations},
                     {"conserve_volume", o.conserve_volume}};
  }
  return j;
}

}  // namespace

// ---------------------------------------------------------------------------------------------

Scene parse_scene(const json& j, const fs::path& file) {
  const Parser p(file);
  using Node = Parser::Node;
  const Node root{j, ""};
  p.expect_object(root, {"name", "description", "mode", "time", "output", "gravity", "solver",
                         "solid", "static", "bodies", "obstacles", "fluid", "coupling"});

  Scene s;
  s.file = file.empty() ? fs::path() : fs::absolute(file).lexically_normal();
  s.name = p.string(root, "name", file.empty() ? std::string("scene") : file.stem().string());
  if (s.name.empty()) p.fail("name", "must not be empty");
  s.description = p.string(root, "description", "");
  if (Parser::has(root, "mode")) {
    s.mode = p.choice(Parser::child(root, "mode"), {"dynamic", "static"}, "mode") == "static"
                 ? Mode::Static
                 : Mode::Dynamic;
  }

  if (Parser::has(root, "time")) {
    const Node t = Parser::child(root, "time");
    p.expect_object(t, {"dt", "end_time", "steps"});
    s.time.dt = p.number(t, "dt", s.time.dt);
    if (s.time.dt <= 0) p.fail("time.dt", fmt::format("must be > 0 (s), got {}", s.time.dt));
    if (Parser::has(t, "end_time") && Parser::has(t, "steps")) {
      p.fail("time", "give either 'end_time' or 'steps', not both");
    }
    if (Parser::has(t, "end_time")) {
      s.time.end_time = p.number(Parser::child(t, "end_time"));
      if (*s.time.end_time <= 0)
        p.fail("time.end_time", fmt::format("must be > 0 (s), got {}", *s.time.end_time));
    }
    if (Parser::has(t, "steps")) {
      s.time.steps = p.integer(Parser::child(t, "steps"));
      if (*s.time.steps < 1)
        p.fail("time.steps", fmt::format("must be >= 1, got {}", *s.time.steps));
    }
  }
  if (!s.time.steps && !s.time.end_time) s.time.end_time = 1.0;
  if (!s.time.steps && *s.time.end_time / s.time.dt > 1e9) {
    p.fail("time", fmt::format("end_time / dt = {:.3g} steps is more than 1e9: check the units",
                               *s.time.end_time / s.time.dt));
  }

  if (Parser::has(root, "output")) {
    const Node o = Parser::child(root, "output");
    p.expect_object(o, {"every", "compression"});
    s.output.every = p.integer(o, "every", s.output.every);
    if (s.output.every < 1)
      p.fail("output.every", fmt::format("must be >= 1, got {}", s.output.every));
    if (Parser::has(o, "compression")) {
      s.output.compression =
          p.choice(Parser::child(o, "compression"), {"lz4", "zlib", "none"}, "compression");
    }
  }

  s.gravity = p.vec3(root, "gravity", s.gravity);

  if (Parser::has(root, "solver")) {
    const Node o = Parser::child(root, "solver");
    p.expect_object(o, {"linear", "rel_tol", "max_iterations"});
    if (Parser::has(o, "linear")) {
      s.solver.linear = p.choice(Parser::child(o, "linear"), solver_names(), "linear solver");
    }
    s.solver.rel_tol = p.number(o, "rel_tol", s.solver.rel_tol);
    if (s.solver.rel_tol <= 0)
      p.fail("solver.rel_tol", fmt::format("must be > 0, got {}", s.solver.rel_tol));
    s.solver.max_iterations = p.integer(o, "max_iterations", s.solver.max_iterations);
    if (s.solver.max_iterations < 1) {
      p.fail("solver.max_iterations", fmt::format("must be >= 1, got {}", s.solver.max_iterations));
    }
  }

  if (Parser::has(root, "solid")) s.solid = p.solid(Parser::child(root, "solid"));

  if (Parser::has(root, "static")) {
    const Node o = Parser::child(root, "static");
    p.expect_object(o, {"load_steps", "rel_tol", "max_iterations"});
    s.statics.load_steps = p.integer(o, "load_steps", s.statics.load_steps);
    if (s.statics.load_steps < 1)
      p.fail("static.load_steps", fmt::format("must be >= 1, got {}", s.statics.load_steps));
    s.statics.rel_tol = p.number(o, "rel_tol", s.statics.rel_tol);
    if (s.statics.rel_tol <= 0)
      p.fail("static.rel_tol", fmt::format("must be > 0, got {}", s.statics.rel_tol));
    s.statics.max_iterations = p.integer(o, "max_iterations", s.statics.max_iterations);
    if (s.statics.max_iterations < 1) {
      p.fail("static.max_iterations",
             fmt::format("must be >= 1, got {}", s.statics.max_iterations));
    }
  }

  // A fluid-only scene (smoke in a box) needs no body; otherwise there is nothing to simulate.
  const bool has_fluid = Parser::has(root, "fluid");
  static const json no_bodies = json::array();
  const Node bodies = has_fluid && !Parser::has(root, "bodies") ? Node{no_bodies, "bodies"}
                                                                : p.require(root, "bodies");
  if (!bodies.j.is_array())
    p.fail("bodies", "expected an array of bodies, got " + describe(bodies.j));
  if (bodies.j.empty() && !has_fluid)
    p.fail("bodies", "a scene needs at least one body (or a 'fluid' section)");
  for (std::size_t i = 0; i < bodies.j.size(); ++i) {
    BodySpec b = p.body({bodies.j[i], Parser::index_path("bodies", i)});
    for (std::size_t k = 0; k < s.bodies.size(); ++k) {
      if (s.bodies[k].name == b.name) {
        p.fail(Parser::index_path("bodies", i) + ".name",
               fmt::format("duplicate body name '{}' (also bodies[{}])", b.name, k));
      }
    }
    s.bodies.push_back(std::move(b));
  }

  if (Parser::has(root, "obstacles")) {
    const Node obs = Parser::child(root, "obstacles");
    if (!obs.j.is_array()) p.fail("obstacles", "expected an array, got " + describe(obs.j));
    for (std::size_t i = 0; i < obs.j.size(); ++i) {
      s.obstacles.push_back(p.obstacle({obs.j[i], Parser::index_path("obstacles", i)}, i));
    }
  }

  if (has_fluid) s.fluid = p.fluid(Parser::child(root, "fluid"), s.gravity);

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

  s.resolved = resolve(s);
  return s;
}

// ---------------------------------------------------------------------------------------------

namespace {

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
      const std::size_t idx = std::stoul(part);
      if (idx >= cur->size()) {
        bad(fmt::format("index {} is out of range ('{}' has {} element{})", idx, walked,
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
  const std::string text = buffer.str();

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

solid::SolidWorld build_world(const Scene& scene) {
  const std::string file = display_name(scene.file);
  solid::SolidWorld world;
  world.gravity = scene.gravity;
  world.linear_solver = parse_solver_kind(scene.solver.linear);
  world.solver_options.rel_tol = scene.solver.rel_tol;
  world.solver_options.max_iterations = scene.solver.max_iterations;
  world.trapezoid =
      scene.solid.trapezoid == "midpoint" ? solid::Trapezoid::Midpoint : solid::Trapezoid::Paper;
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
  return world;
}

std::string fmt_vec(const Vec3& v) {
  return fmt::format("[{:.6g}, {:.6g}, {:.6g}]", v.x(), v.y(), v.z());
}

}  // namespace tetfsi::tools
