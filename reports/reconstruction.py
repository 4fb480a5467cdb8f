#!/usr/bin/python3
"""Reconstruction study: how much of the claims table rests on the readings of
the model that the printed chapter leaves uncertain.

  reconstruction.py --kneedyn PATH --out OUTDIR [--quick] [--jobs N]
                    [--calibrate BIN [--calibrate-grid N] [--calibrate-iterations K]]

For each reading (pulse shape of the garbled Eq. 1.62 × gravity on/off, plus the C¹
ligament law that docs/model.md records as a departure) it runs the chapter's pulse
families with the reference solver (as run_families.py, with the scene patched), evaluates
every claim of reports/claims.yaml with reports/claims.py, and writes
OUTDIR/reconstruction/reconstruction.json: per reading the verdict of each claim, the count
reproduced, the lateral lift-off angle and the valgus→varus crossings of the shortest and
longest pulse. With --calibrate it also runs the Ceres calibration
(reports/calibrate_reconstruction.cpp) into OUTDIR/reconstruction/calibration.json:
--calibrate-grid N (default 5, a whole number in [1, 100]) is its start grid, N × N points
over the pulse scale and the gravity angle (its --grid), --calibrate-iterations K (default 20,
a whole number in [0, 10000]; 0 = the grid only) its Ceres iterations (its --max-iterations).
With --calibrate both are checked before any family run; without it they are not used.
--jobs N: family runs at a time, a whole number in [1, 1024] (default: the number of CPUs).
The sensitivity statements S1/S2 do not depend on the pulse or model reading and are not
re-run per reading; S2 is re-run once under the chapter's DASSL start (s2_dassl_start).
Exit 0 when every run completed, 1 when some failed (recorded per reading), 2 on bad input.
"""
import argparse
import concurrent.futures
import csv
import json
import os
import subprocess
import sys

import numpy as np

sys.dont_write_bytecode = True  # keep the source tree clean
HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import claims  # noqa: E402
import run_families  # noqa: E402
import tool_input  # noqa: E402
from family_data import load_families  # noqa: E402

# (key, label, scene patch). The first is the project's reading (reference-data scene).
SHAPES = [("reconstructed", "A (t/t0) sin(2πt/t0) e^(−4.73 t/t0) (the project's reading; peak 0.077 A)"),
          ("reconstructed_peak", "the same shape normalized to peak A"),
          ("damped_sine", "A sin(2πt/t0) e^(−4.73 t/t0) (peak 0.398 A)"),
          ("half_sine", "A sin(πt/t0) on [0, t0]")]
READINGS = ([(f"{k}/g_on", f"pulse {label}; gravity on", {"pulse": {"shape": k}}) for k, label in SHAPES]
            + [(f"{k}/g_off", f"pulse {label}; gravity off", {"pulse": {"shape": k}, "gravity": {"enabled": False}})
               for k, label in SHAPES]
            + [("reconstructed/g_on/c1_law", "project's reading with the C¹ ligament law (no force jump at ε = 2ε1)",
                {"ligament_law": "c1_continuous"})])
# The model readings: one per ambiguity docs/model.md lists (§2, §3, §5, §6), each a scene
# patch on the project's pulse reading with gravity on. A patch may name a parameter-set
# variant (PARAMETER_SET_VARIANTS), written beside the reading's scenes.
# (key, label, patch, docs/model.md section, what it reads differently)
TABLE_1_2 = {  # Table 1.2 as printed: K1 (first column, the project's k_lin) and K2 (second, k_par)
    "ACL anterior": (83.15, 22.48), "ACL posterior": (83.15, 26.27), "PCL anterior": (125.00, 31.26),
    "PCL posterior": (60.00, 19.29), "MCL anterior": (91.25, 10.00), "MCL oblique": (27.86, 5.00),
    "MCL deep": (21.07, 5.00), "LCL": (72.22, 10.00), "capsule medial": (52.59, 12.00),
    "capsule lateral": (54.62, 12.00), "oblique popliteal": (21.42, 3.00), "arcuate popliteal": (20.82, 3.00)}
