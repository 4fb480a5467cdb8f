// The chart of the `mde` form (formulations/mde.cpp, the open problem's form "mde"): minimal
// differential equations. The contact conditions φ_i(q) = 0
// (contact_kinematics.hpp, any surface pair) are solved for k translations of R0 by Newton
// (∂φ_i/∂R0 = −n_F,i; for sphere on plane φ_i = n_i·(C_i − R0) − d_i − r_i is linear in R0
// and one step is exact), so k active contacts eliminate k translations and the state is
// y = (s, ṡ) with the 6 − k free coordinates s:
//   two-point  s = (y0, α, β, γ): x0, z0 from the 2×2 solve of φ1 = φ2 = 0 (the admissible
//              R0 lie on a line along n1 × n2, parameterised by y0);
//   one-point  s = (x0, y0, α, β, γ): z0 from φ = 0;
//   none       s = q.
// (The eliminated pair/component is the one with the best-conditioned solve at the phase
// start, x0, z0 resp. z0 at the chapter's start poses; after every accepted step the chart
// is switched — integrator restart — when another choice is better conditioned by 2x. A
// chart that lost a factor kMaxChartDegradation within one step is refused with a
// SolverError: the elimination would silently return garbage, e.g. z0 of a one-point
// contact as its normal turns horizontal near 90° flexion.)
// Velocities by the chain rule: φ̇ = J q̇ = 0 with J = ∂φ/∂q = G B (contact.hpp, pose.hpp)
// gives q̇ = P ṡ, P = [I; −J_D⁻¹ J_F] (D eliminated, F free columns).
// Accelerations without second derivatives of the elimination: φ̈ = G ν̇ + κ = 0 with
// ν̇ = B q̈ + (0, Ė θ̇) gives J q̈ + c = 0, c = G_w Ė θ̇ + κ, so q̈ = P s̈ + p with
// p_D = −J_D⁻¹ c, and ν̇ = A s̈ + b with A = B P, b = B p + (0, Ė θ̇). Projecting the
// Newton–Euler equations M ν̇ = Q + Σ N_i G_iᵀ onto the admissible motions (G A = J P = 0):
//   (Aᵀ M A) s̈ = Aᵀ (Q − M b)                                 (Kane / Maggi form)
// Contact forces afterwards from the full equations: Gᵀ N = M ν̇ − Q (least squares).
// The constraints hold by construction (no drift); lift-off root g = N_i.
#pragma once

#include <Eigen/Core>
#include <algorithm>
#include <array>
#include <vector>

#include "solver/dynamics.hpp"
#include "solver/model.hpp"
#include "solver/pose.hpp"

namespace kneedyn {

// |det| of the elimination solve below which the pose is treated as degenerate.
constexpr double kMinEliminationDeterminant = 1.0e-8;
// The chart in use is kept while its |det| is at least this fraction of the best chart's
// (a switch at 2x); the Problem interface's chart event is its zero (problem/problem.cpp).
constexpr double kChartKeepFraction = 0.5;
// Largest loss of conditioning of the chart in use, best |det| / its |det|, tolerated
// inside a step (charts are switched at 2x after each step).
constexpr double kMaxChartDegradation = 1.0e3;
// Newton for the eliminated translations: stop at this max |φ_i| (m) / after this many steps.
constexpr double kEliminationTolerance = 1.0e-15;
constexpr int kMaxEliminationIterations = 20;

// Fixed-capacity Eigen types of the elimination (k ≤ 2 active contacts, m = 6 − k ≤ 6 free
// coordinates): no heap allocation in the right-hand side (tests/zero_allocation_test.cpp).
constexpr int kMaxMdeContacts = 2;
using MatKK = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, kMaxMdeContacts, kMaxMdeContacts>;
using MatK3 = Eigen::Matrix<double, Eigen::Dynamic, 3, 0, kMaxMdeContacts, 3>;
using MatK6 = Eigen::Matrix<double, Eigen::Dynamic, 6, 0, kMaxMdeContacts, 6>;
using MatKM = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, kMaxMdeContacts, 6>;
using Mat6M = Eigen::Matrix<double, 6, Eigen::Dynamic, 0, 6, 6>;
using Mat6K = Eigen::Matrix<double, 6, Eigen::Dynamic, 0, 6, kMaxMdeContacts>;
using MatMM = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, 6, 6>;
using VecK = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, kMaxMdeContacts, 1>;
using VecM = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, 6, 1>;

struct MdeKinematics {
  Vector6d q, qd, qdd;
  std::array<double, kMaxMdeContacts> normal_force{};  // per active contact, N
  MatKM elimination_tangent;  // ∂x_D/∂s = −J_D⁻¹ J_F at q (k × m): a Newton start's predictor
};

// The elimination of one contact phase: which translations are eliminated (the chart), and
// the state (s, ṡ) → (q, q̇, q̈, N) map with s̈. Shared by the mde formulation and the open
// problem's "mde" form, so both evaluate the same right-hand side.
class MdeChart {
 public:
  explicit MdeChart(const Model& model) : model_(model), data_(model) {}

