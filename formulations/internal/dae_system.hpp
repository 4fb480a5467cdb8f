// The chapter's DAE F(t, y, ẏ) = 0 (section 1.3, Eqs. 1.40–1.61) as one object: unknown
// layout, residual, exact Jacobian and consistent starting values, shared by the IDA
// formulations `dae`, `dae-reduced` (dae.cpp), `dae-ggl`, `dae-ggl-reduced` (dae_ggl.cpp)
// and the IDAS sensitivities (sensitivity/), so that the system is written once.
//
// Unknowns y (k active contacts):
//   q = (x0, y0, z0, α, β, γ), u = (vx, vy, vz, ωα, ωβ, ωγ) (coordinate rates),
//   c_i = 4 contact coordinates per contact (chapter form only), N_i per contact,
//   μ_i per contact (GGL only).
// Residual rows:
//   F1–F6    u − q̇ (+ Σ_i K_iᵀ μ_i, K_i = G_i B(q), GGL)        (Eqs. 1.40–1.47)
//   F7–F12   −r of solver/newton_euler.hpp (Q + Σ N_i G_iᵀ − M ν̇) (Eqs. 1.48–1.57)
//   per contact, plain (`dae`): x, y of Eq. 1.8, the normal condition, x, y of Eq. 1.13
//     (chapter form), or the normal condition alone (closed form). The normal condition is
//     the approach velocity G ν = 0 (index 2) or, at --constraint-level position, the gap
//     φ = 0 of the printed chapter (index 3).
//   per contact, GGL: x, y of Eq. 1.8, x, y of Eq. 1.13 (chapter form), then φ = 0 and
//     G ν = 0.
//
// Jacobian dF/dy + cj dF/dẏ: exact, assembled from blocks differentiated
// at their own size (solver/newton_euler_jacobian.hpp: the applied loads analytically, the
// kinematic part with a Jet of 5, each contact over (q, c_i): in closed form for the chapter
// form in the regular chart (RegularChartContactPartials), else with a Jet of 10); the Jet<24>
// derivative of the whole residual (JacobianByJets) is the reference it is tested against
// (tests/dae_system_test.cpp) and the `--jacobian jet` choice.
#pragma once

#include <string>
#include <vector>

#include "formulations/formulation.hpp"
#include "solver/dynamics.hpp"
#include "solver/newton_euler.hpp"

namespace kneedyn {

class DaeSystem {
 public:
  // `ggl`: the Gear–Gupta–Leimkuhler stabilized form (both constraint levels, μ_i);
  // `level` applies to the plain form only.
  DaeSystem(const Model& model, ContactForm form, ConstraintLevel level, bool ggl);

  // The phase: active contacts (indices into model.contacts), the contact guesses (their
  // charts) and the ligament branches locked for it. Sizes the workspaces.
  void SetPhase(const std::vector<int>& active, const std::vector<ContactGuess>& contact,
                const std::vector<signed char>& ligament_branch);
  // The model the residual reads (the sensitivities swap in a perturbed copy; same sizes).
  void SetModel(const Model& model) { model_ = &model; }
  const Model& model() const { return *model_; }

  int size() const { return n_; }
  int per_contact() const { return per_contact_; }  // contact coordinates per contact
  int CoordinateIndex(int c) const { return 12 + per_contact_ * c; }
  int NormalIndex(int c) const { return 12 + per_contact_ * k_ + c; }
  int MuIndex(int c) const { return 12 + (per_contact_ + 1) * k_ + c; }  // GGL only
  int FirstContactRow(int c) const { return 12 + rows_per_contact_ * c; }
  bool ggl() const { return ggl_; }
  ContactForm form() const { return form_; }
  const std::vector<int>& active() const { return active_; }
  // "x0", "u[3]", "lateral x'_c", "N_medial", "mu_lateral".
  std::string UnknownName(int i) const;

  // y, ẏ of a consistent state: q, q̇, q̈, contact coordinates, N, μ = 0; ċ from the time
  // derivative of the contact-coordinate rows, so the predictor starts consistent.
  void InitialValues(const MechanicalState& state, double* y, double* yp);
  // 1 for the differential unknowns (q, u), 0 for the algebraic ones (c, N, μ).
  bool IsDifferential(int i) const { return i < 12; }

