// Conformance of every registered formulation (one interface,
// formulations/formulation.hpp): one
// parameterized suite over RegisteredFormulations(), so a formulation added to
// registry.cpp is tested here without editing this file.
//
// Validates, on the chapter scene: a consistent start (gaps and approach rates ≈ 0 in the
// first sample); the run completes with liftoff_lateral then flexion_90, in time order;
// agreement with `dae` at rtol 1e-10 (the reference, computed once) on the 90° time
// (1e-3 s) and the lift-off angle (0.5°) — conformance-level tolerances; bounded
// constraint drift (max |φ| < 1e-6 m); nonzero statistics.
// Does not validate: accuracy orders or efficiency (benchmarks, reports).
#include <gtest/gtest.h>

#include <cctype>
#include <cmath>
#include <cstdio>
#include <map>
#include <string>
#include <vector>

#include "formulations/run.hpp"
#include "scene/scene.hpp"
#include "solver/units.hpp"
#include "tests/test_support.hpp"

namespace kneedyn {
namespace {

using test_support::ChapterScene;

std::string EventList(const RunResult& r) {
  std::string s;
  for (const EventRecord& e : r.events) {
    s += e.name + " t=" + std::to_string(e.time) + " s, " + std::to_string(RadToDeg(e.flexion)) + " deg; ";
  }
  return s;
}


// Default settings that make sense for each kind of formulation.
RunSettings SettingsFor(const std::string& name) {
  RunSettings settings;
  settings.formulation = name;
  const FormulationInfo& info = FindFormulation(name);
  if (IsFixedStep(info, "")) {
    settings.options.step = kDefaultFixedStep;
  } else if (!info.algebraic_forces) {
    settings.options.rtol = 1e-8;  // ODE formulations, default (adaptive) integrator
  } else {
    settings.options.rtol = 1e-8;
    settings.options.atol = 1e-10;
  }
  return settings;
}

const RunResult& Reference() {
  static const RunResult r = [] {
    RunSettings settings;
    settings.formulation = "dae";
    settings.options.rtol = 1e-10;
    settings.options.atol = 1e-12;
    return RunScene(ChapterScene(), settings);
  }();
  return r;
}

const EventRecord* FindEvent(const RunResult& r, const std::string& name) {
  for (const EventRecord& e : r.events) {
    if (e.name == name) return &e;
  }
  return nullptr;
}

class Conformance : public ::testing::TestWithParam<std::string> {
 protected:
  // One run per formulation, shared by its tests.
  static const RunResult& Run(const std::string& name) {
    static std::map<std::string, RunResult> cache;
    auto it = cache.find(name);
    if (it == cache.end()) it = cache.emplace(name, RunScene(ChapterScene(), SettingsFor(name))).first;
    return it->second;
  }
};

TEST_P(Conformance, StartsConsistent) {
  const RunResult& r = Run(GetParam());
  ASSERT_FALSE(r.samples.empty()) << r.failure;
  const MechanicalState& s0 = r.samples.front();
  EXPECT_EQ(s0.t, 0.0);
  EXPECT_EQ(s0.active, (std::vector<int>{0, 1}));
  std::vector<double> gap, rate;
  ConstraintResiduals(ChapterScene().model, s0, &gap, &rate);
  for (int c : s0.active) {
    EXPECT_NEAR(gap[c], 0.0, 1e-10) << "gap of contact " << c << " (m)";
    EXPECT_NEAR(rate[c], 0.0, 1e-10) << "approach rate of contact " << c << " (m/s)";
    EXPECT_GT(s0.contact[c].normal_force, 0.0);
  }
}

TEST_P(Conformance, CompletesChapterSceneWithLateralLiftoffThenNinetyDegrees) {
  const RunResult& r = Run(GetParam());
  ASSERT_TRUE(r.completed) << r.failure;
  EXPECT_EQ(r.end_reason, "flexion_90");
  ASSERT_GE(r.events.size(), 2u);
  EXPECT_EQ(r.events.front().name, "liftoff_lateral") << EventList(r);
  EXPECT_EQ(r.events.back().name, "flexion_90") << EventList(r);
  for (size_t i = 1; i < r.events.size(); ++i) {
    EXPECT_LE(r.events[i - 1].time, r.events[i].time) << r.events[i].name;
  }
  for (size_t i = 1; i < r.samples.size(); ++i) {
    EXPECT_LT(r.samples[i - 1].t, r.samples[i].t) << "sample " << i;
  }
}

TEST_P(Conformance, AgreesWithReferenceDaeOnEventTimesAndAngles) {
  const RunResult& ref = Reference();
  ASSERT_TRUE(ref.completed) << ref.failure;
  const RunResult& r = Run(GetParam());
  ASSERT_TRUE(r.completed) << r.failure;
  const EventRecord* end_ref = FindEvent(ref, "flexion_90");
  const EventRecord* end = FindEvent(r, "flexion_90");
  const EventRecord* lift_ref = FindEvent(ref, "liftoff_lateral");
  const EventRecord* lift = FindEvent(r, "liftoff_lateral");
  ASSERT_TRUE(end_ref && lift_ref);
  ASSERT_TRUE(end && lift);
  std::printf("%s: 90 deg at %.6f s (dae %.6f s), lift-off %.4f deg (dae %.4f deg), max |gap| %.2e m, "
              "steps %ld\n", GetParam().c_str(), end->time, end_ref->time, RadToDeg(lift->flexion),
              RadToDeg(lift_ref->flexion), r.max_position_residual, r.stats.steps);
  EXPECT_NEAR(end->time, end_ref->time, 1e-3);
  EXPECT_NEAR(RadToDeg(lift->flexion), RadToDeg(lift_ref->flexion), 0.5);
}

TEST_P(Conformance, KeepsConstraintDriftBoundedAndCountsWork) {
  const RunResult& r = Run(GetParam());
  ASSERT_TRUE(r.completed) << r.failure;
  EXPECT_LT(r.max_position_residual, 1e-6) << "m";
  EXPECT_GT(r.stats.steps, 0);
  EXPECT_GT(r.stats.residual_evaluations, 0);
  EXPECT_GE(r.stats.restarts, 2);  // the start and the lift-off phase
}


INSTANTIATE_TEST_SUITE_P(Registered, Conformance, ::testing::ValuesIn(test_support::RegisteredFormulationNames()),
                         test_support::FormulationParamName());

}  // namespace
}  // namespace kneedyn