MODEL_READINGS = [
    ("omega_y_printed", "ω′y with + β̇ cos γ as printed in Eq. 1.20b (not an angular velocity)",
     {"angular_velocity_map": "printed_eq_1_20b"}, "§2"),
    ("r0_medial", "initial R0 from the medial contact condition only; α, β close the lateral contact",
     {"initial_state": {"origin": "medial_contact", "hold": ["x0", "y0", "z0", "gamma", "velocities"]}}, "§6"),
    ("stiffness_as_printed", "Table 1.2 as labelled: K1 (first column) parabolic in N/mm², K2 linear",
     {"ligament_parameters": {n: {"k_linear_N_mm": k2, "k_parabolic_N_mm2": k1} for n, (k1, k2) in TABLE_1_2.items()}},
     "§5"),
    ("plane_slope_y", "tibial planes g = m y′ + c as printed (anterior–posterior slope, signs as printed)",
     {"parameter_set": "variant:plane_slope_y"}, "§3"),
    ("c1_law", "C¹ ligament law (no force jump at ε = 2ε1)", {"ligament_law": "c1_continuous"}, "§5"),
    ("strains_up", "every extension ratio e + 0.0005 (half of Table 1.3's last printed digit)",
     {"parameter_set": "variant:strains_up"}, "§5"),
    ("strains_down", "every extension ratio e − 0.0005", {"parameter_set": "variant:strains_down"}, "§5"),
    ("insertions_a", "every attachment coordinate moved by half its last printed digit (±0.05 or ±0.005 mm), "
     "signs from seed 1", {"parameter_set": "variant:insertions_a"}, "§5"),
    ("insertions_b", "the same with the signs of seed 2", {"parameter_set": "variant:insertions_b"}, "§5"),
]
# Combinations, in the order the Sobol' indices rank what the readings touch: in the
# 20-parameter Saltelli study of the chapter scene (reference-data/specs/chapter_saltelli20.yaml,
# 446 groups) the total indices of the lateral lift-off angle are largest for the reference
# strains (PCL anterior e 0.60, ACL anterior e 0.35), then the stiffnesses (MCL deep k_lin
# 0.20, PCL anterior k_lin 0.19); pulse and mass are below 0.1. So the strain readings come
# first, then the stiffness reading, then the structural readings, which no index ranks.
COMBINATIONS = [("strains_down", "stiffness_as_printed"), ("strains_up", "stiffness_as_printed"),
                ("strains_down", "stiffness_as_printed", "omega_y_printed"),
                ("strains_down", "stiffness_as_printed", "r0_medial"),
                ("strains_down", "stiffness_as_printed", "omega_y_printed", "r0_medial", "c1_law")]


def merge_patch(a, b):
  out = json.loads(json.dumps(a))
  for k, v in b.items():
    if isinstance(v, dict) and isinstance(out.get(k), dict):
      out[k] = merge_patch(out[k], v)
    else:
      out[k] = v
  return out


def combination(keys):
  by = {r[0]: r for r in MODEL_READINGS}
  patch, variants = {}, []
  for k in keys:
    p = dict(by[k][2])
    if str(p.get("parameter_set", "")).startswith("variant:"):
      variants.append(p.pop("parameter_set")[len("variant:"):])
    patch = merge_patch(patch, p)
  if variants:
    patch["parameter_set"] = "variant:" + "+".join(variants)
  sections = sorted({by[k][3] for k in keys}, key=lambda x: int(x.strip("§")))
  return ("model/" + "+".join(keys), "combination: " + " + ".join(keys), patch, ", ".join(sections))


def half_digit(value):
  """Half a unit of the last digit Table 1.1 prints for a coordinate (one or two decimals)."""
  return 0.005 if abs(round(value * 10) - value * 10) > 1e-9 else 0.05


def parameter_set_variant(names, path):
  """Writes the chapter parameter set with the variants `names` applied; returns its path."""
  base = run_families.load_base_scene()["parameter_set"]
  with open(base) as f:
    ps = run_families.yaml.safe_load(f)
  for name in names:
    if name in ("strains_up", "strains_down"):
      for lig in ps["ligaments"]:
        lig["extension_ratio"] = round(lig["extension_ratio"] + (0.0005 if name == "strains_up" else -0.0005), 6)
    elif name in ("insertions_a", "insertions_b"):
      rng = np.random.default_rng(1 if name == "insertions_a" else 2)
      for lig in ps["ligaments"]:
        for key in ("femoral_mm", "tibial_mm"):
          lig[key] = [round(v + float(rng.choice([-1.0, 1.0])) * half_digit(v), 6) for v in lig[key]]
    elif name == "plane_slope_y":
      # Eq. 1.5 as printed: the slope on y′ (the reference pose is solved from these planes).
      for comp in ("medial", "lateral"):
        plane = ps["compartments"][comp]["tibial_surface"]
        plane["slope_x"], plane["slope_y"] = 0.0, plane["slope_x"]
    else:
      raise ValueError(f"unknown parameter-set variant '{name}'")
  with open(path, "w") as f:
    run_families.yaml.safe_dump(ps, f, sort_keys=False)
  return path


