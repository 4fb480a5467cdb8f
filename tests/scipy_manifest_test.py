#!/usr/bin/env python3
"""The fairness manifest of the SciPy side by side (benchmarks/scipy_side_by_side.py --json):
context.components holds kneedyn's build (kneedyn.build_manifest(), formulations/version.hpp)
and then SciPy's entry, whose version is the imported SciPy's, whose origin names the Debian
package with the version dpkg records (queried here, not by the script's code path), and whose
compile flags name every compiler SciPy's own build config records.

  tests/scipy_manifest_test.py [--module-required]   (PYTHONPATH=build/python for the module)
With --module-required (ctest) the real module's manifest is checked too: kneedyn, SUNDIALS,
Ceres, Eigen first, SciPy appended last."""
import json
import re
import os
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(os.path.dirname(HERE), "benchmarks"))
import scipy  # noqa: E402
import scipy_side_by_side as sbs  # noqa: E402

errors = []


def check(cond, what):
    if not cond:
        errors.append(what)


entry = sbs.scipy_component()
check(set(entry) == {"name", "version", "origin", "compile_flags"}, "fields %s" % sorted(entry))
check(entry["name"] == "SciPy", "name %r" % entry["name"])
check(entry["version"] == scipy.__version__, "version %r, imported SciPy %r" % (entry["version"], scipy.__version__))
deb = subprocess.run(["dpkg-query", "-W", "-f=${Version}", "python3-scipy"], capture_output=True, text=True).stdout.strip()
if deb:
    check("python3-scipy" in entry["origin"] and deb in entry["origin"], "origin %r lacks python3-scipy %s" % (entry["origin"], deb))
    check(deb.split("-")[0].split(":")[-1] == scipy.__version__, "dpkg %s is not the imported SciPy %s" % (deb, scipy.__version__))
check(entry["compile_flags"].strip() != "", "empty compile_flags")
config = scipy.show_config(mode="dicts")
for lang, c in config.get("Compilers", {}).items():
    if isinstance(c, dict) and c.get("version"):
        check(c["version"] in entry["compile_flags"], "compiler %s %s missing from %r" % (lang, c["version"], entry["compile_flags"]))


class FakeModule:
    """kneedyn's manifest as two entries: the SciPy entry goes after them, they stay as given."""
    @staticmethod
    def build_manifest():
        return [{"name": "kneedyn", "version": "9.9", "origin": "here", "compile_flags": "-O3"},
                {"name": "SUNDIALS", "version": "6.4.1", "origin": "there", "compile_flags": "-O3"}]


rows = [("scipy DOP853", 1e-8, 0.2162941, 6.5, 0.12), ("kneedyn ede cvode-adams", 1e-8, 0.21629413, 7.9, 0.003)]
doc = json.loads(json.dumps(sbs.side_by_side_json(FakeModule, rows, 0.216294134086, 1)))
comps = doc["context"]["components"]
check([c["name"] for c in comps] == ["kneedyn", "SUNDIALS", "SciPy"], "components %s" % [c["name"] for c in comps])
check(comps[:2] == FakeModule.build_manifest(), "kneedyn's entries changed")
check(comps[-1] == entry, "SciPy entry %r" % comps[-1])
check(len(doc["results"]) == 2 and doc["results"][0]["run"] == "scipy DOP853", "results %r" % doc["results"])
# The file says what made it, as the recorded sweeps do: the command, commit and date.
prov = sbs.recorded_provenance(sbs.__file__, ["--quick", "--json", "X.json"])
doc = sbs.side_by_side_json(FakeModule, rows, 0.216294134086, 1, prov)
check(doc["provenance"]["command"] == "benchmarks/scipy_side_by_side.py --quick --json X.json"
      and doc["provenance"]["commit"] and re.fullmatch(r"\d{4}-\d\d-\d\dT\d\d:\d\d:\d\dZ", doc["provenance"]["date"]),
      "provenance %r" % doc["provenance"])

if "--module-required" in sys.argv:
    import kneedyn as kn
    names = [c["name"] for c in sbs.components(kn)]
    for n in ("kneedyn", "SUNDIALS", "Ceres", "Eigen"):
        check(n in names[:-1], "%s not in the module's manifest %s" % (n, names))
    check(names[-1] == "SciPy", "SciPy not last: %s" % names)
    for c in kn.build_manifest():
        check(all(isinstance(c.get(k), str) and c[k] for k in ("name", "version", "origin", "compile_flags")),
              "incomplete module entry %r" % c)

for e in errors:
    print("FAILED:", e)
print("scipy_manifest: %d checks failed" % len(errors) if errors else "scipy_manifest: ok")
sys.exit(1 if errors else 0)
