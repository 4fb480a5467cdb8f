#!/usr/bin/python3
"""The recorded verdicts (reports/recorded/claims.json, reports/claim_verdicts.py).

Validates: every claim of reports/claims.yaml is present; `explanation` is null exactly for a
reproduced claim and otherwise one of reading / beyond_precision / contradicted / unexplained;
the evidence is non-empty when it is not null (a `reading` names a reading the recorded matrix
shows reproducing the claim; `contradicted` names the other statement); the file has its
provenance (command, commit, date). And the classifier on a synthetic study whose answers are
known by construction: a claim one reading reproduces is `reading` (with that reading and its
cost), one the inverse problem reaches only beyond the printed precision is
`beyond_precision`, one nothing reaches is `unexplained` and says the inverse problem was not
run when it was not, and S2 without a reading is `contradicted` by S1; C1's inverse evidence is
the smallest change that reaches 66° (readings_table), an earlier record's point when that is
smaller than the fit. Which readings are
informative (claim_verdicts.informative), and that the report's matrix names the same ones.
Does not validate: that the study's runs are right (the report's tests and the claim checks do).
"""
import json
import os
import sys

import yaml

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.dont_write_bytecode = True
sys.path.insert(0, os.path.join(ROOT, "reports"))
import claim_verdicts  # noqa: E402

ALLOWED = {"reading", "beyond_precision", "contradicted", "unexplained"}
failures = []


def check(cond, msg):
  if not cond:
    failures.append(msg)


def recorded_file():
  path = os.path.join(ROOT, "reports", "recorded", "claims.json")
  check(os.path.exists(path), f"{path} missing")
  if not os.path.exists(path):
    return
  with open(path, encoding="utf-8") as f:
    rec = json.load(f)
  with open(os.path.join(ROOT, "reports", "claims.yaml"), encoding="utf-8") as f:
    ids = [c["id"] for c in yaml.safe_load(f)["claims"]]
  for k in ("command", "commit", "date"):
    check(rec.get(k) not in (None, "", "unknown"), f"provenance field '{k}' missing")
  claims = rec.get("claims", {})
  check(sorted(claims) == sorted(ids), f"claims differ from claims.yaml: {sorted(set(ids) ^ set(claims))}")
  matrix = rec.get("matrix", {})
  col = {c: j for j, c in enumerate(matrix.get("claims", []))}
  rows = {r["key"]: r for r in matrix.get("readings", [])}
  for cid, v in claims.items():
    e = v.get("explanation")
    if v.get("verdict") == "reproduced":
      check(e is None, f"{cid}: reproduced but explanation {e!r}")
      continue
    check(e in ALLOWED, f"{cid}: explanation {e!r} not in {sorted(ALLOWED)}")
    ev = v.get("evidence") or {}
    check(bool(ev) and bool(ev.get("why") or ev.get("best_reading")), f"{cid}: explanation {e} without evidence")
    if e == "reading":
      r = rows.get(ev.get("best_reading"))
      check(r is not None and cid in col and r["cells"][col[cid]] == 1,
            f"{cid}: best reading {ev.get('best_reading')!r} does not reproduce it in the recorded matrix")
    if e == "contradicted":
      check(bool(ev.get("other_statement")), f"{cid}: contradicted without the other statement")


def synthetic():
  def reading(key, ok, failed=()):
    return {"key": key, "label": key, "time_to_90_s": 0.3, "failed_members": list(failed), "liftoff_lateral_deg": 60.0,
            "verdicts": {c: ("reproduced" if c in ok else "not reproduced") for c in ("A", "B", "C", "D")},
            "counts": {"reproduced": len(ok)}}
  rec = {"claims": ["A", "B", "C", "D"],
         "readings": [reading("reconstructed/g_on", {"A"}), reading("model/x", {"B"}),
                      reading("model/broken", {"A", "B", "C", "D"}, failed=["amplitude_50"])]}
  rows = [{"id": c, "verdict": "reproduced" if c == "A" else "not reproduced"} for c in ("A", "B", "C", "D", "S1")]
  rows.append({"id": "S2", "verdict": "not reproduced"})
  rows[4]["verdict"] = "reproduced"
  inverse = {"targets": {"C": {"reached": True, "normalized_change": 3.5, "max_normalized_change": 3.5,
                               "beyond_precision": True, "parameters": {"LCL.k": 3.5}, "fixes": ["C"], "breaks": ["A"]}}}
  out = claim_verdicts.verdicts(rows, rec, inverse)
  check(out["A"]["explanation"] is None, f"A: {out['A']['explanation']}")
  check(out["B"]["explanation"] == "reading" and out["B"]["evidence"]["best_reading"] == "model/x"
        and out["B"]["evidence"]["best_reading_loses"] == ["A"], f"B: {out['B']}")
  check(out["C"]["explanation"] == "beyond_precision" and out["C"]["evidence"]["normalized_change"] == 3.5
        and "||x|| = 3.5" in out["C"]["evidence"]["why"], f"C: {out['C']}")
  check(out["D"]["explanation"] == "unexplained", f"D: {out['D']}")  # only the incomplete reading has it
  # The inverse problem ran but has no target for D: said so, not "was not run".
  check("has no target for this claim (its targets: C)" in out["D"]["evidence"]["why"], f"D why: {out['D']}")
  check(out["S2"]["explanation"] == "contradicted" and out["S2"]["evidence"]["other_statement"] == "S1", f"S2: {out['S2']}")
  out = claim_verdicts.verdicts(rows, rec, None)
  check(out["C"]["explanation"] == "unexplained" and "not run" in out["C"]["evidence"]["why"], f"C without inverse: {out['C']}")


