#!/usr/bin/python3
"""Report section on the patello-femoral joint (docs/model.md §12; chapter §1.7).

  patella_section.py --kneedyn PATH --out OUTDIR [--quick]

Runs kneedyn at report time and writes OUTDIR/patella/patella_section.json and the figures
OUTDIR/figures/patella_*.png; `section(OUTDIR)` turns them into the report's HTML.

  * Patellar kinematics (flexion, tilt, rotation, medial–lateral shift), the tendon force, the
    two facet forces and the tendon/quadriceps ratio against knee flexion on
    patellofemoral_impact and patellofemoral_extension (trajectory.csv's patella columns,
    docs/outputs.md), from one `ede` run per scene.
  * The ratio beside published values, only those whose text could be read (LITERATURE).
  * Work-precision of the coupling: `staggered` (the chapter's procedure, the tendon force
    lagged one step Δt = --step, dopri5 at rtol 1e-12 inside a step) at a few Δt, `ede` and
    `dae` at a few tolerances, and every other formulation the registry marks as needing a
    patella (`kneedyn formulations`), on patellofemoral_impact. Accuracy: scd of the
    positions (benchmarks/metrics.hpp: −log10 max |x − x_ref| / (|x_ref| + 1 mm or 1°) at
    every 0.02 s and at the end event) by `kneedyn score` against the stored reference
    reference-data/references/patellofemoral_impact.json when it exists, else by the same
    formula here against `ede` at rtol 1e-12 (run first). Cost: CPU s of the kneedyn
    process (getrusage of the child: reading the scene and writing the outputs included)
    and the right-hand-side / residual evaluations of its summary.json. The coupling error
    of `staggered`, max |flexion − reference| over the reference's samples before its first
    event, gives the observed order (least-squares slope of log error on log Δt) and the
    error constant e / Δt^p.

--quick (tests): the two scenes cut to 0.12 s and 0.25 s (written to OUTDIR/patella/scenes),
three Δt and two tolerances; the stored reference does not apply then and `ede` at rtol
1e-12 is the reference. Exit 0 when every run completed, 1 when one failed (shown in the
section), 2 on bad input.
"""
import argparse
import csv
import html
import json
import math
import os
import re
import resource
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SCENE_DIR = os.path.join(ROOT, "reference-data", "scenes")
REFERENCE_DIR = os.path.join(ROOT, "reference-data", "references")
IMPACT, EXTENSION = "patellofemoral_impact", "patellofemoral_extension"

# Full (main job) and quick (tests) plans. Runtime on the 2-core machine: see patella.md.
STEPS_S = {"full": (4e-3, 2e-3, 1e-3, 5e-4), "quick": (2e-3, 1e-3, 5e-4)}
RTOLS = {"full": (1e-6, 1e-8, 1e-10), "quick": (1e-6, 1e-8)}
QUICK_END_S = {IMPACT: 0.12, EXTENSION: 0.25}
STAGGERED_INNER = ["--rtol", "1e-12", "--atol", "1e-14"]  # dopri5 inside a step: the lag dominates
REFERENCE_SETTING = ["--rtol", "1e-12", "--atol", "1e-14"]  # ede, as reports/patella_coupling.py
KINEMATICS_SETTING = ["--rtol", "1e-10", "--atol", "1e-12"]  # ede on the extension scene
ADAPTIVE = ("ede", "dae")  # run a patella scene as one without (docs/model.md §12, form (i))
SAMPLE_INTERVAL_S = 0.02   # the reference's sampling (benchmarks/metrics.hpp)
POSITION_COLUMNS = ["x0_mm", "y0_mm", "z0_mm", "flexion_deg", "valgus_deg", "external_rotation_deg"]
POSITION_FLOOR = 1.0  # 1 mm and 1° (metrics.hpp)
RATIO_EVERY_DEG = 10.0

# Published tendon/quadriceps force ratios (F_P / F_Q), only what the text found says.
LITERATURE = [
    {"key": "jbiomech1988",
     "cite": "“Experimental determination of forces transmitted through the patello-femoral joint”, "
             "J Biomech 21(1):17–23, 1988, doi:10.1016/0021-9290(88)90187-x (PubMed 3339023)",
     "what": "eight cadaver knees; the abstract gives F_Q/F_P from 0.86 at 10° to 1.55 at 70° of flexion, "
             "drawn here as F_P/F_Q = 1/0.86 and 1/1.55",
     "points": [(10.0, 1.0 / 0.86), (70.0, 1.0 / 1.55)]},
    {"key": "invivo_mri",
     "cite": "“The effective quadriceps and patellar tendon moment arms relative to the tibiofemoral finite "
             "helical axis” (PMC4662057)",
     "what": "in vivo, dynamic MRI of 40 subjects in knee extension: F_P/F_Q > 1.0 for knee angles ≤ 20°",
     "points": []},
    {"key": "tension_ratio",
     "cite": "“An evaluation of the ratio between the tensions along the quadriceps tendon and the patellar "
             "ligament” (cadaver knees; abstract)",
     "what": "the ratio of the two tensions, often assumed to be 1, fell by up to 50 % as the knee flexed "
             "(the abstract does not say which tension is divided by which)",
     "points": []},
]
NOT_CONFIRMED = ("Huberti, Hayes, Stone & Shybut (J Orthop Res 2:49–54, 1984) and van Eijden, Kouwenhoven, "
                 "Verburg & Weijs (J Biomech 19:219–229, 1986), which the earlier reports/patella.md cited from "
                 "memory: no text of either (abstract, table or figure) was found, so neither is cited for a value "
                 "here.")


