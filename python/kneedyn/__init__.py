"""kneedyn from Python: scenes, the formulation registry and runs::

    import kneedyn
    scene = kneedyn.load_scene(kneedyn.scene_path("chapter_impact"))
    scene.remove_ligaments("ACL")
    result = kneedyn.run(scene, "dae", rtol=1e-8, atol=1e-10)
    result.trajectory["flexion_deg"], result.events, result.statistics, result.summary

A Scene is a scene document (the dict form of a scene YAML file, see
reference-data/scenes/README.md) plus its validated form. Every change goes through the
C++ scene loader again, so the rules and messages are the CLI's; a change that breaks a
rule raises kneedyn.InputError (a ValueError) and leaves the scene as it was.

run() calls the same driver as `kneedyn run` and returns the same content: the
trajectory with the columns and units of trajectory.csv, and `summary`, the dict that
summary.json holds. The GIL is released during a run, so a ThreadPoolExecutor runs
several scenes at once. See docs/python.md.
"""
import copy as _copy
import inspect as _inspect
import json as _json
import numbers as _numbers
import os as _os
import re as _re

import numpy as _np

from . import _kneedyn
from ._kneedyn import Error, InputError, SolverError, CompiledScene, Problem

__all__ = ["Problem", "sensitivity", "sweep", "SweepResult", "Scene", "Result", "Trajectory", "Event", "load_scene", "run", "formulations",
           "data_dir", "scene_path", "build_manifest", "Error", "InputError", "SolverError"]


class _FileFloat(float):
    """A number read from a scene file in a spelling repr() would not give (`1e-3`, `1.10`):
    a float in every use, written back in the file's own spelling (YamlWriter in
    kneedyn_module.cpp), so that editing a scene changes no field it did not touch."""

    def __new__(cls, value, text):
        number = super().__new__(cls, value)
        number.text = text
        return number

    def __getnewargs__(self):  # copy.deepcopy and pickle rebuild it with its text
        return (float(self), self.text)


class _FileInt(int):
    """An integer read from a scene file in a spelling str() would not give (`+5`, `007`);
    as _FileFloat."""

    def __new__(cls, value, text):
        number = super().__new__(cls, value)
        number.text = text
        return number

    def __getnewargs__(self):
        return (int(self), self.text)


class _FilePlain(str):
    """An unquoted value from a scene file that stays text in Python but that the loader
    reads as a number or boolean (`yes`, `True`, `.inf`): written back unquoted
    (YamlWriter), as the file had it. A plain str of that text is written quoted, and
    a quoted scalar is a string to the loader, never a number or a boolean."""

    __slots__ = ()


def data_dir():
    """Directory of the reference data (parameter sets, scenes); KNEEDYN_DATA_DIR overrides."""
    return _kneedyn.data_dir()


def build_manifest():
    """The fairness manifest of this build (formulations/version.hpp): list of dicts with name,
    version, origin and compile_flags for kneedyn, SUNDIALS, Ceres and Eigen, as the benchmark
    JSON's context.components has them."""
    return _kneedyn.build_manifest()


def scene_path(name):
    """Path of a scene shipped in reference-data/scenes, e.g. scene_path('chapter_impact')."""
    name = _text(name, "scene_path", "name", "a scene's name (str), e.g. 'chapter_impact'")
    if name in ("", ".yaml"):  # gave '<data>/scenes/.yaml', and Problem('') "cannot open scenes/.yaml"
        raise InputError("scene_path(): name = %s: must name a scene, e.g. 'chapter_impact'" % _echo(name))
    return _os.path.join(data_dir(), "scenes", name if name.endswith(".yaml") else name + ".yaml")


def formulations():
    """The formulation registry: list of dicts with name, summary, integrators (values
    `integrator=` accepts; empty: fixed integrator), fixed_step (steps only with `step=`),
    fixed_step_integrators (integrators that take `step=` instead of tolerances) and
    needs_patella (runs only scenes with a `patella:` section)."""
    return _kneedyn.formulations()


