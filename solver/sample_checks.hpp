// Physical-sample checks: states no formulation may report as a result (the run driver
// checks every output sample and stops the run with the reason).
//
//  - a non-finite state;
//  - a pose at the JCS singularity, |sin β| < kJcsSingularityTolerance (rotation.hpp), where
//    the angular velocity cannot be formed from the rates (docs/model.md §2);
//  - an active contact violated by more than kMaxConstraintViolation: velocity-level and
//    fixed-step methods drift, but by far less (≤ 1e-4 mm at the chapter's settings);
//    beyond 1 mm the run has diverged (e.g. Euler outside its stability range);
//  - an active contact whose contact point is not on both surfaces: the point found by the
//    general contact kinematics (contact_kinematics.hpp; closed form for sphere on plane)
//    must lie inside the domain of each surface's regular chart (height_field.hpp; e.g.
//    |u| < 80°, |v| < 170° for sphere and ellipsoid caps, which stays valid past the
//    condyle's equator, unlike the chapter's lower-hemisphere height field). Beyond it the
//    model is not defined. The height-field chart's rim failure, when a run asks for that
//    chart, is the chapter-form formulation's own (its residuals cannot be evaluated there).
#pragma once

#include "solver/state.hpp"

namespace kneedyn {

constexpr double kMaxConstraintViolation = 1.0e-3;  // m

// Throws SolverError naming the rule, the compartment, t and the flexion angle.
void CheckSampleIsPhysical(const Model& model, const MechanicalState& state);

}  // namespace kneedyn
