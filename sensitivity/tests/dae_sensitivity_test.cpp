// IDAS sensitivities of the DAE forms (sensitivity/dae_sensitivity.cpp) on the chapter scene:
// the published ligament law gives 18+ kink restarts and the lateral lift-off on the way to
// 90°, so the jump s_x⁺ = s_x⁻ + (f⁻ − f⁺) dτ/dp, the re-solved algebraic sensitivities and
// the event-time derivatives feed every outcome checked here. Two independent references:
//  (1) central finite differences of the same DAE outcomes (runs without derivatives). What
//      they allow, as in forward_sensitivity_test.cpp: outcomes at rtol 1e-10 carry ~1e-9
//      relative integration noise, so a relative step of 1e-4 (1e-3 for the pulse
//      amplitude, whose effect is small) leaves ~1e-5 … 1e-4 noise plus truncation ~1e-8
//      … 3e-4 (the extension ratio's strong curvature): |d − fd| ≤ 1e-3 |fd| + 1e-4 |y/p|.
//      atol is 1e-12, not 1e-14: `kneedyn run --formulation dae` itself stops at 1e-14
//      (IDA_CONV_FAIL at t = 0.11 s), with or without sensitivities.
//  (2) the CVODES derivatives of ede, a second formulation of the same physics (the ODE on
//      y = (q, q̇), its own integrator and event handling). Measured at rtol 1e-10 over 5
//      parameters × 7 outcomes: ≤ 3.8e-6 relative for all four DAE forms; allowed here:
//      |d − d_ede| ≤ 5e-5 |d_ede| + 1e-6 |y/p| (the floor in normalised units, for the small
//      pulse-amplitude derivatives).
// With the jump removed (s_x⁺ = s_x⁻ at every restart) three of these tests fail, 66 checks
// (lift-off time and angle, 90° values, peaks, the trajectory rows at 0.15 s and 0.25 s; the
// peak PCL force per extension ratio falls from 2351 N to 947 N).
#include <gtest/gtest.h>

#include <cmath>

#include "formulations/run.hpp"
#include "sensitivity/forward_sensitivity.hpp"
#include "sensitivity/sensitivity_cli.hpp"
#include "sensitivity/tests/sensitivity_test_support.hpp"
#include "solver/error.hpp"

