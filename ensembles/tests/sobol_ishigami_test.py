#!/usr/bin/python3
"""The sensitivity pipeline recovers the Ishigami function's known Sobol' indices.

Runs `kneedyn sweep reference-data/specs/ishigami.yaml` (Saltelli design, N = 4096) and
reports/global_sensitivity.py (OpenTURNS), then compares with the closed-form indices of
f = sin x1 + a sin^2 x2 + b x3^4 sin x1 on [-pi, pi]^3 (Ishigami & Homma 1990; a = 7,
b = 0.1): each true index must lie in its 95 % bootstrap interval widened by 0.01, and the
estimate within 0.03 of it. Also checks that an outcome with one value in every run is
reported as "no variance" (not an error), that a sensitivity.json with null `normalized`
entries is read, that pick-freeze groups with a failed run or a
completed run without the outcome are dropped, not used, and counted by cause, and that --local (derivatives beside the indices) gives the linearized
first-order indices of the exact gradient at the nominal point x = 0, grad f = (1, 0, 0):
S_lin = (1, 0, 0), with sigma_k the sample standard deviation, close to pi/sqrt(3) for
U(-pi, pi). Does not check the chapter model's indices (no closed form).

  sobol_ishigami_test.py --kneedyn PATH
"""
import argparse
import csv
import json
import math
import os
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def true_indices(a=7.0, b=0.1):
  pi4, pi8 = math.pi ** 4, math.pi ** 8
  D = a * a / 8 + b * pi4 / 5 + b * b * pi8 / 18 + 0.5
  D1 = b * pi4 / 5 + b * b * pi8 / 50 + 0.5
  D2 = a * a / 8
  D13 = b * b * pi8 / 18 - b * b * pi8 / 50
  return [D1 / D, D2 / D, 0.0], [(D1 + D13) / D, D2 / D, D13 / D]


