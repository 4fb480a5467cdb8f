#!/usr/bin/python3
"""Global sensitivity (ensembles/README.md): first-order and total Sobol' indices with bootstrap
confidence intervals from a Saltelli sweep (`kneedyn sweep`, design type saltelli), computed
with OpenTURNS (Debian python3-openturns), and a ranked bar chart per outcome.

  global_sensitivity.py --sweep DIR/sweep.csv --spec SPEC.yaml --out OUTDIR
                        [--outcomes COL ...] [--bootstrap 300] [--confidence 0.95]
                        [--estimator saltelli|jansen|martinez|mauntz-kucherenko] [--seed 1]
                        [--local SENSITIVITY.json] [--no-charts]

--local takes the sensitivity.json of `kneedyn sensitivity` at the nominal point for the same
parameters and outcomes; each outcome then also gets the local normalized sensitivity p/y
dy/dp and the first-order index a linear model would have,
S_lin,k = (dy/dp_k sigma_k)^2 / sum_j (dy/dp_j sigma_j)^2, with sigma_k the standard deviation
of parameter k in the sweep's own samples. Where S_1 and S_lin agree the outcome is close to
linear over the ranges; where they differ, the local derivative would mislead.

Writes OUTDIR/sobol.json and OUTDIR/sobol_<outcome>.png (one chart per outcome whose indices
were computed; --no-charts draws none, and sobol.json then names no chart). The report shows
them when they are in REPORT_OUT/global_sensitivity/ (section(), hooked into make_report.py).

Dropped groups: a base sample j is used only if all d + 2 runs of its pick-freeze group
(A_j, B_j, A_j with column k from B_j) gave a value. Two causes are counted apart: a run that
failed, and a run that completed without the outcome (a lift-off outcome when the knee
reached its end flexion on both condyles). The indices are then those of the outcome where it
exists: conditional on it, not of the whole design.
Exit status: 0 written; 2 bad input (nothing written).
"""
import argparse
import csv
import html
import json
import math
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import tool_input  # noqa: E402

ESTIMATORS = {"saltelli": "SaltelliSensitivityAlgorithm", "jansen": "JansenSensitivityAlgorithm",
              "martinez": "MartinezSensitivityAlgorithm",
              "mauntz-kucherenko": "MauntzKucherenkoSensitivityAlgorithm"}


def fail(msg):
  print(f"global_sensitivity: error: {msg}", file=sys.stderr)
  sys.exit(2)


def read_sweep(csv_path, d):
  with open(csv_path, newline="", encoding="utf-8") as f:
    rows = list(csv.reader(f))
  if not rows or not rows[0] or rows[0][0] != "index":
    fail(f"--sweep = '{csv_path}': not a kneedyn sweep.csv (first column must be 'index')")
  header = rows[0]
  if "status" not in header:
    fail(f"--sweep = '{csv_path}': no 'status' column (not a kneedyn sweep.csv)")
  status = header.index("status")
  for i, r in enumerate(rows[1:], start=2):
    if len(r) != len(header):
      fail(f"--sweep = '{csv_path}': line {i} has {len(r)} fields, the header {len(header)}")
  params = header[1:1 + d]
  outcomes = header[1 + d:status]
  X = [[float(v) for v in r[1:1 + d]] for r in rows[1:]]
  Y = {o: [float(r[1 + d + k]) if r[status] == "completed" or r[1 + d + k] != "nan" else float("nan")
           for r in rows[1:]] for k, o in enumerate(outcomes)}
  completed = [r[status] == "completed" for r in rows[1:]]
  return params, outcomes, X, Y, completed


