/// @file stats_columns.cpp
/// The tables of stats.csv's columns (stats_columns.hpp).
#include "io/stats_columns.hpp"

#include <algorithm>
#include <tuple>
#include <utility>

#include <fmt/format.h>

#include "mesh/quality.hpp"

namespace tetfsi::app {

namespace {

constexpr StatsFormat I = StatsFormat::Integer;
constexpr StatsFormat X = StatsFormat::Exact;
constexpr StatsFormat S = StatsFormat::Short;

double total_energy(const StepStats& r) {
  return r.total_energy();
}

void append_value(std::string& line, StatsFormat format, double v) {
  if (format == StatsFormat::Exact)
    line += fmt::format(",{:.17g}", v);
  else
    line += fmt::format(",{:.6g}", v);
}

}  // namespace

const std::vector<StatsColumn<StepStats>>& step_head_columns() {
  using R = StepStats;
  static const std::vector<StatsColumn<R>> t = {
      {"step", "", "the step's number, 1-based (0 would be the initial state)", I, &R::step},
      {"time", "s", "the time at the end of the step", X, &R::time},
      {"dt", "s", "the step's length", X, &R::dt},
  };
  return t;
}

const std::vector<StatsColumn<StepStats>>& step_columns() {
  using R = StepStats;
  static const std::vector<StatsColumn<R>> t = {
      {"solver_iterations", "", "iterations of the bodies' linear solve", I, &R::solver_iterations},
      {"solver_residual", "", "its relative residual", X, &R::solver_residual},
      {"contacts", "", "nodes touching obstacles or floors after the step", I, &R::contacts},
      {"kinetic_energy", "J", "the bodies' kinetic energy, summed over bodies", X,
       &R::kinetic_energy},
      {"elastic_energy", "J", "the bodies' elastic energy", X, &R::elastic_energy},
      {"gravity_potential", "J", "the bodies' potential in gravity, -sum m g.x", X,
       &R::gravity_potential},
      {"total_energy", "J", "kinetic + elastic + gravity potential (applied loads' work not in it)",
       X, &total_energy},
      {"equilibrium_iterations", "",
       "directions of the step's equilibrium iteration as [BatheSonnad80] counts them, the most of "
       "any body (0: the linearised integrator, the simultaneous and splitting schemes)",
       I, &R::equilibrium_iterations},
      {"equilibrium_evaluations", "",
       "residual evaluations of that iteration, line searches included", I,
       &R::equilibrium_evaluations},
  };
  return t;
}

const std::vector<StatsColumn<FluidStepStats>>& fluid_mesh_columns() {
  using R = FluidStepStats;
  static const std::vector<StatsColumn<R>> t = {
      {"fluid_cells", "", "fluid cells (tets, or the grid's fluid cells)", I, &R::cells, "cells"},
      {"fluid_vertices", "", "fluid mesh vertices (tet fluid)", I, &R::vertices, "vertices"},
      {"steiner_points", "", "points the remesher added to recover the bodies' faces", I,
       &R::steiner_points, "steiner_points"},
      {"recovery_rounds", "", "rounds of that recovery", I, &R::recovery_rounds, "recovery_rounds"},
      {"remesh_incremental", "", "1: the Delaunay was updated from the last step's, 0: built anew",
       I, &R::remesh_incremental, "remesh_incremental"},
      {"vertices_removed", "", "vertices that update removed", I, &R::vertices_removed,
       "vertices_removed"},
      {"vertices_inserted", "", "vertices it inserted (a new build inserts every vertex)", I,
       &R::vertices_inserted, "vertices_inserted"},
      {"remesh_s", "s", "the remesher's own seconds", S, &R::remesh_s, "remesh_s"},
  };
  return t;
}

const std::vector<StatsColumn<FluidStepStats>>& fluid_step_columns() {
  using R = FluidStepStats;
  static const std::vector<StatsColumn<R>> t = {
      {"pressure_iterations", "", "iterations of the pressure solve", I, &R::pressure_iterations,
       "pressure_iterations"},
      {"pressure_residual", "", "its relative residual", S, &R::pressure_residual,
       "pressure_residual"},
      {"divergence_before", "1/s", "max |D u*| before the projection", X, &R::divergence_before,
       "divergence_before"},
      {"divergence", "1/s", "max |D u| after it", X, &R::divergence, "divergence"},
      {"fluid_kinetic_energy", "J", "the fluid's kinetic energy", X, &R::fluid_kinetic_energy,
       "fluid_kinetic_energy"},
      {"smoke_mass", "kg", "the smoke's mass", X, &R::smoke_mass, "smoke_mass"},
      {"inflow_flux", "m^3/s", "into the box through the inflow patches", X, &R::inflow_flux,
       "inflow_flux"},
      {"outflow_flux", "m^3/s", "out through the open faces", X, &R::outflow_flux, "outflow_flux"},
      {"solid_flux", "m^3/s", "into the solids (0 for rigid motion)", X, &R::solid_flux,
       "solid_flux"},
      {"max_speed", "m/s", "max |u_f| over the faces", X, &R::max_speed, "max_speed"},
      {"cfl", "", "max h |u| / cell size", S, &R::cfl, "cfl"},
      {"traces_clamped", "", "back-traces stopped at a wall or solid", I, &R::traces_clamped,
       "traces_clamped"},
  };
  return t;
}

const std::vector<StatsColumn<CoupledStepStats>>& coupled_columns() {
  using R = CoupledStepStats;
  static const std::vector<StatsColumn<R>> t = {
      {"coupled_iterations", "", "iterations of the coupled solve (1 for LU)", I, &R::iterations,
       "iterations"},
      {"coupled_residual", "", "its worst relative residual", S, &R::residual, "residual"},
      {"interface_power", "W",
       "p^T J^T u: the dynamic pressure's power on the free bodies (0 in the splitting scheme)", X,
       &R::interface_power, "interface_power"},
      {"total_energy_coupled", "J", "fluid kinetic + solid kinetic + elastic after the step", X,
       &R::total_energy, "total_energy"},
      {"enclosed_volume", "m^3",
       "the liquid sealed in bodies (the enclosed regions' volume) after the step", X,
       &R::enclosed_volume, "enclosed_volume"},
      {"enclosed_volume_drift", "", "max over enclosed regions of |after - target| / target", S,
       &R::enclosed_volume_drift, "enclosed_volume_drift"},
      {"contact_rounds", "",
       "solves of the step's floor active set (1: it held at once; 0: iterated schemes)", I,
       &R::contact_rounds},
  };
  return t;
}

const std::vector<StatsColumn<solid::BodyPose>>& body_columns() {
  using R = solid::BodyPose;
  static const std::vector<StatsColumn<R>> t = {
      {"_lowest", "m",
       "the body's lowest point, min over its nodes of x . up (up = -g/|g|; +z without gravity)", X,
       &R::lowest},
      {"_centroid_height", "m", "its lumped-mass centroid along up", X, &R::centroid_height},
      {"_rotation_deg", "deg",
       "the angle (0..180) of its rotation from rest: the R of the polar decomposition of sum m (x "
       "- c)(X - C)^T",
       X, &R::rotation_deg},
  };
  return t;
}

const std::vector<StatsColumn<ContactStepStats>>& contact_columns() {
  using R = ContactStepStats;
  static const std::vector<StatsColumn<R>> t = {
      {"contact_pairs", "", "contact constraints between bodies after the step", I, &R::pairs},
      {"contact_min_gap", "m",
       "the smallest distance between surface primitives of different bodies, or a body's "
       "non-neighbouring ones (capped at 4 d_hat)",
       X, &R::min_gap},
      {"contact_force", "N", "the sum of the pairs' normal forces", X, &R::force},
      {"contact_crossings", "", "pairs the continuous check caught crossing", I, &R::crossings},
      {"contact_solves", "", "solves of the step with the contacts in them", I, &R::rounds},
      {"contact_s", "s", "contact detection and assembly", S, &R::seconds},
  };
  return t;
}

const std::vector<StatsColumn<FluidStepStats>>& liquid_columns() {
  using R = FluidStepStats;
  static const std::vector<StatsColumn<R>> t = {
      {"liquid_volume", "m^3", "where the level set (trilinear) is negative", X, &R::liquid_volume},
      {"liquid_volume_drift", "",
       "against what the particles carry: the first volume plus what was emitted less what drained",
       X, &R::liquid_volume_drift},
      {"liquid_shift", "m", "how far the volume hold moved the surface, on average (> 0 inwards)",
       X, &R::liquid_shift},
      {"liquid_area", "m^2", "the free surface's area", X, &R::liquid_area},
      {"liquid_particles", "", "the liquid's particles", I, &R::liquid_particles},
      {"liquid_advect_s", "s", "surface tracking in transfer: particles moved, separated, emitted",
       S, &R::liquid_advect_s},
      {"liquid_surface_s", "s", "surface tracking in transfer: level set, free surface", S,
       &R::liquid_surface_s},
      {"liquid_p2g_s", "s", "surface tracking in transfer: particles to faces, extrapolation", S,
       &R::liquid_p2g_s},
  };
  return t;
}

const std::vector<PhaseColumn>& phase_columns(bool fluid, bool coupled) {
  static const PhaseColumn assemble{"assemble", "the bodies' matrices and right-hand sides"};
  static const PhaseColumn solve{"solve", "the bodies' linear solves"};
  static const PhaseColumn update{"update",
                                  "positions, velocities, collisions [Chentanez06, "
                                  "Eq. (5)]"};
  static const PhaseColumn remesh{"remesh",
                                  "the bodies' surfaces gathered and the fluid "
                                  "remeshed (or the grid reclassified)"};
  static const PhaseColumn transfer{"transfer", "the fluid advected onto the step's mesh"};
  static const PhaseColumn forces{"forces", "body forces and sources"};
  static const PhaseColumn p_assembly{"pressure_assembly", "the pressure matrix (one-way)"};
  static const PhaseColumn p_solve{"pressure_solve", "the pressure solve (one-way)"};
  static const PhaseColumn c_assembly{"coupled_assembly",
                                      "the bodies' Eq. (4) and the coupled "
                                      "matrix"};
  static const PhaseColumn c_solve{"coupled_solve", "the coupled solve [Chentanez06, Eq. (7)]"};
  static const PhaseColumn solid{"solid", "the bodies' own solves (time splitting)"};
  static const PhaseColumn output{"output", "frames written (fluid: and the mesh's quality)"};
  static const PhaseColumn total{"total", "the whole step"};
  static const std::vector<PhaseColumn> p = {assemble, solve, update, output, total};
  static const std::vector<PhaseColumn> pf = {assemble, solve,      update,  remesh, transfer,
                                              forces,   p_assembly, p_solve, output, total};
  static const std::vector<PhaseColumn> pc = {remesh, transfer, forces, c_assembly, c_solve,
                                              solid,  update,   output, total};
  return fluid ? (coupled ? pc : pf) : p;
}

template <class R>
void append_stats(std::string& line, const std::vector<StatsColumn<R>>& table, const R& r) {
  for (const StatsColumn<R>& c : table) {
    if (auto* m = std::get_if<int R::*>(&c.field))
      line += fmt::format(",{}", r.**m);
    else if (auto* d = std::get_if<double R::*>(&c.field))
      append_value(line, c.format, r.**d);
    else
      append_value(line, c.format, std::get<double (*)(const R&)>(c.field)(r));
  }
}

template <class R>
void append_nan(std::string& line, const std::vector<StatsColumn<R>>& table) {
  for (size_t k = 0; k < table.size(); ++k) line += ",nan";
}

template void append_stats(std::string&, const std::vector<StatsColumn<StepStats>>&,
                           const StepStats&);
template void append_stats(std::string&, const std::vector<StatsColumn<FluidStepStats>>&,
                           const FluidStepStats&);
template void append_stats(std::string&, const std::vector<StatsColumn<CoupledStepStats>>&,
                           const CoupledStepStats&);
template void append_stats(std::string&, const std::vector<StatsColumn<solid::BodyPose>>&,
                           const solid::BodyPose&);
template void append_stats(std::string&, const std::vector<StatsColumn<ContactStepStats>>&,
                           const ContactStepStats&);
template void append_nan(std::string&, const std::vector<StatsColumn<FluidStepStats>>&);
template void append_nan(std::string&, const std::vector<StatsColumn<CoupledStepStats>>&);
template void append_nan(std::string&, const std::vector<StatsColumn<solid::BodyPose>>&);
template void append_nan(std::string&, const std::vector<StatsColumn<ContactStepStats>>&);

// ---- the manual's reference ----------------------------------------------------------------

namespace {

template <class R>
void markdown_rows(std::string& s, const std::vector<StatsColumn<R>>& table,
                   const std::string& prefix = "") {
  for (const StatsColumn<R>& c : table)
    s += fmt::format("| `{}{}` | {} | {} |\n", prefix, c.name, c.unit, c.meaning);
}

void markdown_group(std::string& s, const std::string& title, const std::string& when) {
  s += fmt::format("\n**{}** — {}\n\n| column | unit | meaning |\n|---|---|---|\n", title, when);
}

}  // namespace

std::string stats_columns_markdown() {
  std::string s = "Generated by `tetfsi columns --markdown` from io/stats_columns.cpp.\n";
  markdown_group(s, "Every run", "first");
  markdown_rows(s, step_head_columns());
  markdown_group(s, "Phases", "after `dt`: the seconds of each timed phase of the step");
  std::vector<std::string> seen;
  for (const auto& [fluid, coupled] : {std::pair{true, true}, {true, false}, {false, false}})
    for (const PhaseColumn& p : phase_columns(fluid, coupled))
      if (std::find(seen.begin(), seen.end(), p.name) == seen.end()) {
        seen.emplace_back(p.name);
        s += fmt::format("| `{}` | s | {} |\n", p.name, p.meaning);
      }
  for (const auto& [kind, fluid, coupled] : {std::tuple{"A solid-only run", false, false},
                                             {"A fluid run, one-way", true, false},
                                             {"A two-way coupled run", true, true}}) {
    s += fmt::format("\n{} has:", kind);
    for (const PhaseColumn& p : phase_columns(fluid, coupled)) s += fmt::format(" `{}`", p.name);
    s += ".";
  }
  s += "\n";
  markdown_group(s, "The bodies", "every run, after the phases");
  markdown_rows(s, step_columns());
  markdown_group(s, "The fluid's mesh", "scenes with a fluid");
  markdown_rows(s, fluid_mesh_columns());
  s += "| ";
  for (const auto& [name, value] : mesh::quality_columns(mesh::QualitySummary{}))
    s += fmt::format("`{}` ", name);
  s += "| | the fluid mesh's quality summary (mesh::quality_columns, as `tetfsi quality` "
       "prints it; nan on the grid) |\n";
  markdown_group(s, "The fluid's step", "scenes with a fluid, after the quality columns");
  markdown_rows(s, fluid_step_columns());
  markdown_group(s, "The coupling", "two-way coupled runs");
  markdown_rows(s, coupled_columns());
  markdown_group(s, "Per body", "every run, one group per body `<b>` in body order");
  markdown_rows(s, body_columns(), "<b>");
  markdown_group(s, "Contact between bodies", "scenes with `contact`");
  markdown_rows(s, contact_columns());
  markdown_group(s, "A liquid", "scenes with a free surface; the last columns");
  markdown_rows(s, liquid_columns());
  return s;
}

}  // namespace tetfsi::app
