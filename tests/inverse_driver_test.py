#!/usr/bin/python3
"""The inverse problem's Python driver (reports/inverse_problem.py), on a planted problem.

A stand-in `kneedyn_inverse` (written here) returns fits whose normalized changes x are
planted; a stand-in claims check judges two made-up claims from the parameter set the driver
writes: P ("LCL reference strain raised by at least 0.004") and Q ("LCL reference strain
raised by less than 0.003"), both read back from the written YAML. The answers follow from
the planted x, the bounds of inverse/inverse_problem.yaml and the chapter's Table 1.3 alone.

Validates:
- normalization: a fitted change is x_i × bound_i in the parameter's units, added to the
  parameter set the scene uses, or to the scene's ligament_parameters override where one wins
  (the reading of Table 1.2 as labelled), and nothing else moves;
- verdict assembly: `fixes`/`breaks` of a target's fit against the scene unchanged, and
  against the project's reading for a discrete reading (outer choice);
- the leave-some-out bookkeeping (fold split, closer/further counts) and the claims check at
  each fold's fit;
- the strain scan (the derivative-free C1 check along the uniform extension-ratio shift) on a
  planted linear lift-off: the root it finds and its ||x||;
- the reading loop (--readings), --merge-recorded provenance, --recheck-recorded (an earlier
  record's points run again: a partial point in its units, a whole one normalized), the
  commit rule shared with benchmarks/record_sweep.py, and exit 2 with nothing written on a
  bad --readings key.
Does not validate: the fit itself (inverse/tests: a planted change recovered by Ceres) or
the claim checks (tests/claims_checks_test.py).
"""
import json
import os
import shutil
import stat
import sys
import tempfile

import yaml

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.dont_write_bytecode = True
sys.path.insert(0, os.path.join(ROOT, "reports"))
sys.path.insert(0, os.path.join(ROOT, "benchmarks"))
import inverse_problem  # noqa: E402
import record_sweep  # noqa: E402
from py_test_support import finish  # noqa: E402

failures = []
SCENE = os.path.join(ROOT, "reference-data", "scenes", "chapter_impact.yaml")
LCL_E = 1.050            # Table 1.3, as printed
LCL_E_BOUND = 0.0005     # half a unit of its last digit
# Planted normalized changes: the C1 target moves the LCL e by +10 bounds (+0.005), fold A
# by +2 (+0.001), fold B moves MCL deep k_linear by −4 bounds (−0.02 N/mm).
PLANTED = {"target_C1": {"LCL.extension_ratio": 10.0, "ACL_anterior.femoral_y": -3.0},
           "fold_A": {"LCL.extension_ratio": 2.0},
           "fold_B": {"MCL_deep.k_linear": -4.0}}

FAKE_INVERSE = r'''#!/usr/bin/python3
import json, sys
a = dict(zip(sys.argv[1::2], sys.argv[2::2]))
planted = json.loads(%r)
job = ("target_" + a["--targets"]) if a["--targets"] != "none" else ("fold_" + a["--folds"])
out = {"scene": a["--scene"], "runtime_s": 1.5, "runs": 3, "settings": {"fake": True},
       "baseline": {"C1": {"value": 52.6, "target": 66.0, "residual": -2.68},
                    "K5": {"value": 30.0, "target": 30.0, "residual": 0.0},
                    "L2": {"value": 100.0, "target": 90.0, "residual": 0.5}},
       "targets": {}, "leave_some_out": {}}
fit = {"reached": True, "normalized_change": 1.0, "max_normalized_change": 1.0, "beyond_precision": True,
       "all_parameters_normalized": planted.get(job, {}),
       "fitted_statements": {"C1": {"value": 66.0, "target": 66.0}}}
if job.startswith("target_"):
    out["targets"][a["--targets"]] = fit
elif job.startswith("fold_"):
    # Fold A: K5 judged further (0 -> 2), L2 closer (0.5 -> 0.1). Fold B: C1 judged closer.
    judged = {"fold_A": {"K5": {"value": 40.0, "residual": 2.0}, "L2": {"value": 92.0, "residual": 0.1}},
              "fold_B": {"C1": {"value": 60.0, "residual": -1.2}}}[job]
    out["leave_some_out"]["fit_" + a["--folds"]] = dict(fit, fitted=["X"], judged=sorted(judged), judged_at_fit=judged)
with open(a["--out"], "w") as f:
    json.dump(out, f)
'''


