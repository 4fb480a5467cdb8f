#!/usr/bin/python3
"""The chapter's figure set (Figs. 1.4-1.25) from the family runs, plus work-precision diagrams.

  figures.py --out OUTDIR [--bench JSON]

Reads OUTDIR/families.json and OUTDIR/runs/*, writes OUTDIR/figures/<name>.png.
Frames (spec knee-model.md): x lateral, y anterior, z proximal; valgus = beta - 90 deg (+),
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
from family_data import LIGAMENTS, by_family, ligament_column, load_families  # noqa: E402

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
    ("work_precision_cpu.png", "Work-precision: error (10^-scd) vs CPU time"),
    ("work_precision_residuals.png", "Work-precision: error (10^-scd) vs residual evaluations"),
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


def load_bench(path):
  with open(path) as f:
    data = json.load(f)
  if isinstance(data, dict):  # benchmarks/work_precision.cpp: {"header": ..., "results": [...]}
    data = data.get("results", data.get("runs", []))
  return [r for r in data if isinstance(r, dict)]


def bench_key(r):
  return f"{r.get('formulation', '?')} / {r.get('integrator') or '-'}"


def make_work_precision(outdir, bench_path):
  """Returns (figure files, failed-run rows [(key, setting, reason)])."""
  runs = load_bench(bench_path)
  lines, failed = {}, []
  for r in runs:
    metrics = r.get("metrics") or {}
    scd = metrics.get("scd")
    cpu = r.get("cpu_time_s") or {}
    cpu = cpu.get("median") if isinstance(cpu, dict) else cpu
    res = (r.get("counters") or {}).get("residual_evaluations")
    if r.get("status", "ok") != "ok" or scd is None or not math.isfinite(float(scd)):
      why = r.get("reason") or (f"status {r['status']}" if r.get("status", "ok") != "ok" else "no metrics.scd")
      failed.append((bench_key(r), r.get("setting"), why))
      continue
    lines.setdefault(bench_key(r), []).append((float(scd), cpu, res, r.get("setting")))
  figdir = os.path.join(outdir, "figures")
  os.makedirs(figdir, exist_ok=True)
  files = []
  for fname, xi, xlabel in (("work_precision_cpu.png", 1, "CPU time (median) [s]"),
                            ("work_precision_residuals.png", 2, "Residual evaluations")):
    fig, ax = plt.subplots(figsize=(9, 6))
    colors = plt.get_cmap("tab20").colors  # one distinct colour per formulation × integrator
    markers = "os^Dv<>pP*X"
    for i, (key, pts) in enumerate(sorted(lines.items())):
      pts = [p for p in pts if p[xi] is not None and p[xi] > 0]
      pts.sort(key=lambda p: p[xi])
      if pts:
        ax.loglog([p[xi] for p in pts], [10.0 ** -p[0] for p in pts], "-", marker=markers[i % len(markers)],
                  markersize=4, color=colors[i % len(colors)], label=key)
    ax.set_xlabel(xlabel)
    ax.set_ylabel("Error 10^-scd")
    ax.grid(alpha=0.3, which="both")
    if lines:
      ax.legend(fontsize=8)
    ax.set_title("Work-precision" + ("" if lines else " (no successful runs)"))
    fig.tight_layout()
    fig.savefig(os.path.join(figdir, fname), dpi=90)
    plt.close(fig)
    files.append(fname)
  return files, failed


def main(argv=None):
  ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
  ap.add_argument("--out", required=True, help="directory written by run_families.py")
  ap.add_argument("--bench", help="benchmark JSON (work-precision diagrams)")
  args = ap.parse_args(argv)
  _, members = load_families(args.out)
  files = make_family_figures(args.out, members)
  print(f"figures: {len(files)} family figures -> {os.path.join(args.out, 'figures')}")
  if args.bench and os.path.exists(args.bench):
    wp, failed = make_work_precision(args.out, args.bench)
    print(f"figures: {len(wp)} work-precision figures, {len(failed)} failed runs listed")
  return 0


if __name__ == "__main__":
  sys.exit(main())
