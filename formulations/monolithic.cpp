// `monolithic` and `monolithic-ggl`: the chapter's monolithic DAE of the knee with its
// patella (§1.7; docs/model.md §12, "The monolithic DAE") on SUNDIALS IDA. The tibia's
// index-2 DAE of `dae` (or its GGL form, `dae-ggl`) and the massless patella's 17 equations
// are one system: the patella's unknowns x (six patello-femoral coordinates, 2 × 4 facet
// chart coordinates, two facet-force ratios λ and the tendon ratio τ_t) are algebraic
// variables of IDA, and the tendon force F_t = τ_t F_Q(t) (Eq. 1.63) pulls the tibia from
// them: no Newton solve of the patella inside the residual (which is what `dae` and `ede`
// do). System: formulations/internal/monolithic_system.hpp; 39 unknowns with both tibial
// contacts (the chapter's 33 without the tibia's 6 velocities), 41 for GGL.
//
// IDA settings, as dae.cpp's: IDASetId (q, u differential; c, N, μ and the patella's x
// algebraic) with IDASetSuppressAlg, which excludes every algebraic unknown from the local
// error test: N (and μ) because their BDF error is not O(h^{p+1}) at index 2, x because it
// is a function of q (index 1) whose accuracy follows from q's. Tolerances: those of dae /
// dae-ggl for the tibia (DaeUnknownAtol), --atol for x (m, rad, chart units and force
// ratios: all O(0.01–1) in SI). Jacobian dF/dy + cj dF/dẏ exact (the tibia's blocks of
// dae_system.hpp plus the coupling blocks as a Jet over (q, x)); --jacobian jet: the JetD
// derivative of the whole residual; difference-quotient: IDA's own. Consistent start: the
// simulator's consistent tibial state (its tendon force from SolvePatella) and x from
// SolvePatella at the same tibial pose, so the residual vanishes at t0 to round-off.
//
// Events: those of dae (lift-off, re-contact, 90°, ligament branches), plus one root
// function per patellar facet, g = λ_i: a facet force that changes sign means the facet
// lifts off, which this model does not handle: SolverError naming the facet and the time.
#include <idas/idas.h>
#include <sunlinsol/sunlinsol_dense.h>
#include <sunmatrix/sunmatrix_dense.h>

#include <algorithm>
#include <cmath>
#include <memory>

#include "formulations/internal/dae_on_ida.hpp"
#include "formulations/internal/formulation_base.hpp"
#include "formulations/internal/ida_phase.hpp"
#include "formulations/internal/monolithic_system.hpp"
#include "formulations/internal/sundials_util.hpp"

namespace kneedyn {
namespace {

// The facet roots' directions: either sign change.
const std::vector<int> kFacetRootDirections = {0, 0};

class MonolithicOnIda final : public FormulationBase {
 public:
  MonolithicOnIda(const Scene& scene, const IdaOptions& options, const DaeOnIdaVariant& variant)
      : FormulationBase(scene),
        options_(options),
        variant_(variant),
        system_(RequirePatella(scene, variant.name), options.constraint_level, variant.ggl) {}
  ~MonolithicOnIda() override { Free(); }

  ContactForm contact_form() const override { return ContactForm::kChapter; }

  void Start(const MechanicalState& state, const std::vector<EventSpec>& events) override {
    Free();
    BeginPhase(state, events);
    system_.SetPhase(active_, state.contact, ligament_branch_);
    n_ = system_.size();
    normal_.assign(model_.contacts.size(), 0.0);
    root_flags_.assign(events_.size() + kFacetRootDirections.size(), 0);
    ida_.y = NewSerialVector(n_, ctx_);
    ida_.yp = NewSerialVector(n_, ctx_);
    hot_path_r_ = NewSerialVector(n_, ctx_);
    hot_path_g_.assign(root_flags_.size(), 0.0);
    t_ = state.t;
    N_Vector id = NewSerialVector(n_, ctx_);
    N_Vector atol = NewSerialVector(n_, ctx_);
    system_.InitialValues(state, &guess_, NvData(ida_.y), NvData(ida_.yp));
    double* idp = NvData(id);
    double* at = NvData(atol);
    const int nt = system_.tibia_size();
    for (int i = 0; i < n_; ++i) {
      idp[i] = system_.IsDifferential(i) ? 1.0 : 0.0;
      at[i] = i < nt ? DaeUnknownAtol(variant_.ggl, system_.tibia(), i, options_.control.atol) : options_.control.atol;
    }
    ida_.Start(ctx_, n_, &MonolithicOnIda::Residual,
               options_.jacobian == JacobianKind::kDifferenceQuotient ? nullptr : &MonolithicOnIda::Jacobian,
               &MonolithicOnIda::Roots, this, state.t, atol, id, options_.control, scene_.end.time, events_,
               variant_.name, &sundials_messages_, kFacetRootDirections);
    N_VDestroy(id);
    N_VDestroy(atol);
    ++finished_phases_.restarts;
    advanced_ = false;
  }