def inverse_evidence_for_c1():
  """C1's evidence is the inverse problem's smallest change reaching 66° (readings_table's
  first row), not necessarily its own fit: an earlier point at 22 beats a fit at 40."""
  inverse = {"targets": {"C1": {"reached": True, "normalized_change": 40.0, "beyond_precision": True,
                                "fixes": ["C1"], "breaks": ["C2", "L12"], "parameters": {"LCL.k": 1.0}},
                         "K6": {"reached": False, "normalized_change": 5.0}},
             "readings_table": [{"reading": "chapter_impact", "reached": True, "method": "recorded_point",
                                 "normalized_change": 22.0, "max_normalized_change": 10.0,
                                 "fixes_vs_project": ["C1"], "breaks_vs_project": ["C2"],
                                 "recorded_point": {"recorded_commit": "abc"}}]}
  ev = claim_verdicts.inverse_evidence(inverse, "C1")
  check(ev["normalized_change"] == 22.0 and ev["breaks"] == ["C2"] and ev["beyond_precision"]
        and ev["method"] == "recorded_point" and "parameters" not in ev, f"C1 evidence {ev}")
  check(claim_verdicts.inverse_evidence(inverse, "K6")["normalized_change"] == 5.0, "K6: not its own target")
  inverse["readings_table"][0].update(method="fit", normalized_change=40.0, recorded_point=None)
  ev = claim_verdicts.inverse_evidence(inverse, "C1")
  check(ev["normalized_change"] == 40.0 and ev["parameters"] == {"LCL.k": 1.0}, f"C1 evidence from the fit {ev}")


def informative_rule():
  """Which readings are informative: the reference member reaches 90° and no member's run
  failed; a member that completes short of 90° does not exclude a reading. The report's
  matrix uses the same rule and says so."""
  def r(t90, failed=()):
    return {"time_to_90_s": t90, "failed_members": list(failed)}
  check(claim_verdicts.informative(r(0.3)), "reference at 90°, no failure: not informative")
  check(not claim_verdicts.informative(r(None)), "reference short of 90°: informative")
  check(not claim_verdicts.informative(r(0.3, ["duration_0.05"])), "a failed member: informative")
  import tempfile
  import make_report  # noqa: E402
  with tempfile.TemporaryDirectory(prefix="kneedyn_informative_") as tmp:
    os.makedirs(os.path.join(tmp, "reconstruction"))
    def reading(key, t90, failed=()):
      return {"key": key, "label": key, "time_to_90_s": t90, "failed_members": list(failed),
              "liftoff_lateral_deg": 60.0, "peak_pulse_N": 7.7, "crossing_deg": {},
              "verdicts": {"A": "reproduced"}, "reasons": {}, "counts": {"reproduced": 1}}
    with open(os.path.join(tmp, "reconstruction", "reconstruction.json"), "w") as f:
      json.dump({"claims": ["A"], "claim_text": {"A": "a"},
                 "readings": [reading("ok", 0.3), reading("short", None), reading("failed", 0.3, ["m"])]}, f)
    page = make_report.reconstruction_section(tmp)
    check("reaches 90° of flexion and no family member's run fails): R1." in page,
          "the matrix's text does not state the rule or does not list exactly R1 as informative")


recorded_file()
synthetic()
inverse_evidence_for_c1()
informative_rule()
for f in failures:
  print("FAIL:", f)
print(f"claim_verdicts_test: {len(failures)} failure(s)")
sys.exit(1 if failures else 0)
