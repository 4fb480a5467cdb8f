#!/usr/bin/python3
"""The report's patello-femoral section (reports/patella_section.py) from a tiny run (--quick:
both patella scenes cut to about 0.1 s, three Δt of `staggered`, two tolerances of ede/dae):

  * its four figures are PNG files (> 1 kB) and the section's HTML shows them;
  * the tendon/quadriceps ratio of its table and of its drawn curve equals tendon_force_N of
    trajectory.csv divided by the quadriceps magnitude computed here from the scene's own
    `quadriceps:` entry (docs/model.md §12: constant, ramp or half-sine), at the same output
    row (the extension scene's ramp: a ratio taken against the wrong magnitude fails);
  * every formulation `kneedyn formulations` marks as needing a patella is in the
    work-precision study, each run completed, with a score;
  * the staggered coupling error has an observed order in 0.8–1.3 (the one-step lag is a
    first-order splitting: docs/model.md §12, form (ii));
  * with --make-reference: the section's own scd (metrics.hpp's formula, used until a stored
    reference exists) equals `kneedyn score`'s (the C++ metric) on a reference made for the
    cut scene, for two runs.

  patella_section_test.py --kneedyn PATH [--make-reference PATH] [--keep DIR]
"""
import argparse
import csv
import json
import math
import os
import shutil
import subprocess
import sys
import tempfile

import yaml

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.dont_write_bytecode = True
sys.path.insert(0, os.path.join(ROOT, "reports"))
import patella_section  # noqa: E402

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def quadriceps_N(q, t):
  """F_Q(t) of docs/model.md §12 from the scene's entry."""
  shape = q["shape"]
  if shape == "constant":
    return q["magnitude_N"]
  s = max(t, 0.0) / q["duration_s"]
  if shape == "ramp":
    return q["baseline_N"] + (q["magnitude_N"] - q["baseline_N"]) * min(s, 1.0)
  if shape == "half_sine":
    return q.get("baseline_N", 0.0) + (q["magnitude_N"] * math.sin(math.pi * s) if s <= 1.0 else 0.0)
  raise ValueError(f"unknown quadriceps shape {shape}")


