#!/usr/bin/python3
"""The bounded inverse problem over scene files (a reading is a scene variant), with the
claims check at each fit.

  inverse_problem.py --inverse BIN --kneedyn BIN --out DIR --scenes S1 [S2 ...]
                     [--readings KEY,...|model] [--reading-targets C1] [--merge-recorded FILE]
                     [--recheck-recorded FILE] [--record FILE] [--targets C1,K6|none] [--folds A,B|none] [--max-iterations N]
                     [--no-strain-scan] [--quick] [--jobs N] [--parallel N] [--reuse] [--reuse-only]

Per scene: `kneedyn_inverse` (inverse/inverse_problem.hpp; one process per target and per
fold, --parallel at a time, merged into DIR/<scene>/fit.json) fits each target claim's
statements (inverse/inverse_problem.yaml) with the smallest change of the uncertain
quantities, normalized by their printed precision, and runs the leave-some-out folds. Then
the chapter's pulse families are run at the unchanged parameters and at each target's fit
(the fitted Tables 1.1-1.3 written as a parameter set beside the scene), and
reports/claims.py judges every claim on both: `fixes` are claims not reproduced before and
reproduced at the fit, `breaks` the reverse. The same claims check runs at each leave-some-out
fold's fit. S1/S2 (the sensitivity studies) are not re-run.

The strain scan (per scene and per reading; --no-strain-scan skips it, and the record's
`strain_scan` is then null): a derivative-free check of C1 (lateral lift-off at 66°, reached
within 1°) along one direction, every extension ratio shifted by s × its bound in
inverse/inverse_problem.yaml (0.0005) at once, s = 0, ±0.5, ±1, ±2, ±4, ±8, ±16 (one run of
the reference member each). On each side the first step that brackets 66° is bisected (up to
12 runs, to within 0.1°) and the claims are checked at the smallest |s| reached
(DIR/<scene>/strain_scan/): an upper bound on the smallest change reaching C1 that way.

The discrete readings are the outer choices (--readings): each reading of the reconstruction
study (reports/reconstruction.py READINGS, docs/model.md) becomes one scene, its reference
member A = 100 N, t0 = 0.1 s, and is fitted like a scene file, for --reading-targets only (C1,
lift-off 66°, by default; no folds). `model` = every model reading and the combinations the
Sobol' indices rank first. Per reading the record also compares the claims at the fit with
the project's reading (the first scene unchanged): `fixes_vs_project`, `breaks_vs_project`.
--merge-recorded keeps what an earlier record has and this run does not redo (readings,
targets), each entry marked with the earlier record's commit and date. --recheck-recorded runs
the points of an earlier record's target fits again at the current code, with the claims
check (`recorded_points_rechecked`): the fit is a local search whose path moves with the
solver, so a point found earlier that still reaches its target is a bound too.

Writes DIR/<scene>/fit.json (kneedyn_inverse's file), DIR/<scene>/<run>/ (families, claims)
and DIR/inverse_problem.json; with --record the same JSON also there (the first scene's
targets at the top level, every scene under `readings`). Exit 0 done, 1 a fit or a family
run failed, 2 bad input.
"""
import argparse
import concurrent.futures
import datetime
import json
import os
import subprocess
import sys
import time

import yaml

sys.dont_write_bytecode = True  # keep the source tree clean
HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
sys.path.insert(0, HERE)
sys.path.insert(0, os.path.join(ROOT, "benchmarks"))
import claims  # noqa: E402
import reconstruction  # noqa: E402
import run_families  # noqa: E402
import tool_input  # noqa: E402
from record_sweep import git_commit  # noqa: E402  the recorded files' commit rule (-dirty), one copy

SPEC = os.path.join(ROOT, "inverse", "inverse_problem.yaml")
SENSITIVITY_IDS = {"S1", "S2"}
# kneedyn sensitivity property -> parameter-set key (reference-data/chapter_knee.yaml) and index.
PROPERTY_KEYS = {"femoral_x": ("femoral_mm", 0), "femoral_y": ("femoral_mm", 1), "femoral_z": ("femoral_mm", 2),
                 "tibial_x": ("tibial_mm", 0), "tibial_y": ("tibial_mm", 1), "tibial_z": ("tibial_mm", 2),
                 "extension_ratio": ("extension_ratio", None), "k_linear": ("k_linear_N_mm", None),
                 "k_parabolic": ("k_parabolic_N_mm2", None)}


def scene_key(path):
  return os.path.splitext(os.path.basename(path))[0]


def load_scene(path):
  with open(path) as f:
    scene = yaml.safe_load(f)
  scene["parameter_set"] = os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(path)),
                                                         scene["parameter_set"]))
  return scene


def fitted_scene(scene, changes, path):
  """`scene` (a dict) with `changes` ({sensitivity name: change in its units}) added: the
  parameter set is written to `path` with the changes; where the scene overrides a ligament's
  stiffness or extension ratio (ligament_parameters, e.g. the reading of Table 1.2 as
  labelled) the override carries the change instead, since it wins over the parameter set
  (scene/ligaments.cpp). Returns the new scene dict."""
  with open(scene["parameter_set"]) as f:
    pset = yaml.safe_load(f)
  out = json.loads(json.dumps(scene))
  overrides = out.get("ligament_parameters") or {}
  by_name = {l["name"].replace(" ", "_"): l for l in pset["ligaments"]}
  for name, change in changes.items():
    element, prop = name.rsplit(".", 1)
    if element not in by_name or prop not in PROPERTY_KEYS:
      raise ValueError(f"fitted_scene: parameter '{name}': not a ligament property of {scene['parameter_set']}")
    key, idx = PROPERTY_KEYS[prop]
    lig = by_name[element]
    over = overrides.get(lig["name"], {})
    if idx is None and key in over:
      over[key] = float(over[key]) + change
    elif idx is None:
      lig[key] = float(lig[key]) + change
    else:
      lig[key] = [float(v) for v in lig[key]]
      lig[key][idx] += change
  with open(path, "w") as f:
    yaml.safe_dump(pset, f, sort_keys=False)
  out["parameter_set"] = path
  return out


