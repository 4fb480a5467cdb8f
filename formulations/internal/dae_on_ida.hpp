// The IDA driver of a DAE system (IdaDriver below), shared by `dae`/`dae-reduced` (dae.cpp),
// `dae-ggl`/`dae-ggl-reduced` (dae_ggl.cpp) on formulations/internal/dae_system.hpp and by
// `monolithic`/`monolithic-ggl` (monolithic.cpp) on formulations/internal/monolithic_system.hpp;
// what differs between the variants is declared here.
#pragma once

#include <idas/idas.h>
#include <sunmatrix/sunmatrix_dense.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "formulations/formulation.hpp"
#include "formulations/internal/dae_system.hpp"
#include "formulations/internal/formulation_base.hpp"
#include "formulations/internal/ida_phase.hpp"
#include "formulations/internal/sundials_util.hpp"
#include "solver/events.hpp"

namespace kneedyn {

struct DaeOnIdaVariant {
  const char* name;  // the formulation's name, in messages
  // Gear–Gupta–Leimkuhler stabilized form (dae_system.hpp); it also stops IDA at every output
  // time (outputs are step values, on which both constraint levels hold), with no sliver of a
  // step before it (IdaPhase::SolveToStopTime).
  bool ggl;
};

// Absolute tolerance of unknown i in IDA's Newton test (dae.cpp, dae_ggl.cpp; also the IDAS
// sensitivities, so that their phases take the formulations' steps). The index-2 unknowns
// (N, newtons, and GGL's μ, m/s: every unknown from NormalIndex(0) on) carry round-off of
// order ε/h² in Newton corrections; they get kForceAtolScale (formulation.hpp) per unit
// --atol, floored at kGglIndexTwoAtolFloor for GGL (dae_ggl.cpp's header comment says why)
// and at IndexTwoAtolFloor for the plain index-2 forms: N's round-off ε·M·|q|/h² ≈
// 2.2e-16 · 4 kg · 0.2 m / (1.2e-5 s)² ≈ 1.2e-6 N on a restart's first step at rtol 1e-12 on
// the chapter scene. Without it, --atol < 1e-10 asked N to converge below that, and dae
// failed at rtol ≤ 3.2e-12 after a restart (benchmarks/README.md, "Work-precision sweep",
// has the digits gained). At --atol ≥ 1e-10 it changes nothing on the chapter's knee.
constexpr double kGglIndexTwoAtolFloor = 1.0e-3;
constexpr double kIndexTwoAtolFloor = 1.0e-6;  // N, for elements as stiff as the chapter's
// Stiffer elements shrink the steps at a given accuracy (h ∝ √(M/K)), so the round-off
// ε·M·|q|/h² grows like ε·|q|·K: the floor scales with the elements' total linear stiffness
// K = Σ k_linear over kFloorStiffness, 720 N/mm, just above the chapter's 713.15 N/mm
// (Table 1.2), whose scenes keep 1e-6 N. With 100-fold stiffness (hard/stiff_ligaments_100x,
// floor 9.9e-5 N), dae at rtol 1e-12 --atol 1e-14 and dae-reduced at rtol 1e-13 failed to
// converge with 1e-6 N and complete with any floor from 1e-5 to 1e-3 N.
constexpr double kFloorStiffness = 720.0e3;  // N/m
inline double IndexTwoAtolFloor(const Model& model) {
  double stiffness = 0.0;  // N/m
  for (const Ligament& ligament : model.ligaments) stiffness += ligament.k_linear;
  return kIndexTwoAtolFloor * std::max(1.0, stiffness / kFloorStiffness);
}
inline double DaeUnknownAtol(bool ggl, const DaeSystem& system, int i, double atol) {
  if (i < system.NormalIndex(0)) return atol;
  return std::max(ggl ? kGglIndexTwoAtolFloor : IndexTwoAtolFloor(system.model()), atol * kForceAtolScale);
}

// The options of dae, dae-reduced, dae-ggl and dae-ggl-reduced, typed and checked.
struct IdaOptions {
  StepControl control;  // IDA's tolerances, step cap and step budget
  ConstraintLevel constraint_level = ConstraintLevel::kVelocity;  // dae: index 2 | index-3 variant
  JacobianKind jacobian = JacobianKind::kExact;                    // the iteration matrix
  LinearSolverKind linear_solver = LinearSolverKind::kStructured;  // its factorization
};
// Reads them from a request (dae.cpp); the registry line's capabilities have been checked,
// and these formulations have no rule of their own beyond them.
bool ReadIdaOptions(const OptionRequest& request, IdaOptions* options);

// The IDA driver of a DAE system, one class for `dae`, `dae-reduced`, `dae-ggl`,
// `dae-ggl-reduced` (System = DaeSystem) and `monolithic`, `monolithic-ggl` (System =
// MonolithicSystem, formulations/monolithic.cpp). The system supplies the interface of
// DaeSystem: SetPhase, size, IsDifferential, InitialValues(state, y, ẏ), Residual,
// Jacobian, JacobianByJets, UnknownName, NormalIndex, per_contact. The driver owns the IDA
// phase (ida_phase.hpp), the callbacks, the failure message and the statistics; a system
// with root functions of its own (the monolithic DAE's patellar facets) overrides the
// virtual hooks below. A new phase starts IDA from the simulator's consistent state:
// IDAReInit when the phase has as many unknowns as the last one, else IDA rebuilt at the
// new size (IDAReInit cannot change it); IDACalcIC is not used (index 1 only).
template <class System>
class IdaDriver : public FormulationBase {
 public:
  template <typename... SystemArgs>
  IdaDriver(const Scene& scene, const IdaOptions& options, ContactForm form, const DaeOnIdaVariant& variant,
            SystemArgs&&... system_args)
      : FormulationBase(scene),
        options_(options),
        form_(form),
        variant_(variant),
        system_(std::forward<SystemArgs>(system_args)...) {}
  ~IdaDriver() override { Free(); }

