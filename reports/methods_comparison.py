"""Report section: drift, digits reached and cost of the formulations that bring
their own integrator: the chapter's index-2 DAE (`dae`), its stabilized GGL form
(`dae-ggl`), Newmark's rule on the index-3 reverse EDE (`newmark`), generalized-α on the
same (`generalized-alpha`) and their closed-form-contact (`-reduced`) variants.

Which formulations: those `kneedyn formulations` lists without an `--integrator` choice (the
registry, so a new one appears here by itself); without a kneedyn binary, those of the sweep
JSON whose runs have no integrator. Which of them step with a fixed h: the sweep JSON's
settings (`step`), else the `settings.step_mode` of the run's summary.json.

Two sources, both named in the section:
  * live runs on the chapter scene, one typical setting each (about 0.5 s each):
    position-constraint drift (max |gap| over the output rows, the run's summary.json),
    the (first) lateral lift-off time against the stored reference, contact events beyond the
    reference's (spurious lift-off / re-contact), steps, residual evaluations, wall time;
  * the work-precision sweep JSON (--bench): best scd per method and the cheapest run
    reaching scd 4/6/8/10 (as benchmarks/work_precision_table.py), and generalized-α's lateral
    lift-off times at h and h/2: its O(h²) error and what that term leaves of it (the event
    location on the step's dense output and the higher-order terms).
"""
import html
import json
import os
import subprocess
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import bench_data  # noqa: E402  (which sweep runs count: the diagrams' rule)

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SCENE = os.path.join(ROOT, "reference-data", "scenes", "chapter_impact.yaml")
REFERENCE = os.path.join(ROOT, "reference-data", "references", "chapter_impact.json")
# One typical setting per kind of method: the adaptive ones at rtol 1e-8, the fixed-step ones
# at h = 1e-4 s (the chapter's step) with the sweep's Newton tolerance.
ADAPTIVE_SETTING = ["--rtol", "1e-8", "--atol", "1e-10"]
FIXED_STEP_SETTING = ["--step", "1e-4", "--rtol", "1e-9", "--atol", "1e-11"]
THRESHOLDS = (4, 6, 8, 10)


def esc(x):
  return html.escape(str(x))


def table(headers, rows):
  """A table in a horizontally scrolling box (make_report's CSS class `scroll`)."""
  out = ["<div class='scroll'><table><thead><tr>" + "".join(f"<th>{esc(h)}</th>" for h in headers) + "</tr></thead><tbody>"]
  for r in rows:
    out.append("<tr>" + "".join(f"<td>{esc(c)}</td>" for c in r) + "</tr>")
  out.append("</tbody></table></div>")
  return "\n".join(out)


def reference_events():
  with open(REFERENCE) as f:
    ref = json.load(f)
  return {e["name"]: e["time_s"] for e in ref["solution"]["events"]}


def builtin_integrator_methods(kneedyn=None, results=()):
  """The formulations that bring their own integrator (IDA, or a Newton step), in registry
  order: `kneedyn formulations` lines without an `--integrator` list, else the sweep's
  formulations whose runs have no integrator."""
  if kneedyn and os.path.exists(kneedyn):
    p = subprocess.run([kneedyn, "formulations"], capture_output=True, text=True)
    if p.returncode == 0:
      return [line.split()[0] for line in p.stdout.splitlines() if line.strip() and "--integrator" not in line
              and "needs a patella" not in line]
  return list(dict.fromkeys(r.get("formulation") for r in results if not r.get("integrator")))


def fixed_step_in_sweep(results, method):
  """True / False when the sweep has runs of the method (fixed step: its settings have a
  step), None when it has none."""
  settings = [r.get("setting") or {} for r in results if r.get("formulation") == method]
  return any("step" in s for s in settings) if settings else None


def run_live(kneedyn, run_dir, method, setting):
  cmd = [kneedyn, "run", SCENE, "--formulation", method, *setting, "--out", run_dir, "--quiet"]
  p = subprocess.run(cmd, capture_output=True, text=True)
  summary_path = os.path.join(run_dir, "summary.json")
  if p.returncode != 0 or not os.path.exists(summary_path):
    return p, None
  with open(summary_path) as f:
    return p, json.load(f)