def reading_scene(key, outdir):
  """The reference member (A = 100 N, t0 = 0.1 s) of reconstruction reading `key` written as a
  scene file under outdir (its parameter-set variant beside it). Returns (path, label)."""
  by = {k: (label, patch) for k, label, patch in reconstruction.READINGS}
  if key not in by:
    raise KeyError(key)
  rdir = os.path.join(outdir, "reading_scenes", key.replace("/", "__"))
  os.makedirs(os.path.join(rdir, "scenes"), exist_ok=True)
  label, patch = by[key]
  path = run_families.write_scene(rdir, "reference", run_families.BASE_AMPLITUDE_N, run_families.BASE_DURATION_S,
                                  patch=reconstruction.resolve_patch(patch, rdir))
  return path, label


def model_readings():
  """Every model reading alone, then the combinations the Sobol' indices rank first."""
  return ([f"model/{k}" for k, _, _, _ in reconstruction.MODEL_READINGS]
          + [reconstruction.combination(c)[0] for c in reconstruction.COMBINATIONS])


def run_claims(kneedyn, scene, rdir, quick, jobs):
  """Runs the pulse families of `scene` (a dict) into rdir and judges the claims."""
  for sub in ("scenes", "runs"):
    os.makedirs(os.path.join(rdir, sub), exist_ok=True)
  members = []
  for family, value, amp, dur in run_families.family_members(quick):
    name = run_families.member_name(family, value)
    s = json.loads(json.dumps(scene))
    s["name"] = name
    s["pulse"]["amplitude_N"] = float(amp)
    s["pulse"]["duration_s"] = float(dur)
    path = os.path.join(rdir, "scenes", name + ".yaml")
    with open(path, "w") as f:
      yaml.safe_dump(s, f, sort_keys=False)
    members.append((name, family, value, amp, dur, path))
  with concurrent.futures.ThreadPoolExecutor(max_workers=max(1, jobs)) as pool:
    res = list(pool.map(lambda m: run_families.run_one(kneedyn, m[5], os.path.join(rdir, "runs", m[0])), members))
  fam = [{"name": n, "family": fa, "value": v, "amplitude_N": a, "duration_s": d, "run_dir": os.path.join("runs", n),
          "ok": r["ok"], "status": r["status"], "command": r["command"], "stderr": r["stderr"], "fallback": r["fallback"]}
         for (n, fa, v, a, d, _), r in zip(members, res)]
  with open(os.path.join(rdir, "families.json"), "w") as f:
    json.dump({"solver_args": run_families.SOLVER_ARGS, "output_interval_s": run_families.OUTPUT_INTERVAL_S,
               "quick": quick, "members": fam}, f, indent=1)
  ck = claims.Checker(rdir)
  claims.check_all(ck)
  verdicts = {r["id"]: r["verdict"] for r in ck.rows if r["id"] not in SENSITIVITY_IDS}
  return verdicts, [m["name"] for m in fam if not m["ok"]]


def compare(before, after):
  fixes = sorted(c for c, v in after.items() if v == claims.REPRODUCED and before.get(c) != claims.REPRODUCED)
  breaks = sorted(c for c, v in after.items() if v != claims.REPRODUCED and before.get(c) == claims.REPRODUCED)
  return fixes, breaks


def leave_some_out_summary(fit, fold):
  """Judged statements of one fold: residual before (x = 0) and at the fit."""
  f = fit["leave_some_out"].get(fold, {})
  out = {"fitted": f.get("fitted", []), "judged": f.get("judged", []),
         "normalized_change": f.get("normalized_change"), "max_normalized_change": f.get("max_normalized_change"),
         "fitted_reached": f.get("reached"), "parameters": f.get("parameters", {}), "judged_statements": {}}
  if "error" in f:
    out["error"] = f["error"]
  better = worse = inside_before = inside_after = 0
  for sid in out["judged"]:
    b = fit["baseline"].get(sid, {})
    a = f.get("judged_at_fit", {}).get(sid, {})
    rb, ra = b.get("residual"), a.get("residual")
    out["judged_statements"][sid] = {"target": b.get("target"), "value_before": b.get("value"),
                                     "value_at_fit": a.get("value"), "residual_before": rb, "residual_at_fit": ra}
    if rb is not None and ra is not None:
      better += abs(ra) < abs(rb)
      worse += abs(ra) > abs(rb)
      inside_before += abs(rb) <= 1.0
      inside_after += abs(ra) <= 1.0
  out.update({"judged_closer": better, "judged_further": worse, "judged_within_tolerance_before": inside_before,
              "judged_within_tolerance_at_fit": inside_after})
  return out


def scene_spec(kneedyn, scene_path, sdir):
  """The spec for one scene: inverse/inverse_problem.yaml, less the parameters the scene does
  not have (`kneedyn sensitivity --list`; e.g. k_parabolic under the C¹ law, which derives
  it). Returns (spec path, [names dropped])."""
  p = subprocess.run([kneedyn, "sensitivity", "--list", scene_path], capture_output=True, text=True)
  if p.returncode != 0:
    return SPEC, []  # the fit itself reports why the scene does not run
  have = {line.strip() for line in p.stdout.splitlines()}
  with open(SPEC) as f:
    spec = yaml.safe_load(f)
  dropped = [q["name"] for q in spec["parameters"] if q["name"] not in have]
  if not dropped:
    return SPEC, []
  spec["parameters"] = [q for q in spec["parameters"] if q["name"] in have]
  path = os.path.join(sdir, "inverse_problem.yaml")
  with open(path, "w") as f:
    yaml.safe_dump(spec, f, sort_keys=False, allow_unicode=True)
  return path, dropped


