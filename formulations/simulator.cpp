#include "formulations/simulator.hpp"

#include <algorithm>
#include <cmath>

#include "solver/constrained_dynamics.hpp"
#include "solver/constraint_residuals.hpp"
#include "solver/dynamics.hpp"
#include "solver/error.hpp"
#include "solver/impact.hpp"
#include "solver/sample_checks.hpp"

namespace kneedyn {

double RecontactGapTolerance(double max_position_residual, const Vector6d& q, double rtol, double atol) {
  return 10.0 * std::max(max_position_residual, rtol * q.head<3>().norm() + atol);
}

Simulator::Simulator(const Scene& scene, Formulation* stepper, SimulatorSettings settings, RunResult* record)
    : scene_(scene), stepper_(stepper), settings_(std::move(settings)), record_(record) {}

void Simulator::Record(bool is_event) {
  const Model& model = scene_.model;
  CheckSampleIsPhysical(model, state_);
  record_->samples.push_back(state_);
  record_->sample_is_event.push_back(is_event);
  double max_gap = 0.0, max_gap_rate = 0.0;
  MaxActiveConstraintResiduals(model, state_, &max_gap, &max_gap_rate);
  record_->max_position_residual = std::max(record_->max_position_residual, max_gap);
  record_->max_velocity_residual = std::max(record_->max_velocity_residual, max_gap_rate);
  if (settings_.sample) settings_.sample(state_, is_event);
}

void Simulator::CompleteState() {
  const Model& model = scene_.model;
  if (settings_.restart == RestartProjection::kProject) {
    CompleteHiddenConstraint(model, &state_);
    return;
  }
  const ConstrainedAcceleration a = SolveConstrainedAcceleration(model, state_.t, state_.q, state_.qd, state_.active,
                                                                 {}, &state_.ligament_branch);
  state_.qdd = a.qdd;
  for (size_t c = 0; c < state_.active.size(); ++c) state_.contact[state_.active[c]].normal_force = a.normal_force[c];
  FillContactCoordinates(model, &state_);
}

void Simulator::Initialize() {
  const Model& model = scene_.model;
  std::vector<int> active;
  for (int i = 0; i < static_cast<int>(model.contacts.size()); ++i) active.push_back(i);
  state_ = ConsistentInitialize(model, scene_.initial, active, settings_.init, &record_->init);
  // Refusals the input causes are raised here, before integration (exit code 2): contact
  // rows that are dependent at the start (e.g. two compartments given the same surfaces).
  SolveConstrainedAcceleration(model, state_.t, state_.q, state_.qd, state_.active);
  Record(false);
}

void Simulator::Run() {
  const Model& model = scene_.model;
  const double dt = settings_.output_interval;
  const double t_end = scene_.end.time;
  long next_index = 1;  // next uniform output time = next_index * dt
  bool done = false;
  bool first_phase = true;
  while (!done) {
    const double gap_tolerance =
        RecontactGapTolerance(record_->max_position_residual, state_.q, settings_.rtol, settings_.atol);
    const std::vector<EventSpec> specs = EventsForPhase(model, scene_.end, state_, gap_tolerance);
    if (model.ligament_law == LigamentLaw::kPublished) {
      state_.ligament_branch = LigamentBranchesAt(model, state_.q, state_.qd);
      CompleteState();  // forces on the locked branches
    }
    stepper_->Start(state_, specs);
    if (first_phase && settings_.first_phase_started) settings_.first_phase_started(state_);
    first_phase = false;
    for (;;) {
      const double t_next = std::min(next_index * dt, t_end);
      const AdvanceResult adv = stepper_->Advance(t_next, &state_);
      if (adv.status == AdvanceStatus::kReachedTime) {
        Record(false);
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
      // Events: record them, then switch mode.
      if (std::abs(state_.t - next_index * dt) < 1e-12) ++next_index;
      Record(true);
      std::vector<int> new_active = state_.active;
      bool impact = false;
      for (int k : adv.events) {
        const EventSpec& e = specs[k];
        record_->events.push_back({e.name, state_.t, state_.q(kAlpha)});
        switch (e.kind) {
          case EventKind::kFlexionEnd:
            record_->end_reason = e.name;
            done = true;
            break;
          case EventKind::kLiftoff:
            new_active.erase(std::remove(new_active.begin(), new_active.end(), e.contact), new_active.end());
            state_.contact[e.contact].normal_force = 0.0;
            break;
          case EventKind::kRecontact:
            new_active.push_back(e.contact);
            impact = true;
            break;
          case EventKind::kLigamentKink:
            ++record_->ligament_kink_crossings;
            break;
        }
      }
      if (done) break;
      std::sort(new_active.begin(), new_active.end());
      state_.active = new_active;
      if (impact) ApplyPlasticImpact(model, &state_);
      CompleteState();
      // A contact whose consistent force would pull (N < 0): the most negative one first,
      // then solve again (e.g. a re-contact that bounces off, or the second compartment
      // unloading as the first lifts off).
      for (;;) {
        int worst = -1;
        for (int i : state_.active) {
          if (state_.contact[i].normal_force < 0.0 &&
              (worst < 0 || state_.contact[i].normal_force < state_.contact[worst].normal_force)) {
            worst = i;
          }
        }
        if (worst < 0) break;
        const std::string compartment = CompartmentName(model.contacts[worst].compartment);
        if (settings_.pulling == PullingContact::kRefuse) {
          Throw<SolverError>("Simulator::Run", "at t = ", state_.t, " s the ", compartment, " contact would pull (N = ",
                             state_.contact[worst].normal_force,
                             " N) after the switch: a simultaneous lift-off, whose sensitivities are not defined");
        }
        record_->events.push_back({"liftoff_" + compartment, state_.t, state_.q(kAlpha)});
        state_.active.erase(std::remove(state_.active.begin(), state_.active.end(), worst), state_.active.end());
        state_.contact[worst].normal_force = 0.0;
        CompleteState();
      }
      break;
    }
  }
}

}  // namespace kneedyn
