// `ede`: excess differential equations. All six coordinates and their rates are states,
// y = (q, q̇) (12); the contact conditions enter only through the hidden constraint:
// q̈ and N_i from solver/constrained_dynamics.hpp (closed-form sphere-on-plane contacts,
// [M −Gᵀ; G 0] [ν̇; N] = [Q; −κ − 2a φ̇ − b² φ]). The position and velocity constraints
// φ = 0, φ̇ = 0 are not enforced and drift; summary.json's constraint_residuals (max |φ|,
// |φ̇| over the output rows) is the drift report. --stabilization:
//   none        a = b = 0 (pure index reduction);
//   baumgarte   a = --baumgarte-alpha, b = --baumgarte-beta (1/s);
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
#include <cmath>
#include <memory>

#include "formulations/formulation.hpp"
#include "formulations/ode_integrator.hpp"
#include "solver/consistent_init.hpp"
#include "solver/constrained_dynamics.hpp"

namespace kneedyn {
namespace {

constexpr int kMaxProjectionIterations = 10;
constexpr double kProjectionTolerance = 1.0e-14;  // m

class EdeFormulation final : public Formulation, public OdeProblem {
 public:
  EdeFormulation(const Scene& scene, const FormulationOptions& options)
      : scene_(scene), model_(scene.model), options_(options), integrator_(options, "ede") {
    if (options.stabilization == "baumgarte") {
      gains_.alpha = options.baumgarte_alpha;
      gains_.beta = options.baumgarte_beta;
    }
    project_ = options.stabilization == "projection" || options.stabilization == "cvode-projection";
    solver_projection_ = options.stabilization == "cvode-projection";
    if (solver_projection_ && !integrator_.supports_solver_projection()) {
      Throw<InputError>("EdeFormulation", "--stabilization cvode-projection with --integrator '",
                        integrator_.name(), "': CVODE's projection (CVodeSetProjFn) exists only for "
                        "cvode-bdf; use --integrator cvode-bdf or --stabilization projection");
    }
    if (project_ && !solver_projection_ && integrator_.name() == "cvode-adams") {
      // The project-and-restart loop would restart the multistep method at order 1 every step.
      Throw<InputError>("EdeFormulation", "--stabilization projection with --integrator cvode-adams: "
                        "not supported (CVODE projects only with BDF); use cvode-bdf or an ERK method");
    }
  }

  ContactForm contact_form() const override { return ContactForm::kClosedForm; }

  void Start(const MechanicalState& state, const std::vector<EventSpec>& events) override {
    active_ = state.active;
    events_ = events;
    state_contact_ = state.contact;
    ligament_branch_ = state.ligament_branch;
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
    const ConstrainedAcceleration acc =
        SolveConstrainedAcceleration(model_, t_, q, qd, active_, gains_, &ligament_branch_);
    state->t = t_;
    state->q = q;
    state->qd = qd;
    state->qdd = acc.qdd;
    state->contact = state_contact_;
    state->ligament_branch = ligament_branch_;
    for (size_t c = 0; c < active_.size(); ++c) state->contact[active_[c]].normal_force = acc.normal_force[c];
    FillContactCoordinates(model_, state);
    return root ? EventResult(found) : AdvanceResult{};
  }

  std::string integrator() const override { return integrator_.name(); }
  double fixed_step() const override { return integrator_.step(); }

  SolverStats stats() const override {
    SolverStats s = integrator_.stats();
    s.projections += projections_;
    return s;
  }

  bool Rhs(double t, const double* y, double* ydot) override {
    const Vector6d q = Eigen::Map<const Vector6d>(y);
    const Vector6d qd = Eigen::Map<const Vector6d>(y + 6);
    const ConstrainedAcceleration acc =
        SolveConstrainedAcceleration(model_, t, q, qd, active_, gains_, &ligament_branch_);
    for (int i = 0; i < 6; ++i) {
      ydot[i] = qd(i);
      ydot[6 + i] = acc.qdd(i);
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
    const Vector6d qd = Eigen::Map<const Vector6d>(y + 6);
    std::vector<double> normal(model_.contacts.size(), 0.0);
    if (!active_.empty()) {
      const ConstrainedAcceleration acc =
          SolveConstrainedAcceleration(model_, t, q, qd, active_, gains_, &ligament_branch_);
      for (size_t c = 0; c < active_.size(); ++c) normal[active_[c]] = acc.normal_force[c];
    }
    EvaluateEvents(scene_.model, events_, q, normal, g);
  }

 private:
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

  const Scene& scene_;
  const Model& model_;
  FormulationOptions options_;
  OdeIntegrator integrator_;
  BaumgarteGains gains_;
  bool project_ = false;
  bool solver_projection_ = false;  // cvode-projection: CVodeSetProjFn instead of restarts
  long projections_ = 0;
  double t_ = 0.0;
  VectorXd y_;
  std::vector<int> active_;
  std::vector<EventSpec> events_;
  std::vector<ContactGuess> state_contact_;
  std::vector<signed char> ligament_branch_;
};

}  // namespace

std::unique_ptr<Formulation> CreateEde(const Scene& scene, const FormulationOptions& options) {
  return std::make_unique<EdeFormulation>(scene, options);
}

}  // namespace kneedyn