def live_row(kneedyn, outdir, method, ref_events, fixed_step=None):
  """One live run; fixed_step None: the adaptive setting first, and the fixed-step one when
  the run's summary says the formulation stepped with a fixed h (its default step)."""
  run_dir = os.path.join(outdir, "methods", method)
  setting = FIXED_STEP_SETTING if fixed_step else ADAPTIVE_SETTING
  p, s = run_live(kneedyn, run_dir, method, setting)
  if fixed_step is None and s is not None and (s.get("settings") or {}).get("step_mode") == "fixed":
    setting = FIXED_STEP_SETTING
    p, s = run_live(kneedyn, run_dir, method, setting)
  if s is None:
    return [method, " ".join(setting), f"failed (exit {p.returncode}): {p.stderr.strip()[-200:]}",
            "", "", "", "", "", ""]
  events = s.get("events", [])
  lift = [e["time"] for e in events if e["name"] == "liftoff_lateral"]
  lift_err = f"{lift[0] - ref_events['liftoff_lateral']:+.2e}" if lift and "liftoff_lateral" in ref_events else "—"
  extra = len(events) - len(ref_events)
  st = s.get("statistics", {})
  cr = s.get("constraint_residuals", {})
  return [method, " ".join(setting), lift_err,
          "none" if extra == 0 else f"{extra:+d} (its {len(events)} events: {', '.join(e['name'] for e in events)})",
          f"{cr.get('max_gap_mm', float('nan')):.1e}", f"{cr.get('max_gap_rate_mm_s', float('nan')):.1e}",
          st.get("steps", ""), st.get("residual_evaluations", ""), f"{s.get('wall_time_s', float('nan')):.3f}"]


def completed_runs(results, method):
  """A method's runs of the sweep that count as results: completed with an scd and the
  reference's events (the rule of the work-precision diagrams, bench_data.classify_run)."""
  return [r for r in results if r.get("formulation") == method and r.get("status") == "ok"
          and isinstance((r.get("metrics") or {}).get("scd"), (int, float))
          and bench_data.classify_run(bench_data.normalize_result(r)) == "ok"]


def best_run(results, method):
  """The method's completed run with the highest scd, or None."""
  runs = completed_runs(results, method)
  return max(runs, key=lambda r: r["metrics"]["scd"]) if runs else None


def bench_rows(results, methods):
  rows = []
  for m in methods:
    runs = completed_runs(results, m)
    if not runs:
      n = sum(r.get("formulation") == m for r in results)
      rows.append([m, f"none of its {n} runs counts (failed or wrong event)" if n else "not in the sweep"]
                  + ["—"] * len(THRESHOLDS))
      continue
    best = best_run(results, m)
    cells = []
    for t in THRESHOLDS:
      ok = [r for r in runs if r["metrics"]["scd"] >= t]
      if not ok:
        cells.append("—")
        continue
      f = min(ok, key=lambda r: r["cpu_time_s"]["median"])
      cells.append(f"{f['cpu_time_s']['median']:.3f} ({setting_of(f)})")
    rows.append([m, f"{best['metrics']['scd']:.2f} ({setting_of(best)})"] + cells)
  return rows


def best_adaptive_sentence(results, method):
  best = best_run(results, method)
  if best is None:
    return f"{method}: no completed run in the sweep"
  return f"{method}'s best is scd {best['metrics']['scd']:.2f} at {setting_of(best)}"


def fixed_step_sentence(results, method, digits=6.0):
  """Best scd of a second-order fixed-step method and the step `digits` would take at order 2
  (scd grows by log10(4) per halving: h_digits = h_best · 10^(−(digits − scd_best)/2))."""
  best = best_run(results, method)
  if best is None or not best.get("setting", {}).get("step"):
    return f"{method}: no completed run in the sweep"
  h, scd = best["setting"]["step"], best["metrics"]["scd"]
  return (f"swept down to h = {h:g} s {method} reaches {scd:.2f}; {digits:g} digits would take "
          f"h ≈ {h * 10 ** (-(digits - scd) / 2):.1g} s")


def liftoff_order_text(results, method, near=1e-4):
  """The method's lateral lift-off time error at the sweep's step nearest `near` (the chapter's
  h) and at half of it, from the sweep's completed runs, and their ratio (4 at second order)."""
  runs = {r["setting"]["step"]: r["metrics"]["event_time_error_s"]["liftoff_lateral"]
          for r in completed_runs(results, method)
          if (r.get("setting") or {}).get("step")
          and isinstance(((r.get("metrics") or {}).get("event_time_error_s") or {}).get("liftoff_lateral"), (int, float))}
  pairs = [(h, h / 2) for h in runs if any(abs(k - h / 2) <= 1e-9 * h for k in runs)]
  if not pairs:
    return f"the sweep has no two {method} runs at h and h/2 with a lift-off to compare; see the live run below"
  import math
  h, _ = min(pairs, key=lambda p: abs(math.log(p[0] / near)))
  h2 = next(k for k in runs if abs(k - h / 2) <= 1e-9 * h)
  e, e2 = runs[h], runs[h2]
  ratio = f", {e / e2:.2f}× smaller at half the step" if e2 else ""
  return f"in the sweep {e:.2g} s at h = {h:g} s, {e2:.2g} s at {h2:g} s{ratio}"


def first_event_time(run, name):
  """Time [s] of the run's first event `name` (the sweep's `events`), or None."""
  return next((e.get("time_s") for e in run.get("events") or [] if e.get("name") == name
               and isinstance(e.get("time_s"), (int, float))), None)