def scene_path(name):
  return os.path.join(SCENE_DIR, name + ".yaml")


def cut_scene(name, end_s, out_dir):
  """The scene with `end: {time_s: end_s}` and its parameter set by absolute path (tests)."""
  src = scene_path(name)
  with open(src, encoding="utf-8") as f:
    text = f.read()
  text = re.sub(r"^parameter_set:\s*(\S+)",
                lambda m: "parameter_set: " + os.path.normpath(os.path.join(SCENE_DIR, m.group(1))), text, flags=re.M)
  text, n = re.subn(r"^end:.*$", f"end: {{time_s: {end_s!r}}}", text, flags=re.M)
  if n != 1:
    raise ValueError(f"cut_scene: {src}: expected one 'end:' line, found {n}")
  os.makedirs(out_dir, exist_ok=True)
  path = os.path.join(out_dir, name + ".yaml")
  with open(path, "w", encoding="utf-8") as f:
    f.write(text)
  return path


def number(text):
  try:
    return float(text)
  except (TypeError, ValueError):
    return math.nan


def shown(cmd, out):
  """The command as a reader types it: the binary as kneedyn, paths in the repository relative
  to it, paths under the report's output directory `out` as OUT/…."""
  out_root = os.path.abspath(out)
  words = []
  for i, c in enumerate(cmd):
    a = os.path.abspath(c) if os.sep in c else None
    if i == 0:
      words.append("kneedyn")
    elif a and a.startswith(out_root + os.sep):
      words.append("OUT/" + os.path.relpath(a, out_root))
    elif a and a.startswith(ROOT + os.sep):
      words.append(os.path.relpath(a, ROOT))
    else:
      words.append(c)
  return " ".join(words)


def run(kneedyn, scene, run_dir, formulation, args, out):
  """One `kneedyn run`; its record (command, exit, CPU s, counters, events) and its table."""
  cmd = [kneedyn, "run", scene, "--formulation", formulation, *args, "--out", run_dir, "--quiet"]
  for legacy in ("sampled.csv", "sampled.score.json"):  # written into run directories before 2026-12-03
    if os.path.isfile(os.path.join(run_dir, legacy)):
      os.remove(os.path.join(run_dir, legacy))
  before = resource.getrusage(resource.RUSAGE_CHILDREN)
  p = subprocess.run(cmd, capture_output=True, text=True)
  after = resource.getrusage(resource.RUSAGE_CHILDREN)
  rec = {"formulation": formulation, "args": list(args), "command": shown(cmd, out),
         "exit": p.returncode, "run_dir": run_dir,
         "cpu_s": (after.ru_utime + after.ru_stime) - (before.ru_utime + before.ru_stime)}
  summary_path = os.path.join(run_dir, "summary.json")
  if p.returncode != 0 or not os.path.exists(summary_path):
    rec["ok"] = False
    rec["reason"] = (p.stderr.strip().splitlines() or [f"exit {p.returncode}"])[-1][-300:]
    return rec, None
  with open(summary_path, encoding="utf-8") as f:
    summary = json.load(f)
  with open(os.path.join(run_dir, "trajectory.csv"), newline="", encoding="utf-8") as f:
    table = [{k: number(v) for k, v in r.items()} for r in csv.DictReader(f)]
  stats = summary.get("statistics", {})
  rec.update(ok=True, steps=stats.get("steps"), residual_evaluations=stats.get("residual_evaluations"),
             wall_time_s=summary.get("wall_time_s"),
             events=[{"name": e["name"], "time_s": e["time"]} for e in summary.get("events", [])])
  return rec, table


def formulations(kneedyn):
  """`kneedyn formulations` lines: [(name, needs a patella)] in registry order."""
  import tool_input
  p = tool_input.run_command([kneedyn, "formulations"])  # its failure ends the study: exit 1
  return [(line.split()[0], "needs a patella" in line) for line in p.stdout.splitlines() if line.strip()]


# ---------------------------------------------------------------------------------------
# Reference and metrics (the formula of benchmarks/metrics.hpp, positions only)

def on_grid(t):
  k = round(t / SAMPLE_INTERVAL_S)
  return abs(t - k * SAMPLE_INTERVAL_S) < 1e-9


def samples(table):
  """{time: row} at the sampling times (no event rows), and the end row when it is an event."""
  grid = {round(r["time_s"], 9): r for r in table if r.get("is_event") != 1.0 and on_grid(r["time_s"])}
  end = table[-1] if table and table[-1].get("is_event") == 1.0 else None
  return grid, end


