#!/usr/bin/python3
"""The chapter's figure set (Figs. 1.4-1.25) from the family runs, plus work-precision diagrams.

  figures.py --out OUTDIR [--bench JSON [--include DIR]...]

Reads OUTDIR/families.json and OUTDIR/runs/*, writes OUTDIR/figures/<name>.png; with --bench
also the work-precision diagrams of that sweep. --include DIR (repeatable, needs --bench):
outside solvers' results scored by `kneedyn score` under DIR (every score.json and
*.score.json), drawn beside the sweep's; each must be scored on the sweep's scene against the
reference the sweep used (the rule of `work_precision --include`), else exit 2.
Frames (docs/model.md §1): x lateral, y anterior, z proximal; valgus = beta - 90 deg (+),
external tibial rotation = gamma (+).
"""
import argparse
import json
import math
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

sys.dont_write_bytecode = True  # keep the source tree clean
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import tool_input  # noqa: E402
from family_data import LIGAMENTS, by_family, ligament_column, load_families_checked  # noqa: E402

FAMILIES = [("amplitude", "Amplitude family (t0 = 0.1 s)"),
            ("duration", "Duration family (A = 100 N)")]


def ligament_figure(name):
  return "ligament_" + name.replace(" ", "_") + ".png"


# The chapter's figure for each element (captions of Figs. 1.18-1.25); the four capsular
# elements have no figure in the chapter: kneedyn-only.
LIGAMENT_CHAPTER_FIGURE = {"ACL anterior": "Fig. 1.18", "ACL posterior": "Fig. 1.19",
                           "PCL anterior": "Fig. 1.20", "PCL posterior": "Fig. 1.21",
                           "MCL oblique": "Fig. 1.22", "MCL anterior": "Fig. 1.23",
                           "MCL deep": "Fig. 1.24", "LCL": "Fig. 1.25"}


def ligament_caption(name):
  fig = LIGAMENT_CHAPTER_FIGURE.get(name)
  if fig:
    return f"Force in the {name} element vs flexion ({fig}; the chapter shows the amplitude family)"
  return f"Force in the {name} element vs flexion (kneedyn only: the chapter has no figure for this element)"


# Stable file names, in report order: (file, caption). Chapter figure numbers from the
# chapter's captions; "the chapter shows ..." names the family the chapter plots.
LIFTOFF_NOTE = "; star and dotted line: lateral lift-off (the chapter's point A)"
FIGURES = [
    ("pulses.png", "Posterior impact pulses vs time: amplitude family (Fig. 1.4), duration family (Fig. 1.5)"),
    ("flexion_vs_time.png", "Flexion angle vs time (Fig. 1.6; the chapter shows the duration family)" + LIFTOFF_NOTE),
    ("varus_valgus.png", "Varus-valgus rotation vs flexion (Fig. 1.7; the chapter shows the duration family)" + LIFTOFF_NOTE),
    ("tibial_rotation.png", "Internal-external tibial rotation vs flexion (Fig. 1.8; the chapter shows the duration family)" + LIFTOFF_NOTE),
    ("femoral_contact_pathways.png", "Femoral contact points (femoral frame) vs flexion, medial and lateral (Fig. 1.9; the chapter shows A = 100 N, t0 = 0.1 s)" + LIFTOFF_NOTE),
    ("tibial_contact_pathways.png", "Tibial contact points (tibial frame) vs flexion, medial and lateral (Fig. 1.10; the chapter shows A = 100 N, t0 = 0.1 s)" + LIFTOFF_NOTE),
    ("ml_shift_velocity.png", "Medial-lateral shift velocity of the tibia vs flexion, femoral axes (Fig. 1.11; the chapter shows the duration family)" + LIFTOFF_NOTE),
    ("ap_velocity.png", "Posterior velocity of the tibia vs flexion, femoral axes (Fig. 1.12; the chapter shows the duration family)" + LIFTOFF_NOTE),
    ("flexion_velocity.png", "Flexion angular velocity vs flexion (Fig. 1.13; the chapter shows the duration family)" + LIFTOFF_NOTE),
    ("varus_valgus_velocity.png", "Varus-valgus angular velocity vs flexion (Fig. 1.14; the chapter shows the duration family)" + LIFTOFF_NOTE),
    ("tibial_rotation_velocity.png", "Internal-external rotation velocity vs flexion (Fig. 1.15; the chapter shows the duration family)" + LIFTOFF_NOTE),
    ("contact_force_medial.png", "Medial contact force vs flexion (Fig. 1.16; the chapter shows the amplitude family)" + LIFTOFF_NOTE),
    ("contact_force_lateral.png", "Lateral contact force vs flexion (Fig. 1.17; the chapter shows the amplitude family)" + LIFTOFF_NOTE),
] + [(ligament_figure(n), ligament_caption(n) + LIFTOFF_NOTE) for n in LIGAMENTS]

