#include "formulations/internal/mde_chart.hpp"

#include <Eigen/LU>
#include <Eigen/QR>
#include <algorithm>
#include <cmath>

#include "solver/constrained_dynamics.hpp"
#include "solver/contact_kinematics.hpp"
#include "solver/error.hpp"
#include "solver/units.hpp"

namespace kneedyn {

double MdeChart::BlockDeterminant(const MatK3& normals, const std::vector<int>& cand) {
  const int k = static_cast<int>(cand.size());
  if (k == 0) return 1.0;
  MatKK block(k, k);
  for (int c = 0; c < k; ++c) block.col(c) = normals.col(cand[c]);
  return std::abs(block.determinant());
}

void MdeChart::ConstraintJacobian(const Pose& pose, const Matrix3d& E, const ContactGeometry* geo, MatK6* G,
                                  MatK6* J) const {
  for (int r = 0; r < G->rows(); ++r) {
    G->row(r) = ContactConstraintRow(pose, geo[r]);
    J->block(r, 0, 1, 3) = G->block(r, 0, 1, 3);
    J->block(r, 3, 1, 3) = G->block(r, 3, 1, 3) * E;
  }
}

void MdeChart::SetStartPose(const Vector6d& q) {
  start_q_ = q;
  const int k = static_cast<int>(elim_.size());
  start_tangent_.resize(0, 0);
  if (k == 0) return;
  const EulerAngleTrig<double> trig = EulerAngleTrigOf(q);
  const Pose pose = PoseFromCoordinates(q, trig);
  std::array<ContactGeometry, kMaxMdeContacts> geo;
  for (int r = 0; r < k; ++r) geo[r] = RequireContactKinematics(model_.contacts[active_[r]], pose, "MdeFormulation");
  MatK6 G(k, 6), J(k, 6);
  ConstraintJacobian(pose, AngularVelocityMap(q(kBeta), trig), geo.data(), &G, &J);
  Eigen::PartialPivLU<MatKK> JD_lu;
  start_tangent_ = EliminationTangent(J, &JD_lu);
}

MatKM MdeChart::EliminationTangent(const MatK6& J, Eigen::PartialPivLU<MatKK>* JD_lu) const {
  const int k = static_cast<int>(elim_.size());
  const int m = static_cast<int>(free_.size());
  MatKK JD(k, k);
  MatKM JF(k, m);
  for (int c = 0; c < k; ++c) JD.col(c) = J.col(elim_[c]);
  for (int j = 0; j < m; ++j) JF.col(j) = J.col(free_[j]);
  JD_lu->compute(JD);
  return -JD_lu->solve(JF);
}

MatK3 MdeChart::ContactNormals(const Vector6d& q) const {
  const int k = static_cast<int>(active_.size());
  const Pose pose = PoseFromCoordinates(q);
  MatK3 normals(k, 3);
  for (int r = 0; r < k; ++r) {
    const ContactGeometry g = RequireContactKinematics(model_.contacts[active_[r]], pose, "MdeFormulation");
    normals.row(r) = (pose.R_FT * g.normal_T).transpose();
  }
  return normals;
}

void MdeChart::Choose(const Vector6d& q) {
  const int k = static_cast<int>(active_.size());
  if (k > 2) Throw<SolverError>("MdeFormulation::Start", k, " active contacts; at most 2 supported");
  const MatK3 normals = ContactNormals(q);
  const std::vector<int> current = elim_;
  double current_det = -1.0;
  elim_.clear();
  double best = -1.0;
  for (const std::vector<int>& cand : Candidates(k)) {
    const double det = BlockDeterminant(normals, cand);
    if (cand == current) current_det = det;
    if (det > best * 1.5) {  // keep the documented order unless clearly worse
      best = det;
      elim_ = cand;
    }
  }
  // Keep the chart in use while it stays within a factor 2 of the best one.
  if (!current.empty() && current.size() == static_cast<size_t>(k) && current_det >= kChartKeepFraction * best) {
    elim_ = current;
    best = current_det;
  }
  if (best < kMinEliminationDeterminant) {
    Throw<SolverError>("MdeFormulation::Start", "contact normals are (nearly) dependent: |det| = ", best);
  }
  SetFree();
}

void MdeChart::Conditioning(const Vector6d& q, double* current, double* best) const {
  *current = *best = 1.0;
  const int k = static_cast<int>(active_.size());
  if (k == 0) return;
  const MatK3 normals = ContactNormals(q);
  *best = 0.0;
  for (const std::vector<int>& cand : Candidates(k)) *best = std::max(*best, BlockDeterminant(normals, cand));
  *current = BlockDeterminant(normals, elim_);
}

MdeKinematics MdeChart::Evaluate(double t, const double* y, const std::vector<signed char>* ligament_branch,
                                 VecM* sdd_out) const {
  const int m = static_cast<int>(free_.size());
  const int k = static_cast<int>(elim_.size());
  MdeKinematics kin;
  kin.q = start_q_;
  for (int j = 0; j < m; ++j) kin.q(free_[j]) = y[j];
  // φ_i(q) = 0 solved for the eliminated translations by Newton (∂φ_i/∂R0 = −n_F,i); one
  // step is exact for a sphere on a plane (φ linear in R0), a few for curved surfaces.
  std::array<ContactGeometry, kMaxMdeContacts> geo;
  // Closed form where one exists: n_i · R0 = h_i, the gap being affine in R0
  // (SphereOnPlaneClosingHeight).
  bool closed_form = k > 0;
  std::array<SphereOnPlane, kMaxMdeContacts> sop;
  for (int r = 0; r < k; ++r) closed_form = closed_form && SphereOnPlaneForm(model_.contacts[active_[r]], &sop[r]);
  if (closed_form) {
    const Matrix3d R = RotationFT(kin.q(kAlpha), kin.q(kBeta), kin.q(kGamma));
    MatKK ND(k, k);
    VecK rhs(k);
    for (int r = 0; r < k; ++r) {
      const Vector3d n = R * sop[r].normal_T;
      rhs(r) = SphereOnPlaneClosingHeight(sop[r], n);
      for (int j = 0; j < m; ++j) {
        if (free_[j] < 3) rhs(r) -= n(free_[j]) * kin.q(free_[j]);
      }
      for (int c = 0; c < k; ++c) ND(r, c) = n(elim_[c]);
    }
    const VecK x = ND.partialPivLu().solve(rhs);
    for (int c = 0; c < k; ++c) kin.q(elim_[c]) = x(c);
    const Pose pose_c = PoseFromCoordinates(kin.q);
    for (int r = 0; r < k; ++r) geo[r] = SphereOnPlaneContact(sop[r], pose_c);
  }
  // Newton's start for a general pair: the start pose moved along its tangent (SetStartPose).
  bool at_start = true;  // y holds the start pose's free coordinates, bitwise
  if (k > 0 && !closed_form) {
    for (int j = 0; j < m; ++j) at_start = at_start && y[j] == start_q_(free_[j]);
    if (start_tangent_.rows() == k && start_tangent_.cols() == m) {
      for (int c = 0; c < k; ++c) {
        for (int j = 0; j < m; ++j) kin.q(elim_[c]) += start_tangent_(c, j) * (y[j] - start_q_(free_[j]));
      }
    }
  }
  for (int iter = 0; k > 0 && !closed_form; ++iter) {
    const Pose pose_i = PoseFromCoordinates(kin.q);
    MatKK ND(k, k);
    VecK phi(k);
    for (int r = 0; r < k; ++r) {
      try {
        geo[r] = RequireContactKinematics(model_.contacts[active_[r]], pose_i, "MdeFormulation::Evaluate");
      } catch (const SolverError& e) {
        // The pose in the message is a Newton iterate of the elimination, not a state the run
        // reached: say so, with where the elimination started.
        Throw<SolverError>("MdeFormulation::Evaluate", "at Newton step ", iter,
                           " of eliminating the contact translations at t = ", t,
                           " s (a trial pose, not a state of the run; the elimination started from R0 = (",
                           MToMm(start_q_(kX0)), ", ", MToMm(start_q_(kY0)), ", ", MToMm(start_q_(kZ0)), ") mm): ",
                           MessageUnder("MdeFormulation::Evaluate", e.what()));
      }
      phi(r) = geo[r].gap;
      const Vector3d n = pose_i.R_FT * geo[r].normal_T;
      for (int c = 0; c < k; ++c) ND(r, c) = -n(elim_[c]);
    }
    // At least one step (the result must not depend on the start, start_q_), except at the
    // start's own free coordinates: there the start pose itself is the answer when it closes
    // the contacts, so that the phase's first evaluation sees bitwise the pose the simulator
    // started from. (One step from it moved q by ~3e-17 m, enough to put a ligament that sat
    // 1.4e-17 m short of its kink past it: the kink root fired at the phase start again and
    // again, 514 times at one instant with fehlberg78 on anatomical_surfaces.) It also makes
    // an evaluation at a seeded point repeat bitwise.
    if ((iter > 0 || at_start) && phi.cwiseAbs().maxCoeff() <= kEliminationTolerance) break;
    if (iter == kMaxEliminationIterations) {
      Throw<SolverError>("MdeFormulation::Evaluate", "eliminating the contact translations did not converge at t = ", t,
                         " s: max |gap| = ", phi.cwiseAbs().maxCoeff(), " m after ", iter,
                         " Newton steps (rule: <= ", kEliminationTolerance, " m)");
    }
    const VecK dx = ND.partialPivLu().solve(phi);
    for (int c = 0; c < k; ++c) kin.q(elim_[c]) -= dx(c);
  }
  const EulerAngleTrig<double> trig = EulerAngleTrigOf(kin.q);  // of the final pose (rotation.hpp)
  if (k > 0) {
    // The chart in use must still be usable here (see kMaxChartDegradation). geo[r] is the
    // contact at kin.q already (the elimination stops before updating q), so the normals
    // come from it instead of another k local contact solves (perf: a third of the
    // right-hand side's time on general surfaces).
    MatK3 normals(k, 3);
    const Matrix3d R_FT = RotationFT(trig);
    for (int r = 0; r < k; ++r) normals.row(r) = (R_FT * geo[r].normal_T).transpose();
    double best = 0.0;
    for (const std::vector<int>& cand : Candidates(k)) best = std::max(best, BlockDeterminant(normals, cand));
    const double det = BlockDeterminant(normals, elim_);
    if (!(det * kMaxChartDegradation >= best)) {
      Throw<SolverError>("MdeFormulation::Evaluate", "the eliminated coordinates became ill-conditioned within one step at t = ", t,
                         " s, flexion = ", RadToDeg(kin.q(kAlpha)), " deg: |det| = ", det,
                         " of the eliminated block vs ", best, " of the best one (rule: within a factor ",
                         kMaxChartDegradation, "; reduce --rtol or --max-step)");
    }
  }
  pose_ = PoseFromCoordinates(kin.q, trig);
  const Pose& pose = pose_;
  const Matrix3d E = AngularVelocityMap(kin.q(kBeta), trig);
  // J = ∂φ/∂q = G B, and P = ∂q/∂s.
  MatK6 J(k, 6), G(k, 6);
  ConstraintJacobian(pose, E, geo.data(), &G, &J);
  Mat6M P = Mat6M::Zero(6, m);
  for (int j = 0; j < m; ++j) P(free_[j], j) = 1.0;
  Eigen::PartialPivLU<MatKK> JD_lu;
  if (k > 0) {
    kin.elimination_tangent = EliminationTangent(J, &JD_lu);
    for (int c = 0; c < k; ++c) P.row(elim_[c]) = kin.elimination_tangent.row(c);
  }
  const VecM sd = Eigen::Map<const VectorXd>(y + m, m);
  kin.qd = P * sd;
  const Vector6d nu = GeneralizedVelocity(kin.q, trig, kin.qd);
  const Vector3d qd_ang = kin.qd.tail<3>();
  const Vector3d Edot_thetadot = AngularVelocityMapRateTimesRate(trig, qd_ang);
  // q̈ = P s̈ + p;  c_i = G_w,i Ė θ̇ + κ_i.
  Vector6d p = Vector6d::Zero();
  if (k > 0) {
    VecK c(k);
    for (int r = 0; r < k; ++r) {
      c(r) = (G.block(r, 3, 1, 3) * Edot_thetadot)(0) +
             ContactRateTerm(model_.contacts[active_[r]], kin.q, kin.qd, pose, nu);
    }
    const VecK pD = -JD_lu.solve(c);
    for (int r = 0; r < k; ++r) p(elim_[r]) = pD(r);
  }
  // ν̇ = A s̈ + b.
  Mat6M A(6, m);
  A.topRows(3) = P.topRows(3);
  A.bottomRows(3) = E * P.bottomRows(3);
  Vector6d b;
  b.head<3>() = p.head<3>();
  b.tail<3>() = E * p.tail<3>() + Edot_thetadot;
  Data& data = data_;
  data.ligament_branch = ligament_branch;
  ComputeAppliedWrench(model_, t, pose, &data);
  const Vector6d Q = GeneralizedForce(model_, data, Vector3d(nu.tail<3>()));
  const Matrix6d M = MassMatrix(model_);
  const MatMM AtMA = A.transpose() * M * A;
  const VecM sdd = AtMA.ldlt().solve(A.transpose() * (Q - M * b));
  if (sdd_out) *sdd_out = sdd;
  kin.qdd = P * sdd + p;
  // Gᵀ N = M ν̇ − Q.
  if (k > 0) {
    const Vector6d residual = M * (A * sdd + b) - Q;
    const Mat6K Gt = G.transpose();
    const VecK N = Gt.colPivHouseholderQr().solve(residual);
    for (int c = 0; c < k; ++c) kin.normal_force[c] = N(c);
  }
  return kin;
}

}  // namespace kneedyn
