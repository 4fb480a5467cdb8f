#include "solver/sample_checks.hpp"

#include <cmath>

#include "solver/contact_kinematics.hpp"
#include "solver/error.hpp"
#include "solver/rotation.hpp"
#include "solver/units.hpp"

namespace kneedyn {

void CheckSampleIsPhysical(const Model& model, const MechanicalState& s) {
  const char* kWho = "CheckSampleIsPhysical";
  if (!s.q.allFinite() || !s.qd.allFinite()) {
    Throw<SolverError>(kWho, "non-finite state at t = ", s.t, " s: the run has diverged");
  }
  // A sample inside the JCS band (docs/model.md §2): the integrator's own evaluations may
  // step over it, an output time interpolated there may not be reported.
  if (IsAtJcsSingularity(std::sin(s.q(kBeta)))) {
    Throw<SolverError>(kWho, "pose at the JCS singularity at t = ", s.t, " s: beta = ", RadToDeg(s.q(4)),
                       " deg (|sin beta| < ", kJcsSingularityTolerance,
                       "); the angular-velocity map E is singular there (docs/model.md §2)");
  }
  const Pose pose = PoseFromCoordinates(s.q);
  for (int i : s.active) {
    const ContactPair& pair = model.contacts[i];
    const char* name = CompartmentName(pair.compartment);
    ContactGeometry g;
    double chart[4];
    const bool found = ContactKinematics(pair, pose, &g, chart);
    if (found && std::abs(g.gap) > kMaxConstraintViolation) {
      Throw<SolverError>(kWho, "the ", name, " contact constraint is violated by ", MToMm(g.gap),
                         " mm at t = ", s.t, " s (limit ", MToMm(kMaxConstraintViolation),
                         " mm): the run has diverged");
    }
    ChartSample sample;
    const bool on_femur = found && pair.femoral_surface->EvaluateChart(chart[0], chart[1], &sample);
    const bool on_tibia = found && pair.tibial_surface->EvaluateChart(chart[2], chart[3], &sample);
    if (!on_femur || !on_tibia) {
      const HeightField& left = !on_femur ? *pair.femoral_surface : *pair.tibial_surface;
      Throw<SolverError>(kWho, "the ", name, " contact point left the ", !on_femur ? "femoral" : "tibial",
                         " surface (", left.Describe(), ") at t = ", s.t, " s, flexion = ",
                         RadToDeg(s.q(kAlpha)), " deg: the model is not defined beyond its rim");
    }
  }
}

}  // namespace kneedyn
