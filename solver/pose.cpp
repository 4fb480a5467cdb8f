#include "solver/pose.hpp"

#include <Eigen/LU>

namespace kneedyn {

const char* CoordinateName(int i) {
  static const char* kNames[kNumCoordinates] = {"x0", "y0", "z0", "alpha", "beta", "gamma"};
  return (i >= 0 && i < kNumCoordinates) ? kNames[i] : "?";
}

Vector6d CoordinateAcceleration(const Vector6d& q, const Vector6d& qd, const Vector6d& nu_dot) {
  const Matrix3d E = AngularVelocityMap(q(kBeta), q(kGamma));
  const Vector3d qd_ang = qd.tail<3>();
  Vector6d qdd;
  qdd.head<3>() = nu_dot.head<3>();
  qdd.tail<3>() = E.partialPivLu().solve(
      nu_dot.tail<3>() - AngularVelocityMapRateTimesRate(q(kBeta), q(kGamma), qd_ang));
  return qdd;
}

Vector6d CoordinateVelocity(const Vector6d& q, const Vector6d& nu) {
  const Matrix3d E = AngularVelocityMap(q(kBeta), q(kGamma));
  Vector6d qd;
  qd.head<3>() = nu.head<3>();
  qd.tail<3>() = E.partialPivLu().solve(Vector3d(nu.tail<3>()));
  return qd;
}

}  // namespace kneedyn