def reference_from_run(table, events):
  grid, end = samples(table)
  times = sorted(grid)
  ref = {"times_s": times + ([end["time_s"]] if end else []), "end_is_event": end is not None,
         "positions": [[grid[t][c] for c in POSITION_COLUMNS] for t in times]
         + ([[end[c] for c in POSITION_COLUMNS]] if end else []),
         "events": {e["name"]: e["time_s"] for e in events}}
  return ref


def reference_from_stored(path):
  with open(path, encoding="utf-8") as f:
    j = json.load(f)
  sol = j["solution"]
  cls = sol["classes"]["positions"]
  idx = [cls["names"].index(c) for c in POSITION_COLUMNS]
  return {"times_s": sol["times_s"], "end_is_event": sol.get("end_is_event", False),
          "positions": [[v[i] for i in idx] for v in cls["values"]],
          "events": {e["name"]: e["time_s"] for e in sol["events"]},
          "accuracy_scd": j.get("accuracy_scd")}


def compare(ref, table, events):
  """scd of the positions at the reference's times, the flexion error before the reference's
  first event (deg) and the event-time errors (s)."""
  grid, end = samples(table)
  flexion = POSITION_COLUMNS.index("flexion_deg")
  first_event = min(list(ref["events"].values()) + [math.inf])
  worst, flex_err, missing, worst_at = 0.0, 0.0, 0, None
  n = len(ref["times_s"])
  for i, (t, x_ref) in enumerate(zip(ref["times_s"], ref["positions"])):
    is_end = ref["end_is_event"] and i == n - 1
    row = end if is_end else grid.get(round(t, 9))
    if row is None:
      missing += 1
      continue
    for j, c in enumerate(POSITION_COLUMNS):
      e = abs(row[c] - x_ref[j]) / (abs(x_ref[j]) + POSITION_FLOOR)
      if e > worst:
        worst, worst_at = e, {"time_s": t, "column": c}
    if not is_end and t < first_event:
      flex_err = max(flex_err, abs(row["flexion_deg"] - x_ref[flexion]))
  run_events = {e["name"]: e["time_s"] for e in events}
  return {"scd": (-math.log10(worst) if worst > 0 else 16.0) if missing == 0 else None,
          "missing_times": missing, "flexion_error_deg": flex_err, "worst_at": worst_at,
          "event_time_errors_s": {k: (run_events[k] - v if k in run_events else None) for k, v in ref["events"].items()}}


def score_with_kneedyn(kneedyn, scene, table, rec, reference_path):
  """scd by `kneedyn score` against the stored reference: the run's rows at the reference's
  sampling times and its end-event row (no off-grid rows: those would make kneedyn score
  rerun the reference's configuration). Both files go beside the run directory, not into it:
  kneedyn refuses to overwrite a directory holding files that are not its own outputs."""
  grid, end = samples(table)
  rows = [grid[t] for t in sorted(grid)] + ([end] if end else [])
  csv_path = rec["run_dir"] + ".sampled.csv"
  with open(csv_path, "w", newline="", encoding="utf-8") as f:
    w = csv.writer(f)
    w.writerow(["time_s", "is_event"] + POSITION_COLUMNS)
    for r in rows:
      w.writerow([repr(r["time_s"]), int(r.get("is_event") == 1.0)] + [repr(r[c]) for c in POSITION_COLUMNS])
  out = rec["run_dir"] + ".sampled.score.json"
  summary = os.path.join(rec["run_dir"], "summary.json")
  p = subprocess.run([kneedyn, "score", csv_path, "--scene", scene, "--reference", reference_path,
                      "--events", summary, "--counters", summary, "--cpu-time", repr(rec["cpu_s"]),
                      "--solver-name", rec["formulation"], "--out", out], capture_output=True, text=True)
  if p.returncode != 0 or not os.path.exists(out):
    raise RuntimeError(f"kneedyn score: exit {p.returncode}: {p.stderr.strip()[-300:]}")
  with open(out, encoding="utf-8") as f:
    j = json.load(f)
  m = ((j.get("results") or [{}])[0]).get("metrics") or {}
  if not isinstance(m.get("scd"), (int, float)):
    raise RuntimeError(f"kneedyn score: no scd in {out}")
  return m["scd"], m.get("scd_ceiling"), bool(m.get("scd_above_ceiling"))


def finite(x):
  """x with NaN and infinities as None (strict JSON)."""
  if isinstance(x, float):
    return x if math.isfinite(x) else None
  if isinstance(x, dict):
    return {k: finite(v) for k, v in x.items()}
  if isinstance(x, (list, tuple)):
    return [finite(v) for v in x]
  return x


def fit_order(points):
  """Least-squares slope p of log e on log Δt and the constant C of e = C Δt^p."""
  pts = [(math.log(dt), math.log(e)) for dt, e in points if e > 0]
  if len(pts) < 2:
    return None, None
  mx = sum(x for x, _ in pts) / len(pts)
  my = sum(y for _, y in pts) / len(pts)
  p = sum((x - mx) * (y - my) for x, y in pts) / sum((x - mx) ** 2 for x, _ in pts)
  return p, math.exp(my - p * mx)


# ---------------------------------------------------------------------------------------
# The study

