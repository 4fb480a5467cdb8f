#!/usr/bin/python3
"""The work-precision sweep on a cost axis that does not drift: every configuration of a
sweep file run once by the `kneedyn` program under callgrind, its cost the instructions of
`RunScene` (consistent initialization, every phase and restart, the output samples: what
the sweep's in-process CPU time covers; no start-up, loading or files), its accuracy that
same run's trajectory scored by `kneedyn score` (benchmarks/README.md, "Work-precision
sweep").

    /usr/bin/python3 benchmarks/instruction_sweep.py --kneedyn build/formulations/kneedyn \
        [--sweep benchmarks/recorded/work_precision_chapter_impact.json] [--only SUBSTR] \
        [--scene SCENE.yaml] [--jobs 2] --json OUT.json
    /usr/bin/python3 benchmarks/work_precision_table.py OUT.json --cost instructions

CPU times of one configuration drift by tens of per cent between recordings on a shared
machine; these counts repeat to the instruction for a given binary (the determinism is
tested: tests/instruction_sweep_test.py), so two commits compare cell by cell. Each run is
`valgrind --tool=callgrind --toggle-collect='kneedyn::RunScene(*' kneedyn run SCENE
--formulation F [--integrator I] --rtol R --atol A | --step H [--stabilization S] --quiet
--out TMP` (the command efficiency.py runs) on --scene (default: reference-data/scenes/<the
sweep header's scene>.yaml); callgrind's "Collected" is the count. The run is
the CLI's, with the scene's output interval, so a method that stops at output times (the
ARKODE ones) may take a step or two more or fewer than the sweep's in-process run of the same
setting: the scd recorded here is this run's own.

OUT holds {"header": {...}, "results": [...]}: each result is kneedyn score's entry for the
run (metrics, events), with the configuration's formulation, integrator and setting, its
summary.json statistics as counters, status "ok", and "instructions": {"run_scene": N}; a
run that fails (nonzero exit) has status "failed", its reason and its count; a completed run
that `kneedyn score` cannot score stops the sweep (exit 1, one line naming the command, OUT not
written). reports/bench_data.py reads it as it reads a sweep. Progress goes to stderr. About
20 min on two cores for the recorded sweep's 780 configurations (valgrind slows a run ~50
times).
"""
import argparse
import concurrent.futures
import datetime
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time

sys.dont_write_bytecode = True  # keep the source tree clean
ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "reports"))
sys.path.insert(0, os.path.join(ROOT, "benchmarks"))
from bench_data import load_bench, method_of  # noqa: E402
from efficiency import command_of  # noqa: E402
import tool_input  # noqa: E402
from tool_input import BadInput  # noqa: E402

COLLECTED = re.compile(r"Collected\s*:\s*(\d+)")


def measure(run, kneedyn, scene):
  """One configuration: its results entry (see the module's docstring)."""
  with tempfile.TemporaryDirectory(prefix="kneedyn_isweep_") as tmp:
    out = os.path.join(tmp, "out")
    cmd = ["valgrind", "--tool=callgrind", "--callgrind-out-file=/dev/null",
           "--toggle-collect=kneedyn::RunScene(*"] + command_of(run, kneedyn, scene, out)
    p = subprocess.run(cmd, capture_output=True, text=True)
    m = COLLECTED.search(p.stderr)
    entry = {"formulation": run["formulation"], "integrator": run.get("integrator") or "",
             "setting": run.get("setting") or {},
             "instructions": {"run_scene": int(m.group(1)) if m else None},
             "command": " ".join(command_of(run, "kneedyn", os.path.relpath(scene, ROOT), "TMP"))}
    summary_path = os.path.join(out, "summary.json")
    summary = None
    if os.path.exists(summary_path):
      with open(summary_path, encoding="utf-8") as f:
        summary = json.load(f)
      entry["counters"] = summary.get("statistics") or {}
      entry["events"] = [{"name": e["name"], "time_s": e["time"]} for e in summary.get("events") or []]
    if p.returncode != 0 or m is None:
      # summary.json's failure (a partial run), else kneedyn's own message (input errors).
      messages = [l for l in p.stderr.splitlines() if l.startswith("kneedyn")] or ["no output"]
      entry.update(status="failed", reason=(summary or {}).get("failure") or messages[-1], metrics={"scd": None})
      return entry
    # A completed run that cannot be scored stops the sweep (exit 1, nothing written).
    try:
      tool_input.run_command([kneedyn, "score", "--scene", scene, "--events", summary_path,
                              os.path.join(out, "trajectory.csv")])
    except tool_input.CommandFailed as e:
      raise tool_input.CommandFailed(f"{e} (scoring {entry['command']})") from None
    score_path = os.path.join(out, "trajectory.score.json")
    if not os.path.exists(score_path):
      raise tool_input.CommandFailed(f"kneedyn score wrote no {os.path.basename(score_path)} for {entry['command']}")
    with open(score_path, encoding="utf-8") as f:
      score = json.load(f)
    scored = score["results"][0]
    entry.update(status="ok", reason="", metrics=scored["metrics"])
    entry["_score_header"] = score.get("header") or {}
    return entry


