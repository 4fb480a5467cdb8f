// `dae-ggl` and `dae-ggl-reduced`: the Gear–Gupta–Leimkuhler (1985) stabilized index-2
// form of the chapter's system (section 1.3, Eqs. 1.40–1.61) on SUNDIALS IDA; the pattern
// of SUNDIALS' examples/ida/serial/idaSlCrank_dns.c.
//
// `dae` (dae.cpp) enforces only the normal approach velocity φ̇ = G ν = 0, so the gap φ
// drifts between contact-mode switches. GGL enforces both levels and restores the balance
// of equations and unknowns with one extra multiplier μ_i per active contact:
//
//   q̇ = u + Σ_i K_iᵀ μ_i                      K_i = ∂φ_i/∂q = G_i B(q), B = diag(1, E(β, γ))
//   M ν̇ = Q(t, q, ν) + Σ_i N_i G_iᵀ            (Eqs. 1.48–1.57, solver/dynamics.hpp)
//   φ_i(q, c_i) = 0                              (position level: z of Eq. 1.8 / closed-form gap)
//   G_i ν = 0                                    (velocity level, contact.hpp)
//   x, y of Eq. 1.8 and of Eq. 1.13 for c_i     (chapter form only)
//
// ∂φ/∂q = G B holds on the contact manifold (the tangential motion of the contact point
// does not change the gap to first order), so μ = 0 along the exact solution: the
// stabilization changes nothing but the numerical drift. Position-level residuals are
// exactly zero at every step (to the Newton tolerance), without projection.
//
// Unknowns y (k active contacts): q(6), u(6), c(4k, chapter form only), N(k), μ(k); chapter
// n = 12 + 6k (24 for two contacts), closed form n = 12 + 2k. Residual rows: F1–F6 the
// stabilized kinematics, F7–F12 Newton–Euler, per contact (e_x, e_y of Eq. 1.8, x, y of
// Eq. 1.13, φ, Gν) or (φ, Gν).
//
// Scaling and tolerances (IDASVtolerances, per component, given --rtol r and --atol a):
//   q, u, c        a                      (m, rad, m/s, rad/s, m: all O(0.01–1) in SI)
//   N              max(a · 1e4, 1e-3 N)   (forces are O(10²–10³) N, so a force error of
//                                          a·1e4 N weighs like a position error of a m)
//   μ              max(a · 1e4, 1e-3 m/s) (μ is a velocity correction, exactly 0 in theory)
// Why these are loose: N and μ are index-2 unknowns. A Newton error δN, δμ moves u, q by
// h M⁻¹ Gᵀ δN, h K δμ per step, which the weights of u and q already police; N and μ
// themselves carry round-off ε·M·|q|/h² ≈ 2e-3 N and cj·ε·|φ terms| ≈ 1e-17 m / h (at
// h = 1e-7 s), so tighter tolerances make the Newton test fail on round-off at the tiny
// first steps of tight runs (measured: with a · 1e4 alone, rtol ≤ 1e-11 fails at t = 0
// with IDA_CONV_FAIL; with the floors, rtol 1e-13 completes with scd 10.7 on the chapter
// scene). Scaling the unknowns instead (N/N_ref) would be equivalent for IDA's WRMS tests.
// IDASetId marks q, u differential and c, N, μ algebraic; IDASetSuppressAlg excludes the
// algebraic unknowns from the local error test (their BDF error is not O(h^{p+1}) for
// index 2), as in idaSlCrank_dns.c. The Jacobian dF/dy + cj dF/dẏ comes from forward AD
// (ceres::Jet). All workspaces are allocated in Start; the residual, Jacobian and root
// callbacks allocate nothing.
#include <ida/ida.h>
#include <sunlinsol/sunlinsol_dense.h>
#include <sunmatrix/sunmatrix_dense.h>

#include <algorithm>
#include <cmath>
#include <memory>

#include "formulations/formulation_base.hpp"
#include "formulations/ida_phase.hpp"
#include "formulations/sundials_util.hpp"
#include "solver/dynamics.hpp"
#include "solver/newton_euler.hpp"

