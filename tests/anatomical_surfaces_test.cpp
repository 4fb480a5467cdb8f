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
#include <fstream>
#include <iterator>
#include <map>
#include <string>

#include "formulations/run.hpp"
#include "formulations/run_output.hpp"
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

// A condyle flatter than its plateau (medial semi-axes 30, 40, 21 mm: radius 40²/21 = 76 mm in y
// on a 60 mm dish) touches it at more than one pair of points with aligned normals. The
// chapter form's consistent start (dae) sits on one whose nearest-point gap is 0.30 mm, the
// closed form's (ede) on the nearest: the two formulations start from different states (their
// initial normal forces differ), and the dae run says so in its warnings; the shipped scene,
// whose condyle fits its dish, gives no such warning. Before, the dae run said nothing.
TEST(AnatomicalSurfacesStart, NotAtTheNearestPointsIsWarned) {
  std::ifstream file(test_support::ScenesDir() + "/anatomical_surfaces.yaml");
  std::string text((std::istreambuf_iterator<char>(file)), std::istreambuf_iterator<char>());
  const auto replace = [&text](const std::string& from, const std::string& to) {
    const size_t at = text.find(from);
    ASSERT_NE(at, std::string::npos) << from;
    text.replace(at, from.size(), to);
  };
  replace("semi_axes_mm: [20.0, 24.0, 21.0]", "semi_axes_mm: [30.0, 40.0, 21.0]");
  replace("end: {flexion_deg: 60.0, time_s: 2.0}", "end: {time_s: 0.001}");
  const Scene flat = ParseScene(text, "flat_condyle.yaml", test_support::ScenesDir());
  const auto start_warnings = [](const Scene& scene, const RunResult& r) {
    int n = 0;
    for (const OutputWarning& w : OutputWarnings(MakeTrajectoryTable(scene, r), r)) {
      n += w.kind == "start_not_at_nearest_points";
    }
    return n;
  };
  const RunResult dae = RunScene(flat, TightSettings("dae"));
  const RunResult ede = RunScene(flat, TightSettings("ede"));
  ASSERT_FALSE(dae.init.normal_force.empty());
  ASSERT_FALSE(ede.init.normal_force.empty());
  EXPECT_GT(std::abs(dae.init.normal_force[0] - ede.init.normal_force[0]), 10.0) << "the two starts coincide";
  EXPECT_EQ(start_warnings(flat, dae), 1);
  EXPECT_EQ(start_warnings(flat, ede), 0);
  EXPECT_EQ(start_warnings(AnatomicalScene(), Reference()), 0);
}

// A contact phase that runs on for 8 degrees of flexion (gravity off, an 800 N half-sine along
// (1, -0.3, 0) in the tibial frame: both condyles in contact from 49.2 to 60.8 deg). mde's
// elimination starts its Newton iteration from the phase start; from the start's translations
// alone the first iterate at 57.6 deg fell 135 mm off the medial cap and the run failed. Started
// along the constraint manifold's tangent (MdeChart::SetStartPose) it completes, with dae's
// events (the other formulations share only the contact kernel).
TEST(AnatomicalSurfacesLongPhase, MdeEliminationFollowsTheManifold) {
  std::ifstream file(test_support::ScenesDir() + "/anatomical_surfaces.yaml");
  std::string text((std::istreambuf_iterator<char>(file)), std::istreambuf_iterator<char>());
  const auto replace = [&text](const std::string& from, const std::string& to) {
    const size_t at = text.find(from);
    ASSERT_NE(at, std::string::npos) << from;
    text.replace(at, from.size(), to);
  };
  replace("gravity: {enabled: true}", "gravity: {enabled: false}");
  replace("pulse: {shape: reconstructed, amplitude_N: 100.0, duration_s: 0.1}",
          "pulse: {shape: half_sine, amplitude_N: 800.0, duration_s: 0.03, direction_T: [1.0, -0.3, 0.0]}");
  replace("end: {flexion_deg: 60.0, time_s: 2.0}", "end: {flexion_deg: 90.0, time_s: 0.5}");
  const Scene scene = ParseScene(text, "long_phase.yaml", test_support::ScenesDir());
  const RunResult dae = RunScene(scene, TightSettings("dae"));
  const RunResult mde = RunScene(scene, TightSettings("mde"));
  ASSERT_TRUE(dae.completed) << dae.failure;
  ASSERT_TRUE(mde.completed) << mde.failure;
  ASSERT_EQ(mde.events.size(), dae.events.size());
  ASSERT_GE(dae.events.size(), 7u);  // through the phase that had failed (re-contacts on both sides)
  for (size_t i = 0; i < dae.events.size(); ++i) {
    EXPECT_EQ(mde.events[i].name, dae.events[i].name);
    EXPECT_NEAR(mde.events[i].time, dae.events[i].time, 1e-7 * dae.events[i].time) << dae.events[i].name;
  }
}

INSTANTIATE_TEST_SUITE_P(Registered, AnatomicalSurfaces,
                         ::testing::ValuesIn(test_support::RegisteredFormulationNames()),
                         test_support::FormulationParamName());

}  // namespace
}  // namespace kneedyn