  // F(t, y, ẏ) for T = double or JetD; `data` is the matching workspace (Data or
  // the system's own for JetD). False when a surface is evaluated outside its domain.
  template <typename T>
  bool Residual(double t, const T* y, const T* yp, T* F, DataTpl<T>* data) const;
  bool Residual(double t, const double* y, const double* yp, double* F) const {
    return Residual(t, y, yp, F, &data_);
  }
  // dF/dy + cj dF/dẏ into the column-major n×n array J. Exact, structured (header). No
  // allocation. `J_is_zero`: J already holds zeros (IDA's matrix: idaLsSetup zeroes it
  // before every call), so it is not cleared a second time.
  bool Jacobian(double t, double cj, const double* y, const double* yp, double* J, bool J_is_zero = false) const;
  // The same by forward AD of the whole residual (ceres::Jet<24>, two passes): the reference.
  bool JacobianByJets(double t, double cj, const double* y, const double* yp, double* J) const;

 private:
  const Model* model_;
  ContactForm form_;
  bool position_level_;
  bool ggl_;
  std::vector<int> active_;
  std::vector<ContactChart> chart_;           // per active contact
  std::vector<signed char> ligament_branch_;  // locked for the phase
  int k_ = 0, n_ = 12, per_contact_ = 4, rows_per_contact_ = 5;
  // Workspaces (sized in the constructor / SetPhase; no allocation in the evaluations).
  mutable Data data_;
  mutable DataTpl<JetD> data_jet_;
  mutable std::vector<JetD> yj_, ypj_, Fj_;
};

template <typename T>
bool DaeSystem::Residual(double t, const T* y, const T* yp, T* F, DataTpl<T>* data) const {
  Vector6<T> q, u, qdot, udot;
  for (int i = 0; i < 6; ++i) {
    q(i) = y[i];
    u(i) = y[6 + i];
    qdot(i) = yp[i];
    udot(i) = yp[6 + i];
  }
  for (int i = 0; i < 6; ++i) F[i] = u(i) - qdot(i);  // F1–F6 (before the GGL terms)
  const EulerAngleTrig<T> trig = EulerAngleTrigOf(q);  // once per pose (rotation.hpp)
  const PoseTpl<T> pose = PoseFromCoordinates(q, trig);
  // E once per pose, for ν, the GGL terms and the Newton–Euler residual (rotation.hpp).
  const Matrix3<T> E = AngularVelocityMap(q(kBeta), trig);
  const Vector6<T> nu = GeneralizedVelocity(E, u);
  ContactGeometryTpl<T> geo[kMaxActiveContacts];
  for (int c = 0; c < k_; ++c) {
    const ContactPair& pair = model_->contacts[active_[c]];
    T* Fc = F + FirstContactRow(c);
    T phi;
    if (form_ == ContactForm::kChapter) {
      T r[5];
      if (!ChapterContactResiduals(pair, pose, y + CoordinateIndex(c), r, &geo[c], chart_[c])) return false;
      Fc[0] = r[0];
      Fc[1] = r[1];
      if (ggl_) {
        Fc[2] = r[3];
        Fc[3] = r[4];
      } else {
        Fc[3] = r[3];
        Fc[4] = r[4];
      }
      phi = r[2];
    } else {
      if (!ContactKinematics(pair, pose, &geo[c])) return false;
      phi = geo[c].gap;
    }
    if (!ggl_) {
      T& normal = Fc[per_contact_ == 4 ? 2 : 0];
      normal = position_level_ ? phi : T(ContactConstraintRow(pose, geo[c]).dot(nu));
      continue;
    }
    const Eigen::Matrix<T, 1, 6> G = ContactConstraintRow(pose, geo[c]);
    Fc[rows_per_contact_ - 2] = phi;           // position level
    Fc[rows_per_contact_ - 1] = T(G.dot(nu));  // velocity level
    // Stabilization: F1–F6 += K_iᵀ μ_i, K_i = G_i B(q).
    const T& mu = y[MuIndex(c)];
    for (int i = 0; i < 3; ++i) F[i] += G(i) * mu;
    const Vector3<T> Kang = E.transpose() * G.template tail<3>().transpose();
    for (int i = 0; i < 3; ++i) F[3 + i] += Kang(i) * mu;
  }
  // F7–F12: Q + Σ N_i G_iᵀ − M ν̇ (Eqs. 1.48–1.57; solver/newton_euler.hpp).
  data->ligament_branch = &ligament_branch_;
  const Vector6<T> residual = NewtonEulerResidual(*model_, t, trig, E, nu, u, udot, pose, k_, geo, y + NormalIndex(0), data);
  for (int i = 0; i < 6; ++i) F[6 + i] = -residual(i);
  return true;
}

}  // namespace kneedyn
