#!/usr/bin/env python3
"""Side-by-side evidence (benchmarks/README.md, "SciPy side by side"): an independent SciPy
implementation of the chapter model, written from docs/model.md (not from kneedyn's sources),
and kneedyn, timed in the same process on the chapter scene
(reference-data/scenes/chapter_impact.yaml): time to reach 6 and 8 correct digits of the
lateral lift-off time.

  PYTHONPATH=build/python /usr/bin/python3 benchmarks/scipy_side_by_side.py [--quick]
      [--check-digits D]          exit 1 unless SciPy's tightest lift-off agrees with the
                                  reference to >= D digits (the cross-check test)
      [--repeats N]               min CPU time over N calls (default 3; 1 with --quick)
      [--json PATH]               also write the runs as JSON, with the fairness manifest
                                  (context.components: kneedyn's build, then SciPy's)
  cmake --build build --target bench_scipy

The SciPy model is what a researcher writes first: the excess ODE in (q, q̇) with the
hidden constraint (the contact normal forces from the acceleration-level constraint
solved together with Newton-Euler at every right-hand side, model.md §8), closed-form
sphere-on-plane contact (§4), the published ligament law with each element's branch held
within a segment and a restart at every crossing of ε = 2ε1 (§5, as kneedyn does), the
reconstructed pulse (§7), solve_ivp (DOP853) with events: lift-off is N_lateral crossing
zero downwards (§9). Only the first contact phase (both compartments in contact, from
rest at the reference pose) is needed for the lift-off time.

Reference: the stored reference solution's lateral lift-off
(reference-data/references/chapter_impact.json: make_reference's extended-precision
Gauss-Legendre run in float128, its `generator`). A tight kneedyn dae-ggl run (rtol 1e-11,
the tightest IDA completes) is printed beside it: it is only about 9 digits from it (8.92
on 2026-12-05), too close to 8 digits to judge them. Digits = −log10(|t − t_ref| / t_ref).
Times: min over repeats of the process CPU time (time.process_time; the machine may be
shared) of one call: kneedyn.run in process through the Python binding (the whole run to
90°, plus building its output table: kneedyn does more work than SciPy here), and the
solve_ivp loop up to lift-off.
"""
import argparse
import math
import os
import sys
import time

import numpy as np
import yaml
from scipy.integrate import solve_ivp

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
sys.dont_write_bytecode = True  # keep the source tree clean
sys.path.insert(0, HERE)
from record_sweep import provenance as recorded_provenance  # noqa: E402  the recorded files' rule, one copy
MM = 1e-3
EPS1 = 0.03


# ---------------------------------------------------------------- model (docs/model.md)

def rot(a, b, g):
    """R_FT (model.md §2)."""
    sa, ca, sb, cb, sg, cg = math.sin(a), math.cos(a), math.sin(b), math.cos(b), math.sin(g), math.cos(g)
    return np.array([[sb * cg, sb * sg, cb],
                     [-ca * sg - sa * cb * cg, ca * cg - sa * cb * sg, sa * sb],
                     [sa * sg - ca * cb * cg, -sa * cg - ca * cb * sg, ca * sb]])


def emap(b, g):
    """E(β, γ): ω′ = E (α̇, β̇, γ̇), columns −î, −ê2, −k̂′ (model.md §2)."""
    sb, cb, sg, cg = math.sin(b), math.cos(b), math.sin(g), math.cos(g)
    return np.array([[-sb * cg, sg, 0.0],
                     [-sb * sg, -cg, 0.0],
                     [-cb, 0.0, -1.0]])


def edot_qd(b, g, ad, bd, gd):
    """Ė (α̇, β̇, γ̇)."""
    sb, cb, sg, cg = math.sin(b), math.cos(b), math.sin(g), math.cos(g)
    di = np.array([cb * cg * bd - sb * sg * gd, cb * sg * bd + sb * cg * gd, -sb * bd])
    de2 = np.array([-cg * gd, -sg * gd, 0.0])
    return -(di * ad + de2 * bd)


