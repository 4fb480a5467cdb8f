#include "solver/pose.hpp"

#include <cmath>

namespace kneedyn {

const char* CoordinateName(int i) {
  static const char* kNames[kNumCoordinates] = {"x0", "y0", "z0", "alpha", "beta", "gamma"};
  return (i >= 0 && i < kNumCoordinates) ? kNames[i] : "?";
}

Vector6d CoordinateAcceleration(const Vector6d& q, const EulerAngleTrig<double>& trig, const Vector6d& qd,
                                const Vector6d& nu_dot) {
  return CoordinateAccelerationTpl(q, trig, qd, nu_dot);
}

Vector6d CoordinateAcceleration(const Vector6d& q, const Vector6d& qd, const Vector6d& nu_dot) {
  return CoordinateAcceleration(q, EulerAngleTrigOf(q), qd, nu_dot);
}

Vector6d CoordinateVelocity(const Vector6d& q, const Vector6d& nu) {
  Vector6d qd;
  qd.head<3>() = nu.head<3>();
  qd.tail<3>() = SolveAngularVelocityMap<double>(q(kBeta), EulerAngleTrigOf(q), Vector3d(nu.tail<3>()), "CoordinateVelocity");
  return qd;
}

}  // namespace kneedyn