class Scene:
    """A scene: its document (dict) and the loader's validated form of it."""

    def __init__(self, document, compiled, label, base_dir):
        # A Scene without its compiled form (Scene(doc, None, ...)) crashed run() and
        # sensitivity(): build one with load_scene() or Scene.from_dict().
        if not isinstance(document, dict):
            raise InputError("Scene(): document = %s (%s): must be a dict"
                             % (_echo(document), type(document).__name__))
        if not isinstance(compiled, CompiledScene):
            raise InputError("Scene(): compiled = %s (%s): must be a kneedyn.CompiledScene; build a Scene with "
                             "kneedyn.load_scene() or kneedyn.Scene.from_dict()"
                             % (_echo(compiled), type(compiled).__name__))
        label = _text(label, "Scene", "label")
        base_dir = _file_path(base_dir, "Scene", "base_dir")
        self._doc = document
        self._compiled = compiled
        self._label = label
        self._base_dir = base_dir

    # --- construction -------------------------------------------------------------
    @classmethod
    def from_dict(cls, document, base_dir=None, label="<dict>"):
        """Validates a scene document with the CLI's loader. A relative parameter_set is
        looked up under base_dir (default: the working directory), then under data_dir()."""
        if not isinstance(document, dict):
            raise InputError("Scene.from_dict(): document = %s: must be a dict" % _echo(document))
        label = _text(label, "Scene.from_dict", "label")
        base = _os.path.abspath(_os.getcwd() if base_dir is None else _file_path(base_dir, "Scene.from_dict", "base_dir"))
        _kneedyn.to_yaml(document, "Scene.from_dict")  # refuses, naming the field, what deepcopy cannot copy
        doc = _copy.deepcopy(document)
        return cls(doc, _kneedyn.parse_document(doc, label, base, "Scene.from_dict"), label, base)

    def copy(self):
        return Scene(_copy.deepcopy(self._doc), self._compiled, self._label, self._base_dir)

    # copy.copy and copy.deepcopy give copy(): the compiled form is read-only and shared.
    def __copy__(self):
        return self.copy()

    def __deepcopy__(self, memo):
        return self.copy()

    def __reduce__(self):
        # pickle (e.g. for a ProcessPoolExecutor): the document, label and base directory;
        # unpickling validates the document again with the loader.
        return (_scene_from_pickle, (self._doc, self._label, self._base_dir))

    # --- what it is -----------------------------------------------------------------
    @property
    def compiled(self):
        return self._compiled

    @property
    def name(self):
        return self._compiled.name

    @property
    def path(self):
        return self._compiled.path

    @property
    def ligaments(self):
        """Names of the ligament elements in the model, in model order."""
        return [lig["name"] for lig in self._compiled.ligaments]

    @ligaments.setter
    def ligaments(self, names):
        """Selects the elements (a list of names; [] for none). An element left out loses its
        ligament_parameters entry, which would name an element no longer selected."""
        self.update(self._selection_changes(_names(names, "ligaments", "Scene.ligaments")))

    def _selection_changes(self, selected):
        """The update() that selects `selected` and drops the overrides of the others."""
        changes = {"ligaments": selected}
        overrides = self._doc.get("ligament_parameters")
        if isinstance(overrides, dict):
            gone = {k: None for k in overrides if k not in selected}
            if gone:
                changes["ligament_parameters"] = gone
        return changes

    @property
    def ligament_parameters(self):
        """Per element: stiffnesses (N/mm, N/mm^2, as the law uses them), extension ratio,
        reference and slack lengths (mm)."""
        return self._compiled.ligaments

    @property
    def contacts(self):
        return self._compiled.contacts

    @property
    def pulse(self):
        return self._compiled.pulse

    @property
    def end(self):
        return self._compiled.end

    @property
    def patella(self):
        """The patella as the model holds it (docs/model.md §12), None without a patella:
        section: trochlea_medial|lateral (centre_mm, radius_mm), facet_medial|lateral
        (normal_P as a unit vector, offset_mm), apex_P_mm, base_P_mm, tuberosity_T_mm,
        tendon_length_mm, facet_liftoff, quadriceps (shape, magnitude_N, baseline_N,
        duration_s, direction_F as a unit vector) and start, the equilibrium at the initial
        pose in the solver's SI unknowns (solver/patella.hpp: coordinates in m and rad, chart
        coordinates, force ratios N / F_Q)."""
        return self._compiled.patella

    def to_dict(self):
        """A copy of the scene document."""
        return _copy.deepcopy(self._doc)

    def to_yaml(self):
        """The document as YAML text (what the loader reads; floats as Python's repr, the
        shortest text that reads back as the same double)."""
        return _kneedyn.to_yaml(self._doc, "Scene.to_yaml")

    def write(self, path):
        """Writes the document as a scene file the CLI can run. A relative parameter_set
        is made absolute so that the file works from any directory. A path that cannot be
        written raises InputError, and nothing is written."""
        # Checked before open(): open(True, "w") wrote to file descriptor 1 and closed stdout.
        path = _file_path(path, "Scene.write", "path")
        doc = _copy.deepcopy(self._doc)
        ps = doc.get("parameter_set")
        if isinstance(ps, str) and not _os.path.isabs(ps):
            # The loader's order (scene/scene.cpp): beside the scene, then as a shipped scene's
            # (<data>/scenes/ps: a copied shipped scene's ../chapter_knee.yaml), then <data>/ps.
            # data_dir() may be relative (KNEEDYN_DATA_DIR, the ./reference-data fallback).
            candidates = [_os.path.join(self._base_dir, ps), _os.path.join(data_dir(), "scenes", ps),
                          _os.path.join(data_dir(), ps)]
            found = [c for c in candidates if _os.path.exists(c)]
            doc["parameter_set"] = _os.path.abspath(found[0] if found else candidates[-1])
        text = _kneedyn.to_yaml(doc, "Scene.write")  # before the file is opened: a refusal writes nothing
        try:
            with open(path, "w", encoding="utf-8") as f:
                f.write(text)
        except OSError as e:
            raise InputError("Scene.write(): path = %s: cannot be written (%s)"
                             % (_echo(path), e.strerror or e)) from None

    # --- changes (validated by the loader; atomic) ----------------------------------
    def update(self, changes):
        """Deep-merges `changes` into the document (a value None deletes the key) and
        validates the result; on error the scene is unchanged."""
        if not isinstance(changes, dict):
            raise InputError("Scene.update(): changes = %s (%s): must be a dict of scene keys (a value None "
                             "deletes the key)" % (_echo(changes), type(changes).__name__))
        _kneedyn.to_yaml(changes, "Scene.update")  # refuses, naming the field, what deepcopy cannot copy
        doc = _copy.deepcopy(self._doc)
        _merge(doc, changes)
        label = self._label if self._label.endswith("(modified in Python)") \
            else self._label + " (modified in Python)"
        compiled = _kneedyn.parse_document(doc, label, self._base_dir, "Scene.update")
        self._doc, self._compiled, self._label = doc, compiled, label
        return self

    def remove_ligaments(self, *patterns):
        """Removes every element whose name contains one of the patterns (e.g. 'ACL'; a list
        of patterns counts as its items), with its ligament_parameters entry if the scene
        has one; returns the removed names. A pattern that matches
        nothing, an empty pattern (it would match every element) or one that is not a str
        raises InputError."""
        flat = []
        for p in patterns:
            flat += list(p) if isinstance(p, (list, tuple)) else [p]
        for p in flat:
            if not isinstance(p, str) or not p:
                raise InputError("Scene.remove_ligaments(): pattern %s (%s): must be a non-empty str (part of an "
                                 "element's name, e.g. 'ACL'); to remove every element set scene.ligaments = []"
                                 % (_echo(p), type(p).__name__))
        names = self.ligaments
        removed = []
        for p in flat:
            hit = [n for n in names if p in n]
            if not hit:
                raise InputError("Scene.remove_ligaments(): pattern %s matches no element; the "
                                 "scene has: %s" % (_echo(p), ", ".join(names)))
            removed += [n for n in hit if n not in removed]
        # An override of a removed element would be refused ("not a ligament element selected
        # by this scene"): it goes with the element (None deletes a key in update()).
        self.update(self._selection_changes([n for n in names if n not in removed]))
        return removed

    def set_ligament_parameters(self, name, **values):
        """Replaces one element's parameter-set values (scene key ligament_parameters):
        k_linear_N_mm, k_parabolic_N_mm2, extension_ratio (each > 0)."""
        return self.update({"ligament_parameters": {name: values}})

    def set_ligament_stiffness_scale(self, scale):
        """Scales both stiffnesses of every element (scene key ligament_stiffness_scale)."""
        return self.update({"ligament_stiffness_scale": scale})

    def set_pulse(self, **fields):
        """Pulse fields: shape (reconstructed|half_sine|reconstructed_peak|damped_sine|none),
        amplitude_N, duration_s, direction_T (reference-data/scenes/README.md). Fields are
        merged into the scene's pulse, except that shape="none" removes the keys that shape
        does not use (amplitude_N, duration_s, direction_T); one given with it is refused by
        the loader, as in a scene file."""
        if fields.get("shape") == "none":
            fields = dict({"amplitude_N": None, "duration_s": None, "direction_T": None}, **fields)
        return self.update({"pulse": fields})

    def set_patella(self, **fields):
        """Patella fields (scene key patella; docs/model.md §12): tendon_length_mm,
        trochlea_medial|lateral={centre_mm, radius_mm}, facet_medial|lateral={normal_P,
        offset_mm}, apex_P_mm, base_P_mm, tuberosity_T_mm, quadriceps={...}. Nested dicts are
        merged; the patella's start equilibrium is solved again by the loader. A scene
        without a patella: section raises InputError."""
        if self._compiled.patella is None:
            raise InputError("Scene.set_patella(): scene '%s' has no patella: section; start from a scene "
                             "with one, e.g. patellofemoral_impact.yaml" % self.name)
        return self.update({"patella": fields})

    def set_quadriceps(self, **fields):
        """Quadriceps force fields (scene key patella.quadriceps): shape (constant|ramp|
        half_sine), magnitude_N, baseline_N, duration_s, direction_F. shape="constant" drops
        the baseline_N and duration_s a ramp or half-sine had (the constant shape refuses
        them) unless they are given."""
        if fields.get("shape") == "constant":
            fields = dict({"baseline_N": None, "duration_s": None}, **fields)
        return self.set_patella(quadriceps=fields)

    def set_end(self, **fields):
        """End condition fields: flexion_deg, time_s (None removes one)."""
        return self.update({"end": fields})

    def __repr__(self):
        return "<kneedyn.Scene %s: %d ligaments, contacts %s, pulse %s>" % (
            self.name, len(self.ligaments), self.contacts, self.pulse)


