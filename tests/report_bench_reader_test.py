#!/usr/bin/python3
"""The report's benchmark reader (reports/figures.py load_bench / classify_run) on hand-made
files: the work_precision layout ({header, results}) and Google Benchmark's own layout
({context, benchmarks}) must give the same runs, and failed / wrong-event runs must not be
plotted as points; every series of a work-precision figure has a colour of its own, the same
in every figure. And the numbers of the report's prose that come from data (the leg's
weight, the pulse's peak, generalized-α's lift-off error per step and the part of it the O(h²) term leaves). Values are typed in
here, not copied from a run.
"""
import json
import os
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.dont_write_bytecode = True
sys.path.insert(0, os.path.join(ROOT, "reports"))
from py_test_support import finish  # noqa: E402
import figures  # noqa: E402

RESULTS = {
    "header": {"scene": "chapter_impact", "mode": "full"},
    "provenance": {"command": "cmake --build build --target bench_record", "commit": "abc123", "date": "2026-01-01"},
    "results": [
        {"formulation": "mde", "integrator": "dopri5", "setting": {"rtol": 1e-6, "atol": 1e-8}, "status": "ok",
         "metrics": {"scd": 6.5, "event_time_error_s": {"liftoff_lateral": 2e-7, "flexion_90": 1e-7}},
         "cpu_time_s": {"median": 0.02, "min": 0.019, "max": 0.03}, "counters": {"residual_evaluations": 900}},
        {"formulation": "mde", "integrator": "euler", "setting": {"step": 5e-4}, "status": "ok",
         "metrics": {"scd": 1.2, "event_time_error_s": {"liftoff_lateral": 3e-3, "flexion_90": 0.017}},
         "cpu_time_s": {"median": 0.01}, "counters": {"residual_evaluations": 600}},
        {"formulation": "dae", "integrator": "", "setting": {"rtol": 1e-12}, "status": "failed",
         "reason": "IDASolve: error test failed", "metrics": {"scd": None, "event_time_error_s": {}},
         "cpu_time_s": {"median": 0.5}, "counters": {"residual_evaluations": 10}},
        {"formulation": "ede", "integrator": "rk4", "setting": {"step": 1e-3}, "status": "ok",
         "metrics": {"scd": 3.0, "event_time_error_s": {"liftoff_lateral": None, "flexion_90": 1e-5}},
         "cpu_time_s": {"median": 0.004}, "counters": {"residual_evaluations": 1200}},
    ]}

GOOGLE = {
    "context": {"scene": "chapter_impact", "mode": "full"},
    "provenance": RESULTS["provenance"],
    "benchmarks": [
        {"name": "mde:dopri5/rtol=1e-06/repeats:3", "run_name": "mde:dopri5/rtol=1e-06", "run_type": "iteration",
         "cpu_time": 21.0, "time_unit": "ms", "scd": 6.5, "residual_evaluations": 900},
        {"name": "mde:dopri5/rtol=1e-06_median", "run_name": "mde:dopri5/rtol=1e-06", "run_type": "aggregate",
         "aggregate_name": "median", "cpu_time": 20.0, "time_unit": "ms", "scd": 6.5, "residual_evaluations": 900,
         "event_time_error_s.liftoff_lateral": 2e-7, "event_time_error_s.flexion_90": 1e-7},
        {"name": "mde:euler/step=0.0005_median", "run_name": "mde:euler/step=0.0005", "run_type": "aggregate",
         "aggregate_name": "median", "cpu_time": 10000.0, "time_unit": "us", "scd": 1.2,
         "residual_evaluations": 600, "event_time_error_s": {"liftoff_lateral": 3e-3, "flexion_90": 0.017}},
        {"name": "dae/rtol=1e-12", "run_name": "dae/rtol=1e-12", "run_type": "iteration", "cpu_time": 5e8,
         "time_unit": "ns", "error_occurred": True, "error_message": "IDASolve: error test failed"},
        {"name": "ede:rk4/step=0.001_median", "run_name": "ede:rk4/step=0.001", "run_type": "aggregate",
         "aggregate_name": "median", "cpu_time": 4.0, "time_unit": "ms", "scd": 3.0, "residual_evaluations": 1200,
         "event_time_error_s.liftoff_lateral": None, "event_time_error_s.flexion_90": 1e-5},
    ]}


