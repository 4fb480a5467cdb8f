#!/usr/bin/python3
"""benchmarks/instruction_sweep.py on a planted three-configuration sweep, and
work_precision_table.py --cost on planted results.

  instruction_sweep_test.py KNEEDYN

Validates:
  - determinism, the reason for the axis: one configuration listed twice (ede dopri5, rtol
    1e-4) gives the same RunScene instruction count to the instruction and the same scd;
  - the count is RunScene's: above zero (the toggle names a function the program has) and
    below the whole process's count of the same command under callgrind without the toggle;
  - a failing configuration (ede euler, step 0.004 s: diverged, CheckSampleIsPhysical at
    t ≈ 0.093 s) is recorded as failed with the solver's reason, not scored;
  - the report's Pareto overlay on instructions (reports/figures.py) takes the
    instruction-cheapest runs as the front and counts a wrong-event run as a failure, and
    draws nothing for a file without counts;
  - the table picks each cell by the cost asked for: planted runs whose CPU times and
    instruction counts order the other way round give the CPU-cheapest run under --cost cpu
    and the instruction-cheapest under --cost instructions (expected cells typed in from the
    planted numbers); a file without instruction counts is refused with exit 2.
Does not validate: the counts' values (callgrind's), the scd (kneedyn score's own tests).
Exit 77 (skipped) without valgrind.
"""
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.dont_write_bytecode = True
from py_test_support import finish  # noqa: E402

SCENE = os.path.join(ROOT, "reference-data", "scenes", "chapter_impact.yaml")


def planted_run(formulation, integrator, rtol, cpu, instructions=None, scd=7.0):
  r = {"formulation": formulation, "integrator": integrator, "setting": {"rtol": rtol, "atol": rtol / 100},
       "status": "ok", "reason": "", "cpu_time_s": {"median": cpu},
       "metrics": {"scd": scd, "event_time_error_s": {"liftoff_lateral": 1e-9}},
       "events": [{"name": "liftoff_lateral", "time_s": 0.2163}]}
  if instructions is not None:
    r["instructions"] = {"run_scene": instructions}
  return r


def table(path, *extra):
  return subprocess.run([sys.executable, os.path.join(ROOT, "benchmarks", "work_precision_table.py"), path,
                         *extra], capture_output=True, text=True)


def check_table(tmp, errors):
  # CPU: A cheaper; instructions: B cheaper. Both reach scd 6.
  path = os.path.join(tmp, "planted_costs.json")
  with open(path, "w") as f:
    json.dump({"header": {}, "results": [planted_run("ede", "dopri5", 1e-6, 0.002, 30_000_000),
                                         planted_run("ede", "dopri5", 1e-7, 0.003, 20_000_000)]}, f)
  cpu, ins = table(path), table(path, "--cost", "instructions")
  if "| 2 (rtol=1e-06) |" not in cpu.stdout:
    errors.append(f"--cost cpu: expected the cell '2 (rtol=1e-06)' (CPU ms):\n{cpu.stdout}{cpu.stderr}")
  if "| 20.0 M (rtol=1e-07) |" not in ins.stdout:
    errors.append(f"--cost instructions: expected the cell '20.0 M (rtol=1e-07)':\n{ins.stdout}{ins.stderr}")
  with open(path, "w") as f:
    json.dump({"header": {}, "results": [planted_run("ede", "dopri5", 1e-6, 0.002)]}, f)
  refused = table(path, "--cost", "instructions")
  if refused.returncode != 2 or "no instruction counts" not in refused.stderr:
    errors.append(f"a file without counts: exit {refused.returncode}, stderr {refused.stderr!r} (expected 2)")


