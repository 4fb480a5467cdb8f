// Forward sensitivities of the DAE forms (the registry's SensitivityForm::kDae and kDaeGgl:
// `dae`, `dae-reduced`, `dae-ggl`, `dae-ggl-reduced`) with SUNDIALS IDAS, on the system that
// formulations/internal/dae_system.hpp writes once (the residual, the unknown layout, the exact
// Jacobian and the consistent starting values are DaeSystem's).
//
// State: F(t, y, ẏ; p) = 0, y = (q, u, c_i, N_i) (chapter form; closed form y = (q, u, N_i);
// GGL adds μ_i, ≡ 0 on the exact solution, so s_μ starts at 0), index 2 (normal approach
// velocity G ν = 0). The phases are run by the hybrid simulator of `kneedyn run`
// (formulations/simulator.hpp; RestartProjection::kProject, PullingContact::kRefuse): the
// same consistent state at every phase start (ConsistentInitialize; LigamentBranchesAt +
// CompleteHiddenConstraint), the same events and re-contact hysteresis; as dae.cpp and
// dae_ggl.cpp: tolerances (N, μ: 1e4 per unit atol, GGL with floors; GGL stops at each
// output time, IdaPhase::SolveToStopTime), first step (IdaPhase) and root functions (lift-off g = N_i, the DAE unknown).
//
// Sensitivities s_j = ∂y/∂p_j solve F_y s_j + F_ẏ ṡ_j + F_pj = 0 with our own IDASensResFn:
//   F_y = Jacobian(cj = 0), F_ẏ = Jacobian(cj = 1) − Jacobian(cj = 0) (DaeSystem, exact);
//   F_pj = [F(model at p + h_j e_j) − F(model at p − h_j e_j)] / 2h_j, h_j = 1e-5 p̄_j, over
//   models built once per run and swapped in with DaeSystem::SetModel.
// Not IDAS' difference quotients: they perturb p in place, so every residual call would
// rebuild the scene (ensembles::SceneForRun), and they scale the y step with the error
// weights, which at atol ≪ |y| puts the quotient near round-off (the CVODES note in
// forward_sensitivity.hpp). F_y, F_ẏ and F_p are evaluated once per (t, y, ẏ): the
// staggered corrector calls the residual with the same state in each of its iterations.
//
// Error test: IDASetId (q, u differential; c, N algebraic) with IDASetSuppressAlg masks the
// sensitivities' error weights as well (IDAS: IDASensWrmsNorm with the same id), and
// IDASetSensErrCon(true) puts s_q, s_u into the error test; s_c (index 1) and s_N (index 2)
// are held by the Newton test only, with the state's absolute tolerances per p̄_j. Staggered
// corrector (IDA_STAGGERED). Measured on the chapter scene at rtol 1e-8 (20 derivatives
// against ede at rtol 1e-10): largest relative difference 4.4e-6 as configured (ede itself
// at rtol 1e-8: 9.6e-6), 9e-5 without the sensitivity error test, 1.1e-4 with the
// simultaneous corrector.
//
// Consistent sensitivities (IDACalcIC is for index 1; not used):
//   t = 0: central differences in p_j (step h_j) of the driver's map p -> (y0, ẏ0):
//     ConsistentInitialize, the nominal ligament branches, CompleteHiddenConstraint,
//     DaeSystem::InitialValues.
//   A restart at an event τ (lift-off, ligament kink): x = (q, u) is continuous, and its
//     sensitivity jumps where the vector field changes (Hiskens & Pai 2000, Eq. 9),
//       s_x⁺ = s_x⁻ + (ẋ⁻ − ẋ⁺) dτ/dp,   ẋ = (q̇, q̈) of the old / new mode at the event state
//     (hidden-constraint accelerations, solver/constrained_dynamics.hpp); the algebraic
//     unknowns are re-solved: on the new mode's constraint manifold z(t) = Z(x(t), t, p), so
//     at fixed t s_z = Z_x s_x + Z_p (no Z_t dτ term), and ẏ = Y(x, t, p) likewise. (s⁺, ṡ⁺)
//     is the directional central difference of the restart map (x, p) -> (y, ẏ)
//     (CompleteHiddenConstraint + InitialValues in the new mode) along (s_x⁺, e_j), step h_j.
//     ṡ_N = 0 as InitialValues' Ṅ = 0 (Ṅ never enters F; IDA's predictor corrects it).
//   Check: max over phases, parameters and rows of |F_y s + F_ẏ ṡ + F_p| relative to the
//     size of the row's terms (SensitivityResidual; SensitivityResult::
//     initial_sensitivity_residual): ≤ 2e-9 on the chapter scene (dae, dae-reduced,
//     dae-ggl; rtol 1e-8 and 1e-10).
//
// Outcomes (as ede, forward_sensitivity.hpp): the values are the DAE's (contact forces are
// its unknowns N_i, lift-off is its root N_i = 0, as in `kneedyn run --formulation dae`);
// the derivatives use IDAS' differential sensitivities s_x with the solver/ functions of
// x = (q, u): event times dτ/dp = −(∂g/∂x s_x + ∂g/∂p) / (∂g/∂t + ∂g/∂x ẋ) (implicit-
// function relation at the root; lift-off g is the hidden-constraint force, equal to the
// DAE's N to the integration error), values at an event ∂v/∂t dτ + ∂v/∂x (s_x + ẋ dτ) +
// ∂v/∂p, peaks ∂v/∂x s_x + ∂v/∂p (envelope theorem). Not s_N: at a root IDAS interpolates
// it without error control; measured at a peak of N_medial 4.7 ms after lift-off (rtol
// 1e-10, one parameter) s_N was 3.5e-4 off, the hidden-constraint derivative along s_x
// 8e-7 from ede's.
#include <idas/idas.h>
#include <sunlinsol/sunlinsol_dense.h>
#include <sunmatrix/sunmatrix_dense.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "formulations/internal/dae_on_ida.hpp"
#include "formulations/internal/dae_system.hpp"
#include "formulations/internal/ida_phase.hpp"
#include "formulations/simulator.hpp"
#include "formulations/internal/sundials_util.hpp"
#include "sensitivity/sensitivity_problem.hpp"
#include "solver/consistent_init.hpp"
#include "solver/constraint_residuals.hpp"
#include "solver/units.hpp"

