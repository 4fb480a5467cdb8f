#!/usr/bin/python3
"""Failed and wrong-event runs in the work-precision diagrams, the table and the report, on
small hand-made sweep files in the layouts the project writes:

  * work_precision's (Google Benchmark's `context` and `benchmarks` beside kneedyn's `header`
    and `results`): there a failed run's `scd` counter in `benchmarks` is 0 and carries no
    status, so only `results` tells that it failed;
  * simbody_work_precision --merge's (`header` and `results`; Simbody's settings are
    {accuracy, constraint_tolerance}, no rtol).

Checks: the failure count per formulation in the figures' titles (read back from the PNG's
text chunks) and from bench_data.failure_counts; the Pareto front of a formulation whose
fixed-step run is dominated; benchmarks/work_precision_table.py's rows for both files; the
report's fairness manifest (context.components) as a table, and "not recorded" without it;
bad input to the table (a top-level number, a wrong-typed field, no results, a directory, a
truncated --efficiency, a usage error) refused with exit 2 naming the file and field, and
--help printing the usage; two failed runs that differ only in their stabilization listed as
two different settings.
Every expected value is typed in here from the planted runs, not copied from a run.
"""
import json
import os
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.dont_write_bytecode = True
sys.path.insert(0, os.path.join(ROOT, "reports"))
from py_test_support import finish  # noqa: E402
TABLE = os.path.join(ROOT, "benchmarks", "work_precision_table.py")

EVENTS_OK = {"liftoff_lateral": 2e-7, "flexion_90": 1e-7}
REF_EVENTS = [{"name": "liftoff_lateral", "time_s": 0.2163}, {"name": "flexion_90", "time_s": 0.2996}]


def result(form, integ, setting, scd, cpu, status="ok", reason="", events=None, event_errors=None):
  shown = [f"{k}={v}" if isinstance(v, str) else f"{k}={v:g}" for k, v in setting.items()]
  name = form + (":" + integ if integ else "") + "/" + "/".join(shown)
  return {"name": name, "formulation": form, "integrator": integ, "setting": setting, "status": status,
          "reason": reason, "metrics": {"scd": scd, "event_time_error_s": event_errors or dict(EVENTS_OK)},
          "cpu_time_s": {"median": cpu, "min": cpu, "max": cpu},
          "counters": {"residual_evaluations": int(cpu * 1e5)}, "events": REF_EVENTS if events is None else events}


RESULTS = [
    result("dae", "", {"rtol": 1e-4, "atol": 1e-6}, 3.0, 0.010),
    result("dae", "", {"rtol": 1e-6, "atol": 1e-8}, 5.0, 0.020),
    result("dae", "", {"rtol": 1e-8, "atol": 1e-10}, 7.0, 0.030),
    # Planted failure: IDA gives up at a tight tolerance; its metrics are partial (scd null).
    result("dae", "", {"rtol": 1e-12, "atol": 1e-14}, None, 0.050, status="failed",
           reason="IDASolve(): IDA_CONV_FAIL at t = 0.19 s", events=[],
           event_errors={"liftoff_lateral": None, "flexion_90": None}),
    result("ede", "dopri5", {"rtol": 1e-5, "atol": 1e-7}, 4.5, 0.004),
    result("ede", "dopri5", {"rtol": 1e-7, "atol": 1e-9}, 6.5, 0.008),
    # Planted wrong event: completes with scd 2.5 but its lift-off is 5 ms late (> 1 ms).
    result("ede", "dopri5", {"rtol": 1e-3, "atol": 1e-5}, 2.5, 0.002,
           event_errors={"liftoff_lateral": 5e-3, "flexion_90": 1e-4}),
    # Dominated: rk4 reaches scd 4.2 at 0.012 s, dopri5 scd 6.5 at 0.008 s.
    result("ede", "rk4", {"step": 5e-4}, 4.2, 0.012),
]


def google_entries(results):
  """work_precision's `benchmarks`: per setting a median aggregate with the `scd` counter,
  0 for a run without an scd (work_precision.cpp writes 0.0 when it is not finite)."""
  out = []
  for r in results:
    scd = r["metrics"]["scd"]
    out.append({"name": r["name"] + "_median", "run_name": r["name"], "run_type": "aggregate",
                "aggregate_name": "median", "cpu_time": r["cpu_time_s"]["median"] * 1e3, "time_unit": "ms",
                "scd": 0.0 if scd is None else scd,
                "residual_evaluations": r["counters"]["residual_evaluations"]})
  return out


COMPONENTS = [
    {"name": "kneedyn", "version": "0.1.0", "origin": "this repository", "compile_flags": "-O3 -DNDEBUG"},
    {"name": "SUNDIALS", "version": "6.4.1", "origin": "Debian source package, built in the tree",
     "compile_flags": ["-O3", "-DNDEBUG"]},
]