def sobol_indices(X, y, n, d, bootstrap, confidence, estimator, seed, completed=None):
  """Indices of one outcome from the Saltelli layout (rows: A, B, A_B^1 .. A_B^d, each n).
  completed: per row, whether the run completed (None: all did)."""
  import openturns as ot
  keep = [j for j in range(n) if all(math.isfinite(y[b * n + j]) for b in range(d + 2))]
  m = len(keep)
  ran = completed if completed is not None else [True] * len(y)
  kept = set(keep)  # a failed run keeps what it reached (a lift-off before the failure): its group may stay
  with_failed = sum(1 for j in range(n) if j not in kept and not all(ran[b * n + j] for b in range(d + 2)))
  if m < 8:
    return {"status": f"only {m} complete pick-freeze groups of {n}"}
  xs = [X[b * n + j] for b in range(d + 2) for j in keep]
  ys = [[y[b * n + j]] for b in range(d + 2) for j in keep]
  values = [v[0] for v in ys]
  # One value in every run (a peak reached at t = 0, an element that never stretches): no
  # variance to apportion. Compared by spread, not by a sum of squares about the float mean,
  # which is off in its last digits and left 5e-22 for OpenTURNS to fail on.
  if max(values) - min(values) <= 1e-13 * max(abs(max(values)), abs(min(values))):
    return {"status": "no variance"}
  ot.RandomGenerator.SetSeed(seed)
  ot.ResourceMap.SetAsUnsignedInteger("SobolIndicesAlgorithm-DefaultBootstrapSize", bootstrap)
  algo = getattr(ot, ESTIMATORS[estimator])(ot.Sample(xs), ot.Sample(ys), m)
  algo.setBootstrapSize(bootstrap)
  algo.setConfidenceLevel(confidence)
  s1, st = algo.getFirstOrderIndices(), algo.getTotalOrderIndices()
  i1, it = algo.getFirstOrderIndicesInterval(), algo.getTotalOrderIndicesInterval()
  lo1, hi1, lot, hit = i1.getLowerBound(), i1.getUpperBound(), it.getLowerBound(), it.getUpperBound()
  return {"status": "ok", "groups_used": m, "groups_dropped": n - m,
          "groups_dropped_failed_run": with_failed, "groups_dropped_outcome_undefined": n - m - with_failed,
          "first_order": [s1[k] for k in range(d)], "first_order_ci": [[lo1[k], hi1[k]] for k in range(d)],
          "total": [st[k] for k in range(d)], "total_ci": [[lot[k], hit[k]] for k in range(d)]}


def read_local(path):
  """(outcome, parameter) -> (derivative, normalized) from kneedyn sensitivity's JSON."""
  if not os.path.exists(path):
    fail(f"--local = '{path}': file not found")
  try:
    with open(path) as f:
      rows = json.load(f)["rows"]
    # `normalized` is null where the outcome's value is 0 (docs/outputs.md).
    return {(r["outcome"], r["parameter"]): (float(r["derivative"]),
                                             float("nan") if r["normalized"] is None else float(r["normalized"]))
            for r in rows}
  except (OSError, ValueError, KeyError, TypeError) as e:
    fail(f"--local = '{path}': not a kneedyn sensitivity.json ({e})")


def local_beside(local, outcome, params, X, n):
  """Local derivatives of one outcome and the linearized first-order indices (see --local)."""
  d = len(params)
  rows = X[:2 * n]  # A and B: independent samples of the input distribution
  sigma = []
  for k in range(d):
    m = sum(r[k] for r in rows) / len(rows)
    sigma.append(math.sqrt(sum((r[k] - m) ** 2 for r in rows) / (len(rows) - 1)))
  deriv = [local.get((outcome, p), (float("nan"), float("nan"))) for p in params]
  if any(not math.isfinite(v[0]) for v in deriv):
    missing = [p for p, v in zip(params, deriv) if not math.isfinite(v[0])]
    return {"status": f"no local derivative for {', '.join(missing[:3])}{' ...' if len(missing) > 3 else ''}"}
  var = [(deriv[k][0] * sigma[k]) ** 2 for k in range(d)]
  total = sum(var)
  return {"status": "ok", "derivative": [v[0] for v in deriv], "normalized": [v[1] if math.isfinite(v[1]) else None for v in deriv],
          "sigma": sigma, "linear_first_order": [v / total if total > 0 else 0.0 for v in var]}


def bar_chart(path, title, params, r):
  import matplotlib
  matplotlib.use("Agg")
  import matplotlib.pyplot as plt
  order = sorted(range(len(params)), key=lambda k: -r["total"][k])
  names = [params[k] for k in order]
  fig, ax = plt.subplots(figsize=(8, 0.32 * len(params) + 1.4))
  ypos = list(range(len(order)))
  local = r.get("local", {}).get("status") == "ok"
  bars = ((-0.27, "total", "total S_T", "#c0504d"), (0.0, "first_order", "first-order S_1", "#4f81bd")) if local else \
         ((-0.2, "total", "total S_T", "#c0504d"), (0.2, "first_order", "first-order S_1", "#4f81bd"))
  height = 0.27 if local else 0.4
  for off, key, label, color in bars:
    v = [r[key][k] for k in order]
    ci = r[key + "_ci"] if key == "total" else r["first_order_ci"]
    err = [[max(0.0, v[i] - ci[k][0]) for i, k in enumerate(order)], [max(0.0, ci[k][1] - v[i]) for i, k in enumerate(order)]]
    ax.barh([p + off for p in ypos], v, height=height, xerr=err, color=color, label=label, capsize=2)
  if local:
    v = [r["local"]["linear_first_order"][k] for k in order]
    ax.barh([p + 0.27 for p in ypos], v, height=height, color="#9bbb59",
            label="S_lin from local derivatives (kneedyn sensitivity)")
  ax.set_yticks(ypos)
  ax.set_yticklabels(names, fontsize=7)
  ax.invert_yaxis()
  ax.set_xlabel("Sobol' index (bars: bootstrap confidence interval)")
  ax.set_title(title, fontsize=9)
  ax.legend(fontsize=7, loc="lower right")
  fig.tight_layout()
  fig.savefig(path, dpi=110)
  plt.close(fig)