def resolve_patch(patch, rdir):
  """A patch with parameter_set 'variant:a+b' gets the written variant's path instead."""
  ps = patch.get("parameter_set")
  if isinstance(ps, str) and ps.startswith("variant:"):
    patch = dict(patch, parameter_set=parameter_set_variant(ps[len("variant:"):].split("+"),
                                                            os.path.join(rdir, "parameter_set.yaml")))
  return patch


READINGS += [(f"model/{k}", label, patch) for k, label, patch, _ in MODEL_READINGS]
READINGS += [combination(c)[:3] for c in COMBINATIONS]


def same_as(readings):
  """{key: the earlier reading's key} for a reading whose scene patch equals an earlier one's
  (model/c1_law is the pulse readings' reconstructed/g_on/c1_law): its scenes and runs are the
  same, so it keeps its row (and the numbering) but is not counted again."""
  first, out = {}, {}  # patch (as sorted JSON) -> the first reading with it
  for key, _, patch in readings:
    patch_text = json.dumps(patch, sort_keys=True)
    if patch_text in first:
      out[key] = first[patch_text]
    else:
      first[patch_text] = key
  return out


SAME_AS = same_as(READINGS)
READING_DOCS = {key: ("§5, §7" if key.endswith("c1_law") else "§7") for key, _, _ in READINGS if not key.startswith("model/")}
READING_DOCS.update({f"model/{k}": sec for k, _, _, sec in MODEL_READINGS})
READING_DOCS.update({combination(c)[0]: combination(c)[3] for c in COMBINATIONS})
# --quick (the report's tests): the pulse readings, each model reading alone but the
# precision ones, and the first combination; the families are shrunk too.
QUICK_READINGS = ([r[0] for r in READINGS if not r[0].startswith("model/")]
                  + ["model/omega_y_printed", "model/r0_medial", "model/stiffness_as_printed", "model/plane_slope_y",
                     combination(COMBINATIONS[0])[0]])
QUICK_DASSL_OFFSETS_MM = [0.0, 0.1]
SENSITIVITY_IDS = {"S1", "S2"}


# S2 under the chapter's DASSL start (docs/model.md §6, initial_state.start: unprojected): the
# reference member with the chapter's inconsistent guesses handed to IDA, the contact-point
# guesses offset as run_families.py offsets them, at the report's tolerances and at 1e-6.
DASSL_OFFSETS_MM = [0.0, 1e-6, 1e-3, 0.1]
DASSL_TOLERANCES = [(1e-8, 1e-10), (1e-6, 1e-8)]


