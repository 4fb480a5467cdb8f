// Internal to sensitivity/: what the CVODES (ede) and IDAS (dae, dae-reduced) drivers share
// — the outcomes and what they measure, a phase's mode, the scene at parameter values p and
// the solver/ functions evaluated on the differential state (q, q̇) with directional central
// differences (forward_sensitivity.hpp explains the relations they feed).
#pragma once

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <string>
#include <vector>

#include "ensembles/sweep.hpp"
#include "solver/model.hpp"  // ColumnSafeName: the columns' spelling of an element
#include "formulations/simulator.hpp"
#include "sensitivity/forward_sensitivity.hpp"
#include "solver/constrained_dynamics.hpp"
#include "solver/error.hpp"
#include "solver/events.hpp"
#include "solver/units.hpp"

namespace kneedyn::sensitivity::detail {

using ensembles::ParameterSpec;

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr int kN = 12;  // y = (q, q̇)

// The simulator settings both drivers share: the output interval (--output-interval, else
// the scene's; refused when unusable), the tolerances, pulling contacts refused, and the
// trajectory rows: t0 once the first phase has started (with its consistent initial
// sensitivities), then every output time before the end (no event rows). `dq(j)` is
// ∂q/∂p_j at the state the simulator hands over; called for j < np when `with_s`.
inline SimulatorSettings TrajectorySettings(const Scene& scene, const SensitivityOptions& options, bool with_s, int np,
                                            std::function<Vector6d(int)> dq, SensitivityResult* result) {
  const double t_end = scene.end.time;
  const double dt_out = options.output_interval > 0.0 ? options.output_interval : scene.output_interval;
  std::string why;
  if (!IsValidOutputInterval(dt_out, t_end, &why)) {
    Throw<InputError>("RunSensitivity", options.output_interval > 0.0 ? "--output-interval: " : "scene output.interval_s: ", why);
  }
  const auto row = [with_s, np, dq = std::move(dq), result](const MechanicalState& st) {
    TrajectorySample sample;
    sample.t = st.t;
    sample.q = st.q;
    if (with_s) {
      for (int j = 0; j < np; ++j) sample.dq.push_back(dq(j));
    }
    result->trajectory.push_back(sample);
  };
  SimulatorSettings sim;
  sim.output_interval = dt_out;
  sim.rtol = options.rtol;
  sim.atol = options.atol;
  sim.pulling = PullingContact::kRefuse;
  sim.first_phase_started = row;
  sim.sample = [row, t_end, progress = options.progress, initial_sample = true](const MechanicalState& st,
                                                                                bool is_event) mutable {
    if (!initial_sample && !is_event && st.t < t_end) row(st);
    initial_sample = false;
    if (progress) progress(st.t, st.q(kAlpha));
  };
  return sim;
}

// Relative size of the directional central differences of g and v (their truncation error
// ~ε², round-off ~1e-16/ε: both near 1e-11 relative).
constexpr double kDirectionalStep = 1.0e-6;
// Absolute tolerance floor of the scaled sensitivities p̄_j s_j (SI units of y).
constexpr double kSensitivityAtol = 1.0e-8;
// Relative step of the central difference of the consistent initial state in p.
constexpr double kInitialStateStep = 1.0e-6;

enum class OutcomeKind { kLiftoffTime, kLiftoffFlexion, kTime90, kLigamentAt90, kContactAt90, kPeakLigament, kPeakContact };

struct Outcome {
  std::string column;
  OutcomeKind kind;
  int index = -1;  // ligament (model.ligaments) or contact (model.contacts)
};

inline const std::vector<std::string>& AllGroups() {
  static const std::vector<std::string> kGroups = {"liftoff_time", "liftoff_flexion", "peak_ligament_force",
                                                   "peak_contact_force", "time_at_90", "ligament_force_at_90",
                                                   "contact_force_at_90"};
  return kGroups;
}

inline std::vector<std::string> ColumnsOf(const Scene& scene, const std::vector<std::string>& groups) {
  ensembles::SweepSpec spec;
  spec.base = scene;
  spec.outcome_groups = groups;
  return ensembles::OutcomeColumns(spec);
}

// Maps an outcome column back to what it measures.
inline Outcome ParseOutcome(const Model& m, const std::string& column) {
  Outcome o{column, OutcomeKind::kLiftoffTime, -1};
  if (column == "liftoff_time_s") return o;
  if (column == "liftoff_flexion_deg") return {column, OutcomeKind::kLiftoffFlexion, -1};
  // Per compartment (not sweep columns): liftoff_time_<compartment>_s, liftoff_flexion_<compartment>_deg.
  for (const Compartment c : {Compartment::kMedial, Compartment::kLateral}) {
    const std::string name = CompartmentName(c);
    if (column == "liftoff_time_" + name + "_s") return {column, OutcomeKind::kLiftoffTime, m.ContactIndex(c)};
    if (column == "liftoff_flexion_" + name + "_deg") return {column, OutcomeKind::kLiftoffFlexion, m.ContactIndex(c)};
  }
  if (column == "time_90_s") return {column, OutcomeKind::kTime90, -1};
  const struct {
    const char* prefix;
    OutcomeKind kind;
    bool ligament;
  } kPrefixes[] = {{"peak_F_", OutcomeKind::kPeakLigament, true},
                   {"F90_", OutcomeKind::kLigamentAt90, true},
                   {"peak_N_", OutcomeKind::kPeakContact, false},
                   {"N90_", OutcomeKind::kContactAt90, false}};
  for (const auto& p : kPrefixes) {
    const std::string prefix = p.prefix;
    if (column.rfind(prefix, 0) != 0 || column.size() < prefix.size() + 2) continue;
    const std::string name = column.substr(prefix.size(), column.size() - prefix.size() - 2);
    if (p.ligament) {
      for (size_t j = 0; j < m.ligaments.size(); ++j) {
        if (ColumnSafeName(m.ligaments[j].name) == name) return {column, p.kind, static_cast<int>(j)};
      }
    } else {
      const Compartment c = name == "medial" ? Compartment::kMedial : Compartment::kLateral;
      return {column, p.kind, m.ContactIndex(c)};  // −1 when the scene lacks it (value 0)
    }
  }
  Throw<InputError>("RunSensitivity", "outcome column '", Echo(column), "' is not known");
}

inline bool IsPeak(const Outcome& o) { return o.kind == OutcomeKind::kPeakLigament || o.kind == OutcomeKind::kPeakContact; }

// The mode of a phase: active contacts, locked ligament branches and the events watched.
struct Mode {
  std::vector<int> active;
  std::vector<signed char> branch;
  std::vector<EventSpec> events;
};

// What a phase integrates, with p read from an array (CVODES' copy of the parameters; the
// IDAS driver passes its nominal p): the ODE form's f and the events and force values on
// y = (q, q̇) at the scene SceneForRun gives for p.
class Problem {
 public:
  Problem(const Scene& scene, const std::vector<ParameterSpec>& parameters, const std::vector<Outcome>& outcomes)
      : outcomes_(outcomes) {
    spec_.base = scene;
    spec_.parameters = parameters;
    for (size_t k = 0; k < outcomes.size(); ++k) {
      if (IsPeak(outcomes[k])) peaks_.push_back(static_cast<int>(k));
    }
  }