# Derivative-free check of C1 along one direction: every Table 1.3 extension ratio shifted by
# the same s × its bound (the strain readings are s = ±1; the Sobol' indices rank the strains
# first for the lift-off). It needs only `kneedyn run` (the hybrid simulator crosses a medial
# re-contact, which the sensitivities do not: RunSensitivity stops at a plastic impact), so it
# also runs on the readings the Ceres fit cannot start from. ||x|| = |s| sqrt(12).
STRAIN_SCAN_S = [0.0, -0.5, 0.5, -1.0, 1.0, -2.0, 2.0, -4.0, 4.0, -8.0, 8.0, -16.0, 16.0]
LIFTOFF_TARGET_DEG, LIFTOFF_REACH_DEG = 66.0, 1.0  # C1 in inverse_problem.yaml: reach 0.2 × 5°


def liftoff_at(args, scene, normalized, bounds, rdir):
  """Lateral lift-off (deg) of the reference member at the normalized change, by `kneedyn run`;
  None when the run fails or the condyle does not lift off."""
  os.makedirs(os.path.join(rdir, "scenes"), exist_ok=True)
  s = fitted_scene(scene, {n: x * bounds[n] for n, x in normalized.items() if x != 0.0},
                   os.path.join(rdir, "knee.yaml"))
  s["name"] = "reference"
  s["pulse"]["amplitude_N"] = run_families.BASE_AMPLITUDE_N
  s["pulse"]["duration_s"] = run_families.BASE_DURATION_S
  path = os.path.join(rdir, "scenes", "reference.yaml")
  with open(path, "w") as f:
    yaml.safe_dump(s, f, sort_keys=False)
  r = run_families.run_one(args.kneedyn, path, os.path.join(rdir, "run"))
  if not r["ok"]:
    return None
  return run_families.event_summary(os.path.join(rdir, "run"))["liftoff_lateral_deg"]


def mark_jumps(scan):
  """A final bracket whose ends still differ by more than 1° after the bisection (4096 times
  narrower than the scan step, unless it met 66° within 0.1°): the lift-off jumps there (a
  branch of the motion switches), so 66° may be stepped over rather than passed through."""
  for b in scan.get("brackets", []):
    b["jump"] = (b["s_hi"] != b["s_lo"] and b.get("liftoff_hi_deg") is not None
                 and abs(b["liftoff_hi_deg"] - b["liftoff_lo_deg"]) > LIFTOFF_REACH_DEG)
  return scan


def strain_scan(args, scene, bounds, rdir):
  """The smallest |s| on STRAIN_SCAN_S (either sign) whose segment from the previous same-sign
  point brackets 66°, refined by bisection to within 0.1°; an upper bound on the smallest
  change from this scene along the direction. Returns the scan record."""
  names = [n for n in bounds if n.endswith(".extension_ratio")]
  norm = lambda s_: {n: s_ for n in names}  # noqa: E731
  values = {}
  for k, s_ in enumerate(STRAIN_SCAN_S):
    values[s_] = liftoff_at(args, scene, norm(s_), bounds, os.path.join(rdir, f"s{k}"))
  out = {"direction": "every extension ratio e + s x bound (0.0005)", "parameters": names,
         "scan": [{"s": s_, "liftoff_deg": values[s_]} for s_ in STRAIN_SCAN_S], "reached": False}
  v0 = values[0.0]
  if v0 is not None and abs(v0 - LIFTOFF_TARGET_DEG) <= LIFTOFF_REACH_DEG:
    out.update(reached=True, s=0.0, liftoff_deg=v0, normalized_change=0.0)
    return out
  best = None
  for sign in (-1.0, 1.0):
    prev = 0.0
    for s_ in [x for x in STRAIN_SCAN_S if x * sign > 0]:
      a, b = values[prev], values[s_]
      if a is not None and b is not None and (a - LIFTOFF_TARGET_DEG) * (b - LIFTOFF_TARGET_DEG) <= 0:
        lo, hi, flo = prev, s_, a
        for k in range(12):
          mid = 0.5 * (lo + hi)
          fm = liftoff_at(args, scene, norm(mid), bounds, os.path.join(rdir, f"bisect_{sign:+.0f}_{k}"))
          if fm is None:
            break
          if abs(fm - LIFTOFF_TARGET_DEG) <= 0.1:
            lo = hi = mid
            flo = fm
            break
          if (flo - LIFTOFF_TARGET_DEG) * (fm - LIFTOFF_TARGET_DEG) <= 0:
            hi = mid
          else:
            lo, flo = mid, fm
        # the end of the final bracket nearer 66° (the two agree within 0.1° or 2^-12 of the step)
        cand = lo if abs(flo - LIFTOFF_TARGET_DEG) <= LIFTOFF_REACH_DEG else hi
        fc = flo if cand == lo else liftoff_at(args, scene, norm(cand), bounds, os.path.join(rdir, f"final_{sign:+.0f}"))
        fhi = fc if cand == hi else (flo if hi == lo else
                                     liftoff_at(args, scene, norm(hi), bounds, os.path.join(rdir, f"final_hi_{sign:+.0f}")))
        out.setdefault("brackets", []).append({"s_lo": lo, "liftoff_lo_deg": flo, "s_hi": hi, "liftoff_hi_deg": fhi})
        mark_jumps(out)
        if fc is not None and abs(fc - LIFTOFF_TARGET_DEG) <= LIFTOFF_REACH_DEG and (best is None or abs(cand) < abs(best[0])):
          best = (cand, fc)
        break
      prev = s_
  if best is not None:
    out.update(reached=True, s=best[0], liftoff_deg=best[1], normalized_change=abs(best[0]) * len(names) ** 0.5,
               max_normalized_change=abs(best[0]), beyond_precision=abs(best[0]) > 1.0,
               change_each_extension_ratio=best[0] * bounds[names[0]])
  return out


