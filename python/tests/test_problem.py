"""kneedyn.Problem (python/problem_bindings.cpp, docs/problem.md): the contract names, values
equal to the C++ run's, the exact DAE Jacobian against central differences, the whole
hybrid run driven from Python reproducing `kneedyn run`'s events, and ValueError for bad calls."""
import math
import os
import pathlib

import numpy as np
import pytest

import kneedyn

SCENE = kneedyn.scene_path("chapter_impact")


@pytest.mark.parametrize("form", ["ede", "mde", "dae", "dae-ggl"])
def test_contract_names(form):
    p = kneedyn.Problem(kneedyn.load_scene(SCENE), form=form)
    for name in ["t0", "y0", "t_end", "rtol", "atol", "event_names", "event_directions"]:
        assert hasattr(p, name), name
    assert p.y0.shape == (p.size,) and p.yp0.shape == (p.size,)
    assert len(p.events(p.t0, p.y0)) == len(p.event_names) == len(p.event_directions)
    assert p.rtol == 1e-6 and p.atol == 1e-8 and p.t_end > p.t0
    assert p.index == (0 if form in ("ede", "mde") else 2)


def test_initial_state_is_the_runs_first_row():
    """y0 is kneedyn run's consistent start: its first trajectory row, to the row's digits."""
    p = kneedyn.Problem(SCENE, form="ede")
    result = kneedyn.run(kneedyn.load_scene(SCENE), "ede")
    traj = result.trajectory
    assert traj["time_s"][0] == p.t0
    assert traj["x0_mm"][0] == pytest.approx(p.y0[0] * 1e3, rel=1e-12, abs=1e-12)
    assert traj["flexion_deg"][0] == pytest.approx(math.degrees(p.y0[3]), rel=1e-12, abs=1e-12)


def test_ode_rhs_is_consistent_with_yp0():
    """f(t0, y0) is the phase start's (q̇, q̈) (the same hidden-constraint solve)."""
    p = kneedyn.Problem(SCENE, form="ede")
    np.testing.assert_allclose(p.rhs(p.t0, p.y0), p.yp0, rtol=1e-12, atol=1e-9)


def test_mde_is_ede_in_minimal_coordinates():
    """mde's y0 is ede's (q, q̇) at the free coordinates (y0, α, β, γ with both contacts
    closed), its coordinates() give ede's full start back, and its f agrees with ede's
    hidden-constraint solve on the free rows: two formulations of the same physics."""
    ede, mde = kneedyn.Problem(SCENE, form="ede"), kneedyn.Problem(SCENE, form="mde")
    free = [1, 3, 4, 5]
    assert mde.size == 8 and mde.component_names[:4] == ["y0", "alpha", "beta", "gamma"]
    np.testing.assert_array_equal(mde.y0, np.concatenate([ede.y0[free], ede.y0[[6 + i for i in free]]]))
    q, qd = mde.coordinates(mde.t0, mde.y0)
    np.testing.assert_allclose(q, ede.y0[:6], rtol=1e-13, atol=1e-15)
    np.testing.assert_allclose(qd, ede.y0[6:], rtol=1e-12, atol=1e-12)
    f_ede = ede.rhs(ede.t0, ede.y0)
    np.testing.assert_allclose(mde.rhs(mde.t0, mde.y0)[4:], f_ede[[6 + i for i in free]], rtol=1e-9, atol=1e-9)
    assert mde.event_names[-1] == "mde_chart" and mde.event_directions[-1] == -1