  AdvanceResult Advance(double t_out, MechanicalState* state) override {
    double t_reached = state->t;
    failure_.clear();
    if (variant_.ggl) Check(IDASetStopTime(ida_.mem, std::min(t_out, scene_.end.time)), "IDASetStopTime");
    const int flag = IDASolve(ida_.mem, t_out, &t_reached, ida_.y, ida_.yp, IDA_NORMAL);
    if (flag < 0) {
      Throw<SolverError>(StrCat("IDASolve (", variant_.name, ")").c_str(), ida_.SolveFailure(flag),
                         failure_.empty() ? "" : " (" + failure_ + ")", LargestErrorComponent(),
                         sundials_messages_.Take());
    }
    t_ = t_reached;
    advanced_ = true;
    const double* y = NvData(ida_.y);
    const double* yp = NvData(ida_.yp);
    WriteBack(t_reached, Eigen::Map<const Vector6d>(y), Eigen::Map<const Vector6d>(y + 6),
              Eigen::Map<const Vector6d>(yp + 6), y + system_.tibia().NormalIndex(0), y + 12,
              system_.tibia().per_contact(), state);
    AdvanceResult result;
    if (flag == IDA_ROOT_RETURN) {
      Check(IDAGetRootInfo(ida_.mem, root_flags_.data()), "IDAGetRootInfo");
      for (size_t i = 0; i < kFacetRootDirections.size(); ++i) {
        if (root_flags_[events_.size() + i] == 0) continue;
        Throw<SolverError>(variant_.name, "the ", i == 0 ? "medial" : "lateral",
                           " patellar facet's force ratio lambda changes sign at t = ", t_reached,
                           " s: the facet lifts off, which the monolithic DAE does not model (both facets stay in "
                           "contact; docs/model.md §12)");
      }
      result = EventResult(std::vector<int>(root_flags_.begin(), root_flags_.begin() + events_.size()));
    }
    return result;
  }

  std::string integrator() const override { return "ida"; }  // variable-order BDF, adaptive

  SolverStats PhaseStats() const override {
    return ida_.mem != nullptr ? IdaStatistics(ida_.mem, true) : SolverStats();
  }

  bool EvaluateHotPathForTesting(int n) override {
    if (ida_.mem == nullptr) return false;
    for (int i = 0; i < n; ++i) {
      if (Residual(t_, ida_.y, ida_.yp, hot_path_r_, this) != 0) return false;
      if (Jacobian(t_, 1.0e4, ida_.y, ida_.yp, hot_path_r_, ida_.A, this, nullptr, nullptr, nullptr) != 0) return false;
      if (Roots(t_, ida_.y, ida_.yp, hot_path_g_.data(), this) != 0) return false;
    }
    return true;
  }

  // The patella's unknowns at the end of the last Advance (monolithic_system.hpp test hook).
  bool PatellaUnknowns(std::array<double, kPatellaUnknowns>* x) const {
    if (!advanced_ || ida_.y == nullptr) return false;
    const double* y = NvData(ida_.y);
    for (int i = 0; i < kPatellaUnknowns; ++i) (*x)[i] = y[system_.PatellaIndex(i)];
    return true;
  }

