// `staggered`: the chapter's approximate procedure for the knee with its patella (§1.7;
// docs/model.md §12). The tibia's equations are those of `ede` (y = (q, q̇), q̈ and N from
// the hidden constraint, solver/constrained_dynamics.hpp) with the patellar tendon's pull
// lagged by one step Δt = --step:
//
//   on [t_k, t_k + Δt] the tendon pulls the tibia with the tension F_t,k and towards the
//   apex position R_t,k of the patella's equilibrium solved at t_k (at the tuberosity's
//   position then, F_Q(t_k)); at t_k + Δt the equilibrium is solved again at the
//   tuberosity's new position and the result enters the next step.
//
// Inside a step the tibia is integrated by dopri5 under --rtol/--atol, restarted at every
// t_k (the lagged force jumps there), so that what separates it from the monolithic and
// ODE forms is the lag alone: the coupling error. The step grid starts at each phase start
// (an event restarts it). An event function that changes sign across a lag update (the
// normal forces jump with the lagged tendon force) is an event at that update time. The
// simulator's consistent states at phase starts use the
// equilibrium at the current pose (no lag).
#include <algorithm>
#include <cmath>
#include <memory>

#include "formulations/internal/formulation_base.hpp"
#include "formulations/internal/ode_integrator.hpp"
#include "solver/constrained_dynamics.hpp"

namespace kneedyn {
namespace {

// The scheme's options: the coupling step Δt (--step; 0 = kDefaultFixedStep) and the
// tolerances of the dopri5 run inside each step.
struct StaggeredOptions {
  StepControl control;
};

OdeOptions InnerOptions(const StaggeredOptions& options) {
  OdeOptions inner;
  inner.control = options.control;
  inner.control.step = 0.0;  // dopri5 is adaptive inside a coupling step
  inner.integrator = IntegratorKind::kDopri5;
  return inner;
}

class StaggeredFormulation final : public FormulationBase, public OdeProblem {
 public:
  StaggeredFormulation(const Scene& scene, const StaggeredOptions& options)
      : FormulationBase(scene), integrator_(InnerOptions(options), "staggered"), workspace_(model_),
        step_(options.control.step > 0.0 ? options.control.step : kDefaultFixedStep),
        max_steps_(options.control.max_steps) {
    if (!model_.patella) {
      Throw<InputError>("staggered", "scene '", scene.name,
                        "' has no patella: section; the staggered scheme couples the tibia to the patella "
                        "(docs/model.md §12): use a scene with one, e.g. patellofemoral_impact.yaml");
    }
    acc_.normal_force.reserve(kMaxConstrainedContacts);
    workspace_.data.lagged_tendon = &lagged_;
  }

  ContactForm contact_form() const override { return ContactForm::kClosedForm; }

  void Start(const MechanicalState& state, const std::vector<EventSpec>& events) override {
    BeginPhase(state, events);
    t_ = state.t;
    y_.resize(12);
    y_ << state.q, state.qd;
    phase_coupling_steps_ = 0;
    UpdateLag();
    integrator_.Start(this, t_, y_, RootDirections(events_));
  }