class Knee:
    def __init__(self, scene_path):
        scene = yaml.safe_load(open(scene_path))
        params = yaml.safe_load(open(os.path.join(os.path.dirname(scene_path), scene["parameter_set"])))
        self.m = params["body"]["mass_kg"]
        self.I = np.array(params["body"]["principal_inertia_kg_m2"])
        g = params["gravity"]
        self.W = self.m * g["magnitude_m_s2"] * np.array(g["direction_F"])
        self.A = scene["pulse"]["amplitude_N"]
        self.t0 = scene["pulse"]["duration_s"]
        assert scene["pulse"]["shape"] == "reconstructed" and scene["ligament_law"] == "published"
        self.contacts = []
        for name in ("medial", "lateral"):
            c = params["compartments"][name]
            fs, ts = c["femoral_surface"], c["tibial_surface"]
            s = math.sqrt(1.0 + ts["slope_x"] ** 2)
            self.contacts.append(dict(name=name, r=fs["radius_mm"] * MM, C=np.array(fs["centre_mm"]) * MM,
                                      n=np.array([-ts["slope_x"], 0.0, 1.0]) / s, d=ts["offset_mm"] * MM / s))
        ligs = params["ligaments"]
        self.names = [l["name"] for l in ligs]
        self.A_F = np.array([l["femoral_mm"] for l in ligs]) * MM
        self.B_T = np.array([l["tibial_mm"] for l in ligs]) * MM
        self.k_lin = np.array([l["k_linear_N_mm"] for l in ligs]) * 1e3   # N/m
        self.k_par = np.array([l["k_parabolic_N_mm2"] for l in ligs]) * 1e6  # N/m²
        e = np.array([l["extension_ratio"] for l in ligs])
        # Reference pose (§6): α = 0, β = π/2, γ = 0 (R = I), y0 given, x0 and z0 from the
        # two gaps φ_i = n̂′·(C − R0) − d − r = 0 (linear in x0, z0).
        rp = params["reference_pose"]
        y0 = rp["y0_mm"] * MM
        M2 = np.array([[c["n"][0], c["n"][2]] for c in self.contacts])
        rhs = np.array([c["n"] @ c["C"] - c["d"] - c["r"] - c["n"][1] * y0 for c in self.contacts])
        x0, z0 = np.linalg.solve(M2, rhs)
        self.q_ref = np.array([x0, y0, z0, 0.0, math.pi / 2, 0.0])
        L_ref = np.linalg.norm(self.A_F - (self.q_ref[:3] + self.B_T), axis=1)
        self.L0 = L_ref / e
        self.evals = 0

    def pulse(self, t):
        s = t / self.t0
        return self.A * s * math.sin(2 * math.pi * s) * math.exp(-4.73 * s) if t >= 0 else 0.0

    def strains(self, q):
        R = rot(*q[3:])
        L = np.linalg.norm(self.A_F - (q[:3] + self.B_T @ R.T), axis=1)
        return (L - self.L0) / self.L0

    def accel(self, t, y, linear):
        """q̈ and the normal forces N (both contacts active), ligament branches held:
        linear[j] True = linear region, else toe (or slack)."""
        self.evals += 1
        q, qd = y[:6], y[6:]
        R = rot(*q[3:])
        E = emap(q[4], q[5])
        w = E @ qd[3:]
        # Ligaments (§5): force on the tibia at B towards the femur.
        B = q[:3] + self.B_T @ R.T
        D = self.A_F - B
        L = np.linalg.norm(D, axis=1)
        ext = L - self.L0
        F = np.where(linear, self.k_lin * (L - (1 + EPS1) * self.L0), np.where(ext > 0, self.k_par * ext * ext, 0.0))
        u = D / L[:, None]
        f_F = (F[:, None] * u).sum(axis=0)
        M_T = np.cross(self.B_T, (F[:, None] * u) @ R).sum(axis=0)
        # Loads (§7, §8): weight and the pulse along −y′ at the centre of mass.
        f_F = f_F + self.W + R @ np.array([0.0, -self.pulse(t), 0.0])
        Q = np.concatenate([f_F, M_T - np.cross(w, self.I * w)])
        # Hidden constraint φ̈ = G ν̇ + κ = 0, ν = (Ṙ0 in F, ω′); contact force −N n.
        G = np.zeros((2, 6))
        kappa = np.zeros(2)
        for i, c in enumerate(self.contacts):
            n = R @ c["n"]
            dT = R.T @ (c["C"] - q[:3])
            ndot = R @ np.cross(w, c["n"])
            G[i, :3] = -n
            G[i, 3:] = np.cross(c["n"], dT)
            kappa[i] = np.cross(w, np.cross(w, c["n"])) @ dT - 2.0 * ndot @ qd[:3]
        Mdiag = np.concatenate([[self.m] * 3, self.I])
        K = np.zeros((8, 8))
        K[:6, :6] = np.diag(Mdiag)
        K[:6, 6:] = -G.T
        K[6:, :6] = G
        sol = np.linalg.solve(K, np.concatenate([Q, -kappa]))
        nu_dot, N = sol[:6], sol[6:]
        qdd = np.empty(6)
        qdd[:3] = nu_dot[:3]
        qdd[3:] = np.linalg.solve(E, nu_dot[3:] - edot_qd(q[4], q[5], *qd[3:]))
        return qdd, N

    def liftoff_time(self, rtol, atol, method="DOP853"):
        """Lateral (or first) lift-off time of the two-contact phase, from rest at q_ref."""
        y = np.concatenate([self.q_ref, np.zeros(6)])
        t = 0.0
        linear = self.strains(y[:6]) > 2 * EPS1
        self.evals = 0
        restarts = 0
        while True:
            def rhs(t, y, linear=linear):
                qdd, _ = self.accel(t, y, linear)
                return np.concatenate([y[6:], qdd])

            events = []
            for i in range(2):
                ev = (lambda t, y, i=i, linear=linear: self.accel(t, y, linear)[1][i])
                ev.terminal, ev.direction = True, -1
                events.append(ev)
            for j in range(len(self.L0)):
                ev = (lambda t, y, j=j: self.strains(y[:6])[j] - 2 * EPS1)
                ev.terminal, ev.direction = True, (-1 if linear[j] else 1)
                events.append(ev)
            sol = solve_ivp(rhs, (t, 1.0), y, method=method, rtol=rtol, atol=atol, events=events)
            hit = [k for k, te in enumerate(sol.t_events) if len(te)]
            if not hit:
                raise RuntimeError("no lift-off before t = 1 s: " + sol.message)
            k = min(hit, key=lambda k: sol.t_events[k][0])
            t, y = sol.t_events[k][0], sol.y_events[k][0]
            if k < 2:
                return t, self.contacts[k]["name"], self.evals, restarts
            linear = linear.copy()
            linear[k - 2] = not linear[k - 2]
            restarts += 1


