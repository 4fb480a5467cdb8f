#!/usr/bin/python3
"""The configurations benchmarks/run_targets.cpp times, chosen from the recorded sweep by
the rule its header states, and a check that the program's table still follows it.

    /usr/bin/python3 benchmarks/choose_targets.py \
        [--sweep benchmarks/recorded/work_precision_chapter_impact.json] \
        [--instructions benchmarks/recorded/instructions_chapter_impact.json] \
        [--check benchmarks/run_targets.cpp]

The rule, for one method (formulation[:integrator]) and a target scd: on the sweep's rtol
grid (quarter decades, atol = rtol/100), the loosest rtol at which the run and the four next
tighter runs of the method are all results (reports/bench_data.py, classify_run) with
scd >= the target. One run past the target is not enough: ede's scd scatters by ±0.5 with
round-off (ede dopri5's figures in run_targets.cpp's header).

A target of run_targets.cpp names the method it is chosen among (`among`): one method, or
"" for every variable-step method without stabilization (what run_targets' Config can
express). Among several methods the chosen run is the one of fewest instructions in the
instruction sweep (benchmarks/instruction_sweep.py: RunScene's count, the same on every
run), not of least CPU time, which on a shared machine orders close methods differently
from one evening to the next.

Prints each target's choice. --check reads kTargets of run_targets.cpp and exits 1, naming
each target whose formulation, integrator or rtol differs from the choice (re-choose after
every re-recording of the sweep: tests/run_targets_choice_test.py fails until then). Bad
input (a missing file, a table it cannot read, a chosen run the instruction sweep lacks or
ran with other steps than the sweep: an instruction sweep of another recording) exits 2.
"""
import argparse
import json
import math
import os
import re
import sys

sys.dont_write_bytecode = True  # keep the source tree clean
ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "reports"))
from bench_data import classify_run, load_bench, method_of  # noqa: E402
import tool_input  # noqa: E402

WINDOW = 5  # the chosen run and the four next tighter ones (a decade of quarter-decade steps)

# One entry of kTargets: {"target/NAME", Config("formulation", "integrator", rtol), min_scd, "among"}
TARGET_ENTRY = re.compile(r'\{\s*"(target/[\w]+)"\s*,\s*Config\(\s*"([\w-]*)"\s*,\s*"([\w-]*)"\s*,\s*'
                          r'([0-9.eE+-]+)\s*\)\s*,\s*([0-9.eE+-]+)\s*,\s*"([\w:-]*)"\s*\}')


class InputError(Exception):
  pass


def read_targets(cpp_path):
  """kTargets of run_targets.cpp -> [{name, formulation, integrator, rtol, min_scd, among}]."""
  try:
    with open(cpp_path, encoding="utf-8") as f:
      text = f.read()
  except OSError as e:
    raise InputError(f"read_targets: cannot read {cpp_path}: {e.strerror}")
  targets = [{"name": m[0], "formulation": m[1], "integrator": m[2], "rtol": float(m[3]),
              "min_scd": float(m[4]), "among": m[5]} for m in TARGET_ENTRY.findall(text)]
  if not targets:
    raise InputError(f"read_targets: no entry of the form {{\"target/NAME\", Config(\"f\", \"i\", rtol), "
                     f"min_scd, \"among\"}} in {cpp_path}")
  return targets


def variable_step_series(runs):
  """{method: its runs with an rtol, loosest first}; stabilized methods left out."""
  series = {}
  for r in runs:
    s = r.get("setting") or {}
    if r.get("origin", "kneedyn") != "kneedyn" or "rtol" not in s or s.get("stabilization"):
      continue
    series.setdefault(method_of(r), []).append(r)
  return {m: sorted(rs, key=lambda r: -r["setting"]["rtol"]) for m, rs in series.items()}


def loosest_robust_run(runs, min_scd):
  """The rule on one method's runs (loosest first): the first run that, with the WINDOW − 1
  runs after it, is a result at scd >= min_scd; None when no window qualifies."""
  reaches = [classify_run(r) == "ok" and r["scd"] >= min_scd for r in runs]
  for i in range(len(runs) - WINDOW + 1):
    if all(reaches[i:i + WINDOW]):
      return runs[i]
  return None


def instruction_key(r):
  return (method_of(r), r["setting"].get("rtol"))