@pytest.mark.parametrize("form", ["dae", "dae-ggl"])
def test_dae_jacobian_matches_central_differences(form):
    p = kneedyn.Problem(SCENE, form=form)
    y, yp, c, t = p.y0 + 1e-3 * p.yp0, p.yp0, 25.0, p.t0 + 1e-3
    J = p.jacobian(t, y, yp, c)
    F0 = p.residual(t, y, yp)
    assert J.shape == (p.size, p.size) and F0.shape == (p.size,)
    for j in range(p.size):
        hy, hp = 1e-9 * (1 + abs(y[j])), 1e-9 * (1 + abs(yp[j]))  # O(h) convergence (problem_test.cpp)
        e = np.zeros(p.size); e[j] = 1
        fd = (p.residual(t, y + hy * e, yp) - p.residual(t, y - hy * e, yp)) / (2 * hy) \
            + c * (p.residual(t, y, yp + hp * e) - p.residual(t, y, yp - hp * e)) / (2 * hp)
        np.testing.assert_allclose(J[:, j], fd, atol=1e-6 * max(1.0, np.abs(J[:, j]).max()))


def test_transition_by_name_and_end():
    p = kneedyn.Problem(SCENE, form="dae")
    end = [n for n in p.event_names if n.startswith("flexion_")][0]
    y, yp, ended = p.transition(p.t0 + 0.01, p.y0, end, yp=p.yp0)
    assert ended and y is None and yp is None and p.end_reason == end
    with pytest.raises(ValueError, match="ended"):
        p.residual(p.t0, p.y0, p.yp0)


def test_bad_calls_raise_value_error():
    with pytest.raises(ValueError, match="'rk4'"):
        kneedyn.Problem(SCENE, form="rk4")
    p = kneedyn.Problem(SCENE, form="ede")
    with pytest.raises(ValueError, match="size 11"):
        p.rhs(p.t0, p.y0[:11])
    y = p.y0.copy(); y[2] = np.nan
    with pytest.raises(ValueError, match=r"y\[2\] = nan"):
        p.rhs(p.t0, y)
    y = p.y0.copy(); y[9] = 1e200  # finite, but the dynamics overflow: no NaN handed back
    with pytest.raises(kneedyn.SolverError, match=r"f\[\d+\] = .*every output is finite"):
        p.rhs(p.t0, y)
    with pytest.raises(ValueError, match="1-D"):
        p.rhs(p.t0, np.zeros((3, 4)))
    with pytest.raises(ValueError, match="ODE"):
        p.residual(p.t0, p.y0, p.y0)
    with pytest.raises(ValueError, match="event = 99"):
        p.transition(p.t0, p.y0, 99)
    with pytest.raises(ValueError, match="not an event"):
        p.transition(p.t0, p.y0, "liftoff_nowhere")
    # A yp on an ODE form was taken and ignored, NaN or not.
    with pytest.raises(ValueError, match="yp = .*the ODE forms take none"):
        p.transition(p.t0, p.y0, 0, np.full(p.size, np.nan))
    with pytest.raises(ValueError, match="yp = .*the ODE forms take none"):
        p.coordinates(p.t0, p.y0, p.y0)
    # coordinates takes the DAE forms' yp, as the C interface does (it took none before).
    d = kneedyn.Problem(SCENE, form="dae")
    q, qd = d.coordinates(d.t0, d.y0, d.yp0)
    q_no_yp, _ = d.coordinates(d.t0, d.y0)
    assert np.array_equal(q, q_no_yp) and qd.shape == (6,)
    bad_yp = d.yp0.copy(); bad_yp[0] = np.nan
    with pytest.raises(ValueError, match=r"yp\[0\] = nan"):
        d.coordinates(d.t0, d.y0, bad_yp)
    # transition needs yp on the DAE forms: the message shows the call.
    with pytest.raises(ValueError, match=r"yp is missing.*p.transition\(t, y, event, yp\)"):
        d.transition(d.t0, d.y0, 0)
    # Tolerances past kneedyn run's ranges (the re-contact threshold scales with them).
    with pytest.raises(ValueError, match=r"rtol = 1e\+300.*\(0, 0.5\]"):
        kneedyn.Problem(SCENE, form="ede", rtol=1e300)
    with pytest.raises(ValueError, match=r"\(0, 1e-2\]"):
        kneedyn.Problem(SCENE, form="ede", atol=0.5)
    with pytest.raises(ValueError):
        kneedyn.Problem(SCENE, form="dae").jacobian(0.0, np.zeros(3), np.zeros(3), 1.0)


