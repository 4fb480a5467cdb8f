"""Loading of the family runs written by run_families.py (shared by figures.py and claims.py)."""
import json
import os

import numpy as np

import tool_input

# The twelve elements in parameter-set order (chapter numbering F1..F12), as trajectory.csv
# columns F_<name with spaces -> _>_N.
LIGAMENTS = ["ACL anterior", "ACL posterior", "PCL anterior", "PCL posterior", "MCL anterior",
             "MCL oblique", "MCL deep", "LCL", "capsule medial", "capsule lateral",
             "oblique popliteal", "arcuate popliteal"]


def ligament_column(name):
  return "F_" + name.replace(" ", "_").replace("-", "_").replace("/", "_") + "_N"


def load_csv(path):
  """Trajectory as {column: np.array}; empty cells -> NaN."""
  with open(path) as f:
    header = f.readline().strip().split(",")
    rows = [[float(x) if x else np.nan for x in line.strip().split(",")] for line in f if line.strip()]
  data = np.array(rows, dtype=float).reshape(-1, len(header))
  return {h: data[:, i] for i, h in enumerate(header)}


def tibial_axes_in_F(flexion_deg, valgus_deg, external_rotation_deg):
  """The columns of R_FT = Rx(−α) Ry(π/2 − β) Rz(−γ) (solver/rotation.hpp), the tibial axes in
  femoral components, from the trajectory's angles (valgus = β − 90°): three (x, y, z) tuples.
  Written again here for the report's columns; tests/claims_checks_test.py checks it against
  the stored reference, whose contact points satisfy p_F = R0 + R_FT p_T."""
  a = np.radians(flexion_deg)
  b = np.radians(np.asarray(valgus_deg) + 90.0)
  g = np.radians(external_rotation_deg)
  sa, ca, sb, cb, sg, cg = np.sin(a), np.cos(a), np.sin(b), np.cos(b), np.sin(g), np.cos(g)
  return [(sb * cg, -ca * sg - sa * cb * cg, sa * sg - ca * cb * cg),
          (sb * sg, ca * cg - sa * cb * sg, -sa * cg - ca * cb * sg),
          (cb, sa * sb, ca * sb)]


def add_tibial_frame_columns(t):
  """The velocity columns in the tibia's own axes, beside the femoral-frame / JCS ones:
  v_T = R_FT^T v_F (mm/s) with R_FT of tibial_axes_in_F, and the JCS rates' tibial-axis
  counterparts −ω_T (deg/s; w_T = −α̇ î − β̇ ê2 − γ̇ k̂′, so at the reference pose −ω_T = (α̇, β̇,
  γ̇)). The chapter does not say which axes its Figs. 1.11–1.15 use."""
  # v_T[i] = column_i · v_F.
  cols = tibial_axes_in_F(t["flexion_deg"], t["valgus_deg"], t["external_rotation_deg"])
  v = (t["vx_mm_s"], t["vy_mm_s"], t["vz_mm_s"])
  for name, c in zip(("vx_T_mm_s", "vy_T_mm_s", "vz_T_mm_s"), cols):
    t[name] = c[0] * v[0] + c[1] * v[1] + c[2] * v[2]
  t["flexion_rate_T_deg_s"] = -t["omega_x_T_deg_s"]
  t["valgus_rate_T_deg_s"] = -t["omega_y_T_deg_s"]
  t["external_rotation_rate_T_deg_s"] = -t["omega_z_T_deg_s"]