WORK_PRECISION_FIGURES = [
    ("work_precision_pareto.png", "Pareto front of every formulation on one axis: for each accuracy, the CPU time "
     "of its cheapest run (any integrator, tolerance or step) reaching at least that scd; failed and "
     "wrong-event runs are on no front"),
    ("work_precision_cpu.png", "Work-precision: significant correct digits of the positions (scd) vs CPU time"),
    ("work_precision_residuals.png", "Work-precision: scd of the positions vs residual (right-hand-side) evaluations"),
    ("work_precision_events.png", "Work-precision: event-time digits vs CPU time"),
]

def colors(n):
  cmap = plt.get_cmap("viridis")
  return [cmap(0.85 * i / max(1, n - 1)) for i in range(n)]


def liftoff_point(m, x_col, y):
  """(x, y) of the lateral lift-off (the chapter's point A) on a member's curve, or None."""
  e = m.events.get("liftoff_lateral")
  if not e:
    return None
  x = m.col(x_col)
  xe = e["flexion_deg"] if x_col == "flexion_deg" else e["time"] if x_col == "time_s" else None
  if xe is None:
    return None
  ok = np.isfinite(x) & np.isfinite(y)
  if not np.any(ok):
    return None
  i = int(np.argmin(np.abs(np.where(ok, x, np.inf) - xe)))
  return xe, y[i]


def family_panels(members, ylabel, fn, title, xlabel="Flexion angle [deg]", x_col="flexion_deg",
                  mark_liftoff=True, hline0=False):
  """Two panels (amplitude, duration families), one curve per member; fn(member) -> y.
  mark_liftoff: star at the lateral lift-off on each curve plus a dotted vertical."""
  fig, axes = plt.subplots(1, 2, figsize=(12, 4.6), sharey=True)
  for ax, (family, ftitle) in zip(axes, FAMILIES):
    ms = by_family(members, family)
    for m, c in zip(ms, colors(len(ms))):
      y = fn(m)
      ax.plot(m.col(x_col), y, color=c, label=m.label, lw=1.6)
      p = liftoff_point(m, x_col, y) if mark_liftoff else None
      if p is not None:
        ax.axvline(p[0], color=c, ls=":", lw=1)
        ax.plot([p[0]], [p[1]], marker="*", ms=11, color=c, mec="k", mew=0.5, ls="none")
    if hline0:
      ax.axhline(0, color="k", lw=0.6)
    ax.set_title(ftitle, fontsize=10)
    ax.set_xlabel(xlabel)
    ax.grid(alpha=0.3)
    if ms:
      ax.legend(fontsize=8)
  axes[0].set_ylabel(ylabel)
  fig.suptitle(title)
  fig.tight_layout()
  return fig


def pathway_figure(members, frame, title):
  """Rows x, y, z; columns medial amplitude, medial duration, lateral amplitude, lateral duration."""
  axis_names = {"x": "x (+lateral) [mm]", "y": "y (+anterior) [mm]", "z": "z (+proximal) [mm]"}
  fig, axes = plt.subplots(3, 4, figsize=(16, 10), sharex=True)
  for ci, comp in enumerate(("medial", "lateral")):
    for fi, (family, ftitle) in enumerate(FAMILIES):
      col = 2 * ci + fi
      ms = by_family(members, family)
      for ri, axis in enumerate(("x", "y", "z")):
        ax = axes[ri, col]
        for m, c in zip(ms, colors(len(ms))):
          y = m.col(f"{frame}_{comp}_{axis}_mm")
          ax.plot(m.col("flexion_deg"), y, color=c, label=m.label, lw=1.4)
          p = liftoff_point(m, "flexion_deg", y)
          if p is not None:
            ax.axvline(p[0], color=c, ls=":", lw=1)
            ax.plot([p[0]], [p[1]], marker="*", ms=10, color=c, mec="k", mew=0.5, ls="none")
        ax.grid(alpha=0.3)
        if col == 0:
          ax.set_ylabel(axis_names[axis])
        if ri == 0:
          ax.set_title(f"{comp.capitalize()} - {ftitle}", fontsize=9)
        if ri == 2:
          ax.set_xlabel("Flexion angle [deg]")
      if ms:
        axes[0, col].legend(fontsize=7)
  fig.suptitle(title + " (star / dotted: lateral lift-off, point A)")
  fig.tight_layout()
  return fig