def sweep_file(components):
  context = {"kneedyn_mode": "full", "kneedyn_scene": "chapter_impact"}
  if components is not None:
    context["components"] = components
  return {"context": context, "benchmarks": google_entries(RESULTS),
          "header": {"scene": "chapter_impact", "mode": "full", "rtol_min": 1e-12},
          "results": RESULTS}


# simbody_work_precision --merge's file: the rows it timed carry "engine"; the dae row was
# copied from the merged sweep (another process), whose header and context merged_from keeps.
MERGED = {"header": {"scene": "chapter_impact", "mode": "short", "repetitions": 2, "date": "2026-01-02T00:00:00Z",
                     "command": "simbody_work_precision --short --merge wp.json --json wp.json",
                     "merged_from": {"file": "out/work_precision.json",
                                     "header": {"mode": "short", "repetitions": 3, "rtol_min": 1e-11,
                                                "date": "2026-01-01T00:00:00Z"},
                                     "context": {"git_commit": "feedbeef0001"}}},
          "context": {"git_commit": "c0ffee000002"},
          "results": [dict(result("simbody", "rkm", {"accuracy": 1e-6, "constraint_tolerance": 1e-6}, 5.5, 0.040),
                           engine="simbody"),
                      dict(result("simbody", "rkm", {"accuracy": 1e-8, "constraint_tolerance": 1e-8}, None, 0.090,
                                  status="failed", reason="Simbody: step size underflow", events=[],
                                  event_errors={"liftoff_lateral": None, "flexion_90": None}), engine="simbody"),
                      result("dae", "", {"rtol": 1e-6, "atol": 1e-8}, 5.0, 0.020)]}


def png_text(path):
  from PIL import Image
  with Image.open(path) as im:
    return dict(im.text)


def table_rows(path):
  p = subprocess.run([sys.executable, TABLE, path], capture_output=True, text=True)
  if p.returncode != 0:
    return None, f"exit {p.returncode}: {p.stderr.strip()[-300:]}"
  rows = {}
  for line in p.stdout.splitlines():
    cells = [c.strip() for c in line.strip().strip("|").split("|")]
    if line.startswith("| ") and cells[0] not in ("method",):
      rows[cells[0]] = cells[1:]
  return rows, p.stdout


def bad_input_errors(tmp):
  """Bad input to work_precision_table.py (the exit codes in README.md): exit 2 before any output,
  a message naming the file (and the field), no traceback; --help prints the usage, exit 0."""
  errors = []
  good = result("dae", "", {"rtol": 1e-6, "atol": 1e-8}, 5.0, 0.020)
  bad_metrics = dict(good, metrics=5)
  bad_scd = dict(good, metrics={"scd": "x", "event_time_error_s": dict(EVENTS_OK)})
  planted = {  # name: (file content, text the message must hold besides the file's name)
      "number": ("5", "a JSON number"),
      "metrics": (json.dumps({"header": {}, "results": [good, bad_metrics]}), "results[1].metrics = 5"),
      "scd": (json.dumps({"header": {}, "results": [bad_scd]}), "results[0].metrics.scd = 'x'"),
      "empty": ("{}", "no results"),
      "oops": (json.dumps({"results": "oops"}), "results = 'oops'"),
      "no_setting": (json.dumps({"results": [dict(good, setting={})]}), "results[0].setting"),
      "event": (json.dumps({"results": [dict(good, events=[{"time_s": 0.2}])]}), "results[0].events[0].name"),
      "truncated": (json.dumps({"header": {}, "results": [good]})[:40], "JSONDecodeError")}
  paths = {}
  for name, (text, _) in planted.items():
    paths[name] = os.path.join(tmp, f"bad_{name}.json")
    with open(paths[name], "w") as f:
      f.write(text)
  good_path = os.path.join(tmp, "bad_good.json")
  with open(good_path, "w") as f:
    json.dump({"header": {}, "results": [good]}, f)
  eff_path = os.path.join(tmp, "bad_eff.json")
  with open(eff_path, "w") as f:
    f.write('{"scd": 6, "methods": {"dae": {"residual_sh')
  eff_empty = os.path.join(tmp, "bad_eff_empty.json")
  with open(eff_empty, "w") as f:
    json.dump({"scd": 6, "methods": []}, f)
  cases = [([paths[n]], 2, [os.path.basename(paths[n]), want]) for n, (_, want) in planted.items()]
  cases += [([tmp], 2, [os.path.basename(tmp), "directory"]),
            ([good_path, "--efficiency", eff_path], 2, ["--efficiency", "bad_eff.json"]),
            ([good_path, "--efficiency", tmp], 2, ["--efficiency", "directory"]),
            ([good_path, "--efficiency", eff_empty], 2, ["--efficiency", "methods"]),
            ([good_path, "--efficiency", paths["number"]], 2, ["--efficiency", "not an object"]),
            ([good_path, "--efficiency"], 2, ["--efficiency", "usage"]),
            ([good_path, "--cost"], 2, ["--cost", "usage"]),
            ([], 2, ["usage"]),
            (["--help"], 0, ["usage"]), (["-h"], 0, ["usage"])]
  for args, code, wants in cases:
    p = subprocess.run([sys.executable, TABLE] + args, capture_output=True, text=True)
    said = p.stdout if code == 0 else p.stderr
    what = f"work_precision_table.py {' '.join(os.path.basename(a) for a in args)}"
    if p.returncode != code:
      errors.append(f"{what}: exit {p.returncode}, expected {code}: {p.stderr.strip()[-300:]}")
    if "Traceback" in p.stderr:
      errors.append(f"{what}: a traceback: {p.stderr.strip()[-300:]}")
    if code == 2 and p.stdout:
      errors.append(f"{what}: printed a table before refusing: {p.stdout[:200]!r}")
    for want in wants:
      if want not in said:
        errors.append(f"{what}: message {said.strip()[-300:]!r} does not say {want!r}")
  return errors


