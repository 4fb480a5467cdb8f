#include "formulations/simulator.hpp"

#include <algorithm>
#include <limits>
#include <cmath>
#include <string>

#include "solver/consistent_init.hpp"
#include "solver/constrained_dynamics.hpp"
#include "solver/constraint_residuals.hpp"
#include "solver/dynamics.hpp"
#include "solver/error.hpp"
#include "solver/impact.hpp"
#include "solver/sample_checks.hpp"
#include "solver/units.hpp"

namespace kneedyn {

double RecontactGapTolerance(double max_position_residual, const Vector6d& q, double rtol, double atol) {
  return 10.0 * std::max(max_position_residual, rtol * q.head<3>().norm() + atol);
}

Simulator::Simulator(const Scene& scene, Formulation* stepper, SimulatorSettings settings, RunResult* record)
    : map_reading_(scene.model.angular_velocity_map), scene_(scene), stepper_(stepper), settings_(std::move(settings)), record_(record) {}

void Simulator::Record(bool is_event) {
  const Model& model = scene_.model;
  CheckSampleIsPhysical(model, state_);
  // Across the JCS singularity since the last sample (sin β changed sign): a step can pass
  // over the band |sin β| < 1e-3 without evaluating inside it (docs/model.md §2).
  if (!record_->samples.empty()) {
    const MechanicalState& last = record_->samples.back();
    if (std::sin(last.q(kBeta)) * std::sin(state_.q(kBeta)) < 0.0) {
      Throw<SolverError>("Simulator::Record", "the JCS singularity (sin beta = 0) was crossed between t = ", last.t,
                         " s and t = ", state_.t, " s (beta ", RadToDeg(last.q(kBeta)), " -> ", RadToDeg(state_.q(kBeta)),
                         " deg); the angular-velocity map E is singular there (docs/model.md §2)");
    }
  }
  record_->samples.push_back(state_);
  record_->sample_is_event.push_back(is_event);
  double max_gap = 0.0, max_gap_rate = 0.0;
  MaxActiveConstraintResiduals(model, state_, &max_gap, &max_gap_rate);
  record_->max_position_residual = std::max(record_->max_position_residual, max_gap);
  record_->max_velocity_residual = std::max(record_->max_velocity_residual, max_gap_rate);
  if (settings_.sample) settings_.sample(state_, is_event);
}

void CompleteRestartState(const Model& model, RestartProjection restart, MechanicalState* state) {
  if (restart == RestartProjection::kProject) {
    CompleteHiddenConstraint(model, state);
    return;
  }
  const ConstrainedAcceleration a = RestartAcceleration(model, state);
  state->qdd = a.qdd;
  for (size_t c = 0; c < state->active.size(); ++c) state->contact[state->active[c]].normal_force = a.normal_force[c];
  FillContactCoordinates(model, state);
}

std::vector<EventSpec> StartPhase(const Model& model, const EndCondition& end, double gap_tolerance,
                                  RestartProjection restart, MechanicalState* state, bool complete) {
  RecordSeparationGaps(model, state);
  std::vector<EventSpec> specs = EventsForPhase(model, end, *state, gap_tolerance);
  if (model.ligament_law == LigamentLaw::kPublished) {
    state->ligament_branch = LigamentBranchesAt(model, state->q, state->qd);
    if (complete) CompleteRestartState(model, restart, state);  // forces on the locked branches
    MeasureKinkRootsFromPhaseStart(model, *state, &specs);           // one restart per crossing
  }
  return specs;
}

std::vector<EventSpec> StartRestartedPhase(const Model& model, const EndCondition& end, double gap_tolerance,
                                           RestartProjection restart, PullingContact pulling, MechanicalState* state,
                                           std::vector<EventRecord>* events, bool* released) {
  std::vector<EventSpec> specs = StartPhase(model, end, gap_tolerance, restart, state);
  *released = ReleasePullingContacts(model, restart, pulling,
                                     "at a restart: a lift-off there, whose sensitivities are not defined", state, events);
  if (*released) specs = StartPhase(model, end, gap_tolerance, restart, state, /*complete=*/false);
  return specs;
}

bool ReleasePullingContacts(const Model& model, RestartProjection restart, PullingContact pulling, const char* refusal,
                            MechanicalState* state, std::vector<EventRecord>* events) {
  bool released = false;
  for (;;) {
    int worst = -1;
    for (int i : state->active) {
      if (state->contact[i].normal_force < 0.0 &&
          (worst < 0 || state->contact[i].normal_force < state->contact[worst].normal_force)) {
        worst = i;
      }
    }
    if (worst < 0) return released;
    const std::string compartment = CompartmentName(model.contacts[worst].compartment);
    if (pulling == PullingContact::kRefuse) {
      Throw<SolverError>("Simulator::Run", "at t = ", state->t, " s the ", compartment, " contact would pull (N = ",
                         state->contact[worst].normal_force, " N) ", refusal);
    }
    events->push_back({LiftoffEventName(model.contacts[worst].compartment), state->t, state->q(kAlpha)});
    state->active.erase(std::remove(state->active.begin(), state->active.end(), worst), state->active.end());
    state->contact[worst].normal_force = 0.0;
    CompleteRestartState(model, restart, state);
    released = true;
  }
}

TransitionOutcome PhaseTransition(const Model& model, const std::vector<EventSpec>& specs,
                                  const std::vector<int>& fired, RestartProjection restart,
                                  PullingContact pulling, MechanicalState* state,
                                  std::vector<EventRecord>* events) {
  TransitionOutcome out;
  std::vector<int> new_active = state->active;
  bool impact = false;
  // The lift-offs' forces as the knee's dynamics give them at the event state, the contacts
  // kept (docs/outputs.md, liftoff_force_not_zero); one solve, on a copy of the state.
  ConstrainedAcceleration kept;
  if (std::any_of(fired.begin(), fired.end(), [&](int k) { return specs[k].kind == EventKind::kLiftoff; })) {
    MechanicalState with_contacts = *state;
    try {
      kept = RestartAcceleration(model, &with_contacts);
    } catch (const SolverError&) {
      kept.normal_force.clear();  // no number: no check
    }
  }
  for (int k : fired) {
    const EventSpec& e = specs[k];
    // Kinks restart the stepper but are not events of the knee (docs/outputs.md).
    if (e.kind != EventKind::kLigamentKink) events->push_back({e.name, state->t, state->q(kAlpha)});
    if (e.kind == EventKind::kLiftoff) {
      const auto at = std::find(state->active.begin(), state->active.end(), e.contact);
      const size_t c = static_cast<size_t>(at - state->active.begin());
      if (at != state->active.end() && c < kept.normal_force.size()) {
        events->back().consistent_normal_force = kept.normal_force[c];
      }
    }
    switch (e.kind) {
      case EventKind::kFlexionEnd:
        out.end_reason = e.name;
        out.ended = true;
        break;
      case EventKind::kLiftoff:
        new_active.erase(std::remove(new_active.begin(), new_active.end(), e.contact), new_active.end());
        state->contact[e.contact].normal_force = 0.0;
        break;
      case EventKind::kRecontact:
        new_active.push_back(e.contact);
        impact = true;
        // In contact again: a bounce that lifts it off at this instant (ReleasePullingContacts,
        // no phase start between) separates anew, measured from the gap then.
        if (static_cast<size_t>(e.contact) < state->separation_gap.size()) {
          state->separation_gap[e.contact] = std::numeric_limits<double>::quiet_NaN();
        }
        break;
      case EventKind::kLigamentKink:
        ++out.ligament_kink_crossings;
        break;
      case EventKind::kPatellarLiftoff:  // the massless patella: no impact, no mode of the tibia
      case EventKind::kPatellarRecontact:
        break;
    }
  }
  if (out.ended) return out;
  std::sort(new_active.begin(), new_active.end());
  state->active = new_active;
  if (impact) {
    // The impulse at the pose the phase restarts from. Taken at the penetrated pose (gap
    // −1e-9 m), its rows moved with the projection after it, and they held only to
    // 8.9e-12 m/s, under the restart's 1e-11 m/s: dae then failed the error test on u at
    // rtol ≤ 1e-11 after the re-contact (one_ligament.yaml, hard/distal_pulse_both_separate.yaml).
    if (restart == RestartProjection::kProject) ProjectRestartPose(model, state);
    ApplyPlasticImpact(model, state);
  }
  CompleteRestartState(model, restart, state);
  ReleasePullingContacts(model, restart, pulling,
                         "after the switch: a simultaneous lift-off, whose sensitivities are not defined", state, events);
  return out;
}

void CheckFixedStep(const Model& model, double t, double h, double output_interval, bool pulses) {
  if (!(h > 0.0)) return;
  if (output_interval < h * (1.0 - 1e-12)) {
    Throw<InputError>("Simulator", "output interval ", output_interval, " s is shorter than the fixed step ", h,
                      " s: each step would be cut to an output time (rule: the fixed step, --step or the formulation's"
                      " default, <= the output interval, --output-interval or the scene's output.interval_s)");
  }
  if (!pulses) return;
  if (const PulseStepLimit limit = PulseResolvingStepLimit(model, t); limit.step < h * (1.0 - 1e-12)) {
    Throw<InputError>("Simulator", limit.field, " = ", limit.duration, " s spans fewer than ", kStepsPerPulse,
                      " fixed steps of ", h, " s, which would not resolve it (rule: --step <= ", limit.step, " s)");
  }
}

void Simulator::Initialize() {
  const Model& model = scene_.model;
  std::vector<int> active;
  for (int i = 0; i < static_cast<int>(model.contacts.size()); ++i) active.push_back(i);
  state_ = ConsistentInitialize(model, scene_.initial, active, settings_.init, &record_->init);
  CheckFixedStep(model, state_.t, stepper_->fixed_step(), settings_.output_interval, /*pulses=*/true);
  // A start whose consistent forces pull (an assembled pose; docs/model.md §6) starts with
  // those contacts' lift-offs.
  ReleasePullingContacts(model, settings_.restart, settings_.pulling,
                         "at the start: a lift-off there, whose sensitivities are not defined", &state_, &record_->events);
  // Refusals the input causes are raised here, before integration (exit code 2): contact
  // rows that are dependent at the start (e.g. two compartments given the same surfaces).
  SolveConstrainedAcceleration(model, state_.t, state_.q, state_.qd, state_.active);
  // The start's lift-offs share the first row, a sampling row (is_event 0): scoring drops an
  // event row that another row follows, and the t0 row is compared with the reference.
  Record(false);
}

void Simulator::Run() {
  const Model& model = scene_.model;
  const double dt = settings_.output_interval;
  const double t_end = scene_.end.time;
  long next_index = 1;  // next uniform output time = next_index * dt
  const std::vector<double>& extra = settings_.output_times;
  size_t next_extra = 0;  // next of the extra output times
  // Drops the extra output times up to t (+kOutputTimeMerge): reached, or an output or event there.
  const auto pass_extra = [&](double t) {
    while (next_extra < extra.size() && extra[next_extra] <= t + kOutputTimeMerge) ++next_extra;
  };
  pass_extra(state_.t);
  bool done = false;
  bool first_phase = true;
  while (!done) {
    const double gap_tolerance =
        RecontactGapTolerance(record_->max_position_residual, state_.q, settings_.rtol, settings_.atol);
    record_->max_recontact_gap_tolerance = std::max(record_->max_recontact_gap_tolerance, gap_tolerance);
    record_->max_recontact_gap_tolerance_of_tolerances = std::max(
        record_->max_recontact_gap_tolerance_of_tolerances, RecontactGapTolerance(0.0, state_.q, settings_.rtol, settings_.atol));
    // The chapter's DASSL start hands its first phase to the stepper unprojected.
    bool released = false;
    std::vector<EventSpec> specs =
        !first_phase ? StartRestartedPhase(model, scene_.end, gap_tolerance, settings_.restart, settings_.pulling,
                                           &state_, &record_->events, &released)
        : scene_.initial.unprojected
            ? StartPhase(model, scene_.end, gap_tolerance, settings_.restart, &state_, /*complete=*/false)
            : StartPhase(model, scene_.end, gap_tolerance, settings_.restart, &state_);
    if (released) {
      // The lift-off's row (docs/outputs.md: a row per event): after a kink no row was
      // written; after a patellar event its row, at this time, is the one.
      if (record_->samples.empty() || record_->samples.back().t != state_.t) {
        if (std::abs(state_.t - next_index * dt) < kOutputTimeMerge) ++next_index;
        pass_extra(state_.t);
        Record(true);
      }
    }
    stepper_->Start(state_, specs);
    if (first_phase && settings_.first_phase_started) settings_.first_phase_started(state_);
    first_phase = false;
    for (;;) {
      const double t_uniform = std::min(next_index * dt, t_end);
      // An extra time less than kOutputTimeMerge before the uniform one is that one.
      const bool extra_first = next_extra < extra.size() && extra[next_extra] < t_uniform - kOutputTimeMerge;
      const double t_next = extra_first ? extra[next_extra] : t_uniform;
      const AdvanceResult adv = stepper_->Advance(t_next, &state_);
      if (adv.status == AdvanceStatus::kReachedTime) {
        Record(false);
        pass_extra(t_next);
        if (extra_first) continue;
        if (t_next >= t_end) {
          record_->end_reason = "end_time";
          done = true;
          break;
        }
        ++next_index;
        continue;
      }
      // A ligament crossing the published law's jump only restarts the stepper.
      const bool only_kinks = std::all_of(adv.events.begin(), adv.events.end(), [&](int k) {
        return specs[k].kind == EventKind::kLigamentKink;
      });
      if (only_kinks) {
        ++record_->ligament_kink_crossings;
        break;
      }
      // A patellar facet's lift-off or re-contact (with kinks or not) is recorded with its
      // sample and restarts the stepper: the tibia's contacts do not change.
      const bool only_restarts = std::all_of(adv.events.begin(), adv.events.end(), [&](int k) {
        return specs[k].kind == EventKind::kLigamentKink || specs[k].kind == EventKind::kPatellarLiftoff ||
               specs[k].kind == EventKind::kPatellarRecontact;
      });
      if (only_restarts) {
        if (std::abs(state_.t - next_index * dt) < kOutputTimeMerge) ++next_index;
        pass_extra(state_.t);
        Record(true);
        bool kink = false;
        for (int k : adv.events) {
          if (specs[k].kind == EventKind::kLigamentKink) {
            kink = true;
          } else {
            record_->events.push_back({specs[k].name, state_.t, state_.q(kAlpha)});
          }
        }
        if (kink) ++record_->ligament_kink_crossings;
        break;
      }
      // Events: record them, then switch mode.
      if (std::abs(state_.t - next_index * dt) < kOutputTimeMerge) ++next_index;
      pass_extra(state_.t);
      Record(true);
      const TransitionOutcome outcome =
          PhaseTransition(model, specs, adv.events, settings_.restart, settings_.pulling, &state_, &record_->events);
      record_->ligament_kink_crossings += outcome.ligament_kink_crossings;
      if (outcome.ended) {
        record_->end_reason = outcome.end_reason;
        done = true;
      }
      break;
    }
  }
}

}  // namespace kneedyn
