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

bool RegularChartContactPartials(const ContactPair& pair, const Pose& pose, const Matrix3d dR[3],
                                 const double c[4], ContactJet r[5], Eigen::Matrix<ContactJet, 1, 6>* G) {
  ChartSample f, t;  // femoral (F) and tibial (T) chart samples with second derivatives
  if (!pair.femoral_surface->EvaluateChart(c[0], c[1], &f)) return false;
  if (!pair.tibial_surface->EvaluateChart(c[2], c[3], &t)) return false;
  const Matrix3d& R = pose.R_FT;
  const Vector3d e_F = f.p - pose.PointInF(t.p);
  const Vector3d e_T = R.transpose() * e_F;
  const double len_tu = t.p_u.norm(), len_tv = t.p_v.norm(), len_fu = f.p_u.norm(), len_fv = f.p_v.norm();
  const Vector3d tu_T = t.p_u / len_tu, tv_T = t.p_v / len_tv;  // unit tibial tangents
  const Vector3d fu_F = f.p_u / len_fu, fv_F = f.p_v / len_fv;  // unit femoral tangents
  const Vector3d m_T = t.p_u.cross(t.p_v);
  const double len_m = m_T.norm();
  const Vector3d n_T = m_T.normalized();  // as ChapterContactResiduals: the same value
  const Vector3d n_F = R * n_T, tu_F = R * tu_T, tv_F = R * tv_T;
  // Values (only their derivatives and G's value enter the Jacobian).
  r[0] = ContactJet(e_F.dot(R * t.p_u) / len_tu);
  r[1] = ContactJet(e_F.dot(R * t.p_v) / len_tv);
  r[2] = ContactJet(e_F.dot(n_F));
  r[3] = ContactJet(n_F.dot(f.p_u) / len_fu);
  r[4] = ContactJet(n_F.dot(f.p_v) / len_fv);
  const Vector3d G_ang = n_T.cross(t.p);
  for (int i = 0; i < 3; ++i) {
    (*G)(i) = ContactJet(-n_F(i));
    (*G)(3 + i) = ContactJet(G_ang(i));
  }
  // Rate of a unit vector x̂ = x/|x| along dx.
  auto unit_rate = [](const Vector3d& x_hat, double len, const Vector3d& dx) -> Vector3d {
    return (dx - x_hat * x_hat.dot(dx)) / len;
  };
  // R0 (slots 0–2): e moves by −1 along each axis; normals and tangents do not.
  for (int i = 0; i < 3; ++i) {
    r[0].v[i] = -tu_F(i);
    r[1].v[i] = -tv_F(i);
    r[2].v[i] = -n_F(i);
  }
  // Euler angles (slots 3–5): R moves by dR[a].
  for (int a = 0; a < 3; ++a) {
    const Vector3d de_F = -(dR[a] * t.p);
    const Vector3d dn_F = dR[a] * n_T;
    r[0].v[3 + a] = de_F.dot(tu_F) + e_F.dot(dR[a] * tu_T);
    r[1].v[3 + a] = de_F.dot(tv_F) + e_F.dot(dR[a] * tv_T);
    r[2].v[3 + a] = de_F.dot(n_F) + e_F.dot(dn_F);
    r[3].v[3 + a] = dn_F.dot(fu_F);
    r[4].v[3 + a] = dn_F.dot(fv_F);
    for (int i = 0; i < 3; ++i) (*G)(i).v[3 + a] = -dn_F(i);
  }
  // Femoral chart coordinates (slots 6, 7): Pf moves by dp, its tangents by dp_u, dp_v.
  auto femoral = [&](int slot, const Vector3d& dp, const Vector3d& dp_u, const Vector3d& dp_v) {
    r[0].v[slot] = dp.dot(tu_F);
    r[1].v[slot] = dp.dot(tv_F);
    r[2].v[slot] = dp.dot(n_F);
    r[3].v[slot] = n_F.dot(unit_rate(fu_F, len_fu, dp_u));
    r[4].v[slot] = n_F.dot(unit_rate(fv_F, len_fv, dp_v));
  };
  femoral(6, f.p_u, f.p_uu, f.p_uv);
  femoral(7, f.p_v, f.p_uv, f.p_vv);
  // Tibial chart coordinates (slots 8, 9): P′t, its tangents and normal move; e by −R dp.
  auto tibial = [&](int slot, const Vector3d& dp, const Vector3d& dp_u, const Vector3d& dp_v) {
    const Vector3d dn_T = unit_rate(n_T, len_m, dp_u.cross(t.p_v) + t.p_u.cross(dp_v));
    r[0].v[slot] = -dp.dot(tu_T) + e_T.dot(unit_rate(tu_T, len_tu, dp_u));
    r[1].v[slot] = -dp.dot(tv_T) + e_T.dot(unit_rate(tv_T, len_tv, dp_v));
    r[2].v[slot] = -dp.dot(n_T) + e_T.dot(dn_T);
    const Vector3d dn_F = R * dn_T;
    r[3].v[slot] = dn_F.dot(fu_F);
    r[4].v[slot] = dn_F.dot(fv_F);
    const Vector3d dG_ang = dn_T.cross(t.p) + n_T.cross(dp);
    for (int i = 0; i < 3; ++i) {
      (*G)(i).v[slot] = -dn_F(i);
      (*G)(3 + i).v[slot] = dG_ang(i);
    }
  };
  tibial(8, t.p_u, t.p_uu, t.p_uv);
  tibial(9, t.p_v, t.p_uv, t.p_vv);
  return true;
}

