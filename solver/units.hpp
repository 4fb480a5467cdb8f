// Units. Internally SI (m, kg, s, N, rad); data tables are in mm and degrees and are
// converted once, at load time (docs/model.md §1). Output files convert back and say so in headers.
#pragma once

namespace kneedyn {

constexpr double kPi = 3.14159265358979323846;
constexpr double kMmPerM = 1000.0;
constexpr double kMPerMm = 1.0e-3;
constexpr double kDegPerRad = 180.0 / kPi;
constexpr double kRadPerDeg = kPi / 180.0;

constexpr double MmToM(double mm) { return mm * kMPerMm; }
constexpr double MToMm(double m) { return m * kMmPerM; }
constexpr double DegToRad(double deg) { return deg * kRadPerDeg; }
constexpr double RadToDeg(double rad) { return rad * kDegPerRad; }

}  // namespace kneedyn
