#!/usr/bin/env python3
"""The Python tools' input contract (reports/tool_input.py; the exit codes in README.md): bad
arguments and malformed files are refused before any run, with exit 2, a message naming the
argument and its value, no traceback, and nothing written. Planted cases for
global_sensitivity.py, claim_verdicts.py, inverse_problem.py, patella_coupling.py and
benchmarks/scipy_side_by_side.py, and the shared checks themselves. An external program that
fails (fake valgrind, callgrind_annotate and kneedyn first on PATH or as --kneedyn, exiting 3)
is a failed run: exit 1, one line naming the command, its exit code and the last lines of its
stderr, no traceback, no output file (benchmarks/efficiency.py, reports/patella_section.py).

    tool_inputs_test.py KNEEDYN KNEEDYN_INVERSE
"""
import os
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
sys.path.insert(0, os.path.join(ROOT, "reports"))
import tool_input  # noqa: E402
from py_test_support import finish  # noqa: E402

PY = sys.executable


def refused(cmd, must_name, out=None):
  r = subprocess.run([PY] + cmd, capture_output=True, text=True, timeout=120, cwd=ROOT)
  problems = [p for p, bad in ((f"exit {r.returncode}", r.returncode != 2),
                               (f"no {must_name!r} in stderr", must_name not in r.stderr),
                               ("a traceback", "Traceback" in r.stderr),
                               (f"{out} created", out is not None and os.path.exists(out))) if bad]
  return f"{' '.join(cmd)}: {', '.join(problems)}: {r.stderr.strip()[-300:]}" if problems else ""


def failed_run(cmd, must_names, out=None, path=None, one_line=True):
  """cmd with the directory `path` first on PATH: exit 1 (a failed run, not bad input), each of
  must_names in stderr (on its one line when one_line), no traceback, `out` not created."""
  env = dict(os.environ, PATH=path + os.pathsep + os.environ.get("PATH", "")) if path else None
  r = subprocess.run([PY] + cmd, capture_output=True, text=True, timeout=300, cwd=ROOT, env=env)
  lines = [line for line in r.stderr.splitlines() if line.strip()]
  problems = [p for p, bad in ((f"exit {r.returncode}", r.returncode != 1),
                               *((f"no {n!r} in stderr", n not in r.stderr) for n in must_names),
                               (f"{len(lines)} lines on stderr", one_line and len(lines) != 1),
                               ("a traceback", "Traceback" in r.stderr),
                               (f"{out} created", out is not None and os.path.exists(out))) if bad]
  return f"{' '.join(cmd)}: {', '.join(problems)}: {r.stderr.strip()[-300:]}" if problems else ""