def _merge(doc, changes):
    for k, v in changes.items():
        if v is None:
            doc.pop(k, None)
        elif isinstance(v, dict) and isinstance(doc.get(k), dict):
            _merge(doc[k], v)
        else:
            doc[k] = _copy.deepcopy(v)


def _echo(value, limit=80):
    """A value as a message shows it: its repr (NUL, surrogates escaped), cut at `limit`."""
    try:
        text = repr(value)
    except Exception:  # a repr that raises must not hide the refusal
        text = "<%s object>" % type(value).__name__
    return text if len(text) <= limit else text[:limit] + "... (%d characters)" % len(text)


def _file_path(value, function, argument, expected="a path (str or os.PathLike)"):
    """A str, bytes or os.PathLike path as str; anything else raises InputError naming it
    (before, str() of it was taken as a file name: "cannot open scene file 'None'"), as
    does a path with a NUL (the OS reads up to it: another file) or one that is not UTF-8
    (the C++ side takes UTF-8 text)."""
    if isinstance(value, (str, bytes, _os.PathLike)):
        try:
            path = _os.fsdecode(value)
        except TypeError:  # a PathLike whose __fspath__ gives neither str nor bytes
            path = None
        if isinstance(path, str):
            if "\0" in path:
                raise InputError("%s(): %s = %s: a path cannot hold a NUL character (the system would cut it "
                                 "there)" % (function, argument, _echo(value, 256)))
            try:
                path.encode("utf-8")
            except UnicodeEncodeError:
                raise InputError("%s(): %s = %s: must be a path that decodes as UTF-8"
                                 % (function, argument, _echo(value, 256))) from None
            return path
    hint = " (a scene document: kneedyn.Scene.from_dict)" if isinstance(value, dict) else ""
    raise InputError("%s(): %s = %s (%s): must be %s%s"
                     % (function, argument, _echo(value), type(value).__name__, expected, hint))


