#!/usr/bin/python3
"""Writes OUTDIR/index.html (self-contained HTML, figures referenced relatively) from the outputs
of run_families.py, figures.py and claims.py.

  make_report.py --out OUTDIR [--bench JSON] [--kneedyn PATH] [--quick]
"""
import argparse
import html
import json
import os
import sys

sys.dont_write_bytecode = True  # keep the source tree clean
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import figures  # noqa: E402
import global_sensitivity  # noqa: E402  (issue 14: Sobol' indices section)
from family_data import load_families  # noqa: E402

HERE = os.path.dirname(os.path.abspath(__file__))

CSS = """
body { font-family: -apple-system, 'Segoe UI', Helvetica, Arial, sans-serif; margin: 0 auto;
       max-width: 1300px; padding: 16px 24px; color: #222; line-height: 1.4; }
h1 { font-size: 1.6em; margin-bottom: 0.2em; } h2 { border-bottom: 1px solid #ccc; margin-top: 1.6em; }
table { border-collapse: collapse; font-size: 0.85em; width: 100%; }
th, td { border: 1px solid #ccc; padding: 4px 6px; vertical-align: top; text-align: left; }
th { background: #f0f0f0; position: sticky; top: 0; }
td.id { font-weight: bold; white-space: nowrap; }
td.verdict { white-space: nowrap; font-weight: bold; }
tr.reproduced td.verdict { background: #d8f0d8; color: #165016; }
tr.not-reproduced td.verdict { background: #f6d5d5; color: #7a1515; }
tr.not-checkable td.verdict { background: #eee; color: #555; }
figure { margin: 12px 0 24px 0; } figure img { max-width: 100%; border: 1px solid #ddd; }
figcaption { font-size: 0.9em; color: #444; }
pre { background: #f6f6f6; padding: 8px; overflow-x: auto; font-size: 0.85em; }
.warn { background: #fff4d6; border: 1px solid #e8c766; padding: 8px; }
dl.kv { display: grid; grid-template-columns: max-content auto; gap: 2px 16px; }
dl.kv dt { font-weight: bold; } dl.kv dd { margin: 0; }
nav a { margin-right: 12px; }
.grid2 { display: grid; grid-template-columns: 1fr 1fr; gap: 0 16px; }
"""


def esc(x):
  return html.escape(str(x))


def table(headers, rows, row_classes=None, cell_classes=None):
  out = ["<table><thead><tr>" + "".join(f"<th>{esc(h)}</th>" for h in headers) + "</tr></thead><tbody>"]
  for i, r in enumerate(rows):
    cls = f' class="{row_classes[i]}"' if row_classes else ""
    cells = []
    for j, c in enumerate(r):
      cc = f' class="{cell_classes[j]}"' if cell_classes and cell_classes[j] else ""
      cells.append(f"<td{cc}>{esc(c)}</td>")
    out.append(f"<tr{cls}>" + "".join(cells) + "</tr>")
  out.append("</tbody></table>")
  return "\n".join(out)


