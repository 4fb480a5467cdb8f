#!/usr/bin/python3
"""Automatic checks of the chapter's claims (reports/claims.yaml: ids K1-K9, C1-C10, V1-V6,
L1-L12) and of the two sensitivity statements (S1, S2) on the family runs.

  claims.py --out OUTDIR      -> OUTDIR/claims.json, claims.csv, claims.md

Each check states its tolerance band in `check` (also shown in the table). Verdicts:
reproduced / not reproduced / not checkable. The model is never tuned: the table reports
what the runs measure.

Tolerance conventions (the chapter reads its values off plots):
  - angle locations "near ~X" or "~X-Y": the chapter's band widened by ANGLE_TOL_DEG each side;
  - force magnitudes "≈ F": within ±MAG_TOL (relative);
  - "≈ 0" for a ligament: at most ZERO_FRACTION of its own maximum (or ZERO_ABS_N);
  - trends along a curve ("decreased", "moved posteriorly"): Spearman rank correlation with
    flexion, on a uniform 0.25° flexion grid over the stated range, at least RHO_MIN in size;
  - "monotonously": the curve moves that way over at least MONO_FRACTION of the flexion range;
  - orderings across a family: at least ORDER_FRACTION of a 5° flexion grid agrees.
"""
import argparse
import csv
import json
import os
import sys

import numpy as np
import yaml

sys.dont_write_bytecode = True  # keep the source tree clean
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import tool_input  # noqa: E402
from family_data import LIGAMENTS, by_family, contact_changes, ligament_column, load_families  # noqa: E402

CLAIMS_YAML = os.path.join(os.path.dirname(os.path.abspath(__file__)), "claims.yaml")


def load_claims(path=CLAIMS_YAML):
  """claims.yaml -> (tolerances dict, [claim dicts]); raises ValueError naming the bad field."""
  with open(path, encoding="utf-8") as f:
    doc = yaml.safe_load(f)
  if not isinstance(doc, dict) or not isinstance(doc.get("claims"), list):
    raise ValueError(f"{path}: expected a mapping with a 'claims' list")
  for i, c in enumerate(doc["claims"]):
    for key in ("id", "claim", "source", "check", "justification"):
      if not isinstance(c.get(key), str) or not c[key].strip():
        raise ValueError(f"{path}: claims[{i}].{key} = {c.get(key)!r}: must be a non-empty string")
  ids = [c["id"] for c in doc["claims"]]
  dup = sorted({x for x in ids if ids.count(x) > 1})
  if dup:
    raise ValueError(f"{path}: duplicate claim ids {dup}")
  return doc.get("tolerances", {}), doc["claims"]


TOL, CLAIMS = load_claims()
CLAIM_BY_ID = {c["id"]: c for c in CLAIMS}
ANGLE_TOL_DEG = float(TOL["angle_tolerance_deg"])
MAG_TOL = float(TOL["magnitude_tolerance_rel"])
ZERO_FRACTION = float(TOL["zero_fraction"])
ZERO_ABS_N = float(TOL["zero_abs_N"])
MONO_FRACTION = float(TOL["mono_fraction"])
ORDER_FRACTION = float(TOL["order_fraction"])
LIFTOFF_CHAPTER_DEG = float(TOL["liftoff_chapter_deg"])
LIFTOFF_SPREAD_DEG = float(TOL["liftoff_spread_deg"])
PATHWAY_OVERLAP_MM = float(TOL["pathway_overlap_mm"])
SHARE_OVERLAP = float(TOL["share_overlap"])
RHO_MIN = float(TOL["trend_rank_correlation"])
GRID_DEG = np.arange(5.0, 90.0, 5.0)
# Sensitivity: "insensitive" = flexion changes by < INSENSITIVE_DEG over the run; "very
# sensitive" = a perturbation of at most 0.1 mm changes flexion by > SENSITIVE_DEG (or the run fails).
INSENSITIVE_DEG = float(TOL["insensitive_deg"])
SENSITIVE_DEG = float(TOL["sensitive_deg"])

REPRODUCED, NOT_REPRODUCED, NOT_CHECKABLE = "reproduced", "not reproduced", "not checkable"


class NotCheckable(Exception):
  pass


def fmt(x, nd=3):
  if x is None:
    return "n/a"
  if isinstance(x, (list, tuple)):
    return "[" + ", ".join(fmt(v, nd) for v in x) + "]"
  return f"{x:.{nd}g}"