def _text(value, function, argument, expected="a str"):
    """A str option (a formulation's or integrator's name, a label) that the C++ side can take
    whole: no NUL (it cut the message there), no lone surrogate; else InputError naming it."""
    if not isinstance(value, str):
        raise InputError("%s(): %s = %s (%s): must be %s" % (function, argument, _echo(value), type(value).__name__,
                                                              expected))
    if "\0" in value:
        raise InputError("%s(): %s = %s: must not hold a NUL character" % (function, argument, _echo(value)))
    try:
        value.encode("utf-8")
    except UnicodeEncodeError:
        raise InputError("%s(): %s = %s: must be text that encodes as UTF-8 (it holds a lone surrogate)"
                         % (function, argument, _echo(value))) from None
    return value


def _integer(value, function, argument):
    """A whole number that fits the C++ side's int64, else InputError naming it (before,
    max_steps=1e20 reached pybind11, whose TypeError listed the signature, not the argument).
    bool, str and arrays are refused (True was taken as 1). The C++ side then applies its own
    range (e.g. max_steps in [1, 100000000])."""
    whole = False
    if isinstance(value, _numbers.Real) and not isinstance(value, (bool, _np.bool_)):
        try:
            as_int = int(value)
            whole = as_int == value
        except (TypeError, ValueError, OverflowError):
            pass
    if not whole or not -2**63 <= as_int < 2**63:
        raise InputError("%s(): %s = %s: must be a whole number in the range of a 64-bit integer"
                         % (function, argument, _echo(value)))
    return as_int