def check_figure(tmp, errors):
  """The report's instruction Pareto overlay on planted runs: ede's front is the two
  instruction-cheapest runs (CPU times order them the other way); a wrong-event run is
  on no front and counted in the title."""
  sys.path.insert(0, os.path.join(ROOT, "reports"))
  import bench_data  # noqa: E402
  import figures  # noqa: E402
  from PIL import Image
  late = planted_run("ede", "rk4", 1e-5, 0.0005, 5_000_000, scd=3.0)
  late["metrics"]["event_time_error_s"] = {"liftoff_lateral": 0.01}  # 10 ms late: a wrong event
  runs = [planted_run("ede", "dopri5", 1e-6, 0.002, 30_000_000, scd=6.5),
          planted_run("ede", "dopri5", 1e-7, 0.003, 20_000_000, scd=6.8),
          planted_run("ede", "dopri5", 1e-5, 0.001, 10_000_000, scd=4.0), late]
  path = os.path.join(tmp, "planted_instructions.json")
  with open(path, "w") as f:
    json.dump({"header": {"scene": "chapter_impact", "scd_ceiling": 11.2}, "results": runs}, f)
  _, loaded = bench_data.load_bench(path)
  front = [(r["scd"], r["instructions"]) for r in bench_data.pareto_front(loaded, cost="instructions")]
  if front != [(4.0, 10_000_000), (6.8, 20_000_000)]:
    errors.append(f"Pareto front by instructions: {front} (expected scd 4.0 at 10 M, 6.8 at 20 M)")
  name = figures.make_instruction_pareto(os.path.join(tmp, "report"), path)
  if name != "work_precision_pareto_instructions.png":
    errors.append(f"make_instruction_pareto wrote {name}")
    return
  with Image.open(os.path.join(tmp, "report", "figures", name)) as im:
    title, panels = im.text.get("Title", ""), im.text.get("Description", "").splitlines()
  if "on instructions" not in title or "3 runs are results; 1 failed or wrong event" not in title:
    errors.append(f"instruction Pareto title: {title!r}")
  if panels != ["ede  (1 failed / wrong event)"]:
    errors.append(f"instruction Pareto legend titles: {panels}")
  with open(path, "w") as f:
    json.dump({"header": {}, "results": [planted_run("ede", "dopri5", 1e-6, 0.002)]}, f)
  if figures.make_instruction_pareto(os.path.join(tmp, "report2"), path) is not None:
    errors.append("make_instruction_pareto drew a file without instruction counts")


def main():
  if len(sys.argv) != 2:
    print("usage: instruction_sweep_test.py KNEEDYN", file=sys.stderr)
    return 2
  kneedyn = os.path.abspath(sys.argv[1])
  errors = []
  with tempfile.TemporaryDirectory() as tmp:
    check_table(tmp, errors)
    check_figure(tmp, errors)
    if shutil.which("valgrind") is None:
      print("instruction_sweep_test: valgrind not found: the sweep part skipped")
      return 77
    sweep = os.path.join(tmp, "sweep.json")
    diverging = planted_run("ede", "euler", 0.0, 0.001)
    diverging["setting"] = {"step": 0.004}
    configs = [planted_run("ede", "dopri5", 1e-4, 0.001), diverging, planted_run("ede", "dopri5", 1e-4, 0.001)]
    with open(sweep, "w") as f:
      json.dump({"header": {"scene": "chapter_impact"}, "results": configs}, f)
    out = os.path.join(tmp, "isweep.json")
    p = subprocess.run([sys.executable, os.path.join(ROOT, "benchmarks", "instruction_sweep.py"), "--kneedyn",
                        kneedyn, "--sweep", sweep, "--jobs", "2", "--json", out], capture_output=True, text=True)
    if p.returncode != 0:
      errors.append(f"instruction_sweep.py exited {p.returncode}: {p.stderr}")
      return finish(errors, "instruction_sweep_test: FAIL", "instruction_sweep_test: failed")
    with open(out) as f:
      results = json.load(f)["results"]
    first, failing, again = results
    n = first["instructions"]["run_scene"]
    if n != again["instructions"]["run_scene"]:
      errors.append(f"the same configuration twice: {n} and {again['instructions']['run_scene']} instructions")
    if first["metrics"]["scd"] != again["metrics"]["scd"]:
      errors.append(f"the same configuration twice: scd {first['metrics']['scd']} and {again['metrics']['scd']}")
    if first["status"] != "ok" or not isinstance(first["metrics"]["scd"], float):
      errors.append(f"ede dopri5 rtol 1e-4: status {first['status']}, scd {first['metrics'].get('scd')}")
    whole = subprocess.run(["valgrind", "--tool=callgrind", "--callgrind-out-file=/dev/null", kneedyn, "run", SCENE,
                            "--formulation", "ede", "--integrator", "dopri5", "--rtol", "0.0001", "--atol", "1e-06",
                            "--quiet", "--out", os.path.join(tmp, "whole")], capture_output=True, text=True)
    m = re.search(r"Collected\s*:\s*(\d+)", whole.stderr)
    total = int(m.group(1)) if m else None
    if not (isinstance(n, int) and total is not None and 0 < n < total):
      errors.append(f"RunScene's count {n} is not within (0, whole process {total})")
    if failing["status"] != "failed" or "CheckSampleIsPhysical" not in failing.get("reason", ""):
      errors.append(f"ede euler step 0.004: status {failing['status']}, reason {failing.get('reason')!r} "
                    "(expected failed, CheckSampleIsPhysical)")
    summary = (f"instruction_sweep_test: ede dopri5 rtol 1e-4 twice: {n} instructions in RunScene "
               f"(whole process {total}), scd {first['metrics'].get('scd')}; ede euler step 0.004: {failing['status']}")
  return finish(errors, "instruction_sweep_test: FAIL", summary)


if __name__ == "__main__":
  sys.exit(main())
