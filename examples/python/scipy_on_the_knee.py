#!/usr/bin/env python3
"""SciPy's solve_ivp runs the knee's whole hybrid problem through kneedyn.Problem (docs/problem.md).

kneedyn gives each phase (f, its Jacobian, the named events) and the transition to the next
phase; solve_ivp integrates the phases. Rows at multiples of --dt plus every event go to
OUT/trajectory.csv, events to OUT/events.csv, and `kneedyn score` scores them.

    PYTHONPATH=build/python /usr/bin/python3 examples/python/scipy_on_the_knee.py \
        --method Radau --rtol 1e-8 --atol 1e-10 --out out/scipy --kneedyn build/formulations/kneedyn

--scene: a scene file or a shipped scene's name (default: chapter_impact); --form: the ODE form
solve_ivp integrates, ede or mde (default ede; docs/problem.md); --method: Radau, BDF, LSODA or
DOP853 (default Radau); --rtol/--atol: solve_ivp's tolerances (default 1e-8, 1e-10); --dt: the
output interval in s (default 0.02); --kneedyn: also score the result with it.

Exit codes as kneedyn run's: 0 completed, 1 the solver failed (what was reached is written
and scored as failed), 2 bad arguments (nothing written).
"""
import argparse
import csv
import os
import subprocess
import sys
import time

import numpy as np
from scipy.integrate import solve_ivp

try:
    import kneedyn
except ImportError as e:
    print(f"scipy_on_the_knee: error: the kneedyn module is not importable ({e}); "
          "run with PYTHONPATH=build/python or install it (docs/python.md)", file=sys.stderr)
    sys.exit(2)

M_TO_MM, RAD_TO_DEG = 1e3, 180.0 / np.pi
COLUMNS = ["x0_mm", "y0_mm", "z0_mm", "flexion_deg", "valgus_deg", "external_rotation_deg",
           "vx_mm_s", "vy_mm_s", "vz_mm_s", "flexion_rate_deg_s", "valgus_rate_deg_s", "external_rotation_rate_deg_s"]


def row(p, t, y, is_event):
    q, qd = p.coordinates(t, y)  # ede: y itself; mde: with the eliminated translations
    scale = [M_TO_MM] * 3 + [RAD_TO_DEG] * 3
    pos = [q[i] * scale[i] - (90.0 if i == 4 else 0.0) for i in range(6)]  # valgus_deg = beta - 90 deg
    return [t] + pos + [qd[i] * scale[i] for i in range(6)] + [int(is_event)]


def event_functions(p):
    """One solve_ivp event per kneedyn event of the phase; all evaluated in one call, cached."""
    cache = {}
    def g(t, y):
        key = (t, y.tobytes())
        if key not in cache:
            cache.clear()
            cache[key] = p.events(t, y)
        return cache[key]
    funcs = []
    for k, direction in enumerate(p.event_directions):
        f = lambda t, y, k=k: g(t, y)[k]
        f.terminal, f.direction = True, float(direction)
        funcs.append(f)
    return funcs