# ---------------------------------------------------------------- measurement

def digits(t, ref):
    return math.inf if t == ref else -math.log10(abs(t - ref) / ref)


# ---------------------------------------------------------------- fairness manifest

def scipy_component():
    """SciPy's entry of the fairness manifest (context.components): its version, where it came
    from (the Debian package when dpkg has it) and how it was compiled, as far as SciPy's own
    build configuration (scipy.show_config) records it: compilers, no optimization flags."""
    import subprocess
    import scipy
    try:
        deb = subprocess.run(["dpkg-query", "-W", "-f=${Version}", "python3-scipy"], capture_output=True,
                             text=True, check=False).stdout.strip()
    except OSError:
        deb = ""
    origin = ("Debian 12 binary package python3-scipy %s (shared)" % deb if deb
              else "not a Debian package (%s)" % os.path.dirname(scipy.__file__))
    try:
        config = scipy.show_config(mode="dicts")
    except (TypeError, ValueError):  # SciPy before 1.10: no dict form
        config = {}
    parts = []
    for lang, c in sorted(config.get("Compilers", {}).items()):
        if isinstance(c, dict) and c.get("version"):
            parts.append("%s: %s %s" % (lang, c.get("name", lang), c["version"]))
    for dep, c in sorted(config.get("Build Dependencies", {}).items()):
        if isinstance(c, dict) and c.get("found"):
            parts.append("%s %s" % (c.get("name", dep), c.get("version", "")))
    flags = "; ".join(parts) + "; " if parts else ""
    flags += ("optimization flags not recorded in SciPy's build config: as built by Debian (dpkg-buildflags: -O2)"
              if deb else "optimization flags not recorded in SciPy's build config")
    return {"name": "SciPy", "version": scipy.__version__, "origin": origin, "compile_flags": flags}


def components(kn):
    """context.components of the side-by-side JSON: the kneedyn build it ran (kn.build_manifest(),
    formulations/version.hpp), then SciPy."""
    return list(kn.build_manifest()) + [scipy_component()]


def side_by_side_json(kn, rows, t_ref, repeats, provenance=None):
    """The --json document: the fairness manifest in context.components (as work_precision's
    and simbody_work_precision's files have it), one result per timed run, and the
    provenance {command, commit, date} the recorded files carry (record_sweep.provenance)."""
    return {"provenance": provenance or {},
            "context": {"components": components(kn), "scene": "chapter_impact",
                        "reference_liftoff_lateral_s": t_ref, "repeats": repeats},
            "results": [{"run": who, "tolerance": tol, "liftoff_lateral_s": t, "digits": d, "cpu_time_s": sec}
                        for who, tol, t, d, sec in rows]}


def best_time(f, repeats):
    best, out = math.inf, None
    for _ in range(repeats):
        t0 = time.process_time()
        out = f()
        best = min(best, time.process_time() - t0)
    return best, out