class Curve:
  """A column of one member as a function of flexion (samples with finite values only)."""

  def __init__(self, member, col, sign=1.0):
    a = member.col("flexion_deg")
    y = sign * member.col(col)
    ok = np.isfinite(a) & np.isfinite(y)
    a, y = a[ok], y[ok]
    # The chapter's statements are about the knee flexing: a run that swings back (gravity
    # off, a weak pulse) is read up to its first largest flexion.
    end = int(np.argmax(a)) + 1 if len(a) else 0
    self.a, self.y = a[:end], y[:end]
    if len(self.a) < 3:
      raise NotCheckable(f"{member.name}: column {col} has no data")

  def window(self, lo, hi):
    m = (self.a >= lo) & (self.a <= hi)
    if not np.any(m):
      raise NotCheckable(f"no samples in {lo}-{hi} deg")
    return self.a[m], self.y[m]

  def argmax(self, lo=-1, hi=1e9):
    a, y = self.window(lo, hi)
    i = int(np.argmax(y))
    return a[i], y[i]

  def argmin(self, lo=-1, hi=1e9):
    a, y = self.window(lo, hi)
    i = int(np.argmin(y))
    return a[i], y[i]

  def first_at_or_below(self, threshold):
    """The first flexion angle (deg) with y ≤ threshold; None if there is none."""
    below = self.a[self.y <= threshold]
    return float(below[0]) if len(below) else None

  def at(self, alpha):
    # Flexion increases up to the curve's end (__init__); np.maximum.accumulate guards round-off.
    return float(np.interp(alpha, np.maximum.accumulate(self.a), self.y, left=np.nan, right=np.nan))

  def crossings(self, direction, lo=-1, hi=1e9):
    """Flexion angles where y changes sign; direction +1: - to +, -1: + to -."""
    a, y = self.window(lo, hi)
    out = []
    for i in range(len(y) - 1):
      if (direction < 0 and y[i] > 0 >= y[i + 1]) or (direction > 0 and y[i] < 0 <= y[i + 1]):
        t = y[i] / (y[i] - y[i + 1]) if y[i] != y[i + 1] else 0.0
        out.append(a[i] + t * (a[i + 1] - a[i]))
    return sorted(set(out))

  def on_grid(self, lo, hi, step=0.25):
    """Resampled on a uniform flexion grid over [lo, hi] ∩ data: checks weighted by angle, not
    by output step (output steps are uniform in time and the knee moves slowly at first)."""
    a = np.maximum.accumulate(self.a)
    lo, hi = max(lo, float(a[0])), min(hi, float(a[-1]))
    if hi - lo < 2 * step:
      raise NotCheckable(f"flexion range {lo:.1f}-{hi:.1f} deg too short")
    g = np.arange(lo, hi + 0.5 * step, step)
    return g, np.interp(g, a, self.y)

  def rank_correlation(self, lo, hi):
    """Spearman rank correlation of y with flexion on the uniform flexion grid."""
    g, y = self.on_grid(lo, hi)
    ry = np.argsort(np.argsort(y, kind="stable"), kind="stable").astype(float)
    rg = np.arange(len(g), dtype=float)
    if np.ptp(ry) == 0:
      return 0.0
    return float(np.corrcoef(rg, ry)[0, 1])

  def angle_fraction(self, lo, hi, direction):
    """Fraction of the flexion range [lo, hi] over which y moves in `direction`."""
    g, y = self.on_grid(lo, hi)
    return float(np.mean(direction * np.diff(y) > 0))


def in_band(x, lo, hi):
  """x lies in the chapter's band [lo, hi] widened by ANGLE_TOL_DEG each side (one convention for
  every location: the chapter quotes angles in steps of 5°)."""
  return x is not None and lo - ANGLE_TOL_DEG <= x <= hi + ANGLE_TOL_DEG


def mag_ok(x, target):
  return abs(x - target) <= MAG_TOL * target


def monotone(values, direction):
  d = np.diff(np.asarray(values, dtype=float))
  return bool(np.all(direction * d > 0))