def split_list(text, everything):
  """'' -> everything, 'none' -> [], else the comma-separated items."""
  if text == "none":
    return []
  return [t for t in text.split(",") if t] if text else list(everything)


def run_fits(args, scene_path, sdir, fit_path, targets, folds, spec_path=SPEC):
  """kneedyn_inverse once per target and once per leave-some-out fold, --parallel at a time
  (independent fits: the same result as one process doing them in turn); merged into
  fit_path. With neither a target nor a fold, one run for the statements at x = 0 only.
  Returns (merged JSON or None, error text)."""
  jobs = [("target_" + t, ["--targets", t, "--folds", "none"]) for t in targets]
  jobs += [("fold_" + h, ["--targets", "none", "--folds", h]) for h in folds]
  if not jobs:
    jobs = [("baseline", ["--targets", "none", "--folds", "none"])]
  base = [args.inverse, "--scene", os.path.abspath(scene_path), "--spec", spec_path,
          "--max-iterations", str(args.max_iterations)]

  def one(job):
    name, extra = job
    out = os.path.join(sdir, f"fit_{name}.json")
    cmd = base + ["--out", out] + extra
    if args.reuse_only and not os.path.exists(out):
      print(f"inverse_problem: {os.path.basename(sdir)}: {name}: no {out}, not run (--reuse-only)", flush=True)
      return name, cmd, 3, "not run (--reuse-only): no fit file", out
    if (args.reuse or args.reuse_only) and os.path.exists(out):
      # A fit run earlier (e.g. as its own process): its file is used as it is; the command
      # that made it is the first line of fit_<job>.cmd or of its log when there is one.
      for path in (os.path.join(sdir, f"fit_{name}.cmd"), os.path.join(sdir, f"fit_{name}.log")):
        if os.path.exists(path):
          with open(path) as f:
            first = f.readline().strip()
          if first and "kneedyn_inverse" in first.split(" ")[0]:
            cmd = first.split(" ")
            break
      print(f"inverse_problem: {os.path.basename(sdir)}: {name} reused", flush=True)
      return name, cmd, 0, "reused", out
    p = subprocess.run(cmd, text=True, stderr=subprocess.PIPE)
    with open(os.path.join(sdir, f"fit_{name}.log"), "w") as f:
      f.write(" ".join(cmd) + "\n" + p.stderr)
    print(f"inverse_problem: {os.path.basename(sdir)}: {name} exit {p.returncode}", flush=True)
    return name, cmd, p.returncode, p.stderr, out

  with concurrent.futures.ThreadPoolExecutor(max_workers=max(1, args.parallel)) as pool:
    results = list(pool.map(one, jobs))
  merged, errors = None, ""
  for name, cmd, rc, err, out in results:
    if rc != 0 or not os.path.exists(out):
      errors += f"{name}: exit {rc}: {err[-500:]}\n"
      continue
    with open(out) as f:
      part = json.load(f)
    if merged is None:
      merged = dict(part, targets={}, leave_some_out={}, runtime_s=0.0, runs=0, commands=[])
    merged["targets"].update(part.get("targets", {}))
    merged["leave_some_out"].update(part.get("leave_some_out", {}))
    merged["runtime_s"] += part.get("runtime_s", 0.0)
    if err == "reused":
      merged["reused_runtime_s"] = merged.get("reused_runtime_s", 0.0) + part.get("runtime_s", 0.0)
    merged["runs"] += part.get("runs", 0)
    merged["commands"].append(" ".join(os.path.relpath(c, ROOT) if os.path.isabs(c) and c.startswith(ROOT) else c
                                       for c in cmd))
  if merged is not None:
    merged["cpu_runtime_note"] = "runtime_s: the jobs' wall times summed (they ran --parallel at a time)"
    with open(fit_path, "w") as f:
      json.dump(merged, f, indent=1)
  return merged, errors



def claims_at_fit(args, scene, normalized, bounds, rdir, before):
  """Runs the pulse families at the normalized change `normalized` ({name: x_i}) of `scene`
  and judges the claims. Returns {claims_at_fit, fixes, breaks, liftoff by kneedyn run,
  failed_family_runs} (fixes/breaks against `before`)."""
  changes = {n: x * bounds[n] for n, x in normalized.items() if x != 0.0}
  os.makedirs(rdir, exist_ok=True)
  s = fitted_scene(scene, changes, os.path.join(rdir, "fitted_knee.yaml"))
  after, bad = run_claims(args.kneedyn, s, rdir, args.quick, args.jobs)
  fixes, breaks = compare(before, after)
  out = {"claims_at_fit": after, "fixes": fixes, "breaks": breaks, "failed_family_runs": bad,
         "reproduced_at_fit": sum(v == claims.REPRODUCED for v in after.values())}
  # The reference member (A = 100 N, t0 = 0.1 s) by `kneedyn run` at the fit: an
  # independent check of the lift-off the sensitivity driver fitted.
  ref_run = os.path.join(rdir, "runs", run_families.member_name("amplitude", run_families.BASE_AMPLITUDE_N))
  if os.path.exists(os.path.join(ref_run, "summary.json")):
    out["liftoff_lateral_deg_by_kneedyn_run"] = run_families.event_summary(ref_run)["liftoff_lateral_deg"]
  return out