def summary_section(fam, members):
  ref = next((m for m in members if m.ok and m.amplitude_N == 100.0 and m.duration_s == 0.1), None)
  ref = ref or next((m for m in members if m.summary), None)
  parts = ["<h2 id='summary'>Summary</h2>"]
  if ref is None or ref.summary is None:
    return "\n".join(parts + ["<p class='warn'>No completed run.</p>"])
  s = ref.summary
  sc = s.get("scene", {})
  st = s.get("settings", {})
  ver = s.get("versions", {})
  kv = [("Scene", "reference-data/scenes/chapter_impact.yaml (each member generated from it with the pulse "
                  f"changed; values below from member {sc.get('name')})"),
        ("Parameter set", sc.get("parameter_set")),
        ("Ligaments / contacts", f"{sc.get('ligaments')} elements, {sc.get('contacts')} contacts, law {sc.get('ligament_law')}"),
        ("Pulse", f"{sc.get('pulse', {}).get('shape')}; amplitude family A ∈ "
                  f"{sorted({m.amplitude_N for m in members if m.family == 'amplitude'})} N at t0 = 0.1 s; "
                  f"duration family t0 ∈ {sorted({m.duration_s for m in members if m.family == 'duration'})} s at A = 100 N"),
        ("Solver", f"formulation {s.get('formulation')} (SUNDIALS IDA), rtol {st.get('rtol')}, atol {st.get('atol')}, "
                   f"output every {fam.get('output_interval_s')} s"),
        ("Reference member (A = 100 N, t0 = 0.1 s)",
         f"lateral lift-off at {ref.liftoff_deg:.3f}°, 90° reached at t = {ref.time_to_90_s:.6f} s"
         if ref.liftoff_deg is not None and ref.time_to_90_s is not None else "incomplete"),
        ("Software", f"kneedyn {s.get('kneedyn_version')}, SUNDIALS {ver.get('sundials')}, "
                     f"Ceres {ver.get('ceres')}, Eigen {ver.get('eigen')}"),
        ("Mode", "quick (reduced families, for tests)" if fam.get("quick") else "full")]
  parts.append("<dl class='kv'>" + "".join(f"<dt>{esc(k)}</dt><dd>{esc(v)}</dd>" for k, v in kv) + "</dl>")
  rows = []
  for m in members:
    status = "ok" if m.ok and not m.fallback else (
        f"reference settings failed; completed with rtol {m.fallback['rtol']}, atol {m.fallback['atol']}"
        if m.ok else f"FAILED ({m.meta.get('status')}): {m.meta.get('stderr', '')[-300:]}")
    rows.append([m.name, f"{m.amplitude_N:g}", f"{m.duration_s:g}",
                 f"{m.liftoff_deg:.3f}" if m.liftoff_deg is not None else "-",
                 f"{m.time_to_90_s:.6f}" if m.time_to_90_s is not None else "-", status])
  parts.append("<h3>Family members</h3>")
  parts.append(table(["member", "A [N]", "t0 [s]", "lateral lift-off [deg]", "t(90°) [s]", "status"], rows))
  if any(m.fallback for m in members):
    parts.append("<p class='warn'>Some members failed with the reference settings (IDA error-test failures "
                 "with |h| at hmin after lateral lift-off) and were rerun with the tolerances shown; "
                 "this is a solver finding, reported rather than hidden.</p>")
  return "\n".join(parts)


def claims_section(rows):
  n = {v: sum(r["verdict"] == v for r in rows) for v in ("reproduced", "not reproduced", "not checkable")}
  parts = ["<h2 id='claims'>Chapter claims</h2>",
           f"<p>{n['reproduced']} reproduced, {n['not reproduced']} not reproduced, {n['not checkable']} not checkable "
           f"(of {len(rows)}). Checks on the reference member (A = 100 N, t0 = 0.1 s) unless the claim is about "
           "the families. Claims from <code>chapter-trends.md</code>; S1/S2 are the sensitivity statements. "
           "Tolerance bands are in the <i>check</i> column (and in <code>reports/claims.py</code>). "
           "Also as <a href='claims.csv'>claims.csv</a> and <a href='claims.md'>claims.md</a>.</p>"]
  parts.append(table(["id", "claim", "check (tolerance band)", "measured", "verdict", "reason"],
                     [[r["id"], r["claim"], r["check"], r["measured"], r["verdict"], r["reason"]] for r in rows],
                     row_classes=[r["verdict"].replace(" ", "-") for r in rows],
                     cell_classes=["id", None, None, None, "verdict", None]))
  return "\n".join(parts)


def figures_section(outdir):
  parts = ["<h2 id='figures'>Figures</h2>",
           "<p>Frames: x lateral, y anterior, z proximal (femoral frame F, tibial frame T). "
           "Valgus = β − 90° (+), external tibial rotation = γ (+). Dotted verticals: lateral lift-off.</p>"]
  in_grid = False
  for fname, caption in figures.FIGURES:
    rel = f"figures/{fname}"
    # The twelve element forces: two per row to keep the page short.
    if fname.startswith("ligament_") and not in_grid:
      parts.append("<h3>Forces in the twelve elements</h3><div class='grid2'>")
      in_grid = True
    if os.path.exists(os.path.join(outdir, rel)):
      parts.append(f"<figure><img src='{esc(rel)}' alt='{esc(caption)}'><figcaption>{esc(caption)} "
                   f"(<code>{esc(fname)}</code>)</figcaption></figure>")
    else:
      parts.append(f"<p class='warn'>Missing figure {esc(fname)}</p>")
  if in_grid:
    parts.append("</div>")
  return "\n".join(parts)


