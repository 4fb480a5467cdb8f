// Metric functions of benchmarks/metrics.hpp against hand-computed cases. Validates the
// formulas (scd, mixed error, event errors, time matching, energy error); not the
// accuracy of any formulation (bench_sweep_test and the reference test do that).
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>

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

// Compare pairs each reference time with the run's first row within 1e-9 s in one merge
// pass over the two sorted lists (before: a scan from the first run row per reference time,
// quadratic). Checked against that scan, written out here, on random cases built from the
// edge cases: unequal grids, run rows duplicated, rows 0.5e-9 / 1e-9 / 2e-9 s off a
// reference time (either side), runs ending before or after the reference, with and without
// end events; every row holds random values, so a row paired wrongly changes the mixed
// errors or the scd, which must equal the scan's bit for bit. (A correctness test of the
// merge: the old scan passes it by construction.)
TEST(Compare, MergeMatchesTheScanFromTheStartOnEdgeCases) {
  std::mt19937_64 rng(12345);
  std::uniform_real_distribution<double> value(-2.0, 2.0);
  const std::vector<double> offsets = {0.0, 0.0, 0.0, 0.5e-9, -0.5e-9, 1e-9, -1e-9, 2e-9, -2e-9, 0.01};
  const auto times = [&](size_t n, bool allow_duplicates) {
    std::vector<double> t;
    for (size_t k = 0; t.size() < n && k < 4 * n + 4; ++k) {
      if (rng() % 3 == 0) continue;  // a grid point left out: unequal grids
      const double x = 0.02 * static_cast<double>(k) + offsets[rng() % offsets.size()];
      if (!t.empty() && !(x > t.back())) continue;
      t.push_back(x);
      if (allow_duplicates && rng() % 4 == 0) t.push_back(x);
    }
    return t;
  };
  const auto random_solution = [&](std::vector<double> t, bool end_event) {
    if (end_event) t.push_back(t.empty() ? 1.0 : t.back() + 0.013);
    Solution s = Synthetic(t, end_event, 0.0);
    for (const std::string& c : VariableClasses()) {
      for (auto& row : s.values[c]) {
        for (double& x : row) x = value(rng);
      }
    }
    return s;
  };
  int checked_pairs = 0;
  for (int trial = 0; trial < 2000; ++trial) {
    const Solution ref = random_solution(times(1 + rng() % 12, false), rng() % 2 == 0);
    const Solution run = random_solution(times(rng() % 16, true), rng() % 2 == 0);
    // The scan from the start (the code before the merge).
    std::vector<std::pair<size_t, size_t>> pairs;
    int missing = 0;
    const size_t n_ref = ref.times.size() - (ref.end_is_event ? 1 : 0);
    const size_t n_run = run.times.size() - (run.end_is_event ? 1 : 0);
    for (size_t i = 0; i < n_ref; ++i) {
      size_t k = 0;
      while (k < n_run && std::abs(run.times[k] - ref.times[i]) > 1e-9) ++k;
      if (k < n_run) {
        pairs.push_back({k, i});
      } else {
        ++missing;
      }
    }
    if (ref.end_is_event) {
      if (run.end_is_event) {
        pairs.push_back({run.times.size() - 1, ref.times.size() - 1});
      } else {
        ++missing;
      }
    }
    checked_pairs += static_cast<int>(pairs.size());
    const Metrics m = Compare(run, ref);
    ASSERT_EQ(m.compared_times, static_cast<int>(pairs.size())) << "trial " << trial;
    ASSERT_EQ(m.missing_times, missing) << "trial " << trial;
    double worst_scd = std::numeric_limits<double>::infinity();
    for (const std::string& c : VariableClasses()) {
      double mixed = 0.0;
      for (const auto& [k, i] : pairs) {
        mixed = std::max(mixed, MixedError(run.values.at(c)[k], ref.values.at(c)[i]));
        if (c == "positions") {
          worst_scd = std::min(worst_scd, ScdFromErrors(run.values.at(c)[k], ref.values.at(c)[i],
                                                        {1.0, 1.0, 1.0, 1.0, 1.0, 1.0}));
        }
      }
      if (pairs.empty()) {
        ASSERT_TRUE(std::isnan(m.mixed.at(c))) << "trial " << trial;
      } else {
        ASSERT_EQ(m.mixed.at(c), mixed) << "trial " << trial << " " << c;
      }
    }
    if (!pairs.empty()) {
      ASSERT_EQ(m.scd_compared, worst_scd) << "trial " << trial;
    }
  }
  EXPECT_GT(checked_pairs, 2000);  // the cases pair rows, not only miss them
}

