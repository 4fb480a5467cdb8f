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

#include <type_traits>
#include <vector>

#include <Eigen/LU>

#include "solver/contact_kinematics.hpp"
#include "solver/dynamics.hpp"
#include "solver/error.hpp"

namespace kneedyn {

template <typename T>
struct ConstrainedAccelerationTpl {
  Vector6<T> nu_dot = Vector6<T>::Zero();  // (a_F, ẇ_T)
  Vector6<T> qdd = Vector6<T>::Zero();     // q̈
  std::vector<T> normal_force;             // N_i per active contact, N (may be < 0: lift-off)
};
using ConstrainedAcceleration = ConstrainedAccelerationTpl<double>;

struct BaumgarteGains {
  double alpha = 0.0;  // 1/s, velocity feedback (2a φ̇)
  double beta = 0.0;   // 1/s, position feedback (b² φ)
};

// Largest number of active contacts the allocation-free variant below handles.
constexpr int kMaxConstrainedContacts = 8;

// Workspace of the allocation-free SolveConstrainedAcceleration (mutable data kept
// apart from the constant Model): the applied-load workspace and the Schur-complement system in
// fixed-capacity Eigen types (at most kMaxConstrainedContacts rows, in this object).
template <typename T>
struct ConstrainedDynamicsWorkspaceTpl {
  using Matrix = Eigen::Matrix<T, Eigen::Dynamic, Eigen::Dynamic, 0, kMaxConstrainedContacts, kMaxConstrainedContacts>;
  using Vector = Eigen::Matrix<T, Eigen::Dynamic, 1, 0, kMaxConstrainedContacts, 1>;
  using Rows = Eigen::Matrix<T, Eigen::Dynamic, 6, 0, kMaxConstrainedContacts, 6>;
  explicit ConstrainedDynamicsWorkspaceTpl(const Model& model) : data(model), forms_of(&model) {
    sphere_on_plane.resize(model.contacts.size());
    is_sphere_on_plane.resize(model.contacts.size());
    for (size_t i = 0; i < model.contacts.size(); ++i) {
      is_sphere_on_plane[i] = SphereOnPlaneForm(model.contacts[i], &sphere_on_plane[i]);
    }
  }
  DataTpl<T> data;
  // The closed forms of the model's sphere-on-plane pairs (constant data, found once here
  // instead of per contact and solve: SphereOnPlaneForm asks both surfaces through virtual
  // calls, ~190 instructions per contact per solve). Used only with the model they came from.
  const Model* forms_of;
  std::vector<SphereOnPlane> sphere_on_plane;
  std::vector<char> is_sphere_on_plane;
  // The closed form of contact i of `model`, or nullptr (general pair or another model).
  const SphereOnPlane* SphereOnPlaneOf(const Model& model, int i) const {
    return &model == forms_of && is_sphere_on_plane[i] ? &sphere_on_plane[i] : nullptr;
  }
  PoseTpl<T> pose;  // of the last solve's q (for callers evaluating more at the same point)
  Rows G;    // constraint rows G_i (k×6)
  Matrix S;  // G M⁻¹ Gᵀ (k×k, symmetric positive definite for independent rows)
  Vector b;  // −κ − 2a φ̇ − b² φ − G M⁻¹ Q
  Vector N;  // normal forces
  Eigen::FullPivLU<Matrix> lu;  // of S: rank-revealing, for dependent rows
};
using ConstrainedDynamicsWorkspace = ConstrainedDynamicsWorkspaceTpl<double>;

// x = S⁻¹ b for the k×k Schur complement S (column-major, k ≤ kMaxConstrainedContacts) by
// Eigen's FullPivLU on a matrix of fixed size k (one instantiation per size): the same bits
// as the dynamic-size ws->lu.solve (tests/constrained_dynamics_test.cpp), without its
// dynamic-size bookkeeping, ~1.1 k instructions per 2×2 solve (callgrind, chapter scene).
// Returns the rank by FullPivLU's rule (|u_ii| > max pivot · k ε); x is written only when
// the rank is k.
int SolveSmallFullPivLu(int k, const double* S, const double* b, double* x);

// x = S⁻¹ b for the Schur complement S = G M⁻¹ Gᵀ (k×k, column-major): k = 1 and 2 (one
// and two condyles in contact) by Eigen's closed-form inverse (computeInverseAndDetWithCheck:
// cofactors over the determinant, ~60 instructions against ~530 for the 2×2 FullPivLU),
// with FullPivLU's rank rule for that size (2×2: |u_22| = |det| / p > 2 ε p, p = max |S_ij|,
// the first full pivot); k ≥ 3 by SolveSmallFullPivLu. Agrees with FullPivLU to round-off
// (not bitwise; tests/constrained_dynamics_test.cpp). Returns the rank; x is written only
// when it is k.
int SolveSchurComplement(int k, const double* S, const double* b, double* x);

// SolveConstrainedAcceleration below in any scalar type T with a double time (the pulse is
// evaluated at t; double and long double, the extended-precision references of
// benchmarks/extended_reference.hpp). T = long double: sphere-on-plane contacts only
// (RequireContactKinematicsTpl). `accelerations` false: the normal forces only (the lift-off
// root functions): out->nu_dot and out->qdd are left as they were (saves ν̇ = M⁻¹(Q + Gᵀ N)
// and the coordinate accelerations, ~220 of ~3.7 k instructions per solve).
template <typename T>
void SolveConstrainedAccelerationTpl(const Model& model, double t, const Vector6<T>& q, const Vector6<T>& qd,
                                     const std::vector<int>& active, BaumgarteGains gains,
                                     const std::vector<signed char>* ligament_branch,
                                     ConstrainedDynamicsWorkspaceTpl<T>* ws, ConstrainedAccelerationTpl<T>* out,
                                     bool accelerations = true) {
  const int k = static_cast<int>(active.size());
  if (k > kMaxConstrainedContacts) {
    Throw<SolverError>("SolveConstrainedAcceleration", k, " active contacts exceed ",
                       kMaxConstrainedContacts, " (kMaxConstrainedContacts)");
  }
  const EulerAngleTrig<T> trig = EulerAngleTrigOf(q);  // once per pose
  ws->pose = PoseFromCoordinates(q, trig);
  const PoseTpl<T>& pose = ws->pose;
  const Vector6<T> nu = GeneralizedVelocity(q, trig, qd);
  DataTpl<T>& data = ws->data;
  data.ligament_branch = ligament_branch;
  ComputeAppliedWrench(model, t, pose, &data);
  const Vector6<T> Q = GeneralizedForce(model, data, Vector3<T>(nu.template tail<3>()));

  Vector6<T> M_inverse;
  M_inverse.template head<3>().setConstant(T(1.0) / T(model.mass));
  M_inverse.template tail<3>() = model.inertia_T.template cast<T>().cwiseInverse();
  const Vector6<T> a_free = M_inverse.cwiseProduct(Q);  // M⁻¹ Q
  ws->G.resize(k, 6);
  ws->b.resize(k);
  for (int r = 0; r < k; ++r) {
    const ContactPair& pair = model.contacts[active[r]];
    // A sphere-on-plane pair's closed form: what RequireContactKinematicsTpl and
    // ContactRateTermTpl compute for it (the same calls), without looking the form up again.
    const SphereOnPlane* sop = ws->SphereOnPlaneOf(model, active[r]);
    const ContactGeometryTpl<T> geo = sop ? SphereOnPlaneContact(*sop, pose)
                                          : RequireContactKinematicsTpl(pair, pose, "SolveConstrainedAcceleration");
    const T kappa = sop ? SphereOnPlaneRateTerm(*sop, pose, nu) : ContactRateTermTpl(pair, q, qd, pose, nu);
    const Eigen::Matrix<T, 1, 6> G = ContactConstraintRow(pose, geo);
    ws->G.row(r) = G;
    ws->b(r) = -kappa - 2.0 * gains.alpha * G.dot(nu) - gains.beta * gains.beta * geo.gap - G.dot(a_free);
  }
  Vector6<T> nu_dot = a_free;
  out->normal_force.resize(k);
  if (k > 0) {
    ws->S.noalias() = ws->G * M_inverse.asDiagonal() * ws->G.transpose();
    int rank = 0;
    if constexpr (std::is_same_v<T, double>) {
      ws->N.resize(k);
      rank = SolveSchurComplement(k, ws->S.data(), ws->b.data(), ws->N.data());
    } else {
      ws->lu.compute(ws->S);
      rank = static_cast<int>(ws->lu.rank());
      if (rank == k) ws->N = ws->lu.solve(ws->b);
    }
    if (rank != k) {
      Throw<SolverError>("SolveConstrainedAcceleration", "the contact constraint rows are dependent (rank ",
                         6 + rank, " of ", 6 + k, ") at t = ", t, " s");
    }
    for (int r = 0; r < k; ++r) out->normal_force[r] = ws->N(r);
    if (!accelerations) return;
    nu_dot += M_inverse.cwiseProduct(ws->G.transpose() * ws->N);
  }
  if (!accelerations) return;
  out->nu_dot = nu_dot;
  out->qdd = CoordinateAccelerationTpl(q, trig, qd, out->nu_dot);
}

// The same solve without allocation after the first call with a given number of active
// contacts: into `out` (its normal_force keeps its capacity), using `workspace`.
// Throws SolverError when more than kMaxConstrainedContacts contacts are active.
void SolveConstrainedAcceleration(const Model& model, double t, const Vector6d& q, const Vector6d& qd,
                                  const std::vector<int>& active, BaumgarteGains gains,
                                  const std::vector<signed char>* ligament_branch,
                                  ConstrainedDynamicsWorkspace* workspace, ConstrainedAcceleration* out);
// The same for the normal forces only (out->normal_force; nu_dot and qdd untouched): what the
// lift-off root functions need.
void SolveContactNormalForces(const Model& model, double t, const Vector6d& q, const Vector6d& qd,
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
// through NewtonEulerResidual and the contact kinematics. Any surface pair: κ of a general
// pair is itself a derivative (ContactRateTerm), differentiated through TimeDual over the Jet
// (time_dual.hpp) with the surfaces' third chart derivatives (EvaluateChartThird). Returns
// false (nothing written) when the general solve finds no contact point.
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