def _c_interface():
    """The C interface (libkneedyn_problem_c, kneedyn/problem.h) through ctypes, from the build tree."""
    import ctypes
    import os
    lib = os.path.join(os.environ.get("KNEEDYN_BUILD_DIR", ""), "problem", "libkneedyn_problem_c.so")
    if not os.environ.get("KNEEDYN_BUILD_DIR") or not os.path.exists(lib):
        pytest.skip("needs the build tree's libkneedyn_problem_c.so (run by ctest)")
    c = ctypes.CDLL(lib)
    dp = ctypes.POINTER(ctypes.c_double)
    c.kneedyn_problem_create.argtypes = [ctypes.c_char_p, ctypes.c_char_p, ctypes.c_double, ctypes.c_double,
                                         ctypes.POINTER(ctypes.c_void_p)]
    c.kneedyn_problem_jacobian.argtypes = [ctypes.c_void_p, ctypes.c_double, dp, ctypes.c_int, dp]
    c.kneedyn_problem_rhs.argtypes = [ctypes.c_void_p, ctypes.c_double, dp, ctypes.c_int, dp]
    c.kneedyn_problem_residual.argtypes = [ctypes.c_void_p, ctypes.c_double, dp, dp, ctypes.c_int, dp]
    c.kneedyn_problem_dae_jacobian.argtypes = [ctypes.c_void_p, ctypes.c_double, dp, dp, ctypes.c_double,
                                               ctypes.c_int, dp]
    c.kneedyn_problem_destroy.argtypes = [ctypes.c_void_p]
    c.kneedyn_last_error.restype = ctypes.c_char_p
    return c, dp


@pytest.mark.parametrize("scene", ["anatomical_surfaces", "patellofemoral_impact"])
@pytest.mark.parametrize("form", ["ede", "mde"])
def test_ode_jacobian_on_general_surfaces_equals_c_interface_bitwise(scene, form):
    """p.jacobian and p.rhs on ellipsoid caps on polynomial plateaus and with the patella are
    the C interface's, bitwise (the exact Jacobian against central differences with a step
    study: tests/problem_test.cpp, GeneralSurfaceJacobian)."""
    import ctypes
    c, dp = _c_interface()
    path = kneedyn.scene_path(scene)
    p = kneedyn.Problem(path, form=form)
    t, y = p.t0 + 1e-3, p.y0 + 1e-3 * p.yp0
    J, f = p.jacobian(t, y), p.rhs(t, y)
    h = ctypes.c_void_p()
    assert c.kneedyn_problem_create(path.encode(), form.encode(), 0.0, 0.0, ctypes.byref(h)) == 0, \
        c.kneedyn_last_error()
    try:
        yc = np.ascontiguousarray(y, dtype=np.float64)
        Jc, fc = np.zeros((p.size, p.size)), np.zeros(p.size)
        assert c.kneedyn_problem_jacobian(h, t, yc.ctypes.data_as(dp), p.size, Jc.ctypes.data_as(dp)) == 0, \
            c.kneedyn_last_error()
        assert c.kneedyn_problem_rhs(h, t, yc.ctypes.data_as(dp), p.size, fc.ctypes.data_as(dp)) == 0
    finally:
        c.kneedyn_problem_destroy(h)
    assert np.array_equal(J.view(np.uint64), Jc.view(np.uint64))
    assert np.array_equal(f.view(np.uint64), fc.view(np.uint64))


