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

template <typename T>
Matrix3<T> RotationFT(const T& alpha, const T& beta, const T& gamma) {
  using std::cos;
  using std::sin;
  const T sa = sin(alpha), ca = cos(alpha);
  const T sb = sin(beta), cb = cos(beta);
  const T sg = sin(gamma), cg = cos(gamma);
  Matrix3<T> R;
  R << sb * cg, sb * sg, cb,                                 //
      -ca * sg - sa * cb * cg, ca * cg - sa * cb * sg, sa * sb,  //
      sa * sg - ca * cb * cg, -sa * cg - ca * cb * sg, ca * sb;
  return R;
}

// Throws SolverError when the pose is at the JCS singularity (sin β ≈ 0).
inline void CheckJcsRegular(double beta, const char* caller) {
  if (std::abs(std::sin(beta)) < kJcsSingularityTolerance) {
    Throw<SolverError>(caller, "pose at the JCS singularity: beta = ", beta,
                       " rad (|sin beta| = ", std::abs(std::sin(beta)), " < ",
                       kJcsSingularityTolerance,
                       "); the angular-velocity map E is singular there (spec §2)");
  }
}

// E(β, γ): w_T = E · (α̇, β̇, γ̇). Throws at the JCS singularity.
template <typename T>
Matrix3<T> AngularVelocityMap(const T& beta, const T& gamma) {
  using std::cos;
  using std::sin;
  CheckJcsRegular(ScalarPart(beta), "AngularVelocityMap");
  const T sb = sin(beta), cb = cos(beta);
  const T sg = sin(gamma), cg = cos(gamma);
  Matrix3<T> E;
  E << -sb * cg, sg, T(0.0),  //
      -sb * sg, -cg, T(0.0),  //
      -cb, T(0.0), T(-1.0);
  return E;
}

// Ė · (α̇, β̇, γ̇): the velocity-product term of ẇ_T = E q̈_ang + Ė q̇_ang.
template <typename T>
Vector3<T> AngularVelocityMapRateTimesRate(const T& beta, const T& gamma,
                                           const Vector3<T>& qd_ang) {
  using std::cos;
  using std::sin;
  const T sb = sin(beta), cb = cos(beta);
  const T sg = sin(gamma), cg = cos(gamma);
  const T& ad = qd_ang(0);
  const T& bd = qd_ang(1);
  const T& gd = qd_ang(2);
  // d(î)/dt = î_β β̇ + î_γ γ̇;  d(ê2)/dt = ê2_γ γ̇;  k̂′ constant.
  const Vector3<T> di(cb * cg * bd - sb * sg * gd, cb * sg * bd + sb * cg * gd, -sb * bd);
  const Vector3<T> de2(-cg * gd, -sg * gd, T(0.0));
  return -di * ad - de2 * bd;
}

// ∂R_FT/∂α, ∂R_FT/∂β, ∂R_FT/∂γ (analytic; checked against finite differences in tests).
inline void RotationPartials(double alpha, double beta, double gamma, Matrix3d dR[3]) {
  const double sa = std::sin(alpha), ca = std::cos(alpha);
  const double sb = std::sin(beta), cb = std::cos(beta);
  const double sg = std::sin(gamma), cg = std::cos(gamma);
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

}  // namespace kneedyn
