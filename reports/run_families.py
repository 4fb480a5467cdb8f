#!/usr/bin/python3
"""Runs the chapter's pulse families (reports/claims.yaml, section 1.4 / Figs. 1.4-1.6) and the two
sensitivity studies with the reference solver, in parallel.

  run_families.py --kneedyn PATH --out OUTDIR [--quick] [--jobs N]

--jobs N: runs at a time, a whole number in [1, 1024] (default: the number of CPUs, os.cpu_count()).

Runs go through the kneedyn Python module when it is importable (PYTHONPATH, or
<build>/python beside --kneedyn), in this process; otherwise, or with
KNEEDYN_REPORT_RUNNER=subprocess, one `kneedyn run` process each. Both write the same files.

Writes OUTDIR/scenes/<member>.yaml, OUTDIR/runs/<member>/{trajectory.csv, summary.json},
OUTDIR/families.json (members, status, and no_pulse: the reference member at A = 0 N, for the
report's Summary) and OUTDIR/sensitivity.json.
Exit status 1 if any run failed (all runs are attempted).
"""
import argparse
import concurrent.futures
import json
import os
import subprocess
import sys

import numpy as np
import yaml

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import tool_input  # noqa: E402
from family_data import first_events, load_csv  # noqa: E402  (one CSV reader for all report scripts)

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
BASE_SCENE = os.path.join(ROOT, "reference-data", "scenes", "chapter_impact.yaml")

# The reference solver's settings, those of the main job (README).
SOLVER_ARGS = ["--formulation", "dae", "--rtol", "1e-8", "--atol", "1e-10"]
# If the reference settings fail (IDA error-test failures after lateral lift-off at some
# amplitudes), the run is retried with these settings, in order; the report flags it.
FALLBACK_SETTINGS = [("1e-10", "1e-12"), ("1e-9", "1e-11"), ("1e-7", "1e-9")]
OUTPUT_INTERVAL_S = 0.001  # finer than the scene's 5 ms so early-flexion features are resolved

AMPLITUDES_N = [50.0, 100.0, 200.0, 300.0, 400.0]
DURATIONS_S = [0.05, 0.1, 0.15, 0.2]
QUICK_AMPLITUDES_N = [50.0, 100.0, 400.0]
QUICK_DURATIONS_S = [0.05, 0.2]
BASE_AMPLITUDE_N = 100.0
BASE_DURATION_S = 0.1

# Sensitivity studies (claims S1, S2 of reports/claims.yaml).
# Chapter guesses: medial 150 N, lateral 130 N.
FORCE_GUESSES_N = [(1.0, 1.0), (10.0, 10.0), (150.0, 130.0), (500.0, 500.0), (1000.0, 50.0),
                   (50.0, 1000.0), (5000.0, 5000.0)]
QUICK_FORCE_GUESSES_N = [(10.0, 10.0), (1000.0, 50.0)]
CONTACT_OFFSETS_MM = [1e-6, 1e-3, 1e-1]
QUICK_CONTACT_OFFSETS_MM = [1e-3]


def member_name(family, value):
  return f"{family}_{value:g}"


def family_members(quick):
  """[(family, value, amplitude_N, duration_s)]; family 'amplitude' or 'duration'."""
  amps = QUICK_AMPLITUDES_N if quick else AMPLITUDES_N
  durs = QUICK_DURATIONS_S if quick else DURATIONS_S
  members = [("amplitude", a, a, BASE_DURATION_S) for a in amps]
  members += [("duration", d, BASE_AMPLITUDE_N, d) for d in durs]
  return members


def load_base_scene():
  with open(BASE_SCENE) as f:
    scene = yaml.safe_load(f)
  # Absolute parameter set so the generated scene works from any directory.
  scene["parameter_set"] = os.path.normpath(
      os.path.join(os.path.dirname(BASE_SCENE), scene["parameter_set"]))
  return scene


