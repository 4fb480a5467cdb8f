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
#include "formulations/formulation.hpp"
#include "formulations/ida_statistics.hpp"
#include "formulations/sundials_util.hpp"
#include "solver/dynamics.hpp"

namespace kneedyn {
namespace {

// Absolute tolerance of the normal forces per unit --atol (N per SI unit of the states).
constexpr double kForceAtolScale = 1.0e4;

class DaeFormulation final : public Formulation {
 public:
  DaeFormulation(const Scene& scene, const FormulationOptions& options, ContactForm form)
      : scene_(scene), model_(scene.model), options_(options), form_(form) {
    if (options.step != 0.0) {
      Throw<InputError>("DaeFormulation", "--step = ", options.step,
                        " s: the IDA formulations choose their own steps; use --max-step");
    }
    if (options.stabilization != "none") {
      Throw<InputError>("DaeFormulation", "--stabilization = '", options.stabilization,
                        "' applies to ede only");
    }
  }
  ~DaeFormulation() override { Free(); }

  ContactForm contact_form() const override { return form_; }

  void Start(const MechanicalState& state, const std::vector<EventSpec>& events) override {
    Free();
    active_ = state.active;
    events_ = events;
    const int k = static_cast<int>(active_.size());
    per_contact_ = form_ == ContactForm::kChapter ? 4 : 0;
    n_ = 12 + (per_contact_ + 1) * k;
    if (n_ > kMaxJetSize) Throw<SolverError>("DaeFormulation::Start", "system size ", n_, " exceeds ", kMaxJetSize);
    state_contact_ = state.contact;
    ligament_branch_ = state.ligament_branch;

    y_ = N_VNew_Serial(n_, ctx_);
    yp_ = N_VNew_Serial(n_, ctx_);
    N_Vector id = N_VNew_Serial(n_, ctx_);
    N_Vector atol = N_VNew_Serial(n_, ctx_);
    double* y = NvData(y_);
    double* yp = NvData(yp_);
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
    mem_ = IDACreate(ctx_);
    if (mem_ == nullptr) Throw<SolverError>("DaeFormulation::Start", "IDACreate failed");
    Check(IDASetErrHandlerFn(mem_, &SundialsMessages::Handler, &sundials_messages_), "IDASetErrHandlerFn");
    Check(IDAInit(mem_, &DaeFormulation::Residual, state.t, y_, yp_), "IDAInit");
    Check(IDASetUserData(mem_, this), "IDASetUserData");
    Check(IDASVtolerances(mem_, options_.rtol, atol), "IDASVtolerances");
    Check(IDASetId(mem_, id), "IDASetId");
    Check(IDASetSuppressAlg(mem_, SUNTRUE), "IDASetSuppressAlg");
    Check(IDASetMaxNumSteps(mem_, options_.max_steps), "IDASetMaxNumSteps");
    if (options_.max_step > 0.0) Check(IDASetMaxStep(mem_, options_.max_step), "IDASetMaxStep");
    Check(IDASetStopTime(mem_, scene_.end.time), "IDASetStopTime");
    // First step. IDA's own estimate (h ‖ẏ‖_WRMS ≤ 1/2) is ~1e-11 s at rtol 1e-10 when
    // the tibia moves, and at such steps the O(ε/h²) round-off of the index-2 forces
    // defeats the Newton test. Restarts after a mode switch begin at a quarter of the last
    // step taken; a first start at 1e-4 s · sqrt(rtol / 1e-6) (BDF1 local error ∝ h²),
    // which IDA's error test then adjusts.
    const double h0 = last_step_ > 0.0
                          ? 0.25 * last_step_
                          : std::clamp(1e-4 * std::sqrt(options_.rtol / 1e-6), 1e-8, 1e-3);
    Check(IDASetInitStep(mem_, h0), "IDASetInitStep");
    A_ = SUNDenseMatrix(n_, n_, ctx_);
    LS_ = SUNLinSol_Dense(y_, A_, ctx_);
    Check(IDASetLinearSolver(mem_, LS_, A_), "IDASetLinearSolver");
    Check(IDASetJacFn(mem_, &DaeFormulation::Jacobian), "IDASetJacFn");
    if (!events_.empty()) {
      Check(IDARootInit(mem_, static_cast<int>(events_.size()), &DaeFormulation::Roots), "IDARootInit");
      std::vector<int> dir = RootDirections(events_);
      Check(IDASetRootDirection(mem_, dir.data()), "IDASetRootDirection");
      Check(IDASetNoInactiveRootWarn(mem_), "IDASetNoInactiveRootWarn");
    }
    N_VDestroy(id);
    N_VDestroy(atol);
    ++accumulated_.restarts;
  }

