#include "solver/dynamics.hpp"

#include <cmath>

namespace kneedyn {

Matrix6d MassMatrix(const Model& model) {
  Matrix6d M = Matrix6d::Zero();
  M.diagonal().head<3>().setConstant(model.mass);
  M.diagonal().tail<3>() = model.inertia_T;
  return M;
}

std::vector<signed char> LigamentBranchesAt(const Model& model, const Vector6d& q,
                                            const Vector6d& qd) {
  std::vector<signed char> branch(model.ligaments.size());
  const Pose pose = PoseFromCoordinates(q);
  const double dt = 1e-7;  // s: look-ahead to decide at the kink
  const Vector6d q_next = q + dt * qd;
  const Pose pose_next = PoseFromCoordinates(q_next);
  for (size_t j = 0; j < model.ligaments.size(); ++j) {
    const Ligament& lig = model.ligaments[j];
    double L = LigamentSpan_F(lig, pose).norm();
    if (std::abs(L - LigamentKinkLength(lig)) < 1e-12) L = LigamentSpan_F(lig, pose_next).norm();
    branch[j] = L > LigamentKinkLength(lig) ? kBranchLinear : kBranchToe;
  }
  return branch;
}

double MechanicalEnergy(const Model& model, const Vector6d& q, const Vector6d& qd) {
  return MechanicalEnergyTpl(model, q, qd);
}

}  // namespace kneedyn
