#!/usr/bin/env python3
"""Each stored reference (reference-data/references/*.json) was made by the command that
`cmake --build BUILD --target references` runs for its scene (benchmarks/CMakeLists.txt):
its `generator` field names the same options, and `conservative` is true exactly when that
command passes --conservative. A reference made again by hand with an option left out (the
conservative scene's lost its energy error that way) fails here.

  /usr/bin/python3 tests/reference_generators_test.py [--root DIR]
"""
import argparse
import glob
import json
import os
import re
import shlex
import sys

sys.dont_write_bytecode = True  # keep the source tree clean
from py_test_support import finish  # noqa: E402

DEFAULTS = {"--scalar": "float128"}  # make_reference's defaults, left out of the CMake target


def options(argv):
  """make_reference's options as {flag: value or True}, defaults dropped."""
  out, i = {}, 0
  while i < len(argv):
    flag = argv[i]
    if not flag.startswith("--"):
      raise ValueError(f"unexpected argument {flag!r}")
    if i + 1 < len(argv) and not argv[i + 1].startswith("--"):
      out[flag], i = argv[i + 1], i + 2
    else:
      out[flag], i = True, i + 1
  return {k: v for k, v in out.items() if DEFAULTS.get(k) != v}


def target_commands(cmake_text):
  """The references target's make_reference commands, by scene file (repo-relative)."""
  body = re.search(r"add_custom_target\(references\b(.*?)\n\s*DEPENDS", cmake_text, re.S)
  if body is None:
    raise ValueError("benchmarks/CMakeLists.txt: no references target")
  commands = {}
  for cmd in re.split(r"\bCOMMAND\b", body.group(1))[1:]:
    argv = shlex.split(cmd.replace("${KNEEDYN_DATA_DIR}", "reference-data"))
    if not argv or argv[0] != "make_reference":
      raise ValueError(f"references target: not a make_reference command: {cmd.strip()!r}")
    opts = options(argv[1:])
    commands[opts["--scene"]] = opts
  return commands


def main():
  ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
  ap.add_argument("--root", default=os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
  root = ap.parse_args().root
  with open(os.path.join(root, "benchmarks", "CMakeLists.txt"), encoding="utf-8") as f:
    commands = target_commands(f.read())
  problems, stored_scenes = [], set()
  files = sorted(glob.glob(os.path.join(root, "reference-data", "references", "*.json")))
  for path in files:
    with open(path, encoding="utf-8") as f:
      ref = json.load(f)
    name = os.path.relpath(path, root)
    argv = shlex.split(ref.get("generator", ""))
    if not argv or argv[0] != "make_reference":
      problems.append(f"{name}: generator {ref.get('generator')!r} is not a make_reference command")
      continue
    made = options(argv[1:])
    stored_scenes.add(made.get("--scene"))
    target = commands.get(made.get("--scene"))
    if target is None:
      problems.append(f"{name}: scene {made.get('--scene')!r} has no command in the references target")
      continue
    if made != target:
      problems.append(f"{name}: made with {sorted(made.items())}, the references target runs {sorted(target.items())}")
    if bool(ref.get("conservative")) != ("--conservative" in target):
      problems.append(f"{name}: conservative = {ref.get('conservative')}, the target "
                      f"{'passes' if '--conservative' in target else 'does not pass'} --conservative")
    if ref.get("conservative") and not isinstance((ref.get("primary") or {}).get("energy_error"), (int, float)):
      problems.append(f"{name}: conservative but primary.energy_error is missing")
  for scene in sorted(set(commands) - stored_scenes):
    problems.append(f"the references target makes {scene}'s reference, which is not stored")
  return finish(problems, "reference_generators_test:", f"reference_generators_test: {len(files)} references, "
                f"{len(problems)} disagreements", stream=sys.stdout)


if __name__ == "__main__":
  sys.exit(main())