// Reference events against the run's first event of the same name (a hash map since the
// scan per reference event): duplicates in the run count their first, duplicates in the
// reference their first, names the run lacks are NaN. (Checks the same result as the scan.)
TEST(Compare, EventsAreMatchedWithTheRunsFirstEventOfTheName) {
  Solution ref = Synthetic({0.0, 0.02}, false, 0.0);
  Solution run = Synthetic({0.0, 0.02}, false, 0.0);
  ref.events = {{"a", 1.0, 0.1}, {"b", 2.0, 0.2}, {"a", 5.0, 0.5}, {"c", 3.0, 0.3}};
  run.events = {{"b", 2.5, 0.25}, {"a", 1.25, 0.0}, {"a", 1.0, 0.1}, {"b", 2.0, 0.2}, {"d", 9.0, 0.9}};
  const Metrics m = Compare(run, ref);
  ASSERT_EQ(m.event_time.size(), 3u);
  EXPECT_DOUBLE_EQ(m.event_time.at("a"), 0.25);  // run's first "a" (1.25) against ref's first (1.0)
  EXPECT_DOUBLE_EQ(m.event_angle.at("a"), 0.1 * 180.0 / M_PI);
  EXPECT_DOUBLE_EQ(m.event_time.at("b"), 0.5);
  EXPECT_TRUE(std::isnan(m.event_time.at("c")));
  EXPECT_TRUE(std::isnan(m.event_angle.at("c")));
  EXPECT_EQ(m.event_time.count("d"), 0u);
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

// The diagrams' rule (reports/bench_data.py classify_run, docs: benchmarks/README.md):
// every reference event, each within 1 ms, and no contact event the reference lacks.
TEST(WrongEventReason, MissingLateExtraEventsAndNoneOfTheOthers) {
  Metrics m;
  m.event_time = {{"liftoff_lateral", 0.9e-3}, {"flexion_90", 1e-6}};
  const std::vector<EventRecord> own = {{"liftoff_lateral", 0.2, 0.9}, {"flexion_90", 0.3, 1.57}};
  EXPECT_EQ(WrongEventReason(m, own), "");
  std::vector<EventRecord> with_kink = own;  // a branch switch is no contact event
  with_kink.push_back({"kink_ACL", 0.1, 0.2});
  EXPECT_EQ(WrongEventReason(m, with_kink), "");
  std::vector<EventRecord> with_recontact = own;
  with_recontact.push_back({"recontact_lateral", 0.25, 1.2});
  with_recontact.push_back({"recontact_lateral", 0.26, 1.3});
  EXPECT_EQ(WrongEventReason(m, with_recontact), "wrong events: recontact_lateral not in the reference");
  Metrics late = m;
  late.event_time["liftoff_lateral"] = 1.2e-3;
  EXPECT_EQ(WrongEventReason(late, own), "wrong event time: liftoff_lateral off by 1.2 ms");
  Metrics missing = m;
  missing.event_time["liftoff_lateral"] = kNaN;
  EXPECT_EQ(WrongEventReason(missing, own), "wrong events: reference event(s) liftoff_lateral missing");
  EXPECT_EQ(WrongEventReason(Metrics{}, with_recontact), "");  // a reference without events judges none
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