  int num_parameters() const { return static_cast<int>(spec_.parameters.size()); }
  const std::vector<int>& peaks() const { return peaks_; }
  const std::vector<Outcome>& outcomes() const { return outcomes_; }

  // The scene with parameter values p (cached: f is called with the same p most times).
  const Scene& SceneAt(const double* p) {
    const int np = num_parameters();
    if (!have_scene_ || !std::equal(p, p + np, applied_.begin())) {
      applied_.assign(p, p + np);
      scene_ = ensembles::SceneForRun(spec_, applied_);
      have_scene_ = true;
    }
    return scene_;
  }
  Scene SceneCopyAt(const std::vector<double>& p) { return ensembles::SceneForRun(spec_, p); }

  // The patella's equilibrium (docs/model.md §12) is warm-started from the last solve, as the
  // run driver's workspace does: a fresh workspace per call solved it from the scene's start
  // pose along the tuberosity's straight path every time, and on patellofemoral_extension
  // from t = 0.3283 s the ± evaluations of SensitivityRhs no longer agreed (CVODES stalled at
  // steps of 1e-17 s; minutes before --max-steps ended it).
  ConstrainedAcceleration Accel(const Mode& mode, double t, const double* y, const double* p) {
    const Model& model = SceneAt(p).model;
    const Vector6d q = Eigen::Map<const Vector6d>(y), qd = Eigen::Map<const Vector6d>(y + 6);
    ConstrainedDynamicsWorkspace workspace(model);
    workspace.data.patella_guess = patella_guess_;
    ConstrainedAcceleration out;
    SolveConstrainedAcceleration(model, t, q, qd, mode.active, {}, mode.branch.empty() ? nullptr : &mode.branch,
                                 &workspace, &out);
    patella_guess_ = workspace.data.patella_guess;
    return out;
  }