def check(cond, msg):
  if not cond:
    failures.append(msg)


def lcl(pset):
  return next(l for l in pset["ligaments"] if l["name"] == "LCL")


def fake_claims(kneedyn, scene, rdir, quick, jobs):
  """P: LCL e raised by >= 0.004 over Table 1.3; Q: raised by < 0.003 (from the written file)."""
  with open(scene["parameter_set"]) as f:
    e = float(lcl(yaml.safe_load(f))["extension_ratio"])
  rise = e - LCL_E
  return ({"P": "reproduced" if rise >= 0.004 - 1e-12 else "not reproduced",
           "Q": "reproduced" if rise < 0.003 else "not reproduced"}, [])


def test_fitted_scene_normalization(tmp):
  scene = inverse_problem.load_scene(SCENE)
  with open(scene["parameter_set"]) as f:
    nominal = yaml.safe_load(f)
  changes = {"LCL.extension_ratio": 7.0 * LCL_E_BOUND, "ACL_anterior.femoral_y": -0.15, "MCL_deep.k_linear": 0.02}
  s = inverse_problem.fitted_scene(scene, changes, os.path.join(tmp, "knee.yaml"))
  with open(s["parameter_set"]) as f:
    fitted = yaml.safe_load(f)
  moved = []
  for a, b in zip(nominal["ligaments"], fitted["ligaments"]):
    for key in ("femoral_mm", "tibial_mm", "k_linear_N_mm", "k_parabolic_N_mm2", "extension_ratio"):
      va, vb = (a[key], b[key]) if isinstance(a[key], list) else ([a[key]], [b[key]])
      for i, (x, y) in enumerate(zip(va, vb)):
        if abs(float(x) - float(y)) > 0:
          moved.append((a["name"], key, i, float(y) - float(x)))
  want = {("LCL", "extension_ratio", 0): 0.0035, ("ACL anterior", "femoral_mm", 1): -0.15,
          ("MCL deep", "k_linear_N_mm", 0): 0.02}
  check(len(moved) == 3, f"fitted_scene moved {moved}, expected exactly {sorted(want)}")
  for name, key, i, d in moved:
    check(abs(d - want.get((name, key, i), float("nan"))) < 1e-12, f"fitted_scene: {name}.{key}[{i}] moved by {d}")
  # An override in the scene (Table 1.2 as labelled) wins over the parameter set: the change
  # must land on it.
  scene["ligament_parameters"] = {"MCL deep": {"k_linear_N_mm": 5.0, "k_parabolic_N_mm2": 21.07}}
  s = inverse_problem.fitted_scene(scene, {"MCL_deep.k_linear": 0.02}, os.path.join(tmp, "knee2.yaml"))
  check(abs(s["ligament_parameters"]["MCL deep"]["k_linear_N_mm"] - 5.02) < 1e-12,
        f"override not changed: {s['ligament_parameters']}")
  check(scene["ligament_parameters"]["MCL deep"]["k_linear_N_mm"] == 5.0, "fitted_scene changed its input scene")
  with open(s["parameter_set"]) as f:
    deep = next(l for l in yaml.safe_load(f)["ligaments"] if l["name"] == "MCL deep")
  check(deep["k_linear_N_mm"] == 21.07, f"overridden parameter-set value changed too: {deep['k_linear_N_mm']}")


