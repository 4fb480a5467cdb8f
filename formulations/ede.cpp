// `ede`: excess differential equations. All six coordinates and their rates are states,
// y = (q, q̇) (12); the contact conditions enter only through the hidden constraint:
// q̈ and N_i from solver/constrained_dynamics.hpp (closed-form sphere-on-plane contacts,
// [M −Gᵀ; G 0] [ν̇; N] = [Q; −κ − 2a φ̇ − b² φ]). The position and velocity constraints
// φ = 0, φ̇ = 0 are not enforced and drift; summary.json's constraint_residuals (max |φ|,
// |φ̇| over the output rows) is the drift report. --stabilization:
//   none        a = b = 0 (pure index reduction);
//   baumgarte   a = b = 20 1/s (SolverOptions::baumgarte_alpha, baumgarte_beta; no command-line
//               option sets them: summary.json's settings record them);
//   projection  after every accepted step: positions onto φ(q) = 0 by Gauss–Newton with
//               the minimum-norm correction in q (Eigen CompleteOrthogonalDecomposition of
//               J = ∂φ/∂q = G B), then velocities onto J q̇ = 0 (minimum norm); the
//               integrator restarts from the projected state (stats.projections counts);
//               the state at an event root is projected as well (moves it by ~ the
//               integration error, so the event's flexion is off the root by as much).
//   cvode-projection  (cvode-bdf only) CVODE's own projection (CVodeSetProjFn): CVODE calls
//               the same projection after each step and keeps its BDF order, step history
//               and error estimate (the correction enters the error test); no restart.
//               Other integrators: InputError (CVODE projects only with BDF).
// Events: lift-off g = N_i, re-contact and flexion via solver/events.hpp.
#include <Eigen/QR>
#include <algorithm>
#include <cmath>
#include <cstring>
#include <memory>

#include "formulations/internal/formulation_base.hpp"
#include "formulations/internal/ode_integrator.hpp"
#include "solver/consistent_init.hpp"
#include "solver/constrained_dynamics.hpp"

namespace kneedyn {
namespace {

constexpr int kMaxProjectionIterations = 10;
constexpr double kProjectionTolerance = 1.0e-14;  // m

class EdeFormulation final : public FormulationBase, public OdeProblem {
 public:
  EdeFormulation(const Scene& scene, const OdeOptions& options)
      : FormulationBase(scene), options_(options), integrator_(options, "ede"),
        workspace_(model_), output_workspace_(model_) {
    acc_.normal_force.reserve(kMaxConstrainedContacts);
    output_acc_.normal_force.reserve(kMaxConstrainedContacts);
    normal_.assign(model_.contacts.size(), 0.0);
    const Stabilization stabilization = options.stabilization;
    if (stabilization == Stabilization::kBaumgarte) {
      gains_.alpha = options.baumgarte_alpha;
      gains_.beta = options.baumgarte_beta;
    }
    project_ = stabilization == Stabilization::kProjection || stabilization == Stabilization::kCvodeProjection;
    solver_projection_ = stabilization == Stabilization::kCvodeProjection;
  }

  ContactForm contact_form() const override { return ContactForm::kClosedForm; }

  void Start(const MechanicalState& state, const std::vector<EventSpec>& events) override {
    BeginPhase(state, events);
    cache_valid_ = false;  // new active set and ligament branches
    t_ = state.t;
    y_.resize(12);
    y_ << state.q, state.qd;
    const std::vector<int> dirs = RootDirections(events_);
    integrator_.Start(this, t_, y_, dirs, solver_projection_);
  }

  AdvanceResult Advance(double t_out, MechanicalState* state) override {
    std::vector<int> found;
    bool root = false;
    if (!project_ || solver_projection_) {
      root = integrator_.Evolve(t_out, false, &t_, &y_, &found);
      if (project_ && root) Project(&y_);  // the root state is the solver's interpolant
    } else {
      while (!root && t_ < t_out) {
        root = integrator_.Evolve(t_out, true, &t_, &y_, &found);
        // A root's state (the interpolant's) is projected too; the phase ends there, so no
        // restart is needed.
        if (Project(&y_) && !root) integrator_.Reset(t_, y_);
      }
    }
    Vector6d q = y_.head<6>(), qd = y_.tail<6>();
    // The patella's equilibrium is not unique (docs/model.md §12): the sample's solve starts
    // from the right-hand side's last solution, so that it reports the branch the motion
    // follows (a fresh solve from the start pose may land on another).
    output_workspace_.data.patella_guess = workspace_.data.patella_guess;
    SolveConstrainedAcceleration(model_, t_, q, qd, active_, gains_, &ligament_branch_, &output_workspace_,
                                 &output_acc_);
    WriteBack(t_, q, qd, output_acc_.qdd, output_acc_.normal_force.data(), nullptr, 0, state);
    return root ? EventResult(found) : AdvanceResult{};
  }

  std::string integrator() const override { return integrator_.name(); }
  bool EvaluateHotPathForTesting(int n) override { return integrator_.EvaluateCallbacksForTesting(t_, y_, n); }
  double fixed_step() const override { return integrator_.step(); }

  // y = (q, q̇): "alpha", "alpha_rate", ...
  std::string StateName(int i) const override {
    return i < 6 ? std::string(CoordinateName(i)) : std::string(CoordinateName(i - 6)) + "_rate";
  }

  // The OdeIntegrator lives across phases and counts over the whole run.
  SolverStats PhaseStats() const override {
    SolverStats s = integrator_.stats();
    s.projections += projections_;
    return s;
  }

