#include "solver/constrained_dynamics.hpp"

#include <Eigen/LU>
#include <cmath>
#include <limits>

#include "solver/contact_kinematics.hpp"
#include "solver/error.hpp"
#include "solver/newton_euler.hpp"

namespace kneedyn {

std::vector<ContactGeometry> ClosedFormContacts(const Model& model, const Pose& pose,
                                                const std::vector<int>& contacts) {
  std::vector<ContactGeometry> out;
  out.reserve(contacts.size());
  for (int i : contacts) {
    out.push_back(RequireContactKinematics(model.contacts[i], pose, "ClosedFormContacts"));
  }
  return out;
}

void ContactGapsAndJacobian(const Model& model, const Vector6d& q, const std::vector<int>& contacts,
                            VectorXd* phi, MatrixXd* J) {
  const EulerAngleTrig<double> trig = EulerAngleTrigOf(q);
  const Pose pose = PoseFromCoordinates(q, trig);
  const int k = static_cast<int>(contacts.size());
  phi->resize(k);
  J->resize(k, 6);
  Matrix6d B = Matrix6d::Identity();
  B.bottomRightCorner<3, 3>() = AngularVelocityMap(q(kBeta), trig);
  for (int c = 0; c < k; ++c) {
    const ContactGeometry g =
        RequireContactKinematics(model.contacts[contacts[c]], pose, "ContactGapsAndJacobian");
    (*phi)(c) = g.gap;
    J->row(c) = ContactConstraintRow(pose, g) * B;
  }
}

void ProjectOntoContacts(const Model& model, const std::vector<int>& contacts, double tolerance,
                         int max_iterations, Vector6d* q) {
  if (contacts.empty()) return;
  VectorXd phi;
  MatrixXd J;
  for (int iter = 0; iter < max_iterations; ++iter) {
    ContactGapsAndJacobian(model, *q, contacts, &phi, &J);
    if (phi.cwiseAbs().maxCoeff() <= tolerance) break;
    *q -= J.completeOrthogonalDecomposition().solve(phi);
  }
}

namespace {

// SolveSmallFullPivLu for a size K known at compile time: Eigen's FullPivLU on a fixed-size
// matrix (unrolled, no heap), the same algorithm as the dynamic-size one it replaces.
template <int K>
int SolveFullPivLuFixed(const double* S, const double* b, double* x) {
  const Eigen::FullPivLU<Eigen::Matrix<double, K, K>> lu{Eigen::Map<const Eigen::Matrix<double, K, K>>(S)};
  const int rank = static_cast<int>(lu.rank());
  if (rank == K) {
    Eigen::Map<Eigen::Matrix<double, K, 1>> solution(x);
    solution = lu.solve(Eigen::Map<const Eigen::Matrix<double, K, 1>>(b));
  }
  return rank;
}

}  // namespace

int SolveSmallFullPivLu(int k, const double* S, const double* b, double* x) {
  static_assert(kMaxConstrainedContacts == 8, "one case per size below");
  switch (k) {
    case 0: return 0;
    case 1: return SolveFullPivLuFixed<1>(S, b, x);
    case 2: return SolveFullPivLuFixed<2>(S, b, x);
    case 3: return SolveFullPivLuFixed<3>(S, b, x);
    case 4: return SolveFullPivLuFixed<4>(S, b, x);
    case 5: return SolveFullPivLuFixed<5>(S, b, x);
    case 6: return SolveFullPivLuFixed<6>(S, b, x);
    case 7: return SolveFullPivLuFixed<7>(S, b, x);
    case 8: return SolveFullPivLuFixed<8>(S, b, x);
    default: break;
  }
  Throw<SolverError>("SolveSmallFullPivLu", "size ", k, "; must be in [0, ", kMaxConstrainedContacts, "]");
}

int SolveSchurComplement(int k, const double* S, const double* b, double* x) {
  constexpr double kEpsilon = std::numeric_limits<double>::epsilon();
  if (k == 1) {  // FullPivLU's rule for 1×1: rank 1 iff S ≠ 0
    if (S[0] == 0.0) return 0;
    x[0] = b[0] / S[0];
    return 1;
  }
  if (k == 2) {
    const Eigen::Map<const Eigen::Matrix2d> s(S);
    const double pivot = s.cwiseAbs().maxCoeff();  // FullPivLU's first pivot
    Eigen::Matrix2d inverse;
    double determinant = 0.0;
    bool invertible = false;
    s.computeInverseAndDetWithCheck(inverse, determinant, invertible, 2.0 * kEpsilon * pivot * pivot);
    if (!invertible) return pivot > 0.0 ? 1 : 0;
    Eigen::Map<Eigen::Vector2d> solution(x);
    solution = inverse * Eigen::Map<const Eigen::Vector2d>(b);
    return 2;
  }
  return SolveSmallFullPivLu(k, S, b, x);
}

void SolveConstrainedAcceleration(const Model& model, double t, const Vector6d& q, const Vector6d& qd,
                                  const std::vector<int>& active, BaumgarteGains gains,
                                  const std::vector<signed char>* ligament_branch,
                                  ConstrainedDynamicsWorkspace* ws, ConstrainedAcceleration* out) {
  SolveConstrainedAccelerationTpl(model, t, q, qd, active, gains, ligament_branch, ws, out);
}

void SolveContactNormalForces(const Model& model, double t, const Vector6d& q, const Vector6d& qd,
                              const std::vector<int>& active, BaumgarteGains gains,
                              const std::vector<signed char>* ligament_branch,
                              ConstrainedDynamicsWorkspace* ws, ConstrainedAcceleration* out) {
  SolveConstrainedAccelerationTpl(model, t, q, qd, active, gains, ligament_branch, ws, out, false);
}

ConstrainedAcceleration SolveConstrainedAcceleration(const Model& model, double t,
                                                     const Vector6d& q, const Vector6d& qd,
                                                     const std::vector<int>& active,
                                                     BaumgarteGains gains,
                                                     const std::vector<signed char>* ligament_branch) {
  ConstrainedDynamicsWorkspace workspace(model);
  ConstrainedAcceleration out;
  SolveConstrainedAcceleration(model, t, q, qd, active, gains, ligament_branch, &workspace, &out);
  return out;
}

bool ConstrainedAccelerationJacobian(const Model& model, double t, const Vector6d& q, const Vector6d& qd,
                                     const Vector6d& qdd, const std::vector<int>& active,
                                     const std::vector<double>& normal_force,
                                     const std::vector<signed char>* ligament_branch, double* dqdd_dx) {
  const int k = static_cast<int>(active.size());
  if (k > kMaxJetSize - 18) {
    Throw<SolverError>("ConstrainedAccelerationJacobian", k, " active contacts; at most ", kMaxJetSize - 18);
  }
  std::vector<SphereOnPlane> sop(k);
  std::vector<bool> closed_form(k);
  for (int c = 0; c < k; ++c) closed_form[c] = SphereOnPlaneForm(model.contacts[active[c]], &sop[c]);
  // Jet components: 0–5 q, 6–11 q̇, 12–17 q̈, 18… N.
  Vector6<JetD> qj, qdj, qddj;
  for (int i = 0; i < 6; ++i) {
    qj(i) = JetD(q(i), i);
    qdj(i) = JetD(qd(i), 6 + i);
    qddj(i) = JetD(qdd(i), 12 + i);
  }
  std::vector<JetD> nj(k);
  std::vector<ContactGeometryTpl<JetD>> geo(k);
  const EulerAngleTrig<JetD> trig = EulerAngleTrigOf(qj);
  const PoseTpl<JetD> pose = PoseFromCoordinates(qj, trig);
  for (int c = 0; c < k; ++c) {
    nj[c] = JetD(normal_force[c], 18 + c);
    if (closed_form[c]) {
      geo[c] = SphereOnPlaneContact(sop[c], pose);
    } else if (!ContactKinematics(model.contacts[active[c]], pose, &geo[c])) {
      return false;
    }
  }
  DataTpl<JetD> data(model);
  data.ligament_branch = ligament_branch;
  const Vector6<JetD> r = NewtonEulerResidual(model, t, qj, trig, qdj, qddj, pose, k, geo.data(), nj.data(), &data);
  const Vector6<JetD> nu = GeneralizedVelocity(qj, trig, qdj);
  const Vector6<JetD> nu_dot = GeneralizedAcceleration(qj, trig, qdj, qddj);
  const int m = 6 + k;
  MatrixXd H_x(m, 12), H_z(m, m);
  for (int row = 0; row < m; ++row) {
    JetD h;
    if (row < 6) {
      h = r(row);
    } else {
      // κ of a general pair: its (q, q̇)-derivatives are second derivatives of the contact
      // kinematics, carried by TimeDual over the Jet (time_dual.hpp).
      const int c = row - 6;
      const JetD kappa = closed_form[c] ? SphereOnPlaneRateTerm(sop[c], pose, nu)
                                        : ContactRateTermAlongPath<TimeDual<JetD>>(model.contacts[active[c]], qj, qdj, nu);
      h = JetD(ContactConstraintRow(pose, geo[c]).dot(nu_dot)) + kappa;
    }
    for (int j = 0; j < 12; ++j) H_x(row, j) = h.v(j);
    for (int j = 0; j < m; ++j) H_z(row, j) = h.v(12 + j);
  }
  const MatrixXd dz_dx = -H_z.fullPivLu().solve(H_x);
  for (int i = 0; i < 6; ++i) {
    for (int j = 0; j < 12; ++j) dqdd_dx[12 * i + j] = dz_dx(i, j);
  }
  return true;
}

}  // namespace kneedyn