def main():
  errors = []
  import figures  # noqa: E402
  import make_report  # noqa: E402
  with tempfile.TemporaryDirectory(prefix="kneedyn_wp_failures_") as tmp:
    paths = {}
    for name, doc in (("with_components", sweep_file(COMPONENTS)), ("without_components", sweep_file(None)),
                      ("merged", MERGED)):
      paths[name] = os.path.join(tmp, name + ".json")
      with open(paths[name], "w") as f:
        json.dump(doc, f)

    # 1. The figures: one dae and one ede run drawn as failures, in every figure's titles.
    out = os.path.join(tmp, "report")
    files, failed, _ = figures.make_work_precision(out, paths["with_components"])
    if not files or files[0] != "work_precision_pareto.png":
      errors.append(f"first figure is not the Pareto overlay: {files}")
    whys = sorted(f"{key} {why.split(':')[0]}" for key, _, why in failed)
    if whys != ["dae / - failed", "ede / dopri5 wrong event time"]:
      errors.append(f"runs drawn as failures: {whys}")
    for fname in files:
      text = png_text(os.path.join(out, "figures", fname))
      panels = text.get("Description", "").splitlines()
      if panels != ["dae  (1 failed / wrong event)", "ede  (1 failed / wrong event)"]:
        errors.append(f"{fname}: panel titles {panels}")
      if "2 failed or wrong event" not in text.get("Title", ""):
        errors.append(f"{fname}: title {text.get('Title')!r} does not count 2 failures")
    # Crosses below every result: coarse euler runs have scd −1.3 in the recorded sweep.
    for ys in ([3.0, 7.0], [-1.34, 2.0], []):
      row = figures.failure_row(ys) if hasattr(figures, "failure_row") else 0.0
      if not row + 0.5 < min(ys + [0.0]):
        errors.append(f"failure row at {row} for results {ys}: not below them and 0")
    try:
      import bench_data  # noqa: E402
    except ImportError as e:
      errors.append(f"reports/bench_data.py: {e}")
      bench_data = None
    if bench_data:
      _, runs = bench_data.load_bench(paths["with_components"])
      counts = bench_data.failure_counts(runs)
      if counts != {"dae": 1, "ede": 1}:
        errors.append(f"failure_counts: {counts}")
      _, merged_runs = bench_data.load_bench(paths["merged"])
      if bench_data.failure_counts(merged_runs) != {"simbody": 1, "dae": 0}:
        errors.append(f"merged failure_counts: {bench_data.failure_counts(merged_runs)}")
      # 2. Pareto front of ede: dopri5 scd 4.5 at 4 ms, 6.5 at 8 ms; rk4 (4.2 at 12 ms) is
      # dominated and the wrong-event run (2.5 at 2 ms) is not a result.
      ede = [r for r in runs if r["formulation"] == "ede"]
      front = [(r["integrator"], r["scd"], r["cpu_s"]) for r in bench_data.pareto_front(ede)]
      if front != [("dopri5", 4.5, 0.004), ("dopri5", 6.5, 0.008)]:
        errors.append(f"ede Pareto front: {front}")
      dae_front = [r["scd"] for r in bench_data.pareto_front([r for r in runs if r["formulation"] == "dae"])]
      if dae_front != [3.0, 5.0, 7.0]:
        errors.append(f"dae Pareto front: {dae_front}")

    # 3. The table, from both layouts.
    expected = {
        "dae": ["4", "1", "7.00", "20 (rtol=1e-06)", "30 (rtol=1e-08)", "—", "—"],
        "ede:dopri5": ["3", "1", "6.50", "4 (rtol=1e-05)", "8 (rtol=1e-07)", "—", "—"],
        "ede:rk4": ["1", "0", "4.20", "12 (h=0.0005)", "—", "—", "—"]}
    rows, text = table_rows(paths["with_components"])
    if rows != expected:
      errors.append(f"table of the full-layout file: {rows} != {expected}\n{text}")
    rows, text = table_rows(paths["merged"])
    expected_merged = {"simbody:rkm": ["2", "1", "5.50", "40 (accuracy=1e-06)", "—", "—", "—"],
                       "dae": ["1", "0", "5.00", "20 (rtol=1e-06)", "—", "—", "—"]}
    if rows != expected_merged:
      errors.append(f"table of the merged file: {rows} != {expected_merged}\n{text}")

    # 4. The report's fairness manifest beside the work-precision section.
    html = make_report.bench_section(os.path.join(tmp, "r1"), paths["with_components"])
    for cell in ("<td>SUNDIALS</td>", "<td>6.4.1</td>", "<td>Debian source package, built in the tree</td>",
                 "<td>-O3 -DNDEBUG</td>", "<td>kneedyn</td>"):
      if cell not in html:
        errors.append(f"report with context.components: no {cell}")
    if "Components: not recorded" in html:
      errors.append("report with context.components says 'Components: not recorded'")
    html = make_report.bench_section(os.path.join(tmp, "r2"), paths["without_components"])
    if "Components: not recorded" not in html:
      errors.append("report without context.components does not say 'Components: not recorded'")
    if "2 runs drawn as failures" not in html:
      errors.append("report: the list of runs drawn as failures does not count 2")

    # 4a. The peer file: 2 rows timed in the --merge run, 1 copied from the merged sweep; the
    # provenance of both sweeps from their own headers, no '?'; the copied formulation marked.
    intro = make_report.peer_intro(paths["merged"])
    for want in ("Of the 3 runs in merged.json, 2 were timed in one process run", "The other 1 were copied in"):
      if want not in intro:
        errors.append(f"peer intro does not say {want!r}: {intro[:400]!r}")
    html = make_report.bench_section(os.path.join(tmp, "r4"), paths["merged"], "peer_", "peer", "peer")
    for want in ("this run (2 rows): short, repetitions 2, tightest run accuracy 1e-08",
                 "merged sweep work_precision.json (1 rows): short, repetitions 3, tightest run rtol 1e-06 "
                 "(--rtol-min 1e-11)", "2026-01-01T00:00:00Z", "commit c0ffee000002", "commit feedbeef0001",
                 "simbody_work_precision --short --merge wp.json --json wp.json"):
      if want not in html:
        errors.append(f"peer section's provenance does not say {want!r}")
    if "?" in html.split("<h3>")[0].replace("<dd>", "").split("Source")[1]:
      errors.append("peer section's provenance list has a '?'")
    panels = png_text(os.path.join(tmp, "r4", "figures", "peer_work_precision_cpu.png"))["Description"].splitlines()
    if panels != ["dae [--merge: other process]  (0 failed / wrong event)", "simbody  (1 failed / wrong event)"]:
      errors.append(f"peer panel titles do not mark the copied formulation: {panels}")

    # 4b. Two failed runs that differ only in their stabilization (ede:cvode-bdf at rtol 1e-3,
    # without and with cvode-projection) are two different rows of the failure list.
    stab_path = os.path.join(tmp, "stabilization.json")
    failing = dict(status="failed", reason="CVODE: too much work", events=[],
                   event_errors={"liftoff_lateral": None, "flexion_90": None})
    with open(stab_path, "w") as f:
      json.dump({"header": {"scene": "chapter_impact", "mode": "short"},
                 "results": [result("dae", "", {"rtol": 1e-6, "atol": 1e-8}, 5.0, 0.020),
                             result("ede", "cvode-bdf", {"rtol": 1e-3, "atol": 1e-5}, None, 0.01, **failing),
                             result("ede", "cvode-bdf", {"rtol": 1e-3, "atol": 1e-5,
                                                         "stabilization": "cvode-projection"}, None, 0.01,
                                    **failing)]}, f)
    _, stab_failed, _ = figures.make_work_precision(os.path.join(tmp, "r3"), stab_path)
    labels = sorted((key, setting) for key, setting, _ in stab_failed)
    if labels != [("ede / cvode-bdf", "rtol = 0.001"),
                  ("ede / cvode-bdf", "rtol = 0.001, stabilization = cvode-projection")]:
      errors.append(f"failures differing only in stabilization read as: {labels}")

    # 5. Bad input to the table: refused with exit 2, naming the file and the field.
    errors += bad_input_errors(tmp)
  return finish(errors, "work_precision_failures_test: FAIL:",
                "work_precision_failures_test: " + ("ok" if not errors else f"{len(errors)} failures"))


if __name__ == "__main__":
  sys.exit(main())