def _real(value, function, argument):
    """A real number as float (int, float, NumPy real scalars, Fraction), else InputError naming
    it: bool (True was 1.0), str ("1e-6" was parsed), bytes, complex and arrays are refused, as
    is a number beyond a double's range (10**400)."""
    if isinstance(value, _numbers.Real) and not isinstance(value, (bool, _np.bool_)):
        try:
            return float(value)
        except (TypeError, ValueError, OverflowError):
            raise InputError("%s(): %s = %s: must be a real number within the range of a double"
                             % (function, argument, _echo(value))) from None
    raise InputError("%s(): %s = %s (%s): must be a real number (int or float)"
                     % (function, argument, _echo(value), type(value).__name__))


def _names(value, argument, function="sensitivity"):
    """A list of names from any iterable of str; a single str is refused (list() of it gave its
    letters: "'P' is not a parameter of this scene"), as is anything not iterable."""
    if isinstance(value, (str, bytes)):
        raise InputError("%s(): %s = %s: must be a list of names, e.g. [%s]"
                         % (function, argument, _echo(value), _echo(value)))
    try:
        names = list(value)
    except TypeError:
        raise InputError("%s(): %s = %s (%s): must be a list of names (str)"
                         % (function, argument, _echo(value), type(value).__name__)) from None
    for n in names:
        if not isinstance(n, str):
            raise InputError("%s(): %s: %s (%s) is not a name (str)" % (function, argument, _echo(n), type(n).__name__))
        _text(n, function, argument + " item")
    return names


