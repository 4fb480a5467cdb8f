// Grood–Suntay joint coordinate system (docs/model.md §2; chapter Eq. 1.3 reconstructed).
//
// Frame notation (Drake's monogram notation), used throughout kneedyn:
//   F  femoral frame (fixed): x lateral (right knee), y anterior, z proximal.
//   T  tibial frame: origin at the leg's centre of mass, principal axes; T ∥ F at full
//      extension.
//   R_FT      rotation taking T components to F components.
//   p_FoTo_F  position of T's origin in F (the chapter's R0 = (x0, y0, z0)), metres.
//   w_T       angular velocity of T relative to F, T components (the chapter's ω′), rad/s.
//   Suffix _F / _T on any vector: the frame its components are in.
//
// Generalized coordinates q = (x0, y0, z0, α, β, γ): α flexion, β = π/2 + valgus,
// γ tibial external rotation. Angle rates qd_ang = (α̇, β̇, γ̇).
//
//   R_FT = Rx(−α) · Ry(π/2 − β) · Rz(−γ)
//   w_T  = E(β, γ) · (α̇, β̇, γ̇),   E = [−î, −ê2, −k̂′] (columns, T components),
//     î = (sβ cγ, sβ sγ, cβ), ê2 = (−sγ, cγ, 0), k̂′ = (0, 0, 1);   det E = −sin β.
// Departure from the chapter: Eqs. 1.20/1.21 are not the true angular velocity; this is the
// exact map (docs/model.md §2). E is singular at sin β = 0 (JCS gimbal lock): reported as an error.
#pragma once

#include <cmath>

#include "solver/error.hpp"
#include "solver/scalar.hpp"

namespace kneedyn {

// |sin β| below this is treated as the JCS singularity (β within ~0.06° of 0 or π).
constexpr double kJcsSingularityTolerance = 1.0e-3;

// Sines and cosines of the Euler angles (α, β, γ) of one pose, computed once and passed to
// everything that needs R_FT, E, Ė q̇_ang or ∂R_FT/∂q at that pose (each sin/cos costs
// ~100 instructions; a residual used to take 22 of them for 6 distinct values).
template <typename T>
struct EulerAngleTrig {
  T sa, ca, sb, cb, sg, cg;
};

template <typename T>
EulerAngleTrig<T> EulerAngleTrigOf(const T& alpha, const T& beta, const T& gamma) {
  using std::cos;
  using std::sin;
  return {sin(alpha), cos(alpha), sin(beta), cos(beta), sin(gamma), cos(gamma)};
}

template <typename T>
Matrix3<T> RotationFT(const EulerAngleTrig<T>& trig) {
  const T& sa = trig.sa;
  const T& ca = trig.ca;
  const T& sb = trig.sb;
  const T& cb = trig.cb;
  const T& sg = trig.sg;
  const T& cg = trig.cg;
  Matrix3<T> R;
  R << sb * cg, sb * sg, cb,                                 //
      -ca * sg - sa * cb * cg, ca * cg - sa * cb * sg, sa * sb,  //
      sa * sg - ca * cb * cg, -sa * cg - ca * cb * sg, ca * sb;
  return R;
}

template <typename T>
Matrix3<T> RotationFT(const T& alpha, const T& beta, const T& gamma) {
  return RotationFT(EulerAngleTrigOf(alpha, beta, gamma));
}

// True inside the band |sin β| < kJcsSingularityTolerance where E is taken as singular.
inline bool IsAtJcsSingularity(double sin_beta) { return std::abs(sin_beta) < kJcsSingularityTolerance; }

// |sin β| of a pose below kJcsSingularityTolerance: SolverError naming the caller.
inline void CheckJcsRegular(double beta, double sin_beta, const char* caller) {
  if (IsAtJcsSingularity(sin_beta)) {
    Throw<SolverError>(caller, "pose at the JCS singularity: beta = ", beta,
                       " rad (|sin beta| = ", std::abs(sin_beta), " < ",
                       kJcsSingularityTolerance,
                       "); the angular-velocity map E is singular there (docs/model.md §2)");
  }
}

// Throws SolverError when the pose is at the JCS singularity (sin β ≈ 0).
inline void CheckJcsRegular(double beta, const char* caller) {
  CheckJcsRegular(beta, std::sin(beta), caller);
}

// Which map from (α̇, β̇, γ̇) to w_T a run uses (docs/model.md §2). kExact is the angular
// velocity of R_FT. kPrintedEq1_20b is the chapter's printed Eq. 1.20b, whose β̇ cos γ term of
// ω′y has the sign + (Eq. 1.28b and the exact map have −): a reading of the chapter, not an
// angular velocity (E's leading 2×2 block then has determinant −sin β cos 2γ).
enum class AngularVelocityMapReading { kExact, kPrintedEq1_20b };

// The reading of the map on this thread. A run sets it for its whole life from its model
// (ScopedAngularVelocityMapReading in the hybrid simulator), so that the free functions below
// and every formulation that calls them need no extra argument; outside a run it is kExact.
inline AngularVelocityMapReading& ThreadAngularVelocityMapReading() {
  thread_local AngularVelocityMapReading reading = AngularVelocityMapReading::kExact;
  return reading;
}

class ScopedAngularVelocityMapReading {
 public:
  explicit ScopedAngularVelocityMapReading(AngularVelocityMapReading reading)
      : previous_(ThreadAngularVelocityMapReading()) {
    ThreadAngularVelocityMapReading() = reading;
  }
  ~ScopedAngularVelocityMapReading() { ThreadAngularVelocityMapReading() = previous_; }
  ScopedAngularVelocityMapReading(const ScopedAngularVelocityMapReading&) = delete;
  ScopedAngularVelocityMapReading& operator=(const ScopedAngularVelocityMapReading&) = delete;