def target_entry(t):
  """The recorded fields of one target's fit (kneedyn_inverse's JSON)."""
  entry = {"reached": bool(t.get("reached")), "normalized_change": t.get("normalized_change"),
           "max_normalized_change": t.get("max_normalized_change"),
           "beyond_precision": t.get("beyond_precision"), "parameters": t.get("parameters", {}),
           # The whole point (every x_i), so that a later record can re-check it (--recheck-recorded).
           "all_parameters_normalized": t.get("all_parameters_normalized"),
           "moved": t.get("moved"), "linearized": t.get("linearized"),
           "fitted_statements": t.get("fitted_statements"), "statements_at_fit": t.get("statements_at_fit"),
           "within_precision": {k: (t.get("within_precision") or {}).get(k)
                                for k in ("reached", "normalized_change", "max_normalized_change",
                                          "fitted_statements")},
           "fixes": [], "breaks": []}
  if "error" in t:
    entry["error"] = t["error"]
  return entry


def scene_dir(outdir, key):
  """DIR/<scene key, '/' as '__'>: a scene's fits, claims runs and re-checked points."""
  return os.path.join(outdir, key.replace("/", "__"))


def fit_scene(args, key, scene_path, outdir, targets, folds, bounds, project_before):
  """Fits, the claims check unchanged and at each fit, and the strain scan, of one scene.
  Returns (entry, failed): failed when a fit or a family run failed."""
  sdir = scene_dir(outdir, key)
  os.makedirs(sdir, exist_ok=True)
  t0 = time.monotonic()
  spec_path, dropped = scene_spec(args.kneedyn, scene_path, sdir)
  fit, err = run_fits(args, scene_path, sdir, os.path.join(sdir, "fit.json"), targets, folds, spec_path)
  fit_s = time.monotonic() - t0
  failed = bool(err)
  if err:
    print(f"inverse_problem: {key}: kneedyn_inverse failed: {err[-800:]}", file=sys.stderr)
  scene = load_scene(scene_path)
  t0 = time.monotonic()
  before, bad = run_claims(args.kneedyn, scene, os.path.join(sdir, "unchanged"), args.quick, args.jobs)
  failed |= bool(bad)
  ref = project_before if project_before is not None else before
  scan = None
  scan_file = os.path.join(sdir, "strain_scan", "scan.json")
  if args.strain_scan and (args.reuse or args.reuse_only) and os.path.exists(scan_file):
    with open(scan_file) as f:
      scan = mark_jumps(json.load(f))  # an earlier run's scan of this scene (--reuse); claims re-run below
    scan["reused"] = True
  elif args.strain_scan:
    t1 = time.monotonic()
    scan = strain_scan(args, scene, bounds, os.path.join(sdir, "strain_scan"))
    scan["runtime_s"] = time.monotonic() - t1
    with open(scan_file, "w") as f:
      json.dump(scan, f, indent=1)
  if scan is not None:
    t1 = time.monotonic()
    if scan.get("reached"):
      at = claims_at_fit(args, scene, {n: scan["s"] for n in scan["parameters"]}, bounds,
                         os.path.join(sdir, "strain_scan", "claims"), ref)
      scan.update({"claims_at_fit": at["claims_at_fit"], "reproduced_at_fit": at["reproduced_at_fit"],
                   "fixes_vs_project": at["fixes"], "breaks_vs_project": at["breaks"],
                   "liftoff_lateral_deg_by_kneedyn_run": at.get("liftoff_lateral_deg_by_kneedyn_run")})
    scan["claims_runtime_s"] = time.monotonic() - t1
    print(f"inverse_problem: {key}: strain scan: reached {scan['reached']}, s {scan.get('s')}, "
          f"|x| {scan.get('normalized_change')}", flush=True)
  rel_scene = os.path.relpath(os.path.abspath(scene_path), ROOT)
  common = {"scene": rel_scene, "claims_unchanged": before,
            "reproduced_unchanged": sum(v == claims.REPRODUCED for v in before.values()),
            "failed_family_runs_unchanged": bad, "strain_scan": scan, "fit_wall_s": fit_s,
            "spec": os.path.relpath(spec_path, ROOT) if spec_path.startswith(ROOT) else spec_path,
            "parameters_not_in_scene": dropped}
  if project_before is not None:
    common["fixes_vs_project"], common["breaks_vs_project"] = compare(project_before, before)
  if fit is None:
    return dict(common, error=err[-2000:]), True
  out_targets = {}
  for cid, t in fit.get("targets", {}).items():
    entry = target_entry(t)
    if t.get("all_parameters_normalized"):
      entry.update(claims_at_fit(args, scene, t["all_parameters_normalized"], bounds,
                                 os.path.join(sdir, "fit_" + cid), before))
      entry["fixes_vs_project"], entry["breaks_vs_project"] = compare(ref, entry["claims_at_fit"])
      failed |= bool(entry["failed_family_runs"])
    out_targets[cid] = entry
    print(f"inverse_problem: {key}: {cid}: reached {entry['reached']}, |x| {entry['normalized_change']}, "
          f"fixes {entry['fixes']}, breaks {entry['breaks']}", flush=True)
  lso = {}
  for fold, f in fit.get("leave_some_out", {}).items():
    lso[fold] = leave_some_out_summary(fit, fold)
    if f.get("all_parameters_normalized"):
      # The claims check at the fold's fit: the whole claims table, not only the judged half.
      lso[fold].update(claims_at_fit(args, scene, f["all_parameters_normalized"], bounds,
                                     os.path.join(sdir, fold), before))
      failed |= bool(lso[fold]["failed_family_runs"])
      print(f"inverse_problem: {key}: {fold}: claims fixed {lso[fold]['fixes']}, broken {lso[fold]['breaks']}",
            flush=True)
  entry = dict(common, targets=out_targets, fit_errors=err or None, baseline_statements=fit.get("baseline"),
               leave_some_out=lso, reused_fit_s=fit.get("reused_runtime_s", 0.0), fit_commands=fit.get("commands"),
               claims_runtime_s=time.monotonic() - t0, sensitivity_runs=fit.get("runs"), settings=fit.get("settings"))
  return entry, failed


