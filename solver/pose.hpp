// Pose of the tibia from generalized coordinates, and the generalized-velocity map.
// Notation: see rotation.hpp.  q = (x0, y0, z0 [m], α, β, γ [rad]).
// ν = (v_F, w_T): velocity of the centre of mass in F (m/s) and angular velocity in T (rad/s);
// ν = B(q) q̇ with B = diag(I, E(β, γ)).
#pragma once

#include "solver/rotation.hpp"

namespace kneedyn {

// Indices into q and q̇.
enum CoordinateIndex { kX0 = 0, kY0 = 1, kZ0 = 2, kAlpha = 3, kBeta = 4, kGamma = 5 };
constexpr int kNumCoordinates = 6;
const char* CoordinateName(int i);  // "x0", ..., "gamma"

template <typename T>
struct PoseTpl {
  Vector3<T> p_FoTo_F;  // R0, m
  Matrix3<T> R_FT;

  // Femoral coordinates of a point given in tibial coordinates: P = R0 + R r (Eq. 1.2).
  Vector3<T> PointInF(const Vector3<T>& p_T) const { return p_FoTo_F + R_FT * p_T; }
  Vector3<T> PointInT(const Vector3<T>& p_F) const {
    return R_FT.transpose() * (p_F - p_FoTo_F);
  }
};
using Pose = PoseTpl<double>;

// The sines and cosines of q's Euler angles: computed once per pose and passed to the
// overloads below that take them (rotation.hpp).
template <typename T>
EulerAngleTrig<T> EulerAngleTrigOf(const Vector6<T>& q) {
  return EulerAngleTrigOf(q(kAlpha), q(kBeta), q(kGamma));
}

template <typename T>
PoseTpl<T> PoseFromCoordinates(const Vector6<T>& q, const EulerAngleTrig<T>& trig) {
  PoseTpl<T> pose;
  pose.p_FoTo_F = q.template head<3>();
  pose.R_FT = RotationFT(trig);
  return pose;
}

template <typename T>
PoseTpl<T> PoseFromCoordinates(const Vector6<T>& q) {
  return PoseFromCoordinates(q, EulerAngleTrigOf(q));
}

// w_T = E(β, γ) (α̇, β̇, γ̇).
template <typename T>
Vector3<T> AngularVelocityT(const Vector6<T>& q, const EulerAngleTrig<T>& trig, const Vector6<T>& qd) {
  return AngularVelocityMap(q(kBeta), trig) * qd.template tail<3>();
}

template <typename T>
Vector3<T> AngularVelocityT(const Vector6<T>& q, const Vector6<T>& qd) {
  return AngularVelocityMap(q(kBeta), q(kGamma)) * qd.template tail<3>();
}

// ν = (v_F, w_T) from q̇ and E = AngularVelocityMap(β, trig) of q, for a caller that has E
// already (the DAE residual: E once per pose for ν, ν̇ and the GGL terms).
template <typename T>
Vector6<T> GeneralizedVelocity(const Matrix3<T>& E, const Vector6<T>& qd) {
  Vector6<T> nu;
  nu.template head<3>() = qd.template head<3>();
  nu.template tail<3>() = E * qd.template tail<3>();
  return nu;
}

// ν = (v_F, w_T) from (q, q̇).
template <typename T>
Vector6<T> GeneralizedVelocity(const Vector6<T>& q, const EulerAngleTrig<T>& trig, const Vector6<T>& qd) {
  return GeneralizedVelocity(AngularVelocityMap(q(kBeta), trig), qd);
}

// The same without α's sine and cosine, which E does not use.
template <typename T>
Vector6<T> GeneralizedVelocity(const Vector6<T>& q, const Vector6<T>& qd) {
  return GeneralizedVelocity(AngularVelocityMap(q(kBeta), q(kGamma)), qd);
}

// ν̇ = (a_F, ẇ_T) from (q̇, q̈) and E = AngularVelocityMap(β, trig) of q:
// ẇ_T = E q̈_ang + Ė q̇_ang.
template <typename T>
Vector6<T> GeneralizedAcceleration(const Matrix3<T>& E, const EulerAngleTrig<T>& trig, const Vector6<T>& qd,
                                   const Vector6<T>& qdd) {
  Vector6<T> nud;
  nud.template head<3>() = qdd.template head<3>();
  const Vector3<T> qd_ang = qd.template tail<3>();
  nud.template tail<3>() = E * qdd.template tail<3>() + AngularVelocityMapRateTimesRate(trig, qd_ang);
  return nud;
}

// ν̇ = (a_F, ẇ_T) from (q, q̇, q̈).
template <typename T>
Vector6<T> GeneralizedAcceleration(const Vector6<T>& q, const EulerAngleTrig<T>& trig, const Vector6<T>& qd,
                                   const Vector6<T>& qdd) {
  return GeneralizedAcceleration(AngularVelocityMap(q(kBeta), trig), trig, qd, qdd);
}

template <typename T>
Vector6<T> GeneralizedAcceleration(const Vector6<T>& q, const Vector6<T>& qd, const Vector6<T>& qdd) {
  return GeneralizedAcceleration(q, EulerAngleTrigOf(q), qd, qdd);
}

// x = E(β, γ)⁻¹ r in closed form (rotation.hpp: the leading 2×2 block of E has
// determinant sin β, its third column is −k̂′). Throws at the JCS singularity.
template <typename T>
Vector3<T> SolveAngularVelocityMap(const T& beta, const EulerAngleTrig<T>& trig, const Vector3<T>& r,
                                   const char* caller) {
  CheckJcsRegular(ScalarPart(beta), ScalarPart(trig.sb), caller);
  const T &sb = trig.sb, &cb = trig.cb;
  const T &sg = trig.sg, &cg = trig.cg;
  Vector3<T> x;
  if (ThreadAngularVelocityMapReading() == AngularVelocityMapReading::kPrintedEq1_20b) {
    // E(1, 1) = +cγ (Eq. 1.20b): the 2×2 block's determinant is −sin β cos 2γ.
    const T det = -sb * (cg * cg - sg * sg);
    if (std::abs(static_cast<double>(ScalarPart(det))) < kJcsSingularityTolerance) {
      Throw<SolverError>(caller, "the printed map of Eq. 1.20b is singular at gamma = ",
                         std::atan2(static_cast<double>(ScalarPart(sg)), static_cast<double>(ScalarPart(cg))), " rad (|sin beta cos 2 gamma| = ",
                         std::abs(static_cast<double>(ScalarPart(det))), " < ", kJcsSingularityTolerance, "; docs/model.md §2)");
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

// q̈ from ν̇ for any scalar type (the double overloads below call it).
template <typename T>
Vector6<T> CoordinateAccelerationTpl(const Vector6<T>& q, const EulerAngleTrig<T>& trig, const Vector6<T>& qd,
                                     const Vector6<T>& nu_dot) {
  const Vector3<T> qd_ang = qd.template tail<3>();
  Vector6<T> qdd;
  qdd.template head<3>() = nu_dot.template head<3>();
  qdd.template tail<3>() = SolveAngularVelocityMap<T>(
      q(kBeta), trig, nu_dot.template tail<3>() - AngularVelocityMapRateTimesRate(trig, qd_ang),
      "CoordinateAcceleration");
  return qdd;
}

// Inverse of the above: q̈ from ν̇ (q̈_ang = E⁻¹ (ẇ_T − Ė q̇_ang)). Throws at the singularity.
Vector6d CoordinateAcceleration(const Vector6d& q, const Vector6d& qd, const Vector6d& nu_dot);
Vector6d CoordinateAcceleration(const Vector6d& q, const EulerAngleTrig<double>& trig, const Vector6d& qd,
                                const Vector6d& nu_dot);
// q̇ from ν (q̇_ang = E⁻¹ w_T).
Vector6d CoordinateVelocity(const Vector6d& q, const Vector6d& nu);

}  // namespace kneedyn
