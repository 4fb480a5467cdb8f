#!/usr/bin/python3
"""A verdict per claim that the reference solver does not reproduce, recorded in the repository
with its provenance (like benchmarks/recorded/), for the report's claims table and its
reading × claim matrix.

  claim_verdicts.py --report OUTDIR [--inverse reports/recorded/inverse_problem.json]
                    [--out reports/recorded/claims.json] [--command "the command that made OUTDIR"]
                    [--runtime-s SECONDS]
  claim_verdicts.py --run-study KNEEDYN --report OUTDIR ...   (runs report.py --reconstruction
                    into OUTDIR first and records its command and wall time; this is what
                    `cmake --build build --target claim_verdicts` does, about 1 min on 2 cores)

OUTDIR is a report directory made with the reconstruction study (report.py --reconstruction,
or `cmake --build build --target claim_verdicts`): OUTDIR/claims.json (the project's reading,
S1/S2 included) and OUTDIR/reconstruction/reconstruction.json (every reading).

Writes --out = {"claims": {id: {claim, verdict, explanation, evidence}}, "readings": [...],
"matrix": {...}, "headline": {...}, "command", "commit", "date"}. `explanation` is null for
a reproduced claim, else one of
  reading           some reading of the printed chapter (docs/model.md) reproduces it; the
                    evidence names the readings, the best one (fewest claims lost), its cost and
                    the statements no reading reproduces together with it;
  contradicted      no reading reproduces it and the chapter's own text excludes it (the other
                    statement named and quoted);
  beyond_precision  the inverse problem reaches it only with a change beyond the printed
                    precision (normalized change, from --inverse);
  unexplained       none of the above (the evidence says what was tried).
Exit 0 written; 2 bad input (nothing written).
"""
import argparse
import datetime
import json
import os
import subprocess
import sys
import time

sys.dont_write_bytecode = True  # keep the source tree clean
HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
sys.path.insert(0, os.path.join(ROOT, "benchmarks"))
sys.path.insert(0, HERE)
import tool_input  # noqa: E402
from record_sweep import git_commit  # noqa: E402  the recorded files' commit rule (-dirty), one copy
EXPLANATIONS = ("reading", "beyond_precision", "contradicted", "unexplained")
REPRODUCED = "reproduced"
LIFTOFF_CHAPTER_DEG = 66.0  # claims.yaml liftoff_chapter_deg

# Statements the chapter's own text excludes, whatever the reading: (claim, other statement,
# the words). S2 asks a 0.1 mm change of the contact-point guesses to move the motion, but the
# chapter requires the initial values to satisfy the contact and compatibility equations (its
# closing section) and finds the force guesses irrelevant (S1): with consistent initial values
# the contact points are fixed by the pose as the forces are by the hidden constraint.
TEXT_CONTRADICTIONS = {
    "S2": ("S1", "\"These initial values must satisfy the tibio-femoral contact and compatibility equations\" "
                 "(chapter, closing section) and S1 (force guesses do not matter, reproduced): a consistent start "
                 "fixes the contact points by the pose, so their guesses cannot move the motion. Only an "
                 "inconsistent start handed to the integrator could (the DASSL-start reading, not run here)."),
}


def informative(reading):
  """A reading whose reference member (A = 100 N, t0 = 0.1 s) reaches 90° of flexion and none
  of whose family members' runs failed (a member that completes short of 90° still counts):
  elsewhere most claims fail for want of the motion they describe. A reading that repeats an
  earlier one's scenes (`same_as`, reports/reconstruction.py) is not counted twice."""
  return reading.get("time_to_90_s") is not None and not reading.get("failed_members") and not reading.get("same_as")


def inverse_evidence(inverse, cid):
  """What the inverse problem needs to reach claim `cid` (its target's fit), or None. For C1,
  the lift-off the readings are fitted for, the headline scene's row of `readings_table`: the
  smallest change found that reaches 66° (the fit, the strain scan or the previous record's
  point run again; reports/inverse_problem.py)."""
  t = (inverse or {}).get("targets", {}).get(cid)
  row = next(iter((inverse or {}).get("readings_table") or []), None)
  if cid != "C1" or not row or not row.get("reached"):
    return t
  out = {"reached": True, "normalized_change": row["normalized_change"],
         "max_normalized_change": row["max_normalized_change"],
         "beyond_precision": row["max_normalized_change"] > 1.0,
         "fixes": row.get("fixes_vs_project"), "breaks": row.get("breaks_vs_project"), "method": row.get("method")}
  if row.get("method") == "fit" and t:
    out["parameters"] = t.get("parameters")
  if row.get("recorded_point"):
    out["recorded_point"] = row["recorded_point"]
  return out


