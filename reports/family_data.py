"""Loading of the family runs written by run_families.py (shared by figures.py and claims.py)."""
import json
import os

import numpy as np

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
      # Drop event rows that duplicate a time (keep the event row itself: it is on the curve).
      self.traj = t
    js = os.path.join(run_dir, "summary.json")
    if os.path.exists(js):
      with open(js) as f:
        self.summary = json.load(f)
    self.events = {e["name"]: e for e in (self.summary or {}).get("events", [])}

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


def load_families(outdir):
  with open(os.path.join(outdir, "families.json")) as f:
    fam = json.load(f)
  members = [Member(outdir, m) for m in fam["members"]]
  return fam, members


def by_family(members, family):
  ms = [m for m in members if m.family == family and m.traj is not None]
  return sorted(ms, key=lambda m: m.value)