def main(argv=None):
  ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
  ap.add_argument("--sweep", required=True, help="sweep.csv of a Saltelli sweep")
  ap.add_argument("--spec", required=True, help="the sweep's spec (YAML): parameter count and N")
  ap.add_argument("--out", required=True)
  ap.add_argument("--outcomes", nargs="*", help="outcome columns (default: all)")
  ap.add_argument("--bootstrap", type=int, default=300)
  ap.add_argument("--confidence", type=float, default=0.95)
  ap.add_argument("--estimator", default="saltelli", choices=sorted(ESTIMATORS))
  ap.add_argument("--seed", type=int, default=1)
  ap.add_argument("--no-charts", action="store_true")
  ap.add_argument("--local", help="sensitivity.json of kneedyn sensitivity at the nominal point")
  a = ap.parse_args(argv)
  import yaml
  for flag, p in (("--sweep", a.sweep), ("--spec", a.spec)):
    try:
      tool_input.existing_file(flag, p)
    except tool_input.BadInput as e:
      fail(str(e))

  def load_spec(path):
    with open(path, encoding="utf-8") as f:
      return yaml.safe_load(f)
  try:
    spec = tool_input.checked(load_spec, "--spec", a.spec)
  except tool_input.BadInput as e:
    fail(str(e))
  if not isinstance(spec, dict):
    fail(f"--spec = '{a.spec}': a YAML {type(spec).__name__}, not a sweep spec (a mapping)")
  design = spec.get("design") if isinstance(spec.get("design"), dict) else {}
  if design.get("type") != "saltelli":
    fail(f"--spec = '{a.spec}': field 'design.type' = '{design.get('type')}': Sobol' indices need a saltelli design")
  if not isinstance(spec.get("parameters"), (list, dict)) or not spec["parameters"]:
    fail(f"--spec = '{a.spec}': field 'parameters' = {tool_input.echo(spec.get('parameters'))}: must list the parameters")
  samples = design.get("samples")
  if isinstance(samples, float) and samples.is_integer():
    samples = int(samples)  # 4096.0, as kneedyn sweep reads it
  if isinstance(samples, bool) or not isinstance(samples, int) or samples < 1:
    fail(f"--spec = '{a.spec}': field 'design.samples' = {tool_input.echo(samples)}: must be a whole number >= 1")
  if not 1 <= a.bootstrap <= 100000:
    fail(f"--bootstrap = {a.bootstrap}: must be in [1, 100000]")
  if not 0.0 < a.confidence < 1.0:
    fail(f"--confidence = {a.confidence}: must be in (0, 1)")
  if not 0 <= a.seed < 2**32:
    fail(f"--seed = {a.seed}: must be in [0, 2^32)")
  try:
    tool_input.output_directory("--out", a.out)
  except tool_input.BadInput as e:
    fail(str(e))
  d, n = len(spec["parameters"]), samples
  try:
    params, outcomes, X, Y, completed = read_sweep(a.sweep, d)
  except (OSError, ValueError, IndexError, UnicodeDecodeError) as e:
    fail(f"--sweep = '{a.sweep}': not a kneedyn sweep.csv ({type(e).__name__}: {tool_input.echo(e)})")
  if len(X) != n * (d + 2):
    fail(f"--sweep = '{a.sweep}': {len(X)} rows, but the spec's Saltelli design has N (d + 2) = {n * (d + 2)}")
  chosen = a.outcomes or outcomes
  for o in chosen:
    if o not in Y:
      fail(f"--outcomes: '{o}' is not a column of {a.sweep}; columns: {', '.join(outcomes)}")
  local = read_local(a.local) if a.local else None
  os.makedirs(a.out, exist_ok=True)
  result = {"sweep": os.path.abspath(a.sweep), "spec": os.path.abspath(a.spec), "parameters": params,
            "base_samples": n, "runs": len(X), "estimator": a.estimator, "bootstrap": a.bootstrap,
            "confidence": a.confidence, "outcomes": {},
            "local": os.path.abspath(a.local) if a.local else None}
  for o in chosen:
    r = sobol_indices(X, Y[o], n, d, a.bootstrap, a.confidence, a.estimator, a.seed, completed)
    if local is not None and r["status"] == "ok":
      r["local"] = local_beside(local, o, params, X, n)
    result["outcomes"][o] = r
    if r["status"] == "ok" and not a.no_charts:
      r["chart"] = f"sobol_{o}.png"
      bar_chart(os.path.join(a.out, r["chart"]), f"{o}: Sobol' indices ({a.estimator}, N = {r['groups_used']}, "
                f"{int(100 * a.confidence)} % bootstrap CI)", params, r)
  tmp = os.path.join(a.out, "sobol.json.tmp")
  with open(tmp, "w") as f:
    json.dump(result, f, indent=1)
  os.replace(tmp, os.path.join(a.out, "sobol.json"))
  print(f"global_sensitivity: {len(chosen)} outcomes -> {os.path.join(a.out, 'sobol.json')}")
  return 0


