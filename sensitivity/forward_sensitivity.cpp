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
#include "formulations/internal/sundials_kernels.hpp"
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

}  // namespace

int EditDistance(const std::string& a, const std::string& b) {
  std::vector<int> row(b.size() + 1);
  for (size_t j = 0; j <= b.size(); ++j) row[j] = static_cast<int>(j);
  for (size_t i = 1; i <= a.size(); ++i) {
    int diag = row[0];
    row[0] = static_cast<int>(i);
    for (size_t j = 1; j <= b.size(); ++j) {
      const int up = row[j];
      row[j] = std::min({row[j] + 1, row[j - 1] + 1, diag + (a[i - 1] == b[j - 1] ? 0 : 1)});
      diag = up;
    }
  }
  return row[b.size()];
}

const char* SensitivityIntegrator(const std::string& formulation) {
  return formulation == "ede" ? "cvodes-bdf" : "idas-bdf";
}

const char* SensitivityMethod(const std::string& formulation) {
  return formulation == "ede" ? "staggered, difference-quotient right-hand side (centred)"
                              : "staggered, own residual F_y s + F_ydot s' + F_p: F_y, F_ydot exact (DaeSystem::Jacobian), "
                                "F_p by central differences over perturbed models (relative step 1e-5)";
}

bool SensitivityOptions::IsValid(std::string* error) const {
  if (std::find(std::begin(kSensitivityFormulations), std::end(kSensitivityFormulations), formulation) ==
      std::end(kSensitivityFormulations)) {
    *error = StrCat("--formulation = '", Echo(formulation),
                    "': sensitivities are implemented for ede (CVODES on y = (q, q')) and dae, dae-reduced, dae-ggl, "
                    "dae-ggl-reduced (IDAS on the DAE of formulations/internal/dae_system.hpp)");
    return false;
  }
  if (!(rtol > 0.0 && rtol < 1.0)) {
    *error = StrCat("--rtol = ", rtol, ": must be in (0, 1)");
    return false;
  }
  if (!(output_interval >= 0.0 && std::isfinite(output_interval))) {
    *error = StrCat("--output-interval = ", output_interval, ": must be >= 0 (0: the scene's)");
    return false;
  }
  if (!(atol > 0.0 && std::isfinite(atol))) {
    *error = StrCat("--atol = ", atol, ": must be > 0");
    return false;
  }
  if (max_steps < 1) {
    *error = StrCat("--max-steps = ", max_steps, ": must be >= 1");
    return false;
  }
  return true;
}

