#!/usr/bin/python3
"""One command for the whole chapter report: families + sensitivity runs, figures, claims, HTML.

  report.py --kneedyn PATH --out DIR [--quick] [--bench JSON] [--include DIR]... [--peer-bench JSON]
            [--hard-cases CSV] [--reconstruction [--calibrate BIN]]

Exit status: 0 when every family, sensitivity and patella run (reports/patella_section.py)
completed (possibly with a documented fallback tolerance) and the report was written; 1 when
one of them failed (the report is still written); 2 on bad input, refused before any run with
nothing written (--kneedyn not the kneedyn program, --out not a directory that can be
written, --bench / --peer-bench / --hard-cases not files of their kind, --calibrate not
executable). Runs that fail under a reading of the reconstruction study are results shown in
its table, not failures of the report.
"""
import argparse
import os
import shlex
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
sys.dont_write_bytecode = True  # keep the source tree clean
sys.path.insert(0, HERE)
import bench_data  # noqa: E402
import claims  # noqa: E402
import figures  # noqa: E402
import make_report  # noqa: E402
import patella_section  # noqa: E402
import reconstruction  # noqa: E402
import run_families  # noqa: E402
import tool_input  # noqa: E402


def main(argv=None):
  ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
  ap.add_argument("--kneedyn", required=True, help="path to the kneedyn binary")
  ap.add_argument("--out", required=True, help="output directory")
  ap.add_argument("--quick", action="store_true", help="reduced families (tests)")
  ap.add_argument("--bench", help="benchmark JSON for the work-precision diagrams")
  ap.add_argument("--peer-bench", help="work-precision JSON with Simbody's integrators beside kneedyn's "
                  "(crosscheck/simbody/simbody_work_precision --merge; the section says which rows it timed "
                  "in one process and which it copied)")
  ap.add_argument("--include", action="append", default=[], metavar="DIR",
                  help="outside solvers' results scored by kneedyn score under DIR (score.json, *.score.json), "
                  "drawn beside the --bench sweep (repeatable; examples/outside_results.sh writes them)")
  ap.add_argument("--hard-cases", help="hard_cases.csv (or .md beside it) from kneedyn_catalog")
  ap.add_argument("--reconstruction", action="store_true", help="run the reconstruction study")
  ap.add_argument("--calibrate", help="calibrate_reconstruction binary: also the Ceres calibration")
  # The command as given, for the report's Reproduction section.
  command = shlex.join([sys.executable, sys.argv[0] if argv is None else os.path.abspath(__file__)]
                       + list(sys.argv[1:] if argv is None else argv))
  args = ap.parse_args(argv)
  # Every input is checked before the long runs and before --out is made (README, "Exit codes").
  tool_input.kneedyn_executable("--kneedyn", args.kneedyn)
  tool_input.output_directory("--out", args.out)
  if args.calibrate is not None:
    tool_input.executable("--calibrate", args.calibrate)
  if args.include and not args.bench:
    raise tool_input.BadInput("--include needs --bench (the sweep the outside results are drawn beside)")
  # --bench, --peer-bench and --hard-cases read as make_report reads them.
  make_report.check_sources(args.bench, args.hard_cases, args.peer_bench)
  if args.include:  # scene and reference must match the sweep's
    header, _ = tool_input.checked(bench_data.load_bench, "--bench", args.bench)
    for d in args.include:
      try:
        bench_data.load_included(d, header.get("scene"), bench_data.reference_command(header))
      except ValueError as e:
        raise tool_input.BadInput(str(e)) from None
  steps = []  # each piece as it is run here, for the Reproduction section

  def piece(tool, tool_args):
    steps.append(shlex.join([sys.executable, os.path.join(os.path.relpath(HERE), tool)] + tool_args))
    return tool_args
  fam_args = piece("run_families.py", ["--kneedyn", args.kneedyn, "--out", args.out] + (["--quick"] if args.quick else []))
  rc = run_families.main(fam_args)
  if rc == 2 or not os.path.exists(os.path.join(args.out, "families.json")):
    return 2
  if args.reconstruction or args.calibrate:
    rec = reconstruction.main(piece("reconstruction.py", ["--kneedyn", args.kneedyn, "--out", args.out]
                                    + (["--quick"] if args.quick else [])
                                    + (["--calibrate", args.calibrate] if args.calibrate else [])
                                    + (["--calibrate-grid", "2", "--calibrate-iterations", "2"] if args.quick else [])))
    # Failed runs under a reading are findings, shown in the study's table (e.g. a reading in
    # which the knee never reaches 90°); only bad input stops the report.
    if rec == 2:
      return 2
  # The patello-femoral joint (docs/model.md §12): its runs, figures and coupling study; a
  # failed run is shown in its section and makes the exit status 1.
  pat = patella_section.main(piece("patella_section.py", ["--kneedyn", args.kneedyn, "--out", args.out]
                                   + (["--quick"] if args.quick else [])))
  if pat == 2:
    return 2
  figures.main(piece("figures.py", ["--out", args.out]))
  claims.build_claims(args.out)
  piece("claims.py", ["--out", args.out])
  piece("make_report.py", make_report.cli_args(args.out, args.bench, args.kneedyn, args.quick, args.hard_cases,
                                               args.peer_bench, args.include))
  path = make_report.make_report(args.out, args.bench, os.path.abspath(args.kneedyn), args.quick,
                                 args.hard_cases, args.peer_bench, args.include, command=command, steps=steps)
  print(f"report: {path}")
  return 1 if rc or pat else 0


if __name__ == "__main__":
  sys.exit(tool_input.exit_code("report", main))