  // Issue 18: which unknown IDA's failure is about — the component with the largest
  // weighted local error estimate |e_i| w_i (IDAGetEstLocalErrors, IDAGetErrWeights).
  std::string LargestErrorComponent() const {
    N_Vector e = N_VClone(y_), w = N_VClone(y_);
    std::string out;
    if (IDAGetEstLocalErrors(mem_, e) == IDA_SUCCESS && IDAGetErrWeights(mem_, w) == IDA_SUCCESS) {
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
    const int flag = IDASolve(mem_, t_out, &t_reached, y_, yp_, IDA_NORMAL);
    AdvanceResult result;
    if (flag < 0) {
      double h = 0.0, t_cur = 0.0;
      IDAGetCurrentStep(mem_, &h);
      IDAGetCurrentTime(mem_, &t_cur);
      char* name = IDAGetReturnFlagName(flag);
      const std::string text = name ? name : "?";
      free(name);
      Throw<SolverError>("IDASolve", text, " at t = ", t_cur, " s with step h = ", h, " s",
                         failure_.empty() ? "" : " (" + failure_ + ")", LargestErrorComponent(),
                         sundials_messages_.Take());
    }
    const double* y = NvData(y_);
    const double* yp = NvData(yp_);
    state->t = t_reached;
    for (int i = 0; i < 6; ++i) {
      state->q(i) = y[i];
      state->qd(i) = y[6 + i];
      state->qdd(i) = yp[6 + i];
    }
    state->contact = state_contact_;
    state->ligament_branch = ligament_branch_;
    for (size_t c = 0; c < active_.size(); ++c) {
      for (int j = 0; j < per_contact_; ++j) {
        state->contact[active_[c]].coordinates[j] = y[12 + per_contact_ * c + j];
      }
      state->contact[active_[c]].normal_force = y[NormalIndex(static_cast<int>(c))];
    }
    if (per_contact_ == 0) FillContactCoordinates(model_, state);
    if (flag == IDA_ROOT_RETURN) {
      std::vector<int> found(events_.size());
      Check(IDAGetRootInfo(mem_, found.data()), "IDAGetRootInfo");
      result = EventResult(found);
    }
    return result;
  }

  std::string integrator() const override { return "ida"; }  // variable-order BDF, adaptive

  SolverStats stats() const override {
    SolverStats s = accumulated_;
    if (mem_ != nullptr) s += CurrentStats();
    return s;
  }

  // F(t, y, ẏ) for any scalar type. Returns false on a recoverable failure (surface
  // evaluated outside its domain).
  template <typename T>
  bool EvaluateResidual(double t, const T* y, const T* yp, T* F) const {
    Vector6<T> q, u, qdot, udot;
    for (int i = 0; i < 6; ++i) {
      q(i) = y[i];
      u(i) = y[6 + i];
      qdot(i) = yp[i];
      udot(i) = yp[6 + i];
    }
    for (int i = 0; i < 6; ++i) F[i] = u(i) - qdot(i);  // F1–F6
    const PoseTpl<T> pose = PoseFromCoordinates(q);
    DataTpl<T> data(model_);
    data.ligament_branch = &ligament_branch_;
    ComputeAppliedWrench(model_, t, pose, &data);
    // Contact wrenches are added to the applied loads (Eqs. 1.48–1.57 sum both).
    Vector3<T>& force = data.applied_force_F;
    Vector3<T>& moment = data.applied_moment_T;
    const Vector6<T> nu = GeneralizedVelocity(q, u);
    const int k = static_cast<int>(active_.size());
    for (int c = 0; c < k; ++c) {
      const ContactPair& pair = model_.contacts[active_[c]];
      T* Fc = F + 12 + 5 * c - (form_ == ContactForm::kClosedForm ? 4 * c : 0);
      ContactGeometryTpl<T> geo;
      if (form_ == ContactForm::kChapter) {
        T r[5];
        if (!ChapterContactResiduals(pair, pose, y + 12 + 4 * c, r, &geo,
                                     state_contact_[active_[c]].chart)) {
          return false;
        }
        Fc[0] = r[0];
        Fc[1] = r[1];
        Fc[2] = options_.constraint_level == "position" ? r[2]
                                                        : T(ContactConstraintRow(pose, geo).dot(nu));
        Fc[3] = r[3];
        Fc[4] = r[4];
      } else {
        if (!ContactKinematics(pair, pose, &geo)) return false;
        Fc[0] = options_.constraint_level == "position" ? geo.gap
                                                        : T(ContactConstraintRow(pose, geo).dot(nu));
      }
      AddContactWrench(pose, geo, y[NormalIndex(c)], &force, &moment);
    }
    const Vector6<T> Q = GeneralizedForce(model_, data, Vector3<T>(nu.template tail<3>()));
    const Vector6<T> residual = Q - MassTimes(model_, GeneralizedAcceleration(q, u, udot));
    for (int i = 0; i < 6; ++i) F[6 + i] = residual(i);  // F7–F12
    return true;
  }

  // dF/dy + cj dF/dẏ by forward AD (two Jet passes).
  bool EvaluateJacobian(double t, double cj, const double* y, const double* yp, MatrixXd* J) const {
    std::vector<JetD> yj(n_), ypj(n_), Fj(n_);
    J->setZero(n_, n_);
    for (int pass = 0; pass < 2; ++pass) {
      for (int i = 0; i < n_; ++i) {
        yj[i] = JetD(y[i]);
        ypj[i] = JetD(yp[i]);
        if (pass == 0) yj[i].v[i] = 1.0;
        else ypj[i].v[i] = 1.0;
      }
      if (!EvaluateResidual(t, yj.data(), ypj.data(), Fj.data())) return false;
      const double scale = pass == 0 ? 1.0 : cj;
      for (int r = 0; r < n_; ++r) {
        for (int c = 0; c < n_; ++c) (*J)(r, c) += scale * Fj[r].v[c];
      }
    }
    return true;
  }

  int size() const { return n_; }

 private:
  int NormalIndex(int c) const { return 12 + per_contact_ * static_cast<int>(active_.size()) + c; }

  // ċ from the time derivative of the contact-coordinate equations (rows x, y of Eq. 1.8
  // and of Eq. 1.13): ∂g/∂c ċ = −∂g/∂(q) q̇, so the predictor starts consistent.
  void ContactCoordinateRates(double t, const double* y, double* yp) const {
    MatrixXd J;
    if (!EvaluateJacobian(t, 0.0, y, yp, &J)) return;
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
      return self->EvaluateResidual(t, NvData(yy), NvData(yp), NvData(rr)) ? 0 : 1;
    } catch (const std::exception& e) {
      self->failure_ = e.what();
      return -1;
    }
  }