class _SavingDict(dict):
  """Saves and closes each figure as it is assigned (keeps few figures open)."""

  def __init__(self, figdir):
    super().__init__()
    self.figdir = figdir

  def __setitem__(self, name, fig):
    fig.savefig(os.path.join(self.figdir, name), dpi=90)
    plt.close(fig)
    super().__setitem__(name, True)


def make_family_figures(outdir, members):
  figdir = os.path.join(outdir, "figures")
  os.makedirs(figdir, exist_ok=True)
  figs = _SavingDict(figdir)
  figs["pulses.png"] = family_panels(members, "Pulse force [N]", lambda m: m.col("pulse_N"),
                                     "Posterior impact pulse at the tibial centre of mass",
                                     xlabel="Time [s]", x_col="time_s", mark_liftoff=False)
  figs["flexion_vs_time.png"] = family_panels(members, "Flexion angle [deg]", lambda m: m.col("flexion_deg"),
                                              "Flexion vs time", xlabel="Time [s]", x_col="time_s")
  figs["varus_valgus.png"] = family_panels(members, "Valgus (+) / varus (-) [deg]",
                                           lambda m: m.col("valgus_deg"), "Varus-valgus rotation",
                                           hline0=True)
  figs["tibial_rotation.png"] = family_panels(members, "External (+) / internal (-) rotation [deg]",
                                              lambda m: m.col("external_rotation_deg"),
                                              "Tibial rotation", hline0=True)
  figs["femoral_contact_pathways.png"] = pathway_figure(members, "femoral", "Femoral contact points, femoral frame")
  figs["tibial_contact_pathways.png"] = pathway_figure(members, "tibial", "Tibial contact points, tibial frame")
  figs["ml_shift_velocity.png"] = family_panels(members, "Lateral (+) / medial (-) shift velocity [mm/s]",
                                                lambda m: m.col("vx_mm_s"), "Medial-lateral shift velocity (x0 dot)",
                                                hline0=True)
  figs["ap_velocity.png"] = family_panels(members, "Posterior velocity (-y0 dot) [mm/s]",
                                          lambda m: -m.col("vy_mm_s"), "Anterior-posterior velocity",
                                          hline0=True)
  figs["flexion_velocity.png"] = family_panels(members, "Flexion angular velocity [deg/s]",
                                               lambda m: m.col("flexion_rate_deg_s"), "Flexion velocity")
  figs["varus_valgus_velocity.png"] = family_panels(members, "Valgus (+) / varus (-) velocity [deg/s]",
                                                    lambda m: m.col("valgus_rate_deg_s"),
                                                    "Varus-valgus angular velocity", hline0=True)
  figs["tibial_rotation_velocity.png"] = family_panels(
      members, "External (+) / internal (-) rotation velocity [deg/s]",
      lambda m: m.col("external_rotation_rate_deg_s"), "Tibial rotation velocity", hline0=True)
  figs["contact_force_medial.png"] = family_panels(members, "Medial contact force [N]",
                                                   lambda m: m.col("N_medial_N"), "Medial contact force")
  figs["contact_force_lateral.png"] = family_panels(members, "Lateral contact force [N]",
                                                    lambda m: m.col("N_lateral_N"),
                                                    "Lateral contact force")
  for n in LIGAMENTS:
    col = ligament_column(n)
    fig_no = LIGAMENT_CHAPTER_FIGURE.get(n, "kneedyn only, no chapter figure")
    figs[ligament_figure(n)] = family_panels(members, f"{n} force [N]",
                                             lambda m, col=col: m.col(col), f"Force in the {n} element ({fig_no})")
  missing = [f for f, _ in FIGURES if f not in figs]
  assert not missing, missing
  return [f for f, _ in FIGURES]


