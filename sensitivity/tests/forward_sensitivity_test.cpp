// Forward sensitivities (sensitivity/forward_sensitivity.hpp) against central finite
// differences of the same outcomes, on the chapter scene (published ligament law: the run
// crosses 11 kinks and one lift-off, so the jump relation s⁺ = s⁻ + (f⁻ − f⁺) dτ/dp and
// the event-time derivatives are exercised on the way to every outcome).
//
// What finite differences allow: outcomes at rtol 1e-10 carry an error of order
// 1e-10 |y| (more after 13 phases), so a central difference with relative step h = 1e-4
// (1e-3 for the pulse amplitude) has noise ~1e-6 |y|/(h p) · a few and truncation
// ~h² ≈ 1e-8 relative. The rule below
// accepts |d − fd| ≤ 1e-3 |fd| + 1e-4 |y/p|, i.e. relative 1e-3, or 1e-4 in the normalised
// sensitivity (p/y) dy/dp where the derivative is small (pulse amplitude on the peak PCL
// force: normalised −0.007). Measured: relative 3e-7 … 9e-4 for these nine pairs
// (`kneedyn sensitivity ... --fd-step`, docs/outputs.md).
// Not validated here: IDAS/DAE sensitivities (dae_sensitivity_test.cpp); impacts (refused).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "formulations/run.hpp"
#include "sensitivity/forward_sensitivity.hpp"
#include "sensitivity/sensitivity_cli.hpp"
#include "sensitivity/sensitivity_problem.hpp"
#include "sensitivity/tests/sensitivity_test_support.hpp"
#include "solver/error.hpp"