class Member:
  """One family member: metadata from families.json, trajectory and summary."""

  def __init__(self, outdir, meta):
    self.meta = meta
    self.name = meta["name"]
    self.family = meta["family"]
    self.value = meta["value"]
    self.amplitude_N = meta["amplitude_N"]
    self.duration_s = meta["duration_s"]
    run_dir = os.path.join(outdir, meta["run_dir"])
    self.ok = bool(meta.get("ok"))
    self.fallback = meta.get("fallback")
    self.traj = None
    self.summary = None
    csv = os.path.join(run_dir, "trajectory.csv")
    if os.path.exists(csv):
      t = load_csv(csv)
      # Every row, event rows included: an event row is a state on the curve.
      self.traj = t
    if self.traj is not None and "omega_x_T_deg_s" in self.traj:
      add_tibial_frame_columns(self.traj)
    js = os.path.join(run_dir, "summary.json")
    if os.path.exists(js):
      with open(js) as f:
        self.summary = json.load(f)
    self.event_list = (self.summary or {}).get("events", [])
    self.events = first_events(self.event_list)

  @property
  def label(self):
    if self.family == "amplitude":
      s = f"A = {self.amplitude_N:g} N"
    else:
      s = f"t0 = {self.duration_s:g} s"
    if not self.ok:
      s += " (failed, partial)"
    elif self.fallback:
      s += f" (rtol {self.fallback['rtol']})"
    return s

  @property
  def liftoff_deg(self):
    e = self.events.get("liftoff_lateral")
    return e["flexion_deg"] if e else None

  @property
  def time_to_90_s(self):
    e = self.events.get("flexion_90")
    return e["time"] if e else None

  def col(self, name):
    return self.traj[name]


def first_events(events):
  """Each event name's first occurrence in a summary.json's `events`. The chapter's lift-off
  (C1, C2) is where a condyle first separates: a later `liftoff_lateral` after a re-contact is
  a bounce, not that separation (keeping the last one credited 62.1° to a reading whose
  lateral condyle first left at 27.2°)."""
  out = {}
  for e in events or []:
    out.setdefault(e["name"], e)
  return out


def contact_changes(events):
  """The lift-offs and re-contacts of the tibio-femoral compartments, in order: (name, flexion)."""
  return [(e["name"], e["flexion_deg"]) for e in events or []
          if e["name"] in ("liftoff_medial", "liftoff_lateral", "recontact_medial", "recontact_lateral")]


def load_families(outdir):
  with open(os.path.join(outdir, "families.json")) as f:
    fam = json.load(f)
  members = [Member(outdir, m) for m in fam["members"]]
  return fam, members


def run_directory(option, outdir):
  """The directory run_families.py wrote (--out of figures.py, claims.py, make_report.py run
  standalone): an existing, writable directory with families.json; BadInput naming option."""
  if outdir is None or str(outdir) == "":
    raise tool_input.BadInput(f"{option} is empty: the directory written by run_families.py is needed")
  if not os.path.exists(outdir):
    raise tool_input.BadInput(f"{option} = '{tool_input.echo(outdir)}': directory not found "
                              "(write it first with reports/run_families.py or reports/report.py)")
  if not os.path.isdir(outdir):
    raise tool_input.BadInput(f"{option} = '{tool_input.echo(outdir)}': a file, not the directory "
                              "written by run_families.py")
  if not os.path.exists(os.path.join(outdir, "families.json")):
    raise tool_input.BadInput(f"{option} = '{tool_input.echo(outdir)}': no families.json in it "
                              "(not a directory written by run_families.py)")
  tool_input.output_directory(option, outdir)
  return outdir


def load_families_checked(option, outdir):
  """load_families(outdir) with a missing directory, a missing or malformed families.json or a
  malformed run in it as BadInput naming option and the file."""
  run_directory(option, outdir)
  path = os.path.join(outdir, "families.json")
  try:
    return load_families(outdir)
  except (OSError, ValueError, KeyError, TypeError, AttributeError, IndexError) as e:
    raise tool_input.BadInput(f"{option} = '{tool_input.echo(outdir)}': '{tool_input.echo(path)}' or a run it "
                              f"lists is not what run_families.py writes ({type(e).__name__}: "
                              f"{tool_input.echo(e)})") from None


def by_family(members, family):
  ms = [m for m in members if m.family == family and m.traj is not None]
  return sorted(ms, key=lambda m: m.value)
