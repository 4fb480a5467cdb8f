#include "solver/pose.hpp"

#include <cmath>

namespace kneedyn {

const char* CoordinateName(int i) {
  static const char* kNames[kNumCoordinates] = {"x0", "y0", "z0", "alpha", "beta", "gamma"};
  return (i >= 0 && i < kNumCoordinates) ? kNames[i] : "?";
}

namespace {
// x = E(β, γ)⁻¹ r in closed form (rotation.hpp: the leading 2×2 block of E has
// determinant sin β, its third column is −k̂′). Throws at the JCS singularity.
Vector3d SolveAngularVelocityMap(double beta, const EulerAngleTrig<double>& trig, const Vector3d& r,
                                 const char* caller) {
  CheckJcsRegular(beta, trig.sb, caller);
  const double sb = trig.sb, cb = trig.cb;
  const double sg = trig.sg, cg = trig.cg;
  Vector3d x;
  if (ThreadAngularVelocityMapReading() == AngularVelocityMapReading::kPrintedEq1_20b) {
    // E(1, 1) = +cγ (Eq. 1.20b): the 2×2 block's determinant is −sin β cos 2γ.
    const double det = -sb * (cg * cg - sg * sg);
    if (std::abs(det) < kJcsSingularityTolerance) {
      Throw<SolverError>(caller, "the printed map of Eq. 1.20b is singular at gamma = ", std::atan2(sg, cg),
                         " rad (|sin beta cos 2 gamma| = ", std::abs(det), " < ", kJcsSingularityTolerance,
                         "; docs/model.md §2)");
    }
    x(0) = (cg * r(0) - sg * r(1)) / det;
    x(1) = sb * (sg * r(0) - cg * r(1)) / det;
    x(2) = -r(2) - cb * x(0);
    return x;
  }
  x(0) = (-cg * r(0) - sg * r(1)) / sb;
  x(1) = sg * r(0) - cg * r(1);
  x(2) = -r(2) - cb * x(0);
  return x;
}
}  // namespace

Vector6d CoordinateAcceleration(const Vector6d& q, const EulerAngleTrig<double>& trig, const Vector6d& qd,
                                const Vector6d& nu_dot) {
  const Vector3d qd_ang = qd.tail<3>();
  Vector6d qdd;
  qdd.head<3>() = nu_dot.head<3>();
  qdd.tail<3>() = SolveAngularVelocityMap(
      q(kBeta), trig, nu_dot.tail<3>() - AngularVelocityMapRateTimesRate(trig, qd_ang), "CoordinateAcceleration");
  return qdd;
}

Vector6d CoordinateAcceleration(const Vector6d& q, const Vector6d& qd, const Vector6d& nu_dot) {
  return CoordinateAcceleration(q, EulerAngleTrigOf(q), qd, nu_dot);
}

Vector6d CoordinateVelocity(const Vector6d& q, const Vector6d& nu) {
  Vector6d qd;
  qd.head<3>() = nu.head<3>();
  qd.tail<3>() = SolveAngularVelocityMap(q(kBeta), EulerAngleTrigOf(q), Vector3d(nu.tail<3>()), "CoordinateVelocity");
  return qd;
}

}  // namespace kneedyn