namespace kneedyn::sensitivity {
namespace {

using test_support::Chapter;
using test_support::Nominal;
using test_support::RunCentralDifference;

TEST(ForwardSensitivity, AgreesWithCentralDifferencesOnTheChapterScene) {
  const Scene scene = Chapter();
  // A ligament stiffness, an extension (slack) ratio, the pulse amplitude.
  const auto params = ResolveParameters(scene, {"PCL_anterior.k_linear", "PCL_anterior.extension_ratio", "pulse.amplitude"});
  const auto outcomes = ResolveOutcomes(scene, {"liftoff_time_s", "N90_medial_N", "peak_F_PCL_anterior_N"});
  SensitivityOptions options;
  options.rtol = 1e-10;
  options.atol = 1e-14;
  const std::vector<double> p = Nominal(params);
  const SensitivityResult r = RunSensitivity(scene, params, p, outcomes, options);
  ASSERT_EQ(r.end_reason, "flexion_90");
  // Relative steps per parameter: 1e-4, except 1e-3 for the pulse amplitude, whose effect
  // is small (normalised −0.007 on the peak PCL force) and at 1e-4 is buried in the
  // outcomes' integration noise (its central difference moved by 1 % when only the
  // output times changed).
  const double steps[] = {1e-4, 1e-4, 1e-3};
  for (size_t j = 0; j < params.size(); ++j) {
    const auto fd = CentralDifferences(scene, {params[j]}, {p[j]}, outcomes, options, steps[j]);
    for (size_t k = 0; k < outcomes.size(); ++k) {
      const double d = r.derivatives[k][j], f = fd[k][0];
      ASSERT_TRUE(std::isfinite(d)) << outcomes[k] << " / " << params[j].name;
      EXPECT_NE(d, 0.0) << outcomes[k] << " / " << params[j].name;
      EXPECT_LE(std::abs(d - f), 1e-3 * std::abs(f) + 1e-4 * std::abs(r.values[k] / p[j]))
          << outcomes[k] << " / " << params[j].name << ": derivative " << d << ", central difference " << f;
    }
  }
}

// The forward run itself against the run driver (an independent integration: ede with
// CVODE through formulations/, with the driver's projections at mode switches).
TEST(ForwardSensitivity, OutcomesMatchTheRunDriver) {
  const Scene scene = Chapter();
  const auto params = ResolveParameters(scene, {"pulse.amplitude"});
  const auto outcomes = ResolveOutcomes(
      scene, {"liftoff_time_s", "liftoff_flexion_deg", "time_90_s", "liftoff_time_lateral_s", "liftoff_time_medial_s"});
  SensitivityOptions options;
  options.rtol = 1e-10;
  options.atol = 1e-12;
  options.derivatives = false;
  const SensitivityResult r = RunSensitivity(scene, params, Nominal(params), outcomes, options);
  RunSettings settings;
  settings.formulation = "ede";
  settings.options.integrator = IntegratorKind::kCvodeBdf;
  settings.options.rtol = 1e-10;
  settings.options.atol = 1e-12;
  const RunResult run = RunScene(scene, settings);
  ASSERT_TRUE(run.completed) << run.failure;
  ASSERT_EQ(run.events.size(), 2u);
  EXPECT_EQ(run.events[0].name, "liftoff_lateral");
  EXPECT_NEAR(r.values[0], run.events[0].time, 1e-7);
  EXPECT_NEAR(r.values[1], run.events[0].flexion * 180.0 / M_PI, 1e-5);
  EXPECT_NEAR(r.values[2], run.events[1].time, 1e-7);
  EXPECT_EQ(r.values[3], r.values[0]);      // the lateral compartment lifts off first
  EXPECT_TRUE(std::isnan(r.values[4]));     // the medial one stays in contact to 90°
  // Without derivatives nothing is claimed.
  EXPECT_TRUE(std::isnan(r.derivatives[0][0]));
}

// dτ/dp of the end event is what the kink and lift-off jumps feed: a slack length
// (mm) against central differences, with the mass, on time_90 and the 90° PCL force.
TEST(ForwardSensitivity, SlackLengthAndMassOnNinetyDegreeValues) {
  const Scene scene = Chapter();
  const auto params = ResolveParameters(scene, {"MCL deep.slack_length", "mass"});
  const auto outcomes = ResolveOutcomes(scene, {"time_90_s", "F90_PCL_anterior_N"});
  SensitivityOptions options;
  options.rtol = 1e-10;
  options.atol = 1e-14;
  const std::vector<double> p = Nominal(params);
  const SensitivityResult r = RunSensitivity(scene, params, p, outcomes, options);
  const auto fd = CentralDifferences(scene, params, p, outcomes, options, 1e-4);
  for (size_t k = 0; k < outcomes.size(); ++k) {
    for (size_t j = 0; j < params.size(); ++j) {
      EXPECT_LE(std::abs(r.derivatives[k][j] - fd[k][j]), 1e-3 * std::abs(fd[k][j]) + 1e-4 * std::abs(r.values[k] / p[j]))
          << outcomes[k] << " / " << params[j].name;
    }
  }
}

// The trajectory derivatives of y0 and alpha of `r` at the samples `rows`, against central
// differences of the same samples in each parameter (the rule at the top of this file).
void ExpectTrajectoryDerivativesAgree(const Scene& scene, const std::vector<ensembles::ParameterSpec>& params,
                                      const std::vector<double>& p, const std::vector<std::string>& outcomes,
                                      const SensitivityOptions& options, const SensitivityResult& r,
                                      const std::vector<size_t>& rows) {
  for (size_t j = 0; j < params.size(); ++j) {
    const auto [h, a, b] = RunCentralDifference(scene, params, p, j, outcomes, options);
    for (size_t n : rows) {
      ASSERT_NEAR(a.trajectory[n].t, r.trajectory[n].t, 1e-15);
      for (int i : {kY0, kAlpha}) {
        const double fd = (a.trajectory[n].q(i) - b.trajectory[n].q(i)) / (2 * h);
        const double d = r.trajectory[n].dq[j](i);
        EXPECT_LE(std::abs(d - fd), 1e-3 * std::abs(fd) + 1e-4 * std::abs(r.trajectory[n].q(i) / p[j]))
            << params[j].name << " t = " << r.trajectory[n].t << " coordinate " << i << ": " << d << " vs " << fd;
      }
    }
  }
}

SensitivityOptions TightTrajectoryOptions() {
  SensitivityOptions options;
  options.rtol = 1e-10;
  options.atol = 1e-14;
  options.output_interval = 0.05;
  return options;
}

// Trajectory sensitivities at fixed output times (before and after the lift-off and the
// PCL kinks) against central differences of the same samples.
TEST(ForwardSensitivity, TrajectoryDerivativesAgreeWithCentralDifferences) {
  const Scene scene = Chapter();
  const auto params = ResolveParameters(scene, {"pulse.amplitude", "PCL_anterior.extension_ratio"});
  const auto outcomes = ResolveOutcomes(scene, {"time_90_s"});
  const SensitivityOptions options = TightTrajectoryOptions();
  const std::vector<double> p = Nominal(params);
  const SensitivityResult r = RunSensitivity(scene, params, p, outcomes, options);
  ASSERT_EQ(r.trajectory.size(), 6u);  // t = 0, 0.05, ..., 0.25 (90° at 0.299 s)
  // 0.15 s (both contacts), 0.25 s (after lift-off, kinks)
  ExpectTrajectoryDerivativesAgree(scene, params, p, outcomes, options, r, {3u, 5u});
}

// A phase with no root function (no contact, no end angle reached, no peak outcome): CVODES
// refused the root directions ("Rootfinding was not initialized", exit 1) where `kneedyn run`
// and the DAE forms complete. The run completes and its trajectory derivatives agree with
// central differences (the rule of TrajectoryDerivativesAgreeWithCentralDifferences).
TEST(ForwardSensitivity, APhaseWithoutRootFunctionsCompletes) {
  const std::string text =
      "name: no_roots\n"
      "parameter_set: " + std::string(KNEEDYN_SOURCE_DIR) + "/reference-data/chapter_knee.yaml\n"
      "ligaments: all\nligament_law: c1_continuous\ncontacts: []\ngravity: {enabled: true}\n"
      "pulse: {shape: none}\ninitial_state: {pose: reference}\nend: {time_s: 0.2}\noutput: {interval_s: 0.05}\n";
  const Scene scene = ParseScene(text, "no_roots.yaml", ".");
  const auto params = ResolveParameters(scene, {"mass"});
  const auto outcomes = ResolveOutcomes(scene, {"time_90_s"});
  const SensitivityOptions options = TightTrajectoryOptions();
  const std::vector<double> p = Nominal(params);
  const SensitivityResult r = RunSensitivity(scene, params, p, outcomes, options);
  EXPECT_EQ(r.end_reason, "end_time");
  EXPECT_TRUE(std::isnan(r.values[0]));  // 90 degrees is not reached
  ASSERT_EQ(r.trajectory.size(), 4u);    // t = 0, 0.05, 0.1, 0.15
  ExpectTrajectoryDerivativesAgree(scene, params, p, outcomes, options, r, {3u});
}

TEST(ForwardSensitivity, RefusesImpacts) {
  const Scene scene = LoadScene(std::string(KNEEDYN_SOURCE_DIR) + "/reference-data/scenes/hard/lateral_pulse_recontact.yaml");
  const auto params = ResolveParameters(scene, {"pulse.amplitude"});
  const auto outcomes = ResolveOutcomes(scene, {"time_90_s"});
  try {
    RunSensitivity(scene, params, Nominal(params), outcomes, SensitivityOptions());
    FAIL() << "a run with a re-contact must be refused";
  } catch (const SolverError& e) {
    EXPECT_NE(std::string(e.what()).find("impact"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("recontact_"), std::string::npos) << e.what();
  }
}

TEST(ForwardSensitivity, UnknownNamesNameTheNearestValidOne) {
  const Scene scene = Chapter();
  try {
    ResolveParameters(scene, {"pulse.amplitude", "PCL_anterir.k_linear"});
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("--parameters"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("'PCL_anterior.k_linear'"), std::string::npos) << e.what();
  }
  try {
    ResolveOutcomes(scene, {"peak_F_PCL_anterio_N"});
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("'peak_F_PCL_anterior_N'"), std::string::npos) << e.what();
  }
  EXPECT_THROW(ResolveParameters(scene, {"mass", "mass"}), InputError);
  // Groups expand to the sweep's columns.
  EXPECT_EQ(ResolveOutcomes(scene, {"contact_force_at_90"}), (std::vector<std::string>{"N90_medial_N", "N90_lateral_N"}));
  // A formulation without sensitivities: the message names the field, the value and the
  // forms that have them.
  SensitivityOptions bad;
  bad.formulation = "newmark";
  std::string why;
  EXPECT_FALSE(bad.IsValid(&why));
  EXPECT_NE(why.find("--formulation = 'newmark'"), std::string::npos) << why;
  EXPECT_NE(why.find("dae-reduced"), std::string::npos) << why;
  for (const std::string& ok : SensitivityFormulations()) {
    SensitivityOptions good;
    good.formulation = ok;
    EXPECT_TRUE(good.IsValid(&why)) << ok << ": " << why;
  }
}

// An element whose name has a '-' is named as trajectory.csv and the sweep name it (its
// '-' as '_', docs/outputs.md) in parameters and outcomes alike. Before, the sweep's outcome
// column peak_F_MCL_deep_N was "not known" to the sensitivity, which kept the '-'.
TEST(ForwardSensitivity, ElementNamesWithADashAreSpeltAsTheColumns) {
  Scene scene = Chapter();
  int renamed = -1;
  for (size_t j = 0; j < scene.model.ligaments.size(); ++j) {
    if (scene.model.ligaments[j].name == "MCL deep") scene.model.ligaments[j].name = "MCL-deep", renamed = static_cast<int>(j);
  }
  ASSERT_GE(renamed, 0);
  const detail::Outcome o = detail::ParseOutcome(scene.model, "peak_F_MCL_deep_N");
  EXPECT_EQ(o.kind, detail::OutcomeKind::kPeakLigament);
  EXPECT_EQ(o.index, renamed);
  const std::vector<std::string> names = ParameterNames(scene);
  EXPECT_NE(std::find(names.begin(), names.end(), "MCL_deep.k_linear"), names.end());
  EXPECT_EQ(ResolveParameters(scene, {"MCL_deep.k_linear"}).size(), 1u);
  EXPECT_EQ(ResolveParameters(scene, {"MCL-deep.k_linear"}).size(), 1u);
}

// A scene without a tibial pulse (shape none) has no pulse parameters: listed names leave
// them out, and asking for one is refused rather than differentiated to 0.
TEST(ForwardSensitivity, PulseParametersNeedAPulse) {
  const Scene none = LoadScene(std::string(KNEEDYN_SOURCE_DIR) + "/reference-data/scenes/gravity_only.yaml");
  ASSERT_EQ(none.model.pulse.shape, PulseShape::kNone);
  for (const char* name : {"pulse.amplitude", "pulse.duration"}) {
    const std::vector<std::string> names = ParameterNames(none);
    EXPECT_EQ(std::count(names.begin(), names.end(), name), 0) << name;
    const std::vector<std::string> chapter_names = ParameterNames(Chapter());
    EXPECT_EQ(std::count(chapter_names.begin(), chapter_names.end(), name), 1) << name;
    try {
      ResolveParameters(none, {name});
      ADD_FAILURE() << name << " accepted on a scene without a pulse";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find("no tibial pulse (pulse.shape none)"), std::string::npos) << e.what();
    }
  }
}

TEST(ForwardSensitivity, EditDistance) {
  EXPECT_EQ(EditDistance("kitten", "sitting"), 3);
  EXPECT_EQ(EditDistance("", "abc"), 3);
  EXPECT_EQ(EditDistance("mass", "mass"), 0);
}

// --max-steps bounds the steps of a phase over all its output intervals, as in `kneedyn
// run` (CVODES' and IDAS' own limits count per call). c1_law (no ligament kinks) cut at
// 0.2 s, before its lift-off, is one phase of 40 output intervals: a budget of exactly the
// steps it took completes, one step less stops naming the budget. On the old per-call
// budget both completed.
TEST(ForwardSensitivity, MaxStepsIsABudgetPerPhase) {
  Scene scene = LoadScene(std::string(KNEEDYN_SOURCE_DIR) + "/reference-data/scenes/hard/c1_law.yaml");
  scene.end.time = 0.2;  // s
  scene.end.flexion.reset();
  const auto params = ResolveParameters(scene, {"mass"});
  const auto outcomes = ResolveOutcomes(scene, {"peak_F_PCL_anterior_N"});
  for (const std::string& formulation : SensitivityFormulations()) {
    SensitivityOptions options;
    options.formulation = formulation;
    const SensitivityResult full = RunSensitivity(scene, params, Nominal(params), outcomes, options);
    ASSERT_EQ(full.end_reason, "end_time") << formulation;
    ASSERT_EQ(full.stats.restarts, 1) << formulation << ": the run must be one phase";
    ASSERT_GT(full.trajectory.size(), 20u) << formulation;
    options.max_steps = full.stats.steps;
    EXPECT_EQ(RunSensitivity(scene, params, Nominal(params), outcomes, options).stats.steps, full.stats.steps)
        << formulation;
    options.max_steps = full.stats.steps - 1;
    try {
      RunSensitivity(scene, params, Nominal(params), outcomes, options);
      ADD_FAILURE() << formulation << ": a budget one step short must stop the run";
    } catch (const SolverError& e) {
      EXPECT_NE(std::string(e.what()).find(StrCat("more than --max-steps = ", options.max_steps, " steps in this phase")),
                std::string::npos) << formulation << ": " << e.what();
    }
  }
}

}  // namespace
}  // namespace kneedyn::sensitivity
