// Exact first derivatives of the Newton–Euler residual (newton_euler.hpp; chapter Eqs.
// 1.48–1.57) without a Jet over every unknown (the exact DAE Jacobian;
// benchmarks/performance-log.md, "Performance targets: measured"). The residual splits as
//
//   r(t, q, q̇, q̈, c, N) = r_free(t, q, q̇, q̈) − Σ_i N_i G_i(q, c_i)ᵀ
//   r_free = M ν̇(q, q̇, q̈) + (0, w_T × I w_T) − (F_applied_F(t, q), M_applied_T(t, q))
//
// and each part is differentiated at its own size:
//  - the applied loads (gravity, pulse, ligaments: most of the flops) analytically,
//    ∂(F_applied_F, M_applied_T)/∂q from ∂R/∂q (RotationPartials) and the ligament law's
//    slope (LigamentStiffness);
//  - the kinematic part M ν̇ + (0, w × I w): its q̈ block M (diag(I) E for the angles) in
//    closed form, the rest with a Jet over the 5 values it reads (β, γ, q̇_ang);
//  - the contact terms from the contact geometry as a Jet over (q, c_i) (ContactJet: 10
//    slots), which callers form with PoseWithCoordinateDerivatives; ∂r/∂N_i = −G_iᵀ.
// Tests (tests/dae_system_test.cpp) compare every block with the Jet<24>
// derivative of the same residual and with central differences.
#pragma once

#include "solver/contact.hpp"
#include "solver/dynamics.hpp"

namespace kneedyn {

// Derivative slots: 0–5 the coordinates q, 6–9 one contact's coordinates c_i.
constexpr int kContactJetSize = 10;
using ContactJet = ceres::Jet<double, kContactJetSize>;

// The pose as Jets whose slots 0–5 hold ∂/∂q (∂p_FoTo_F/∂q_i = e_i for i < 3, ∂R_FT/∂q_i
// from RotationPartials for i ≥ 3); the other slots are zero.
template <int N>
PoseTpl<ceres::Jet<double, N>> PoseWithCoordinateDerivatives(const Vector6d& q) {
  static_assert(N >= 6, "the first six slots hold dq");
  using J = ceres::Jet<double, N>;
  PoseTpl<J> out;
  const EulerAngleTrig<double> trig = EulerAngleTrigOf(q);
  const Matrix3d R = RotationFT(trig);
  Matrix3d dR[3];
  RotationPartials(trig, dR);
  for (int i = 0; i < 3; ++i) {
    out.p_FoTo_F(i) = J(q(i), i);
    for (int j = 0; j < 3; ++j) {
      J r(R(i, j));
      for (int a = 0; a < 3; ++a) r.v[3 + a] = dR[a](i, j);
      out.R_FT(i, j) = r;
    }
  }
  return out;
}

// One contact's chapter-form residuals in the regular chart (ChapterContactResiduals with
// ContactChart::kRegular: r[0..4], Eq. 1.8 tangential and normal components, Eq. 1.13) and its
// velocity-constraint row G = [−n_Fᵀ, (n′ × X′t)ᵀ] (ContactConstraintRow), as ContactJets
// whose slots hold the exact first derivatives over (q, c_i) — the numbers those functions
// give on PoseWithCoordinateDerivatives' Jet pose, to round-off — differentiated in closed
// form from the charts' second derivatives (ChartSample) and ∂R/∂q (dR, RotationPartials at
// the pose). With e = Pf − (R0 + R P′t), ε = Rᵀ e (T) and x̂ = x/|x|, d(x̂) = (dx − x̂ (x̂·dx))/|x|:
//   ∂r_0/∂R0 = −R P̂′t_u,  ∂r_0/∂q_a = −(∂_a R P′t)·(R P̂′t_u) + e·(∂_a R P̂′t_u)  (a: α, β, γ)
//   ∂r_0/∂uf = Pf_u·(R P̂′t_u),  ∂r_0/∂ut = −P′t_u·P̂′t_u + ε·∂(P̂′t_u)/∂ut      (likewise r_1, r_2)
//   ∂r_3/∂q_a = (∂_a R n′)·P̂f_u,  ∂r_3/∂uf = n_F·∂(P̂f_u)/∂uf,  ∂r_3/∂ut = (R ∂n′/∂ut)·P̂f_u
// with ∂n′/∂ut from ∂(P′t_u × P′t_v)/∂ut = P′t_uu × P′t_v + P′t_u × P′t_uv. False outside a
// chart's domain. Tested against the Jet evaluation (tests/dae_system_test.cpp).
bool RegularChartContactPartials(const ContactPair& pair, const Pose& pose, const Matrix3d dR[3],
                                 const double c[4], ContactJet r[5], Eigen::Matrix<ContactJet, 1, 6>* G);

// ∂r_free/∂q, ∂r_free/∂q̇, ∂r_free/∂q̈ (6×6 each, ν-rows, q-columns).
struct NewtonEulerPartials {
  Matrix6d d_q = Matrix6d::Zero();
  Matrix6d d_qd = Matrix6d::Zero();
  Matrix6d d_qdd = Matrix6d::Zero();
};

// ∂(F_applied_F, M_applied_T)/∂q (rows 0–2 force, 3–5 moment) of ComputeAppliedWrench at
// (t, q), on the ligament branches in data->ligament_branch (null: by length). No allocation.
void AppliedWrenchPartials(const Model& model, double t, const Vector6d& q, const Data& data,
                           Matrix6d* d_q);

// The partials of r_free at (t, q, q̇, q̈). No allocation. Throws at the JCS singularity.
void FreeNewtonEulerPartials(const Model& model, double t, const Vector6d& q, const Vector6d& qd,
                             const Vector6d& qdd, const Data& data, NewtonEulerPartials* out);

}  // namespace kneedyn