def recheck_points(args, old, scene_path, sdir, bounds, before):
  """The target fits of an earlier record (its headline scene), run again at the current code:
  each point as recorded (every x_i, or the parameters it lists, those moved by at least a tenth
  of the largest, in records before the whole point was kept), with the claims check. A fit is
  a local search whose path moves with the solver; a point found earlier that still reaches its
  target bounds the smallest change too."""
  scene = load_scene(scene_path)
  out = {}
  for cid, t in sorted((old.get("targets") or {}).items()):
    whole = t.get("all_parameters_normalized")
    point = dict(whole) if whole else {n: v / bounds[n] for n, v in (t.get("parameters") or {}).items()}
    if not point:
      continue
    at = claims_at_fit(args, scene, point, bounds, os.path.join(sdir, "recheck_" + cid), before)
    norm = sum(x * x for x in point.values()) ** 0.5
    out[cid] = {"recorded_commit": old.get("commit"), "recorded_date": old.get("date"),
                "recorded_normalized_change": t.get("normalized_change"), "recorded_reached": t.get("reached"),
                "point": "every x_i" if whole else "the recorded parameters only (%d of %d)" % (len(point), len(bounds)),
                "normalized_change": norm, "max_normalized_change": max(abs(x) for x in point.values()),
                "liftoff_lateral_deg_by_kneedyn_run": at.get("liftoff_lateral_deg_by_kneedyn_run"),
                "reproduced_at_fit": at["reproduced_at_fit"], "fixes": at["fixes"], "breaks": at["breaks"],
                "failed_family_runs": at["failed_family_runs"]}
    print(f"inverse_problem: recorded {cid} point of {old.get('commit')}: |x| {norm:.2f}, lift-off "
          f"{out[cid]['liftoff_lateral_deg_by_kneedyn_run']}, fixes {at['fixes']}, breaks {at['breaks']}", flush=True)
  return out


def merge_recorded(readings, old):
  """Readings and targets of an earlier record that this run did not redo, each marked with
  the earlier record's provenance."""
  prov = {k: old.get(k) for k in ("command", "commit", "date")}
  for key, r in old.get("readings", {}).items():
    if key not in readings:
      readings[key] = dict(r, recorded_earlier=r.get("recorded_earlier", prov))
      continue
    new = readings[key]
    for cid, t in r.get("targets", {}).items():
      if cid not in new.get("targets", {}):
        new.setdefault("targets", {})[cid] = dict(t, recorded_earlier=t.get("recorded_earlier", prov))
    for fold, f in r.get("leave_some_out", {}).items():
      if fold not in new.get("leave_some_out", {}):
        new.setdefault("leave_some_out", {})[fold] = dict(f, recorded_earlier=f.get("recorded_earlier", prov))
  return readings


def readings_table(readings, first):
  """One row per reading: the lift-off unchanged, and the smallest change found that reaches 66°
  from it (the Ceres fit, the strain scan or, for the headline scene, the previous record's
  C1 point run again: whichever is smallest) with its cost in claims."""
  rows = []
  for key, r in readings.items():
    base = (r.get("baseline_statements") or {}).get("C1", {})
    c1 = (r.get("targets") or {}).get("C1", {})
    scan = r.get("strain_scan") or {}
    lo0 = base.get("value")
    if lo0 is None and scan.get("scan"):
      lo0 = scan["scan"][0]["liftoff_deg"]
    row = {"reading": key, "label": r.get("label"), "liftoff_deg_unchanged": lo0,
           "reproduced_unchanged": r.get("reproduced_unchanged"),
           "C1_fit_reached": c1.get("reached"), "C1_fit_normalized_change": c1.get("normalized_change"),
           "C1_fit_error": c1.get("error") or (base.get("error") if not c1 else None),
           "C1_within_precision_liftoff_deg":
               ((c1.get("within_precision") or {}).get("fitted_statements") or {}).get("C1", {}).get("value"),
           "strain_scan_reached": scan.get("reached"), "strain_scan_s": scan.get("s"),
           "strain_scan_normalized_change": scan.get("normalized_change"),
           "strain_scan_jumps": [b for b in scan.get("brackets", []) if b.get("jump")], "error": r.get("error")}
    options = []
    if c1.get("reached") and c1.get("normalized_change") is not None:
      options.append(("fit", c1["normalized_change"], c1.get("max_normalized_change"),
                      (c1.get("fitted_statements") or {}).get("C1", {}).get("value"), c1))
    if scan.get("reached"):
      options.append(("strain_scan", scan["normalized_change"], scan.get("max_normalized_change", 0.0),
                      scan.get("liftoff_deg"), scan))
    # The C1 point of the record this one replaced, run again (--recheck-recorded): reached
    # when kneedyn run's lift-off there is within C1's reach of 66°.
    again = (r.get("recorded_points_rechecked") or {}).get("C1") or {}
    lo_again = again.get("liftoff_lateral_deg_by_kneedyn_run")
    if lo_again is not None and abs(lo_again - LIFTOFF_TARGET_DEG) <= LIFTOFF_REACH_DEG:
      options.append(("recorded_point", again["normalized_change"], again["max_normalized_change"], lo_again, again))
    if options:
      how, n, mx, lo, src = min(options, key=lambda o: o[1])
      row.update({"reached": True, "method": how, "normalized_change": n, "max_normalized_change": mx,
                  "liftoff_deg_at_change": lo,
                  "reproduced_at_change": src.get("reproduced_at_fit",
                                                  sum(v == claims.REPRODUCED for v in src["claims_at_fit"].values())
                                                  if src.get("claims_at_fit") else None),
                  "recorded_earlier": src.get("recorded_earlier"),
                  "recorded_point": ({k: src.get(k) for k in ("recorded_commit", "recorded_date", "point")}
                                     if how == "recorded_point" else None),
                  "fixes_vs_project": src.get("fixes_vs_project", src.get("fixes") if key == first else None),
                  "breaks_vs_project": src.get("breaks_vs_project", src.get("breaks") if key == first else None)})
    else:
      row["reached"] = False
    rows.append(row)
  return rows