def main():
  kneedyn, inverse = sys.argv[1], sys.argv[2]
  failures = []
  with tempfile.TemporaryDirectory() as tmp:
    out = os.path.join(tmp, "out")
    def write(name, text):
      path = os.path.join(tmp, name)
      os.makedirs(os.path.dirname(path), exist_ok=True)
      with open(path, "w") as f:
        f.write(text)
      return path
    spec_words = write("spec_words.yaml", "design: {type: saltelli, samples: ten}\nparameters: [a]\n")
    spec_list = write("spec_list.yaml", "- a\n")
    spec = write("spec.yaml", "design: {type: saltelli, samples: 2}\nparameters: [a]\n")
    # samples: 2.0 is 2, as kneedyn sweep reads it: past the spec, the bad sweep is refused.
    spec_float = write("spec_float.yaml", "design: {type: saltelli, samples: 2.0}\nparameters: [a]\n")
    sweep_nostatus = write("nostatus.csv", "index,a,y\n0,1,2\n")
    sweep_text = write("text.csv", "index,a,y,status\n0,x,2,completed\n")
    gs = ["reports/global_sensitivity.py", "--out", out]
    failures += [refused(gs + ["--spec", spec_words, "--sweep", sweep_text], "design.samples", out),
                 refused(gs + ["--spec", spec_list, "--sweep", sweep_text], "not a sweep spec", out),
                 refused(gs + ["--spec", tmp, "--sweep", sweep_text], "--spec", out),
                 refused(gs + ["--spec", spec, "--sweep", sweep_nostatus], "'status'", out),
                 refused(gs + ["--spec", spec, "--sweep", sweep_text], "--sweep", out),
                 refused(gs + ["--spec", spec_float, "--sweep", sweep_text], "--sweep", out),
                 refused(gs + ["--spec", spec, "--sweep", sweep_text, "--bootstrap", "99999999999"], "--bootstrap", out),
                 refused(gs + ["--spec", spec, "--sweep", sweep_text, "--seed", "-1"], "--seed", out)]
    report = os.path.join(tmp, "report")
    write("report/claims.json", '{"claims": [')
    write("report/reconstruction/reconstruction.json", "[]")
    cv_out = os.path.join(tmp, "claims_out.json")
    cv = ["reports/claim_verdicts.py", "--report", report, "--out", cv_out]
    failures += [refused(cv, "claims.json", cv_out),
                 refused(cv + ["--runtime-s", "nan"], "--runtime-s = nan", cv_out),
                 refused(cv + ["--run-study", "/bin/true"], "--run-study = '/bin/true'", cv_out),
                 refused(["reports/claim_verdicts.py", "--report", report, "--out", "/proc/kneedyn/c.json"], "--out")]
    scene = os.path.join(ROOT, "reference-data", "scenes", "chapter_impact.yaml")
    ip = ["reports/inverse_problem.py", "--inverse", inverse, "--kneedyn", kneedyn, "--scenes", scene, "--out", out]
    failures += [refused(ip + ["--max-iterations", "-1"], "--max-iterations = -1", out),
                 refused(ip + ["--record", "/proc/kneedyn/i.json"], "--record", out),
                 refused(ip[:-1] + ["/proc/kneedyn/out"], "--out")]
    pc = ["reports/patella_coupling.py", "--kneedyn", kneedyn, "--out", out]
    failures += [refused(pc + ["--scene", "/dev/null"], "--scene = '/dev/null'", out),
                 refused(["reports/patella_coupling.py", "--kneedyn", "/bin/true", "--out", out], "--kneedyn", out)]
    ss = ["benchmarks/scipy_side_by_side.py", "--quick"]
    failures += [refused(ss + ["--repeats", "0"], "--repeats = 0"),
                 refused(ss + ["--check-digits", "nan"], "--check-digits = nan"),
                 refused(ss + ["--json", "/proc/kneedyn/s.json"], "--json")]
    # A failed external command: exit 1 naming it, not a CalledProcessError traceback.
    def fake(directory, name, script):
      path = write(os.path.join(directory, name), "#!/bin/sh\n" + script)
      os.chmod(path, 0o755)
      return path
    fake("valgrind_fails", "valgrind", "echo '==1== fake valgrind: starting' >&2\n"
                                       "echo 'fake valgrind: no such tool' >&2\nexit 3\n")
    fake("annotate_fails", "valgrind", "exit 0\n")
    fake("annotate_fails", "callgrind_annotate", "echo 'fake callgrind_annotate: cannot read the profile' >&2\nexit 3\n")
    fake_kneedyn = fake("kneedyn_fails", "kneedyn",
                        'case "$1" in\n  --version) echo "kneedyn 0.0.0 (fake)";;\n'
                        '  formulations) echo "fake kneedyn: no registry" >&2; exit 3;;\n'
                        '  *) echo "fake kneedyn: $1 is not run here" >&2; exit 1;;\nesac\n')
    # instruction_sweep: a run that cannot be scored ends the sweep without running the queued
    # configurations (the with block waited for all of them). The fake valgrind counts its runs.
    count = os.path.join(tmp, "valgrind_runs")
    fake("valgrind_counts", "valgrind", f"echo run >> '{count}'\necho '==1== Collected : 5' >&2\nexit 0\n")
    isw_json = os.path.join(tmp, "isweep.json")
    isw = ["benchmarks/instruction_sweep.py", "--kneedyn", kneedyn, "--only", "dae", "--jobs", "1", "--json", isw_json]
    failures.append(failed_run(isw, ["kneedyn score", "(scoring kneedyn run"], isw_json,
                               os.path.join(tmp, "valgrind_counts")))
    runs = len(open(count).read().split()) if os.path.exists(count) else 0
    if runs > 2:  # the failing one, and at most one the single worker had already started
      failures.append(f"instruction_sweep.py ran {runs} configurations after the first failed to be scored")
    eff_json = os.path.join(tmp, "efficiency.json")
    eff = ["benchmarks/efficiency.py", "--kneedyn", kneedyn, "--only", "dae", "--json", eff_json]
    ps = ["reports/patella_section.py", "--kneedyn", fake_kneedyn, "--out", os.path.join(tmp, "ps"), "--quick"]
    failures += [failed_run(eff, ["`valgrind --tool=callgrind", "exited 3", "fake valgrind: no such tool"], eff_json,
                            os.path.join(tmp, "valgrind_fails")),
                 failed_run(eff, ["`callgrind_annotate --inclusive=yes", "exited 3",
                                  "fake callgrind_annotate: cannot read the profile"], eff_json,
                            os.path.join(tmp, "annotate_fails")),
                 failed_run(ps, ["formulations` exited 3", "fake kneedyn: no registry"])]
    # The shared checks.
    failed = tool_input.command_failed(["prog", "a b"], 3, "one\n\ntwo\nthree\nfour\n")
    if str(failed) != "`prog 'a b'` exited 3: two | three | four":
      failures.append(f"command_failed(): {failed} (not the command, exit code and last three lines)")
    try:  # a program that cannot start is a failed run too, not an OSError traceback
      tool_input.run_command([os.path.join(tmp, "no_such_program")])
      failures.append("run_command(): a missing program ran")
    except tool_input.CommandFailed as e:
      if "no_such_program` could not run" not in str(e):
        failures.append(f"run_command(): {e} (does not name the program)")
    for check, args, name in ((tool_input.output_directory, ("--out", "/proc/kneedyn/x"), "--out"),
                              (tool_input.output_directory, ("--out", spec), "an existing file"),
                              (tool_input.output_file, ("--json", tmp), "a directory"),
                              (tool_input.kneedyn_executable, ("--kneedyn", "/bin/true"), "not the kneedyn program"),
                              (tool_input.kneedyn_executable, ("--kneedyn", tmp), "a directory"),
                              (tool_input.json_object, ("--bench", spec_list), "not a file this tool reads"),
                              (tool_input.json_object, ("--bench", write("deep.json", "[" * 200000 + "]" * 200000)),
                               "nested too deep"),  # a RecursionError traceback before
                              (tool_input.number, ("--n", float("nan"), 0.0), "--n = nan")):
      try:
        check(*args)
        failures.append(f"{check.__name__}{args}: accepted")
      except tool_input.BadInput as e:
        if name not in str(e):
          failures.append(f"{check.__name__}{args}: {e} (does not say {name!r})")
    try:
      tool_input.kneedyn_executable("--kneedyn", kneedyn)
      tool_input.output_directory("--out", os.path.join(tmp, "new", "deeper"))
    except tool_input.BadInput as e:
      failures.append(f"a valid kneedyn or a creatable directory refused: {e}")
    if any(n.startswith(".kneedyn-probe-") for n in os.listdir(tmp)):
      failures.append("a probe directory was left behind")
  failures = [f for f in failures if f]
  return finish(failures, "FAILED:", f"tool_inputs: {len(failures)} failure(s)")


if __name__ == "__main__":
  sys.exit(main())
