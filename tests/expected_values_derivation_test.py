#!/usr/bin/python3
"""A second, independent derivation of the expected values typed into
tests/expected_values_test.cpp, checked against those typed values to their printed precision.

  expected_values_derivation_test.py [--root DIR] [--expected FILE]

From the repository's own data alone (the scene reference-data/scenes/chapter_impact.yaml and
the parameter set it loads, Tables 1.1-1.3 as reference-data/chapter_knee.yaml stores them)
and the formulas of docs/model.md, written out here with numpy and no kneedyn code:

  * the reference pose R0 (docs/model.md §6): alpha, beta, gamma and y0 as stored, x0 and z0
    from the two sphere-on-plane contact conditions (docs/model.md §4, closed form), which are
    linear in (x0, z0) at R = I;
  * the contact points in F (C - r n) and in T (R^T (P - R0));
  * each element's L_ref = |femoral - (R0 + R tibial)|, L0 = L_ref / e (Eq. 1.16) and its
    tension from the published law (Eq. 1.14, docs/model.md §5; first column k_lin);
  * the consistent initial normal forces at rest (docs/model.md §6, §8): the Newton-Euler
    equations with the hidden constraint G nu_dot = 0 (at rest the velocity terms vanish),
    one 8x8 linear solve [[M, G^T], [G, 0]] (nu_dot, N) = (f, 0).

The typed values are parsed from FILE (default tests/expected_values_test.cpp); each must agree
with the derivation within half a unit in its last printed decimal (kElements' columns to the
decimals the C++ test checks them to). Before the typed values, the comparison runs on the
derivation rounded to each value's decimals (must pass) and moved by two units in the last
decimal (must be flagged), so the test cannot pass by comparing nothing. Exit 0 when all
agree, 1 otherwise, 2 on bad arguments or unreadable data.
"""
import argparse
import os
import re
import sys

import numpy as np
import yaml

sys.dont_write_bytecode = True  # keep the source tree clean
from py_test_support import finish  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SCENE = os.path.join("reference-data", "scenes", "chapter_impact.yaml")
EPS1 = 0.03  # the law's ε1 (Eq. 1.14, docs/model.md §5)


class BadInput(Exception):
  pass


# ---------------------------------------------------------------- the derivation (mm, N, kg, s)

def load_knee(root):
  """The scene and its parameter set (mm, degrees as stored)."""
  scene_path = os.path.join(root, SCENE)
  with open(scene_path, encoding="utf-8") as f:
    scene = yaml.safe_load(f)
  params_path = os.path.normpath(os.path.join(os.path.dirname(scene_path), scene["parameter_set"]))
  if os.path.commonpath([os.path.abspath(params_path), os.path.abspath(root)]) != os.path.abspath(root):
    raise BadInput(f"parameter_set = '{scene['parameter_set']}': outside the repository")
  with open(params_path, encoding="utf-8") as f:
    knee = yaml.safe_load(f)
  if scene.get("ligament_law", "published") != "published":
    raise BadInput(f"ligament_law = '{scene['ligament_law']}': this derivation writes out the published law only")
  if scene.get("contacts") != ["medial", "lateral"]:
    raise BadInput(f"contacts = {scene.get('contacts')}: expected [medial, lateral]")
  return scene, knee


def rotation_FT(alpha, beta, gamma):
  """Eq. 1.3 as docs/model.md §2 writes it (takes T components to F components)."""
  sa, ca, sb, cb, sg, cg = np.sin(alpha), np.cos(alpha), np.sin(beta), np.cos(beta), np.sin(gamma), np.cos(gamma)
  return np.array([[sb * cg, sb * sg, cb],
                   [-ca * sg - sa * cb * cg, ca * cg - sa * cb * sg, sa * sb],
                   [sa * sg - ca * cb * cg, -sa * cg - ca * cb * sg, ca * sb]])


def plane_normal_T(tibial):
  """Unit normal of z' = mx x' + my y' + c towards the femur, and the plane's offset d (mm)."""
  mx, my, c = tibial["slope_x"], tibial["slope_y"], tibial["offset_mm"]
  s = np.sqrt(1.0 + mx * mx + my * my)
  return np.array([-mx, -my, 1.0]) / s, c / s


