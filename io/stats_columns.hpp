#pragma once
/// @file stats_columns.hpp
/// The columns of stats.csv, declared once: one table per stats record (StepStats,
/// FluidStepStats, CoupledStepStats, solid::BodyPose, ContactStepStats), each column with
/// its name, unit, meaning, printed form and the field it reads. stats.csv's header and every
/// row (StatsWriter), the run's checkpoint records of the last step's figures (run/) and the
/// manual's column reference (`tetfsi columns --markdown`, docs/user/output.md, checked by a
/// test) all come from these tables. Adding a column is one line in its table.
#include <string>
#include <variant>
#include <vector>

#include "io/output.hpp"

namespace tetfsi::app {

/// How a column's value is printed: an integer, a double with 17 significant digits (exact:
/// it reads back bit for bit) or with 6 (figures whose last bits are noise: seconds,
/// residuals).
enum class StatsFormat { Integer, Exact, Short };

/// One column of a stats record R.
template <class R>
struct StatsColumn {
  /// The field it reads: an int or double member, or a figure computed from the record.
  using Field = std::variant<int R::*, double R::*, double (*)(const R&)>;
  const char* name;     ///< the column's header (for the bodies: a suffix of the body's name)
  const char* unit;     ///< "s", "m", "J", "" (a count or ratio) …
  const char* meaning;  ///< one sentence for the manual
  StatsFormat format;
  Field field;
  /// The name of the field's checkpoint record (run/run_stats.cpp saves the last step's
  /// figures under it); null: not saved (recomputed every step).
  const char* record = nullptr;
};

/// step, time, dt (before the phases' seconds).
const std::vector<StatsColumn<StepStats>>& step_head_columns();
/// The solid's figures after the phases: solver_iterations … equilibrium_evaluations.
const std::vector<StatsColumn<StepStats>>& step_columns();
/// A fluid scene: the mesh built after the step (fluid_cells … remesh_s); the mesh quality
/// columns (mesh::quality_columns) follow them.
const std::vector<StatsColumn<FluidStepStats>>& fluid_mesh_columns();
/// A fluid scene, after the quality columns: the fluid's step (pressure_iterations …).
const std::vector<StatsColumn<FluidStepStats>>& fluid_step_columns();
/// A two-way coupled run, after the fluid's: coupled_iterations … contact_rounds.
const std::vector<StatsColumn<CoupledStepStats>>& coupled_columns();
/// Per body b, in body order: b + each name (b_lowest, b_centroid_height, b_rotation_deg).
const std::vector<StatsColumn<solid::BodyPose>>& body_columns();
/// Contact between bodies: contact_pairs … contact_s.
const std::vector<StatsColumn<ContactStepStats>>& contact_columns();
/// A liquid with a free surface: liquid_volume … liquid_p2g_s (the last columns).
const std::vector<StatsColumn<FluidStepStats>>& liquid_columns();

/// A timed phase's column: its name and what it times.
struct PhaseColumn {
  const char* name;
  const char* meaning;
};
/// The phases that get a column (seconds), in order, for a solid-only run, a fluid run and a
/// two-way coupled run.
const std::vector<PhaseColumn>& phase_columns(bool fluid, bool coupled);

/// Append ",value" for every column of `table` read from `r`.
template <class R>
void append_stats(std::string& line, const std::vector<StatsColumn<R>>& table, const R& r);
/// Append ",nan" for every column of `table` (a row without that record).
template <class R>
void append_nan(std::string& line, const std::vector<StatsColumn<R>>& table);

/// The columns' reference in Markdown (docs/user/output.md's generated block): one table
/// per group, in stats.csv's order, with unit and meaning.
std::string stats_columns_markdown();

/// Visit every column of `table` that has a checkpoint record as f(record, field&) — the form
/// io/state_io.hpp's RecordSaver / RecordLoader take. `S` is R or const R.
template <class R, class S, class F>
void visit_records(const std::vector<StatsColumn<R>>& table, S& r, F&& f) {
  for (const StatsColumn<R>& c : table) {
    if (!c.record) continue;
    if (auto* m = std::get_if<int R::*>(&c.field))
      f(c.record, r.**m);
    else if (auto* d = std::get_if<double R::*>(&c.field))
      f(c.record, r.**d);
  }
}

}  // namespace tetfsi::app