  ContactForm contact_form() const override { return form_; }

  void Start(const MechanicalState& state, const std::vector<EventSpec>& events) override {
    // The last phase's counters are banked; its IDA objects are re-initialized when this
    // phase has as many unknowns (ida_phase.hpp), else replaced.
    ida_.EndPhase(&finished_phases_, watches_roots_);
    BeginPhase(state, events);
    system_.SetPhase(active_, state.contact, ligament_branch_);
    n_ = system_.size();
    normal_.assign(model_.contacts.size(), 0.0);
    extra_root_directions_ = ExtraRootDirections();
    watches_roots_ = !events_.empty() || !extra_root_directions_.empty();
    root_flags_.assign(events_.size() + extra_root_directions_.size(), 0);

    ida_.Reserve(ctx_, n_);
    if (hot_path_r_ != nullptr && N_VGetLength(hot_path_r_) != n_) { N_VDestroy(hot_path_r_); hot_path_r_ = nullptr; }
    if (hot_path_r_ == nullptr) hot_path_r_ = NewSerialVector(n_, ctx_);
    hot_path_g_.assign(root_flags_.size(), 0.0);
    t_ = state.t;
    N_Vector id = NewSerialVector(n_, ctx_);
    N_Vector atol = NewSerialVector(n_, ctx_);
    system_.InitialValues(state, NvData(ida_.y), NvData(ida_.yp));  // μ = 0 on the exact solution
    double* idp = NvData(id);
    double* at = NvData(atol);
    for (int i = 0; i < n_; ++i) {
      idp[i] = system_.IsDifferential(i) ? 1.0 : 0.0;
      at[i] = UnknownAtol(i);
    }
    ida_.Start(ctx_, n_, &IdaDriver::Residual,
               options_.jacobian == JacobianKind::kDifferenceQuotient ? nullptr : &IdaDriver::Jacobian,
               &IdaDriver::Roots, this, state.t, atol, id, options_.control, scene_.end.time, events_, variant_.name,
               &sundials_messages_, extra_root_directions_, options_.linear_solver,
               PulseResolvingStep(scene_.model, state.t));
    N_VDestroy(id);
    N_VDestroy(atol);
    ++finished_phases_.restarts;
    advanced_ = false;
  }

  AdvanceResult Advance(double t_out, MechanicalState* state) override {
    double t_reached = state->t;
    failure_.clear();
    // GGL stops at t_out instead of interpolating to it: outputs are step values, on which
    // the position and velocity constraints hold to the Newton tolerance; no sliver of a step
    // before it (IdaPhase::SolveToStopTime).
    const int flag = variant_.ggl ? ida_.SolveToStopTime(std::min(t_out, scene_.end.time), &t_reached)
                                  : ida_.Solve(t_out, &t_reached);
    AdvanceResult result;
    if (flag < 0) {
      const std::string function = SolveFunctionName();
      Throw<SolverError>(function.c_str(), ida_.SolveFailure(flag), failure_.empty() ? "" : " (" + failure_ + ")",
                         LargestErrorComponent(), sundials_messages_.Take());
    }
    t_ = t_reached;
    advanced_ = true;
    const double* y = NvData(ida_.y);
    const double* yp = NvData(ida_.yp);
    WriteBack(t_reached, Eigen::Map<const Vector6d>(y), Eigen::Map<const Vector6d>(y + 6),
              Eigen::Map<const Vector6d>(yp + 6), y + system_.NormalIndex(0), y + 12, system_.per_contact(), state);
    if (flag == IDA_ROOT_RETURN) {
      Check(IDAGetRootInfo(ida_.mem, root_flags_.data()), "IDAGetRootInfo");
      result = RootResult(t_reached);
    }
    return result;
  }