def summary(runs):
  return sorted((r["formulation"], r["integrator"], round(r["cpu_s"], 9), figures.classify_run(r).split(":")[0])
                for r in runs)


def ceiling_errors(tmp):
  """A planted score above the reference's ceiling (accuracy 7.0 → ceiling 6.0): dopri5's 6.5
  is flagged by the reader (from the header alone, as in files written before the sweep set
  metrics.scd_above_ceiling), marked in work_precision_table's best scd, and the diagrams
  still draw; euler's 1.2 is not flagged."""
  import importlib
  errors = []
  doc = json.loads(json.dumps(RESULTS))
  doc["header"]["reference_accuracy_scd"] = 7.0
  path = os.path.join(tmp, "ceiling.json")
  with open(path, "w") as f:
    json.dump(doc, f)
  header, runs = figures.load_bench(path)
  flagged = sorted(r["integrator"] for r in runs if r.get("above_ceiling"))
  if flagged != ["dopri5"]:
    errors.append(f"ceiling 6.0: flagged {flagged}, expected ['dopri5']")
  sys.path.insert(0, os.path.join(ROOT, "benchmarks"))
  table = importlib.import_module("work_precision_table").table(path)
  if not any(line.startswith("| mde:dopri5 |") and "| 6.50* |" in line for line in table):
    errors.append("work_precision_table: mde:dopri5's 6.50 not marked above the ceiling:\n" + "\n".join(table))
  if not any(line.startswith("Reference ceiling: scd 6.0") for line in table):
    errors.append("work_precision_table: no ceiling note")
  files, _, _ = figures.make_work_precision(os.path.join(tmp, "ceiling"), path)
  if len(files) != len(figures.WORK_PRECISION_FIGURES):
    errors.append(f"ceiling: {len(files)} diagrams")
  return errors


def exact_errors(tmp):
  """A planted exact result (scd null, scd_exact true: every compared position equals the
  reference's) is a result above the ceiling, not a failure: before, it was counted as "no
  scd" and the table's failed column and the figures' failure counts grew by one."""
  import importlib
  errors = []
  doc = json.loads(json.dumps(RESULTS))
  doc["header"]["reference_accuracy_scd"] = 7.0
  doc["results"].append(
      {"formulation": "ede", "integrator": "verner65", "setting": {"rtol": 1e-7, "atol": 1e-9}, "status": "ok",
       "metrics": {"scd": None, "scd_exact": True, "event_time_error_s": {"liftoff_lateral": 0.0, "flexion_90": 0.0}},
       "cpu_time_s": {"median": 0.003}, "counters": {"residual_evaluations": 500}})
  path = os.path.join(tmp, "exact.json")
  with open(path, "w") as f:
    json.dump(doc, f)
  _, runs = figures.load_bench(path)
  exact = [r for r in runs if r["integrator"] == "verner65"]
  if len(exact) != 1 or figures.classify_run(exact[0]) != "ok" or not exact[0].get("above_ceiling") \
      or exact[0]["scd"] != 6.0:
    errors.append(f"exact run read as {[(figures.classify_run(r), r.get('scd'), r.get('above_ceiling')) for r in exact]}, "
                  "expected ok at the ceiling 6.0, flagged")
  sys.path.insert(0, os.path.join(ROOT, "benchmarks"))
  table = importlib.import_module("work_precision_table").table(path)
  if not any(line.startswith("| ede:verner65 | 1 | 0 | 6.00* |") for line in table):
    errors.append("work_precision_table: the exact run is not a result at the ceiling:\n" + "\n".join(table))
  _, failed, _ = figures.make_work_precision(os.path.join(tmp, "exact"), path)
  if len(failed) != 3:  # dae, euler and rk4, as without the exact run
    errors.append(f"exact: {len(failed)} runs drawn as failures, expected 3: {[f[2] for f in failed]}")
  # A file that states no ceiling: the table says "exact", not "inf".
  del doc["header"]["reference_accuracy_scd"]
  with open(path, "w") as f:
    json.dump(doc, f)
  table = importlib.import_module("work_precision_table").table(path)
  if not any(line.startswith("| ede:verner65 | 1 | 0 | exact* |") for line in table):
    errors.append("work_precision_table without a ceiling: the exact run is not shown as exact:\n" + "\n".join(table))
  return errors


