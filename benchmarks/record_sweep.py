#!/usr/bin/python3
"""Records a full work-precision sweep in the repository, with its provenance, for the
report's work-precision section (the main job reads the recorded file instead of sweeping).

  record_sweep.py --work-precision BIN --out FILE [-- extra work_precision arguments]
  record_sweep.py --from SWEEP.json --command "the command that wrote it" [--commit SHA] --out FILE

Writes FILE = the sweep's JSON unchanged plus a top-level "provenance": {command, commit
(git HEAD, "-dirty" when the tree had changes), date (UTC), recorded_by}. Works with either
benchmark JSON layout (work_precision's {header, results} or Google Benchmark's
{context, benchmarks}). Regenerate with `cmake --build build --target bench_record`.
Exit 2 on bad input (nothing written).
"""
import argparse
import datetime
import json
import os
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.dont_write_bytecode = True  # keep the source tree clean
sys.path.insert(0, os.path.join(ROOT, "reports"))
import tool_input  # noqa: E402
from tool_input import BadInput  # noqa: E402


def git_commit():
  try:
    head = subprocess.run(["git", "-C", ROOT, "rev-parse", "HEAD"], capture_output=True, text=True,
                          check=True).stdout.strip()
    dirty = subprocess.run(["git", "-C", ROOT, "status", "--porcelain", "--untracked-files=no"],
                           capture_output=True, text=True, check=True).stdout.strip()
    return head + ("-dirty" if dirty else "")
  except (OSError, subprocess.CalledProcessError):
    return "unknown (not a git checkout)"


def provenance(script, argv):
  """What made a recorded file: the command (the script relative to the repository, then its
  arguments), the commit (git_commit) and the UTC date, as the recorded sweeps carry them."""
  return {"command": " ".join([os.path.relpath(os.path.abspath(script), ROOT)] + list(argv)),
          "commit": git_commit(),
          "date": datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ")}


def relative_paths(x):
  """Paths inside the checkout -> relative to it (a recorded file names no machine path), also
  inside a command line (header.command holds the program and its arguments in one string)."""
  if isinstance(x, dict):
    return {k: relative_paths(v) for k, v in x.items()}
  if isinstance(x, list):
    return [relative_paths(v) for v in x]
  if isinstance(x, str) and x.startswith(ROOT + os.sep):
    x = os.path.relpath(x.split(" ")[0], ROOT) + x[len(x.split(" ")[0]):]
  if isinstance(x, str):
    return x.replace(" " + ROOT + os.sep, " ")
  return x


def main(argv=None):
  ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
  ap.add_argument("--work-precision", help="work_precision binary (runs the full sweep)")
  ap.add_argument("--from", dest="src", help="an existing sweep JSON to record instead")
  ap.add_argument("--command", help="with --from: the command that wrote it")
  ap.add_argument("--commit", help="with --from: the commit the sweep's binary was built from "
                  "(default: the checkout's HEAD)")
  ap.add_argument("--out", required=True)
  ap.add_argument("extra", nargs="*", help="arguments passed to work_precision")
  args = ap.parse_args(argv)
  if bool(args.work_precision) == bool(args.src):
    raise BadInput("give exactly one of --work-precision BIN or --from JSON")
  if args.src and not args.command:
    raise BadInput("--from needs --command (the command that wrote the sweep)")
  tool_input.output_file("--out", args.out)
  if args.work_precision:
    tool_input.executable("--work-precision", args.work_precision)
  else:
    tool_input.existing_file("--from", args.src)
  commit = args.commit if (args.src and args.commit) else git_commit()
  with tempfile.TemporaryDirectory(prefix="kneedyn_sweep_") as tmp:
    if args.work_precision:
      src = os.path.join(tmp, "sweep.json")
      cmd = [os.path.abspath(args.work_precision), "--json", src, "--csv", os.path.join(tmp, "sweep.csv")] + args.extra
      rc = subprocess.run(cmd, cwd=ROOT).returncode
      if rc != 0:
        # work_precision's exit 2 (bad input, its message above) stays 2; a failure is 1.
        print(f"record_sweep: {args.work_precision} failed (exit {rc})", file=sys.stderr)
        return 2 if rc == 2 else 1
      command = " ".join([os.path.relpath(args.work_precision, ROOT), "--json FILE"] + args.extra)
    else:
      src, command = args.src, args.command
    try:
      with open(src, encoding="utf-8") as f:
        doc = json.load(f)
    except (OSError, ValueError) as e:
      raise BadInput(f"--from = '{tool_input.echo(src)}': {tool_input.echo(e)}") from None
    if not isinstance(doc, dict) or not ("results" in doc or "benchmarks" in doc):
      raise BadInput(f"--from = '{tool_input.echo(src)}': neither a 'results' nor a 'benchmarks' array")
    for key in ("header", "context"):
      if key in doc:
        doc[key] = relative_paths(doc[key])
    doc["provenance"] = {"command": command, "commit": commit,
                         "date": datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ"),
                         "recorded_by": "benchmarks/record_sweep.py"}
    tmp_out = args.out + ".tmp"
    with open(tmp_out, "w", encoding="utf-8") as f:
      json.dump(doc, f, separators=(",", ":"))
      f.write("\n")
    os.replace(tmp_out, args.out)
  print(f"record_sweep: {args.out} ({command}, commit {commit})")
  return 0


if __name__ == "__main__":
  sys.exit(tool_input.exit_code("record_sweep", main))
