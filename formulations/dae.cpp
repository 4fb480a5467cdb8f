// `dae` and `dae-reduced`: the chapter's modified reverse EDE (section 1.3), an index-2
// DAE, on SUNDIALS IDA (DASSL's maintained successor).
//
// Unknowns y (chapter form, k active contacts, n = 12 + 5k: 22 two-point, 17 one-point):
//   q = (x0, y0, z0, α, β, γ), u = (vx, vy, vz, ωα, ωβ, ωγ),
//   c_i = (xc, yc, x′c, y′c) per contact, then N_i per contact.
// Residuals F(t, y, ẏ) (Eqs. 1.40–1.61):
//   F1–F6    u − q̇                                          (kinematic, Eqs. 1.40–1.47)
//   F7–F9    ΣF − m v̇                                        (Newton, in F)
//   F10–F12  ΣM′ − I ẇ − w × I w, ẇ = E u̇_ang + Ė u_ang     (Euler, in T; spec §2 exact E)
//   per contact: x, y of Eq. 1.8; the normal condition; x, y of Eq. 1.13.
// The normal condition: the printed F15/F18 (z of Eq. 1.8, a position-level constraint)
// makes the system index 3, not the index 2 the chapter states. kneedyn's `dae` uses its
// time derivative, the normal approach velocity φ̇ = G ν = 0 (contact.hpp), so that the
// contact coordinates are index 1 and the forces index 2 — the semi-explicit index-2 form
// the chapter describes. `--constraint-level position` keeps the printed position-level
// condition (the index-3 variant of issue 7). Position drift of the velocity-level form is
// reported in every trajectory row (gap_*_mm).
//
// `dae-reduced`: the same physics with the closed-form sphere-on-plane contact:
// y = (q, u, N_i), n = 12 + k, constraint φ̇_i = 0 (or φ_i = 0 at position level).
//
// IDA settings: IDASetId (q, u differential; c, N algebraic) with IDASetSuppressAlg, so
// the index-2 algebraic variables are excluded from the error test; dense Jacobian
// dF/dy + cj dF/dẏ by forward-mode AD (ceres::Jet); root functions from solver/events.hpp.
// A contact-mode switch rebuilds IDA at the new size from the driver's consistent state
// (IDAReInit cannot change the size). IDACalcIC is not used (it is only valid for index 1);
// the initial y, ẏ come from the consistent initialization.
#include <ida/ida.h>
#include <sunlinsol/sunlinsol_dense.h>
#include <sunmatrix/sunmatrix_dense.h>

#include <cmath>
#include <algorithm>
#include <memory>

#include "formulations/dae_testing.hpp"
#include "formulations/formulation_base.hpp"
#include "formulations/ida_phase.hpp"
#include "formulations/sundials_util.hpp"
#include "solver/dynamics.hpp"
#include "solver/newton_euler.hpp"

namespace kneedyn {
namespace {

// Absolute tolerance of the normal forces per unit --atol (N per SI unit of the states).
constexpr double kForceAtolScale = 1.0e4;

class DaeFormulation final : public FormulationBase {
 public:
  DaeFormulation(const Scene& scene, const FormulationOptions& options, ContactForm form)
      : FormulationBase(scene), options_(options), form_(form), data_(model_), data_jet_(model_) {
    if (options.step != 0.0) {
      Throw<InputError>("DaeFormulation", "--step = ", options.step,
                        " s: the IDA formulations choose their own steps; use --max-step");
    }
    if (options.Parsed().stabilization != Stabilization::kNone) {
      Throw<InputError>("DaeFormulation", "--stabilization = '", options.stabilization,
                        "' applies to ede only");
    }
  }
  ~DaeFormulation() override { Free(); }

  ContactForm contact_form() const override { return form_; }