def registered_formulations():
  """The names formulations/registry.cpp registers (read from the source: a second list, not
  the report's)."""
  import re
  with open(os.path.join(ROOT, "formulations", "registry.cpp"), encoding="utf-8") as f:
    return re.findall(r'FormulationInfo\("([a-z0-9-]+)"', f.read())


def colour_errors(tmp):
  """Every series of a work-precision figure has its own colour, at least 0.25 apart in RGB
  from any other drawn in it (the Simbody peer figure drew dae in tab10's orange and simbody in
  Dark2's, 0.20 apart), and a series keeps its colour from figure to figure (the main sweep's
  dae is the peer sweep's dae). Series: every registered formulation, Simbody, the outside
  solvers of examples/ and eight names the report does not know (the spares repeated after
  five)."""
  import itertools
  import math
  import matplotlib.colors as mc
  errors = []
  names = registered_formulations()
  if len(names) < 10 or "dae" not in names:
    return [f"formulations/registry.cpp: read {names}"]
  names += ["simbody", "scipy", "c-example", "c-rk4", "scipy-mde"]
  names += [f"unnamed-{i}" for i in range(6)]  # with c-rk4 and scipy-mde: 8 not in SERIES_COLOURS
  unknown = [n for n in names if n not in figures.SERIES_COLOURS]
  if len(unknown) < 8:
    return [f"expected 8 series outside SERIES_COLOURS, got {unknown}"]
  drawn = {}  # figure file -> [(series, rgb)]
  save = figures._save

  def capture(fig, path, title, panel_titles, **kw):
    series = []
    for ax in fig.axes:
      if os.path.basename(path).endswith("pareto.png"):
        handles, labels = ax.get_legend_handles_labels()
        series += [(lab.split(" ")[0], mc.to_rgb(h.get_color())) for h, lab in zip(handles, labels)
                   if not lab.startswith("reference")]
      elif ax.get_visible() and ax.get_title():  # one panel per formulation, titled in its colour
        series.append((ax.get_title().split(" ")[0], mc.to_rgb(ax.title.get_color())))
    drawn[os.path.basename(path)] = series
    save(fig, path, title, panel_titles, **kw)

  def sweep(forms, name):
    doc = {"header": {"scene": "chapter_impact", "mode": "short"}, "results": [
        {"formulation": f, "integrator": "", "setting": {"rtol": 1e-6}, "status": "ok",
         "metrics": {"scd": 6.0 + 0.1 * i, "event_time_error_s": {"liftoff_lateral": 1e-7, "flexion_90": 1e-7}},
         "cpu_time_s": {"median": 0.01 * (i + 1)}, "counters": {"residual_evaluations": 100}}
        for i, f in enumerate(forms)]}
    path = os.path.join(tmp, name + ".json")
    with open(path, "w") as f:
      json.dump(doc, f)
    drawn.clear()
    figures.make_work_precision(os.path.join(tmp, name), path)
    return dict(drawn)

  figures._save = capture
  try:
    peer = sweep(names, "colours_peer")
    main_sweep = sweep(["dae", "ede", "mde"], "colours_main")
  finally:
    figures._save = save
  for fig, series in peer.items():
    if sorted(n for n, _ in series) != sorted(names):
      errors.append(f"{fig}: series {sorted(n for n, _ in series)}, expected {sorted(names)}")
    for (a, ca), (b, cb) in itertools.combinations(series, 2):
      if math.dist(ca, cb) < 0.25:
        errors.append(f"{fig}: {a} and {b} drawn {math.dist(ca, cb):.3f} apart in RGB ({mc.to_hex(ca)}, {mc.to_hex(cb)})")
  for fig, series in main_sweep.items():
    for n, c in series:
      other = dict(peer.get(fig, [])).get(n)
      if other != c:
        errors.append(f"{fig}: {n} is {mc.to_hex(c)} without Simbody, {other and mc.to_hex(other)} with it")
  return errors


