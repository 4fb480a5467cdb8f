"""pytest suite of the kneedyn Python module, run by ctest (label python).

What it validates:
  - the module's runs equal the CLI's for the same scene and settings: every cell of
    trajectory.csv (the CSV prints 12 significant digits, "%.12g", so that is the
    precision this comparison has) and, bitwise, everything in summary.json (JSON numbers
    are written shortest-round-trip, so equal text means equal doubles): events, final
    state, initialization residuals, solver counters;
  - scenes edited in Python equal the same edits written to a file and run by the CLI;
  - bad scenes and options raise InputError with the loader's message (field and value),
    the same text the CLI prints before exiting with code 2, and leave the scene unchanged;
  - a thread pool of runs gives bitwise the same results as serial runs.
What it does not: accuracy of the physics (the C++ suites do that).
"""
import concurrent.futures
import copy
import csv
import io
import json
import math
import os
import pathlib
import shutil
import subprocess
import sys
import tempfile

import numpy as np
import pytest

import kneedyn

CLI = os.environ.get("KNEEDYN_CLI", "build/formulations/kneedyn")
OUT = os.environ.get("KNEEDYN_TEST_OUT") or tempfile.mkdtemp(prefix="kneedyn_py_")
CHAPTER = os.path.join("reference-data", "scenes", "chapter_impact.yaml")

# (formulation, options): one per family of method (IDA, fixed-step Newton, explicit RK
# with error control, CVODE).
CASES = [
    ("dae", dict(rtol=1e-8, atol=1e-10)),
    ("newmark", dict(step=2e-4)),
    ("mde", dict(integrator="dopri5", rtol=1e-7, atol=1e-9)),
    ("ede", dict(integrator="cvode-bdf", stabilization="cvode-projection")),
    ("dae-reduced", dict(rtol=1e-8, atol=1e-10, jacobian="jet")),
    ("dae-ggl", dict(rtol=1e-8, atol=1e-10, linear_solver="dense")),
    ("generalized-alpha", dict(step=2e-4, contact_chart="height-field")),
    # The scheme's parameters, as the CLI's --rho-inf (before: no keyword, only the default 0.9).
    ("generalized-alpha", dict(step=2e-4, rho_inf=0.5)),
]


def cli_args(options):
    args = []
    for k, v in options.items():
        args += ["--" + k.replace("_", "-"), repr(v) if isinstance(v, float) else str(v)]
    return args


def run_cli(scene_file, formulation, options, name):
    out = os.path.join(OUT, name)
    p = subprocess.run([CLI, "run", scene_file, "--formulation", formulation, "--quiet", "--out", out]
                       + cli_args(options), capture_output=True, text=True)
    assert p.returncode == 0, p.stderr
    with open(os.path.join(out, "trajectory.csv")) as f:
        rows = list(csv.reader(f))
    with open(os.path.join(out, "summary.json")) as f:
        summary = json.load(f)
    return rows[0], rows[1:], summary


def assert_same_as_cli(result, header, rows, summary, ignore_path=False):
    traj = result.trajectory
    assert traj.columns == header
    assert len(traj) == len(rows)
    mismatches = []
    for c, name in enumerate(header):
        col = traj[name]
        for r, row in enumerate(rows):
            mine = "" if not math.isfinite(col[r]) else "%.12g" % col[r]
            if mine != row[c]:
                mismatches.append((r, name, mine, row[c]))
    assert not mismatches, mismatches[:5]
    a, b = dict(result.summary), dict(summary)
    # The CLI records its argv in command_line; a run from Python has none (empty list).
    assert a.pop("command_line") == [] and b.pop("command_line")[1] == "run"
    for d in (a, b):
        d.pop("wall_time_s")
        if ignore_path:
            d["scene"].pop("path")
    assert a == b


@pytest.mark.parametrize("formulation,options", CASES, ids=["%s-%d" % (c[0], i) for i, c in enumerate(CASES)])
def test_run_equals_cli(formulation, options):
    case = "%s_%d" % (formulation, CASES.index((formulation, options)))
    header, rows, summary = run_cli(CHAPTER, formulation, options, "cli_" + case)
    result = kneedyn.run(kneedyn.load_scene(CHAPTER), formulation, **options)
    assert result.completed and result.end_reason == "flexion_90"
    assert_same_as_cli(result, header, rows, summary)
    # The trajectory is float64 straight from the driver, not re-read from text: the CSV's
    # 12 digits agree to their rounding.
    flex = np.array([float(r[header.index("flexion_deg")]) for r in rows])
    assert np.allclose(result.trajectory["flexion_deg"], flex, rtol=1e-11, atol=0)
    # out=DIR writes the CLI's files: the same bytes (summary.json up to its wall time).
    mine = os.path.join(OUT, "py_" + case)
    kneedyn.run(kneedyn.load_scene(CHAPTER), formulation, out=mine, **options)
    for name in ("trajectory.csv", "trajectory.sto"):
        with open(os.path.join(mine, name)) as f1, open(os.path.join(OUT, "cli_" + case, name)) as f2:
            assert f1.read() == f2.read(), name
    with open(os.path.join(mine, "summary.json")) as f:
        written = json.load(f)
    written.pop("wall_time_s"), summary.pop("wall_time_s")
    written.pop("command_line"), summary.pop("command_line")  # the CLI's argv; none from Python
    assert written == summary


def test_python_edits_equal_the_same_edits_in_a_file():
    scene = kneedyn.load_scene(CHAPTER)
    removed = scene.remove_ligaments("ACL")
    assert removed == ["ACL anterior", "ACL posterior"]
    scene.set_pulse(amplitude_N=80.0, duration_s=0.12)
    scene.set_end(flexion_deg=70.0, time_s=1.0)
    scene.set_ligament_stiffness_scale(1.1)
    assert scene.pulse["amplitude_N"] == 80.0 and scene.end["flexion_deg"] == pytest.approx(70.0)
    assert len(scene.ligaments) == 10 and not any("ACL" in n for n in scene.ligaments)
    path = os.path.join(OUT, "edited_scene.yaml")
    os.makedirs(OUT, exist_ok=True)
    scene.write(path)
    header, rows, summary = run_cli(path, "dae", dict(rtol=1e-7, atol=1e-9), "cli_edited")
    result = kneedyn.run(scene, "dae", rtol=1e-7, atol=1e-9)
    assert summary["scene"]["ligaments"] == 10
    assert_same_as_cli(result, header, rows, summary, ignore_path=True)
    assert not any(c.startswith("F_ACL") for c in result.trajectory.columns)
    # The edits changed the run (the file on disk was not touched).
    base = kneedyn.run(kneedyn.load_scene(CHAPTER), "dae", rtol=1e-7, atol=1e-9)
    assert base.trajectory["flexion_deg"].shape != result.trajectory["flexion_deg"].shape or \
        not np.array_equal(base.trajectory["flexion_deg"], result.trajectory["flexion_deg"])


def test_ligament_parameters_equal_the_stiffness_scale():
    # Doubling both stiffnesses of every element by ligament_parameters is what
    # ligament_stiffness_scale 2 does (a power of two: bitwise the same model and run).
    by_element = kneedyn.load_scene(CHAPTER)
    for lig in by_element.ligament_parameters:
        by_element.set_ligament_parameters(lig["name"], k_linear_N_mm=2 * lig["k_linear_N_mm"])
    doc = by_element.to_dict()
    for name, p in doc["ligament_parameters"].items():
        pub = next(l for l in kneedyn.load_scene(CHAPTER).ligament_parameters if l["name"] == name)
        # k_parabolic as the law uses it is the published one under ligament_law: published
        p["k_parabolic_N_mm2"] = 2 * pub["k_parabolic_N_mm2"]
    by_element.update(doc)
    scaled = kneedyn.load_scene(CHAPTER).set_ligament_stiffness_scale(2.0)
    assert by_element.ligament_parameters == scaled.ligament_parameters
    a = kneedyn.run(by_element, "dae-reduced")
    b = kneedyn.run(scaled, "dae-reduced")
    assert np.array_equal(a.trajectory.array, b.trajectory.array, equal_nan=True)
    # extension ratio: slack length = reference length / ratio (Eq. 1.16's L0).
    s = kneedyn.load_scene(CHAPTER).set_ligament_parameters("LCL", extension_ratio=1.25)
    lcl = next(l for l in s.ligament_parameters if l["name"] == "LCL")
    assert lcl["slack_length_mm"] == pytest.approx(lcl["reference_length_mm"] / 1.25, rel=1e-14)
    with pytest.raises(kneedyn.InputError, match=r"field 'ligament_parameters.LCL.extension_ratio' = '0': must be > 0"):
        s.set_ligament_parameters("LCL", extension_ratio=0)
    with pytest.raises(kneedyn.InputError, match=r"field 'ligament_parameters.LCL.stiffness'.*unknown ligament parameter"):
        s.set_ligament_parameters("LCL", stiffness=3)
    s.remove_ligaments("ACL")
    with pytest.raises(kneedyn.InputError, match=r"field 'ligament_parameters.ACL anterior': not a ligament element selected"):
        s.set_ligament_parameters("ACL anterior", k_linear_N_mm=10)


