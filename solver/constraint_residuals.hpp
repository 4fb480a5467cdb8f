// Constraint residuals of a mechanical state (docs/model.md §4; chapter Eq. 1.8 normal component
// and its rate): per contact pair of the model, the gap φ_i(q) and the normal approach rate
// φ̇_i = G_i ν, both from the general contact kinematics (contact_kinematics.hpp), so they
// hold for any surface pair and do not depend on the formulation's contact description.
#pragma once

#include <vector>

#include "solver/state.hpp"

namespace kneedyn {

// Per model.contacts entry (active or not): φ (m) and φ̇ (m/s); NaN where the contact
// kinematics finds no contact point (general surfaces far apart or off a cap).
void ConstraintResiduals(const Model& model, const MechanicalState& state,
                         std::vector<double>* gap, std::vector<double>* gap_rate);

// Largest |φ_i| (m) and |φ̇_i| (m/s) over the state's active contacts, NaN entries skipped;
// 0 when none is active.
void MaxActiveConstraintResiduals(const Model& model, const MechanicalState& state,
                                  double* max_gap, double* max_gap_rate);

}  // namespace kneedyn
