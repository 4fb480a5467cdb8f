// The calibration's angle readings (reports/calibration_measures.hpp) on made-up runs whose
// answers follow from the definitions: each is read while the knee flexes, up to its first
// sample of largest flexion; a run that swings back is not read on the way back (before,
// the reconstruction's gravity-off fits were read there: a peak taken at 8.6° of a
// swing-back).
#include "reports/calibration_measures.hpp"

#include <gtest/gtest.h>

#include <vector>

namespace kneedyn {
namespace {

// Samples with flexion α_k and valgus β_k − 90° = valgus_k (deg), external rotation γ_k (deg).
RunResult MadeUpRun(const std::vector<double>& flexion, const std::vector<double>& valgus, const std::vector<double>& rotation) {
  RunResult r;
  for (size_t k = 0; k < flexion.size(); ++k) {
    MechanicalState s;
    s.t = 0.01 * static_cast<double>(k);
    s.q(kAlpha) = DegToRad(flexion[k]);
    s.q(kBeta) = DegToRad(90.0 + valgus[k]);
    s.q(kGamma) = DegToRad(rotation[k]);
    r.samples.push_back(s);
  }
  return r;
}

TEST(CalibrationMeasures, ReadWhileTheKneeFlexesOnly) {
  // Flexes 0 → 40° and swings back to 10°. While flexing, valgus stays positive and the
  // rotation peaks (5°) at 30°; on the way back valgus crosses zero and the rotation reaches
  // 9° at 20°: neither counts.
  const RunResult swing = MadeUpRun({0, 10, 20, 30, 40, 30, 20, 10}, {2, 2, 1, 1, 0.5, -1, -2, -3},
                              {0, 2, 4, 5, 4.5, 7, 9, 8});
  EXPECT_EQ(calibration::FlexingEnd(swing), 4u);
  EXPECT_EQ(calibration::ValgusCrossing(swing), 90.0);  // none while flexing
  EXPECT_DOUBLE_EQ(calibration::ArgMaxFlexion(swing, kGamma, +1.0), 30.0);
  // Most varus (−β) while flexing: the last flexing sample's 0.5° is the least valgus.
  EXPECT_DOUBLE_EQ(calibration::ArgMaxFlexion(swing, kBeta, -1.0), 40.0);

  // A crossing while flexing, between 20° (valgus +1) and 30° (valgus −1): at 25° by linear
  // interpolation. One before 1° of flexion does not count.
  const RunResult flexing = MadeUpRun({0, 0.5, 20, 30, 40}, {-1, 1, 1, -1, -2}, {0, 0, 0, 0, 0});
  EXPECT_DOUBLE_EQ(calibration::ValgusCrossing(flexing), 25.0);
  EXPECT_EQ(calibration::ValgusCrossing(RunResult{}), 90.0);
  EXPECT_EQ(calibration::ArgMaxFlexion(RunResult{}, kGamma, 1.0), 90.0);
}

}  // namespace
}  // namespace kneedyn
