"""Work-precision sweep files read into one form, and the rules that decide which runs are
results: shared by the report's diagrams (figures.py, make_report.py) and
benchmarks/work_precision_table.py, so that a diagram and the table never disagree on which
runs failed. No plotting here (the table must not need matplotlib).

Files: benchmarks/work_precision.cpp's JSON (Google Benchmark's `context` and `benchmarks`
beside kneedyn's `header` and `results`; docs/outputs.md), the same after
crosscheck/simbody/simbody_work_precision --merge (`header`, `results` only), or Google
Benchmark's layout alone.
"""
import json
import math

from tool_input import BadInput, echo

# A run is drawn as a failure (not a point) when it failed, lacks a reference event, has
# contact events the reference lacks, or misses an event time by more than this. 1 ms is
# 0.5° of flexion at the end of the chapter run (α̇ ≈ 460°/s): any run whose positions
# carry 2 or more digits must place its events closer than that.
WRONG_EVENT_TIME_S = 1e-3
UNIT_TO_S = {"ns": 1e-9, "us": 1e-6, "ms": 1e-3, "s": 1.0}
COMPONENT_FIELDS = ("name", "version", "origin", "compile_flags")


def _parse_name(name):
  """Google-Benchmark name 'formulation[:integrator]/rtol=X[/...]' or '/step=X' -> parts."""
  parts = name.split("/")
  form, _, integ = parts[0].partition(":")
  setting = {}
  for p in parts[1:]:
    k, _, v = p.partition("=")
    if k in ("rtol", "atol", "step"):
      try:
        setting[k] = float(v)
      except ValueError:
        pass
  return form, integ, setting


def load_bench(path):
  """Benchmark JSON -> (header, [run dicts]) in one normalized form. Accepts
    (a) kneedyn's `results` [{formulation, integrator, setting, status, reason, metrics{scd,
        event_time_error_s}, cpu_time_s{median}, counters, events}] under {"header", ...} (or a
        bare list of such results). A file that has both `results` and Google Benchmark's
        `benchmarks` (what work_precision writes) is read from `results`: the `benchmarks`
        entries carry no status, and a failed run's `scd` counter there is 0, so read from
        them every failed run would be a point at scd 0;
    (b) Google Benchmark's own layout alone {"context", "benchmarks": [{name, run_name, run_type,
        aggregate_name, cpu_time, time_unit, <counters>, ...}]}: one run per run_name (the
        median aggregate if present, else the mean of the iterations); formulation, integrator
        and setting from the fields of the same name, else from the benchmark name; scd and
        event errors from fields `scd`, `metrics` or `event_time_error_s[.<event>]`; failures from
        `error_occurred` or `status`. Not work_precision's own entries alone (its context has
        `kneedyn_mode`): they mark no failure and carry no events, and are refused.
  A top-level "provenance" {command, commit, date} is passed through in the header, and
  `context.components` (the fairness manifest) as header["components"].
  Every field read is checked: a wrong type raises BadInput (a ValueError) naming the file
  and the field path, e.g. "'f.json': results[3].metrics.scd = 'x': must be a number or
  null"; so does a file with no results (no non-empty `results`, `runs` or `benchmarks`)."""
  with open(path, encoding="utf-8") as f:
    data = json.load(f)
  where = f"'{echo(path)}'"
  header = {}
  if isinstance(data, dict):
    for key in ("header", "context"):
      if data.get(key) is not None and not isinstance(data[key], dict):
        _bad(f"{where}: {key}", data[key], "an object")
    header = dict(data.get("header") or data.get("context") or {})
    if "provenance" in data:
      header["provenance"] = data["provenance"]
    context = data.get("context")
    if isinstance(context, dict) and "components" in context:
      header["components"] = context["components"]
    if isinstance(context, dict) and context.get("git_commit") and "git_commit" not in header:
      header["git_commit"] = context["git_commit"]
    _check_header(where, header)
    if not isinstance(data.get("results"), list) and isinstance(data.get("benchmarks"), list):
      if not data["benchmarks"]:
        raise BadInput(f"{where}: no results (its 'benchmarks' array is empty)")
      # work_precision's own Google Benchmark entries mark no failure (a failed run's scd
      # counter is 0) and carry no events: without its `results`, every failed and wrong-event
      # run would be drawn as a result. Such a file (its context names kneedyn_mode) is refused.
      if isinstance(context, dict) and "kneedyn_mode" in context:
        raise BadInput(f"{where}: work_precision's 'benchmarks' entries without its 'results': they mark no failed "
                       "run and carry no events, so failures and wrong events could not be counted; use the file "
                       "work_precision --json wrote, whole")
      return header, flag_above_ceiling(_from_google_benchmark(data["benchmarks"], where), scd_ceiling(header))
    key = "results" if "results" in data else "runs" if "runs" in data else None
    if key is None:
      raise BadInput(f"{where}: no results (neither a 'results' nor a 'benchmarks' array; "
                     f"keys: {echo(', '.join(map(str, data)) or 'none', 120)})")
    data = data[key]
    if not isinstance(data, list):
      _bad(f"{where}: {key}", data, "an array of results")
  elif isinstance(data, list):
    key = "results"
  else:
    raise BadInput(f"{where}: a JSON {_json_type(data)}, not a sweep (an object with 'results' or 'benchmarks')")
  if not data:
    raise BadInput(f"{where}: no results (its '{key}' array is empty)")
  runs = []
  for i, r in enumerate(data):
    runs.append(normalize_result(r, f"{where}: {key}[{i}]"))
    setting = runs[-1]["setting"]
    if not any(k in setting for k in ("step", "rtol", "accuracy")):
      raise BadInput(f"{where}: {key}[{i}].setting = {echo(json.dumps(setting))}: "
                     "has none of step, rtol or accuracy")
  return header, flag_above_ceiling(runs, scd_ceiling(header))