def verdicts(rows, rec, inverse=None):
  """{id: {claim, verdict, explanation, evidence}} from the project's rows, the reconstruction
  summary and the inverse problem's targets (or None)."""
  base = {r["id"]: r for r in rows}
  readings = [r for r in rec["readings"] if informative(r)]
  project = next((r for r in rec["readings"] if r["key"] == "reconstructed/g_on"), None)
  project_ok = {c for c, v in (project or {}).get("verdicts", {}).items() if v == REPRODUCED}
  skipped = [r["key"] for r in rec["readings"] if not informative(r)]
  out = {}
  for cid, row in base.items():
    entry = {"claim": row.get("claim"), "verdict": row["verdict"], "explanation": None,
             "evidence": {"measured": row.get("measured")}}
    out[cid] = entry
    if row["verdict"] == REPRODUCED:
      losing = [r["key"] for r in readings if r["verdicts"].get(cid, REPRODUCED) != REPRODUCED]
      entry["evidence"]["readings_that_lose_it"] = losing
      continue
    ev = entry["evidence"]
    fixing = [r for r in readings if r["verdicts"].get(cid) == REPRODUCED]
    costs = {r["key"]: sorted(project_ok - {c for c, v in r["verdicts"].items() if v == REPRODUCED}) for r in fixing}
    gains = {r["key"]: sorted({c for c, v in r["verdicts"].items() if v == REPRODUCED} - project_ok) for r in fixing}
    ev["readings_tried"] = len(readings)
    ev["readings_not_informative"] = skipped
    if cid == "S2" and rec.get("s2_dassl_start"):
      ds = rec["s2_dassl_start"]
      ev["dassl_start_reading"] = ds
      reproduced = any(
          (t["max_dflexion_deg"] or 0.0) > 0.5 or
          (any(r["ok"] for r in t["runs"] if r["offset_mm"] == 0.0) and not all(r["ok"] for r in t["runs"]))
          for t in ds["tolerances"])
      if reproduced:
        entry["explanation"] = "reading"
        ev.update({"best_reading": "s2_dassl_start", "why": "under the chapter's DASSL start an offset of at most "
                   "0.1 mm changes the motion by more than 0.5° or breaks a run that starts without it"})
        continue
    if cid in TEXT_CONTRADICTIONS and not fixing:
      other, words = TEXT_CONTRADICTIONS[cid]
      entry["explanation"] = "contradicted"
      ev.update({"other_statement": other, "why": words})
      if cid == "S2" and rec.get("s2_dassl_start"):
        parts = []
        for t in rec["s2_dassl_start"]["tolerances"]:
          n_ok = sum(r["ok"] for r in t["runs"])
          parts.append(f"rtol {t['rtol']:g}: {n_ok}/{len(t['runs'])} runs complete"
                       + (f", max |Δflexion| {t['max_dflexion_deg']:.2g}° over offsets ≤ 0.1 mm"
                          if t["max_dflexion_deg"] is not None else "")
                       + ("" if n_ok else " (IDA refuses the inconsistent start at t = 0 for every offset, zero included)"))
        ev["why"] = words.replace("(the DASSL-start reading, not run here)", "(the DASSL-start reading, run: "
                                  + "; ".join(parts) + ")")
      continue
    if fixing:
      best = min(fixing, key=lambda r: (len(costs[r["key"]]), -len(gains[r["key"]])))
      # Statements of the chapter that no reading reproduces together with this one.
      together = set()
      for r in readings:
        if r["verdicts"].get(cid) == REPRODUCED:
          together |= {c for c, v in r["verdicts"].items() if v == REPRODUCED}
      never = sorted(c for c in project_ok if c not in together)
      entry["explanation"] = "reading"
      ev.update({"readings": [r["key"] for r in fixing], "best_reading": best["key"],
                 "best_reading_label": best["label"], "best_reading_docs_model_md": best.get("docs_model_md"),
                 "best_reading_liftoff_deg": best.get("liftoff_lateral_deg"),
                 "best_reading_loses": costs[best["key"]], "best_reading_also_fixes": gains[best["key"]],
                 "never_reproduced_together_with": never,
                 "why": (f"{len(fixing)} of {len(readings)} readings reproduce it; the one losing fewest of the "
                         f"project's reproduced claims ({best['key']}) loses {len(costs[best['key']])}"
                         + (f"; no reading reproduces it together with {', '.join(never)}" if never else ""))})
      t = inverse_evidence(inverse, cid)
      if t:  # what the inverse problem needs instead of the reading (evidence, not the verdict)
        ev["inverse_problem"] = {k: t.get(k) for k in ("reached", "normalized_change", "beyond_precision",
                                                       "fixes", "breaks", "method", "recorded_point") if k in t}
      continue
    t = inverse_evidence(inverse, cid)
    if t and t.get("reached") and t.get("beyond_precision"):
      entry["explanation"] = "beyond_precision"
      ev.update({"normalized_change": t.get("normalized_change"), "parameters": t.get("parameters"),
                 "fixes": t.get("fixes"), "breaks": t.get("breaks"), "source": "reports/recorded/inverse_problem.json",
                 "why": (f"no reading reproduces it; the inverse problem reaches it with a change of Tables "
                         f"1.1-1.3 of ||x|| = {t.get('normalized_change'):.1f} printed precisions, its largest "
                         f"|x_i| {t.get('max_normalized_change'):.1f} > 1")})
      continue
    entry["explanation"] = "unexplained"
    if t:
      ev["inverse_problem"] = {k: t.get(k) for k in ("reached", "normalized_change", "beyond_precision", "parameters")}
      ev["why"] = ("no reading reproduces it and the inverse problem "
                   + ("reaches it within the printed precision without a named reading"
                      if t.get("reached") else "does not reach it within its bounds"))
    elif inverse:
      targets = sorted((inverse.get("targets") or {}).keys())
      ev["why"] = ("no reading reproduces it; the inverse problem has no target for this claim (its targets: "
                   + (", ".join(targets) or "none") + ")")
    else:
      ev["why"] = "no reading reproduces it; the inverse problem was not run (reports/recorded/inverse_problem.json absent)"
  return out