  void Rhs(const Mode& mode, double t, const double* y, const double* p, double* ydot) {
    const ConstrainedAcceleration a = Accel(mode, t, y, p);
    for (int i = 0; i < 6; ++i) {
      ydot[i] = y[6 + i];
      ydot[6 + i] = a.qdd(i);
    }
  }

  // g_k of the mode's events at p (kink lengths (1 + 2ε1) L0 follow p).
  void Events(const Mode& mode, double t, const double* y, const double* p, double* g) {
    std::vector<double> normal;
    const Scene& scene = SceneAt(p);
    normal.assign(scene.model.contacts.size(), 0.0);
    if (!mode.active.empty()) {
      const ConstrainedAcceleration a = Accel(mode, t, y, p);
      for (size_t c = 0; c < mode.active.size(); ++c) normal[mode.active[c]] = a.normal_force[c];
    }
    std::vector<EventSpec> specs = mode.events;
    for (EventSpec& e : specs) {
      if (e.kind == EventKind::kLigamentKink) e.offset = LigamentKinkLength(scene.model.ligaments[e.ligament]);
    }
    EvaluateEvents(scene.model, specs, Vector6d(Eigen::Map<const Vector6d>(y)), normal, g);
  }
  double Event(const Mode& mode, int k, double t, const double* y, const double* p) {
    std::vector<double> g(mode.events.size());
    Events(mode, t, y, p, g.data());
    return g[k];
  }

  // A force outcome's instantaneous value v(t, y, p): ligament tension (on the mode's
  // branch) or contact normal force (0 while separated).
  double Value(const Mode& mode, const Outcome& o, double t, const double* y, const double* p) {
    if (o.kind == OutcomeKind::kPeakLigament || o.kind == OutcomeKind::kLigamentAt90) {
      const Model& model = SceneAt(p).model;
      Data data(model);
      if (!mode.branch.empty()) data.ligament_branch = &mode.branch;
      ComputeAppliedWrench(model, t, PoseFromCoordinates(Vector6d(Eigen::Map<const Vector6d>(y))), &data);
      return data.ligament_tension[o.index];
    }
    const auto it = std::find(mode.active.begin(), mode.active.end(), o.index);
    if (o.index < 0 || it == mode.active.end()) return 0.0;
    return Accel(mode, t, y, p).normal_force[it - mode.active.begin()];
  }

  // Central difference of fn along (dt, dy, dp) at (t, y, p): ∂fn/∂t dt + ∂fn/∂y dy + ∂fn/∂p dp.
  // Step ε of a directional difference: the largest relative change of a component of
  // (t, y, p) is kDirectionalStep (components near 0 relative to 0.1 s, 1e-3 SI, 1).
  double DirectionalStep(double t, const double* y, const double* p, double dt, const double* dy, const double* dp) const {
    const int np = static_cast<int>(spec_.parameters.size());
    double r = std::abs(dt) / std::max(std::abs(t), 0.1);
    for (int i = 0; i < kN; ++i) r = std::max(r, std::abs(dy[i]) / std::max(std::abs(y[i]), 1.0e-3));
    for (int j = 0; j < np; ++j) r = std::max(r, std::abs(dp[j]) / (p[j] != 0.0 ? std::abs(p[j]) : 1.0));
    return r == 0.0 ? 0.0 : kDirectionalStep / r;
  }