def _json_type(v):
  return {dict: "object", list: "array", str: "string", bool: "boolean", type(None): "null"}.get(
      type(v), "number" if isinstance(v, (int, float)) else type(v).__name__)


def _bad(field, value, what):
  """BadInput "field = value: must be what" (field: the file and the field path)."""
  shown = f"'{echo(value)}'" if isinstance(value, str) else echo(value if isinstance(value, float) else
                                                                 json.dumps(value, default=str))
  raise BadInput(f"{field} = {shown}: must be {what}")


def _is_number(v):
  return isinstance(v, (int, float)) and not isinstance(v, bool)


def _number(field, v, null=True):
  if (v is None and null) or _is_number(v):
    return v
  _bad(field, v, "a number or null" if null else "a number")


def _string(field, v, null=True):
  if (v is None and null) or isinstance(v, str):
    return v
  _bad(field, v, "a string or null" if null else "a string")


def _object(field, v, null=True):
  if (v is None and null) or isinstance(v, dict):
    return v
  _bad(field, v, "an object or null" if null else "an object")


# Numbers of a run's setting (work_precision, simbody_work_precision, instruction_sweep).
SETTING_NUMBERS = ("rtol", "atol", "step", "accuracy", "constraint_tolerance", "newton_rtol", "newton_atol",
                   "max_steps")


def _check_header(where, header):
  for k in ("scd_ceiling", "reference_accuracy_scd"):
    _number(f"{where}: header.{k}", header.get(k))