def write_scene(outdir, name, amplitude_N, duration_s, init_extra=None, patch=None):
  """patch: {key: value or dict} merged into the base scene (dicts one level deep), e.g.
  {"pulse": {"shape": "half_sine"}, "gravity": {"enabled": False}} (reconstruction study)."""
  scene = load_base_scene()
  for k, v in (patch or {}).items():
    if isinstance(v, dict) and isinstance(scene.get(k), dict):
      scene[k].update(v)
    else:
      scene[k] = v
  scene["name"] = name
  scene["pulse"]["amplitude_N"] = float(amplitude_N)
  scene["pulse"]["duration_s"] = float(duration_s)
  if init_extra:
    scene["initial_state"].update(init_extra)
  path = os.path.join(outdir, "scenes", name + ".yaml")
  with open(path, "w") as f:
    yaml.safe_dump(scene, f, sort_keys=False)
  return path


_MODULE = {}


def kneedyn_module(kneedyn):
  """The kneedyn Python module (python/, docs/python.md) if importable — from PYTHONPATH or from the
  build tree beside the binary (<build>/python) — else None. KNEEDYN_REPORT_RUNNER=subprocess
  forces the subprocess path. A partial build (the package directory without the _kneedyn
  extension: a namespace package, or one without run/Error) is None too: the CLI runs."""
  if os.environ.get("KNEEDYN_REPORT_RUNNER") == "subprocess":
    return None
  if kneedyn not in _MODULE:
    build_python = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(kneedyn))), "python")
    if os.path.isdir(os.path.join(build_python, "kneedyn")) and build_python not in sys.path:
      sys.path.insert(0, build_python)
    try:
      import kneedyn as module
      if not all(hasattr(module, a) for a in ("run", "Error", "InputError", "__file__")) or not module.__file__:
        module = None
    except ImportError:
      module = None
    _MODULE[kneedyn] = module
  return _MODULE[kneedyn]


def runner_description(kneedyn):
  m = kneedyn_module(kneedyn)
  return (f"in-process through the kneedyn Python module ({m.__file__}), same driver and file writer as the CLI"
          if m else "one kneedyn CLI process per run")


def run_once(kneedyn, scene_path, run_dir, solver_args):
  cmd = [kneedyn, "run", scene_path] + solver_args + [
      "--output-interval", str(OUTPUT_INTERVAL_S), "--out", run_dir, "--quiet"]
  module = kneedyn_module(kneedyn)
  if module is not None:
    # Same run and same files as `cmd` (python/tests: byte-identical trajectory.csv), in this
    # process; the thread pool runs several at once (the module releases the GIL).
    opts = dict(zip(solver_args[0::2], solver_args[1::2]))
    try:
      r = module.run(scene_path, opts["--formulation"], rtol=float(opts["--rtol"]), atol=float(opts["--atol"]),
                     output_interval=OUTPUT_INTERVAL_S, out=run_dir)
      ok, status, rc, err = r.completed, r.status, 0 if r.completed else 1, r.failure
    except module.Error as e:  # InputError: what the CLI reports with exit code 2
      ok, status, rc, err = False, "failed", 2 if isinstance(e, module.InputError) else 1, str(e)
    return {"command": " ".join(cmd), "ok": ok, "status": status, "returncode": rc,
            "stderr": err[-2000:], "runner": "module"}
  p = subprocess.run(cmd, capture_output=True, text=True)
  ok = p.returncode == 0 and os.path.exists(os.path.join(run_dir, "summary.json"))
  status = "failed"
  if ok:
    with open(os.path.join(run_dir, "summary.json")) as f:
      status = json.load(f).get("status", "failed")
    ok = status == "completed"
  return {"command": " ".join(cmd), "ok": ok, "status": status, "returncode": p.returncode,
          "stderr": p.stderr.strip()[-2000:], "runner": "subprocess"}


def run_one(kneedyn, scene_path, run_dir):
  """Reference settings first, then FALLBACK_SETTINGS; records the first failure."""
  r = run_once(kneedyn, scene_path, run_dir, SOLVER_ARGS)
  r["fallback"] = None
  if r["ok"]:
    return r
  first = r
  for rtol, atol in FALLBACK_SETTINGS:
    r = run_once(kneedyn, scene_path, run_dir, ["--formulation", "dae", "--rtol", rtol, "--atol", atol])
    if r["ok"]:
      r["fallback"] = {"rtol": rtol, "atol": atol, "reference_failure": first["stderr"],
                       "reference_command": first["command"]}
      return r
  # Nothing worked: rerun the reference so the partial output on disk is the reference one.
  return dict(run_once(kneedyn, scene_path, run_dir, SOLVER_ARGS), fallback=None)


