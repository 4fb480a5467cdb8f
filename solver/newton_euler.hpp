// The Newton–Euler residual of the tibia with contact wrenches (chapter Eqs. 1.48–1.57,
// F7–F12; docs/model.md §8), for any scalar type (double, ceres::Jet). One function for every
// formulation that writes the equations of motion as residuals (dae, dae-ggl, newmark,
// generalized-alpha):
//
//   r(t, q, q̇, q̈, N) = M ν̇ − Q(t, q, ν) − Σ_i N_i G_iᵀ            (6, ν-coordinates)
//
// with ν = (v_F, w_T), ν̇ = (a_F, ẇ_T = E q̈_ang + Ė q̇_ang) (pose.hpp), M = diag(m 1, I),
// Q = (F_applied_F, M_applied_T − w_T × I w_T) (dynamics.hpp) and the contact force −N_i n_F,i
// applied at the tibial contact point (contact.hpp: Σ N_i G_iᵀ is that wrench). The contact
// forces are summed into the applied loads, as the chapter sums them (Eqs. 1.48–1.57),
// before the gyroscopic term is taken: the order of the floating-point operations is that
// of the formulations before this function existed, so their results are unchanged.
#pragma once

#include "solver/contact.hpp"
#include "solver/dynamics.hpp"

namespace kneedyn {

// `geometry[i]` and `normal_force[i]` (N) for the k active contacts, in the formulation's
// order. `data` is the caller's workspace (its ligament_branch is read; the applied loads
// plus contact wrenches are left in applied_force_F / applied_moment_T). No allocation.
// `trig`: the sines and cosines of q's Euler angles (pose.hpp), those `pose` was made from;
// `E` = AngularVelocityMap(β, trig) and `nu` = (q̇_lin, E q̇_ang) at that pose, for a caller
// that has them already (the overloads below build them: E once for ν and ν̇).
template <typename T>
Vector6<T> NewtonEulerResidual(const Model& model, double t, const EulerAngleTrig<T>& trig, const Matrix3<T>& E,
                               const Vector6<T>& nu, const Vector6<T>& qd, const Vector6<T>& qdd,
                               const PoseTpl<T>& pose, int k, const ContactGeometryTpl<T>* geometry,
                               const T* normal_force, DataTpl<T>* data) {
  ComputeAppliedWrench(model, t, pose, data);
  for (int c = 0; c < k; ++c) {
    AddContactWrench(pose, geometry[c], normal_force[c], &data->applied_force_F,
                     &data->applied_moment_T);
  }
  const Vector6<T> Q = GeneralizedForce(model, *data, Vector3<T>(nu.template tail<3>()));
  return MassTimes(model, GeneralizedAcceleration(E, trig, qd, qdd)) - Q;
}

template <typename T>
Vector6<T> NewtonEulerResidual(const Model& model, double t, const Vector6<T>& q,
                               const EulerAngleTrig<T>& trig, const Vector6<T>& qd, const Vector6<T>& qdd,
                               const PoseTpl<T>& pose, int k, const ContactGeometryTpl<T>* geometry,
                               const T* normal_force, DataTpl<T>* data) {
  const Matrix3<T> E = AngularVelocityMap(q(kBeta), trig);
  return NewtonEulerResidual(model, t, trig, E, GeneralizedVelocity(E, qd), qd, qdd, pose, k, geometry, normal_force,
                             data);
}

template <typename T>
Vector6<T> NewtonEulerResidual(const Model& model, double t, const Vector6<T>& q,
                               const Vector6<T>& qd, const Vector6<T>& qdd, const PoseTpl<T>& pose,
                               int k, const ContactGeometryTpl<T>* geometry, const T* normal_force,
                               DataTpl<T>* data) {
  return NewtonEulerResidual(model, t, q, EulerAngleTrigOf(q), qd, qdd, pose, k, geometry, normal_force, data);
}

// Largest number of simultaneously active contacts the residual formulations size their
// stack arrays for (the Jet size kMaxJetSize = 24 allows at most 2 chapter-form GGL
// contacts; closed forms more).
constexpr int kMaxActiveContacts = 8;

}  // namespace kneedyn
