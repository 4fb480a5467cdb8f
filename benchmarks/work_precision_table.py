#!/usr/bin/python3
"""Fastest run reaching scd 4/6/8/10, per method, from work-precision JSON files
(benchmarks/README.md, "Work-precision sweep").

    build/benchmarks/work_precision --rtol-min 1e-13 --json wp.json
    /usr/bin/python3 benchmarks/work_precision_table.py wp.json [MORE.json ...]
    /usr/bin/python3 benchmarks/work_precision_table.py ISWEEP.json --cost instructions [--efficiency EFF.json]

Reads the full sweep (benchmarks/recorded/), the short one (`work_precision --short`) and
a short one with Simbody's methods merged in (`simbody_work_precision --merge`). A method is
formulation[:integrator][/stabilization]. A run counts when the report's diagrams plot it
(reports/bench_data.py: status ok, an scd, every reference event and no other, each event
within 1 ms); the others are counted in the column "failed / wrong event". Prints one
markdown table per file: median CPU time (s) and the setting of the cheapest counted run
reaching each threshold, '—' if none. --efficiency EFF.json (benchmarks/efficiency.py
--json) adds the column "efficiency": the share of the instructions of the scd ≥ 6 run spent
in the model's residual / right-hand side, and in all model callbacks; the file must have
chosen its runs by the table's cost (its "cost"; exit 2 otherwise). --cost instructions
(files of benchmarks/instruction_sweep.py) picks and prints each cell by the instructions of
RunScene instead of CPU time: a cost that does not drift between recordings.
"""
import math
import os
import sys

sys.dont_write_bytecode = True  # keep the source tree clean
sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "reports"))
from bench_data import load_bench, method_of, scd_ceiling, split_runs  # noqa: E402
import tool_input  # noqa: E402
from tool_input import BadInput  # noqa: E402

THRESHOLDS = (4, 6, 8, 10)


def setting_of(r):
  s = r.get("setting", {})
  for key, name in (("step", "h"), ("rtol", "rtol"), ("accuracy", "accuracy")):
    if key in s:
      return f"{name}={s[key]:g}" if key == "step" else f"{name}={s[key]:.2g}"
  return "?"


def cost_of(r, cost):
  """The run's cost by `cost` ("cpu": median CPU s, printed in ms; "instructions": of RunScene), None if absent."""
  v = r.get("cpu_s") if cost == "cpu" else r.get("instructions")
  return v if isinstance(v, (int, float)) else None


def cell(r, cost):
  # CPU in ms to 3 significant digits: whole milliseconds to 3 decimals of a second tied
  # methods 1.7 and 2.4 ms apart.
  return (f"{r['cpu_s'] * 1e3:.3g}" if cost == "cpu" else f"{r['instructions'] / 1e6:.1f} M") + f" ({setting_of(r)})"


def rows(runs, cost="cpu"):
  """[method, runs, failed / wrong event, best scd, cell per threshold] in order of appearance."""
  ok, failed = split_runs(runs)
  methods = list(dict.fromkeys(method_of(r) for r in runs))
  out = []
  for m in methods:
    mine = [r for r in ok if method_of(r) == m]
    n_failed = sum(method_of(r) == m for r, _ in failed)
    best = max((r["scd"] for r in mine), default=math.nan)
    # An scd above the reference's ceiling (bench_data.scd_ceiling) is the reference's error:
    # marked "*", see the note under the table.
    best_flag = "*" if any(r.get("above_ceiling") and r["scd"] == best for r in mine) else ""
    cells = []
    for t in THRESHOLDS:
      reach = [r for r in mine if r["scd"] >= t and cost_of(r, cost) is not None]
      if not reach:
        cells.append("—")
        continue
      cells.append(cell(min(reach, key=lambda r: cost_of(r, cost)), cost))
    # +inf: an exact result in a file that states no ceiling (bench_data.flag_above_ceiling).
    shown = "—" if math.isnan(best) else "exact*" if best == math.inf else f"{best:.2f}{best_flag}"
    out.append([m, str(len(mine) + n_failed), str(n_failed), shown]
               + cells)
  return out


def efficiency_cell(eff, method):
  e = (eff or {}).get("methods", {}).get(method)
  if not e:
    return "—"
  return f"{100 * e['residual_share']:.0f} % ({100 * e['callback_share']:.0f} %)"


