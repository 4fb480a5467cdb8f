// Explicit-ODE driver y' = f(t, y) with root functions, shared by `mde` and `ede` (the one
// place for their SUNDIALS glue). Integrators (the --integrator names are a contract):
//   euler, rk4         fixed step --step H (default kDefaultFixedStep), ARKODE ARKStep
//                      explicit with Butcher tables built here (ARKODE 6.4 has no Euler/RK4
//                      table). The stop time is set to every output time, so outputs lie on
//                      step boundaries (the true discrete solution, not an interpolant): an
//                      output time that is not a multiple of H makes the last step before it
//                      shorter (ARKODE snaps a step ending within round-off of the stop time
//                      onto it). The next step has H again.
//                      (Root states come from the Hermite interpolant: history-free, so valid
//                      right after an ede projection restart; Lagrange is not.)
//   dopri5, verner65,  adaptive embedded ERK (ARKODE_DORMAND_PRINCE_7_4_5,
//   fehlberg78         ARKODE_VERNER_8_5_6, ARKODE_FEHLBERG_13_7_8), --rtol/--atol.
//                      dopri5 in ARKODE's ERKStep, which reuses the last stage's right-hand
//                      side as the next step's first (first same as last: six per step),
//                      with ARKStep's step-size controller; verner65 and fehlberg78 in
//                      ARKStep (not first-same-as-last; ode_integrator.cpp, ArkodeStepper).
//   cvode-bdf          CVODE BDF, Newton with dense LU, difference-quotient Jacobian.
//   cvode-adams        CVODE Adams–Moulton with fixed-point (functional) iteration.
// Default (empty --integrator): dopri5. Roots located by ARKODE/CVODE root finding with the
// EventSpec directions; a root's state is the solver's interpolant at the root, except with
// verner65 and fehlberg78: there ARKODE's Hermite interpolant (degree <= 5, its degree-4 and
// -5 forms built on lower-degree ones) is less accurate than these methods' long steps, so
// the root's state is one step of the method itself from the step's start, and the root
// time is refined on such steps (StepToRoot; measured: benchmarks/performance-log.md, "Event states
// of the high-order Runge–Kutta methods").
#pragma once

#include <nvector/nvector_serial.h>
#include <sundials/sundials_linearsolver.h>
#include <sundials/sundials_matrix.h>
#include <sundials/sundials_nonlinearsolver.h>

#include <string>
#include <vector>

#include "formulations/formulation.hpp"
#include "formulations/internal/sundials_util.hpp"
#include "solver/scalar.hpp"

namespace kneedyn {

struct ArkodeStepper;  // ode_integrator.cpp

// The problem an OdeIntegrator integrates.
class OdeProblem {
 public:
  virtual ~OdeProblem() = default;
  // ẏ = f(t, y). Returns false on a recoverable failure (the solver retries with a smaller
  // step when it can); throws on an unrecoverable one (its message is kept for the error).
  virtual bool Rhs(double t, const double* y, double* ydot) = 0;
  // g_k(t, y), one per root direction given to Start.
  virtual void Roots(double t, const double* y, double* g) = 0;
  // Projection onto the constraint manifold for CVODE's own projection (cvode-bdf):
  // writes corr with y + corr on the manifold. Only called when enabled in Start.
  virtual void ProjectionCorrection(double t, const double* y, double* corr) {
    (void)t, (void)y, (void)corr;
  }
  // Name of state component i in failure messages ("alpha", "alpha_rate", ...).
  virtual std::string StateName(int i) const { return "y[" + std::to_string(i) + "]"; }
};

// The options of mde and ede, typed and checked (ReadOdeOptions).
struct OdeOptions {
  StepControl control;
  IntegratorKind integrator = IntegratorKind::kDopri5;
  Stabilization stabilization = Stabilization::kNone;  // ede
  double baumgarte_alpha = 20.0;  // 1/s, --stabilization baumgarte
  double baumgarte_beta = 20.0;   // 1/s
};
// Reads them from a request (ode_integrator.cpp): the integrator (not given: dopri5) and the
// rules that tie the stabilization to the integrator.
bool ReadOdeOptions(const OptionRequest& request, OdeOptions* options);

class OdeIntegrator {
 public:
  // options.integrator with options.control (its step for euler and rk4); `owner` names the
  // formulation in messages.
  OdeIntegrator(const OdeOptions& options, std::string owner);
  ~OdeIntegrator();
  OdeIntegrator(const OdeIntegrator&) = delete;
  OdeIntegrator& operator=(const OdeIntegrator&) = delete;

  const std::string& name() const { return name_; }
  IntegratorKind kind() const { return kind_; }
  bool fixed_step() const { return kind_ == IntegratorKind::kEuler || kind_ == IntegratorKind::kRk4; }
  double step() const { return fixed_step() ? step_ : 0.0; }  // s; 0: adaptive