# ---------------------------------------------------------------- work-precision
# Reading the sweep file and deciding which runs are results: bench_data.py (shared with
# benchmarks/work_precision_table.py). Re-exported here for the report and its tests.
from bench_data import (WRONG_EVENT_TIME_S, bench_key, classify_run, event_digits,  # noqa: E402,F401
                        failure_counts, load_bench, load_included, pareto_front, reference_command,
                        scd_ceiling, setting_str, split_runs, timed_where, TIMED_MERGED)

POSITION_SCD_LABEL = "scd of positions vs reference\n−log10 max|e|/(|ref| + 1 mm or 1°)"
FAILURE_MARKER = dict(marker="x", color="k", ms=8, mew=1.6, ls="none")


OUTSIDE_MARK = " [outside, kneedyn score]"
# A formulation whose runs simbody_work_precision --merge copied from another sweep (timed in
# that sweep's process, not beside the rows it timed itself): all of them, or some.
MERGED_MARK = {"all": " [--merge: other process]", "part": " [partly --merge]"}


def merged_marks(header, runs):
  """{formulation: "all" | "part"} for the formulations with runs timed in a merged sweep."""
  marks = {}
  for f in {r["formulation"] for r in runs if r.get("origin") != "outside"}:
    where = {timed_where(r, header) for r in runs if r["formulation"] == f}
    if TIMED_MERGED in where:
      marks[f] = "all" if where == {TIMED_MERGED} else "part"
  return marks


def failure_title(formulation, n_failed, n_untimed=0, outside=False, merged=None):
  """A panel's title: the formulation (an outside solver, a merged one marked so) and how many
  of its runs are drawn as failures."""
  untimed = f", {n_untimed} without a time" if n_untimed else ""
  return (f"{formulation}{OUTSIDE_MARK if outside else ''}{MERGED_MARK.get(merged, '')}  "
          f"({n_failed} failed / wrong event{untimed})")


def failure_row(values):
  """The y of a panel's failure row: a full unit below the lowest plotted value and below 0,
  so that no cross reads as a result (scd 0 and below are results some coarse runs reach);
  the dashed line between sits half a unit above it."""
  return math.floor(min(list(values) + [0.0])) - 1.0


def _save(fig, path, title, panel_titles, **savefig_args):
  """PNG with its titles also as text chunks (Title, Description): what a reader of the file
  (and the report's tests) can check without looking at the pixels."""
  fig.savefig(path, dpi=80, metadata={"Title": title, "Description": "\n".join(panel_titles)}, **savefig_args)
  plt.close(fig)


CPU_LABEL = "CPU time per run (median) [s]"
INSTRUCTIONS_LABEL = "instructions of RunScene per run (callgrind)"
INSTRUCTIONS_PARETO = ("work_precision_pareto_instructions.png",
                       "The same Pareto fronts on instruction counts (benchmarks/instruction_sweep.py: each configuration "
                       "run once under callgrind, RunScene's instructions, scored by kneedyn score): a cost that does not "
                       "drift between recordings as CPU time does")