def derive(knee):
  """Every quantity tests/expected_values_test.cpp types in, from docs/model.md §4-§8."""
  pose = knee["reference_pose"]
  alpha, beta, gamma = (np.radians(pose[k]) for k in ("alpha_deg", "beta_deg", "gamma_deg"))
  y0 = pose["y0_mm"]
  R = rotation_FT(alpha, beta, gamma)
  comps = [knee["compartments"][c] for c in ("medial", "lateral")]
  for c in comps:
    if c["femoral_surface"]["type"] != "sphere_cap" or c["tibial_surface"]["type"] != "plane":
      raise BadInput("compartments: the closed form needs sphere_cap on plane")
  # Gap φ = n·(C − R0) − d − r = 0 (docs/model.md §4), n = R n̂′: linear in R0; y0 held.
  A, b = [], []
  for c in comps:
    n = R @ plane_normal_T(c["tibial_surface"])[0]
    d = plane_normal_T(c["tibial_surface"])[1]
    C = np.array(c["femoral_surface"]["centre_mm"], dtype=float)
    r = c["femoral_surface"]["radius_mm"]
    A.append([n[0], n[2]])
    b.append(n @ C - d - r - n[1] * y0)
  x0, z0 = np.linalg.solve(np.array(A), np.array(b))
  R0 = np.array([x0, y0, z0])

  contacts = []
  for c in comps:
    n_T, _ = plane_normal_T(c["tibial_surface"])
    n = R @ n_T
    P_F = np.array(c["femoral_surface"]["centre_mm"], dtype=float) - c["femoral_surface"]["radius_mm"] * n
    P_T = R.T @ (P_F - R0)
    contacts.append({"F": P_F, "T": P_T, "n_F": n, "n_T": n_T})

  elements = {}
  f_F = np.array(knee["gravity"]["direction_F"], dtype=float)
  f_F = f_F / np.linalg.norm(f_F) * knee["body"]["mass_kg"] * knee["gravity"]["magnitude_m_s2"]  # N
  m_T = np.zeros(3)  # N mm, about the centre of mass, T components
  for lig in knee["ligaments"]:
    A_F = np.array(lig["femoral_mm"], dtype=float)
    r_T = np.array(lig["tibial_mm"], dtype=float)
    u = A_F - (R0 + R @ r_T)
    L_ref = np.linalg.norm(u)
    L0 = L_ref / lig["extension_ratio"]  # Eq. 1.16
    L = L_ref  # at the reference pose
    eps = (L - L0) / L0  # Eq. 1.15
    if eps <= 0.0:
      F = 0.0
    elif eps <= 2.0 * EPS1:
      F = lig["k_parabolic_N_mm2"] * (L - L0) ** 2
    else:
      F = lig["k_linear_N_mm"] * (L - (1.0 + EPS1) * L0)
    elements[lig["name"]] = (L_ref, L0, F)
    force_F = F * u / L  # on the tibia, towards the femur
    f_F += force_F
    m_T += np.cross(r_T, R.T @ force_F)

  # At rest (ν = 0): M ν̇ = f − Gᵀ N, G ν̇ = 0 (the hidden constraint; the Ġ ν and ω′ × I ω′
  # terms vanish), ν = (Ṙ0 in F, ω′ in T). The pulse is zero at t = 0 for every shape
  # (docs/model.md §7). Row i of G: φ̇_i = −(n·Ṙ0 + ω′·(r_P × n̂′)) (docs/model.md §4:
  # force −N n at the tibial contact point r_P). Lengths in m for consistent units.
  mass = knee["body"]["mass_kg"]
  inertia = np.array(knee["body"]["principal_inertia_kg_m2"], dtype=float)
  M = np.diag([mass, mass, mass, *inertia])
  G = np.array([np.concatenate([c["n_F"], np.cross(c["T"] * 1e-3, c["n_T"])]) for c in contacts])
  kkt = np.zeros((8, 8))
  kkt[:6, :6] = M
  kkt[:6, 6:] = G.T
  kkt[6:, :6] = G
  rhs = np.concatenate([f_F, m_T * 1e-3, np.zeros(2)])
  sol = np.linalg.solve(kkt, rhs)
  return {"R0": R0, "angles": (alpha, beta, gamma), "contacts": contacts, "elements": elements,
          "normal_forces": sol[6:]}


# ---------------------------------------------------------------- the typed values

NUM = r"(-?\d+\.\d+)"


def decimals(text):
  return len(text.split(".")[1])


def parse_expected(source):
  """[(label, typed text, decimals checked, key into the derivation)] from the C++ test."""
  out = []
  for coord, text, dec in re.findall(r"MToMm\(q\(k([XYZ]0)\)\),\s*" + NUM + r",\s*HalfUlp\((\d+)\)", source):
    out.append((f"R0 {coord} (mm)", text, max(decimals(text), int(dec)), ("R0", "XYZ".index(coord[0]))))
  for frame in ("F", "T"):
    m = re.search(r"expected_" + frame + r"\[2\]\s*=\s*\{(.*?)\};", source, re.S)
    if m:
      vecs = re.findall(r"Vector3d\(\s*" + NUM + r",\s*" + NUM + r",\s*" + NUM + r"\)", m.group(1))
      for i, vec in enumerate(vecs):
        for k, text in enumerate(vec):
          out.append((f"{('medial', 'lateral')[i]} contact point in {frame}, component {k} (mm)", text,
                      decimals(text), ("contact", i, frame, k)))
  checked = dict(re.findall(r"e\.(L_ref_mm|L0_mm|F_N),\s*HalfUlp\((\d+)\)", source))
  m = re.search(r"kElements\[12\]\s*=\s*\{(.*?)\};", source, re.S)
  if m:
    for name, lref, l0, f in re.findall(r'\{"([^"]+)",\s*' + NUM + r",\s*" + NUM + r",\s*" + NUM + r"\}", m.group(1)):
      for col, text, unit, j in (("L_ref_mm", lref, "mm", 0), ("L0_mm", l0, "mm", 1), ("F_N", f, "N", 2)):
        out.append((f"{name} {col.split('_')[0]} ({unit})", text,
                    max(decimals(text), int(checked.get(col, 0))), ("element", name, j)))
  for i, text in re.findall(r"EXPECT_NEAR\(acc\.normal_force\[(\d)\],\s*" + NUM, source):
    out.append((f"{('medial', 'lateral')[int(i)]} normal force at rest (N)", text, decimals(text),
                ("N", int(i))))
  return out


