#!/usr/bin/python3
"""simbody_work_precision --merge on a planted sweep file: the file it writes says how it was
made and which rows it timed itself.

  simbody_merge_test.py SIMBODY_WORK_PRECISION

Checks: header.command is the command line given; header.merged_from keeps the merged
file's header and context (its git_commit); only the row timed in this run carries
`engine`: the copied rows do not, even one that carried `engine` in the planted file (a
file merged before); the copied rows are all there, a method measured here with another
stabilization among them; the kneedyn/Simbody ratio is null when no Simbody method ran. Exit 0 when every check holds, 1
otherwise, 2 on bad arguments.
"""
import json
import os
import subprocess
import sys
import tempfile


def row(form, integ, engine=None, stabilization=None):
  r = {"formulation": form, "integrator": integ, "setting": {"rtol": 1e-6, "atol": 1e-8}, "status": "ok",
       "reason": "", "metrics": {"scd": 4.0}, "cpu_time_s": {"median": 0.01}}
  if stabilization:
    r["setting"]["stabilization"] = stabilization
  if engine:
    r["engine"] = engine
  return r


def main():
  if len(sys.argv) != 2 or not os.access(sys.argv[1], os.X_OK):
    print("usage: simbody_merge_test.py SIMBODY_WORK_PRECISION", file=sys.stderr)
    return 2
  errors = []
  with tempfile.TemporaryDirectory(prefix="kneedyn_simbody_merge_") as tmp:
    merged, out = os.path.join(tmp, "wp.json"), os.path.join(tmp, "peer.json")
    with open(merged, "w") as f:
      json.dump({"header": {"mode": "short", "repetitions": 3, "date": "2026-01-01T00:00:00Z"},
                 "context": {"git_commit": "feedbeef0001"},
                 "results": [row("dae-reduced", ""), row("simbody", "rk2", engine="simbody"), row("ede", "dopri5"),
                             row("ede", "dopri5", stabilization="projection")]}, f)
    cmd = [sys.argv[1], "--short", "--only", "ede/dopri5/rtol=1e-08", "--repetitions", "1", "--merge", merged,
           "--json", out]
    p = subprocess.run(cmd, capture_output=True, text=True, timeout=240)
    if p.returncode != 0:
      print(f"simbody_merge_test: exit {p.returncode}: {p.stderr[-500:]}", file=sys.stderr)
      return 1
    with open(out, encoding="utf-8") as f:
      doc = json.load(f)
    h = doc["header"]
    if h.get("command", "").split() != cmd:
      errors.append(f"header.command {h.get('command')!r} is not the command given {' '.join(cmd)!r}")
    if not isinstance(h.get("scd_ceiling"), (int, float)):  # the reference's accuracy_scd − 1, as work_precision's
      errors.append(f"header.scd_ceiling {h.get('scd_ceiling')!r}: not a number")
    mf = h.get("merged_from") or {}
    if (mf.get("header") or {}).get("repetitions") != 3 or (mf.get("context") or {}).get("git_commit") != "feedbeef0001":
      errors.append(f"merged_from lacks the merged file's header or context: {mf}")
    timed = [(r["formulation"], r["integrator"]) for r in doc["results"] if r.get("engine")]
    if timed != [("ede", "dopri5")]:
      errors.append(f"rows with engine (timed here): {timed}, expected only the ede dopri5 run")
    # The plain ede dopri5 is measured here and replaced; ede dopri5 with projection is another
    # method and is copied (it had been dropped with the plain one).
    copied = sorted((r["formulation"], r["integrator"], r["setting"].get("stabilization", "none"))
                    for r in doc["results"] if not r.get("engine"))
    if copied != [("dae-reduced", "", "none"), ("ede", "dopri5", "projection"), ("simbody", "rk2", "none")]:
      errors.append(f"copied rows: {copied}")
    # No Simbody method ran: the ratio is null, not 0 (kneedyn's time over an infinite one).
    ratio = (doc.get("ratio_kneedyn_over_simbody") or {}).get("scd6") or {}
    if ratio.get("ratio") is not None or ratio.get("simbody_cpu_s") is not None:
      errors.append(f"ratio at scd 6 without a Simbody run: {ratio}")
  # Its command line is the suite's (solver/internal/command_line.hpp): --help exits 0; an
  # unknown argument, an empty value or 0 repetitions exit 2 naming it, and write nothing.
  p = subprocess.run([sys.argv[1], "--help"], capture_output=True, text=True, timeout=60)
  if p.returncode != 0 or "--merge" not in p.stdout:
    errors.append(f"--help: exit {p.returncode}, {p.stdout[:200]!r}")
  with tempfile.TemporaryDirectory(prefix="kneedyn_simbody_args_") as tmp:
    for args, needle in ((["--bogus"], "--bogus"), (["--repetitions", "0"], "--repetitions"),
                         (["--only", ""], "--only = ''")):
      out = os.path.join(tmp, "peer.json")
      p = subprocess.run([sys.argv[1], *args, "--json", out], capture_output=True, text=True, timeout=60)
      if p.returncode != 2 or not p.stderr.startswith("simbody_work_precision: error: ") or needle not in p.stderr \
         or os.path.exists(out):
        errors.append(f"{args}: exit {p.returncode}, {p.stderr.strip()[:200]!r}")
  for e in errors:
    print("simbody_merge_test: FAIL:", e, file=sys.stderr)
  print(f"simbody_merge_test: {len(errors)} failure(s)")
  return 1 if errors else 0


if __name__ == "__main__":
  sys.exit(main())