def _pareto_figure(path, header, runs, ok_runs, failed, forms, fcol, imark, outside, cost="cpu_s",
                   ylabel=CPU_LABEL, merged=None):
  """One axis, every formulation's front (SciMLBenchmarks' layout: error against time, both
  logarithmic; here the error falls to the right, as scd grows in the panels): the cheapest
  run reaching each accuracy, as a staircase (the minimal cost among runs reaching at least
  that scd is constant between front points). `cost`: the run's key drawn ("cpu_s",
  "instructions"), labelled `ylabel`."""
  fig, ax = plt.subplots(figsize=(10.5, 6.2))
  titles = []
  nfail = failure_counts(runs)
  merged = merged or {}
  for f in forms:
    front = pareto_front([r for r in ok_runs if r["formulation"] == f], cost)
    titles.append(failure_title(f, nfail.get(f, 0), outside=f in outside, merged=merged.get(f)))
    name = f + (OUTSIDE_MARK if f in outside else "") + MERGED_MARK.get(merged.get(f), "")
    if not front:  # still in the legend, with its failures
      ax.plot([], [], color=fcol[f], lw=1.6, ls=":", label=f"{name} (none on a front, {nfail.get(f, 0)} failed / wrong event)")
      continue
    err = [10.0 ** -r["scd"] for r in front]
    cpu = [r[cost] for r in front]
    # Staircase in order of growing error: between front points i and i+1 the cheapest run
    # reaching the accuracy is point i.
    ax.plot(err[::-1], cpu[::-1], drawstyle="steps-post", color=fcol[f], lw=1.6,
            label=f"{name} ({len(front)} on the front, {nfail.get(f, 0)} failed / wrong event)")
    for r, x, y in zip(front, err, cpu):
      ax.plot([x], [y], ls="none", marker=imark[r["integrator"] or "-"], color=fcol[f], ms=6, mfc="white")
  ceiling = scd_ceiling(header)
  if ceiling is not None:  # the reference cannot measure errors below this one
    ax.axvline(10.0 ** -ceiling, color="0.4", lw=1.2, ls="-.",
               label=f"reference ceiling: scd {ceiling:.1f} (the highest the scores can measure)")
  ax.set_xscale("log")
  ax.set_yscale("log")
  ax.invert_xaxis()
  ax.set_xlabel("max relative position error 10^(−scd)  (accuracy grows to the right)")
  ax.set_ylabel(ylabel)
  ax.grid(alpha=0.3, which="both")
  legends = []
  if ax.get_legend_handles_labels()[0]:
    first = ax.legend(title="formulation: best configuration at each accuracy", fontsize=7, title_fontsize=8,
                      loc="upper left", bbox_to_anchor=(1.01, 1.0))
    ax.add_artist(first)
    integs = sorted({r["integrator"] or "-" for r in ok_runs})
    handles = [plt.Line2D([], [], ls="none", marker=imark[g], color="0.3", mfc="white", ms=6) for g in integs]
    second = ax.legend(handles, [g if g != "-" else "built-in (IDA / Newmark)" for g in integs],
                       title="integrator (marker)", fontsize=7, title_fontsize=8, loc="lower left",
                       bbox_to_anchor=(1.01, 0.0))
    legends = [first, second]
  title = (f"Pareto fronts{' on instructions' if cost == 'instructions' else ''}, scene "
           f"{header.get('scene', '?')}, {header.get('mode', 'instruction' if cost == 'instructions' else '?')} sweep: "
           f"{len(ok_runs)} runs are results; {len(failed)} failed or wrong event (on no front)")
  ax.set_title(title, fontsize=10)
  fig.tight_layout()
  # The legends sit right of the axis; a tight box counts an add_artist legend only if named.
  _save(fig, path, title, titles, bbox_inches="tight", bbox_extra_artists=legends)


# One colour per series of the work-precision figures, the same in every figure (the main
# sweep's, the Simbody peer sweep's, the instruction sweep's): kneedyn's registered formulations
# (formulations/registry.cpp), Simbody and the outside solvers of examples/outside_results.sh.
# Chosen from matplotlib's qualitative palettes by farthest-point selection: any two are at least
# 0.25 apart in RGB (each channel in [0, 1]), and as far from the black failure crosses, the grey
# reference-ceiling line and the white background.
SERIES_COLOURS = {
    "dae": "#386cb0", "dae-reduced": "#9c9ede", "dae-ggl": "#ff7f00", "dae-ggl-reduced": "#e7ba52",
    "newmark": "#2ca02c", "newmark-reduced": "#a6d854", "generalized-alpha": "#e31a1c",
    "generalized-alpha-reduced": "#ff9896", "mde": "#984ea3", "ede": "#a6761d", "staggered": "#ce6dbd",
    "monolithic": "#17becf", "monolithic-ggl": "#66c2a5", "simbody": "#f0027f", "scipy": "#1b9e77",
    "c-example": "#393b79"}
MIN_COLOUR_DISTANCE = 0.25  # RGB, the palette's smallest pairwise distance


