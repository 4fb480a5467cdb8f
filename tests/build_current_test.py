#!/usr/bin/env python3
"""ctest refuses a stale build tree before any test (tests/build_current.py, run through
cmake/CTestCustom.cmake.in). Checked on throw-away trees whose generated commit header is
written here, the commit expected from git itself (`git rev-parse --short=12 HEAD`):
- the source's own commit, and the same with -dirty: current (exit 0, silent);
- another commit: exit 1 naming both commits and `cmake --build`;
- no header: exit 1, "not been built";
- end to end: ctest on a tree with the configured CTestCustom.cmake and one test that writes a
  marker file runs no test on a stale header (non-zero exit, no marker, the message shown), and
  runs it on a current one; the tree's path holds a space.

  build_current_test.py --source SOURCE --python PYTHON
"""
import argparse
import subprocess
import sys
import tempfile
from pathlib import Path

ap = argparse.ArgumentParser()
ap.add_argument("--source", required=True, type=Path)
ap.add_argument("--python", required=True)
a = ap.parse_args()
source = a.source.resolve()
script = source / "tests" / "build_current.py"
failures = []

git = subprocess.run(["git", "-C", str(source), "rev-parse", "--show-toplevel"], capture_output=True, text=True)
in_git = git.returncode == 0 and Path(git.stdout.strip()).resolve() == source
commit = (subprocess.run(["git", "-C", str(source), "rev-parse", "--short=12", "HEAD"], capture_output=True,
                         text=True, check=True).stdout.strip() if in_git else "")
other = "0123456789ab" if commit != "0123456789ab" else "ba9876543210"


def tree(d, header_commit):
    build = Path(d)
    if header_commit is not None:
        (build / "generated").mkdir(parents=True, exist_ok=True)
        (build / "generated" / "kneedyn_git_commit.h").write_text('#define KNEEDYN_GIT_COMMIT "%s"\n' % header_commit)
    return build


def check(build):
    p = subprocess.run([a.python, str(script), "--source", str(source), "--build-dir", str(build)],
                       capture_output=True, text=True)
    return p.returncode, p.stdout + p.stderr


for label, header in (("its own commit", commit), ("its own commit, -dirty", commit + "-dirty")):
    with tempfile.TemporaryDirectory() as d:
        rc, out = check(tree(d, header))
        if rc != 0 or out:
            failures.append("a tree built at %s (%r) is called stale: exit %d, %r" % (label, header, rc, out))

with tempfile.TemporaryDirectory() as d:
    rc, out = check(tree(d, other))
    if not (rc == 1 and other in out and (commit or "(none)") in out and "cmake --build" in out):
        failures.append("a tree built at %s: exit %d, expected 1 naming %s, %s and cmake --build: %r"
                        % (other, rc, other, commit or "(none)", out))

with tempfile.TemporaryDirectory() as d:
    rc, out = check(tree(d, None))
    if not (rc == 1 and "not been built" in out):
        failures.append("a tree without a commit header: exit %d, expected 1 'not been built': %r" % (rc, out))

# End to end through ctest: the template configured as CMakeLists.txt configures it.
for header, should_run in ((other, False), (commit, True)):
    with tempfile.TemporaryDirectory(prefix="kneedyn build ") as d:  # a space: the command is quoted
        build = tree(d, header)
        marker = build / "marker"
        configure = build / "configure.cmake"
        configure.write_text('configure_file("%s" "%s" @ONLY)\n'
                             % (source / "cmake" / "CTestCustom.cmake.in", build / "CTestCustom.cmake"))
        subprocess.run(["cmake", "-DKNEEDYN_PYTHON=%s" % a.python, "-DPROJECT_SOURCE_DIR=%s" % source,
                        "-DPROJECT_BINARY_DIR=%s" % build, "-P", str(configure)], check=True)
        (build / "CTestTestfile.cmake").write_text('add_test(marker "%s" -E touch "%s")\n' % ("cmake", marker))
        p = subprocess.run(["ctest", "--test-dir", str(build)], capture_output=True, text=True)
        out = p.stdout + p.stderr
        if should_run and (p.returncode != 0 or not marker.exists()):
            failures.append("ctest on a current tree: exit %d, marker %s:\n%s"
                            % (p.returncode, "written" if marker.exists() else "missing", out[-2000:]))
        if not should_run and (p.returncode == 0 or marker.exists() or "stale" not in out):
            failures.append("ctest on a stale tree: exit %d, marker %s, expected a refusal before any test:\n%s"
                            % (p.returncode, "written" if marker.exists() else "missing", out[-2000:]))

for f in failures:
    print("FAIL:", f)
print("ok" if not failures else "%d failure(s)" % len(failures))
sys.exit(1 if failures else 0)