  AdvanceResult Advance(double t_out, MechanicalState* state) override {
    std::vector<int> found;
    bool root = false;
    while (!root && t_ < t_out) {
      const double target = std::min(t_out, next_update_);
      root = integrator_.Evolve(target, false, &t_, &y_, &found);
      if (!root && t_ >= next_update_) {  // end of a coupling step: the patella catches up
        // --max-steps bounds the coupling steps of a phase (and dopri5's steps within each):
        // --step 1e-9 ran 3.4e8 coupling steps (hours) when only the inner steps were bounded.
        if (phase_coupling_steps_ >= max_steps_) {
          Throw<SolverError>("staggered", "more than --max-steps = ", max_steps_, " coupling steps of ", step_,
                             " s in this phase (t = ", t_, " s)");
        }
        // The event functions jump with the lagged force (a normal force can change sign
        // there): a sign change in an event's direction across the update is its root.
        std::vector<double> before(events_.size()), after(events_.size());
        Roots(t_, y_.data(), before.data());
        try {
          UpdateLag();
        } catch (const SolverError& e) {
          // Where it stopped: the run's "last state" is this one, not the last output row
          // (before, a failure 3.3 ms past the row named the row's time and no step).
          state->t = t_;
          state->q = y_.head<6>();
          state->qd = y_.tail<6>();
          Throw<SolverError>("staggered", "at the coupling step ending at t = ", t_, " s (--step h = ", step_,
                             " s): ", e.what());
        }
        Roots(t_, y_.data(), after.data());
        found.assign(events_.size(), 0);
        for (size_t e = 0; e < events_.size(); ++e) {
          const int dir = events_[e].direction;
          const bool down = before[e] > 0.0 && after[e] <= 0.0, up = before[e] < 0.0 && after[e] >= 0.0;
          if ((down && dir <= 0) || (up && dir >= 0)) {
            found[e] = dir == 0 ? (down ? -1 : 1) : dir;
            root = true;
          }
        }
        if (!root) integrator_.Reset(t_, y_, /*new_step_budget=*/true);  // the inner steps: per coupling step
      }
    }
    const Vector6d q = y_.head<6>(), qd = y_.tail<6>();
    SolveConstrainedAcceleration(model_, t_, q, qd, active_, {}, &ligament_branch_, &workspace_, &acc_);
    WriteBack(t_, q, qd, acc_.qdd, acc_.normal_force.data(), nullptr, 0, state);
    return root ? EventResult(found) : AdvanceResult{};
  }

  std::string integrator() const override { return "dopri5"; }
  double fixed_step() const override { return step_; }
  std::string StateName(int i) const override {
    return i < 6 ? std::string(CoordinateName(i)) : std::string(CoordinateName(i - 6)) + "_rate";
  }
  SolverStats PhaseStats() const override { return integrator_.stats(); }

  bool Rhs(double t, const double* y, double* ydot) override {
    const Vector6d q = Eigen::Map<const Vector6d>(y), qd = Eigen::Map<const Vector6d>(y + 6);
    SolveConstrainedAcceleration(model_, t, q, qd, active_, {}, &ligament_branch_, &workspace_, &acc_);
    for (int i = 0; i < 6; ++i) {
      ydot[i] = qd(i);
      ydot[6 + i] = acc_.qdd(i);
    }
    return true;
  }

  void Roots(double t, const double* y, double* g) override {
    const Vector6d q = Eigen::Map<const Vector6d>(y), qd = Eigen::Map<const Vector6d>(y + 6);
    std::vector<double> normal(model_.contacts.size(), 0.0);
    if (active_.empty()) {
      EvaluateEvents(model_, events_, q, normal, g);
      return;
    }
    SolveConstrainedAcceleration(model_, t, q, qd, active_, {}, &ligament_branch_, &workspace_, &acc_);
    for (size_t c = 0; c < active_.size(); ++c) normal[active_[c]] = acc_.normal_force[c];
    EvaluateEvents(model_, events_, q, workspace_.pose, normal, g);
  }

 private:
  // The patella's equilibrium at (t_, y_): the tendon the next step carries.
  void UpdateLag() {
    const Vector6d q = y_.head<6>();
    lagged_ = SolvedTendon(*model_.patella, t_, PoseFromCoordinates(q), &guess_);
    next_update_ = t_ + step_;
    ++coupling_steps_;
    ++phase_coupling_steps_;
  }

  OdeIntegrator integrator_;
  ConstrainedDynamicsWorkspace workspace_;
  ConstrainedAcceleration acc_;
  double step_;           // Δt, s
  long max_steps_;        // --max-steps: coupling steps per phase
  long phase_coupling_steps_ = 0;
  double t_ = 0.0;
  double next_update_ = 0.0;
  VectorXd y_;
  LaggedTendon lagged_;
  PatellaGuess guess_;
  long coupling_steps_ = 0;
};

}  // namespace

FormulationMaker ConfigureStaggered(const OptionRequest& request) {
  StaggeredOptions options;
  options.control = request.options.step_control();
  return [options](const Scene& scene) { return std::make_unique<StaggeredFormulation>(scene, options); };
}

}  // namespace kneedyn
