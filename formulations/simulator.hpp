// The hybrid simulator: the one place that runs the knee from phase to phase (docs/model.md
// §9). Drake's Simulator/Integrator split: a stepper (the Formulation interface: Start a
// phase from a consistent state, Advance to an output time or the first event root)
// integrates inside one contact mode; the simulator owns everything between phases and
// around them, the same for every stepper:
//
//   - consistent initialization at t0 (ConsistentInitialize with every contact active);
//   - the output samples: every output_interval, plus every event; an output time that
//     coincides with an event (|t_event − t_out| < 1e-12 s) is skipped so that times stay
//     strictly increasing; the end time is the last sample;
//   - a phase start: the events of the phase (EventsForPhase, with the re-contact hysteresis
//     below), the published ligament law's branches locked from the direction of motion
//     (LigamentBranchesAt) and the hidden constraint solved on them;
//   - the events the stepper reports: the end flexion ends the run; a ligament kink alone
//     only restarts the stepper; a lift-off drops its contact; a re-contact adds its contact
//     and applies the perfectly plastic impact (solver/impact.hpp); then the restart state
//     (RestartProjection) and contacts whose consistent force would pull (PullingContact).
//
// Re-contact hysteresis, the one rule (docs/model.md §9): a separated compartment re-contacts
// when its gap falls below min(gap at separation, 0) by
//     gap_tolerance = 10 · max(observed position drift, rtol · |x0| + atol),   ≥ 1 nm,
// the observed drift being the largest |φ_i| of the active contacts over the samples so far
// (output rows and events) and rtol · |x0| + atol the position tolerance of an adaptive
// method at the origin translation x0 = (x0, y0, z0) of the phase start (m): ten times what
// integration error can put on a gap, so that it cannot re-close a contact that has just
// opened. Every driver (kneedyn run, sweep, batch, both sensitivity drivers) passes its
// own rtol and atol.
//
// Sensitivity drivers plug in as steppers: their Start computes the sensitivities' jump
// conditions at the phase start they are given (the restart state the simulator made), their
// Advance records what they measure at events; the hooks below hand them the samples.
#pragma once

#include <functional>
#include <string>
#include <vector>

#include "formulations/formulation.hpp"
#include "formulations/run.hpp"
#include "solver/rotation.hpp"