  // A new phase with these active contacts (indices into model.contacts) from the pose q:
  // a fresh chart (Choose) whose Newton starts from q (SetStartPose).
  void Begin(const std::vector<int>& active, const Vector6d& q) {
    active_ = active;
    elim_.clear();
    Choose(q);
    SetStartPose(q);
  }
  // The Newton start of the eliminated translations, a consistent pose q in the chart in use
  // (a chart switch sets it to the pose): Evaluate starts from q's eliminated translations
  // moved along the constraint manifold's tangent at q, x_D = x_D(q) + ∂x_D/∂s (s − s(q)).
  // Without the tangent term a start a few degrees of flexion back can put the first Newton
  // iterate off the surfaces (anatomical caps); with it the start is off by second order.
  void SetStartPose(const Vector6d& q);
  // The same from a point Evaluate returned in the chart in use (its tangent already computed):
  // the mde formulation re-seeds after every accepted step, the open problem's mde form after
  // every evaluation, so that the start stays near however far a contact phase runs (from the
  // phase start alone, 36 deg into one phase, the first Newton iterate fell off the surfaces).
  void SetStartPose(const MdeKinematics& at) {
    start_q_ = at.q;
    start_tangent_ = at.elimination_tangent;
  }

  // Picks the k translations to eliminate: the best-conditioned k×k block of the normals;
  // the chart in use is kept while it stays within a factor 2 of the best one. Throws
  // SolverError for more than 2 active contacts or (nearly) dependent normals.
  void Choose(const Vector6d& q);
  // Picks afresh, the chart in use forgotten (the open problem's chart-switch event).
  void ChooseAfresh(const Vector6d& q) {
    elim_.clear();
    Choose(q);
  }

  // |det| of the chart in use and of the best chart at the pose q, in the normals of its
  // active contacts (1 and 1 with none).
  void Conditioning(const Vector6d& q, double* current, double* best) const;

  // q from s (closed-form elimination); qd = P ṡ; s̈ (if sdd_out) and q̈, N. ligament_branch:
  // the phase's locked branches (loads.hpp).
  MdeKinematics Evaluate(double t, const double* y, const std::vector<signed char>* ligament_branch,
                         VecM* sdd_out) const;

  // The pose and ligament lengths of the last Evaluate (the root functions reuse them at the
  // same point instead of a new pose and twelve spans).
  const Pose& last_pose() const { return pose_; }
  const std::vector<double>& last_ligament_length() const { return data_.ligament_length; }

  const std::vector<int>& free() const { return free_; }         // indices into q of s, ascending
  const std::vector<int>& eliminated() const { return elim_; }  // one translation per active contact
  int size() const { return 2 * static_cast<int>(free_.size()); }

 private:
  void SetFree() {
    free_.clear();
    for (int i = 0; i < 6; ++i) {
      if (std::find(elim_.begin(), elim_.end(), i) == elim_.end()) free_.push_back(i);
    }
  }

  // Candidate eliminated sets for k active contacts, in the documented order.
  static const std::vector<std::vector<int>>& Candidates(int k) {
    static const std::vector<std::vector<int>> kNone = {{}};
    static const std::vector<std::vector<int>> kOne = {{kZ0}, {kX0}, {kY0}};
    static const std::vector<std::vector<int>> kTwo = {{kX0, kZ0}, {kY0, kZ0}, {kX0, kY0}};
    return k == 0 ? kNone : k == 1 ? kOne : kTwo;
  }

  // |det| of the elimination block of `cand` for the normals n_i = R n̂′_i (rows).
  static double BlockDeterminant(const MatK3& normals, const std::vector<int>& cand);
  // Contact normals n_F (rows) of the active contacts at the full pose q.
  MatK3 ContactNormals(const Vector6d& q) const;

  const Model& model_;
  std::vector<int> active_;
  std::vector<int> free_;  // indices into q of s, ascending
  std::vector<int> elim_;  // eliminated translations (one per active contact)
  // J = ∂φ/∂q = G B of the active contacts at `pose` (geometry geo[r]), and G.
  void ConstraintJacobian(const Pose& pose, const Matrix3d& E, const ContactGeometry* geo, MatK6* G, MatK6* J) const;
  // J's eliminated columns factored (J_D, k × k, into *JD_lu) and the elimination's tangent
  // ∂x_D/∂s = −J_D⁻¹ J_F (k × m): shared by the start pose and every evaluation.
  MatKM EliminationTangent(const MatK6& J, Eigen::PartialPivLU<MatKK>* JD_lu) const;

  // The eliminated translations start Newton from the start pose's values moved along its
  // tangent; the result depends on the start only at round-off (Newton to
  // kEliminationTolerance, at least one step). start_tangent_ = ∂x_D/∂s = −J_D⁻¹ J_F at
  // start_q_ (k × m).
  Vector6d start_q_ = Vector6d::Zero();
  MatKM start_tangent_;
  mutable Data data_;  // applied-load workspace of Evaluate
  mutable Pose pose_;  // pose of the last Evaluate
};

}  // namespace kneedyn
