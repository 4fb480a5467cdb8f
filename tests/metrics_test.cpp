// Metric functions of benchmarks/metrics.hpp against hand-computed cases. Validates the
// formulas (scd, mixed error, event errors, time matching, energy error); not the
// accuracy of any formulation (bench_sweep_test and the reference test do that).
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "benchmarks/metrics.hpp"
#include "solver/dynamics.hpp"
#include "solver/pose.hpp"

namespace kneedyn {
namespace bench {
namespace {

const double kNaN = std::numeric_limits<double>::quiet_NaN();

TEST(Scd, RelativeErrorWithFloorInDigits) {
  // |1.001 − 1| / (1 + 1) = 5e-4 → 3.30103 digits; the 0 component (error 2e-4 over the
  // floor 1) is less.
  EXPECT_NEAR(ScdFromErrors({1.001, 2e-4}, {1.0, 0.0}, {1.0, 1.0}), -std::log10(5e-4), 1e-12);
  // Near-zero component dominates: |1e-2| / (0 + 1) = 1e-2 → 2 digits.
  EXPECT_NEAR(ScdFromErrors({100.0, 1e-2}, {100.0, 0.0}, {1.0, 1.0}), 2.0, 1e-12);
  EXPECT_TRUE(std::isinf(ScdFromErrors({3.0}, {3.0}, {1.0})));
  EXPECT_NEAR(ScdFromErrors({kNaN, 1.1}, {5.0, 1.0}, {1.0, 1.0}), -std::log10(0.05), 1e-12);
  EXPECT_THROW(ScdFromErrors({1.0}, {1.0, 2.0}, {1.0}), InputError);
}

TEST(MixedError, MaxAbsoluteOverOnePlusReference) {
  // max(|2−1|/2, |10.5−10|/11) = 0.5
  EXPECT_DOUBLE_EQ(MixedError({2.0, 10.5}, {1.0, 10.0}), 0.5);
  // large reference: relative; small: absolute
  EXPECT_DOUBLE_EQ(MixedError({999.0}, {1000.0}), 1.0 / 1001.0);
  EXPECT_DOUBLE_EQ(MixedError({1e-3}, {0.0}), 1e-3);
  EXPECT_DOUBLE_EQ(MixedError({kNaN, 1.0}, {1.0, kNaN}), 0.0);
}

// A solution with one component per class and value v(t) = t at each time.
Solution Synthetic(const std::vector<double>& times, bool end_event, double offset) {
  Solution s;
  s.times = times;
  s.end_is_event = end_event;
  for (const std::string& c : VariableClasses()) {
    s.names[c] = {c + "_0", c + "_1", c + "_2", c + "_3", c + "_4", c + "_5"};
    for (double t : times) s.values[c].push_back({t + offset, 0.0, 0.0, 0.0, 0.0, 0.0});
  }
  return s;
}

TEST(Compare, MatchesTimesEndEventAndEvents) {
  Solution ref = Synthetic({0.0, 0.02, 0.04, 0.3}, true, 0.0);
  ref.events = {{"liftoff_lateral", 0.2, 0.9}, {"flexion_90", 0.3, M_PI / 2}};
  // The run has an extra time (ignored) and lacks 0.04 (counted missing); its values are
  // off by 1e-3 everywhere.
  Solution run = Synthetic({0.0, 0.01, 0.02, 0.3}, true, 1e-3);
  run.events = {{"flexion_90", 0.31, M_PI / 2 + 1e-3}};
  const Metrics m = Compare(run, ref);
  EXPECT_EQ(m.compared_times, 3);  // 0, 0.02 and the end states
  EXPECT_EQ(m.missing_times, 1);
  // Worst mixed: 1e-3 / (1 + 0) at t = 0.
  EXPECT_DOUBLE_EQ(m.mixed.at("velocities"), 1e-3);
  // A missing time: no scd (the mixed errors cover the times compared).
  EXPECT_TRUE(std::isnan(m.scd));
  // Over the times compared: worst 1e-3 / (|0| + 1 mm floor) at t = 0 → 3 digits.
  EXPECT_NEAR(m.scd_compared, 3.0, 1e-9);
  EXPECT_NEAR(m.event_time.at("flexion_90"), 0.01, 1e-15);
  EXPECT_NEAR(m.event_angle.at("flexion_90"), 1e-3 * 180.0 / M_PI, 1e-12);
  EXPECT_TRUE(std::isnan(m.event_time.at("liftoff_lateral")));
}

TEST(Compare, RunWithoutEndEventMissesTheEndState) {
  const Solution ref = Synthetic({0.0, 0.02, 0.3}, true, 0.0);
  const Solution run = Synthetic({0.0, 0.02}, false, 0.0);
  const Metrics m = Compare(run, ref);
  EXPECT_EQ(m.compared_times, 2);
  EXPECT_EQ(m.missing_times, 1);
  EXPECT_TRUE(std::isnan(m.scd));
}

TEST(Compare, ScdOfPositionsWithTheFloor) {
  const Solution ref = Synthetic({0.0, 0.02, 0.3}, true, 0.0);
  const Solution run = Synthetic({0.0, 0.02, 0.3}, true, 1e-3);
  const Metrics m = Compare(run, ref);
  EXPECT_EQ(m.missing_times, 0);
  // Worst at t = 0: 1e-3 / (|0| + 1 mm floor) → 3 digits.
  EXPECT_NEAR(m.scd, 3.0, 1e-9);
  EXPECT_DOUBLE_EQ(m.mixed.at("ligament_forces"), 1e-3);
}

// A planted score above what the reference can measure: a run that matches an 11.2-digit
// reference to 14 digits is flagged (its error is the reference's own), one at 9 digits is
// not, and without a stated accuracy nothing is flagged.
TEST(ScdCeiling, FlagsAScoreAboveTheReferenceAccuracyMinusOneDigit) {
  const Solution ref = Synthetic({0.0, 0.02, 0.3}, true, 0.0);
  Metrics over = Compare(Synthetic({0.0, 0.02, 0.3}, true, 1e-14), ref);
  ASSERT_GT(over.scd, 13.5);
  ApplyScdCeiling(11.2, &over);
  EXPECT_NEAR(over.scd_ceiling, 10.2, 1e-12);
  EXPECT_TRUE(over.scd_above_ceiling);
  const nlohmann::json j = MetricsJson(over);
  EXPECT_TRUE(j.at("scd_above_ceiling").get<bool>());
  EXPECT_NEAR(j.at("scd_ceiling").get<double>(), 10.2, 1e-12);

  Metrics under = Compare(Synthetic({0.0, 0.02, 0.3}, true, 1e-9), ref);
  ApplyScdCeiling(11.2, &under);
  EXPECT_FALSE(under.scd_above_ceiling);

  Metrics unstated = Compare(Synthetic({0.0, 0.02, 0.3}, true, 1e-14), ref);
  ApplyScdCeiling(std::numeric_limits<double>::quiet_NaN(), &unstated);
  EXPECT_FALSE(unstated.scd_above_ceiling);
  EXPECT_TRUE(MetricsJson(unstated).at("scd_ceiling").is_null());
}

TEST(Solution, JsonRoundTripKeepsNaN) {
  Solution s = Synthetic({0.0, 0.02}, false, 0.5);
  s.values["contact_points"][1][2] = kNaN;
  s.events = {{"liftoff_medial", 0.1, 0.5}};
  const Solution back = SolutionFromJson(SolutionJson(s));
  EXPECT_EQ(back.times, s.times);
  EXPECT_TRUE(std::isnan(back.values.at("contact_points")[1][2]));
  EXPECT_DOUBLE_EQ(back.values.at("positions")[1][0], 0.52);
  ASSERT_EQ(back.events.size(), 1u);
  EXPECT_NEAR(back.events[0].flexion, 0.5, 1e-15);
}

class SceneMetrics : public ::testing::Test {
 protected:
  void SetUp() override { scene_ = LoadScene(ReferenceDataDir() + "/scenes/chapter_impact.yaml"); }
  MechanicalState At(double t) const {
    MechanicalState s;
    s.t = t;
    s.q = scene_.reference_q;
    s.active = {0, 1};
    s.contact.resize(scene_.model.contacts.size());
    s.contact[0].normal_force = 10.0 * t;
    return s;
  }
  Scene scene_;
};

TEST_F(SceneMetrics, ExtractsMultiplesOfTheIntervalAndTheEndEvent) {
  RunResult r;
  for (int i = 0; i <= 9; ++i) {
    r.samples.push_back(At(0.005 * i));
    r.sample_is_event.push_back(false);
  }
  r.samples.push_back(At(0.0467));  // end event
  r.sample_is_event.push_back(true);
  r.completed = true;
  r.end_reason = "flexion_90";
  const Solution s = ExtractSolution(scene_, ContactForm::kClosedForm, r, 0.02);
  ASSERT_EQ(s.times.size(), 4u);  // 0, 0.02, 0.04, end
  EXPECT_DOUBLE_EQ(s.times[1], 0.02);
  EXPECT_DOUBLE_EQ(s.times[3], 0.0467);
  EXPECT_TRUE(s.end_is_event);
  EXPECT_DOUBLE_EQ(s.values.at("contact_forces")[2][0], 0.4);  // N_medial = 10 t at 0.04
  EXPECT_DOUBLE_EQ(s.values.at("positions")[0][3], 0.0);       // flexion at reference pose
  EXPECT_EQ(s.values.at("contact_points")[0].size(), 12u);
  EXPECT_EQ(s.values.at("ligament_forces")[0].size(), scene_.model.ligaments.size());
}

TEST_F(SceneMetrics, EnergyErrorIsKineticEnergyOverInitialEnergy) {
  RunResult r;
  r.samples = {At(0.0), At(0.1)};
  const double v = 0.2;  // m/s along x0: ΔE = ½ m v²
  r.samples[1].qd(kX0) = v;
  const double e0 = MechanicalEnergy(scene_.model, r.samples[0].q, r.samples[0].qd);
  EXPECT_NEAR(EnergyError(scene_, r), 0.5 * scene_.model.mass * v * v / std::abs(e0), 1e-12);
}

}  // namespace
}  // namespace bench
}  // namespace kneedyn
