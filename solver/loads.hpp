// External loads (spec §7): the impact pulse and its shapes. Gravity and constant loads
// are applied in dynamics.hpp.
#pragma once

#include <string>

#include "solver/model.hpp"

namespace kneedyn {

// Pulse magnitude Fe(t) in N (positive along pulse.direction_T).
//   reconstructed: A (t/t0) sin(2π t/t0) exp(−4.73 t/t0)   (Eq. 1.62 as reconstructed)
//   half_sine:     A sin(π t/t0) for 0 ≤ t ≤ t0, else 0
//   none:          0
// Zero for t < 0.
double PulseMagnitude(const Pulse& pulse, double t);

// Scene-file spelling of the shapes: "reconstructed", "half_sine", "none".
PulseShape ParsePulseShape(const std::string& name);  // throws InputError
const char* PulseShapeName(PulseShape shape);

}  // namespace kneedyn