class _KeywordNames:
    """Within it, an InputError from the C++ checks, which name the CLI's flags (--max-steps),
    is raised again naming the keyword arguments of `function` (max_steps) a Python caller
    gave instead."""

    def __init__(self, function):
        self.keywords = set(_inspect.signature(function).parameters)

    def __enter__(self):
        return self

    def __exit__(self, kind, error, trace):
        if kind is None or not issubclass(kind, InputError):
            return False
        # Flags only: a whole word starting "--" outside the message's quoted values (a path
        # or a value the caller gave, '.../a--out/f', stays as given).
        flag = _re.compile(r"(?<![\w/.'-])--([a-z][a-z-]*)(?![\w-])")
        parts = _re.split(r"('[^']*')", str(error))
        for i in range(0, len(parts), 2):
            parts[i] = flag.sub(lambda m: m.group(1).replace("-", "_") if m.group(1).replace("-", "_") in self.keywords
                                else m.group(0), parts[i])
        text = "".join(parts)
        if text == str(error):
            return False
        raise InputError(text) from error


def _scene(scene, function):
    """A kneedyn.Scene, or one loaded from a scene file's path."""
    if isinstance(scene, Scene):
        return scene
    return load_scene(_file_path(scene, function, "scene", "a kneedyn.Scene or a scene file's path"))


def _scene_from_pickle(document, label, base_dir):
    return Scene(document, _kneedyn.parse_document(document, label, base_dir, "pickle.loads"), label, base_dir)


def load_scene(path):
    """Reads and validates a scene file exactly as `kneedyn run` does."""
    path = _file_path(path, "load_scene", "path")
    compiled, document = _kneedyn.load_file(path)
    return Scene(document, compiled, path, _os.path.dirname(_os.path.abspath(path)))


def _unit(column):
    if column in ("contacts_active",):
        return "count"
    if column == "is_event":
        return "flag (1: event row)"
    if column.startswith("strain_"):
        return "1 (strain)"
    if column == "tendon_quadriceps_ratio":
        return "1 (ratio)"
    for suffix, unit in (("_deg_s", "deg/s"), ("_mm_s", "mm/s"), ("_deg", "deg"), ("_mm", "mm"),
                         ("_N", "N"), ("_s", "s")):
        if column.endswith(suffix):
            return unit
    return ""


class Trajectory:
    """The run's output rows with the columns of trajectory.csv (same names, same units:
    mm, deg, N, s; NaN where the CSV has an empty cell). `traj['flexion_deg']` is a
    contiguous read-only view, `traj.array` the (rows x columns) array."""

    def __init__(self, columns, data):
        self.columns = list(columns)
        self._index = {c: i for i, c in enumerate(self.columns)}
        data.setflags(write=False)
        self._data = data  # (columns, rows)

    @property
    def array(self):
        return self._data.T

    @property
    def units(self):
        return {c: _unit(c) for c in self.columns}

    def __getitem__(self, column):
        try:
            return self._data[self._index[column]]
        except KeyError:
            raise KeyError("no column '%s'; columns: %s" % (column, ", ".join(self.columns))) from None

    def __contains__(self, column):
        return column in self._index

    def __len__(self):
        return self._data.shape[1]

    def to_dict(self):
        return {c: self[c] for c in self.columns}