  // The sensitivity right-hand side ṡ_j = ∂f/∂y s_j + ∂f/∂p_j (CVodeSensInit1's fS1) by a
  // central difference along (s_j, e_j), scaled per component (DirectionalStep); CVODES'
  // own quotient scales y by the error weights, which with atol ≪ |y| makes the p step
  // ~1e-11 relative and the quotient round-off bound.
  void SensitivityRhs(const Mode& mode, double t, const double* y, const double* p, int j, const double* s, double* sdot) {
    const int np = num_parameters();
    std::vector<double> e(np, 0.0);
    e[j] = 1.0;
    const double eps = DirectionalStep(t, y, p, 0.0, s, e.data());
    if (eps == 0.0) {
      std::fill(sdot, sdot + kN, 0.0);
      return;
    }
    double yp[kN], ym[kN], fp[kN], fm[kN];
    std::vector<double> pp(p, p + np), pm(p, p + np);
    for (int i = 0; i < kN; ++i) yp[i] = y[i] + eps * s[i], ym[i] = y[i] - eps * s[i];
    pp[j] += eps, pm[j] -= eps;
    Rhs(mode, t, yp, pp.data(), fp);
    Rhs(mode, t, ym, pm.data(), fm);
    for (int i = 0; i < kN; ++i) sdot[i] = (fp[i] - fm[i]) / (2.0 * eps);
  }

  template <typename Fn>
  double Directional(Fn fn, double t, const double* y, const double* p, double dt, const double* dy, const double* dp) {
    const int np = num_parameters();
    const double eps = DirectionalStep(t, y, p, dt, dy, dp);
    if (eps == 0.0) return 0.0;
    double yp[kN], ym[kN];
    std::vector<double> pp(p, p + np), pm(p, p + np);
    for (int i = 0; i < kN; ++i) yp[i] = y[i] + eps * dy[i], ym[i] = y[i] - eps * dy[i];
    for (int j = 0; j < np; ++j) pp[j] += eps * dp[j], pm[j] -= eps * dp[j];
    const double plus = fn(t + eps * dt, yp, pp.data());
    const double minus = fn(t - eps * dt, ym, pm.data());
    return (plus - minus) / (2.0 * eps);
  }

  // Root functions of a phase: its events, then dv/dt of every peak outcome.
  void Roots(const Mode& mode, double t, const double* y, const double* p, double* g) {
    Events(mode, t, y, p, g);
    if (peaks_.empty()) return;
    double f[kN];
    Rhs(mode, t, y, p, f);
    std::vector<double> zero(num_parameters(), 0.0);
    for (size_t k = 0; k < peaks_.size(); ++k) {
      const Outcome& o = outcomes_[peaks_[k]];
      // A slack ligament or a separated contact (v = 0) has dv/dt ≡ 0, which the root finder
      // refuses (a root on an interval): −1 there, so only rising-then-falling v crosses 0.
      if (!(Value(mode, o, t, y, p) > 0.0)) {
        g[mode.events.size() + k] = -1.0;
        continue;
      }
      const double rate = Directional(
          [&](double tt, const double* yy, const double* pp) { return Value(mode, o, tt, yy, pp); }, t, y, p, 1.0, f,
          zero.data());
      // Near the maximum the difference quotient is quantized (plus == minus to the last
      // bit over a short interval); an exact 0 there would be a root on an interval, which
      // CVODES refuses. The first exact 0 counts as just past the maximum.
      g[mode.events.size() + k] = rate != 0.0 ? rate : -std::numeric_limits<double>::min();
    }
  }

