#!/usr/bin/python3
"""benchmarks/efficiency.py and work_precision_table.py --efficiency on planted inputs (no
valgrind): the callback shares read from a hand-written callgrind_annotate listing (the
callbacks' [clone .cold] parts added, functions they call not counted twice, other functions
not counted), the command line rebuilt from a sweep run's setting, and the table's
efficiency column (a method without a measured run shows '—'). Expected values are typed in
from the planted numbers. With the kneedyn binary as argument, also that the callback
patterns of the integrators that reach scd 6 (IDA's driver, CVODE's and ARKODE's
callbacks) name functions the binary defines (`nm -C`): a renamed callback would otherwise
read as a 0 % share.
"""
import json
import os
import re
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.dont_write_bytecode = True
sys.path.insert(0, os.path.join(ROOT, "benchmarks"))
sys.path.insert(0, os.path.join(ROOT, "reports"))
from py_test_support import finish  # noqa: E402
import efficiency  # noqa: E402
from bench_data import normalize_result  # noqa: E402

LISTING = """--------------------------------------------------------------------------------
Ir
--------------------------------------------------------------------------------
1,000,000 (100.0%)  PROGRAM TOTALS

--------------------------------------------------------------------------------
Ir                 file:function
--------------------------------------------------------------------------------
  900,000 (90.00%)  ???:main [/x/kneedyn]
  200,000 (20.00%)  ???:kneedyn::IdaDriver<kneedyn::DaeSystem>::Residual(double, _generic_N_Vector*, _generic_N_Vector*, _generic_N_Vector*, void*) [/x/kneedyn]
    1,000 ( 0.10%)  ???:kneedyn::IdaDriver<kneedyn::DaeSystem>::Residual(double, _generic_N_Vector*, _generic_N_Vector*, _generic_N_Vector*, void*) [clone .cold] [/x/kneedyn]
  190,000 (19.00%)  ???:kneedyn::DaeSystem::Residual(double, double const*, double const*, double*) const [/x/kneedyn]
  150,000 (15.00%)  ???:kneedyn::IdaDriver<kneedyn::DaeSystem>::Jacobian(double, double, _generic_N_Vector*, _generic_N_Vector*, _generic_N_Vector*, _generic_SUNMatrix*, void*, _generic_N_Vector*, _generic_N_Vector*, _generic_N_Vector*) [/x/kneedyn]
   50,000 ( 5.00%)  ???:kneedyn::IdaDriver<kneedyn::DaeSystem>::Roots(double, _generic_N_Vector*, _generic_N_Vector*, double*, void*) [/x/kneedyn]
   70,000 ( 7.00%)  ???:kneedyn::WriteRunOutputs(...) [/x/kneedyn]
"""


