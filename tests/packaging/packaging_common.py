"""What the packaging tests (tests/packaging/*_test.py) share: their arguments with a fresh
work directory, the check that the build tree is current, and the verdict they print."""
import argparse
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path


def fresh_directory(path):
    """`path` resolved, emptied and created."""
    path = path.resolve()
    shutil.rmtree(path, ignore_errors=True)
    path.mkdir(parents=True)
    return path


def write_commit_header(source, out):
    """Writes to `out` the commit header a build of `source` would get now
    (cmake/git_commit.cmake, the script the build runs)."""
    subprocess.run(["cmake", "-DSOURCE=%s" % source, "-DOUT=%s" % out, "-P",
                    str(source / "cmake" / "git_commit.cmake")], check=True)


def stale_build_reason(source, build):
    """Why `build` is older than `source`'s git state, or None.

    pip (setup.py with KNEEDYN_CMAKE_BUILD_DIR) and cpack (its preinstall target) build the
    tree they are given. When the commit the tree was built at is not the source's now (a
    commit, or the first edit, after the build), the generated commit header changes and they
    relink kneedyn, the Python module and the test programs while the tests beside them run
    those files: a test then fails on a half-written file, or on a module and a program of two
    builds. The header the build would write now is compared with the tree's.
    """
    built = build / "generated" / "kneedyn_git_commit.h"
    if not built.is_file():
        return None  # no commit header to compare (an unconfigured tree fails later, by name)
    built_text = built.read_text()
    with tempfile.TemporaryDirectory() as d:
        now = Path(d) / "kneedyn_git_commit.h"
        write_commit_header(source, now)
        now_text = now.read_text()
    if now_text == built_text:
        return None
    return "built at %s, the source is now at %s" % (built_text.split()[-1], now_text.split()[-1])


def source_build_work():
    """--source, --build-dir, --work, resolved; the work directory fresh. Exits 1 before
    touching anything when the build tree is stale (stale_build_reason)."""
    ap = argparse.ArgumentParser()
    ap.add_argument("--source", required=True, type=Path)
    ap.add_argument("--build-dir", required=True, type=Path)
    ap.add_argument("--work", required=True, type=Path)
    args = ap.parse_args()
    source, build = args.source.resolve(), args.build_dir.resolve()
    reason = stale_build_reason(source, build)
    if reason:
        print("FAIL: the build tree %s is stale (%s); this test would relink the programs under the "
              "tests running beside it. Build first: cmake --build %s" % (build, reason, build))
        sys.exit(1)
    return source, build, fresh_directory(args.work)


def verdict(problems, ok="OK", work=None):
    """FAIL with each problem, or `ok`; the exit code (1 or 0). On success the work directory
    (installs, packages, venvs: 40-130 MB each) is removed, so that the suite's disk use does
    not grow with each test on a machine short of space; on failure it is kept to look at."""
    if problems:
        print("FAIL:\n  " + "\n  ".join(problems))
        return 1
    if work is not None:
        shutil.rmtree(work, ignore_errors=True)
    print(ok)
    return 0
