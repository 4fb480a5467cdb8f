#!/usr/bin/python3
"""Builds the chapter report with --quick into a temporary directory and checks its outputs:
every figure of reports/figures.FIGURES is a valid PNG (> 1 kB), index.html references them,
and the claims table has exactly one row per claim id of reports/claims.yaml; the
Reproduction section gives the command that was run, with every argument, the pieces
report.py ran and the main job's steps (.ci/bootstrap run).

  report_test.py --kneedyn PATH [--keep DIR]
"""
import argparse
import csv
import json
import os
import shlex
import shutil
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.dont_write_bytecode = True  # keep the source tree clean
sys.path.insert(0, os.path.join(ROOT, "reports"))
import claims  # noqa: E402
import figures  # noqa: E402
import patella_section  # noqa: E402

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def claim_ids():
  """Ids of reports/claims.yaml (the repository's own claims file)."""
  return [c["id"] for c in claims.load_claims()[1]]


def main():
  ap = argparse.ArgumentParser()
  ap.add_argument("--kneedyn", required=True)
  ap.add_argument("--keep", help="build into this directory instead of a temporary one")
  ap.add_argument("--work-precision", help="work_precision binary: also check the work-precision "
                  "diagrams against a real (short, one-formulation) sweep")
  ap.add_argument("--catalog", help="kneedyn_catalog binary: add a two-case hard-case section")
  ap.add_argument("--calibrate", help="calibrate_reconstruction binary: run the reconstruction study "
                  "(quick families) and a two-iteration calibration, and check their section")
  args = ap.parse_args()
  errors = []
  spec_ids = claim_ids()
  if len(spec_ids) < 30:
    print(f"report_test: only {len(spec_ids)} claim ids in claims.yaml", file=sys.stderr)
    return 1

  with tempfile.TemporaryDirectory(prefix="kneedyn_report_") as tmp:
    out = args.keep or tmp
    if args.keep:  # start clean: a stale page from an earlier run must not pass
      shutil.rmtree(out, ignore_errors=True)
      os.makedirs(out)
    cmd = ["/usr/bin/python3" if os.path.exists("/usr/bin/python3") else sys.executable,
           os.path.join(ROOT, "reports", "report.py"), "--kneedyn", args.kneedyn, "--out", out, "--quick"]
    bench = None
    if args.work_precision:
      bench = os.path.join(out, "wp.json")
      w = subprocess.run([args.work_precision, "--short", "--only", "dae-reduced", "--json", bench,
                          "--csv", os.path.join(out, "wp.csv")], capture_output=True, text=True,
                         timeout=60, cwd=ROOT)
      if w.returncode != 0 or not os.path.exists(bench):
        errors.append(f"work_precision failed ({w.returncode}): {w.stderr[-500:]}")
        bench = None
      else:
        cmd += ["--bench", bench]
    if args.catalog:
      hc = os.path.join(out, "hard_cases")
      c = subprocess.run([args.catalog, "--out", hc, "--case", "c1_law", "--case", "jcs_singular_pose"],
                         capture_output=True, text=True, timeout=120, cwd=ROOT)
      if c.returncode != 0:
        errors.append(f"kneedyn_catalog failed ({c.returncode}): {c.stderr[-500:]}")
      else:
        cmd += ["--hard-cases", os.path.join(hc, "hard_cases.csv")]
    if args.calibrate:
      cmd += ["--reconstruction", "--calibrate", args.calibrate]
    p = subprocess.run(cmd, capture_output=True, text=True, timeout=280)
    print(p.stdout)
    print(p.stderr, file=sys.stderr)
    index = os.path.join(out, "index.html")
    if not os.path.exists(index):
      print("report_test: index.html not written", file=sys.stderr)
      return 1
    # A failed run still produces the report (exit 1); the run itself is not under test here,
    # but it must be reported in the page.
    if p.returncode not in (0, 1):
      errors.append(f"report.py exited with {p.returncode}")
    page = open(index, encoding="utf-8").read()

    for fname, _ in figures.FIGURES:
      path = os.path.join(out, "figures", fname)
      if not os.path.exists(path):
        errors.append(f"missing figure {fname}")
        continue
      with open(path, "rb") as f:
        head = f.read(8)
      size = os.path.getsize(path)
      if head != PNG_SIGNATURE:
        errors.append(f"{fname}: not a PNG (signature {head!r})")
      if size <= 1024:
        errors.append(f"{fname}: only {size} bytes")
      if f"figures/{fname}" not in page:
        errors.append(f"index.html does not reference figures/{fname}")

    with open(os.path.join(out, "claims.csv"), newline="", encoding="utf-8") as f:
      rows = list(csv.DictReader(f))
    row_ids = [r["id"] for r in rows]
    for cid in spec_ids:
      n = row_ids.count(cid)
      if n != 1:
        errors.append(f"claim {cid}: {n} rows in claims.csv (expected 1)")
      elif f">{cid}<" not in page:
        errors.append(f"claim {cid} not in the index.html table")
    for r in rows:
      if r["verdict"] not in ("reproduced", "not reproduced", "not checkable"):
        errors.append(f"claim {r['id']}: bad verdict '{r['verdict']}'")
      if r["verdict"] != "not checkable" and not r["measured"]:
        errors.append(f"claim {r['id']}: verdict without a measured value")
    if bench:
      # The diagrams read the benchmark's own JSON: every successful run must be plotted.
      _, runs = figures.load_bench(bench)
      _, failed, _ = figures.make_work_precision(os.path.join(out, "wp_check"), bench)
      if not runs:
        errors.append(f"{bench}: no runs read by figures.load_bench")
      elif len(failed) >= len(runs):
        errors.append(f"work-precision: all {len(runs)} runs unplotted ({failed[:2]})")
      for fname, _ in figures.WORK_PRECISION_FIGURES:
        if f"figures/{fname}" not in page:
          errors.append(f"index.html does not reference figures/{fname}")
    # The methods section with a live run per formulation with its own integrator
    # (the four below among them; each row a completed run).
    if "id='methods'" not in page:
      errors.append("index.html has no methods section (reports/methods_comparison.py)")
    else:
      methods_part = page[page.index("id='methods'"):]
      for m in ("dae", "dae-ggl", "newmark", "generalized-alpha"):
        if f"<tr><td>{m}</td>" not in methods_part:
          errors.append(f"methods section: no row for {m}")
      if "failed (exit" in methods_part.split("</table>")[0]:
        errors.append("methods section: a live run failed")
    # The inverse problem's earlier points run again: one row per target of the recorded file.
    with open(os.path.join(ROOT, "reports", "recorded", "inverse_problem.json"), encoding="utf-8") as f:
      rechecked = json.load(f).get("recorded_points_rechecked") or {}
    if rechecked and "id='inverse-rechecked'" not in page:
      errors.append("index.html has no table of the inverse problem's rechecked points")
    elif rechecked:
      part = page[page.index("id='inverse-rechecked'"):].split("</table>")[0]
      for cid, r in rechecked.items():
        lo = r.get("liftoff_lateral_deg_by_kneedyn_run")
        row = f"<tr><td>{cid}</td><td>{str(r['recorded_commit'])[:12]}, {r['recorded_date']}</td>"
        if row not in part or (lo is not None and f"<td>{lo:.1f}</td>" not in part):
          errors.append(f"rechecked inverse point {cid}: no row '{row}' with lift-off {lo}")
    if args.catalog and "<table class='hard'>" not in page:
      errors.append("index.html has no compact hard-case table")
    if args.calibrate:
      rec_path = os.path.join(out, "reconstruction", "reconstruction.json")
      if not os.path.exists(rec_path):
        errors.append("reconstruction.json not written")
      else:
        with open(rec_path, encoding="utf-8") as f:
          rec = json.load(f)
        want = len(claims.load_claims()[1]) - 2  # S1/S2 are not re-run per reading
        for r in rec["readings"]:
          if len(r["verdicts"]) != want:
            errors.append(f"reading {r['key']}: {len(r['verdicts'])} verdicts (expected {want})")
        if len(rec["readings"]) < 9:
          errors.append(f"only {len(rec['readings'])} readings")
      if "<table class='matrix'>" not in page or "Calibration (Ceres)" not in page:
        errors.append("index.html lacks the reconstruction matrix or the calibration")
      if not os.path.exists(os.path.join(out, "reconstruction", "calibration.json")):
        errors.append("calibration.json not written")
    # The patello-femoral section (reports/patella_section.py; its own test: patella_section).
    if "id='patella'" not in page:
      errors.append("index.html has no patella section (reports/patella_section.py)")
    for fname, _ in patella_section.FIGURES:
      if f"figures/{fname}" not in page or not os.path.exists(os.path.join(out, "figures", fname)):
        errors.append(f"patella section: figures/{fname} missing or not referenced")
    # The Reproduction section: the command as it was run (every argument, in order), the
    # pieces report.py ran, and the main job's steps that made the inputs (.ci/bootstrap run).
    if "id='reproduce'" not in page:
      errors.append("index.html has no Reproduction section")
    else:
      import html as html_mod
      repro = html_mod.unescape(page[page.index("id='reproduce'"):])
      if shlex.join(cmd[1:]) not in repro:
        errors.append(f"Reproduction section does not give the command that made the page: {shlex.join(cmd[1:])}")
      pieces = ["run_families.py", "patella_section.py", "figures.py", "claims.py", "make_report.py"]
      pieces += ["reconstruction.py"] if args.calibrate else []
      for want in pieces + ["kneedyn_catalog", "outside_results.sh", "work_precision", "simbody_work_precision",
                            "sweep \"$spec\"", "sensitivity --spec", "global_sensitivity.py"]:
        if want not in repro:
          errors.append(f"Reproduction section does not list {want}")
    for extra in ("claims.md", "sensitivity.json"):
      if not os.path.exists(os.path.join(out, extra)):
        errors.append(f"missing {extra}")

  for e in errors:
    print("report_test: FAIL:", e, file=sys.stderr)
  if not errors:
    print(f"report_test: ok ({len(figures.FIGURES)} figures, {len(spec_ids)} claims)")
  return 1 if errors else 0


if __name__ == "__main__":
  sys.exit(main())
