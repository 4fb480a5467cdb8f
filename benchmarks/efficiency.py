#!/usr/bin/python3
"""Efficiency: the share of a run's instructions spent in the model's own evaluations
(benchmarks/README.md, "The same sweep on instruction counts", column "efficiency").

    /usr/bin/python3 benchmarks/efficiency.py --kneedyn build/formulations/kneedyn \
        [--sweep benchmarks/recorded/instructions_chapter_impact.json] [--cost instructions|cpu] \
        [--scd 6] [--only SUBSTR] [--scene SCENE.yaml] [--json OUT.json]

For each method of the sweep (formulation[:integrator][/stabilization]) it takes the
cheapest counted run reaching scd >= --scd (the cell of `work_precision_table.py SWEEP --cost
COST`'s column "scd >= 6"): by default the cheapest by RunScene's instructions in the
instruction sweep (benchmarks/instruction_sweep.py), so that which run is measured does not
depend on the evening's CPU times; `--cost cpu` takes the cheapest by CPU time of a sweep
file. --scene is the scene the runs use (default: reference-data/scenes/<the sweep header's
scene>.yaml). It runs that configuration once under `valgrind --tool=callgrind` (whole process:
`kneedyn run <scene> ... --quiet --out TMP`) and reads the inclusive instruction counts of
the callbacks the integrator calls (`callgrind_annotate --inclusive=yes`):

  residual / right-hand side: IdaDriver<…>::Residual (IDA), OdeIntegrator::RhsCallback (CVODE,
      ARKODE; includes mde's and ede's cache hits), StepResidual (newmark, generalized-alpha);
  all model callbacks: the above plus the Jacobian (IdaDriver<…>::Jacobian, StepJacobian,
      CVODE's own difference quotients otherwise), the root functions (IdaDriver<…>::Roots,
      OdeIntegrator::RootCallback, the fixed-step schemes' Events) and the projection
      (OdeIntegrator::ProjCallback).

Shares are of the whole process (start-up, loading and output included), so the column is
what a user's run spends on the model. These callbacks do not call one another, so their
inclusive counts add without overlap. Instruction counts are deterministic, unlike CPU time
on a shared machine. Prints a markdown table; --json writes {scd, cost, sweep, methods:
{method: {...}}} for `work_precision_table.py --efficiency`, which shows the column only in
a table of the same cost (its cells are then the runs measured here). Exit 0 measured; 1 when a
run, valgrind or callgrind_annotate fails (one line naming the command, its exit code and the
end of its stderr; no --json written); 2 on bad input.
"""
import argparse
import json
import os
import re
import shutil
import sys
import subprocess
import tempfile
import time

sys.dont_write_bytecode = True  # keep the source tree clean
ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "reports"))
sys.path.insert(0, os.path.join(ROOT, "benchmarks"))
from bench_data import load_bench, method_of, split_runs  # noqa: E402
from record_sweep import provenance as recorded_provenance  # noqa: E402  the recorded files' rule, one copy
import tool_input  # noqa: E402
from tool_input import BadInput  # noqa: E402

# Function-name patterns (demangled, as callgrind_annotate prints them).
# A run whose residual matches none of them is an error (measure), not a 0 % share: the
# names follow the code (tests/efficiency_test.py looks each one up in the kneedyn binary).
RESIDUAL = (r"IdaDriver<[\w:]+>::Residual\(", r"OdeIntegrator::RhsCallback\(", r"::StepResidual<double>\(")
OTHER_CALLBACKS = (r"IdaDriver<[\w:]+>::Jacobian\(", r"IdaDriver<[\w:]+>::Roots\(", r"OdeIntegrator::RootCallback\(",
                   r"OdeIntegrator::ProjCallback\(",
                   r"::StepJacobian\(", r"NewmarkFormulation::Events\(")
LINE = re.compile(r"^\s*([\d,]+)\s+\(\s*[\d.]+%\)\s+(.*)$")


