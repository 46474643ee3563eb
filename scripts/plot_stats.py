#!/usr/bin/python3
"""A run's stats.csv as a page of plots over time (what `tetfsi plot OUT` runs).

    /usr/bin/python3 scripts/plot_stats.py OUT/stats.csv -o OUT/stats.png [--title NAME]
        [--panels WORD,...]

Panels (each drawn only from the columns the run wrote; a panel none of whose columns exist,
or all NaN, is left out): the energy budget, solver iterations, solver residuals, divergence,
enclosed volume drift, fluid mesh quality, flow (CFL, speed), the bodies' heights (lowest
point and centroid) and rotation from rest, and seconds per phase. Needs
Debian's python3-matplotlib and python3-numpy (scripts/setup.sh). Errors: one line
`error: ...` on stderr, exit code 1.
"""
import argparse
import csv
import logging
import math
import os
import sys
import warnings


def fail(message):
    print(f"error: {message}", file=sys.stderr)
    sys.exit(1)


# (title, y label, log scale, [(column, legend label), ...])
PANELS = [
    ("energy budget", "J", False, [
        ("kinetic_energy", "bodies: kinetic"), ("elastic_energy", "bodies: elastic"),
        ("gravity_potential", "bodies: gravity potential"),
        ("total_energy", "bodies: total"), ("fluid_kinetic_energy", "fluid: kinetic"),
        ("total_energy_coupled", "fluid + bodies (kinetic + elastic)")]),
    ("solver iterations", "iterations per step", False, [
        ("solver_iterations", "solids' linear solve"), ("pressure_iterations", "pressure solve"),
        ("coupled_iterations", "coupled solve"), ("equilibrium_iterations", "equilibrium")]),
    ("solver residuals", "relative residual", True, [
        ("solver_residual", "solids' linear solve"), ("pressure_residual", "pressure solve"),
        ("coupled_residual", "coupled solve")]),
    ("divergence", "max |D u| (1/s)", True, [
        ("divergence_before", "before the projection"), ("divergence", "after")]),
    ("enclosed volume drift", "max |V - V0| / V0", False, [
        ("enclosed_volume_drift", "enclosed liquid")]),
    ("fluid mesh quality", "degrees", False, [
        ("q_min_dihedral_deg", "min dihedral"),
        ("q_min_dihedral_away_deg", "min dihedral away from solids"),
        ("q_min_dihedral_p01", "1st percentile of min dihedral")]),
    ("flow", "", False, [
        ("cfl", "CFL (max h |u| / cell size)"), ("max_speed", "max speed (m/s)")]),
]


def body_panels(columns):
    """The bodies' pose panels, from the columns <body>_lowest, <body>_centroid_height and
    <body>_rotation_deg (one triple per body, in the header's order)."""
    bodies = [n[:-len("_rotation_deg")] for n in columns if n.endswith("_rotation_deg")]
    heights = []
    for b in bodies:
        heights += [(f"{b}_lowest", f"{b}: lowest point"),
                    (f"{b}_centroid_height", f"{b}: centroid")]
    return [("bodies: height", "m (against gravity)", False, heights),
            ("bodies: rotation from rest", "degrees", False,
             [(f"{b}_rotation_deg", b) for b in bodies])]


PHASES = ["assemble", "solve", "remesh", "transfer", "forces", "pressure_assembly",
          "pressure_solve", "coupled_assembly", "coupled_solve", "solid", "update", "output"]


def read_columns(path):
    try:
        with open(path, newline="") as f:
            rows = list(csv.reader(f))
    except OSError as e:
        fail(f"cannot read '{path}': {e.strerror}")
    if not rows:
        fail(f"{path}: empty (no header line); was the run stopped before it started?")
    header, body = rows[0], rows[1:]
    columns = {name: [] for name in header}
    for i, row in enumerate(body, start=2):
        if len(row) != len(header):
            if i == len(rows):  # a last line being written: leave it out
                break
            fail(f"{path}:{i}: {len(row)} fields, the header has {len(header)}")
        for name, text in zip(header, row):
            try:
                columns[name].append(float(text))
            except ValueError:
                columns[name].append(math.nan)
    return columns