def main():
  failures = []

  def check(cond, what):
    if not cond:
      failures.append(what)

  if len(sys.argv) > 1:
    names = subprocess.run(["nm", "-C", "--defined-only", sys.argv[1]], capture_output=True, text=True,
                           check=True).stdout.splitlines()
    for p in (efficiency.RESIDUAL[:2] + efficiency.OTHER_CALLBACKS[:4]):
      check(any(re.search(p, n) for n in names), f"pattern {p} names no function of {sys.argv[1]}")
  # A profile whose residual matches no pattern is refused, not read as 0 %.
  check(efficiency.share(efficiency.parse_annotate(LISTING.replace("Residual(", "Rsd("))[1], efficiency.RESIDUAL) == 0,
        "renamed residual still matched")

  total, costs = efficiency.parse_annotate(LISTING)
  check(total == 1_000_000, f"total {total}")
  residual = efficiency.share(costs, efficiency.RESIDUAL)
  callbacks = residual + efficiency.share(costs, efficiency.OTHER_CALLBACKS)
  check(residual == 201_000, f"residual {residual} (expected 200,000 + 1,000 cold)")
  check(callbacks == 401_000, f"callbacks {callbacks} (expected 201,000 + 150,000 + 50,000)")

  run = {"formulation": "ede", "integrator": "dopri5", "setting": {"rtol": 1e-7, "atol": 1e-9, "stabilization": "projection"}}
  cmd = efficiency.command_of(run, "K", "S.yaml", "OUT")
  check(cmd == ["K", "run", "S.yaml", "--formulation", "ede", "--integrator", "dopri5", "--rtol", "1e-07",
                "--atol", "1e-09", "--stabilization", "projection", "--quiet", "--out", "OUT"], f"command {cmd}")
  cmd = efficiency.command_of({"formulation": "newmark", "integrator": "", "setting": {"step": 0.001}}, "K", "S", "O")
  check(cmd == ["K", "run", "S", "--formulation", "newmark", "--step", "0.001", "--quiet", "--out", "O"], f"command {cmd}")
  # The sweep records a fixed-step formulation's Newton tolerances as newton_rtol / newton_atol
  # (benchmarks/bench_run.cpp): the command must pass them, or the CLI runs its defaults.
  cmd = efficiency.command_of({"formulation": "generalized-alpha", "integrator": "",
                               "setting": {"step": 1e-4, "newton_rtol": 1e-9, "newton_atol": 1e-11}}, "K", "S", "O")
  check(cmd == ["K", "run", "S", "--formulation", "generalized-alpha", "--step", "0.0001", "--rtol", "1e-09",
                "--atol", "1e-11", "--quiet", "--out", "O"], f"command {cmd}")

  events = {"liftoff_lateral": 1e-7, "flexion_90": 1e-7}
  ref = [{"name": "liftoff_lateral", "time_s": 0.2163}, {"name": "flexion_90", "time_s": 0.2996}]

  def result(form, integ, setting, scd, cpu):
    return {"formulation": form, "integrator": integ, "setting": setting, "status": "ok", "reason": "",
            "metrics": {"scd": scd, "event_time_error_s": dict(events)},
            "cpu_time_s": {"median": cpu}, "counters": {}, "events": ref}

  sweep = {"header": {"scene": "chapter_impact"},
           "results": [result("dae", "", {"rtol": 1e-8, "atol": 1e-10}, 6.5, 0.01),
                       result("ede", "dopri5", {"rtol": 1e-7, "atol": 1e-9}, 6.2, 0.005)]}
  eff = {"scd": 6, "methods": {"dae": {"residual_share": 0.213, "callback_share": 0.415}}}
  with tempfile.TemporaryDirectory() as tmp:
    sp, ep = os.path.join(tmp, "wp.json"), os.path.join(tmp, "eff.json")
    json.dump(sweep, open(sp, "w"))
    json.dump(eff, open(ep, "w"))
    out = subprocess.run([sys.executable, os.path.join(ROOT, "benchmarks", "work_precision_table.py"), sp,
                          "--efficiency", ep], capture_output=True, text=True)
    check(out.returncode == 0, f"table exit {out.returncode}: {out.stderr}")
    rows = {line.split("|")[1].strip(): line for line in out.stdout.splitlines() if line.startswith("| ")}
    check("efficiency" in out.stdout.splitlines()[0], f"header: {out.stdout.splitlines()[:1]}")
    check(rows.get("dae", "").endswith("| 21 % (42 %) |"), f"dae row: {rows.get('dae')}")
    check(rows.get("ede:dopri5", "").endswith("| — |"), f"ede row: {rows.get('ede:dopri5')}")
    plain = subprocess.run([sys.executable, os.path.join(ROOT, "benchmarks", "work_precision_table.py"), sp],
                           capture_output=True, text=True).stdout
    check("efficiency" not in plain, "column without --efficiency")
    missing = subprocess.run([sys.executable, os.path.join(ROOT, "benchmarks", "work_precision_table.py"), sp,
                              "--efficiency", os.path.join(tmp, "none.json")], capture_output=True, text=True)
    check(missing.returncode == 2 and "none.json" in missing.stderr, f"missing file: {missing.returncode} {missing.stderr}")

    # An efficiency file picked by instructions beside a CPU table: refused (its runs are not the
    # table's cells); a file without "cost" was picked by CPU time.
    json.dump(dict(eff, cost="instructions"), open(ep, "w"))
    mixed = subprocess.run([sys.executable, os.path.join(ROOT, "benchmarks", "work_precision_table.py"), sp,
                            "--efficiency", ep], capture_output=True, text=True)
    check(mixed.returncode == 2 and "chosen by instructions" in mixed.stderr and not mixed.stdout,
          f"instruction-picked efficiency beside a CPU table: {mixed.returncode} {mixed.stderr}")
    # efficiency.py --cost instructions on a sweep without counts: exit 2 before any run.
    code = subprocess.run([sys.executable, os.path.join(ROOT, "benchmarks", "efficiency.py"), "--kneedyn", "K",
                           "--sweep", sp], capture_output=True, text=True)
    check(code.returncode == 2 and "no instruction counts" in code.stderr, f"no counts: {code.returncode} {code.stderr}")

  # Which run each method's cell is: dae at rtol 1e-8 is the cheaper by CPU time (0.010 s
  # against 0.012 s), at 1e-9 the cheaper by instructions (40 M against 50 M); 1e-7 misses
  # scd 6 and a failed run, though cheapest, is no result.
  planted = [dict(result("dae", "", {"rtol": 1e-8, "atol": 1e-10}, 6.5, 0.010), instructions={"run_scene": 50_000_000}),
             dict(result("dae", "", {"rtol": 1e-9, "atol": 1e-11}, 7.5, 0.012), instructions={"run_scene": 40_000_000}),
             dict(result("dae", "", {"rtol": 1e-7, "atol": 1e-9}, 5.5, 0.001), instructions={"run_scene": 1_000_000}),
             dict(result("dae", "", {"rtol": 1e-10, "atol": 1e-12}, 8.0, 0.001), instructions={"run_scene": 1_000_000},
                  status="failed", reason="IDA_CONV_FAIL")]
  runs = [normalize_result(r) for r in planted]
  by_cpu, by_ins = efficiency.pick_runs(runs, 6.0, "cpu"), efficiency.pick_runs(runs, 6.0, "instructions")
  check(by_cpu["dae"]["setting"]["rtol"] == 1e-8, f"cheapest by CPU: {by_cpu['dae']['setting']}")
  check(by_ins["dae"]["setting"]["rtol"] == 1e-9, f"cheapest by instructions: {by_ins['dae']['setting']}")
  check(efficiency.pick_runs(runs, 9.0, "instructions") == {}, "a method without a run at scd 9 has a pick")

  return finish(failures, "FAIL:", "efficiency_test: " + ("FAILED" if failures else "ok"), sys.stdout)


if __name__ == "__main__":
  sys.exit(main())