def calibration_peak_errors(tmp, scene):
  """The calibration's peak force is calibration.json's pulse_peak_factor (written by the C++,
  solver/loads.hpp PulsePeakFactor) × the fitted A: a planted factor of 0.25 for a half-sine
  (whose true factor is 1, what a re-derivation of the shape in Python would give) must
  show as 0.25 × 400 N = 100 N, 2.0× the scene's 50 N weight; without the field the report
  says the peak is not computed rather than deriving it."""
  import make_report
  errors = []
  res = {k: {"measured": 10.0, "target": 12.0, "residual": -0.4}
         for k in ("liftoff_lateral_deg", "crossing_t0_0.05_deg", "crossing_t0_0.2_deg",
                   "external_rotation_peak_deg", "max_varus_deg")}
  res.update(cost=0.4, failed_runs=0)
  cal = {"scene": scene, "pulse_shape": "half_sine", "amplitude_N": 100.0, "pulse_peak_factor": 0.25,
         "settings": {"formulation": "dae", "rtol": 1e-7}, "grid": [],
         "start": {"scale": 4.0, "theta_deg": 0.0, "cost": 0.5},
         "best": {"scale": 4.0, "theta_deg": 0.0, "pulse_amplitude_N": 400.0, "result": res}}
  for name, doc, want in (("planted", cal, "pulse peak ≈ 100 N, 2.0× the leg&#x27;s weight of 50.0 N"),
                          ("old", {k: v for k, v in cal.items() if k != "pulse_peak_factor"},
                           "pulse peak not computed: calibration.json has no pulse_peak_factor")):
    out = os.path.join(tmp, "cal_" + name)
    os.makedirs(os.path.join(out, "reconstruction"))
    with open(os.path.join(out, "reconstruction", "calibration.json"), "w") as f:
      json.dump(doc, f)
    text = make_report.calibration_part(out)
    if want not in text:
      errors.append(f"calibration_part ({name}): no {want!r} in {text[text.find('Best fit'):][:300]!r}")
  # A best fit whose motion never reaches 90° (the leg swings back) is said so, and the
  # plausibility verdict starts there; one whose runs all reach 90° says that.
  swinging = json.loads(json.dumps(cal))
  swinging["best"]["result"].update(runs_not_reaching_end_flexion=2, **{"max_flexion_deg_t0_0.1": 70.8})
  reaching = json.loads(json.dumps(cal))
  reaching["best"]["result"].update(runs_not_reaching_end_flexion=0, **{"max_flexion_deg_t0_0.1": 90.0})
  for name, doc, wants in (("swinging", swinging, ["2 of them never reach 90° (the t0 = 0.1 s run's largest flexion: 70.8°",
                                                   "<b>Plausibility:</b> the fitted motion is not the chapter's"]),
                           ("reaching", reaching, ["all three reach 90°"])):
    out = os.path.join(tmp, "cal_" + name)
    os.makedirs(os.path.join(out, "reconstruction"))
    with open(os.path.join(out, "reconstruction", "calibration.json"), "w") as f:
      json.dump(doc, f)
    text = make_report.calibration_part(out)
    for want in wants:
      if want not in text:
        errors.append(f"calibration_part ({name}): no {want!r} in {text[text.find('Best fit'):][:400]!r}")
  return errors


