#!/usr/bin/python3
"""Fails on citations of a document's section that lead nowhere. Code and documents cite
sections by name or number: `benchmarks/README.md, "Instruction counts"`,
`benchmarks/performance-log.md "Fourth round"`, `docs/model.md §6`. Each cited name must
begin one of the headings of the named document (or a heading must begin the cited text,
when a citation goes on into the heading's subtitle), and each § number of docs/model.md
must number one of its headings ("## 6. ..."). A moved or renamed section therefore fails
here until its citations follow it. Each chapter equation cited ("Eq. 1.62", "Eqs. 1.40–1.47",
"Eqs. 1.9, 1.10", "Eq. (1.88)") must be one docs/model.md mentions, alone or in a range: the
project's account of the model says what every equation the code cites is.

  doc_citations_test.py [--root DIR]

Scans the files comment_references_test.py scans. A citation may wrap onto the next
comment line (`benchmarks/README.md,` then `// "SUNDIALS build")`). The named document is
looked up from the repository root, then from the citing file's folder. Prints each
unresolved citation as FILE:LINE: CITATION and a count; exit 0 when every one resolves,
1 otherwise, 2 on bad arguments. Before scanning, the checks must reject planted bad
citations and accept planted good ones against a planted document, so the test cannot
pass by matching nothing.
"""
import os
import re
import sys
import tempfile

sys.dont_write_bytecode = True  # keep the source tree clean
from comment_references_test import root_argument, scanned_files  # noqa: E402

# `FILE.md` (optionally in backquotes), then optionally "," and/or "(", then a quoted name.
QUOTED = re.compile(r"([\w./-]+\.md)`?,?\s*\(?\s*[\"\u201c]([^\"\u201d]{3,}?)(?:[\"\u201d]|$)")
MODEL_SECTION = re.compile(r"docs/model\.md,?\s*\u00a7\s*(\d+)")
# "Eq. 1.8", "Eqs. 1.40–1.47", "Eqs. 1.9, 1.10", "Eqs. (1.40) through (1.61)", "Eq. 1.20b".
EQUATIONS = re.compile(r"\bEq(?:s?\.|uations?)\s*((?:\(?1\.\d+[a-z]?\)?)"
                       r"(?:\s*(?:,|and|\u2013|-|to|through)\s*\(?1\.\d+[a-z]?\)?)*)")
CODE = re.compile(r"[{};<>=+]|\(\s*$|^\W")
COMMENT_LEADER = re.compile(r"^\s*(//+|#+|\*|--)?\s*")


def equations_cited(text):
  """The chapter equation numbers N of "1.N" that `text` cites, ranges expanded."""
  numbers = set()
  for m in EQUATIONS.finditer(text):
    for part in re.split(r"\s*(?:,|\band\b)\s*", m.group(1)):
      ends = [int(x) for x in re.findall(r"1\.(\d+)", part)]
      if ends:
        numbers.update(range(ends[0], ends[-1] + 1))
  return numbers


def equations_in_model(root, cache):
  key = ("equations", root)
  if key not in cache:
    try:
      with open(os.path.join(root, "docs", "model.md"), encoding="utf-8") as f:
        cache[key] = equations_cited(f.read())
    except OSError:
      cache[key] = set()
  return cache[key]


def headings_of(path, cache):
  if path not in cache:
    try:
      with open(path, encoding="utf-8") as f:
        cache[path] = [l.lstrip("#").strip() for l in f if l.startswith("#")]
    except OSError:
      cache[path] = None
  return cache[path]


def resolve(doc, citing_rel, root, cache):
  for candidate in (os.path.join(root, doc), os.path.join(root, os.path.dirname(citing_rel), doc)):
    heads = headings_of(os.path.normpath(candidate), cache)
    if heads is not None:
      return heads
  return None


def unresolved(text, citing_rel, root, cache):
  """The citations in `text` (one line, perhaps with the next joined) that lead nowhere."""
  bad = []
  for m in QUOTED.finditer(text):
    name = m.group(2).strip().rstrip(".,;)")
    if CODE.search(name):
      continue  # a string of code beside a file name, not a section's name
    heads = resolve(m.group(1), citing_rel, root, cache)
    if heads is None:
      # A repository path (its first folder exists) must exist; a bare name such as
      # "claims.md" is a file some program writes, not a citation.
      first = m.group(1).split("/")[0]
      if "/" in m.group(1) and first and os.path.isdir(os.path.join(root, first)):
        bad.append(f"{m.group(1)}: no such document")
    elif not any(h.startswith(name) or (len(h) >= 4 and name.startswith(h)) for h in heads):
      bad.append(f'{m.group(1)}, "{name}": no such heading')
  for m in MODEL_SECTION.finditer(text):
    heads = resolve("docs/model.md", citing_rel, root, cache)
    if heads is None or not any(h.startswith(m.group(1) + ".") for h in heads):
      bad.append(f"docs/model.md \u00a7{m.group(1)}: no such section")
  if os.path.normpath(citing_rel) != os.path.join("docs", "model.md"):
    missing = sorted(equations_cited(text) - equations_in_model(root, cache))
    if missing:
      bad.append("Eq. " + ", ".join(f"1.{n}" for n in missing) + ": not in docs/model.md")
  return bad


