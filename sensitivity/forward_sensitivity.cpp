#include "sensitivity/forward_sensitivity.hpp"

#include <cvodes/cvodes.h>
#include <sunlinsol/sunlinsol_dense.h>
#include <sunmatrix/sunmatrix_dense.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <set>

#include "ensembles/sweep.hpp"
#include "formulations/simulator.hpp"
#include "formulations/internal/sundials_util.hpp"
#include "sensitivity/sensitivity_problem.hpp"
#include "solver/constrained_dynamics.hpp"
#include "solver/error.hpp"
#include "solver/units.hpp"

namespace kneedyn::sensitivity {

using ensembles::ParameterSpec;
using namespace detail;

namespace {

[[noreturn]] void UnknownName(const std::string& field, const std::string& value,
                              const std::vector<std::string>& valid, const std::string& what) {
  std::string nearest;
  int best = std::numeric_limits<int>::max();
  for (const std::string& v : valid) {
    const int d = EditDistance(value, v);
    if (d < best) best = d, nearest = v;
  }
  Throw<InputError>("kneedyn sensitivity", field, ": '", Echo(value), "' is not ", what, "; nearest valid name: '",
                    nearest, "' (all names: `kneedyn sensitivity --list SCENE`)");
}

// One CVODES instance per phase (sizes of the root set change between phases).
struct Cvodes {
  Problem* problem = nullptr;
  const Mode* mode = nullptr;
  double* p = nullptr;  // CVODES' parameter array (perturbed in place by its difference quotients)
  std::string failure;
  SundialsMessages messages;
  void* mem = nullptr;
  N_Vector y = nullptr;
  N_Vector* yS = nullptr;
  int ns = 0;
  SUNMatrix A = nullptr;
  SUNLinearSolver LS = nullptr;

  ~Cvodes() { Free(); }
  void Free() {
    if (mem) CVodeFree(&mem);
    if (LS) SUNLinSolFree(LS), LS = nullptr;
    if (A) SUNMatDestroy(A), A = nullptr;
    if (yS) N_VDestroyVectorArray(yS, ns), yS = nullptr;
    if (y) N_VDestroy(y), y = nullptr;
  }
  void Check(int flag, const char* call) {
    CheckSundials(flag, call, "RunSensitivity", CVodeGetReturnFlagName, &messages);
  }
  static int RhsFn(double t, N_Vector y, N_Vector ydot, void* user) {
    auto* self = static_cast<Cvodes*>(user);
    try {
      self->problem->Rhs(*self->mode, t, NvData(y), self->p, NvData(ydot));
      return 0;
    } catch (const std::exception& e) {
      self->failure = e.what();
      return -1;
    }
  }
  static int SensRhsFn(int, double t, N_Vector y, N_Vector, int j, N_Vector yS, N_Vector ySdot, void* user, N_Vector,
                       N_Vector) {
    auto* self = static_cast<Cvodes*>(user);
    try {
      self->problem->SensitivityRhs(*self->mode, t, NvData(y), self->p, j, NvData(yS), NvData(ySdot));
      return 0;
    } catch (const std::exception& e) {
      self->failure = e.what();
      return -1;
    }
  }
  static int RootFn(double t, N_Vector y, double* g, void* user) {
    auto* self = static_cast<Cvodes*>(user);
    try {
      self->problem->Roots(*self->mode, t, NvData(y), self->p, g);
      return 0;
    } catch (const std::exception& e) {
      self->failure = e.what();
      return -1;
    }
  }
};

SolverStats CountersOf(void* mem, bool roots) {
  SolverStats s;
  long v = 0;
  CVodeGetNumSteps(mem, &v), s.steps = v;
  CVodeGetNumRhsEvals(mem, &v), s.residual_evaluations = v;
  CVodeGetNumLinRhsEvals(mem, &v), s.residual_evaluations += v;
  CVodeGetNumJacEvals(mem, &v), s.jacobian_evaluations = v;
  CVodeGetNumLinSolvSetups(mem, &v), s.linear_solver_setups = v;
  CVodeGetNumNonlinSolvIters(mem, &v), s.nonlinear_iterations = v;
  CVodeGetNumErrTestFails(mem, &v), s.error_test_failures = v;
  CVodeGetNumNonlinSolvConvFails(mem, &v), s.convergence_failures = v;
  if (roots) CVodeGetNumGEvals(mem, &v), s.root_evaluations = v;
  s.restarts = 1;
  return s;
}

// The ODE y = (q, q̇) and its sensitivities on CVODES as a stepper of the hybrid simulator
// (formulations/simulator.hpp): Start computes s at the phase start (t0: central differences
// of the initialization; a restart: the jump s⁺ = s⁻ + (f⁻ − f⁺) dτ/dp), Advance integrates,
// locates the peaks' roots inside the phase and, at an event, dτ/dp and the event's outcomes.
class OdeSensitivity : public Formulation {
 public:
  OdeSensitivity(Problem& problem, const std::vector<double>& values, const SensitivityOptions& options,
                 const std::vector<Outcome>& outcomes, SensitivityResult* result)
      : problem_(problem),
        options_(options),
        outcomes_(outcomes),
        result_(result),
        p_(values),
        np_(static_cast<int>(values.size())),
        with_s_(options.derivatives && !values.empty()),
        scene_p_(problem.SceneCopyAt(values)),
        contact_form_(CreateFormulation(options.formulation, scene_p_, FormulationOptions())->contact_form()),
        y_(kN),
        s_(np_, VectorXd::Zero(kN)),
        pbar_(np_),
        unit_(np_, 0.0),
        zero_dt_(np_, 0.0),
        dtau_(np_, 0.0),
        w_(np_),
        peak_(outcomes.size()) {
    cv_.problem = &problem_;
    cv_.p = p_.data();
    for (int j = 0; j < np_; ++j) pbar_[j] = p_[j] != 0.0 ? std::abs(p_[j]) : 1.0;
  }