namespace kneedyn::sensitivity::detail {
namespace {

// Relative step h_j / p̄_j of F_p and of the consistent-value maps. Their central
// differences have truncation ~h² and round-off ~δ/h, δ ~ 1e-13 relative from the hidden-
// constraint solve in the maps; the residual of the consistent initial sensitivities
// (initial_sensitivity_residual, chapter scene, 5 parameters, dae, rtol 1e-10) measured
// 1.6e-8 at 1e-7, 1.8e-9 at 1e-6, 5.8e-10 at 1e-5 and 3.5e-8 at 1e-4.
constexpr double kParameterStep = 1.0e-5;

struct DaeForm {
  ContactForm contact;
  bool ggl;
};

// The registry's DAE form of a formulation: its contact form (Formulation::contact_form) and
// whether it is the GGL system (FormulationInfo::sensitivity).
DaeForm DaeFormOf(const std::string& name, const Scene& scene) {
  const FormulationInfo& info = FindFormulation(name);
  if (info.sensitivity != SensitivityForm::kDae && info.sensitivity != SensitivityForm::kDaeGgl) {
    Throw<InputError>("RunDaeSensitivity", "--formulation = '", Echo(name), "' is not a DAE form");
  }
  return {Configure(info, FormulationOptions())(scene)->contact_form(), info.sensitivity == SensitivityForm::kDaeGgl};
}

// The DAE and its sensitivities on IDAS as a stepper of the hybrid simulator
// (formulations/simulator.hpp): Start computes the consistent (initial or restart)
// sensitivities at the phase start the simulator hands it; Advance integrates, locates the
// peaks' roots inside the phase and, at an event, dτ/dp and the event's outcomes.
class DaeSensitivity : public Formulation {
 public:
  DaeSensitivity(Problem& problem, const std::vector<double>& p, const SensitivityOptions& options,
                 SensitivityResult* result)
      : problem_(problem),
        options_(options),
        p_(p),
        np_(static_cast<int>(p.size())),
        with_s_(options.derivatives && !p.empty()),
        nominal_(problem.SceneCopyAt(p)),
        form_(DaeFormOf(options.formulation, nominal_)),
        system_(nominal_.model, form_.contact, ConstraintLevel::kVelocity, form_.ggl),
        result_(result) {
    // The perturbed models of F_p and of the consistent-value maps, built once.
    for (int j = 0; j < np_; ++j) {
      pbar_.push_back(p_[j] != 0.0 ? std::abs(p_[j]) : 1.0);
      h_.push_back(kParameterStep * pbar_[j]);
      if (!with_s_) continue;
      std::vector<double> plus = p_, minus = p_;
      plus[j] += h_[j];
      minus[j] -= h_[j];
      plus_.push_back(problem.SceneCopyAt(plus));
      minus_.push_back(problem.SceneCopyAt(minus));
    }
    ida_options_.rtol = options.rtol;
    ida_options_.atol = options.atol;
    ida_options_.max_steps = options.max_steps;
    normal_.assign(nominal_.model.contacts.size(), 0.0);
    zero_p_.assign(np_, 0.0);
  }
  ~DaeSensitivity() override { FreePhase(); }
  DaeSensitivity(const DaeSensitivity&) = delete;
  DaeSensitivity& operator=(const DaeSensitivity&) = delete;

  // The simulator's run with this stepper; fills the result.
  void Run();

  ContactForm contact_form() const override { return form_.contact; }
  void Start(const MechanicalState& state, const std::vector<EventSpec>& events) override;
  AdvanceResult Advance(double t_out, MechanicalState* state) override;
  SolverStats stats() const override { return stats_; }

