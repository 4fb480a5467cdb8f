// The hidden (acceleration-level) constraint with the contact kinematics of
// contact_kinematics.hpp (any surface pair):
// contact forces and accelerations at a state (q, q̇), shared by every formulation that
// needs them (consistent initialization, EDE right-hand side, MDE force recovery, lift-off
// events of the ODE formulations, output of contact forces).
//
//   [ M   −Gᵀ ] [ ν̇ ]   [ Q                          ]
//   [ G    0  ] [ N ] = [ −κ − 2a φ̇ − b² φ (Baumgarte) ]
//
// with a = b = 0 the exact index-reduced constraint φ̈ = 0. M is diagonal in
// ν-coordinates (dynamics.hpp), so the system is solved through its Schur complement
// (a k×k system instead of a (6 + k)² LU):
//   (G M⁻¹ Gᵀ) N = rhs − G M⁻¹ Q,   ν̇ = M⁻¹ (Q + Gᵀ N).
#pragma once

#include <vector>

#include <Eigen/LU>

#include "solver/dynamics.hpp"

namespace kneedyn {

struct ConstrainedAcceleration {
  Vector6d nu_dot = Vector6d::Zero();  // (a_F, ẇ_T)
  Vector6d qdd = Vector6d::Zero();     // q̈
  std::vector<double> normal_force;    // N_i per active contact, N (may be < 0: lift-off)
};

struct BaumgarteGains {
  double alpha = 0.0;  // 1/s, velocity feedback (2a φ̇)
  double beta = 0.0;   // 1/s, position feedback (b² φ)
};

// Largest number of active contacts the allocation-free variant below handles.
constexpr int kMaxConstrainedContacts = 8;

// Workspace of the allocation-free SolveConstrainedAcceleration (mutable data kept
// apart from the constant Model): the applied-load workspace and the Schur-complement system in
// fixed-capacity Eigen types (at most kMaxConstrainedContacts rows, in this object).
struct ConstrainedDynamicsWorkspace {
  using Matrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, kMaxConstrainedContacts, kMaxConstrainedContacts>;
  using Vector = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, kMaxConstrainedContacts, 1>;
  using Rows = Eigen::Matrix<double, Eigen::Dynamic, 6, 0, kMaxConstrainedContacts, 6>;
  explicit ConstrainedDynamicsWorkspace(const Model& model) : data(model) {}
  Data data;
  Pose pose;  // of the last solve's q (for callers evaluating more at the same point)
  Rows G;    // constraint rows G_i (k×6)
  Matrix S;  // G M⁻¹ Gᵀ (k×k, symmetric positive definite for independent rows)
  Vector b;  // −κ − 2a φ̇ − b² φ − G M⁻¹ Q
  Vector N;  // normal forces
  Eigen::FullPivLU<Matrix> lu;  // of S: rank-revealing, for dependent rows
};

// The same solve without allocation after the first call with a given number of active
// contacts: into `out` (its normal_force keeps its capacity), using `workspace`.
// Throws SolverError when more than kMaxConstrainedContacts contacts are active.
void SolveConstrainedAcceleration(const Model& model, double t, const Vector6d& q, const Vector6d& qd,
                                  const std::vector<int>& active, BaumgarteGains gains,
                                  const std::vector<signed char>* ligament_branch,
                                  ConstrainedDynamicsWorkspace* workspace, ConstrainedAcceleration* out);

// `active` lists indices into model.contacts.
// Throws SolverError when the constraint rows are dependent.
ConstrainedAcceleration SolveConstrainedAcceleration(const Model& model, double t,
                                                     const Vector6d& q, const Vector6d& qd,
                                                     const std::vector<int>& active,
                                                     BaumgarteGains gains = {},
                                                     const std::vector<signed char>* ligament_branch = nullptr);

// ∂q̈/∂(q, q̇) (6×12, row-major into dqdd_dx) of the hidden-constraint solve above (gains 0)
// at (q, q̇) with its solution q̈, N (normal_force, one per active contact), exactly: by the
// implicit function theorem on H(x, z) = (Newton–Euler residual, G ν̇ + κ) = 0 with
// x = (q, q̇), z = (q̈, N), dz/dx = −H_z⁻¹ H_x, H_x and H_z by forward AD (ceres::Jet)
// through NewtonEulerResidual and the contact kinematics. Returns false (nothing written)
// when a contact is not a sphere on a plane: κ of the general pair is itself a derivative
// (ContactRateTerm), whose derivative would need nested Jets.
bool ConstrainedAccelerationJacobian(const Model& model, double t, const Vector6d& q, const Vector6d& qd,
                                     const Vector6d& qdd, const std::vector<int>& active,
                                     const std::vector<double>& normal_force,
                                     const std::vector<signed char>* ligament_branch, double* dqdd_dx);

// Gaps φ_i (m) of the listed contacts at q and their Jacobian
// ∂φ/∂q = G B(q) (k×6; G from contact.hpp, B = diag(1, E)).
void ContactGapsAndJacobian(const Model& model, const Vector6d& q, const std::vector<int>& contacts,
                            VectorXd* phi, MatrixXd* J);

// Moves q onto φ_i(q) = 0 for the listed contacts: Gauss–Newton with minimum-norm steps,
// until max |φ_i| ≤ tolerance (m) or max_iterations steps. Used by EDE's projection and by
// the driver's restarts.
void ProjectOntoContacts(const Model& model, const std::vector<int>& contacts, double tolerance,
                         int max_iterations, Vector6d* q);

// Contact geometries (contact_kinematics.hpp) of the listed contacts at a pose; throws
// SolverError when one has no contact point.
std::vector<ContactGeometry> ClosedFormContacts(const Model& model, const Pose& pose,
                                                const std::vector<int>& contacts);

}  // namespace kneedyn
