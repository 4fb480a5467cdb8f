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
# A run is drawn as a failure (not a point) when it failed, lacks a reference event, has
# contact events the reference lacks, or misses an event time by more than this. 1 ms is
# 0.5° of flexion at the end of the chapter run (α̇ ≈ 460°/s): any run whose positions
# carry 2 or more digits must place its events closer than that.
WRONG_EVENT_TIME_S = 1e-3
UNIT_TO_S = {"ns": 1e-9, "us": 1e-6, "ms": 1e-3, "s": 1.0}


def _parse_name(name):
  """Google-Benchmark name 'formulation[:integrator]/rtol=X[/...]' or '/step=X' -> parts."""
  parts = name.split("/")
  form, _, integ = parts[0].partition(":")
  setting = {}
  for p in parts[1:]:
    k, _, v = p.partition("=")
    if k in ("rtol", "atol", "step"):
      try:
        setting[k] = float(v)
      except ValueError:
        pass
  return form, integ, setting


def load_bench(path):
  """Benchmark JSON -> (header, [run dicts]) in one normalized form. Accepts
    (a) benchmarks/work_precision.cpp's layout {"header", "results": [{formulation, integrator,
        setting, status, reason, metrics{scd, event_time_error_s}, cpu_time_s{median}, counters,
        events}]} (or a bare list of such results), and
    (b) Google Benchmark's own layout {"context", "benchmarks": [{name, run_name, run_type,
        aggregate_name, cpu_time, time_unit, <counters>, ...}]}: one run per run_name (the
        median aggregate if present, else the mean of the iterations); formulation, integrator
        and setting from the fields of the same name, else from the benchmark name; scd and
        event errors from fields `scd`, `metrics` or `event_time_error_s[.<event>]`.
  A top-level "provenance" {command, commit, date} is passed through in the header."""
  with open(path, encoding="utf-8") as f:
    data = json.load(f)
  header = {}
  if isinstance(data, dict):
    header = dict(data.get("header") or data.get("context") or {})
    if "provenance" in data:
      header["provenance"] = data["provenance"]
    if isinstance(data.get("benchmarks"), list):
      return header, _from_google_benchmark(data["benchmarks"])
    data = data.get("results", data.get("runs", []))
  runs = []
  for r in data:
    if not isinstance(r, dict):
      continue
    m = r.get("metrics") or {}
    cpu = r.get("cpu_time_s")
    cpu = cpu.get("median") if isinstance(cpu, dict) else cpu
    runs.append({"formulation": r.get("formulation", "?"), "integrator": r.get("integrator") or "",
                 "setting": r.get("setting") or {}, "status": r.get("status", "ok"),
                 "reason": r.get("reason") or "", "scd": m.get("scd"),
                 "event_time_error_s": m.get("event_time_error_s") or {},
                 "cpu_s": cpu, "residual_evaluations": (r.get("counters") or {}).get("residual_evaluations"),
                 "events": r.get("events")})
  return header, runs