 private:
  const Model& model() const { return nominal_.model; }

  // --- The phase's IDAS instance. ---
  void StartPhase(double t, const std::vector<std::vector<double>>& s, const std::vector<std::vector<double>>& sdot);
  void FreePhase();
  void Check(int flag, const char* call) {
    CheckSundials(flag, call, "RunSensitivity", IDAGetReturnFlagName, &messages_);
  }

  // --- Values on the DAE unknowns of the current phase. ---
  // The outcome's instantaneous value: a ligament tension (q), or the DAE's normal force N.
  double Value(const Outcome& o, double t, const double* y) const {
    if (!IsContact(o)) return problem_.Value(mode_, o, t, y, p_.data());
    const int a = ActiveSlot(o);
    return a < 0 ? 0.0 : y[system_.NormalIndex(a)];
  }
  static bool IsContact(const Outcome& o) {
    return o.kind == OutcomeKind::kPeakContact || o.kind == OutcomeKind::kContactAt90;
  }
  int ActiveSlot(const Outcome& o) const {
    const auto it = std::find(mode_.active.begin(), mode_.active.end(), o.index);
    return o.index < 0 || it == mode_.active.end() ? -1 : static_cast<int>(it - mode_.active.begin());
  }
  // d/dt along the trajectory (t, x, ẋ) of the hidden-constraint value of o (N per s).
  double Rate(const Outcome& o, double t, const double* y, const double* xdot) {
    return problem_.Directional([&](double tt, const double* yy, const double* pv) { return problem_.Value(mode_, o, tt, yy, pv); },
                                t, y, p_.data(), 1.0, xdot, zero_p_.data());
  }
  // Total derivative per parameter of o at (t, y) moving with dτ/dp: ∂v/∂t dτ + ∂v/∂x w + ∂v/∂p
  // (w = s_x + ẋ dτ) of the solver/ value on x = (q, u): a ligament tension, or the
  // hidden-constraint normal force, not s_N (see the header: IDAS' s_N at a root is
  // interpolated without error control).
  std::vector<double> Total(const Outcome& o, double t, const double* y, const std::vector<double>& dtau,
                            const std::vector<std::vector<double>>& w) {
    std::vector<double> d(np_, kNaN);
    if (!with_s_) return d;
    if (IsContact(o) && ActiveSlot(o) < 0) return std::vector<double>(np_, 0.0);  // separated: v ≡ 0
    std::vector<double> e(np_, 0.0);
    for (int j = 0; j < np_; ++j) {
      std::fill(e.begin(), e.end(), 0.0);
      e[j] = 1.0;
      d[j] = problem_.Directional([&](double tt, const double* yy, const double* pv) { return problem_.Value(mode_, o, tt, yy, pv); },
                                  t, y, p_.data(), dtau[j], w[j].data(), e.data());
    }
    return d;
  }
  // A maximum candidate for every peak outcome at (t, y) (only == k: that one alone).
  void Candidates(double t, const double* y, const std::vector<double>& dtau, const std::vector<std::vector<double>>& w,
                  int only = -1) {
    for (int k : problem_.peaks()) {
      if (only >= 0 && k != only) continue;
      const double v = Value(problem_.outcomes()[k], t, y);
      if (v > peak_[k].value) {
        peak_[k].value = v;
        peak_[k].derivative = Total(problem_.outcomes()[k], t, y, dtau, w);
      }
    }
  }

  // --- Consistent values and their sensitivities. ---
  // (y, ẏ) of the phase at `state` (t, q, q̇, active, contacts, branches) under `m`: the
  // driver's CompleteHiddenConstraint, then DaeSystem::InitialValues.
  void ConsistentValues(const Model& m, MechanicalState state, double* y, double* yp) {
    CompleteHiddenConstraint(m, &state);
    system_.SetModel(m);
    system_.InitialValues(state, y, yp);
    system_.SetModel(model());
  }
  void InitialSensitivities(const MechanicalState& nominal, std::vector<std::vector<double>>* s,
                            std::vector<std::vector<double>>* sdot);
  void RestartSensitivities(const MechanicalState& state, const std::vector<std::vector<double>>& s_x,
                            std::vector<std::vector<double>>* s, std::vector<std::vector<double>>* sdot);
  double SensitivityResidual(double t, const double* y, const double* yp, const std::vector<std::vector<double>>& s,
                             const std::vector<std::vector<double>>& sdot);

