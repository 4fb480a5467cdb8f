#!/usr/bin/env python3
"""The packaging tests refuse a stale build tree before touching it (packaging_common.py,
stale_build_reason): each of pip_install, deb_package and docs_site, given a tree whose
generated commit header names another commit than the source's, exits 1 naming both and
`cmake --build`, and writes nothing into its work directory. A tree whose header is the
source's own (written here by cmake/git_commit.cmake) is current.

  stale_tree_test.py --source SOURCE
"""
import argparse
import subprocess
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from packaging_common import stale_build_reason, write_commit_header  # noqa: E402

ap = argparse.ArgumentParser()
ap.add_argument("--source", required=True, type=Path)
source = ap.parse_args().source.resolve()
failures = []

with tempfile.TemporaryDirectory() as d:
    build = Path(d) / "build"
    (build / "generated").mkdir(parents=True)
    header = build / "generated" / "kneedyn_git_commit.h"
    write_commit_header(source, header)
    reason = stale_build_reason(source, build)
    if reason is not None:
        failures.append("a tree with the source's own commit header is called stale: %s" % reason)
    header.write_text('#define KNEEDYN_GIT_COMMIT "0123456789ab"\n')
    for test in ("pip_install_test.py", "deb_package_test.py", "docs_site_test.py"):
        work = Path(d) / ("work_" + test)
        p = subprocess.run([sys.executable, str(source / "tests" / "packaging" / test), "--source", str(source),
                            "--build-dir", str(build), "--work", str(work)], capture_output=True, text=True)
        out = p.stdout + p.stderr
        if not (p.returncode == 1 and "stale" in out and '"0123456789ab"' in out and "cmake --build" in out):
            failures.append("%s on a stale tree: exit %d, expected 1 naming the commits and cmake --build:\n%s"
                            % (test, p.returncode, out[-2000:]))
        if work.exists():
            failures.append("%s wrote its work directory %s on a stale tree" % (test, work))

for f in failures:
    print("FAIL:", f)
print("ok" if not failures else "%d failure(s)" % len(failures))
sys.exit(1 if failures else 0)
