// The run driver shared by every formulation (`kneedyn run`, sweep, batch): the formulation
// as the stepper of the hybrid simulator (simulator.hpp: consistent initialization, phases
// between contact-mode switches, events, re-contact as a perfectly plastic impact, output at
// a uniform interval plus every event), and the run's statistics.
#pragma once

#include <functional>
#include <limits>
#include <string>
#include <vector>

#include "formulations/formulation.hpp"
#include "solver/constraint_residuals.hpp"  // ConstraintResiduals, for callers of RunScene

namespace kneedyn {

struct RunSettings {
  std::string formulation = "dae";
  FormulationOptions options;
  ConsistentInitOptions init;       // init.form is set from the formulation
  double output_interval = 0.0;     // s; 0 = the scene's output.interval_s
  std::vector<double> output_times;  // s, increasing: more output rows (SimulatorSettings)
  // Called after every output row with (t, flexion in rad); may be empty.
  std::function<void(double, double)> progress;
  // The command that asked for the run (argv), recorded in summary.json; may be empty.
  std::vector<std::string> command_line;
};

struct EventRecord {
  std::string name;    // liftoff_medial, recontact_lateral, flexion_90, ...
  double time = 0.0;   // s
  double flexion = 0.0;  // rad
  // A located tibial lift-off only: the contact's normal force (N) of the hidden-constraint
  // solve at the event state with the contact kept (RestartAcceleration). About 0 where the
  // method's own force crossed zero accurately; far from 0 where it crossed on an error mode
  // (warning `liftoff_force_not_zero`, run_output.hpp). NaN otherwise.
  double consistent_normal_force = std::numeric_limits<double>::quiet_NaN();
};

struct RunResult {
  bool completed = false;       // false: solver failure, see failure
  std::string failure;          // the solver's reason, t and h
  std::string end_reason;       // event name that ended the run, or "end_time"
  InitReport init;
  std::vector<EventRecord> events;
  std::vector<MechanicalState> samples;  // output rows, in time order
  std::vector<bool> sample_is_event;     // parallel to samples
  SolverStats stats;
  std::string integrator;   // the integrator actually run (Formulation::integrator())
  double fixed_step = 0.0;  // s, the fixed step actually used; 0: adaptive
  double wall_time_s = 0.0;
  double max_position_residual = 0.0;  // max |φ_i| over active contacts and samples, m
  double max_velocity_residual = 0.0;  // max |φ̇_i|, m/s
  // The re-contact hysteresis over the run's phases (simulator.hpp, m): its largest value,
  // and the largest part of it the tolerances alone give, 10 (rtol |x0| + atol). The first
  // exceeds the second when the observed drift set it.
  double max_recontact_gap_tolerance = 0.0;
  double max_recontact_gap_tolerance_of_tolerances = 0.0;
  long ligament_kink_crossings = 0;    // restarts at the published law's jump
};

// Runs a scene. Input errors (options, scene) throw InputError before anything runs;
// solver failures during integration are caught and returned (completed = false) with
// what was computed up to there.
RunResult RunScene(const Scene& scene, const RunSettings& settings);

}  // namespace kneedyn