  // --- IDAS callbacks. ---
  static int ResidualFn(double t, N_Vector yy, N_Vector yp, N_Vector rr, void* user) {
    auto* self = static_cast<DaeSensitivity*>(user);
    try {
      return self->system_.Residual(t, NvData(yy), NvData(yp), NvData(rr)) ? 0 : 1;
    } catch (const std::exception& e) {
      self->failure_ = e.what();
      return -1;
    }
  }
  static int JacobianFn(double t, double cj, N_Vector yy, N_Vector yp, N_Vector, SUNMatrix J, void* user, N_Vector,
                        N_Vector, N_Vector) {
    auto* self = static_cast<DaeSensitivity*>(user);
    try {
      return self->system_.Jacobian(t, cj, NvData(yy), NvData(yp), SUNDenseMatrix_Data(J)) ? 0 : 1;
    } catch (const std::exception& e) {
      self->failure_ = e.what();
      return -1;
    }
  }
  static int RootFn(double t, N_Vector yy, N_Vector yp, double* g, void* user) {
    auto* self = static_cast<DaeSensitivity*>(user);
    try {
      self->Roots(t, NvData(yy), NvData(yp), g);
      return 0;
    } catch (const std::exception& e) {
      self->failure_ = e.what();
      return -1;
    }
  }
  static int SensResidualFn(int ns, double t, N_Vector yy, N_Vector yp, N_Vector, N_Vector* yS, N_Vector* ypS,
                            N_Vector* rS, void* user, N_Vector, N_Vector, N_Vector) {
    auto* self = static_cast<DaeSensitivity*>(user);
    try {
      if (!self->PartialDerivatives(t, NvData(yy), NvData(yp))) return 1;
      const int n = self->n_;
      const Eigen::Map<const MatrixXd> Fy(self->Fy_.data(), n, n), Fyp(self->Fyp_.data(), n, n);
      for (int j = 0; j < ns; ++j) {
        Eigen::Map<VectorXd> r(NvData(rS[j]), n);
        r.noalias() = Fy * Eigen::Map<const VectorXd>(NvData(yS[j]), n);
        r.noalias() += Fyp * Eigen::Map<const VectorXd>(NvData(ypS[j]), n);
        r += Eigen::Map<const VectorXd>(self->Fp_.data() + static_cast<size_t>(n) * j, n);
      }
      return 0;
    } catch (const std::exception& e) {
      self->failure_ = e.what();
      return -1;
    }
  }
  // dae's root functions (events with N_i the DAE unknown), then dv/dt of each peak outcome.
  void Roots(double t, const double* y, const double* yp, double* g);
  // F_y, F_ẏ, F_p at (t, y, ẏ), cached for repeated calls at the same state. False when a
  // surface is evaluated outside its domain (IDAS retries with a smaller step).
  bool PartialDerivatives(double t, const double* y, const double* yp);

  Problem& problem_;
  SensitivityOptions options_;
  std::vector<double> p_;
  int np_;
  bool with_s_;
  Scene nominal_;                    // the scene at p (DaeSystem points at its model)
  DaeForm form_;
  std::vector<Scene> plus_, minus_;  // at p ± h_j e_j
  std::vector<double> pbar_, h_;     // |p_j| (1 when 0) and the central-difference steps
  DaeSystem system_;
  SensitivityResult* result_;
  StepControl ida_options_;   // rtol, atol, max_steps for IdaPhase
  Mode mode_;                        // the phase's contacts, branches and events
  int n_ = 0;

  SundialsContext ctx_;  // outlives ida_ (FreePhase in the destructor)
  SundialsMessages messages_;
  std::string failure_;
  IdaPhase ida_;
  N_Vector* yS_ = nullptr;
  N_Vector* ypS_ = nullptr;
  SolverStats stats_;
  long sensitivity_residual_evaluations_ = 0;
  long sensitivity_error_test_failures_ = 0;

  std::vector<double> normal_;  // N per model contact, for the event functions
  std::vector<double> zero_p_;  // dp = 0 of the directional differences along the trajectory
  std::vector<Peak> peak_;

