#!/usr/bin/python3
"""benchmarks/choose_targets.py: run_targets.cpp's configurations follow the rule its header
states, on the recorded sweep and instruction sweep; and the rule itself on a planted sweep
whose expected choices are worked out by hand below (a scatter dip and a failed run inside
the five-rtol window, a method cheaper in CPU time but dearer in instructions, a stabilized
and a fixed-step method that run_targets cannot express), with the check's exit codes (a
wrong table 1; bad input 2, among it an instruction sweep whose runs took other steps).
"""
import contextlib
import io
import json
import math
import os
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.dont_write_bytecode = True
sys.path.insert(0, os.path.join(ROOT, "benchmarks"))
sys.path.insert(0, os.path.join(ROOT, "tests"))
sys.path.insert(0, os.path.join(ROOT, "reports"))
from bench_data import normalize_result  # noqa: E402
from py_test_support import finish  # noqa: E402
import choose_targets  # noqa: E402

GRID = [10 ** (-k / 4) for k in range(20, 45)]  # rtol 1e-5 … 1e-11, quarter decades


def run(formulation, integrator, rtol, scd, cpu_s, status="ok", stabilization=None, step=None):
  setting = {"step": step} if step else {"rtol": rtol, "atol": rtol / 100}
  if stabilization:
    setting["stabilization"] = stabilization
  return {"formulation": formulation, "integrator": integrator, "setting": setting, "status": status,
          "reason": "" if status == "ok" else "IDA_CONV_FAIL",
          "metrics": {"scd": scd, "event_time_error_s": {"liftoff_lateral": 1e-9}},
          "cpu_time_s": {"median": cpu_s}, "counters": {"steps": 100},
          "events": [{"name": "liftoff_lateral", "time_s": 0.2}]}


def planted_runs():
  """Three methods on GRID (k = 20 … 44, rtol = 10^(−k/4)), scd = k/4 − 1 unless stated:
    ede:adams  first reaches 8 at k = 36, but k = 36 reads 7.9 (a scatter dip): the rule's run
               for scd 8 is k = 37 (its window k = 37 … 41, scd 8.25 … 9.25);
    ede:rk     scd = k/4 − 1.25 (8 first at k = 37, window from k = 37); CPU time half of
               adams's at every rtol, instructions twice: among both, adams at k = 37 wins;
    dae        scd = k/4 − 1.75 reaches 6 at k = 31, but k = 33 failed: the rule's run for
               scd 6 is k = 34; scd 9 (k ≥ 43) has no five rtols on the grid.
  Plus ede:adams/projection (cheapest of all) and newmark with fixed steps: neither is a
  candidate. Returns (sweep results, instruction results)."""
  sweep, instructions = [], []
  for k, rtol in zip(range(20, 45), GRID):
    for form, integ, scd, cpu, ins in (("ede", "adams", 7.9 if k == 36 else k / 4 - 1, 2.0, 1e6),
                                       ("ede", "rk", k / 4 - 1.25, 1.0, 2e6),
                                       ("dae", "", k / 4 - 1.75, 3.0, 3e6)):
      status = "failed" if (form == "dae" and k == 33) else "ok"
      r = run(form, integ, rtol, scd if status == "ok" else 0.0, cpu * 1e-3, status)
      sweep.append(r)
      instructions.append(dict(r, instructions={"run_scene": int(ins * (1 + k / 100))}))
    r = run("ede", "adams", rtol, k / 4, 1e-5, stabilization="projection")
    sweep.append(r)
    instructions.append(dict(r, instructions={"run_scene": 1000}))
  for h in (1e-3, 5e-4):
    r = run("newmark", "", None, 12.0, 1e-6, step=h)
    sweep.append(r)
    instructions.append(dict(r, instructions={"run_scene": 10}))
  return sweep, instructions


def cpp_table(entries):
  rows = "\n".join(f'    {{"target/{n}", Config("{f}", "{i}", {rtol!r}), {scd}, "{among}"}},'
                   for n, f, i, rtol, scd, among in entries)
  return f"const Target kTargets[] = {{\n{rows}\n}};\n"