  std::string integrator() const override { return "ida"; }  // variable-order BDF, adaptive

  SolverStats PhaseStats() const override {
    return ida_.mem != nullptr && !ida_.counted ? IdaStatistics(ida_.mem, watches_roots_) : SolverStats();
  }

  // The residual, Jacobian (cj = 1e4 1/s) and root callbacks IDA calls, at the current y, ẏ.
  bool EvaluateHotPathForTesting(int n) override {
    if (ida_.mem == nullptr) return false;
    for (int i = 0; i < n; ++i) {
      if (Residual(t_, ida_.y, ida_.yp, hot_path_r_, this) != 0) return false;
      SUNMatZero(ida_.A);  // as idaLsSetup does before the Jacobian callback
      if (Jacobian(t_, 1.0e4, ida_.y, ida_.yp, hot_path_r_, ida_.A, this, nullptr, nullptr, nullptr) != 0) return false;
      if (watches_roots_ && Roots(t_, ida_.y, ida_.yp, hot_path_g_.data(), this) != 0) return false;
    }
    return true;
  }

 protected:
  // Hooks of a system with more than DaeSystem's (the monolithic DAE's patella).
  // Absolute tolerance of unknown i in IDA's Newton test: DaeUnknownAtol above, or the
  // system's overload (monolithic.cpp), found by argument-dependent lookup.
  double UnknownAtol(int i) const { return DaeUnknownAtol(variant_.ggl, system_, i, options_.control.atol); }
  // Directions of root functions after the phase's events, evaluated by EvaluateRoots.
  virtual std::vector<int> ExtraRootDirections() const { return {}; }
  // g of the phase's events (solver/events.hpp), then of the extra roots, at unknowns y.
  virtual void EvaluateRoots(const double* y, double* g) {
    Vector6d q;
    for (int i = 0; i < 6; ++i) q(i) = y[i];
    std::fill(normal_.begin(), normal_.end(), 0.0);
    for (size_t c = 0; c < active_.size(); ++c) normal_[active_[c]] = y[system_.NormalIndex(static_cast<int>(c))];
    EvaluateEvents(scene_.model, events_, q, normal_, g);
  }
  // The result of a root return at t (s), root_flags_ filled: the phase's events that fired.
  virtual AdvanceResult RootResult(double /*t*/) { return EventResult(root_flags_); }
  // The function IDASolve failures name: dae's and dae-reduced's keep the plain prefix, GGL
  // failures name their formulation (dae-ggl or dae-ggl-reduced).
  virtual std::string SolveFunctionName() const {
    return variant_.ggl ? StrCat("IDASolve (", variant_.name, ")") : std::string("IDASolve");
  }

  // Which unknown IDA's failure is about — the component with the largest
  // weighted local error estimate |e_i| w_i (IDAGetEstLocalErrors, IDAGetErrWeights) among
  // the differential unknowns. The algebraic ones are out of the error test
  // (IDASetSuppressAlg), and their estimates, round-off ∝ 1/h² for N, are not what failed it.
  // With it, RoundOffNote: whether that unknown's tolerance was near round-off.
  std::string LargestErrorComponent() const {
    N_Vector e = N_VClone(ida_.y), w = N_VClone(ida_.y);
    std::string out;
    if (IDAGetEstLocalErrors(ida_.mem, e) == IDA_SUCCESS && IDAGetErrWeights(ida_.mem, w) == IDA_SUCCESS) {
      const double* ed = NvData(e);
      const double* wd = NvData(w);
      int worst = 0;
      for (int i = 1; i < n_; ++i) {
        if (system_.IsDifferential(i) && std::abs(ed[i] * wd[i]) > std::abs(ed[worst] * wd[worst])) worst = i;
      }
      out = StrCat("; largest weighted local error estimate: ", system_.UnknownName(worst), " (",
                   std::abs(ed[worst] * wd[worst]), " of the tolerance)", RoundOffNote(worst, 1.0 / wd[worst]));
    }
    N_VDestroy(e);
    N_VDestroy(w);
    return out;
  }