PATELLA_COLUMNS = ["flexion_deg", "patella_flexion_deg", "patella_tilt_deg", "patella_rotation_deg",
                   "patella_shift_mm", "quadriceps_N", "tendon_force_N", "N_patella_medial_N",
                   "N_patella_lateral_N", "tendon_quadriceps_ratio"]


def against_flexion(table, every_deg=RATIO_EVERY_DEG):
  """The first rows past each multiple of every_deg of flexion, in the run's direction
  (flexing: 0, 10, …; extending from 90°: 90, 80, …)."""
  rows = [r for r in table if r.get("is_event") != 1.0 or r is table[-1]]
  if not rows:
    return []
  extending = rows[-1]["flexion_deg"] < rows[0]["flexion_deg"]
  out = []
  sign = -1.0 if extending else 1.0
  target = math.ceil(rows[0]["flexion_deg"] / every_deg - 1e-9) * every_deg if not extending else \
      math.floor(rows[0]["flexion_deg"] / every_deg + 1e-9) * every_deg
  for r in rows:
    if sign * (r["flexion_deg"] - target) >= 0:
      out.append({"time_s": r["time_s"], **{c: r[c] for c in PATELLA_COLUMNS}})
      while sign * (r["flexion_deg"] - target) >= 0:
        target += sign * every_deg
  return out


def at_flexion(table, angle_deg, column):
  """column at the first crossing of angle_deg of knee flexion (linear between the two rows),
  None when the run does not cross it."""
  for a, b in zip(table, table[1:]):
    fa, fb = a["flexion_deg"], b["flexion_deg"]
    if fa != fb and min(fa, fb) <= angle_deg <= max(fa, fb):
      w = (angle_deg - fa) / (fb - fa)
      return a[column] + w * (b[column] - a[column])
  return None


def pulling_facet(table):
  """The first row where a facet force is negative (the facet would pull: outside the
  two-contact model, which has no patellar facet lift-off), or None."""
  for r in table:
    for facet in ("medial", "lateral"):
      if r[f"N_patella_{facet}_N"] < 0:
        return {"facet": facet, "time_s": r["time_s"], "flexion_deg": r["flexion_deg"]}
  return None


def curves(table):
  cols = ["time_s"] + PATELLA_COLUMNS
  return {c: [r[c] for r in table] for c in cols}


