#!/usr/bin/env python3
"""Reading a 1 MB scene of the densest shape measured (a flow list of small flow maps,
`ligaments: [{k: 1, j: [1,2]}, ...]`, benchmarks/README.md "YAML libraries") costs a bounded
number of instructions per byte, and ten times the file costs at most about ten times as much
(linear in the size). Counted by valgrind (callgrind, LoadScene only), not timed: the wall
time of a shared machine says more about its load than about the reader. Skipped (exit 77)
without valgrind.

  yaml_parse_instructions_test.py --kneedyn PATH --parameter-set PATH
"""
import argparse
import os
import re
import shutil
import subprocess
import sys
import tempfile

# Instructions per byte of LoadScene on the 1 MB file: 1,086 with libyaml's document API
# (yaml_document_add_* copying each value and tag, and freeing them one by one), 798 with the
# reader's own node store (scene/yaml_field.cpp, YamlNodes).
MAX_PER_BYTE = 950
# I(1 MB) / I(1/8 MB): 8 for a linear reader; a quadratic one gives about 64.
MAX_GROWTH = 10.0

ap = argparse.ArgumentParser()
ap.add_argument("--kneedyn", required=True)
ap.add_argument("--parameter-set", required=True)
a = ap.parse_args()
if shutil.which("valgrind") is None:
    print("valgrind not found: skipped")
    sys.exit(77)


def scene(size):
    text = "name: flow\nparameter_set: %s\nligaments: [" % os.path.abspath(a.parameter_set)
    unit = "{k: 1, j: [1,2]}, "
    text += unit * ((size - len(text)) // len(unit))
    return text[:-2] + "]\n"


def instructions(path, work):
    p = subprocess.run(["valgrind", "--tool=callgrind", "--callgrind-out-file=" + os.path.join(work, "cg.out"),
                        "--toggle-collect=kneedyn::LoadScene*", a.kneedyn, "info", path],
                       capture_output=True, text=True)
    # The scene is refused (ligaments[0] is not a name): the whole file is parsed first.
    if p.returncode != 2 or "ligaments[0]" not in p.stderr:
        sys.exit("unexpected answer for %s: exit %d\n%s" % (path, p.returncode, p.stderr[-2000:]))
    m = re.search(r"Collected : (\d+)", p.stderr)
    if not m:
        sys.exit("no instruction count in valgrind's output:\n" + p.stderr[-2000:])
    return int(m.group(1))


failures = []
with tempfile.TemporaryDirectory() as work:
    counts = {}
    for size in ((1 << 20) - 64, (1 << 17) - 8):
        path = os.path.join(work, "scene_%d.yaml" % size)
        text = scene(size)
        open(path, "w").write(text)
        counts[size] = (len(text), instructions(path, work))
    (big_bytes, big), (small_bytes, small) = counts[(1 << 20) - 64], counts[(1 << 17) - 8]
    per_byte = big / big_bytes
    growth = big / small
    print("LoadScene: %d bytes %d instructions (%.0f a byte); %d bytes %d; growth %.2f for %.2f times the size"
          % (big_bytes, big, per_byte, small_bytes, small, growth, big_bytes / small_bytes))
    if per_byte > MAX_PER_BYTE:
        failures.append("%.0f instructions a byte > %d" % (per_byte, MAX_PER_BYTE))
    if growth > MAX_GROWTH:
        failures.append("growth %.2f for 8 times the size > %.1f: not linear" % (growth, MAX_GROWTH))
for f in failures:
    print("FAIL:", f)
sys.exit(1 if failures else 0)
