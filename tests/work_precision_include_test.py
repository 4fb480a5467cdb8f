#!/usr/bin/python3
"""Outside results beside the built-ins: `work_precision --include DIR` and the report's
work-precision section (`report.py --include DIR`, figures.make_work_precision(include=...)).

The outside results are real: the C example (examples/c/rk4_on_the_knee.c, on the C interface
alone) runs the chapter scene at h = 1e-3 s and `kneedyn score` scores it; the same trajectory
scored again with --failed is the planted failed outside run. Checks:
  * work_precision --short --only ede:rk4/step=0.002 --include DIR: both records in `results`
    (origin outside, their status, the ok one with a finite scd; RK4 at h = 1e-3 s gives at
    least 2 digits: its lift-off error is O(h^4)), one CSV row each, the file in the header;
  * the figures drawn from that JSON: the outside solver's panel, marked as outside, counts
    exactly 1 failure (the planted one), and its ok run is on the Pareto front's legend;
  * the report's section with a sweep file plus --include DIR: the outside-solver table lists
    the solver, and the failed run is in the failure list;
  * bad input: a score for another scene, a directory without score files, score files
    nested 100 and 200,000 deep: exit 2, nothing written (and bench_data refuses each).
Expected values are the planted facts (1 failure, the names given to kneedyn score), not
values copied from a run.

  work_precision_include_test.py --kneedyn K --work-precision W --rk4 R
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.dont_write_bytecode = True
sys.path.insert(0, os.path.join(ROOT, "reports"))
from py_test_support import finish  # noqa: E402
SCENE = os.path.join(ROOT, "reference-data", "scenes", "chapter_impact.yaml")
SOLVER = "c-example"
FAILURE = "planted: the outside driver gave up"


def png_text(path):
  from PIL import Image
  with Image.open(path) as im:
    return dict(im.text)


def main():
  ap = argparse.ArgumentParser()
  ap.add_argument("--kneedyn", required=True)
  ap.add_argument("--work-precision", required=True)
  ap.add_argument("--rk4", required=True)
  a = ap.parse_args()
  errors = []
  import figures  # noqa: E402
  import make_report  # noqa: E402
  with tempfile.TemporaryDirectory(prefix="kneedyn_wp_include_") as tmp:
    inc = os.path.join(tmp, "outside")
    run_dir = os.path.join(inc, "c_rk4")
    os.makedirs(run_dir)
    subprocess.run([a.rk4, SCENE, "1e-3", run_dir], check=True, stdout=subprocess.DEVNULL)
    base = [a.kneedyn, "score", os.path.join(run_dir, "trajectory.csv"), "--scene", SCENE, "--events",
            os.path.join(run_dir, "events.csv"), "--solver-name", SOLVER, "--integrator", "rk4", "--step", "1e-3",
            "--cpu-time", "0.004"]
    subprocess.run(base + ["--out", os.path.join(run_dir, "score.json")], check=True, stdout=subprocess.DEVNULL)
    subprocess.run(base + ["--failed", FAILURE, "--out", os.path.join(run_dir, "failed.score.json")], check=True,
                   stdout=subprocess.DEVNULL)

    # 1. work_precision --include
    wp = os.path.join(tmp, "wp.json")
    r = subprocess.run([a.work_precision, "--short", "--only", "ede:rk4/step=0.002", "--repetitions", "2",
                        "--include", inc, "--json", wp], capture_output=True, text=True)
    if r.returncode != 0:
      errors.append(f"work_precision --include: exit {r.returncode}: {r.stderr[-800:]}")
      data = {"results": [], "header": {}}
    else:
      with open(wp) as f:
        data = json.load(f)
    outside = [x for x in data["results"] if x.get("origin") == "outside"]
    built_in = [x for x in data["results"] if x.get("origin") != "outside"]
    if sorted(x.get("status") for x in outside) != ["failed", "ok"] or any(x["formulation"] != SOLVER for x in outside):
      errors.append(f"included records: {[(x.get('formulation'), x.get('status')) for x in outside]}")
    if [x.get("formulation") for x in built_in] != ["ede"]:
      errors.append(f"built-in records: {[x.get('formulation') for x in built_in]} (want the one ede:rk4 run)")
    ok = [x for x in outside if x.get("status") == "ok"]
    if ok and not (isinstance(ok[0]["metrics"].get("scd"), float) and ok[0]["metrics"]["scd"] >= 2.0):
      errors.append(f"the included ok run's scd: {ok[0]['metrics'].get('scd')}")
    failed = [x for x in outside if x.get("status") == "failed"]
    if failed and failed[0].get("reason") != FAILURE:
      errors.append(f"the included failed run's reason: {failed[0].get('reason')!r}")
    if len((data["header"].get("included") or {}).get("files", [])) != 2:
      errors.append(f"header.included: {data['header'].get('included')}")
    # The fairness manifest names the outside solver as built and timed outside kneedyn (it had
    # listed kneedyn's own components alone, as if every curve were built alike).
    manifest = {c.get("name"): c for c in (data.get("context") or {}).get("components", [])}
    if SOLVER not in manifest or "outside" not in manifest[SOLVER].get("origin", ""):
      errors.append(f"context.components lacks the outside solver {SOLVER}: {sorted(manifest)}")
    if os.path.exists(wp[:-5] + ".csv"):
      with open(wp[:-5] + ".csv") as f:
        rows = [line for line in f.read().splitlines()[1:] if line.startswith(f'"{SOLVER}"')]
      if len(rows) != 2:
        errors.append(f"CSV rows of {SOLVER}: {rows}")

    # 2. The figures from that file: the outside panel, marked, with its one failure.
    out = os.path.join(tmp, "report")
    if os.path.exists(wp):
      files, failed_rows, header = figures.make_work_precision(out, wp)
      want = f"{SOLVER} [outside, kneedyn score]  (1 failed / wrong event)"
      for fname in files:
        panels = png_text(os.path.join(out, "figures", fname)).get("Description", "").splitlines()
        if not any(p.startswith(want[:-1]) for p in panels):  # ")" or ", 1 without a time)"
          errors.append(f"{fname}: no panel {want!r} in {panels}")
      if not any(key.startswith(SOLVER) and why.startswith("failed: planted") for key, _, why in failed_rows):
        errors.append(f"failure rows: {failed_rows}")
      if len(header.get("included_runs", [])) != 2:
        errors.append(f"included_runs: {len(header.get('included_runs', []))}")

    # 3. The report's section: a sweep file without outside results plus --include DIR.
    if built_in:
      sweep = os.path.join(tmp, "sweep_only.json")
      with open(sweep, "w") as f:
        json.dump({"header": data["header"], "results": built_in}, f)
      html = make_report.bench_section(os.path.join(tmp, "report2"), sweep, include=[inc])
      if "Outside solvers (scored by <code>kneedyn score</code>)" not in html or f"<td>{SOLVER}</td>" not in html:
        errors.append("report section: no outside-solver table listing " + SOLVER)
      if FAILURE not in html:
        errors.append("report section: the failed outside run is not listed")
      html_without = make_report.bench_section(os.path.join(tmp, "report3"), sweep)
      if SOLVER in html_without:
        errors.append(f"report section without --include lists {SOLVER}")

    # 4. Bad input: another scene's score; a directory without score files.
    bad = os.path.join(tmp, "bad")
    os.makedirs(bad)
    with open(os.path.join(run_dir, "score.json")) as f:
      other = json.load(f)
    other["header"]["scene"] = "another_scene"
    with open(os.path.join(bad, "x.score.json"), "w") as f:
      json.dump(other, f)
    empty = os.path.join(tmp, "empty")
    os.makedirs(empty)
    deep = os.path.join(tmp, "deep")  # nesting past work_precision's limit of 64, refused as read
    os.makedirs(deep)
    with open(os.path.join(deep, "score.json"), "w") as f:
      f.write("[" * 100 + "]" * 100)
    deeper = os.path.join(tmp, "deeper")  # past Python's recursion limit too (a RecursionError before)
    os.makedirs(deeper)
    with open(os.path.join(deeper, "score.json"), "w") as f:
      f.write("[" * 200000 + "]" * 200000)
    # (directory, what work_precision says, what bench_data.load_included says)
    for d, words, py_words in ((bad, "another_scene", "another_scene"), (empty, "no score.json", "no score.json"),
                               (deep, "nesting depth 65 exceeds the limit of 64", "not kneedyn score's JSON"),
                               (deeper, "nesting depth 65 exceeds the limit of 64", "nested too deep")):
      target = os.path.join(tmp, "not_written.json")
      r = subprocess.run([a.work_precision, "--short", "--only", "ede:rk4/step=0.002", "--include", d, "--json", target],
                         capture_output=True, text=True)
      if r.returncode != 2 or words not in r.stderr or os.path.exists(target):
        errors.append(f"--include {d}: exit {r.returncode}, stderr {r.stderr.strip()!r}, written {os.path.exists(target)}")
      try:
        import bench_data
        bench_data.load_included(d, "chapter_impact")
        errors.append(f"load_included({d}) accepted it")
      except ValueError as e:
        if py_words not in str(e):
          errors.append(f"load_included({d}): {e}")

  return finish(errors, "FAIL:", "work_precision_include: " + ("FAILED" if errors else "passed"), sys.stdout)


if __name__ == "__main__":
  sys.exit(main())