namespace kneedyn {
namespace {

// Absolute tolerance of the normal forces per unit --atol (N per SI unit of the states).
constexpr double kForceAtolScale = 1.0e4;
// Absolute tolerance of the stabilizing multipliers μ per unit --atol (s⁻¹; see header).
constexpr double kMuAtolScale = 1.0e4;
// Floors of those tolerances (N, m/s): above the round-off of the index-2 unknowns at the
// smallest steps IDA takes at rtol 1e-13 (see header).
constexpr double kForceAtolFloor = 1.0e-3;
constexpr double kMuAtolFloor = 1.0e-3;

class DaeGglFormulation final : public FormulationBase {
 public:
  DaeGglFormulation(const Scene& scene, const FormulationOptions& options, ContactForm form)
      : FormulationBase(scene), options_(options), form_(form), data_(model_), data_jet_(model_) {
    const char* name = form == ContactForm::kChapter ? "dae-ggl" : "dae-ggl-reduced";
    if (options.step != 0.0) {
      Throw<InputError>("DaeGglFormulation", "--step = ", options.step,
                        " s: ", name, " chooses its own steps; use --max-step");
    }
    const ParsedFormulationOptions parsed = options.Parsed();
    if (parsed.stabilization != Stabilization::kNone) {
      Throw<InputError>("DaeGglFormulation", "--stabilization = '", options.stabilization,
                        "' applies to ede only (", name, " enforces both constraint levels)");
    }
    if (parsed.constraint_level != ConstraintLevel::kVelocity) {
      Throw<InputError>("DaeGglFormulation", "--constraint-level = '", options.constraint_level,
                        "': ", name, " always enforces position and velocity level; leave the default");
    }
    normal_.assign(model_.contacts.size(), 0.0);
  }
  ~DaeGglFormulation() override { Free(); }

  ContactForm contact_form() const override { return form_; }

  void Start(const MechanicalState& state, const std::vector<EventSpec>& events) override {
    Free();
    BeginPhase(state, events);
    const int k = static_cast<int>(active_.size());
    per_contact_ = form_ == ContactForm::kChapter ? 4 : 0;
    rows_per_contact_ = per_contact_ + 2;
    n_ = 12 + (per_contact_ + 2) * k;
    if (n_ > kMaxJetSize) {
      Throw<SolverError>("DaeGglFormulation::Start", "system size ", n_, " exceeds ", kMaxJetSize);
    }
    if (k > kMaxActiveContacts) {
      Throw<SolverError>("DaeGglFormulation::Start", k, " active contacts exceed ", kMaxActiveContacts);
    }
    yj_.assign(n_, JetD(0.0));
    ypj_.assign(n_, JetD(0.0));
    Fj_.assign(n_, JetD(0.0));
    J_.setZero(n_, n_);
    root_flags_.assign(events_.size(), 0);

    ida_.y = N_VNew_Serial(n_, ctx_);
    ida_.yp = N_VNew_Serial(n_, ctx_);
    hot_path_r_ = N_VNew_Serial(n_, ctx_);
    hot_path_g_.assign(events_.size(), 0.0);
    t_ = state.t;
    N_Vector id = N_VNew_Serial(n_, ctx_);
    N_Vector atol = N_VNew_Serial(n_, ctx_);
    double* y = NvData(ida_.y);
    double* yp = NvData(ida_.yp);
    std::fill(y, y + n_, 0.0);
    std::fill(yp, yp + n_, 0.0);
    for (int i = 0; i < 6; ++i) {
      y[i] = state.q(i);
      y[6 + i] = state.qd(i);
      yp[i] = state.qd(i);
      yp[6 + i] = state.qdd(i);
    }
    for (int c = 0; c < k; ++c) {
      for (int j = 0; j < per_contact_; ++j) {
        y[12 + per_contact_ * c + j] = state.contact[active_[c]].coordinates[j];
      }
      y[NormalIndex(c)] = state.contact[active_[c]].normal_force;
      y[MuIndex(c)] = 0.0;  // μ = 0 on the exact solution
    }
    if (per_contact_ > 0) ContactCoordinateRates(state.t, y, yp);
    double* idp = NvData(id);
    double* at = NvData(atol);
    for (int i = 0; i < n_; ++i) {
      idp[i] = i < 12 ? 1.0 : 0.0;
      const bool force = k > 0 && i >= NormalIndex(0) && i < MuIndex(0);
      const bool mu = k > 0 && i >= MuIndex(0);
      at[i] = force ? std::max(kForceAtolFloor, options_.atol * kForceAtolScale)
                    : mu ? std::max(kMuAtolFloor, options_.atol * kMuAtolScale) : options_.atol;
    }
    ida_.Start(ctx_, n_, &DaeGglFormulation::Residual, &DaeGglFormulation::Jacobian, &DaeGglFormulation::Roots, this, state.t, atol, id,
               options_, scene_.end.time, events_, "DaeGglFormulation::Start", &sundials_messages_);
    N_VDestroy(id);
    N_VDestroy(atol);
    ++finished_phases_.restarts;
  }

