#!/usr/bin/python3
"""Fails if the physics library depends on the loader or the formulations, or if a library
includes a layer above it:

  layering_test.py --probe BIN --yaml-user BIN [--root DIR]

  1. no file in solver/ includes anything from scene/ or formulations/, or yaml-cpp or
     libyaml, or names YAML:: ; solver/CMakeLists.txt links neither yaml-cpp, libyaml nor
     kneedyn_scene / kneedyn_formulations;
  2. `ldd BIN` of --probe (tests/solver_only_probe.cpp, linked with kneedyn_solver alone)
     lists no libyaml (-cpp or -0), and the probe runs (exit 0: its own exact check);
  4. the arrows of docs/architecture.md point down only: no folder of LAYERS includes a
     folder of its own or a higher layer (ensembles/ and problem/ share a layer and use
     neither the other), and the installed (public) headers of formulations/ include nothing
     from formulations/internal/ (which is not installed);
  5. docs/architecture.md is the map of the tree: its diagram names each folder of LAYERS
     at the start of a line, and every folder the top-level CMakeLists.txt enters
     (add_subdirectory) is a layer or is named in its paragraph "Beside them";
  3. so that the test can fail, before scanning: planted bad lines must each be flagged,
     and `ldd` of --yaml-user (a program linking the loader with the shared libyaml, e.g.
     scene_test) must list a libyaml, i.e. the ldd check sees the library when it is there.
"""
import argparse
import os
import re
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

sys.dont_write_bytecode = True  # keep the source tree clean
from py_test_support import finish  # noqa: E402

SOURCE_RULES = [
    ("includes the loader", re.compile(r'#\s*include\s*[<"]scene/')),
    ("includes a formulation", re.compile(r'#\s*include\s*[<"]formulations/')),
    ("includes yaml-cpp", re.compile(r'#\s*include\s*[<"]yaml-cpp/')),
    ("includes libyaml", re.compile(r'#\s*include\s*[<"]yaml\.h[>"]')),
    ("uses yaml-cpp", re.compile(r"\bYAML::")),
]
CMAKE_RULES = [
    ("links yaml-cpp", re.compile(r"target_link_libraries\([^)]*yaml-cpp", re.S)),
    ("links libyaml", re.compile(r"target_link_libraries\([^)]*\byaml\b(?!-)", re.S)),
    ("links the loader or the formulations",
     re.compile(r"target_link_libraries\([^)]*kneedyn_(scene|formulations)", re.S)),
]
# Rule 4: the layers of docs/architecture.md, lowest first; a folder may include only the
# folders of lower layers (and its own). Folders beside the layers (benchmarks/, python/,
# crosscheck/, tests/, examples/) are not checked.
LAYERS = [["solver"], ["scene"], ["formulations"], ["ensembles", "problem"], ["sensitivity"], ["inverse"],
          ["app"]]
UPWARD = {folder: [other for higher in LAYERS[rank:] for other in higher if other != folder]
          for rank, layer in enumerate(LAYERS) for folder in layer}


INTERNAL = re.compile(r'#\s*include\s*[<"]formulations/internal/')


def scan_upward(folder, rel, text):
  hits = []
  if folder == "formulations" and os.path.dirname(rel) == "formulations" and rel.endswith(".hpp"):
    hits += [f"{rel}:{n}: a public header includes an internal one: {line.strip()}"
             for n, line in enumerate(text.splitlines(), 1) if INTERNAL.search(line)]
  for n, line in enumerate(text.splitlines(), 1):
    m = re.search(r'#\s*include\s*[<"]([A-Za-z_]+)/', line)
    if m and m.group(1) in UPWARD[folder]:
      hits.append(f"{rel}:{n}: includes {m.group(1)}/, which is not a layer below {folder}/: {line.strip()}")
  return hits


# Both YAML libraries: libyaml (the project's reader) and yaml-cpp (test oracle, benchmark).
YAML_LIB = re.compile(r"libyaml")


def scan_source(rel, text):
  hits = []
  for n, line in enumerate(text.splitlines(), 1):
    for what, rx in SOURCE_RULES:
      if rx.search(line):
        hits.append(f"{rel}:{n}: {what}: {line.strip()}")
  return hits


def scan_architecture_doc(doc, top_cmake):
  """Rule 5: folders of the build that docs/architecture.md does not place."""
  hits = []
  fence = re.search(r"## Layers.*?```\n(.*?)```", doc, re.S)
  diagram = fence.group(1) if fence else ""
  beside = re.search(r"^Beside them:(.*?)(?:\n\n|\Z)", doc, re.S | re.M)
  beside = beside.group(1) if beside else ""
  layered = [f for layer in LAYERS for f in layer]
  for folder in layered:
    if not re.search(rf"(^|\s){folder}/\s", diagram, re.M):
      hits.append(f"docs/architecture.md: the layer diagram does not show {folder}/")
  for folder in sorted(set(re.findall(r"^\s*add_subdirectory\(([\w-]+)", top_cmake, re.M))):
    if folder not in layered and f"`{folder}/" not in beside:
      hits.append(f"docs/architecture.md: {folder}/ (built by CMakeLists.txt) is neither a layer nor "
                  "named under \"Beside them\"")
  return hits


def scan_cmake(rel, text):
  # Comments are not links.
  text = "\n".join(line.split("#", 1)[0] for line in text.splitlines())
  return [f"{rel}: {what}" for what, rx in CMAKE_RULES if rx.search(text)]


