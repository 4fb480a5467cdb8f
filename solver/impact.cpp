#include "solver/impact.hpp"

#include <Eigen/LU>

#include "solver/contact_kinematics.hpp"
#include "solver/dynamics.hpp"

namespace kneedyn {

Vector6d PlasticImpactVelocity(const Model& model, const Vector6d& q, const Vector6d& qd,
                               const std::vector<int>& active, std::vector<double>* impulses) {
  const Pose pose = PoseFromCoordinates(q);
  const int k = static_cast<int>(active.size());
  MatrixXd A = MatrixXd::Zero(6 + k, 6 + k);
  VectorXd b = VectorXd::Zero(6 + k);
  A.topLeftCorner<6, 6>() = MassMatrix(model);
  const Vector6d nu = GeneralizedVelocity(q, qd);
  for (int r = 0; r < k; ++r) {
    const Eigen::Matrix<double, 1, 6> G = ContactConstraintRow(
        pose, RequireContactKinematics(model.contacts[active[r]], pose, "PlasticImpactVelocity"));
    A.block<1, 6>(6 + r, 0) = G;
    A.block<6, 1>(0, 6 + r) = -G.transpose();
    b(6 + r) = -G.dot(nu);
  }
  const VectorXd x = A.fullPivLu().solve(b);
  if (impulses != nullptr) impulses->assign(x.data() + 6, x.data() + 6 + k);
  return CoordinateVelocity(q, nu + x.head<6>());
}

void ApplyPlasticImpact(const Model& model, MechanicalState* state) {
  state->qd = PlasticImpactVelocity(model, state->q, state->qd, state->active);
}

}  // namespace kneedyn
