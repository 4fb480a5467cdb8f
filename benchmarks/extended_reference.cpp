#include "benchmarks/extended_reference.hpp"

#include <algorithm>
#include <cmath>
#include <ctime>
#include <limits>
#include <type_traits>

#include "benchmarks/float128_scalar.hpp"
#include "benchmarks/gauss_legendre.hpp"
#include "formulations/internal/formulation_base.hpp"
#include "formulations/simulator.hpp"
#include "solver/constrained_dynamics.hpp"
#include "solver/error.hpp"
#include "solver/surface_wide.hpp"
#include "solver/units.hpp"

namespace kneedyn {
namespace bench {

namespace {

constexpr double kTimeMatch = 1e-9;  // s, as ExtractSolution

// The comparison row of metrics.hpp's classes at a long double state, rounded once.
template <typename T>
void AppendRowTpl(const Model& model, const Vector6<T>& q, const Vector6<T>& qd, const std::vector<int>& active,
                  const std::vector<T>& normal_force, const std::vector<signed char>* branch, double t,
                  PatellaGuess* patella_guess, Solution* s) {
  const T mm = T(kMmPerM), deg = T(kDegPerRad);
  auto d = [](const T& v) { return static_cast<double>(v); };
  s->values["positions"].push_back({d(q(kX0) * mm), d(q(kY0) * mm), d(q(kZ0) * mm), d(q(kAlpha) * deg),
                                    d(q(kBeta) * deg - T(90.0)), d(q(kGamma) * deg)});
  s->values["velocities"].push_back({d(qd(kX0) * mm), d(qd(kY0) * mm), d(qd(kZ0) * mm), d(qd(kAlpha) * deg),
                                     d(qd(kBeta) * deg), d(qd(kGamma) * deg)});
  const PoseTpl<T> pose = PoseFromCoordinates(q);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  std::vector<double> points, forces, tensions;
  for (int i = 0; i < static_cast<int>(model.contacts.size()); ++i) {
    const auto it = std::find(active.begin(), active.end(), i);
    if (it == active.end()) {
      for (int a = 0; a < 6; ++a) points.push_back(nan);
      forces.push_back(0.0);
      continue;
    }
    const ContactGeometryTpl<T> g = RequireContactKinematicsTpl(model.contacts[i], pose, "ExtendedReference");
    for (int a = 0; a < 3; ++a) points.push_back(d(g.point_F(a) * mm));
    for (int a = 0; a < 3; ++a) points.push_back(d(g.point_T(a) * mm));
    forces.push_back(d(normal_force[it - active.begin()]));
  }
  DataTpl<T> data(model);
  data.ligament_branch = branch;
  data.patella_guess = *patella_guess;  // the patella's equilibrium warm-started from the last row's
  ComputeAppliedWrench(model, t, pose, &data);
  *patella_guess = data.patella_guess;
  for (const T& f : data.ligament_tension) tensions.push_back(d(f));
  s->values["contact_points"].push_back(points);
  s->values["contact_forces"].push_back(forces);
  s->values["ligament_forces"].push_back(tensions);
}

// Sign change of g from gl to gr in the direction of an EventSpec (SUNDIALS convention).
template <typename T>
bool Crossed(const T& gl, const T& gr, int direction) {
  return (direction <= 0 && gl > 0 && gr <= 0) || (direction >= 0 && gl < 0 && gr >= 0);
}

template <typename T>
class ExtendedStepper final : public FormulationBase {
 public:
  using Vector = typename GaussLegendre<T>::Vector;

  ExtendedStepper(const Scene& scene, const ExtendedReferenceSettings& settings)
      : FormulationBase(scene), settings_(settings), method_(settings.stages), workspace_(model_) {
    rhs_ = [this](const T& t, const Vector& y, Vector* ydot) { Rhs(t, y, ydot); };
  }

  ContactForm contact_form() const override { return ContactForm::kClosedForm; }

  void Start(const MechanicalState& state, const std::vector<EventSpec>& events) override {
    BeginPhase(state, events);
    ++finished_phases_.restarts;
    bool keep = has_state_ && static_cast<double>(t_) == state.t;
    for (int i = 0; keep && i < 6; ++i) {
      keep = std::abs(static_cast<double>(y_(i)) - state.q(i)) <= 1e-12 * (1.0 + std::abs(state.q(i))) &&
             std::abs(static_cast<double>(y_(6 + i)) - state.qd(i)) <= 1e-12 * (1.0 + std::abs(state.qd(i)));
    }
    if (!keep) {
      y_.resize(12);
      for (int i = 0; i < 6; ++i) {
        y_(i) = T(state.q(i));
        y_(6 + i) = T(state.qd(i));
      }
      t_ = T(state.t);
      if (has_state_) ++restarts_from_double_;
    }
    has_state_ = true;
    EventValues(t_, y_, &g_left_);
  }

