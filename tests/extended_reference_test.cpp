// Conservation as an independent witness of the extended-precision references
// (benchmarks/extended_reference.hpp): on the conservative scene (elastic ligaments, workless
// frictionless contacts, gravity; docs/model.md §5, §8) the mechanical energy
// (MechanicalEnergyTpl, dynamics.hpp) must stay constant. The long double reference holds it
// to 15 digits over the run; the same integrator in double does not (round-off, ~1e-14),
// which is what the bound separates. Label `reference` (a few seconds).
#include <gtest/gtest.h>

#include "benchmarks/extended_reference.hpp"
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

}  // namespace
}  // namespace kneedyn
