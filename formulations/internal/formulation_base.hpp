// The plumbing every formulation shares, written once (Drake's
// IntegratorBase plays this role there): the scene and model, the phase's bookkeeping (active
// contacts, events, contact-chart guesses, locked ligament branches, recorded by BeginPhase
// in Start), the run's statistics and the write-back of the state reached at the end of
// Advance. Formulations
// derive from it and keep only their method.
#pragma once

#include <vector>

#include "formulations/formulation.hpp"
#include "solver/consistent_init.hpp"

namespace kneedyn {

class FormulationBase : public Formulation {
 public:
  // Cumulative statistics over the run (Formulation::stats): the counters of the finished
  // phases, which the base keeps, plus those of the phase in progress, which only the
  // method's solver knows.
  SolverStats stats() const final {
    SolverStats s = finished_phases_;
    s += PhaseStats();
    return s;
  }

 protected:
  // Counters not yet in finished_phases_: the phase in progress (0 when there is none), or
  // the whole run for a method whose solver object lives across phases and counts on.
  virtual SolverStats PhaseStats() const = 0;

  explicit FormulationBase(const Scene& scene) : scene_(scene), model_(scene.model) {}

  // Records the phase that starts at `state` with `events` to watch.
  void BeginPhase(const MechanicalState& state, const std::vector<EventSpec>& events) {
    active_ = state.active;
    events_ = events;
    state_contact_ = state.contact;
    ligament_branch_ = state.ligament_branch;
  }

  // Writes the state reached into *state: t, q, q̇, q̈, the phase's contact guesses and
  // ligament branches, normal_force[c] (N) of each active contact c and, when
  // `coordinates` is given, its per_contact chapter coordinates (coordinates[per_contact c
  // + j]); without them (closed forms) the coordinates come from the contact kinematics.
  void WriteBack(double t, const Vector6d& q, const Vector6d& qd, const Vector6d& qdd,
                 const double* normal_force, const double* coordinates, int per_contact,
                 MechanicalState* state) const {
    state->t = t;
    state->q = q;
    state->qd = qd;
    state->qdd = qdd;
    state->contact = state_contact_;
    state->ligament_branch = ligament_branch_;
    for (size_t c = 0; c < active_.size(); ++c) {
      ContactGuess& guess = state->contact[active_[c]];
      if (coordinates != nullptr) {
        for (int j = 0; j < per_contact; ++j) guess.coordinates[j] = coordinates[per_contact * c + j];
      }
      guess.normal_force = normal_force[c];
    }
    if (coordinates == nullptr || per_contact == 0) FillContactCoordinates(model_, state);
  }

  const Scene& scene_;
  const Model& model_;
  std::vector<int> active_;                   // indices into model.contacts, this phase
  std::vector<EventSpec> events_;             // roots watched in this phase
  std::vector<ContactGuess> state_contact_;   // contact guesses (charts) at the phase start
  std::vector<signed char> ligament_branch_;  // locked for the phase
  SolverStats finished_phases_;               // counters of finished phases, and restarts
};

}  // namespace kneedyn