def _from_google_benchmark(entries):
  groups = {}
  for e in entries:
    if isinstance(e, dict) and e.get("name"):
      groups.setdefault(e.get("run_name") or e["name"], []).append(e)
  runs = []
  for name, es in groups.items():
    med = [e for e in es if e.get("run_type") == "aggregate" and e.get("aggregate_name") == "median"]
    its = [e for e in es if e.get("run_type", "iteration") == "iteration"]
    e = med[0] if med else (its[0] if its else es[0])
    unit = UNIT_TO_S.get(e.get("time_unit", "ns"), 1e-9)
    if med:
      cpu = e.get("cpu_time")
      cpu = cpu * unit if isinstance(cpu, (int, float)) else None
    else:
      ts = [x["cpu_time"] * UNIT_TO_S.get(x.get("time_unit", "ns"), 1e-9) for x in its
            if isinstance(x.get("cpu_time"), (int, float))]
      cpu = float(np.mean(ts)) if ts else None
    form, integ, setting = _parse_name(name)
    metrics = e.get("metrics") if isinstance(e.get("metrics"), dict) else {}
    ev = dict(metrics.get("event_time_error_s") or e.get("event_time_error_s") or {})
    for k, v in e.items():
      if k.startswith("event_time_error_s.") or k.startswith("event_time_error_s_"):
        ev[k[len("event_time_error_s") + 1:]] = v
    failed = bool(e.get("error_occurred")) or str(e.get("status", "ok")) not in ("ok", "completed")
    runs.append({"formulation": e.get("formulation", form), "integrator": e.get("integrator", integ) or "",
                 "setting": e.get("setting") if isinstance(e.get("setting"), dict) else setting,
                 "status": "failed" if failed else "ok",
                 "reason": e.get("error_message") or e.get("reason") or e.get("label") or "",
                 "scd": metrics.get("scd", e.get("scd")), "event_time_error_s": ev, "cpu_s": cpu,
                 "residual_evaluations": e.get("residual_evaluations"), "events": e.get("events")})
  return runs


def setting_str(s):
  if "step" in s:
    return f"h = {s['step']:.3g} s"
  if "rtol" in s:
    return f"rtol = {s['rtol']:.3g}"
  return json.dumps(s)


def classify_run(r):
  """'ok', or the reason the run is drawn as a failure. The reference's events are the keys
  of event_time_error_s (one per reference event)."""
  if r["status"] != "ok":
    return f"failed: {r['reason'] or r['status']}"
  scd = r.get("scd")
  if scd is None or not math.isfinite(float(scd)):
    return "no scd (comparison times missing: ended early or failed)"
  ev = r.get("event_time_error_s") or {}
  missing = [k for k, v in ev.items() if v is None or not math.isfinite(float(v))]
  if missing:
    return f"wrong events: reference event(s) {', '.join(missing)} missing"
  late = {k: float(v) for k, v in ev.items() if float(v) > WRONG_EVENT_TIME_S}
  if late:
    k = max(late, key=late.get)
    return f"wrong event time: {k} off by {late[k] * 1e3:.1f} ms (> {WRONG_EVENT_TIME_S * 1e3:g} ms)"
  if ev and r.get("events") is not None:
    extra = sorted({e["name"] for e in r["events"]} - set(ev) - {"flexion_90"})
    if extra:
      return f"wrong events: {', '.join(extra)} not in the reference"
  return "ok"


def event_digits(r):
  """Event-time digits: −log10 of the largest |t − t_ref| [s] over the reference's events."""
  ev = [float(v) for v in (r.get("event_time_error_s") or {}).values() if v is not None]
  if not ev:
    return None
  worst = max(ev)
  return 16.0 if worst <= 0 else -math.log10(worst)


def bench_key(r):
  return f"{r.get('formulation', '?')} / {r.get('integrator') or '-'}"


