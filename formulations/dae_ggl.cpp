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
// index 2), as in idaSlCrank_dns.c. The system (unknowns, residual, the exact Jacobian
// dF/dy + cj dF/dẏ) is formulations/dae_system.hpp, shared with dae. All workspaces are
// allocated in Start; the residual, Jacobian and root callbacks allocate nothing.
#include <idas/idas.h>
#include <sunlinsol/sunlinsol_dense.h>
#include <sunmatrix/sunmatrix_dense.h>

#include <algorithm>
#include <cmath>
#include <memory>

#include "formulations/dae_system.hpp"
#include "formulations/formulation_base.hpp"
#include "formulations/ida_phase.hpp"
#include "formulations/sundials_kernels.hpp"
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
      : FormulationBase(scene),
        options_(options),
        parsed_(options.Parsed()),
        form_(form),
        system_(model_, form, ConstraintLevel::kVelocity, /*ggl=*/true) {
    const char* name = form == ContactForm::kChapter ? "dae-ggl" : "dae-ggl-reduced";
    if (options.step != 0.0) {
      Throw<InputError>("DaeGglFormulation", "--step = ", options.step,
                        " s: ", name, " chooses its own steps; use --max-step");
    }
    if (parsed_.stabilization != Stabilization::kNone) {
      Throw<InputError>("DaeGglFormulation", "--stabilization = '", options.stabilization,
                        "' applies to ede only (", name, " enforces both constraint levels)");
    }
    if (parsed_.constraint_level != ConstraintLevel::kVelocity) {
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
    system_.SetPhase(active_, state.contact, ligament_branch_);
    n_ = system_.size();
    const int k = static_cast<int>(active_.size());
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
      const bool force = k > 0 && i >= system_.NormalIndex(0) && i < system_.MuIndex(0);
      const bool mu = k > 0 && i >= system_.MuIndex(0);
      at[i] = force ? std::max(kForceAtolFloor, options_.atol * kForceAtolScale)
                    : mu ? std::max(kMuAtolFloor, options_.atol * kMuAtolScale) : options_.atol;
    }
    ida_.Start(ctx_, n_, &DaeGglFormulation::Residual,
               parsed_.jacobian == JacobianKind::kDifferenceQuotient ? nullptr : &DaeGglFormulation::Jacobian,
               &DaeGglFormulation::Roots, this, state.t, atol, id, options_, scene_.end.time, events_,
               "DaeGglFormulation::Start", &sundials_messages_);
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
              Eigen::Map<const Vector6d>(yp + 6), y + system_.NormalIndex(0), y + 12,
              system_.per_contact(), state);
    if (flag == IDA_ROOT_RETURN) {
      Check(IDAGetRootInfo(ida_.mem, root_flags_.data()), "IDAGetRootInfo");
      result = EventResult(root_flags_);
    }
    return result;
  }

  SolverStats PhaseStats() const override { return ida_.mem != nullptr ? CurrentStats() : SolverStats(); }

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
    auto* self = static_cast<DaeGglFormulation*>(user);
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
    auto* self = static_cast<DaeGglFormulation*>(user);
    try {
      double* J = SUNDenseMatrix_Data(JJ);
      const bool ok = self->parsed_.jacobian == JacobianKind::kJet
                          ? self->system_.JacobianByJets(t, cj, NvData(yy), NvData(yp), J)
                          : self->system_.Jacobian(t, cj, NvData(yy), NvData(yp), J);
      return ok ? 0 : 1;
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
        self->normal_[self->active_[c]] = y[self->system_.NormalIndex(static_cast<int>(c))];
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
  ParsedFormulationOptions parsed_;
  ContactForm form_;
  SundialsContext ctx_;
  DaeSystem system_;  // unknowns, residual, Jacobian (dae_system.hpp)
  double t_ = 0.0;  // s: time of the phase's y, ẏ (phase start or last Advance)
  N_Vector hot_path_r_ = nullptr;   // residual of EvaluateHotPathForTesting
  std::vector<double> hot_path_g_;  // root values of EvaluateHotPathForTesting
  IdaPhase ida_;  // IDA memory, y, ẏ, matrix and linear solver of the phase
  int n_ = 0;
  mutable std::string failure_;
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
