#include "solver/constraint_residuals.hpp"

#include <cmath>

#include "solver/contact_kinematics.hpp"

namespace kneedyn {

void ConstraintResiduals(const Model& model, const MechanicalState& state,
                         std::vector<double>* gap, std::vector<double>* gap_rate) {
  const Pose pose = PoseFromCoordinates(state.q);
  const Vector6d nu = GeneralizedVelocity(state.q, state.qd);
  gap->assign(model.contacts.size(), std::nan(""));
  gap_rate->assign(model.contacts.size(), std::nan(""));
  for (size_t i = 0; i < model.contacts.size(); ++i) {
    ContactGeometry g;
    if (!ContactKinematics(model.contacts[i], pose, &g)) continue;
    (*gap)[i] = g.gap;
    (*gap_rate)[i] = ContactConstraintRow(pose, g).dot(nu);  // φ̇ = G ν
  }
}

void MaxActiveConstraintResiduals(const Model& model, const MechanicalState& state,
                                  double* max_gap, double* max_gap_rate) {
  std::vector<double> gap, rate;
  ConstraintResiduals(model, state, &gap, &rate);
  *max_gap = 0.0;
  *max_gap_rate = 0.0;
  for (int i : state.active) {
    if (std::isfinite(gap[i])) *max_gap = std::max(*max_gap, std::abs(gap[i]));
    if (std::isfinite(rate[i])) *max_gap_rate = std::max(*max_gap_rate, std::abs(rate[i]));
  }
}

}  // namespace kneedyn
