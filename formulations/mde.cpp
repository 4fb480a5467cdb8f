// `mde`: minimal differential equations, y = (s, ṡ) with s the 6 − k coordinates left free by
// eliminating k translations through the k active contact conditions. The elimination (the
// chart), its derivation and the right-hand side are MdeChart
// (formulations/internal/mde_chart.hpp), which the open problem's "mde" form shares; this
// file is the integrator, the chart switch after every accepted step and the cache.
#include <array>
#include <cstring>
#include <memory>

#include "formulations/internal/formulation_base.hpp"
#include "formulations/internal/mde_chart.hpp"
#include "formulations/internal/ode_integrator.hpp"
#include "solver/consistent_init.hpp"

namespace kneedyn {
namespace {

class MdeFormulation final : public FormulationBase, public OdeProblem {
 public:
  MdeFormulation(const Scene& scene, const OdeOptions& options)
      : FormulationBase(scene), options_(options), integrator_(options, "mde"), chart_(model_) {
    normal_.assign(model_.contacts.size(), 0.0);
  }

  ContactForm contact_form() const override { return ContactForm::kClosedForm; }

  void Start(const MechanicalState& state, const std::vector<EventSpec>& events) override {
    BeginPhase(state, events);
    phase_steps_ = 0;
    chart_.Begin(active_, state.q);
    StartIntegrator(state);
  }

  // (Re)starts the integrator from a state in the current chart.
  void StartIntegrator(const MechanicalState& state) {
    const std::vector<int>& free = chart_.free();
    const int m = static_cast<int>(free.size());
    y_.resize(2 * m);
    for (int j = 0; j < m; ++j) {
      y_(j) = state.q(free[j]);
      y_(m + j) = state.qd(free[j]);
    }
    t_ = state.t;
    cache_valid_ = false;  // new chart, start point or phase
    const std::vector<int> dirs = RootDirections(events_);
    integrator_.Start(this, t_, y_, dirs);
  }

  AdvanceResult Advance(double t_out, MechanicalState* state) override {
    std::vector<int> found;
    bool root = false;
    do {
      // One step at a time: the chart is checked after every step, not only at output
      // times (whose spacing must not change the physics).
      root = integrator_.Evolve(t_out, true, &t_, &y_, &found);
      if (++phase_steps_ > options_.control.max_steps) {  // the integrator's own budget restarts with a chart
        Throw<SolverError>("MdeFormulation::Advance", "more than --max-steps = ", options_.control.max_steps,
                           " steps in this contact phase at t = ", t_, " s");
      }
      if (!root && !active_.empty()) SwitchChartIfBetter();
    } while (!root && t_ < t_out);
    const MdeKinematics kin = Evaluate(t_, y_.data(), nullptr);
    WriteBack(t_, kin.q, kin.qd, kin.qdd, kin.normal_force.data(), nullptr, 0, state);
    return root ? EventResult(found) : AdvanceResult{};
  }

  // y = (s, ṡ), s the free coordinates of the phase: "alpha", "alpha_rate", ...
  std::string StateName(int i) const override {
    const std::vector<int>& free = chart_.free();
    const int m = static_cast<int>(free.size());
    return i < m ? std::string(CoordinateName(free[i])) : std::string(CoordinateName(free[i - m])) + "_rate";
  }

  // The OdeIntegrator lives across phases and counts over the whole run.
  SolverStats PhaseStats() const override { return integrator_.stats(); }
  std::string integrator() const override { return integrator_.name(); }
  bool EvaluateHotPathForTesting(int n) override { return integrator_.EvaluateCallbacksForTesting(t_, y_, n); }
  double fixed_step() const override { return integrator_.step(); }

  bool Rhs(double t, const double* y, double* ydot) override {
    const int m = static_cast<int>(chart_.free().size());
    VecM sdd(m);
    Evaluate(t, y, &sdd);
    for (int j = 0; j < m; ++j) {
      ydot[j] = y[m + j];
      ydot[m + j] = sdd(j);
    }
    return true;
  }

  void Roots(double t, const double* y, double* g) override {
    const MdeKinematics kin = Evaluate(t, y, nullptr);
    std::fill(normal_.begin(), normal_.end(), 0.0);
    for (size_t c = 0; c < active_.size(); ++c) normal_[active_[c]] = kin.normal_force[c];
    // The evaluation's pose and ligament lengths at kin.q (the chart's last Evaluate is the
    // cached point's: only an uncached Evaluate writes them, and it refills the cache).
    EvaluateEvents(scene_.model, events_, kin.q, chart_.last_pose(), normal_, chart_.last_ligament_length(), g);
  }

 private:
  // After an accepted step: restart in a better chart when the one in use lost a factor 2,
  // else re-seed the elimination's Newton start at the accepted point.
  void SwitchChartIfBetter() {
    const std::vector<int> before = chart_.eliminated();
    // The new chart's state from the full q, q̇ of the old one (exact: same point).
    const MdeKinematics kin = Evaluate(t_, y_.data(), nullptr);
    chart_.Choose(kin.q);
    if (chart_.eliminated() == before) {
      chart_.SetStartPose(kin);  // the next step's Newton starts from this accepted point
      return;
    }
    chart_.SetStartPose(kin.q);
    MechanicalState at;
    at.t = t_;
    at.q = kin.q;
    at.qd = kin.qd;
    StartIntegrator(at);
  }

  // q from s (closed-form elimination); qd = P ṡ; s̈ (if sdd) and q̈, N.
  // Returns the last result when (t, y) are bitwise those of the previous call in this
  // chart: the root functions at a step's end, the chart check after the step and the
  // first stage of the next (FSAL of the Dormand–Prince pair) ask for the same point.
  MdeKinematics Evaluate(double t, const double* y, VecM* sdd_out) const {
    const int m = static_cast<int>(chart_.free().size());
    if (cache_valid_ && t == cache_t_ && std::memcmp(y, cache_y_.data(), sizeof(double) * 2 * m) == 0) {
      if (sdd_out) *sdd_out = cache_sdd_;
      return cache_kin_;
    }
    cache_valid_ = false;  // a throwing evaluation leaves no stale entry
    const MdeKinematics kin = chart_.Evaluate(t, y, &ligament_branch_, &cache_sdd_);
    if (sdd_out) *sdd_out = cache_sdd_;
    cache_t_ = t;
    std::memcpy(cache_y_.data(), y, sizeof(double) * 2 * m);
    cache_kin_ = kin;
    cache_valid_ = true;
    return kin;
  }

  OdeOptions options_;
  OdeIntegrator integrator_;
  double t_ = 0.0;
  VectorXd y_;
  MdeChart chart_;
  long phase_steps_ = 0;  // steps since Start (the --max-steps budget is per phase)
  // Evaluate's last result and its (t, y) (2 m ≤ 12 values; reset by StartIntegrator).
  mutable bool cache_valid_ = false;
  mutable double cache_t_ = 0.0;
  mutable std::array<double, 12> cache_y_{};
  mutable MdeKinematics cache_kin_;
  mutable VecM cache_sdd_;
  std::vector<double> normal_;  // N per model contact, for the root functions
};

}  // namespace

FormulationMaker ConfigureMde(const OptionRequest& request) {
  OdeOptions options;
  if (!ReadOdeOptions(request, &options)) return nullptr;
  return [options](const Scene& scene) { return std::make_unique<MdeFormulation>(scene, options); };
}

}  // namespace kneedyn