def main():
  errors = []

  def check(cond, what):
    if not cond:
      errors.append(what)

  def call(args):
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
      code = choose_targets.main(args)
    return code, out.getvalue(), err.getvalue()

  # The repository's table follows the rule on the recorded files.
  code, out, err = call([])
  check(code == 0, f"run_targets.cpp does not follow the rule on the recorded sweep (exit {code}): {err.strip()} "
                   f"— re-choose with benchmarks/choose_targets.py")
  targets = choose_targets.read_targets(os.path.join(ROOT, "benchmarks/run_targets.cpp"))
  check({t["name"] for t in targets} == {"target/dae_scd6", "target/best_scd8", "target/ede_dopri5_scd8"},
        f"run_targets.cpp's targets read as {[t['name'] for t in targets]}")

  sweep, instructions = planted_runs()
  runs, counted = [normalize_result(r) for r in sweep], [normalize_result(r) for r in instructions]
  def name(pick):  # (formulation, integrator, k of rtol = 10^(−k/4))
    return pick[0]["formulation"], pick[0]["integrator"], round(-4 * math.log10(pick[0]["setting"]["rtol"]))
  adams = choose_targets.choose(runs, counted, "ede:adams", 8.0)
  check(adams and name(adams) == ("ede", "adams", 37), f"ede:adams at scd 8: {adams and name(adams)} (want k = 37)")
  check(adams and adams[2] == (8.25, 9.25), f"ede:adams window scd range {adams and adams[2]} (want 8.25–9.25)")
  rk = choose_targets.choose(runs, counted, "ede:rk", 8.0)
  check(rk and name(rk) == ("ede", "rk", 37), f"ede:rk at scd 8: {rk and name(rk)} (want k = 37)")
  best = choose_targets.choose(runs, counted, "", 8.0)
  check(best and name(best) == ("ede", "adams", 37),
        f"every method at scd 8: {best and name(best)} (want ede adams k = 37: fewest instructions; "
        f"rk is cheaper in CPU time, the projection method is not a candidate)")
  dae = choose_targets.choose(runs, counted, "dae", 6.0)
  check(dae and name(dae) == ("dae", "", 34), f"dae at scd 6: {dae and name(dae)} (want k = 34, after the failed k = 33)")
  check(choose_targets.choose(runs, counted, "dae", 9.0) is None, "dae reaches scd 9 at five rtols?")

  with tempfile.TemporaryDirectory() as tmp:
    paths = {}
    for label, data in (("sweep", sweep), ("instructions", instructions)):
      paths[label] = os.path.join(tmp, label + ".json")
      with open(paths[label], "w") as f:
        json.dump({"header": {}, "results": data}, f)
    cpp = os.path.join(tmp, "run_targets.cpp")
    files = ["--sweep", paths["sweep"], "--instructions", paths["instructions"], "--check", cpp]
    k37, k36 = GRID[17], GRID[16]
    with open(cpp, "w") as f:
      f.write(cpp_table([("a_scd8", "ede", "adams", k37, 8.0, "ede:adams"), ("best_scd8", "ede", "adams", k37, 8.0, ""),
                         ("dae_scd6", "dae", "", GRID[14], 6.0, "dae")]))
    code, out, err = call(files)
    check(code == 0, f"a table that follows the rule: exit {code}, {err.strip()}")
    check(out.count("target/") == 3, f"three choices printed: {out!r}")
    # The loosest rtol reaching scd 8 (k = 36), not the rule's: refused, naming both rtols.
    with open(cpp, "w") as f:
      f.write(cpp_table([("a_scd8", "ede", "adams", k36, 8.0, "ede:adams")]))
    code, out, err = call(files)
    check(code == 1 and "target/a_scd8" in err and f"{k36:.17g}" in err and f"{k37:.17g}" in err,
          f"a wrong rtol: exit {code}, {err.strip()!r}")
    # Chosen by CPU time (rk) instead of instructions: refused.
    with open(cpp, "w") as f:
      f.write(cpp_table([("best_scd8", "ede", "rk", k37, 8.0, "")]))
    code, _, err = call(files)
    check(code == 1 and "ede rk" in err and "ede adams" in err, f"chosen by CPU time: exit {code}, {err.strip()!r}")
    # Bad input: exit 2.
    with open(cpp, "w") as f:
      f.write("const Target kTargets[] = {};\n")
    code, _, err = call(files)
    check(code == 2 and "no entry" in err, f"no targets in the table: exit {code}, {err.strip()!r}")
    with open(cpp, "w") as f:
      f.write(cpp_table([("x_scd8", "ede", "adams", k37, 8.0, "ede:nonesuch")]))
    code, _, err = call(files)
    check(code == 2 and "ede:nonesuch" in err, f"an unknown method: exit {code}, {err.strip()!r}")
    with open(paths["instructions"], "w") as f:
      json.dump({"header": {}, "results": [r for r in instructions if r["integrator"] != "rk"]}, f)
    with open(cpp, "w") as f:
      f.write(cpp_table([("best_scd8", "ede", "adams", k37, 8.0, "")]))
    code, _, err = call(files)
    check(code == 2 and "ede:rk" in err, f"a competing run without an instruction count: exit {code}, {err.strip()!r}")
    # An instruction sweep of another recording (one chosen run took other steps): refused.
    stale = [dict(r, counters={"steps": 101}) if r["integrator"] == "adams" else r for r in instructions]
    with open(paths["instructions"], "w") as f:
      json.dump({"header": {}, "results": stale}, f)
    code, _, err = call(files)
    check(code == 2 and "re-record" in err and "101" in err, f"a stale instruction sweep: exit {code}, {err.strip()!r}")
    with open(paths["sweep"], "w") as f:
      f.write("{not json")
    code, _, err = call(files)
    check(code == 2 and "not JSON" in err, f"a sweep that is not JSON: exit {code}, {err.strip()!r}")
  return finish(errors, "FAIL:", f"run_targets choice: {len(errors)} failure(s)")


if __name__ == "__main__":
  sys.exit(main())