class Checker:
  def __init__(self, outdir):
    self.outdir = outdir
    self.fam, members = load_families(outdir)
    self.all = members
    self.ok_members = [m for m in members if m.ok and m.traj is not None]
    self.excluded = [m.name for m in members if not m.ok]
    refs = [m for m in self.ok_members if m.amplitude_N == 100.0 and m.duration_s == 0.1]
    self.ref = refs[0] if refs else None
    sens = os.path.join(outdir, "sensitivity.json")
    self.sens = json.load(open(sens)) if os.path.exists(sens) else None
    self.rows = []

  def family(self, family):
    ms = [m for m in by_family(self.ok_members, family)]
    if len(ms) < 2:
      raise NotCheckable(f"fewer than two completed members in the {family} family")
    return ms

  def need_ref(self):
    if self.ref is None:
      raise NotCheckable("reference member (A = 100 N, t0 = 0.1 s) missing or failed")
    return self.ref

  def curve(self, col, member=None, sign=1.0):
    return Curve(member or self.need_ref(), col, sign)

  def add(self, cid, fn):
    """Runs fn() -> Subs / EitherFrame; the table shows claims.yaml's wording and, when the
    claim is not reproduced, the sub-checks that failed with their values."""
    if cid not in CLAIM_BY_ID:
      raise KeyError(f"claims.py: claim id {cid} is checked but missing from {CLAIMS_YAML}")
    spec = CLAIM_BY_ID[cid]
    try:
      res = fn()
      verdict = REPRODUCED if res.ok else NOT_REPRODUCED
      measured = res.measured()
      reason = "" if res.ok else "failed: " + "; ".join(res.failures())
    except NotCheckable as e:
      verdict, measured, reason = NOT_CHECKABLE, "", str(e)
    if verdict != NOT_CHECKABLE and self.excluded:
      reason = "; ".join(x for x in (reason, "failed runs excluded: " + ", ".join(self.excluded)) if x)
    self.rows.append({"id": cid, "claim": spec["claim"], "source": spec["source"], "check": spec["check"],
                      "justification": spec["justification"], "measured": measured,
                      "verdict": verdict, "reason": reason})

  # ---- family helpers
  def family_values(self, family, fn):
    ms = self.family(family)
    return [m.value for m in ms], [fn(m) for m in ms]

  def ordered_on_grid(self, family, col, direction, sign=1.0, hi=90.0):
    """Fraction of grid angles where col(α) is strictly monotone in the family parameter."""
    ms = self.family(family)
    curves = [Curve(m, col, sign) for m in ms]
    good = total = 0
    for g in GRID_DEG[GRID_DEG <= hi]:
      vals = [c.at(g) for c in curves]
      if any(not np.isfinite(v) for v in vals):
        continue
      total += 1
      good += monotone(vals, direction)
    if total == 0:
      raise NotCheckable(f"{col}: no common flexion range")
    return good / total


class Subs:
  """The sub-checks of one claim: (name, passed or None for information, value string)."""

  def __init__(self):
    self.items = []

  def req(self, name, ok, value):
    self.items.append((name, bool(ok), value))
    return bool(ok)

  def info(self, name, value):
    self.items.append((name, None, value))

  @property
  def ok(self):
    return all(ok for _, ok, _ in self.items if ok is not None)

  def measured(self):
    return "; ".join(f"{n} {v}" for n, _, v in self.items)

  def failures(self):
    return [f"{n} {v}" for n, ok, v in self.items if ok is False]


# Velocity claims are judged in both frames (the chapter does not say which axes Figs.
# 1.11-1.15 use): femoral axes / JCS rates, and the tibia's own axes.
FRAMES = [("femoral/JCS", ""), ("tibial axes", "_T")]


def frame_col(col, suffix):
  """vx_mm_s -> vx_T_mm_s; flexion_rate_deg_s -> flexion_rate_T_deg_s."""
  if not suffix:
    return col
  stem, unit = col.rsplit("_", 2)[0], "_".join(col.rsplit("_", 2)[1:])
  return f"{stem}{suffix}_{unit}"


class EitherFrame:
  """A velocity claim: reproduced if every sub-check holds in at least one frame."""

  def __init__(self, per_frame):
    self.per_frame = per_frame  # [(frame name, Subs)]

  @property
  def ok(self):
    return any(s.ok for _, s in self.per_frame)

  def measured(self):
    return " | ".join(f"[{f}{' ✓' if s.ok else ''}] {s.measured()}" for f, s in self.per_frame)

  def failures(self):
    if self.ok:
      return []
    return [f"[{f}] " + ", ".join(s.failures()) for f, s in self.per_frame]


def both_frames(fn):
  """fn(suffix, Subs) fills the sub-checks for one frame."""
  def run():
    out = []
    for name, suffix in FRAMES:
      s = Subs()
      fn(suffix, s)
      out.append((name, s))
    return EitherFrame(out)
  return run