def choose(sweep_runs, instruction_runs, among, min_scd):
  """The rule's run for one target, and the scd range of its window:
  (run, instructions or None, (min, max) scd)."""
  series = variable_step_series(sweep_runs)
  if among:
    if among not in series:
      raise InputError(f"choose: method {among!r} has no variable-step run in the sweep")
    series = {among: series[among]}
  counted = {instruction_key(r): r for r in instruction_runs}
  picks = []
  for m, runs in series.items():
    r = loosest_robust_run(runs, min_scd)
    if r is None:
      continue
    i = runs.index(r)
    window = [x["scd"] for x in runs[i:i + WINDOW]]
    twin = counted.get(instruction_key(r))
    # The instruction sweep replays the sweep's configurations; a run that took other steps
    # was recorded from another sweep or another binary, and its count says nothing here.
    if twin is not None and twin.get("steps") != r.get("steps"):
      raise InputError(f"choose: {m} rtol {r['setting']['rtol']:.3g} took {r.get('steps')} steps in the sweep and "
                       f"{twin.get('steps')} in the instruction sweep: re-record the instruction sweep "
                       f"(cmake --build build --target bench_record_instructions)")
    picks.append((r, twin.get("instructions") if twin else None, (min(window), max(window))))
  if not picks:
    return None
  if len(picks) > 1:
    missing = [method_of(p[0]) for p in picks if not isinstance(p[1], (int, float))]
    if missing:
      raise InputError(f"choose: the instruction sweep has no count for the rule's run of {', '.join(missing)} "
                       f"(re-record it: cmake --build build --target bench_record_instructions)")
  return min(picks, key=lambda p: (p[1] if p[1] is not None else 0, method_of(p[0])))


def differences(target, pick):
  """What differs between a kTargets entry and the rule's pick (empty when they agree)."""
  if pick is None:
    return [f"{target['name']}: no method among {target['among'] or 'all'} reaches scd {target['min_scd']:g} "
            f"at {WINDOW} consecutive rtols"]
  r = pick[0]
  want = (r["formulation"], r.get("integrator") or "", r["setting"]["rtol"])
  have = (target["formulation"], target["integrator"], target["rtol"])
  if want[:2] == have[:2] and math.isclose(want[2], have[2], rel_tol=1e-12):
    return []
  return [f"{target['name']}: run_targets has {have[0]} {have[1] or '-'} rtol {have[2]:.17g}; "
          f"the rule chooses {want[0]} {want[1] or '-'} rtol {want[2]:.17g}"]


def read_sweep(option, path):
  """load_bench(path), its errors (BadInput) naming `option` and the file."""
  def load(p):
    try:
      return load_bench(p)
    except json.JSONDecodeError as e:
      raise tool_input.BadInput(f"{option} = '{tool_input.echo(p)}': not JSON ({e})") from None
    except tool_input.BadInput as e:
      raise tool_input.BadInput(f"{option}: {e}") from None
  return tool_input.checked(load, option, path)


def main(argv=None):
  ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
  ap.add_argument("--sweep", default=os.path.join(ROOT, "benchmarks/recorded/work_precision_chapter_impact.json"))
  ap.add_argument("--instructions", default=os.path.join(ROOT, "benchmarks/recorded/instructions_chapter_impact.json"))
  ap.add_argument("--check", default=os.path.join(ROOT, "benchmarks/run_targets.cpp"),
                  help="run_targets.cpp whose kTargets are checked (default: the repository's)")
  a = ap.parse_args(argv)
  try:
    targets = read_targets(a.check)
    # Each file's errors name its option (--sweep or --instructions) and the file.
    _, sweep = read_sweep("--sweep", a.sweep)
    _, instructions = read_sweep("--instructions", a.instructions)
    found = []
    for t in targets:
      pick = choose(sweep, instructions, t["among"], t["min_scd"])
      if pick is not None:
        r, ins, (lo, hi) = pick
        cost = f"{ins / 1e6:.2f} M instructions" if isinstance(ins, (int, float)) else "no instruction count"
        print(f"{t['name']}: {method_of(r)} rtol {r['setting']['rtol']:.17g} (scd {lo:.2f}–{hi:.2f} over "
              f"{WINDOW} rtols; {cost})")
      found += differences(t, pick)
  except InputError as e:
    print(f"choose_targets: {e}", file=sys.stderr)
    return 2
  except tool_input.BadInput as e:
    print(f"choose_targets: {e}", file=sys.stderr)
    return 2
  for d in found:
    print(f"choose_targets: {d}", file=sys.stderr)
  return 1 if found else 0


if __name__ == "__main__":
  sys.exit(tool_input.exit_code("choose_targets", main))