def prose_number_errors(tmp):
  """Numbers of the report's prose read or computed from data: the leg's weight from the
  scene (its parameter set, or its own override), the pulse's peak from calibration.json, and
  generalized-α's lift-off error at h and h/2 from the sweep's runs."""
  import make_report
  import methods_comparison
  errors = []
  ps = os.path.join(tmp, "params", "knee.yaml")
  os.makedirs(os.path.dirname(ps))
  with open(ps, "w") as f:
    f.write("body: {mass_kg: 5.0}\ngravity: {magnitude_m_s2: 10.0}\n")
  scenes = os.path.join(tmp, "scenes")
  os.makedirs(scenes)
  for name, extra, want in (("plain", "", 50.0), ("heavier", "body: {mass_kg: 2.0}\n", 20.0)):
    path = os.path.join(scenes, name + ".yaml")
    with open(path, "w") as f:
      f.write("parameter_set: ../params/knee.yaml\n" + extra)
    got = make_report.leg_weight_N(path)
    if got != want:
      errors.append(f"leg_weight_N({name}): {got}, expected {want}")
  if make_report.leg_weight_N(os.path.join(scenes, "missing.yaml")) is not None:
    errors.append("leg_weight_N of a missing scene is not None")
  errors += calibration_peak_errors(tmp, os.path.join(scenes, "plain.yaml"))

  def ga(h, err):
    return {"formulation": "generalized-alpha", "integrator": "", "setting": {"step": h}, "status": "ok",
            "metrics": {"scd": 4.0, "event_time_error_s": {"liftoff_lateral": err, "flexion_90": 1e-6}},
            "cpu_time_s": {"median": 0.1}, "events": None}
  text = methods_comparison.liftoff_order_text([ga(2e-4, 4e-5), ga(1e-4, 1e-5), ga(5e-5, 2.5e-6)],
                                               "generalized-alpha")
  if "1e-05 s at h = 0.0001 s, 2.5e-06 s at 5e-05 s, 4.00× smaller" not in text:
    errors.append(f"liftoff_order_text: {text!r}")
  text = methods_comparison.liftoff_order_text([ga(1e-4, 1e-5)], "generalized-alpha")
  if "no two" not in text:
    errors.append(f"liftoff_order_text with one run: {text!r}")
  # The event location's share of the lift-off error: runs whose lift-off is t_ref + C h² + δ(h)
  # with planted δ(1e-4) = +3e-8 s, δ(5e-5) = −1e-8 s: e(h) − 4 e(h/2) = δ(h) − 4 δ(h/2) = +7e-8 s
  # (C h² cancels), 0.7 % of e(1e-4) = 1e-5 + 3e-8 s; the pair nearest 1e-4 s is (1e-4, 5e-5).
  t_ref = 0.2

  def ga_at(h, delta):
    run = ga(h, abs(1000.0 * h * h + delta))
    run["events"] = [{"name": "liftoff_lateral", "time_s": t_ref + 1000.0 * h * h + delta},
                     {"name": "flexion_90", "time_s": 0.3}]
    return run
  text = methods_comparison.liftoff_location_text([ga_at(2e-4, 0.0), ga_at(1e-4, 3e-8), ga_at(5e-5, -1e-8)],
                                                  "generalized-alpha", t_ref)
  if "at h = 0.0001 s" not in text or "is +7e-08 s, 0.7% of e(h)" not in text:
    errors.append(f"liftoff_location_text: {text!r}")
  text = methods_comparison.liftoff_location_text([ga(1e-4, 1e-5), ga(5e-5, 2.5e-6)], "generalized-alpha", t_ref)
  if "no two" not in text:
    errors.append(f"liftoff_location_text without event times: {text!r}")
  return errors