def check_all(ck):
  def claim(cid):
    """Registers fn(s) as the check of claim cid: fn fills the sub-checks s (a fresh Subs)."""
    def register(fn):
      def run():
        s = Subs()
        fn(s)
        return s
      ck.add(cid, run)
      return fn
    return register

  def rho_str(r):
    return f"ρ = {r:+.2f}"

  def first_crossing(s, name, c, direction, lo, hi, band_lo, band_hi):
    """Sub-check: c's first sign change (Curve.crossings) in [lo, hi] lies in the band ±tol
    (deg); returns the crossings."""
    x = c.crossings(direction, lo, hi)
    s.req(name, bool(x) and in_band(x[0], band_lo, band_hi), f"{fmt(x)}°" if x else f"no crossing in {lo}–{hi}°")
    return x

  # ---------------- Kinematics
  def k12(family):
    def fn(s):
      vals, t90 = ck.family_values(family, lambda m: m.time_to_90_s)
      if any(t is None for t in t90):
        raise NotCheckable("a member did not reach 90 deg")
      s.req(f"t(90°) over {family} {fmt(vals)}:", monotone(t90, -1), f"{fmt(t90, 4)} s")
    return fn
  claim("K1")(k12("amplitude"))
  claim("K2")(k12("duration"))

  @claim("K3")
  def k3(s):
    c = ck.curve("valgus_deg")
    a_pk, v_pk = c.argmax(0, 20)
    s.req("early valgus peak value", v_pk > 0, f"{v_pk:.3f}°")
    s.req("peak location (0–10° ±tol)", in_band(a_pk, 0, 10), f"{a_pk:.1f}°")
    r = c.rank_correlation(0, a_pk)
    s.req("rising before the peak (over flexion)", r >= RHO_MIN, rho_str(r))

  @claim("K4")
  def k4(s):
    first_crossing(s, "first valgus→varus crossing (25–45° ±tol)", ck.curve("valgus_deg"), -1, 1, 90, 25, 45)

  @claim("K5")
  def k5(s):
    c = ck.curve("valgus_deg")
    a_m, v_m = c.argmin(0, 90)
    end = c.y[-1]
    s.req("max varus location (45–70° ±tol)", in_band(a_m, 45, 70), f"{-v_m:.2f}° at {a_m:.1f}°")
    s.req("varus at 90° below the max", end > v_m, f"{-end:.2f}°")

  @claim("K6")
  def k6(s):
    ms = ck.family("duration")
    zc = [Curve(m, "valgus_deg").crossings(-1, 1, 90) for m in ms]
    if any(not z for z in zc):
      raise NotCheckable("a member has no zero crossing")
    zc = [z[0] for z in zc]
    mv = [-Curve(m, "valgus_deg").argmin(0, 90)[1] for m in ms]
    s.info("t0", f"{fmt([m.value for m in ms])} s")
    s.req("zero crossing increasing", monotone(zc, +1), f"{fmt(zc, 4)}°")
    s.req("max varus decreasing", monotone(mv, -1), f"{fmt(mv, 4)}°")

  @claim("K7")
  def k7(s):
    a_pk, g_pk = ck.curve("external_rotation_deg").argmax(0, 90)
    s.req("peak external rotation > 0", g_pk > 0, f"{g_pk:.2f}°")
    s.req("peak location (15–20° ±tol)", in_band(a_pk, 15, 20), f"{a_pk:.1f}°")

  @claim("K8")
  def k8(s):
    c = ck.curve("external_rotation_deg")
    a_pk, _ = c.argmax(0, 90)
    r = c.rank_correlation(a_pk, 90)
    s.req(f"γ falling from the peak ({a_pk:.1f}°) to 90°", r <= -RHO_MIN, rho_str(r))
    a_min, g_min = c.argmin(0, 90)
    s.req("largest internal rotation at 90° (−tol)", a_min >= 90 - ANGLE_TOL_DEG, f"{-g_min:.2f}° at {a_min:.1f}°")

  @claim("K9")
  def k9(s):
    for family in ("amplitude", "duration"):
      ms = ck.family(family)
      pk = [Curve(m, "external_rotation_deg").argmax(0, 90)[1] for m in ms]
      fin = [-Curve(m, "external_rotation_deg").argmin(0, 90)[1] for m in ms]
      s.req(f"{family} {fmt([m.value for m in ms])}: peak external increasing", monotone(pk, +1), f"{fmt(pk, 3)}°")
      s.req(f"{family}: max internal increasing", monotone(fin, +1), f"{fmt(fin, 3)}°")

  # ---------------- Contact
  @claim("C1")
  def c1(s):
    ref = ck.need_ref()
    lo = ref.liftoff_deg  # the first lateral lift-off
    s.req("lateral lift-off (66° ±tol)", lo is not None and abs(lo - LIFTOFF_CHAPTER_DEG) <= ANGLE_TOL_DEG,
          f"{fmt(lo, 4)}°")
    # "Both condyles stay in contact up to [it]; beyond it only the medial one does": the
    # lateral lift-off is the first change of contact and the last.
    changes = contact_changes(ref.event_list)
    s.req("the only change of contact", changes == [("liftoff_lateral", lo)],
          ", ".join(f"{n} {a:.1f}°" for n, a in changes) or "none")

  @claim("C2")
  def c2(s):
    vals = [m.liftoff_deg for m in ck.ok_members if m.liftoff_deg is not None]
    if len(vals) < 2:
      raise NotCheckable("fewer than two lift-off events")
    spread = max(vals) - min(vals)
    s.req(f"spread over {len(vals)} members ({min(vals):.2f}–{max(vals):.2f}°)", spread <= LIFTOFF_SPREAD_DEG,
          f"{spread:.2f}°")

  @claim("C3")
  def c3(s):
    for comp in ("medial", "lateral"):
      cy, cz = ck.curve(f"femoral_{comp}_y_mm"), ck.curve(f"femoral_{comp}_z_mm")
      hi = min(90.0, float(cy.a[-1]))
      ry, rz = cy.rank_correlation(0, hi), cz.rank_correlation(0, hi)
      s.req(f"{comp} y_F falling (posterior) over 0–{hi:.0f}°", ry <= -RHO_MIN, rho_str(ry))
      s.req(f"{comp} z_F rising (proximal)", rz >= RHO_MIN, rho_str(rz))

  @claim("C4")
  def c4(s):
    for comp in ("medial", "lateral"):
      rx, ry = np.ptp(ck.curve(f"femoral_{comp}_x_mm").y), np.ptp(ck.curve(f"femoral_{comp}_y_mm").y)
      s.req(f"{comp} range x / range y ≤ 0.25", rx <= 0.25 * ry, f"{rx:.2f} / {ry:.2f} mm")

  @claim("C5")
  def c5(s):
    for comp, sign, word in (("medial", +1, "rising (anterior)"), ("lateral", -1, "falling (posterior)")):
      c = ck.curve(f"tibial_{comp}_y_mm")
      hi = min(90.0, float(c.a[-1]))
      r = c.rank_correlation(15, hi)
      s.req(f"{comp} y′_T {word} over 15–{hi:.0f}°", sign * r >= RHO_MIN, rho_str(r))

  @claim("C6")
  def c6(s):
    ref_m = ck.need_ref()
    worst, where = 0.0, ""
    for m in ck.ok_members:
      for frame in ("femoral", "tibial"):
        for comp in ("medial", "lateral"):
          for ax in "xyz":
            col = f"{frame}_{comp}_{ax}_mm"
            cr, cm = Curve(ref_m, col), Curve(m, col)
            for g in GRID_DEG:
              d = abs(cr.at(g) - cm.at(g))
              if np.isfinite(d) and d > worst:
                worst, where = d, f"{m.name} {col} at {g:g}°"
    s.req(f"max deviation from the reference pathway ({where})", worst <= PATHWAY_OVERLAP_MM, f"{worst:.3f} mm")

  @claim("C7")
  def c7(s):
    c = ck.curve("N_medial_N")
    a_min, n_min = c.argmin(0, 30)
    a_max, n_max = c.argmax(30, 90)
    n0, n90 = c.y[0], c.y[-1]
    s.req("early minimum below N_m(0)", n_min < n0, f"{n_min:.1f} < {n0:.1f} N")
    s.req("early minimum location (0–15° ±tol)", in_band(a_min, 0, 15), f"{a_min:.1f}°")
    s.req("maximum location (60° ±tol)", in_band(a_max, 60, 60), f"{n_max:.1f} N at {a_max:.1f}°")
    s.req("N_m(90) below the maximum", n90 < n_max, f"{n90:.1f} N")

  @claim("C8")
  def c8(s):
    c = ck.curve("N_lateral_N")
    a_max, n_max = c.argmax(0, 90)
    s.req("maximum at extension (≤ tol)", a_max <= ANGLE_TOL_DEG, f"{n_max:.1f} N at {a_max:.1f}°")
    lo = ck.need_ref().liftoff_deg
    s.req("separation (lift-off event)", lo is not None, f"{fmt(lo, 4)}°")
    hi = lo if lo is not None else float(c.a[-1])
    r = c.rank_correlation(0, hi)
    s.req(f"falling over 0–{hi:.1f}° (over flexion)", r <= -RHO_MIN, rho_str(r))

  @claim("C9")
  def c9(s):
    for family in ("amplitude", "duration"):
      for comp in ("medial", "lateral"):
        f = ck.ordered_on_grid(family, f"N_{comp}_N", -1, hi=90 if comp == "medial" else 50)
        s.req(f"{family}/{comp}: grid fraction with N falling in the parameter", f >= ORDER_FRACTION, f"{f:.2f}")

  @claim("C10")
  def c10(s):
    nm = np.nanmax(ck.need_ref().col("N_medial_N"))
    nl = np.nanmax(ck.need_ref().col("N_lateral_N"))
    s.req("max N_medial > max N_lateral", nm > nl, f"{nm:.1f} N vs {nl:.1f} N")

  # ---------------- Velocities (both frames)
  def v1(suffix, s):
    c = ck.curve(frame_col("vx_mm_s", suffix))
    a_pk, v_pk = c.argmax(0, 40)
    s.req("lateral peak (15° ±tol)", v_pk > 0 and in_band(a_pk, 15, 15), f"{v_pk:.1f} mm/s at {a_pk:.1f}°")
    x = first_crossing(s, "first + → − crossing (30° ±tol)", c, -1, 5, 90, 30, 30)
    a_end, _ = c.argmin(x[0] if x else 0, 90)
    s.req("largest medial velocity at 90° (−tol)", a_end >= 90 - ANGLE_TOL_DEG, f"at {a_end:.1f}°")
  ck.add("V1", both_frames(v1))

  def v2(suffix, s):
    c = ck.curve(frame_col("vy_mm_s", suffix), sign=-1.0)
    a_pk, v_pk = c.argmax(0, 90)
    end = c.y[-1]
    s.req("posterior peak (50–60° ±tol)", in_band(a_pk, 50, 60), f"{v_pk:.1f} mm/s at {a_pk:.1f}°")
    s.req("at 90° within 70–100 % of the peak", 0.7 * v_pk <= end <= v_pk, f"{end:.1f} mm/s")
  ck.add("V2", both_frames(v2))

  def v3(suffix, s):
    c = ck.curve(frame_col("flexion_rate_deg_s", suffix))
    f = c.angle_fraction(0, 90, +1)
    s.req("rising, fraction of the flexion range", f >= MONO_FRACTION, f"{f:.2f}")
    a_pk, _ = c.argmax(0, 90)
    s.req("maximum at 90° (−tol)", a_pk >= 90 - ANGLE_TOL_DEG, f"at {a_pk:.1f}°")
  ck.add("V3", both_frames(v3))

  def v4(suffix, s):
    c = ck.curve(frame_col("valgus_rate_deg_s", suffix))
    a_vp, v_vp = c.argmax(0, 20)
    s.req("valgus-velocity peak (5° ±tol)", v_vp > 0 and in_band(a_vp, 5, 5), f"{v_vp:.1f}°/s at {a_vp:.1f}°")
    first_crossing(s, "zero (10° ±tol)", c, -1, 0.5, 30, 10, 10)
    a_rp, v_rp = c.argmin(20, 70)
    s.req("varus-velocity peak (40–50° ±tol)", v_rp < 0 and in_band(a_rp, 40, 50), f"{-v_rp:.1f}°/s at {a_rp:.1f}°")
    first_crossing(s, "zero (60–65° ±tol)", c, +1, 40, 85, 60, 65)
    s.req("valgus velocity at 90°", c.y[-1] > 0, f"{c.y[-1]:.1f}°/s")
  ck.add("V4", both_frames(v4))

  def v5(suffix, s):
    c = ck.curve(frame_col("external_rotation_rate_deg_s", suffix))
    a_i1, v_i1 = c.argmin(0, 5)
    s.req("early internal peak (2° ±tol)", v_i1 < 0 and in_band(a_i1, 2, 2), f"{-v_i1:.1f}°/s at {a_i1:.2f}°")
    a_e, v_e = c.argmax(0, 20)
    s.req("external peak (8° ±tol)", v_e > 0 and in_band(a_e, 8, 8), f"{v_e:.1f}°/s at {a_e:.1f}°")
    first_crossing(s, "zero (20° ±tol)", c, -1, a_e, 60, 20, 20)
    a_i2, v_i2 = c.argmin(25, 90)
    s.req("internal max (45–60° ±tol)", in_band(a_i2, 45, 60), f"{-v_i2:.1f}°/s at {a_i2:.1f}°")
  ck.add("V5", both_frames(v5))

  def v6(suffix, s):
    for family in ("amplitude", "duration"):
      fp = ck.ordered_on_grid(family, frame_col("vy_mm_s", suffix), +1, sign=-1.0)
      ff = ck.ordered_on_grid(family, frame_col("flexion_rate_deg_s", suffix), +1)
      s.req(f"{family}: posterior, grid fraction increasing", fp >= ORDER_FRACTION, f"{fp:.2f}")
      s.req(f"{family}: flexion, grid fraction increasing", ff >= ORDER_FRACTION, f"{ff:.2f}")
  ck.add("V6", both_frames(v6))

  # ---------------- Ligaments
  def F(name):
    return ck.curve(ligament_column(name))

  def zero_tol(c):
    return max(ZERO_ABS_N, ZERO_FRACTION * float(np.max(c.y)))

  def max_at_extension(s, c, newtons):
    """Sub-checks "maximum at extension" and "maximum ≈ newtons N"; returns (angle °, force N)."""
    a_pk, f_pk = c.argmax()
    s.req("maximum at extension (≤ tol)", a_pk <= ANGLE_TOL_DEG, f"at {a_pk:.1f}°")
    s.req(f"maximum ≈ {newtons} N (±50 %)", mag_ok(f_pk, newtons), f"{f_pk:.1f} N")
    return a_pk, f_pk

  @claim("L1")
  def l1(s):
    c = F("ACL anterior")
    a_pk, f_pk = c.argmax()
    s.req("slack at extension (F1(0) ≤ zero_abs)", c.y[0] <= ZERO_ABS_N, f"{c.y[0]:.2f} N")
    s.req("maximum at 90° (−tol)", a_pk >= 90 - ANGLE_TOL_DEG, f"at {a_pk:.1f}°")
    s.req("maximum ≈ 70 N (±50 %)", mag_ok(f_pk, 70), f"{f_pk:.1f} N")

  @claim("L2")
  def l2(s):
    c = F("ACL posterior")
    nz = c.a[c.y > ZERO_ABS_N]
    a_zero = float(nz[-1]) if len(nz) else 0.0
    max_at_extension(s, c, 50)
    s.req("slack from ≈ 75° (±tol)", in_band(a_zero, 75, 75), f"last > {ZERO_ABS_N:g} N at {a_zero:.1f}°")

  @claim("L3")
  def l3(s):
    c1_, c2_ = F("ACL anterior"), F("ACL posterior")
    g = np.arange(0.0, 20.0, 0.25)
    frac = float(np.mean([c2_.at(x) > c1_.at(x) for x in g]))
    s.req("F2 > F1 over 0–20° (fraction of the range)", frac == 1.0, f"{frac:.0%}")

  @claim("L4")
  def l4(s):
    c = F("PCL anterior")
    a_pk, f_pk = c.argmax()
    s.req("≈ 0 at extension (≤ 10 % of max)", c.y[0] <= zero_tol(c), f"{c.y[0]:.2f} N")
    s.req("maximum location (60° ±tol)", in_band(a_pk, 60, 60), f"at {a_pk:.1f}°")
    s.req("maximum ≈ 150 N (±50 %)", mag_ok(f_pk, 150), f"{f_pk:.1f} N")
    s.req("F3(90) below the maximum", c.y[-1] < f_pk, f"{c.y[-1]:.1f} N")

  @claim("L5")
  def l5(s):
    c = F("PCL posterior")
    a_zero = c.first_at_or_below(ZERO_ABS_N)
    max_at_extension(s, c, 50)
    s.req("slack from ≈ 10° (±tol)", in_band(a_zero, 10, 10), f"first ≤ {ZERO_ABS_N:g} N at {fmt(a_zero)}°")

  @claim("L6")
  def l6(s):
    c = F("MCL oblique")
    a_pk, f_pk = c.argmax()
    late = float(np.max(c.window(20, 90)[1]))
    s.req("maximum near extension (≈ 5°, ≤ 10°)", a_pk <= 10, f"at {a_pk:.1f}°")
    s.req("maximum ≈ 30 N (±50 %)", mag_ok(f_pk, 30), f"{f_pk:.1f} N")
    s.req("very small beyond 20° (≤ 10 % of max)", late <= zero_tol(c), f"max {late:.2f} N")

  @claim("L7")
  def l7(s):
    c = F("MCL anterior")
    early = float(np.max(c.window(0, 20)[1]))
    a_pk, f_pk = c.argmax()
    s.req("≈ 0 over 0–20° (≤ 10 % of max)", early <= zero_tol(c), f"max {early:.2f} N")
    s.req("maximum location (40–50° ±tol)", in_band(a_pk, 40, 50), f"at {a_pk:.1f}°")
    s.req("maximum ≈ 100 N (±50 %)", mag_ok(f_pk, 100), f"{f_pk:.1f} N")
    s.req("≈ 0 at 90°", c.y[-1] <= zero_tol(c), f"{c.y[-1]:.1f} N")

  @claim("L8")
  def l8(s):
    c = F("MCL deep")
    f45 = c.at(45.0)
    _, late = c.window(45, 90)
    ratio = float(np.max(late) / max(np.min(late), 1e-9))
    s.req("F7(45°) ≈ 90 N (±50 %)", mag_ok(f45, 90), f"{f45:.1f} N")
    s.req("roughly level over 45–90° (max/min ≤ 1.5)", ratio <= 1.5, f"{ratio:.2f}")

  def integral(name, lo=0.0, hi=90.0):
    a, y = F(name).window(lo, hi)
    return float(np.trapz(y, a))

  @claim("L9")
  def l9(s):
    d, a, o = integral("MCL deep"), integral("MCL anterior"), integral("MCL oblique")
    s.req("∫F dα deep > anterior > oblique", d > a > o, f"{d:.0f} > {a:.0f} > {o:.0f} N·deg")

  @claim("L10")
  def l10(s):
    c = F("LCL")
    _, f_pk = max_at_extension(s, c, 90)
    a_small = c.first_at_or_below(ZERO_FRACTION * f_pk)
    s.req("force only up to 45–60° (±tol): first ≤ 10 % of max", in_band(a_small, 45, 60), f"at {fmt(a_small)}°")

  @claim("L11")
  def l11(s):
    ref_m = ck.need_ref()
    if len(ck.ok_members) < 2:
      raise NotCheckable("fewer than two completed members")

    def shares(m):
      cols = [Curve(m, ligament_column(n)) for n in LIGAMENTS]
      F_ = np.array([[c.at(g) for g in GRID_DEG] for c in cols])
      tot = np.nansum(F_, axis=0)
      return F_ / np.where(tot > 0, tot, np.nan)
    s_ref = shares(ref_m)
    worst, where = 0.0, ""
    for m in ck.ok_members:
      d = np.abs(shares(m) - s_ref)
      if np.any(np.isfinite(d)) and np.nanmax(d) > worst:
        worst = float(np.nanmax(d))
        j, g = np.unravel_index(np.nanargmax(d), d.shape)
        where = f"{m.name}, {LIGAMENTS[j]} at {GRID_DEG[g]:g}°"
    s.req(f"max change of a share ({where})", worst <= SHARE_OVERLAP, f"{worst:.3f}")

  @claim("L12")
  def l12(s):
    ints = {n: integral(n, 20, 90) for n in LIGAMENTS}
    top = sorted(ints, key=ints.get, reverse=True)[:3]
    s.req("top three ∫F dα over 20–90°", set(top) == {"PCL anterior", "MCL anterior", "MCL deep"},
          ", ".join(f"{n} ({ints[n]:.0f})" for n in top))

  # ---------------- Sensitivity statements
  @claim("S1")
  def s1(s):
    if not ck.sens or not ck.sens.get("force_guess"):
      raise NotCheckable("no sensitivity.json force-guess runs")
    rows = ck.sens["force_guess"]
    failed = [r["name"] for r in rows if not r.get("ok")]
    s.req("every perturbed run completed", not failed, ", ".join(failed) or "all")
    ok_rows = [r for r in rows if r.get("ok")]
    if ok_rows:
      worst = max(r["max_abs_diff_flexion_deg"] for r in ok_rows)
      wn = max(max(r["max_abs_diff_N_medial_N"], r["max_abs_diff_N_lateral_N"]) for r in ok_rows)
      s.info("guesses (medial, lateral) N", ", ".join(f"({r['medial_N']:g}, {r['lateral_N']:g})" for r in rows))
      s.req("max |Δflexion|", worst < INSENSITIVE_DEG, f"{worst:.3g}°")
      s.info("max |ΔN|", f"{wn:.3g} N")

  @claim("S2")
  def s2(s):
    if not ck.sens or not ck.sens.get("contact_offset"):
      raise NotCheckable("no sensitivity.json contact-offset runs")
    rows = ck.sens["contact_offset"]
    failed = [r for r in rows if not r.get("ok")]
    parts = [f"{r['offset_mm']:g} mm: " + (f"{r['max_abs_diff_flexion_deg']:.3g}°" if r.get("ok") else "failed")
             for r in rows]
    sensitive = bool(failed) or any(r.get("max_abs_diff_flexion_deg", 0) > SENSITIVE_DEG for r in rows)
    s.req("|Δflexion| per offset (some > sensitive_deg, or a failure)", sensitive, "; ".join(parts))


