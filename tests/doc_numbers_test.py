#!/usr/bin/python3
"""Numbers the documents state about recorded data, checked against that data:

  * README.md's count of claims under the informative readings (how many readings are
    informative, the claims reproduced under every one and under none, and under how many
    lift-off at 66° (C1) is reproduced) against the matrix of reports/recorded/claims.json
    (a cell is 1 when the claim is reproduced under the reading);
  * the stated accuracy of the chapter scene's reference (README.md, docs/problem.md,
    benchmarks/README.md) against `accuracy_scd` of reference-data/references/chapter_impact.json;
  * README.md's kneedyn / Simbody time ratios and the speed-ups it derives from them against
    the recording in crosscheck/simbody/README.md (the recorded JSON is not in the repository).

  doc_numbers_test.py [--root DIR]

Before the real documents, each check runs on planted text with a wrong number and must
flag it, and on planted text with the right numbers and must not, so the test cannot pass by
matching nothing. Exit 0 when every number agrees, 1 otherwise, 2 on bad arguments.
"""
import json
import os
import re
import sys

sys.dont_write_bytecode = True  # keep the source tree clean
from comment_references_test import root_argument  # noqa: E402


def flat(text):
  """Whitespace runs as one space (sentences wrap over lines)."""
  return re.sub(r"\s+", " ", text)


def read(root, rel):
  with open(os.path.join(root, rel), encoding="utf-8") as f:
    return flat(f.read())


def claim_counts(claims_json):
  """(informative readings, claims reproduced under all of them, under none, readings that
  reproduce C1) from the recorded matrix."""
  m = claims_json["matrix"]
  ids, inf = m["claims"], [r for r in m["readings"] if r["informative"]]
  every = [c for j, c in enumerate(ids) if all(r["cells"][j] == 1 for r in inf)]
  none = [c for j, c in enumerate(ids) if all(r["cells"][j] != 1 for r in inf)]
  c1 = sum(r["cells"][ids.index("C1")] == 1 for r in inf)
  return len(inf), every, none, c1


README_CLAIMS = re.compile(r"Under the (\d+) informative readings .*? (\d+) claims are reproduced under every one "
                           r"\(([^)]*)\) and (\d+) under none \(([^)]*)\); lift-off at ≈ 66° \(C1\) is reproduced "
                           r"under (\d+)")


def claims_errors(readme, counts):
  m = README_CLAIMS.search(readme)
  if not m:
    return ["README.md: no sentence 'Under the N informative readings ... N claims are reproduced under every "
            "one (...) and N under none (...); lift-off at ≈ 66° (C1) is reproduced under N'"]
  n_inf, every, none, c1 = counts
  said = (int(m[1]), int(m[2]), [c.strip() for c in m[3].split(",")], int(m[4]),
          [c.strip() for c in m[5].split(",")], int(m[6]))
  want = (n_inf, len(every), every, len(none), none, c1)
  return [] if said == want else [f"README.md says {said} (informative, every, ids, none, ids, C1); "
                                  f"reports/recorded/claims.json gives {want}"]


ACCURACY = [("README.md", re.compile(r"computed in quadruple precision to (\d+\.\d) digits")),
            ("docs/problem.md", re.compile(r"`accuracy_scd` = (\d+\.\d) digits")),
            ("benchmarks/README.md", re.compile(r"quadruple-precision reference: (\d+\.\d) digits"))]


def accuracy_errors(texts, accuracy_scd):
  errors = []
  for rel, pattern in ACCURACY:
    found = pattern.findall(texts[rel])
    if not found:
      errors.append(f"{rel}: no statement of the reference's accuracy ({pattern.pattern})")
    errors += [f"{rel}: reference accuracy {v} digits, chapter_impact.json has {accuracy_scd:.1f}"
               for v in found if float(v) != round(accuracy_scd, 1)]
  return errors


README_RATIO = re.compile(r"scd 6 about (\d+)× and scd 8 about (\d+)× sooner: time ratios (0\.\d+) and (0\.\d+)")
SIMBODY_RATIO = re.compile(r"\(fastest of each\): (0\.\d+) at scd 6 .*? and (0\.\d+) at scd 8")


