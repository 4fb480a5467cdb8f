#!/usr/bin/env python3
"""Checks an outside solver's events.csv (name,time_s[,flexion_deg]) against the stored
reference's events (reference-data/references/SCENE.json): every reference event must be
present, and its time must agree to at least MIN_DIGITS digits, -log10(|t - t_ref| / t_ref).

    check_liftoff.py EVENTS.csv REFERENCE.json MIN_DIGITS
"""
import csv
import json
import math
import sys


def main():
    events_csv, reference_json, min_digits = sys.argv[1], sys.argv[2], float(sys.argv[3])
    with open(events_csv) as f:
        got = {}
        for r in csv.DictReader(f):
            got.setdefault(r["name"], float(r["time_s"]))
    ok = True
    for e in json.load(open(reference_json))["solution"]["events"]:
        if e["name"] not in got:
            print(f"{e['name']}: missing (events given: {sorted(got)})")
            ok = False
            continue
        err = abs(got[e["name"]] - e["time_s"])
        digits = math.inf if err == 0 else -math.log10(err / e["time_s"])
        print(f"{e['name']}: t = {got[e['name']]:.15g} s, reference {e['time_s']:.15g} s, {digits:.2f} digits "
              f"(need {min_digits})")
        ok &= digits >= min_digits
    sys.exit(0 if ok else 1)


if __name__ == "__main__":
    main()
