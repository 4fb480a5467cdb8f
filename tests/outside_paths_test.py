#!/usr/bin/python3
"""Fails if a tracked source, script, CMake or YAML file refers to a path outside the
repository: a clone must build, test and run with nothing beside it.

  outside_paths_test.py [--root DIR]

Flags, per line:
  - any mention of the reading material kept beside the clone (a `shared` directory one
    level up, or its `spec/`, `seed/` sub-directories);
  - absolute paths into home or work directories (home, root's home, macOS Users, work, tilde);
  - relative paths ("../x") that, resolved against the file's own directory, leave the root.
System paths (/usr/bin/python3, /usr/bin/chromium, /dev/null, /proc/...) are allowed.
Before scanning, the scanner is run on a few planted bad lines and must flag each one, so
the test cannot pass by matching nothing.
"""
import argparse
import os
import re
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SOURCE_EXT = (".cpp", ".hpp", ".h", ".cc", ".c", ".py", ".sh", ".cmake", ".yaml", ".yml", ".in",
              ".json")
SOURCE_NAMES = ("CMakeLists.txt", "bootstrap", "run")

# Built from pieces so this file does not flag itself.
_SH = "sha" + "red"
PATTERNS = [
    ("reading material beside the clone", re.compile(r"(\.\./)+" + _SH + r"\b|\b" + _SH + r"/(spec|seed)/")),
    ("absolute home/work path", re.compile(r"(?<![\w.])(/ho" + r"me/\w|/ro" + r"ot/|/Us" + r"ers/|/wo" + r"rk/)")),
    ("home-relative path", re.compile(r"(?<![\w.$])~/\w")),
]
RELATIVE = re.compile(r"(?<![\w./])((?:\.\./)+)[\w.-]+")


def tracked_files(root):
  try:
    out = subprocess.run(["git", "-C", root, "ls-files", "-z"], capture_output=True, check=True)
    files = [f for f in out.stdout.decode().split("\0") if f]
  except (OSError, subprocess.CalledProcessError):  # not a git checkout: walk the tree
    files = []
    for d, dirs, names in os.walk(root):
      dirs[:] = [x for x in dirs if not x.startswith(".") or x == ".ci"]
      dirs[:] = [x for x in dirs if x not in ("build", "out") and not os.path.exists(os.path.join(d, x, "CMakeCache.txt"))]
      files += [os.path.relpath(os.path.join(d, n), root) for n in names]
  return [f for f in files if f.endswith(SOURCE_EXT) or os.path.basename(f) in SOURCE_NAMES]


def scan_text(root, rel, text):
  """[(file, line number, what, the line)] for every outside reference in text."""
  hits = []
  here = os.path.dirname(os.path.join(root, rel))
  for n, line in enumerate(text.splitlines(), 1):
    for what, rx in PATTERNS:
      if rx.search(line):
        hits.append((rel, n, what, line.strip()))
    for m in RELATIVE.finditer(line):
      target = os.path.normpath(os.path.join(here, m.group(1)))
      if os.path.relpath(target, root).startswith(".."):
        hits.append((rel, n, f"relative path '{m.group(0)}' leaves the repository", line.strip()))
  return hits


def self_check(root):
  """The scanner must flag each planted line (and not a clean one)."""
  bad = ["spec = '../" + _SH + "/spec/chapter-trends.md'", "open('/wo" + "rk/main/x')",
         "DATA=/ho" + "me/alice/kneedyn", "p = '~/" + "data'", "f = '" + "../" * 3 + "outside.txt'",
         "// values from " + _SH + "/spec/knee-model.md"]
  missed = [b for b in bad if not scan_text(root, "tests/planted.py", b)]
  clean = "parameter_set: ../chapter_knee.yaml  # python /usr/bin/python3"
  false_hit = scan_text(root, "reference-data/scenes/x.yaml", clean)
  return missed, false_hit


def main():
  ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
  ap.add_argument("--root", default=ROOT)
  args = ap.parse_args()
  root = os.path.abspath(args.root)
  missed, false_hit = self_check(root)
  if missed or false_hit:
    print(f"outside_paths_test: scanner broken: missed {missed}, false hits {false_hit}", file=sys.stderr)
    return 1
  files = tracked_files(root)
  if len(files) < 20:
    print(f"outside_paths_test: only {len(files)} files found under {root}", file=sys.stderr)
    return 1
  hits = []
  for rel in files:
    path = os.path.join(root, rel)
    try:
      with open(path, encoding="utf-8", errors="replace") as f:
        hits += scan_text(root, rel, f.read())
    except OSError as e:
      hits.append((rel, 0, f"unreadable: {e}", ""))
  for rel, n, what, line in hits:
    print(f"{rel}:{n}: {what}: {line}", file=sys.stderr)
  print(f"outside_paths_test: {len(files)} files scanned, {len(hits)} outside references")
  return 1 if hits else 0


if __name__ == "__main__":
  sys.exit(main())