  AdvanceResult Advance(double t_out, MechanicalState* state) override {
    const T t_end = T(t_out);
    Vector y_next(12);
    std::vector<T> g_right;
    while (t_ < t_end) {
      const T h = std::min(T(settings_.step), t_end - t_);
      StepOrThrow(t_, y_, h, &y_next);
      const T t_next = h == t_end - t_ ? t_end : t_ + h;
      EventValues(t_next, y_next, &g_right);
      int first = -1;
      T tau_first = h;
      Vector y_first = y_next;
      for (size_t k = 0; k < g_right.size(); ++k) {
        if (!Crossed(g_left_[k], g_right[k], Direction(k))) continue;
        Vector y_root(12);
        const T tau = LocateRoot(k, h, g_right[k], &y_root);
        if (first < 0 || tau < tau_first) {
          first = static_cast<int>(k);
          tau_first = tau;
          y_first = y_root;
        }
      }
      if (first < 0) {
        t_ = t_next;
        y_ = y_next;
        g_left_ = g_right;
        continue;
      }
      // The step ends at the first root: every model event crossed there fires.
      const T t_root = tau_first == h ? t_next : t_ + tau_first;
      std::vector<T> g_root;
      EventValues(t_root, y_first, &g_root);
      std::vector<int> fired;
      for (size_t k = 0; k < events_.size(); ++k) {
        if (Crossed(g_left_[k], g_root[k], Direction(k)) || static_cast<int>(k) == first) fired.push_back(static_cast<int>(k));
      }
      t_ = t_root;
      y_ = y_first;
      g_left_ = g_root;
      if (fired.empty()) {
        ++slack_breakpoints_;  // a slack length: the step ends there, no event
        continue;
      }
      WriteState(state);
      AdvanceResult r;
      r.status = AdvanceStatus::kEvent;
      r.events = fired;
      return r;
    }
    WriteState(state);
    return AdvanceResult{};
  }

  std::string integrator() const override { return StrCat("gauss-legendre-", method_.stages()); }
  double fixed_step() const override { return settings_.step; }

  // The current state and what it implies, in T.
  T t() const { return t_; }
  const Vector& y() const { return y_; }
  const std::vector<T>& normal_force() const { return last_.normal_force; }
  void EvaluateAt() {
    Vector ydot(12);
    Rhs(t_, y_, &ydot);
  }
  const std::vector<int>& active() const { return active_; }
  const std::vector<signed char>& branches() const { return ligament_branch_; }
  bool has_state() const { return has_state_; }
  const typename GaussLegendre<T>::Counters& counters() const { return method_.counters(); }
  long event_iterations() const { return event_iterations_; }
  long slack_breakpoints() const { return slack_breakpoints_; }
  long restarts_from_double() const { return restarts_from_double_; }

 protected:
  SolverStats PhaseStats() const override {
    SolverStats s;
    s.steps = method_.counters().steps;
    s.residual_evaluations = method_.counters().rhs_evaluations;
    s.nonlinear_iterations = method_.counters().newton_iterations;
    s.jacobian_evaluations = method_.counters().jacobians;
    s.root_evaluations = event_iterations_;
    return s;
  }

 private:
  void Rhs(const T& t, const Vector& y, Vector* ydot) {
    const Vector6<T> q = y.template head<6>();
    const Vector6<T> qd = y.template tail<6>();
    SolveConstrainedAccelerationTpl(model_, static_cast<double>(t), q, qd, active_, BaumgarteGains{},
                                    &ligament_branch_, &workspace_, &last_);
    ydot->resize(12);
    ydot->template head<6>() = qd;
    ydot->template tail<6>() = last_.qdd;
  }

  int Direction(size_t k) const { return k < events_.size() ? events_[k].direction : 0; }