def main():
  ap = argparse.ArgumentParser()
  ap.add_argument("--kneedyn", required=True)
  ap.add_argument("--keep", help="write into this directory instead of a temporary one")
  ap.add_argument("--make-reference", help="make_reference binary: also check the section's scd against "
                  "kneedyn score on a reference it makes for the cut scene")
  args = ap.parse_args()
  errors = []
  with tempfile.TemporaryDirectory(prefix="kneedyn_patella_") as tmp:
    out = args.keep or tmp
    if args.keep:
      shutil.rmtree(out, ignore_errors=True)
      os.makedirs(out)
    p = subprocess.run([sys.executable, os.path.join(ROOT, "reports", "patella_section.py"), "--kneedyn",
                        args.kneedyn, "--out", out, "--quick"], capture_output=True, text=True, timeout=240)
    print(p.stdout)
    print(p.stderr, file=sys.stderr)
    if p.returncode != 0:
      errors.append(f"patella_section.py exited with {p.returncode}")
    path = os.path.join(out, "patella", "patella_section.json")
    if not os.path.exists(path):
      print("patella_section_test: patella_section.json not written", file=sys.stderr)
      return 1
    with open(path, encoding="utf-8") as f:
      result = json.load(f)
    page = patella_section.section(out)

    for fname, _ in patella_section.FIGURES:
      fpath = os.path.join(out, "figures", fname)
      if not os.path.exists(fpath):
        errors.append(f"missing figure {fname}")
        continue
      with open(fpath, "rb") as f:
        if f.read(8) != PNG_SIGNATURE:
          errors.append(f"{fname}: not a PNG")
      if os.path.getsize(fpath) <= 1024:
        errors.append(f"{fname}: only {os.path.getsize(fpath)} bytes")
      if f"figures/{fname}" not in page:
        errors.append(f"section HTML does not show figures/{fname}")
    if "id='patella'" not in page:
      errors.append("section HTML has no id='patella'")

    # The ratio column against tendon force / quadriceps magnitude, row by row.
    for name in (patella_section.IMPACT, patella_section.EXTENSION):
      kin = result.get("kinematics", {}).get(name)
      if not kin or not kin["against_flexion"]:
        errors.append(f"{name}: no kinematics rows")
        continue
      scene_file = result["scenes"][name]
      scene_file = scene_file if os.path.isabs(scene_file) else os.path.join(ROOT, scene_file)
      with open(scene_file, encoding="utf-8") as f:
        q = yaml.safe_load(f)["patella"]["quadriceps"]
      with open(os.path.join(out, kin["run_dir"], "trajectory.csv"), newline="", encoding="utf-8") as f:
        by_time = {round(float(r["time_s"]), 9): r for r in csv.DictReader(f) if r["is_event"] == "0"}
      # The drawn curve, every output row (the extension's ramp included).
      c = kin["curves"]
      for t, ratio in zip(c["time_s"], c["tendon_quadriceps_ratio"]):
        r = by_time.get(round(t, 9))
        if r is None:
          continue
        expected = float(r["tendon_force_N"]) / quadriceps_N(q, t)
        if not abs(ratio - expected) <= 1e-9 * max(1.0, abs(expected)):
          errors.append(f"{name} curve t = {t}: ratio {ratio} != tendon / quadriceps {expected}")
      for row in kin["against_flexion"]:
        r = by_time.get(round(row["time_s"], 9))
        if r is None:
          errors.append(f"{name}: table row at t = {row['time_s']} is not an output row of trajectory.csv")
          continue
        expected = float(r["tendon_force_N"]) / quadriceps_N(q, row["time_s"])
        if not abs(row["tendon_quadriceps_ratio"] - expected) <= 1e-9 * max(1.0, abs(expected)):
          errors.append(f"{name} t = {row['time_s']}: ratio {row['tendon_quadriceps_ratio']} != tendon / "
                        f"quadriceps {expected}")
        if f"<td>{expected:.4f}</td>" not in page:
          errors.append(f"{name} t = {row['time_s']}: ratio {expected:.4f} not in the section's table")

    # Every formulation needing a patella is studied; the staggered order.
    listed = subprocess.run([args.kneedyn, "formulations"], capture_output=True, text=True).stdout
    needing = [line.split()[0] for line in listed.splitlines() if "needs a patella" in line]
    if "staggered" not in needing:
      errors.append("kneedyn formulations lists no staggered needing a patella")
    for n in needing:
      pts = [w for w in result["work_precision"] if w["formulation"] == n]
      if len(pts) < 2:
        errors.append(f"{n}: {len(pts)} work-precision points (expected >= 2)")
      for w in pts:
        if not w.get("ok") or not isinstance(w.get("scd"), (int, float)) or not w.get("cpu_s", 0) > 0:
          errors.append(f"{n} {w.get('setting')}: not a scored run ({w.get('reason')})")
    # The section's scd (metrics.hpp's formula in Python, used until a stored reference
    # exists) against kneedyn score's C++ metric on a reference made by make_reference.
    if args.make_reference:
      scene = result["scenes"][patella_section.IMPACT]
      scene = scene if os.path.isabs(scene) else os.path.join(ROOT, scene)
      ref = os.path.join(out, "patella", "made_reference.json")
      m = subprocess.run([args.make_reference, "--scene", scene, "--out", ref, "--method", "formulations",
                          "--formulation", "ede", "--integrator", "dopri5", "--rtol", "1e-12", "--atol", "1e-14",
                          "--check", "ede", "--check-integrator", "verner65", "--check-rtol", "1e-11",
                          "--check-atol", "1e-13"], capture_output=True, text=True, timeout=120)
      if m.returncode != 0:
        errors.append(f"make_reference failed ({m.returncode}): {m.stderr[-300:]}")
      else:
        for w in [w for w in result["work_precision"] if w.get("ok")][:2]:
          run_dir = w["run_dir"]
          with open(os.path.join(run_dir, "trajectory.csv"), newline="", encoding="utf-8") as f:
            table = [{k: patella_section.number(v) for k, v in r.items()} for r in csv.DictReader(f)]
          ours = patella_section.compare(patella_section.reference_from_stored(ref), table, [])["scd"]
          theirs, _, _ = patella_section.score_with_kneedyn(args.kneedyn, scene, table, w, ref)
          if not abs(ours - theirs) <= 1e-9:
            errors.append(f"{w['formulation']} {w['setting']}: scd {ours} here, {theirs} by kneedyn score")
          # Scoring leaves the run directory as kneedyn wrote it, so the next main job can
          # run into it again (kneedyn refuses a directory holding files that are not its outputs).
          again, _ = patella_section.run(args.kneedyn, scene, run_dir, w["formulation"], w["args"], out)
          if not again.get("ok", True) or again["exit"] != 0:
            errors.append(f"{w['formulation']} {w['setting']}: a second run into {run_dir} after scoring "
                          f"failed: {again.get('reason')}")
    order = result["staggered_order"]["fitted_order"]
    if order is None or not 0.8 <= order <= 1.3:
      errors.append(f"staggered coupling order {order}, expected 0.8-1.3")
  for e in errors:
    print("patella_section_test:", e, file=sys.stderr)
  return 1 if errors else 0


if __name__ == "__main__":
  sys.exit(main())
