// The knee as an open initial-value problem, one phase at a time (docs/problem.md): what an
// outside solver needs to run the whole hybrid problem itself — sizes and index, the
// consistent initial values of the phase, f (ODE forms) or F (DAE forms) with Jacobians, the
// named event functions, and the transition to the next phase. Built on the functions the
// formulations call (solver/constrained_dynamics.hpp for the ODE form, DaeSystem for the
// DAE forms) and on the simulator's own phase start and transition (StartPhase,
// PhaseTransition in formulations/simulator.hpp), so no physics is written here.
//
// Forms: "ede"  y = (q, q̇) (12), f = (q̇, q̈) with q̈ from the hidden constraint (index 0 ODE);
//        "mde"  y = (s, ṡ), s the 6 − k coordinates the k active contacts leave free (the mde
//               formulation's chart, MdeChart; 12 − 2k), f = (ṡ, s̈) (index 0 ODE, no drift);
//               a phase with contacts also watches "mde_chart" (the chart in use lost a factor
//               2 against the best one), whose transition restarts in the best chart;
//        "dae"  the chapter's index-2 DAE (DaeSystem, chapter contact form), y = (q, u, c, N);
//        "dae-ggl" its Gear–Gupta–Leimkuhler form (index 2), y = (q, u, c, N, μ).
// Errors: ProblemError (a std::invalid_argument) names the call, the value and the rule.
#pragma once

#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "formulations/internal/dae_system.hpp"
#include "formulations/internal/mde_chart.hpp"
#include "formulations/run.hpp"
#include "formulations/simulator.hpp"
#include "scene/scene.hpp"
#include "solver/constrained_dynamics.hpp"

namespace kneedyn {

class ProblemError : public std::invalid_argument {
 public:
  using std::invalid_argument::invalid_argument;
};

class Problem {
 public:
  // form: "ede", "mde", "dae", "dae-ggl". Throws ProblemError for another form and InputError for a
  // scene whose start is inconsistent. rtol, atol: the defaults an adaptive solver is run
  // with (they also set the re-contact hysteresis, as in kneedyn run); in kneedyn run's
  // ranges (kMaxRtol, kMaxAtol), else ProblemError. Every evaluation throws SolverError when
  // a value it computes from finite inputs is not finite.
  Problem(const Scene& scene, const std::string& form, double rtol = 1.0e-6, double atol = 1.0e-8);

  const std::string& form() const { return form_; }
  bool is_dae() const { return form_ == "dae" || form_ == "dae-ggl"; }
  bool is_mde() const { return form_ == "mde"; }
  // mde: the coordinates of q that s holds (ascending) in the chart in use.
  const std::vector<int>& free_coordinates() const { return chart_->free(); }
  // Index of the form: 0 (ODE), 2 (both DAE forms, velocity-level constraint).
  int index() const { return is_dae() ? 2 : 0; }
  int size() const { return n_; }  // of the current phase (the DAE size changes with contacts)
  double t0() const { return t0_; }
  double t_end() const { return scene_.end.time; }
  double rtol() const { return rtol_; }
  double atol() const { return atol_; }
  bool ended() const { return ended_; }
  // Throws ProblemError naming `call` once the run has ended (no phase is open).
  void CheckOpen(const char* call) const;
  const std::string& end_reason() const { return end_reason_; }
  // Phases started so far − 1 (a restart at a ligament kink counts, as in the simulator).
  int phase() const { return phase_; }
  const MechanicalState& phase_state() const { return state_; }
  double phase_start_time() const { return state_.t; }

  // Consistent values at the phase start (t0 for the first phase, else the transition time).
  // These, the ids, names and events below are the open phase's: after the end they throw.
  const std::vector<double>& y0() const { CheckOpen("y0"); return y0_; }
  const std::vector<double>& yp0() const { CheckOpen("yp0"); return yp0_; }
  // 1 for differential, 0 for algebraic components (DAE forms; all 1 for ede).
  std::vector<double> differential_ids() const;
  std::vector<std::string> component_names() const;

