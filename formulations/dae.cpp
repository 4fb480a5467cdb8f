// `dae` and `dae-reduced`: the chapter's modified reverse EDE (section 1.3), an index-2
// DAE, on SUNDIALS IDA (DASSL's maintained successor).
//
// Unknowns y (chapter form, k active contacts, n = 12 + 5k: 22 two-point, 17 one-point):
//   q = (x0, y0, z0, α, β, γ), u = (vx, vy, vz, ωα, ωβ, ωγ),
//   c_i = (xc, yc, x′c, y′c) per contact, then N_i per contact.
// Residuals F(t, y, ẏ) (Eqs. 1.40–1.61):
//   F1–F6    u − q̇                                          (kinematic, Eqs. 1.40–1.47)
//   F7–F9    ΣF − m v̇                                        (Newton, in F)
//   F10–F12  ΣM′ − I ẇ − w × I w, ẇ = E u̇_ang + Ė u_ang     (Euler, in T; docs/model.md §2 exact E)
//   per contact: x, y of Eq. 1.8; the normal condition; x, y of Eq. 1.13.
// The normal condition: the printed F15/F18 (z of Eq. 1.8, a position-level constraint)
// makes the system index 3, not the index 2 the chapter states. kneedyn's `dae` uses its
// time derivative, the normal approach velocity φ̇ = G ν = 0 (contact.hpp), so that the
// contact coordinates are index 1 and the forces index 2 — the semi-explicit index-2 form
// the chapter describes. `--constraint-level position` keeps the printed position-level
// condition (the index-3 variant, --constraint-level position). Position drift of the velocity-level form is
// reported in every trajectory row (gap_*_mm).
//
// `dae-reduced`: the same physics with the closed-form sphere-on-plane contact:
// y = (q, u, N_i), n = 12 + k, constraint φ̇_i = 0 (or φ_i = 0 at position level).
//
// The system itself (unknowns, residual rows, exact Jacobian) is formulations/internal/dae_system.hpp,
// shared with dae-ggl and the IDAS sensitivities. The IDA driver below (DaeOnIda) serves
// dae, dae-reduced and, with the GGL variant of dae_ggl.cpp, dae-ggl and dae-ggl-reduced.
//
// IDA settings: IDASetId (q, u differential; c, N algebraic) with IDASetSuppressAlg, so
// the index-2 algebraic variables are excluded from the error test; dense Jacobian
// dF/dy + cj dF/dẏ exact from the system's blocks (--jacobian jet: the Jet<24> reference;
// difference-quotient: IDA's own); root functions from solver/events.hpp.
// A contact-mode switch rebuilds IDA at the new size from the driver's consistent state
// (IDAReInit cannot change the size). IDACalcIC is not used (it is only valid for index 1);
// the initial y, ẏ come from the consistent initialization.
#include <idas/idas.h>
#include <sunlinsol/sunlinsol_dense.h>
#include <sunmatrix/sunmatrix_dense.h>

#include <algorithm>
#include <cmath>
#include <memory>

#include "formulations/internal/dae_on_ida.hpp"
#include "formulations/internal/dae_system.hpp"
#include "formulations/internal/dae_testing.hpp"
#include "formulations/internal/formulation_base.hpp"
#include "formulations/internal/ida_phase.hpp"
#include "formulations/internal/sundials_util.hpp"
#include "solver/dynamics.hpp"

namespace kneedyn {
namespace {

class DaeOnIda final : public FormulationBase {
 public:
  DaeOnIda(const Scene& scene, const IdaOptions& options, ContactForm form, const DaeOnIdaVariant& variant)
      : FormulationBase(scene),
        options_(options),
        form_(form),
        variant_(variant),
        system_(model_, form, options.constraint_level, variant.ggl) {}
  ~DaeOnIda() override { Free(); }

  ContactForm contact_form() const override { return form_; }

