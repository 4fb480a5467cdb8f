#include "solver/loads.hpp"

#include <cmath>

#include "solver/error.hpp"
#include "solver/units.hpp"

namespace kneedyn {
namespace {

// The decay of Eq. 1.62's exponential per unit of t/t0 (loads.hpp): one value for every shape
// that has it, and for the damped sine's peak below.
constexpr double kPulseDecay = 4.73;

// Eq. 1.62's force (N) at s = t / t0: A s sin(2π s) e^(−4.73 s), in this order of products.
double ReconstructedForce(double amplitude, double s) {
  return amplitude * s * std::sin(2.0 * kPi * s) * std::exp(-kPulseDecay * s);
}

}  // namespace

double PulseMagnitude(const Pulse& pulse, double t) {
  if (t < 0.0) return 0.0;
  const double s = t / pulse.duration;
  switch (pulse.shape) {
    case PulseShape::kNone:
      return 0.0;
    case PulseShape::kReconstructed:
      return ReconstructedForce(pulse.amplitude, s);
    case PulseShape::kHalfSine:
      return s <= 1.0 ? pulse.amplitude * std::sin(kPi * s) : 0.0;
    case PulseShape::kReconstructedPeak:
      return ReconstructedForce(pulse.amplitude, s) / kReconstructedPeakValue;
    case PulseShape::kDampedSine:
      return pulse.amplitude * std::sin(2.0 * kPi * s) * std::exp(-kPulseDecay * s);
  }
  return 0.0;
}

double PulsePeakFactor(PulseShape shape) {
  switch (shape) {
    case PulseShape::kNone:
      return 0.0;
    case PulseShape::kReconstructed:
      return kReconstructedPeakValue;
    case PulseShape::kHalfSine:
    case PulseShape::kReconstructedPeak:
      return 1.0;
    case PulseShape::kDampedSine: {
      // d/ds [sin(2πs) e^(−k s)] = 0 at 2π cos(2πs) = k sin(2πs): the first maximum.
      const double phase = std::atan(2.0 * kPi / kPulseDecay);  // rad, 2π s at the peak
      return std::sin(phase) * std::exp(-kPulseDecay * phase / (2.0 * kPi));
    }
  }
  return 0.0;
}

PulseShape ParsePulseShape(const std::string& name) {
  if (name == "none") return PulseShape::kNone;
  if (name == "reconstructed") return PulseShape::kReconstructed;
  if (name == "half_sine") return PulseShape::kHalfSine;
  if (name == "reconstructed_peak") return PulseShape::kReconstructedPeak;
  if (name == "damped_sine") return PulseShape::kDampedSine;
  Throw<InputError>("ParsePulseShape", "unknown pulse shape '", name,
                    "'; expected one of: reconstructed, half_sine, reconstructed_peak, damped_sine, none");
}

const char* PulseShapeName(PulseShape shape) {
  switch (shape) {
    case PulseShape::kNone: return "none";
    case PulseShape::kReconstructed: return "reconstructed";
    case PulseShape::kHalfSine: return "half_sine";
    case PulseShape::kReconstructedPeak: return "reconstructed_peak";
    case PulseShape::kDampedSine: return "damped_sine";
  }
  return "?";
}

}  // namespace kneedyn
