#include "formulations/internal/dae_system.hpp"

#include <algorithm>

#include <Eigen/LU>

#include "solver/newton_euler_jacobian.hpp"

namespace kneedyn {

DaeSystem::DaeSystem(const Model& model, ContactForm form, ConstraintLevel level, bool ggl)
    : model_(&model),
      form_(form),
      position_level_(level == ConstraintLevel::kPosition),
      ggl_(ggl),
      data_(model),
      data_jet_(model) {}

void DaeSystem::SetPhase(const std::vector<int>& active, const std::vector<ContactGuess>& contact,
                         const std::vector<signed char>& ligament_branch) {
  active_ = active;
  k_ = static_cast<int>(active.size());
  if (k_ > kMaxActiveContacts) {
    Throw<SolverError>("DaeSystem::SetPhase", k_, " active contacts exceed ", kMaxActiveContacts);
  }
  chart_.resize(k_);
  for (int c = 0; c < k_; ++c) chart_[c] = contact[active[c]].chart;
  ligament_branch_ = ligament_branch;
  per_contact_ = form_ == ContactForm::kChapter ? 4 : 0;
  rows_per_contact_ = per_contact_ + (ggl_ ? 2 : 1);
  n_ = 12 + rows_per_contact_ * k_;
  if (n_ > kMaxJetSize) {
    Throw<SolverError>("DaeSystem::SetPhase", "system size ", n_, " exceeds ", kMaxJetSize, " (kMaxJetSize)");
  }
  yj_.assign(n_, JetD(0.0));
  ypj_.assign(n_, JetD(0.0));
  Fj_.assign(n_, JetD(0.0));
}

std::string DaeSystem::UnknownName(int i) const {
  if (i < 6) return CoordinateName(i);
  if (i < 12) return StrCat("u[", i - 6, "]");
  auto compartment = [&](int c) { return CompartmentName(model_->contacts[active_[c]].compartment); };
  if (i < NormalIndex(0)) {
    static const char* kCoord[4] = {"x_c", "y_c", "x'_c", "y'_c"};
    return StrCat(compartment((i - 12) / per_contact_), " ", kCoord[(i - 12) % per_contact_]);
  }
  if (i < NormalIndex(k_)) return StrCat("N_", compartment(i - NormalIndex(0)));
  return StrCat("mu_", compartment(i - MuIndex(0)));
}

void DaeSystem::InitialValues(const MechanicalState& state, double* y, double* yp) {
  std::fill(y, y + n_, 0.0);
  std::fill(yp, yp + n_, 0.0);
  for (int i = 0; i < 6; ++i) {
    y[i] = state.q(i);
    y[6 + i] = state.qd(i);
    yp[i] = state.qd(i);
    yp[6 + i] = state.qdd(i);
  }
  for (int c = 0; c < k_; ++c) {
    for (int j = 0; j < per_contact_; ++j) y[CoordinateIndex(c) + j] = state.contact[active_[c]].coordinates[j];
    y[NormalIndex(c)] = state.contact[active_[c]].normal_force;
  }
  if (per_contact_ == 0) return;
  // ċ: ∂g/∂c ċ = −∂g/∂q q̇ for the four contact-coordinate rows g of each contact (x, y of
  // Eqs. 1.8 and 1.13), differentiated alone over (q, c_i): in closed form in the regular
  // chart (RegularChartContactPartials), else as a Jet of 10.
  const Vector6d q = Eigen::Map<const Vector6d>(y);
  const EulerAngleTrig<double> trig = EulerAngleTrigOf(q);
  const Pose pose_value = PoseFromCoordinates(q, trig);
  Matrix3d dR[3];
  RotationPartials(trig, dR);
  const PoseTpl<ContactJet> pose = PoseWithCoordinateDerivatives<kContactJetSize>(q);
  for (int c = 0; c < k_; ++c) {
    const int col0 = CoordinateIndex(c);
    const ContactPair& pair = model_->contacts[active_[c]];
    ContactJet r[5];
    if (chart_[c] == ContactChart::kRegular) {
      Eigen::Matrix<ContactJet, 1, 6> G;
      if (!RegularChartContactPartials(pair, pose_value, dR, y + col0, r, &G)) return;
    } else {
      ContactJet coords[4];
      for (int j = 0; j < 4; ++j) coords[j] = ContactJet(y[col0 + j], 6 + j);
      if (!ChapterContactResiduals(pair, pose, coords, r, static_cast<ContactGeometryTpl<ContactJet>*>(nullptr),
                                   chart_[c])) {
        return;
      }
    }
    const int rows[4] = {0, 1, 3, 4};  // residual entries: x, y of Eq. 1.8; x, y of Eq. 1.13
    Eigen::Matrix4d A;
    Eigen::Vector4d b;
    for (int i = 0; i < 4; ++i) {
      const ContactJet& g = r[rows[i]];
      b(i) = 0.0;
      for (int j = 0; j < 6; ++j) b(i) -= g.v[j] * yp[j];
      for (int j = 0; j < 4; ++j) A(i, j) = g.v[6 + j];
    }
    const Eigen::Vector4d cd = A.fullPivLu().solve(b);
    for (int j = 0; j < 4; ++j) yp[col0 + j] = cd(j);
  }
}

bool DaeSystem::JacobianByJets(double t, double cj, const double* y, const double* yp, double* J) const {
  std::fill(J, J + static_cast<size_t>(n_) * n_, 0.0);
  for (int pass = 0; pass < 2; ++pass) {
    for (int i = 0; i < n_; ++i) {
      yj_[i] = JetD(y[i]);
      ypj_[i] = JetD(yp[i]);
      if (pass == 0) yj_[i].v[i] = 1.0;
      else ypj_[i].v[i] = 1.0;
    }
    if (!Residual(t, yj_.data(), ypj_.data(), Fj_.data(), &data_jet_)) return false;
    const double scale = pass == 0 ? 1.0 : cj;
    for (int r = 0; r < n_; ++r) {
      for (int c = 0; c < n_; ++c) J[r + static_cast<size_t>(n_) * c] += scale * Fj_[r].v[c];
    }
  }
  return true;
}

bool DaeSystem::Jacobian(double t, double cj, const double* y, const double* yp, double* Jdata,
                         bool J_is_zero) const {
  Eigen::Map<MatrixXd> J(Jdata, n_, n_);
  if (!J_is_zero) J.setZero();
  Vector6d q, u, udot;
  for (int i = 0; i < 6; ++i) {
    q(i) = y[i];
    u(i) = y[6 + i];
    udot(i) = yp[6 + i];
  }
  // F1–F6 = u − q̇ (+ GGL terms below).
  for (int i = 0; i < 6; ++i) {
    J(i, 6 + i) = 1.0;
    J(i, i) = -cj;
  }
  // F7–F12 = −r_free + Σ N_i G_iᵀ: the free part.
  data_.ligament_branch = &ligament_branch_;
  NewtonEulerPartials free;
  FreeNewtonEulerPartials(*model_, t, q, u, udot, data_, &free);
  J.block<6, 6>(6, 0) = -free.d_q;
  J.block<6, 6>(6, 6) = -free.d_qd - cj * free.d_qdd;
  if (k_ == 0) return true;

  // Contacts: ν and E as Jets over (q, c_i) (slots 0–5 q, 6–9 c_i). The chapter form in the
  // regular chart takes its residuals' and G's derivatives in closed form
  // (RegularChartContactPartials: a fifth of the Jet's cost) from the double pose and ∂R/∂q;
  // the other forms differentiate the contact geometry on the pose as Jets. GGL included:
  // its blocks equal the Jet derivative (tests/dae_system_test.cpp, chapter_chapter_ggl); its
  // max gap at rtol 1e-10 scatters over an order of magnitude between neighbouring
  // tolerances with either (benchmarks/performance-log.md, "Fourth round").
  bool all_closed_form_partials = form_ == ContactForm::kChapter;
  for (int c = 0; c < k_; ++c) all_closed_form_partials &= chart_[c] == ContactChart::kRegular;
  PoseTpl<ContactJet> pose;
  Pose pose_value;
  Matrix3d dR[3];
  if (all_closed_form_partials) {
    const EulerAngleTrig<double> trig = EulerAngleTrigOf(q);
    pose_value = PoseFromCoordinates(q, trig);
    RotationPartials(trig, dR);
  } else {
    pose = PoseWithCoordinateDerivatives<kContactJetSize>(q);
  }
  // E(β, γ) and w = E u_ang depend on β, γ only: a Jet of 2 (the same numbers as in the
  // ContactJet, whose other slots stay zero), lifted into the β, γ slots.
  using BetaGammaJet = ceres::Jet<double, 2>;
  const Matrix3<BetaGammaJet> E2 = AngularVelocityMap(BetaGammaJet(q(kBeta), 0), BetaGammaJet(q(kGamma), 1));
  const Vector3<BetaGammaJet> w2 = E2 * u.tail<3>().cast<BetaGammaJet>();
  auto lift = [](const BetaGammaJet& x) {
    ContactJet out(x.a);
    out.v[kBeta] = x.v[0];
    out.v[kGamma] = x.v[1];
    return out;
  };
  Matrix3<ContactJet> E;
  Vector6<ContactJet> nu;
  Matrix3d E_value;
  for (int i = 0; i < 3; ++i) {
    nu(i) = ContactJet(u(i));
    nu(3 + i) = lift(w2(i));
    for (int j = 0; j < 3; ++j) {
      E(i, j) = lift(E2(i, j));
      E_value(i, j) = E2(i, j).a;
    }
  }
  for (int c = 0; c < k_; ++c) {
    const ContactPair& pair = model_->contacts[active_[c]];
    const int col_c = CoordinateIndex(c);
    // ∂x/∂q into columns 0–5 and ∂x/∂c_i into the contact's coordinate columns.
    auto put = [&](int row, const ContactJet& x, double scale) {
      for (int j = 0; j < 6; ++j) J(row, j) += scale * x.v[j];
      for (int j = 0; j < per_contact_; ++j) J(row, col_c + j) += scale * x.v[6 + j];
    };
    ContactJet r[5];
    Eigen::Matrix<ContactJet, 1, 6> G;
    if (all_closed_form_partials) {
      if (!RegularChartContactPartials(pair, pose_value, dR, y + col_c, r, &G)) return false;
    } else {
      ContactGeometryTpl<ContactJet> geo;
      if (form_ == ContactForm::kChapter) {
        ContactJet coords[4];
        for (int j = 0; j < 4; ++j) coords[j] = ContactJet(y[col_c + j], 6 + j);
        if (!ChapterContactResiduals(pair, pose, coords, r, &geo, chart_[c])) return false;
      } else {
        if (!ContactKinematics(pair, pose, &geo)) return false;
        r[2] = geo.gap;
      }
      G = ContactConstraintRow(pose, geo);
    }
    const ContactJet approach = G.dot(nu);  // G ν
    Eigen::Matrix<double, 1, 6> G_value, dapproach_du;
    for (int j = 0; j < 6; ++j) G_value(j) = G(j).a;
    dapproach_du.head<3>() = G_value.head<3>();
    dapproach_du.tail<3>() = G_value.tail<3>() * E_value;
    const int row0 = FirstContactRow(c);
    auto put_approach = [&](int row) {
      put(row, approach, 1.0);
      for (int j = 0; j < 6; ++j) J(row, 6 + j) += dapproach_du(j);
    };
    if (!ggl_) {
      if (per_contact_ == 4) {
        put(row0, r[0], 1.0);
        put(row0 + 1, r[1], 1.0);
        put(row0 + 3, r[3], 1.0);
        put(row0 + 4, r[4], 1.0);
      }
      const int normal_row = row0 + (per_contact_ == 4 ? 2 : 0);
      if (position_level_) put(normal_row, r[2], 1.0);
      else put_approach(normal_row);
    } else {
      if (per_contact_ == 4) {
        put(row0, r[0], 1.0);
        put(row0 + 1, r[1], 1.0);
        put(row0 + 2, r[3], 1.0);
        put(row0 + 3, r[4], 1.0);
      }
      put(row0 + rows_per_contact_ - 2, r[2], 1.0);
      put_approach(row0 + rows_per_contact_ - 1);
      // F1–F6 += K_iᵀ μ_i with K_iᵀ = (G_lin, Eᵀ G_angᵀ).
      const double mu = y[MuIndex(c)];
      const Vector3<ContactJet> Kang = E.transpose() * G.tail<3>().transpose();
      for (int i = 0; i < 3; ++i) {
        J(i, MuIndex(c)) += G_value(i);
        J(3 + i, MuIndex(c)) += Kang(i).a;
        put(i, G(i), mu);
        put(3 + i, Kang(i), mu);
      }
    }
    // Newton–Euler rows: ∂(N_i G_iᵀ)/∂N_i = G_iᵀ, ∂/∂(q, c_i) = N_i ∂G_iᵀ.
    const double N = y[NormalIndex(c)];
    for (int i = 0; i < 6; ++i) {
      J(6 + i, NormalIndex(c)) += G_value(i);
      put(6 + i, G(i), N);
    }
  }
  return true;
}

}  // namespace kneedyn