  void Start(const MechanicalState& state, const std::vector<EventSpec>& events) override {
    Free();
    BeginPhase(state, events);
    system_.SetPhase(active_, state.contact, ligament_branch_);
    n_ = system_.size();
    normal_.assign(model_.contacts.size(), 0.0);
    root_flags_.assign(events_.size(), 0);

    ida_.y = NewSerialVector(n_, ctx_);
    ida_.yp = NewSerialVector(n_, ctx_);
    hot_path_r_ = NewSerialVector(n_, ctx_);
    hot_path_g_.assign(events_.size(), 0.0);
    t_ = state.t;
    N_Vector id = NewSerialVector(n_, ctx_);
    N_Vector atol = NewSerialVector(n_, ctx_);
    system_.InitialValues(state, NvData(ida_.y), NvData(ida_.yp));  // μ = 0 on the exact solution
    double* idp = NvData(id);
    double* at = NvData(atol);
    for (int i = 0; i < n_; ++i) {
      idp[i] = system_.IsDifferential(i) ? 1.0 : 0.0;
      at[i] = DaeUnknownAtol(variant_.ggl, system_, i, options_.control.atol);  // dae_on_ida.hpp
    }
    ida_.Start(ctx_, n_, &DaeOnIda::Residual,
               options_.jacobian == JacobianKind::kDifferenceQuotient ? nullptr : &DaeOnIda::Jacobian,
               &DaeOnIda::Roots, this, state.t, atol, id, options_.control, scene_.end.time, events_, variant_.name,
               &sundials_messages_);
    N_VDestroy(id);
    N_VDestroy(atol);
    ++finished_phases_.restarts;
  }

  // Which unknown IDA's failure is about — the component with the largest
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
      out = StrCat("; largest weighted local error estimate: ", system_.UnknownName(worst), " (",
                   std::abs(ed[worst] * wd[worst]), " of the tolerance)");
    }
    N_VDestroy(e);
    N_VDestroy(w);
    return out;
  }

  AdvanceResult Advance(double t_out, MechanicalState* state) override {
    double t_reached = state->t;
    failure_.clear();
    // GGL stops at t_out instead of interpolating to it: outputs are step values, on which
    // the position and velocity constraints hold to the Newton tolerance.
    if (variant_.ggl) Check(IDASetStopTime(ida_.mem, std::min(t_out, scene_.end.time)), "IDASetStopTime");
    const int flag = IDASolve(ida_.mem, t_out, &t_reached, ida_.y, ida_.yp, IDA_NORMAL);
    AdvanceResult result;
    if (flag < 0) {
      // GGL failures name their formulation (dae-ggl or dae-ggl-reduced); dae's and
      // dae-reduced's keep the plain prefix.
      const std::string function = variant_.ggl ? StrCat("IDASolve (", variant_.name, ")") : std::string("IDASolve");
      Throw<SolverError>(function.c_str(), ida_.SolveFailure(flag), failure_.empty() ? "" : " (" + failure_ + ")",
                         LargestErrorComponent(), sundials_messages_.Take());
    }
    t_ = t_reached;
    const double* y = NvData(ida_.y);
    const double* yp = NvData(ida_.yp);
    WriteBack(t_reached, Eigen::Map<const Vector6d>(y), Eigen::Map<const Vector6d>(y + 6),
              Eigen::Map<const Vector6d>(yp + 6), y + system_.NormalIndex(0), y + 12,
              system_.per_contact(), state);
    if (flag == IDA_ROOT_RETURN) {
      Check(IDAGetRootInfo(ida_.mem, root_flags_.data()), "IDAGetRootInfo");
      result = EventResult(root_flags_);
    }
    return result;
  }

  std::string integrator() const override { return "ida"; }  // variable-order BDF, adaptive