def _spare_colours():
  """Colours for series not named above (a new formulation, another outside solver), in name
  order: the five the report has used, then matplotlib's qualitative palettes, then a 1/8-step
  RGB lattice, each taken when it is at least MIN_COLOUR_DISTANCE from every SERIES_COLOURS
  colour, the black crosses, the grey (0.4) ceiling line, the white background and the spares
  before it (59 colours; only a figure with more unnamed series repeats one)."""
  import itertools
  import matplotlib.colors as mc
  taken = [mc.to_rgb(c) for c in SERIES_COLOURS.values()] + [(0.0, 0.0, 0.0), (0.4, 0.4, 0.4), (1.0, 1.0, 1.0)]
  candidates = [mc.to_rgb(c) for c in ("#d6616b", "#843c39", "#f7b6d2", "#969696", "#a1d99b")]
  for name in ("tab20", "tab20b", "tab20c", "Set1", "Set2", "Set3", "Dark2", "Paired", "Accent", "Pastel1",
               "Pastel2", "tab10"):
    candidates += [tuple(c[:3]) for c in matplotlib.colormaps[name].colors]
  candidates += [tuple(x / 8 for x in p) for p in itertools.product(range(9), repeat=3)]
  spares = []
  for rgb in candidates:
    if all(math.dist(rgb, t) >= MIN_COLOUR_DISTANCE for t in taken):
      spares.append(mc.to_hex(rgb))
      taken.append(rgb)
  return tuple(spares)


SPARE_COLOURS = _spare_colours()


def series_colours(names):
  """{name: colour} for the series of one figure: SERIES_COLOURS, and spares for the others."""
  others = sorted(n for n in set(names) if n not in SERIES_COLOURS)
  out = {n: SERIES_COLOURS[n] for n in names if n in SERIES_COLOURS}
  out.update({n: SPARE_COLOURS[i % len(SPARE_COLOURS)] for i, n in enumerate(others)})
  return out


def _styles(runs):
  """(formulations, colour by formulation, marker by integrator) of the work-precision figures."""
  forms = sorted({r["formulation"] for r in runs})
  integs = sorted({r["integrator"] or "-" for r in runs})
  markers = "osD^v<>pP*Xh"
  return (forms, series_colours(forms), {g: markers[i % len(markers)] for i, g in enumerate(integs)})


def make_instruction_pareto(outdir, path, prefix=""):
  """The Pareto overlay of an instruction sweep file (benchmarks/instruction_sweep.py) as
  figures/<prefix>work_precision_pareto_instructions.png; returns its file name, or None when
  the file holds no instruction counts."""
  header, runs = load_bench(path)
  if not any(isinstance(r.get("instructions"), int) for r in runs):
    return None
  ok_runs, failed = split_runs(runs)
  forms, fcol, imark = _styles(runs)
  figdir = os.path.join(outdir, "figures")
  os.makedirs(figdir, exist_ok=True)
  name = prefix + INSTRUCTIONS_PARETO[0]
  _pareto_figure(os.path.join(figdir, name), header, runs, ok_runs, failed, forms, fcol, imark, set(),
                 cost="instructions", ylabel=INSTRUCTIONS_LABEL)
  return name