std::vector<std::string> ParameterNames(const Scene& scene) {
  std::vector<std::string> names = {"pulse.amplitude", "pulse.duration", "mass"};
  for (const Ligament& l : scene.model.ligaments) {
    const std::string e = Sanitize(l.name) + ".";
    names.push_back(e + "k_linear");
    if (scene.model.ligament_law == LigamentLaw::kPublished) names.push_back(e + "k_parabolic");
    names.push_back(e + "slack_length");
    names.push_back(e + "extension_ratio");
    for (const char* a : {"femoral_x", "femoral_y", "femoral_z", "tibial_x", "tibial_y", "tibial_z"}) names.push_back(e + a);
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
    // Names as the sweep writes them, with spaces or with '_' for spaces.
    const std::string key = Sanitize(name);
    if (std::find(valid.begin(), valid.end(), key) == valid.end()) UnknownName(field, name, valid, "a parameter of this scene");
    ParameterSpec p = ensembles::ResolveParameterName(scene, name, scene.path, field);
    if (!seen.insert(p.column).second) Throw<InputError>("kneedyn sensitivity", field, ": '", Echo(name), "' is listed twice");
    out.push_back(p);
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
  const bool with_s = options.derivatives && np > 0;
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
  if (options.formulation != "ede") {  // the DAE forms, on IDAS (dae_sensitivity.cpp)
    RunDaeSensitivity(problem, values, options, &result);
    return finish();
  }

  // Consistent initial state at p, and s0 = ∂y0/∂p by central differences of the
  // initialization (zero when, as for the chapter scene, p does not enter it).
  std::vector<double> p = values;
  ConsistentInitOptions init;
  init.form = ContactForm::kClosedForm;
  std::vector<int> all;
  for (int i = 0; i < static_cast<int>(scene.model.contacts.size()); ++i) all.push_back(i);
  auto initial = [&](const std::vector<double>& pv) {
    InitReport report;
    const Scene s = problem.SceneCopyAt(pv);
    return ConsistentInitialize(s.model, s.initial, all, init, &report);
  };
  MechanicalState state = initial(p);
  std::vector<VectorXd> s(np, VectorXd::Zero(kN));
  if (with_s) {
    for (int j = 0; j < np; ++j) {
      const double h = kInitialStateStep * (p[j] != 0.0 ? std::abs(p[j]) : 1.0);
      std::vector<double> pp = p, pm = p;
      pp[j] += h, pm[j] -= h;
      const MechanicalState a = initial(pp), b = initial(pm);
      s[j].head<6>() = (a.q - b.q) / (2 * h);
      s[j].tail<6>() = (a.qd - b.qd) / (2 * h);
    }
  }
  const Scene& scene_p = problem.SceneAt(p.data());
  const Model& model_p = scene_p.model;
  Mode mode;
  mode.active = state.active;
  if (model_p.ligament_law == LigamentLaw::kPublished) mode.branch = LigamentBranchesAt(model_p, state.q, state.qd);
  mode.events = EventsForPhase(scene_p.model, scene_p.end, state);
  double t = state.t;
  VectorXd y(kN);
  y << state.q, state.qd;
  const double t_end = scene.end.time;
  const double dt_out = options.output_interval > 0.0 ? options.output_interval : scene.output_interval;
  if (!IsValidOutputInterval(dt_out, t_end, &why)) {
    Throw<InputError>("RunSensitivity", options.output_interval > 0.0 ? "--output-interval: " : "scene output.interval_s: ", why);
  }
  long next_out = 1;
  auto sample = [&]() {
    TrajectorySample row;
    row.t = t;
    row.q = y.head<6>();
    if (with_s) {
      for (int j = 0; j < np; ++j) row.dq.push_back(s[j].head<6>());
    }
    result.trajectory.push_back(row);
  };
  sample();

  std::vector<double> unit(np, 0.0);
  auto unit_vector = [&](int j) {
    std::fill(unit.begin(), unit.end(), 0.0);
    unit[j] = 1.0;
    return unit.data();
  };
  // Total derivative of a value v at (t, y) with dt/dp_j, dy/dp_j given.
  auto total = [&](const Mode& m, const Outcome& o, const std::vector<double>& dt, const std::vector<VectorXd>& dy) {
    std::vector<double> d(np);
    for (int j = 0; j < np; ++j) {
      d[j] = problem.Directional([&](double tt, const double* yy, const double* pv) { return problem.Value(m, o, tt, yy, pv); },
                                 t, y.data(), p.data(), dt[j], dy[j].data(), unit_vector(j));
    }
    return d;
  };
  std::vector<Peak> peak(outcomes.size());
  // A maximum candidate for every peak outcome at the current (t, y) in mode m.
  auto candidate = [&](const Mode& m, const std::vector<double>& dt, const std::vector<VectorXd>& dy, bool only = false,
                       int which = -1) {
    for (int k : problem.peaks()) {
      if (only && k != which) continue;
      const double v = problem.Value(m, outcomes[k], t, y.data(), p.data());
      if (v > peak[k].value) {
        peak[k].value = v;
        peak[k].derivative = with_s ? total(m, outcomes[k], dt, dy) : std::vector<double>(np, kNaN);
      }
    }
  };
  const std::vector<double> zero_dt(np, 0.0);
  candidate(mode, zero_dt, s);

  SundialsContext ctx;  // outlives cv (destroyed after it)
  Cvodes cv;
  cv.problem = &problem;
  cv.p = p.data();
  std::vector<double> pbar(np);
  for (int j = 0; j < np; ++j) pbar[j] = p[j] != 0.0 ? std::abs(p[j]) : 1.0;
  double last_h = 0.0;
  bool done = false;
  auto bank = [&]() {
    if (!cv.mem) return;
    result.stats += CountersOf(cv.mem, true);
    long v = 0;
    if (with_s) {
      CVodeGetSensNumRhsEvals(cv.mem, &v), result.sensitivity_rhs_evaluations += v;
      CVodeGetSensNumErrTestFails(cv.mem, &v), result.sensitivity_error_test_failures += v;
    }
    CVodeGetLastStep(cv.mem, &last_h);
  };
  while (!done) {
    // A phase: fresh CVODES instance in the current mode.
    bank();
    cv.Free();
    cv.mode = &mode;
    cv.y = NewSerialVector(kN, ctx);
    for (int i = 0; i < kN; ++i) NvData(cv.y)[i] = y(i);
    cv.mem = CVodeCreate(CV_BDF, ctx);
    if (!cv.mem) Throw<SolverError>("RunSensitivity", "CVodeCreate failed");
    cv.Check(CVodeSetErrHandlerFn(cv.mem, &SundialsMessages::Handler, &cv.messages), "CVodeSetErrHandlerFn");
    cv.Check(CVodeInit(cv.mem, &Cvodes::RhsFn, t, cv.y), "CVodeInit");
    cv.Check(CVodeSetUserData(cv.mem, &cv), "CVodeSetUserData");
    cv.Check(CVodeSStolerances(cv.mem, options.rtol, options.atol), "CVodeSStolerances");
    cv.Check(CVodeSetMaxNumSteps(cv.mem, options.max_steps), "CVodeSetMaxNumSteps");
    cv.Check(CVodeSetStopTime(cv.mem, t_end), "CVodeSetStopTime");
    if (last_h > 0.0) cv.Check(CVodeSetInitStep(cv.mem, 0.25 * last_h), "CVodeSetInitStep");
    cv.A = SUNDenseMatrix(kN, kN, ctx);
    cv.LS = NewDenseLinearSolver(cv.y, cv.A, ctx);
    cv.Check(CVodeSetLinearSolver(cv.mem, cv.LS, cv.A), "CVodeSetLinearSolver");
    const int n_events = static_cast<int>(mode.events.size());
    const int n_roots = n_events + static_cast<int>(problem.peaks().size());
    std::vector<int> dirs = RootDirections(mode.events);
    dirs.resize(n_roots, -1);  // dv/dt decreasing through 0: a maximum
    cv.Check(CVodeRootInit(cv.mem, n_roots, &Cvodes::RootFn), "CVodeRootInit");
    cv.Check(CVodeSetRootDirection(cv.mem, dirs.data()), "CVodeSetRootDirection");
    cv.Check(CVodeSetNoInactiveRootWarn(cv.mem), "CVodeSetNoInactiveRootWarn");
    if (with_s) {
      cv.ns = np;
      cv.yS = N_VCloneVectorArray(np, cv.y);
      for (int j = 0; j < np; ++j) {
        for (int i = 0; i < kN; ++i) NvData(cv.yS[j])[i] = s[j](i);
      }
      cv.Check(CVodeSensInit1(cv.mem, np, CV_STAGGERED1, &Cvodes::SensRhsFn, cv.yS), "CVodeSensInit1");
      cv.Check(CVodeSetSensParams(cv.mem, p.data(), pbar.data(), nullptr), "CVodeSetSensParams");
      // Tolerances of p̄_j s_j (SI units of y per 100 % change of p_j): rtol and
      // kSensitivityAtol. CVODES' default atol/p̄_j sits below the round-off of the
      // difference-quotient fS (~1e-16 |f|/ε) at tight atol and stalls the step at ~1e-8 s.
      std::vector<double> atol_s(np);
      for (int j = 0; j < np; ++j) atol_s[j] = std::max(options.atol, kSensitivityAtol) / pbar[j];
      cv.Check(CVodeSensSStolerances(cv.mem, options.rtol, atol_s.data()), "CVodeSensSStolerances");
      // Sensitivities in the error test: without it their error follows the step sequence
      // (1 % on N90 measured), not the tolerance.
      cv.Check(CVodeSetSensErrCon(cv.mem, SUNTRUE), "CVodeSetSensErrCon");
    }
    for (;;) {
      double t_reached = t;
      cv.failure.clear();
      while (next_out * dt_out <= t * (1.0 + 1e-12)) ++next_out;  // an event on an output time
      const double t_out = std::min(next_out * dt_out, t_end);
      const int flag = CVode(cv.mem, t_out, cv.y, &t_reached, CV_NORMAL);
      if (flag < 0) {
        double h = 0.0;
        CVodeGetCurrentStep(cv.mem, &h);
        char* name = CVodeGetReturnFlagName(flag);
        const std::string text = name ? name : "?";
        free(name);
        Throw<SolverError>("RunSensitivity", "CVODES ", text, " at t = ", t_reached, " s with step h = ", h, " s",
                           cv.failure.empty() ? "" : " (" + cv.failure + ")", cv.messages.Take());
      }
      t = t_reached;
      for (int i = 0; i < kN; ++i) y(i) = NvData(cv.y)[i];
      if (with_s) {
        double ts = 0.0;
        cv.Check(CVodeGetSens(cv.mem, &ts, cv.yS), "CVodeGetSens");
        for (int j = 0; j < np; ++j) {
          for (int i = 0; i < kN; ++i) s[j](i) = NvData(cv.yS[j])[i];
        }
      }
      if (flag != CV_ROOT_RETURN && t < t_end) {  // an output time
        sample();
        ++next_out;
        continue;
      }
      if (flag != CV_ROOT_RETURN) {  // the end time (CV_TSTOP_RETURN or CV_SUCCESS at t_end)
        result.end_reason = "end_time";
        candidate(mode, zero_dt, s);
        done = true;
        break;
      }
      std::vector<int> fired(n_roots, 0);
      cv.Check(CVodeGetRootInfo(cv.mem, fired.data()), "CVodeGetRootInfo");
      // Interior maxima (dv/dt = 0): envelope theorem, dV/dp = ∂v/∂y s + ∂v/∂p.
      for (size_t k = 0; k < problem.peaks().size(); ++k) {
        if (fired[n_events + k]) candidate(mode, zero_dt, s, true, problem.peaks()[k]);
      }
      int first = -1;
      for (int k = 0; k < n_events; ++k) {
        if (fired[k] && first < 0) first = k;
      }
      if (first < 0) continue;  // only peaks: CVODES continues the same phase

      // An event: τ(p) from g(τ, y(τ; p), p) = 0.
      double fm[kN];
      problem.Rhs(mode, t, y.data(), p.data(), fm);
      std::vector<double> dtau(np, 0.0);
      std::vector<VectorXd> w(np);  // total derivative d y(τ(p); p)/dp = s⁻ + f⁻ dτ/dp
      if (with_s) {
        auto g = [&](double tt, const double* yy, const double* pv) { return problem.Event(mode, first, tt, yy, pv); };
        const std::vector<double> zero_p(np, 0.0);
        const double gdot = problem.Directional(g, t, y.data(), p.data(), 1.0, fm, zero_p.data());
        if (!(std::abs(gdot) > 0.0)) {
          Throw<SolverError>("RunSensitivity", "event ", mode.events[first].name, " at t = ", t,
                             " s is tangential (dg/dt = ", gdot, "): its time is not differentiable in p");
        }
        for (int j = 0; j < np; ++j) {
          dtau[j] = -problem.Directional(g, t, y.data(), p.data(), 0.0, s[j].data(), unit_vector(j)) / gdot;
          w[j] = s[j] + Eigen::Map<const VectorXd>(fm, kN) * dtau[j];
        }
      } else {
        for (int j = 0; j < np; ++j) w[j] = VectorXd::Zero(kN), dtau[j] = kNaN;
      }
      Mode next = mode;
      std::vector<double> dalpha(np, kNaN);
      for (int j = 0; j < np && with_s; ++j) dalpha[j] = w[j](kAlpha);
      done = RecordEvent(mode, fired, t, y(kAlpha), dtau, dalpha, with_s, outcomes, &next.active, &result);
      // 90° values, on the mode before the end event (left limits).
      for (size_t k = 0; k < outcomes.size() && done; ++k) {
        const Outcome& o = outcomes[k];
        if (o.kind == OutcomeKind::kLigamentAt90 || o.kind == OutcomeKind::kContactAt90) {
          result.values[k] = problem.Value(mode, o, t, y.data(), p.data());
          result.derivatives[k] = with_s ? total(mode, o, dtau, w) : std::vector<double>(np, kNaN);
        }
      }
      candidate(mode, dtau, w);
      if (done) break;
      // The new mode: contacts, branches (by the direction of motion at a kink), events.
      const Scene& sc = problem.SceneAt(p.data());
      MechanicalState at;
      at.t = t;
      at.q = y.head<6>();
      at.qd = y.tail<6>();
      at.active = next.active;
      if (!next.branch.empty()) next.branch = LigamentBranchesAt(sc.model, at.q, at.qd);
      if (!next.active.empty()) {
        const ConstrainedAcceleration a = problem.Accel(next, t, y.data(), p.data());
        for (size_t c = 0; c < next.active.size(); ++c) {
          if (a.normal_force[c] < 0.0) {
            Throw<SolverError>("RunSensitivity", "at t = ", t, " s the ",
                               CompartmentName(sc.model.contacts[next.active[c]].compartment),
                               " contact would pull (N = ", a.normal_force[c],
                               " N) after the switch: simultaneous lift-off is not differentiable here");
          }
        }
      }
      const Scene& scene_at = problem.SceneAt(p.data());
      next.events = EventsForPhase(scene_at.model, scene_at.end, at);
      // s⁺ = s⁻ + (f⁻ − f⁺) dτ/dp where the vector field changes.
      double fp[kN];
      problem.Rhs(next, t, y.data(), p.data(), fp);
      if (with_s) {
        for (int j = 0; j < np; ++j) {
          for (int i = 0; i < kN; ++i) s[j](i) += (fm[i] - fp[i]) * dtau[j];
        }
      }
      mode = next;
      candidate(mode, dtau, w);  // right limits (e.g. the far side of a kink's jump)
      break;
    }
  }
  bank();
  for (int k : problem.peaks()) {
    result.values[k] = peak[k].value;
    result.derivatives[k] = peak[k].derivative;
  }
  return finish();
}

}  // namespace kneedyn::sensitivity
