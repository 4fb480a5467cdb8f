// Conservation as an independent witness of the extended-precision references
// (benchmarks/extended_reference.hpp): on the conservative scene (elastic ligaments, workless
// frictionless contacts, gravity; docs/model.md §5, §8) the mechanical energy
// (MechanicalEnergyTpl, dynamics.hpp) must stay constant. The long double reference holds it
// to 15 digits over the run; the same integrator in double does not (round-off, ~1e-14),
// which is what the bound separates. Label `reference` (a few seconds).
#include <gtest/gtest.h>

#include <cmath>

#include "benchmarks/extended_reference.hpp"
#include "benchmarks/float128_scalar.hpp"
#include "test_support.hpp"

namespace kneedyn {
namespace {

TEST(ExtendedReference, ConservativeSceneHoldsEnergyTo15Digits) {
  const Scene scene = LoadScene(test_support::ScenesDir() + "/conservative.yaml");
  bench::ExtendedReferenceSettings settings;
  settings.stages = 6;
  settings.step = 2.5e-4;
  const bench::ExtendedReferenceRun extended = bench::RunExtendedReference<long double>(scene, settings);
  EXPECT_TRUE(extended.result.completed);
  EXPECT_EQ(extended.result.end_reason, "end_time");
  EXPECT_LT(extended.energy_error, 1e-15) << "relative energy error over the run";
  EXPECT_GT(extended.energy_error, 0.0);  // evaluated, not skipped
  // The constraints hold to round-off (the index-reduced form is not stabilized).
  EXPECT_LT(extended.max_gap_m, 1e-16);
  EXPECT_LT(extended.max_gap_rate_m_s, 1e-16);
}

TEST(ExtendedReference, TheSameIntegratorInDoubleMissesTheBound) {
  const Scene scene = LoadScene(test_support::ScenesDir() + "/conservative.yaml");
  bench::ExtendedReferenceSettings settings;
  settings.stages = 6;
  settings.step = 2.5e-4;
  const bench::ExtendedReferenceRun run = bench::RunExtendedReference<double>(scene, settings);
  EXPECT_GT(run.energy_error, 1e-15);
}

// The extended path beyond sphere on plane, over a short interval (0.01 s, 40 steps of
// 2.5e-4 s) in quadruple precision against the same integrator in double: the same motion
// to double's round-off (the double run's, amplified over 40 steps), the patella's
// equilibrium refined in T (solver/patella_extended.hpp). (anatomical_surfaces in quadruple
// precision stops at t = 0.006 s: the Gauss-Legendre Newton does not converge with κ of the
// general pairs by finite differences, contact_kinematics.hpp.)
void ExpectFloat128AgreesWithDouble(Scene scene, double min_digits) {
  scene.end.time = 0.01;
  scene.end.flexion.reset();
  bench::ExtendedReferenceSettings settings;
  settings.stages = 6;
  settings.step = 2.5e-4;
  settings.output_interval = 0.0025;
  const bench::ExtendedReferenceRun quad = bench::RunExtendedReference<bench::Float128>(scene, settings, 0.0025);
  const bench::ExtendedReferenceRun dbl = bench::RunExtendedReference<double>(scene, settings, 0.0025);
  ASSERT_TRUE(quad.result.completed);
  EXPECT_EQ(quad.result.end_reason, "end_time");
  const bench::Metrics m = bench::Compare(dbl.solution, quad.solution);
  EXPECT_EQ(m.compared_times, 5);
  EXPECT_GT(m.scd, min_digits) << scene.name;
  for (const auto& [cls, mixed] : m.mixed) {
    if (!std::isnan(mixed)) {
      EXPECT_LT(mixed, std::pow(10.0, -min_digits)) << scene.name << " " << cls;
    }
  }
  // The t = 0 row is the double consistent initialization's state (its projection's round-off).
  EXPECT_LT(quad.max_gap_m, 1e-16) << scene.name;
}

TEST(ExtendedReference, PatellaSceneRunsInFloat128AndAgreesWithDouble) {
  ExpectFloat128AgreesWithDouble(LoadScene(test_support::ScenesDir() + "/patellofemoral_impact.yaml"), 12.0);
}

}  // namespace
}  // namespace kneedyn