def check_result(r, where="result"):
  """Checks the types of the fields of one `results` entry that the readers use; raises
  BadInput naming `where` (e.g. "'f.json': results[3]") and the field (".metrics.scd")."""
  if not isinstance(r, dict):
    _bad(where, r, "an object (one run)")
  if "formulation" in r:
    _string(f"{where}.formulation", r["formulation"], null=False)
  for k in ("integrator", "status", "reason", "origin", "source", "engine", "timing"):
    _string(f"{where}.{k}", r.get(k))
  setting = _object(f"{where}.setting", r.get("setting")) or {}
  for k in SETTING_NUMBERS:
    if k in setting:
      _number(f"{where}.setting.{k}", setting[k], null=False)
  _string(f"{where}.setting.stabilization", setting.get("stabilization"))
  m = _object(f"{where}.metrics", r.get("metrics")) or {}
  _number(f"{where}.metrics.scd", m.get("scd"))
  ev = _object(f"{where}.metrics.event_time_error_s", m.get("event_time_error_s")) or {}
  for k, v in ev.items():
    _number(f"{where}.metrics.event_time_error_s.{k}", v)
  cpu = r.get("cpu_time_s")
  if isinstance(cpu, dict):
    _number(f"{where}.cpu_time_s.median", cpu.get("median"))
  else:
    _number(f"{where}.cpu_time_s", cpu)
  counters = _object(f"{where}.counters", r.get("counters")) or {}
  for k in ("residual_evaluations", "steps"):
    _number(f"{where}.counters.{k}", counters.get(k))
  events = r.get("events")
  if events is not None:
    if not isinstance(events, list):
      _bad(f"{where}.events", events, "an array or null")
    for j, e in enumerate(events):
      _object(f"{where}.events[{j}]", e, null=False)
      _string(f"{where}.events[{j}].name", e.get("name"), null=False)
  ins = _object(f"{where}.instructions", r.get("instructions")) or {}
  _number(f"{where}.instructions.run_scene", ins.get("run_scene"))
  return r


def scd_ceiling(header):
  """The highest scd the file's reference can measure: its stated accuracy minus one digit
  (`scd_ceiling` of work_precision's header; for files written before that field,
  `reference_accuracy_scd` − 1); None when neither is recorded. A run above it measures the
  reference's error, not its own: flagged (`above_ceiling`), drawn and tabulated as such."""
  c = header.get("scd_ceiling")
  if isinstance(c, (int, float)) and math.isfinite(c):
    return float(c)
  a = header.get("reference_accuracy_scd")
  if isinstance(a, (int, float)) and math.isfinite(a):
    return float(a) - 1.0
  return None


def flag_above_ceiling(runs, ceiling):
  """Sets r["above_ceiling"] on every run: its scd exceeds the ceiling (or the sweep flagged
  it, metrics.scd_above_ceiling). An exact result (scd +inf, metrics.scd_exact) is above any
  ceiling: drawn and tabulated at the ceiling, flagged, when the file states one."""
  for r in runs:
    if r.get("scd") == math.inf:
      r["above_ceiling"] = True
      if ceiling is not None:
        r["scd"] = ceiling
      continue
    scd = r.get("scd")
    over = (ceiling is not None and isinstance(scd, (int, float)) and math.isfinite(scd) and scd > ceiling)
    r["above_ceiling"] = bool(over or r.get("above_ceiling"))
  return runs


def normalize_result(r, where="result"):
  """One entry of a sweep's `results` in the form the readers use (cpu_s = median CPU time).
  Raises BadInput naming `where` and the field when a field has the wrong type (check_result)."""
  check_result(r, where)
  m = r.get("metrics") or {}
  cpu = r.get("cpu_time_s")
  cpu = cpu.get("median") if isinstance(cpu, dict) else cpu
  # Every compared position equal to the reference's: scd null with scd_exact true
  # (metrics.cpp); before, counted as a failure ("no scd").
  exact = m.get("scd") is None and m.get("scd_exact") is True
  return {"formulation": r.get("formulation", "?"), "integrator": r.get("integrator") or "",
          "setting": r.get("setting") or {}, "status": r.get("status", "ok"),
          "reason": r.get("reason") or "", "scd": math.inf if exact else m.get("scd"),
          "event_time_error_s": m.get("event_time_error_s") or {},
          "cpu_s": cpu, "residual_evaluations": (r.get("counters") or {}).get("residual_evaluations"),
          "steps": (r.get("counters") or {}).get("steps"),
          "events": r.get("events"), "origin": r.get("origin") or "kneedyn", "source": r.get("source"),
          # simbody_work_precision marks the rows it timed itself (not those --merge copied).
          "engine": r.get("engine"), "timing": r.get("timing"),
          "above_ceiling": bool(m.get("scd_above_ceiling")),
          # benchmarks/instruction_sweep.py's cost: instructions of RunScene (None elsewhere).
          "instructions": (r.get("instructions") or {}).get("run_scene")}


def is_score_file(name):
  """kneedyn score's output names (examples/outside_results.sh, `kneedyn score --out`)."""
  return name == "score.json" or (name.endswith(".score.json") and name != ".score.json")