def make_work_precision(outdir, bench_path, prefix="", include=()):
  """Returns (figure files, not-plotted rows [(key, setting, reason)], header). `prefix` keeps a
  second diagram set (e.g. the Simbody peer sweep) from overwriting the first. The first
  figure overlays each formulation's Pareto front; the others have one panel per formulation
  with every integrator and setting, failures as crosses on a row below the data. `include`:
  directories of outside results scored by `kneedyn score` (bench_data.load_included, checked
  against the sweep's scene and reference), drawn beside the sweep's, their failures counted
  as failures; results the sweep file already holds (work_precision --include) are drawn too.
  header["included_runs"] lists every outside run drawn."""
  header, runs = load_bench(bench_path)
  for d in include:
    runs += load_included(d, header.get("scene"), reference_command(header))
  outside = {r["formulation"] for r in runs if r.get("origin") == "outside"}
  header["included_runs"] = [r for r in runs if r.get("origin") == "outside"]
  merged = merged_marks(header, runs)
  ok_runs, failed = split_runs(runs)
  forms, fcol, imark = _styles(runs)
  figdir = os.path.join(outdir, "figures")
  os.makedirs(figdir, exist_ok=True)
  files = [prefix + "work_precision_pareto.png"]
  _pareto_figure(os.path.join(figdir, files[0]), header, runs, ok_runs, failed, forms, fcol, imark, outside,
                 merged=merged)
  specs = [("work_precision_cpu.png", "cpu_s", "CPU time per run (median) [s]", lambda r: r["scd"],
            POSITION_SCD_LABEL),
           ("work_precision_residuals.png", "residual_evaluations", "Residual (right-hand-side) evaluations",
            lambda r: r["scd"], POSITION_SCD_LABEL),
           ("work_precision_events.png", "cpu_s", "CPU time per run (median) [s]", event_digits,
            "event-time digits\n−log10 max over events |t − t_ref| [s]")]
  def order(r):  # tolerance / step order along a series
    st = r["setting"]
    return -(st.get("rtol") or st.get("step") or st.get("accuracy") or 0.0)

  # One curve per integrator and stabilization (ede:dopri5 with and without projection are
  # two curves, dashed with).
  series = sorted({(r["integrator"] or "-", r["setting"].get("stabilization")) for r in runs},
                  key=lambda s: (s[0], s[1] or ""))
  for fname, xkey, xlabel, yfn, ylabel in specs:
    ncol = min(3, max(1, len(forms)))
    nrow = max(1, math.ceil(len(forms) / ncol))
    fig, axes = plt.subplots(nrow, ncol, figsize=(4.6 * ncol, 3.6 * nrow + 0.8), sharex=True, sharey=True,
                             squeeze=False)
    ys = [yfn(r) for r in ok_runs if yfn(r) is not None]
    top = max(ys) + 0.5 if ys else 10.0
    ceiling = scd_ceiling(header) if ylabel == POSITION_SCD_LABEL else None
    if ceiling is not None:
      top = max(top, ceiling + 0.5)
    fail_y = failure_row(ys)
    titles = []
    for ax, f in zip(axes.flat, forms):
      for g, stab in series:
        pts = sorted((r for r in ok_runs if r["formulation"] == f and (r["integrator"] or "-") == g
                      and r["setting"].get("stabilization") == stab and r.get(xkey) and yfn(r) is not None),
                     key=order)
        if pts:
          label = (g if g != "-" else "built-in (IDA / Newmark)") + (f" / {stab}" if stab else "")
          if merged.get(f) == "part" and all(timed_where(r, header) == TIMED_MERGED for r in pts):
            label += " (--merge)"
          ax.semilogx([r[xkey] for r in pts], [yfn(r) for r in pts], "--" if stab else "-", color=fcol[f],
                      marker=imark[g], ms=5, mfc="none", lw=0.8, label=label)
      mine = [r for r, _ in failed if r["formulation"] == f]
      placed = [r for r in mine if r.get(xkey)]
      if placed:
        ax.semilogx([r[xkey] for r in placed], [fail_y] * len(placed), label=f"failed / wrong event ({len(mine)})",
                    **FAILURE_MARKER)
      ax.axhline(fail_y + 0.5, color="k", lw=0.5, ls="--")
      if ceiling is not None:  # above it the reference's own error is measured
        ax.axhline(ceiling, color="0.4", lw=1.2, ls="-.", label=f"reference ceiling (scd {ceiling:.1f})")
      titles.append(failure_title(f, len(mine), len(mine) - len(placed), outside=f in outside,
                                  merged=merged.get(f)))
      ax.set_title(titles[-1], color=fcol[f], fontsize=10, fontweight="bold")
      ax.grid(alpha=0.3, which="both")
      ax.set_ylim(fail_y - 0.7, top)
      ticks = [t for t in ax.get_yticks() if fail_y + 0.5 < t <= top]
      ax.set_yticks([fail_y] + ticks, ["✗"] + [f"{t:g}" for t in ticks])
      if ax.get_legend_handles_labels()[0]:
        ax.legend(title="integrator (marker)", fontsize=7, title_fontsize=7, loc="upper left")
    for ax in axes.flat[len(forms):]:
      ax.set_visible(False)
    for ax in axes[-1, :]:
      ax.set_xlabel(xlabel)
    for ax in axes[:, 0]:
      ax.set_ylabel(ylabel, fontsize=9)
    title = (f"Work-precision, scene {header.get('scene', '?')}, {header.get('mode', '?')} sweep: "
             f"{len(ok_runs)} runs plotted; {len(failed)} failed or wrong event (× on the row below the dashed line)")
    fig.suptitle(title, fontsize=11)
    fig.tight_layout()
    _save(fig, os.path.join(figdir, prefix + fname), title, titles)
    files.append(prefix + fname)
  return files, [(bench_key(r), setting_str(r["setting"]), why) for r, why in failed], header