def top(r, params, key="total", count=3):
  """The `count` parameters with the largest index `key`, with their intervals."""
  order = sorted(range(len(params)), key=lambda k: -r[key][k])[:count]
  return [(params[k], r[key][k], r[key + "_ci"][k] if key == "total" else r["first_order_ci"][k]) for k in order]


def section(outdir):
  """Report section (hooked into make_report.py): OUTDIR/global_sensitivity/sobol.json, if any."""
  path = os.path.join(outdir, "global_sensitivity", "sobol.json")
  if not os.path.exists(path):
    return ""
  with open(path) as f:
    s = json.load(f)
  e = html.escape
  parts = ["<h2 id='global-sensitivity'>Global sensitivity (Sobol' indices)</h2>",
           f"<p>Saltelli sweep of {s['runs']} runs (N = {s['base_samples']}, {len(s['parameters'])} parameters), "
           f"estimator {e(s['estimator'])} (OpenTURNS), {int(100 * s['confidence'])} % bootstrap confidence intervals "
           f"({s['bootstrap']} resamples). Ranked by total index. Source: <code>{e(s['sweep'])}</code>.</p>"]
  if s.get("local"):
    parts.append("<p>Beside them, the local derivatives at the nominal point (<code>kneedyn sensitivity</code>, CVODES "
                 "forward sensitivities): the normalized sensitivity p/y dy/dp and S_lin, the first-order index a "
                 "model linear in the parameters would have over the sweep's ranges, (dy/dp_k &sigma;_k)&sup2; / "
                 "&Sigma;_j (dy/dp_j &sigma;_j)&sup2;. S_1 &asymp; S_lin means the outcome is close to linear over the "
                 f"ranges; a gap means the local derivative alone would mislead. Source: <code>{e(s['local'])}</code>.</p>")
  for o, r in s["outcomes"].items():
    if r.get("status") != "ok":
      parts.append(f"<p>{e(o)}: {e(r.get('status'))}</p>")
      continue
    loc = r.get("local", {})
    has_local = loc.get("status") == "ok"
    params = s["parameters"]
    rows = ""
    for p, v, ci in top(r, params):
      k = params.index(p)
      c1 = r["first_order_ci"][k]
      rows += (f"<tr><td>{e(p)}</td><td>{v:.3f} [{ci[0]:.3f}, {ci[1]:.3f}]</td>"
               f"<td>{r['first_order'][k]:.3f} [{c1[0]:.3f}, {c1[1]:.3f}]</td>")
      rows += (f"<td>{loc['normalized'][k]:.3g}</td><td>{loc['linear_first_order'][k]:.3f}</td></tr>" if has_local
               else "</tr>")
    head = "<tr><th>parameter</th><th>S_T [CI]</th><th>S_1 [CI]</th>"
    head += "<th>local p/y dy/dp</th><th>S_lin</th></tr>" if has_local else "</tr>"
    note = "" if has_local or not loc else f" Local derivatives: {e(loc.get('status', ''))}."
    dropped = f"{r['groups_dropped']} dropped"
    if "groups_dropped_failed_run" in r and r["groups_dropped"]:
      dropped += (f": {r['groups_dropped_outcome_undefined']} where a completed run has no value of it (for a "
                  f"lift-off: no lift-off before the end), {r['groups_dropped_failed_run']} with a failed run; the "
                  "indices are those of the designs where it exists")
    parts.append(f"<h3>{e(o)}</h3><p>{r['groups_used']} complete groups ({dropped}). "
                 f"Top three by S_T:{note}</p><table>{head}{rows}</table>")
    if r.get("chart"):
      rel = os.path.join("global_sensitivity", r["chart"])
      parts.append(f"<figure><img src='{e(rel)}' alt='Sobol indices of {e(o)}'></figure>")
  return "\n".join(parts)


if __name__ == "__main__":
  sys.exit(main())
