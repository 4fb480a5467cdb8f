#!/usr/bin/env python3
"""Run by ctest before any test (CTEST_CUSTOM_PRE_TEST of the build tree's CTestCustom.cmake,
written from cmake/CTestCustom.cmake.in): refuses to start the suite when the build tree was
built at another commit than the source is at now.

After a commit, a checkout or a pull without `cmake --build`, the tests would run programs of
the older commit: the version tests fail for a reason that has nothing to do with them, and
every other result belongs to code that is no longer the source. The commit the build wrote
into generated/kneedyn_git_commit.h (cmake/git_commit.cmake) is compared with the commit the
same script gives for the source now. "-dirty" is left out of the comparison: an edit without
a build is the developer's own business, as in any CMake project, and Python-only edits need
no build. Outside git both are empty and the check passes.

  build_current.py --source SOURCE --build-dir BUILD
Exit 0 when current, 1 (with one message naming both commits and the command) when not.
"""
import argparse
import subprocess
import sys
import tempfile
from pathlib import Path

HEADER = Path("generated") / "kneedyn_git_commit.h"


def header_commit(text):
    """The commit of a '#define KNEEDYN_GIT_COMMIT "<commit>[-dirty]"' line, without -dirty."""
    value = text.split('"')[1] if text.count('"') >= 2 else ""
    return value[:-len("-dirty")] if value.endswith("-dirty") else value


def source_commit(source):
    """The commit cmake/git_commit.cmake gives for `source` now (without -dirty)."""
    with tempfile.TemporaryDirectory() as d:
        out = Path(d) / "kneedyn_git_commit.h"
        subprocess.run(["cmake", "-DSOURCE=%s" % source, "-DOUT=%s" % out, "-P",
                        str(source / "cmake" / "git_commit.cmake")], check=True)
        return header_commit(out.read_text())


def stale_reason(source, build):
    """Why `build` does not match `source`, or None."""
    built = build / HEADER
    if not built.is_file():
        return "it has not been built yet (no %s)" % HEADER
    was, now = header_commit(built.read_text()), source_commit(source)
    if was == now:
        return None
    return "it was built at commit %s; the source is now at %s" % (was or "(none)", now or "(none)")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--source", required=True, type=Path)
    ap.add_argument("--build-dir", required=True, type=Path)
    a = ap.parse_args()
    source, build = a.source.resolve(), a.build_dir.resolve()
    reason = stale_reason(source, build)
    if reason is None:
        return 0
    print("kneedyn tests: the build tree %s is stale: %s. The tests would run the older programs. "
          "Build first: cmake --build %s" % (build, reason, build), file=sys.stderr)
    return 1


if __name__ == "__main__":
    sys.exit(main())
