// Contact kinematics of one pair of smooth surfaces at a pose — the one interface every
// formulation, the consistent initialization, the events, the impact law, the projection
// and the restarts use (docs/model.md §4; chapter Eqs. 1.6–1.13).
//
// Femoral surface Pf(uf, vf) in F, tibial surface Pt(ut, vt) in T, both in their regular
// charts (height_field.hpp: P_u × P_v points to +z). The contact points are where the
// normals are parallel and the separation lies along them, i.e. the four equations
//
//   F1,2 = (Pf − (R0 + R Pt)) · R Pt_{u,v} = 0      separation normal to the tibial surface
//   F3,4 = (R Pt_u × R Pt_v) · Pf_{u,v}    = 0      normals parallel
//
// in z = (uf, vf, ut, vt). The gap is φ = (Pf − (R0 + R Pt)) · n_F with n_F = R n_T the unit
// tibial normal (towards the femur): φ > 0 separated, φ < 0 penetrating.
//
//  - Sphere on plane: closed form (SphereOnPlaneContact in contact.hpp), chosen from the
//    surfaces' SphereForm/PlaneForm.
//  - Any other pair: a starting point (closed-form PointWithNormal of a convex femoral cap,
//    alternated with the tibial chart's projection), then Newton on the 4×4 system with
//    its analytic Jacobian (second chart derivatives), to round-off.
//  - For T = ceres::Jet the double solution is lifted by one Newton step in T
//    (implicit-function theorem): z = z* − J⁻¹ F(z*, pose(T)), exact first derivatives.
//
// Velocity level: because the contact points are stationary, φ̇ = −n_F · (velocity of the
// tibial material point at the contact) = G ν with G from ContactConstraintRow (contact.hpp),
// for every pair. Acceleration level: φ̈ = G ν̇ + κ with κ = (dG/dt) ν (ContactRateTerm;
// closed form for sphere on plane, Jet-differentiated G otherwise).
#pragma once

#include <Eigen/LU>
#include <cmath>
#include <limits>
#include <type_traits>

#include "solver/contact.hpp"
#include "solver/time_dual.hpp"

