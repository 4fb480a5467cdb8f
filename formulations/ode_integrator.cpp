#include "formulations/internal/ode_integrator.hpp"

#include "formulations/internal/sundials_util.hpp"

#include <arkode/arkode_arkstep.h>
#include <arkode/arkode_erkstep.h>
#include <arkode/arkode_butcher_erk.h>
#include <cvode/cvode.h>
#include <cvode/cvode_proj.h>
#include <sunlinsol/sunlinsol_dense.h>
#include <sunmatrix/sunmatrix_dense.h>
#include <sunnonlinsol/sunnonlinsol_fixedpoint.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <limits>

#include "solver/error.hpp"

namespace kneedyn {

// The ARKODE stepper an explicit Runge–Kutta method runs in, as a table of the calls
// ARKStep and ERKStep share (same signatures; creation, the Butcher table, the
// right-hand-side counter and the step's own state differ and are written out where used).
// dopri5 runs in ERKStep: its first stage takes the last stage's right-hand side of the
// previous step (first same as last: the last row of A is b and c = 1, so the last stage
// is the step's solution), six right-hand sides a step where ARKStep 6.4 evaluates seven
// (arkStep_TakeStep_Z calls f for the first stage every step). The other tables stay in
// ARKStep: ERKStep 6.4 reuses the last stage whenever its c is 1 (erkStep_FullRHS), which
// is right only for a first-same-as-last table (rk4, verner65 and fehlberg78 are not).
struct ArkodeStepper {
  const char* name;  // "ARKStep" or "ERKStep", for messages
  int (*Evolve)(void*, double, N_Vector, double*, int);
  int (*SetStopTime)(void*, double);
  int (*GetDky)(void*, double, int, N_Vector);
  int (*Reset)(void*, double, N_Vector);
  int (*SetInitStep)(void*, double);
  int (*SetFixedStep)(void*, double);
  int (*SetMaxStep)(void*, double);
  int (*SetMaxNumSteps)(void*, long);
  int (*SStolerances)(void*, double, double);
  int (*SetInterpolantType)(void*, int);
  int (*SetUserData)(void*, void*);
  int (*SetErrHandlerFn)(void*, ARKErrHandlerFn, void*);
  int (*RootInit)(void*, int, ARKRootFn);
  int (*SetRootDirection)(void*, int*);
  int (*SetNoInactiveRootWarn)(void*);
  int (*GetRootInfo)(void*, int*);
  int (*GetCurrentStep)(void*, double*);
  int (*GetCurrentTime)(void*, double*);
  int (*GetLastStep)(void*, double*);
  int (*GetNumSteps)(void*, long*);
  int (*GetNumErrTestFails)(void*, long*);
  int (*GetNumGEvals)(void*, long*);
  int (*GetEstLocalErrors)(void*, N_Vector);
  int (*GetErrWeights)(void*, N_Vector);
  char* (*GetReturnFlagName)(long);
  void (*Free)(void**);
};

namespace {

// One table per stepper, the same calls in the same order (the fields of ArkodeStepper).
#define KNEEDYN_ARKODE_STEPPER(Module)                                                         \
  ArkodeStepper {                                                                              \
    #Module, Module##Evolve, Module##SetStopTime, Module##GetDky, Module##Reset,               \
        Module##SetInitStep, Module##SetFixedStep, Module##SetMaxStep, Module##SetMaxNumSteps, \
        Module##SStolerances, Module##SetInterpolantType, Module##SetUserData,                 \
        Module##SetErrHandlerFn, Module##RootInit, Module##SetRootDirection,                   \
        Module##SetNoInactiveRootWarn, Module##GetRootInfo, Module##GetCurrentStep,            \
        Module##GetCurrentTime, Module##GetLastStep, Module##GetNumSteps,                      \
        Module##GetNumErrTestFails, Module##GetNumGEvals, Module##GetEstLocalErrors,           \
        Module##GetErrWeights, Module##GetReturnFlagName, Module##Free                         \
  }
const ArkodeStepper kArkStep = KNEEDYN_ARKODE_STEPPER(ARKStep);
const ArkodeStepper kErkStep = KNEEDYN_ARKODE_STEPPER(ERKStep);
#undef KNEEDYN_ARKODE_STEPPER

SolverStats Minus(SolverStats a, const SolverStats& b) {
  a.steps -= b.steps;
  a.residual_evaluations -= b.residual_evaluations;
  a.jacobian_evaluations -= b.jacobian_evaluations;
  a.linear_solver_setups -= b.linear_solver_setups;
  a.nonlinear_iterations -= b.nonlinear_iterations;
  a.error_test_failures -= b.error_test_failures;
  a.convergence_failures -= b.convergence_failures;
  a.root_evaluations -= b.root_evaluations;
  return a;
}

// Forward Euler (order 1) and the classical RK4 (order 4), no embedding (fixed step).
ARKodeButcherTable FixedStepTable(IntegratorKind kind) {
  if (kind == IntegratorKind::kEuler) {
    double c[1] = {0.0}, A[1] = {0.0}, b[1] = {1.0};
    // Table order field 2, not 1: ARKODE 6.4 caps the Hermite interpolant degree at the
    // table's q − 1, and degree 0 is the constant (y_old + y_new)/2 over the step, so roots
    // were reported just after the step start with that average state (one step of time
    // lost per event) and tstop outputs were the average too. Degree 1 is the chord
    // y_n + (t − t_n) f(t_n, y_n), Euler's own continuous extension (exact for it). With
    // a fixed step the field drives nothing else (no error control). SUNDIALS 6.6 made the
    // linear interpolant the default for first-order methods.
    return ARKodeButcherTable_Create(1, 2, 0, c, A, b, nullptr);
  }
  double c[4] = {0.0, 0.5, 0.5, 1.0};
  double A[16] = {0.0, 0.0, 0.0, 0.0,  //
                  0.5, 0.0, 0.0, 0.0,  //
                  0.0, 0.5, 0.0, 0.0,  //
                  0.0, 0.0, 1.0, 0.0};
  double b[4] = {1.0 / 6.0, 1.0 / 3.0, 1.0 / 3.0, 1.0 / 6.0};
  return ARKodeButcherTable_Create(4, 4, 0, c, A, b, nullptr);
}

}  // namespace

bool ReadOdeOptions(const OptionRequest& request, OdeOptions* options) {
  const FormulationOptions& o = request.options;
  options->control = o.step_control();
  options->integrator = o.integrator.value_or(IntegratorKind::kDopri5);
  options->stabilization = o.stabilization;
  options->baumgarte_alpha = o.baumgarte_alpha;
  options->baumgarte_beta = o.baumgarte_beta;
  if (!(o.baumgarte_alpha >= 0.0) || !(o.baumgarte_beta >= 0.0)) {
    return request.Fail(StrCat("Baumgarte gains (", o.baumgarte_alpha, ", ", o.baumgarte_beta, "); must be >= 0"));
  }
  const std::string with = o.integrator ? StrCat(" with --integrator ", OptionName(*o.integrator)) : "";
  if (o.stabilization == Stabilization::kCvodeProjection && options->integrator != IntegratorKind::kCvodeBdf) {
    return request.Fail(StrCat("--stabilization cvode-projection", with.empty() ? " with the default integrator" : with,
                               ": CVODE's projection (CVodeSetProjFn) exists only for cvode-bdf; use --integrator "
                               "cvode-bdf or --stabilization projection"));
  }
  if (o.stabilization == Stabilization::kProjection &&
      (options->integrator == IntegratorKind::kCvodeAdams || options->integrator == IntegratorKind::kCvodeBdf)) {
    // The project-and-restart loop restarts a multistep method at order 1 after every
    // projection: with cvode-bdf on the chapter scene about 40x the steps of the unstabilized
    // run at the default tolerances, and a Jacobian per step.
    return request.Fail(StrCat("--stabilization projection with --integrator ", OptionName(options->integrator),
                               ": not supported (the project-and-restart loop restarts the multistep method at order 1 "
                               "after every projection); use --integrator cvode-bdf --stabilization cvode-projection "
                               "(CVODE's own projection) or an ERK method"));
  }
  return true;
}

OdeIntegrator::OdeIntegrator(const OdeOptions& options, std::string owner)
    : options_(options.control),
      owner_(std::move(owner)),
      kind_(options.integrator),
      name_(OptionName(kind_)),
      ark_(in_erkstep() ? &kErkStep : &kArkStep) {
  if (fixed_step()) step_ = options.control.step > 0.0 ? options.control.step : kDefaultFixedStep;
}

OdeIntegrator::~OdeIntegrator() { Free(); }

void OdeIntegrator::CheckArk(int flag, const char* call) {
  if (flag >= 0) return;
  Check(flag, StrCat(ark_->name, call).c_str());  // "ERKStepSetStopTime"
}

void OdeIntegrator::Check(int flag, const char* call) {
  if (is_cvode()) {
    CheckSundials(flag, call, "OdeIntegrator", CVodeGetReturnFlagName, &sundials_messages_);
  } else {
    CheckSundials(flag, call, "OdeIntegrator", ark_->GetReturnFlagName, &sundials_messages_);
  }
}

int OdeIntegrator::RhsCallback(double t, N_Vector y, N_Vector ydot, void* user) {
  auto* self = static_cast<OdeIntegrator*>(user);
  try {
    return self->problem_->Rhs(t, NvData(y), NvData(ydot)) ? 0 : 1;
  } catch (const std::exception& e) {
    self->failure_ = e.what();
    return -1;
  }
}

int OdeIntegrator::RootCallback(double t, N_Vector y, double* g, void* user) {
  auto* self = static_cast<OdeIntegrator*>(user);
  try {
    self->problem_->Roots(t, NvData(y), g);
    return 0;
  } catch (const std::exception& e) {
    self->failure_ = e.what();
    return -1;
  }
}

int OdeIntegrator::ProjCallback(double t, N_Vector y, N_Vector corr, double, N_Vector, void* user) {
  auto* self = static_cast<OdeIntegrator*>(user);
  try {
    self->problem_->ProjectionCorrection(t, NvData(y), NvData(corr));
    return 0;
  } catch (const std::exception& e) {
    self->failure_ = e.what();
    return -1;
  }
}

void OdeIntegrator::Start(OdeProblem* problem, double t0, const VectorXd& y0,
                          const std::vector<int>& root_directions, bool solver_projection) {
  if (solver_projection && !supports_solver_projection()) {
    Throw<InputError>("OdeIntegrator::Start", "solver projection with --integrator ", name_,
                      ": CVODE projects only with BDF (cvode-bdf)");
  }
  const double previous_step = LastStep();
  const int n = static_cast<int>(y0.size());
  // CVODE: a phase as large as the last one re-initializes the solver (CVodeReInit sets the
  // state CVodeInit sets; the options are kept), else the solver is built anew. ARKODE is
  // always built anew: a run re-initialized by ARKStepReInit is not a new instance's (its
  // root-finding memory and counters persist; measured: the patellofemoral dopri5 trajectory
  // moves, the chapter run counts 2,759 right-hand sides instead of 2,704).
  const bool reinitialize = is_cvode() && mem_ != nullptr && n == n_ && solver_projection == solver_projection_;
  if (reinitialize) {
    accumulated_ += Minus(CurrentCounters(), baseline_);
  } else {
    Free();
    n_ = n;
    y_ = NewSerialVector(n_, ctx_);
    hot_path_y_ = NewSerialVector(n_, ctx_);
    hot_path_ydot_ = NewSerialVector(n_, ctx_);
  }
  problem_ = problem;
  stepped_to_root_ = false;
  solver_projection_ = solver_projection;
  num_roots_ = static_cast<int>(root_directions.size());
  for (int i = 0; i < n_; ++i) NvData(y_)[i] = y0(i);
  hot_path_g_.assign(num_roots_, 0.0);
  std::vector<int> dirs = root_directions;
  if (is_cvode()) {
    if (reinitialize) {
      Check(CVodeReInit(mem_, t0, y_), "CVodeReInit");
      Check(CVodeRootInit(mem_, 0, nullptr), "CVodeRootInit");  // the root functions' state afresh
      linear_counters_stale_ = true;
    } else {
      mem_ = CVodeCreate(kind_ == IntegratorKind::kCvodeBdf ? CV_BDF : CV_ADAMS, ctx_);
      if (mem_ == nullptr) Throw<SolverError>("OdeIntegrator::Start", "CVodeCreate failed");
      Check(CVodeSetErrHandlerFn(mem_, &SundialsMessages::Handler, &sundials_messages_), "CVodeSetErrHandlerFn");
      Check(CVodeInit(mem_, &OdeIntegrator::RhsCallback, t0, y_), "CVodeInit");
      Check(CVodeSetUserData(mem_, this), "CVodeSetUserData");
      Check(CVodeSStolerances(mem_, options_.rtol, options_.atol), "CVodeSStolerances");
      Check(CVodeSetMaxNumSteps(mem_, options_.max_steps), "CVodeSetMaxNumSteps");
      if (options_.max_step > 0.0) Check(CVodeSetMaxStep(mem_, options_.max_step), "CVodeSetMaxStep");
      if (kind_ == IntegratorKind::kCvodeBdf) {
        // Dense LU; no Jacobian function: CVODE's difference-quotient Jacobian.
        A_ = SUNDenseMatrix(n_, n_, ctx_);
        LS_ = SUNLinSol_Dense(y_, A_, ctx_);
        Check(CVodeSetLinearSolver(mem_, LS_, A_), "CVodeSetLinearSolver");
        if (solver_projection) Check(CVodeSetProjFn(mem_, &OdeIntegrator::ProjCallback), "CVodeSetProjFn");
      } else {
        NLS_ = SUNNonlinSol_FixedPoint(y_, 0, ctx_);
        Check(CVodeSetNonlinearSolver(mem_, NLS_), "CVodeSetNonlinearSolver");
      }
    }
    if (num_roots_ > 0) {
      Check(CVodeRootInit(mem_, num_roots_, &OdeIntegrator::RootCallback), "CVodeRootInit");
      Check(CVodeSetRootDirection(mem_, dirs.data()), "CVodeSetRootDirection");
      Check(CVodeSetNoInactiveRootWarn(mem_), "CVodeSetNoInactiveRootWarn");
    }
    // 0: CVODE's own estimate.
    Check(CVodeSetInitStep(mem_, previous_step > 0.0 ? 0.25 * previous_step : 0.0), "CVodeSetInitStep");
  } else {
    const bool erk = in_erkstep();
    mem_ = erk ? ERKStepCreate(&OdeIntegrator::RhsCallback, t0, y_, ctx_)
               : ARKStepCreate(&OdeIntegrator::RhsCallback, nullptr, t0, y_, ctx_);
    if (mem_ == nullptr) Throw<SolverError>("OdeIntegrator::Start", ark_->name, "Create failed");
    if (erk) {
      // ARKStep's step-size controller (arkSetDefaults: PID with its default gains, safety
      // 0.96, bias 1.5, growth 20; arkode_adapt_impl.h), not ERKStep's PI one: the stepper
      // changes the cost of a step, not the step sizes the method is compared at.
      CheckArk(ERKStepSetAdaptivityMethod(mem_, ARK_ADAPT_PID, 1, 0, nullptr), "SetAdaptivityMethod");
      CheckArk(ERKStepSetSafetyFactor(mem_, 0.96), "SetSafetyFactor");
      CheckArk(ERKStepSetErrorBias(mem_, 1.5), "SetErrorBias");
      CheckArk(ERKStepSetMaxGrowth(mem_, 20.0), "SetMaxGrowth");
    }
    CheckArk(ark_->SetErrHandlerFn(mem_, &SundialsMessages::Handler, &sundials_messages_), "SetErrHandlerFn");
    CheckArk(ark_->SetUserData(mem_, this), "SetUserData");
    // Hermite interpolant (ARKODE's default), also for euler/rk4: it needs no step history,
    // so root states stay accurate right after a projection restart (the Lagrange one
    // drops to low degree there). Outputs do not use it: the stop time puts them on steps.
    CheckArk(ark_->SetInterpolantType(mem_, ARK_INTERP_HERMITE), "SetInterpolantType");
    CheckArk(ark_->SetMaxNumSteps(mem_, options_.max_steps), "SetMaxNumSteps");
    ARKodeButcherTable table = nullptr;
    int q = 0, p = 0;
    if (fixed_step()) {
      CheckArk(ark_->SetFixedStep(mem_, step_), "SetFixedStep");
      table = FixedStepTable(kind_);
      q = kind_ == IntegratorKind::kEuler ? 1 : 4;
    } else {
      CheckArk(ark_->SStolerances(mem_, options_.rtol, options_.atol), "SStolerances");
      if (options_.max_step > 0.0) CheckArk(ark_->SetMaxStep(mem_, options_.max_step), "SetMaxStep");
      if (kind_ == IntegratorKind::kDopri5) {
        table = ARKodeButcherTable_LoadERK(ARKODE_DORMAND_PRINCE_7_4_5), q = 5, p = 4;
      } else if (kind_ == IntegratorKind::kVerner65) {
        table = ARKodeButcherTable_LoadERK(ARKODE_VERNER_8_5_6), q = 6, p = 5;
      } else {
        table = ARKodeButcherTable_LoadERK(ARKODE_FEHLBERG_13_7_8), q = 8, p = 7;
      }
      if (previous_step > 0.0) CheckArk(ark_->SetInitStep(mem_, 0.25 * previous_step), "SetInitStep");
    }
    if (table == nullptr) Throw<SolverError>("OdeIntegrator::Start", "Butcher table for ", name_, " not created");
    const int flag = erk ? ERKStepSetTable(mem_, table) : ARKStepSetTables(mem_, q, p, nullptr, table);
    ARKodeButcherTable_Free(table);
    CheckArk(flag, erk ? "SetTable" : "SetTables");
    if (num_roots_ > 0) {
      CheckArk(ark_->RootInit(mem_, num_roots_, &OdeIntegrator::RootCallback), "RootInit");
      CheckArk(ark_->SetRootDirection(mem_, dirs.data()), "SetRootDirection");
      CheckArk(ark_->SetNoInactiveRootWarn(mem_), "SetNoInactiveRootWarn");
    }
  }
  baseline_ = SolverStats();
  ++accumulated_.restarts;
  start_steps_ = 0;
}

bool OdeIntegrator::Evolve(double t_out, bool one_step, double* t, VectorXd* y, std::vector<int>* roots) {
  if (stepped_to_root_) RefuseAfterSteppedRoot("OdeIntegrator::Evolve");
  failure_.clear();
  roots->assign(num_roots_, 0);
  // Already at t_out: a restart at a root that ARKODE located at the end of a step that
  // ended on the stop time t_out (the driver then asks for t_out again). ARKODE would fail
  // with ARK_ILL_INPUT ("tstop is behind current t"), CVODE with CV_ILL_INPUT. Same
  // round-off window as ARKODE's own stop-time snap (FUZZ_FACTOR 100).
  const double t_roundoff = 100.0 * std::numeric_limits<double>::epsilon() * (std::abs(*t) + std::abs(t_out));
  if (t_out - *t <= t_roundoff) {
    if (*t - t_out > t_roundoff) {
      Throw<SolverError>("OdeIntegrator::Evolve", owner_, " (", name_, "): t_out = ", t_out,
                         " s is behind the current time t = ", *t, " s; must be >= t");
    }
    *t = t_out;
    return false;
  }
  // --max-steps is a budget per phase: a call to t_out gets what the phase's earlier calls
  // left (SUNDIALS' own limit counts per call). t_out is past *t here, so nothing left fails.
  const long left = PerCallStepLimit(options_.max_steps, start_steps_, t_out, *t);
  const auto out_of_steps = [&](double t_at) {
    Throw<SolverError>("OdeIntegrator::Evolve", owner_, " (", name_, "): more than --max-steps = ",
                       options_.max_steps, " steps in this phase at t = ", t_at,
                       " s (the budget is per phase, over all output intervals)");
  };
  if (left <= 0) out_of_steps(*t);
  const auto steps_taken = [&] {
    long v = 0;
    if (is_cvode()) {
      CVodeGetNumSteps(mem_, &v);
    } else {
      ark_->GetNumSteps(mem_, &v);
    }
    return v;
  };
  const long steps_before = steps_taken();
  double t_reached = *t;
  int flag = 0;
  bool root = false;
  if (is_cvode()) {
    Check(CVodeSetStopTime(mem_, t_out), "CVodeSetStopTime");
    if (!one_step) Check(CVodeSetMaxNumSteps(mem_, left), "CVodeSetMaxNumSteps");
    flag = CVode(mem_, t_out, y_, &t_reached, one_step ? CV_ONE_STEP : CV_NORMAL);
    linear_counters_stale_ = false;  // CVode's first call after a re-initialization zeroed them
    root = flag == CV_ROOT_RETURN;
  } else {
    CheckArk(ark_->SetStopTime(mem_, t_out), "SetStopTime");
    if (!one_step) CheckArk(ark_->SetMaxNumSteps(mem_, left), "SetMaxNumSteps");
    flag = ark_->Evolve(mem_, t_out, y_, &t_reached, one_step ? ARK_ONE_STEP : ARK_NORMAL);
    root = flag == ARK_ROOT_RETURN;
  }
  start_steps_ += steps_taken() - steps_before;
  if (flag < 0) {
    double h = 0.0, t_cur = 0.0;
    std::string text;
    if (is_cvode()) {
      CVodeGetCurrentStep(mem_, &h);
      CVodeGetCurrentTime(mem_, &t_cur);
      text = ReturnFlagText(CVodeGetReturnFlagName, flag);
    } else {
      ark_->GetCurrentStep(mem_, &h);
      ark_->GetCurrentTime(mem_, &t_cur);
      text = ReturnFlagText(ark_->GetReturnFlagName, flag);
    }
    if (flag == (is_cvode() ? CV_TOO_MUCH_WORK : ARK_TOO_MUCH_WORK)) {  // this call's share of the budget
      text = StepBudgetFailure(options_.max_steps, text);
    }
    Throw<SolverError>("OdeIntegrator::Evolve", owner_, " (", name_, "): ", text, " at t = ", t_cur, " s with step h = ", h, " s",
                       LargestErrorComponent(), failure_.empty() ? "" : " (" + failure_ + ")", sundials_messages_.Take());
  }
  *t = t_reached;
  y->resize(n_);
  N_Vector y_out = y_;
  if (!is_cvode() && !root && !in_erkstep()) {
    // ARKODE 6.4 returns the interpolant at a stop time; its own step state there (tcur
    // is snapped onto tstop) is the true discrete solution, also for the shortened step.
    // (ERKStep 6.4 has no GetCurrentState; there the interpolant at the step's end, τ = 0,
    // is that state: its weights are 1 on y_new and ±0 on the rest.)
    CheckArk(ARKStepGetCurrentState(mem_, &y_out), "GetCurrentState");
  }
  for (int i = 0; i < n_; ++i) (*y)(i) = NvData(y_out)[i];
  if (root) {
    if (is_cvode()) {
      Check(CVodeGetRootInfo(mem_, roots->data()), "CVodeGetRootInfo");
    } else {
      CheckArk(ark_->GetRootInfo(mem_, roots->data()), "GetRootInfo");
      if (steps_to_roots()) StepToRoot(*roots, t, y);
    }
  }
  return root;
}

void OdeIntegrator::StepToRoot(const std::vector<int>& fired, double* t, VectorXd* y) {
  const auto first = std::find_if(fired.begin(), fired.end(), [](int flag) { return flag != 0; });
  if (first == fired.end()) return;
  const int k = static_cast<int>(first - fired.begin());
  // The step that crossed the root, [t_start, t_end], and its two states: the Hermite
  // interpolant's ends, which are the step's own states (ycur is the root finding's scratch
  // after a root return, arkode_root.c).
  double t_end = 0.0, h = 0.0;
  CheckArk(ark_->GetCurrentTime(mem_, &t_end), "GetCurrentTime");
  CheckArk(ark_->GetLastStep(mem_, &h), "GetLastStep");
  const double t_start = t_end - h;
  N_Vector y_start = N_VClone(y_);
  N_Vector y_hi = N_VClone(y_);
  CheckArk(ark_->GetDky(mem_, t_start, 0, y_start), "GetDky");
  CheckArk(ark_->GetDky(mem_, t_end, 0, y_hi), "GetDky");
  std::vector<double> g(num_roots_);
  const auto g_at = [&](double tt, N_Vector yy) {
    problem_->Roots(tt, NvData(yy), g.data());
    ++accumulated_.root_evaluations;
    return g[k];
  };
  // One step of the method from (t_start, y_start) to about tt; returns the time reached,
  // its state in y_.
  const auto step_to = [&](double tt) {
    CheckArk(ark_->Reset(mem_, t_start, y_start), "Reset");
    CheckArk(ark_->SetFixedStep(mem_, tt - t_start), "SetFixedStep");
    double reached = t_start;
    const int flag = ark_->Evolve(mem_, tt, y_, &reached, ARK_ONE_STEP);
    if (flag < 0) {
      Throw<SolverError>("OdeIntegrator::StepToRoot", owner_, " (", name_, "): ",
                         ReturnFlagText(ark_->GetReturnFlagName, flag), " in the step from t = ",
                         t_start, " s to the root near t = ", tt, " s", failure_.empty() ? "" : " (" + failure_ + ")",
                         sundials_messages_.Take());
    }
    return reached;
  };
  double lo = t_start, g_lo = g_at(t_start, y_start);
  double hi = t_end, g_hi = g_at(t_end, y_hi);
  const auto crossed = [&](double gc) { return gc == 0.0 || (gc > 0.0) != (g_lo > 0.0); };
  if (g_lo != 0.0 && crossed(g_hi)) {
    // The root functions stay quiet in these trial steps; ARKODE's stop time is t_end.
    CheckArk(ark_->RootInit(mem_, 0, nullptr), "RootInit");
    CheckArk(ark_->SetStopTime(mem_, t_end), "SetStopTime");
    // Illinois regula falsi on [lo, hi], the first trial ARKODE's root; hi keeps the side
    // past the root, as ARKODE's own root return does.
    const double t_tol = 100.0 * std::numeric_limits<double>::epsilon() * (std::abs(t_end) + std::abs(h));
    double trial = std::clamp(*t, lo, hi);
    int last_side = 0;
    for (int iteration = 0; iteration < 50 && hi - lo > t_tol && g_hi != 0.0; ++iteration) {
      if (!(trial > lo && trial < hi)) trial = 0.5 * (lo + hi);
      const double reached = step_to(trial);
      const double g_trial = g_at(reached, y_);
      if (crossed(g_trial)) {
        hi = reached, g_hi = g_trial;
        N_VScale(1.0, y_, y_hi);
        if (last_side == 1) g_lo *= 0.5;
        last_side = 1;
      } else {
        lo = reached, g_lo = g_trial;
        if (last_side == -1) g_hi *= 0.5;
        last_side = -1;
      }
      trial = hi - g_hi * (hi - lo) / (g_hi - g_lo);
    }
    stepped_to_root_ = true;
    *t = hi;
    for (int i = 0; i < n_; ++i) (*y)(i) = NvData(y_hi)[i];
  }
  N_VDestroy(y_start);
  N_VDestroy(y_hi);
}

void OdeIntegrator::RefuseAfterSteppedRoot(const char* function) const {
  Throw<SolverError>(function, owner_, " (", name_, "): called after a root without Start: the root's trial "
                     "steps (StepToRoot) left the solver at a trial step; every root ends the phase");
}

void OdeIntegrator::Reset(double t, const VectorXd& y, bool new_step_budget) {
  if (stepped_to_root_) RefuseAfterSteppedRoot("OdeIntegrator::Reset");
  if (new_step_budget) start_steps_ = 0;
  // The step the controller proposed next (not the last one taken, which may have been cut
  // by a stop time): restarting from it keeps the step-size history across projections.
  double h = 0.0;
  if (is_cvode()) {
    CVodeGetCurrentStep(mem_, &h);
  } else {
    ark_->GetCurrentStep(mem_, &h);
  }
  h = std::abs(h);
  for (int i = 0; i < n_; ++i) NvData(y_)[i] = y(i);
  // Reinitialization may zero the counters: bank them and take a fresh baseline.
  accumulated_ += Minus(CurrentCounters(), baseline_);
  if (is_cvode()) {
    Check(CVodeReInit(mem_, t, y_), "CVodeReInit");
    linear_counters_stale_ = true;
    if (h > 0.0) Check(CVodeSetInitStep(mem_, h), "CVodeSetInitStep");
  } else {
    CheckArk(ark_->Reset(mem_, t, y_), "Reset");
    if (h > 0.0 && !fixed_step()) CheckArk(ark_->SetInitStep(mem_, h), "SetInitStep");
  }
  baseline_ = CurrentCounters();  // CVODE: zero (CVodeReInit); ARKODE's Reset keeps the counters
}

double OdeIntegrator::LastStep() const {
  double h = 0.0;
  if (mem_ == nullptr) return 0.0;
  if (is_cvode()) {
    CVodeGetLastStep(mem_, &h);
  } else {
    ark_->GetLastStep(mem_, &h);
  }
  return std::abs(h);
}

SolverStats OdeIntegrator::CurrentCounters() const {
  SolverStats s;
  if (mem_ == nullptr) return s;
  long v = 0;
  if (is_cvode()) {
    CVodeGetNumSteps(mem_, &v); s.steps = v;
    CVodeGetNumRhsEvals(mem_, &v); s.residual_evaluations = v;
    CVodeGetNumErrTestFails(mem_, &v); s.error_test_failures = v;
    CVodeGetNumNonlinSolvIters(mem_, &v); s.nonlinear_iterations = v;
    CVodeGetNumNonlinSolvConvFails(mem_, &v); s.convergence_failures = v;
    if (kind_ == IntegratorKind::kCvodeBdf) {
      CVodeGetNumLinSolvSetups(mem_, &v); s.linear_solver_setups = v;
      if (!linear_counters_stale_) {
        CVodeGetNumJacEvals(mem_, &v); s.jacobian_evaluations = v;
        CVodeGetNumLinRhsEvals(mem_, &v); s.residual_evaluations += v;  // difference quotients
      }
    }
    if (num_roots_ > 0) { CVodeGetNumGEvals(mem_, &v); s.root_evaluations = v; }
  } else {
    long nfe = 0, nfi = 0;
    ark_->GetNumSteps(mem_, &v); s.steps = v;
    if (in_erkstep()) {
      ERKStepGetNumRhsEvals(mem_, &nfe);
    } else {
      ARKStepGetNumRhsEvals(mem_, &nfe, &nfi);
    }
    s.residual_evaluations = nfe + nfi;
    ark_->GetNumErrTestFails(mem_, &v); s.error_test_failures = v;
    if (num_roots_ > 0) { ark_->GetNumGEvals(mem_, &v); s.root_evaluations = v; }
  }
  return s;
}

// Which state component a failure is about — the largest weighted local error
// estimate |e_i| w_i of the last attempted step (CVodeGetEstLocalErrors/ARKODE's GetEstLocalErrors
// with the error weights); empty when the solver has none (fixed steps: all zero).
std::string OdeIntegrator::LargestErrorComponent() const {
  N_Vector e = N_VClone(y_), w = N_VClone(y_);
  const bool ok = is_cvode()
                      ? CVodeGetEstLocalErrors(mem_, e) == CV_SUCCESS && CVodeGetErrWeights(mem_, w) == CV_SUCCESS
                      : ark_->GetEstLocalErrors(mem_, e) == ARK_SUCCESS && ark_->GetErrWeights(mem_, w) == ARK_SUCCESS;
  std::string out;
  if (ok) {
    const double* ed = N_VGetArrayPointer(e);
    const double* wd = N_VGetArrayPointer(w);
    int worst = 0;
    for (int i = 1; i < n_; ++i) {
      if (std::abs(ed[i] * wd[i]) > std::abs(ed[worst] * wd[worst])) worst = i;
    }
    const double weighted = std::abs(ed[worst] * wd[worst]);
    if (weighted > 0.0 && std::isfinite(weighted)) {
      out = StrCat("; largest weighted local error estimate: ", problem_ ? problem_->StateName(worst) : StrCat("y[", worst, "]"),
                   " (", weighted, " of the tolerance)");
    }
  }
  N_VDestroy(e);
  N_VDestroy(w);
  return out;
}

SolverStats OdeIntegrator::stats() const {
  SolverStats s = accumulated_;
  s += Minus(CurrentCounters(), baseline_);
  return s;
}

void OdeIntegrator::Free() {
  if (mem_ != nullptr) {
    accumulated_ += Minus(CurrentCounters(), baseline_);
    baseline_ = SolverStats();
    if (is_cvode()) {
      CVodeFree(&mem_);
    } else {
      ark_->Free(&mem_);
    }
    mem_ = nullptr;
  }
  linear_counters_stale_ = false;
  if (NLS_) { SUNNonlinSolFree(NLS_); NLS_ = nullptr; }
  if (LS_) { SUNLinSolFree(LS_); LS_ = nullptr; }
  if (A_) { SUNMatDestroy(A_); A_ = nullptr; }
  if (y_) { N_VDestroy(y_); y_ = nullptr; }
  if (hot_path_y_) { N_VDestroy(hot_path_y_); hot_path_y_ = nullptr; }
  if (hot_path_ydot_) { N_VDestroy(hot_path_ydot_); hot_path_ydot_ = nullptr; }
}

bool OdeIntegrator::EvaluateCallbacksForTesting(double t, const VectorXd& y, int n) {
  if (mem_ == nullptr || y.size() != n_) return false;
  for (int i = 0; i < n_; ++i) NvData(hot_path_y_)[i] = y(i);
  for (int i = 0; i < n; ++i) {
    if (RhsCallback(t, hot_path_y_, hot_path_ydot_, this) != 0) return false;
    if (num_roots_ > 0 && RootCallback(t, hot_path_y_, hot_path_g_.data(), this) != 0) return false;
  }
  return true;
}

}  // namespace kneedyn