def load_included(directory, scene=None, reference_primary=None):
  """Outside results under `directory` scored by `kneedyn score` (every score.json and
  *.score.json, in path order), normalized, with origin "outside" and their file as source.
  The same rule as `work_precision --include`: each file must be for `scene` and scored
  against the reference made by `reference_primary` (its command) when these are given.
  Raises ValueError naming the directory or the file."""
  import os
  if not os.path.isdir(directory):
    raise ValueError(f"--include = '{directory}': not a directory")
  paths = sorted(os.path.join(d, f) for d, _, fs in os.walk(directory) for f in fs if is_score_file(f))
  if not paths:
    raise ValueError(f"--include = '{directory}': no score.json or *.score.json (written by kneedyn score) under it")
  runs = []
  for path in paths:
    try:
      with open(path, encoding="utf-8") as f:
        data = json.load(f)
    except (OSError, ValueError) as e:
      raise ValueError(f"--include = '{directory}': '{path}': not JSON ({e})") from None
    except RecursionError:  # Python's json recurses per level: a traceback, not a refusal
      raise ValueError(f"--include = '{directory}': '{path}': JSON nested too deep to read") from None
    if not isinstance(data, dict) or not isinstance(data.get("header"), dict) or not isinstance(data.get("results"), list):
      raise ValueError(f"--include = '{directory}': '{path}': not kneedyn score's JSON (no header and results)")
    h = data["header"]
    if scene is not None and h.get("scene") != scene:
      raise ValueError(f"--include = '{directory}': '{path}': scored on scene '{h.get('scene')}', the sweep's is '{scene}'")
    if reference_primary is not None and h.get("reference_primary") != reference_primary:
      raise ValueError(f"--include = '{directory}': '{path}': scored against another reference (made by "
                       f"'{h.get('reference_primary')}'; the sweep's was made by '{reference_primary}')")
    for i, r in enumerate(data["results"]):
      if isinstance(r, dict):
        runs.append(normalize_result(dict(r, origin="outside", source=path), f"--include = '{directory}': '{path}': results[{i}]"))
  return runs


def reference_command(header):
  """The command that made a sweep's reference (header.reference_primary), or None."""
  prim = header.get("reference_primary")
  return prim.get("command") if isinstance(prim, dict) else prim


def _check_google_entry(e, where):
  """The types of the fields of one Google Benchmark entry that the reader uses."""
  _object(where, e, null=False)
  _string(f"{where}.name", e.get("name"), null=False)
  for k in ("run_name", "run_type", "aggregate_name", "time_unit", "formulation", "integrator"):
    _string(f"{where}.{k}", e.get(k))
  if e.get("time_unit") is not None and e["time_unit"] not in UNIT_TO_S:
    _bad(f"{where}.time_unit", e["time_unit"], "one of " + ", ".join(UNIT_TO_S))
  for k in ("cpu_time", "scd", "residual_evaluations"):
    _number(f"{where}.{k}", e.get(k))
  _object(f"{where}.setting", e.get("setting"))
  m = _object(f"{where}.metrics", e.get("metrics")) or {}
  _number(f"{where}.metrics.scd", m.get("scd"))
  for field, ev in ((f"{where}.metrics.event_time_error_s", m.get("event_time_error_s")),
                    (f"{where}.event_time_error_s", e.get("event_time_error_s"))):
    for k, v in (_object(field, ev) or {}).items():
      _number(f"{field}.{k}", v)
  for k, v in e.items():
    if k.startswith("event_time_error_s.") or k.startswith("event_time_error_s_"):
      _number(f"{where}.{k}", v)


