// External loads (docs/model.md §7): the impact pulse and its shapes. Gravity and constant loads
// are applied in dynamics.hpp.
#pragma once

#include <limits>
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

// PulseMagnitude with its last value kept: an integrator evaluates the model several times at
// one t (IDA's Newton iterations, CVODE's corrector iterations and the root functions at the
// step's end), and Fe(t) costs a sin and an exp (~180 instructions). Keyed on t and on the
// fields Fe depends on, so a pulse changed in place is recomputed. Same bits as PulseMagnitude.
struct PulseMagnitudeCache {
  double At(const Pulse& pulse, double t) {
    if (!(t == t_ && pulse.shape == shape_ && pulse.amplitude == amplitude_ && pulse.duration == duration_)) {
      value_ = PulseMagnitude(pulse, t);
      t_ = t;
      shape_ = pulse.shape;
      amplitude_ = pulse.amplitude;
      duration_ = pulse.duration;
    }
    return value_;
  }

 private:
  double t_ = std::numeric_limits<double>::quiet_NaN();  // s; NaN: nothing kept yet
  PulseShape shape_ = PulseShape::kNone;
  double amplitude_ = 0.0, duration_ = 0.0, value_ = 0.0;
};

// max over s ≥ 0 of s sin(2π s) exp(−4.73 s), at s = 0.23706557 (checked in loads_test).
constexpr double kReconstructedPeakValue = 0.0769927007935922;

// Peak force over amplitude, max over t ≥ 0 of PulseMagnitude / A (dimensionless): 1 for
// half_sine and reconstructed_peak, kReconstructedPeakValue for reconstructed,
// sin(φ) exp(−4.73 φ / 2π) with tan φ = 2π / 4.73 (≈ 0.398) for damped_sine, 0 for none.
// Written to summary.json (scene.pulse.peak_factor) and calibration.json so that the report
// takes the peak from here instead of re-deriving the shapes (docs/outputs.md).
double PulsePeakFactor(PulseShape shape);

// Scene-file spelling of the shapes: "reconstructed", "half_sine", "reconstructed_peak",
// "damped_sine", "none".
PulseShape ParsePulseShape(const std::string& name);  // throws InputError
const char* PulseShapeName(PulseShape shape);

}  // namespace kneedyn
