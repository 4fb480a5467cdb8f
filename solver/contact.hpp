// Tibio-femoral contact (chapter Eqs. 1.6–1.13; docs/model.md §4), two equivalent descriptions.
//
// Chapter form, any smooth height fields. Per contact the unknowns are the contact
// coordinates c = (xc, yc) on the femur (F) and (x′c, y′c) on the tibia (T):
//   Xf = (xc, yc, f(xc, yc))  in F,        X′t = (x′c, y′c, g(x′c, y′c))  in T
//   e  = Xf − (R0 + R X′t)                 (Eq. 1.8; three components: F13–F15)
//   nf − R n′t, x and y components         (Eq. 1.13; F19, F20), n = (∂x h, ∂y h, −1)/norm
// Closed form, sphere on plane (contact_kinematics.hpp chooses it): the gap φ = n·(C − R0) − d − r with n = R n̂′ (in F);
// contact point Xc = C − r n (reported in both frames). φ > 0 separated, φ < 0 penetrating.
//
// Velocity level (both forms): the normal approach velocity of the tibial material point
// at the contact, written as φ̇ = −n_F · (v_F + w_F × R X′t) = G ν with ν = (v_F, w_T),
//   G = [−n_Fᵀ, (n′_T × X′t)ᵀ]                 (1×6)
// and at acceleration level φ̈ = G ν̇ + κ (any pair: ContactRateTerm, contact_kinematics.hpp).
//
// Contact force on the tibia: −N n_F applied at the tibial contact point (docs/model.md §4).
#pragma once

#include "solver/model.hpp"
#include "solver/pose.hpp"

