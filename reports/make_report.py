#!/usr/bin/python3
"""Writes OUTDIR/index.html (self-contained HTML, figures referenced relatively) from the outputs
of run_families.py, figures.py and claims.py.

  make_report.py --out OUTDIR [--bench JSON] [--kneedyn PATH] [--quick] [--hard-cases CSV]
                 [--peer-bench JSON] [--include DIR]...

--hard-cases: kneedyn_catalog's hard_cases.csv (or the hard_cases.md beside it) for the
hard-case section; without it the section says how to make one. --peer-bench: the sweep with
Simbody's integrators (simbody_work_precision --merge) for the peer section. --include DIR:
outside results scored by kneedyn score, drawn beside --bench (repeatable; needs --bench).
The options are report.py's (reports/report.py runs this page last).
"""
import argparse
import html
import json
import math
import os
import re
import shlex
import sys

sys.dont_write_bytecode = True  # keep the source tree clean
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import bench_data  # noqa: E402  (the sweep JSON and its fairness manifest)
import claim_verdicts  # noqa: E402  (which readings are informative)
import figures  # noqa: E402
import global_sensitivity  # noqa: E402  (Sobol' indices section)
import methods_comparison  # noqa: E402  (dae / dae-ggl / newmark / generalized-alpha)
import patella_section  # noqa: E402  (the patello-femoral joint, docs/model.md §12)
import tool_input  # noqa: E402
from family_data import load_families, load_families_checked  # noqa: E402

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
.scroll { overflow-x: auto; max-width: 100%; }
table.hard td.hc { white-space: nowrap; font-size: 0.9em; }
table.hard td.ok { background: #e6f4e6; } table.hard td.fail { background: #f8dcdc; }
table.hard td.err { background: #eee; } table.hard td.ref { font-size: 0.8em; max-width: 18em; }
details { margin: 4px 0; } summary { cursor: pointer; }
td { overflow-wrap: anywhere; }
table.matrix { width: auto; } table.matrix td.m { text-align: center; min-width: 2.2em; }
table.matrix td.reproduced { background: #d8f0d8; } table.matrix td.not-reproduced { background: #f6d5d5; }
table.matrix tr.varies td.id { background: #fff4d6; }
div.why { color: #666; font-size: 0.9em; margin-top: 3px; }
"""



def short_message(text):
  """An error message for a table cell: whole (a cut had turned "1.06 mm" into "1.06 m"), one
  line, its long numbers rounded to 4 significant digits."""
  return re.sub(r"-?\d+\.\d{5,}(?:e[-+]?\d+)?", lambda m: f"{float(m.group()):.4g}", " ".join(text.split()))

def esc(x):
  return html.escape(str(x))


class Raw(str):
  """A table cell that is already HTML."""


def table(headers, rows, row_classes=None, cell_classes=None):
  out = ["<table><thead><tr>" + "".join(f"<th>{esc(h)}</th>" for h in headers) + "</tr></thead><tbody>"]
  for i, r in enumerate(rows):
    cls = f' class="{row_classes[i]}"' if row_classes else ""
    cells = []
    for j, c in enumerate(r):
      cc = f' class="{cell_classes[j]}"' if cell_classes and cell_classes[j] else ""
      cells.append(f"<td{cc}>{c if isinstance(c, Raw) else esc(c)}</td>")
    out.append(f"<tr{cls}>" + "".join(cells) + "</tr>")
  out.append("</tbody></table>")
  return "\n".join(out)


def no_pulse_text(no_pulse, ref, members=()):
  """How much of the reference member's motion its pulse makes: the same run at A = 0 N
  (run_families.py), its lift-off and t(90°) beside the member's. In the project's reading the
  leg's weight moves the knee and the pulse's peak is a fraction of it, so the orderings the
  chapter draws across its pulse families are differences of that size."""
  if not no_pulse:
    return "not run (families.json from a run_families.py without the A = 0 N run)"
  lo, t90 = no_pulse.get("liftoff_lateral_deg"), no_pulse.get("time_to_90_s")
  if not no_pulse.get("ok") or lo is None or t90 is None:
    return f"did not complete ({no_pulse.get('status')})"
  if ref.liftoff_deg is None or ref.time_to_90_s is None:
    return f"lateral lift-off at {lo:.3f}°, 90° reached at t = {t90:.6f} s"
  text = (f"lateral lift-off at {lo:.3f}°, 90° reached at t = {t90:.6f} s: the reference member's pulse moves "
          f"the lift-off by {ref.liftoff_deg - lo:+.2f}° and the time to 90° by "
          f"{100 * (ref.time_to_90_s - t90) / t90:+.2f} %")
  los = [m.liftoff_deg for m in members if m.liftoff_deg is not None]
  ts = [m.time_to_90_s for m in members if m.time_to_90_s is not None]
  if los and ts:
    text += (f"; across the pulse families the lift-off spans {max(los) - min(los):.2f}° and the time to 90° "
             f"{100 * (max(ts) - min(ts)) / t90:.1f} %. The knee falls under its own weight (docs/model.md §7): the "
             "orderings the chapter draws across its pulse families (claims K1, K2, K6, K9 and C9 among them) compare "
             "members this close here. Their closeness is not the whole story: K9 and C9 are reproduced under none of "
             "the readings below, including those without gravity, where the pulse dominates")
  return text


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
        ("The reference member without its pulse (A = 0 N)", no_pulse_text(fam.get("no_pulse"), ref, members)),
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


RECORDED_VERDICTS = os.path.join(HERE, "recorded", "claims.json")


def load_json(path):
  """The JSON document at path, or None where there is none (a study not run)."""
  if not os.path.exists(path):
    return None
  with open(path, encoding="utf-8") as f:
    return json.load(f)


def not_run(parts, command):
  """A study's section when its output is missing: its parts so far and the command that runs it."""
  return "\n".join(parts + [f"<p>Not run (<code>{command}</code>).</p>"])


def load_recorded_verdicts(path=RECORDED_VERDICTS):
  """reports/recorded/claims.json (reports/claim_verdicts.py), or None."""
  return load_json(path)


def explanation_cell(v):
  """The verdict column: why a claim is not reproduced, with its evidence in short."""
  if v is None:
    return "not recorded"
  e, ev = v.get("explanation"), v.get("evidence", {})
  if e is None:
    return "–"
  if e == "reading":
    lo = ev.get("best_reading_liftoff_deg")
    notes = [f"docs/model.md {ev['best_reading_docs_model_md']}"] if ev.get("best_reading_docs_model_md") else []
    notes += [f"lift-off {lo:.1f}°"] if lo is not None else []
    return Raw(f"<b>reading</b>: {esc(ev.get('best_reading'))}{' (' + esc('; '.join(notes)) + ')' if notes else ''}; "
               f"loses {esc(', '.join(ev.get('best_reading_loses') or []) or 'nothing')}"
               f"<div class='why'>{esc(ev.get('why', ''))}</div>")
  if e == "contradicted":
    other = ev.get("other_statement")
    other = ", ".join(other) if isinstance(other, list) else other
    return Raw(f"<b>contradicted</b> by {esc(other)}<div class='why'>{esc(ev.get('why', ''))}</div>")
  if e == "beyond_precision":
    change = ev.get("normalized_change")
    change = f"{change:.3g}" if isinstance(change, (int, float)) and not isinstance(change, bool) else change
    return Raw(f"<b>beyond precision</b>: normalized change {esc(change)} printed precisions")
  return Raw(f"<b>unexplained</b><div class='why'>{esc(ev.get('why', ''))}</div>")


RECORDED_INVERSE = os.path.join(HERE, "recorded", "inverse_problem.json")


def fmt_num(x, f="{:.1f}"):
  return "–" if x is None else f.format(x)


def inverse_section(path=RECORDED_INVERSE, recorded_claims=None):
  """The bounded inverse problem (reports/recorded/inverse_problem.json, reports/inverse_problem.py):
  per target the smallest normalized change and its cost in claims, the claims at each
  leave-some-out fold's fit, and the readings as outer choices of the lift-off fit. Where the
  recorded claims (reports/recorded/claims.json, `recorded_claims`) are newer, each reading's
  lift-off there stands beside the inverse recording's."""
  inv = load_json(path)
  if inv is None:
    return ""
  parts = ["<h3 id='inverse'>Inverse problem: what it would take</h3>",
           "<p>The smallest change of Tables 1.1–1.3 (108 numbers, each normalized by half a unit of its last "
           "printed digit: ‖x‖ = 1 is one printed precision; bounds and reasons in "
           "<code>inverse/inverse_problem.yaml</code>) that reaches a statement of the chapter, fitted with Ceres "
           "and the IDAS sensitivities, and the claims judged at the fitted parameters (<b>fixes</b>/<b>breaks</b> "
           "against the unchanged model). Recorded in <code>reports/recorded/inverse_problem.json</code> at commit "
           f"{esc(inv.get('commit'))}, {esc(inv.get('date'))} (command: <code>{esc(inv.get('command'))}</code>; "
           f"{fmt_num(inv.get('runtime_s'), '{:.0f}')} s). The fits are upper bounds on the smallest change "
           "(rough statements, few iterations), not certified minima.</p>"]
  earlier = {}  # (commit, date) -> the targets recorded then
  for cid, t in inv.get("targets", {}).items():
    if e := t.get("recorded_earlier"):
      earlier.setdefault((e.get("commit"), e.get("date")), []).append(cid)
  for (commit, date), ids in earlier.items():
    parts.append(f"<p>The target rows {esc(', '.join(ids))} were not redone by that command: they were recorded "
                 f"earlier, at commit {esc(str(commit)[:12])}, {esc(date)} (each target's <code>recorded_earlier"
                 "</code>).</p>")
  parts.append("<p>A target is <i>reached</i> when its fitted statements are, on the reference member; the claim "
               "itself is judged on all its sub-checks over the pulse families at the fit, so a reached target can "
               "still break its own claim.</p>")
  rows = []
  for cid, t in inv.get("targets", {}).items():
    wp = (t.get("within_precision") or {}).get("fitted_statements") or {}
    rows.append([cid, "yes" if t.get("reached") else "no", fmt_num(t.get("normalized_change")),
                 fmt_num(t.get("max_normalized_change")),
                 "; ".join(f"{k} {fmt_num(v.get('value'))}" for k, v in wp.items() if v.get("value") is not None) or "–",
                 ", ".join(t.get("fixes") or []) or "–", ", ".join(t.get("breaks") or []) or "–"])
  if rows:
    parts.append(table(["target", "reached", "‖x‖", "max |x_i|", "closest within the precision (|x_i| ≤ 1)",
                        "fixes", "breaks"], rows))
  rechecked = inv.get("recorded_points_rechecked") or {}
  if rechecked:
    parts.append("<p id='inverse-rechecked'><b>Points of the earlier record, run again.</b> The fit is a local "
                 "search whose path moves with the solver, so each target's point from the record before this one "
                 "(<code>--recheck-recorded</code>) is run again at this commit, with the claims check: where it "
                 "still reaches its target, it bounds the smallest change as well as this record's fit.</p>")
    parts.append(table(["target", "recorded at", "‖x‖ then", "point run again", "‖x‖", "max |x_i|",
                        "lift-off by kneedyn run (°)", "claims reproduced", "fixes", "breaks"],
                       [[cid, f"{str(r.get('recorded_commit'))[:12]}, {r.get('recorded_date')}",
                         fmt_num(r.get("recorded_normalized_change")), r.get("point"),
                         fmt_num(r.get("normalized_change")), fmt_num(r.get("max_normalized_change")),
                         fmt_num(r.get("liftoff_lateral_deg_by_kneedyn_run")), str(r.get("reproduced_at_fit")),
                         ", ".join(r.get("fixes") or []) or "–", ", ".join(r.get("breaks") or []) or "–"]
                        for cid, r in rechecked.items()]))
  lso = inv.get("leave_some_out", {})
  if lso:
    parts.append("<p><b>Leave-some-out.</b> The statements of one half fitted together, the other half judged at "
                 "that fit, and every claim checked there; a fit that moves the judged half away from the chapter "
                 "is not a validation.</p>")
    parts.append(table(["fold", "fitted", "‖x‖", "judged closer / further", "claims fixed", "claims broken"],
                       [[fold, ", ".join(f.get("fitted") or []), fmt_num(f.get("normalized_change")),
                         f"{f.get('judged_closer')} / {f.get('judged_further')}",
                         (", ".join(f.get("fixes") or []) or "none") if "claims_at_fit" in f else "not run",
                         (", ".join(f.get("breaks") or []) or "none") if "claims_at_fit" in f else "not run"]
                        for fold, f in lso.items()]))
  rt = inv.get("readings_table", [])
  if rt:
    parts.append("<p><b>The readings as outer choices.</b> Lift-off 66° (C1) from each reading of docs/model.md "
                 "instead of the project's (first row): the Ceres fit where the IDAS sensitivities run (they stop at "
                 "a medial re-contact, which every reading with Table 1.2 as labelled has), and a derivative-free "
                 "scan that shifts every extension ratio by s × its bound (‖x‖ = |s|√12). Claims at the smaller "
                 "change, against the project's reading.</p>")

    def fit_cell(r):
      if r.get("C1_fit_reached"):
        return f"{r['C1_fit_normalized_change']:.1f}"
      if r.get("C1_fit_normalized_change") is not None:
        return f"not reached ({r['C1_fit_normalized_change']:.1f})"
      if "not run" in str(r.get("error") or ""):
        return "not run: " + short_message(str(r["error"]).split("not run", 1)[1].strip().strip("()"))
      return "does not run" + (f": {short_message(str(r.get('C1_fit_error')))}" if r.get("C1_fit_error") else "")
    now = {m["key"]: m.get("liftoff_lateral_deg")
           for m in ((recorded_claims or {}).get("matrix") or {}).get("readings", [])}
    now["chapter_impact"] = now.get("reconstructed/g_on")
    if now and recorded_claims:
      parts.append(f"<p>The column <i>lift-off in claims.json</i> is the reading's lateral lift-off in the newer "
                   f"reconstruction study (<code>reports/recorded/claims.json</code>, {esc(recorded_claims.get('date'))}); "
                   "where it differs from the recording's own, the fits of this table were made on the model as it "
                   "was then.</p>")

    def now_cell(r):
      if r["reading"] not in now:
        return "–"
      v = now[r["reading"]]
      return "none" if v is None else fmt_num(v)
    parts.append(table(["reading", "lift-off unchanged (°)", "lift-off in claims.json (°)", "Ceres fit ‖x‖",
                        "strain scan s", "smallest ‖x‖",
                        "max |x_i|", "lift-off there (°)", "claims reproduced", "fixes vs project",
                        "breaks vs project"],
                       [[r["reading"], fmt_num(r.get("liftoff_deg_unchanged")), now_cell(r), fit_cell(r),
                         fmt_num(r.get("strain_scan_s"), "{:+.3f}") if r.get("strain_scan_reached") else "not reached",
                         fmt_num(r.get("normalized_change"), "{:.2f}") if r.get("reached") else "–",
                         fmt_num(r.get("max_normalized_change"), "{:.2f}") if r.get("reached") else "–",
                         fmt_num(r.get("liftoff_deg_at_change")),
                         "–" if r.get("reproduced_at_change") is None else str(r["reproduced_at_change"]),
                         ", ".join(r.get("fixes_vs_project") or []) or "–",
                         ", ".join(r.get("breaks_vs_project") or []) or "–"]
                        for r in rt]))
  if inv.get("headline"):
    parts.append(f"<p><b>Headline.</b> {esc(inv['headline'])}</p>")
  return "\n".join(parts)


def claims_section(rows, recorded=None):
  n = {v: sum(r["verdict"] == v for r in rows) for v in ("reproduced", "not reproduced", "not checkable")}
  parts = ["<h2 id='claims'>Chapter claims</h2>",
           f"<p>{n['reproduced']} reproduced, {n['not reproduced']} not reproduced, {n['not checkable']} not checkable "
           f"(of {len(rows)}). Checks on the reference member (A = 100 N, t0 = 0.1 s) unless the claim is about "
           "the families. Claims, checks and the justification of every tolerance band: "
           "<code>reports/claims.yaml</code> (S1/S2 are the sensitivity statements). "
           "Also as <a href='claims.csv'>claims.csv</a> and <a href='claims.md'>claims.md</a>.</p>"]
  rv = (recorded or {}).get("claims", {})
  if recorded:
    parts.append("<p>The column <i>why not</i> is the recorded verdict on each claim that is not reproduced "
                 "(<code>reports/recorded/claims.json</code>, made by <code>reports/claim_verdicts.py</code> from "
                 f"the reconstruction study at commit {esc(recorded.get('commit'))}, {esc(recorded.get('date'))}; "
                 f"command: <code>{esc(recorded.get('command'))}</code>): <b>reading</b> — a named reading of the "
                 "printed chapter (docs/model.md) reproduces it; <b>contradicted</b> — another of the chapter's "
                 "statements excludes it; <b>beyond precision</b> — only parameter changes beyond the printed "
                 "precision reach it; <b>unexplained</b>. Inverse problem: "
                 f"{esc(recorded.get('inverse_problem'))}.</p>")
  parts.append(table(["id", "claim (source)", "check (tolerance band)", "measured", "verdict", "why not", "reason"],
                     [[r["id"], f"{r['claim']} ({r.get('source', '')})",
                       Raw(f"{esc(r['check'])}<div class='why'>why: {esc(r.get('justification', ''))}</div>"),
                       r["measured"], r["verdict"],
                       "–" if r["verdict"] == "reproduced" else explanation_cell(rv.get(r["id"])), r["reason"]]
                      for r in rows],
                     row_classes=[r["verdict"].replace(" ", "-") for r in rows],
                     cell_classes=["id", None, None, None, "verdict", None, None]))
  if recorded and recorded.get("matrix"):
    parts.append("<figure><img src='figures/reading_claim_matrix.png' alt='reading × claim matrix'>"
                 "<figcaption>Reading × claim matrix of the recorded verdicts: every reading of the study (the "
                 "pulse readings R1–R8 and the C¹ ligament law R9, then one per documented ambiguity of docs/model.md, then their combinations in "
                 "the order the Sobol' indices rank what they touch), each claim's verdict under it, and its "
                 "lateral lift-off angle (chapter ≈ 66°).</figcaption></figure>")
    hl = recorded.get("headline", {})
    best = (hl.get("by_reading") or [None])[0]
    if best:
      parts.append(f"<p><b>Headline.</b> The project's reading lifts off at {hl['project_liftoff_deg']:.1f}°. The "
                   f"reading that moves lift-off furthest towards 66° is <code>{esc(best['reading'])}</code>: "
                   f"{best['liftoff_deg']:.1f}° ({best['towards_66_deg']:+.1f}° towards 66°), losing "
                   f"{esc(', '.join(best['loses']) or 'no claim')} and gaining {esc(', '.join(best['gains']) or 'none')}."
                   "</p>")
  parts.append(inverse_section(recorded_claims=recorded))
  return "\n".join(parts)


def figures_section(outdir):
  parts = ["<h2 id='figures'>Figures</h2>",
           "<p>Frames: x lateral, y anterior, z proximal (femoral frame F, tibial frame T). "
           "Valgus = β − 90° (+), external tibial rotation = γ (+). Star and dotted vertical on every curve against flexion: lateral lift-off (the chapter marks it as point A on Figs. 1.7 and 1.8 only). Figure numbers are the chapter's; the four capsular elements have no chapter figure (kneedyn only).</p>"]
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
  s = load_json(os.path.join(outdir, "sensitivity.json"))
  parts = ["<h2 id='sensitivity'>Sensitivity studies</h2>"]
  if s is None:
    return "\n".join(parts + ["<p class='warn'>sensitivity.json missing</p>"])
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


def leg_weight_N(scene_path):
  """m g of the scene's leg: body.mass_kg and gravity.magnitude_m_s2 of the scene where it
  sets them, else of its parameter set (a path relative to the scene's directory); None when
  they cannot be read."""
  import yaml
  try:
    with open(scene_path, encoding="utf-8") as f:
      scene = yaml.safe_load(f) or {}
    ps_path = os.path.join(os.path.dirname(os.path.abspath(scene_path)), str(scene.get("parameter_set")))
    with open(ps_path, encoding="utf-8") as f:
      ps = yaml.safe_load(f) or {}
  except (OSError, TypeError, yaml.YAMLError):
    return None
  mass = (scene.get("body") or {}).get("mass_kg", (ps.get("body") or {}).get("mass_kg"))
  g = (scene.get("gravity") or {}).get("magnitude_m_s2", (ps.get("gravity") or {}).get("magnitude_m_s2"))
  return mass * g if isinstance(mass, (int, float)) and isinstance(g, (int, float)) else None


VERDICT_MARK = {"reproduced": "✓", "not reproduced": "✗", "not checkable": "–"}


def reconstruction_section(outdir):
  parts = ["<h2 id='reconstruction'>Reconstruction study</h2>"]
  rec = load_json(os.path.join(outdir, "reconstruction", "reconstruction.json"))
  if rec is None:
    return not_run(parts, "report.py --reconstruction")
  rd, ids = rec["readings"], rec["claims"]
  parts.append(
      "<p>The printed chapter leaves parts of the model uncertain: Eq. 1.62 (the pulse) is garbled, the "
      "direction of the weight is not stated, and the published ligament law has a force jump the chapter does "
      "not discuss; docs/model.md lists further ambiguities (the sign of ω′y's β̇ cos γ term, R0 from the medial "
      "condition, Table 1.2's column labels, the plateaus' slope direction, the printed precision of Tables 1.1 "
      "and 1.3), each a reading <code>model/…</code> here, alone and combined (docs/model.md §11). The "
      "project's reading (first column) is one hypothesis. Here every claim is re-evaluated "
      "under each plausible reading (the same families, solver and checks; only the scene changes). A claim "
      "whose verdict changes across columns rests on the reading; one that does not is robust to it."
      + (" <b>Quick mode: reduced families.</b>" if rec.get("quick") else "") + "</p>")
  labels = [f"R{i + 1}" for i in range(len(rd))]
  label_of_key = {r["key"]: lab for lab, r in zip(labels, rd)}
  rows = []
  for lab, r in zip(labels, rd):
    cr = r.get("crossing_deg") or {}
    keys = sorted(cr, key=float)
    cross = " → ".join(f"{cr[k]:.1f}°" if cr[k] is not None else "none" for k in keys)
    same = label_of_key.get(r.get("same_as"))
    label = r["label"] + (f" (the same scenes as {same}; not counted again)" if same else "")
    rows.append([Raw(f"<b style='white-space:nowrap'>{lab}</b>"), label, f"{r['peak_pulse_N']:.1f}" if r.get("peak_pulse_N") is not None else "–",
                 f"{r['liftoff_lateral_deg']:.1f}°" if r.get("liftoff_lateral_deg") is not None else "none",
                 cross + (f" (t0 {keys[0]}→{keys[-1]} s)" if keys else "–"),
                 f"{r['counts']['reproduced']} / {len(ids)}",
                 ", ".join(r.get("failed_members") or []) or "–"])
  parts.append(table(["", "reading", "peak pulse at A = 100 N [N]", "lateral lift-off (chapter ≈ 66°)",
                      "valgus→varus crossing (chapter 25° → 45°)", "claims reproduced", "failed runs"], rows))
  # Matrix: claims × readings.
  head = "<tr><th>claim</th>" + "".join(f"<th title='{esc(r['label'])}'>{lab}</th>" for lab, r in zip(labels, rd)) \
      + "</tr>"
  # claim_verdicts.informative, the rule of the recorded verdicts: the others (e.g. a 7.7 N
  # pulse without gravity barely moves the knee) fail most claims trivially.
  informative = [i for i, r in enumerate(rd) if claim_verdicts.informative(r)]
  body = []
  for cid in ids:
    vs = [r["verdicts"].get(cid, "not checkable") for r in rd]
    varies = len({vs[i] for i in informative}) > 1
    cells = "".join(f"<td class='m {v.replace(' ', '-')}' title='{esc(r['reasons'].get(cid, ''))[:300]}'>"
                    f"{VERDICT_MARK.get(v, '?')}</td>" for v, r in zip(vs, rd))
    body.append(f"<tr{' class=varies' if varies else ''}><td class='id' title='{esc(rec['claim_text'].get(cid, ''))}'>"
                f"{esc(cid)}{' *' if varies else ''}</td>{cells}</tr>")
  body.append("<tr><td class='id'>count ✓</td>" + "".join(f"<td class='m'><b>{r['counts']['reproduced']}</b></td>"
                                                          for r in rd) + "</tr>")
  body.append("<tr><td class='id'>lift-off</td>" + "".join(
      f"<td class='m'>{r['liftoff_lateral_deg']:.1f}°</td>" if r.get("liftoff_lateral_deg") is not None else
      "<td class='m'>none</td>" for r in rd) + "</tr>")
  n_vary = sum(len({rd[i]["verdicts"].get(c) for i in informative}) > 1 for c in ids)
  inf_labels = ", ".join(labels[i] for i in informative) or "none"
  robust_ok = [c for c in ids if informative and all(rd[i]["verdicts"].get(c) == "reproduced" for i in informative)]
  robust_no = [c for c in ids if informative and all(rd[i]["verdicts"].get(c) == "not reproduced" for i in informative)]
  parts.append(f"<p>Reading × claim (✓ reproduced, ✗ not reproduced, – not checkable). Informative readings (the "
               f"reference member, A = 100 N and t0 = 0.1 s, reaches 90° of flexion and no family member's run "
               f"fails): {inf_labels}. Across them {n_vary} of "
               f"{len(ids)} verdicts depend on the reading (marked *); reproduced under all of them: "
               f"{', '.join(robust_ok) or 'none'}; reproduced under none: {', '.join(robust_no) or 'none'}. "
               "Hover a cell for the failed sub-checks. S1/S2 (sensitivity statements) do not depend on the reading "
               "and are not re-run.</p>")
  parts.append("<div class='scroll'><table class='matrix'><thead>" + head + "</thead><tbody>" + "\n".join(body)
               + "</tbody></table></div>")
  parts.append(calibration_part(outdir))
  parts.append(
      "<h3>What this can and cannot establish</h3><ul>"
      "<li>It <b>can</b> show which verdicts depend on the uncertain readings and which hold under all of them, "
      "and whether any reading (or any pulse scale and weight direction within the bounds searched) reaches the "
      "chapter's quantitative statements.</li>"
      "<li>It <b>cannot</b> identify the chapter's actual pulse or weight direction: five targets read off plots "
      "to about ±5°, two fitted parameters, and other unknowns the study does not vary (typos in the printed "
      "parameter tables, the frame of the pulse direction, the surfaces) could compensate one another. A good "
      "fit is consistency, not proof; a bad fit says that these two quantities alone do not explain the "
      "difference.</li></ul>")
  return "\n".join(parts)


def calibration_part(outdir):
  parts = ["<h3>Calibration (Ceres)</h3>"]
  cal = load_json(os.path.join(outdir, "reconstruction", "calibration.json"))
  if cal is None:
    return not_run(parts, "report.py --reconstruction --calibrate build/reports/calibrate_reconstruction")
  best = cal["best"]
  res = best["result"]
  parts.append(
      "<p><code>reports/calibrate_reconstruction.cpp</code> fits two continuous quantities, the pulse scale s "
      "(amplitude s × A, shape as in the scene) and the angle θ of the weight in the sagittal plane "
      "(g<sub>F</sub> = g (0, −cos θ, −sin θ); θ = 0 is the project's reading, weight posterior with the thigh "
      "horizontal; θ = 90° weight distal), to five statements of the chapter, each residual (measured − target) / "
      "5°: a coarse grid picks the start, Ceres Levenberg–Marquardt (central differences, bounds s ∈ [0.5, 200], "
      f"θ ∈ [−90°, 90°]) refines it. Runs: {esc(cal['settings']['formulation'])}, rtol {cal['settings']['rtol']:g}."
      f" Pulse shape {esc(cal.get('pulse_shape'))}, A = {cal.get('amplitude_N'):g} N.</p>")
  names = [("liftoff_lateral_deg", "lateral lift-off (C1, Fig. 1.9)"),
           ("crossing_t0_0.05_deg", "valgus→varus crossing, t0 = 0.05 s (K4/K6, Fig. 1.7)"),
           ("crossing_t0_0.2_deg", "valgus→varus crossing, t0 = 0.2 s (K6, Fig. 1.7)"),
           ("external_rotation_peak_deg", "peak external rotation (K7, Fig. 1.8)"),
           ("max_varus_deg", "maximum varus (K5, Fig. 1.7)")]
  start = cal.get("start", {})
  base = next((g["result"] for g in cal.get("grid", []) if abs(g["scale"] - 1.0) < 1e-9 and abs(g["theta_deg"]) < 1e-9),
              None)
  rows = []
  for k, label in names:
    rows.append([label, f"{res[k]['target']:g}°", f"{base[k]['measured']:.1f}°" if base else "–",
                 f"{res[k]['measured']:.1f}°", f"{res[k]['residual']:+.2f}"])
  parts.append(table(["statement", "chapter", "project's reading (s = 1, θ = 0)", "best fit", "residual [×5°]"], rows))
  # max Fe / A of the scene's shape as calibrate_reconstruction writes it (solver/loads.hpp
  # PulsePeakFactor, docs/outputs.md): the shapes are not derived again here.
  factor = cal.get("pulse_peak_factor")
  factor = factor if isinstance(factor, (int, float)) and not isinstance(factor, bool) else None
  peak = best["pulse_amplitude_N"] * factor if factor is not None else None
  weight = leg_weight_N(cal.get("scene") or os.path.join(os.path.dirname(HERE), "reference-data", "scenes",
                                                         "chapter_impact.yaml"))
  worst = max(abs(res[k]["residual"]) for k, _ in names)
  verdict = ("every statement within 5°" if worst <= 1.0 else
             f"the worst statement is {worst * 5:.0f}° away")
  peak_text = (f"pulse peak ≈ {peak:.0f} N" if peak is not None
               else f"pulse peak not computed: calibration.json has no pulse_peak_factor (shape "
               f"{cal.get('pulse_shape')!r}; written by a calibrate_reconstruction older than the field)")
  if peak is not None and weight:
    peak_text += f", {peak / weight:.1f}× the leg's weight of {weight:.1f} N"
  elif peak is not None:
    peak_text += " (the leg's weight could not be read from the scene)"
  parts.append(
      f"<p><b>Best fit:</b> s = {best['scale']:.2f} (A = {best['pulse_amplitude_N']:.0f} N, {esc(peak_text)}), "
      f"θ = {best['theta_deg']:.1f}°; cost "
      f"{res['cost']:.2f} (start {start.get('cost', float('nan')):.2f} at s = {start.get('scale', float('nan')):.2f}, "
      f"θ = {start.get('theta_deg', float('nan')):.0f}°); {verdict}; "
      f"{res.get('failed_runs', 0)} of the three runs at the best fit failed (its angles are then taken up to the "
      "failure)"
      + (f"; {res['runs_not_reaching_end_flexion']} of them never reach 90° (the t0 = 0.1 s run's largest flexion: "
         f"{res.get('max_flexion_deg_t0_0.1', float('nan')):.1f}°; angles are read while the knee flexes)"
         if res.get("runs_not_reaching_end_flexion") else
         ("; all three reach 90°" if "runs_not_reaching_end_flexion" in res else "")) + ". "
      + (f"Ceres: {esc(cal['ceres']['brief_report'])}." if cal.get("ceres") else "") + "</p>")
  plaus = []
  if peak is not None and weight:
    plaus.append("a pulse peak of a few leg weights is physically plausible for an impact"
                 if 1.0 <= peak / weight <= 50 else "the fitted pulse peak is outside 1–50 leg weights: implausible")
  th = best["theta_deg"]
  plaus.append(
      f"θ = {th:.0f}° means the thigh inclined {abs(th):.0f}° from horizontal ({'knee below hip' if th > 0 else 'knee above hip'}); "
      f"at full extension {math.cos(math.radians(th)):.2f} of the weight still acts posteriorly, so the chapter's "
      "wording (the weight is part of the 'posterior load', its posterior component falling with flexion) does not "
      "exclude it, but the chapter describes no such posture" if abs(th) > 15 else
      f"θ = {th:.0f}° is close to the project's reading (weight posterior, thigh horizontal)")
  if res.get("runs_not_reaching_end_flexion"):
    plaus.insert(0, "the fitted motion is not the chapter's: the chapter follows the knee to 90° of flexion, and at "
                 "the best fit the leg does not get there, so the fit does not explain the statements it matches")
  parts.append("<p><b>Plausibility:</b> " + "; ".join(plaus) + ".</p>")
  return "\n".join(parts)


def included_table(runs):
  """The outside results drawn in the diagrams (kneedyn score's records): solver, method,
  setting, status, scd, CPU time as the outside driver measured it, and the score file."""
  rows = []
  for r in runs:
    scd, cpu = r.get("scd"), r.get("cpu_s")
    rows.append([r["formulation"], r.get("integrator") or "—", bench_data.setting_str(r.get("setting") or {}),
                 r["status"] + (f": {r['reason']}" if r.get("reason") else ""),
                 f"{scd:.2f}" if isinstance(scd, (int, float)) else "—",
                 f"{cpu:.4g}" if isinstance(cpu, (int, float)) else "—", os.path.basename(os.path.dirname(r.get("source") or ""))
                 + "/" + os.path.basename(r.get("source") or "")])
  return ("<h3>Outside solvers (scored by <code>kneedyn score</code>)</h3>"
          "<p>Outside solvers ran the knee through the open problem interface (<code>docs/problem.md</code>: "
          "SciPy's <code>solve_ivp</code> on <code>kneedyn.Problem</code>, examples/python/scipy_on_the_knee.py; a "
          "C program with RK4 on <code>kneedyn/problem.h</code>, examples/c/rk4_on_the_knee.c; "
          "examples/outside_results.sh runs them) and were scored by <code>kneedyn score</code> against the same "
          "reference with the same metrics, their failures counted as failures. Their CPU times are measured by "
          "the outside driver (Python's <code>time.process_time</code>, C's <code>clock</code>, around the whole "
          "hybrid loop, interpreter overhead included), once, on the machine that built this report, not by Google "
          "Benchmark in the sweep's run: compare them as orders of magnitude.</p>"
          "<div class='scroll'>" + table(["solver", "method", "setting", "status", "scd", "CPU [s]", "score file"], rows)
          + "</div>")


def bench_section(outdir, bench, prefix="", title="Work-precision", anchor="work-precision", intro="", include=()):
  parts = [f"<h2 id='{anchor}'>{esc(title)}</h2>"]
  if intro:
    parts.append(intro)
  if not bench or not os.path.exists(bench):
    parts.append("<p>No benchmark JSON given (<code>--bench JSON</code>); diagrams omitted.</p>")
    return "\n".join(parts)
  files, failed, header = figures.make_work_precision(outdir, bench, prefix, include)
  kv = [("Source", os.path.basename(bench)), ("Scene", header.get("scene", NOT_RECORDED)),
        ("Reference", f"{header.get('reference', NOT_RECORDED)} (accuracy "
                      f"{header.get('reference_accuracy_scd', NOT_RECORDED)} digits)")]
  kv += sweep_provenance(header, bench_data.load_bench(bench)[1])
  kv += [("Machine", (header.get("machine") or {}).get("uname", NOT_RECORDED)
          if isinstance(header.get("machine"), dict) else NOT_RECORDED)]
  parts.append("<dl class='kv'>" + "".join(f"<dt>{esc(k)}</dt><dd>{esc(v)}</dd>" for k, v in kv) + "</dl>")
  parts.append(components_table(header))
  mh = merged_header(header)
  if mh and mh.get("components") and mh["components"] != header.get("components"):
    parts.append(components_table(mh).replace("Components (fairness manifest)",
                                              "Components of the merged sweep (fairness manifest)"))
  parts.append("<p>Error metrics (<code>benchmarks/metrics.hpp</code>): <b>scd</b> = −log10 max |x − x_ref| / "
               "(|x_ref| + floor) over the positions x0, y0, z0 (floor 1 mm) and α, β, γ (floor 1°) at every 0.02 s "
               "and at the end event; <b>event-time digits</b> = −log10 of the largest |t − t_ref| in seconds over "
               "the reference's events (lateral lift-off, 90°). The first diagram overlays each formulation's "
               "Pareto front (for each accuracy, the CPU time of its cheapest run reaching at least that scd, any "
               "integrator or setting); the others have one panel per formulation, colour = formulation, marker = "
               "integrator. Runs that failed, lack a reference event, add a contact event, or miss an event by more "
               f"than {figures.WRONG_EVENT_TIME_S * 1e3:g} ms are not points: each panel's title counts them, they "
               "are the crosses (✗) below the dashed line of each panel, on no front, and are listed underneath.</p>")
  for (fname, caption) in figures.WORK_PRECISION_FIGURES:
    if prefix + fname in files:
      parts.append(f"<figure><img src='figures/{esc(prefix + fname)}' alt='{esc(caption)}'>"
                   f"<figcaption>{esc(caption)}</figcaption></figure>")
  # The same sweep on instruction counts, when one was recorded beside it
  # (benchmarks/recorded/instructions_<scene>.json, benchmarks/instruction_sweep.py).
  ipath = os.path.join(os.path.dirname(os.path.abspath(bench)), f"instructions_{header.get('scene', '?')}.json")
  iname = figures.make_instruction_pareto(outdir, ipath, prefix) if os.path.exists(ipath) else None
  if iname:
    ihead = bench_data.load_bench(ipath)[0]
    ceiling = ihead.get("scd_ceiling")
    ceiling = f"{ceiling:.3g}" if isinstance(ceiling, (int, float)) else "not recorded"
    parts.append(f"<figure><img src='figures/{esc(iname)}' alt='{esc(figures.INSTRUCTIONS_PARETO[1])}'>"
                 f"<figcaption>{esc(figures.INSTRUCTIONS_PARETO[1])}. Source: {esc(os.path.basename(ipath))}, "
                 f"{esc(ihead.get('kneedyn', '?'))}, {esc(ihead.get('date', '?'))}; the scd of each run is kneedyn "
                 f"score's on its 12-digit CSV (ceiling {ceiling}). Command: "
                 f"<code>{esc(ihead.get('command', '?'))}</code>.</figcaption></figure>")
  if header.get("included_runs"):
    parts.append(included_table(header["included_runs"]))
  if failed:
    parts.append(f"<details><summary>{len(failed)} runs drawn as failures (failed or wrong event)</summary>")
    parts.append(table(["formulation / integrator", "setting", "why"], [list(map(str, f)) for f in failed]))
    parts.append("</details>")
  else:
    parts.append("<p>No failed runs.</p>")
  return "\n".join(parts)


NOT_RECORDED = "not recorded in the file"


def merged_header(header):
  """The header of the sweep simbody_work_precision --merge copied rows from (header.merged_from),
  with that sweep's build (git_commit, components) from its context and its file; None when
  nothing was merged."""
  mf = header.get("merged_from")
  if not isinstance(mf, dict):
    return None
  h = dict(mf.get("header") or {})
  ctx = mf.get("context") if isinstance(mf.get("context"), dict) else {}
  for k in ("git_commit", "components"):
    if ctx.get(k) and k not in h:
      h[k] = ctx[k]
  h["file"] = mf.get("file")
  return h


def _sweep_line(h, runs):
  """mode, repetitions and the tightest setting among `runs` (with --rtol-min, the floor the
  sweep was given, when it is recorded: a short sweep stops above it)."""
  tight = bench_data.tightest_setting(runs) or "none"
  floor = f" (--rtol-min {h['rtol_min']:.3g})" if isinstance(h.get("rtol_min"), (int, float)) else ""
  return f"{h.get('mode', NOT_RECORDED)}, repetitions {h.get('repetitions', NOT_RECORDED)}, tightest run {tight}{floor}"


def sweep_provenance(header, runs):
  """The sweep's provenance rows (Sweep, Swept, Built / Recorded, Command) for the section's
  list. A file written by simbody_work_precision --merge holds two sweeps: the rows it timed
  and the rows it copied; both are described, each from its own header."""
  outside = [r for r in runs if bench_data.timed_where(r, header) == bench_data.TIMED_OUTSIDE]
  mh = merged_header(header)
  if mh is None:
    prov = header.get("provenance") or {}
    own = [r for r in runs if r not in outside]
    recorded = (f"{prov.get('date', NOT_RECORDED)}, sweep binary built from commit "
                f"{prov.get('commit', NOT_RECORDED)}" if prov else
                f"not a recorded sweep (no provenance); sweep binary built from commit "
                f"{bench_data.build_commit(header) or NOT_RECORDED}")
    return [("Sweep", _sweep_line(header, own)), ("Swept", header.get("date", NOT_RECORDED)),
            ("Recorded", recorded), ("Command", prov.get("command") or header.get("command") or NOT_RECORDED)]
  here = [r for r in runs if bench_data.timed_where(r, header) == bench_data.TIMED_HERE]
  merged = [r for r in runs if bench_data.timed_where(r, header) == bench_data.TIMED_MERGED]
  src = os.path.basename(mh.get("file") or "") or NOT_RECORDED
  this = f"this run ({len(here)} rows)"
  copied = f"merged sweep {src} ({len(merged)} rows{f', {len(outside)} outside rows with them' if outside else ''})"
  return [("Sweep", f"{this}: {_sweep_line(header, here)}; {copied}: {_sweep_line(mh, merged)}"),
          ("Swept", f"{this}: {header.get('date', NOT_RECORDED)}; merged sweep: {mh.get('date', NOT_RECORDED)}"),
          ("Built from", f"{this}: commit {bench_data.build_commit(header) or NOT_RECORDED}; merged sweep: commit "
                         f"{bench_data.build_commit(mh) or NOT_RECORDED}"),
          ("Command", f"{this}: {header.get('command') or NOT_RECORDED}; merged sweep: "
                      f"{mh.get('command') or NOT_RECORDED}")]


def components_table(header):
  """The fairness manifest (context.components of the sweep JSON): for every component in the
  diagrams, its version, where it came from and its compile flags, so that a reader can see
  whether the solvers compared were built alike."""
  rows = bench_data.components(header)
  head = "<h3>Components (fairness manifest)</h3>"
  if rows is None:
    return head + ("<p>Components: not recorded (this sweep JSON has no <code>context.components</code>: "
                   "versions, origins and compile flags of the solvers compared are unknown).</p>")
  if isinstance(rows, str):
    return head + f"<p class='warn'>Components: {esc(rows)}.</p>"
  return head + "<div class='scroll'>" + table(["component", "version", "origin", "compile flags"], rows) + "</div>"


STATUS_MARK = {"ok": "✓", "solver_failure": "✗", "error": "⊘"}


# The columns of kneedyn_catalog's hard_cases.csv that hard_cases_section reads.
HARD_CASE_COLUMNS = ("case", "formulation", "reference", "status", "t_reached_s", "flexion_deg", "err_alpha_deg",
                     "err_R0_mm", "max_gap_mm", "energy_drift_J", "steps", "residual_evaluations", "wall_s",
                     "reason")


def hard_cases_csv_path(path):
  """hard_cases.csv for a given hard_cases.csv or the hard_cases.md beside it."""
  return path[:-3] + ".csv" if path and path.endswith(".md") else path


def read_hard_cases_csv(path):
  import csv
  with open(path, newline="", encoding="utf-8") as f:
    return list(csv.DictReader(f))


def load_hard_cases(path):
  """The rows of hard_cases.csv (or of the .csv beside a hard_cases.md), with every column
  hard_cases_section reads; ValueError when one is missing or a row is cut short."""
  import csv
  csv_path = hard_cases_csv_path(path)
  with open(csv_path, newline="", encoding="utf-8") as f:
    reader = csv.DictReader(f)
    rows = list(reader)
    names = reader.fieldnames or []
  missing = [c for c in HARD_CASE_COLUMNS if c not in names]
  if missing:
    raise ValueError(f"not kneedyn_catalog's hard_cases.csv: no column(s) {', '.join(missing)}")
  for i, r in enumerate(rows, start=2):
    if any(r.get(c) is None for c in HARD_CASE_COLUMNS):
      raise ValueError(f"'{csv_path}' line {i}: fewer cells than columns")
  return rows


def hard_cases_section(hard_cases):
  """The hard-case catalog (kneedyn_catalog's hard_cases.csv beside hard_cases.md) as a compact
  case × formulation table (status, time reached, error vs the case's reference) with the
  details of each case on demand."""
  parts = ["<h2 id='hard-cases'>Hard cases</h2>"]
  path = hard_cases_csv_path(hard_cases)
  if not path or not os.path.exists(path):
    parts.append("<p>No hard-case table given (<code>--hard-cases hard_cases.csv</code>, written by "
                 "<code>kneedyn_catalog --out DIR</code>); section omitted.</p>")
    return "\n".join(parts)
  rows = load_hard_cases(path)
  cases = list(dict.fromkeys(r["case"] for r in rows))
  forms = list(dict.fromkeys(r["formulation"] for r in rows))
  by = {(r["case"], r["formulation"]): r for r in rows}
  parts.append("<p>Every case of <code>reference-data/scenes/hard/</code> with every formulation at the same "
               "default options (adaptive rtol 1e-8, atol 1e-10; newmark* h = 1e-4 s). Cell: status "
               "(✓ completed, ✗ solver failure, ⊘ refused / error), time reached [s], and the largest flexion "
               "error |Δα| [deg] against the case's reference over the output times both reached. The reference of "
               "each case is the first of dae, mde, ede at rtol 1e-10 that <i>completed</i> (stated per case; a "
               "failed run is never a reference). ⚠: the run's own warnings (summary.json's <code>warnings</code>, "
               "docs/outputs.md), e.g. <code>liftoff_force_not_zero</code>, a lift-off where the knee's force is "
               "not zero. Open a case for its events, failure reasons and counters.</p>")
  head = "<tr><th>case</th><th>reference</th>" + "".join(f"<th>{esc(f)}</th>" for f in forms) + "</tr>"
  body = []
  for c in cases:
    ref = next((by[(c, f)]["reference"] for f in forms if (c, f) in by), "")
    cells = []
    for f in forms:
      r = by.get((c, f))
      if r is None:
        cells.append("<td class='na'>–</td>")
        continue
      mark = STATUS_MARK.get(r["status"], r["status"])
      t = r["t_reached_s"] or "–"
      try:
        t = f"{float(t):.3g}"
      except ValueError:
        pass
      err = r["err_alpha_deg"]
      try:
        # No error for a run that stopped at t = 0: nothing was compared.
        err = f"{float(err):.1e}°" if float(r["t_reached_s"] or 0) > 0 and float(err) == float(err) else ""
      except ValueError:
        err = ""
      cls = {"ok": "ok", "solver_failure": "fail", "error": "err"}.get(r["status"], "")
      met = " <b>expectation not met</b>" if r.get("met") == "no" else ""
      # The run's own warnings (docs/outputs.md; a catalog older than the column has none).
      warned = r.get("warnings") or ""
      flag = f"<br>⚠ {esc(warned)}" if warned else ""
      cells.append(f"<td class='hc {cls}' title='{esc(r['reason'][:300])}'>{mark} {esc(t)}"
                   f"{'<br>' + esc(err) if err else ''}{flag}{met}</td>")
    body.append(f"<tr><td class='id'>{esc(c)}</td><td class='ref'>{esc(ref)}</td>" + "".join(cells) + "</tr>")
  parts.append("<div class='scroll'><table class='hard'><thead>" + head + "</thead><tbody>" + "\n".join(body)
               + "</tbody></table></div>")
  parts.append("<h3>Details per case</h3>")
  for c in cases:
    detail_rows = []
    for f in forms:
      r = by.get((c, f))
      if r is None:
        continue
      ev = r.get("events", "")
      n_ev = len(ev.split()) if ev else 0
      ev_short = " ".join(ev.split()[:6]) + (f" … ({n_ev} events)" if n_ev > 6 else "")
      detail_rows.append([f, r["status"], r.get("end_reason", ""), r["t_reached_s"], r["flexion_deg"],
                          r["err_alpha_deg"], r["err_R0_mm"], r["max_gap_mm"], r["energy_drift_J"], r["steps"],
                          r["residual_evaluations"], r["wall_s"], ev_short, r.get("warnings") or "",
                          r["reason"][:400]])
    parts.append(f"<details><summary>{esc(c)} — reference: {esc(by.get((c, forms[0]), {}).get('reference', ''))}"
                 "</summary><div class='scroll'>"
                 + table(["formulation", "status", "end", "t [s]", "flexion [deg]", "err α [deg]", "err R0 [mm]",
                          "max gap [mm]", "energy drift [J]", "steps", "res. evals", "wall [s]", "events",
                          "warnings", "reason"], detail_rows) + "</div></details>")
  parts.append(f"<p>Source: <code>{esc(os.path.basename(path))}</code> (full table: hard_cases.md / .csv "
               "beside it).</p>")
  return "\n".join(parts)


def cli_args(outdir, bench=None, kneedyn=None, quick=False, hard_cases=None, peer_bench=None, include=()):
  """make_report.py's arguments that write this page from the run directory."""
  return (["--out", outdir] + (["--bench", bench] if bench else []) + (["--kneedyn", kneedyn] if kneedyn else [])
          + (["--quick"] if quick else []) + (["--hard-cases", hard_cases] if hard_cases else [])
          + (["--peer-bench", peer_bench] if peer_bench else []) + [a for d in include for a in ("--include", d)])


BOOTSTRAP = os.path.join(os.path.dirname(HERE), ".ci", "bootstrap")


def main_job_steps(path=BOOTSTRAP):
  """The main job's steps: the `run` branch of .ci/bootstrap (after the test branch's `else`,
  to its closing `fi`) verbatim without its comments, or None when the file or the branch is
  not there. Read, not copied, so that it cannot drift from what the job runs."""
  try:
    with open(path, encoding="utf-8") as f:
      lines = f.read().splitlines()
  except OSError:
    return None
  try:
    i = next(k for k, ln in enumerate(lines) if ln.startswith('if [[ "$mode" == test ]]'))
    start = next(k for k in range(i, len(lines)) if lines[k] == "else") + 1
    end = next(k for k in range(start, len(lines)) if lines[k] == "fi")
  except StopIteration:
    return None
  return [ln[2:] if ln.startswith("  ") else ln for ln in lines[start:end] if not ln.strip().startswith("#")]


def commands_section(outdir, kneedyn, quick, bench, fam, include=(), command=None, steps=None, hard_cases=None,
                     peer_bench=None):
  """The Reproduction section: the command that made this page as it was given (report.py's, or
  make_report.py's own), the pieces report.py ran with their arguments, the main job's steps
  that made its inputs (.ci/bootstrap run) and one family member by hand."""
  kd = kneedyn or "build/formulations/kneedyn"
  if command is None:  # not given: the make_report.py command that rewrites this page
    command = shlex.join(["/usr/bin/python3", "reports/make_report.py"]
                         + cli_args(outdir, bench, kneedyn, quick, hard_cases, peer_bench, include))
  cands = [m for m in fam.get("members", []) if m.get("command")]
  one = next((m for m in cands if m["name"] == "amplitude_100"), cands[0] if cands else None)
  lines = [f"# this page, as it was made (in {os.getcwd()})", command,
           "# or, from a build directory: report.py with --kneedyn and --out <build-dir>/report only (no sweep, "
           "hard cases or reconstruction)",
           "cmake --build <build-dir> --target report"]
  if steps:
    lines += ["# the pieces report.py ran, in order, with their arguments"] + list(steps)
  job = main_job_steps()
  if job:
    lines += ["# the main job that made the inputs (.ci/bootstrap run: its run branch, verbatim; "
              "$build = build directory, $out = output directory, this page in $out/report)"] + job
  if one:
    lines += ["# one member by hand", one["command"]]
  runner = (f"<p>Simulations ran {esc(fam['runner'])} (reports/run_families.py; "
            "KNEEDYN_REPORT_RUNNER=subprocess runs one CLI process each instead).</p>") if fam.get("runner") else ""
  return "<h2 id='reproduce'>Reproduction</h2>\n" + runner + "<pre>" + esc("\n".join(lines)) + "</pre>"


def peer_intro(bench):
  """The peer section's opening, from the file's rows: which were timed in the
  simbody_work_precision run itself (their CPU times compare as ratios), which --merge copied
  from another sweep's process, which outside drivers timed."""
  header, runs = bench_data.load_bench(bench)
  groups = {w: [r for r in runs if bench_data.timed_where(r, header) == w]
            for w in (bench_data.TIMED_HERE, bench_data.TIMED_MERGED, bench_data.TIMED_OUTSIDE)}

  def methods(rs):
    return ", ".join(dict.fromkeys(bench_data.method_of(r) for r in rs))
  here, merged, outside = groups["here"], groups["merged"], groups["outside"]
  sub = [r for r in here if r.get("timing")]
  rows = [[f"this run ({header.get('generator') or 'the program that wrote the file'})", len(here), methods(here),
           f"one process, {header.get('timer') or 'CPU time'}"
           + (f"; {methods(sub)}: {sub[0]['timing']}" if sub else "")]]
  if merged:
    mh = merged_header(header) or {}
    rows.append([f"another sweep's process (--merge from {os.path.basename(mh.get('file') or '') or NOT_RECORDED})",
                 len(merged), methods(merged), "benchmarks/work_precision's Google Benchmark CPU time"])
  if outside:
    rows.append(["outside drivers", len(outside), methods(outside),
                 "each driver's own clock (Python's time.process_time, C's clock), once"])
  text = (f"<p>Simbody's integrators (<code>crosscheck/simbody</code>, the chapter knee rebuilt in Simbody's own "
          f"terms) beside kneedyn's formulations. Of the {len(runs)} runs in {esc(os.path.basename(bench))}, "
          f"{len(here)} were timed in one process run of <code>simbody_work_precision</code>: only their CPU "
          "times compare as ratios.")
  if merged or outside:
    src = os.path.basename((merged_header(header) or {}).get("file") or "") or "another sweep file"
    text += (f" The other {len(merged) + len(outside)} were copied in by <code>--merge</code> from "
             f"{esc(src)}, timed in that sweep's process"
             + (" (and the outside solvers' by their own drivers, interpreter and loop overhead included)"
                if outside else "")
             + ": the same machine, not the same run, so not ratios of one run. In "
             f"the diagrams a formulation is marked{figures.MERGED_MARK['all']} when all its runs were copied, "
             f"{figures.MERGED_MARK['part']} when some were (those series say (--merge)), and "
             f"{figures.OUTSIDE_MARK} for an outside solver.")
  text += " Same reference and metrics as above.</p>"
  return text + table(["timed in", "runs", "methods", "clock"], rows)


def make_report(outdir, bench=None, kneedyn=None, quick=False, hard_cases=None, peer_bench=None, include=(),
                command=None, steps=None):
  """Writes OUTDIR/index.html; `command` (the command that made it) and `steps` (the pieces
  report.py ran) for the Reproduction section."""
  fam, members = load_families(outdir)
  with open(os.path.join(outdir, "claims.json")) as f:
    rows = json.load(f)
  recorded = load_recorded_verdicts()
  if recorded and recorded.get("matrix"):
    os.makedirs(os.path.join(outdir, "figures"), exist_ok=True)
    figures.reading_claim_matrix(RECORDED_VERDICTS, os.path.join(outdir, "figures", "reading_claim_matrix.png"))
  body = ["<h1>kneedyn: chapter reproduction report</h1>",
          "<p>Hefzy &amp; Abdel-Rahman, 3D dynamic knee model: pulse families of section 1.4 "
          "(Figs. 1.4–1.25) with the reference solver, the chapter's claims checked automatically.</p>",
          "<nav><a href='#summary'>Summary</a><a href='#claims'>Claims</a><a href='#figures'>Figures</a>"
          "<a href='#sensitivity'>Sensitivity</a><a href='#reconstruction'>Reconstruction</a>"
          "<a href='#work-precision'>Work-precision</a>"
          "<a href='#methods'>Methods</a>"
          "<a href='#patella'>Patella</a>"
          "<a href='#hard-cases'>Hard cases</a>"
          "<a href='#reproduce'>Reproduction</a></nav>",
          summary_section(fam, members), claims_section(rows, recorded), figures_section(outdir),
          sensitivity_section(outdir), reconstruction_section(outdir), global_sensitivity.section(outdir), bench_section(outdir, bench, include=include), \
          methods_comparison.section(outdir, kneedyn, bench), \
          *([bench_section(outdir, peer_bench, "peer_", "kneedyn and Simbody", "peer-work-precision",
                           peer_intro(peer_bench))] if peer_bench else []), patella_section.section(outdir),
          hard_cases_section(hard_cases),
          commands_section(outdir, kneedyn, quick, bench, fam, include, command, steps, hard_cases, peer_bench)]
  page = ("<!DOCTYPE html>\n<html lang='en'><head><meta charset='utf-8'>"
          "<title>kneedyn chapter report</title><style>" + CSS + "</style></head><body>\n"
          + "\n".join(body) + "\n</body></html>\n")
  path = os.path.join(outdir, "index.html")
  tmp = path + ".tmp"
  with open(tmp, "w") as f:
    f.write(page)
  os.replace(tmp, path)
  return path


def check_inputs(outdir, bench=None, hard_cases=None, peer_bench=None, option="--out"):
  """What make_report reads, checked before it writes anything (BadInput naming the option):
  the run directory with families.json and claims.json (claims.py), the sweep JSONs and the
  hard-case table when given."""
  load_families_checked(option, outdir)
  tool_input.json_document(option, os.path.join(outdir, "claims.json"), (list,))  # claims.py's rows
  check_sources(bench, hard_cases, peer_bench)


def check_sources(bench=None, hard_cases=None, peer_bench=None):
  """The sweep JSONs (--bench, --peer-bench) and the hard-case table (--hard-cases) when
  given: read as make_report reads them (BadInput naming the option and the file)."""
  for option, path in (("--bench", bench), ("--peer-bench", peer_bench)):
    if path is not None:
      tool_input.checked(bench_data.load_bench, option, path)
  if hard_cases is not None:
    tool_input.checked(load_hard_cases, "--hard-cases", hard_cases)


def main(argv=None):
  ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
  ap.add_argument("--out", required=True)
  ap.add_argument("--bench")
  ap.add_argument("--kneedyn")
  ap.add_argument("--quick", action="store_true")
  ap.add_argument("--hard-cases")
  ap.add_argument("--peer-bench")
  ap.add_argument("--include", action="append", default=[], metavar="DIR")
  command = shlex.join([sys.executable, sys.argv[0] if argv is None else os.path.abspath(__file__)]
                       + list(sys.argv[1:] if argv is None else argv))
  args = ap.parse_args(argv)
  check_inputs(args.out, args.bench, args.hard_cases, args.peer_bench)
  if args.include and not args.bench:
    raise tool_input.BadInput("--include needs --bench (the sweep the outside results are drawn beside)")
  print("make_report:", make_report(args.out, args.bench, args.kneedyn, args.quick, args.hard_cases,
                                    args.peer_bench, args.include, command=command))
  return 0


if __name__ == "__main__":
  sys.exit(tool_input.exit_code("make_report", main))
