#!/usr/bin/env python3
"""Checks an outside solver's events.csv (name,time_s[,flexion_deg]) against the stored
reference's events (reference-data/references/SCENE.json): every reference event must be
present, and its time must agree to at least MIN_DIGITS digits, -log10(|t - t_ref| / t_ref).

    check_liftoff.py EVENTS.csv REFERENCE.json MIN_DIGITS

Exit codes: 0 every reference event within MIN_DIGITS, 1 not, 2 bad input (usage, unreadable
or malformed files).
"""
import argparse
import csv
import json
import math
import sys


def read_events(path):
    """{name: time_s} of the first row of each name."""
    got = {}
    with open(path, newline="", encoding="utf-8") as f:
        for i, r in enumerate(csv.DictReader(f), start=2):
            if r.get("name") is None or r.get("time_s") is None:
                raise ValueError(f"line {i}: needs the columns name and time_s")
            try:
                t = float(r["time_s"])
            except ValueError:
                raise ValueError(f"line {i}: time_s = '{r['time_s']}' is not a number") from None
            got.setdefault(r["name"], t)
    return got


def reference_events(path):
    """[(name, time_s)] of the reference's solution.events."""
    with open(path, encoding="utf-8") as f:
        events = json.load(f)["solution"]["events"]
    return [(str(e["name"]), float(e["time_s"])) for e in events]


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0],
                                 epilog="Exit codes: 0 every event within MIN_DIGITS, 1 not, 2 bad input.")
    ap.add_argument("events_csv", metavar="EVENTS.csv")
    ap.add_argument("reference_json", metavar="REFERENCE.json")
    ap.add_argument("min_digits", metavar="MIN_DIGITS", type=float)
    a = ap.parse_args()
    if not math.isfinite(a.min_digits):
        ap.error(f"MIN_DIGITS = {a.min_digits}: must be a finite number")
    try:
        got = read_events(a.events_csv)
    except (OSError, ValueError, UnicodeDecodeError) as e:
        ap.error(f"EVENTS.csv = '{a.events_csv}': {e}")
    try:
        expected = reference_events(a.reference_json)
    except (OSError, ValueError, KeyError, TypeError, UnicodeDecodeError) as e:
        ap.error(f"REFERENCE.json = '{a.reference_json}': not a reference with solution.events[name, time_s] "
                 f"({type(e).__name__}: {e})")
    ok = True
    for name, t_ref in expected:
        if name not in got:
            print(f"{name}: missing (events given: {sorted(got)})")
            ok = False
            continue
        err = abs(got[name] - t_ref)
        digits = math.inf if err == 0 else -math.log10(err / t_ref)
        print(f"{name}: t = {got[name]:.15g} s, reference {t_ref:.15g} s, {digits:.2f} digits "
              f"(need {a.min_digits:g})")
        ok &= digits >= a.min_digits
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
