#include "solver/contact_kinematics.hpp"

#include <cmath>

#include "solver/error.hpp"

namespace kneedyn {

bool SphereOnPlaneForm(const ContactPair& pair, SphereOnPlane* out) {
  return pair.femoral_surface->SphereForm(&out->centre_F, &out->radius) &&
         pair.tibial_surface->PlaneForm(&out->normal_T, &out->offset);
}

namespace {

constexpr int kMaxNewtonIterations = 30;
constexpr int kStartRounds = 4;
// Newton stops when the step in every chart coordinate is below this (chart units: rad
// for angle charts, m for height-field charts — both far below any physical scale).
constexpr double kStepTolerance = 1.0e-14;

// F and ∂F/∂z at z (header of contact_kinematics.hpp).
bool EvaluateSystem(const ContactPair& pair, const Pose& pose, const Eigen::Vector4d& z,
                    Eigen::Vector4d* F, Eigen::Matrix4d* J, double* orientation) {
  ChartSample f, t;
  if (!pair.femoral_surface->EvaluateChart(z(0), z(1), &f)) return false;
  if (!pair.tibial_surface->EvaluateChart(z(2), z(3), &t)) return false;
  const Matrix3d& R = pose.R_FT;
  const Vector3d d = f.p - pose.PointInF(t.p);
  const Vector3d tt1 = R * t.p_u, tt2 = R * t.p_v;
  const Vector3d a = R * t.p_uu, b = R * t.p_uv, c = R * t.p_vv;
  const Vector3d m = tt1.cross(tt2);
  (*F) << d.dot(tt1), d.dot(tt2), m.dot(f.p_u), m.dot(f.p_v);
  // ∂/∂uf, ∂/∂vf
  (*J)(0, 0) = f.p_u.dot(tt1);
  (*J)(1, 0) = f.p_u.dot(tt2);
  (*J)(2, 0) = m.dot(f.p_uu);
  (*J)(3, 0) = m.dot(f.p_uv);
  (*J)(0, 1) = f.p_v.dot(tt1);
  (*J)(1, 1) = f.p_v.dot(tt2);
  (*J)(2, 1) = m.dot(f.p_uv);
  (*J)(3, 1) = m.dot(f.p_vv);
  // ∂/∂ut, ∂/∂vt: d_u = −tt1, (tt1)_u = a, (tt2)_u = b; d_v = −tt2, (tt1)_v = b, (tt2)_v = c.
  const Vector3d m_u = a.cross(tt2) + tt1.cross(b);
  const Vector3d m_v = b.cross(tt2) + tt1.cross(c);
  (*J)(0, 2) = -tt1.dot(tt1) + d.dot(a);
  (*J)(1, 2) = -tt1.dot(tt2) + d.dot(b);
  (*J)(2, 2) = m_u.dot(f.p_u);
  (*J)(3, 2) = m_u.dot(f.p_v);
  (*J)(0, 3) = -tt2.dot(tt1) + d.dot(b);
  (*J)(1, 3) = -tt2.dot(tt2) + d.dot(c);
  (*J)(2, 3) = m_v.dot(f.p_u);
  (*J)(3, 3) = m_v.dot(f.p_v);
  *orientation = m.dot(f.p_u.cross(f.p_v));
  return true;
}

// Starting point: femoral point below the tibia's view of the femoral chart origin, then a
// few rounds of (femoral point with the tibial normal, tibial point under the femoral one).
bool StartingPoint(const ContactPair& pair, const Pose& pose, Eigen::Vector4d* z) {
  const HeightField& fem = *pair.femoral_surface;
  const HeightField& tib = *pair.tibial_surface;
  ChartSample f, t;
  double zf[2] = {0.0, 0.0}, zt[2];
  if (!fem.EvaluateChart(zf[0], zf[1], &f)) return false;
  tib.ChartCoordinates(pose.PointInT(f.p), zt);
  for (int round = 0; round < kStartRounds; ++round) {
    if (!tib.EvaluateChart(zt[0], zt[1], &t)) return false;
    const Vector3d n_F = (pose.R_FT * t.p_u.cross(t.p_v)).normalized();
    if (!fem.PointWithNormal(n_F, zf)) break;
    if (!fem.EvaluateChart(zf[0], zf[1], &f)) return false;
    tib.ChartCoordinates(pose.PointInT(f.p), zt);
  }
  *z << zf[0], zf[1], zt[0], zt[1];
  return true;
}

}  // namespace

bool SolveContactPoints(const ContactPair& pair, const Pose& pose, ContactSolution* out) {
  Eigen::Vector4d z;
  if (!StartingPoint(pair, pose, &z)) return false;
  Eigen::Vector4d F;
  Eigen::Matrix4d J;
  double orientation = 0.0;
  for (int it = 0; it < kMaxNewtonIterations; ++it) {
    if (!EvaluateSystem(pair, pose, z, &F, &J, &orientation)) return false;
    const Eigen::FullPivLU<Eigen::Matrix4d> lu(J);
    if (!lu.isInvertible()) return false;
    const Eigen::Vector4d dz = lu.solve(F);
    if (!dz.allFinite()) return false;
    z -= dz;
    out->iterations = it + 1;
    if (dz.cwiseAbs().maxCoeff() <= kStepTolerance * (1.0 + z.cwiseAbs().maxCoeff())) {
      if (!EvaluateSystem(pair, pose, z, &F, &J, &orientation)) return false;
      if (!(orientation > 0.0)) return false;  // antiparallel normals: the far side
      out->z = z;
      out->jacobian = J;
      return true;
    }
  }
  return false;
}

ContactGeometry RequireContactKinematics(const ContactPair& pair, const Pose& pose,
                                         const char* caller, double chart[4]) {
  ContactGeometry g;
  if (!ContactKinematics(pair, pose, &g, chart)) {
    Throw<SolverError>(caller, "no contact point found for the ", CompartmentName(pair.compartment),
                       " pair (femoral ", pair.femoral_surface->Describe(), ", tibial ",
                       pair.tibial_surface->Describe(), ") at R0 = (", pose.p_FoTo_F.transpose() * 1e3,
                       ") mm (rule: the normals must be parallel inside both surfaces' domains)");
  }
  return g;
}

double ContactRateTerm(const ContactPair& pair, const Vector6d& q, const Vector6d& qd) {
  return ContactRateTerm(pair, q, qd, PoseFromCoordinates(q), GeneralizedVelocity(q, qd));
}

double ContactRateTerm(const ContactPair& pair, const Vector6d& q, const Vector6d& qd, const Pose& pose,
                       const Vector6d& nu) {
  SphereOnPlane sop;
  if (SphereOnPlaneForm(pair, &sop)) return SphereOnPlaneRateTerm(sop, pose, nu);
  return ContactRateTermAlongPath<ceres::Jet<double, 1>>(pair, q, qd, nu);
}

}  // namespace kneedyn