@pytest.mark.parametrize("form", ["dae", "dae-ggl"])
def test_dae_residual_and_jacobian_equal_c_interface_bitwise(form):
    """p.residual and p.jacobian(t, y, yp, c) are the C interface's, bitwise."""
    import ctypes
    c, dp = _c_interface()
    p = kneedyn.Problem(SCENE, form=form)
    t, y, yp, cj = p.t0 + 1e-3, p.y0 + 1e-3 * p.yp0, p.yp0.copy(), 25.0
    F, J = p.residual(t, y, yp), p.jacobian(t, y, yp, cj)
    h = ctypes.c_void_p()
    assert c.kneedyn_problem_create(SCENE.encode(), form.encode(), 0.0, 0.0, ctypes.byref(h)) == 0, \
        c.kneedyn_last_error()
    try:
        yc, ypc = (np.ascontiguousarray(v, dtype=np.float64) for v in (y, yp))
        Fc, Jc = np.zeros(p.size), np.zeros((p.size, p.size))
        assert c.kneedyn_problem_residual(h, t, yc.ctypes.data_as(dp), ypc.ctypes.data_as(dp), p.size,
                                          Fc.ctypes.data_as(dp)) == 0, c.kneedyn_last_error()
        assert c.kneedyn_problem_dae_jacobian(h, t, yc.ctypes.data_as(dp), ypc.ctypes.data_as(dp), cj, p.size,
                                              Jc.ctypes.data_as(dp)) == 0, c.kneedyn_last_error()
    finally:
        c.kneedyn_problem_destroy(h)
    assert np.array_equal(F.view(np.uint64), Fc.view(np.uint64))
    assert np.array_equal(J.view(np.uint64), Jc.view(np.uint64))


def test_arguments_of_the_wrong_kind_are_refused_naming_them():
    """Events, c, y and the scene path of the wrong kind raise ValueError naming the argument
    (not pybind11's cast error, and not a silent cast: NumPy would drop an imaginary part
    and read digit strings, bytes would iterate as indices, True would be event 1)."""
    p = kneedyn.Problem(SCENE, form="ede")
    for event in [None, 1.5, 1.0, True, {0}, {0: 1}, [[0]], b"\x00", np.float64(0)]:
        with pytest.raises(ValueError, match="event = "):
            p.transition(p.t0 + 0.01, p.y0, event)
    for event in [2**40, 10**30, -2**40]:
        with pytest.raises(ValueError, match="has events 0 to"):
            p.transition(p.t0 + 0.01, p.y0, event)
    with pytest.raises(ValueError, match="given twice"):
        p.transition(p.t0 + 0.01, p.y0, [0, 0])
    with pytest.raises(ValueError, match="given twice"):
        p.transition(p.t0 + 0.01, p.y0, [p.event_names[0], 0])
    for y in [p.y0.astype(complex), [str(v) for v in p.y0], [None] * p.size, np.ones(p.size, dtype=bool)]:
        with pytest.raises(ValueError, match="y = .*real numbers"):
            p.rhs(p.t0, y)
    with pytest.raises(ValueError, match="t = nan"):
        p.rhs(float("nan"), p.y0)
    # t of the wrong kind, in every method that takes it (True was read as 1.0 s, text raised
    # pybind11's TypeError); a NumPy float and an int are real numbers.
    d0 = kneedyn.Problem(SCENE, form="dae")
    calls = {"rhs": lambda t: p.rhs(t, p.y0), "events": lambda t: p.events(t, p.y0),
             "coordinates": lambda t: p.coordinates(t, p.y0), "jacobian": lambda t: p.jacobian(t, p.y0),
             "transition": lambda t: p.transition(t, p.y0, 0),
             "residual": lambda t: d0.residual(t, d0.y0, d0.yp0)}
    for method, call in calls.items():
        for t in [True, "0", b"0", None, [0.0]]:
            with pytest.raises(ValueError, match=r"kneedyn.Problem.%s: t = " % method):
                call(t)
    assert np.array_equal(p.rhs(np.float64(p.t0), p.y0), p.rhs(p.t0, p.y0))
    assert np.array_equal(p.rhs(int(p.t0), p.y0), p.rhs(float(int(p.t0)), p.y0))
    with pytest.raises(ValueError, match="scene = .*NUL"):
        kneedyn.Problem(SCENE + "\0junk", form="ede")
    with pytest.raises(ValueError, match="scene = .*decodes as UTF-8"):
        kneedyn.Problem(os.fsdecode(b"/tmp/\xff.yaml"), form="ede")
    for form in [None, b"ede", 1]:
        with pytest.raises(ValueError, match="form = .*must be a str"):
            kneedyn.Problem(SCENE, form=form)
    with pytest.raises(ValueError, match=r"form = 'ede\?x': one of"):  # the message was cut at the NUL
        kneedyn.Problem(SCENE, form="ede\0x")
    for value in [True, "1e-6", 1 + 0j, None, 10**400]:
        for name in ("rtol", "atol"):
            with pytest.raises(ValueError, match=name + " = "):
                kneedyn.Problem(SCENE, form="ede", **{name: value})
    assert kneedyn.Problem(pathlib.Path(SCENE), form="ede").t0 == p.t0  # os.PathLike, as load_scene

    class NotAScene:
        compiled = 5
    with pytest.raises(ValueError, match="scene.compiled = 5"):
        kneedyn.Problem(NotAScene(), form="ede")
    d = kneedyn.Problem(SCENE, form="dae")
    for c in ["x", [1.0], 10**400, True]:
        with pytest.raises(ValueError, match="c = "):
            d.jacobian(d.t0, d.y0, d.yp0, c)
    yp = d.yp0.copy(); yp[4] = np.nan
    with pytest.raises(ValueError, match=r"yp\[4\] = nan"):
        d.residual(d.t0, d.y0, yp)
    assert p.phase == 0 and p.events_recorded == [] and d.phase == 0


