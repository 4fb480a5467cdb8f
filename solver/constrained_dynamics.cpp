#include "solver/constrained_dynamics.hpp"

#include <Eigen/LU>

#include "solver/contact_kinematics.hpp"
#include "solver/error.hpp"

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
  const Pose pose = PoseFromCoordinates(q);
  const int k = static_cast<int>(contacts.size());
  phi->resize(k);
  J->resize(k, 6);
  Matrix6d B = Matrix6d::Identity();
  B.bottomRightCorner<3, 3>() = AngularVelocityMap(q(kBeta), q(kGamma));
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

void SolveConstrainedAcceleration(const Model& model, double t, const Vector6d& q, const Vector6d& qd,
                                  const std::vector<int>& active, BaumgarteGains gains,
                                  const std::vector<signed char>* ligament_branch,
                                  ConstrainedDynamicsWorkspace* ws, ConstrainedAcceleration* out) {
  const int k = static_cast<int>(active.size());
  if (k > kMaxConstrainedContacts) {
    Throw<SolverError>("SolveConstrainedAcceleration", k, " active contacts exceed ",
                       kMaxConstrainedContacts, " (kMaxConstrainedContacts)");
  }
  const Pose pose = PoseFromCoordinates(q);
  const Vector6d nu = GeneralizedVelocity(q, qd);
  Data& data = ws->data;
  data.ligament_branch = ligament_branch;
  ComputeAppliedWrench(model, t, pose, &data);
  const Vector6d Q = GeneralizedForce(model, data, Vector3d(nu.tail<3>()));

  ConstrainedDynamicsWorkspace::Matrix& A = ws->A;
  ConstrainedDynamicsWorkspace::Vector& b = ws->b;
  A.setZero(6 + k, 6 + k);
  b.resize(6 + k);
  A.topLeftCorner<6, 6>() = MassMatrix(model);
  b.head<6>() = Q;
  for (int r = 0; r < k; ++r) {
    const ContactPair& pair = model.contacts[active[r]];
    const ContactGeometry geo = RequireContactKinematics(pair, pose, "SolveConstrainedAcceleration");
    const Eigen::Matrix<double, 1, 6> G = ContactConstraintRow(pose, geo);
    A.block<1, 6>(6 + r, 0) = G;
    A.block<6, 1>(0, 6 + r) = -G.transpose();
    b(6 + r) = -ContactRateTerm(pair, q, qd) - 2.0 * gains.alpha * G.dot(nu) -
               gains.beta * gains.beta * geo.gap;
  }
  ws->lu.compute(A);
  if (!ws->lu.isInvertible()) {
    Throw<SolverError>("SolveConstrainedAcceleration", "the contact constraint rows are dependent (rank ",
                       ws->lu.rank(), " of ", 6 + k, ") at t = ", t, " s");
  }
  ws->x = ws->lu.solve(b);
  out->nu_dot = ws->x.head<6>();
  out->qdd = CoordinateAcceleration(q, qd, out->nu_dot);
  out->normal_force.assign(ws->x.data() + 6, ws->x.data() + 6 + k);
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

}  // namespace kneedyn
