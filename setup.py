"""`pip install .` and `pip wheel .`: the project's CMake builds the Python module and the
programs; the wheel holds what `cmake --install --component runtime` installs
(cmake/install.cmake):

  kneedyn/ (the package: __init__.py, _kneedyn*.so)   -> site-packages
  bin/kneedyn, bin/kneedyn_catalog                   -> <prefix>/bin
  lib/kneedyn/kneedyn_sweep_io.so (sweep.h5, mpirun),
  lib/kneedyn/kneedyn_ceres_fallback.so (Ceres)       -> <prefix>/lib/kneedyn
  share/kneedyn/ (scenes, parameter set, references)  -> <prefix>/share/kneedyn

The programs and the module find the data and the plugins relative to themselves, so a venv
(or ~/.local, or /usr/local) works as an install prefix. Offline with Debian's setuptools:
`pip install --no-build-isolation .` (docs/python.md, "Install with pip").

KNEEDYN_CMAKE_BUILD_DIR=DIR: use that configured build tree (e.g. build/ after
`bash .ci/bootstrap test`) instead of configuring a private one under build/python-package/;
only the needed targets are (re)built there. Its CMake options are left as they are.
"""
import os
import re
import shutil
import subprocess
import sys
import sysconfig
from pathlib import Path

from setuptools import Extension, setup
from setuptools.command.build_ext import build_ext

ROOT = Path(__file__).resolve().parent
# Everything setuptools writes stays under build/ (the project's build directory).
BUILD_BASE = Path("build") / "python-package"
TARGETS = ["_kneedyn", "kneedyn", "kneedyn_catalog"]


def project_version():
    text = (ROOT / "CMakeLists.txt").read_text()
    match = re.search(r"project\(kneedyn\s+VERSION\s+([0-9.]+)", text)
    if not match:
        sys.exit("setup.py: no 'project(kneedyn VERSION x.y.z)' in CMakeLists.txt")
    return match.group(1)


def run(cmd):
    print("[setup.py] " + " ".join(str(c) for c in cmd), flush=True)
    subprocess.run([str(c) for c in cmd], check=True)


class CMakeBuild(build_ext):
    """Builds with CMake, installs the runtime component into a staging prefix, puts the
    package into the wheel's library tree and the rest into its data tree."""

    def build_extension(self, ext):
        cmake = shutil.which("cmake")
        if not cmake:
            sys.exit("setup.py: cmake not found (Debian: apt-get install cmake; see .ci/bootstrap)")
        jobs = os.environ.get("CMAKE_BUILD_PARALLEL_LEVEL", str(os.cpu_count() or 1))
        given = os.environ.get("KNEEDYN_CMAKE_BUILD_DIR")
        if given:
            tree = Path(given).resolve()
            if not (tree / "CMakeCache.txt").is_file():
                sys.exit("setup.py: KNEEDYN_CMAKE_BUILD_DIR = '%s': not a configured CMake build tree "
                         "(no CMakeCache.txt)" % given)
        else:
            tree = (ROOT / BUILD_BASE / "cmake").resolve()
            run([cmake, "-S", ROOT, "-B", tree, "-DCMAKE_BUILD_TYPE=Release", "-DKNEEDYN_BUILD_TESTS=OFF",
                 "-DKNEEDYN_WITH_PYTHON=ON", "-DKNEEDYN_PYTHON=" + sys.executable,
                 "-DPYTHON_EXECUTABLE=" + sys.executable])
        run([cmake, "--build", tree, "-j", jobs, "--target"] + TARGETS)

        stage = (ROOT / BUILD_BASE / "stage").resolve()
        shutil.rmtree(stage, ignore_errors=True)
        run([cmake, "--install", tree, "--component", "runtime", "--prefix", stage])

        # The package: the directory the install put _kneedyn into, for this interpreter.
        suffix = sysconfig.get_config_var("EXT_SUFFIX")
        modules = sorted(stage.rglob("_kneedyn*.so"))
        if not modules:
            sys.exit("setup.py: the CMake install of %s put no _kneedyn module under %s "
                     "(is KNEEDYN_WITH_PYTHON off there?)" % (tree, stage))
        if modules[0].name != "_kneedyn" + suffix:
            sys.exit("setup.py: %s was built for another Python (module '%s'; this interpreter, %s, "
                     "loads '_kneedyn%s')" % (tree, modules[0].name, sys.executable, suffix))
        package = modules[0].parent
        target = Path(self.get_ext_fullpath(ext.name)).parent
        shutil.rmtree(target, ignore_errors=True)
        shutil.copytree(package, target)

        # The rest (programs, plugin, data), relative to the install prefix.
        site = package.parent
        data = {}
        for path in sorted(stage.rglob("*")):
            if path.is_file() and site not in path.parents:
                data.setdefault(str(path.parent.relative_to(stage)), []).append(str(path))
        self.distribution.data_files = sorted(data.items())


# egg_info writes there before any command runs.
(ROOT / BUILD_BASE).mkdir(parents=True, exist_ok=True)
setup(
    version=project_version(),
    packages=[],  # the package comes from the CMake install (CMakeBuild), not from a scan
    py_modules=[],
    ext_modules=[Extension("kneedyn._kneedyn", sources=[])],
    cmdclass={"build_ext": CMakeBuild},
    options={"build": {"build_base": str(BUILD_BASE)}, "egg_info": {"egg_base": str(BUILD_BASE)}},
    zip_safe=False,
)