namespace kneedyn {

// The re-contact hysteresis of a phase starting at q (m; see the header).
double RecontactGapTolerance(double max_position_residual, const Vector6d& q, double rtol, double atol);

// The state a phase starts from after a contact switch and at a phase start of the
// published ligament law (branches locked).
enum class RestartProjection {
  // CompleteHiddenConstraint: (q, q̇) projected onto the active contacts' position and
  // velocity constraints (removes the drift of velocity-level methods and the hysteresis
  // penetration of a re-contact), then the hidden level (q̈, N). kneedyn run and the DAE
  // sensitivities (whose restart sensitivities differentiate this map).
  kProject,
  // (q, q̇) unchanged; the hidden level (q̈, N) solved at them. The ODE sensitivities
  // (CVODES on y = (q, q̇)): their jump s⁺ = s⁻ + (f⁻ − f⁺) dτ/dp (Hiskens & Pai 2000,
  // Eq. 9) holds for a state that is continuous at the event.
  kKeepState,
};

// A contact whose consistent force would pull (N < 0) right after a switch.
enum class PullingContact {
  kSeparate,  // it lifts off at once (recorded as liftoff_<compartment>); solved again
  kRefuse,    // SolverError: the sensitivities of a simultaneous lift-off are not defined
};

// Output times closer than this share one sample (s): an extra output time within it of a
// uniform output time, an earlier output or an event, and a uniform output time within it of
// an event. A step that short would only add round-off (CVODE stops at each output time).
inline constexpr double kOutputTimeMerge = 1e-12;

struct SimulatorSettings {
  ConsistentInitOptions init;     // form and chart of the stepper
  double output_interval = 0.0;   // s, > 0 (callers validate it with IsValidOutputInterval)
  // More output times (s, increasing) besides the uniform ones; a time within 1e-12 s of a
  // uniform output time, an earlier output or an event adds no sample. Empty: the uniform
  // grid alone (kneedyn run). `kneedyn score` asks for a result's own times here.
  std::vector<double> output_times;
  double rtol = 1.0e-6;           // the stepper's tolerances, for the re-contact hysteresis
  double atol = 1.0e-8;
  RestartProjection restart = RestartProjection::kProject;
  PullingContact pulling = PullingContact::kSeparate;
  // Called after the first phase has started (the stepper's Start has run at t0).
  std::function<void(const MechanicalState&)> first_phase_started;
  // Called after every output sample with the sample and whether it is an event row.
  std::function<void(const MechanicalState&, bool is_event)> sample;
};

// What a transition did (PhaseTransition).
struct TransitionOutcome {
  bool ended = false;              // an end event fired: no next phase
  std::string end_reason;          // its name when ended
  long ligament_kink_crossings = 0;
};

// The transition from one phase to the next, the one the Simulator runs at every event
// that is not a ligament kink alone (docs/model.md §9): at *state (the event's state from
// the stepper), with `fired` indices into `specs` (the phase's events):
//   the end flexion ends the run (state untouched apart from dropped forces);
//   a lift-off drops its contact; a re-contact adds its contact and applies the perfectly
//   plastic impact (solver/impact.hpp); then the restart state (RestartProjection) and
//   contacts whose consistent force would pull (PullingContact: recorded as
//   liftoff_<compartment>, or SolverError for kRefuse).
// The events of the switch are appended to *events in the order recorded (also those
// recorded before a SolverError). On return (not ended) *state is the next phase's consistent state: active contacts,
// q, q̇, q̈, N. The next phase's events and ligament branches come from the phase start
// (EventsForPhase, LigamentBranchesAt), as Simulator::Run does.
TransitionOutcome PhaseTransition(const Model& model, const std::vector<EventSpec>& specs,
                                  const std::vector<int>& fired, RestartProjection restart,
                                  PullingContact pulling, MechanicalState* state,
                                  std::vector<EventRecord>* events);

// Releases the active contacts whose consistent force would pull (N < 0): the most negative
// first, then solves again (e.g. a re-contact that bounces off, the second compartment
// unloading as the first lifts off, or an assembled start whose forces are tensile), each
// recorded as a lift-off at state->t (docs/model.md §9). `refusal`: kRefuse's reason.
// Returns whether it released any. The Simulator calls it at the start, after each switch
// (inside PhaseTransition) and at each restart; the Problem interface likewise.
bool ReleasePullingContacts(const Model& model, RestartProjection restart, PullingContact pulling, const char* refusal,
                            MechanicalState* state, std::vector<EventRecord>* events);

// The start of every phase after the first (a restart after a switch, a ligament kink or a
// patellar event), as Simulator::Run and the Problem interface do it: StartPhase, then the
// contacts whose consistent force pulls there lift off at once (ReleasePullingContacts; their
// roots would start negative and never cross zero: generalized-alpha at A = 1e5 N kept a
// lateral contact at -1.4 kN for 6 ms), and the phase starts again on the new contact set.
// *released: whether any lifted off (recorded in *events).
std::vector<EventSpec> StartRestartedPhase(const Model& model, const EndCondition& end, double gap_tolerance,
                                           RestartProjection restart, PullingContact pulling, MechanicalState* state,
                                           std::vector<EventRecord>* events, bool* released);

// RestartProjection at *state: the hidden level (q̈, N, contact coordinates) on the
// active contacts, after projecting (q, q̇) for kProject.
void CompleteRestartState(const Model& model, RestartProjection restart, MechanicalState* state);

// The start of a phase at *state, as Simulator::Run does it: the phase's events
// (EventsForPhase with the re-contact hysteresis gap_tolerance) and, for the published
// ligament law, the branches locked from the direction of motion with the restart state
// solved on them (not when `complete` is false: the chapter's DASSL start).
std::vector<EventSpec> StartPhase(const Model& model, const EndCondition& end, double gap_tolerance,
                                  RestartProjection restart, MechanicalState* state, bool complete = true);

// The rules a fixed step h (s) keeps on a scene, refused before integrating (InputError, exit
// 2): a fixed-step method lands on each output time by cutting a step there, so an interval
// (s) shorter than its step would set its step; and a step longer than a tenth of a pulse
// lasting past t (the tibial pulse or the quadriceps half-sine) does not resolve it
// (kStepsPerPulse, formulation.hpp; `pulses` false skips that rule). h = 0: an adaptive method.
// The simulator applies them at the start; batches and sweeps on their base scene, before the runs.
void CheckFixedStep(const Model& model, double t, double h, double output_interval, bool pulses);

class Simulator {
 public:
  // `scene` and `stepper` outlive the simulator; `record` receives init, events, samples,
  // sample_is_event, end_reason, the residual maxima and the kink crossings.
  Simulator(const Scene& scene, Formulation* stepper, SimulatorSettings settings, RunResult* record);

  // Consistent initialization and the t0 sample. Throws InputError for contact rows that
  // are dependent at the start.
  void Initialize();
  // Phases until the end condition. Throws what the stepper throws (SolverError, ...);
  // state() is then the last state the simulator holds.
  void Run();
  const MechanicalState& state() const { return state_; }

 private:
  void Record(bool is_event);

  // The model's reading of the angular-velocity map, on this thread for the simulator's life.
  ScopedAngularVelocityMapReading map_reading_;
  const Scene& scene_;
  Formulation* stepper_;
  SimulatorSettings settings_;
  RunResult* record_;
  MechanicalState state_;
};

}  // namespace kneedyn