def command_of(run, kneedyn, scene, out):
  s = run.get("setting") or {}
  cmd = [kneedyn, "run", scene, "--formulation", run["formulation"]]
  if run.get("integrator"):
    cmd += ["--integrator", run["integrator"]]
  for key in ("rtol", "atol", "step"):
    if key in s:
      cmd += ["--" + key, repr(float(s[key]))]
  # The fixed-step formulations' Newton tolerances, recorded apart from the step (bench_run.cpp).
  for key, flag in (("newton_rtol", "--rtol"), ("newton_atol", "--atol")):
    if key in s and flag.lstrip("-") not in s:
      cmd += [flag, repr(float(s[key]))]
  if s.get("stabilization"):
    cmd += ["--stabilization", s["stabilization"]]
  return cmd + ["--quiet", "--out", out]


def inclusive_costs(callgrind_out):
  """(total instructions, {function: inclusive instructions}) of a callgrind output file;
  tool_input.CommandFailed (exit 1) when callgrind_annotate fails."""
  text = tool_input.run_command(["callgrind_annotate", "--inclusive=yes", "--threshold=100", callgrind_out]).stdout
  return parse_annotate(text)


def parse_annotate(text):
  """(total, {function: inclusive}) from `callgrind_annotate --inclusive=yes` output."""
  total = None
  costs = {}
  for line in text.splitlines():
    m = LINE.match(line)
    if m is None:
      t = re.match(r"^\s*([\d,]+)\s+\(100\.0%\)\s+PROGRAM TOTALS", line)
      if t:
        total = int(t.group(1).replace(",", ""))
      continue
    name = m.group(2)
    costs[name] = costs.get(name, 0) + int(m.group(1).replace(",", ""))
  if total is None:
    t = re.search(r"^\s*([\d,]+)\s+\(100\.0%\)\s+PROGRAM TOTALS", text, re.M)
    total = int(t.group(1).replace(",", "")) if t else None
  return total, costs


def share(costs, patterns):
  """Inclusive instructions of the functions matching `patterns` ([clone .cold] parts added)."""
  return sum(v for name, v in costs.items() if any(re.search(p, name) for p in patterns))


def measure(run, kneedyn, scene, tmp):
  out = os.path.join(tmp, "out")
  cg = os.path.join(tmp, "callgrind.out")
  cmd = ["valgrind", "--tool=callgrind", f"--callgrind-out-file={cg}"] + command_of(run, kneedyn, scene, out)
  # A run that fails is a failure of the program measured (or of valgrind): exit 1.
  tool_input.run_command(cmd)
  total, costs = inclusive_costs(cg)
  residual = share(costs, RESIDUAL)
  if residual == 0:
    name = run["formulation"] + (f" {run['integrator']}" if run.get("integrator") else "")
    raise SystemExit(f"efficiency.py: measure(): no function of the {name} run's profile matches the residual "
                     f"patterns {RESIDUAL}; a callback was renamed (update RESIDUAL / OTHER_CALLBACKS)")
  callbacks = residual + share(costs, OTHER_CALLBACKS)
  return {"setting": run.get("setting"), "scd": run["scd"], "instructions": total,
          "residual_share": residual / total, "callback_share": callbacks / total,
          "command": " ".join(command_of(run, "kneedyn", os.path.relpath(scene, ROOT), "TMP"))}


def pick_runs(runs, scd, cost, only=""):
  """{method: its cheapest result with scd >= `scd`} by `cost` ("instructions": RunScene's
  count of the instruction sweep; "cpu": the median CPU time), for the methods whose name
  contains `only`; methods without such a run are left out."""
  key = "instructions" if cost == "instructions" else "cpu_s"
  ok, _ = split_runs(runs)
  picks = {}
  for m in dict.fromkeys(method_of(r) for r in runs):
    if only not in m:
      continue
    reach = [r for r in ok if method_of(r) == m and r["scd"] >= scd and isinstance(r.get(key), (int, float))]
    if reach:
      picks[m] = min(reach, key=lambda r: r[key])
  return picks


