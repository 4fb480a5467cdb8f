// Perfectly plastic impact at re-contact (docs/model.md §4; a kneedyn addition: the chapter
// never re-contacts). The contacts in `active` receive impulses P_i along their
// normals that zero their normal approach velocity; the pose does not change:
//
//   M Δν = Σ_i G_iᵀ P_i,     G_i (ν + Δν) = 0        (ν = (v_F, w_T), M = diag(m 1, I))
//
// solved as one saddle-point system [M −Gᵀ; G 0] (Δν, P) = (0, −G ν). Consequences the
// tests check: every generalized-momentum component d with G d = 0 is conserved
// (dᵀ M Δν = 0) and kinetic energy does not increase. G_i from the general contact
// kinematics (contact_kinematics.hpp), so any surface pair.
#pragma once

#include <vector>

#include "solver/state.hpp"

namespace kneedyn {

// ν + Δν for the contacts `active` (indices into model.contacts) at (q, q̇), as q̇ (angle
// rates). `impulses` (optional) receives P_i (N s), parallel to `active`. Throws
// SolverError when a contact point of an active pair cannot be found.
Vector6d PlasticImpactVelocity(const Model& model, const Vector6d& q, const Vector6d& qd,
                               const std::vector<int>& active,
                               std::vector<double>* impulses = nullptr);

// Applies the impact to state->qd for the state's active contacts.
void ApplyPlasticImpact(const Model& model, MechanicalState* state);

}  // namespace kneedyn