def test_driver(tmp):
  fake = os.path.join(tmp, "kneedyn_inverse")
  with open(fake, "w") as f:
    f.write(FAKE_INVERSE % json.dumps(PLANTED))
  os.chmod(fake, os.stat(fake).st_mode | stat.S_IXUSR)
  inverse_problem.run_claims = fake_claims
  out = os.path.join(tmp, "out")
  earlier = os.path.join(tmp, "earlier.json")
  with open(earlier, "w") as f:
    json.dump({"command": "earlier command", "commit": "abc", "date": "2026-01-01T00:00:00Z",
               "readings": {"chapter_impact": {"targets": {"K9": {"reached": False}}},
                            "old/reading": {"targets": {}}},
               # Points to re-check: one as older records kept it (the moved parameters, in
               # their units: +9 bounds of the LCL e), one whole (+2 bounds).
               "targets": {"C1": {"reached": True, "normalized_change": 20.0,
                                  "parameters": {"LCL.extension_ratio": 9.0 * LCL_E_BOUND}},
                           "K6": {"reached": False, "normalized_change": 3.0,
                                  "all_parameters_normalized": {"LCL.extension_ratio": 2.0}}}}, f)
  rc = inverse_problem.main(["--inverse", fake, "--kneedyn", sys.executable, "--out", out, "--scenes", SCENE,
                             "--targets", "C1", "--readings", "model/strains_down", "--parallel", "1",
                             "--merge-recorded", earlier, "--recheck-recorded", earlier, "--no-strain-scan"])
  check(rc == 0, f"driver exit {rc}")
  with open(os.path.join(out, "inverse_problem.json")) as f:
    res = json.load(f)
  # Target C1 at +0.005 LCL e: P reproduced (0.005 >= 0.004), Q lost.
  c1 = res["targets"]["C1"]
  check(c1["fixes"] == ["P"] and c1["breaks"] == ["Q"], f"C1 fixes {c1['fixes']} breaks {c1['breaks']}")
  with open(os.path.join(out, "chapter_impact", "fit_C1", "fitted_knee.yaml")) as f:
    e = lcl(yaml.safe_load(f))["extension_ratio"]
  check(abs(e - (LCL_E + 10.0 * LCL_E_BOUND)) < 1e-12, f"fitted LCL e {e}, planted {LCL_E + 10 * LCL_E_BOUND}")
  # Fold A at +0.001: neither claim changes; fold B does not touch the LCL: neither.
  lso = res["leave_some_out"]
  check(set(lso) == {"fit_A", "fit_B"}, f"folds {sorted(lso)}")
  for fold in ("fit_A", "fit_B"):
    f = lso.get(fold, {})
    check(f.get("claims_at_fit") == {"P": "not reproduced", "Q": "reproduced"},
          f"{fold}: claims at the fold's fit {f.get('claims_at_fit')}")
    check(f.get("fixes") == [] and f.get("breaks") == [], f"{fold}: fixes {f.get('fixes')} breaks {f.get('breaks')}")
  a = lso.get("fit_A", {})
  check(a.get("judged_closer") == 1 and a.get("judged_further") == 1,
        f"fold A closer/further {a.get('judged_closer')}/{a.get('judged_further')}, expected 1/1 (L2 / K5)")
  check(a.get("judged_within_tolerance_before") == 2 and a.get("judged_within_tolerance_at_fit") == 1,
        f"fold A within tolerance {a.get('judged_within_tolerance_before')} -> {a.get('judged_within_tolerance_at_fit')}")
  check(lso.get("fit_B", {}).get("judged_closer") == 1, "fold B: C1 judged closer")
  # The reading e − 0.0005 everywhere, then the planted +0.005: rise 0.0045 -> P reproduced;
  # its unchanged state (rise −0.0005) keeps Q; against the project's reading: fixes P, breaks Q.
  r = res["readings"].get("model/strains_down", {})
  check(r.get("claims_unchanged") == {"P": "not reproduced", "Q": "reproduced"},
        f"reading unchanged claims {r.get('claims_unchanged')}")
  rc1 = r.get("targets", {}).get("C1", {})
  check(rc1.get("fixes_vs_project") == ["P"] and rc1.get("breaks_vs_project") == ["Q"],
        f"reading C1 vs project: fixes {rc1.get('fixes_vs_project')} breaks {rc1.get('breaks_vs_project')}")
  check(r.get("leave_some_out") == {}, "a reading ran folds (only the headline scene has them)")
  with open(os.path.join(out, "model__strains_down", "fit_C1", "fitted_knee.yaml")) as f:
    e = lcl(yaml.safe_load(f))["extension_ratio"]
  check(abs(e - (LCL_E - 0.0005 + 10.0 * LCL_E_BOUND)) < 1e-9, f"reading's fitted LCL e {e}")
  rows = {row["reading"]: row for row in res.get("readings_table", [])}
  check(set(rows) >= {"chapter_impact", "model/strains_down"}, f"readings_table rows {sorted(rows)}")
  check("model/strains_down" in res.get("headline", "") and "breaks Q" in res.get("headline", ""),
        f"headline does not name the reading reaching 66 deg and its cost: {res.get('headline')!r}")
  # Merged: an earlier target and reading kept, marked with the earlier record.
  k9 = res["readings"]["chapter_impact"]["targets"].get("K9", {})
  check(k9.get("recorded_earlier", {}).get("commit") == "abc", f"merged K9 {k9}")
  check(res["readings"].get("old/reading", {}).get("recorded_earlier", {}).get("command") == "earlier command",
        "merged reading lost its provenance")
  check("recorded_earlier" not in c1, "a target run now marked as recorded earlier")
  # The recorded points re-checked: +0.0045 (P reproduced: fixes P, breaks Q), +0.001 (none).
  re = res.get("recorded_points_rechecked") or {}
  rc1, rk6 = re.get("C1", {}), re.get("K6", {})
  check(rc1.get("fixes") == ["P"] and rc1.get("breaks") == ["Q"], f"rechecked C1 point: {rc1}")
  check(abs(rc1.get("normalized_change", 0) - 9.0) < 1e-9 and rc1.get("point", "").startswith("the recorded parameters"),
        f"rechecked C1 point: |x| {rc1.get('normalized_change')}, point {rc1.get('point')!r}")
  check(rc1.get("recorded_commit") == "abc" and rc1.get("recorded_normalized_change") == 20.0, f"provenance {rc1}")
  with open(os.path.join(out, "chapter_impact", "recheck_C1", "fitted_knee.yaml")) as f:
    e = lcl(yaml.safe_load(f))["extension_ratio"]
  check(abs(e - (LCL_E + 9.0 * LCL_E_BOUND)) < 1e-12, f"rechecked C1 point: LCL e {e}")
  check(rk6.get("fixes") == [] and rk6.get("breaks") == [] and rk6.get("point") == "every x_i"
        and abs(rk6.get("normalized_change", 0) - 2.0) < 1e-12, f"rechecked K6 point: {rk6}")
  check(c1.get("all_parameters_normalized") == PLANTED["target_C1"],
        f"the fit's whole point is not recorded: {c1.get('all_parameters_normalized')}")
  check(res["commit"] == record_sweep.git_commit(), f"commit {res['commit']!r} not record_sweep's rule")
  for k in ("command", "date", "runtime_s"):
    check(res.get(k) not in (None, ""), f"provenance '{k}' missing")
  # Bad input: exit 2, nothing written.
  bad_out = os.path.join(tmp, "bad")
  rc = inverse_problem.main(["--inverse", fake, "--kneedyn", sys.executable, "--out", bad_out, "--scenes", SCENE,
                             "--readings", "model/no_such_reading"])
  check(rc == 2 and not os.path.exists(bad_out), f"bad --readings: exit {rc}, wrote {os.path.exists(bad_out)}")


