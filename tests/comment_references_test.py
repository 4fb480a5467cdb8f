#!/usr/bin/python3
"""Fails on references a reader of the repository cannot follow: issue numbers, the private
style guide and the old model spec's sections. Comments and documents cite the chapter's
equations ("Eq. 1.20b"), docs/model.md's sections ("docs/model.md §6"), other documents of
the repository and the tests that guard a behaviour instead.

  comment_references_test.py [--root DIR]

Scans every file under the root with a source or document extension (.cpp .hpp .h .py .txt
.cmake .in .sh .yaml .md .dict) and .ci/bootstrap, skipping build*/ and .git/, and prints
each offending line as FILE:LINE: TEXT. Exit 0 when there is none, 1 otherwise, 2 on bad
arguments. Before scanning, the patterns must flag a few planted lines and pass a few
clean ones, so the test cannot pass by matching nothing.
"""
import argparse
import os
import re
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
EXTENSIONS = (".cpp", ".hpp", ".h", ".py", ".txt", ".cmake", ".in", ".sh", ".yaml", ".md", ".dict")
EXTRA_FILES = (os.path.join(".ci", "bootstrap"),)

# Written so that this file does not flag itself.
PATTERNS = [
    ("issue number", re.compile(r"\bissues?[ -]?#?[0-9]", re.IGNORECASE)),
    ("private style guide", re.compile(r"\bstyle\.md\b", re.IGNORECASE)),
    ("old spec section", re.compile(r"\bspec\s*(\u00a7|sections?\s+[0-9])", re.IGNORECASE)),
]

PLANTED_BAD = [
    "// Restarts (iss" + "ue 12 item 2): cheap.",
    "# Iss" + "ue 18: bounded input.",
    "// data apart from model (sty" + "le.md \u00a71).",
    "// x0, z0 from the contact conditions (" + "spec \u00a76).",
    "// (" + "Spec \u00a710: -214.743856 mm)",
    "# posterior (spec sec" + "tion 1)",
    "## Micro-benchmarks (iss" + "ues 12, 13)",
]
PLANTED_CLEAN = [
    "// x0, z0 from the contact conditions (docs/model.md \u00a76; chapter Eq. 1.8).",
    "// The exact map (Eq. 1.20b is printed with the wrong sign).",
    "# tissue 3 and the sweep spec's units are fine",
    "# the model spec, docs/model.md (sections 1, 3)",
]


def offences(line):
  return [what for what, rx in PATTERNS if rx.search(line)]


def scanned_files(root):
  files = []
  for d, dirs, names in os.walk(root):
    # Not .git, nor a build tree inside the source (any name: KNEEDYN_BUILD_DIR; a CMakeCache.txt
    # marks it), whose _deps hold other projects' sources.
    dirs[:] = sorted(x for x in dirs if x != ".git" and not x.startswith("build")
                     and not os.path.exists(os.path.join(d, x, "CMakeCache.txt")))
    for n in sorted(names):
      rel = os.path.relpath(os.path.join(d, n), root)
      if n.endswith(EXTENSIONS) or rel in EXTRA_FILES:
        files.append(rel)
  return files


def self_check():
  errors = [f"planted line not flagged: {s!r}" for s in PLANTED_BAD if not offences(s)]
  errors += [f"clean line flagged: {s!r}" for s in PLANTED_CLEAN if offences(s)]
  return errors


def root_argument(program, doc):
  """The --root of a repository scan (default: this checkout), or None after printing why
  it is not a folder (the caller exits 2)."""
  parser = argparse.ArgumentParser(description=doc.splitlines()[0])
  parser.add_argument("--root", default=ROOT, help="repository root (default: this checkout)")
  root = parser.parse_args().root
  if not os.path.isdir(root):
    print(f"{program}: --root = '{root}': not a directory", file=sys.stderr)
    return None
  return root


def main():
  root = root_argument("comment_references_test", __doc__)
  if root is None:
    return 2
  errors = self_check()
  if errors:
    print("comment_references_test: the patterns are broken:\n  " + "\n  ".join(errors), file=sys.stderr)
    return 1
  hits = []
  files = scanned_files(root)
  for rel in files:
    with open(os.path.join(root, rel), encoding="utf-8", errors="replace") as f:
      for n, line in enumerate(f, 1):
        what = offences(line)
        if what:
          hits.append(f"{rel}:{n}: [{', '.join(what)}] {line.strip()[:160]}")
  for h in hits:
    print(h)
  print(f"comment_references_test: {len(files)} files scanned, {len(hits)} unresolvable references")
  return 1 if hits else 0


if __name__ == "__main__":
  sys.exit(main())
