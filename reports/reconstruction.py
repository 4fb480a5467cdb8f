#!/usr/bin/python3
"""Reconstruction study: how much of the claims table rests on the readings of
the model that the printed chapter leaves uncertain.

  reconstruction.py --kneedyn PATH --out OUTDIR [--quick] [--calibrate BIN] [--jobs N]

For each reading (pulse shape of the garbled Eq. 1.62 × gravity on/off, plus the C¹
ligament law that docs/model.md records as a departure) it runs the chapter's pulse
families with the reference solver (as run_families.py, with the scene patched), evaluates
every claim of reports/claims.yaml with reports/claims.py, and writes
OUTDIR/reconstruction/reconstruction.json: per reading the verdict of each claim, the count
reproduced, the lateral lift-off angle and the valgus→varus crossings of the shortest and
longest pulse. With --calibrate it also runs the Ceres calibration
(reports/calibrate_reconstruction.cpp) into OUTDIR/reconstruction/calibration.json.
The sensitivity statements S1/S2 do not depend on the reading and are not re-run here.
Exit 0 when every run completed, 1 when some failed (recorded per reading), 2 on bad input.
"""
import argparse
import concurrent.futures
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
QUICK_READINGS = [r[0] for r in READINGS]  # all readings; --quick shrinks the families instead
SENSITIVITY_IDS = {"S1", "S2"}


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
  if not os.access(args.kneedyn, os.X_OK):
    print(f"reconstruction: --kneedyn = '{args.kneedyn}': not an executable file", file=sys.stderr)
    return 2
  if args.calibrate and not os.access(args.calibrate, os.X_OK):
    print(f"reconstruction: --calibrate = '{args.calibrate}': not an executable file", file=sys.stderr)
    return 2
  outdir = os.path.abspath(args.out)
  jobs = []
  for key, label, patch in READINGS:
    rdir = reading_dir(outdir, key)
    for sub in ("scenes", "runs"):
      os.makedirs(os.path.join(rdir, sub), exist_ok=True)
    for family, value, amp, dur in run_families.family_members(args.quick):
      name = run_families.member_name(family, value)
      scene = run_families.write_scene(rdir, name, amp, dur, patch=patch)
      jobs.append((key, rdir, name, scene, (family, value, amp, dur)))
  results = {}
  with concurrent.futures.ThreadPoolExecutor(max_workers=max(1, args.jobs)) as pool:
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
  for key, label, patch in READINGS:
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
    ev.update({"key": key, "label": label, "patch": patch})
    summary["readings"].append(ev)
    print(f"reconstruction: {key:28s} reproduced {ev['counts'][claims.REPRODUCED]:2d}/{len(summary['claims'])}, "
          f"lift-off {ev['liftoff_lateral_deg']}", flush=True)
  os.makedirs(os.path.join(outdir, "reconstruction"), exist_ok=True)
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
  sys.exit(main())