 private:
  ensembles::SweepSpec spec_;
  std::vector<Outcome> outcomes_;
  std::vector<int> peaks_;  // indices into outcomes_
  Scene scene_;
  std::vector<double> applied_;
  bool have_scene_ = false;
  PatellaGuess patella_guess_;  // the last patellar equilibrium solved (Accel's warm start)
};

// A maximum candidate of a peak outcome.
struct Peak {
  double value = -std::numeric_limits<double>::infinity();
  std::vector<double> derivative;
};

// What an event does, in both drivers: records the fired events of `mode` at time t (s) and
// flexion α (rad) with dτ/dp (empty without derivatives), refuses a re-contact (a plastic
// impact), removes lifted-off contacts from *next_active and sets the end reason at the end
// flexion; then fills the outcomes this event decides: lift-off time and flexion (the first
// lift-off, or that of the outcome's compartment; dα/dp = dalpha, rad per parameter unit)
// and, at the end, time_90. Returns true at the end event (the driver then adds the 90°
// force values with its own value functions).
inline bool RecordEvent(const Mode& mode, const std::vector<int>& fired, double t, double alpha,
                        const std::vector<double>& dtau, const std::vector<double>& dalpha, bool with_s,
                        const std::vector<Outcome>& outcomes, std::vector<int>* next_active, SensitivityResult* result) {
  bool end = false;
  const int n_events = static_cast<int>(mode.events.size());
  for (int k = 0; k < n_events; ++k) {
    if (!fired[k]) continue;
    const EventSpec& e = mode.events[k];
    result->events.push_back({e.name, t, alpha, with_s ? dtau : std::vector<double>()});
    switch (e.kind) {
      case EventKind::kRecontact:
        Throw<SolverError>("RunSensitivity", e.name, " at t = ", t, " s, flexion = ", RadToDeg(alpha),
                           " deg: a re-contact is a plastic impact (a state reset); sensitivities across impacts "
                           "are not implemented");
      case EventKind::kFlexionEnd:
        result->end_reason = e.name;
        end = true;
        break;
      case EventKind::kLiftoff:
        next_active->erase(std::remove(next_active->begin(), next_active->end(), e.contact), next_active->end());
        break;
      case EventKind::kLigamentKink:
      case EventKind::kPatellarLiftoff:  // the tendon force is continuous there: no jump
      case EventKind::kPatellarRecontact:
        break;
    }
  }
  const int np = static_cast<int>(dtau.size());
  for (size_t k = 0; k < outcomes.size(); ++k) {
    const Outcome& o = outcomes[k];
    // First lift-off (index −1) or that of one compartment.
    bool liftoff = false;
    for (int e = 0; e < n_events; ++e) {
      liftoff = liftoff || (fired[e] && mode.events[e].kind == EventKind::kLiftoff &&
                            (o.index < 0 || mode.events[e].contact == o.index));
    }
    if ((o.kind == OutcomeKind::kLiftoffTime || o.kind == OutcomeKind::kLiftoffFlexion) && liftoff &&
        std::isnan(result->values[k])) {
      const bool time = o.kind == OutcomeKind::kLiftoffTime;
      result->values[k] = time ? t : RadToDeg(alpha);
      for (int j = 0; j < np; ++j) result->derivatives[k][j] = time ? dtau[j] : (with_s ? RadToDeg(dalpha[j]) : kNaN);
    }
    if (end && o.kind == OutcomeKind::kTime90 && result->end_reason == Flexion90EventName()) {
      result->values[k] = t;
      result->derivatives[k] = dtau;
    }
  }
  return end;
}

// The DAE forms (dae_sensitivity.cpp): integrates `problem`'s scene at `values` with IDAS on
// formulations/internal/dae_system.hpp and fills `result` (sized by the caller: outcomes, NaN values
// and derivatives) with the values, derivatives, events, trajectory and counters.
void RunDaeSensitivity(Problem& problem, const std::vector<double>& values, const SensitivityOptions& options,
                       SensitivityResult* result);

}  // namespace kneedyn::sensitivity::detail