  // No allocation (workspace_, acc_; tests/zero_allocation_test.cpp).
  bool Rhs(double t, const double* y, double* ydot) override {
    const Vector6d qd = Eigen::Map<const Vector6d>(y + 6);
    AccelerationAt(t, y);
    for (int i = 0; i < 6; ++i) {
      ydot[i] = qd(i);
      ydot[6 + i] = acc_.qdd(i);
    }
    return true;
  }

  void ProjectionCorrection(double, const double* y, double* corr) override {
    VectorXd projected = Eigen::Map<const VectorXd>(y, 12);
    Project(&projected);
    for (int i = 0; i < 12; ++i) corr[i] = projected(i) - y[i];
  }

  void Roots(double t, const double* y, double* g) override {
    const Vector6d q = Eigen::Map<const Vector6d>(y);
    std::fill(normal_.begin(), normal_.end(), 0.0);
    if (active_.empty()) {  // gaps, flexion and ligament lengths only: no constrained solve
      EvaluateEvents(scene_.model, events_, q, normal_, g);
      return;
    }
    // With ARKStep the next step's first stage asks for this same (t, y): solve for q̈ too, so
    // that it finds it in the cache (with dopri5 in ERKStep the step's last stage left it
    // there). Not with a patella: its equilibrium solve starts from the last one's, so a
    // solve's result depends on the calls before it (at the solve's tolerance), and patella
    // runs keep the order of solves they had.
    SolveAt(t, y, integrator_.next_step_starts_at_step_end() && !model_.patella);
    for (size_t c = 0; c < active_.size(); ++c) normal_[active_[c]] = acc_.normal_force[c];
    // The solve's pose and ligament lengths at q (with CVODE the constrained solve at this
    // (t, y) is new: its Adams corrector never evaluates f at the accepted y_n).
    EvaluateEvents(scene_.model, events_, q, workspace_.pose, normal_, workspace_.data.ligament_length, g);
  }

 private:
  // acc_ at (t, y): the hidden-constraint solve, or its last result when (t, y) are bitwise
  // those of the previous call (the root functions at a step's end and the explicit
  // Runge–Kutta stage that follows ask for the same point).
  void AccelerationAt(double t, const double* y) { SolveAt(t, y, true); }
  // `accelerations` false: acc_.normal_force (and the workspace's pose and ligament lengths)
  // only, without ν̇ and q̈ (SolveContactNormalForces), unless the cache has them.
  void SolveAt(double t, const double* y, bool accelerations) {
    if (cache_valid_ && (cache_has_accelerations_ || !accelerations) && t == cache_t_ &&
        std::memcmp(y, cache_y_, sizeof cache_y_) == 0) {
      return;
    }
    const Vector6d q = Eigen::Map<const Vector6d>(y);
    const Vector6d qd = Eigen::Map<const Vector6d>(y + 6);
    cache_valid_ = false;  // a throwing solve leaves no stale entry
    if (accelerations) {
      SolveConstrainedAcceleration(model_, t, q, qd, active_, gains_, &ligament_branch_, &workspace_, &acc_);
    } else {
      SolveContactNormalForces(model_, t, q, qd, active_, gains_, &ligament_branch_, &workspace_, &acc_);
    }
    cache_t_ = t;
    std::memcpy(cache_y_, y, sizeof cache_y_);
    cache_valid_ = true;
    cache_has_accelerations_ = accelerations;
  }

  // φ (k) and J = ∂φ/∂q = G B(q) (k×6) of the active contacts.
  // Projects y = (q, q̇) onto φ = 0, J q̇ = 0. Returns true when y changed.
  bool Project(VectorXd* y) {
    if (active_.empty()) return false;
    Vector6d q = y->head<6>(), qd = y->tail<6>();
    ProjectOntoContacts(model_, active_, kProjectionTolerance, kMaxProjectionIterations, &q);
    VectorXd phi;
    MatrixXd J;
    ContactGapsAndJacobian(model_, q, active_, &phi, &J);
    qd -= Eigen::CompleteOrthogonalDecomposition<MatrixXd>(J).solve(VectorXd(J * qd));
    y->head<6>() = q;
    y->tail<6>() = qd;
    ++projections_;
    return true;
  }

  OdeOptions options_;
  OdeIntegrator integrator_;
  BaumgarteGains gains_;
  bool project_ = false;
  bool solver_projection_ = false;  // cvode-projection: CVodeSetProjFn instead of restarts
  long projections_ = 0;
  double t_ = 0.0;
  VectorXd y_;
  // Workspaces of the right-hand side and root functions (sized once; no allocation there).
  ConstrainedDynamicsWorkspace workspace_;
  ConstrainedAcceleration acc_;
  // The output samples' solve (Advance), apart from the right-hand side's cache.
  ConstrainedDynamicsWorkspace output_workspace_;
  ConstrainedAcceleration output_acc_;
  bool cache_valid_ = false;  // acc_ belongs to (cache_t_, cache_y_)
  bool cache_has_accelerations_ = false;  // and holds q̈, not only the normal forces
  double cache_t_ = 0.0;
  double cache_y_[12] = {};
  std::vector<double> normal_;  // N per model contact, for the root functions
};

}  // namespace

FormulationMaker ConfigureEde(const OptionRequest& request) {
  OdeOptions options;
  if (!ReadOdeOptions(request, &options)) return nullptr;
  return [options](const Scene& scene) { return std::make_unique<EdeFormulation>(scene, options); };
}

}  // namespace kneedyn