def main(argv=None):
  ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
  ap.add_argument("--kneedyn", required=True)
  ap.add_argument("--sweep", default=os.path.join(ROOT, "benchmarks/recorded/instructions_chapter_impact.json"))
  ap.add_argument("--cost", choices=("instructions", "cpu"), default="instructions",
                  help="which cost picks each method's cheapest run (default: instructions)")
  ap.add_argument("--scene", default=None, help="default: the sweep header's scene")
  ap.add_argument("--scd", type=float, default=6.0)
  ap.add_argument("--only", default="")
  ap.add_argument("--json", default=None)
  a = ap.parse_args(argv)
  header, runs = tool_input.checked(load_bench, "--sweep", a.sweep)
  if a.cost == "instructions" and not any(isinstance(r.get("instructions"), int) for r in runs):
    raise BadInput(f"--cost instructions: {a.sweep} has no instruction counts (benchmarks/instruction_sweep.py "
                   "writes them; --cost cpu picks by CPU time)")
  tool_input.number("--scd", a.scd)
  if a.json is not None:
    tool_input.output_file("--json", a.json)
  picks = pick_runs(runs, a.scd, a.cost, a.only)
  if not picks:
    if a.only and not any(a.only in method_of(r) for r in runs):
      raise BadInput(f"--only = '{tool_input.echo(a.only)}': no method of '{a.sweep}' matches")
    raise BadInput(f"--scd = {a.scd:g}: no method{f' matching --only {a.only!r}' if a.only else ''} of "
                   f"'{a.sweep}' has a result reaching it")
  tool_input.kneedyn_executable("--kneedyn", a.kneedyn)
  for tool in ("valgrind", "callgrind_annotate"):
    if shutil.which(tool) is None:
      raise BadInput(f"{tool} not found (apt-get install valgrind)")
  name = os.path.splitext(os.path.basename(str(header.get("scene") or "chapter_impact")))[0]
  scene = a.scene or os.path.join(ROOT, "reference-data/scenes", name + ".yaml")
  tool_input.existing_file("--scene", scene)
  result = {}
  for m, best in picks.items():
    with tempfile.TemporaryDirectory() as tmp:
      result[m] = measure(best, os.path.abspath(a.kneedyn), scene, tmp)
    e = result[m]
    print(f"{m}: {e['instructions'] / 1e6:.2f} M, residual/rhs {100 * e['residual_share']:.1f} %, "
          f"all callbacks {100 * e['callback_share']:.1f} %", file=sys.stderr)
  print(f"| method | configuration (cheapest by {a.cost} at scd ≥ {a.scd:g}) | instructions | residual / rhs | "
        "all model callbacks |")
  print("|---|---|---|---|---|")
  for m, e in result.items():
    setting = ", ".join(f"{k}={v:g}" if isinstance(v, float) else f"{k}={v}" for k, v in (e["setting"] or {}).items())
    print(f"| {m} | {setting} | {e['instructions'] / 1e6:.2f} M | {100 * e['residual_share']:.1f} % | "
          f"{100 * e['callback_share']:.1f} % |")
  if a.json:
    with open(a.json, "w") as f:
      # Provenance as the recorded sweeps carry it (record_sweep.py): what made the file, from
      # which commit (-dirty), when, and which kneedyn ran.
      version = subprocess.run([os.path.abspath(a.kneedyn), "--version"], capture_output=True, text=True).stdout
      provenance = dict(recorded_provenance(__file__, sys.argv[1:] if argv is None else argv),
                        kneedyn=version.splitlines()[0] if version else "unknown")
      json.dump({"scd": a.scd, "cost": a.cost, "sweep": os.path.relpath(a.sweep, ROOT), "methods": result,
                 "provenance": provenance}, f, indent=1)
  return 0


if __name__ == "__main__":
  sys.exit(tool_input.exit_code("efficiency.py", main))