def test_strain_scan(tmp):
  """A planted lift-off, linear in the uniform strain shift s: 62.1° − 8.2° s (the stiffness
  reading's 62.1° at s = 0 and 70.3° at s = −1). 66° at s* = −3.9/8.2; the scan must bracket
  it on the negative side, bisect to within 0.1°, and report ||x|| = |s| sqrt(12) over the 12
  extension ratios, each moved by s × 0.0005."""
  seen = []

  def planted(args, scene, normalized, bounds, rdir):
    es = {n: x for n, x in normalized.items()}
    check(sorted(es) == sorted(n for n in bounds if n.endswith(".extension_ratio")) or not es,
          f"scan moved {sorted(es)}")
    s_ = next(iter(es.values())) if es else 0.0
    check(all(v == s_ for v in es.values()), "scan direction not uniform")
    seen.append(s_)
    return 62.1 - 8.2 * s_

  saved = inverse_problem.liftoff_at
  inverse_problem.liftoff_at = planted
  try:
    bounds = {p["name"]: p["bound"] for p in yaml.safe_load(open(inverse_problem.SPEC))["parameters"]}
    scan = inverse_problem.strain_scan(None, {}, bounds, tmp)
  finally:
    inverse_problem.liftoff_at = saved
  s_star = -3.9 / 8.2
  check(scan["reached"], f"strain scan did not reach 66 deg: {scan}")
  if scan["reached"]:
    check(abs(scan["liftoff_deg"] - 66.0) <= 0.1, f"scan lift-off {scan['liftoff_deg']}, want 66 within 0.1")
    check(abs(scan["s"] - s_star) <= 0.1 / 8.2 + 1e-12, f"scan s {scan['s']}, planted {s_star}")
    check(abs(scan["normalized_change"] - abs(scan["s"]) * 12 ** 0.5) < 1e-12, "||x|| is not |s| sqrt(12)")
    check(abs(scan["change_each_extension_ratio"] - scan["s"] * 0.0005) < 1e-15, "change per e is not s x 0.0005")
    check(scan["beyond_precision"] is False, "|s| < 1 reported beyond the printed precision")
    check(not any(b["jump"] for b in scan.get("brackets", [])), f"a linear lift-off reported as a jump: {scan}")
  # A step from 62° to 70° at s = −0.3: 66° is stepped over, not reached, and the bracket says so.
  inverse_problem.liftoff_at = lambda a, sc, normalized, b, r: 70.0 if next(iter(normalized.values()), 0.0) <= -0.3 else 62.0
  try:
    step = inverse_problem.strain_scan(None, {}, bounds, tmp)
  finally:
    inverse_problem.liftoff_at = saved
  br = step.get("brackets", [{}])[0]
  check(not step["reached"] and br.get("jump") and abs(br.get("s_lo", 0) + 0.3) < 1e-3,
        f"step lift-off: reached {step['reached']}, bracket {br}")
  # Never reaching 66° (flat at 52.6°): not reached, and no bisection.
  inverse_problem.liftoff_at = lambda *a: 52.6
  try:
    flat = inverse_problem.strain_scan(None, {}, bounds, tmp)
  finally:
    inverse_problem.liftoff_at = saved
  check(not flat["reached"] and len(flat["scan"]) == len(inverse_problem.STRAIN_SCAN_S), f"flat scan {flat}")