  static int Jacobian(double t, double cj, N_Vector yy, N_Vector yp, N_Vector, SUNMatrix JJ,
                      void* user, N_Vector, N_Vector, N_Vector) {
    auto* self = static_cast<DaeFormulation*>(user);
    try {
      MatrixXd J;
      if (!self->EvaluateJacobian(t, cj, NvData(yy), NvData(yp), &J)) return 1;
      for (int c = 0; c < self->n_; ++c) {
        double* col = SUNDenseMatrix_Column(JJ, c);
        for (int r = 0; r < self->n_; ++r) col[r] = J(r, c);
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
      std::vector<double> normal(self->model_.contacts.size(), 0.0);
      for (size_t c = 0; c < self->active_.size(); ++c) {
        normal[self->active_[c]] = y[self->NormalIndex(static_cast<int>(c))];
      }
      (void)t;
      EvaluateEvents(self->scene_.model, self->events_, q, normal, g);
      return 0;
    } catch (const std::exception& e) {
      self->failure_ = e.what();
      return -1;
    }
  }

  void Check(int flag, const char* call) {
    CheckSundials(flag, call, "DaeFormulation", IDAGetReturnFlagName, &sundials_messages_);
  }

  SolverStats CurrentStats() const { return IdaStatistics(mem_, !events_.empty()); }

  void Free() {
    if (mem_ != nullptr) {
      accumulated_ += CurrentStats();
      IDAGetLastStep(mem_, &last_step_);
      IDAFree(&mem_);
      mem_ = nullptr;
    }
    if (LS_) { SUNLinSolFree(LS_); LS_ = nullptr; }
    if (A_) { SUNMatDestroy(A_); A_ = nullptr; }
    if (y_) { N_VDestroy(y_); y_ = nullptr; }
    if (yp_) { N_VDestroy(yp_); yp_ = nullptr; }
  }

  const Scene& scene_;
  const Model& model_;
  FormulationOptions options_;
  ContactForm form_;
  SundialsContext ctx_;
  void* mem_ = nullptr;
  N_Vector y_ = nullptr, yp_ = nullptr;
  SUNMatrix A_ = nullptr;
  SUNLinearSolver LS_ = nullptr;
  int n_ = 0;
  int per_contact_ = 4;
  double last_step_ = 0.0;  // s: last step of the previous phase, the restart's first step
  std::vector<int> active_;
  std::vector<EventSpec> events_;
  std::vector<ContactGuess> state_contact_;
  std::vector<signed char> ligament_branch_;  // locked for the phase
  SolverStats accumulated_;
  mutable std::string failure_;
  SundialsMessages sundials_messages_;  // SUNDIALS' error text, for the failure reason
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
    if (!dae.EvaluateResidual(t, y.data(), yp.data(), F->data())) return false;
  }
  if (J && !dae.EvaluateJacobian(t, cj, y.data(), yp.data(), J)) return false;
  return true;
}

}  // namespace kneedyn