def test_removing_an_element_removes_its_override():
    """An element removed with its ligament_parameters entry: the scene is the one without
    that element (before: InputError, the override naming an element no longer selected)."""
    scene = kneedyn.load_scene(CHAPTER)
    scene.set_ligament_parameters("LCL", k_linear_N_mm=10)
    assert scene.remove_ligaments("LCL") == ["LCL"]
    plain = kneedyn.load_scene(CHAPTER)
    plain.remove_ligaments("LCL")
    a = kneedyn.run(scene, "dae-reduced")
    b = kneedyn.run(plain, "dae-reduced")
    assert np.array_equal(a.trajectory.array, b.trajectory.array, equal_nan=True)
    # The same through the selection itself, down to no element at all.
    selected = kneedyn.load_scene(CHAPTER)
    selected.set_ligament_parameters("LCL", k_linear_N_mm=10)
    selected.ligaments = [n for n in selected.ligaments if n != "LCL"]
    c = kneedyn.run(selected, "dae-reduced")
    assert np.array_equal(c.trajectory.array, b.trajectory.array, equal_nan=True)
    selected.ligaments = []
    assert selected.ligaments == [] and not selected.to_dict().get("ligament_parameters")


def test_from_dict_equals_load_scene():
    scene = kneedyn.load_scene(CHAPTER)
    doc = scene.to_dict()
    again = kneedyn.Scene.from_dict(doc, base_dir=os.path.dirname(CHAPTER))
    a = kneedyn.run(scene, "dae-reduced")
    b = kneedyn.run(again, "dae-reduced")
    assert np.array_equal(a.trajectory.array, b.trajectory.array, equal_nan=True)


def test_written_copy_of_a_shipped_scene_runs_from_anywhere(tmp_path):
    """A shipped scene copied elsewhere finds its ../chapter_knee.yaml as a shipped scene's
    (the loader looks in <data>/scenes/); Scene.write must write that file's path. Before, it
    wrote <data>/chapter_knee.yaml, which does not exist, and the CLI refused the file."""
    os.makedirs(tmp_path / "sub")
    copy_path = tmp_path / "sub" / "s.yaml"
    shutil.copy(CHAPTER, copy_path)
    scene = kneedyn.load_scene(str(copy_path))
    scene.set_pulse(amplitude_N=90.0)
    written = tmp_path / "w.yaml"
    scene.write(str(written))
    again = kneedyn.load_scene(str(written))  # the loader's own reading of the written path
    assert os.path.samefile(again.to_dict()["parameter_set"], os.path.join(kneedyn.data_dir(), "chapter_knee.yaml"))
    a = kneedyn.run(scene, "dae-reduced")
    b = kneedyn.run(again, "dae-reduced")
    assert np.array_equal(a.trajectory.array, b.trajectory.array, equal_nan=True)


def chapter_doc():
    return kneedyn.load_scene(CHAPTER).to_dict()


@pytest.mark.parametrize("change,field,value", [
    ({"pulse": {"amplitude_N": -5.0}}, "pulse.amplitude_N", "-5.0"),  # floats as repr(): -5.0 stays -5.0
    ({"pulse": {"shape": "square"}}, "pulse.shape", "square"),
    ({"end": {"flexion_deg": -10}}, "end.flexion_deg", "-10"),
    ({"ligaments": ["ACL anterior", "no such ligament"]}, "ligaments[1]", "no such ligament"),
    ({"gravity": {"enabled": "maybe"}}, "gravity.enabled", "maybe"),
    ({"output": {"interval_s": float("nan")}}, "output.interval_s", ".nan"),
])
def test_bad_scene_raises_loader_message(change, field, value):
    scene = kneedyn.load_scene(CHAPTER)
    before = scene.to_dict()
    with pytest.raises(kneedyn.InputError) as e:
        scene.update(change)
    msg = str(e.value)
    assert "field '%s'" % field in msg and "'%s'" % value in msg, msg
    assert scene.to_dict() == before  # unchanged
    with pytest.raises(ValueError):  # InputError is a ValueError
        doc = chapter_doc()
        kneedyn.Scene.from_dict(doc, base_dir=os.path.dirname(CHAPTER)).update(change)


def test_bad_scene_message_is_the_clis():
    doc = chapter_doc()
    doc["pulse"]["duration_s"] = 0
    doc["parameter_set"] = os.path.abspath(os.path.join(os.path.dirname(CHAPTER), doc["parameter_set"]))
    path = os.path.join(OUT, "bad_scene.yaml")
    os.makedirs(OUT, exist_ok=True)
    with open(path, "w") as f:
        f.write(kneedyn._kneedyn.to_yaml(doc))
    with pytest.raises(kneedyn.InputError) as e:
        kneedyn.load_scene(path)
    out_dir = os.path.join(OUT, "bad_scene_out")
    p = subprocess.run([CLI, "run", path, "--quiet", "--out", out_dir], capture_output=True, text=True)
    assert p.returncode == 2
    assert p.stderr.strip() == "kneedyn: error: " + str(e.value)
    assert "field 'pulse.duration_s' = '0': must lie in" in str(e.value)
    assert not os.path.exists(out_dir)


def test_missing_field_unknown_type_and_missing_file():
    with pytest.raises(kneedyn.InputError, match="missing required field 'parameter_set'"):
        kneedyn.Scene.from_dict({"name": "x"})
    doc = chapter_doc()
    doc["pulse"]["amplitude_N"] = object()
    with pytest.raises(kneedyn.InputError, match=r"field 'pulse.amplitude_N' = <object"):
        kneedyn.Scene.from_dict(doc)
    with pytest.raises(kneedyn.InputError, match="cannot open scene file '/no/such.yaml'"):
        kneedyn.load_scene("/no/such.yaml")
    scene = kneedyn.load_scene(CHAPTER)
    with pytest.raises(kneedyn.InputError, match="pattern 'XYZ' matches no element"):
        scene.remove_ligaments("XYZ")


def test_a_scene_that_is_neither_a_scene_nor_a_path_names_the_argument():
    # Before, str() of any object was taken as a file name: "cannot open scene file 'None'".
    with pytest.raises(kneedyn.InputError, match=r"run\(\): scene = None \(NoneType\): must be a kneedyn.Scene"):
        kneedyn.run(None)
    with pytest.raises(kneedyn.InputError, match=r"run\(\): scene = \{'name': 'x'\} \(dict\).*Scene.from_dict"):
        kneedyn.run({"name": "x"})
    with pytest.raises(kneedyn.InputError, match=r"sensitivity\(\): scene = 5 \(int\)"):
        kneedyn.sensitivity(5, ["PCL_anterior.k_linear"], ["peak_F_PCL_anterior_N"])
    with pytest.raises(kneedyn.InputError, match=r"load_scene\(\): path = \[1, 2\] \(list\)"):
        kneedyn.load_scene([1, 2])
    with pytest.raises(kneedyn.InputError, match=r"sweep\(\): spec_path = None"):
        kneedyn.sweep(None)
    # out= and the name lists: before, run(out=5) wrote into a directory named '5', and a
    # single name was taken letter by letter ("'P' is not a parameter").
    with pytest.raises(kneedyn.InputError, match=r"run\(\): out = 5 \(int\)"):
        kneedyn.run(CHAPTER, out=5)
    with pytest.raises(kneedyn.InputError, match=r"parameters = 'PCL_anterior.k_linear': must be a list of names"):
        kneedyn.sensitivity(CHAPTER, "PCL_anterior.k_linear", ["peak_F_PCL_anterior_N"])
    with pytest.raises(kneedyn.InputError, match=r"outcomes: 3 \(int\) is not a name"):
        kneedyn.sensitivity(CHAPTER, ["PCL_anterior.k_linear"], [3])
    # Integers past int64 (pybind11's TypeError named no argument) and fractions are refused.
    with pytest.raises(kneedyn.InputError, match=r"run\(\): max_steps = 1e\+20: must be a whole number"):
        kneedyn.run(CHAPTER, max_steps=1e20)
    with pytest.raises(kneedyn.InputError, match=r"run\(\): max_steps = 2.5"):
        kneedyn.run(CHAPTER, max_steps=2.5)
    with pytest.raises(kneedyn.InputError, match=r"sweep\(\): threads = 1000000000000000000000"):
        kneedyn.sweep(os.path.join(OUT, "does_not_matter.yaml"), threads=10**21)
    # Paths as bytes and os.PathLike are paths.
    assert kneedyn.load_scene(pathlib.Path(CHAPTER)).to_dict() == kneedyn.load_scene(os.fsencode(CHAPTER)).to_dict()