def ratio_errors(readme, simbody_readme):
  m, s = README_RATIO.search(readme), SIMBODY_RATIO.search(simbody_readme)
  if not m or not s:
    return [f"no kneedyn / Simbody ratio sentence in {'README.md' if not m else 'crosscheck/simbody/README.md'}"]
  errors = []
  if (m[3], m[4]) != (s[1], s[2]):
    errors.append(f"README.md's ratios {m[3]}, {m[4]} are not crosscheck/simbody/README.md's {s[1]}, {s[2]}")
  for times, ratio in ((m[1], m[3]), (m[2], m[4])):  # to two significant digits
    if int(times) != int(float(f"{1.0 / float(ratio):.2g}")):
      errors.append(f"README.md: {times}× sooner does not follow from the ratio {ratio} (1/{ratio} = "
                    f"{1.0 / float(ratio):.0f})")
  return errors


def self_check():
  """Each check on planted text: a wrong number flagged, the right ones not."""
  problems = []
  matrix = {"matrix": {"claims": ["A", "B", "C1"], "readings": [
      {"informative": True, "cells": [1, 0, 0]}, {"informative": True, "cells": [1, 0, 1]},
      {"informative": False, "cells": [0, 1, 1]}]}}
  counts = claim_counts(matrix)
  good = ("Under the 2 informative readings of x, 1 claims are reproduced under every one (A) and 1 under none "
          "(B); lift-off at ≈ 66° (C1) is reproduced under 1")
  if claims_errors(good, counts):
    problems.append(f"claims check flags the right counts: {claims_errors(good, counts)}")
  if not claims_errors(good.replace("under none (B)", "under none (C1)"), counts):
    problems.append("claims check misses a wrong claim id")
  texts = {"README.md": "computed in quadruple precision to 15.7 digits", "docs/problem.md": "`accuracy_scd` = 15.7 "
           "digits", "benchmarks/README.md": "quadruple-precision reference: 15.7 digits"}
  if accuracy_errors(texts, 15.7):
    problems.append(f"accuracy check flags the right value: {accuracy_errors(texts, 15.7)}")
  if not accuracy_errors(dict(texts, **{"docs/problem.md": "`accuracy_scd` = 15.6 digits"}), 15.7):
    problems.append("accuracy check misses 15.6 against 15.7")
  simbody = "(fastest of each): 0.0085 at scd 6 (x) and 0.0044 at scd 8 (y)"
  readme = "scd 6 about 120× and scd 8 about 230× sooner: time ratios 0.0085 and 0.0044"
  if ratio_errors(readme, simbody):
    problems.append(f"ratio check flags the right values: {ratio_errors(readme, simbody)}")
  if not ratio_errors(readme.replace("about 120×", "about 140×"), simbody):
    problems.append("ratio check misses 140× against 0.0085")
  return problems


def main():
  root = root_argument("doc_numbers_test", __doc__)
  if root is None:
    return 2
  problems = self_check()
  if problems:
    for p in problems:
      print("doc_numbers_test: self-check:", p, file=sys.stderr)
    return 1
  with open(os.path.join(root, "reports", "recorded", "claims.json"), encoding="utf-8") as f:
    counts = claim_counts(json.load(f))
  with open(os.path.join(root, "reference-data", "references", "chapter_impact.json"), encoding="utf-8") as f:
    accuracy = json.load(f)["accuracy_scd"]
  texts = {rel: read(root, rel) for rel, _ in ACCURACY}
  errors = (claims_errors(texts["README.md"], counts) + accuracy_errors(texts, accuracy)
            + ratio_errors(texts["README.md"], read(root, "crosscheck/simbody/README.md")))
  for e in errors:
    print("doc_numbers_test: FAIL:", e, file=sys.stderr)
  print(f"doc_numbers_test: {len(errors)} disagreement(s)")
  return 1 if errors else 0


if __name__ == "__main__":
  sys.exit(main())