  AdvanceResult Advance(double t_out, MechanicalState* state) override {
    double t_reached = state->t;
    failure_.clear();
    // Stop at t_out instead of interpolating to it: outputs are step values, on which the
    // position and velocity constraints hold to the Newton tolerance.
    Check(IDASetStopTime(ida_.mem, std::min(t_out, scene_.end.time)), "IDASetStopTime");
    const int flag = IDASolve(ida_.mem, t_out, &t_reached, ida_.y, ida_.yp, IDA_NORMAL);
    AdvanceResult result;
    if (flag < 0) {
      double h = 0.0, t_cur = 0.0;
      IDAGetCurrentStep(ida_.mem, &h);
      IDAGetCurrentTime(ida_.mem, &t_cur);
      char* name = IDAGetReturnFlagName(flag);
      const std::string text = name ? name : "?";
      free(name);
      Throw<SolverError>("IDASolve (dae-ggl)", text, " at t = ", t_cur, " s with step h = ", h, " s",
                         failure_.empty() ? "" : " (" + failure_ + ")");
    }
    t_ = t_reached;
    const double* y = NvData(ida_.y);
    const double* yp = NvData(ida_.yp);
    WriteBack(t_reached, Eigen::Map<const Vector6d>(y), Eigen::Map<const Vector6d>(y + 6),
              Eigen::Map<const Vector6d>(yp + 6), y + NormalIndex(0), y + 12, per_contact_, state);
    if (flag == IDA_ROOT_RETURN) {
      Check(IDAGetRootInfo(ida_.mem, root_flags_.data()), "IDAGetRootInfo");
      result = EventResult(root_flags_);
    }
    return result;
  }

  SolverStats PhaseStats() const override { return ida_.mem != nullptr ? CurrentStats() : SolverStats(); }

  // F(t, y, ẏ) for T = double or JetD; `data` is the matching preallocated workspace.
  // Returns false on a recoverable failure (surface evaluated outside its domain).
  template <typename T>
  bool EvaluateResidual(double t, const T* y, const T* yp, T* F, DataTpl<T>* data) const {
    Vector6<T> q, u, qdot, udot;
    for (int i = 0; i < 6; ++i) {
      q(i) = y[i];
      u(i) = y[6 + i];
      qdot(i) = yp[i];
      udot(i) = yp[6 + i];
    }
    for (int i = 0; i < 6; ++i) F[i] = u(i) - qdot(i);  // F1–F6 before stabilization
    const PoseTpl<T> pose = PoseFromCoordinates(q);
    const Vector6<T> nu = GeneralizedVelocity(q, u);
    const Matrix3<T> E = AngularVelocityMap(q(kBeta), q(kGamma));
    const int k = static_cast<int>(active_.size());
    ContactGeometryTpl<T> geo[kMaxActiveContacts];
    for (int c = 0; c < k; ++c) {
      const ContactPair& pair = model_.contacts[active_[c]];
      T* Fc = F + 12 + rows_per_contact_ * c;
      T phi;
      if (form_ == ContactForm::kChapter) {
        T r[5];
        if (!ChapterContactResiduals(pair, pose, y + 12 + 4 * c, r, &geo[c],
                                     state_contact_[active_[c]].chart)) {
          return false;
        }
        Fc[0] = r[0];
        Fc[1] = r[1];
        Fc[2] = r[3];
        Fc[3] = r[4];
        phi = r[2];
      } else {
        if (!ContactKinematics(pair, pose, &geo[c])) return false;
        phi = geo[c].gap;
      }
      const Eigen::Matrix<T, 1, 6> G = ContactConstraintRow(pose, geo[c]);
      Fc[rows_per_contact_ - 2] = phi;                      // position level
      Fc[rows_per_contact_ - 1] = T(G.dot(nu));             // velocity level
      // Stabilization: F1–F6 += K_iᵀ μ_i, K_i = G_i B(q).
      const T& mu = y[MuIndex(c)];
      for (int i = 0; i < 3; ++i) F[i] += G(i) * mu;
      const Vector3<T> Kang = E.transpose() * G.template tail<3>().transpose();
      for (int i = 0; i < 3; ++i) F[3 + i] += Kang(i) * mu;
    }
    // F7–F12: Q + Σ N_i G_iᵀ − M ν̇ (Eqs. 1.48–1.57; solver/newton_euler.hpp).
    data->ligament_branch = &ligament_branch_;
    const Vector6<T> residual =
        NewtonEulerResidual(model_, t, q, u, udot, pose, k, geo, y + NormalIndex(0), data);
    for (int i = 0; i < 6; ++i) F[6 + i] = -residual(i);  // F7–F12
    return true;
  }

