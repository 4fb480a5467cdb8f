#!/usr/bin/python3
"""The claim-check machinery of reports/claims.py on synthetic curves with known answers:

  - a trend judged over flexion, not over output steps: α(t) = 90 (t/T)^3 moves slowly at
    first, y = −α + an oscillation of 6° period whose slope beats the trend: the rank
    correlation over flexion is close to −1 and the claim "decreasing" passes, although
    barely two thirds of the output steps decrease (the old time-weighted rule failed it);
  - a monotone curve has angle fraction 1, an increasing one ρ = +1;
  - a knee that flexes and swings back is read while it flexes (up to its largest flexion);
  - the reason of a failed claim names the failing sub-check and its value;
  - claims.yaml loading refuses a claim without a field, naming the field;
  - the tibial-frame velocity columns preserve the speed (a rotation) and equal the JCS rates
    at the reference pose.
"""
import json
import os
import sys
import tempfile

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.dont_write_bytecode = True
sys.path.insert(0, os.path.join(ROOT, "reports"))
from py_test_support import finish  # noqa: E402
import claims  # noqa: E402
from family_data import add_tibial_frame_columns, tibial_axes_in_F  # noqa: E402


class FakeMember:
  def __init__(self, cols):
    self.name = "synthetic"
    self.cols = cols

  def col(self, name):
    return self.cols[name]


def rotation_against_reference():
  """tibial_axes_in_F against kneedyn's own R_FT (solver/rotation.hpp) through the stored
  reference: an active contact's point in F is R0 + R_FT times its point in T, to the gap
  (< 1e-9 mm there). A transposed matrix or a flipped angle moves it by millimetres."""
  with open(os.path.join(ROOT, "reference-data", "references", "chapter_impact.json"), encoding="utf-8") as f:
    classes = json.load(f)["solution"]["classes"]
  pos = classes["positions"]
  points = classes["contact_points"]
  worst, compared = 0.0, 0
  for p, c in zip(pos["values"], points["values"]):
    q = dict(zip(pos["names"], p))
    cp = dict(zip(points["names"], c))
    axes = tibial_axes_in_F(q["flexion_deg"], q["valgus_deg"], q["external_rotation_deg"])
    for side in ("medial", "lateral"):
      p_T = [cp[f"tibial_{side}_{a}_mm"] for a in "xyz"]
      p_F = [cp[f"femoral_{side}_{a}_mm"] for a in "xyz"]
      if any(v is None for v in p_T + p_F):
        continue  # separated: no contact point
      for i, r0 in enumerate((q["x0_mm"], q["y0_mm"], q["z0_mm"])):
        mapped = r0 + sum(float(axes[k][i]) * p_T[k] for k in range(3))
        worst = max(worst, abs(mapped - p_F[i]))
      compared += 1
  if compared < 10:
    return [f"rotation check: only {compared} contact points in the reference"]
  return [] if worst < 1e-6 else [f"tibial_axes_in_F: p_F − (R0 + R_FT p_T) up to {worst:.3g} mm "
                                  f"over {compared} contact points of the stored reference"]


