#!/usr/bin/python3
"""Coupling-error study of the chapter's staggered procedure (docs/model.md §12).

  patella_coupling.py --kneedyn PATH --out OUTDIR [--scene SCENE]

Runs the patello-femoral impact scene with the ODE check (`ede`, the patella's equilibrium
solved inside the right-hand side) at rtol 1e-12 as the reference, the Newton-based DAE
(`dae`, IDA, rtol 1e-10) as the second monolithic-in-the-tibia form, and `staggered` at
Δt = 4, 2, 1, 0.5, 0.25 ms (dopri5 inside a step at rtol 1e-12, so that the lag is what
separates it from the reference). Coupling error of a run: max |flexion − reference| (deg)
over the output rows before the first event, and the error of each event time (s).
Observed order between successive Δt: log2(e(2Δt)/e(Δt)); error constant: e/Δt^p with p
the least-squares slope. Writes OUTDIR/patella/coupling.json and coupling.png (error
against Δt, and against wall time). Exit 0 when every run completed, 1 otherwise,
2 on bad input.
"""
import argparse
import csv
import json
import math
import os
import subprocess
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import tool_input  # noqa: E402

STEPS = [4e-3, 2e-3, 1e-3, 5e-4, 2.5e-4]


def run(kneedyn, scene, outdir, formulation, args):
  d = os.path.join(outdir, formulation + "".join(a.replace("-", "") for a in args))
  p = subprocess.run([kneedyn, "run", scene, "--formulation", formulation, "--quiet", "--out", d] + args,
                     capture_output=True, text=True)
  if p.returncode == 2:  # kneedyn refused the input: the scene or the options
    raise tool_input.BadInput(f"kneedyn run refused {formulation} {' '.join(args)}: {p.stderr.strip()[-400:]}")
  if p.returncode != 0:
    print(f"patella_coupling.py: {formulation} {' '.join(args)}: exit {p.returncode}: {p.stderr.strip()[-400:]}",
          file=sys.stderr)
    return None
  with open(os.path.join(d, "summary.json")) as f:
    summary = json.load(f)
  with open(os.path.join(d, "trajectory.csv")) as f:
    table = list(csv.DictReader(f))
  rows = [(float(r["time_s"]), float(r["flexion_deg"])) for r in table]
  return {"summary": summary, "rows": rows, "table": table}


PATELLA_COLUMNS = ["flexion_deg", "patella_flexion_deg", "patella_tilt_deg", "patella_rotation_deg",
                   "patella_shift_mm", "tendon_force_N", "N_patella_medial_N", "N_patella_lateral_N",
                   "tendon_quadriceps_ratio"]


def against_flexion(result, every_deg=10.0):
  """The patella's columns at the first rows past 0, 10, 20, ... degrees of flexion."""
  out, next_deg = [], 0.0
  for r in result["table"]:
    if float(r["flexion_deg"]) >= next_deg:
      out.append({c: float(r[c]) for c in PATELLA_COLUMNS})
      next_deg += every_deg
  return out


def coupling_error(result, reference):
  first_event = min([e["time"] for e in reference["summary"]["events"]] + [math.inf])
  ref = {round(t, 9): a for t, a in reference["rows"]}
  err = 0.0
  for t, a in result["rows"]:
    if t < first_event and round(t, 9) in ref:
      err = max(err, abs(a - ref[round(t, 9)]))
  return err