namespace kneedyn::sensitivity {
namespace {

using test_support::Chapter;
using test_support::Nominal;
using test_support::RunCentralDifference;

SensitivityOptions Tight(const std::string& formulation) {
  SensitivityOptions options;
  options.formulation = formulation;
  options.rtol = 1e-10;
  options.atol = 1e-12;
  return options;
}

// Reference (2): d against ede's d_ede for outcome value y and parameter value p.
void ExpectAgreesWithEde(double d, double d_ede, double y, double p, const std::string& what) {
  EXPECT_LE(std::abs(d - d_ede), 5e-5 * std::abs(d_ede) + 1e-6 * std::abs(y / p))
      << what << ": IDAS " << d << ", CVODES/ede " << d_ede;
}

TEST(DaeSensitivity, AgreesWithCentralDifferencesAndWithEde) {
  const Scene scene = Chapter();
  // A stiffness, an extension (slack) ratio, the pulse amplitude.
  const auto params = ResolveParameters(scene, {"PCL_anterior.k_linear", "PCL_anterior.extension_ratio", "pulse.amplitude"});
  // Event-time derivatives (lateral lift-off time and angle), values at 90°, two peaks.
  const auto outcomes = ResolveOutcomes(scene, {"liftoff_time_lateral_s", "liftoff_flexion_lateral_deg", "N90_medial_N",
                                                "F90_PCL_anterior_N", "peak_F_PCL_anterior_N", "peak_N_medial_N"});
  const std::vector<double> p = Nominal(params);
  const SensitivityResult r = RunSensitivity(scene, params, p, outcomes, Tight("dae"));
  ASSERT_EQ(r.end_reason, "flexion_90");
  // Consistent initial sensitivities at every phase start: |F_y s + F_ẏ ṡ + F_p| relative to
  // its terms (measured 6e-10).
  EXPECT_LT(r.initial_sensitivity_residual, 1e-7);
  EXPECT_GE(r.stats.restarts, 12);  // the 11 kink crossings, one restart each, and the lift-off
  const SensitivityResult ede = RunSensitivity(scene, params, p, outcomes, Tight("ede"));
  const double steps[] = {1e-4, 1e-4, 1e-3};
  for (size_t j = 0; j < params.size(); ++j) {
    const auto fd = CentralDifferences(scene, {params[j]}, {p[j]}, outcomes, Tight("dae"), steps[j]);
    for (size_t k = 0; k < outcomes.size(); ++k) {
      const std::string what = outcomes[k] + " / " + params[j].name;
      const double d = r.derivatives[k][j], f = fd[k][0];
      ASSERT_TRUE(std::isfinite(d)) << what;
      EXPECT_NE(d, 0.0) << what;
      EXPECT_LE(std::abs(d - f), 1e-3 * std::abs(f) + 1e-4 * std::abs(r.values[k] / p[j]))
          << what << ": derivative " << d << ", central difference " << f;
      ExpectAgreesWithEde(d, ede.derivatives[k][j], r.values[k], p[j], what);
    }
  }
}

// Trajectory sensitivities at fixed output times: 0.15 s (both contacts, after the early
// kinks) and 0.25 s (after the PCL kinks and the lateral lift-off).
TEST(DaeSensitivity, TrajectoryDerivativesAtFixedTimes) {
  const Scene scene = Chapter();
  const auto params = ResolveParameters(scene, {"pulse.amplitude", "PCL_anterior.extension_ratio"});
  const auto outcomes = ResolveOutcomes(scene, {"time_90_s"});
  SensitivityOptions options = Tight("dae");
  options.output_interval = 0.05;
  const std::vector<double> p = Nominal(params);
  const SensitivityResult r = RunSensitivity(scene, params, p, outcomes, options);
  ASSERT_EQ(r.trajectory.size(), 6u);  // t = 0, 0.05, ..., 0.25 (90° at 0.299 s)
  SensitivityOptions ede_options = options;
  ede_options.formulation = "ede";
  const SensitivityResult ede = RunSensitivity(scene, params, p, outcomes, ede_options);
  ASSERT_EQ(ede.trajectory.size(), 6u);
  for (size_t j = 0; j < params.size(); ++j) {
    const auto [h, a, b] = RunCentralDifference(scene, params, p, j, outcomes, options);
    for (size_t n : {3u, 5u}) {
      ASSERT_NEAR(a.trajectory[n].t, r.trajectory[n].t, 1e-15);
      ASSERT_NEAR(ede.trajectory[n].t, r.trajectory[n].t, 1e-15);
      for (int i : {kY0, kAlpha}) {
        const std::string what = params[j].name + " t = " + std::to_string(r.trajectory[n].t) + " coordinate " +
                                 std::to_string(i);
        const double fd = (a.trajectory[n].q(i) - b.trajectory[n].q(i)) / (2 * h);
        const double d = r.trajectory[n].dq[j](i);
        EXPECT_LE(std::abs(d - fd), 1e-3 * std::abs(fd) + 1e-4 * std::abs(r.trajectory[n].q(i) / p[j]))
            << what << ": " << d << " vs " << fd;
        ExpectAgreesWithEde(d, ede.trajectory[n].dq[j](i), r.trajectory[n].q(i), p[j], what);
      }
    }
  }
}

// The outcome values are those of `kneedyn run --formulation dae` (the same phases, states,
// tolerances and root functions): event times and the 90° contact force.
TEST(DaeSensitivity, OutcomesMatchTheRunDriver) {
  const Scene scene = Chapter();
  const auto params = ResolveParameters(scene, {"mass"});
  const auto outcomes =
      ResolveOutcomes(scene, {"liftoff_time_lateral_s", "liftoff_flexion_lateral_deg", "time_90_s", "N90_medial_N"});
  SensitivityOptions options = Tight("dae");
  options.derivatives = false;
  const SensitivityResult r = RunSensitivity(scene, params, Nominal(params), outcomes, options);
  RunSettings settings;
  settings.formulation = "dae";
  settings.options.rtol = options.rtol;
  settings.options.atol = options.atol;
  const RunResult run = RunScene(scene, settings);
  ASSERT_TRUE(run.completed) << run.failure;
  const EventRecord* liftoff = nullptr;
  for (const EventRecord& e : run.events) {
    if (!liftoff && e.name == "liftoff_lateral") liftoff = &e;
  }
  ASSERT_NE(liftoff, nullptr);
  ASSERT_EQ(run.events.back().name, "flexion_90");
  EXPECT_NEAR(r.values[0], liftoff->time, 1e-9);
  EXPECT_NEAR(r.values[1], liftoff->flexion * 180.0 / M_PI, 1e-6);
  EXPECT_NEAR(r.values[2], run.events.back().time, 1e-9);
  const int medial = scene.model.ContactIndex(Compartment::kMedial);
  EXPECT_NEAR(r.values[3], run.samples.back().contact[medial].normal_force, 1e-6);
  EXPECT_TRUE(std::isnan(r.derivatives[0][0]));  // without derivatives nothing is claimed
}

// The closed-form contact and the GGL forms share the driver: a stiffness-free pair of
// parameters (pulse amplitude, a slack length) on an angle, a 90° force and a peak.
TEST(DaeSensitivity, OtherDaeFormsAgreeWithEde) {
  const Scene scene = Chapter();
  const auto params = ResolveParameters(scene, {"pulse.amplitude", "MCL_deep.slack_length"});
  const auto outcomes = ResolveOutcomes(scene, {"liftoff_flexion_lateral_deg", "N90_medial_N", "peak_F_PCL_anterior_N"});
  const std::vector<double> p = Nominal(params);
  const SensitivityResult ede = RunSensitivity(scene, params, p, outcomes, Tight("ede"));
  for (const char* form : {"dae-reduced", "dae-ggl", "dae-ggl-reduced"}) {
    const SensitivityResult r = RunSensitivity(scene, params, p, outcomes, Tight(form));
    ASSERT_EQ(r.end_reason, "flexion_90") << form;
    EXPECT_LT(r.initial_sensitivity_residual, 1e-7) << form;
    for (size_t k = 0; k < outcomes.size(); ++k) {
      for (size_t j = 0; j < params.size(); ++j) {
        ExpectAgreesWithEde(r.derivatives[k][j], ede.derivatives[k][j], r.values[k], p[j],
                            std::string(form) + " " + outcomes[k] + " / " + params[j].name);
      }
    }
  }
}

// A scene with a patella (its equilibrium solved inside every right-hand side): ede's
// sensitivities on patellofemoral_extension stalled at t = 0.3283 s (CVODES steps of 1e-17 s;
// the patella was solved from the scene's start pose at every call, and the difference
// quotients' two sides stopped agreeing). With the equilibrium warm-started they complete and
// agree with IDAS on the peak medial force, for a body and a load parameter (a patella
// geometry parameter agrees too, but its scene is rebuilt for each difference quotient:
// 80 s at this tolerance, docs/outputs.md).
TEST(DaeSensitivity, EdeAgreesWithDaeOnTheExtensionSceneWithItsPatella) {
  const Scene scene =
      LoadScene(std::string(KNEEDYN_SOURCE_DIR) + "/reference-data/scenes/patellofemoral_extension.yaml");
  const auto params = ResolveParameters(scene, {"mass", "quadriceps.magnitude"});
  const auto outcomes = ResolveOutcomes(scene, {"peak_N_medial_N"});
  const std::vector<double> p = Nominal(params);
  SensitivityOptions ede_options = Tight("ede");
  ede_options.max_steps = 20000;  // the stall took 200,000 steps of ~5 ms: fail in seconds instead
  const SensitivityResult ede = RunSensitivity(scene, params, p, outcomes, ede_options);
  const SensitivityResult dae = RunSensitivity(scene, params, p, outcomes, Tight("dae"));
  ASSERT_EQ(ede.end_reason, "end_time");
  ASSERT_EQ(dae.end_reason, "end_time");
  for (size_t j = 0; j < params.size(); ++j) {
    ExpectAgreesWithEde(dae.derivatives[0][j], ede.derivatives[0][j], dae.values[0], p[j],
                        outcomes[0] + " / " + params[j].name);
  }
}

TEST(DaeSensitivity, RefusesImpacts) {
  const Scene scene = LoadScene(std::string(KNEEDYN_SOURCE_DIR) + "/reference-data/scenes/hard/lateral_pulse_recontact.yaml");
  const auto params = ResolveParameters(scene, {"pulse.amplitude"});
  const auto outcomes = ResolveOutcomes(scene, {"time_90_s"});
  try {
    RunSensitivity(scene, params, Nominal(params), outcomes, Tight("dae"));
    FAIL() << "a run with a re-contact must be refused";
  } catch (const SolverError& e) {
    EXPECT_NE(std::string(e.what()).find("impact"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("recontact_"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace kneedyn::sensitivity
