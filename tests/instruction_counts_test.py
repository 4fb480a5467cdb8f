#!/usr/bin/env python3
"""compare_counters --instructions (benchmarks/README.md, "Instruction
counts") can fail, reports improvements and
skips without valgrind. One cheap run (ede, cvode-adams) under valgrind per case, against
baselines built here: a whole-process `kneedyn run` (dynamic loading of SUNDIALS, Ceres,
libyaml alone) executes far more than 1e6 instructions and far fewer than 1e12.

  instruction_counts_test.py --compare-counters PATH --kneedyn PATH --baseline PATH
"""
import argparse
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile

ap = argparse.ArgumentParser()
ap.add_argument("--compare-counters", required=True)
ap.add_argument("--kneedyn", required=True)
ap.add_argument("--baseline", required=True)
a = ap.parse_args()

base = json.load(open(a.baseline))
ic = base["instruction_counts"]
ede = [r for r in ic["runs"] if r["formulation"] == "ede"][0]
failures = []


def run(baseline_runs, extra=(), **instruction_counts):
    b = dict(base)
    b["instruction_counts"] = dict(ic, runs=baseline_runs, **instruction_counts)
    with tempfile.TemporaryDirectory() as d:
        path = os.path.join(d, "baseline.json")
        json.dump(b, open(path, "w"))
        p = subprocess.run([a.compare_counters, "--instructions", "--kneedyn", a.kneedyn, "--baseline", path,
                            *extra], capture_output=True, text=True)
        return p.returncode, p.stdout + p.stderr, json.load(open(path))


def expect(cond, what, out):
    if not cond:
        failures.append(what + "\n--- output ---\n" + out)


code, out, _ = run([ede], ["--valgrind", "/nonexistent/valgrind"])
expect(code == 77 and "SKIPPED: valgrind" in out, "no valgrind: exit 77 with SKIPPED", out)

code, out, _ = run([ede], ["--kneedyn", "/nonexistent/kneedyn"])
expect(code == 2 and "--kneedyn" in out, "bad --kneedyn: exit 2 naming it", out)

for field, value in (("instructions", "many"), ("instructions", 0), ("outside_run_scene", -1),
                     ("outside_run_scene", None)):
    code, out, _ = run([dict(ede, **{field: value})])
    counted = re.search(r"\d{6,} (instructions|outside)", out)  # a run was made first
    expect(code == 2 and field in out and json.dumps(value) in out and not counted,
           "%s = %r: exit 2 naming the field and value, before any run" % (field, value), out)

for share in (10, 0, -0.1, "ten"):
    code, out, _ = run([ede], outside_target_share=share)
    expect(code == 2 and "outside_target_share" in out,
           "outside_target_share = %r: exit 2 naming the field" % (share,), out)

# A negative or non-numeric threshold: every entry a regression (exit 1), or a string that
# nlohmann::json refused without naming the field; now exit 2 naming it, before any run.
for threshold in (-0.5, 0, 1.5, "five"):
    code, out, _ = run([ede], threshold=threshold)
    counted = re.search(r"\d{6,} (instructions|outside)", out)
    expect(code == 2 and "instruction_counts.threshold" in out and not counted,
           "threshold = %r: exit 2 naming the field, before any run" % (threshold,), out)
for field, value in (("counter_threshold", -1), ("counter_threshold", "x"), ("scd_drop", -0.5)):
    b = dict(base, **{field: value})
    with tempfile.TemporaryDirectory() as d:
        path = os.path.join(d, "baseline.json")
        json.dump(b, open(path, "w"))
        p = subprocess.run([a.compare_counters, "--baseline", path], capture_output=True, text=True)
    out = p.stdout + p.stderr
    expect(p.returncode == 2 and field + " = " + json.dumps(value) in out and "chapter_impact" not in out,
           "%s = %r: exit 2 naming the field and value, before any run" % (field, value), out)

if shutil.which("valgrind") is None:
    print("SKIPPED: valgrind not found on PATH (Debian package valgrind)")
    sys.exit(77 if not failures else 1)

code, out, _ = run([dict(ede, instructions=1_000_000)])
expect(code == 1 and "REGRESSION" in out, "count above baseline + 5 %: exit 1, REGRESSION", out)

code, out, _ = run([dict(ede, instructions=10**12)])
expect(code == 0 and "improved" in out, "count far below baseline: exit 0, reported as improved", out)

code, out, written = run([dict(ede, instructions=1)], ["--write"])
n = written["instruction_counts"]["runs"][0]["instructions"]
expect(code == 0 and 1_000_000 < n < 10**12, "--write records the measured count (got %s)" % n, out)
# ... and what recorded it: the command, the commit compare_counters was built from, the UTC
# date, and the measured kneedyn's --version line (which names its own commit).
prov = written["instruction_counts"].get("provenance", {})
version = subprocess.run([a.kneedyn, "--version"], capture_output=True, text=True).stdout.splitlines()
expect(prov.get("command", "").startswith("compare_counters --instructions") and "--write" in prov.get("command", "")
       and re.fullmatch(r"[0-9a-f]{7,40}(-dirty)?|unknown \(not built from git\)", prov.get("commit", ""))
       and re.fullmatch(r"\d{4}-\d\d-\d\dT\d\d:\d\d:\d\dZ", prov.get("date", ""))
       and version and prov.get("kneedyn") == version[0],
       "--write records its provenance (got %r)" % (prov,), out)

# The same run twice in one baseline counts the same, to path lengths and dates (a few
# hundred): the second may not pay for replacing the first one's output files (~30 k).
code, out, written = run([dict(ede, instructions=1), dict(ede, instructions=1)], ["--write"])
n1, n2 = (r["instructions"] for r in written["instruction_counts"]["runs"])
expect(code == 0 and abs(n1 - n2) < 2_000, "the same run twice: %s and %s instructions" % (n1, n2), out)

# The outside-RunScene count (start-up, loading, output) of the default dae run, gated on
# its own. Bounds with their reasons: above 5e5, since the run formats ~4,400 numbers and
# scans 4.9 KB of YAML, each at over a hundred instructions a number and fifty a byte;
# below half of the run, which takes ~1,600 steps of thousands of instructions each. With
# the toggle naming no function, the inside count is 0 and compare_counters refuses.
default_dae = {"formulation": "dae", "args": []}
code, out, written = run([dict(default_dae, instructions=1, outside_run_scene=1)], ["--write"])
w = written["instruction_counts"]["runs"][0]
outside, whole = w.get("outside_run_scene", 0), w["instructions"]
expect(code == 0 and 500_000 < outside < whole / 2,
       "--write records the outside count, 5e5 < %s < half of %s" % (outside, whole), out)
expect("outside RunScene" in out and "% of" in out and "target <= 10 %" in out,
       "the outside count is printed as a share beside the target", out)
if code == 0:
    code, out, _ = run([dict(w, outside_run_scene=outside // 2)])
    expect(code == 1 and "REGRESSION: outside RunScene" in out,
           "outside count above its baseline + 5 % (whole count unchanged): exit 1", out)
    code, out, _ = run([dict(w, outside_run_scene=outside * 2)])
    expect(code == 0 and "improved: outside RunScene" in out, "outside count far below baseline: improved", out)

for f in failures:
    print("FAIL:", f)
print("ok" if not failures else "%d failure(s)" % len(failures))
sys.exit(1 if failures else 0)