def _from_google_benchmark(entries, where="benchmarks"):
  groups = {}
  for i, e in enumerate(entries):
    _check_google_entry(e, f"{where}: benchmarks[{i}]")
    if e.get("name"):
      groups.setdefault(e.get("run_name") or e["name"], []).append(e)
  runs = []
  for name, es in groups.items():
    med = [e for e in es if e.get("run_type") == "aggregate" and e.get("aggregate_name") == "median"]
    its = [e for e in es if e.get("run_type", "iteration") == "iteration"]
    e = med[0] if med else (its[0] if its else es[0])
    unit = UNIT_TO_S.get(e.get("time_unit", "ns"), 1e-9)
    if med:
      cpu = e.get("cpu_time")
      cpu = cpu * unit if isinstance(cpu, (int, float)) else None
    else:
      ts = [x["cpu_time"] * UNIT_TO_S.get(x.get("time_unit", "ns"), 1e-9) for x in its
            if isinstance(x.get("cpu_time"), (int, float))]
      cpu = sum(ts) / len(ts) if ts else None
    form, integ, setting = _parse_name(name)
    metrics = e.get("metrics") if isinstance(e.get("metrics"), dict) else {}
    ev = dict(metrics.get("event_time_error_s") or e.get("event_time_error_s") or {})
    for k, v in e.items():
      if k.startswith("event_time_error_s.") or k.startswith("event_time_error_s_"):
        ev[k[len("event_time_error_s") + 1:]] = v
    failed = bool(e.get("error_occurred")) or str(e.get("status", "ok")) not in ("ok", "completed")
    runs.append({"formulation": e.get("formulation", form), "integrator": e.get("integrator", integ) or "",
                 "setting": e.get("setting") if isinstance(e.get("setting"), dict) else setting,
                 "status": "failed" if failed else "ok",
                 "reason": e.get("error_message") or e.get("reason") or e.get("label") or "",
                 "scd": metrics.get("scd", e.get("scd")), "event_time_error_s": ev, "cpu_s": cpu,
                 "residual_evaluations": e.get("residual_evaluations"), "events": e.get("events")})
  return runs


TIMED_HERE, TIMED_MERGED, TIMED_OUTSIDE = "here", "merged", "outside"


def timed_where(r, header):
  """Where a run's CPU time was measured: TIMED_OUTSIDE (an outside driver's own clock),
  TIMED_MERGED (copied by simbody_work_precision --merge from another sweep: timed in that
  sweep's process; the rows timed in the --merge run itself carry `engine`), or TIMED_HERE
  (in the process that wrote the file)."""
  if r.get("origin") == "outside":
    return TIMED_OUTSIDE
  if header.get("merged_from") and not r.get("engine"):
    return TIMED_MERGED
  return TIMED_HERE


def build_commit(header):
  """The kneedyn commit the sweep binary was built from: header/context git_commit, else the
  kneedyn component's origin ("this repository, git <hash>"); None when the file has neither."""
  if isinstance(header.get("git_commit"), str) and header["git_commit"]:
    return header["git_commit"]
  for c in header.get("components") or []:
    origin = c.get("origin") if isinstance(c, dict) else None
    if isinstance(origin, str) and c.get("name") == "kneedyn" and " git " in f" {origin}":
      return origin.split("git ", 1)[1].split()[0] or None
  return None


def tightest_setting(runs):
  """The tightest setting of each kind among runs ("rtol 1e-08, accuracy 1e-08, h 5e-05"),
  or None when they have none."""
  parts = []
  for k, name in (("rtol", "rtol"), ("accuracy", "accuracy"), ("step", "h")):
    vals = [r["setting"][k] for r in runs if isinstance((r.get("setting") or {}).get(k), (int, float))]
    if vals:
      parts.append(f"{name} {min(vals):.3g}" + (" s" if k == "step" else ""))
  return ", ".join(parts) or None


def setting_str(s):
  """A run's setting as a reader writes it: fixed step, tolerance, or Simbody's accuracy, with
  the stabilization when there is one (ede:cvode-bdf at one rtol runs with none and with
  cvode-projection: without it the two rows of a failure table read alike)."""
  if "step" in s:
    text = f"h = {s['step']:.3g} s"
  elif "rtol" in s:
    text = f"rtol = {s['rtol']:.3g}"
  elif "accuracy" in s:
    text = f"accuracy = {s['accuracy']:.3g}"
  else:
    return json.dumps(s)
  if "max_steps" in s:
    text += f", max_steps = {s['max_steps']}"
  if s.get("stabilization"):
    text += f", stabilization = {s['stabilization']}"
  return text


def method_of(r):
  """formulation[:integrator][/stabilization]: one curve of the sweep."""
  name = r["formulation"] + (":" + r["integrator"] if r.get("integrator") else "")
  stab = (r.get("setting") or {}).get("stabilization")
  return name + ("/" + stab if stab else "")


