// Every registered formulation on reference-data/scenes/anatomical_surfaces.yaml
// (ellipsoidal condyles on a concave medial and a convex lateral polynomial plateau):
// the general contact kernel in every formulation.
//
// Validates: each formulation completes the scene, finds the same events in the same order,
// and agrees with `dae` at rtol 1e-10 (computed once) on every event time — adaptive
// formulations at rtol 1e-10, atol 1e-12 to 7 significant digits (|Δt| ≤ 1e-7 t);
// fixed-step formulations (second order, h = 1e-4 s) to |Δt| ≤ 2e-6 s (measured 4e-7 s; 7
// digits need h ≈ 2.5e-5 s, ~10 s per run, too long for the default suite).
// Independent: the formulations share only the kernel, not their contact equations (chapter
// coordinates in dae/newmark, the gap in the reduced forms, elimination in mde, the hidden
// constraint in ede). Does not validate: the surfaces' anatomical realism.
#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <string>

#include "formulations/run.hpp"
#include "tests/test_support.hpp"

namespace kneedyn {
namespace {

const Scene& AnatomicalScene() {
  static const Scene scene = LoadScene(test_support::ScenesDir() + "/anatomical_surfaces.yaml");
  return scene;
}

RunSettings TightSettings(const std::string& name) {
  RunSettings s;
  s.formulation = name;
  if (IsFixedStep(FindFormulation(name), "")) {
    s.options.step = kDefaultFixedStep;
  } else {
    s.options.rtol = 1e-10;
    s.options.atol = 1e-12;
  }
  return s;
}

const RunResult& Reference() {
  static const RunResult r = RunScene(AnatomicalScene(), TightSettings("dae"));
  return r;
}

class AnatomicalSurfaces : public ::testing::TestWithParam<std::string> {};

TEST_P(AnatomicalSurfaces, CompletesWithTheReferenceEventTimes) {
  const std::string name = GetParam();
  const RunResult& ref = Reference();
  ASSERT_TRUE(ref.completed) << ref.failure;
  ASSERT_FALSE(ref.events.empty());
  const RunResult r = RunScene(AnatomicalScene(), TightSettings(name));
  ASSERT_TRUE(r.completed) << name << ": " << r.failure;
  ASSERT_EQ(r.events.size(), ref.events.size()) << name;
  const bool fixed = IsFixedStep(FindFormulation(name), "");
  for (size_t i = 0; i < ref.events.size(); ++i) {
    EXPECT_EQ(r.events[i].name, ref.events[i].name) << name;
    const double tol = fixed ? 2e-6 : 1e-7 * ref.events[i].time;
    EXPECT_NEAR(r.events[i].time, ref.events[i].time, tol) << name << " " << ref.events[i].name;
  }
}

INSTANTIATE_TEST_SUITE_P(Registered, AnatomicalSurfaces,
                         ::testing::ValuesIn(test_support::RegisteredFormulationNames()),
                         test_support::FormulationParamName());

}  // namespace
}  // namespace kneedyn