def test_bad_options_raise_before_running():
    scene = kneedyn.load_scene(CHAPTER)
    # The C++ rule's text, naming the keyword given, not the CLI's flag (it said "--rtol").
    with pytest.raises(kneedyn.InputError, match=r"\(\): rtol = -1; must lie in \(0, 0.5\]"):
        kneedyn.run(scene, "dae", rtol=-1)
    with pytest.raises(kneedyn.InputError, match=r"\(\): max_steps = 0; must lie in") as e:
        kneedyn.run(scene, "dae", max_steps=0)
    assert "--" not in str(e.value)
    with pytest.raises(kneedyn.InputError, match=r"output_interval") as e:
        kneedyn.run(scene, "dae", output_interval=-1)
    assert "--output-interval" not in str(e.value)
    with pytest.raises(kneedyn.InputError, match=r"max_steps = 0") as e:
        kneedyn.sensitivity(scene, ["pulse.amplitude"], ["liftoff_time"], max_steps=0)
    # Only flags are renamed: a quoted value the caller gave stays as given.
    with pytest.raises(kneedyn.InputError, match=r"integrator = '--rtol'"):
        kneedyn.run(scene, "mde", integrator="--rtol")
    with pytest.raises(kneedyn.InputError, match="unknown formulation 'nope'; registered: dae"):
        kneedyn.run(scene, "nope")
    with pytest.raises(kneedyn.InputError, match="integrator = 'rk9' is not available"):
        kneedyn.run(scene, "mde", integrator="rk9")
    with pytest.raises(kneedyn.InputError, match="linear_solver = 'lu'"):
        kneedyn.run(scene, "dae", linear_solver="lu")
    # generalized-alpha's scheme: its rules as the CLI's (only generalized-alpha takes it; the
    # explicit parameters in Chung and Hulbert's stable region).
    with pytest.raises(kneedyn.InputError, match="apply only to generalized-alpha, generalized-alpha-reduced, not to dae"):
        kneedyn.run(scene, "dae", rho_inf=0.9)
    with pytest.raises(kneedyn.InputError, match="rho_inf"):
        kneedyn.run(scene, "generalized-alpha", step=2e-4, rho_inf=1.5)
    with pytest.raises(kneedyn.InputError, match=r"run\(\): gamma = 'x'"):
        kneedyn.run(scene, "generalized-alpha", gamma="x")


def test_solver_failure_is_a_partial_result():
    # Euler with a step outside its stability range diverges (ede: the medial contact is
    # violated by ~4 mm at t = 0.08 s; the step is the longest a fixed step may be
    # on this scene: its output interval, 5 ms); the CLI writes it as status partial with
    # the reason, so does run(). (mde's Euler at this step chatters through re-contacts, and
    # whether it ends failed or completed follows round-off in its restarts.)
    scene = kneedyn.load_scene(CHAPTER)
    r = kneedyn.run(scene, "ede", integrator="euler", step=0.005)
    assert r.status == "partial" and not r.completed
    assert r.failure and r.failure == r.summary["failure"]
    assert len(r.trajectory) >= 1


def test_formulations_is_the_registry():
    regs = kneedyn.formulations()
    p = subprocess.run([CLI, "formulations"], capture_output=True, text=True, check=True)
    listed = [line.split()[0] for line in p.stdout.splitlines() if line.strip()]
    assert [f["name"] for f in regs] == listed
    mde = next(f for f in regs if f["name"] == "mde")
    assert "dopri5" in mde["integrators"] and mde["fixed_step_integrators"] == ["euler", "rk4"]
    assert next(f for f in regs if f["name"] == "newmark")["fixed_step"]


def test_thread_pool_equals_serial():
    scene = kneedyn.load_scene(CHAPTER)
    acl_free = scene.copy()
    acl_free.remove_ligaments("ACL")
    jobs = [(s, f, o) for s in (scene, acl_free) for f, o in CASES]
    serial = [kneedyn.run(s, f, **o) for s, f, o in jobs]
    with concurrent.futures.ThreadPoolExecutor(max_workers=4) as pool:
        parallel = list(pool.map(lambda j: kneedyn.run(j[0], j[1], **j[2]), jobs))
    for a, b in zip(serial, parallel):
        assert a.trajectory.columns == b.trajectory.columns
        assert np.array_equal(a.trajectory.array, b.trajectory.array, equal_nan=True)
        sa, sb = dict(a.summary), dict(b.summary)
        sa.pop("wall_time_s"), sb.pop("wall_time_s")
        assert sa == sb


def test_trajectory_columns_are_views_with_units():
    r = kneedyn.run(kneedyn.load_scene(CHAPTER), "dae-reduced")
    t = r.trajectory
    col = t["flexion_deg"]
    assert col.flags.c_contiguous and not col.flags.writeable
    assert np.shares_memory(col, t.array)
    assert t.units["flexion_deg"] == "deg" and t.units["F_PCL_anterior_N"] == "N"
    assert t.units["vx_mm_s"] == "mm/s" and t.units["time_s"] == "s"
    with pytest.raises(KeyError, match="no column 'nope'"):
        t["nope"]


def test_example_remove_acl_runs():
    out = os.path.join(OUT, "remove_acl")
    p = subprocess.run([sys.executable, os.path.join("examples", "python", "remove_acl.py"), "--out", out],
                       capture_output=True, text=True)
    assert p.returncode == 0, p.stderr
    assert os.path.getsize(os.path.join(out, "remove_acl.png")) > 10000
    assert "lift-off" in p.stdout


@pytest.mark.skipif(not os.environ.get("KNEEDYN_BUILD_DIR"), reason="needs the build tree (run by ctest)")
def test_import_from_install_prefix():
    prefix = os.path.join(OUT, "prefix")
    subprocess.run([os.environ.get("KNEEDYN_CMAKE", "cmake"), "--install", os.environ["KNEEDYN_BUILD_DIR"],
                    "--prefix", prefix], check=True, capture_output=True)
    site = os.path.join(prefix, os.environ["KNEEDYN_PYTHON_INSTALL_DIR"])
    env = dict(os.environ, PYTHONPATH=site)
    # A sweep with out= writes sweep.h5 through the installed sweep I/O plugin (HDF5),
    # found from the installed module.
    spec = os.path.join(OUT, "install_sweep_spec.yaml")
    with open(spec, "w") as f:
        f.write(SWEEP_SPEC.format(scene=os.path.abspath(CHAPTER)))
    sweep_out = os.path.join(OUT, "install_sweep")
    p = subprocess.run([sys.executable, "-c", "import kneedyn, sys; print(kneedyn.__file__); "
                        "print(kneedyn.run(kneedyn.scene_path('chapter_impact'), 'dae-reduced').status); "
                        "kneedyn.sweep(sys.argv[1], threads=1, out=sys.argv[2])", spec, sweep_out],
                       capture_output=True, text=True, env=env, cwd=prefix)
    assert p.returncode == 0, p.stderr
    assert p.stdout.split() == [os.path.join(site, "kneedyn", "__init__.py"), "completed"]
    assert os.path.getsize(os.path.join(sweep_out, "sweep.h5")) > 0
    shutil.rmtree(prefix)  # a whole install (~37 MB): kept only when an assertion above failed


