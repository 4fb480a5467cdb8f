#!/usr/bin/python3
"""The report tools' input contract (the exit codes in README.md): bad input to reports/report.py
and its pieces (run_families.py, patella_section.py, reconstruction.py, figures.py, claims.py,
make_report.py) is refused before any run: exit 2, a message naming the argument, no Python
traceback, nothing written (no --out directory, no file beside the planted inputs), and fast.

  report_inputs_test.py --kneedyn PATH
"""
import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
REPORTS = os.path.join(ROOT, "reports")
sys.path.insert(0, HERE)
sys.dont_write_bytecode = True
from py_test_support import finish  # noqa: E402

# A refusal comes before any run; a run of the quick families alone takes far longer.
FAST_S = 5.0


def snapshot(d):
  return sorted(os.path.relpath(os.path.join(p, f), d) for p, ds, fs in os.walk(d) for f in fs + ds)


# In a fresh interpreter: run_families' runner beside BINARY, and one run of a missing scene.
PARTIAL_PROBE = """
import json, os, sys
sys.path.insert(0, sys.argv[1])
import run_families
m = run_families.kneedyn_module(sys.argv[2])
r = run_families.run_once(sys.argv[2], os.path.join(sys.argv[3], "missing.yaml"), os.path.join(sys.argv[3], "run"),
                          run_families.SOLVER_ARGS)
print(json.dumps({"module": m is not None, "runner": r["runner"], "returncode": r["returncode"],
                  "description": run_families.runner_description(sys.argv[2])}))
"""


def partial_module_errors(kneedyn):
  """A partial Python build (build/python/kneedyn without the _kneedyn extension: an empty
  package directory, or __init__.py alone) must leave run_families on the CLI: a run of a
  missing scene is the CLI's exit 2, not an AttributeError from a package without run/Error."""
  errors = []
  for layout in ("empty directory", "__init__.py without _kneedyn"):
    with tempfile.TemporaryDirectory(prefix="report_partial_") as tmp:
      os.makedirs(os.path.join(tmp, "build", "formulations"))
      binary = os.path.join(tmp, "build", "formulations", "kneedyn")
      os.symlink(kneedyn, binary)
      package = os.path.join(tmp, "build", "python", "kneedyn")
      os.makedirs(package)
      if layout.startswith("__init__"):
        shutil.copy(os.path.join(ROOT, "python", "kneedyn", "__init__.py"), package)
      env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "KNEEDYN_REPORT_RUNNER")}
      env["PYTHONDONTWRITEBYTECODE"] = "1"
      p = subprocess.run([sys.executable, "-c", PARTIAL_PROBE, REPORTS, binary, tmp], capture_output=True,
                         text=True, env=env, cwd=tmp, timeout=120)
      if p.returncode != 0:
        errors.append(f"partial build ({layout}): the runner crashed: {p.stderr[-600:]!r}")
        continue
      got = json.loads(p.stdout.strip().splitlines()[-1])
      if got["module"] or got["runner"] != "subprocess" or got["returncode"] != 2 or "CLI" not in got["description"]:
        errors.append(f"partial build ({layout}): expected the CLI runner (exit 2 for a missing scene), got {got}")
  return errors