def scan(lines, rel, root, cache):
  """(unresolved citations as "FILE:LINE: what", number of citations) of one file's lines."""
  hits, count = [], 0
  for n, line in enumerate(lines):
    count += len(QUOTED.findall(line)) + len(MODEL_SECTION.findall(line)) + len(EQUATIONS.findall(line))
    # A citation that starts on this line, perhaps ending on the next: reported here.
    joined = line + " " + COMMENT_LEADER.sub("", lines[n + 1]) if n + 1 < len(lines) else line
    starts = [m.start() for rx in (QUOTED, MODEL_SECTION, EQUATIONS) for m in rx.finditer(joined) if m.start() < len(line)]
    if starts:
      hits += [f"{rel}:{n + 1}: {b}" for b in unresolved(joined[min(starts):], rel, root, cache)]
  return hits, count


def self_check(tmp_root):
  os.makedirs(os.path.join(tmp_root, "docs"), exist_ok=True)
  with open(os.path.join(tmp_root, "docs", "model.md"), "w", encoding="utf-8") as f:
    f.write("# Model\n\n## 1. Units (Eqs. 1.1, 1.2)\n\n## 6. Reference pose and initial state\n\n"
            "Rows F1-F6 (Eqs. 1.40\u20131.47) and the pulse (Eq. 1.62).\n")
  with open(os.path.join(tmp_root, "guide.md"), "w", encoding="utf-8") as f:
    f.write("# Guide\n\n## Instruction counts\n\n### Fourth round: closed form (2026)\n")
  cache = {}
  bad = ['// see guide.md, "Fifth round"', '# (guide.md "Instruction totals")', "// docs/model.md \u00a77",
         '// docs/missing.md, "Instruction counts"', '// (`guide.md` ("Performance targets"))',
         '// guide.md, "Instruction count totals"', '// (guide.md,\n// "Fifth round")',
         "// the point transform (Eq. 1.3)", "// rows (Eqs. 1.40\u20131.48)", "// (Eqs. 1.2, 1.5)",
         "// the residual of Eqs. (1.40) through (1.61)", "// force law (Eqs.\n// 1.14)"]
  good = ['// see guide.md, "Instruction counts"', '# (guide.md "Fourth round")', "// docs/model.md \u00a76",
          '// guide.md, "Fourth round: closed form (2026)"', '(`guide.md` ("Instruction counts"))',
          "// docs/model.md, \u00a71 and guide.md's headings", '// guide.md, "Instruction counts, second part"',
          '// (guide.md,\n// "Fourth round")', "// the point transform (Eq. 1.2)", "// rows (Eqs. 1.41-1.46)",
          "// (Eqs. 1.1, 1.2; Eq. 1.62)", "// Eq. (1.40) through (1.47)", "// Eq. 1.1b's sign"]
  errors = [f"planted bad citation accepted: {s!r}" for s in bad if not scan(s.split("\n"), "x.cpp", tmp_root, cache)[0]]
  errors += [f"planted good citation rejected: {s!r}" for s in good if scan(s.split("\n"), "x.cpp", tmp_root, cache)[0]]
  return errors


def main():
  root = root_argument("doc_citations_test", __doc__)
  if root is None:
    return 2
  with tempfile.TemporaryDirectory() as tmp:
    errors = self_check(tmp)
  if errors:
    print("doc_citations_test: the checks are broken:\n  " + "\n  ".join(errors), file=sys.stderr)
    return 1
  cache, hits, count = {}, [], 0
  files = scanned_files(root)
  for rel in files:
    if rel == os.path.join("tests", os.path.basename(__file__)):
      continue  # this checker's own patterns and planted lines
    with open(os.path.join(root, rel), encoding="utf-8", errors="replace") as f:
      found, cited = scan(f.read().split("\n"), rel, root, cache)
    hits += found
    count += cited
  for h in sorted(set(hits)):
    print(h)
  print(f"doc_citations_test: {len(files)} files scanned, about {count} citations, {len(set(hits))} unresolved")
  return 1 if hits else 0


if __name__ == "__main__":
  sys.exit(main())