def test_report_runner_module_equals_subprocess(monkeypatch):
    # reports/run_families.py runs through the module when it can; its files must be the
    # subprocess path's.
    sys.path.insert(0, os.path.join(os.getcwd(), "reports"))
    import run_families
    scene = os.path.join(OUT, "family_scene.yaml")
    kneedyn.load_scene(CHAPTER).write(scene)
    args = ["--formulation", "dae", "--rtol", "1e-7", "--atol", "1e-9"]
    via_module = run_families.run_once(CLI, scene, os.path.join(OUT, "fam_module"), args)
    monkeypatch.setenv("KNEEDYN_REPORT_RUNNER", "subprocess")
    via_cli = run_families.run_once(CLI, scene, os.path.join(OUT, "fam_cli"), args)
    assert (via_module["runner"], via_cli["runner"]) == ("module", "subprocess")
    assert via_module["ok"] and via_cli["ok"]
    for name in ("trajectory.csv", "trajectory.sto"):
        with open(os.path.join(OUT, "fam_module", name)) as a, open(os.path.join(OUT, "fam_cli", name)) as b:
            assert a.read() == b.read(), name


def test_gil_is_released_during_a_run():
    # While a run integrates in another thread, this thread keeps executing Python. Were the
    # GIL held for the run, this loop would stall for a whole run: its longest pause would
    # be at least the run's own wall time. Released, the pauses are thread switches.
    import threading
    import time
    scene = kneedyn.load_scene(CHAPTER)
    walls = []
    started = threading.Event()

    def work():
        started.set()
        for _ in range(3):
            # A run of ~0.1-0.3 s (generalized-alpha at a small fixed step), so that the OS's
            # scheduling pauses on a loaded 2-core machine (12 ms seen) stay far below half a
            # run; dae at rtol 1e-11 now takes ~25 ms, too close to them.
            walls.append(kneedyn.run(scene, "generalized-alpha", step=3.125e-5).wall_time_s)

    t = threading.Thread(target=work)
    t.start()
    started.wait()
    longest, last = 0.0, time.perf_counter()
    while t.is_alive():
        now = time.perf_counter()
        longest, last = max(longest, now - last), now
    t.join()
    print("longest pause %.4f s, run wall times %s" % (longest, walls))
    assert longest < 0.5 * min(walls), (longest, walls)


SWEEP_SPEC = """\
# Four Latin-hypercube runs of the chapter scene (pulse amplitude, PCL-anterior stiffness).
scene: {scene}
parameters:
  - {{name: pulse.amplitude, uniform: [80, 120]}}
  - {{name: PCL anterior.k_linear, relative: 0.3}}
design: {{type: lhs, samples: 4, seed: 7}}
outcomes: [liftoff_time, liftoff_flexion, peak_ligament_force]
solver: {{formulation: mde, integrator: dopri5, rtol: 1.0e-7, atol: 1.0e-9}}
"""


def test_sweep_equals_cli_sweep_for_any_thread_count():
    """kneedyn.sweep runs the ensembles/ API in process: its sweep.csv is byte-identical to
    `kneedyn sweep`'s, whatever the thread count, and its arrays hold the CSV's rows."""
    spec = os.path.join(OUT, "sweep_spec.yaml")
    with open(spec, "w") as f:
        f.write(SWEEP_SPEC.format(scene=os.path.abspath(CHAPTER)))
    cli_out = os.path.join(OUT, "sweep_cli")
    p = subprocess.run([CLI, "sweep", spec, "--threads", "1", "--quiet", "--out", cli_out],
                       capture_output=True, text=True)
    assert p.returncode == 0, p.stderr
    one = kneedyn.sweep(spec, threads=1, out=os.path.join(OUT, "sweep_py1"))
    two = kneedyn.sweep(spec, threads=2, out=os.path.join(OUT, "sweep_py2"))
    with open(os.path.join(cli_out, "sweep.csv"), "rb") as f:
        cli_csv = f.read()
    for d in ("sweep_py1", "sweep_py2"):
        with open(os.path.join(OUT, d, "sweep.csv"), "rb") as f:
            assert f.read() == cli_csv, d
    assert len(one) == 4 and one.total_runs == 4 and list(one.index) == [0, 1, 2, 3]
    assert one.completed.all()
    for name in one.outcomes:
        assert np.array_equal(one.outcomes[name], two.outcomes[name], equal_nan=True), name
    # The arrays are the CSV's rows (the CSV prints round-trip digits or fewer: compare as
    # the CSV's own text parsed back).
    rows = list(csv.DictReader(io.StringIO(cli_csv.decode())))
    lift = np.array([float(r["liftoff_flexion_deg"]) for r in rows])
    assert np.allclose(one.outcomes["liftoff_flexion_deg"], lift, rtol=1e-9, atol=0)
    # The amplitudes stay inside the spec's range, one per LHS stratum.
    amp = np.sort(one.parameters["pulse.amplitude"] if "pulse.amplitude" in one.parameters
                  else next(v for k, v in one.parameters.items() if "amplitude" in k))
    assert all(80 + 10 * i <= a <= 80 + 10 * (i + 1) for i, a in enumerate(amp))


def test_sweep_bad_threads_is_an_input_error():
    with pytest.raises(kneedyn.InputError, match="threads = -1"):
        kneedyn.sweep(os.path.join(OUT, "does_not_matter.yaml"), threads=-1)


def test_sensitivity_matches_the_cli_and_names_the_nearest_name():
    """kneedyn.sensitivity runs sensitivity/ in process: the same derivatives as
    `kneedyn sensitivity`'s CSV (same code path: equal to the CSV's 12 digits)."""
    cli_out = os.path.join(OUT, "sensitivity_cli")
    p = subprocess.run([CLI, "sensitivity", CHAPTER, "--parameters", "pulse.amplitude,mass",
                        "--outcomes", "liftoff_time_s", "--out", cli_out], capture_output=True, text=True)
    assert p.returncode == 0, p.stderr
    r = kneedyn.sensitivity(CHAPTER, ["pulse.amplitude", "mass"], ["liftoff_time_s"])
    with open(os.path.join(cli_out, "sensitivity.csv")) as f:
        rows = list(csv.DictReader(f))
    assert [row["parameter"] for row in rows] == r["parameters"]
    for j, row in enumerate(rows):
        assert math.isclose(float(row["derivative"]), r["derivatives"][0][j], rel_tol=1e-11)
    assert r["end_reason"] == "flexion_90"
    with pytest.raises(kneedyn.InputError, match="nearest valid name: 'mass'"):
        kneedyn.sensitivity(CHAPTER, ["mas"], ["liftoff_time_s"])


def test_sensitivity_formulation_dae_matches_the_cli():
    """formulation="dae" is `kneedyn sensitivity --formulation dae` (IDAS), to the CSV's
    12 digits; an unknown formulation is an InputError naming it."""
    cli_out = os.path.join(OUT, "sensitivity_cli_dae")
    p = subprocess.run([CLI, "sensitivity", CHAPTER, "--formulation", "dae", "--parameters", "pulse.amplitude",
                        "--outcomes", "liftoff_time_s", "--out", cli_out], capture_output=True, text=True)
    assert p.returncode == 0, p.stderr
    r = kneedyn.sensitivity(CHAPTER, ["pulse.amplitude"], ["liftoff_time_s"], formulation="dae")
    with open(os.path.join(cli_out, "sensitivity.csv")) as f:
        rows = list(csv.DictReader(f))
    assert math.isclose(float(rows[0]["derivative"]), r["derivatives"][0][0], rel_tol=1e-11)
    with pytest.raises(kneedyn.InputError, match="\\(\\): formulation = 'newmark'"):
        kneedyn.sensitivity(CHAPTER, ["mass"], ["liftoff_time_s"], formulation="newmark")


def test_sensitivity_takes_the_clis_max_steps_and_output_interval():
    """max_steps and output_interval are --max-steps and --output-interval (before: no keyword):
    a peak read from 1 ms rows equals the CLI's, and differs from the scene's 5 ms rows'."""
    cli_out = os.path.join(OUT, "sensitivity_cli_rows")
    p = subprocess.run([CLI, "sensitivity", CHAPTER, "--parameters", "mass", "--outcomes", "peak_F_PCL_anterior_N",
                        "--output-interval", "0.001", "--max-steps", "50000", "--out", cli_out],
                       capture_output=True, text=True)
    assert p.returncode == 0, p.stderr
    r = kneedyn.sensitivity(CHAPTER, ["mass"], ["peak_F_PCL_anterior_N"], output_interval=0.001, max_steps=50000)
    coarse = kneedyn.sensitivity(CHAPTER, ["mass"], ["peak_F_PCL_anterior_N"])
    with open(os.path.join(cli_out, "sensitivity.csv")) as f:
        rows = list(csv.DictReader(f))
    assert math.isclose(float(rows[0]["derivative"]), r["derivatives"][0][0], rel_tol=1e-11)
    assert r["values"][0] != coarse["values"][0]
    with pytest.raises(kneedyn.InputError, match="max_steps = 0"):
        kneedyn.sensitivity(CHAPTER, ["mass"], ["peak_F_PCL_anterior_N"], max_steps=0)
    with pytest.raises(kneedyn.SolverError, match="max-steps = 10"):  # the budget reaches the run
        kneedyn.sensitivity(CHAPTER, ["mass"], ["peak_F_PCL_anterior_N"], max_steps=10)