def liftoff_location_text(results, method, reference_liftoff_s, near=1e-4):
  """The part of the method's lateral lift-off error that its O(h²) term does not explain, at the
  pair of steps liftoff_order_text uses: with signed errors e = t_run − t_ref (the runs' first
  liftoff_lateral against the reference), e(h) − 4 e(h/2) cancels C h² and leaves the event
  location on the step's dense output (where in the step the root lands) and the higher-order
  terms, together; their size next to e(h) is what the location can add."""
  import math
  times = {r["setting"]["step"]: first_event_time(r, "liftoff_lateral") for r in completed_runs(results, method)
           if (r.get("setting") or {}).get("step")}
  times = {h: t for h, t in times.items() if t is not None}
  pairs = [(h, k) for h in times for k in times if abs(k - h / 2) <= 1e-9 * h]
  if not pairs or not isinstance(reference_liftoff_s, (int, float)):
    return (f"the sweep has no two {method} runs at h and h/2 with lift-off times to separate the event location "
            "from the O(h²) error")
  h, h2 = min(pairs, key=lambda p: abs(math.log(p[0] / near)))
  e, e2 = times[h] - reference_liftoff_s, times[h2] - reference_liftoff_s
  rest = e - 4.0 * e2
  share = f", {abs(rest / e):.1%} of e(h)" if e else ""
  return (f"what the O(h²) term leaves of the error at h = {h:g} s, e(h) − 4 e(h/2) from the same runs' signed "
          f"lift-off times, is {rest:+.2g} s{share}: the event location on the step's dense output and the "
          "higher-order terms together")


def setting_of(r):
  s = r.get("setting", {})
  return f"h = {s['step']:g} s" if s.get("step") else f"rtol {s.get('rtol', 0):.2g}"


def section(outdir, kneedyn=None, bench=None):
  parts = ["<h2 id='methods'>Index-2, GGL, Newmark and generalized-α</h2>",
           "<p>The chapter's formulation (<code>dae</code>: velocity-level contact conditions, index 2, IDA) "
           "lets the positions drift off the contact surfaces between mode switches; <code>dae-ggl</code> "
           "enforces positions and velocities (Gear–Gupta–Leimkuhler, one extra multiplier per contact); "
           "<code>newmark</code> and <code>generalized-alpha</code> enforce the positions at every step "
           "(index 3, Newton at each step, fixed step h). Newmark's trapezoidal rule does not damp the "
           "index-3 error modes: the normal forces oscillate and the lateral lift-off comes early; "
           "generalized-α (ρ∞ = 0.9) damps them and its lift-off error is its second-order global error "]
  sweep, results = None, []
  if bench and os.path.exists(bench):
    with open(bench) as f:
      sweep = json.load(f)
    results = sweep.get("results", [])
  order = liftoff_order_text(results, "generalized-alpha")
  location = liftoff_location_text(results, "generalized-alpha", reference_events().get("liftoff_lateral"))
  # Without two runs at h and h/2 the first text already says so; the second would repeat it.
  parts[-1] += f"({esc(order)}" + ("" if location.startswith("the sweep has no two") else f"; {esc(location)}") + ").</p>"
  methods = builtin_integrator_methods(kneedyn, results)
  if kneedyn and os.path.exists(kneedyn):
    ref_events = reference_events()
    rows = [live_row(kneedyn, outdir, m, ref_events, fixed_step_in_sweep(results, m)) for m in methods]
    parts.append("<p>Chapter scene, one setting per method (live runs of this report): lift-off error against "
                 f"the stored reference ({ref_events.get('liftoff_lateral', float('nan')):.9f} s); contact events "
                 "beyond the reference's; drift = max |gap| and |gap rate| over the output rows.</p>")
    parts.append(table(["method", "setting", "lateral lift-off error [s]", "extra events", "max |gap| [mm]",
                        "max |gap rate| [mm/s]", "steps", "residual evaluations", "wall [s]"], rows))
  else:
    parts.append("<p>No kneedyn binary given; live comparison omitted.</p>")
  if sweep is not None:
    rtol_min = (sweep.get("header") or {}).get("rtol_min", "?")
    parts.append(f"<p>Digits and cost from the work-precision sweep (<code>{esc(os.path.basename(bench))}</code>): "
                 "best scd of the positions and the median CPU time of the cheapest run reaching scd 4/6/8/10, "
                 "over the runs the diagrams plot (a failed run, or one with a contact event the reference lacks, "
                 "without one it has, or more than 1 ms off, does not count). "
                 "The fixed-step methods gain 0.6 digits per step halving (second order): "
                 f"{esc(fixed_step_sentence(results, 'generalized-alpha'))}. The adaptive ones stop at "
                 f"the sweep's tightest rtol ({esc(rtol_min)}; {esc(best_adaptive_sentence(results, 'dae-ggl'))})."
                 "</p>")
    parts.append(table(["method", "best scd (setting)"] + [f"scd ≥ {t}: CPU s (setting)" for t in THRESHOLDS],
                       bench_rows(results, methods)))
  else:
    parts.append("<p>No benchmark JSON given; digits and cost omitted.</p>")
  return "\n".join(parts)