def sensitivity_section(outdir):
  path = os.path.join(outdir, "sensitivity.json")
  parts = ["<h2 id='sensitivity'>Sensitivity studies</h2>"]
  if not os.path.exists(path):
    return "\n".join(parts + ["<p class='warn'>sensitivity.json missing</p>"])
  with open(path) as f:
    s = json.load(f)
  parts.append("<p>Each perturbed run is compared with the unperturbed reference run (A = 100 N, t0 = 0.1 s) "
               "on the reference's output times: maximum absolute differences over the run. "
               "Differences of order 1e-6° are at the level of the integration tolerance.</p>")

  def num(r, k, fmt_="{:.3g}"):
    v = r.get(k)
    return fmt_.format(v) if isinstance(v, (int, float)) else "-"
  parts.append("<h3>(a) Initial contact-force guesses</h3>")
  rows = []
  for r in s.get("force_guess", []):
    init = r.get("initial_normal_force_N") or {}
    rows.append([f"{r['medial_N']:g} / {r['lateral_N']:g}", "ok" if r.get("ok") else f"failed: {r.get('reason', '')[-200:]}",
                 f"{init.get('medial', float('nan')):.6f} / {init.get('lateral', float('nan')):.6f}" if init else "-",
                 num(r, "max_abs_diff_flexion_deg"), num(r, "max_abs_diff_valgus_deg"),
                 num(r, "max_abs_diff_N_medial_N"), num(r, "max_abs_diff_N_lateral_N"),
                 num(r, "liftoff_lateral_deg", "{:.5f}")])
  parts.append(table(["guess medial / lateral [N]", "status", "consistent initial N medial / lateral [N]",
                      "max |Δflexion| [deg]", "max |Δvalgus| [deg]", "max |ΔN_m| [N]", "max |ΔN_l| [N]",
                      "lift-off [deg]"], rows))
  parts.append("<h3>(b) Initial contact-point guesses offset</h3>")
  rows = []
  for r in s.get("contact_offset", []):
    rows.append([f"{r['offset_mm']:g}", "ok" if r.get("ok") else f"failed: {r.get('reason', '')[-200:]}",
                 num(r, "max_abs_diff_flexion_deg"), num(r, "max_abs_diff_valgus_deg"),
                 num(r, "max_abs_diff_external_rotation_deg"), num(r, "max_abs_diff_N_medial_N"),
                 num(r, "max_abs_diff_N_lateral_N"), num(r, "liftoff_lateral_deg", "{:.5f}")])
  parts.append(table(["offset of every contact coordinate guess [mm]", "status", "max |Δflexion| [deg]",
                      "max |Δvalgus| [deg]", "max |Δext. rotation| [deg]", "max |ΔN_m| [N]", "max |ΔN_l| [N]",
                      "lift-off [deg]"], rows))
  ref = s.get("reference_events") or {}
  if ref:
    parts.append(f"<p>Unperturbed: lift-off {ref.get('liftoff_lateral_deg', float('nan')):.5f}°, "
                 f"t(90°) {ref.get('time_to_90_s', float('nan')):.6f} s.</p>")
  return "\n".join(parts)


def bench_section(outdir, bench):
  parts = ["<h2 id='work-precision'>Work-precision</h2>"]
  if not bench or not os.path.exists(bench):
    parts.append("<p>No benchmark JSON given (<code>--bench JSON</code>); diagrams omitted.</p>")
    return "\n".join(parts)
  files, failed = figures.make_work_precision(outdir, bench)
  for (fname, caption) in figures.WORK_PRECISION_FIGURES:
    if fname in files:
      parts.append(f"<figure><img src='figures/{esc(fname)}' alt='{esc(caption)}'>"
                   f"<figcaption>{esc(caption)} (source: {esc(bench)})</figcaption></figure>")
  if failed:
    parts.append("<h3>Failed runs</h3>")
    parts.append(table(["formulation / integrator", "setting", "reason"], [list(map(str, f)) for f in failed]))
  else:
    parts.append("<p>No failed runs.</p>")
  return "\n".join(parts)


