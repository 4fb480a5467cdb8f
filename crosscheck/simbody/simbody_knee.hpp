// The chapter knee rebuilt in Simbody (crosscheck/simbody/README.md): a second engine that
// shares none of kneedyn's physics, as an independent check and as the peer benchmark.
//
// What comes from kneedyn: the Scene (scene/scene.hpp: parameter set, selection of
// elements and contacts, pulse, initial pose, end condition) — data only — and, for the
// *output* conversion only, the pure JCS kinematics of solver/pose.hpp (q̇ and q̈ from
// the body's spatial velocity and acceleration). Everything that makes the motion is
// Simbody's or written here again in Simbody's terms:
//   tibia       MobilizedBody::Free on Ground (quaternions; no JCS singularity); body
//               frame = T, origin at the centre of mass, principal inertia.
//   femur       Ground = F.
//   contacts    Constraint::SphereOnPlaneContact (femoral sphere on Ground, tibial plane
//               on the tibia), enforceRolling = false (frictionless sliding, docs/model.md §4).
//   ligaments   Force::Custom, the chapter's law (Eqs. 1.14–1.16), published or
//               c1_continuous; the published law's jump at ε = 2ε1 is made an event
//               (each element's branch is a Stage::Dynamics discrete variable flipped
//               by a triggered handler), so no step straddles it.
//   gravity     Force::UniformGravity.
//   pulse       Force::Custom at the centre of mass along R·d_T (turns with the tibia).
//   start       Simbody's Assembler (held coordinates locked), then projectU.
//   events      triggered handlers: lift-off when a normal force falls to 0 (the
//               constraint is disabled), re-contact when a separated gap falls 1 nm below
//               its value at separation (the constraint is enabled; perfectly plastic
//               impact M Δu = Gᵀ λ, G(u + Δu) = 0, then projection), end at the scene's
//               flexion angle.
#pragma once

#include <string>
#include <vector>

#include "formulations/run.hpp"
#include "scene/scene.hpp"

namespace kneedyn {
namespace simbody {

struct Options {
  // rkm (RungeKuttaMerson), rk3, rk2, rkf (RungeKuttaFeldberg), cpodes-bdf, cpodes-adams,
  // verlet, see2 (SemiExplicitEuler2), see (SemiExplicitEuler, fixed step),
  // euler (ExplicitEuler, fixed step).
  std::string integrator = "rkm";
  double accuracy = 1e-6;              // Simbody's relative accuracy
  double constraint_tolerance = 0.0;   // 0: Simbody's default (= accuracy)
  double fixed_step = 0.0;             // s; required by see and euler, optional elsewhere
  double output_interval = 0.0;        // s; 0 = the scene's
  long max_steps = 5000000;            // safety cap on accepted steps

  // Checks the options; returns false and says why (names the option, value and rule).
  bool IsValid(std::string* error) const;
};

const std::vector<std::string>& IntegratorNames();

// One output row, everything computed from Simbody's state (except the JCS conversion).
struct Sample {
  double t = 0.0;
  bool is_event = false;
  MechanicalState state;  // q, q̇, q̈ (JCS), active contacts, normal forces
  double pulse_N = 0.0;
  // Per model.contacts: contact point on the femoral sphere (F, m) and in T (m), gap (m)
  // and gap rate (m/s) from Simbody's constraint geometry.
  std::vector<Vector3d> point_F, point_T;
  std::vector<double> gap, gap_rate;
  std::vector<double> ligament_length, ligament_tension;  // m, N (law written here)
  double energy = 0.0;  // J: Simbody's kinetic + potential (gravity, ligaments)
};

struct Result {
  RunResult run;                // events, samples (MechanicalState), stats, init, status
  std::vector<Sample> samples;  // parallel to run.samples
};

// Runs a scene in Simbody. Throws InputError on bad options or a scene the port cannot
// build (a contact that is not sphere-on-plane); solver failures are returned.
Result Run(const Scene& scene, const Options& options);

// Writes trajectory.csv, trajectory.sto and summary.json in the layout of `kneedyn run`.
void WriteOutputs(const std::string& dir, const Scene& scene, const Options& options,
                  const Result& result);

// Maximum relative change of Simbody's total energy over the samples.
double EnergyDrift(const Result& result);

}  // namespace simbody
}  // namespace kneedyn