def trajectory_difference(ref_dir, run_dir):
  """Max differences of flexion and contact forces over the common time span (deg, N)."""
  a = load_csv(os.path.join(ref_dir, "trajectory.csv"))
  b = load_csv(os.path.join(run_dir, "trajectory.csv"))
  # Drop event rows (duplicate times) and compare on the reference's regular samples.
  ma, mb = a["is_event"] == 0, b["is_event"] == 0
  ta, tb = a["time_s"][ma], b["time_s"][mb]
  t_end = min(ta[-1], tb[-1])
  t = ta[ta <= t_end]
  out = {}
  for col, key in (("flexion_deg", "max_abs_diff_flexion_deg"),
                   ("valgus_deg", "max_abs_diff_valgus_deg"),
                   ("external_rotation_deg", "max_abs_diff_external_rotation_deg"),
                   ("N_medial_N", "max_abs_diff_N_medial_N"),
                   ("N_lateral_N", "max_abs_diff_N_lateral_N")):
    fa = np.interp(t, ta, a[col][ma])
    fb = np.interp(t, tb, b[col][mb])
    d = np.abs(fa - fb)
    out[key] = float(np.nanmax(d)) if np.any(np.isfinite(d)) else None
  return out


def event_summary(run_dir):
  with open(os.path.join(run_dir, "summary.json")) as f:
    s = json.load(f)
  ev = first_events(s.get("events"))  # the lateral condyle's first separation, not a later bounce
  lo = ev.get("liftoff_lateral")
  f90 = ev.get("flexion_90")
  init = s.get("initialization", {})
  return {"liftoff_lateral_deg": lo["flexion_deg"] if lo else None,
          "time_to_90_s": f90["time"] if f90 else None,
          "initial_normal_force_N": init.get("normal_force_N"),
          "initial_normal_force_guess_N": init.get("normal_force_guess_N")}