def dassl_start(kneedyn, outdir, quick=False):
  """{tolerances: [{rtol, atol, runs: [{offset_mm, ok, failure, liftoff_deg}], max_dflexion_deg}]}."""
  d = os.path.join(outdir, "reconstruction", "s2_dassl_start")
  os.makedirs(os.path.join(d, "scenes"), exist_ok=True)
  offsets = QUICK_DASSL_OFFSETS_MM if quick else DASSL_OFFSETS_MM
  out = {"offsets_mm": offsets, "tolerances": []}
  for rtol, atol in DASSL_TOLERANCES:
    runs, flex = [], {}
    for off in offsets:
      name = f"rtol{rtol:g}_offset{off:g}"
      scene = run_families.write_scene(d, name, run_families.BASE_AMPLITUDE_N, run_families.BASE_DURATION_S,
                                       init_extra={"start": "unprojected", "contact_guess_offset_mm": off})
      rd = os.path.join(d, "runs", name)
      p = subprocess.run([kneedyn, "run", scene, "--formulation", "dae", "--rtol", f"{rtol:g}", "--atol", f"{atol:g}",
                          "--quiet", "--out", rd], capture_output=True, text=True)
      summary = {}
      if os.path.exists(os.path.join(rd, "summary.json")):
        with open(os.path.join(rd, "summary.json")) as f:
          summary = json.load(f)
      ok = p.returncode == 0 and summary.get("status") == "completed"
      lo = next((e["flexion_deg"] for e in summary.get("events", []) if e["name"] == "liftoff_lateral"), None)
      if ok:
        with open(os.path.join(rd, "trajectory.csv")) as f:
          rows = list(csv.reader(f))
        i = rows[0].index("flexion_deg")
        flex[off] = np.array([float(r[i]) for r in rows[1:]])
      runs.append({"offset_mm": off, "ok": ok, "liftoff_deg": lo, "exit": p.returncode,
                   "failure": summary.get("failure") or p.stderr.strip()[-400:] or None})
    dmax = None
    if 0.0 in flex and len(flex) > 1:
      dmax = max(float(np.max(np.abs(v[:min(len(v), len(flex[0.0]))] - flex[0.0][:min(len(v), len(flex[0.0]))])))
                 for k, v in flex.items() if k != 0.0)
    out["tolerances"].append({"rtol": rtol, "atol": atol, "runs": runs, "max_dflexion_deg": dmax})
  return out


def reading_dir(outdir, key):
  return os.path.join(outdir, "reconstruction", key.replace("/", "__"))


def crossing(member):
  c = claims.Curve(member, "valgus_deg")
  x = c.crossings(-1, 1, 90)
  return x[0] if x else None


def evaluate(rdir):
  """Verdicts and key numbers of one reading's families."""
  ck = claims.Checker(rdir)
  claims.check_all(ck)
  rows = [r for r in ck.rows if r["id"] not in SENSITIVITY_IDS]
  fam, members = load_families(rdir)
  durs = sorted((m for m in members if m.family == "duration" and m.ok), key=lambda m: m.value)
  ref = ck.ref
  peak = None
  if ref is not None:
    peak = float(np.nanmax(np.abs(ref.col("pulse_N"))))
  return {"verdicts": {r["id"]: r["verdict"] for r in rows},
          "reasons": {r["id"]: r["reason"] for r in rows},
          "counts": {v: sum(r["verdict"] == v for r in rows)
                     for v in (claims.REPRODUCED, claims.NOT_REPRODUCED, claims.NOT_CHECKABLE)},
          "liftoff_lateral_deg": ref.liftoff_deg if ref is not None else None,
          "time_to_90_s": ref.time_to_90_s if ref is not None else None,
          "peak_pulse_N": peak,
          "crossing_deg": {f"{m.value:g}": crossing(m) for m in durs},
          "failed_members": [m.name for m in members if not m.ok]}