  // The phase's event functions, then the ligaments' elongations L − L0 (slack breakpoints).
  void EventValues(const T& t, const Vector& y, std::vector<T>* g) {
    Vector ydot(12);
    Rhs(t, y, &ydot);  // normal forces at (t, y)
    std::vector<T> normal(model_.contacts.size(), T(0));
    for (size_t c = 0; c < active_.size(); ++c) normal[active_[c]] = last_.normal_force[c];
    const Vector6<T> q = y.template head<6>();
    const PoseTpl<T> pose = PoseFromCoordinates(q);
    g->assign(events_.size() + model_.ligaments.size(), T(0));
    EvaluateEventsTpl(model_, events_, q, pose, normal, g->data());
    for (size_t j = 0; j < model_.ligaments.size(); ++j) {
      const Ligament& lig = model_.ligaments[j];
      (*g)[events_.size() + j] = LigamentSpan_F(lig, pose).norm() - lig.slack_length;
    }
  }

  void StepOrThrow(const T& t, const Vector& y, const T& h, Vector* y_next) {
    if (!method_.Step(rhs_, t, y, h, y_next)) {
      Throw<SolverError>("ExtendedReference", "Gauss-Legendre Newton did not converge at t = ",
                         static_cast<double>(t), " s, h = ", static_cast<double>(h), " s");
    }
  }

  // Root of g_k in (0, h] from the step start: Illinois regula falsi on τ, each trial an
  // exact step of size τ; returns the right end of the final bracket (g_k crossed there).
  T LocateRoot(size_t k, const T& h, const T& g_h, Vector* y_root) {
    using std::abs;
    const T eps = std::numeric_limits<T>::epsilon();
    T a = 0, b = h, ga = g_left_[k], gb = g_h;
    Vector y_b(12), y_trial(12);
    StepOrThrow(t_, y_, h, &y_b);
    std::vector<T> g;
    int side = 0;
    for (int iter = 0; iter < 200 && b - a > 4 * eps * (abs(t_) + h); ++iter) {
      T tau = b - gb * (b - a) / (gb - ga);
      const T margin = (b - a) / 1000;  // keep trials inside the bracket
      tau = std::min(std::max(tau, a + margin), b - margin);
      StepOrThrow(t_, y_, tau, &y_trial);
      ++event_iterations_;
      EventValues(t_ + tau, y_trial, &g);
      const T gt = g[k];
      if (Crossed(g_left_[k], gt, Direction(k))) {
        b = tau;
        gb = gt;
        y_b = y_trial;
        if (side == 1) ga /= 2;  // Illinois: the retained end's value halved
        side = 1;
      } else {
        a = tau;
        ga = gt;
        if (side == -1) gb /= 2;
        side = -1;
      }
    }
    *y_root = y_b;
    return b;
  }

  void WriteState(MechanicalState* state) {
    Vector ydot(12);
    Rhs(t_, y_, &ydot);
    Vector6d q, qd, qdd;
    for (int i = 0; i < 6; ++i) {
      q(i) = static_cast<double>(y_(i));
      qd(i) = static_cast<double>(y_(6 + i));
      qdd(i) = static_cast<double>(last_.qdd(i));
    }
    std::vector<double> normal(active_.size());
    for (size_t c = 0; c < active_.size(); ++c) normal[c] = static_cast<double>(last_.normal_force[c]);
    WriteBack(static_cast<double>(t_), q, qd, qdd, normal.data(), nullptr, 0, state);
  }