  // ODE form: f(t, y) into f (size()).
  void Rhs(double t, const double* y, int n, double* f) const;
  // ODE forms: ∂f/∂y (row-major size()×size()), exact for every surface pair and the patella:
  // ede by ConstrainedAccelerationJacobian (forward AD and the implicit function theorem;
  // general pairs' κ through TimeDual over the Jet), mde by the chain rule through the
  // chart's elimination (MdeJacobian).
  void Jacobian(double t, const double* y, int n, double* J_row_major) const;
  // DAE forms: F(t, y, ẏ) into F.
  void Residual(double t, const double* y, const double* yp, int n, double* F) const;
  // DAE forms: ∂F/∂y + c ∂F/∂ẏ, exact (DaeSystem::Jacobian), row-major.
  void Jacobian(double t, const double* y, const double* yp, double c, int n, double* J_row_major) const;

  // The events of the phase: g_k, their names and directions (−1 decreasing, +1 increasing,
  // 0 both; SUNDIALS convention).
  int event_count() const { return static_cast<int>(specs_.size()) + (has_chart_event() ? 1 : 0); }
  std::vector<std::string> event_names() const;
  std::vector<int> event_directions() const;
  void Events(double t, const double* y, int n, double* g) const;

  // n: the length of y (and yp), checked against size(); times and states must be finite.
  // The transition at the roots of `events` (distinct indices; t, y: the event state, t in
  // [phase_start_time(), t_end()]; yp for the DAE forms): the simulator's PhaseTransition and
  // StartPhase. Returns true when the run has ended; otherwise y0(), yp0(), size() and the
  // events are the next phase's. The events recorded (with pulling contacts that lift off at
  // once) are appended to events_recorded(). All or nothing: when it throws, the problem is
  // left in the phase it was in.
  bool Transition(double t, const double* y, const double* yp, int n, const std::vector<int>& events);
  const std::vector<EventRecord>& events_recorded() const { return events_; }
  // The name of the mde chart-switch event.
  static constexpr const char* kChartEvent = "mde_chart";

  // The mechanical state (t, q, q̇, q̈, N, contact coordinates) a form's (t, y, ẏ) stands for.
  MechanicalState StateAt(double t, const double* y, const double* yp) const;
  // StateAt with y (and yp for the DAE forms, may be null) checked like the other calls.
  MechanicalState Coordinates(double t, const double* y, const double* yp, int n) const {
    CheckTime("Coordinates", t);
    CheckState("Coordinates", "y", y, n);
    if (yp != nullptr) CheckState("Coordinates", "yp", yp, n);
    return StateAt(t, y, yp);
  }

 private:
  // What a transition changes, kept to put back when it throws part-way.
  struct PhaseSnapshot;
  PhaseSnapshot Save() const;
  void Restore(PhaseSnapshot&& saved);
  bool TransitionUnguarded(double t, const double* y, const double* yp, const std::vector<int>& events);

  void BeginPhase();
  // The scene's reading of the angular-velocity map (docs/model.md §2) on the calling
  // thread for one call: the solver's functions read it per thread (as a run sets it for its
  // life), and an outside solver may call from any thread.
  ScopedAngularVelocityMapReading MapReading() const {
    return ScopedAngularVelocityMapReading(scene_.model.angular_velocity_map);
  }
  // `name` ("y" or "yp") is the array the message names.
  void CheckState(const char* call, const char* name, const double* y, int n) const;
  void CheckTime(const char* call, double t) const;
  void AccelerationAt(double t, const double* y) const;
  void BeginChart();  // mde: y0, yp0 in the chart in use
  void MdeJacobian(double t, const double* y, double* J) const;
  // mde: the chart's evaluation at (t, y), then its Newton start re-seeded there (as the mde
  // formulation after each step), so f depends on the calls before it at round-off level on
  // surfaces without a closed form.
  MdeKinematics MdeEvaluate(double t, const double* y, VecM* sdd) const;
  bool has_chart_event() const { return is_mde() && !state_.active.empty(); }

  const Scene& scene_;
  std::string form_;
  double rtol_, atol_;
  double t0_ = 0.0;
  int n_ = 12;
  int phase_ = 0;
  bool ended_ = false;
  std::string end_reason_;
  double max_position_residual_ = 0.0;  // observed drift, for the re-contact hysteresis (m)
  MechanicalState state_;                // the phase start
  std::vector<EventSpec> specs_;
  std::vector<EventRecord> events_;
  std::vector<double> y0_, yp0_;
  std::unique_ptr<DaeSystem> dae_;
  mutable ConstrainedDynamicsWorkspace workspace_;
  mutable ConstrainedAcceleration acc_;
  mutable std::vector<double> normal_;
  std::unique_ptr<MdeChart> chart_;  // a pointer so that a transition can put the old chart back
};

}  // namespace kneedyn