def main(argv=None):
  ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
  ap.add_argument("--kneedyn", required=True)
  ap.add_argument("--out", required=True)
  ap.add_argument("--quick", action="store_true", help="reduced families (tests)")
  ap.add_argument("--calibrate", help="calibrate_reconstruction binary (Ceres fit)")
  ap.add_argument("--calibrate-grid", type=int, default=5)
  ap.add_argument("--calibrate-iterations", type=int, default=20)
  ap.add_argument("--jobs", type=int, default=os.cpu_count() or 1)
  args = ap.parse_args(argv)
  tool_input.kneedyn_executable("--kneedyn", args.kneedyn)
  tool_input.number("--jobs", args.jobs, 1, 1024, integer=True)  # the range inverse_problem.py checks
  if args.calibrate is not None:
    tool_input.executable("--calibrate", args.calibrate)
    # calibrate_reconstruction's own limits (--grid >= 1, --max-iterations >= 0), checked
    # here so that a bad value costs no family run.
    tool_input.number("--calibrate-grid", args.calibrate_grid, 1, 100, integer=True)
    tool_input.number("--calibrate-iterations", args.calibrate_iterations, 0, 10000, integer=True)
  tool_input.output_directory("--out", args.out)
  outdir = os.path.abspath(args.out)
  readings = [r for r in READINGS if not args.quick or r[0] in QUICK_READINGS]
  jobs = []
  for key, label, patch in readings:
    rdir = reading_dir(outdir, key)
    for sub in ("scenes", "runs"):
      os.makedirs(os.path.join(rdir, sub), exist_ok=True)
    run_patch = resolve_patch(patch, rdir)
    for family, value, amp, dur in run_families.family_members(args.quick):
      name = run_families.member_name(family, value)
      scene = run_families.write_scene(rdir, name, amp, dur, patch=run_patch)
      jobs.append((key, rdir, name, scene, (family, value, amp, dur)))
  results = {}
  with concurrent.futures.ThreadPoolExecutor(max_workers=args.jobs) as pool:
    futs = {pool.submit(run_families.run_one, args.kneedyn, scene, os.path.join(rdir, "runs", name)):
            (key, name) for key, rdir, name, scene, _ in jobs}
    for i, fut in enumerate(concurrent.futures.as_completed(futs), 1):
      results[futs[fut]] = fut.result()
      if i % 10 == 0 or i == len(futs):
        print(f"reconstruction: {i}/{len(futs)} runs", flush=True)
  summary = {"claims": [c["id"] for c in claims.CLAIMS if c["id"] not in SENSITIVITY_IDS],
             "claim_text": {c["id"]: c["claim"] for c in claims.CLAIMS},
             "quick": args.quick, "readings": []}
  any_failed = False
  for key, label, patch in readings:
    rdir = reading_dir(outdir, key)
    members = []
    for k, _, name, _, (family, value, amp, dur) in jobs:
      if k != key:
        continue
      r = results[(key, name)]
      any_failed |= not r["ok"]
      members.append({"name": name, "family": family, "value": value, "amplitude_N": amp, "duration_s": dur,
                      "run_dir": os.path.join("runs", name), "ok": r["ok"], "status": r["status"],
                      "command": r["command"], "stderr": r["stderr"], "fallback": r["fallback"]})
    with open(os.path.join(rdir, "families.json"), "w") as f:
      json.dump({"solver_args": run_families.SOLVER_ARGS, "output_interval_s": run_families.OUTPUT_INTERVAL_S,
                 "quick": args.quick, "reading": key, "patch": patch, "members": members}, f, indent=2)
    ev = evaluate(rdir)
    ev.update({"key": key, "label": label, "patch": patch, "docs_model_md": READING_DOCS.get(key),
               "same_as": SAME_AS.get(key)})
    summary["readings"].append(ev)
    print(f"reconstruction: {key:28s} reproduced {ev['counts'][claims.REPRODUCED]:2d}/{len(summary['claims'])}, "
          f"lift-off {ev['liftoff_lateral_deg']}", flush=True)
  os.makedirs(os.path.join(outdir, "reconstruction"), exist_ok=True)
  summary["s2_dassl_start"] = dassl_start(args.kneedyn, outdir, args.quick)
  for t in summary["s2_dassl_start"]["tolerances"]:
    print(f"reconstruction: S2 DASSL start at rtol {t['rtol']:g}: {sum(r['ok'] for r in t['runs'])}/{len(t['runs'])} "
          f"completed, max |Δflexion| {t['max_dflexion_deg']}", flush=True)
  with open(os.path.join(outdir, "reconstruction", "reconstruction.json"), "w") as f:
    json.dump(summary, f, indent=1, ensure_ascii=False)
  if args.calibrate:
    os.makedirs(os.path.join(outdir, "reconstruction", "scenes"), exist_ok=True)
    base = run_families.write_scene(os.path.join(outdir, "reconstruction"), "calibration_base",
                                    run_families.BASE_AMPLITUDE_N, run_families.BASE_DURATION_S)
    cmd = [args.calibrate, "--scene", base, "--out", os.path.join(outdir, "reconstruction", "calibration.json"),
           "--grid", str(args.calibrate_grid), "--max-iterations", str(args.calibrate_iterations)]
    p = subprocess.run(cmd, capture_output=True, text=True)
    with open(os.path.join(outdir, "reconstruction", "calibration.log"), "w") as f:
      f.write(" ".join(cmd) + "\n" + p.stderr)
    if p.returncode != 0:
      print(f"reconstruction: calibration failed ({p.returncode}): {p.stderr[-500:]}", file=sys.stderr)
      any_failed = True
  return 1 if any_failed else 0


if __name__ == "__main__":
  sys.exit(tool_input.exit_code("reconstruction", main))