def matrix(rec):
  """The reading × claim matrix: readings (rows) × claims (columns), 1 reproduced, 0 not,
  null not checkable; with each reading's lift-off angle."""
  ids = rec["claims"]
  rows = []
  for r in rec["readings"]:
    rows.append({"key": r["key"], "label": r["label"], "informative": informative(r), "same_as": r.get("same_as"),
                 "liftoff_lateral_deg": r.get("liftoff_lateral_deg"), "reproduced": r["counts"].get(REPRODUCED),
                 "cells": [1 if r["verdicts"].get(c) == REPRODUCED else
                           (0 if r["verdicts"].get(c) == "not reproduced" else None) for c in ids]})
  return {"claims": ids, "readings": rows}


def headline(rec):
  """Which reading moves the lateral lift-off towards 66° and what it costs."""
  project = next((r for r in rec["readings"] if r["key"] == "reconstructed/g_on"), None)
  if project is None or project.get("liftoff_lateral_deg") is None:
    return {"note": "the project's reading has no lift-off"}
  base = project["liftoff_lateral_deg"]
  ok0 = {c for c, v in project["verdicts"].items() if v == REPRODUCED}
  moves = []
  for r in rec["readings"]:
    lo = r.get("liftoff_lateral_deg")
    if lo is None or not informative(r) or r is project:
      continue
    ok = {c for c, v in r["verdicts"].items() if v == REPRODUCED}
    moves.append({"reading": r["key"], "liftoff_deg": lo, "towards_66_deg": abs(base - LIFTOFF_CHAPTER_DEG) - abs(lo - LIFTOFF_CHAPTER_DEG),
                  "loses": sorted(ok0 - ok), "gains": sorted(ok - ok0)})
  moves.sort(key=lambda m: -m["towards_66_deg"])
  return {"project_liftoff_deg": base, "chapter_liftoff_deg": LIFTOFF_CHAPTER_DEG, "by_reading": moves}