def study(kneedyn, out, quick):
  plan = "quick" if quick else "full"
  pdir = os.path.join(out, "patella")
  os.makedirs(pdir, exist_ok=True)
  scenes = {n: (cut_scene(n, QUICK_END_S[n], os.path.join(pdir, "scenes")) if quick else scene_path(n))
            for n in (IMPACT, EXTENSION)}
  stored = os.path.join(REFERENCE_DIR, IMPACT + ".json")
  use_stored = (not quick) and os.path.exists(stored)
  result = {"plan": plan, "scenes": {n: os.path.relpath(p, ROOT) if p.startswith(ROOT) else p for n, p in scenes.items()},
            "runs": [], "failed": []}
  ok = True

  def record(rec):
    nonlocal ok
    result["runs"].append(rec)
    if not rec.get("ok"):
      ok = False
      result["failed"].append(rec)

  # The reference: stored, or ede at rtol 1e-12; either way this run is the impact scene's
  # kinematics run (at rtol 1e-10 when the stored reference scores).
  ref_rec, ref_table = run(kneedyn, scenes[IMPACT], os.path.join(pdir, "impact_ede"), "ede",
                           KINEMATICS_SETTING if use_stored else REFERENCE_SETTING, out)
  ref_rec["role"] = "reference" if not use_stored else "kinematics"
  record(ref_rec)
  if use_stored:
    reference = reference_from_stored(stored)
    result["reference"] = {"kind": "stored", "path": os.path.relpath(stored, ROOT),
                           "accuracy_scd": reference.get("accuracy_scd"), "scorer": "kneedyn score"}
  elif ref_table is not None:
    reference = reference_from_run(ref_table, ref_rec["events"])
    result["reference"] = {"kind": "run", "command": ref_rec["command"], "scorer": "patella_section.compare "
                           "(benchmarks/metrics.hpp's scd formula)"}
  else:
    result["reference"] = {"kind": "failed", "reason": ref_rec.get("reason")}
    reference = None
  result["reference"]["events"] = reference["events"] if reference else {}

  # Kinematics and forces against flexion: the impact's reference run, the extension's ede run.
  ext_rec, ext_table = run(kneedyn, scenes[EXTENSION], os.path.join(pdir, "extension_ede"), "ede", KINEMATICS_SETTING,
                        out)
  ext_rec["role"] = "kinematics"
  record(ext_rec)
  result["kinematics"] = {}
  for name, rec, table in ((IMPACT, ref_rec, ref_table), (EXTENSION, ext_rec, ext_table)):
    if table is not None:
      result["kinematics"][name] = {"command": rec["command"], "run_dir": os.path.relpath(rec["run_dir"], out),
                                    "against_flexion": against_flexion(table), "curves": curves(table),
                                    "pulling_facet": pulling_facet(table),
                                    "ratio_at_literature_angles": {
                                        f"{x:g}": at_flexion(table, x, "tendon_quadriceps_ratio")
                                        for L in LITERATURE for x, _ in L["points"]}}

  # Work-precision: staggered and every formulation needing a patella, ede and dae.
  forms = formulations(kneedyn)
  needing = [n for n, needs in forms if needs]
  settings = []
  for name in needing:
    settings += [(name, ["--step", repr(h)] + STAGGERED_INNER, {"step_s": h}) for h in STEPS_S[plan]]
  for name in ADAPTIVE:
    settings += [(name, ["--rtol", repr(r), "--atol", repr(r * 1e-2)], {"rtol": r}) for r in RTOLS[plan]]
  result["needs_patella"] = needing
  points = []
  refused_step = set()
  for name, args, setting in settings:
    if name in refused_step and "step_s" in setting:  # adaptive, needing a patella: tolerances instead
      continue
    tag = name + "_" + "_".join(f"{k}{v:g}" for k, v in setting.items())
    rec, table = run(kneedyn, scenes[IMPACT], os.path.join(pdir, "wp", tag), name, args, out)
    if rec["exit"] == 2 and "step_s" in setting and "--step" in rec.get("reason", ""):
      refused_step.add(name)
      for r in RTOLS[plan]:
        settings.append((name, ["--rtol", repr(r), "--atol", repr(r * 1e-2)], {"rtol": r}))
      continue
    rec["setting"] = setting
    rec["role"] = "work-precision"
    if table is not None and reference is not None:
      rec.update(compare(reference, table, rec["events"]))
      if use_stored:
        try:
          rec["scd_python"] = rec["scd"]
          rec["scd"], rec["scd_ceiling"], rec["scd_above_ceiling"] = score_with_kneedyn(
              kneedyn, scenes[IMPACT], table, rec, stored)
        except RuntimeError as e:
          rec["score_error"] = str(e)
    record(rec)
    points.append(rec)
  result["work_precision"] = points
  stag = [r for r in points if r["formulation"] == "staggered" and r.get("ok") and "step_s" in r["setting"]]
  p, c = fit_order([(r["setting"]["step_s"], r["flexion_error_deg"]) for r in stag])
  for prev, cur in zip(stag, stag[1:]):
    if prev["flexion_error_deg"] > 0 and cur["flexion_error_deg"] > 0:
      cur["observed_order"] = math.log(prev["flexion_error_deg"] / cur["flexion_error_deg"]) / \
          math.log(prev["setting"]["step_s"] / cur["setting"]["step_s"])
  result["staggered_order"] = {"fitted_order": p, "error_constant_deg_per_s_p": c}
  result["cpu_s_total"] = sum(r["cpu_s"] for r in result["runs"])
  result["literature"] = [{k: v for k, v in L.items()} for L in LITERATURE]
  result["not_confirmed"] = NOT_CONFIRMED
  with open(os.path.join(pdir, "patella_section.json"), "w", encoding="utf-8") as f:
    json.dump(finite(result), f, indent=1, allow_nan=False)
  return result, ok


# ---------------------------------------------------------------------------------------
# Figures

FIGURES = [("patella_kinematics.png", "Patellar kinematics against knee flexion"),
           ("patella_forces.png", "Tendon force and facet contact forces against knee flexion"),
           ("patella_ratio.png", "Patellar-tendon / quadriceps force ratio against knee flexion"),
           ("patella_work_precision.png", "Work-precision of the tibia–patella coupling on patellofemoral_impact: CPU time "
            "against scd (left); the staggered scheme's coupling error, max |flexion − reference| before the "
            "reference's first event, against Δt (right)")]
STYLE = {IMPACT: "-", EXTENSION: "--"}