def report_progress(done, todo, i, e, start):
  """One line on stderr for the done-th finished configuration (todo[i], its entry e)."""
  elapsed = time.monotonic() - start
  n = e["instructions"]["run_scene"]
  scd = (e.get("metrics") or {}).get("scd")
  print(f"{done}/{len(todo)} {method_of(todo[i])} {e['setting']}: "
        f"{'?' if n is None else f'{n / 1e6:.2f} M'}, {e['status']}"
        + (f", scd {scd:.2f}" if isinstance(scd, (int, float)) else "")
        + f" ({elapsed:.0f} s, about {elapsed / done * (len(todo) - done):.0f} s left)", file=sys.stderr)


def main(argv=None):
  ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
  ap.add_argument("--kneedyn", required=True, help="the kneedyn program to measure")
  ap.add_argument("--sweep", default=os.path.join(ROOT, "benchmarks/recorded/work_precision_chapter_impact.json"),
                  help="the sweep whose configurations to run (default: the recorded one)")
  ap.add_argument("--scene", default=None, help="default: the sweep header's scene")
  ap.add_argument("--only", default="", help="only methods whose name contains this")
  ap.add_argument("--jobs", type=int, default=2, help="runs at once (default 2)")
  ap.add_argument("--json", required=True, help="output file")
  a = ap.parse_args(argv)
  if a.jobs < 1:
    raise BadInput(f"--jobs = {a.jobs}: must be at least 1")
  tool_input.output_file("--json", a.json)
  header, runs = tool_input.checked(load_bench, "--sweep", a.sweep)
  name = os.path.splitext(os.path.basename(str(header.get("scene") or "chapter_impact")))[0]
  scene = os.path.abspath(tool_input.existing_file("--scene" if a.scene else "the sweep header's scene",
                                                   a.scene or os.path.join(ROOT, "reference-data/scenes",
                                                                           name + ".yaml")))
  # Outside solvers' results (`work_precision --include`) are not kneedyn's to run.
  todo = [r for r in runs if r.get("origin", "kneedyn") == "kneedyn" and a.only in method_of(r)]
  if not todo:
    raise BadInput(f"--only = '{a.only}': no configuration of '{a.sweep}' matches")
  if shutil.which("valgrind") is None:
    raise BadInput("valgrind not found (apt-get install valgrind)")
  tool_input.kneedyn_executable("--kneedyn", a.kneedyn)
  kneedyn = os.path.abspath(a.kneedyn)
  results = [None] * len(todo)
  start = time.monotonic()
  with concurrent.futures.ThreadPoolExecutor(max_workers=a.jobs) as pool:
    futures = {pool.submit(measure, r, kneedyn, scene): i for i, r in enumerate(todo)}
    try:
      for done, fut in enumerate(concurrent.futures.as_completed(futures), 1):
        i = futures[fut]
        results[i] = fut.result()
        e = results[i]
        report_progress(done, todo, i, e, start)
    except BaseException:
      # The sweep has failed (or was interrupted): the queued configurations are not run. The
      # with block alone would wait for every one of them (~20 min for the recorded sweep).
      pool.shutdown(cancel_futures=True)
      raise
  # How many CLI runs took the very steps of the sweep's in-process run of the same setting
  # (those that stop at output times may not: see the module's docstring).
  same = sum(1 for e, r in zip(results, todo)
             if (e.get("counters") or {}).get("steps") is not None
             and (e.get("counters") or {}).get("steps") == r.get("steps"))
  score_header = next((e["_score_header"] for e in results if "_score_header" in e), {})
  for e in results:
    e.pop("_score_header", None)
  version = subprocess.run([kneedyn, "--version"], capture_output=True, text=True).stdout.strip()
  commit = version.splitlines()[0] if version else "?"
  # The highest scd these scores can measure: kneedyn score's ceiling for a 12-digit CSV
  # (the reference run again at the result's times, minus one digit), not the stored
  # reference's own accuracy; the table's footnote reads it (bench_data.scd_ceiling).
  ceilings = [e["metrics"]["scd_ceiling"] for e in results
              if isinstance((e.get("metrics") or {}).get("scd_ceiling"), (int, float))]
  rel = lambda p: os.path.relpath(os.path.abspath(p), ROOT)  # noqa: E731
  argv = [rel(x) if os.path.exists(x) else x for x in (sys.argv[1:] if argv is None else argv)]
  out = {"header": {"scene": name, "cost": "instructions of kneedyn::RunScene (callgrind --toggle-collect)",
                    "scd_ceiling": min(ceilings) if ceilings else None,
                    "reference": score_header.get("reference_primary"),
                    "reference_accuracy_scd": score_header.get("reference_accuracy_scd"),
                    "sweep": rel(a.sweep), "kneedyn": commit,
                    "same_steps_as_sweep": same,
                    "date": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
                    "command": "benchmarks/instruction_sweep.py " + " ".join(argv)},
         "results": results}
  with open(a.json, "w", encoding="utf-8") as f:
    json.dump(out, f, indent=1)
  print(f"instruction_sweep.py: {len(results)} configurations, {sum(e['status'] == 'ok' for e in results)} completed, "
        f"{same} with the steps of the sweep's in-process run -> {a.json}", file=sys.stderr)
  return 0


if __name__ == "__main__":
  sys.exit(tool_input.exit_code("instruction_sweep.py", main))
