// Newton–Euler equations of the tibia (chapter Eqs. 1.17–1.24; docs/model.md §8), shared by every
// formulation. In ν = (v_F, w_T) coordinates the mass matrix is constant:
//
//   m a_F                   = W + Fe(t) R d_T + Σ_j F_j û_j − Σ_i N_i n_i     (Eqs. 1.48–1.57)
//   I ẇ_T + w_T × (I w_T)   = M′ (ligament and contact moments about the COM, T components)
//
// i.e.  M ν̇ = Q(t, q, ν) + Σ_i N_i G_iᵀ  with M = diag(m 1, I) and
//       Q = (F_applied_F, M_applied_T − w_T × I w_T);  G_i from contact.hpp.
// (The printed Eq. 1.22 repeats the y′ equation; the x′ one is the cyclic one, docs/model.md §8.)
#pragma once

#include <vector>

#include "solver/contact_kinematics.hpp"
#include "solver/ligament.hpp"
#include "solver/loads.hpp"
#include "solver/patella.hpp"
#include "solver/patella_extended.hpp"

namespace kneedyn {

// Workspace of the applied-load computation (mutable data kept apart from the
// constant Model).
template <typename T>
struct DataTpl {
  explicit DataTpl(const Model& model)
      : ligament_length(model.ligaments.size()), ligament_tension(model.ligaments.size()) {}
  std::vector<T> ligament_length;   // L_j, m
  std::vector<T> ligament_tension;  // F_j ≥ 0, N
  Vector3<T> applied_force_F;       // gravity + pulse + ligaments + constant load, N
  Vector3<T> applied_moment_T;      // ligaments + constant torque, about the COM, N m
  double pulse_magnitude = 0.0;     // Fe(t), N
  PulseMagnitudeCache pulse_cache;  // Fe at the last t (loads.hpp)
  // Optional branch per ligament (ligament.hpp, discontinuity locking); null = by length.
  const std::vector<signed char>* ligament_branch = nullptr;
  // Patella (model.patella only): the warm start of its equilibrium solve, and the tendon
  // tension F_t (N) of the last computation.
  PatellaGuess patella_guess;
  T tendon_tension = T(0.0);
  // Staggered coupling (chapter §1.7): when set, the tendon pulls the tibia with the
  // tension and towards the apex position found at the end of the previous step (held over
  // the step) instead of the patella's equilibrium at the current pose.
  const LaggedTendon* lagged_tendon = nullptr;
};
using Data = DataTpl<double>;

// Fills data with the loads that do not depend on contact: gravity, pulse and constant
// load at the COM, ligament forces at their tibial attachments.
template <typename T>
void ComputeAppliedWrench(const Model& model, double t, const PoseTpl<T>& pose,
                          DataTpl<T>* data) {
  data->pulse_magnitude = data->pulse_cache.At(model.pulse, t);
  Vector3<T> force = (model.mass * model.gravity_F + model.constant_load.force_F).template cast<T>();
  force += pose.R_FT * (data->pulse_magnitude * model.pulse.direction_T).template cast<T>();
  Vector3<T> moment = model.constant_load.torque_T.template cast<T>();
  if (model.manufactured_load) {  // verification hook (model.hpp); empty in scenes
    Vector3d extra_force_F = Vector3d::Zero(), extra_torque_T = Vector3d::Zero();
    model.manufactured_load(t, &extra_force_F, &extra_torque_T);
    force += extra_force_F.template cast<T>();
    moment += extra_torque_T.template cast<T>();
  }
  const Matrix3<T> R_TF = pose.R_FT.transpose();
  // The locked branches (ligament.hpp), looked up once rather than per element; null: by length.
  const signed char* branches =
      data->ligament_branch && !data->ligament_branch->empty() ? data->ligament_branch->data() : nullptr;
  for (size_t j = 0; j < model.ligaments.size(); ++j) {
    const Ligament& lig = model.ligaments[j];
    const Vector3<T> span_F = LigamentSpan_F(lig, pose);
    const T length = span_F.norm();
    const LigamentBranch branch = branches ? static_cast<LigamentBranch>(branches[j]) : kBranchAuto;
    const T tension = LigamentTension(lig, length, branch);
    data->ligament_length[j] = length;
    data->ligament_tension[j] = tension;
    if (ScalarPart(tension) == 0.0) continue;
    const Vector3<T> f_F = tension * span_F / length;  // towards the femoral attachment
    force += f_F;
    moment += lig.p_ToB_T.template cast<T>().cross(R_TF * f_F);
  }
  if (model.patella) {  // the patellar tendon at the tuberosity (docs/model.md §12, Eq. 1.63)
    Vector3<T> f_F;
    if (data->lagged_tendon != nullptr) {
      const Vector3<T> span_F = data->lagged_tendon->apex_F.template cast<T>() - TuberosityInF(*model.patella, pose);
      data->tendon_tension = T(data->lagged_tendon->tension);
      f_F = data->tendon_tension * span_F / span_F.norm();
    } else if constexpr (IsDoubleOrJet<T>::value) {
      PatellarTendonForce(*model.patella, t, pose, &data->patella_guess, &data->tendon_tension, &f_F);
    } else {  // wide scalar: the double solve refined in T (patella_extended.hpp)
      PatellarTendonForceExtended(*model.patella, t, pose, &data->patella_guess, &data->tendon_tension, &f_F);
    }
    force += f_F;
    moment += model.patella->tuberosity_T.template cast<T>().cross(R_TF * f_F);
  }
  data->applied_force_F = force;
  data->applied_moment_T = moment;
}

// Q(t, q, ν): applied generalized force minus gyroscopic term, ν-coordinates.
template <typename T>
Vector6<T> GeneralizedForce(const Model& model, const DataTpl<T>& data, const Vector3<T>& w_T) {
  const Vector3<T> I = model.inertia_T.template cast<T>();
  const Vector3<T> Iw = I.cwiseProduct(w_T);
  Vector6<T> Q;
  Q.template head<3>() = data.applied_force_F;
  Q.template tail<3>() = data.applied_moment_T - w_T.cross(Iw);
  return Q;
}

// M ν̇ (M constant and diagonal in ν-coordinates).
template <typename T>
Vector6<T> MassTimes(const Model& model, const Vector6<T>& nu_dot) {
  Vector6<T> out;
  out.template head<3>() = model.mass * nu_dot.template head<3>();
  out.template tail<3>() = model.inertia_T.template cast<T>().cwiseProduct(nu_dot.template tail<3>());
  return out;
}

Matrix6d MassMatrix(const Model& model);

// The branch each ligament is on just after (q, q̇): by length, except at the kink itself
// (within 1e-12 m), where the direction of motion decides. For phase starts.
std::vector<signed char> LigamentBranchesAt(const Model& model, const Vector6d& q, const Vector6d& qd);

// Kinetic + gravitational + ligament strain energy (J), for conservative scenes.
// Gravitational potential −m g·R0 (g constant); constant loads add −F·R0.
double MechanicalEnergy(const Model& model, const Vector6d& q, const Vector6d& qd);
// The same in any scalar type (the double overload calls it).
template <typename T>
T MechanicalEnergyTpl(const Model& model, const Vector6<T>& q, const Vector6<T>& qd) {
  const Vector6<T> nu = GeneralizedVelocity(q, qd);
  const Vector3<T> w = nu.template tail<3>();
  T energy = 0.5 * model.mass * nu.template head<3>().squaredNorm() +
             0.5 * w.dot(model.inertia_T.template cast<T>().cwiseProduct(w));
  energy -= (model.mass * model.gravity_F + model.constant_load.force_F).template cast<T>().dot(q.template head<3>());
  const PoseTpl<T> pose = PoseFromCoordinates(q);
  for (const Ligament& lig : model.ligaments) {
    energy += LigamentPotentialTpl(lig, T(LigamentSpan_F(lig, pose).norm()));
  }
  return energy;
}

}  // namespace kneedyn