def classify_run(r):
  """'ok', or the reason the run is drawn as a failure. The reference's events are the keys
  of event_time_error_s (one per reference event)."""
  if r["status"] != "ok":
    return f"failed: {r['reason'] or r['status']}"
  scd = _number("scd", r.get("scd"))
  for k, v in (_object("event_time_error_s", r.get("event_time_error_s")) or {}).items():
    _number(f"event_time_error_s.{k}", v)
  if scd is None or math.isnan(float(scd)) or float(scd) == -math.inf:
    return "no scd (comparison times missing: ended early or failed)"
  ev = r.get("event_time_error_s") or {}
  missing = [k for k, v in ev.items() if v is None or not math.isfinite(float(v))]
  if missing:
    return f"wrong events: reference event(s) {', '.join(missing)} missing"
  late = {k: float(v) for k, v in ev.items() if float(v) > WRONG_EVENT_TIME_S}
  if late:
    k = max(late, key=late.get)
    return f"wrong event time: {k} off by {late[k] * 1e3:.1f} ms (> {WRONG_EVENT_TIME_S * 1e3:g} ms)"
  if ev and r.get("events") is not None:
    # Ligament branch switches (kink_*) are not contact events: the sweep leaves them out of
    # its records, an outside solver's events.csv may list them.
    for j, e in enumerate(r["events"]):
      _string(f"events[{j}].name", e.get("name") if isinstance(e, dict) else e, null=False)
    extra = sorted({e["name"] for e in r["events"] if not e["name"].startswith("kink_")} - set(ev) - {"flexion_90"})
    if extra:
      return f"wrong events: {', '.join(extra)} not in the reference"
  return "ok"


def split_runs(runs):
  """(runs that are results, [(run, why)] drawn as failures) by classify_run."""
  ok, failed = [], []
  for r in runs:
    why = classify_run(r)
    if why == "ok":
      ok.append(r)
    else:
      failed.append((r, why))
  return ok, failed


def failure_counts(runs, key=lambda r: r["formulation"]):
  """{key(run): number of its runs drawn as failures} over every key that has runs."""
  counts = {}
  for r in runs:
    k = key(r)
    counts[k] = counts.get(k, 0) + (classify_run(r) != "ok")
  return counts


def event_digits(r):
  """Event-time digits: −log10 of the largest |t − t_ref| [s] over the reference's events."""
  ev = [float(v) for v in (r.get("event_time_error_s") or {}).values() if v is not None]
  if not ev:
    return None
  worst = max(ev)
  return 16.0 if worst <= 0 else -math.log10(worst)


def bench_key(r):
  return f"{r.get('formulation', '?')} / {r.get('integrator') or '-'}"


def pareto_front(runs, cost="cpu_s"):
  """The runs on the work-precision front of `runs` (results only; pass one formulation's):
  for each accuracy s, the cheapest run with scd >= s is on the front. Returned in order of
  increasing scd (and increasing cost); a run costlier than one at least as accurate is not
  on it."""
  pts = [r for r in runs if isinstance(r.get(cost), (int, float)) and isinstance(r.get("scd"), (int, float))
         and math.isfinite(r["scd"]) and classify_run(r) == "ok"]
  front, cheapest = [], math.inf
  for r in sorted(pts, key=lambda r: (-r["scd"], r[cost])):  # most accurate first
    if r[cost] < cheapest:
      front.append(r)
      cheapest = r[cost]
  return front[::-1]


def components(header):
  """The fairness manifest (context.components) as rows [name, version, origin, compile_flags],
  None when the file does not record it, or a string saying why it cannot be read."""
  comps = header.get("components")
  if comps is None:
    return None
  if not isinstance(comps, list) or not all(isinstance(c, dict) for c in comps):
    return f"context.components is not a list of objects ({type(comps).__name__})"
  rows = []
  for c in comps:
    row = []
    for k in COMPONENT_FIELDS:
      v = c.get(k)
      row.append("—" if v in (None, "") else " ".join(map(str, v)) if isinstance(v, list) else str(v))
    rows.append(row)
  return rows