class Event:
    __slots__ = ("name", "time", "flexion_deg")

    def __init__(self, name, time, flexion_deg):
        self.name, self.time, self.flexion_deg = name, time, flexion_deg

    def __repr__(self):
        return "Event(%r, t=%.6g s, flexion=%.6g deg)" % (self.name, self.time, self.flexion_deg)


class Result:
    """A run: `summary` is the dict summary.json holds; status, failure, end_reason,
    events, statistics are taken from it; `trajectory` holds trajectory.csv's columns."""

    def __init__(self, summary, trajectory):
        self.summary = summary
        self.trajectory = trajectory

    status = property(lambda self: self.summary["status"])       # completed | partial
    completed = property(lambda self: self.summary["status"] == "completed")
    failure = property(lambda self: self.summary.get("failure", ""))
    end_reason = property(lambda self: self.summary["end_reason"])
    statistics = property(lambda self: self.summary["statistics"])
    wall_time_s = property(lambda self: self.summary["wall_time_s"])

    @property
    def events(self):
        return [Event(e["name"], e["time"], e["flexion_deg"]) for e in self.summary["events"]]

    def event(self, prefix):
        """First event whose name starts with prefix (e.g. 'liftoff'), or None."""
        prefix = _text(prefix, "Result.event", "prefix", "a str, e.g. 'liftoff'")
        return next((e for e in self.events if e.name.startswith(prefix)), None)

    def __repr__(self):
        return "<kneedyn.Result %s (%s), %d rows, %d steps>" % (
            self.status, self.end_reason or self.failure, len(self.trajectory),
            self.statistics["steps"])


_DEFAULTS = _kneedyn.default_options()


def run(scene, formulation="dae", *, rtol=_DEFAULTS["rtol"], atol=_DEFAULTS["atol"],
        integrator=_DEFAULTS["integrator"], step=_DEFAULTS["step"], max_step=_DEFAULTS["max_step"],
        max_steps=_DEFAULTS["max_steps"], stabilization=_DEFAULTS["stabilization"],
        constraint_level=_DEFAULTS["constraint_level"], jacobian=_DEFAULTS["jacobian"],
        output_interval=0.0, out=None, linear_solver=_DEFAULTS["linear_solver"],
        contact_chart=_DEFAULTS["contact_chart"], rho_inf=None, alpha_m=None, alpha_f=None, beta=None,
        gamma=None):
    """Runs a scene (a Scene, or a path to a scene file) like `kneedyn run` with the
    options of the same names (errors name these keywords, not the CLI's flags) (output_interval 0: the scene's; jacobian and linear_solver
    '' : the formulation's default; contact_chart "regular" or "height-field";
    generalized-alpha's rho_inf, or alpha_m, alpha_f, beta and gamma together, as the CLI's
    --rho-inf ...; None: not given). Bad options raise
    InputError before anything runs; a start the consistent initialization cannot close
    raises SolverError (the CLI: exit 2); a solver failure returns a Result with
    status 'partial' and the reason in `failure`, as the CLI does. With out=DIR the
    CLI's files (trajectory.csv, trajectory.sto, summary.json) are written there by the
    CLI's writer. The fields of `Result.summary` are those of summary.json, listed in
    docs/outputs.md (:ref:`summary.json <outputs.md#summaryjson-schema_version-2>`)."""
    scene = _scene(scene, "run")
    with _KeywordNames(run):
        out = _kneedyn.run(scene.compiled, _text(formulation, "run", "formulation"), _real(rtol, "run", "rtol"),
                           _real(atol, "run", "atol"), _text(integrator, "run", "integrator"), _real(step, "run", "step"),
                           _real(max_step, "run", "max_step"), _integer(max_steps, "run", "max_steps"),
                           _text(stabilization, "run", "stabilization"), _text(constraint_level, "run", "constraint_level"),
                           _text(jacobian, "run", "jacobian"), _real(output_interval, "run", "output_interval"),
                           "" if out is None else _file_path(out, "run", "out"),
                           _text(linear_solver, "run", "linear_solver"), _text(contact_chart, "run", "contact_chart"),
                           {k: _real(v, "run", k) for k, v in (("rho_inf", rho_inf), ("alpha_m", alpha_m),
                                                               ("alpha_f", alpha_f), ("beta", beta), ("gamma", gamma))
                            if v is not None})
    return Result(_json.loads(out["summary_json"]), Trajectory(out["columns"], out["data"]))