  // The phase: IDAS' time, the full DAE sensitivities s, ṡ; at the last event the (q, u)
  // part s_x, the total derivative w = s_x + ẋ dτ, dτ/dp, ẋ of the old mode and x.
  bool first_phase_ = true;
  double t_ = 0.0;
  std::vector<std::vector<double>> s_, sdot_, s_x_, w_;
  std::vector<double> dtau_, zero_dtau_;
  double f_minus_[kN] = {};
  double event_x_[kN] = {};
  std::vector<double> e_;
  // Cache of PartialDerivatives.
  bool have_partials_ = false;
  double partials_t_ = 0.0;
  std::vector<double> partials_y_, partials_yp_, Fy_, Fyp_, Fp_, r_plus_, r_minus_;
};

void DaeSensitivity::FreePhase() {
  if (ida_.mem != nullptr) {
    long v = 0;
    if (yS_ != nullptr) {
      IDAGetSensNumResEvals(ida_.mem, &v), sensitivity_residual_evaluations_ += v;
      IDAGetSensNumErrTestFails(ida_.mem, &v), sensitivity_error_test_failures_ += v;
    }
    ++stats_.restarts;
  }
  ida_.Free(&stats_, true);
  if (yS_) N_VDestroyVectorArray(yS_, np_), yS_ = nullptr;
  if (ypS_) N_VDestroyVectorArray(ypS_, np_), ypS_ = nullptr;
}

void DaeSensitivity::StartPhase(double t, const std::vector<std::vector<double>>& s,
                                const std::vector<std::vector<double>>& sdot) {
  N_Vector id = NewSerialVector(n_, ctx_);
  N_Vector atol = NewSerialVector(n_, ctx_);
  // Absolute tolerances of the unknowns (dae.cpp, dae_ggl.cpp) and the row scale of the
  // sensitivities' (per unit atol).
  std::vector<double> scale(n_, 1.0);
  for (int i = 0; i < n_; ++i) {
    NvData(id)[i] = system_.IsDifferential(i) ? 1.0 : 0.0;
    const double a = DaeUnknownAtol(form_.ggl, system_, i, options_.atol);  // dae_on_ida.hpp
    if (i >= system_.NormalIndex(0)) scale[i] = kForceAtolScale;
    NvData(atol)[i] = a;
  }
  std::vector<int> peak_directions(problem_.peaks().size(), -1);  // dv/dt falling through 0: a maximum
  ida_.Start(ctx_, n_, &DaeSensitivity::ResidualFn, &DaeSensitivity::JacobianFn, &DaeSensitivity::RootFn, this, t, atol,
             id, ida_options_, nominal_.end.time, mode_.events, "RunSensitivity", &messages_, peak_directions);
  N_VDestroy(id);
  N_VDestroy(atol);
  if (!with_s_) return;
  yS_ = N_VCloneVectorArray(np_, ida_.y);
  ypS_ = N_VCloneVectorArray(np_, ida_.y);
  N_Vector* atolS = N_VCloneVectorArray(np_, ida_.y);
  for (int j = 0; j < np_; ++j) {
    std::copy(s[j].begin(), s[j].end(), NvData(yS_[j]));
    std::copy(sdot[j].begin(), sdot[j].end(), NvData(ypS_[j]));
    // Tolerances of p̄_j s_j as the ede driver's (kSensitivityAtol floor), forces scaled.
    for (int i = 0; i < n_; ++i) NvData(atolS[j])[i] = std::max(options_.atol, kSensitivityAtol) * scale[i] / pbar_[j];
  }
  try {
    Check(IDASensInit(ida_.mem, np_, IDA_STAGGERED, &DaeSensitivity::SensResidualFn, yS_, ypS_), "IDASensInit");
    Check(IDASensSVtolerances(ida_.mem, options_.rtol, atolS), "IDASensSVtolerances");
    Check(IDASetSensErrCon(ida_.mem, SUNTRUE), "IDASetSensErrCon");
  } catch (...) {
    N_VDestroyVectorArray(atolS, np_);
    throw;
  }
  N_VDestroyVectorArray(atolS, np_);
}

bool DaeSensitivity::PartialDerivatives(double t, const double* y, const double* yp) {
  const int n = n_;
  if (have_partials_ && t == partials_t_ && std::equal(y, y + n, partials_y_.begin()) &&
      std::equal(yp, yp + n, partials_yp_.begin())) {
    return true;
  }
  have_partials_ = false;
  if (!system_.Jacobian(t, 0.0, y, yp, Fy_.data())) return false;
  if (!system_.Jacobian(t, 1.0, y, yp, Fyp_.data())) return false;
  for (size_t i = 0; i < Fyp_.size(); ++i) Fyp_[i] -= Fy_[i];
  bool ok = true;
  for (int j = 0; j < np_ && ok; ++j) {
    system_.SetModel(plus_[j].model);
    ok = system_.Residual(t, y, yp, r_plus_.data());
    system_.SetModel(minus_[j].model);
    ok = ok && system_.Residual(t, y, yp, r_minus_.data());
    for (int i = 0; i < n; ++i) Fp_[static_cast<size_t>(n) * j + i] = (r_plus_[i] - r_minus_[i]) / (2.0 * h_[j]);
  }
  system_.SetModel(model());
  if (!ok) return false;
  std::copy(y, y + n, partials_y_.begin());
  std::copy(yp, yp + n, partials_yp_.begin());
  partials_t_ = t;
  have_partials_ = true;
  return true;
}

void DaeSensitivity::Roots(double t, const double* y, const double* yp, double* g) {
  Vector6d q;
  for (int i = 0; i < 6; ++i) q(i) = y[i];
  std::fill(normal_.begin(), normal_.end(), 0.0);
  for (size_t c = 0; c < mode_.active.size(); ++c) normal_[mode_.active[c]] = y[system_.NormalIndex(static_cast<int>(c))];
  EvaluateEvents(model(), mode_.events, q, normal_, g);
  const size_t n_events = mode_.events.size();
  for (size_t k = 0; k < problem_.peaks().size(); ++k) {
    const Outcome& o = problem_.outcomes()[problem_.peaks()[k]];
    // A slack ligament or a separated contact has dv/dt ≡ 0, which the root finder refuses
    // (a root on an interval): −1 there (as in ede).
    if (!(Value(o, t, y) > 0.0)) {
      g[n_events + k] = -1.0;
      continue;
    }
    // Along (1, q̇, u̇) of IDA's ẏ; contact forces: the hidden-constraint force's rate.
    const double rate = Rate(o, t, y, yp);
    g[n_events + k] = rate != 0.0 ? rate : -std::numeric_limits<double>::min();
  }
}

void DaeSensitivity::InitialSensitivities(const MechanicalState& nominal, std::vector<std::vector<double>>* s,
                                          std::vector<std::vector<double>>* sdot) {
  std::vector<double> yp_plus(n_), yp_minus(n_), y_plus(n_), y_minus(n_);
  ConsistentInitOptions init;
  init.form = form_.contact;
  init.chart = FormulationOptions().contact_chart;
  std::vector<int> all;
  for (int i = 0; i < static_cast<int>(model().contacts.size()); ++i) all.push_back(i);
  auto at = [&](const Scene& scene, double* y, double* yp) {
    InitReport report;
    MechanicalState state = ConsistentInitialize(scene.model, scene.initial, all, init, &report);
    state.ligament_branch = nominal.ligament_branch;  // locked to the nominal branches
    if (state.active != nominal.active) {
      Throw<SolverError>("RunSensitivity", "the active contacts at t = 0 change with the parameters: not differentiable");
    }
    ConsistentValues(scene.model, state, y, yp);
  };
  for (int j = 0; j < np_; ++j) {
    at(plus_[j], y_plus.data(), yp_plus.data());
    at(minus_[j], y_minus.data(), yp_minus.data());
    for (int i = 0; i < n_; ++i) {
      (*s)[j][i] = (y_plus[i] - y_minus[i]) / (2.0 * h_[j]);
      (*sdot)[j][i] = (yp_plus[i] - yp_minus[i]) / (2.0 * h_[j]);
    }
  }
}

void DaeSensitivity::RestartSensitivities(const MechanicalState& state, const std::vector<std::vector<double>>& s_x,
                                          std::vector<std::vector<double>>* s, std::vector<std::vector<double>>* sdot) {
  std::vector<double> yp_plus(n_), yp_minus(n_), y_plus(n_), y_minus(n_);
  for (int j = 0; j < np_; ++j) {
    MechanicalState up = state, down = state;
    for (int i = 0; i < 6; ++i) {
      up.q(i) += h_[j] * s_x[j][i], down.q(i) -= h_[j] * s_x[j][i];
      up.qd(i) += h_[j] * s_x[j][6 + i], down.qd(i) -= h_[j] * s_x[j][6 + i];
    }
    ConsistentValues(plus_[j].model, up, y_plus.data(), yp_plus.data());
    ConsistentValues(minus_[j].model, down, y_minus.data(), yp_minus.data());
    for (int i = 0; i < n_; ++i) {
      (*s)[j][i] = (y_plus[i] - y_minus[i]) / (2.0 * h_[j]);
      (*sdot)[j][i] = (yp_plus[i] - yp_minus[i]) / (2.0 * h_[j]);
    }
  }
}

double DaeSensitivity::SensitivityResidual(double t, const double* y, const double* yp,
                                           const std::vector<std::vector<double>>& s,
                                           const std::vector<std::vector<double>>& sdot) {
  if (!PartialDerivatives(t, y, yp)) return kNaN;
  // Row i, parameter j: |r_ij| p̄_j (the residual for a 100 % change of p_j) over the size of
  // the row's terms for a 100 % change of the state and of p_j, Σ_c |F_y,ic y_c| +
  // |F_ẏ,ic ẏ_c| + p̄_j |F_p,ij| — a scale that does not vanish where s_j does (e.g. right
  // after the kink at which a stiffness starts to act, where all of s_j is round-off).
  double worst = 0.0;
  for (int i = 0; i < n_; ++i) {
    double scale = 0.0;
    for (int c = 0; c < n_; ++c) {
      scale += std::abs(Fy_[i + static_cast<size_t>(n_) * c] * y[c]) + std::abs(Fyp_[i + static_cast<size_t>(n_) * c] * yp[c]);
    }
    for (int j = 0; j < np_; ++j) {
      const double fp = Fp_[static_cast<size_t>(n_) * j + i];
      double r = fp;
      for (int c = 0; c < n_; ++c) {
        r += Fy_[i + static_cast<size_t>(n_) * c] * s[j][c] + Fyp_[i + static_cast<size_t>(n_) * c] * sdot[j][c];
      }
      const double size = scale + pbar_[j] * std::abs(fp);
      if (size > 0.0) worst = std::max(worst, pbar_[j] * std::abs(r) / size);
    }
  }
  return worst;
}

void DaeSensitivity::Start(const MechanicalState& state, const std::vector<EventSpec>& specs) {
  mode_.active = state.active;
  mode_.branch = state.ligament_branch;
  mode_.events = specs;
  system_.SetPhase(state.active, state.contact, state.ligament_branch);
  n_ = system_.size();
  for (auto* v : {&partials_y_, &partials_yp_, &r_plus_, &r_minus_}) v->assign(n_, 0.0);
  Fy_.assign(static_cast<size_t>(n_) * n_, 0.0);
  Fyp_.assign(static_cast<size_t>(n_) * n_, 0.0);
  Fp_.assign(static_cast<size_t>(n_) * np_, 0.0);
  have_partials_ = false;

  FreePhase();
  ida_.Reserve(ctx_, n_);
  double* y = NvData(ida_.y);
  double* yp = NvData(ida_.yp);
  system_.InitialValues(state, y, yp);
  for (int j = 0; j < np_; ++j) s_[j].assign(n_, 0.0), sdot_[j].assign(n_, 0.0);
  if (with_s_) {
    if (first_phase_) {
      InitialSensitivities(state, &s_, &sdot_);
    } else {
      // s_x⁺ = s_x⁻ + (ẋ⁻ − ẋ⁺) dτ/dp (Hiskens & Pai 2000, Eq. 9), ẋ⁺ in the new mode at
      // the event state; then the algebraic unknowns re-solved along (s_x⁺, e_j).
      double f_plus[kN];
      problem_.Rhs(mode_, state.t, event_x_, p_.data(), f_plus);
      for (int j = 0; j < np_; ++j) {
        for (int i = 0; i < kN; ++i) s_x_[j][i] += (f_minus_[i] - f_plus[i]) * dtau_[j];
      }
      RestartSensitivities(state, s_x_, &s_, &sdot_);
    }
    result_->initial_sensitivity_residual =
        std::max(result_->initial_sensitivity_residual, SensitivityResidual(state.t, y, yp, s_, sdot_));
  }
  if (first_phase_) {
    Candidates(state.t, y, zero_dtau_, s_);  // t = 0
  } else {
    Candidates(state.t, y, dtau_, w_);  // right limits at the event (e.g. the far side of a kink's force jump)
  }
  first_phase_ = false;
  StartPhase(state.t, s_, sdot_);
  t_ = state.t;
}

AdvanceResult DaeSensitivity::Advance(double t_out, MechanicalState* state) {
  const Model& m = model();
  const std::vector<Outcome>& outcomes = problem_.outcomes();
  const double t_end = nominal_.end.time;
  double* y = NvData(ida_.y);
  double* yp = NvData(ida_.yp);
  // The DAE state as a MechanicalState (FormulationBase::WriteBack).
  auto write_back = [&](MechanicalState* st) {
    st->t = t_;
    for (int i = 0; i < 6; ++i) st->q(i) = y[i], st->qd(i) = y[6 + i], st->qdd(i) = yp[6 + i];
    for (size_t c = 0; c < mode_.active.size(); ++c) {
      ContactGuess& guess = st->contact[mode_.active[c]];
      for (int j = 0; j < system_.per_contact(); ++j) guess.coordinates[j] = y[system_.CoordinateIndex(static_cast<int>(c)) + j];
      guess.normal_force = y[system_.NormalIndex(static_cast<int>(c))];
    }
    if (system_.per_contact() == 0) FillContactCoordinates(m, st);
  };
  auto unit = [&](int j) {
    std::fill(e_.begin(), e_.end(), 0.0);
    e_[j] = 1.0;
    return e_.data();
  };
  const int n_events = static_cast<int>(mode_.events.size());
  const int n_roots = n_events + static_cast<int>(problem_.peaks().size());
  std::vector<int> fired(n_roots, 0);
  for (;;) {
    failure_.clear();
    double t_reached = t_;
    // dae_ggl.cpp: outputs are steps, with no sliver of a step before them (ida_phase.hpp).
    const int flag = form_.ggl ? ida_.SolveToStopTime(t_out, &t_reached)
                               : ida_.Solve(t_out, &t_reached);
    if (flag < 0) {
      Throw<SolverError>("RunSensitivity", "IDAS ", ida_.SolveFailure(flag),
                         failure_.empty() ? "" : " (" + failure_ + ")", messages_.Take());
    }
    t_ = t_reached;
    if (with_s_) {
      double ts = 0.0;
      Check(IDAGetSens(ida_.mem, &ts, yS_), "IDAGetSens");
      for (int j = 0; j < np_; ++j) std::copy(NvData(yS_[j]), NvData(yS_[j]) + n_, s_[j].begin());
    }
    if (flag != IDA_ROOT_RETURN) {  // an output time, or the end time
      write_back(state);
      if (!(t_ < t_end)) {
        result_->end_reason = "end_time";
        Candidates(t_, y, zero_dtau_, s_);
      }
      return {};
    }
    Check(IDAGetRootInfo(ida_.mem, fired.data()), "IDAGetRootInfo");
    // Interior maxima (dv/dt = 0): envelope theorem, dV/dp = ∂v/∂y s + ∂v/∂p.
    for (size_t k = 0; k < problem_.peaks().size(); ++k) {
      if (fired[n_events + k]) Candidates(t_, y, zero_dtau_, s_, problem_.peaks()[k]);
    }
    int first = -1;
    for (int k = 0; k < n_events && first < 0; ++k) {
      if (fired[k]) first = k;
    }
    if (first < 0) continue;  // only peaks: IDAS continues the same phase

    // An event at τ(p): g(τ, y(τ; p), p) = 0 (implicit-function relation).
    const double t = t_;
    problem_.Rhs(mode_, t, y, p_.data(), f_minus_);  // ẋ⁻ = (q̇, q̈) of the old mode
    std::copy(y, y + kN, event_x_);
    const EventSpec& g_event = mode_.events[first];
    if (with_s_) {
      // g of solver/events.hpp on x = (q, u) (lift-off: the hidden-constraint force, whose
      // root is the DAE's N_i = 0 to the integration error).
      auto g = [&](double tt, const double* yy, const double* pv) { return problem_.Event(mode_, first, tt, yy, pv); };
      const double gdot = problem_.Directional(g, t, y, p_.data(), 1.0, f_minus_, zero_p_.data());
      if (!(std::abs(gdot) > 0.0)) {
        Throw<SolverError>("RunSensitivity", "event ", g_event.name, " at t = ", t,
                           " s is tangential (dg/dt = ", gdot, "): its time is not differentiable in p");
      }
      for (int j = 0; j < np_; ++j) {
        dtau_[j] = -problem_.Directional(g, t, y, p_.data(), 0.0, s_[j].data(), unit(j)) / gdot;
        for (int i = 0; i < kN; ++i) {
          s_x_[j][i] = s_[j][i];
          w_[j][i] = s_[j][i] + f_minus_[i] * dtau_[j];
        }
      }
    } else {
      std::fill(dtau_.begin(), dtau_.end(), kNaN);
    }
    std::vector<int> next_active = mode_.active;  // the simulator switches the contacts
    std::vector<double> dalpha(np_, kNaN);
    for (int j = 0; j < np_ && with_s_; ++j) dalpha[j] = w_[j][kAlpha];
    const bool done = RecordEvent(mode_, fired, t, y[kAlpha], dtau_, dalpha, with_s_, outcomes, &next_active, result_);
    // 90° values, in the mode before the end event (left limits); a scene ending at another
    // flexion has none.
    for (size_t k = 0; k < outcomes.size() && done && result_->end_reason == Flexion90EventName(); ++k) {
      const Outcome& o = outcomes[k];
      if (o.kind == OutcomeKind::kLigamentAt90 || o.kind == OutcomeKind::kContactAt90) {
        result_->values[k] = Value(o, t, y);
        result_->derivatives[k] = Total(o, t, y, dtau_, w_);
      }
    }
    Candidates(t, y, dtau_, w_);
    write_back(state);
    AdvanceResult result;
    result.status = AdvanceStatus::kEvent;
    for (int k = 0; k < n_events; ++k) {
      if (fired[k]) result.events.push_back(k);
    }
    return result;
  }
}

void DaeSensitivity::Run() {
  peak_.assign(problem_.outcomes().size(), Peak());
  s_.assign(np_, {});
  sdot_.assign(np_, {});
  s_x_.assign(np_, std::vector<double>(kN, 0.0));
  w_.assign(np_, std::vector<double>(kN, 0.0));
  dtau_.assign(np_, 0.0);
  zero_dtau_.assign(np_, 0.0);
  e_.assign(np_, 0.0);
  first_phase_ = true;

  SimulatorSettings sim = TrajectorySettings(
      nominal_, options_, with_s_, np_, [this](int j) -> Vector6d { return Eigen::Map<const Vector6d>(s_[j].data()); },
      result_);
  sim.init.form = form_.contact;
  sim.init.chart = FormulationOptions().contact_chart;
  sim.restart = RestartProjection::kProject;  // as kneedyn run; RestartSensitivities differentiates it
  RunResult record;
  Simulator simulator(nominal_, this, sim, &record);
  simulator.Initialize();
  simulator.Run();
  FreePhase();
  for (int k : problem_.peaks()) {
    result_->values[k] = peak_[k].value;
    result_->derivatives[k] = peak_[k].derivative;
  }
  result_->stats = stats_;
  result_->sensitivity_rhs_evaluations = sensitivity_residual_evaluations_;
  result_->sensitivity_error_test_failures = sensitivity_error_test_failures_;
}

}  // namespace

void RunDaeSensitivity(Problem& problem, const std::vector<double>& values, const SensitivityOptions& options,
                       SensitivityResult* result) {
  DaeSensitivity run(problem, values, options, result);
  run.Run();
}

}  // namespace kneedyn::sensitivity::detail
