#include "solver/events.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "solver/contact_kinematics.hpp"
#include "solver/ligament.hpp"
#include "solver/error.hpp"
#include "solver/units.hpp"

namespace kneedyn {

bool MechanicalState::IsActive(int i) const {
  return std::find(active.begin(), active.end(), i) != active.end();
}

std::string FlexionEventName(double flexion_rad) {
  const double deg = RadToDeg(flexion_rad);
  const double whole = std::round(deg);
  if (std::abs(deg - whole) < 1e-9) return StrCat("flexion_", static_cast<long>(whole));
  char buf[32];
  std::snprintf(buf, sizeof(buf), "flexion_%.1f", deg);
  return buf;
}

std::vector<EventSpec> EventsForPhase(const Model& model, const EndCondition& end,
                                      const MechanicalState& state, double gap_tolerance) {
  std::vector<EventSpec> specs;
  const Pose pose = PoseFromCoordinates(state.q);
  for (int i = 0; i < static_cast<int>(model.contacts.size()); ++i) {
    const std::string comp = CompartmentName(model.contacts[i].compartment);
    if (state.IsActive(i)) {
      specs.push_back({EventKind::kLiftoff, i, -1, -1, 0.0, LiftoffEventName(model.contacts[i].compartment), nullptr});
    } else {
      const double gap = RequireContactKinematics(model.contacts[i], pose, "EventsForPhase").gap;  // m
      const bool recorded = static_cast<size_t>(i) < state.separation_gap.size() && std::isfinite(state.separation_gap[i]);
      const double at_separation = recorded ? state.separation_gap[i] : gap;
      const double offset = std::min(std::min(at_separation, 0.0) - std::max(gap_tolerance, kMinRecontactHysteresis),
                                     gap - kMinRecontactHysteresis);
      specs.push_back({EventKind::kRecontact, i, -1, -1, offset, "recontact_" + comp, nullptr});
    }
  }
  if (end.flexion) {
    specs.push_back({EventKind::kFlexionEnd, -1, -1, +1, *end.flexion, FlexionEventName(*end.flexion), nullptr});
  }
  if (model.ligament_law == LigamentLaw::kPublished) {
    for (int j = 0; j < static_cast<int>(model.ligaments.size()); ++j) {
      const Ligament& lig = model.ligaments[j];
      specs.push_back({EventKind::kLigamentKink, -1, j, 0,
                       LigamentKinkLength(lig), "kink_" + ColumnSafeName(lig.name), nullptr});
    }
  }
  if (model.patella && model.patella->facet_liftoff) {  // after the tibio-femoral events: their indices stay
    // One warm start for the phase's patellar events: the equilibrium at the phase's start,
    // followed from the scene's start along the tibial path (the run's branch: a solve from
    // the start straight at this pose could land on another, docs/model.md §12).
    const Patella& patella = *model.patella;
    auto guess = std::make_shared<PatellaGuess>();
    SolvePatella(patella, TuberosityInF(patella, PoseFromCoordinates(patella.start_q)), "EventsForPhase", guess.get());
    SolvePatellaAlongTibialPath(patella, patella.start_q, state.q, "EventsForPhase", guess.get());
    for (int i = 0; i < 2; ++i) {
      const std::string facet = CompartmentName(static_cast<Compartment>(i));
      const double c = PatellarContactFunction(patella, *guess, i);
      if (c > 0.5 * kPatellarRecontactRatio) {
        specs.push_back({EventKind::kPatellarLiftoff, i, -1, -1, 0.0, "liftoff_patellar_" + facet, guess});
      } else {
        specs.push_back({EventKind::kPatellarRecontact, i, -1, -1, -kPatellarRecontactRatio,
                         "recontact_patellar_" + facet, guess});
      }
    }
    // A phase that starts at a facet's switch has to continue past it: the one-facet branch
    // must hold there (a positive compliance), else the fold's SolverError. Here, not in
    // SolvePatella: the integrators evaluate past the switch while they locate it, where
    // SolvePatella keeps the facet pressing with λ_i < 0 until the event stops them.
    CheckPatellarFacetSwitch(patella, TuberosityInF(patella, pose), *guess, state.t, "EventsForPhase");
  }
  return specs;
}

void RecordSeparationGaps(const Model& model, MechanicalState* state) {
  const double kNone = std::numeric_limits<double>::quiet_NaN();
  state->separation_gap.resize(model.contacts.size(), kNone);
  const Pose pose = PoseFromCoordinates(state->q);
  for (int i = 0; i < static_cast<int>(model.contacts.size()); ++i) {
    double& at_separation = state->separation_gap[i];
    if (state->IsActive(i)) {
      at_separation = kNone;
    } else if (!std::isfinite(at_separation)) {
      at_separation = RequireContactKinematics(model.contacts[i], pose, "RecordSeparationGaps").gap;
    }
  }
}

void MeasureKinkRootsFromPhaseStart(const Model& model, const MechanicalState& state, std::vector<EventSpec>* specs) {
  if (state.ligament_branch.empty()) return;
  const Pose pose = PoseFromCoordinates(state.q);
  for (EventSpec& spec : *specs) {
    if (spec.kind != EventKind::kLigamentKink) continue;
    const double length = LigamentSpan_F(model.ligaments[spec.ligament], pose).norm();  // m
    const double g = length - spec.offset;
    const bool linear = state.ligament_branch[spec.ligament] == kBranchLinear;  // entering L > L_kink
    const bool left_side = linear ? g <= 0.0 : g >= 0.0;
    if (!left_side || std::abs(g) <= kKinkRoundOffFloor || std::abs(g) > kKinkRoundOff) continue;
    spec.offset = linear ? length - kKinkStartMargin : length + kKinkStartMargin;
  }
}

double PatellarContactFunctionAt(const Model& model, const Vector6d& q, PatellaGuess* guess, int facet) {
  const Patella& patella = *model.patella;
  SolvePatella(patella, TuberosityInF(patella, PoseFromCoordinates(q)), "EvaluateEvents", guess);
  return PatellarContactFunction(patella, *guess, facet);
}

void EvaluateEvents(const Model& model, const std::vector<EventSpec>& specs, const Vector6d& q,
                    const std::vector<double>& normal_force, double* g) {
  EvaluateEvents(model, specs, q, PoseFromCoordinates(q), normal_force, g);
}

void EvaluateEvents(const Model& model, const std::vector<EventSpec>& specs, const Vector6d& q,
                    const Pose& pose, const std::vector<double>& normal_force, double* g) {
  EvaluateEventsTpl(model, specs, q, pose, normal_force, g);
}

void EvaluateEvents(const Model& model, const std::vector<EventSpec>& specs, const Vector6d& q,
                    const Pose& pose, const std::vector<double>& normal_force,
                    const std::vector<double>& ligament_length, double* g) {
  EvaluateEventsTpl(model, specs, q, pose, normal_force, g, &ligament_length);
}

}  // namespace kneedyn