  void Start(const MechanicalState& state, const std::vector<EventSpec>& events) override {
    Free();
    BeginPhase(state, events);
    const int k = static_cast<int>(active_.size());
    per_contact_ = form_ == ContactForm::kChapter ? 4 : 0;
    n_ = 12 + (per_contact_ + 1) * k;
    if (n_ > kMaxJetSize) Throw<SolverError>("DaeFormulation::Start", "system size ", n_, " exceeds ", kMaxJetSize);
    if (k > kMaxActiveContacts) Throw<SolverError>("DaeFormulation::Start", k, " active contacts exceed ", kMaxActiveContacts);
    yj_.assign(n_, JetD(0.0));
    ypj_.assign(n_, JetD(0.0));
    Fj_.assign(n_, JetD(0.0));
    J_.setZero(n_, n_);
    normal_.assign(model_.contacts.size(), 0.0);
    root_flags_.assign(events_.size(), 0);
    position_level_ = options_.Parsed().constraint_level == ConstraintLevel::kPosition;

    ida_.y = N_VNew_Serial(n_, ctx_);
    ida_.yp = N_VNew_Serial(n_, ctx_);
    hot_path_r_ = N_VNew_Serial(n_, ctx_);
    hot_path_g_.assign(events_.size(), 0.0);
    t_ = state.t;
    N_Vector id = N_VNew_Serial(n_, ctx_);
    N_Vector atol = N_VNew_Serial(n_, ctx_);
    double* y = NvData(ida_.y);
    double* yp = NvData(ida_.yp);
    for (int i = 0; i < 6; ++i) {
      y[i] = state.q(i);
      y[6 + i] = state.qd(i);
      yp[i] = state.qd(i);
      yp[6 + i] = state.qdd(i);
    }
    for (int c = 0; c < k; ++c) {
      for (int j = 0; j < per_contact_; ++j) {
        y[12 + per_contact_ * c + j] = state.contact[active_[c]].coordinates[j];
        yp[12 + per_contact_ * c + j] = 0.0;
      }
      y[NormalIndex(c)] = state.contact[active_[c]].normal_force;
      yp[NormalIndex(c)] = 0.0;
    }
    if (per_contact_ > 0) ContactCoordinateRates(state.t, y, yp);
    double* idp = NvData(id);
    double* at = NvData(atol);
    for (int i = 0; i < n_; ++i) {
      idp[i] = i < 12 ? 1.0 : 0.0;
      // Index-2 multipliers N (newtons) carry round-off of order ε/h² in Newton corrections;
      // they are excluded from the error test and get a force-scaled absolute tolerance
      // in the Newton convergence test (KNEEDYN_DAE_FORCE_ATOL_SCALE N per unit atol).
      at[i] = i >= NormalIndex(0) ? options_.atol * kForceAtolScale : options_.atol;
    }
    ida_.Start(ctx_, n_, &DaeFormulation::Residual, &DaeFormulation::Jacobian, &DaeFormulation::Roots, this, state.t, atol, id,
               options_, scene_.end.time, events_, "DaeFormulation::Start", &sundials_messages_);
    N_VDestroy(id);
    N_VDestroy(atol);
    ++finished_phases_.restarts;
  }

  // Issue 18: which unknown IDA's failure is about — the component with the largest
  // weighted local error estimate |e_i| w_i (IDAGetEstLocalErrors, IDAGetErrWeights).
  std::string LargestErrorComponent() const {
    N_Vector e = N_VClone(ida_.y), w = N_VClone(ida_.y);
    std::string out;
    if (IDAGetEstLocalErrors(ida_.mem, e) == IDA_SUCCESS && IDAGetErrWeights(ida_.mem, w) == IDA_SUCCESS) {
      const double* ed = NvData(e);
      const double* wd = NvData(w);
      int worst = 0;
      for (int i = 1; i < n_; ++i) {
        if (std::abs(ed[i] * wd[i]) > std::abs(ed[worst] * wd[worst])) worst = i;
      }
      out = StrCat("; largest weighted local error estimate: ", UnknownName(worst), " (",
                   std::abs(ed[worst] * wd[worst]), " of the tolerance)");
    }
    N_VDestroy(e);
    N_VDestroy(w);
    return out;
  }
  // y = (q: x0 … gamma, u: generalized velocity, contact coordinates, N per contact).
  std::string UnknownName(int i) const {
    if (i < 6) return CoordinateName(i);
    if (i < 12) return StrCat("u[", i - 6, "]");
    const int k = static_cast<int>(active_.size());
    const int coords = per_contact_ * k;
    if (i < 12 + coords) {
      static const char* kCoord[4] = {"x_c", "y_c", "x'_c", "y'_c"};
      return StrCat(CompartmentName(state_contact_compartment((i - 12) / per_contact_)), " ",
                    kCoord[(i - 12) % per_contact_]);
    }
    return StrCat("N_", CompartmentName(state_contact_compartment(i - 12 - coords)));
  }
  Compartment state_contact_compartment(int c) const { return model_.contacts[active_[c]].compartment; }