def main(argv=None):
  ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
  ap.add_argument("--kneedyn", required=True, help="path to the kneedyn binary")
  ap.add_argument("--out", required=True, help="output directory")
  ap.add_argument("--quick", action="store_true", help="fewer members and sensitivity cases")
  ap.add_argument("--jobs", type=int, default=os.cpu_count() or 1)
  args = ap.parse_args(argv)
  tool_input.kneedyn_executable("--kneedyn", args.kneedyn)
  tool_input.number("--jobs", args.jobs, 1, 1024, integer=True)  # the range inverse_problem.py checks
  tool_input.output_directory("--out", args.out)
  outdir = os.path.abspath(args.out)
  for sub in ("scenes", "runs"):
    os.makedirs(os.path.join(outdir, sub), exist_ok=True)

  jobs = {}  # name -> (scene path, run dir, meta)
  for family, value, amp, dur in family_members(args.quick):
    name = member_name(family, value)
    jobs[name] = (write_scene(outdir, name, amp, dur), {"kind": "family", "family": family,
                                                      "value": value, "amplitude_N": amp,
                                                      "duration_s": dur})
  ref_name = "reference"
  jobs[ref_name] = (write_scene(outdir, ref_name, BASE_AMPLITUDE_N, BASE_DURATION_S),
                    {"kind": "sensitivity_reference"})
  # The reference member without its pulse (A = 0 N): how much of the motion the pulse makes
  # (the report's Summary; the leg's weight moves the knee too, docs/model.md §7).
  jobs["no_pulse"] = (write_scene(outdir, "no_pulse", 0.0, BASE_DURATION_S), {"kind": "pulse_off"})
  for med, lat in (QUICK_FORCE_GUESSES_N if args.quick else FORCE_GUESSES_N):
    name = f"force_guess_{med:g}_{lat:g}"
    jobs[name] = (write_scene(outdir, name, BASE_AMPLITUDE_N, BASE_DURATION_S,
                              {"normal_force_guesses_N": {"medial": med, "lateral": lat}}),
                  {"kind": "force_guess", "medial_N": med, "lateral_N": lat})
  for d in (QUICK_CONTACT_OFFSETS_MM if args.quick else CONTACT_OFFSETS_MM):
    name = f"contact_offset_{d:g}"
    jobs[name] = (write_scene(outdir, name, BASE_AMPLITUDE_N, BASE_DURATION_S,
                              {"contact_guess_offset_mm": d}),
                  {"kind": "contact_offset", "offset_mm": d})

  results = {}
  with concurrent.futures.ThreadPoolExecutor(max_workers=args.jobs) as pool:
    futs = {pool.submit(run_one, args.kneedyn, scene, os.path.join(outdir, "runs", name)): name
            for name, (scene, _) in jobs.items()}
    done = 0
    for fut in concurrent.futures.as_completed(futs):
      name = futs[fut]
      r = fut.result()
      results[name] = r
      done += 1
      state = "ok" if r["ok"] else "FAILED (" + r["status"] + ")"
      if r["ok"] and r["fallback"]:
        state = f"reference settings FAILED, ok with rtol {r['fallback']['rtol']}"
      print(f"[{done}/{len(jobs)}] {name}: {state}", flush=True)

  members = []
  for family, value, amp, dur in family_members(args.quick):
    name = member_name(family, value)
    members.append({"name": name, "family": family, "value": value, "amplitude_N": amp,
                    "duration_s": dur, "run_dir": os.path.join("runs", name),
                    "ok": results[name]["ok"], "status": results[name]["status"],
                    "command": results[name]["command"], "stderr": results[name]["stderr"],
                    "fallback": results[name]["fallback"]})
  no_pulse = {"name": "no_pulse", "amplitude_N": 0.0, "duration_s": BASE_DURATION_S,
              "run_dir": os.path.join("runs", "no_pulse"), "ok": results["no_pulse"]["ok"],
              "status": results["no_pulse"]["status"]}
  if results["no_pulse"]["ok"]:
    no_pulse.update(event_summary(os.path.join(outdir, "runs", "no_pulse")))
  with open(os.path.join(outdir, "families.json"), "w") as f:
    json.dump({"solver_args": SOLVER_ARGS, "output_interval_s": OUTPUT_INTERVAL_S,
               "quick": args.quick, "runner": runner_description(args.kneedyn), "members": members,
               "no_pulse": no_pulse}, f, indent=2)

  # Sensitivity studies: differences vs the unperturbed run.
  sens = {"reference": ref_name, "force_guess": [], "contact_offset": []}
  ref_dir = os.path.join(outdir, "runs", ref_name)
  ref_ok = results[ref_name]["ok"]
  if ref_ok:
    sens["reference_events"] = event_summary(ref_dir)
  for name, (_, meta) in jobs.items():
    if meta["kind"] not in ("force_guess", "contact_offset"):
      continue
    row = dict(meta)
    row["name"] = name
    row["ok"] = results[name]["ok"]
    run_dir = os.path.join(outdir, "runs", name)
    if results[name]["ok"] and ref_ok:
      row.update(trajectory_difference(ref_dir, run_dir))
      row.update(event_summary(run_dir))
    else:
      row["reason"] = results[name]["stderr"] or results[name]["status"]
    sens[meta["kind"]].append(row)
  with open(os.path.join(outdir, "sensitivity.json"), "w") as f:
    json.dump(sens, f, indent=2)

  rescued = [n for n, r in results.items() if r["ok"] and r["fallback"]]
  if rescued:
    print(f"run_families: reference settings failed, fallback used: {', '.join(sorted(rescued))}",
          file=sys.stderr)
  failed = [n for n, r in results.items() if not r["ok"]]
  if failed:
    print(f"run_families: {len(failed)} run(s) failed: {', '.join(sorted(failed))}", file=sys.stderr)
    return 1
  print(f"run_families: {len(results)} runs ok -> {outdir}")
  return 0


if __name__ == "__main__":
  sys.exit(tool_input.exit_code("run_families", main))