  ExtendedReferenceSettings settings_;
  GaussLegendre<T> method_;
  typename GaussLegendre<T>::Rhs rhs_;
  ConstrainedDynamicsWorkspaceTpl<T> workspace_;
  ConstrainedAccelerationTpl<T> last_;
  bool has_state_ = false;
  T t_ = 0;
  Vector y_;
  std::vector<T> g_left_;
  long event_iterations_ = 0;
  long slack_breakpoints_ = 0;
  long restarts_from_double_ = 0;
};

}  // namespace

template <typename T>
ExtendedReferenceRun RunExtendedReference(const Scene& scene, const ExtendedReferenceSettings& settings,
                                          double comparison_interval) {
  if (!(settings.step > 0.0) || settings.stages < 1 || settings.stages > 12) {
    Throw<InputError>("ExtendedReference", "step = ", settings.step, " s, stages = ", settings.stages,
                      "; need step > 0 and 1 <= stages <= 12");
  }
  const std::clock_t cpu_start = std::clock();
  const Model& model = scene.model;
  ExtendedReferenceRun run;
  ExtendedStepper<T> stepper(scene, settings);
  SimulatorSettings sim;
  sim.init.form = ContactForm::kClosedForm;
  sim.output_interval = settings.output_interval;
  sim.rtol = 1e-15;  // the re-contact hysteresis (simulator.hpp) of a method at this accuracy
  sim.atol = 1e-17;
  // Rows in T, one per simulator sample (the t0 row from the consistent double state).
  Solution rows;
  T energy0 = 0;
  bool have_energy0 = false;
  PatellaGuess row_patella_guess;
  sim.sample = [&](const MechanicalState& st, bool) {
    Vector6<T> q, qd;
    std::vector<T> normal;
    std::vector<int> active = st.active;
    if (stepper.has_state()) {
      stepper.EvaluateAt();
      q = stepper.y().template head<6>();
      qd = stepper.y().template tail<6>();
      normal = stepper.normal_force();
    } else {
      for (int i = 0; i < 6; ++i) {
        q(i) = T(st.q(i));
        qd(i) = T(st.qd(i));
      }
      for (int i : st.active) normal.push_back(T(st.contact[i].normal_force));
    }
    // Tensions by length (no locked branch), as ComputeObservables reports them.
    AppendRowTpl(model, q, qd, active, normal, nullptr, st.t, &row_patella_guess, &rows);
    rows.times.push_back(st.t);
    // Constraint residuals and energy in T.
    const EulerAngleTrig<T> trig = EulerAngleTrigOf(q);
    const PoseTpl<T> pose = PoseFromCoordinates(q, trig);
    const Vector6<T> nu = GeneralizedVelocity(q, trig, qd);
    for (int i : active) {
      const ContactGeometryTpl<T> g = RequireContactKinematicsTpl(model.contacts[i], pose, "ExtendedReference");
      run.max_gap_m = std::max(run.max_gap_m, std::abs(static_cast<double>(g.gap)));
      run.max_gap_rate_m_s =
          std::max(run.max_gap_rate_m_s, std::abs(static_cast<double>(ContactConstraintRow(pose, g).dot(nu))));
    }
    const T energy = MechanicalEnergyTpl(model, q, qd);
    if (!have_energy0) {
      energy0 = energy;
      have_energy0 = true;
    }
    using std::abs;
    run.energy_error = std::max(run.energy_error, static_cast<double>(abs((energy - energy0) / energy0)));
  };
  Simulator simulator(scene, &stepper, sim, &run.result);
  simulator.Initialize();
  simulator.Run();
  run.result.completed = true;
  run.result.stats = stepper.stats();
  run.result.integrator = stepper.integrator();

  // The comparison rows, selected as ExtractSolution selects them; its double rows give the
  // names and the times to check against.
  run.solution = ExtractSolution(scene, ContactForm::kClosedForm, run.result, comparison_interval);
  for (const std::string& c : VariableClasses()) run.solution.values[c].clear();
  std::vector<double> times;
  const RunResult& r = run.result;
  auto take = [&](size_t k) {
    times.push_back(r.samples[k].t);
    for (const std::string& c : VariableClasses()) run.solution.values[c].push_back(rows.values[c][k]);
  };
  for (size_t k = 0; k < r.samples.size(); ++k) {
    if (r.sample_is_event[k]) continue;
    const double n = std::round(r.samples[k].t / comparison_interval);
    if (std::abs(r.samples[k].t - n * comparison_interval) > kTimeMatch) continue;
    take(k);
  }
  if (run.solution.end_is_event) take(r.samples.size() - 1);
  if (times != run.solution.times) {
    Throw<SolverError>("ExtendedReference", "comparison times differ from ExtractSolution's (", times.size(), " vs ",
                       run.solution.times.size(), ")");
  }
  const auto& k = stepper.counters();
  run.steps = k.steps;
  run.rhs_evaluations = k.rhs_evaluations;
  run.newton_iterations = k.newton_iterations;
  run.event_iterations = stepper.event_iterations();
  run.slack_breakpoints = stepper.slack_breakpoints();
  run.restarts_from_double = stepper.restarts_from_double();
  run.cpu_time_s = static_cast<double>(std::clock() - cpu_start) / CLOCKS_PER_SEC;
  return run;
}

template ExtendedReferenceRun RunExtendedReference<double>(const Scene&, const ExtendedReferenceSettings&, double);
template ExtendedReferenceRun RunExtendedReference<long double>(const Scene&, const ExtendedReferenceSettings&,
                                                                double);
template ExtendedReferenceRun RunExtendedReference<Float128>(const Scene&, const ExtendedReferenceSettings&, double);

}  // namespace bench
}  // namespace kneedyn