  SolverStats PhaseStats() const override {
    return ida_.mem != nullptr ? IdaStatistics(ida_.mem, !events_.empty()) : SolverStats();
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

 private:
  static int Residual(double t, N_Vector yy, N_Vector yp, N_Vector rr, void* user) {
    auto* self = static_cast<DaeOnIda*>(user);
    try {
      return self->system_.Residual(t, NvData(yy), NvData(yp), NvData(rr)) ? 0 : 1;
    } catch (const std::exception& e) {
      self->failure_ = e.what();
      return -1;
    }
  }

  // dF/dy + cj dF/dẏ straight into IDA's column-major dense matrix.
  static int Jacobian(double t, double cj, N_Vector yy, N_Vector yp, N_Vector, SUNMatrix JJ,
                      void* user, N_Vector, N_Vector, N_Vector) {
    auto* self = static_cast<DaeOnIda*>(user);
    try {
      double* J = SUNDenseMatrix_Data(JJ);
      const bool ok = self->options_.jacobian == JacobianKind::kJet
                          ? self->system_.JacobianByJets(t, cj, NvData(yy), NvData(yp), J)
                          : self->system_.Jacobian(t, cj, NvData(yy), NvData(yp), J);
      return ok ? 0 : 1;
    } catch (const std::exception& e) {
      self->failure_ = e.what();
      return -1;
    }
  }

  static int Roots(double, N_Vector yy, N_Vector, double* g, void* user) {
    auto* self = static_cast<DaeOnIda*>(user);
    try {
      const double* y = NvData(yy);
      Vector6d q;
      for (int i = 0; i < 6; ++i) q(i) = y[i];
      std::fill(self->normal_.begin(), self->normal_.end(), 0.0);
      for (size_t c = 0; c < self->active_.size(); ++c) {
        self->normal_[self->active_[c]] = y[self->system_.NormalIndex(static_cast<int>(c))];
      }
      EvaluateEvents(self->scene_.model, self->events_, q, self->normal_, g);
      return 0;
    } catch (const std::exception& e) {
      self->failure_ = e.what();
      return -1;
    }
  }

  void Check(int flag, const char* call) {
    CheckSundials(flag, call, variant_.name, IDAGetReturnFlagName, &sundials_messages_);
  }

  void Free() {
    ida_.Free(&finished_phases_, !events_.empty());
    if (hot_path_r_) { N_VDestroy(hot_path_r_); hot_path_r_ = nullptr; }
  }

  IdaOptions options_;
  ContactForm form_;
  DaeOnIdaVariant variant_;
  SundialsContext ctx_;
  DaeSystem system_;  // unknowns, residual, Jacobian (dae_system.hpp)
  double t_ = 0.0;  // s: time of the phase's y, ẏ (phase start or last Advance)
  N_Vector hot_path_r_ = nullptr;   // residual of EvaluateHotPathForTesting
  std::vector<double> hot_path_g_;  // root values of EvaluateHotPathForTesting
  IdaPhase ida_;  // IDA memory, y, ẏ, matrix and linear solver of the phase
  int n_ = 0;
  mutable std::string failure_;
  SundialsMessages sundials_messages_;  // SUNDIALS' error text, for the failure reason
  std::vector<double> normal_;  // N per model contact, for the root functions
  std::vector<int> root_flags_;
};

constexpr DaeOnIdaVariant kPlain = {"dae", false};
constexpr DaeOnIdaVariant kPlainReduced = {"dae-reduced", false};

}  // namespace

bool ReadIdaOptions(const OptionRequest& request, IdaOptions* options) {
  const FormulationOptions& o = request.options;
  options->control = o.step_control();
  options->constraint_level = o.constraint_level;
  options->jacobian = o.jacobian.value_or(JacobianKind::kExact);
  return true;
}

std::unique_ptr<Formulation> CreateDaeOnIda(const Scene& scene, const IdaOptions& options,
                                            ContactForm form, const DaeOnIdaVariant& variant) {
  return std::make_unique<DaeOnIda>(scene, options, form, variant);
}

FormulationMaker ConfigureDae(const OptionRequest& request) {
  IdaOptions options;
  if (!ReadIdaOptions(request, &options)) return nullptr;
  return [options](const Scene& scene) { return CreateDaeOnIda(scene, options, ContactForm::kChapter, kPlain); };
}
FormulationMaker ConfigureDaeReduced(const OptionRequest& request) {
  IdaOptions options;
  if (!ReadIdaOptions(request, &options)) return nullptr;
  return [options](const Scene& scene) {
    return CreateDaeOnIda(scene, options, ContactForm::kClosedForm, kPlainReduced);
  };
}

// Test hook (dae_testing.hpp).
bool DaeResidualAndJacobianForTesting(const Scene& scene, const FormulationOptions& options,
                                      ContactForm form, const MechanicalState& state, double t,
                                      const std::vector<double>& y, const std::vector<double>& yp,
                                      double cj, std::vector<double>* F, MatrixXd* J, int* size) {
  DaeSystem system(scene.model, form, options.constraint_level, /*ggl=*/false);
  system.SetPhase(state.active, state.contact, state.ligament_branch);
  const int n = system.size();
  if (size) *size = n;
  if (static_cast<int>(y.size()) != n || static_cast<int>(yp.size()) != n) return false;
  if (F) {
    F->assign(n, 0.0);
    if (!system.Residual(t, y.data(), yp.data(), F->data())) return false;
  }
  if (J) {
    J->resize(n, n);
    const bool ok = options.jacobian == JacobianKind::kJet
                        ? system.JacobianByJets(t, cj, y.data(), yp.data(), J->data())
                        : system.Jacobian(t, cj, y.data(), yp.data(), J->data());
    if (!ok) return false;
  }
  return true;
}

}  // namespace kneedyn