 private:
  AngularVelocityMapReading previous_;
};

// E(β, γ): w_T = E · (α̇, β̇, γ̇). Throws at the JCS singularity (`beta` only names it there).
template <typename T>
Matrix3<T> AngularVelocityMap(const T& beta, const EulerAngleTrig<T>& trig) {
  CheckJcsRegular(ScalarPart(beta), ScalarPart(trig.sb), "AngularVelocityMap");
  const T& sb = trig.sb;
  const T& cb = trig.cb;
  const T& sg = trig.sg;
  const T& cg = trig.cg;
  Matrix3<T> E;
  E << -sb * cg, sg, T(0.0),  //
      -sb * sg, -cg, T(0.0),  //
      -cb, T(0.0), T(-1.0);
  if (ThreadAngularVelocityMapReading() == AngularVelocityMapReading::kPrintedEq1_20b) {
    E(1, 1) = cg;  // Eq. 1.20b: ω′y = … + β̇ cos γ
  }
  return E;
}

template <typename T>
Matrix3<T> AngularVelocityMap(const T& beta, const T& gamma) {
  using std::cos;
  using std::sin;
  return AngularVelocityMap(beta, EulerAngleTrig<T>{T(0.0), T(1.0), sin(beta), cos(beta), sin(gamma), cos(gamma)});
}

// Ė · (α̇, β̇, γ̇): the velocity-product term of ẇ_T = E q̈_ang + Ė q̇_ang.
template <typename T>
Vector3<T> AngularVelocityMapRateTimesRate(const EulerAngleTrig<T>& trig, const Vector3<T>& qd_ang) {
  const T& sb = trig.sb;
  const T& cb = trig.cb;
  const T& sg = trig.sg;
  const T& cg = trig.cg;
  const T& ad = qd_ang(0);
  const T& bd = qd_ang(1);
  const T& gd = qd_ang(2);
  // d(î)/dt = î_β β̇ + î_γ γ̇;  d(ê2)/dt = ê2_γ γ̇;  k̂′ constant.
  const Vector3<T> di(cb * cg * bd - sb * sg * gd, cb * sg * bd + sb * cg * gd, -sb * bd);
  const Vector3<T> de2(-cg * gd, -sg * gd, T(0.0));
  if (ThreadAngularVelocityMapReading() == AngularVelocityMapReading::kPrintedEq1_20b) {
    // E's β column is (sγ, +cγ, 0): its rate is (cγ γ̇, −sγ γ̇, 0).
    const Vector3<T> dcol_beta(cg * gd, -sg * gd, T(0.0));
    return -di * ad + dcol_beta * bd;
  }
  return -di * ad - de2 * bd;
}

template <typename T>
Vector3<T> AngularVelocityMapRateTimesRate(const T& beta, const T& gamma,
                                           const Vector3<T>& qd_ang) {
  using std::cos;
  using std::sin;
  return AngularVelocityMapRateTimesRate(
      EulerAngleTrig<T>{T(0.0), T(1.0), sin(beta), cos(beta), sin(gamma), cos(gamma)}, qd_ang);
}

// ∂R_FT/∂α, ∂R_FT/∂β, ∂R_FT/∂γ (analytic; checked against finite differences in tests).
inline void RotationPartials(const EulerAngleTrig<double>& trig, Matrix3d dR[3]) {
  const double sa = trig.sa, ca = trig.ca;
  const double sb = trig.sb, cb = trig.cb;
  const double sg = trig.sg, cg = trig.cg;
  dR[0] << 0, 0, 0,                                      //
      sa * sg - ca * cb * cg, -sa * cg - ca * cb * sg, ca * sb,  //
      ca * sg + sa * cb * cg, -ca * cg + sa * cb * sg, -sa * sb;
  dR[1] << cb * cg, cb * sg, -sb,    //
      sa * sb * cg, sa * sb * sg, sa * cb,  //
      ca * sb * cg, ca * sb * sg, ca * cb;
  dR[2] << -sb * sg, sb * cg, 0,                         //
      -ca * cg + sa * cb * sg, -ca * sg - sa * cb * cg, 0,  //
      sa * cg + ca * cb * sg, sa * sg - ca * cb * cg, 0;
}

inline void RotationPartials(double alpha, double beta, double gamma, Matrix3d dR[3]) {
  RotationPartials(EulerAngleTrigOf(alpha, beta, gamma), dR);
}

}  // namespace kneedyn
