#!/usr/bin/env python3
"""Worked example (docs/python.md): the chapter's impact with and without the ACL.

Loads the chapter scene, removes the two ACL elements in Python (no file is written),
runs the reference DAE and the minimal ODE (mde, dopri5) on both knees, plots flexion
against time and the PCL force against flexion, and compares the lift-off angles.

    PYTHONPATH=build/python /usr/bin/python3 examples/python/remove_acl.py --out out/remove_acl
"""
import argparse
import os
import sys

import matplotlib
matplotlib.use("Agg")
import matplotlib.pyplot as plt

try:
    import kneedyn
except ImportError as e:
    print(f"remove_acl: error: the kneedyn module is not importable ({e}); "
          "run with PYTHONPATH=build/python or install it (docs/python.md)", file=sys.stderr)
    sys.exit(2)

RUNS = [("dae", dict(rtol=1e-8, atol=1e-10)), ("mde", dict(integrator="dopri5", rtol=1e-8, atol=1e-10))]


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", default="out/remove_acl", help="directory for remove_acl.png")
    args = ap.parse_args()
    try:
        os.makedirs(args.out, exist_ok=True)
    except OSError as e:
        ap.error(f"--out = '{args.out}': cannot be created ({e.strerror or e})")

    intact = kneedyn.load_scene(kneedyn.scene_path("chapter_impact"))
    acl_deficient = intact.copy()
    removed = acl_deficient.remove_ligaments("ACL")
    print("removed:", ", ".join(removed), "->", len(acl_deficient.ligaments), "elements left")

    fig, (ax_t, ax_f) = plt.subplots(1, 2, figsize=(11, 4.2))
    print("%-14s %-4s %-10s %14s %12s %8s" % ("knee", "form", "status", "lift-off (deg)", "t_90 (s)", "steps"))
    liftoff = {}
    for label, scene in (("intact", intact), ("ACL removed", acl_deficient)):
        for formulation, options in RUNS:
            r = kneedyn.run(scene, formulation, **options)
            t = r.trajectory
            lo = r.event("liftoff")
            end = r.event("flexion_90")
            liftoff[(label, formulation)] = lo.flexion_deg if lo else None
            print("%-14s %-4s %-10s %14s %12s %8d" % (
                label, formulation, r.status, "%.4f" % lo.flexion_deg if lo else "none",
                "%.6f" % end.time if end else "-", r.statistics["steps"]))
            style = "-" if formulation == "dae" else "--"
            ax_t.plot(t["time_s"], t["flexion_deg"], style, label="%s, %s" % (label, formulation))
            pcl = t["F_PCL_anterior_N"] + t["F_PCL_posterior_N"]
            ax_f.plot(t["flexion_deg"], pcl, style, label="%s, %s" % (label, formulation))
    ax_t.set(xlabel="time (s)", ylabel="flexion (deg)", title="Flexion")
    ax_f.set(xlabel="flexion (deg)", ylabel="PCL force, both bundles (N)", title="PCL force against flexion")
    for ax in (ax_t, ax_f):
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    fig.tight_layout()
    png = os.path.join(args.out, "remove_acl.png")
    fig.savefig(png, dpi=110)
    print("wrote", png)

    for label in ("intact", "ACL removed"):
        a, b = liftoff[(label, "dae")], liftoff[(label, "mde")]
        if a is not None and b is not None:
            print("%s: lift-off dae %.4f deg, mde %.4f deg, difference %.2e deg" % (label, a, b, a - b))
    a, b = liftoff[("intact", "dae")], liftoff[("ACL removed", "dae")]
    if a is not None and b is not None:
        print("removing the ACL moves the lift-off by %+.3f deg (dae)" % (b - a))


if __name__ == "__main__":
    main()