def test_smallest_change_among_fit_and_recorded_point():
  """The headline row takes the smallest change that reaches 66°: a fit at ||x|| 40 loses to the
  previous record's point run again at 22 when that lands within 1° of 66°, not when it misses."""
  def readings(liftoff_again):
    fit = {"reached": True, "normalized_change": 40.0, "max_normalized_change": 12.0,
           "fitted_statements": {"C1": {"value": 66.7}}, "reproduced_at_fit": 22, "fixes": ["C1"],
           "breaks": ["C2", "L12"]}
    again = {"recorded_commit": "0aa95ac50b1a", "recorded_date": "2026-12-02T14:16:07Z", "point": "every x_i",
             "normalized_change": 22.0, "max_normalized_change": 10.0,
             "liftoff_lateral_deg_by_kneedyn_run": liftoff_again, "reproduced_at_fit": 23, "fixes": ["C1"],
             "breaks": ["C2"]}
    return {"chapter_impact": {"baseline_statements": {"C1": {"value": 52.6}}, "targets": {"C1": fit},
                               "recorded_points_rechecked": {"C1": again}}}
  row = inverse_problem.readings_table(readings(66.6), "chapter_impact")[0]
  check(row.get("method") == "recorded_point" and row.get("normalized_change") == 22.0
        and row.get("breaks_vs_project") == ["C2"] and row.get("reproduced_at_change") == 23,
        f"a reaching earlier point at 22 not taken over the fit at 40: {row}")
  head = inverse_problem.headline([row], "chapter_impact")
  check("||x|| = 22.00" in head and "2026-12-02 (0aa95ac), run again" in head, f"headline: {head}")
  row = inverse_problem.readings_table(readings(64.5), "chapter_impact")[0]
  check(row.get("method") == "fit" and row.get("normalized_change") == 40.0,
        f"an earlier point 1.5° short of 66° taken: {row}")


def main():
  tmp = tempfile.mkdtemp(prefix="inverse_driver_test_")
  try:
    test_fitted_scene_normalization(tmp)
    test_strain_scan(tmp)
    test_driver(tmp)
    test_smallest_change_among_fit_and_recorded_point()
  finally:
    shutil.rmtree(tmp, ignore_errors=True)
  return finish(failures, "FAIL:", f"inverse_driver_test: {len(failures)} failure(s)", stream=sys.stdout)


if __name__ == "__main__":
  sys.exit(main())