def test_integer_events_of_any_integer_type_and_numpy_scalars_are_accepted():
    """An index may be a Python int, a NumPy integer or a 0-d integer array."""
    end = [k for k, n in enumerate(kneedyn.Problem(SCENE, form="ede").event_names) if n.startswith("flexion_")][0]
    for event in [end, np.int64(end), np.int32(end), np.array(end), [np.int16(end)]]:
        p = kneedyn.Problem(SCENE, form="ede")
        y, ended = p.transition(p.t0 + 0.01, p.y0, event)
        assert ended and y is None, event


def test_after_the_end_only_the_runs_own_facts_answer():
    """After the end no phase is open: its values, sizes, ids, names and events raise; the
    times, tolerances, phase, end reason and records answer."""
    p = kneedyn.Problem(SCENE, form="dae")
    end = [n for n in p.event_names if n.startswith("flexion_")][0]
    y0, yp0 = p.y0, p.yp0
    p.transition(p.t0 + 0.01, y0, end, yp=yp0)
    for name in ["y0", "yp0", "size", "differential_ids", "component_names", "event_names", "event_directions"]:
        with pytest.raises(ValueError, match="ended"):
            getattr(p, name)
    assert p.end_reason == end and [e[0] for e in p.events_recorded] == [end]
    assert p.t_end > p.t0 and p.rtol == 1e-6 and p.phase == 0


def test_a_problem_is_not_copied_but_a_pickled_scene_builds_the_same_problem():
    """A Problem holds its open phase (active contacts, events so far): copy and pickle raise
    TypeError (docs/problem.md). A process pool sends the Scene instead: the Problem built from
    the unpickled scene starts where the original does, with the same f, bitwise."""
    import copy
    import pickle
    scene = kneedyn.load_scene(SCENE)
    p = kneedyn.Problem(scene, form="ede")
    for clone in (copy.copy, copy.deepcopy, pickle.dumps):
        with pytest.raises(TypeError):
            clone(p)
    q = kneedyn.Problem(pickle.loads(pickle.dumps(scene)), form="ede")
    assert q.t0 == p.t0 and q.event_names == p.event_names
    np.testing.assert_array_equal(q.y0, p.y0)
    np.testing.assert_array_equal(q.rhs(p.t0 + 0.01, p.y0), p.rhs(p.t0 + 0.01, p.y0))