def main(argv=None):
  ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
  ap.add_argument("--report", required=True, help="report directory made with the reconstruction study")
  ap.add_argument("--inverse", default=os.path.join(HERE, "recorded", "inverse_problem.json"))
  ap.add_argument("--out", default=os.path.join(HERE, "recorded", "claims.json"))
  ap.add_argument("--command", help="the command that made --report (recorded)")
  ap.add_argument("--runtime-s", type=float, help="wall time of that command (recorded)")
  ap.add_argument("--run-study", metavar="KNEEDYN", help="run report.py --reconstruction with this binary first")
  args = ap.parse_args(argv)
  try:  # before the study runs: its inputs, the number recorded, the file written
    if args.run_study:
      tool_input.kneedyn_executable("--run-study", args.run_study)
    if args.runtime_s is not None:
      tool_input.number("--runtime-s", args.runtime_s, 0.0)
    tool_input.output_file("--out", args.out)
  except tool_input.BadInput as e:
    print(f"claim_verdicts: error: {e}", file=sys.stderr)
    return 2
  if args.run_study:
    cmd = [sys.executable, os.path.join(HERE, "report.py"), "--kneedyn", args.run_study, "--out", args.report,
           "--reconstruction"]
    start = time.monotonic()
    # The binary given, not a Python module found beside it (run_families.kneedyn_module).
    rc = subprocess.run(cmd, env=dict(os.environ, KNEEDYN_REPORT_RUNNER="subprocess")).returncode
    args.runtime_s = round(time.monotonic() - start, 1)
    if rc == 2:
      print("claim_verdicts: the study refused its input (report.py exit 2)", file=sys.stderr)
      return 2
    args.command = args.command or ("/usr/bin/python3 reports/report.py --kneedyn build/formulations/kneedyn "
                                    "--out build/readings --reconstruction")
  paths = {"claims": os.path.join(args.report, "claims.json"),
           "reconstruction": os.path.join(args.report, "reconstruction", "reconstruction.json")}
  for what, p in paths.items():
    if not os.path.exists(p):
      print(f"claim_verdicts: --report = '{args.report}': no {os.path.relpath(p, args.report)} "
            f"(run report.py --reconstruction first)", file=sys.stderr)
      return 2
  try:
    rows = tool_input.json_document("--report", paths["claims"], (dict, list))
    rows = rows["claims"] if isinstance(rows, dict) else rows
    if not isinstance(rows, list) or not all(isinstance(r, dict) for r in rows):
      raise tool_input.BadInput(f"--report: '{paths['claims']}': not report.py's claims.json (a list of claims)")
    rec = tool_input.json_object("--report", paths["reconstruction"])
    inverse = tool_input.json_object("--inverse", args.inverse) if os.path.exists(args.inverse) else None
  except tool_input.BadInput as e:
    print(f"claim_verdicts: error: {e}", file=sys.stderr)
    return 2
  if rec.get("quick"):
    print("claim_verdicts: warning: the reconstruction study ran in quick mode (reduced families)", file=sys.stderr)
  result = {"claims": verdicts(rows, rec, inverse), "matrix": matrix(rec), "headline": headline(rec),
            "inverse_problem": (os.path.relpath(args.inverse, ROOT) if inverse else
                                "not run (reports/recorded/inverse_problem.json absent)"),
            "quick": bool(rec.get("quick")),
            "command": args.command or "unknown", "runtime_s": args.runtime_s, "commit": git_commit(),
            "date": datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ"),
            "recorded_by": "reports/claim_verdicts.py"}
  os.makedirs(os.path.dirname(os.path.abspath(args.out)), exist_ok=True)
  with open(args.out, "w", encoding="utf-8") as f:
    json.dump(result, f, indent=1, ensure_ascii=False)
    f.write("\n")
  counts = {e: sum(v["explanation"] == e for v in result["claims"].values()) for e in EXPLANATIONS}
  print(f"claim_verdicts: {args.out}: {counts}")
  return 0


if __name__ == "__main__":
  sys.exit(main())