  AdvanceResult Advance(double t_out, MechanicalState* state) override {
    double t_reached = state->t;
    failure_.clear();
    const int flag = IDASolve(ida_.mem, t_out, &t_reached, ida_.y, ida_.yp, IDA_NORMAL);
    AdvanceResult result;
    if (flag < 0) {
      double h = 0.0, t_cur = 0.0;
      IDAGetCurrentStep(ida_.mem, &h);
      IDAGetCurrentTime(ida_.mem, &t_cur);
      char* name = IDAGetReturnFlagName(flag);
      const std::string text = name ? name : "?";
      free(name);
      Throw<SolverError>("IDASolve", text, " at t = ", t_cur, " s with step h = ", h, " s",
                         failure_.empty() ? "" : " (" + failure_ + ")", LargestErrorComponent(),
                         sundials_messages_.Take());
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

  std::string integrator() const override { return "ida"; }  // variable-order BDF, adaptive

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
    for (int i = 0; i < 6; ++i) F[i] = u(i) - qdot(i);  // F1–F6
    const PoseTpl<T> pose = PoseFromCoordinates(q);
    const Vector6<T> nu = GeneralizedVelocity(q, u);
    const int k = static_cast<int>(active_.size());
    ContactGeometryTpl<T> geo[kMaxActiveContacts];
    for (int c = 0; c < k; ++c) {
      const ContactPair& pair = model_.contacts[active_[c]];
      T* Fc = F + 12 + 5 * c - (form_ == ContactForm::kClosedForm ? 4 * c : 0);
      if (form_ == ContactForm::kChapter) {
        T r[5];
        if (!ChapterContactResiduals(pair, pose, y + 12 + 4 * c, r, &geo[c],
                                     state_contact_[active_[c]].chart)) {
          return false;
        }
        Fc[0] = r[0];
        Fc[1] = r[1];
        Fc[2] = position_level_ ? r[2]
                                                        : T(ContactConstraintRow(pose, geo[c]).dot(nu));
        Fc[3] = r[3];
        Fc[4] = r[4];
      } else {
        if (!ContactKinematics(pair, pose, &geo[c])) return false;
        Fc[0] = position_level_ ? geo[c].gap
                                                        : T(ContactConstraintRow(pose, geo[c]).dot(nu));
      }
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
  const MatrixXd& jacobian() const { return J_; }

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

 private:
  int NormalIndex(int c) const { return 12 + per_contact_ * static_cast<int>(active_.size()) + c; }

  // ċ from the time derivative of the contact-coordinate equations (rows x, y of Eq. 1.8
  // and of Eq. 1.13): ∂g/∂c ċ = −∂g/∂(q) q̇, so the predictor starts consistent.
  void ContactCoordinateRates(double t, const double* y, double* yp) const {
    if (!EvaluateJacobian(t, 0.0, y, yp)) return;
    const MatrixXd& J = J_;
    for (size_t c = 0; c < active_.size(); ++c) {
      const int row0 = 12 + 5 * static_cast<int>(c);
      const int col0 = 12 + 4 * static_cast<int>(c);
      const int rows[4] = {row0, row0 + 1, row0 + 3, row0 + 4};
      Eigen::Matrix4d A;
      Eigen::Vector4d b;
      for (int r = 0; r < 4; ++r) {
        b(r) = 0.0;
        for (int i = 0; i < 6; ++i) b(r) -= J(rows[r], i) * yp[i];
        for (int j = 0; j < 4; ++j) A(r, j) = J(rows[r], col0 + j);
      }
      const Eigen::Vector4d cd = A.fullPivLu().solve(b);
      for (int j = 0; j < 4; ++j) yp[col0 + j] = cd(j);
    }
  }

  static int Residual(double t, N_Vector yy, N_Vector yp, N_Vector rr, void* user) {
    auto* self = static_cast<DaeFormulation*>(user);
    try {
      return self->EvaluateResidual(t, NvData(yy), NvData(yp), NvData(rr), &self->data_) ? 0 : 1;
    } catch (const std::exception& e) {
      self->failure_ = e.what();
      return -1;
    }
  }

  static int Jacobian(double t, double cj, N_Vector yy, N_Vector yp, N_Vector, SUNMatrix JJ,
                      void* user, N_Vector, N_Vector, N_Vector) {
    auto* self = static_cast<DaeFormulation*>(user);
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

  static int Roots(double t, N_Vector yy, N_Vector, double* g, void* user) {
    auto* self = static_cast<DaeFormulation*>(user);
    try {
      const double* y = NvData(yy);
      Vector6d q;
      for (int i = 0; i < 6; ++i) q(i) = y[i];
      std::fill(self->normal_.begin(), self->normal_.end(), 0.0);
      for (size_t c = 0; c < self->active_.size(); ++c) {
        self->normal_[self->active_[c]] = y[self->NormalIndex(static_cast<int>(c))];
      }
      (void)t;
      EvaluateEvents(self->scene_.model, self->events_, q, self->normal_, g);
      return 0;
    } catch (const std::exception& e) {
      self->failure_ = e.what();
      return -1;
    }
  }

  void Check(int flag, const char* call) {
    CheckSundials(flag, call, "DaeFormulation", IDAGetReturnFlagName, &sundials_messages_);
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
  mutable std::string failure_;
  SundialsMessages sundials_messages_;  // SUNDIALS' error text, for the failure reason
  bool position_level_ = false;  // --constraint-level position (index-3 variant)
  // Workspaces sized in the constructor / Start (no allocation in the callbacks).
  mutable DataTpl<double> data_;
  mutable DataTpl<JetD> data_jet_;
  mutable std::vector<JetD> yj_, ypj_, Fj_;
  mutable MatrixXd J_;
  std::vector<double> normal_;  // N per model contact, for the root functions
  std::vector<int> root_flags_;
};

}  // namespace

std::unique_ptr<Formulation> CreateDae(const Scene& scene, const FormulationOptions& options) {
  return std::make_unique<DaeFormulation>(scene, options, ContactForm::kChapter);
}
std::unique_ptr<Formulation> CreateDaeReduced(const Scene& scene, const FormulationOptions& options) {
  return std::make_unique<DaeFormulation>(scene, options, ContactForm::kClosedForm);
}

// Test hook (dae_testing.hpp).
bool DaeResidualAndJacobianForTesting(const Scene& scene, const FormulationOptions& options,
                                      ContactForm form, const MechanicalState& state, double t,
                                      const std::vector<double>& y, const std::vector<double>& yp,
                                      double cj, std::vector<double>* F, MatrixXd* J, int* size) {
  DaeFormulation dae(scene, options, form);
  dae.Start(state, {});
  const int n = dae.size();
  if (size) *size = n;
  if (static_cast<int>(y.size()) != n || static_cast<int>(yp.size()) != n) return false;
  if (F) {
    F->assign(n, 0.0);
    Data data(scene.model);
    if (!dae.EvaluateResidual(t, y.data(), yp.data(), F->data(), &data)) return false;
  }
  if (J) {
    if (!dae.EvaluateJacobian(t, cj, y.data(), yp.data())) return false;
    *J = dae.jacobian();
  }
  return true;
}

}  // namespace kneedyn
