// Quantities derived from one mechanical state — the one place they are computed for the
// trajectory writer (formulations/run_output.cpp), the benchmark metrics
// (benchmarks/metrics.cpp) and the hard-case catalog (app/hard_case_catalog.cpp).
// Sizes come from the model: one ContactObservables per model.contacts entry, one
// LigamentObservables per model.ligaments entry. SI units except where a name says
// otherwise (the joint angles as the outputs report them).
//
//   joint angles   flexion α, valgus β − 90° (β is the raw JCS coordinate, 90° = neutral),
//                  external rotation γ, their rates (Eq. 1.3), and w_T (docs/model.md §2: the exact map)
//   energies       kinetic ½ m|v|² + ½ w_Tᵀ I w_T; potential of gravity and the constant
//                  load −(m g + F)·R0; ligament strain energy Σ V_j(L_j) (the integral of
//                  Eq. 1.14); mechanical = their sum, equal to MechanicalEnergy (dynamics.hpp)
//   contacts       active flag, femoral point (F) and tibial point (T), normal force N
//                  (0 when separated), gap φ and rate φ̇ (constraint_residuals.hpp), and
//                  the slope |∇f| of the femoral height-field chart at the contact point
//                  (conditioning of the chapter's chart near the condyle rim)
//   ligaments      length L (m), strain ε = (L − L0)/L0, tension F ≥ 0 (N) by the law as
//                  written (Eq. 1.14, branch chosen by length)
#pragma once

#include <limits>
#include <vector>

#include "solver/state.hpp"

namespace kneedyn {

// Where the contact points come from.
enum class ContactPointSource {
  // The surface points at the state's contact coordinates (every formulation keeps them;
  // chapter-form unknowns, Eq. 1.8): what trajectory.csv reports.
  kStateCoordinates,
  // The contact kinematics at q (contact_kinematics.hpp); for a sphere on a plane the
  // tibial point is the femoral point in T (on the line of action). The metrics use it for
  // closed-form formulations.
  kPose,
};

struct JointObservables {
  double flexion_deg = 0.0, valgus_deg = 0.0, external_rotation_deg = 0.0;
  double flexion_rate_deg_s = 0.0, valgus_rate_deg_s = 0.0, external_rotation_rate_deg_s = 0.0;
  Vector3d omega_T = Vector3d::Zero();  // w_T, rad/s
};

struct EnergyObservables {
  double kinetic = 0.0;             // J
  double load_potential = 0.0;      // −(m g + F_const)·R0, J
  double ligament_potential = 0.0;  // Σ_j V_j, J
  double mechanical = 0.0;          // sum, summed as MechanicalEnergy does, J
};

struct ContactObservables {
  bool active = false;
  bool point_found = false;  // active and its points could be evaluated
  Vector3d point_F = Vector3d::Constant(std::numeric_limits<double>::quiet_NaN());  // m
  Vector3d point_T = Vector3d::Constant(std::numeric_limits<double>::quiet_NaN());  // m
  double normal_force = 0.0;  // N; 0 when separated
  double gap = std::numeric_limits<double>::quiet_NaN();       // φ, m
  double gap_rate = std::numeric_limits<double>::quiet_NaN();  // φ̇, m/s
  // |∇f| of the femoral height-field chart at the femoral point from the contact kinematics
  // at q; +inf outside the height field's domain; NaN when inactive or no point found.
  double femoral_slope = std::numeric_limits<double>::quiet_NaN();
};

struct LigamentObservables {
  double length = 0.0;   // L, m
  double strain = 0.0;   // ε
  double tension = 0.0;  // F, N
};

struct Observables {
  double t = 0.0;               // s
  double pulse = 0.0;           // Fe(t), N
  int contacts_active = 0;
  JointObservables joint;
  EnergyObservables energy;
  std::vector<ContactObservables> contacts;    // per model.contacts
  std::vector<LigamentObservables> ligaments;  // per model.ligaments
};

// What ComputeObservables fills besides t, the pulse, the joint, the contacts (points,
// force, gap, gap rate) and the ligaments. Each is a second pass over the pose (the energies
// every ligament's length again, the slope a second contact kinematics), and the trajectory
// table prints neither (formulations/run_output.cpp asks for kObserveNothingMore).
enum ObservableExtras : unsigned {
  kObserveNothingMore = 0,
  kObserveEnergies = 1u << 0,      // else `energy` is all 0
  kObserveFemoralSlope = 1u << 1,  // else every contact's femoral_slope is NaN
  kObserveEverything = kObserveEnergies | kObserveFemoralSlope,
};

// Fills `out` (vectors resized to the model's counts).
void ComputeObservables(const Model& model, const MechanicalState& state,
                        ContactPointSource source, Observables* out,
                        unsigned extras = kObserveEverything);

// Energies alone (no contact kinematics), for drift measurements over many samples.
EnergyObservables ComputeEnergies(const Model& model, const Vector6d& q, const Vector6d& qd);

}  // namespace kneedyn
