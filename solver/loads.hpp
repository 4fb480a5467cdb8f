// External loads (docs/model.md §7): the impact pulse and its shapes. Gravity and constant loads
// are applied in dynamics.hpp.
#pragma once

#include <string>

#include "solver/model.hpp"

namespace kneedyn {

// Pulse magnitude Fe(t) in N (positive along pulse.direction_T).
//   reconstructed: A (t/t0) sin(2π t/t0) exp(−4.73 t/t0)   (Eq. 1.62 as reconstructed)
//   half_sine:     A sin(π t/t0) for 0 ≤ t ≤ t0, else 0
//   reconstructed_peak: the reconstructed shape divided by its peak value
//                  kReconstructedPeakValue, so that max Fe = A (A is then the peak force)
//   damped_sine:   A sin(2π t/t0) exp(−4.73 t/t0) (Eq. 1.62 read without the t/t0 factor;
//                  peak 0.398 A at t = 0.147 t0)
//   none:          0
// The printed Eq. 1.62 is garbled; the last two shapes are the other plausible readings
// used by the reconstruction study (reports/reconstruction.py).
// Zero for t < 0.
double PulseMagnitude(const Pulse& pulse, double t);

// max over s ≥ 0 of s sin(2π s) exp(−4.73 s), at s = 0.23706557 (checked in loads_test).
constexpr double kReconstructedPeakValue = 0.0769927007935922;

// Scene-file spelling of the shapes: "reconstructed", "half_sine", "reconstructed_peak",
// "damped_sine", "none".
PulseShape ParsePulseShape(const std::string& name);  // throws InputError
const char* PulseShapeName(PulseShape shape);

}  // namespace kneedyn