def headline(rows, first):
  """Which reading, or reading + smallest change, brings lift-off to 66° (C1), at what cost in
  claims against the project's reading (the first scene unchanged)."""
  def cost(r):
    return (f"{r.get('reproduced_at_change')} claims reproduced; fixes {', '.join(r.get('fixes_vs_project') or []) or 'none'}, "
            f"breaks {', '.join(r.get('breaks_vs_project') or []) or 'none'}")

  def change(r):
    jumps = r.get("strain_scan_jumps") if r.get("method") == "strain_scan" else None
    jump = (f"; on a jump of the lift-off: {jumps[0]['liftoff_lo_deg']:.1f}° at s = {jumps[0]['s_lo']:.5f}, "
            f"{jumps[0]['liftoff_hi_deg']:.1f}° at s = {jumps[0]['s_hi']:.5f}" if jumps else "")
    point = r.get("recorded_point") if r.get("method") == "recorded_point" else None
    origin = (f": the fit of the record of {point['recorded_date'][:10]} ({str(point['recorded_commit'])[:7]}), "
              f"run again" if point else "")
    return (f"||x|| = {r['normalized_change']:.2f} (largest |x_i| {r['max_normalized_change']:.2f}, "
            f"{'beyond' if r['max_normalized_change'] > 1.0 else 'within'} the printed precision; {r['method']}"
            f"{origin}{jump})")
  by = {r["reading"]: r for r in rows}
  out = []
  p = by.get(first)
  if p and p.get("liftoff_deg_unchanged") is not None:
    out.append(f"Project's reading: lift-off {p['liftoff_deg_unchanged']:.1f}°; "
               + (f"66° needs {change(p)}, {cost(p)}." if p.get("reached") else "66° not reached."))
  others = [r for r in rows if r["reading"] != first]
  reached = [r for r in others if r.get("reached")]
  if reached:
    best = min(reached, key=lambda r: r["normalized_change"])
    out.append(f"Smallest change from a reading: {best['reading']} (lift-off {best['liftoff_deg_unchanged']:.1f}° "
               f"unchanged) + {change(best)} gives {best['liftoff_deg_at_change']:.1f}°; {cost(best)}.")
    cheap = min(reached + ([p] if p and p.get("reached") else []),
                key=lambda r: (len(r.get("breaks_vs_project") or []), r["normalized_change"]))
    if cheap is not best:
      out.append(f"Fewest claims broken: {'the project' + chr(39) + 's reading' if cheap is p else cheap['reading']} "
                 f"+ {change(cheap)}; {cost(cheap)}.")
  failed = [r["reading"] for r in others if r.get("liftoff_deg_unchanged") is None]
  if others:
    out.append(f"{len(others)} readings tried, {len(reached)} reach 66°"
               + (f"; {len(failed)} do not run ({', '.join(failed)})" if failed else "") + ".")
  return " ".join(out)


