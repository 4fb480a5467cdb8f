#!/usr/bin/env python3
"""Every file under reference-data/ is described: named (in a `code span`) by the README of
its own directory or of reference-data/ (reference-data/README.md, scenes/README.md,
scenes/hard/README.md). A scene, reference or parameter set added without a word on what it is
fails here. A self-check plants an undescribed file in a copy and expects it to be flagged.

  /usr/bin/python3 tests/reference_data_listed_test.py [--root DIR]
"""
import argparse
import os
import re
import shutil
import sys
import tempfile

sys.dont_write_bytecode = True  # keep the source tree clean
from py_test_support import finish  # noqa: E402

CODE_SPAN = re.compile(r"`([^`]+)`")


def undescribed(data_dir):
  """Paths (relative to data_dir) of files that no README on their way up names."""
  missing = []
  for here, dirs, files in os.walk(data_dir):
    dirs.sort()
    for name in sorted(files):
      if name == "README.md":
        continue
      rel = os.path.relpath(os.path.join(here, name), data_dir)
      spans = set()
      folder = here
      while True:
        readme = os.path.join(folder, "README.md")
        if os.path.exists(readme):
          with open(readme, encoding="utf-8") as f:
            spans |= set(CODE_SPAN.findall(f.read()))
        if os.path.samefile(folder, data_dir):
          break
        folder = os.path.dirname(folder)
      stem = os.path.splitext(name)[0]
      if not ({name, stem, rel} & spans or any(s.endswith("/" + name) for s in spans)):
        missing.append(rel)
  return missing


def main():
  parser = argparse.ArgumentParser()
  parser.add_argument("--root", default=os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
  data_dir = os.path.join(parser.parse_args().root, "reference-data")
  errors = [f"reference-data/{p}: described in no README.md of its directory or above" for p in undescribed(data_dir)]
  with tempfile.TemporaryDirectory() as tmp:
    copy = os.path.join(tmp, "reference-data")
    shutil.copytree(data_dir, copy)
    with open(os.path.join(copy, "scenes", "planted_scene.yaml"), "w", encoding="utf-8") as f:
      f.write("name: planted_scene\n")
    if set(undescribed(copy)) != {"scenes/planted_scene.yaml"} | set(undescribed(data_dir)):
      errors.append(f"self-check: a planted undescribed scene gives {undescribed(copy)}")
  return finish(errors, "reference_data_listed_test: FAIL:",
                f"reference_data_listed_test: {len(errors)} problem(s)")


if __name__ == "__main__":
  sys.exit(main())