void FreeNewtonEulerPartials(const Model& model, double t, const Vector6d& q, const Vector6d& qd,
                             const Vector6d& qdd, const Data& data, NewtonEulerPartials* out) {
  Matrix6d applied;
  AppliedWrenchPartials(model, t, q, data, &applied);
  out->d_q = -applied;
  out->d_qd.setZero();
  out->d_qdd.setZero();
  out->d_qdd.topLeftCorner<3, 3>().diagonal().setConstant(model.mass);
  // Rotational part I (E q̈_ang + Ė q̇_ang) + w × I w, w = E q̇_ang: linear in q̈_ang, so
  // ∂/∂q̈_ang = diag(I) E; the rest with a Jet of the 5 values it reads (β, γ, q̇_ang).
  using J5 = ceres::Jet<double, 5>;
  const J5 beta(q(kBeta), 0), gamma(q(kGamma), 1);
  Vector3<J5> rate, accel;
  for (int i = 0; i < 3; ++i) {
    rate(i) = J5(qd(3 + i), 2 + i);
    accel(i) = J5(qdd(3 + i));
  }
  using std::cos;
  using std::sin;
  const EulerAngleTrig<J5> trig{J5(0.0), J5(1.0), sin(beta), cos(beta), sin(gamma), cos(gamma)};  // α unused
  const Matrix3<J5> E = AngularVelocityMap(beta, trig);
  const Vector3<J5> w = E * rate;
  const Vector3<J5> w_dot = E * accel + AngularVelocityMapRateTimesRate(trig, rate);
  const Vector3<J5> I = model.inertia_T.cast<J5>();
  const Vector3<J5> rotational = I.cwiseProduct(w_dot) + w.cross(I.cwiseProduct(w));
  for (int i = 0; i < 3; ++i) {
    const auto& v = rotational(i).v;
    out->d_q(3 + i, kBeta) += v(0);
    out->d_q(3 + i, kGamma) += v(1);
    for (int j = 0; j < 3; ++j) {
      out->d_qd(3 + i, 3 + j) = v(2 + j);
      out->d_qdd(3 + i, 3 + j) = model.inertia_T(i) * E(i, j).a;
    }
  }
}

}  // namespace kneedyn
