#!/usr/bin/env python3
"""`pip install .` and `pip wheel .` as a user runs them (tests/packaging/CMakeLists.txt).

Each in a fresh venv with --system-site-packages (Debian's NumPy, setuptools, pip), offline
(--no-index), --no-build-isolation, with KNEEDYN_CMAKE_BUILD_DIR at this build tree so that
setup.py rebuilds nothing that is up to date. Then, from a directory outside the source
tree and without PYTHONPATH or KNEEDYN_DATA_DIR:
  - every file of `cmake --install --component runtime` is in the venv, byte for byte
    (the Python package in its site-packages, the rest under the venv's prefix);
  - `import kneedyn` loads the venv's copy, whose data_dir() is the venv's share/kneedyn;
  - kneedyn.run(kneedyn.load_scene(kneedyn.scene_path('chapter_impact'))) completes, and
    the venv's `kneedyn` program runs that installed scene to the same summary.
"""
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from packaging_common import source_build_work, verdict


def run(cmd, **kw):
    print("+ " + " ".join(str(c) for c in cmd), flush=True)
    return subprocess.run([str(c) for c in cmd], check=True, **kw)


def clean_env(**extra):
    env = {k: v for k, v in os.environ.items()
           if k not in ("PYTHONPATH", "KNEEDYN_DATA_DIR", "PYTHONHOME", "VIRTUAL_ENV")}
    env.update(extra)
    return env


def make_venv(path):
    shutil.rmtree(path, ignore_errors=True)
    # No pip of its own: Debian's (system site) installs into the venv it runs in.
    run(["/usr/bin/python3", "-m", "venv", "--system-site-packages", "--without-pip", path])
    return path / "bin" / "python"


CHECK = r"""
import json, os, sys
import kneedyn

scene_path = kneedyn.scene_path('chapter_impact')
r = kneedyn.run(kneedyn.load_scene(scene_path))
print(json.dumps({"module": kneedyn.__file__, "data_dir": kneedyn.data_dir(), "scene_path": scene_path,
                  "completed": r.completed, "summary": r.summary}))
"""


def comparable(summary):
    s = dict(summary)
    for volatile in ("wall_time_s", "command_line", "git_commit", "scene_path", "scene_file", "outputs"):
        s.pop(volatile, None)
    return s


def check_venv(venv, expected, pyrel, outside):
    """expected: {relative path under the install prefix: bytes}."""
    python = venv / "bin" / "python"
    site = Path(subprocess.run([python, "-c", "import sysconfig; print(sysconfig.get_path('platlib'))"],
                               check=True, capture_output=True, text=True, env=clean_env()).stdout.strip())
    problems = []
    for rel, content in expected.items():
        where = site / Path(rel).relative_to(pyrel) if Path(rel).is_relative_to(pyrel) else venv / rel
        if not where.is_file():
            problems.append("missing: %s (installed by cmake --install --component runtime as %s)" % (where, rel))
        elif where.read_bytes() != content:
            problems.append("differs from the CMake install: %s" % where)
    out = subprocess.run([python, "-c", CHECK], cwd=outside, check=True, capture_output=True, text=True,
                         env=clean_env()).stdout
    got = json.loads(out.strip().splitlines()[-1])
    if not Path(got["module"]).is_relative_to(site):
        problems.append("import kneedyn loaded %s, not the venv's copy under %s" % (got["module"], site))
    if Path(got["data_dir"]).resolve() != (venv / "share" / "kneedyn").resolve():
        problems.append("kneedyn.data_dir() = %s, expected the venv's share/kneedyn" % got["data_dir"])
    if not got["completed"]:
        problems.append("kneedyn.run(chapter_impact) did not complete: %s" % got["summary"].get("failure"))

    # The program, on the installed scene, from outside the source tree.
    cli_out = outside / ("cli_" + venv.name)
    shutil.rmtree(cli_out, ignore_errors=True)
    run([venv / "bin" / "kneedyn", "--version"], cwd=outside, env=clean_env())
    run([venv / "bin" / "kneedyn", "run", got["scene_path"], "--quiet", "--out", cli_out], cwd=outside, env=clean_env())
    cli = json.loads((cli_out / "summary.json").read_text())
    a, b = comparable(cli), comparable(got["summary"])
    if a != b:
        diff = sorted(k for k in set(a) | set(b) if a.get(k) != b.get(k))
        problems.append("the venv's kneedyn program and module disagree on chapter_impact in: %s" % diff)
    return problems


def main():
    source, build, work = source_build_work()

    env = clean_env(KNEEDYN_CMAKE_BUILD_DIR=str(build))
    outside = Path(tempfile.mkdtemp(prefix="kneedyn-user-", dir=work))
    problems = []
    timings = {}

    t0 = time.monotonic()
    python = make_venv(work / "venv-install")
    run([python, "-m", "pip", "install", "--no-build-isolation", "--no-index", "-q", source], env=env, cwd=work)
    timings["pip install ."] = time.monotonic() - t0
    # What the wheel must hold: the runtime component, installed by CMake itself (after pip
    # brought the tree up to date).
    prefix = work / "cmake-runtime"
    run(["cmake", "--install", build, "--component", "runtime", "--prefix", prefix], stdout=subprocess.DEVNULL)
    expected = {p.relative_to(prefix).as_posix(): p.read_bytes() for p in prefix.rglob("*") if p.is_file()}
    modules = [r for r in expected if Path(r).name.startswith("_kneedyn")]
    if len(modules) != 1:
        return print("FAIL: cmake --install --component runtime installed %d _kneedyn modules" % len(modules)) or 1
    pyrel = Path(modules[0]).parent.parent  # e.g. lib/python3.11/site-packages
    print("runtime component: %d files; Python package under %s" % (len(expected), pyrel))

    problems += ["pip install .: " + p for p in check_venv(work / "venv-install", expected, pyrel, outside)]

    t0 = time.monotonic()
    wheels = work / "wheels"
    run([python, "-m", "pip", "wheel", "--no-build-isolation", "--no-index", "--no-deps", "-q", "-w", wheels, source],
        env=env, cwd=work)
    found = sorted(wheels.glob("kneedyn-*.whl"))
    if len(found) != 1:
        sys.exit("FAIL: pip wheel wrote %s" % [p.name for p in wheels.iterdir()])
    python = make_venv(work / "venv-wheel")
    run([python, "-m", "pip", "install", "--no-index", "-q", found[0]], env=clean_env(), cwd=work)
    timings["pip wheel + install"] = time.monotonic() - t0
    problems += ["wheel %s: %s" % (found[0].name, p) for p in check_venv(work / "venv-wheel", expected, pyrel, outside)]

    for what, seconds in timings.items():
        print("%-22s %.1f s" % (what, seconds))
    return verdict(problems, "OK: %s and the venvs of both paths hold the %d files of the runtime component"
                   % (found[0].name, len(expected)), work=work)


if __name__ == "__main__":
    sys.exit(main())