namespace kneedyn {

// Sphere-on-plane data of a pair when the femoral surface is a sphere and the tibial one a
// plane (from the surfaces' SphereForm/PlaneForm); false otherwise.
bool SphereOnPlaneForm(const ContactPair& pair, SphereOnPlane* out);

// The double-precision local solve of the general case: chart coordinates z and the
// Jacobian ∂F/∂z at the solution. False when no contact point is found inside the charts'
// domains (e.g. the surfaces are far apart or the point left a cap).
struct ContactSolution {
  Eigen::Vector4d z = Eigen::Vector4d::Zero();   // (uf, vf, ut, vt)
  Eigen::Matrix4d jacobian = Eigen::Matrix4d::Zero();
  int iterations = 0;
};
bool SolveContactPoints(const ContactPair& pair, const Pose& pose, ContactSolution* out);

template <typename T>
Pose ScalarPose(const PoseTpl<T>& pose) {
  Pose out;
  for (int i = 0; i < 3; ++i) {
    out.p_FoTo_F(i) = ScalarPart(pose.p_FoTo_F(i));
    for (int j = 0; j < 3; ++j) out.R_FT(i, j) = ScalarPart(pose.R_FT(i, j));
  }
  return out;
}

// F(z, pose) of the header comment, for the Jet lift.
template <typename T, typename Z>
bool ContactPointResiduals(const ContactPair& pair, const PoseTpl<T>& pose, const Z z[4],
                           Vector3<T>* pf, Vector3<T>* pt_T, Vector3<T>* n_T, T F[4]) {
  Vector3<T> pf_u, pf_v, pt_u, pt_v;
  if (!EvaluateChart(*pair.femoral_surface, T(z[0]), T(z[1]), pf, &pf_u, &pf_v)) return false;
  if (!EvaluateChart(*pair.tibial_surface, T(z[2]), T(z[3]), pt_T, &pt_u, &pt_v)) return false;
  const Vector3<T> d = *pf - pose.PointInF(*pt_T);
  const Vector3<T> tt1 = pose.R_FT * pt_u, tt2 = pose.R_FT * pt_v;
  const Vector3<T> m = tt1.cross(tt2);
  F[0] = d.dot(tt1);
  F[1] = d.dot(tt2);
  F[2] = m.dot(pf_u);
  F[3] = m.dot(pf_v);
  *n_T = pt_u.cross(pt_v).normalized();
  return true;
}

// The general solve for a wide scalar (long double, quadruple: neither double nor Jet): the
// double solution refined in T, z ← z − J⁻¹ F_T(z) with F evaluated in T on the surfaces'
// charts in T (surface_wide.hpp) and J the double solve's Jacobian (iterative refinement:
// each iteration gains ~16 digits), to max |Δz_i| ≤ 8 ε_T (1 + |z_i|). False when F leaves
// a chart or 12 iterations do not get there.
template <typename T>
bool RefineContactPointsWide(const ContactPair& pair, const PoseTpl<T>& pose, const ContactSolution& solution,
                             T z[4]) {
  for (int i = 0; i < 4; ++i) z[i] = T(solution.z(i));
  const Eigen::PartialPivLU<Eigen::Matrix4d> lu(solution.jacobian);
  const double eps = static_cast<double>(std::numeric_limits<T>::epsilon());
  Vector3<T> pf, pt, n_T;
  T F[4];
  for (int iteration = 0; iteration < 12; ++iteration) {
    if (!ContactPointResiduals(pair, pose, z, &pf, &pt, &n_T, F)) return false;
    Eigen::Vector4d F_d;
    for (int i = 0; i < 4; ++i) F_d(i) = static_cast<double>(F[i]);
    const Eigen::Vector4d dz = lu.solve(F_d);
    bool converged = true;
    for (int i = 0; i < 4; ++i) {
      z[i] -= T(dz(i));
      if (!(std::abs(dz(i)) <= 8.0 * eps * (1.0 + std::abs(static_cast<double>(z[i]))))) converged = false;
    }
    if (converged) return true;
  }
  return false;
}

// Contact geometry of a pair at a pose: gap, contact points in both frames, unit tibial
// normal (geometry.normal_T; n_F = R n_T). `chart` (optional) receives the regular chart
// coordinates (uf, vf, ut, vt) of the contact points. Returns false when the general solve
// finds no contact point (never for sphere on plane).
template <typename T>
bool ContactKinematics(const ContactPair& pair, const PoseTpl<T>& pose,
                       ContactGeometryTpl<T>* geometry, double chart[4] = nullptr) {
  SphereOnPlane sop;
  if (SphereOnPlaneForm(pair, &sop)) {
    *geometry = SphereOnPlaneContact(sop, pose);
    if (chart != nullptr) {
      Vector3d pf, pt;  // femoral point; tibial point on the plane, φ n′ below it
      for (int i = 0; i < 3; ++i) {
        pf(i) = ScalarPart(geometry->point_F(i));
        pt(i) = ScalarPart(geometry->point_T(i)) - ScalarPart(geometry->gap) * sop.normal_T(i);
      }
      pair.femoral_surface->ChartCoordinates(pf, chart);
      pair.tibial_surface->ChartCoordinates(pt, chart + 2);
    }
    return true;
  }
  ContactSolution sol;
  if (!SolveContactPoints(pair, ScalarPose(pose), &sol)) return false;
  if (chart != nullptr) {
    for (int i = 0; i < 4; ++i) chart[i] = sol.z(i);
  }
  Vector3<T> pf, pt, n_T;
  T F[4];
  if constexpr (!IsDoubleOrJet<T>::value) {
    T z[4];
    if (!RefineContactPointsWide(pair, pose, sol, z)) return false;
    ContactPointResiduals(pair, pose, z, &pf, &pt, &n_T, F);
    geometry->point_F = pf;
    geometry->point_T = pt;
    geometry->normal_T = n_T;
    geometry->gap = (pf - pose.PointInF(pt)).dot(pose.R_FT * n_T);
    return true;
  }
  // Lift: z = z* − J⁻¹ F(z*, pose) with only the derivative part kept (F(z*) ≈ 0).
  const double* z0 = sol.z.data();
  if (!ContactPointResiduals(pair, pose, z0, &pf, &pt, &n_T, F)) return false;
  const Eigen::Matrix4d Jinv = sol.jacobian.inverse();
  T z[4];
  for (int i = 0; i < 4; ++i) {
    T dz = T(0.0);
    for (int j = 0; j < 4; ++j) dz -= Jinv(i, j) * F[j];
    z[i] = T(z0[i]) + (dz - T(ScalarPart(dz)));
  }
  T unused[4];
  ContactPointResiduals(pair, pose, z, &pf, &pt, &n_T, unused);
  // Mixed second derivatives (TimeDual over a Jet, time_dual.hpp): each further chord step
  // with the same J⁻¹ makes the lift exact to one more order (its error is the previous
  // error times a first-order term).
  for (int order = 1; order < DerivativeOrder<T>::value; ++order) {
    for (int i = 0; i < 4; ++i) {
      T dz = T(0.0);
      for (int j = 0; j < 4; ++j) dz -= Jinv(i, j) * unused[j];
      z[i] += dz - T(ScalarPart(dz));
    }
    ContactPointResiduals(pair, pose, z, &pf, &pt, &n_T, unused);
  }
  geometry->point_F = pf;
  geometry->point_T = pt;
  geometry->normal_T = n_T;
  geometry->gap = (pf - pose.PointInF(pt)).dot(pose.R_FT * n_T);
  return true;
}

// ContactKinematics in double; throws SolverError naming the compartment and `caller` when
// no contact point is found.
ContactGeometry RequireContactKinematics(const ContactPair& pair, const Pose& pose,
                                         const char* caller, double chart[4] = nullptr);

// κ of a sphere on a plane (the gap is linear in R0; n = R n̂′), any scalar type:
//   κ = (w_F × (w_F × n)) · (C − R0) − 2 (w_F × n) · v_F.
template <typename T>
T SphereOnPlaneRateTerm(const SphereOnPlane& sop, const PoseTpl<T>& pose, const Vector6<T>& nu) {
  const Vector3<T> n = pose.R_FT * sop.normal_T.template cast<T>();
  const Vector3<T> w_F = pose.R_FT * Vector3<T>(nu.template tail<3>());
  const Vector3<T> v_F = nu.template head<3>();
  const Vector3<T> wxn = w_F.cross(n);
  return w_F.cross(wxn).dot(sop.centre_F.template cast<T>() - pose.p_FoTo_F) - T(2.0) * wxn.dot(v_F);
}

// RequireContactKinematics for any scalar type (a wide scalar: the closed form, or the double
// solve refined in T, RefineContactPointsWide).
template <typename T>
ContactGeometryTpl<T> RequireContactKinematicsTpl(const ContactPair& pair, const PoseTpl<T>& pose,
                                                  const char* caller) {
  if constexpr (std::is_same_v<T, double>) {
    return RequireContactKinematics(pair, pose, caller);
  } else {
    ContactGeometryTpl<T> geometry;
    if (!ContactKinematics(pair, pose, &geometry)) {
      Throw<SolverError>(caller, "no contact point found for the ", CompartmentName(pair.compartment),
                         " pair (femoral ", pair.femoral_surface->Describe(), ", tibial ",
                         pair.tibial_surface->Describe(), ") in extended precision (rule: the normals must be "
                         "parallel inside both surfaces' domains, and the refinement converge)");
    }
    return geometry;
  }
}

// κ = (dG/dt) ν of any pair: G along the path q(t) = q + t q̇ in the scalar Path (a
// one-direction dual over T: ceres::Jet<double, 1> for T = double, TimeDual<T> for a Jet,
// time_dual.hpp; TimeDerivative reads the direction). The pose of the path is the general
// solve's (ContactKinematics), so T = Jet gives κ with its exact derivatives in (q, q̇).
template <typename Path, typename T>
T ContactRateTermAlongPath(const ContactPair& pair, const Vector6<T>& q, const Vector6<T>& qd, const Vector6<T>& nu) {
  Vector6<Path> q_path;
  for (int i = 0; i < 6; ++i) {
    q_path(i) = Path(q(i));
    TimeDerivativeRef(q_path(i)) = qd(i);
  }
  const PoseTpl<Path> pose_path = PoseFromCoordinates(q_path);
  ContactGeometryTpl<Path> geo;
  if (!ContactKinematics(pair, pose_path, &geo)) {
    RequireContactKinematics(pair, ScalarPose(pose_path), "ContactRateTerm");
  }
  const Eigen::Matrix<Path, 1, 6> G = ContactConstraintRow(pose_path, geo);
  T kappa = T(0.0);
  for (int i = 0; i < 6; ++i) kappa += TimeDerivativeRef(G(i)) * nu(i);
  return kappa;
}

// κ in φ̈ = G ν̇ + κ at (q, q̇) (header comment). Throws like RequireContactKinematics.
double ContactRateTerm(const ContactPair& pair, const Vector6d& q, const Vector6d& qd);
// The same with the pose and ν = (v_F, w_T) of (q, q̇) already at hand (the hidden-constraint
// solve computes them once for all contacts).
double ContactRateTerm(const ContactPair& pair, const Vector6d& q, const Vector6d& qd, const Pose& pose,
                       const Vector6d& nu);
// κ for a wider scalar (long double, quadruple): sphere on plane in closed form; another pair
// as κ = (dG/ds) ν along q(s) = q + s q̇ by the fourth-order central difference
// (−G(2δ) + 8 G(δ) − 8 G(−δ) + G(−2δ)) / (12 δ), δ = 1e-7 s, each G from the contact points
// refined in T: truncation ~δ⁴ G⁽⁵⁾ ≈ 1e-28 and round-off ~ε_T/δ ≈ 1e-27 in quadruple
// precision, far below double's 1e-16 (the double path's Jet over double would carry
// double round-off). Throws SolverError like RequireContactKinematicsTpl.
template <typename T>
T ContactRateTermTpl(const ContactPair& pair, const Vector6<T>& q, const Vector6<T>& qd, const PoseTpl<T>& pose,
                     const Vector6<T>& nu) {
  if constexpr (std::is_same_v<T, double>) {
    return ContactRateTerm(pair, q, qd, pose, nu);
  } else {
    SphereOnPlane sop;
    if (SphereOnPlaneForm(pair, &sop)) return SphereOnPlaneRateTerm(sop, pose, nu);
    const T delta = T(1e-7);  // s
    auto row = [&](int k) {
      const PoseTpl<T> shifted = PoseFromCoordinates(Vector6<T>(q + (T(k) * delta) * qd));
      return ContactConstraintRow(shifted, RequireContactKinematicsTpl(pair, shifted, "ContactRateTerm"));
    };
    const Eigen::Matrix<T, 1, 6> dG = (row(-2) - T(8) * row(-1) + T(8) * row(1) - row(2)) / (T(12) * delta);
    return dG.dot(nu);
  }
}

}  // namespace kneedyn
