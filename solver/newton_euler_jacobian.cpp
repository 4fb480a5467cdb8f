#include "solver/newton_euler_jacobian.hpp"

namespace kneedyn {

namespace {

Matrix3d Skew(const Vector3d& v) {
  Matrix3d S;
  S << 0.0, -v(2), v(1),  //
      v(2), 0.0, -v(0),   //
      -v(1), v(0), 0.0;
  return S;
}

}  // namespace

void AppliedWrenchPartials(const Model& model, double t, const Vector6d& q, const Data& data,
                           Matrix6d* d_q) {
  Matrix6d& D = *d_q;
  D.setZero();
  const EulerAngleTrig<double> trig = EulerAngleTrigOf(q);
  const Matrix3d R = RotationFT(trig);
  Matrix3d dR[3];
  RotationPartials(trig, dR);
  // Pulse R_FT (Fe(t) d_T) at the centre of mass: no moment.
  const Vector3d pulse_T = PulseMagnitude(model.pulse, t) * model.pulse.direction_T;
  for (int a = 0; a < 3; ++a) D.block<3, 1>(0, 3 + a) += dR[a] * pulse_T;
  // Ligament j: span s = p_FoA_F − (R0 + R b), b = p_ToB_T; f_F = F(L) s/L with L = |s|;
  // df = K ds, K = F′ ŝŝᵀ + (F/L)(1 − ŝŝᵀ); moment b × (Rᵀ f).
  const Vector3d p = q.head<3>();
  for (size_t j = 0; j < model.ligaments.size(); ++j) {
    const Ligament& lig = model.ligaments[j];
    const Vector3d& b = lig.p_ToB_T;
    const Vector3d s = lig.p_FoA_F - (p + R * b);
    const double L = s.norm();
    const LigamentBranch branch = data.ligament_branch && !data.ligament_branch->empty()
                                      ? static_cast<LigamentBranch>((*data.ligament_branch)[j])
                                      : kBranchAuto;
    const double tension = LigamentTension(lig, L, branch);
    if (tension == 0.0) continue;  // as ComputeAppliedWrench: a slack element adds nothing
    const double stiffness = LigamentStiffness(lig, L, branch);
    const Vector3d u = s / L;
    const Matrix3d K = stiffness * u * u.transpose() + (tension / L) * (Matrix3d::Identity() - u * u.transpose());
    Eigen::Matrix<double, 3, 6> df;
    df.leftCols<3>() = -K;
    for (int a = 0; a < 3; ++a) df.col(3 + a) = -K * (dR[a] * b);
    D.topRows<3>() += df;
    const Vector3d f_F = tension * u;
    const Matrix3d Sb = Skew(b);
    Eigen::Matrix<double, 3, 6> dRtf = R.transpose() * df;
    for (int a = 0; a < 3; ++a) dRtf.col(3 + a) += dR[a].transpose() * f_F;
    D.bottomRows<3>() += Sb * dRtf;
  }
  // Patellar tendon at the tuberosity (docs/model.md §12): a Jet over q through the
  // implicit-function lift of the patella's equilibrium (PatellarTendonForce).
  if (model.patella) {
    using J6 = ceres::Jet<double, 6>;
    const PoseTpl<J6> pose = PoseWithCoordinateDerivatives<6>(q);
    Vector3<J6> f_F;
    if (data.lagged_tendon != nullptr) {
      const Vector3<J6> span_F = data.lagged_tendon->apex_F.cast<J6>() - TuberosityInF(*model.patella, pose);
      f_F = J6(data.lagged_tendon->tension) * span_F / span_F.norm();
    } else {
      PatellaGuess guess = data.patella_guess;
      J6 tension;
      PatellarTendonForce(*model.patella, t, pose, &guess, &tension, &f_F);
    }
    const Vector3<J6> moment_T = model.patella->tuberosity_T.cast<J6>().cross(pose.R_FT.transpose() * f_F);
    for (int i = 0; i < 3; ++i) {
      D.row(i) += f_F(i).v.transpose();
      D.row(3 + i) += moment_T(i).v.transpose();
    }
  }
}

void FreeNewtonEulerPartials(const Model& model, double t, const Vector6d& q, const Vector6d& qd,
                             const Vector6d& qdd, const Data& data, NewtonEulerPartials* out) {
  Matrix6d applied;
  AppliedWrenchPartials(model, t, q, data, &applied);
  out->d_q = -applied;
  out->d_qd.setZero();
  out->d_qdd.setZero();
  out->d_qdd.topLeftCorner<3, 3>().diagonal().setConstant(model.mass);
  // Rotational part I (E q̈_ang + Ė q̇_ang) + w × I w, w = E q̇_ang, over x = (β, γ, q̇_ang,
  // q̈_ang): a Jet of the 8 values it reads.
  using J8 = ceres::Jet<double, 8>;
  const J8 beta(q(kBeta), 0), gamma(q(kGamma), 1);
  Vector3<J8> rate, accel;
  for (int i = 0; i < 3; ++i) {
    rate(i) = J8(qd(3 + i), 2 + i);
    accel(i) = J8(qdd(3 + i), 5 + i);
  }
  using std::cos;
  using std::sin;
  const EulerAngleTrig<J8> trig{J8(0.0), J8(1.0), sin(beta), cos(beta), sin(gamma), cos(gamma)};  // α unused
  const Matrix3<J8> E = AngularVelocityMap(beta, trig);
  const Vector3<J8> w = E * rate;
  const Vector3<J8> w_dot = E * accel + AngularVelocityMapRateTimesRate(trig, rate);
  const Vector3<J8> I = model.inertia_T.cast<J8>();
  const Vector3<J8> rotational = I.cwiseProduct(w_dot) + w.cross(I.cwiseProduct(w));
  for (int i = 0; i < 3; ++i) {
    const auto& v = rotational(i).v;
    out->d_q(3 + i, kBeta) += v(0);
    out->d_q(3 + i, kGamma) += v(1);
    for (int j = 0; j < 3; ++j) {
      out->d_qd(3 + i, 3 + j) = v(2 + j);
      out->d_qdd(3 + i, 3 + j) = v(5 + j);
    }
  }
}

}  // namespace kneedyn