def kneedyn_liftoff(kn, scene, formulation, **opts):
    r = kn.run(scene, formulation, **opts)
    e = r.event("liftoff_")
    return e.time if e else math.nan


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="fewer tolerances, one repeat")
    ap.add_argument("--check-digits", type=float, default=None,
                    help="exit 1 unless SciPy's tightest run agrees with the reference to this many digits")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--json", default=None, help="also write the runs and the fairness manifest to this JSON file")
    a = ap.parse_args()
    # Checked before the runs (the repository's exit-code rule: 2, nothing written).
    if not 1 <= a.repeats <= 100:
        ap.error(f"--repeats = {a.repeats}: must be in [1, 100]")
    if a.check_digits is not None and not 0.0 <= a.check_digits <= 17.0:
        ap.error(f"--check-digits = {a.check_digits}: must be in [0, 17]")
    if a.json and (os.path.isdir(a.json) or not os.path.isdir(os.path.dirname(os.path.abspath(a.json)))):
        ap.error(f"--json = '{a.json}': a directory, or its directory does not exist")
    repeats = 1 if a.quick else a.repeats
    try:
        import kneedyn as kn
    except ImportError:
        print("kneedyn Python module not found: PYTHONPATH=build/python", file=sys.stderr)
        return 2
    scene_path = os.path.join(ROOT, "reference-data", "scenes", "chapter_impact.yaml")
    scene = kn.load_scene(scene_path)
    import json
    ref = json.load(open(os.path.join(ROOT, "reference-data", "references", "chapter_impact.json")))
    t_ref = [e["time_s"] for e in ref["solution"]["events"] if e["name"] == "liftoff_lateral"][0]
    print("reference: %s: lateral lift-off t = %.15f s" % (ref["generator"], t_ref))
    t_ggl = kneedyn_liftoff(kn, scene, "dae-ggl", rtol=1e-11, atol=1e-13)
    print("kneedyn dae-ggl rtol 1e-11:  t = %.15f s, %.2f digits from the reference" % (t_ggl, digits(t_ggl, t_ref)))

    rows = []
    print("\n%-34s %10s %22s %7s %10s" % ("run", "tolerance", "lift-off t (s)", "digits", "time (s)"))

    def record(who, tol, f):
        sec, (t, extra) = best_time(f, repeats)
        d = digits(t, t_ref)
        rows.append((who, tol, t, d, sec))
        print("%-34s %10.0e %22.15f %7.2f %10.5f  %s" % (who, tol, t, d, sec, extra))

    knee = Knee(scene_path)
    scipy_tols = [1e-6, 1e-8, 1e-10, 1e-12] if a.quick else [1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-11, 1e-12, 1e-13]
    for tol in scipy_tols:
        def f(tol=tol):
            t, which, evals, restarts = knee.liftoff_time(tol, tol * 1e-2)
            assert which == "lateral", which
            return t, "rhs evals %d, restarts %d" % (evals, restarts)
        record("scipy DOP853", tol, f)
    kn_cfgs = [("ede", "cvode-adams"), ("dae", ""), ("mde", "cvode-adams")]
    kn_tols = [1e-6, 1e-8, 1e-10] if a.quick else [1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-11]
    for form, integ in kn_cfgs:
        for tol in kn_tols:
            def f(form=form, integ=integ, tol=tol):
                return kneedyn_liftoff(kn, scene, form, rtol=tol, atol=tol * 1e-2, integrator=integ), ""
            record("kneedyn %s %s" % (form, integ), tol, f)

    print("\ntime to accuracy (fastest run reaching the digits; whole run to 90 deg for kneedyn, "
          "to lift-off for SciPy):")
    ok = True
    for need in (6, 8):
        best = {}
        for who, tol, t, d, sec in rows:
            side = "scipy" if who.startswith("scipy") else "kneedyn"
            if d >= need and (side not in best or sec < best[side][4]):
                best[side] = (who, tol, t, d, sec)
        if "scipy" in best and "kneedyn" in best:
            s, k = best["scipy"], best["kneedyn"]
            print("  %d digits: SciPy %.4f s (%s rtol %.0e), kneedyn %.5f s (%s rtol %.0e): ratio %.0f" %
                  (need, s[4], s[0], s[1], k[4], k[0], k[1], s[4] / k[4]))
        else:
            print("  %d digits: not reached by %s" % (need, " and ".join(x for x in ("scipy", "kneedyn") if x not in best)))
    if a.json:
        with open(a.json, "w") as f:
            json.dump(side_by_side_json(kn, rows, t_ref, repeats, recorded_provenance(__file__, sys.argv[1:])), f,
                      indent=1)
        print("wrote %s" % a.json)
    print("\ncomponents:")
    for c in components(kn):
        print("  %-9s %-8s %s; %s" % (c["name"], c["version"], c["origin"], c["compile_flags"]))
    tight = [r for r in rows if r[0].startswith("scipy")][-1]
    print("\nSciPy's tightest run agrees with the kneedyn reference to %.2f digits" % tight[3])
    if a.check_digits is not None and not tight[3] >= a.check_digits:
        print("FAILED: fewer than %.1f digits" % a.check_digits)
        ok = False
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