PATELLA = os.path.join("reference-data", "scenes", "patellofemoral_impact.yaml")


def test_patella_parameters_set_in_python_equal_the_same_edits_in_a_file():
    # Quadriceps magnitude, tendon length and facet geometry set from Python: the loader
    # builds the model (and the patella's start equilibrium) from the edited document, and
    # the run equals the CLI's on the same document written to a file.
    scene = kneedyn.load_scene(PATELLA)
    assert scene.patella["quadriceps"]["magnitude_N"] == 50.0
    assert scene.patella["tendon_length_mm"] == pytest.approx(42.0)
    start = scene.patella["start"]["patella_proximal"]
    scene.set_quadriceps(magnitude_N=80.0)
    scene.set_patella(tendon_length_mm=43.0, trochlea_lateral={"radius_mm": 29.0},
                      facet_medial={"offset_mm": 0.5})
    p = scene.patella
    assert p["quadriceps"]["magnitude_N"] == 80.0 and p["quadriceps"]["shape"] == "constant"
    assert p["tendon_length_mm"] == pytest.approx(43.0)
    assert p["trochlea_lateral"]["radius_mm"] == pytest.approx(29.0)
    assert p["trochlea_lateral"]["centre_mm"] == pytest.approx([22.0, -8.0, 14.0])  # merged, kept
    assert p["facet_medial"]["offset_mm"] == pytest.approx(0.5)
    assert p["start"]["patella_proximal"] != start  # the equilibrium moved with the tendon
    path = os.path.join(OUT, "edited_patella_scene.yaml")
    os.makedirs(OUT, exist_ok=True)
    scene.write(path)
    header, rows, summary = run_cli(path, "ede", dict(rtol=1e-7, atol=1e-9), "cli_patella_edited")
    result = kneedyn.run(scene, "ede", rtol=1e-7, atol=1e-9)
    assert_same_as_cli(result, header, rows, summary, ignore_path=True)


def test_quadriceps_shape_constant_drops_the_ramps_fields():
    # The extension scene's ramp has baseline_N and duration_s, which the constant shape
    # refuses: set_quadriceps(shape="constant") raised on them unless they were set to None.
    scene = kneedyn.load_scene(os.path.join("reference-data", "scenes", "patellofemoral_extension.yaml"))
    assert "baseline_N" in scene.to_dict()["patella"]["quadriceps"]
    scene.set_quadriceps(shape="constant", magnitude_N=100.0)
    q = scene.patella["quadriceps"]
    assert q["shape"] == "constant" and q["magnitude_N"] == 100.0
    document = scene.to_dict()["patella"]["quadriceps"]
    assert "baseline_N" not in document and "duration_s" not in document
    with pytest.raises(kneedyn.InputError, match="baseline_N"):  # given explicitly: still refused
        scene.set_quadriceps(shape="constant", magnitude_N=100.0, baseline_N=20.0)


def test_patella_setters_refuse_a_scene_without_patella():
    scene = kneedyn.load_scene(CHAPTER)
    assert scene.patella is None
    with pytest.raises(kneedyn.InputError, match="no patella"):
        scene.set_quadriceps(magnitude_N=80.0)
    patella = kneedyn.load_scene(PATELLA)
    with pytest.raises(kneedyn.InputError, match="magnitude_N"):
        patella.set_quadriceps(magnitude_N=-5.0)
    assert patella.patella["quadriceps"]["magnitude_N"] == 50.0  # unchanged


def test_patella_property_holds_every_field_of_the_section():
    # apex_P_mm, base_P_mm, tuberosity_T_mm and facet_liftoff were missing from scene.patella
    # (set_patella could set them, nothing read them back). The values: the scene document's.
    scene = kneedyn.load_scene(PATELLA)
    doc = scene.to_dict()["patella"]
    p = scene.patella
    for key in ("apex_P_mm", "base_P_mm", "tuberosity_T_mm"):
        assert p[key] == pytest.approx(doc[key], rel=1e-15), key
    assert p["facet_liftoff"] is False  # the scene has no key: the default, both facets press
    scene.set_patella(facet_liftoff=True, apex_P_mm=[0.0, 8.5, -22.0])
    assert scene.patella["facet_liftoff"] is True
    assert scene.patella["apex_P_mm"] == pytest.approx([0.0, 8.5, -22.0], rel=1e-15)


def test_scene_path_refuses_an_empty_name():
    # scene_path("") gave '<data>/scenes/.yaml', and Problem("") said it could not open that.
    for name in ("", ".yaml"):
        with pytest.raises(kneedyn.InputError, match=r"scene_path\(\): name = '(\.yaml)?': must name a scene"):
            kneedyn.scene_path(name)
    with pytest.raises(ValueError, match="must name a scene"):
        kneedyn.Problem("", form="ede")


# --- bad input from Python: refused with InputError, never a crash, a hang or a silent change ---

