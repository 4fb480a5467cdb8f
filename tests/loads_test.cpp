// Validates: the pulse shapes of solver/loads.* (docs/model.md §7; the readings of the garbled
// Eq. 1.62 used by the reconstruction study) against their closed forms, typed in here:
// value at a sample time, the peak found by dense sampling (reconstructed_peak peaks at A;
// damped_sine at 0.398 A, the maximum of sin(2πs)e^{−4.73s}), zero before t = 0, the
// half-sine's support, and the scene spelling round trip. Does not validate the physics
// of the pulse (dynamics tests do).
#include <gtest/gtest.h>

#include <cmath>

#include "solver/error.hpp"
#include "solver/loads.hpp"

namespace kneedyn {
namespace {

Pulse MakePulse(PulseShape shape, double amplitude = 100.0, double duration = 0.1) {
  Pulse p;
  p.shape = shape;
  p.amplitude = amplitude;
  p.duration = duration;
  return p;
}

double PeakBySampling(const Pulse& p, double* t_peak) {
  double best = -1.0;
  for (int i = 0; i <= 200000; ++i) {
    const double t = 2.0 * p.duration * i / 200000.0;
    const double v = PulseMagnitude(p, t);
    if (v > best) {
      best = v;
      *t_peak = t;
    }
  }
  return best;
}

TEST(Loads, ReconstructedPeakConstantIsTheMaximum) {
  double t = 0.0;
  const double peak = PeakBySampling(MakePulse(PulseShape::kReconstructed, 1.0, 1.0), &t);
  EXPECT_NEAR(peak, kReconstructedPeakValue, 1e-9);
  EXPECT_NEAR(t, 0.2370656, 1e-5);
}

TEST(Loads, ReconstructedPeakReachesAmplitude) {
  double t = 0.0;
  const Pulse p = MakePulse(PulseShape::kReconstructedPeak, 100.0, 0.2);
  EXPECT_NEAR(PeakBySampling(p, &t), 100.0, 1e-6);
  EXPECT_NEAR(t, 0.2370656 * 0.2, 1e-5);
  // Same shape as the reconstructed pulse, scaled: ratio constant in time.
  const Pulse r = MakePulse(PulseShape::kReconstructed, 100.0, 0.2);
  for (double s : {0.05, 0.3, 0.7, 1.3}) {
    EXPECT_NEAR(PulseMagnitude(p, s * 0.2) * kReconstructedPeakValue, PulseMagnitude(r, s * 0.2), 1e-12);
  }
}

TEST(Loads, DampedSineClosedForm) {
  const Pulse p = MakePulse(PulseShape::kDampedSine, 100.0, 0.1);
  // s = 0.25: sin(π/2) = 1, exp(−1.1825) = 0.306507...
  EXPECT_NEAR(PulseMagnitude(p, 0.025), 100.0 * std::exp(-4.73 * 0.25), 1e-12);
  double t = 0.0;
  EXPECT_NEAR(PeakBySampling(p, &t), 39.803650727, 1e-6);
  EXPECT_NEAR(t, 0.0147298502, 1e-6);
  EXPECT_LT(PulseMagnitude(p, 0.07), 0.0);  // second lobe reverses (sin(2π·0.7) < 0)
}

TEST(Loads, HalfSineSupportAndZeroBeforeStart) {
  const Pulse p = MakePulse(PulseShape::kHalfSine, 50.0, 0.1);
  EXPECT_NEAR(PulseMagnitude(p, 0.05), 50.0, 1e-12);
  EXPECT_EQ(PulseMagnitude(p, 0.1000001), 0.0);
  for (PulseShape s : {PulseShape::kReconstructed, PulseShape::kReconstructedPeak, PulseShape::kDampedSine,
                       PulseShape::kHalfSine}) {
    EXPECT_EQ(PulseMagnitude(MakePulse(s), -1e-3), 0.0);
  }
}

// The factor summary.json and calibration.json carry (the report's peak force = factor × A)
// against the sampled maximum of the shape itself: a second evaluation, not the formula again.
TEST(Loads, PeakFactorIsTheSampledMaximumOverAmplitude) {
  for (PulseShape s : {PulseShape::kReconstructed, PulseShape::kReconstructedPeak, PulseShape::kDampedSine,
                       PulseShape::kHalfSine}) {
    double t = 0.0;
    EXPECT_NEAR(PulsePeakFactor(s), PeakBySampling(MakePulse(s, 1.0, 1.0), &t), 1e-9) << PulseShapeName(s);
  }
  EXPECT_EQ(PulsePeakFactor(PulseShape::kNone), 0.0);
}

TEST(Loads, SceneSpellingRoundTrip) {
  for (const char* n : {"none", "reconstructed", "half_sine", "reconstructed_peak", "damped_sine"}) {
    EXPECT_STREQ(PulseShapeName(ParsePulseShape(n)), n);
  }
  try {
    ParsePulseShape("square");
    FAIL() << "accepted an unknown shape";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("damped_sine"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace kneedyn