  // Sets the solver up for a phase: re-initialized when the phase has as many unknowns as
  // the last one (and the same `solver_projection`), else built for the new size (sizes may
  // change between phases). `solver_projection`:
  // use CVODE's projection after each step (CVodeSetProjFn; cvode-bdf only) instead of the
  // caller's own project-and-Reset loop (which restarts a multistep method at order 1).
  void Start(OdeProblem* problem, double t0, const VectorXd& y0, const std::vector<int>& root_directions,
             bool solver_projection = false);
  bool supports_solver_projection() const { return kind_ == IntegratorKind::kCvodeBdf; }
  // The next step's first right-hand side is at the point where the root functions were last
  // evaluated, the step's end (tn, yn): true for the methods in ARKStep (their first stage),
  // false for CVODE (its corrector starts from the predicted y) and for dopri5 in ERKStep
  // (its first stage is the last stage's right-hand side, at the same point, not evaluated).
  bool next_step_starts_at_step_end() const { return !is_cvode() && !in_erkstep(); }
  // A root's state and time come from the method's own steps (StepToRoot), not from ARKODE's
  // interpolant: verner65, fehlberg78 (header comment).
  bool steps_to_roots() const { return kind_ == IntegratorKind::kVerner65 || kind_ == IntegratorKind::kFehlberg78; }
  // Integrates towards t_out (stop time t_out): to t_out, or one step if `one_step`, or to a
  // root. On entry *t is the current time (of the last Start, Reset or Evolve). Writes t and
  // y reached; returns true when roots were found (`roots`: their flags). t_out equal to *t
  // (within ARKODE's stop-time round-off, 100 ε (|t| + |t_out|)) is already reached: no
  // step, *t = t_out, y unchanged (ARKODE rejects a stop time at the current time, e.g. after
  // a restart at a root found at the end of a step that ended on an output time).
  // t_out < *t throws. --max-steps (StepControl::max_steps) bounds the steps since the last
  // Start, over all calls (a phase of ede; a chart of mde, which counts its phase itself;
  // a coupling step of staggered, Reset):
  // each call may take only what is left, and running out throws SolverError naming it.
  bool Evolve(double t_out, bool one_step, double* t, VectorXd* y, std::vector<int>* roots);
  // Restarts from a modified state (after a projection), keeping the step size and counters.
  // `new_step_budget`: the --max-steps budget starts again (staggered's coupling steps, each
  // its own integration; the budget of their count is the formulation's).
  void Reset(double t, const VectorXd& y, bool new_step_budget = false);
  SolverStats stats() const;
  // Testing hook (Formulation::EvaluateHotPathForTesting): the right-hand-side and root
  // callbacks the solver calls, n times at (t, y), through the same glue; false on failure.
  bool EvaluateCallbacksForTesting(double t, const VectorXd& y, int n);

 private:
  static int RhsCallback(double t, N_Vector y, N_Vector ydot, void* user);
  // After ARKODE's root return (steps_to_roots()): replaces its interpolated t, y by the
  // discrete solution at the root of the first fired function, found by Illinois regula
  // falsi on single steps of the method from the crossing step's start (ARKStepReset, then
  // a fixed step to each trial time; the trial steps and root evaluations are counted).
  // Keeps ARKODE's root when the exact steps show no sign change across the step. ARKODE is
  // then left at a trial step: every root ends the phase, and Start builds it anew; Evolve
  // and Reset refuse until then.
  void StepToRoot(const std::vector<int>& fired, double* t, VectorXd* y);
  [[noreturn]] void RefuseAfterSteppedRoot(const char* function) const;
  static int RootCallback(double t, N_Vector y, double* g, void* user);
  static int ProjCallback(double t, N_Vector y, N_Vector corr, double eps, N_Vector err, void* user);
  bool is_cvode() const { return kind_ == IntegratorKind::kCvodeBdf || kind_ == IntegratorKind::kCvodeAdams; }
  // dopri5 runs in ERKStep, the other explicit methods in ARKStep (ode_integrator.cpp, ArkodeStepper).
  bool in_erkstep() const { return kind_ == IntegratorKind::kDopri5; }
  void Check(int flag, const char* call);
  // Check for a call of the ARKODE stepper in use, named "ARKStep" or "ERKStep" + call.
  void CheckArk(int flag, const char* call);
  SolverStats CurrentCounters() const;
  double LastStep() const;
  void Free();

  StepControl options_;
  std::string owner_;
  IntegratorKind kind_ = IntegratorKind::kDopri5;
  std::string name_;  // OptionName(kind_)
  const ArkodeStepper* ark_;  // the ARKODE stepper of the explicit methods (ode_integrator.cpp)
  double step_ = 0.0;  // s, fixed-step methods
  SundialsContext ctx_;
  OdeProblem* problem_ = nullptr;
  std::string LargestErrorComponent() const;
  void* mem_ = nullptr;
  N_Vector y_ = nullptr;
  N_Vector hot_path_y_ = nullptr, hot_path_ydot_ = nullptr;  // EvaluateCallbacksForTesting
  std::vector<double> hot_path_g_;
  SUNMatrix A_ = nullptr;
  SUNLinearSolver LS_ = nullptr;
  SUNNonlinearSolver NLS_ = nullptr;
  int n_ = 0;
  int num_roots_ = 0;
  bool solver_projection_ = false;  // CVodeSetProjFn is set on mem_
  bool stepped_to_root_ = false;     // StepToRoot moved ARKODE to a trial step (until Start)
  // CVodeReInit leaves the linear solver interface's counters (Jacobians, difference-quotient
  // right-hand sides) to the next CVode call, which zeroes them: until then they count as 0.
  bool linear_counters_stale_ = false;
  long start_steps_ = 0;     // steps taken since the last Start (the --max-steps budget)
  SolverStats accumulated_;  // finished solver instances and pre-reset segments
  SolverStats baseline_;     // counters of the live instance at its last reset
  std::string failure_;
  SundialsMessages sundials_messages_;  // SUNDIALS' error text, for the failure reason
};

}  // namespace kneedyn