 private:
  static const Model& RequirePatella(const Scene& scene, const char* name) {
    if (!scene.model.patella) {
      Throw<InputError>(name, "scene '", scene.name,
                        "' has no patella: section; the monolithic DAE couples the tibia to the patella "
                        "(docs/model.md §12): use a scene with one, e.g. patellofemoral_impact.yaml");
    }
    return scene.model;
  }

  // The unknown with the largest weighted local error estimate, for a failure message.
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

  static int Residual(double t, N_Vector yy, N_Vector yp, N_Vector rr, void* user) {
    auto* self = static_cast<MonolithicOnIda*>(user);
    try {
      return self->system_.Residual(t, NvData(yy), NvData(yp), NvData(rr)) ? 0 : 1;
    } catch (const std::exception& e) {
      self->failure_ = e.what();
      return -1;
    }
  }

  static int Jacobian(double t, double cj, N_Vector yy, N_Vector yp, N_Vector, SUNMatrix JJ, void* user, N_Vector,
                      N_Vector, N_Vector) {
    auto* self = static_cast<MonolithicOnIda*>(user);
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

  // The phase's events (solver/events.hpp), then λ_medial, λ_lateral.
  static int Roots(double, N_Vector yy, N_Vector, double* g, void* user) {
    auto* self = static_cast<MonolithicOnIda*>(user);
    try {
      const double* y = NvData(yy);
      const Vector6d q = Eigen::Map<const Vector6d>(y);
      std::fill(self->normal_.begin(), self->normal_.end(), 0.0);
      for (size_t c = 0; c < self->active_.size(); ++c) {
        self->normal_[self->active_[c]] = y[self->system_.tibia().NormalIndex(static_cast<int>(c))];
      }
      if (!self->events_.empty()) EvaluateEvents(self->scene_.model, self->events_, q, self->normal_, g);
      for (size_t i = 0; i < kFacetRootDirections.size(); ++i) {
        g[self->events_.size() + i] = y[self->system_.PatellaIndex(kPatellaFacetRatio + static_cast<int>(i))];
      }
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
    ida_.Free(&finished_phases_, true);
    if (hot_path_r_) { N_VDestroy(hot_path_r_); hot_path_r_ = nullptr; }
  }

  IdaOptions options_;
  DaeOnIdaVariant variant_;
  SundialsContext ctx_;
  MonolithicSystem system_;  // unknowns, residual, Jacobian (monolithic_system.hpp)
  PatellaGuess guess_;       // the patella's last equilibrium: warm start of the next phase's x
  double t_ = 0.0;           // s: time of the phase's y, ẏ (phase start or last Advance)
  bool advanced_ = false;    // y is the state of an Advance (not of a Start)
  N_Vector hot_path_r_ = nullptr;
  std::vector<double> hot_path_g_;
  IdaPhase ida_;
  int n_ = 0;
  mutable std::string failure_;
  SundialsMessages sundials_messages_;
  std::vector<double> normal_;  // N per model contact, for the root functions
  std::vector<int> root_flags_;
};

constexpr DaeOnIdaVariant kMonolithic = {"monolithic", false};
constexpr DaeOnIdaVariant kMonolithicGgl = {"monolithic-ggl", true};

}  // namespace

FormulationMaker ConfigureMonolithic(const OptionRequest& request) {
  IdaOptions options;
  if (!ReadIdaOptions(request, &options)) return nullptr;
  return [options](const Scene& scene) { return std::make_unique<MonolithicOnIda>(scene, options, kMonolithic); };
}
FormulationMaker ConfigureMonolithicGgl(const OptionRequest& request) {
  IdaOptions options;
  if (!ReadIdaOptions(request, &options)) return nullptr;
  return [options](const Scene& scene) { return std::make_unique<MonolithicOnIda>(scene, options, kMonolithicGgl); };
}

bool MonolithicPatellaUnknownsForTesting(const Formulation& formulation, std::array<double, kPatellaUnknowns>* x) {
  const auto* monolithic = dynamic_cast<const MonolithicOnIda*>(&formulation);
  return monolithic != nullptr && monolithic->PatellaUnknowns(x);
}

}  // namespace kneedyn