class SweepResult:
    """One row per design run of a sweep (same rows as `kneedyn sweep`'s sweep.csv):
    `index`, `parameters[name]` and `outcomes[name]` as NumPy arrays (spec units; NaN where a
    run did not reach an outcome), `completed`, `steps`, `end_reason`, `failure`."""

    def __init__(self, d):
        self.index = d["index"]
        self.parameters = {c: d["parameters"][i] for i, c in enumerate(d["parameter_columns"])}
        self.outcomes = {c: d["outcomes"][i] for i, c in enumerate(d["outcome_columns"])}
        self.completed = d["completed"]
        self.steps = d["steps"]
        self.end_reason = list(d["end_reason"])
        self.failure = list(d["failure"])
        self.total_runs = d["total_runs"]

    def __len__(self):
        return len(self.index)

    def __repr__(self):
        return "<kneedyn.SweepResult: %d runs, %d failed>" % (len(self), int((~self.completed).sum()))


def sweep(spec_path, threads=0, out=None):
    """Runs a sweep spec (ensembles/README.md) in process on `threads` workers (0: all cores),
    the GIL released; `out` also writes sweep.csv and sweep.h5 as `kneedyn sweep --out` does.
    The rows do not depend on the thread count."""
    return SweepResult(_kneedyn.sweep(_file_path(spec_path, "sweep", "spec_path"),
                                      _integer(threads, "sweep", "threads"),
                                      "" if out is None else _file_path(out, "sweep", "out")))


def sensitivity(scene, parameters, outcomes, *, rtol=1e-8, atol=1e-10, fd_step=0.0, out=None, formulation="ede",
                max_steps=200000, output_interval=0.0):
    """Forward sensitivities like `kneedyn sensitivity` (docs/outputs.md): `parameters` and
    `outcomes` are the sweep's names (e.g. "PCL_anterior.k_linear", "peak_F_PCL_anterior_N"
    or a group such as "contact_force_at_90"); `formulation` "ede" (CVODES) or a DAE form
    "dae", "dae-reduced", "dae-ggl", "dae-ggl-reduced" (IDAS). Returns a dict with `parameters`,
    `parameter_values`, `outcomes`, `values`, `derivatives` ([outcome][parameter]),
    `end_reason`, `steps`, and with fd_step > 0 `fd_derivatives` (central differences with
    that relative step). `out` also writes sensitivity.csv and sensitivity.json; max_steps
    (per phase) and output_interval (s between the rows of sensitivity_trajectory.csv; 0: the
    scene's; the peaks are the continuous solution's maxima, not the rows') as the CLI's
    --max-steps and --output-interval. Unknown
    names raise InputError naming the nearest valid name; a run with an impact SolverError."""
    scene = _scene(scene, "sensitivity")
    with _KeywordNames(sensitivity):
        return _kneedyn.sensitivity(scene.compiled, _names(parameters, "parameters"), _names(outcomes, "outcomes"),
                                    _real(rtol, "sensitivity", "rtol"), _real(atol, "sensitivity", "atol"),
                                    _real(fd_step, "sensitivity", "fd_step"),
                                    "" if out is None else _file_path(out, "sensitivity", "out"),
                                    _text(formulation, "sensitivity", "formulation"),
                                    _integer(max_steps, "sensitivity", "max_steps"),
                                    _real(output_interval, "sensitivity", "output_interval"))
