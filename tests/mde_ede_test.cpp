// mde and ede against a second formulation (dae), the full constrained equations,
// and an exact solution (torque-free symmetric top in free fall) for the integrator orders.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <map>

#include "formulations/run.hpp"
#include "solver/constrained_dynamics.hpp"
#include "solver/dynamics.hpp"
#include "solver/pose.hpp"
#include "scene/scene.hpp"

namespace kneedyn {
namespace {

Scene ChapterScene() { return LoadScene(ReferenceDataDir() + "/scenes/chapter_impact.yaml"); }

RunResult RunWith(const Scene& scene, const std::string& formulation, FormulationOptions options) {
  RunSettings settings;
  settings.formulation = formulation;
  settings.options = options;
  RunResult r = RunScene(scene, settings);
  EXPECT_TRUE(r.completed) << formulation << ": " << r.failure;
  return r;
}

FormulationOptions Tight() {
  FormulationOptions o;
  o.rtol = 1.0e-10;
  o.atol = 1.0e-12;
  return o;
}

// Explicit Euler at the fixed step h (s).
FormulationOptions Euler(double h) {
  FormulationOptions o;
  o.integrator = IntegratorKind::kEuler;
  o.step = h;
  return o;
}

const EventRecord* FindEvent(const RunResult& r, const std::string& name) {
  for (const EventRecord& e : r.events) {
    if (e.name == name) return &e;
  }
  return nullptr;
}

// Measured (rtol 1e-10): dae lift-off 0.216294133603 s / 52.597259832°, 90° at
// 0.299192187834 s; mde 0.216294134060 s / 52.597260032°, 0.299192187771 s; ede-projection
// 0.216294134063 s / 52.597260034°, 0.299192187767 s: differences ≤ 4.6e-10 s, 2.0e-7°.
// Tolerances 1e-7 s, 1e-5° (≥ 50x margin).
TEST(MdeEde, ChapterEventsAgreeWithDae) {
  const Scene scene = ChapterScene();
  const RunResult dae = RunWith(scene, "dae", Tight());
  FormulationOptions ede_options = Tight();
  ede_options.stabilization = Stabilization::kProjection;
  const std::map<std::string, RunResult> runs = {{"mde", RunWith(scene, "mde", Tight())},
                                                 {"ede", RunWith(scene, "ede", ede_options)}};
  for (const auto& [name, r] : runs) {
    for (const char* event : {"liftoff_lateral", "flexion_90"}) {
      const EventRecord* ref = FindEvent(dae, event);
      const EventRecord* got = FindEvent(r, event);
      ASSERT_NE(ref, nullptr) << event;
      ASSERT_NE(got, nullptr) << name << " " << event;
      std::printf("%s %s: t = %.12f s (dae %.12f), flexion = %.9f deg (dae %.9f)\n", name.c_str(), event,
                  got->time, ref->time, got->flexion * 180.0 / M_PI, ref->flexion * 180.0 / M_PI);
      EXPECT_NEAR(got->time, ref->time, 1.0e-7) << name << " " << event;
      EXPECT_NEAR(got->flexion * 180.0 / M_PI, ref->flexion * 180.0 / M_PI, 1.0e-5) << name << " " << event;
    }
  }
  // mde holds the constraints by construction: round-off only (measured 1e-16 m).
  EXPECT_LT(runs.at("mde").max_position_residual, 1.0e-13);
}

// mde's forces come from its projected (minimal) dynamics, Gᵀ N = M ν̇ − Q; they must equal
// the full constrained equations at the same state, and dae's N at the same output time.
// Measured: vs SolveConstrainedAcceleration 1.5e-14 relative (59 rows); vs dae 8.9e-7
// relative (59 rows). Tolerances 1e-8 and 1e-4.
TEST(MdeEde, MdeForcesEqualFullEquations) {
  const Scene scene = ChapterScene();
  const RunResult mde = RunWith(scene, "mde", Tight());
  const RunResult dae = RunWith(scene, "dae", Tight());
  std::map<long, const MechanicalState*> dae_at;  // by output time in µs
  for (size_t i = 0; i < dae.samples.size(); ++i) {
    if (!dae.sample_is_event[i]) dae_at[std::lround(dae.samples[i].t * 1e6)] = &dae.samples[i];
  }
  int checked = 0, compared_with_dae = 0;
  double worst_full = 0.0, worst_dae = 0.0;
  for (size_t s = 1; s < mde.samples.size(); ++s) {
    const MechanicalState& st = mde.samples[s];
    if (st.active.empty() || mde.sample_is_event[s]) continue;
    const ConstrainedAcceleration full =
        SolveConstrainedAcceleration(scene.model, st.t, st.q, st.qd, st.active, {}, &st.ligament_branch);
    for (size_t c = 0; c < st.active.size(); ++c) {
      const double n = st.contact[st.active[c]].normal_force;
      const double rel = std::abs(n - full.normal_force[c]) / std::max(1.0, std::abs(full.normal_force[c]));
      worst_full = std::max(worst_full, rel);
      EXPECT_LT(rel, 1.0e-8) << "t = " << st.t << " contact " << st.active[c];
    }
    EXPECT_LT((st.qdd - full.qdd).norm(), 1.0e-8 * std::max(1.0, full.qdd.norm())) << "t = " << st.t;
    ++checked;
    const auto it = dae_at.find(std::lround(st.t * 1e6));
    if (it != dae_at.end() && it->second->active == st.active) {
      for (int i : st.active) {
        const double ref = it->second->contact[i].normal_force;
        const double rel = std::abs(st.contact[i].normal_force - ref) / std::max(1.0, std::abs(ref));
        worst_dae = std::max(worst_dae, rel);
        EXPECT_LT(rel, 1.0e-4) << "t = " << st.t << " contact " << i;
      }
      ++compared_with_dae;
    }
  }
  std::printf("mde N vs full equations: worst rel %.3e over %d rows; vs dae: %.3e over %d rows\n", worst_full,
              checked, worst_dae, compared_with_dae);
  EXPECT_GT(checked, 40);
  EXPECT_GT(compared_with_dae, 40);
}

// EDE drift at a loose setting (rk4, h = 1 ms): without stabilization |φ| grows over the
// run; projection keeps it at round-off. Measured: none 2.4e-10 m (first third of the
// two-contact phase) vs 7.2e-10 m (last third); projection 7e-15 m over the run.
TEST(MdeEde, EdeDriftWithoutStabilizationGrowsAndProjectionRemovesIt) {
  const Scene scene = ChapterScene();
  FormulationOptions o;
  o.integrator = IntegratorKind::kRk4;
  o.step = 1.0e-3;
  const RunResult none = RunWith(scene, "ede", o);
  o.stabilization = Stabilization::kProjection;
  const RunResult projected = RunWith(scene, "ede", o);
  // Drift over the two-contact phase (before lift-off): max |φ| in the first and last thirds.
  std::vector<double> drift;
  for (const MechanicalState& s : none.samples) {
    if (s.active.size() != 2) break;
    std::vector<double> gap, rate;
    ConstraintResiduals(scene.model, s, &gap, &rate);
    drift.push_back(std::max(std::abs(gap[0]), std::abs(gap[1])));
  }
  ASSERT_GT(drift.size(), 30u);
  const size_t third = drift.size() / 3;
  const double early = *std::max_element(drift.begin(), drift.begin() + third);
  const double late = *std::max_element(drift.end() - third, drift.end());
  std::printf("ede rk4 1 ms: drift early %.3e m, late %.3e m, run max none %.3e m, projection %.3e m\n", early,
              late, none.max_position_residual, projected.max_position_residual);
  EXPECT_GT(late, 2.0 * early);
  EXPECT_GT(none.max_position_residual, 100.0 * projected.max_position_residual);
  EXPECT_GT(projected.stats.projections, 0);
}

// Convergence orders on an exact solution: no contacts, no ligaments, gravity on. The tibia
// (I_xx = I_yy ≠ I_zz) is a torque-free symmetric top in free fall. Body-frame angular
// velocity: w_z constant, (w_x, w_y) rotating at λ = (I_zz − I)/I · w_z:
//   w_x = w0x cos λt − w0y sin λt,  w_y = w0x sin λt + w0y cos λt.
// R0 = ½ g t² (RK4 integrates that quadratic exactly, so the measure is the w_T error,
// which both methods integrate with a truncation error). Slopes from 4 step sizes.
// Measured slopes: euler 1.000 (errors 2.2e-3 .. 2.7e-4 rad/s; before the interpolant fix
// the outputs were step averages, errors 5e-2 .. 6e-3), rk4 4.009, 4.006, 4.002
// (7e-9 .. 1.7e-12 rad/s, above round-off).
Scene TopScene() {
  const std::string yaml = R"(
name: symmetric_top
description: torque-free symmetric tibia in free fall (exact solution)
parameter_set: ../chapter_knee.yaml
ligaments: none
contacts: []
gravity: {enabled: true}
pulse: {shape: none}
initial_state: {pose: reference}
end: {time_s: 0.2}
)";
  return ParseScene(yaml, "symmetric_top (inline)", ReferenceDataDir() + "/scenes");
}

double TopError(const Scene& scene, const std::string& formulation, const std::string& integrator, double h) {
  const Model& model = scene.model;
  const Vector3d w0(1.5, -1.0, 30.0);  // rad/s, T (precession λ ≈ −28 rad/s)
  MechanicalState state;
  state.q << 0.0, 0.0, 0.0, 0.0, M_PI / 2.0, 0.0;
  Vector6d nu;
  nu << 0.0, 0.0, 0.0, w0;
  state.qd = CoordinateVelocity(state.q, nu);
  FormulationOptions o;
  o.integrator = IntegratorOption(integrator);
  o.step = h;
  std::unique_ptr<Formulation> f = CreateFormulation(formulation, scene, o);
  f->Start(state, {});
  const double t_end = 0.2;
  const AdvanceResult r = f->Advance(t_end, &state);
  EXPECT_EQ(r.status, AdvanceStatus::kReachedTime);
  EXPECT_NEAR(state.t, t_end, 1e-14);
  const double I = model.inertia_T(0);
  EXPECT_DOUBLE_EQ(model.inertia_T(1), I);
  const double lambda = (model.inertia_T(2) - I) / I * w0(2);
  const double c = std::cos(lambda * t_end), s = std::sin(lambda * t_end);
  const Vector3d w_exact(w0(0) * c - w0(1) * s, w0(0) * s + w0(1) * c, w0(2));
  const Vector3d R0_exact = 0.5 * model.gravity_F * t_end * t_end;
  const double w_error = (AngularVelocityT(state.q, state.qd) - w_exact).norm();
  if (integrator == "rk4") {
    EXPECT_LT((state.q.head<3>() - R0_exact).norm(), 1e-12);  // quadratic: exact
  }
  return w_error;
}

void ExpectOrder(const std::string& formulation, const std::string& integrator, std::vector<double> steps,
                 double order) {
  const Scene scene = TopScene();
  std::vector<double> err;
  for (double h : steps) err.push_back(TopError(scene, formulation, integrator, h));
  for (size_t i = 1; i < steps.size(); ++i) {
    const double slope = std::log(err[i - 1] / err[i]) / std::log(steps[i - 1] / steps[i]);
    std::printf("%s %s: h %.2e err %.3e -> h %.2e err %.3e, slope %.3f\n", formulation.c_str(), integrator.c_str(),
                steps[i - 1], err[i - 1], steps[i], err[i], slope);
    EXPECT_NEAR(slope, order, 0.2) << formulation << " " << integrator << " h = " << steps[i];
  }
}

TEST(MdeEde, EulerIsFirstOrderOnExactSolution) {
  ExpectOrder("ede", "euler", {2e-3, 1e-3, 5e-4, 2.5e-4}, 1.0);
  ExpectOrder("mde", "euler", {2e-3, 1e-3, 5e-4, 2.5e-4}, 1.0);
}

TEST(MdeEde, Rk4IsFourthOrderOnExactSolution) {
  ExpectOrder("ede", "rk4", {1e-2, 5e-3, 2.5e-3, 1.25e-3}, 4.0);
  ExpectOrder("mde", "rk4", {1e-2, 5e-3, 2.5e-3, 1.25e-3}, 4.0);
}

// Output times that are not multiples of H end on a step boundary (shortened last step).
TEST(MdeEde, FixedStepHitsOutputTimesExactly) {
  const Scene scene = TopScene();
  MechanicalState state;
  state.q << 0.0, 0.0, 0.0, 0.0, M_PI / 2.0, 0.0;
  FormulationOptions o;
  o.integrator = IntegratorKind::kRk4;
  o.step = 3.0e-3;
  std::unique_ptr<Formulation> f = CreateFormulation("ede", scene, o);
  f->Start(state, {});
  for (double t : {0.005, 0.0101, 0.02}) {
    f->Advance(t, &state);
    EXPECT_DOUBLE_EQ(state.t, t);
    // Free fall from rest: RK4 is exact for the quadratic R0(t) at every step boundary.
    EXPECT_NEAR((state.q.head<3>() - 0.5 * scene.model.gravity_F * t * t).norm(), 0.0, 1e-14);
  }
}

// Euler (a regression: every euler run failed). Old code: (1) ARK_ILL_INPUT ("tstop = 0.01 is
// behind current t = 0.01") when a phase restarted at a root ARKODE located at the end of
// a step that ended on an output time, and the driver asked for that time again; (2) ARKODE
// 6.4 capped the Hermite interpolant at degree q − 1 = 0, the step average, so roots came
// just after a step start with the average state and stop-time outputs were averages.
// Checks: the chapter scene's first 0.05 s (impact, contact phases, ligament kinks) with
// H = 4e-3, 2e-3, 1e-3 completes and every uniform row lies exactly on k·dt (dt = 5 ms is
// no multiple of 4e-3 or 2e-3: shortened last steps); the full scene with small H
// completes and reaches 90° near dae's 0.299192 s (rtol 1e-10; first order in H).
// Measured 90° times: mde 0.300705 / 0.299088 s, ede 0.300452 / 0.299306 s (H = 2.5e-4 /
// 1e-4); tolerances 3e-3 / 1e-3 s. (Larger H leave Euler's stability region on this
// scene: e.g. ede H = 4e-3 blows up by 0.11 s.)
void ExpectUniformRowsOnOutputTimes(const RunResult& r, double dt, const std::string& what) {
  int uniform_rows = 0;
  for (size_t i = 0; i < r.samples.size(); ++i) {
    if (i > 0) {
      EXPECT_GT(r.samples[i].t, r.samples[i - 1].t) << what << " row " << i;
    }
    if (r.sample_is_event[i]) continue;
    EXPECT_EQ(r.samples[i].t, std::round(r.samples[i].t / dt) * dt) << what << " row " << i;
    ++uniform_rows;
  }
  EXPECT_GT(uniform_rows, 0) << what;
}

TEST(MdeEde, EulerCompletesAndHitsOutputTimesExactly) {
  Scene scene = ChapterScene();
  const double dt = scene.output_interval;
  scene.end.time = 0.05;
  for (const char* name : {"mde", "ede"}) {
    for (double h : {4e-3, 2e-3, 1e-3}) {
      const RunResult r = RunWith(scene, name, Euler(h));
      const std::string what = std::string(name) + " h = " + std::to_string(h);
      ASSERT_TRUE(r.completed) << what;
      EXPECT_EQ(r.end_reason, "end_time") << what;
      EXPECT_EQ(r.samples.back().t, 0.05) << what;
      ExpectUniformRowsOnOutputTimes(r, dt, what);
    }
  }
}

TEST(MdeEde, EulerChapterSceneConvergesToDae90DegreeTime) {
  const Scene scene = ChapterScene();
  // The second formulation's 90° time, computed here (dae, rtol 1e-10; measured 0.299192 s).
  const RunResult dae = RunWith(scene, "dae", Tight());
  const EventRecord* dae_90 = FindEvent(dae, "flexion_90");
  ASSERT_NE(dae_90, nullptr);
  const double t90_dae = dae_90->time;
  for (const char* name : {"mde", "ede"}) {
    for (const auto& [h, tol] : {std::pair<double, double>{2.5e-4, 3e-3}, {1e-4, 1e-3}}) {
      const RunResult r = RunWith(scene, name, Euler(h));
      const std::string what = std::string(name) + " h = " + std::to_string(h);
      ASSERT_TRUE(r.completed) << what;
      const EventRecord* e = FindEvent(r, "flexion_90");
      ASSERT_NE(e, nullptr) << what;
      std::printf("%s euler h = %.1e: 90 deg at %.6f s (dae %.6f), %ld steps\n", name, h, e->time, t90_dae,
                  r.stats.steps);
      EXPECT_NEAR(e->time, t90_dae, tol) << what;
      ExpectUniformRowsOnOutputTimes(r, scene.output_interval, what);
    }
  }
}

// Hard case long_conservative_contact (C¹ law, gravity, both contacts, no pulse) up to just
// before the first re-contact (0.3266 s): conservative (workless contacts, lift-off at
// 0.218 s without impact), and the medial one-point phase passes 90° flexion, where z0 can
// no longer be eliminated (n_z → 0). One output interval over the whole run: mde must
// switch charts inside it, not only at output times. Checks: energy conserved, and the
// end state equal to ede's (second formulation). Old code (chart switched at outputs
// only) ended far off with energy drift of order 1e2 J. Measured after the fix: drift
// ~2e-8 J, |Δα| vs ede ~1e-7°; tolerances 1e-5 J, 1e-4°.
TEST(MdeEde, MdeSwitchesChartsInsideAnOutputInterval) {
  Scene scene = LoadScene(ReferenceDataDir() + "/scenes/hard/long_conservative_contact.yaml");
  scene.end.time = 0.32;
  FormulationOptions o;
  o.rtol = 1.0e-8;
  o.atol = 1.0e-10;
  std::map<std::string, RunResult> runs;
  for (const char* name : {"mde", "ede"}) {
    for (double interval : {0.32, 0.01}) {
      scene.output_interval = interval;
      const std::string key = std::string(name) + (interval > 0.1 ? "_coarse" : "_fine");
      runs.emplace(key, RunWith(scene, name, o));
    }
  }
  for (const auto& [key, r] : runs) {
    ASSERT_FALSE(r.samples.empty()) << key;
    ASSERT_NE(FindEvent(r, "liftoff_lateral"), nullptr) << key;
    EXPECT_NEAR(r.samples.back().t, 0.32, 1e-12) << key;
    const double e0 = MechanicalEnergy(scene.model, r.samples.front().q, r.samples.front().qd);
    double drift = 0.0;
    for (const MechanicalState& s : r.samples) {
      drift = std::max(drift, std::abs(MechanicalEnergy(scene.model, s.q, s.qd) - e0));
    }
    const double da = std::abs(r.samples.back().q(kAlpha) - runs.at("ede_fine").samples.back().q(kAlpha));
    std::printf("%s: end flexion %.9f deg, energy drift %.3e J, |dalpha| vs ede %.3e deg\n", key.c_str(),
                r.samples.back().q(kAlpha) * 180.0 / M_PI, drift, da * 180.0 / M_PI);
    EXPECT_LT(drift, 1.0e-5) << key;
    EXPECT_LT(da * 180.0 / M_PI, 1.0e-4) << key;
  }
  // Passed 90° in the one-point phase (so the z0 chart had to be left).
  EXPECT_GT(runs.at("mde_coarse").samples.back().q(kAlpha), M_PI / 2.0);
}

// The same run twice gives bit-identical results (no uninitialized or stale state).
TEST(MdeEde, MdeIsDeterministic) {
  Scene scene = LoadScene(ReferenceDataDir() + "/scenes/hard/long_conservative_contact.yaml");
  scene.end.time = 0.5;
  scene.output_interval = 0.05;
  FormulationOptions o;
  o.rtol = 1.0e-8;
  o.atol = 1.0e-10;
  const RunResult a = RunWith(scene, "mde", o), b = RunWith(scene, "mde", o);
  ASSERT_EQ(a.samples.size(), b.samples.size());
  for (size_t i = 0; i < a.samples.size(); ++i) {
    EXPECT_EQ(a.samples[i].t, b.samples[i].t) << i;
    for (int j = 0; j < 6; ++j) {
      EXPECT_EQ(a.samples[i].q(j), b.samples[i].q(j)) << i << " " << j;
      EXPECT_EQ(a.samples[i].qd(j), b.samples[i].qd(j)) << i << " " << j;
    }
  }
}

TEST(MdeEde, RejectsBadIntegratorOptions) {
  const Scene scene = ChapterScene();
  FormulationOptions o;
  o.integrator = IntegratorKind::kDopri5;
  o.step = 1e-3;
  EXPECT_THROW(CreateFormulation("mde", scene, o), InputError);
  o = FormulationOptions();
  o.stabilization = Stabilization::kProjection;
  EXPECT_THROW(CreateFormulation("mde", scene, o), InputError);
  EXPECT_THROW(ParsedOptionValue<IntegratorKind>("rk5"), InputError);  // refused where it is read
}

// A SUNDIALS failure of an ODE form names the state component with the
// largest weighted local error estimate, by its name in that form. The step budget of 30
// makes CVODE stop (CV_TOO_MUCH_WORK) early in the first phase.
TEST(OdeFailures, NameTheLargestWeightedLocalErrorComponent) {
  const Scene scene = ChapterScene();
  RunSettings settings;
  settings.formulation = "ede";
  settings.options.integrator = IntegratorKind::kCvodeBdf;
  settings.options.max_steps = 30;
  const RunResult r = RunScene(scene, settings);
  ASSERT_FALSE(r.completed);
  const std::string key = "largest weighted local error estimate: ";
  const size_t at = r.failure.find(key);
  ASSERT_NE(at, std::string::npos) << r.failure;
  const std::string name = r.failure.substr(at + key.size(), r.failure.find(' ', at + key.size()) - at - key.size());
  bool known = false;
  for (int i = 0; i < 6; ++i) {
    known = known || name == CoordinateName(i) || name == std::string(CoordinateName(i)) + "_rate";
  }
  EXPECT_TRUE(known) << "'" << name << "' in: " << r.failure;
  EXPECT_NE(r.failure.find("CV_TOO_MUCH_WORK"), std::string::npos) << r.failure;
}

// --max-steps bounds the steps of a phase, over all the integrator calls of its output
// intervals (SUNDIALS' own limit counts per call). The scene c1_law has two phases (no
// ligament kinks restart it): rk4 at h = 1e-4 s takes 50 steps per 0.005 s output interval
// and ceil(0.2167 / h) = 2167 in the first phase (lift-off at 0.2167 s), about 830 in the
// second (to 90° at 0.2993 s). A budget of 2100 runs out at t = 2100 h = 0.21 s; one of 2200
// covers both phases. On the old per-call budget both completed.
TEST(OdeFailures, MaxStepsIsABudgetPerPhase) {
  const Scene scene = LoadScene(ReferenceDataDir() + "/scenes/hard/c1_law.yaml");
  for (const char* stabilization : {"none", "projection"}) {
    FormulationOptions o;
    o.integrator = IntegratorKind::kRk4;
    o.step = 1.0e-4;
    o.stabilization = ParsedOptionValue<Stabilization>(stabilization);
    o.max_steps = 2100;
    RunSettings settings;
    settings.formulation = "ede";
    settings.options = o;
    const RunResult short_budget = RunScene(scene, settings);
    ASSERT_FALSE(short_budget.completed) << stabilization;
    EXPECT_NE(short_budget.failure.find("more than --max-steps = 2100 steps in this phase"), std::string::npos)
        << stabilization << ": " << short_budget.failure;
    ASSERT_FALSE(short_budget.samples.empty());
    // The last row written is the output time before the budget ran out (0.21 s).
    EXPECT_NEAR(short_budget.samples.back().t, 0.21, 1.0e-9) << stabilization;
    settings.options.max_steps = 2200;
    const RunResult enough = RunScene(scene, settings);
    EXPECT_TRUE(enough.completed) << stabilization << ": " << enough.failure;
  }
}

}  // namespace
}  // namespace kneedyn
