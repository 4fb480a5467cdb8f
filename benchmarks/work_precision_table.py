#!/usr/bin/python3
"""Fastest run reaching scd 4/6/8/10, per method, from a work_precision JSON (issue 13).

    build/benchmarks/work_precision --rtol-min 1e-13 --json wp.json
    /usr/bin/python3 benchmarks/work_precision_table.py wp.json

A method is formulation[:integrator][/stabilization]; a run counts when its status is ok and
its scd (metrics.hpp, against the stored reference) reaches the threshold. Prints a
markdown table: median CPU time (s) and the setting of the cheapest such run, '—' if none.
"""
import json
import sys

THRESHOLDS = (4, 6, 8, 10)


def method_of(r):
    name = r["formulation"] + (":" + r["integrator"] if r.get("integrator") else "")
    stab = r.get("setting", {}).get("stabilization")
    return name + ("/" + stab if stab else "")


def setting_of(r):
    s = r.get("setting", {})
    return f"h={s['step']:g}" if "step" in s else f"rtol={s['rtol']:.2g}"


def main(path):
    results = json.load(open(path))["results"]
    methods = []
    for r in results:
        m = method_of(r)
        if m not in methods:
            methods.append(m)
    print("| method | best scd | " + " | ".join(f"scd ≥ {t}: CPU s (setting)" for t in THRESHOLDS) + " |")
    print("|---|---|" + "---|" * len(THRESHOLDS))
    for m in methods:
        runs = [r for r in results if method_of(r) == m and r["status"] == "ok"
                and isinstance(r.get("metrics", {}).get("scd"), (int, float))]
        best = max((r["metrics"]["scd"] for r in runs), default=float("nan"))
        cells = []
        for t in THRESHOLDS:
            ok = [r for r in runs if r["metrics"]["scd"] >= t]
            if not ok:
                cells.append("—")
                continue
            f = min(ok, key=lambda r: r["cpu_time_s"]["median"])
            cells.append(f"{f['cpu_time_s']['median']:.3f} ({setting_of(f)})")
        print(f"| {m} | {best:.2f} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit("usage: work_precision_table.py WORK_PRECISION.json")
    main(sys.argv[1])