def write_tables(outdir, rows):
  with open(os.path.join(outdir, "claims.json"), "w") as f:
    json.dump(rows, f, indent=2, ensure_ascii=False)
  with open(os.path.join(outdir, "claims.csv"), "w", newline="") as f:
    w = csv.DictWriter(f, fieldnames=["id", "claim", "source", "check", "justification", "measured",
                                      "verdict", "reason"])
    w.writeheader()
    w.writerows(rows)
  with open(os.path.join(outdir, "claims.md"), "w") as f:
    f.write("| id | claim | source | check (tolerance band) | measured | verdict | reason |\n"
            "|---|---|---|---|---|---|---|\n")
    for r in rows:
      cells = [str(r[k]).replace("|", "\\|")
               for k in ("id", "claim", "source", "check", "measured", "verdict", "reason")]
      f.write("| " + " | ".join(cells) + " |\n")


def check_run_directory(option, outdir):
  """What build_claims reads, checked before it writes anything: the run directory, its
  families.json with the runs it lists, and sensitivity.json when present (BadInput naming option)."""
  from family_data import load_families_checked
  load_families_checked(option, outdir)
  sens = os.path.join(outdir, "sensitivity.json")
  if os.path.exists(sens):
    tool_input.checked(_load_json, option, sens)


def _load_json(path):
  with open(path, encoding="utf-8") as f:
    return json.load(f)


def build_claims(outdir):
  ck = Checker(outdir)
  check_all(ck)
  missing = [c["id"] for c in CLAIMS if c["id"] not in {r["id"] for r in ck.rows}]
  if missing:
    raise KeyError(f"claims.py: claims {missing} of {CLAIMS_YAML} have no check")
  write_tables(outdir, ck.rows)
  return ck.rows


def main(argv=None):
  ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
  ap.add_argument("--out", required=True, help="directory written by run_families.py")
  args = ap.parse_args(argv)
  check_run_directory("--out", args.out)
  rows = build_claims(args.out)
  for r in rows:
    print(f"{r['id']:4s} {r['verdict']:15s} {r['measured']}")
  return 0


if __name__ == "__main__":
  sys.exit(tool_input.exit_code("claims", main))