def table(path, eff=None, cost="cpu"):
  header, runs = tool_input.checked(load_bench, "WORK_PRECISION.json", path)
  if cost == "instructions" and not any(isinstance(r.get("instructions"), int) for r in runs):
    raise BadInput(f"--cost instructions: '{path}' has no instruction counts "
                   "(benchmarks/instruction_sweep.py writes them)")
  unit = "CPU ms" if cost == "cpu" else "instructions of RunScene"
  extra = " efficiency at scd ≥ 6: residual / rhs (all model callbacks) |" if eff else ""
  lines = ["| method | runs | failed / wrong event | best scd | "
           + " | ".join(f"scd ≥ {t}: {unit} (setting)" for t in THRESHOLDS) + " |" + extra,
           "|---|---|---|---|" + "---|" * len(THRESHOLDS) + ("---|" if eff else "")]
  body = rows(runs, cost)
  lines += ["| " + " | ".join(r + ([efficiency_cell(eff, r[0])] if eff else [])) + " |" for r in body]
  ceiling = scd_ceiling(header)
  if ceiling is not None:
    lines.append("")
    accuracy = header.get("reference_accuracy_scd")
    from_accuracy = isinstance(accuracy, (int, float)) and abs(ceiling - (accuracy - 1.0)) < 1e-9
    why = ("the reference's accuracy minus one digit" if from_accuracy else
           f"the file's own scd_ceiling, below the reference's accuracy minus one digit"
           + (f" ({accuracy - 1.0:.1f})" if isinstance(accuracy, (int, float)) else "")
           + ": the limit of how its runs were scored")
    lines.append(f"Reference ceiling: scd {ceiling:.1f} (the highest scd the file's scores can measure: {why}); "
                 + ("* above it: the limit of the comparison (the reference, or a result CSV's 12 printed "
                    "digits: the reference's own samples printed so score 11.34 on chapter_impact), not the method's error."
                    if any(r[3].endswith("*") for r in body) else "no best scd above it."))
  return lines


def load_efficiency(path, cost):
  """benchmarks/efficiency.py --json's file, checked field by field; its runs must have been
  chosen by `cost`, the table's."""
  eff = tool_input.json_object("--efficiency", path)
  where = f"--efficiency = '{tool_input.echo(path)}'"
  methods = eff.get("methods")
  if not isinstance(methods, dict) or not methods:
    raise BadInput(f"{where}: methods = {tool_input.echo(methods)}: must be an object of methods "
                   "(benchmarks/efficiency.py --json writes it)")
  for m, e in methods.items():
    if not isinstance(e, dict):
      raise BadInput(f"{where}: methods.{m} = {tool_input.echo(e)}: must be an object")
    for k in ("residual_share", "callback_share"):
      v = e.get(k)
      if not (isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)):
        raise BadInput(f"{where}: methods.{m}.{k} = {tool_input.echo(v)}: must be a finite number")
  # The column is the efficiency of the runs in the scd ≥ 6 cells: efficiency.py picked
  # them by its cost (files without the field: by CPU time), which must be the table's.
  eff_cost = eff.get("cost", "cpu")
  if eff_cost not in ("cpu", "instructions"):
    raise BadInput(f"{where}: cost = {tool_input.echo(eff_cost)}: must be cpu or instructions")
  if eff_cost != cost:
    raise BadInput(f"{where}: its runs were chosen by {eff_cost}, this table's cells by {cost} "
                   f"(use --cost {eff_cost}, or re-run efficiency.py --cost {cost})")
  return eff


def print_tables(paths, eff=None, cost="cpu"):
  tables = [table(path, eff, cost) for path in paths]  # every file read before any output
  for i, (path, lines) in enumerate(zip(paths, tables)):
    if len(paths) > 1:
      print(("\n" if i else "") + f"{path}:\n")
    print("\n".join(lines))


USAGE = ("usage: work_precision_table.py WORK_PRECISION.json [MORE.json ...] [--efficiency EFF.json] "
         "[--cost cpu|instructions]")


def option(args, name):
  """Removes `name VALUE` from args and returns VALUE (None when absent)."""
  if name not in args:
    return None
  k = args.index(name)
  if k + 1 >= len(args) or args[k + 1].startswith("--"):
    raise BadInput(f"{name} needs a value\n{USAGE}")
  value = args[k + 1]
  del args[k:k + 2]
  return value


def main(argv=None):
  args = list(sys.argv[1:] if argv is None else argv)
  if "--help" in args or "-h" in args:
    print(USAGE)
    print(__doc__)
    return 0
  eff_path = option(args, "--efficiency")
  cost = option(args, "--cost") or "cpu"
  if cost not in ("cpu", "instructions"):
    raise BadInput(f"--cost = '{tool_input.echo(cost)}': expected cpu or instructions")
  unknown = [a for a in args if a.startswith("--")]
  if unknown:
    raise BadInput(f"{unknown[0]}: unknown option\n{USAGE}")
  if not args:
    raise BadInput(f"no work-precision file given\n{USAGE}")
  for p in args:
    tool_input.existing_file("WORK_PRECISION.json", p)
  eff = load_efficiency(eff_path, cost) if eff_path is not None else None
  print_tables(args, eff, cost)
  return 0


if __name__ == "__main__":
  sys.exit(tool_input.exit_code("work_precision_table", main))