def main():
  errors = []
  t = np.linspace(0.0, 1.0, 1001)
  alpha = 90.0 * t ** 3
  y = -alpha + 3.0 * np.sin(2 * np.pi * alpha / 6.0)
  c = claims.Curve(FakeMember({"flexion_deg": alpha, "y": y}), "y")
  rho = c.rank_correlation(0, 90)
  steps_down = float(np.mean(np.diff(y) < 0))
  if not rho <= -0.95:
    errors.append(f"oscillating decreasing curve: rho {rho:.3f} (expected <= -0.95)")
  if not steps_down < 0.9:
    errors.append(f"synthetic case not hard enough: {steps_down:.2f} of output steps decrease")
  mono = claims.Curve(FakeMember({"flexion_deg": alpha, "y": 5.0 + alpha ** 2}), "y")
  if mono.angle_fraction(0, 90, +1) != 1.0 or abs(mono.rank_correlation(10, 80) - 1.0) > 1e-12:
    errors.append("monotone increasing curve: angle fraction / rho not 1")

  # A knee that swings back (gravity off: flexes to 40°, returns to 10°) is read while it
  # flexes: y = α on the way up and 100 − α on the way back has its peak over the flexing
  # part at 40° (y = 40), not at 10° on the way back (y = 90), and its value at 20° is the
  # flexing one (20).
  up = np.linspace(0.0, 40.0, 41)
  back = np.linspace(39.0, 10.0, 30)
  swing = claims.Curve(FakeMember({"flexion_deg": np.concatenate([up, back]),
                                   "y": np.concatenate([up, 100.0 - back])}), "y")
  at_peak, peak = swing.argmax()
  if abs(at_peak - 40.0) > 1e-12 or abs(peak - 40.0) > 1e-12 or abs(swing.at(20.0) - 20.0) > 1e-12:
    errors.append(f"swinging curve read on the way back: peak {peak} at {at_peak}°, value at 20° {swing.at(20.0)}")

  s = claims.Subs()
  s.req("peak location (15° ±tol)", False, "2.3°")
  s.req("sign", True, "+")
  if s.ok or s.failures() != ["peak location (15° ±tol) 2.3°"]:
    errors.append(f"Subs failures {s.failures()}")

  with tempfile.NamedTemporaryFile("w", suffix=".yaml", delete=False) as f:
    f.write("tolerances: {}\nclaims:\n- {id: X1, claim: c, source: s, check: k}\n")
  try:
    claims.load_claims(f.name)
    errors.append("a claim without 'justification' was accepted")
  except ValueError as e:
    if "justification" not in str(e):
      errors.append(f"message does not name the field: {e}")
  finally:
    os.remove(f.name)

  rng = np.random.default_rng(1)
  n = 50
  cols = {"flexion_deg": rng.uniform(0, 90, n), "valgus_deg": rng.uniform(-5, 5, n),
          "external_rotation_deg": rng.uniform(-20, 5, n), "vx_mm_s": rng.normal(size=n),
          "vy_mm_s": rng.normal(size=n), "vz_mm_s": rng.normal(size=n),
          "omega_x_T_deg_s": rng.normal(size=n), "omega_y_T_deg_s": rng.normal(size=n),
          "omega_z_T_deg_s": rng.normal(size=n)}
  add_tibial_frame_columns(cols)
  sp_f = np.sqrt(cols["vx_mm_s"] ** 2 + cols["vy_mm_s"] ** 2 + cols["vz_mm_s"] ** 2)
  sp_t = np.sqrt(cols["vx_T_mm_s"] ** 2 + cols["vy_T_mm_s"] ** 2 + cols["vz_T_mm_s"] ** 2)
  if np.max(np.abs(sp_f - sp_t)) > 1e-12:
    errors.append("tibial-frame velocity is not a rotation of the femoral one")
  ref = {k: np.zeros(1) for k in cols}
  ref.update({"vx_mm_s": np.array([1.0]), "vy_mm_s": np.array([2.0]), "vz_mm_s": np.array([3.0])})
  add_tibial_frame_columns(ref)  # reference pose: T parallel to F
  if abs(ref["vx_T_mm_s"][0] - 1.0) + abs(ref["vy_T_mm_s"][0] - 2.0) + abs(ref["vz_T_mm_s"][0] - 3.0) > 1e-12:
    errors.append("tibial-frame velocity differs from the femoral one at the reference pose")
  errors += rotation_against_reference()

  return finish(errors, "claims_checks_test: FAIL:", f"claims_checks_test: {'ok' if not errors else 'FAILED'} "
                f"(rho {rho:.3f}, output steps decreasing {steps_down:.2f})")


if __name__ == "__main__":
  sys.exit(main())