def run_isolated(code):
    """Runs `code` in a fresh interpreter (after `import kneedyn` and s = the chapter scene), so
    that a crash it would cause fails the test instead of killing pytest; returns stdout."""
    prelude = "import kneedyn, numpy as np\nCH = %r\ns = kneedyn.load_scene(CH)\n" % CHAPTER
    p = subprocess.run([sys.executable, "-c", prelude + code], capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, "exit %d (a negative code is a signal: crashed)\n%s" % (p.returncode, p.stderr)
    return p.stdout


def test_a_document_that_contains_itself_is_refused_not_a_crash():
    # Before: the YAML writer recursed until the stack overflowed (SIGSEGV).
    out = run_isolated("""
def refused(f, *a, **k):
    try:
        f(*a, **k)
        print("ACCEPTED")
    except kneedyn.InputError as e:
        print(e)
d = {}; d["a"] = d
refused(kneedyn.Scene.from_dict, d)
g = {}; g["x"] = g
refused(s.update, {"gravity": g})
l = []; l.append(l)
refused(s.set_pulse, direction_T=l)
""").splitlines()
    assert len(out) == 3 and "ACCEPTED" not in out, out
    assert out[0].startswith("Scene.from_dict(): field 'a.a.a.") and "nesting depth 65 exceeds the limit of 64" in out[0]
    assert out[1].startswith("Scene.update(): field 'gravity.x.x.") and "limit of 64" in out[1]
    assert out[2].startswith("Scene.update(): field 'pulse.direction_T[0][0]") and "limit of 64" in out[2]


def test_a_scene_without_its_compiled_form_is_refused_not_a_crash():
    # Before: Scene(doc, None, ...) was accepted, and run()/sensitivity() dereferenced the
    # null scene (SIGSEGV).
    out = run_isolated("""
for call in (lambda: kneedyn.Scene(s.to_dict(), None, "", ""),
             lambda: kneedyn.run(s, "dae-reduced"),
             lambda: kneedyn.sensitivity(s, ["mass"], ["liftoff_time_s"])):
    try:
        call()
        print("ACCEPTED")
    except kneedyn.InputError as e:
        print(e)
    s._compiled = None  # as Scene(doc, None, ...) was before: no compiled scene
""").splitlines()
    assert out[0].startswith("Scene(): compiled = None (NoneType): must be a kneedyn.CompiledScene"), out
    assert out[1].startswith("kneedyn.run(): scene = None: must be a compiled scene"), out
    assert out[2].startswith("kneedyn.sensitivity(): scene = None: must be a compiled scene"), out


def test_a_document_larger_than_a_scene_file_is_refused_naming_the_limit():
    # Before: 200,000 keys reached the loader, whose duplicate-key check compared all pairs
    # (90 s), then refused the unknown key. A document is held to a scene file's size.
    s = kneedyn.load_scene(CHAPTER)
    before = s.to_dict()
    with pytest.raises(kneedyn.InputError, match=r"Scene.update\(\): the document's YAML text passes 1048576 bytes "
                                                 r"at field 'extra.k\d+'( \(\d+ bytes of text there\))?; "
                                                 r"the limit is 1048576 bytes"):
        s.update({"extra": {"k%d" % i: i for i in range(200000)}})
    assert s.to_dict() == before
    # A list shared at every level (2**40 items written) is stopped by the same limit.
    shared = [1.0]
    for _ in range(40):
        shared = [shared, shared]
    with pytest.raises(kneedyn.InputError, match="the limit is 1048576 bytes"):
        s.update({"extra": shared})


def test_the_size_refusal_names_the_field_that_passed_the_limit():
    # Before: a 2 MiB description was blamed on the next key written (parameter_set), or on
    # no field when it came last: the emitter's buffer lags behind the fields.
    d = kneedyn.load_scene(CHAPTER).to_dict()
    big = "x" * (2 << 20)
    last = {k: v for k, v in d.items() if k != "description"}
    last["description"] = big
    for doc in ({**d, "description": big}, last):
        with pytest.raises(kneedyn.InputError, match=r"at field 'description' \(2097152 bytes of text there\)"):
            kneedyn.Scene.from_dict(doc, base_dir=os.path.dirname(CHAPTER))


def test_values_deepcopy_cannot_copy_are_refused_naming_the_field():
    # Before: copy.deepcopy's TypeError ("cannot pickle 'generator' object"), naming no field.
    s = kneedyn.load_scene(CHAPTER)
    with pytest.raises(kneedyn.InputError, match=r"Scene.update\(\): field 'ligaments' = <generator"):
        s.copy().update({"ligaments": (n for n in ["LCL"])})
    with pytest.raises(kneedyn.InputError, match=r"field 'pulse.direction_T' = <generator"):
        s.copy().set_pulse(direction_T=(x for x in [0, -1, 0]))
    d = s.to_dict()
    d["description"] = (c for c in "ab")
    with pytest.raises(kneedyn.InputError, match=r"Scene.from_dict\(\): field 'description' = <generator"):
        kneedyn.Scene.from_dict(d, base_dir=os.path.dirname(CHAPTER))


def test_write_makes_the_parameter_set_absolute_under_a_relative_data_dir(monkeypatch, tmp_path):
    # Before: with KNEEDYN_DATA_DIR relative, the file said parameter_set: reference-data/...,
    # which the CLI could not find from any other directory.
    d = kneedyn.load_scene(CHAPTER).to_dict()
    data = os.path.abspath(kneedyn.data_dir())
    monkeypatch.chdir(os.path.dirname(data))
    monkeypatch.setenv("KNEEDYN_DATA_DIR", os.path.basename(data))
    d["parameter_set"] = "chapter_knee.yaml"  # not beside base_dir: found under data_dir()
    path = tmp_path / "relative_data_dir.yaml"
    kneedyn.Scene.from_dict(d, base_dir=str(tmp_path)).write(str(path))
    line = next(l for l in path.read_text().splitlines() if l.startswith("parameter_set:"))
    written = line.split(":", 1)[1].strip()
    assert os.path.isabs(written) and os.path.isfile(written), line


def test_numpy_values_keep_their_type():
    s = kneedyn.load_scene(CHAPTER)
    # Before: np.array(1.9) had __index__ and was written as the integer 1.
    s.set_ligament_stiffness_scale(np.array(1.9))
    assert "ligament_stiffness_scale: 1.9\n" in s.to_yaml()
    s.set_pulse(amplitude_N=np.float32(80.5), duration_s=np.float64(0.12))
    assert s.pulse["amplitude_N"] == 80.5 and s.pulse["duration_s"] == 0.12
    # A 1-D array is a list (a direction), not a number: a 1-element one is refused where a
    # number is wanted (before: np.array([80.7]) became 80).
    s.set_pulse(direction_T=np.array([0., -1., 0.]))
    assert "- -1.0" in s.to_yaml()
    with pytest.raises(kneedyn.InputError, match=r"field 'pulse.amplitude_N': must be a number"):
        s.set_pulse(amplitude_N=np.array([80.7]))
    with pytest.raises(kneedyn.InputError, match=r"field 'pulse.direction_T' = .*shape \(3, 1\).*1-D array"):
        s.set_pulse(direction_T=np.zeros((3, 1)))
    # np.bool_ is a boolean (before: a number, refused by the loader or read as 0/1).
    s.update({"gravity": {"enabled": np.bool_(False)}})
    assert "enabled: false" in s.to_yaml()
    # Complex numbers are refused, not cut to their real part.
    for value in (1 + 2j, np.complex128(80 + 1j), np.array(80 + 1j)):
        with pytest.raises(kneedyn.InputError, match=r"field 'pulse.amplitude_N' = .*real number"):
            s.set_pulse(amplitude_N=value)


def test_text_fields_of_a_loaded_scene_survive_an_edit():
    # Before: any text strtod/strtoll read became a number, written back with 17 digits.
    scene_text = open(CHAPTER).read()
    ps = os.path.abspath(os.path.join(os.path.dirname(CHAPTER), kneedyn.load_scene(CHAPTER).to_dict()["parameter_set"]))
    # A decimal is a number (the loader reads it as one) whatever its spelling; text the
    # loader does not read as a number stays a string.
    for desc, value in (("1.10", 1.1), ("0x1F", "0x1F"), ("nan", "nan"), ("+5", 5), ("1e-6", 1e-6), ("007", 7),
                        ("123456789012345678901234567890", 123456789012345678901234567890), ("0.1", 0.1),
                        ("80.0", 80.0), ("7", 7), ("True", "True"), ("true", True)):
        doc = kneedyn.load_scene(CHAPTER).to_dict()
        doc["parameter_set"] = ps
        doc["description"] = "PLACEHOLDER"
        path = os.path.join(OUT, "text_fields.yaml")
        os.makedirs(OUT, exist_ok=True)
        with open(path, "w") as f:
            f.write(kneedyn._kneedyn.to_yaml(doc).replace("PLACEHOLDER", desc))
        s = kneedyn.load_scene(path)
        got = s.to_dict()["description"]
        assert got == value and isinstance(got, type(value)), (desc, got)
        if not isinstance(value, bool):
            s.update({})
            assert s.compiled.description == desc, (desc, s.compiled.description)
            copied = copy.deepcopy(s.to_dict())  # the spelling survives copies (Scene keeps deep copies)
            assert "description: %s\n" % desc in kneedyn._kneedyn.to_yaml(copied), desc
            if isinstance(value, float):
                assert got * 2 == value * 2 and type(got * 2) is float  # arithmetic gives plain numbers
    # Shipped scenes' 1e-3-like values are numbers, written back as spelled.
    for name in ("hard/guess_offset_1e-3mm", "anatomical_surfaces"):
        s = kneedyn.load_scene(kneedyn.scene_path(name))
        spelled = [(k, v) for k, v in _leaves(s.to_dict()) if isinstance(v, (kneedyn._FileFloat, kneedyn._FileInt))]
        assert spelled, name
        text = s.set_pulse(amplitude_N=90.0).to_yaml()  # an edit elsewhere
        for key, v in spelled:
            assert "%s: %s\n" % (key, v.text) in text, (name, key, v.text)
    assert scene_text  # the shipped scene itself is untouched
    # Floats are written as the shortest text that reads back exactly.
    s = kneedyn.load_scene(CHAPTER).set_pulse(duration_s=0.1 + 0.02)
    assert "duration_s: 0.12000000000000001" in s.to_yaml()
    assert "interval_s: 0.005\n" in s.to_yaml()


@pytest.mark.parametrize("scene_file,change,field,value,rule", [
    (CHAPTER, {"pulse": {"amplitude_N": "42"}}, "pulse.amplitude_N", "42", "must be a number, not a quoted string"),
    (CHAPTER, {"end": {"time_s": "1e-1"}}, "end.time_s", "1e-1", "must be a number, not a quoted string"),
    (CHAPTER, {"gravity": {"enabled": "true"}}, "gravity.enabled", "true", "must be true or false, not a quoted string"),
    (os.path.join("reference-data", "scenes", "patellofemoral_impact.yaml"), {"patella": {"facet_liftoff": "yes"}},
     "patella.facet_liftoff", "yes", "must be true or false, not a quoted string"),
])
def test_a_str_where_a_number_or_bool_belongs_is_refused(scene_file, change, field, value, rule):
    # YAML: a quoted scalar is a string. A Python str is written quoted when plain text would
    # read as a number or boolean, and the loader refuses it there; before, '42' became 42.
    scene = kneedyn.load_scene(scene_file)
    with pytest.raises(ValueError) as e:
        scene.update(change)
    assert "field '%s' = '%s': %s" % (field, value, rule) in str(e.value), str(e.value)
    # A str in a text field stays text, even one that reads as a number plain.
    assert scene.update({"description": "42"}).compiled.description == "42"


def test_plain_booleans_and_numbers_of_a_file_survive_an_edit():
    # `enabled: yes` (unquoted) is a boolean to the loader but text to FromYaml: written back
    # unquoted, so an edit elsewhere keeps the scene loadable.
    doc = chapter_doc()
    doc["parameter_set"] = os.path.abspath(os.path.join(os.path.dirname(CHAPTER), doc["parameter_set"]))
    path = os.path.join(OUT, "plain_yes.yaml")
    os.makedirs(OUT, exist_ok=True)
    with open(path, "w") as f:
        f.write(kneedyn._kneedyn.to_yaml(doc).replace("enabled: true", "enabled: yes"))
    s = kneedyn.load_scene(path)
    assert s.to_dict()["gravity"]["enabled"] == "yes"
    assert "enabled: yes\n" in s.set_pulse(amplitude_N=90.0).to_yaml()


def test_pulse_shape_none_removes_the_keys_it_does_not_use():
    # shape="none" drops the chapter's amplitude_N and duration_s (a direction_T too), which
    # that shape does not use; one given with it would be ignored, so the loader refuses it
    # by name, as in a scene file. The compiled pulse (the loader's) has no force.
    for start in (kneedyn.load_scene(CHAPTER), kneedyn.load_scene(CHAPTER).set_pulse(direction_T=[0.0, 0.0, 1.0])):
        scene = start.set_pulse(shape="none")
        assert scene.to_dict()["pulse"] == {"shape": "none"}
        assert scene.pulse["amplitude_N"] == 0.0
    with pytest.raises(kneedyn.InputError, match=r"pulse\.amplitude_N.*not used by pulse shape none"):
        kneedyn.load_scene(CHAPTER).set_pulse(shape="none", amplitude_N=5.0)
    # Back to a shape with a force: its fields are needed again, and named when missing.
    with pytest.raises(kneedyn.InputError, match=r"field 'pulse': missing required field 'amplitude_N'"):
        kneedyn.load_scene(CHAPTER).set_pulse(shape="none").set_pulse(shape="half_sine")
    # A run of it applies no pulse force.
    free = kneedyn.run(kneedyn.load_scene(CHAPTER).set_pulse(shape="none").set_end(time_s=0.05), "ede")
    assert not np.any(free.trajectory["pulse_N"])


def test_pulse_peak_factor_equals_the_clis_summary():
    # Independent path: the CLI's summary.json (formulations/run_output.cpp) for the same
    # scene; a half sine's largest force is its amplitude (peak factor 1).
    factors = {}
    for shape in ("reconstructed", "half_sine", "damped_sine", "reconstructed_peak"):
        scene = kneedyn.load_scene(CHAPTER).set_pulse(shape=shape).set_end(time_s=0.01)
        path = os.path.join(OUT, "peak_factor_%s.yaml" % shape)
        os.makedirs(OUT, exist_ok=True)
        scene.write(path)
        out = os.path.join(OUT, "peak_factor_%s" % shape)
        p = subprocess.run([CLI, "run", path, "--quiet", "--out", out], capture_output=True, text=True)
        assert p.returncode == 0, p.stderr
        with open(os.path.join(out, "summary.json")) as f:
            cli = json.load(f)["scene"]["pulse"]
        assert scene.pulse["peak_factor"] == cli["peak_factor"], (shape, scene.pulse, cli)
        factors[shape] = scene.pulse["peak_factor"]
    assert factors["half_sine"] == pytest.approx(1.0, abs=1e-12)
    assert len(set(factors.values())) >= 3, factors  # the shapes differ


def _leaves(node, key=None):
    """(key, value) of every scalar of a document (list items under their list's key)."""
    if isinstance(node, dict):
        for k, v in node.items():
            yield from _leaves(v, k)
    elif isinstance(node, list):
        for v in node:
            yield from _leaves(v, key)
    else:
        yield key, node


def test_paths_with_nul_are_refused():
    # Before: the path was cut at the NUL and another file read (or a directory made).
    spec = os.path.join(OUT, "nul_spec.yaml")
    for call, match in (
            (lambda: kneedyn.load_scene(CHAPTER + "\0junk"), r"load_scene\(\): path = '.*\\x00junk': a path cannot hold a NUL"),
            (lambda: kneedyn.run(CHAPTER + "\0junk", "dae-reduced"), r"run\(\): scene = .*NUL"),
            (lambda: kneedyn.sweep(spec + "\0junk"), r"sweep\(\): spec_path = .*NUL"),
            (lambda: kneedyn.sweep(spec, out=os.path.join(OUT, "swout\0junk")), r"sweep\(\): out = .*NUL"),
            (lambda: kneedyn.load_scene(CHAPTER).update({"parameter_set": "../chapter_knee.yaml\0junk"}),
             r"field 'parameter_set' = '../chapter_knee.yaml\?junk': must be a file path without NUL")):
        with pytest.raises(kneedyn.InputError, match=match):
            call()
    assert not os.path.exists(os.path.join(OUT, "swout"))


@pytest.mark.parametrize("call,match", [
    (lambda s: kneedyn.run(s, "dae-reduced", max_steps=True), r"run\(\): max_steps = True: must be a whole number"),
    (lambda s: kneedyn.run(s, "dae-reduced", output_interval=True), r"run\(\): output_interval = True \(bool\): must be a real number"),
    (lambda s: kneedyn.run(s, "dae-reduced", rtol="1e-6"), r"run\(\): rtol = '1e-6' \(str\): must be a real number"),
    (lambda s: kneedyn.run(s, "dae-reduced", rtol=np.array([1e-6])), r"run\(\): rtol = array\(\[1.e-06\]\) \(ndarray\)"),
    (lambda s: kneedyn.run(s, rtol=None), r"run\(\): rtol = None \(NoneType\): must be a real number"),
    (lambda s: kneedyn.run(s, rtol=1 + 0j), r"run\(\): rtol = \(1\+0j\) \(complex\): must be a real number"),
    (lambda s: kneedyn.run(s, rtol=10**400), r"run\(\): rtol = 1000.*: must be a real number within the range of a double"),
    (lambda s: kneedyn.sensitivity(s, ["mass"], ["liftoff_time_s"], rtol="1e-8"), r"sensitivity\(\): rtol = '1e-8' \(str\)"),
    (lambda s: kneedyn.sweep("x.yaml", threads=True), r"sweep\(\): threads = True: must be a whole number"),
    (lambda s: kneedyn.sweep("x.yaml", threads=2**31), r"sweep\(\): threads = 2147483648: must be in \[0, 4096\]"),
    (lambda s: kneedyn.run(s, None), r"run\(\): formulation = None \(NoneType\): must be a str"),
    (lambda s: kneedyn.run(s, integrator=None), r"run\(\): integrator = None"),
    (lambda s: kneedyn.run(s, jacobian=None), r"run\(\): jacobian = None"),
    (lambda s: kneedyn.run(s, linear_solver=None), r"run\(\): linear_solver = None"),
    (lambda s: kneedyn.run(s, stabilization=1), r"run\(\): stabilization = 1 \(int\): must be a str"),
    (lambda s: kneedyn.run(s, "nope\0x"), r"run\(\): formulation = 'nope\\x00x': must not hold a NUL character"),
    (lambda s: kneedyn.Scene.from_dict(s.to_dict(), label=None), r"Scene.from_dict\(\): label = None"),
    (lambda s: kneedyn.load_scene(b"/tmp/\xff.yaml"), r"load_scene\(\): path = b'/tmp/\\xff.yaml': must be a path that decodes as UTF-8"),
    (lambda s: kneedyn.run(CHAPTER, out=b"/tmp/\xff"), r"run\(\): out = b'/tmp/\\xff'"),
    (lambda s: kneedyn.sweep(b"/tmp/\xfe"), r"sweep\(\): spec_path = b'/tmp/\\xfe'"),
    (lambda s: kneedyn.sensitivity(s, ["mass"], ["liftoff_time_s"], out=b"/tmp/\xfe"), r"sensitivity\(\): out = b'/tmp/\\xfe'"),
    (lambda s: s.update({"description": "a\udcffb"}), r"Scene.update\(\): field 'description' = 'a\\udcffb': .*lone surrogate"),
    (lambda s: s.update(None), r"Scene.update\(\): changes = None \(NoneType\): must be a dict"),
    (lambda s: s.update([("name", "x")]), r"Scene.update\(\): changes = \[\('name', 'x'\)\] \(list\): must be a dict"),
    (lambda s: kneedyn.scene_path(None), r"scene_path\(\): name = None \(NoneType\): must be a scene's name"),
    (lambda s: kneedyn.scene_path(b"x"), r"scene_path\(\): name = b'x' \(bytes\)"),
    (lambda s: setattr(s, "ligaments", "LCL"), r"Scene.ligaments\(\): ligaments = 'LCL': must be a list of names"),
    (lambda s: setattr(s, "ligaments", None), r"Scene.ligaments\(\): ligaments = None \(NoneType\): must be a list"),
    (lambda s: kneedyn.sensitivity(s, None, ["liftoff_time_s"]), r"sensitivity\(\): parameters = None \(NoneType\)"),
    (lambda s: kneedyn.Result({"events": []}, None).event(None), r"Result.event\(\): prefix = None \(NoneType\)"),
    (lambda s: s.remove_ligaments(""), r"remove_ligaments\(\): pattern '' \(str\): must be a non-empty str"),
    (lambda s: s.remove_ligaments(5), r"remove_ligaments\(\): pattern 5 \(int\)"),
    (lambda s: s.remove_ligaments(None), r"remove_ligaments\(\): pattern None \(NoneType\)"),
])
def test_bad_arguments_name_the_argument(call, match):
    # Before: silently accepted (True as 1, "" matching every ligament), pybind11's
    # "incompatible function arguments", or a TypeError naming no argument.
    s = kneedyn.load_scene(CHAPTER)
    before = (s.to_dict(), s.ligaments)
    with pytest.raises(kneedyn.InputError, match=match):
        call(s)
    assert (s.to_dict(), s.ligaments) == before


def test_remove_ligaments_takes_lists_of_patterns():
    s = kneedyn.load_scene(CHAPTER)
    assert s.remove_ligaments(["ACL"], ("LCL",)) == ["ACL anterior", "ACL posterior", "LCL"]
    assert len(s.ligaments) == 9 and not any(n.startswith(("ACL", "LCL")) for n in s.ligaments)


def test_write_refuses_a_bad_path_and_writes_nothing():
    # Before: write(True) opened file descriptor 1, wrote the scene to stdout and closed it.
    out = run_isolated("""
import sys
try:
    s.write(True)
except kneedyn.InputError as e:
    print(e)
print("stdout open")
""").splitlines()
    assert out == ["Scene.write(): path = True (bool): must be a path (str or os.PathLike)", "stdout open"], out
    s = kneedyn.load_scene(CHAPTER)
    os.makedirs(OUT, exist_ok=True)
    with pytest.raises(kneedyn.InputError, match=r"Scene.write\(\): path = '.*': cannot be written \(Is a directory\)"):
        s.write(OUT)
    missing = os.path.join(OUT, "no_such_dir", "x.yaml")
    with pytest.raises(kneedyn.InputError, match=r"cannot be written \(No such file or directory\)"):
        s.write(missing)
    assert not os.path.exists(os.path.dirname(missing))


def test_sweep_refuses_an_unusable_out_before_running():
    # Before: kneedyn.Error (a RuntimeError) only after every run of the design.
    spec = os.path.join(OUT, "sweep_spec_out.yaml")
    os.makedirs(OUT, exist_ok=True)
    with open(spec, "w") as f:
        f.write(SWEEP_SPEC.format(scene=os.path.abspath(CHAPTER)))
    a_file = os.path.join(OUT, "sweep_out_is_a_file")
    open(a_file, "w").close()
    with pytest.raises(kneedyn.InputError, match=r"sweep\(\): out = '.*sweep_out_is_a_file': exists and is not a directory"):
        kneedyn.sweep(spec, out=a_file)
    with pytest.raises(kneedyn.InputError, match=r"sweep\(\): out = '/proc/x': cannot"):
        kneedyn.sweep(spec, out="/proc/x")


def test_run_refuses_an_unusable_out_before_running():
    # Before: the whole run, then WriteRunOutputs' refusal. A step longer than the output
    # interval is refused by the run itself (Simulator), so which message comes shows which
    # check came first.
    scene = kneedyn.load_scene(CHAPTER)
    with pytest.raises(kneedyn.InputError, match="shorter than the fixed step"):
        kneedyn.run(scene, "newmark", step=0.05)
    os.makedirs(OUT, exist_ok=True)
    a_file = os.path.join(OUT, "run_out_is_a_file")
    open(a_file, "w").close()
    with pytest.raises(kneedyn.InputError, match=r"\(\): out = '.*run_out_is_a_file' exists and is not a directory"):
        kneedyn.run(scene, "newmark", step=0.05, out=a_file)
    assert os.path.isfile(a_file) and os.path.getsize(a_file) == 0


def test_copies_and_pickles_of_a_scene_run_as_the_scene():
    # copy.copy / copy.deepcopy raised pybind11's "cannot pickle CompiledScene". A pickled
    # scene is validated again from its document: its run must equal the original's, for a
    # scene read from a file and for one edited in Python (a second way to the same model).
    import pickle
    base = kneedyn.load_scene(CHAPTER)
    edited = base.copy()
    edited.set_ligament_parameters("LCL", k_linear_N_mm=80.0)
    edited.set_pulse(shape="half_sine", amplitude_N=80.0, duration_s=0.12)
    for scene in (base, edited):
        want = kneedyn.run(scene, "mde", rtol=1e-7, atol=1e-9)
        for other in (copy.copy(scene), copy.deepcopy(scene), pickle.loads(pickle.dumps(scene))):
            assert other is not scene and other.to_dict() == scene.to_dict()
            got = kneedyn.run(other, "mde", rtol=1e-7, atol=1e-9)
            assert np.array_equal(got.trajectory.array, want.trajectory.array, equal_nan=True)
            a, b = dict(got.summary), dict(want.summary)
            a.pop("wall_time_s"), b.pop("wall_time_s")
            assert a == b
    # A copy's edits leave the original as it was.
    deep = copy.deepcopy(base)
    deep.set_ligament_parameters("LCL", k_linear_N_mm=1.0)
    assert base.to_dict() == kneedyn.load_scene(CHAPTER).to_dict()


def test_a_field_path_with_a_nul_is_echoed_whole():
    # The loader's message stopped at the NUL of a ligament name used as a key.
    scene = kneedyn.load_scene(CHAPTER)
    with pytest.raises(kneedyn.InputError,
                       match=r"field 'ligament_parameters\.LCL\?x': not a ligament element selected"):
        scene.set_ligament_parameters("LCL\0x", k_linear_N_mm=1.0)


def test_the_data_beside_the_module_wins_over_data_beside_the_interpreter(tmp_path):
    """The module looks for share/kneedyn beside itself before beside the running program: an
    interpreter whose prefix holds another kneedyn's data (a .deb under /usr, a venv's python
    linked to /usr/bin/python3) must not make the module read that data."""
    interpreter = tmp_path / "bin" / "python3"
    interpreter.parent.mkdir()
    shutil.copy2(os.path.realpath(sys.executable), interpreter)  # /proc/self/exe is its real path
    (tmp_path / "share" / "kneedyn" / "scenes").mkdir(parents=True)  # the other install's data
    env = {k: v for k, v in os.environ.items() if k != "KNEEDYN_DATA_DIR"}
    env["PYTHONPATH"] = os.path.dirname(os.path.dirname(os.path.abspath(kneedyn.__file__)))
    code = "import kneedyn; print(kneedyn.data_dir())"
    found = {}
    for name, program in (("usual", sys.executable), ("copied", str(interpreter))):
        p = subprocess.run([program, "-c", code], env=env, capture_output=True, text=True, timeout=120,
                           cwd=str(tmp_path))
        assert p.returncode == 0, p.stderr
        found[name] = p.stdout.strip()
    assert not found["copied"].startswith(str(tmp_path)), found
    assert found["copied"] == found["usual"], found