  // dF/dy + cj dF/dẏ into J_ by forward AD (two Jet passes); no allocation.
  bool EvaluateJacobian(double t, double cj, const double* y, const double* yp) const {
    J_.setZero();
    for (int pass = 0; pass < 2; ++pass) {
      for (int i = 0; i < n_; ++i) {
        yj_[i] = JetD(y[i]);
        ypj_[i] = JetD(yp[i]);
        if (pass == 0) yj_[i].v[i] = 1.0;
        else ypj_[i].v[i] = 1.0;
      }
      if (!EvaluateResidual(t, yj_.data(), ypj_.data(), Fj_.data(), &data_jet_)) return false;
      const double scale = pass == 0 ? 1.0 : cj;
      for (int r = 0; r < n_; ++r) {
        for (int c = 0; c < n_; ++c) J_(r, c) += scale * Fj_[r].v[c];
      }
    }
    return true;
  }

  // The residual, Jacobian (cj = 1e4 1/s) and root callbacks IDA calls, at the current y, ẏ.
  bool EvaluateHotPathForTesting(int n) override {
    if (ida_.mem == nullptr) return false;
    for (int i = 0; i < n; ++i) {
      if (Residual(t_, ida_.y, ida_.yp, hot_path_r_, this) != 0) return false;
      if (Jacobian(t_, 1.0e4, ida_.y, ida_.yp, hot_path_r_, ida_.A, this, nullptr, nullptr, nullptr) != 0) return false;
      if (!events_.empty() && Roots(t_, ida_.y, ida_.yp, hot_path_g_.data(), this) != 0) return false;
    }
    return true;
  }

  int size() const { return n_; }
  const MatrixXd& jacobian() const { return J_; }

 private:
  int NormalIndex(int c) const { return 12 + per_contact_ * static_cast<int>(active_.size()) + c; }
  int MuIndex(int c) const { return NormalIndex(static_cast<int>(active_.size())) + c; }

  // ċ from the derivative of the contact-coordinate rows (x, y of Eqs. 1.8 and 1.13):
  // ∂g/∂c ċ = −∂g/∂q q̇, so the predictor starts consistent.
  void ContactCoordinateRates(double t, const double* y, double* yp) const {
    if (!EvaluateJacobian(t, 0.0, y, yp)) return;
    for (size_t c = 0; c < active_.size(); ++c) {
      const int row0 = 12 + rows_per_contact_ * static_cast<int>(c);
      const int col0 = 12 + 4 * static_cast<int>(c);
      const int rows[4] = {row0, row0 + 1, row0 + 2, row0 + 3};
      Eigen::Matrix4d A;
      Eigen::Vector4d b;
      for (int r = 0; r < 4; ++r) {
        b(r) = 0.0;
        for (int i = 0; i < 6; ++i) b(r) -= J_(rows[r], i) * yp[i];
        for (int j = 0; j < 4; ++j) A(r, j) = J_(rows[r], col0 + j);
      }
      const Eigen::Vector4d cd = A.fullPivLu().solve(b);
      for (int j = 0; j < 4; ++j) yp[col0 + j] = cd(j);
    }
  }

