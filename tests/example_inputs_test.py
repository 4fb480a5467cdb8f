#!/usr/bin/env python3
"""The examples refuse bad arguments as kneedyn's programs do: exit 2, a message naming the
argument and its value, no traceback, nothing written; examples/c/rk4_on_the_knee as well.

    example_inputs_test.py RK4_EXECUTABLE REFERENCE.json
(run with PYTHONPATH holding the kneedyn module; ctest example_inputs)
"""
import os
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
EXAMPLES = os.path.join(ROOT, "examples")
PY = sys.executable
sys.path.insert(0, os.path.join(ROOT, "tests"))
from py_test_support import finish  # noqa: E402


def expect_refused(cmd, must_name, out=None):
    """Exit 2, stderr naming must_name, no traceback, out not created. Returns a failure or ''."""
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    problems = []
    if r.returncode != 2:
        problems.append(f"exit {r.returncode}")
    if must_name not in r.stderr:
        problems.append(f"stderr does not name {must_name!r}")
    if "Traceback" in r.stderr:
        problems.append("a traceback")
    if out and os.path.exists(out):
        problems.append(f"{out} was created")
    return f"{' '.join(cmd[1:])}: {', '.join(problems)}: {r.stderr.strip()[-300:]}" if problems else ""


def main():
    rk4, reference = sys.argv[1], sys.argv[2]
    scene = os.path.join(ROOT, "reference-data", "scenes", "chapter_impact.yaml")
    failures = []
    with tempfile.TemporaryDirectory() as tmp:
        good = os.path.join(tmp, "events.csv")
        with open(good, "w") as f:
            f.write("name,time_s\nliftoff_lateral,0.216\n")
        bad = os.path.join(tmp, "bad.csv")
        with open(bad, "w") as f:
            f.write("name,time_s\nliftoff_lateral,soon\n")
        check = [PY, os.path.join(EXAMPLES, "check_liftoff.py")]
        failures += [expect_refused(check + [bad, reference, "6"], "time_s = 'soon'"),
                     expect_refused(check + [tmp, reference, "6"], "EVENTS.csv"),
                     expect_refused(check + [good, "/dev/null", "6"], "REFERENCE.json"),
                     expect_refused(check + [good, reference, "nan"], "MIN_DIGITS = nan"),
                     expect_refused(check, "required")]
        out = os.path.join(tmp, "scipy_out")
        scipy = [PY, os.path.join(EXAMPLES, "python", "scipy_on_the_knee.py"), "--out", out]
        failures += [expect_refused(scipy + ["--dt", "0"], "--dt = 0.0", out),
                     expect_refused(scipy + ["--dt", "nan"], "--dt = nan", out),
                     expect_refused(scipy + ["--rtol", "-1"], "--rtol = -1.0", out),
                     expect_refused(scipy + ["--scene", "/nonexistent.yaml"], "/nonexistent.yaml", out),
                     expect_refused(scipy + ["--kneedyn", "/nonexistent"], "--kneedyn = '/nonexistent'", out)]
        remove = [PY, os.path.join(EXAMPLES, "python", "remove_acl.py")]
        failures.append(expect_refused(remove + ["--out", "/proc/kneedyn/remove_acl"], "--out = '/proc/kneedyn"))
        rk4_out = os.path.join(tmp, "rk4_out")
        os.makedirs(rk4_out)
        for step in ["nan", "inf", "1e-30", "0", "abc"]:
            failures.append(expect_refused([rk4, scene, step, rk4_out], f"STEP_S = '{step}'"))
        if os.listdir(rk4_out):
            failures.append(f"rk4_on_the_knee wrote {os.listdir(rk4_out)} when refusing")
    failures = [f for f in failures if f]
    return finish(failures, "FAILED:", f"example_inputs: {len(failures)} failure(s)")


if __name__ == "__main__":
    sys.exit(main())