def derived_value(d, key):
  if key[0] == "R0":
    return d["R0"][key[1]]
  if key[0] == "contact":
    return d["contacts"][key[1]][key[2]][key[3]]
  if key[0] == "element":
    if key[1] not in d["elements"]:
      return None
    return d["elements"][key[1]][key[2]]
  return d["normal_forces"][key[1]]


def disagreements(d, expected):
  """Each typed value farther from the derivation than half a unit in its checked decimal."""
  errors = []
  for label, text, dec, key in expected:
    value = derived_value(d, key)
    if value is None:
      errors.append(f"{label}: no such element in the parameter set")
      continue
    tol = 0.5 * 10.0 ** (-dec) * (1.0 + 1e-6)
    if abs(float(text) - value) > tol:
      errors.append(f"{label}: typed {text}, derived {value:.{dec + 3}f} (|diff| {abs(float(text) - value):.2e} > {tol:.1e})")
  return errors


def self_check(d, expected):
  """The derivation rounded to each value's checked decimals must pass, and moved by ±2 units in
  that decimal must be flagged (the typed values play no part: a wrong one cannot hide here)."""
  errors = []
  for label, _, dec, key in expected:
    value = derived_value(d, key)
    if value is None:
      continue  # reported by disagreements()
    rounded = round(value, dec)
    for units in (0, 2, -2):
      planted = (label, f"{rounded + units * 10.0 ** (-dec):.{dec}f}", dec, key)
      flagged = bool(disagreements(d, [planted]))
      if flagged != (units != 0):
        errors.append(f"self-check: {label} at {planted[1]} {'flagged' if flagged else 'not flagged'}")
  return errors


def main():
  parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
  parser.add_argument("--root", default=ROOT, help="repository root (default: this checkout)")
  parser.add_argument("--expected", default=None,
                      help="the C++ test with the typed values (default: ROOT/tests/expected_values_test.cpp)")
  args = parser.parse_args()
  prog = "expected_values_derivation_test"
  if not os.path.isdir(args.root):
    print(f"{prog}: --root = '{args.root}': not a directory", file=sys.stderr)
    return 2
  expected_path = args.expected or os.path.join(args.root, "tests", "expected_values_test.cpp")
  try:
    with open(expected_path, encoding="utf-8") as f:
      source = f.read()
  except OSError as e:
    print(f"{prog}: --expected = '{expected_path}': {e.strerror}", file=sys.stderr)
    return 2
  try:
    d = derive(load_knee(args.root)[1])
  except (OSError, KeyError, TypeError, yaml.YAMLError, BadInput) as e:
    print(f"{prog}: cannot derive from {SCENE}: {e}", file=sys.stderr)
    return 2
  expected = parse_expected(source)
  # 3 R0 coordinates, 12 contact point components, 36 element columns, 2 forces.
  if len(expected) != 53:
    print(f"{prog}: --expected = '{expected_path}': parsed {len(expected)} typed values, expected 53", file=sys.stderr)
    return 2
  errors = self_check(d, expected)
  if errors:
    return finish(errors, f"{prog}:", f"{prog}: the comparison is broken")
  alpha, beta, gamma = d["angles"]
  if not (alpha == 0.0 and gamma == 0.0 and abs(beta - np.pi / 2.0) < 1e-15):
    errors.append(f"reference angles (alpha, beta, gamma) = {d['angles']}: expected (0, pi/2, 0) (docs/model.md §6)")
  for i, c in enumerate(d["contacts"]):
    gap_check = np.linalg.norm(c["F"] - (d["R0"] + c["T"]))  # the points coincide at R = I
    if gap_check > 1e-9:
      errors.append(f"contact {i}: femoral and tibial points {gap_check:.2e} mm apart")
  errors += disagreements(d, expected)
  return finish(errors, f"{prog}:", f"{prog}: {len(expected)} typed values of {os.path.relpath(expected_path, args.root)} "
                f"checked against the derivation: {'FAIL' if errors else 'all agree'}")


if __name__ == "__main__":
  sys.exit(main())