def usable(columns, name):
    values = columns.get(name)
    return values is not None and any(math.isfinite(v) for v in values)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("stats", help="stats.csv of a run")
    parser.add_argument("-o", "--output", required=True, help="the PNG to write")
    parser.add_argument("--title", default="", help="the page's title (the scene's name)")
    parser.add_argument("--panels", default="",
                        help="only the panels whose titles contain one of these comma-separated "
                             "words, e.g. 'height,rotation' (default: every panel)")
    args = parser.parse_args()
    wanted = [w.strip() for w in args.panels.split(",") if w.strip()]

    logging.getLogger("matplotlib").setLevel(logging.ERROR)
    warnings.filterwarnings("ignore")
    try:
        import numpy as np
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError as e:
        fail(f"{sys.executable} cannot import {e.name}: run scripts/setup.sh (Debian packages "
             "python3-matplotlib, python3-numpy)")

    columns = read_columns(args.stats)
    if "time" not in columns:
        fail(f"{args.stats}: no 'time' column; is it a tetfsi stats.csv?")
    if not columns["time"]:
        fail(f"{args.stats}: no steps yet (only the header line)")
    t = np.array(columns["time"])

    panels, skipped = [], []
    for title, ylabel, log, series in PANELS + body_panels(columns):
        if wanted and not any(w in title for w in wanted):
            continue
        present = [(c, label) for c, label in series if usable(columns, c)]
        if title == "enclosed volume drift" and not any(
                v > 0 for v in columns.get("enclosed_volume", []) if math.isfinite(v)):
            present = []  # no enclosed liquid: the drift column is all 0
        if log:
            present = [(c, label) for c, label in present
                       if any(v > 0 for v in columns[c] if math.isfinite(v))]
        (panels if present else skipped).append((title, ylabel, log, present))
    phases = [p for p in PHASES if usable(columns, p)]
    if not wanted or any(w in "seconds per phase" for w in wanted):
        if phases:
            panels.append(("seconds per phase", "s per step", False, phases))
        else:
            skipped.append(("seconds per phase", "", False, []))
    if not panels:
        fail(f"no panel of {args.stats} matches --panels '{args.panels}'")

    ncols = 2
    nrows = max(1, math.ceil(len(panels) / ncols))
    fig, axes = plt.subplots(nrows, ncols, figsize=(13, 3.1 * nrows + 0.8), squeeze=False,
                             sharex=True)
    steps = len(t)
    fig.suptitle(f"{args.title or os.path.basename(os.path.dirname(os.path.abspath(args.stats)))}"
                 f": {steps} step{'s' if steps != 1 else ''} to t = {t[-1]:.4g} s",
                 fontsize=14, fontweight="bold")
    for ax, (title, ylabel, log, series) in zip(axes.flat, panels):
        ax.set_title(title, fontsize=11, loc="left")
        if title == "seconds per phase":
            values = [np.nan_to_num(np.array(columns[p])) for p in series]
            ax.stackplot(t, values, labels=series, alpha=0.85)
            if usable(columns, "total"):
                ax.plot(t, columns["total"], color="black", lw=1, label="total")
        else:
            for c, label in series:
                y = np.array(columns[c])
                if log:
                    y = np.where(y > 0, y, np.nan)
                ax.plot(t, y, lw=1.4, label=label, marker="." if steps < 30 else None)
            if log:
                ax.set_yscale("log")
        ax.set_ylabel(ylabel)
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=8, loc="best", ncol=2 if len(series) > 4 else 1)
    for ax in list(axes.flat)[len(panels):]:
        ax.set_visible(False)
    for i, ax in enumerate(list(axes.flat)[:len(panels)]):
        if i + ncols >= len(panels):  # nothing drawn below it: its own time axis
            ax.set_xlabel("time (s)")
            ax.xaxis.set_tick_params(labelbottom=True)
    fig.tight_layout(rect=(0, 0, 1, 0.97))
    tmp = args.output + ".tmp"
    try:
        fig.savefig(tmp, dpi=80, format="png")
        os.replace(tmp, args.output)
    except OSError as e:
        if os.path.exists(tmp):
            os.remove(tmp)
        fail(f"cannot write '{args.output}': {e.strerror} (check that the folder exists and is "
             "writable)")
    names = ", ".join(p[0] for p in panels)
    note = f"; left out (no data): {', '.join(s[0] for s in skipped)}" if skipped else ""
    print(f"{args.output}: {len(panels)} panels ({names}){note}")


if __name__ == "__main__":
    main()
