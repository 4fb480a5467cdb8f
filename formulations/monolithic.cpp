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
// The IDA driver is dae's (IdaDriver, formulations/internal/dae_on_ida.hpp); this file adds
// the patella's tolerances and root functions. IDA settings, as dae.cpp's: IDASetId (q, u differential; c, N, μ and the patella's x
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
// Events: those of dae (lift-off, re-contact, 90°, ligament branches). Without the scene's
// patella.facet_liftoff, plus one root function per patellar facet, g = λ_i (the unknown):
// a facet force that changes sign means the facet would pull, which both-facet contact
// does not allow: SolverError naming the facet and the time. With facet_liftoff, the
// patellar events of every formulation (solver/events.hpp: liftoff_patellar_*,
// recontact_patellar_*, the contact function of SolvePatella's complementarity at the
// tibial pose, so that all stop at the same events), which restart IDA; each phase's facets
// are those SolvePatella's complementarity chooses at its start (MonolithicSystem::
// InitialValues), a separated facet's gap row replaced by λ_i = 0 (the same 17 unknowns,
// solver/patella.hpp). Where the one-facet equilibrium does not hold past a switch (the
// branch's fold), the next phase's start stops the run with the fold's SolverError, as for
// every formulation (CheckPatellarFacetSwitch, solver/patella.hpp).
#include <algorithm>
#include <array>
#include <memory>

#include "formulations/internal/dae_on_ida.hpp"
#include "formulations/internal/monolithic_system.hpp"

namespace kneedyn {
namespace {

// The facet roots' directions: either sign change.
const std::vector<int> kFacetRootDirections = {0, 0};

}  // namespace

// IDA's absolute tolerance of unknown i (IdaDriver::UnknownAtol): the tibia's as dae's /
// dae-ggl's (dae_on_ida.hpp), --atol for the patella's x.
double DaeUnknownAtol(bool ggl, const MonolithicSystem& system, int i, double atol) {
  return i < system.tibia_size() ? DaeUnknownAtol(ggl, system.tibia(), i, atol) : atol;
}

namespace {

class MonolithicOnIda final : public IdaDriver<MonolithicSystem> {
 public:
  MonolithicOnIda(const Scene& scene, const IdaOptions& options, const DaeOnIdaVariant& variant)
      : IdaDriver(scene, options, ContactForm::kChapter, variant, RequirePatella(scene, variant.name),
                  options.constraint_level, variant.ggl),
        facet_liftoff_(scene.model.patella->facet_liftoff) {}

  // Without facet_liftoff the root g = λ_i stops the run where a facet starts to pull. A phase
  // that starts with a facet pulling (λ_i < 0; e.g. the quadriceps line (0.3, -0.2, 1) of the
  // impact scene: N_medial = -8.1 N at t = 0) never sees that root: it ran 0.12 s with the facet
  // pulling, then stopped where it pressed again, saying "past it the facet would pull". It
  // stops at its start instead.
  void Start(const MechanicalState& state, const std::vector<EventSpec>& events) override {
    IdaDriver::Start(state, events);
    if (facet_liftoff_) return;
    const double* y = NvData(ida_.y);
    for (int i = 0; i < 2; ++i) {
      const double ratio = y[system_.PatellaIndex(kPatellaFacetRatio + i)];
      if (!(ratio < 0.0)) continue;
      Throw<SolverError>(variant_.name, "the ", i == 0 ? "medial" : "lateral",
                         " patellar facet pulls at the start of the phase at t = ", state.t, " s (lambda = ", ratio,
                         ", N = ", ratio * QuadricepsMagnitude(scene_.model.patella->quadriceps, state.t),
                         " N): the two-contact model has no patellar equilibrium with both facets pressing there. The "
                         "monolithic DAE stops; the scene key patella.facet_liftoff lets the facet separate "
                         "(docs/model.md §12)");
    }
  }

  // The patella's unknowns at the end of the last Advance (monolithic_system.hpp test hook).
  bool PatellaUnknowns(std::array<double, kPatellaUnknowns>* x) const {
    if (!advanced_ || ida_.y == nullptr) return false;
    const double* y = NvData(ida_.y);
    for (int i = 0; i < kPatellaUnknowns; ++i) (*x)[i] = y[system_.PatellaIndex(i)];
    return true;
  }

 protected:
  std::vector<int> ExtraRootDirections() const override {
    return facet_liftoff_ ? std::vector<int>() : kFacetRootDirections;
  }

  // The phase's events (solver/events.hpp), then λ_medial, λ_lateral without facet_liftoff.
  void EvaluateRoots(const double* y, double* g) override {
    if (facet_liftoff_) return IdaDriver::EvaluateRoots(y, g);
    const Vector6d q = Eigen::Map<const Vector6d>(y);
    std::fill(normal_.begin(), normal_.end(), 0.0);
    for (size_t c = 0; c < active_.size(); ++c) normal_[active_[c]] = y[system_.NormalIndex(static_cast<int>(c))];
    if (!events_.empty()) EvaluateEvents(scene_.model, events_, q, normal_, g);
    for (size_t i = 0; i < kFacetRootDirections.size(); ++i) {
      g[events_.size() + i] = y[system_.PatellaIndex(kPatellaFacetRatio + static_cast<int>(i))];
    }
  }

  AdvanceResult RootResult(double t) override {
    if (facet_liftoff_) return IdaDriver::RootResult(t);
    for (size_t i = 0; i < kFacetRootDirections.size(); ++i) {
      if (root_flags_[events_.size() + i] == 0) continue;
      Throw<SolverError>(variant_.name, "the ", i == 0 ? "medial" : "lateral",
                         " patellar facet's force ratio lambda changes sign at t = ", t,
                         " s: past it the two-contact model has no patellar equilibrium with both facets pressing "
                         "(the facet would pull). The monolithic DAE stops there; the scene key "
                         "patella.facet_liftoff lets the facet separate (docs/model.md §12)");
    }
    return EventResult(std::vector<int>(root_flags_.begin(), root_flags_.begin() + events_.size()));
  }

  // Failures name the formulation, plain and GGL.
  std::string SolveFunctionName() const override { return StrCat("IDASolve (", variant_.name, ")"); }

 private:
  static const Model& RequirePatella(const Scene& scene, const char* name) {
    if (!scene.model.patella) {
      Throw<InputError>(name, "scene '", scene.name,
                        "' has no patella: section; the monolithic DAE couples the tibia to the patella "
                        "(docs/model.md §12): use a scene with one, e.g. patellofemoral_impact.yaml");
    }
    return scene.model;
  }

  bool facet_liftoff_;  // the scene's patella.facet_liftoff: a facet may separate (solver/patella.hpp)
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
