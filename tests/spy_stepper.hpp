// A stepper for tests of the hybrid simulator (formulations/simulator.hpp) and of what must
// equal it (the open problem's transition): delegates the integration to a registered
// formulation and records the states it was started from with the events watched, and
// the event states it reported with the roots found and the phase they ended.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "formulations/formulation.hpp"

namespace kneedyn {
namespace test_support {

class SpyStepper : public Formulation {
 public:
  SpyStepper(const std::string& name, const Scene& scene) : inner_(CreateFormulation(name, scene, {})) {}
  ContactForm contact_form() const override { return inner_->contact_form(); }
  void Start(const MechanicalState& state, const std::vector<EventSpec>& events) override {
    starts.push_back(state);
    start_events.push_back(events);
    inner_->Start(state, events);
  }
  AdvanceResult Advance(double t_out, MechanicalState* state) override {
    const long restarts_before = inner_->stats().restarts;
    const AdvanceResult r = inner_->Advance(t_out, state);
    // A restart inside Advance is mde's switch to a better chart after a step.
    if (inner_->stats().restarts > restarts_before) chart_switch_phases.push_back(static_cast<int>(starts.size()) - 1);
    if (r.status == AdvanceStatus::kEvent) {
      event_states.push_back(*state);
      fired.push_back(r.events);
      event_phase.push_back(static_cast<int>(starts.size()) - 1);
    }
    return r;
  }
  SolverStats stats() const override { return inner_->stats(); }

  std::vector<MechanicalState> starts, event_states;
  std::vector<std::vector<EventSpec>> start_events;  // per start
  std::vector<std::vector<int>> fired;               // per event state: the roots
  std::vector<int> event_phase;                      // per event state: index into starts
  std::vector<int> chart_switch_phases;              // per mde chart switch: its phase

 private:
  std::unique_ptr<Formulation> inner_;
};

}  // namespace test_support
}  // namespace kneedyn