def hard_cases_section(hard_cases):
  """The hard-case catalog (kneedyn_catalog's hard_cases.md), its tables rendered as HTML."""
  parts = ["<h2 id='hard-cases'>Hard cases</h2>"]
  if not hard_cases or not os.path.exists(hard_cases):
    parts.append("<p>No hard-case table given (<code>--hard-cases hard_cases.md</code>, written by "
                 "<code>kneedyn_catalog --out DIR</code>); section omitted.</p>")
    return "\n".join(parts)
  rows, text = [], []

  def flush_table():
    if rows:
      body = [r for r in rows[1:] if not all(set(c) <= set("-: ") for c in r)]
      parts.append("<div style='overflow-x:auto'>" + table(rows[0], body) + "</div>")
      rows.clear()

  with open(hard_cases, encoding="utf-8") as f:
    for line in f:
      line = line.rstrip("\n")
      if line.startswith("|"):
        rows.append([c.strip() for c in line.strip().strip("|").split("|")])
        continue
      flush_table()
      if line.strip() and not line.startswith("#"):
        parts.append(f"<p>{esc(line)}</p>")
  flush_table()
  parts.append(f"<p>Source: <code>{esc(hard_cases)}</code>.</p>")
  return "\n".join(parts)


def commands_section(outdir, kneedyn, quick, bench, fam):
  kd = kneedyn or "build/formulations/kneedyn"
  cmd = f"/usr/bin/python3 reports/report.py --kneedyn {kd} --out {outdir}" + (" --quick" if quick else "") + (
      f" --bench {bench}" if bench else "")
  cands = [m for m in fam.get("members", []) if m.get("command")]
  one = next((m for m in cands if m["name"] == "amplitude_100"), cands[0] if cands else None)
  lines = ["# whole report (families + sensitivity + figures + claims + this page)", cmd,
           "# or, from a build directory", "cmake --build <build-dir> --target report",
           "# the pieces", f"/usr/bin/python3 reports/run_families.py --kneedyn {kd} --out {outdir}",
           f"/usr/bin/python3 reports/figures.py --out {outdir}", f"/usr/bin/python3 reports/claims.py --out {outdir}",
           f"/usr/bin/python3 reports/make_report.py --out {outdir}"]
  if one:
    lines += ["# one member by hand", one["command"]]
  return "<h2 id='reproduce'>Reproduction</h2>\n<pre>" + esc("\n".join(lines)) + "</pre>"


def make_report(outdir, bench=None, kneedyn=None, quick=False, hard_cases=None):
  fam, members = load_families(outdir)
  with open(os.path.join(outdir, "claims.json")) as f:
    rows = json.load(f)
  body = [f"<h1>kneedyn: chapter reproduction report</h1>",
          "<p>Hefzy &amp; Abdel-Rahman, 3D dynamic knee model: pulse families of section 1.4 "
          "(Figs. 1.6–1.25) with the reference solver, the chapter's claims checked automatically.</p>",
          "<nav><a href='#summary'>Summary</a><a href='#claims'>Claims</a><a href='#figures'>Figures</a>"
          "<a href='#sensitivity'>Sensitivity</a><a href='#work-precision'>Work-precision</a>"
          "<a href='#hard-cases'>Hard cases</a>"
          "<a href='#reproduce'>Reproduction</a></nav>",
          summary_section(fam, members), claims_section(rows), figures_section(outdir),
          sensitivity_section(outdir), global_sensitivity.section(outdir), bench_section(outdir, bench), hard_cases_section(hard_cases),
          commands_section(outdir, kneedyn, quick, bench, fam)]
  page = ("<!DOCTYPE html>\n<html lang='en'><head><meta charset='utf-8'>"
          "<title>kneedyn chapter report</title><style>" + CSS + "</style></head><body>\n"
          + "\n".join(body) + "\n</body></html>\n")
  path = os.path.join(outdir, "index.html")
  tmp = path + ".tmp"
  with open(tmp, "w") as f:
    f.write(page)
  os.replace(tmp, path)
  return path


def main(argv=None):
  ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
  ap.add_argument("--out", required=True)
  ap.add_argument("--bench")
  ap.add_argument("--kneedyn")
  ap.add_argument("--quick", action="store_true")
  ap.add_argument("--hard-cases")
  args = ap.parse_args(argv)
  print("make_report:", make_report(args.out, args.bench, args.kneedyn, args.quick, args.hard_cases))
  return 0


if __name__ == "__main__":
  sys.exit(main())
