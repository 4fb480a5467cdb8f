#!/usr/bin/env python3
"""examples/notebooks/knee_impact.ipynb under `jupyter nbconvert --execute`
(tests/packaging/CMakeLists.txt; PYTHONPATH names the build tree's module).

Fails if the committed notebook holds outputs or execution counts (it is committed clean),
if any cell raises (nbconvert then exits non-zero; the cells assert that the two
formulations agree on the lift-off and that the sensitivity matches central differences),
or if the executed notebook lacks its figures.
"""
import argparse
import subprocess
import sys
import time
from pathlib import Path

import nbformat

from packaging_common import fresh_directory, verdict


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--notebook", required=True, type=Path)
    ap.add_argument("--work", required=True, type=Path)
    args = ap.parse_args()
    work = fresh_directory(args.work)
    problems = []

    committed = nbformat.read(args.notebook, as_version=4)
    for i, cell in enumerate(committed.cells):
        if cell.cell_type == "code" and (cell.get("outputs") or cell.get("execution_count") is not None):
            problems.append("cell %d is committed with outputs or an execution count (clear them)" % i)

    t0 = time.monotonic()
    # From the work directory, so that nothing the notebook might write lands in the source tree.
    r = subprocess.run([sys.executable, "-m", "nbconvert", "--to", "notebook", "--execute",
                        "--ExecutePreprocessor.timeout=600", "--output-dir", str(work), str(args.notebook.resolve())],
                       cwd=work)
    print("nbconvert --execute: %.1f s, exit %d" % (time.monotonic() - t0, r.returncode))
    if r.returncode != 0:
        problems.append("jupyter nbconvert --execute failed (a cell raised; see above)")
    else:
        executed = nbformat.read(work / args.notebook.name, as_version=4)
        figures = sum(1 for c in executed.cells if c.cell_type == "code"
                      for o in c.outputs if "image/png" in o.get("data", {}))
        errors = [o for c in executed.cells if c.cell_type == "code" for o in c.outputs if o.output_type == "error"]
        if errors:
            problems.append("%d cells hold errors" % len(errors))
        if figures < 2:
            problems.append("the executed notebook has %d figures, expected 2" % figures)
    return verdict(problems, work=work)


if __name__ == "__main__":
    sys.exit(main())
