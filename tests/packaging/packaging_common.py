"""What the packaging tests (tests/packaging/*_test.py) share: their arguments with a fresh
work directory, and the verdict they print."""
import argparse
import shutil
from pathlib import Path


def fresh_directory(path):
    """`path` resolved, emptied and created."""
    path = path.resolve()
    shutil.rmtree(path, ignore_errors=True)
    path.mkdir(parents=True)
    return path


def source_build_work():
    """--source, --build-dir, --work, resolved; the work directory fresh."""
    ap = argparse.ArgumentParser()
    ap.add_argument("--source", required=True, type=Path)
    ap.add_argument("--build-dir", required=True, type=Path)
    ap.add_argument("--work", required=True, type=Path)
    args = ap.parse_args()
    return args.source.resolve(), args.build_dir.resolve(), fresh_directory(args.work)


def verdict(problems, ok="OK"):
    """FAIL with each problem, or `ok`; the exit code (1 or 0)."""
    if problems:
        print("FAIL:\n  " + "\n  ".join(problems))
        return 1
    print(ok)
    return 0
