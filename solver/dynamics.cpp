#include "solver/dynamics.hpp"

namespace kneedyn {

Matrix6d MassMatrix(const Model& model) {
  Matrix6d M = Matrix6d::Zero();
  M.diagonal().head<3>().setConstant(model.mass);
  M.diagonal().tail<3>() = model.inertia_T;
  return M;
}

double MechanicalEnergy(const Model& model, const Vector6d& q, const Vector6d& qd) {
  const Vector6d nu = GeneralizedVelocity(q, qd);
  const Vector3d w = nu.tail<3>();
  double energy = 0.5 * model.mass * nu.head<3>().squaredNorm() +
                  0.5 * w.dot(model.inertia_T.cwiseProduct(w));
  energy -= (model.mass * model.gravity_F + model.constant_load.force_F).dot(q.head<3>());
  const Pose pose = PoseFromCoordinates(q);
  for (const Ligament& lig : model.ligaments) {
    energy += LigamentPotential(lig, LigamentSpan_F(lig, pose).norm());
  }
  return energy;
}

}  // namespace kneedyn