def main():
  ap = argparse.ArgumentParser()
  ap.add_argument("--kneedyn", required=True, help="the kneedyn binary (a valid one: the other inputs are bad)")
  args = ap.parse_args()
  kneedyn = os.path.abspath(args.kneedyn)
  not_kneedyn = shutil.which("true") or "/bin/true"
  errors = []
  checked = 0
  env = dict(os.environ, PYTHONDONTWRITEBYTECODE="1")
  with tempfile.TemporaryDirectory(prefix="report_inputs_") as tmp:
    def plant(name, text, mode=0o644):
      path = os.path.join(tmp, name)
      os.makedirs(os.path.dirname(path), exist_ok=True)
      with open(path, "w") as f:
        f.write(text)
      os.chmod(path, mode)
      return path

    bad_json = plant("bad.json", '{"results": [')
    no_columns = plant("hard_cases.csv", "a,b\n1,2\n")
    not_exec = plant("calibrate_reconstruction", "#!/bin/sh\nexit 0\n", 0o644)
    calibrate_stub = plant("calibrate_stub", "#!/bin/sh\nexit 0\n", 0o755)
    a_file = plant("a_file.txt", "not a directory\n")
    a_dir = os.path.join(tmp, "a_dir")
    os.makedirs(a_dir)
    truncated = os.path.join(tmp, "truncated_run")
    plant("truncated_run/families.json", '{"members": [')
    # A minimal directory run_families.py + claims.py could have left: make_report.py reads it.
    minimal = os.path.join(tmp, "minimal_run")
    plant("minimal_run/families.json", '{"members": []}')
    plant("minimal_run/claims.json", "[]")

    def out(name):
      return os.path.join(tmp, "out_" + name)

    report = [os.path.join(REPORTS, "report.py"), "--quick"]
    cases = [  # (name, command, option the message must name, --out that must not appear)
        ("bench_bad_json", report + ["--kneedyn", kneedyn, "--out", out("a"), "--bench", bad_json], "--bench", out("a")),
        ("peer_bench_bad_json", report + ["--kneedyn", kneedyn, "--out", out("b"), "--peer-bench", bad_json],
         "--peer-bench", out("b")),
        ("include_bad_bench", report + ["--kneedyn", kneedyn, "--out", out("c"), "--bench", bad_json,
                                        "--include", a_dir], "--bench", out("c")),
        ("include_without_bench", report + ["--kneedyn", kneedyn, "--out", out("d"), "--include", a_dir],
         "--include", out("d")),
        ("hard_cases_directory", report + ["--kneedyn", kneedyn, "--out", out("e"), "--hard-cases", a_dir],
         "--hard-cases", out("e")),
        ("hard_cases_no_columns", report + ["--kneedyn", kneedyn, "--out", out("f"), "--hard-cases", no_columns],
         "--hard-cases", out("f")),
        ("kneedyn_not_kneedyn", report + ["--kneedyn", not_kneedyn, "--out", out("g")], "--kneedyn", out("g")),
        ("kneedyn_directory", report + ["--kneedyn", a_dir, "--out", out("h")], "--kneedyn", out("h")),
        ("out_under_proc", report + ["--kneedyn", kneedyn, "--out", "/proc/x/y"], "--out", "/proc/x/y"),
        ("out_existing_file", report + ["--kneedyn", kneedyn, "--out", a_file], "--out", None),
        ("calibrate_not_executable", report + ["--kneedyn", kneedyn, "--out", out("i"), "--reconstruction",
                                               "--calibrate", not_exec], "--calibrate", out("i")),
        ("run_families_kneedyn_directory", [os.path.join(REPORTS, "run_families.py"), "--kneedyn", a_dir,
                                            "--out", out("j"), "--quick"], "--kneedyn", out("j")),
        ("run_families_jobs_zero", [os.path.join(REPORTS, "run_families.py"), "--kneedyn", kneedyn,
                                    "--out", out("j2"), "--quick", "--jobs", "0"], "--jobs", out("j2")),
        ("run_families_out_under_proc", [os.path.join(REPORTS, "run_families.py"), "--kneedyn", kneedyn,
                                         "--out", "/proc/x/y", "--quick"], "--out", "/proc/x/y"),
        ("patella_not_kneedyn", [os.path.join(REPORTS, "patella_section.py"), "--kneedyn", not_kneedyn,
                                 "--out", out("k"), "--quick"], "--kneedyn", out("k")),
        ("patella_out_existing_file", [os.path.join(REPORTS, "patella_section.py"), "--kneedyn", kneedyn,
                                       "--out", a_file, "--quick"], "--out", None),
        ("reconstruction_calibrate", [os.path.join(REPORTS, "reconstruction.py"), "--kneedyn", kneedyn,
                                      "--out", out("l"), "--quick", "--calibrate", not_exec], "--calibrate", out("l")),
        ("reconstruction_calibrate_grid", [os.path.join(REPORTS, "reconstruction.py"), "--kneedyn", kneedyn,
                                           "--out", out("l2"), "--quick", "--calibrate", calibrate_stub,
                                           "--calibrate-grid", "-1"], "--calibrate-grid", out("l2")),
        ("reconstruction_jobs_negative", [os.path.join(REPORTS, "reconstruction.py"), "--kneedyn", kneedyn,
                                          "--out", out("l3"), "--quick", "--jobs", "-2"], "--jobs", out("l3")),
        ("reconstruction_not_kneedyn", [os.path.join(REPORTS, "reconstruction.py"), "--kneedyn", not_kneedyn,
                                        "--out", out("m"), "--quick"], "--kneedyn", out("m")),
        ("claims_missing_out", [os.path.join(REPORTS, "claims.py"), "--out", out("n")], "--out", out("n")),
        ("claims_truncated_families", [os.path.join(REPORTS, "claims.py"), "--out", truncated], "--out", None),
        ("figures_out_is_file", [os.path.join(REPORTS, "figures.py"), "--out", a_file], "--out", None),
        ("figures_empty_out", [os.path.join(REPORTS, "figures.py"), "--out", a_dir], "--out", None),
        ("make_report_truncated_families", [os.path.join(REPORTS, "make_report.py"), "--out", truncated],
         "--out", None),
        ("make_report_missing_bench", [os.path.join(REPORTS, "make_report.py"), "--out", minimal,
                                       "--bench", os.path.join(tmp, "nonexistent.json")], "--bench", None),
        ("make_report_hard_cases_no_columns", [os.path.join(REPORTS, "make_report.py"), "--out", minimal,
                                               "--hard-cases", no_columns], "--hard-cases", None),
    ]
    for name, cmd, option, must_not_exist in cases:
      before = snapshot(tmp)
      start = time.monotonic()
      try:
        p = subprocess.run([sys.executable] + cmd, capture_output=True, text=True, timeout=120, cwd=ROOT, env=env)
      except subprocess.TimeoutExpired:
        errors.append(f"{name}: still running after 120 s (the bad input was not refused before the runs)")
        continue
      elapsed = time.monotonic() - start
      checked += 1
      tool = os.path.splitext(os.path.basename(cmd[0]))[0]
      where = f"{name}: {' '.join(cmd[1:])}"
      if p.returncode != 2:
        errors.append(f"{where}: exit {p.returncode}, expected 2; stderr: {p.stderr[-400:]!r}")
      if "Traceback" in p.stderr:
        errors.append(f"{where}: traceback on stderr: {p.stderr[-400:]!r}")
      if option not in p.stderr:
        errors.append(f"{where}: the message does not name {option}: {p.stderr[-400:]!r}")
      if not p.stderr.startswith(f"{tool}: error: "):
        errors.append(f"{where}: the message does not start with '{tool}: error: ': {p.stderr[:200]!r}")
      if must_not_exist and os.path.exists(must_not_exist):
        errors.append(f"{where}: --out '{must_not_exist}' was created")
      after = snapshot(tmp)
      if after != before:
        errors.append(f"{where}: wrote {sorted(set(after) - set(before))}")
      if elapsed > FAST_S:
        errors.append(f"{where}: took {elapsed:.1f} s: not refused before the runs (limit {FAST_S} s)")
  errors += partial_module_errors(kneedyn)
  return finish(errors, "report_inputs_test: FAIL", f"report_inputs_test: {checked} bad inputs refused, "
                f"{len(errors)} problem(s)")


if __name__ == "__main__":
  sys.exit(main())