  void Run();

  ContactForm contact_form() const override { return contact_form_; }
  void Start(const MechanicalState& state, const std::vector<EventSpec>& events) override;
  AdvanceResult Advance(double t_out, MechanicalState* state) override;
  SolverStats stats() const override { return result_->stats; }

 private:
  const double* UnitVector(int j) {
    std::fill(unit_.begin(), unit_.end(), 0.0);
    unit_[j] = 1.0;
    return unit_.data();
  }
  // Total derivative of a value v at (t, y) with dt/dp_j, dy/dp_j given.
  std::vector<double> Total(const Mode& m, const Outcome& o, const std::vector<double>& dt, const std::vector<VectorXd>& dy) {
    std::vector<double> d(np_);
    for (int j = 0; j < np_; ++j) {
      d[j] = problem_.Directional([&](double tt, const double* yy, const double* pv) { return problem_.Value(m, o, tt, yy, pv); },
                                  t_, y_.data(), p_.data(), dt[j], dy[j].data(), UnitVector(j));
    }
    return d;
  }
  // A maximum candidate for every peak outcome at the current (t, y) in mode m.
  void Candidate(const Mode& m, const std::vector<double>& dt, const std::vector<VectorXd>& dy, bool only = false,
                 int which = -1) {
    for (int k : problem_.peaks()) {
      if (only && k != which) continue;
      const double v = problem_.Value(m, outcomes_[k], t_, y_.data(), p_.data());
      if (v > peak_[k].value) {
        peak_[k].value = v;
        peak_[k].derivative = with_s_ ? Total(m, outcomes_[k], dt, dy) : std::vector<double>(np_, kNaN);
      }
    }
  }
  // Adds the current CVODES instance's counters to the result.
  void Bank();