  // A tolerance within kRoundOffMargin of round-off: unknown `i` (q or u) had the tolerance
  // `tolerance` = rtol |y_i| + atol_i, while the Newton systems give its group (q: the six
  // coordinates, m and rad; u: the six rates) to ε · max |y_j| of the group at best (LU
  // solutions are accurate relative to the solution's norm, not per component, and the
  // index-2 Newton matrix's condition grows like 1/h²; the ODE forms complete there). At rtol
  // 1e-13 with --atol 1e-15 the rates' ε max |u| is 1.4e-15 to 4.5e-15 on the shipped scenes
  // (rates up to 1-20 rad/s), and the IDA forms failed on five of them, h shrinking to 1e-15 s;
  // --atol 1e-14 completes them (README.md, "Running"). Empty otherwise.
  std::string RoundOffNote(int i, double tolerance) const {
    constexpr double kRoundOffMargin = 10.0;
    const int first = i < 6 ? 0 : 6;
    if (i >= 12) return "";
    const double* y = NvData(ida_.y);
    double largest = 0.0;
    for (int j = first; j < first + 6; ++j) largest = std::max(largest, std::abs(y[j]));
    const double round_off = DBL_EPSILON * largest;
    if (!(tolerance < kRoundOffMargin * round_off)) return "";
    return StrCat("; its tolerance rtol |y| + atol = ", tolerance, " is within ", kRoundOffMargin,
                  " times the round-off of ", first == 0 ? "q" : "u", " (eps max |", first == 0 ? "q" : "u", "| = ",
                  round_off, "): double precision may not resolve it; a larger --atol may let IDA converge");
  }

  void Check(int flag, const char* call) {
    CheckSundials(flag, call, variant_.name, IDAGetReturnFlagName, &sundials_messages_);
  }

  IdaOptions options_;
  ContactForm form_;
  DaeOnIdaVariant variant_;
  SundialsContext ctx_;
  System system_;  // unknowns, residual, Jacobian
  IdaPhase ida_;   // IDA memory, y, ẏ, matrix and linear solver of the phase
  int n_ = 0;
  double t_ = 0.0;         // s: time of the phase's y, ẏ (phase start or last Advance)
  bool advanced_ = false;  // y is the state of an Advance (not of a Start)
  std::vector<double> normal_;  // N per model contact, for the root functions
  std::vector<int> root_flags_;  // the phase's events, then the extra roots

 private:
  static int Residual(double t, N_Vector yy, N_Vector yp, N_Vector rr, void* user) {
    auto* self = static_cast<IdaDriver*>(user);
    try {
      return self->system_.Residual(t, NvData(yy), NvData(yp), NvData(rr)) ? 0 : 1;
    } catch (const std::exception& e) {
      self->failure_ = e.what();
      return -1;
    }
  }

  // dF/dy + cj dF/dẏ straight into IDA's column-major dense matrix, which idaLsSetup has
  // just zeroed (SUNMatZero before every call with a direct linear solver).
  static int Jacobian(double t, double cj, N_Vector yy, N_Vector yp, N_Vector, SUNMatrix JJ, void* user, N_Vector,
                      N_Vector, N_Vector) {
    auto* self = static_cast<IdaDriver*>(user);
    try {
      double* J = SUNDenseMatrix_Data(JJ);
      const bool ok = self->options_.jacobian == JacobianKind::kJet
                          ? self->system_.JacobianByJets(t, cj, NvData(yy), NvData(yp), J)
                          : self->system_.Jacobian(t, cj, NvData(yy), NvData(yp), J, /*J_is_zero=*/true);
      return ok ? 0 : 1;
    } catch (const std::exception& e) {
      self->failure_ = e.what();
      return -1;
    }
  }

  static int Roots(double, N_Vector yy, N_Vector, double* g, void* user) {
    auto* self = static_cast<IdaDriver*>(user);
    try {
      self->EvaluateRoots(NvData(yy), g);
      return 0;
    } catch (const std::exception& e) {
      self->failure_ = e.what();
      return -1;
    }
  }

  void Free() {
    ida_.Free(&finished_phases_, watches_roots_);
    if (hot_path_r_) { N_VDestroy(hot_path_r_); hot_path_r_ = nullptr; }
  }

  std::vector<int> extra_root_directions_;
  bool watches_roots_ = false;      // IDARootInit was called for the phase
  N_Vector hot_path_r_ = nullptr;   // residual of EvaluateHotPathForTesting
  std::vector<double> hot_path_g_;  // root values of EvaluateHotPathForTesting
  mutable std::string failure_;
  SundialsMessages sundials_messages_;  // SUNDIALS' error text, for the failure reason
};

std::unique_ptr<Formulation> CreateDaeOnIda(const Scene& scene, const IdaOptions& options,
                                            ContactForm form, const DaeOnIdaVariant& variant);

}  // namespace kneedyn