def make_figures(result, out):
  import matplotlib
  matplotlib.use("Agg")
  import matplotlib.pyplot as plt
  import matplotlib.ticker  # noqa: F401  (matplotlib.ticker below)
  fdir = os.path.join(out, "figures")
  os.makedirs(fdir, exist_ok=True)
  kin = result.get("kinematics", {})
  written = []

  def finish(a, xlabel, ylabel, **grid):
    """Axis labels, a light grid (matplotlib grid keywords) and the legend."""
    a.set_xlabel(xlabel)
    a.set_ylabel(ylabel)
    a.grid(alpha=0.3, **grid)
    a.legend(fontsize=7)

  def save(fig, name):
    """Writes fig as figures/name (110 dpi) and closes it."""
    fig.tight_layout()
    fig.savefig(os.path.join(fdir, name), dpi=110)
    plt.close(fig)
    written.append(name)

  fig, ax = plt.subplots(1, 2, figsize=(10, 3.8))
  for name, k in kin.items():
    c = k["curves"]
    for col, lab, colour in (("patella_flexion_deg", "flexion", "C0"), ("patella_tilt_deg", "tilt", "C1"),
                             ("patella_rotation_deg", "rotation", "C2")):
      ax[0].plot(c["flexion_deg"], c[col], STYLE[name], color=colour, label=f"{lab} ({name.split('_')[1]})")
    ax[1].plot(c["flexion_deg"], c["patella_shift_mm"], STYLE[name], color="C3", label=name.split("_")[1])
  finish(ax[0], "knee flexion (deg)", "patellar angle (deg)")
  finish(ax[1], "knee flexion (deg)", "patellar medial–lateral shift x_P (mm)")
  save(fig, "patella_kinematics.png")

  fig, ax = plt.subplots(1, 2, figsize=(10, 3.8))
  for i, (name, k) in enumerate(kin.items()):
    c = k["curves"]
    for col, lab, colour in (("tendon_force_N", "tendon F_t", "C0"), ("N_patella_medial_N", "medial facet", "C1"),
                             ("N_patella_lateral_N", "lateral facet", "C2"), ("quadriceps_N", "quadriceps F_Q", "k")):
      ax[i].plot(c["flexion_deg"], c[col], "-", color=colour, label=lab)
    ax[i].axhline(0.0, color="0.6", lw=0.8)
    ax[i].set_title(name, fontsize=9)
    finish(ax[i], "knee flexion (deg)", "force (N)")
  save(fig, "patella_forces.png")

  fig, ax = plt.subplots(figsize=(6.5, 4))
  for name, k in kin.items():
    c = k["curves"]
    ax.plot(c["flexion_deg"], c["tendon_quadriceps_ratio"], STYLE[name], color="C0", label=f"kneedyn, {name}")
  for L, marker in zip([L for L in result.get("literature", []) if L["points"]], "so^"):
    xs, ys = zip(*L["points"])
    ax.plot(xs, ys, marker, color="C3", linestyle="none", label="cadaver, J Biomech 1988 (abstract)")
  ax.axhline(1.0, color="0.6", lw=0.8)
  finish(ax, "knee flexion (deg)", "F_t / F_Q")
  save(fig, "patella_ratio.png")

  pts = [r for r in result.get("work_precision", []) if r.get("ok") and isinstance(r.get("scd"), (int, float))]
  fig, ax = plt.subplots(1, 2, figsize=(10.5, 4))
  for i, name in enumerate(dict.fromkeys(r["formulation"] for r in pts)):
    rs = [r for r in pts if r["formulation"] == name]
    ax[0].semilogy([r["scd"] for r in rs], [r["cpu_s"] for r in rs], "o-", color=f"C{i}", label=name)
    for r in rs:
      s = r["setting"]
      ax[0].annotate(f"Δt {s['step_s'] * 1e3:g} ms" if "step_s" in s else f"rtol {s['rtol']:.0e}",
                     (r["scd"], r["cpu_s"]), fontsize=6, xytext=(5, -3), textcoords="offset points")
  finish(ax[0], "accuracy: scd of the positions (digits)", "CPU time of the kneedyn run (s)", which="both")
  stag = [r for r in pts if r["formulation"] == "staggered" and "step_s" in r["setting"]]
  if stag:
    dts = [r["setting"]["step_s"] for r in stag]
    errs = [r["flexion_error_deg"] for r in stag]
    ax[1].loglog([h * 1e3 for h in dts], errs, "o-", color="C0", label="staggered")
    o = result.get("staggered_order", {})
    if o.get("fitted_order") is not None:
      ax[1].loglog([h * 1e3 for h in dts], [o["error_constant_deg_per_s_p"] * h ** o["fitted_order"] for h in dts],
                   "k--", label=f"fit: order {o['fitted_order']:.2f}")
    ax[1].xaxis.set_major_locator(matplotlib.ticker.FixedLocator([h * 1e3 for h in dts]))
    ax[1].xaxis.set_major_formatter(matplotlib.ticker.FormatStrFormatter("%g"))
    ax[1].xaxis.set_minor_locator(matplotlib.ticker.NullLocator())
  finish(ax[1], "Δt (ms)", "coupling error: max |Δflexion| (deg)", which="both")
  save(fig, "patella_work_precision.png")
  return written


# ---------------------------------------------------------------------------------------
# HTML

def esc(x):
  return html.escape(str(x))


def fmt(v, spec):
  return format(v, spec) if isinstance(v, (int, float)) and not (isinstance(v, float) and math.isnan(v)) else "–"


def html_table(headers, rows):
  out = ["<div class='scroll'><table><thead><tr>" + "".join(f"<th>{esc(h)}</th>" for h in headers)
         + "</tr></thead><tbody>"]
  for r in rows:
    out.append("<tr>" + "".join(f"<td>{esc(c)}</td>" for c in r) + "</tr>")
  out.append("</tbody></table></div>")
  return "\n".join(out)


def figure(fname, caption):
  return (f"<figure><img src='figures/{esc(fname)}' alt='{esc(caption)}'><figcaption>{esc(caption)} "
          f"(<code>{esc(fname)}</code>)</figcaption></figure>")


