// The chapter's angle statements read off a run (calibrate_reconstruction's residuals,
// reports/calibrate_reconstruction.cpp): each is read while the knee flexes, up to the first
// sample of largest flexion, since the chapter's statements are about the flexing knee and
// a fitted run can swing back (tests/calibration_measures_test.cpp).
#pragma once

#include <cmath>
#include <cstddef>

#include "formulations/run.hpp"
#include "solver/units.hpp"

namespace kneedyn::calibration {

// Index of the first sample of largest flexion α (0 for no samples).
inline size_t FlexingEnd(const RunResult& r) {
  size_t end = 0;
  for (size_t i = 0; i < r.samples.size(); ++i) {
    if (r.samples[i].q(kAlpha) > r.samples[end].q(kAlpha)) end = i;
  }
  return end;
}

// Flexion (deg) of the first + → − crossing of β − 90° after 1° of flexion while the knee
// flexes, linearly interpolated between samples; 90 when none.
inline double ValgusCrossing(const RunResult& r) {
  const size_t end = r.samples.empty() ? 0 : FlexingEnd(r) + 1;
  for (size_t i = 1; i < end; ++i) {
    const double a0 = RadToDeg(r.samples[i - 1].q(kAlpha)), a1 = RadToDeg(r.samples[i].q(kAlpha));
    const double v0 = RadToDeg(r.samples[i - 1].q(kBeta)) - 90.0, v1 = RadToDeg(r.samples[i].q(kBeta)) - 90.0;
    if (a0 >= 1.0 && v0 > 0.0 && v1 <= 0.0) return a0 + v0 / (v0 - v1) * (a1 - a0);
  }
  return 90.0;
}

// Flexion (deg) at the maximum of sign × q(coordinate) while the knee flexes; 90 when no
// sample.
inline double ArgMaxFlexion(const RunResult& r, int coordinate, double sign) {
  double best = -INFINITY, at = 90.0;
  const size_t end = r.samples.empty() ? 0 : FlexingEnd(r) + 1;
  for (size_t i = 0; i < end; ++i) {
    const MechanicalState& s = r.samples[i];
    const double v = sign * s.q(coordinate);
    if (v > best) {
      best = v;
      at = RadToDeg(s.q(kAlpha));
    }
  }
  return at;
}

}  // namespace kneedyn::calibration