namespace kneedyn {

// The sphere-on-plane closed form of a contact pair (docs/model.md §4), from the surfaces'
// SphereForm/PlaneForm (contact_kinematics.hpp: SphereOnPlaneForm).
struct SphereOnPlane {
  Vector3d centre_F;  // sphere centre C in F, m
  double radius = 0.0;  // r, m
  Vector3d normal_T;  // unit plane normal n̂′ in T, towards the femur
  double offset = 0.0;  // d: n̂′ · x′ = d on the plane, m
};

// Where a contact acts on the tibia and its normal; shared by both forms.
template <typename T>
struct ContactGeometryTpl {
  Vector3<T> point_F;   // femoral contact point Xf, m
  Vector3<T> point_T;   // tibial contact point X′t (tibial coordinates), m; any point on
                        // the line of action gives the same G and wrench: the closed form
                        // reports the femoral point here, the general solve the tibial one
  Vector3<T> normal_T;  // unit tibial normal n′, towards the femur
  T gap = T(0.0);       // closed form φ; chapter form: n_F · e (signed distance along n)
};
using ContactGeometry = ContactGeometryTpl<double>;

// Chapter-form residuals for one pair, in one of two charts (height_field.hpp):
//  - kHeightField, the chapter's: c = (xc, yc, x′c, y′c) in m; residual[0..2] = e (Eq. 1.8),
//    residual[3..4] = x, y of nf − R n′t (Eq. 1.13). Singular where |∇f| → ∞ (the rim of a
//    condylar sphere) and where the normal turns horizontal in F.
//  - kRegular: c = (uf, vf, ut, vt) in the surfaces' regular charts; the same conditions
//    written in the tangent frame, regular up to and beyond the equator:
//      residual[0,1] = e · R P′t_{u,v} / |P′t_{u,v}|   (Eq. 1.8, tangential components)
//      residual[2]   = e · n_F                          (Eq. 1.8, normal component: the gap)
//      residual[3,4] = n_F · Pf_{u,v} / |Pf_{u,v}|     (Eq. 1.13: normals parallel)
// Returns false when a surface is evaluated outside its domain (recoverable for solvers).
template <typename T>
bool ChapterContactResiduals(const ContactPair& pair, const PoseTpl<T>& pose, const T c[4],
                             T residual[5], ContactGeometryTpl<T>* geometry = nullptr,
                             ContactChart chart = ContactChart::kHeightField) {
  using std::sqrt;
  if (chart == ContactChart::kRegular) {
    Vector3<T> pf, pf_u, pf_v, pt, pt_u, pt_v;
    if (!EvaluateChart(*pair.femoral_surface, c[0], c[1], &pf, &pf_u, &pf_v)) return false;
    if (!EvaluateChart(*pair.tibial_surface, c[2], c[3], &pt, &pt_u, &pt_v)) return false;
    const Vector3<T> e = pf - pose.PointInF(pt);
    const Vector3<T> t1 = pose.R_FT * pt_u, t2 = pose.R_FT * pt_v;
    const Vector3<T> n_T = pt_u.cross(pt_v).normalized();
    const Vector3<T> n_F = pose.R_FT * n_T;
    residual[0] = e.dot(t1) / t1.norm();
    residual[1] = e.dot(t2) / t2.norm();
    residual[2] = e.dot(n_F);
    residual[3] = n_F.dot(pf_u) / pf_u.norm();
    residual[4] = n_F.dot(pf_v) / pf_v.norm();
    if (geometry != nullptr) {
      geometry->point_F = pf;
      geometry->point_T = pt;
      geometry->normal_T = n_T;
      geometry->gap = residual[2];
    }
    return true;
  }
  T f, g, df[2], dg[2];
  if (!EvaluateHeight(*pair.femoral_surface, c[0], c[1], &f, df)) return false;
  if (!EvaluateHeight(*pair.tibial_surface, c[2], c[3], &g, dg)) return false;
  const Vector3<T> Xf(c[0], c[1], f);
  const Vector3<T> Xt(c[2], c[3], g);
  const Vector3<T> e = Xf - pose.PointInF(Xt);
  const Vector3<T> nf = Vector3<T>(df[0], df[1], T(-1.0)) /
                        sqrt(df[0] * df[0] + df[1] * df[1] + T(1.0));
  const Vector3<T> nt = Vector3<T>(dg[0], dg[1], T(-1.0)) /
                        sqrt(dg[0] * dg[0] + dg[1] * dg[1] + T(1.0));
  const Vector3<T> colinear = nf - pose.R_FT * nt;
  residual[0] = e(0);
  residual[1] = e(1);
  residual[2] = e(2);
  residual[3] = colinear(0);
  residual[4] = colinear(1);
  if (geometry != nullptr) {
    geometry->point_F = Xf;
    geometry->point_T = Xt;
    geometry->normal_T = -nt;  // chapter normals point away from the femur; flip
    geometry->gap = -(pose.R_FT * nt).dot(e);
  }
  return true;
}

// Closed-form sphere-on-plane contact at a pose.
template <typename T>
ContactGeometryTpl<T> SphereOnPlaneContact(const SphereOnPlane& sop, const PoseTpl<T>& pose) {
  ContactGeometryTpl<T> out;
  const Vector3<T> n_F = pose.R_FT * sop.normal_T.template cast<T>();
  const Vector3<T> C = sop.centre_F.template cast<T>();
  out.gap = n_F.dot(C - pose.p_FoTo_F) - sop.offset - sop.radius;
  out.point_F = C - sop.radius * n_F;
  out.point_T = pose.PointInT(out.point_F);
  out.normal_T = sop.normal_T.template cast<T>();
  return out;
}

// The gap of a sphere on a plane is affine in the tibial origin R0 (F) at a fixed orientation:
// gap = h − n_F · R0 with n_F = R_FT n̂′ and h = n_F · C − d − r (SphereOnPlaneContact's gap
// regrouped, docs/model.md §4). h is the value of n_F · R0 that closes the contact, m; the
// MDE chart solves n_F · R0 = h for the translations it eliminates in one linear solve.
template <typename T>
T SphereOnPlaneClosingHeight(const SphereOnPlane& sop, const Vector3<T>& normal_F) {
  return normal_F.dot(sop.centre_F.template cast<T>()) - sop.offset - sop.radius;
}

// φ̇ = G ν: the 1×6 velocity-constraint row at a contact (see header comment).
template <typename T>
Eigen::Matrix<T, 1, 6> ContactConstraintRow(const PoseTpl<T>& pose,
                                            const ContactGeometryTpl<T>& geometry) {
  Eigen::Matrix<T, 1, 6> G;
  G.template head<3>() = -(pose.R_FT * geometry.normal_T).transpose();
  G.template tail<3>() = geometry.normal_T.cross(geometry.point_T).transpose();
  return G;
}

// Force (F) and moment about the centre of mass (T) of −N n_F applied at point_T.
template <typename T>
void AddContactWrench(const PoseTpl<T>& pose, const ContactGeometryTpl<T>& geometry,
                      const T& normal_force, Vector3<T>* force_F, Vector3<T>* moment_T) {
  *force_F -= normal_force * (pose.R_FT * geometry.normal_T);
  *moment_T -= normal_force * geometry.point_T.cross(geometry.normal_T);
}

}  // namespace kneedyn