def ldd(binary):
  out = subprocess.run(["ldd", binary], capture_output=True, text=True)
  if out.returncode != 0:
    sys.exit(f"layering: ldd {binary} failed: {out.stderr.strip()}")
  return out.stdout


def main():
  ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
  ap.add_argument("--root", default=ROOT)
  ap.add_argument("--probe", required=True)
  ap.add_argument("--yaml-user", required=True)
  args = ap.parse_args()
  solver = os.path.join(os.path.abspath(args.root), "solver")

  # 3. The checks must be able to fail.
  planted = ['#include "scene/scene.hpp"', '#include "formulations/run.hpp"',
             "#include <yaml-cpp/yaml.h>", "  const YAML::Node n = YAML::Load(text);", "#include <yaml.h>"]
  missed = [p for p in planted if not scan_source("solver/planted.hpp", p)]
  planted_cmake = ["target_link_libraries(kneedyn_solver PUBLIC Eigen3::Eigen\n  yaml-cpp)",
                   "target_link_libraries(kneedyn_solver PRIVATE yaml)",
                   "target_link_libraries(kneedyn_solver PUBLIC kneedyn_scene)"]
  missed += [p for p in planted_cmake if not scan_cmake("solver/CMakeLists.txt", p)]
  clean = '#include "solver/state.hpp"  // filled by the loader (scene/scene.hpp)'
  planted_upward = [("formulations", '#include "ensembles/sweep_cli.hpp"'),
                    ("formulations", '#include "sensitivity/sensitivity_cli.hpp"'),
                    ("ensembles", '#include "app/cli.hpp"'), ("solver", '#include <app/cli.hpp>'),
                    ("scene", '#include "formulations/run.hpp"'), ("problem", '#include "ensembles/sweep.hpp"'),
                    ("ensembles", '#include "problem/problem.hpp"'),
                    ("sensitivity", '#include "inverse/inverse_problem.hpp"')]
  missed += [p for folder, p in planted_upward if not scan_upward(folder, folder + "/planted.cpp", p)]
  planted_internal = '#include "formulations/internal/ida_phase.hpp"'
  if not scan_upward("formulations", "formulations/planted.hpp", planted_internal) or \
     scan_upward("formulations", "formulations/planted.cpp", planted_internal):
    missed.append(planted_internal + " (public header vs. source)")
  if scan_upward("formulations", "formulations/x.cpp", '#include "formulations/run.hpp"  // not ensembles/'):
    missed.append("(clean formulations/ include flagged)")
  if missed or scan_source("solver/x.hpp", clean) or \
     scan_cmake("solver/CMakeLists.txt", "# links no yaml-cpp\ntarget_link_libraries(kneedyn_solver PUBLIC Eigen3::Eigen)"):
    sys.exit(f"layering: self-check failed (missed planted lines {missed} or flagged a clean one)")
  root = os.path.abspath(args.root)
  with open(os.path.join(root, "docs", "architecture.md"), encoding="utf-8") as f:
    doc = f.read()
  with open(os.path.join(root, "CMakeLists.txt"), encoding="utf-8") as f:
    top_cmake = f.read()
  planted_doc = [doc.replace("\nproblem/ ", "\nproblems/ ").replace(" problem/ ", " problems/ "),
                 doc.replace("`fuzz/`", "`fuzzing`")]
  if any(not scan_architecture_doc(d, top_cmake) for d in planted_doc) or \
     not scan_architecture_doc(doc, top_cmake + "\nadd_subdirectory(newfolder)\n"):
    sys.exit("layering: self-check failed: a folder dropped from docs/architecture.md or added to the build "
             "was not flagged")
  if not YAML_LIB.search(ldd(args.yaml_user)):
    sys.exit(f"layering: self-check failed: ldd {args.yaml_user} (links the loader) lists no libyaml, "
             "so the ldd check below could not see it either")

  # 1. Sources and CMake of solver/.
  hits = []
  for dirpath, dirs, files in os.walk(solver):  # solver/internal/ included
    dirs.sort()
    for name in sorted(files):
      path = os.path.join(dirpath, name)
      rel = os.path.relpath(path, root)
      if name == "CMakeLists.txt":
        with open(path, encoding="utf-8") as f:
          hits += scan_cmake(rel, f.read())
      elif name.endswith((".hpp", ".cpp", ".h")):
        with open(path, encoding="utf-8") as f:
          hits += scan_source(rel, f.read())
  # 5. The map of the tree.
  hits += scan_architecture_doc(doc, top_cmake)
  # 4. No include points up.
  for folder in UPWARD:
    for dirpath, _, files in os.walk(os.path.join(root, folder)):
      for name in sorted(files):
        if name.endswith((".hpp", ".cpp", ".h")):
          path = os.path.join(dirpath, name)
          with open(path, encoding="utf-8") as f:
            hits += scan_upward(folder, os.path.relpath(path, root), f.read())
  # 2. The binary linked with kneedyn_solver alone.
  libs = [l.strip() for l in ldd(args.probe).splitlines() if YAML_LIB.search(l)]
  if libs:
    hits.append(f"{args.probe} (kneedyn_solver only) loads {libs}")
  run = subprocess.run([args.probe], capture_output=True, text=True)
  if run.returncode != 0:
    hits.append(f"{args.probe} exit {run.returncode}: {run.stdout.strip()} {run.stderr.strip()}")
  return finish(hits, "layering:", f"layering: {len(hits)} violation(s); self-check caught "
                f"{len(planted) + len(planted_cmake) + len(planted_upward)} planted lines", sys.stdout)


if __name__ == "__main__":
  sys.exit(main())