  Problem& problem_;
  SensitivityOptions options_;
  const std::vector<Outcome>& outcomes_;
  SensitivityResult* result_;
  std::vector<double> p_;  // CVODES' parameter array (perturbed in place by its difference quotients)
  int np_;
  bool with_s_;
  Scene scene_p_;  // the scene at p, for the simulator (problem_.SceneAt follows CVODES' perturbations)
  ContactForm contact_form_;
  Mode mode_;
  double t_ = 0.0;
  VectorXd y_;
  std::vector<VectorXd> s_;
  std::vector<double> pbar_, unit_, zero_dt_;
  // At the last event: dτ/dp, w = s⁻ + f⁻ dτ/dp, f⁻.
  std::vector<double> dtau_;
  std::vector<VectorXd> w_;
  double f_minus_[kN] = {};
  std::vector<Peak> peak_;
  bool first_phase_ = true;
  double last_h_ = 0.0;
  SundialsContext ctx_;  // outlives cv_ (destroyed after it)
  Cvodes cv_;
};

void OdeSensitivity::Bank() {
  if (!cv_.mem) return;
  result_->stats += CountersOf(cv_.mem, true);
  long v = 0;
  if (with_s_) {
    CVodeGetSensNumRhsEvals(cv_.mem, &v), result_->sensitivity_rhs_evaluations += v;
    CVodeGetSensNumErrTestFails(cv_.mem, &v), result_->sensitivity_error_test_failures += v;
  }
  CVodeGetLastStep(cv_.mem, &last_h_);
}

void OdeSensitivity::Start(const MechanicalState& state, const std::vector<EventSpec>& events) {
  Mode mode;
  mode.active = state.active;
  if (scene_p_.model.ligament_law == LigamentLaw::kPublished) mode.branch = state.ligament_branch;
  mode.events = events;
  t_ = state.t;
  y_ << state.q, state.qd;  // RestartProjection::kKeepState: y is continuous at an event
  if (first_phase_) {
    // s0 = ∂y0/∂p by central differences of the initialization (zero when, as for the
    // chapter scene, p does not enter it).
    if (with_s_) {
      ConsistentInitOptions init;
      init.form = contact_form_;
      std::vector<int> all;
      for (int i = 0; i < static_cast<int>(scene_p_.model.contacts.size()); ++i) all.push_back(i);
      auto initial = [&](const std::vector<double>& pv) {
        InitReport report;
        const Scene sc = problem_.SceneCopyAt(pv);
        return ConsistentInitialize(sc.model, sc.initial, all, init, &report);
      };
      for (int j = 0; j < np_; ++j) {
        const double h = kInitialStateStep * pbar_[j];
        std::vector<double> pp = p_, pm = p_;
        pp[j] += h, pm[j] -= h;
        const MechanicalState a = initial(pp), b = initial(pm);
        s_[j].head<6>() = (a.q - b.q) / (2 * h);
        s_[j].tail<6>() = (a.qd - b.qd) / (2 * h);
      }
    }
    mode_ = mode;
    Candidate(mode_, zero_dt_, s_);
  } else {
    // s⁺ = s⁻ + (f⁻ − f⁺) dτ/dp where the vector field changes.
    double fp[kN];
    problem_.Rhs(mode, t_, y_.data(), p_.data(), fp);
    if (with_s_) {
      for (int j = 0; j < np_; ++j) {
        for (int i = 0; i < kN; ++i) s_[j](i) += (f_minus_[i] - fp[i]) * dtau_[j];
      }
    }
    mode_ = mode;
    Candidate(mode_, dtau_, w_);  // right limits (e.g. the far side of a kink's jump)
  }
  first_phase_ = false;

  // A fresh CVODES instance in the phase's mode (the root set changes between phases).
  Bank();
  cv_.Free();
  cv_.mode = &mode_;
  cv_.y = NewSerialVector(kN, ctx_);
  for (int i = 0; i < kN; ++i) NvData(cv_.y)[i] = y_(i);
  cv_.mem = CVodeCreate(CV_BDF, ctx_);
  if (!cv_.mem) Throw<SolverError>("RunSensitivity", "CVodeCreate failed");
  cv_.Check(CVodeSetErrHandlerFn(cv_.mem, &SundialsMessages::Handler, &cv_.messages), "CVodeSetErrHandlerFn");
  cv_.Check(CVodeInit(cv_.mem, &Cvodes::RhsFn, t_, cv_.y), "CVodeInit");
  cv_.Check(CVodeSetUserData(cv_.mem, &cv_), "CVodeSetUserData");
  cv_.Check(CVodeSStolerances(cv_.mem, options_.rtol, options_.atol), "CVodeSStolerances");
  cv_.Check(CVodeSetMaxNumSteps(cv_.mem, options_.max_steps), "CVodeSetMaxNumSteps");
  cv_.Check(CVodeSetStopTime(cv_.mem, scene_p_.end.time), "CVodeSetStopTime");
  if (last_h_ > 0.0) cv_.Check(CVodeSetInitStep(cv_.mem, 0.25 * last_h_), "CVodeSetInitStep");
  cv_.A = SUNDenseMatrix(kN, kN, ctx_);
  cv_.LS = SUNLinSol_Dense(cv_.y, cv_.A, ctx_);
  cv_.Check(CVodeSetLinearSolver(cv_.mem, cv_.LS, cv_.A), "CVodeSetLinearSolver");
  const int n_events = static_cast<int>(mode_.events.size());
  const int n_roots = n_events + static_cast<int>(problem_.peaks().size());
  std::vector<int> dirs = RootDirections(mode_.events);
  dirs.resize(n_roots, -1);  // dv/dt decreasing through 0: a maximum
  // A phase with nothing to locate (no contact, no lift-off or end angle, no peak outcome)
  // has no root functions: CVODES refuses the direction and warning settings then.
  if (n_roots > 0) {
    cv_.Check(CVodeRootInit(cv_.mem, n_roots, &Cvodes::RootFn), "CVodeRootInit");
    cv_.Check(CVodeSetRootDirection(cv_.mem, dirs.data()), "CVodeSetRootDirection");
    cv_.Check(CVodeSetNoInactiveRootWarn(cv_.mem), "CVodeSetNoInactiveRootWarn");
  }
  if (with_s_) {
    cv_.ns = np_;
    cv_.yS = N_VCloneVectorArray(np_, cv_.y);
    for (int j = 0; j < np_; ++j) {
      for (int i = 0; i < kN; ++i) NvData(cv_.yS[j])[i] = s_[j](i);
    }
    cv_.Check(CVodeSensInit1(cv_.mem, np_, CV_STAGGERED1, &Cvodes::SensRhsFn, cv_.yS), "CVodeSensInit1");
    cv_.Check(CVodeSetSensParams(cv_.mem, p_.data(), pbar_.data(), nullptr), "CVodeSetSensParams");
    // Tolerances of p̄_j s_j (SI units of y per 100 % change of p_j): rtol and
    // kSensitivityAtol. CVODES' default atol/p̄_j sits below the round-off of the
    // difference-quotient fS (~1e-16 |f|/ε) at tight atol and stalls the step at ~1e-8 s.
    std::vector<double> atol_s(np_);
    for (int j = 0; j < np_; ++j) atol_s[j] = std::max(options_.atol, kSensitivityAtol) / pbar_[j];
    cv_.Check(CVodeSensSStolerances(cv_.mem, options_.rtol, atol_s.data()), "CVodeSensSStolerances");
    // Sensitivities in the error test: without it their error follows the step sequence
    // (1 % on N90 measured), not the tolerance.
    cv_.Check(CVodeSetSensErrCon(cv_.mem, SUNTRUE), "CVodeSetSensErrCon");
  }
}

AdvanceResult OdeSensitivity::Advance(double t_out, MechanicalState* state) {
  const int n_events = static_cast<int>(mode_.events.size());
  const int n_roots = n_events + static_cast<int>(problem_.peaks().size());
  auto write = [&]() {
    state->t = t_;
    state->q = y_.head<6>();
    state->qd = y_.tail<6>();
  };
  for (;;) {
    double t_reached = t_;
    cv_.failure.clear();
    // --max-steps is per phase (a fresh CVODES instance each, its step count from 0).
    long phase_steps = 0;
    CVodeGetNumSteps(cv_.mem, &phase_steps);
    double t_current = t_;  // s: the end of CVODES' last step
    CVodeGetCurrentTime(cv_.mem, &t_current);
    const long limit = PerCallStepLimit(options_.max_steps, phase_steps, t_out, t_current);
    int flag = CV_TOO_MUCH_WORK;
    if (limit > 0) {
      cv_.Check(CVodeSetMaxNumSteps(cv_.mem, limit), "CVodeSetMaxNumSteps");
      flag = CVode(cv_.mem, t_out, cv_.y, &t_reached, CV_NORMAL);
    }
    if (flag < 0) {
      double h = 0.0;
      CVodeGetCurrentStep(cv_.mem, &h);
      std::string text = ReturnFlagText(CVodeGetReturnFlagName, flag);
      if (flag == CV_TOO_MUCH_WORK) text = StepBudgetFailure(options_.max_steps, text);
      Throw<SolverError>("RunSensitivity", "CVODES ", text, " at t = ", t_reached,
                         " s with step h = ", h, " s",
                         cv_.failure.empty() ? "" : " (" + cv_.failure + ")", cv_.messages.Take());
    }
    t_ = t_reached;
    for (int i = 0; i < kN; ++i) y_(i) = NvData(cv_.y)[i];
    if (with_s_) {
      double ts = 0.0;
      cv_.Check(CVodeGetSens(cv_.mem, &ts, cv_.yS), "CVodeGetSens");
      for (int j = 0; j < np_; ++j) {
        for (int i = 0; i < kN; ++i) s_[j](i) = NvData(cv_.yS[j])[i];
      }
    }
    if (flag != CV_ROOT_RETURN) {  // an output time, or the end time (CV_TSTOP_RETURN or CV_SUCCESS at t_end)
      write();
      if (!(t_ < scene_p_.end.time)) {
        result_->end_reason = "end_time";
        Candidate(mode_, zero_dt_, s_);
      }
      return {};
    }
    std::vector<int> fired(n_roots, 0);
    cv_.Check(CVodeGetRootInfo(cv_.mem, fired.data()), "CVodeGetRootInfo");
    // Interior maxima (dv/dt = 0): envelope theorem, dV/dp = ∂v/∂y s + ∂v/∂p.
    for (size_t k = 0; k < problem_.peaks().size(); ++k) {
      if (fired[n_events + k]) Candidate(mode_, zero_dt_, s_, true, problem_.peaks()[k]);
    }
    int first = -1;
    for (int k = 0; k < n_events; ++k) {
      if (fired[k] && first < 0) first = k;
    }
    if (first < 0) continue;  // only peaks: CVODES continues the same phase

    // An event: τ(p) from g(τ, y(τ; p), p) = 0.
    problem_.Rhs(mode_, t_, y_.data(), p_.data(), f_minus_);
    if (with_s_) {
      auto g = [&](double tt, const double* yy, const double* pv) { return problem_.Event(mode_, first, tt, yy, pv); };
      const std::vector<double> zero_p(np_, 0.0);
      const double gdot = problem_.Directional(g, t_, y_.data(), p_.data(), 1.0, f_minus_, zero_p.data());
      if (!(std::abs(gdot) > 0.0)) {
        Throw<SolverError>("RunSensitivity", "event ", mode_.events[first].name, " at t = ", t_,
                           " s is tangential (dg/dt = ", gdot, "): its time is not differentiable in p");
      }
      for (int j = 0; j < np_; ++j) {
        dtau_[j] = -problem_.Directional(g, t_, y_.data(), p_.data(), 0.0, s_[j].data(), UnitVector(j)) / gdot;
        w_[j] = s_[j] + Eigen::Map<const VectorXd>(f_minus_, kN) * dtau_[j];
      }
    } else {
      for (int j = 0; j < np_; ++j) w_[j] = VectorXd::Zero(kN), dtau_[j] = kNaN;
    }
    std::vector<int> next_active = mode_.active;  // the simulator switches the contacts
    std::vector<double> dalpha(np_, kNaN);
    for (int j = 0; j < np_ && with_s_; ++j) dalpha[j] = w_[j](kAlpha);
    const bool done = RecordEvent(mode_, fired, t_, y_(kAlpha), dtau_, dalpha, with_s_, outcomes_, &next_active, result_);
    // 90° values, on the mode before the end event (left limits); a scene ending at another
    // flexion has none.
    for (size_t k = 0; k < outcomes_.size() && done && result_->end_reason == Flexion90EventName(); ++k) {
      const Outcome& o = outcomes_[k];
      if (o.kind == OutcomeKind::kLigamentAt90 || o.kind == OutcomeKind::kContactAt90) {
        result_->values[k] = problem_.Value(mode_, o, t_, y_.data(), p_.data());
        result_->derivatives[k] = with_s_ ? Total(mode_, o, dtau_, w_) : std::vector<double>(np_, kNaN);
      }
    }
    Candidate(mode_, dtau_, w_);
    write();
    AdvanceResult result;
    result.status = AdvanceStatus::kEvent;
    for (int k = 0; k < n_events; ++k) {
      if (fired[k]) result.events.push_back(k);
    }
    return result;
  }
}

void OdeSensitivity::Run() {
  SimulatorSettings sim = TrajectorySettings(
      scene_p_, options_, with_s_, np_, [this](int j) -> Vector6d { return s_[j].head<6>(); }, result_);
  sim.init.form = contact_form_;
  sim.restart = RestartProjection::kKeepState;  // the jump condition needs y continuous
  RunResult record;
  Simulator simulator(scene_p_, this, sim, &record);
  simulator.Initialize();
  simulator.Run();
  Bank();
  for (int k : problem_.peaks()) {
    result_->values[k] = peak_[k].value;
    result_->derivatives[k] = peak_[k].derivative;
  }
}

}  // namespace


std::vector<std::string> SensitivityFormulations() {
  std::vector<std::string> names;
  for (const FormulationInfo& info : RegisteredFormulations()) {
    if (info.sensitivity != SensitivityForm::kNone) names.push_back(info.name);
  }
  return names;
}

bool IsOdeSensitivity(const std::string& formulation) {
  for (const FormulationInfo& info : RegisteredFormulations()) {
    if (info.name == formulation) return info.sensitivity == SensitivityForm::kOde;
  }
  return false;
}

const char* SensitivityIntegrator(const std::string& formulation) {
  return IsOdeSensitivity(formulation) ? "cvodes-bdf" : "idas-bdf";
}

const char* SensitivityMethod(const std::string& formulation) {
  return IsOdeSensitivity(formulation) ? "staggered, difference-quotient right-hand side (centred)"
                              : "staggered, own residual F_y s + F_ydot s' + F_p: F_y, F_ydot exact (DaeSystem::Jacobian), "
                                "F_p by central differences over perturbed models (relative step 1e-5)";
}

bool SensitivityOptions::IsValid(std::string* error, const OptionText& typed) const {
  const auto shown = [&typed](const char* flag, auto value) {
    const auto it = typed.find(flag);
    return it != typed.end() ? StrCat("'", Echo(it->second), "'") : StrCat(value);
  };
  const std::vector<std::string> forms = SensitivityFormulations();
  if (std::find(forms.begin(), forms.end(), formulation) == forms.end()) {
    std::string ode, dae;
    for (const std::string& f : forms) {
      std::string& list = IsOdeSensitivity(f) ? ode : dae;
      list += (list.empty() ? "" : ", ") + f;
    }
    *error = StrCat("--formulation = '", Echo(formulation), "': sensitivities are implemented for ", ode,
                    " (CVODES on y = (q, q')) and ", dae, " (IDAS on the DAE of formulations/internal/dae_system.hpp)");
    return false;
  }
  if (!(output_interval >= 0.0 && std::isfinite(output_interval))) {
    *error = StrCat("--output-interval = ", shown("--output-interval", output_interval), ": must be >= 0 (0: the scene's)");
    return false;
  }
  // The tolerances and the step budget under the rules `kneedyn run` applies to the same
  // formulation (ValidateOptions): one rule per option. Before, sensitivity took --rtol up
  // to 1 (run: 0.5), any --atol (run: 1e-2) and any --max-steps (run: 100000000).
  FormulationOptions shared;
  shared.rtol = rtol;
  shared.atol = atol;
  shared.max_steps = max_steps;
  return ValidateOptions(FindFormulation(formulation), shared, error, typed);
}

std::vector<std::string> ParameterNames(const Scene& scene) {
  std::vector<std::string> names = {"mass"};
  if (scene.model.pulse.shape != PulseShape::kNone) names.insert(names.begin(), {"pulse.amplitude", "pulse.duration"});
  for (const Ligament& l : scene.model.ligaments) {
    const std::string e = ColumnSafeName(l.name) + ".";
    names.push_back(e + "k_linear");
    if (scene.model.ligament_law == LigamentLaw::kPublished) names.push_back(e + "k_parabolic");
    names.push_back(e + "slack_length");
    names.push_back(e + "extension_ratio");
    for (const char* a : {"femoral_x", "femoral_y", "femoral_z", "tibial_x", "tibial_y", "tibial_z"}) names.push_back(e + a);
  }
  if (scene.model.patella) {  // the patella's (ensembles/README.md)
    names.push_back("quadriceps.magnitude");
    if (scene.model.patella->quadriceps.shape != QuadricepsShape::kConstant) {
      names.push_back("quadriceps.baseline");
      names.push_back("quadriceps.duration");
    }
    names.push_back("patella.tendon_length");
    for (const char* f : {"medial", "lateral"}) {
      const std::string t = StrCat("patella.trochlea_", f, ".");
      for (const char* a : {"radius", "centre_x", "centre_y", "centre_z"}) names.push_back(t + a);
      names.push_back(StrCat("patella.facet_", f, ".offset"));
    }
  }
  return names;
}

std::vector<ParameterSpec> ResolveParameters(const Scene& scene, const std::vector<std::string>& names,
                                             const std::string& field) {
  const std::vector<std::string> valid = ParameterNames(scene);
  std::vector<ParameterSpec> out;
  std::set<std::string> seen;
  if (names.empty()) Throw<InputError>("kneedyn sensitivity", field, ": give at least one parameter");
  for (const std::string& name : names) {
    // Names as the sweep writes them: spaces, '-' and '/' as '_' (ColumnSafeName), or as given.
    const std::string key = ColumnSafeName(name);
    // A pulse parameter of a scene without a pulse: ResolveParameterName says why it is refused.
    const bool pulse_parameter = key == "pulse.amplitude" || key == "pulse.duration";
    if (!pulse_parameter && std::find(valid.begin(), valid.end(), key) == valid.end()) {
      // A sweep parameter (e.g. inertia_x) that has no derivative here is not a typo.
      bool sweep_parameter = true;
      try {
        (void)ensembles::ResolveParameterName(scene, name, scene.path, field);
      } catch (const InputError&) {
        sweep_parameter = false;
      }
      if (sweep_parameter) {
        Throw<InputError>("kneedyn sensitivity", field, ": '", Echo(name),
                          "' is a sweep parameter whose sensitivity is not implemented (all names that have "
                          "one: `kneedyn sensitivity --list SCENE`)");
      }
      UnknownName(field, name, valid, "a parameter of this scene");
    }
    ParameterSpec p = ensembles::ResolveParameterName(scene, name, scene.path, field);
    if (!seen.insert(p.column).second) Throw<InputError>("kneedyn sensitivity", field, ": '", Echo(name), "' is listed twice");
    out.push_back(p);
  }
  if (const std::string why = ensembles::ParametersThatCannotVaryTogether(out); !why.empty()) {
    Throw<InputError>("kneedyn sensitivity", field, ": ", why, " (ask for them in two runs)");
  }
  return out;
}

std::vector<std::string> OutcomeNames(const Scene& scene) {
  std::vector<std::string> names = ColumnsOf(scene, AllGroups());
  for (const ContactPair& c : scene.model.contacts) {
    names.push_back(StrCat("liftoff_time_", CompartmentName(c.compartment), "_s"));
    names.push_back(StrCat("liftoff_flexion_", CompartmentName(c.compartment), "_deg"));
  }
  return names;
}

std::vector<std::string> ResolveOutcomes(const Scene& scene, const std::vector<std::string>& names,
                                         const std::string& field) {
  const std::vector<std::string> columns = OutcomeNames(scene);
  std::vector<std::string> valid = columns;
  valid.insert(valid.end(), AllGroups().begin(), AllGroups().end());
  std::vector<std::string> out;
  if (names.empty()) Throw<InputError>("kneedyn sensitivity", field, ": give at least one outcome");
  for (const std::string& name : names) {
    std::vector<std::string> add;
    if (std::find(AllGroups().begin(), AllGroups().end(), name) != AllGroups().end()) {
      add = ColumnsOf(scene, {name});
    } else if (std::find(columns.begin(), columns.end(), name) != columns.end()) {
      add = {name};
    } else {
      UnknownName(field, name, valid, "an outcome");
    }
    for (const std::string& c : add) {
      if (std::find(out.begin(), out.end(), c) != out.end()) {
        Throw<InputError>("kneedyn sensitivity", field, ": '", Echo(name), "' repeats outcome '", c, "'");
      }
      out.push_back(c);
    }
  }
  return out;
}

SensitivityResult RunSensitivity(const Scene& scene, const std::vector<ParameterSpec>& parameters,
                                 const std::vector<double>& values, const std::vector<std::string>& outcome_columns,
                                 const SensitivityOptions& options) {
  const auto wall_start = std::chrono::steady_clock::now();
  std::string why;
  if (!options.IsValid(&why)) Throw<InputError>("RunSensitivity", why);
  if (values.size() != parameters.size()) {
    Throw<InputError>("RunSensitivity", values.size(), " values for ", parameters.size(), " parameters");
  }
  if (scene.model.contacts.size() > 2) {
    Throw<InputError>("RunSensitivity", scene.model.contacts.size(), " contacts; at most 2 supported");
  }
  const int np = static_cast<int>(parameters.size());
  std::vector<Outcome> outcomes;
  for (const std::string& c : outcome_columns) outcomes.push_back(ParseOutcome(scene.model, c));
  Problem problem(scene, parameters, outcomes);

  SensitivityResult result;
  for (const ParameterSpec& p : parameters) result.parameters.push_back(p.name), result.parameter_columns.push_back(p.column);
  result.parameter_values = values;
  result.outcomes = outcome_columns;
  result.values.assign(outcomes.size(), kNaN);
  result.derivatives.assign(outcomes.size(), std::vector<double>(np, kNaN));
  auto finish = [&]() {
    if (!options.derivatives) {
      for (auto& row : result.derivatives) std::fill(row.begin(), row.end(), kNaN);
    }
    result.wall_time_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall_start).count();
    return result;
  };
  if (FindFormulation(options.formulation).sensitivity != SensitivityForm::kOde) {  // the DAE forms, on IDAS
    RunDaeSensitivity(problem, values, options, &result);
    return finish();
  }
  OdeSensitivity stepper(problem, values, options, outcomes, &result);
  stepper.Run();
  return finish();
}

}  // namespace kneedyn::sensitivity
