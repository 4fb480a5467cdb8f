#include "solver/constrained_dynamics.hpp"

#include <Eigen/LU>

#include "solver/error.hpp"

namespace kneedyn {

std::vector<ContactGeometry> ClosedFormContacts(const Model& model, const Pose& pose,
                                                const std::vector<int>& contacts) {
  std::vector<ContactGeometry> out;
  out.reserve(contacts.size());
  for (int i : contacts) {
    out.push_back(SphereOnPlaneContact(
        RequireSphereOnPlane(model.contacts[i], "ClosedFormContacts"), pose));
  }
  return out;
}

ConstrainedAcceleration SolveConstrainedAcceleration(const Model& model, double t,
                                                     const Vector6d& q, const Vector6d& qd,
                                                     const std::vector<int>& active,
                                                     BaumgarteGains gains,
                                                     const std::vector<signed char>* ligament_branch) {
  const Pose pose = PoseFromCoordinates(q);
  const Vector6d nu = GeneralizedVelocity(q, qd);
  Data data(model);
  data.ligament_branch = ligament_branch;
  ComputeAppliedWrench(model, t, pose, &data);
  const Vector6d Q = GeneralizedForce(model, data, Vector3d(nu.tail<3>()));

  const int k = static_cast<int>(active.size());
  MatrixXd A = MatrixXd::Zero(6 + k, 6 + k);
  VectorXd b(6 + k);
  A.topLeftCorner<6, 6>() = MassMatrix(model);
  b.head<6>() = Q;
  for (int r = 0; r < k; ++r) {
    const SphereOnPlane& sop =
        RequireSphereOnPlane(model.contacts[active[r]], "SolveConstrainedAcceleration");
    const ContactGeometry geo = SphereOnPlaneContact(sop, pose);
    const Eigen::Matrix<double, 1, 6> G = ContactConstraintRow(pose, geo);
    A.block<1, 6>(6 + r, 0) = G;
    A.block<6, 1>(0, 6 + r) = -G.transpose();
    b(6 + r) = -ContactAccelerationTerm(sop, pose, nu) - 2.0 * gains.alpha * G.dot(nu) -
               gains.beta * gains.beta * geo.gap;
  }
  Eigen::FullPivLU<MatrixXd> lu(A);
  if (!lu.isInvertible()) {
    Throw<SolverError>("SolveConstrainedAcceleration", "the contact constraint rows are dependent (rank ",
                       lu.rank(), " of ", 6 + k, ") at t = ", t, " s");
  }
  const VectorXd x = lu.solve(b);
  ConstrainedAcceleration out;
  out.nu_dot = x.head<6>();
  out.qdd = CoordinateAcceleration(q, qd, out.nu_dot);
  out.normal_force.assign(x.data() + 6, x.data() + 6 + k);
  return out;
}

}  // namespace kneedyn