def make_work_precision(outdir, bench_path, prefix=""):
  """Returns (figure files, not-plotted rows [(key, setting, reason)], header). `prefix` keeps a
  second diagram set (e.g. the Simbody peer sweep) from overwriting the first."""
  header, runs = load_bench(bench_path)
  ok_runs, failed = [], []
  for r in runs:
    why = classify_run(r)
    if why == "ok":
      ok_runs.append(r)
    else:
      failed.append((bench_key(r), setting_str(r["setting"]), why, r))
  forms = sorted({r["formulation"] for r in runs})
  integs = sorted({r["integrator"] or "-" for r in runs})
  palette = plt.get_cmap("tab10").colors
  fcol = {f: palette[i % len(palette)] for i, f in enumerate(forms)}
  markers = "osD^v<>pP*Xh"
  imark = {g: markers[i % len(markers)] for i, g in enumerate(integs)}
  figdir = os.path.join(outdir, "figures")
  os.makedirs(figdir, exist_ok=True)
  files = []
  specs = [("work_precision_cpu.png", "cpu_s", "CPU time per run (median) [s]", lambda r: r["scd"],
            "scd of positions vs reference\n−log10 max|e|/(|ref| + 1 mm or 1°)"),
           ("work_precision_residuals.png", "residual_evaluations", "Residual (right-hand-side) evaluations",
            lambda r: r["scd"], "scd of positions vs reference\n−log10 max|e|/(|ref| + 1 mm or 1°)"),
           ("work_precision_events.png", "cpu_s", "CPU time per run (median) [s]", event_digits,
            "event-time digits\n−log10 max over events |t − t_ref| [s]")]
  def order(r):  # tolerance / step order along a series
    st = r["setting"]
    return -(st.get("rtol") or st.get("step") or 0.0)

  FAIL_Y = -0.6  # the failure row below each panel's data
  for fname, xkey, xlabel, yfn, ylabel in specs:
    ncol = min(3, max(1, len(forms)))
    nrow = max(1, math.ceil(len(forms) / ncol))
    fig, axes = plt.subplots(nrow, ncol, figsize=(4.6 * ncol, 3.6 * nrow + 0.8), sharex=True, sharey=True,
                             squeeze=False)
    ys = [yfn(r) for r in ok_runs if yfn(r) is not None]
    top = max(ys) + 0.5 if ys else 10.0
    for ax, f in zip(axes.flat, forms):
      for g in integs:
        pts = sorted((r for r in ok_runs if r["formulation"] == f and (r["integrator"] or "-") == g
                      and r.get(xkey) and yfn(r) is not None), key=order)
        if pts:
          ax.semilogx([r[xkey] for r in pts], [yfn(r) for r in pts], "-", color=fcol[f], marker=imark[g],
                      ms=5, mfc="none", lw=0.8, label=g if g != "-" else "built-in (IDA / Newmark)")
      bad = [row[3] for row in failed if row[3]["formulation"] == f and row[3].get(xkey)]
      if bad:
        ax.semilogx([r[xkey] for r in bad], [FAIL_Y] * len(bad), "x", color=fcol[f], ms=7, ls="none")
      ax.axhline(FAIL_Y + 0.45, color="k", lw=0.5, ls="--")
      ax.set_title(f"{f}  ({len(bad)} failed / wrong event)", color=fcol[f], fontsize=10, fontweight="bold")
      ax.grid(alpha=0.3, which="both")
      ax.set_ylim(FAIL_Y - 0.5, top)
      if ax.get_legend_handles_labels()[0]:
        ax.legend(title="integrator (marker)", fontsize=7, title_fontsize=7, loc="upper left")
    for ax in axes.flat[len(forms):]:
      ax.set_visible(False)
    for ax in axes[-1, :]:
      ax.set_xlabel(xlabel)
    for ax in axes[:, 0]:
      ax.set_ylabel(ylabel, fontsize=9)
    fig.suptitle(f"Work-precision, scene {header.get('scene', '?')}, {header.get('mode', '?')} sweep: "
                 f"{len(ok_runs)} runs plotted; {len(failed)} failed or wrong event (× on the bottom row)",
                 fontsize=11)
    fig.tight_layout()
    fig.savefig(os.path.join(figdir, prefix + fname), dpi=80)
    plt.close(fig)
    files.append(prefix + fname)
  return files, [row[:3] for row in failed], header


def main(argv=None):
  ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
  ap.add_argument("--out", required=True, help="directory written by run_families.py")
  ap.add_argument("--bench", help="benchmark JSON (work-precision diagrams)")
  args = ap.parse_args(argv)
  _, members = load_families(args.out)
  files = make_family_figures(args.out, members)
  print(f"figures: {len(files)} family figures -> {os.path.join(args.out, 'figures')}")
  if args.bench and os.path.exists(args.bench):
    wp, failed, _ = make_work_precision(args.out, args.bench)
    print(f"figures: {len(wp)} work-precision figures, {len(failed)} failed runs listed")
  return 0


if __name__ == "__main__":
  sys.exit(main())