def reading_claim_matrix(verdicts_json, path):
  """The reading × claim matrix of the recorded verdicts (reports/recorded/claims.json): one row
  per reading of the printed chapter, one column per claim (green reproduced, red not, grey not
  checkable or a reading whose runs did not all reach 90°), and each reading's lateral lift-off
  angle at the right. Returns the path, or None when the file has no matrix."""
  with open(verdicts_json, encoding="utf-8") as f:
    rec = json.load(f)
  m = rec.get("matrix")
  if not m or not m.get("readings"):
    return None
  ids, rows = m["claims"], m["readings"]
  grid = np.full((len(rows), len(ids)), np.nan)
  for i, r in enumerate(rows):
    for j, c in enumerate(r["cells"]):
      if c is not None and r["informative"]:
        grid[i, j] = c
  from matplotlib.colors import ListedColormap
  fig, ax = plt.subplots(figsize=(max(8.0, 0.26 * len(ids) + 5.5), 0.3 * len(rows) + 1.8))
  cmap = ListedColormap(["#e8a5a5", "#9fd49f"])
  cmap.set_bad("#dddddd")
  ax.imshow(np.ma.masked_invalid(grid), cmap=cmap, vmin=0, vmax=1, aspect="auto", interpolation="nearest")
  ax.set_xticks(range(len(ids)))
  ax.set_xticklabels(ids, rotation=90, fontsize=7)
  ax.set_yticks(range(len(rows)))
  ax.set_yticklabels([r["key"] + ("" if r["informative"] else f" (= {r['same_as']})" if r.get("same_as")
                                  else " (incomplete)") for r in rows], fontsize=7)
  for i, r in enumerate(rows):
    lo = r.get("liftoff_lateral_deg")
    # An informative reading without a lateral lift-off still has its count (damped_sine/g_off).
    where = f"  {lo:.1f}°" if lo is not None else "  no lift-off" if r["informative"] else "  —"
    count = f"  {r.get('reproduced')}✓" if r["informative"] else ""
    ax.text(len(ids) - 0.3, i, where + count,
            va="center", ha="left", fontsize=7)
  title = ("Reading × claim: green reproduced, red not reproduced, grey not checkable or incomplete; "
           "right: lateral lift-off (chapter ≈ 66°) and claims reproduced")
  ax.set_title(title, fontsize=8)
  fig.tight_layout()
  _save(fig, path, "Reading x claim matrix", [title], bbox_inches="tight")
  return path


def main(argv=None):
  ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
  ap.add_argument("--out", required=True, help="directory written by run_families.py")
  ap.add_argument("--bench", help="benchmark JSON (work-precision diagrams)")
  ap.add_argument("--include", action="append", default=[], metavar="DIR",
                  help="outside results scored by kneedyn score under DIR, beside the sweep's (repeatable)")
  args = ap.parse_args(argv)
  _, members = load_families_checked("--out", args.out)
  if args.include and not args.bench:
    raise tool_input.BadInput("--include needs --bench (the sweep the outside results are drawn beside)")
  if args.bench:
    header, _ = tool_input.checked(load_bench, "--bench", args.bench)
    for d in args.include:
      try:
        load_included(d, header.get("scene"), reference_command(header))
      except ValueError as e:
        raise tool_input.BadInput(str(e)) from None
  files = make_family_figures(args.out, members)
  print(f"figures: {len(files)} family figures -> {os.path.join(args.out, 'figures')}")
  if args.bench:
    wp, failed, _ = make_work_precision(args.out, args.bench, include=args.include)
    print(f"figures: {len(wp)} work-precision figures, {len(failed)} failed runs listed")
  return 0


if __name__ == "__main__":
  sys.exit(tool_input.exit_code("figures", main))