def no_pulse_errors():
  """The Summary's A = 0 N row states the pulse's share of the motion from the runs: planted
  lift-offs 52.6° (member) and 52.0° (no pulse), t(90°) 0.299 s and 0.302 s, a family spanning
  50.0–54.0° and 0.290–0.302 s: +0.60°, −0.99 %, 4.00°, 4.0 %; without the run it says so."""
  import types
  import make_report
  errors = []
  ref = types.SimpleNamespace(liftoff_deg=52.6, time_to_90_s=0.299)
  members = [types.SimpleNamespace(liftoff_deg=lo, time_to_90_s=t) for lo, t in ((50.0, 0.302), (54.0, 0.290), (52.6, 0.299))]
  text = make_report.no_pulse_text({"ok": True, "liftoff_lateral_deg": 52.0, "time_to_90_s": 0.302}, ref, members)
  for want in ("lift-off by +0.60°", "time to 90° by -0.99 %", "lift-off spans 4.00°", "time to 90° 4.0 %"):
    if want not in text:
      errors.append(f"no_pulse_text: no {want!r} in {text!r}")
  if "not run" not in make_report.no_pulse_text(None, ref, members):
    errors.append("no_pulse_text without the run does not say it was not run")
  return errors


def main():
  errors = []
  with tempfile.TemporaryDirectory(prefix="kneedyn_bench_reader_") as tmp:
    got = {}
    for name, doc in (("results", RESULTS), ("google", GOOGLE)):
      path = os.path.join(tmp, name + ".json")
      with open(path, "w") as f:
        json.dump(doc, f)
      header, runs = figures.load_bench(path)
      got[name] = summary(runs)
      if header.get("provenance", {}).get("commit") != "abc123":
        errors.append(f"{name}: provenance not passed through: {header}")
      files, failed, _ = figures.make_work_precision(os.path.join(tmp, name), path)
      if len(files) != len(figures.WORK_PRECISION_FIGURES):
        errors.append(f"{name}: {len(files)} diagrams")
      whys = sorted(f[2].split(":")[0] for f in failed)
      # dopri5 is the only valid point: euler misses 90° by 17 ms, dae failed, rk4 lacks lift-off.
      if whys != ["failed", "wrong event time", "wrong events"]:
        errors.append(f"{name}: failures classified as {whys}")
    if got["results"] != got["google"]:
      errors.append(f"layouts disagree:\n  {got['results']}\n  {got['google']}")
    # work_precision's own file with its `results` removed: its Google Benchmark entries mark
    # no failure (scd 0) and carry no events, so it is refused rather than read as 0 failures
    # (it was: a probe's copy of the recorded sweep read "780 runs are results; 0 failed").
    recorded = os.path.join(ROOT, "benchmarks", "recorded", "work_precision_chapter_impact.json")
    with open(recorded, encoding="utf-8") as f:
      stripped = json.load(f)
    stripped.pop("results")
    path = os.path.join(tmp, "benchmarks_only.json")
    with open(path, "w") as f:
      json.dump(stripped, f)
    try:
      figures.load_bench(path)
      errors.append("work_precision's entries without its results were read")
    except ValueError as e:
      if "without its 'results'" not in str(e):
        errors.append(f"work_precision's entries without its results: {e}")
    expected = [("dae", "", 0.5, "failed"), ("ede", "rk4", 0.004, "wrong events"),
                ("mde", "dopri5", 0.02, "ok"), ("mde", "euler", 0.01, "wrong event time")]
    if got["results"] != expected:
      errors.append(f"results layout: {got['results']} != {expected}")
    errors += no_pulse_errors()
    errors += ceiling_errors(tmp)
    errors += exact_errors(tmp)
    errors += prose_number_errors(tmp)
    errors += colour_errors(tmp)
  return finish(errors, "report_bench_reader_test: FAIL:",
                "report_bench_reader_test: " + ("ok" if not errors else f"{len(errors)} failures"))


if __name__ == "__main__":
  sys.exit(main())
