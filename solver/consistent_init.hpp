// Consistent initialization, shared by all formulations. Takes a partial or
// inconsistent state and returns one that satisfies, in order:
//   1. position level: the contact conditions of the active contacts — chapter form (Eqs.
//      1.8, 1.13: five residuals per contact) or closed form (gap φ_i = 0) — over the coordinates
//      not held (more of those than contacts: both take the closed form's pose, docs/model.md §6);
//   2. velocity level: φ̇_i = G_i ν = 0 over the velocities not held (minimum-norm
//      correction);
//   3. the hidden constraint: N_i and ν̇ from the Newton–Euler equations and φ̈_i = 0
//      (starting from the scene's contact-force guesses; the problem is linear in them,
//      which is why the chapter found their initial values do not matter).
// Levels 1 and 3 take Newton's method directly when the system is square (as many unknowns
// as residuals, e.g. the chapter scene's four held coordinates) and it converges; otherwise
// (more unknowns than residuals, a singular Jacobian, no convergence) Ceres's
// Levenberg–Marquardt from the same start. Jacobians by automatic differentiation in both.
// Each level reports its residual norm before and after; a level that cannot reach its
// tolerance throws SolverError naming the level, the residual and the tolerance.
#pragma once

#include <string>
#include <vector>

#include "solver/constrained_dynamics.hpp"
#include "solver/state.hpp"

namespace kneedyn {

struct ConsistentInitOptions {
  ContactForm form = ContactForm::kChapter;
  // Chart of the chapter-form contact coordinates (contact.hpp): regular by default; the
  // chapter's height-field chart reproduces its failure at the condyle rim.
  ContactChart chart = ContactChart::kRegular;
  double position_tolerance = 1.0e-11;  // max |residual| (m; normals dimensionless)
  double velocity_tolerance = 1.0e-11;  // max |φ̇| (m/s)
  double hidden_tolerance = 1.0e-7;     // max |residual| (N, N m, m/s²)
  int max_iterations = 200;             // Ceres iterations per level
  // Newton iterations per level before falling back to Ceres; 0: Ceres only.
  int newton_iterations = 20;

  bool IsValid(std::string* error) const;
};

// How a level was solved: nothing to do (already within tolerance, or the linear velocity
// level), Newton's method directly, or Ceres after the direct path failed or was declined.
enum class InitMethod { kNone, kNewton, kCeres };

struct InitLevelReport {
  double residual_before = 0.0;  // max |residual| at the start
  double residual_after = 0.0;
  int iterations = 0;            // Newton or Ceres iterations (0 for the velocity level)
  InitMethod method = InitMethod::kNone;
};

struct InitReport {
  InitLevelReport position, velocity, hidden;
  std::vector<std::string> held;                // names of held quantities
  std::vector<double> normal_force_guess;       // per model.contacts, N
  std::vector<double> normal_force;             // consistent, per model.contacts, N
  std::string form;                             // "chapter" / "closed_form"
};

// `active`: contacts in contact at the start (indices into model.contacts); `initial`: the
// starting point, the held coordinates and rates and the contact guesses. With
// initial.unprojected the state is the guesses as they are (q̈ = 0, N the guesses), no level
// solved: the chapter's DASSL start.
MechanicalState ConsistentInitialize(const Model& model, const InitialState& initial,
                                     const std::vector<int>& active,
                                     const ConsistentInitOptions& options, InitReport* report);

// After a mode switch: projects the positions onto the active contacts' gaps φ_i = 0
// (Gauss–Newton, minimum-norm corrections; removes the drift of velocity-level
// formulations and the hysteresis penetration of a re-contact), then levels 2–3 (the
// hidden level by the direct saddle-point solve of constrained_dynamics.hpp, not Ceres);
// fills qdd, normal forces and (from the contact kinematics) contact coordinates.
void CompleteHiddenConstraint(const Model& model, MechanicalState* state);

// A restart's constrained accelerations and normal forces at state's (t, q, q̇) on its locked
// ligament branches. With a patella, its equilibrium is first followed from the state's last
// one (state->patella at patella_q; the model builder's start at first) to q along the tibial
// path (SolvePatellaAlongTibialPath), and the solve starts from it: a solve from the builder's
// start could land on another equilibrium than the one the run followed (a 2 kN quadriceps
// run's DAE restart began 786 N from consistency). Throws SolverError when it cannot follow.
ConstrainedAcceleration RestartAcceleration(const Model& model, MechanicalState* state);

// Moves state->q onto the active contacts' gaps φ = 0 to round-off (1e-14 m): the pose a
// restart continues from (CompleteHiddenConstraint's first step; a re-contact's impulse is
// taken there, formulations/simulator.cpp).
void ProjectRestartPose(const Model& model, MechanicalState* state);

// Chapter-form contact coordinates of the active contacts from the contact kinematics
// (contact_kinematics.hpp).
void FillContactCoordinates(const Model& model, MechanicalState* state);

}  // namespace kneedyn