def main(argv=None):
  ap = argparse.ArgumentParser()
  ap.add_argument("--kneedyn", required=True)
  ap.add_argument("--out", required=True)
  ap.add_argument("--scene", default=os.path.join(os.path.dirname(os.path.abspath(__file__)), "..",
                                                  "reference-data", "scenes", "patellofemoral_impact.yaml"))
  a = ap.parse_args(argv)
  tool_input.kneedyn_executable("--kneedyn", a.kneedyn)
  tool_input.existing_file("--scene", a.scene)
  tool_input.output_directory("--out", a.out)
  info = subprocess.run([a.kneedyn, "info", a.scene], capture_output=True, text=True)
  if info.returncode != 0:  # the scene is read before anything is written
    raise tool_input.BadInput(f"--scene = '{tool_input.echo(a.scene)}': {info.stderr.strip()[-400:]}")
  out = os.path.join(a.out, "patella")
  os.makedirs(out, exist_ok=True)
  reference = run(a.kneedyn, a.scene, out, "ede", ["--rtol", "1e-12", "--atol", "1e-14"])
  dae = run(a.kneedyn, a.scene, out, "dae", ["--rtol", "1e-10", "--atol", "1e-12"])
  if reference is None or dae is None:
    print("patella_coupling.py: a reference run failed", file=sys.stderr)
    return 1
  ref_events = reference["summary"]["events"]
  table = {"reference": "ede rtol 1e-12", "events": ref_events,
           "dae_event_time_differences_s": [d["time"] - r["time"] for d, r in zip(dae["summary"]["events"], ref_events)],
           "staggered": [], "patella_against_flexion": against_flexion(reference)}
  ok = True
  for dt in STEPS:
    r = run(a.kneedyn, a.scene, out, "staggered", ["--step", repr(dt), "--rtol", "1e-12", "--atol", "1e-14"])
    if r is None:
      ok = False
      continue
    table["staggered"].append({
        "dt_s": dt, "flexion_error_deg": coupling_error(r, reference),
        "event_time_errors_s": [e["time"] - f["time"] for e, f in zip(r["summary"]["events"], ref_events)],
        "wall_time_s": r["summary"].get("wall_time_s")})
  rows = table["staggered"]
  for prev, cur in zip(rows, rows[1:]):
    cur["observed_order"] = math.log2(prev["flexion_error_deg"] / cur["flexion_error_deg"])
  xs = [math.log(r["dt_s"]) for r in rows]
  ys = [math.log(r["flexion_error_deg"]) for r in rows]
  n = len(xs)
  if n >= 2:
    mx, my = sum(xs) / n, sum(ys) / n
    p = sum((x - mx) * (y - my) for x, y in zip(xs, ys)) / sum((x - mx) ** 2 for x in xs)
    table["fitted_order"] = p
    table["error_constant_deg_per_s_p"] = math.exp(my - p * mx)
  with open(os.path.join(out, "coupling.json"), "w") as f:
    json.dump(table, f, indent=1)
  try:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(1, 2, figsize=(9, 3.6))
    ax[0].loglog([r["dt_s"] for r in rows], [r["flexion_error_deg"] for r in rows], "o-", label="staggered")
    ax[0].loglog([r["dt_s"] for r in rows], [rows[0]["flexion_error_deg"] * r["dt_s"] / rows[0]["dt_s"] for r in rows],
                 "k--", label="slope 1")
    ax[0].set_xlabel("Δt (s)")
    ax[0].set_ylabel("max |flexion − reference| (deg)")
    ax[0].legend()
    ax[1].loglog([r["wall_time_s"] for r in rows], [r["flexion_error_deg"] for r in rows], "o-")
    ax[1].set_xlabel("wall time (s)")
    ax[1].set_ylabel("coupling error (deg)")
    fig.tight_layout()
    fig.savefig(os.path.join(out, "coupling.png"), dpi=120)
  except ImportError:
    pass
  print("flexion  patella flexion/tilt/rotation (deg)  tendon (N)  facets m/l (N)  tendon/quadriceps")
  for r in table["patella_against_flexion"]:
    print(f"{r['flexion_deg']:6.1f}  {r['patella_flexion_deg']:7.2f} {r['patella_tilt_deg']:6.2f} {r['patella_rotation_deg']:6.2f}"
          f"  {r['tendon_force_N']:7.2f}  {r['N_patella_medial_N']:6.2f} {r['N_patella_lateral_N']:6.2f}"
          f"  {r['tendon_quadriceps_ratio']:.3f}")
  for r in rows:
    print(f"dt = {r['dt_s']:.2e} s  error = {r['flexion_error_deg']:.3e} deg  order = {r.get('observed_order', float('nan')):.3f}"
          f"  event time errors = {['%.2e' % e for e in r['event_time_errors_s']]}  wall = {r['wall_time_s']} s")
  print("fitted order", table.get("fitted_order"), "error constant", table.get("error_constant_deg_per_s_p"))
  print("dae - ede event times (s):", table["dae_event_time_differences_s"])
  return 0 if ok else 1


if __name__ == "__main__":
  sys.exit(tool_input.exit_code("patella_coupling.py", main))