def section(outdir):
  path = os.path.join(outdir, "patella", "patella_section.json")
  parts = ["<h2 id='patella'>The patello-femoral joint</h2>"]
  if not os.path.exists(path):
    return "\n".join(parts + ["<p class='warn'>No patella study (reports/patella_section.py did not run).</p>"])
  with open(path, encoding="utf-8") as f:
    r = json.load(f)
  kin = r.get("kinematics", {})
  parts.append(
      "<p>The knee with its patella (chapter §1.7; docs/model.md §12): a massless third body on two frictionless "
      "facet contacts, held by a rigid patellar tendon to the tibial tuberosity and pulled by the quadriceps. The "
      "chapter gives no patellar data; the geometry is partly assumed (docs/model.md §12, table), so the numbers "
      "describe this model, not a measured knee. Scenes: <code>patellofemoral_impact</code> (the chapter's impact "
      "with a constant 50 N quadriceps force) and <code>patellofemoral_extension</code> (from 90° under a quadriceps "
      "force ramped from 20 to 400 N, gravity on)" + (" — <b>quick mode</b>: both cut short (" + esc(", ".join(
          f"{k}: {v}" for k, v in r.get("scenes", {}).items())) + ")" if r.get("plan") == "quick" else "") + ". "
      "Runs: " + "; ".join(f"<code>{esc(k['command'])}</code>" for k in kin.values()) + ".</p>")
  parts.append(figure(*FIGURES[0]))
  parts.append("<p>Patellar flexion φ, tilt τ and rotation ρ and the shift x_P are the patello-femoral joint "
               "coordinates of docs/model.md §12 (patellar frame P against the femoral frame F); the tendon force "
               "F_t and the facet forces N come from the patella's equilibrium at each output row's tibial pose "
               "(trajectory.csv's patella columns, docs/outputs.md).</p>")
  parts.append(figure(*FIGURES[1]))
  for name, k in kin.items():
    pf = k.get("pulling_facet")
    if pf:
      parts.append(f"<p class='warn'>{esc(name)}: the {esc(pf['facet'])} facet force turns negative at "
                   f"{pf['flexion_deg']:.1f}° of knee flexion (t = {pf['time_s']:.3f} s): the facet would pull. This "
                   "two-contact model has no patellar facet lift-off (docs/model.md §12), so past that point its "
                   "patellar pose and forces are outside the model's validity; they are drawn, not interpreted.</p>")
  parts.append(figure(*FIGURES[2]))
  rows = []
  for name, k in kin.items():
    for a in k["against_flexion"]:
      rows.append([name, fmt(a["time_s"], ".3f"), fmt(a["flexion_deg"], ".1f"), fmt(a["patella_flexion_deg"], ".2f"),
                   fmt(a["patella_tilt_deg"], ".2f"), fmt(a["patella_rotation_deg"], ".2f"),
                   fmt(a["patella_shift_mm"], ".2f"), fmt(a["quadriceps_N"], ".1f"), fmt(a["tendon_force_N"], ".2f"),
                   fmt(a["N_patella_medial_N"], ".2f"), fmt(a["N_patella_lateral_N"], ".2f"),
                   fmt(a["tendon_quadriceps_ratio"], ".4f")])
  parts.append("<h3>At every 10° of knee flexion</h3><p>First output row past each multiple of 10° (the "
               "extension scene from 90° down).</p>")
  parts.append(html_table(["scene", "t [s]", "knee flexion [deg]", "patellar flexion [deg]", "tilt [deg]",
                           "rotation [deg]", "shift [mm]", "F_Q [N]", "F_t [N]", "medial facet [N]",
                           "lateral facet [N]", "F_t / F_Q"], rows))
  lit = "".join(f"<li>{esc(L['cite'])}: {esc(L['what'])}.</li>" for L in r.get("literature", []))
  parts.append(
      "<p><b>Tendon/quadriceps ratio: a plausibility check, not a claim of the chapter.</b> Published values "
      "confirmed from their abstracts (the search found no full text of any):</p><ul>" + lit + "</ul>"
      + "".join(f"<p>This model at the cadaver abstract's angles, {esc(name)}: " + ", ".join(
          f"{esc(a)}°: {v:.2f}" if isinstance(v, (int, float)) else f"{esc(a)}°: not reached"
          for a, v in k.get("ratio_at_literature_angles", {}).items()) + ".</p>" for name, k in kin.items()) +
      f"<p>Not confirmed: {esc(r.get('not_confirmed', ''))} The points in the ratio figure are the cadaver "
      "abstract's two values only. In this model the ratio is a function of the tibial pose alone (docs/model.md "
      "§12: the equilibrium divided by F_Q does not contain F_Q), so the two scenes' curves differ only through "
      "their different tibial poses at the same flexion. The comparison is of shape and order of magnitude: the "
      "values depend on the assumed tuberosity, quadriceps line and facet angles.</p>")

  parts.append("<h3>The staggered scheme: coupling error and work-precision</h3>")
  ref = r.get("reference", {})
  ref_text = (f"the stored reference <code>{esc(ref.get('path'))}</code> (accuracy {esc(ref.get('accuracy_scd'))} "
              "digits), scored by <code>kneedyn score</code>" if ref.get("kind") == "stored" else
              f"<code>{esc(ref.get('command'))}</code> (no stored reference for the scene at report time), scored "
              "with benchmarks/metrics.hpp's scd formula in reports/patella_section.py" if ref.get("kind") == "run"
              else f"none: the reference run failed ({esc(ref.get('reason'))})")
  o = r.get("staggered_order", {})
  stag = [p for p in r.get("work_precision", []) if p["formulation"] == "staggered" and p.get("ok")]
  parts.append(
      "<p><code>staggered</code> is the chapter's procedure: on [t_k, t_k + Δt] the tendon pulls with the tension "
      "and towards the apex of the patella's equilibrium solved at t_k (Δt = <code>--step</code>), the tibia "
      "integrated by dopri5 at rtol 1e-12 inside a step, so the one-step lag is what separates it from "
      "<code>ede</code>, which solves the patella at every right-hand side. Formulations drawn: every one the "
      f"registry marks as needing a patella ({esc(', '.join(r.get('needs_patella', [])) or 'none')}) at Δt or at "
      "tolerances, and <code>ede</code>, <code>dae</code> at tolerances (atol = 1e-2 rtol), on "
      f"<code>{esc(r.get('scenes', {}).get(IMPACT))}</code>. Reference: {ref_text}. Accuracy: scd of the positions "
      "(x0, y0, z0 with a 1 mm floor, α, β, γ with 1°) at every 0.02 s and at the end event. Cost: CPU s of the "
      "whole kneedyn process (reading the scene and writing the outputs included; one run each, on the machine "
      "that built this report) and its right-hand-side / residual evaluations. Coupling error: max |flexion − "
      "reference| over the reference's samples before its first event.</p>")
  parts.append(figure(*FIGURES[3]))
  if o.get("fitted_order") is not None:
    parts.append(f"<p><b>Observed order</b> of the staggered coupling error {o['fitted_order']:.3f} (least squares "
                 f"over {len(stag)} Δt), error constant {o['error_constant_deg_per_s_p']:.3g} °/s^p: the one-step lag "
                 "is a first-order splitting.</p>")
  first_event = min(list(ref.get("events", {}).values()) + [math.inf])
  late = [p for p in stag if p.get("worst_at") and p["worst_at"]["time_s"] > first_event]
  if late:
    parts.append(f"<p>The staggered runs' scd is set after the reference's first event (t = {first_event:.4f} s) in "
                 f"{len(late)} of {len(stag)} runs (column <i>largest error at</i>): after the lateral lift-off the "
                 "tibia moves fast, and the lag's error in the event time (the event-time errors column) shows there "
                 "as the largest position error. The coupling error and its order are measured before the first "
                 "event.</p>")
  wp_rows = []
  for p in r.get("work_precision", []):
    s = p.get("setting", {})
    ev = p.get("event_time_errors_s") or {}
    scd = fmt(p.get("scd"), ".2f") + (f" (above the reference's ceiling {p['scd_ceiling']:.1f})"
                                      if p.get("scd_above_ceiling") else "")
    wp_rows.append([p["formulation"], f"Δt = {s['step_s']:g} s" if "step_s" in s else f"rtol = {s.get('rtol', 0):g}",
                    "ok" if p.get("ok") else f"failed: {p.get('reason', '')}", scd,
                    (f"{p['worst_at']['column']} at {p['worst_at']['time_s']:.4f} s" if p.get("worst_at") else "–"),
                    fmt(p.get("flexion_error_deg"), ".3e"), fmt(p.get("observed_order"), ".3f"),
                    " ".join(f"{k} {fmt(v, '+.2e')}" for k, v in ev.items()) or "–",
                    fmt(p.get("cpu_s"), ".3f"), fmt(p.get("residual_evaluations"), "d"), fmt(p.get("steps"), "d")])
  parts.append(html_table(["formulation", "setting", "status", "scd", "largest error (scd) at",
                           "coupling error [deg]", "order",
                           "event-time errors [s]", "CPU [s]", "RHS / residual evals", "steps"], wp_rows))
  parts.append(f"<p>The whole study (all runs above, the reference and the extension run) took "
               f"{r.get('cpu_s_total', 0):.1f} CPU s. Command: <code>/usr/bin/python3 reports/patella_section.py "
               "--kneedyn build/formulations/kneedyn --out OUT</code> (report.py runs it). More Δt and the dae–ede "
               "agreement: reports/patella.md.</p>")
  return "\n".join(parts)


def main(argv=None):
  ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
  ap.add_argument("--kneedyn", required=True)
  ap.add_argument("--out", required=True)
  ap.add_argument("--quick", action="store_true", help="cut scenes, fewer points (tests)")
  a = ap.parse_args(argv)
  import tool_input
  tool_input.kneedyn_executable("--kneedyn", a.kneedyn)
  tool_input.output_directory("--out", a.out)
  result, ok = study(os.path.abspath(a.kneedyn), a.out, a.quick)
  make_figures(result, a.out)
  o = result["staggered_order"]
  print(f"patella_section: {len(result['runs'])} runs, {result['cpu_s_total']:.1f} CPU s; staggered order "
        f"{o['fitted_order']}, constant {o['error_constant_deg_per_s_p']}; failed: {len(result['failed'])}")
  return 0 if ok else 1


if __name__ == "__main__":
  import tool_input
  sys.exit(tool_input.exit_code("patella_section", main))