def main():
  ap = argparse.ArgumentParser()
  ap.add_argument("--kneedyn", required=True)
  a = ap.parse_args()
  spec = os.path.join(ROOT, "reference-data", "specs", "ishigami.yaml")
  script = os.path.join(ROOT, "reports", "global_sensitivity.py")
  failures = []
  with tempfile.TemporaryDirectory() as tmp:
    subprocess.run([a.kneedyn, "sweep", spec, "--quiet", "--out", tmp], check=True, stdout=subprocess.DEVNULL)
    subprocess.run([sys.executable, script, "--sweep", os.path.join(tmp, "sweep.csv"), "--spec", spec,
                    "--out", os.path.join(tmp, "gs"), "--bootstrap", "200"], check=True, stdout=subprocess.DEVNULL)
    with open(os.path.join(tmp, "gs", "sobol.json")) as f:
      r = json.load(f)["outcomes"]["value"]
    s1, st = true_indices()
    for name, est, ci, truth in (("S1", r["first_order"], r["first_order_ci"], s1), ("ST", r["total"], r["total_ci"], st)):
      for k in range(3):
        ok = ci[k][0] - 0.01 <= truth[k] <= ci[k][1] + 0.01 and abs(est[k] - truth[k]) < 0.03
        print(f"{name}[x{k + 1}] = {est[k]:.4f} CI [{ci[k][0]:.4f}, {ci[k][1]:.4f}], exact {truth[k]:.4f}: {'ok' if ok else 'FAIL'}")
        if not ok:
          failures.append(f"{name}[x{k + 1}]")
    # Local derivatives beside the indices: the exact gradient at x = 0 as a sensitivity.json.
    with open(os.path.join(tmp, "sweep.csv"), newline="") as f:
      names = next(csv.reader(f))[1:4]
    # `normalized` is null where the value is 0 (docs/outputs.md), as kneedyn sensitivity writes it.
    rows = [{"outcome": "value", "parameter": p, "parameter_value": 0.0, "value": 0.0, "derivative": g,
             "normalized": None} for p, g in zip(names, (1.0, 0.0, 0.0))]
    with open(os.path.join(tmp, "local.json"), "w") as f:
      json.dump({"rows": rows}, f)
    subprocess.run([sys.executable, script, "--sweep", os.path.join(tmp, "sweep.csv"), "--spec", spec,
                    "--out", os.path.join(tmp, "gsl"), "--bootstrap", "10", "--local", os.path.join(tmp, "local.json")],
                   check=True, stdout=subprocess.DEVNULL)
    with open(os.path.join(tmp, "gsl", "sobol.json")) as f:
      loc = json.load(f)["outcomes"]["value"].get("local", {})
    sigma_exact = math.pi / math.sqrt(3.0)
    ok = (loc.get("status") == "ok" and loc["linear_first_order"] == [1.0, 0.0, 0.0]
          and all(abs(sg / sigma_exact - 1.0) < 0.03 for sg in loc["sigma"]))
    print(f"local: {loc.get('status')}, S_lin {loc.get('linear_first_order')}, sigma {loc.get('sigma')} "
          f"(exact {sigma_exact:.4f}): {'ok' if ok else 'FAIL'}")
    if not ok:
      failures.append("local derivatives beside the indices")
    if not os.path.exists(os.path.join(tmp, "gsl", "sobol_value.png")):
      failures.append("chart with local bars not written")
    # Failed runs: mark two rows of different groups failed, and a third group's run completed
    # without the outcome (a lift-off that did not happen); exactly three groups are dropped,
    # counted by cause. A fourth group's failed run keeps its value (what it reached before the
    # failure): that group is used, and not counted as dropped.
    with open(os.path.join(tmp, "sweep.csv"), newline="") as f:
      rows = list(csv.reader(f))
    n = 4096
    for row in (1 + 5, 1 + 3 * n + 9):  # group 5 (in A), group 9 (in A_B^1)
      rows[row][4] = "nan"
      rows[row][5] = "failed"
    rows[1 + n + 17][4] = "nan"  # group 17 (in B): completed, outcome undefined
    rows[1 + 2 * n + 23][5] = "failed"  # group 23 (in A_B^0): failed with a value it reached: kept
    with open(os.path.join(tmp, "broken.csv"), "w", newline="") as f:
      csv.writer(f).writerows(rows)
    subprocess.run([sys.executable, script, "--sweep", os.path.join(tmp, "broken.csv"), "--spec", spec,
                    "--out", os.path.join(tmp, "gs2"), "--bootstrap", "10", "--no-charts"], check=True,
                   stdout=subprocess.DEVNULL)
    with open(os.path.join(tmp, "gs2", "sobol.json")) as f:
      r2 = json.load(f)["outcomes"]["value"]
    # An outcome with one value in every run whose float mean is not that value (98.36654237141033
    # 1,536 times: the summed mean is off in its last digits, the sum of squares 5e-22, not 0):
    # "no variance", not OpenTURNS' zero-bandwidth error.
    with open(os.path.join(tmp, "sweep.csv"), newline="") as f:
      rows = list(csv.reader(f))
    for row in rows[1:]:
      row[4] = "98.36654237141033"
    with open(os.path.join(tmp, "constant.csv"), "w", newline="") as f:
      csv.writer(f).writerows(rows)
    done = subprocess.run([sys.executable, script, "--sweep", os.path.join(tmp, "constant.csv"), "--spec", spec,
                           "--out", os.path.join(tmp, "gs3"), "--bootstrap", "10", "--no-charts"],
                          stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    status = None
    if done.returncode == 0:
      with open(os.path.join(tmp, "gs3", "sobol.json")) as f:
        status = json.load(f)["outcomes"]["value"].get("status")
    print(f"constant outcome: exit {done.returncode}, status {status!r}")
    if done.returncode != 0 or status != "no variance":
      failures.append(f"constant outcome: exit {done.returncode}, status {status!r} {done.stderr[-300:]}")
    if (r2["groups_dropped"] != 3 or r2["groups_used"] != n - 3 or r2.get("groups_dropped_failed_run") != 2
        or r2.get("groups_dropped_outcome_undefined") != 1):
      failures.append(f"groups dropped {r2['groups_dropped']} (expected 3), with a failed run "
                      f"{r2.get('groups_dropped_failed_run')} (2), outcome undefined "
                      f"{r2.get('groups_dropped_outcome_undefined')} (1)")
  if failures:
    print("FAILED: " + ", ".join(failures))
    return 1
  return 0


if __name__ == "__main__":
  sys.exit(main())