def main(argv=None):
  ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
  ap.add_argument("--inverse", required=True, help="kneedyn_inverse binary")
  ap.add_argument("--kneedyn", required=True)
  ap.add_argument("--out", required=True)
  ap.add_argument("--scenes", nargs="+", required=True, help="scene files; the first is the headline")
  ap.add_argument("--readings", default="",
                  help="reconstruction readings to fit as outer choices (comma-separated keys of "
                       "reports/reconstruction.py READINGS, 'model': every model reading and the combinations, 'none')")
  ap.add_argument("--reading-targets", default="C1", help="targets fitted per reading ('none': the statements at x = 0 only)")
  ap.add_argument("--record", help="also write the result JSON here (reports/recorded/inverse_problem.json)")
  ap.add_argument("--merge-recorded", help="an earlier record: keep its readings, targets and folds not redone here")
  ap.add_argument("--recheck-recorded",
                  help="an earlier record: run its target fits' points again (claims check) -> recorded_points_rechecked")
  ap.add_argument("--targets", default="C1,K6,K7,V2,V4",
                  help="claim ids ('' = every claim with a statement, 'none' = no target); default: the statements "
                       "the unchanged model misses (C1, K6, K7, V2, V4)")
  ap.add_argument("--folds", default="A,B", help="leave-some-out folds of the scenes ('none': no fold)")
  ap.add_argument("--max-iterations", type=int, default=8)
  ap.add_argument("--no-strain-scan", dest="strain_scan", action="store_false",
                  help="skip the derivative-free C1 check along the uniform extension-ratio shift")
  ap.add_argument("--quick", action="store_true", help="reduced pulse families for the claims check")
  ap.add_argument("--jobs", type=int, default=os.cpu_count() or 1, help="family runs at a time (claims check)")
  ap.add_argument("--parallel", type=int, default=3, help="kneedyn_inverse processes at a time")
  ap.add_argument("--reuse", action="store_true",
                  help="use DIR/<scene>/fit_<job>.json where it exists instead of running that fit again")
  ap.add_argument("--reuse-only", action="store_true", help="as --reuse, and run no fit: a missing one is reported")
  args = ap.parse_args(argv)
  for flag, path in (("--inverse", args.inverse), ("--kneedyn", args.kneedyn)):
    if not os.access(path, os.X_OK):
      print(f"inverse_problem: {flag} = '{path}': not an executable file", file=sys.stderr)
      return 2
  for s in args.scenes:
    if not os.path.isfile(s):
      print(f"inverse_problem: --scenes: '{s}': no such file", file=sys.stderr)
      return 2
  with open(SPEC) as f:
    spec = yaml.safe_load(f)
  claim_ids = list(dict.fromkeys(st["claim"] for st in spec["statements"]))
  bounds = {p["name"]: p["bound"] for p in spec["parameters"]}
  reading_keys = (model_readings() if args.readings == "model"
                  else [] if args.readings == "none" else [k for k in args.readings.split(",") if k])
  known = {k for k, _, _ in reconstruction.READINGS}
  for flag, value, allowed in (("--targets", args.targets, claim_ids), ("--reading-targets", args.reading_targets, claim_ids),
                               ("--folds", args.folds, ["A", "B"]), ("--readings", ",".join(reading_keys), known)):
    bad = [v for v in split_list(value, allowed) if v not in allowed]
    if bad:
      print(f"inverse_problem: {flag}: '{bad[0]}' is none of {', '.join(sorted(allowed))}", file=sys.stderr)
      return 2
  try:  # the numbers and the files written, before any fit
    tool_input.number("--max-iterations", args.max_iterations, 1, 1000, integer=True)
    tool_input.number("--jobs", args.jobs, 1, 1024, integer=True)
    tool_input.number("--parallel", args.parallel, 1, 1024, integer=True)
    tool_input.output_directory("--out", args.out)
    if args.record:
      tool_input.output_file("--record", args.record)
  except tool_input.BadInput as e:
    print(f"inverse_problem: error: {e}", file=sys.stderr)
    return 2
  earlier = {}  # read before anything is written: either file may be the --record file itself
  for flag, path in (("--merge-recorded", args.merge_recorded), ("--recheck-recorded", args.recheck_recorded)):
    if path:
      try:
        with open(path) as f:
          earlier[flag] = json.load(f)
      except (OSError, ValueError) as e:
        print(f"inverse_problem: {flag} = '{path}': {e}", file=sys.stderr)
        return 2
  old = earlier.get("--merge-recorded")
  t_start = time.monotonic()
  outdir = os.path.abspath(args.out)
  os.makedirs(outdir, exist_ok=True)
  failed = False
  readings = {}
  first = scene_key(args.scenes[0])
  project_before = None
  for n, scene_path in enumerate(args.scenes):
    key = scene_key(scene_path)
    entry, bad = fit_scene(args, key, scene_path, outdir, split_list(args.targets, claim_ids),
                           split_list(args.folds, ["A", "B"]), bounds, project_before)
    readings[key] = entry
    failed |= bad
    if n == 0:
      project_before = entry.get("claims_unchanged")
      if "--recheck-recorded" in earlier and project_before is not None:
        entry["recorded_points_rechecked"] = recheck_points(
            args, earlier["--recheck-recorded"], scene_path, scene_dir(outdir, key), bounds, project_before)
  for key in reading_keys:
    path, label = reading_scene(key, outdir)
    entry, bad = fit_scene(args, key, path, outdir, split_list(args.reading_targets, claim_ids), [], bounds,
                           project_before)
    entry["label"] = label
    entry["docs_model_md"] = reconstruction.READING_DOCS.get(key)
    readings[key] = entry
    # A reading that does not run (the printed ω′y sign, the printed slope) or whose motion the
    # sensitivities cannot follow is a result, recorded in its entry, not a failure of the study.
    del bad
  if old is not None:
    readings = merge_recorded(readings, old)
  head = readings.get(first, {})
  table = readings_table(readings, first)
  result = {"targets": head.get("targets", {}),
            "leave_some_out": head.get("leave_some_out", {}),
            "recorded_points_rechecked": head.get("recorded_points_rechecked"),
            "readings": readings,
            "readings_table": table,
            "headline": headline(table, first),
            "spec": os.path.relpath(SPEC, ROOT),
            "normalization": "x_i = change_i / bound_i (inverse/inverse_problem.yaml: half a unit of the last printed "
                             "digit); normalized_change = ||x||_2; beyond_precision: max |x_i| > 1",
            "command": " ".join(["/usr/bin/python3"] + [os.path.relpath(a, ROOT) if os.path.isabs(a) and a.startswith(ROOT)
                                                         else a for a in [sys.argv[0]] + (argv if argv is not None
                                                                                          else sys.argv[1:])]),
            "commit": git_commit(),
            "date": datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ"),
            # This run's wall time plus the wall times of the fits it reused (--reuse), i.e. the
            # study's time with the fit processes counted one after the other.
            "runtime_s": time.monotonic() - t_start + sum(r.get("reused_fit_s", 0.0) for r in readings.values()
                                                          if "recorded_earlier" not in r),
            "runtime_note": "fits: one kneedyn_inverse process per target and per fold, run concurrently "
                            "(--parallel); runtime_s sums their wall times and adds the claims runs; entries with "
                            "recorded_earlier come from an earlier record (--merge-recorded) and are not in it",
            "quick": args.quick}
  for path in [os.path.join(outdir, "inverse_problem.json")] + ([args.record] if args.record else []):
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    with open(path, "w") as f:
      json.dump(result, f, indent=1, ensure_ascii=False)
      f.write("\n")
  print(f"inverse_problem: {len(readings)} scene(s) in {result['runtime_s']:.0f} s -> "
        f"{args.record or os.path.join(outdir, 'inverse_problem.json')}", flush=True)
  return 1 if failed else 0


if __name__ == "__main__":
  sys.exit(main())