  static int Residual(double t, N_Vector yy, N_Vector yp, N_Vector rr, void* user) {
    auto* self = static_cast<DaeGglFormulation*>(user);
    try {
      return self->EvaluateResidual(t, NvData(yy), NvData(yp), NvData(rr), &self->data_) ? 0 : 1;
    } catch (const std::exception& e) {
      self->failure_ = e.what();
      return -1;
    }
  }

  static int Jacobian(double t, double cj, N_Vector yy, N_Vector yp, N_Vector, SUNMatrix JJ,
                      void* user, N_Vector, N_Vector, N_Vector) {
    auto* self = static_cast<DaeGglFormulation*>(user);
    try {
      if (!self->EvaluateJacobian(t, cj, NvData(yy), NvData(yp))) return 1;
      for (int c = 0; c < self->n_; ++c) {
        double* col = SUNDenseMatrix_Column(JJ, c);
        for (int r = 0; r < self->n_; ++r) col[r] = self->J_(r, c);
      }
      return 0;
    } catch (const std::exception& e) {
      self->failure_ = e.what();
      return -1;
    }
  }

  static int Roots(double, N_Vector yy, N_Vector, double* g, void* user) {
    auto* self = static_cast<DaeGglFormulation*>(user);
    try {
      const double* y = NvData(yy);
      Vector6d q;
      for (int i = 0; i < 6; ++i) q(i) = y[i];
      std::fill(self->normal_.begin(), self->normal_.end(), 0.0);
      for (size_t c = 0; c < self->active_.size(); ++c) {
        self->normal_[self->active_[c]] = y[self->NormalIndex(static_cast<int>(c))];
      }
      EvaluateEvents(self->scene_.model, self->events_, q, self->normal_, g);
      return 0;
    } catch (const std::exception& e) {
      self->failure_ = e.what();
      return -1;
    }
  }

  void Check(int flag, const char* call) const {
    CheckSundials(flag, call, "DaeGglFormulation", IDAGetReturnFlagName, &sundials_messages_);
  }

  SolverStats CurrentStats() const { return IdaStatistics(ida_.mem, !events_.empty()); }

  void Free() {
    ida_.Free(&finished_phases_, !events_.empty());
    if (hot_path_r_) { N_VDestroy(hot_path_r_); hot_path_r_ = nullptr; }
  }


  FormulationOptions options_;
  ContactForm form_;
  SundialsContext ctx_;
  double t_ = 0.0;  // s: time of the phase's y, ẏ (phase start or last Advance)
  N_Vector hot_path_r_ = nullptr;   // residual of EvaluateHotPathForTesting
  std::vector<double> hot_path_g_;  // root values of EvaluateHotPathForTesting
  IdaPhase ida_;  // IDA memory, y, ẏ, matrix and linear solver of the phase
  int n_ = 0;
  int per_contact_ = 4;
  int rows_per_contact_ = 6;
  mutable std::string failure_;
  // Workspaces sized in the constructor / Start (no allocation in the callbacks).
  mutable DataTpl<double> data_;
  mutable DataTpl<JetD> data_jet_;
  mutable std::vector<JetD> yj_, ypj_, Fj_;
  mutable MatrixXd J_;
  std::vector<double> normal_;  // N per model contact, for the root functions
  std::vector<int> root_flags_;
  mutable SundialsMessages sundials_messages_;  // SUNDIALS' error text, for the failure reason
};

}  // namespace

std::unique_ptr<Formulation> CreateDaeGgl(const Scene& scene, const FormulationOptions& options) {
  return std::make_unique<DaeGglFormulation>(scene, options, ContactForm::kChapter);
}
std::unique_ptr<Formulation> CreateDaeGglReduced(const Scene& scene, const FormulationOptions& options) {
  return std::make_unique<DaeGglFormulation>(scene, options, ContactForm::kClosedForm);
}

}  // namespace kneedyn