def run(p, method, rtol, atol, dt, out):
    """Fills out: rows, events, nfev, njev; returns the end event's name. Raises on a failure
    (out keeps what was reached)."""
    rows, events = out["rows"], out["events"]
    rows.append(row(p, p.t0, p.y0, False))
    t, y = p.t0, p.y0
    while True:
        grid = dt * np.arange(np.floor(t / dt + 1e-9) + 1, np.floor(p.t_end / dt + 1e-9) + 1)
        sol = solve_ivp(p.rhs, (t, p.t_end), y, method=method, t_eval=grid, events=event_functions(p), rtol=rtol,
                        atol=atol, **({} if method == "DOP853" else {"jac": p.jacobian}))
        if sol.status < 0:
            raise RuntimeError(f"solve_ivp ({method}) at t = {sol.t[-1] if sol.t.size else t} s: {sol.message}")
        out["nfev"], out["njev"] = out["nfev"] + sol.nfev, out["njev"] + sol.njev
        rows += [row(p, tk, yk, False) for tk, yk in zip(sol.t, np.asarray(sol.y).T)]
        fired = [k for k, te in enumerate(sol.t_events) if te.size]
        if not fired:  # reached t_end
            return "end_time"
        t_event = min(sol.t_events[k][0] for k in fired)
        fired = [k for k in fired if sol.t_events[k][0] == t_event]
        y_event = sol.y_events[fired[0]][0]
        rows[:] = [r for r in rows if r[0] < t_event - 1e-12] + [row(p, t_event, y_event, True)]
        names = p.event_names
        y_next, ended = p.transition(t_event, y_event, fired)
        events += [(name, t_e, fl * RAD_TO_DEG) for name, t_e, fl in p.events_recorded[len(events):]]  # mde_chart: none
        if ended:
            return names[fired[0]]
        # The root just handled is ~0 at the restart (a ligament kink stays watched): step
        # 1e-9 s without events so that solve_ivp does not find it again at the start.
        step = solve_ivp(p.rhs, (t_event, t_event + 1e-9), y_next, method=method, rtol=rtol, atol=atol)
        t, y, out["nfev"] = step.t[-1], step.y[:, -1], out["nfev"] + step.nfev


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", default=kneedyn.scene_path("chapter_impact"))
    ap.add_argument("--method", default="Radau", choices=["Radau", "BDF", "LSODA", "DOP853"])
    ap.add_argument("--form", default="ede", choices=["ede", "mde"], help="the ODE form (docs/problem.md)")
    ap.add_argument("--rtol", type=float, default=1e-8)
    ap.add_argument("--atol", type=float, default=1e-10)
    ap.add_argument("--dt", type=float, default=0.02, help="output interval (s): the reference's sampling")
    ap.add_argument("--out", default="out/scipy_on_the_knee")
    ap.add_argument("--kneedyn", help="kneedyn executable: score the result with `kneedyn score`")
    a = ap.parse_args()
    # kneedyn run's limits; checked before the run, as kneedyn's programs do.
    for option, value, low, high in (("--rtol", a.rtol, 0.0, 0.5), ("--atol", a.atol, 0.0, 1e-2),
                                     ("--dt", a.dt, 1e-6, 100.0)):
        if not (low < value <= high):
            ap.error(f"{option} = {value}: must be in ({low:g}, {high:g}]")
    if a.kneedyn and not (os.path.isfile(a.kneedyn) and os.access(a.kneedyn, os.X_OK)):
        ap.error(f"--kneedyn = '{a.kneedyn}': not an executable file")
    if os.path.exists(a.out) and not os.path.isdir(a.out):
        ap.error(f"--out = '{a.out}': an existing file, not a directory")
    try:
        p = kneedyn.Problem(a.scene, form=a.form, rtol=a.rtol, atol=a.atol)
        os.makedirs(a.out, exist_ok=True)
    except (ValueError, OSError) as e:  # kneedyn.InputError is a ValueError
        ap.error(f"{'--out' if isinstance(e, OSError) else '--scene'}: {e}")
    start = time.process_time()
    res = {"rows": [], "events": [], "nfev": 0, "njev": 0}
    try:
        end, failure = run(p, a.method, a.rtol, a.atol, a.dt, res), ""
    except (RuntimeError, ValueError) as e:  # a failed run is a result: scored as failed
        end, failure = None, str(e).replace("\n", " ")
    cpu = time.process_time() - start
    rows, events, nfev, njev = res["rows"], res["events"], res["nfev"], res["njev"]
    traj, ev = os.path.join(a.out, "trajectory.csv"), os.path.join(a.out, "events.csv")
    with open(traj, "w", newline="") as f:
        csv.writer(f).writerows([["time_s"] + COLUMNS + ["is_event"]] + [[repr(v) for v in r] for r in rows])
    with open(ev, "w", newline="") as f:
        csv.writer(f).writerows([["name", "time_s", "flexion_deg"]] + [[n, repr(t), repr(d)] for n, t, d in events])
    for name, t_e, fl in events:
        print(f"{name}: t = {t_e:.12g} s, flexion = {fl:.10g} deg")
    print(f"scipy {a.method}: end {end or 'failed: ' + failure}, {nfev} f evaluations, {njev} Jacobians, "
          f"{cpu:.3f} s CPU")
    if a.kneedyn:  # one curve per method in the work-precision diagrams: solver scipy, integrator the method
        scored = subprocess.run([a.kneedyn, "score", traj, "--scene", a.scene, "--events", ev, "--solver-name",
                        "scipy" if a.form == "ede" else f"scipy-{a.form}", "--integrator", a.method, "--rtol", str(a.rtol), "--atol", str(a.atol), "--cpu-time",
                        repr(cpu), "--counter", f"residual_evaluations={nfev}", "--counter",
                        f"jacobian_evaluations={njev}", "--out", os.path.join(a.out, "score.json")]
                       + (["--failed", failure] if failure else []), check=False)
        if scored.returncode != 0:
            print(f"scipy_on_the_knee: error: kneedyn score exited {scored.returncode}", file=sys.stderr)
            return 1
    return 1 if failure else 0


if __name__ == "__main__":
    sys.exit(main())
