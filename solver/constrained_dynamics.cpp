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

void SolveConstrainedAcceleration(const Model& model, double t, const Vector6d& q, const Vector6d& qd,
                                  const std::vector<int>& active, BaumgarteGains gains,
                                  const std::vector<signed char>* ligament_branch,
                                  ConstrainedDynamicsWorkspace* ws, ConstrainedAcceleration* out) {
  SolveConstrainedAccelerationTpl(model, t, q, qd, active, gains, ligament_branch, ws, out);
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
