// `newmark` and `newmark-reduced`: the chapter's reverse EDE (Abdel-Rahman & Hefzy), the
// Newton–Euler equations with the contact conditions at position level, integrated by the
// Newmark average-acceleration rule (β = 1/4, γ = 1/2; trapezoidal, unconditionally stable,
// second order, no numerical damping).
//
// One step of size h from t_n to t_{n+1} = t_n + h, unknowns x at t_{n+1}:
//   `newmark`          x = (q, c_1 … c_k, N_1 … N_k), c_i = (xc, yc, x′c, y′c)  (6 + 5k)
//   `newmark-reduced`  x = (q, N_1 … N_k)                                      (6 + k)
// with the Newmark formulas
//   q̈_{n+1} = 4/h² (q_{n+1} − q_n − h q̇_n) − q̈_n
//   q̇_{n+1} = q̇_n + h/2 (q̈_n + q̈_{n+1})
// and the equations at t_{n+1}:
//   h²/4 [Q(t, q, ν) + Σ_i N_i G_iᵀ − M ν̇] = 0, ν̇ = GeneralizedAcceleration(q, q̇, q̈)
//                                          (Eqs. 1.48–1.57, as dae.cpp rows F7–F12;
//                                           scaled by h²/4 so rows are ~ M Δq)
//   chapter form: the five ChapterContactResiduals per contact (Eqs. 1.8, 1.13)
//   closed form:  φ_i(q) = 0 (sphere on plane)
// solved by Newton–Raphson with the exact tangent from forward AD (ceres::Jet) and a
// full-pivoting LU (Eigen). Convergence (weighted max norm of the Newton update):
//   |Δx_i| ≤ rtol |x_i| + atol_i,  atol_i = atol (m, rad) for q and c, 1e4 atol (N) for N;
// N is a multiplier whose Newton update carries O(ε M/h²) round-off, so it is also
// accepted once the q and c updates are below 1e-3 of their tolerance. At most 20
// iterations; on failure the step is halved (at most 20 times below the nominal step,
// then SolverError with t, h and the distinct reasons of the failed solves, e.g. the JCS
// singularity thrown by solver/rotation.hpp, or non-convergence naming the unknown with the
// largest weighted Newton update, its value, t and h) and regrows by doubling after each accepted step.
//
// Events (solver/events.hpp) are evaluated after each accepted step; N is an unknown, so
// lift-off uses it directly. A sign change (respecting EventSpec::direction) is located on
// the step's interpolant (cubic Hermite q, linear q̈ and N) by the shared fixed-step locator
// (event_locator.hpp: Illinois) until the bracket is 1e-12 s wide; the state returned is
// the interpolated one just past the root (a retaken step of size h′ ≪ h would amplify the
// Newton tolerance in q̈ and N by 4/h′²). The driver re-solves the hidden constraint at
// restart. The location error is small beside the scheme's global O(h²) error of the
// state (tests/generalized_alpha_test.cpp, LiftoffLocatedOnTheStateAndErrorIsSecondOrder;
// figures in benchmarks/README.md, "Work-precision sweep").
// Generalized-α with a step other than the one a_n belongs to (output times, halvings,
// the start) first moves a_n to the new step (RescalePseudoAcceleration). Generalized-α
// starts each phase on the smooth solution of its error recursion (PerturbedStart: a_0 and
// an O(h²) velocity perturbation), which removes the O(h) start-up layer of the multipliers.
// Output times: the last steps before t_out are shortened (Newmark with variable h).
//
// The same machinery runs `generalized-alpha` (generalized_alpha.cpp): the scheme
// (newmark_scheme.hpp) replaces the two Newmark formulas by those of Arnold & Brüls (2007)
// with the pseudo-acceleration a; αm = αf = 0, β = 1/4, γ = 1/2 is the rule above (a = q̈).
// The ligament branch is locked for a phase (state.ligament_branch, set by the driver),
// and the driver restarts the phase at the law's kinks, which are among the events.
#include <Eigen/LU>

#include <algorithm>
#include <array>
#include <cmath>
#include <memory>
#include <string>
#include <vector>

#include "formulations/internal/event_locator.hpp"
#include "formulations/formulation.hpp"
#include "formulations/internal/formulation_base.hpp"
#include "formulations/internal/newmark_scheme.hpp"
#include "formulations/internal/newmark_testing.hpp"
#include "solver/consistent_init.hpp"
#include "solver/constrained_dynamics.hpp"
#include "solver/dynamics.hpp"
#include "solver/newton_euler.hpp"
#include "solver/newton_euler_jacobian.hpp"

namespace kneedyn {
namespace {

constexpr int kMaxNewtonIterations = 20;
constexpr int kMaxHalvings = 20;                  // below the nominal step
constexpr double kMultiplierAcceptFactor = 1.0e-3;  // see header: N round-off
constexpr double kEventTimeResolution = 1.0e-12;  // s
constexpr int kMaxEventIterations = 100;

// Fixed-capacity Eigen types (kMaxJetSize = the largest system, checked at Start): no heap
// allocation in a step, the event location or the Newton solve once a phase has started
// (tests/zero_allocation_test.cpp; the workspaces below are sized in Start).
using XVector = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, kMaxJetSize, 1>;
using XMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, kMaxJetSize, kMaxJetSize>;

// The integrator state at one time: what Newmark needs to take the next step.
struct StepState {
  double t = 0.0;
  Vector6d q = Vector6d::Zero();
  Vector6d qd = Vector6d::Zero();
  Vector6d qdd = Vector6d::Zero();
  Vector6d a = Vector6d::Zero();  // generalized-α pseudo-acceleration (= q̈ for Newmark)
  double h_a = 0.0;  // s, the step a belongs to: a ≈ q̈(t + (αm − αf) h_a)
  XVector extra;  // (c_1 … c_k, N_1 … N_k) chapter form, (N_1 … N_k) closed form
};

class NewmarkFormulation final : public FormulationBase {
 public:
  NewmarkFormulation(const Scene& scene, const NewmarkOptions& options, ContactForm form)
      : FormulationBase(scene), options_(options.control), form_(form), scheme_(options.scheme), data_(model_),
        data_jet_(model_) {
    jet_jacobian_ = options.jacobian == JacobianKind::kJet;
    // The default step never exceeds the scene's end time (a run shorter than one step).
    step_ = options.control.step > 0.0 ? options.control.step : std::min(kDefaultFixedStep, scene.end.time);
    if (step_ > scene.end.time) {
      Throw<InputError>("NewmarkFormulation", "--step = ", step_, " s exceeds the scene's end time ",
                        scene.end.time, " s");
    }
  }

  ContactForm contact_form() const override { return form_; }

  void Start(const MechanicalState& state, const std::vector<EventSpec>& events) override {
    BeginPhase(state, events);
    locator_.Reserve(events.size());
    g_hot_path_.resize(events.size());
    per_contact_ = form_ == ContactForm::kChapter ? 4 : 0;
    const int k = static_cast<int>(active_.size());
    n_ = 6 + (per_contact_ + 1) * k;
    if (n_ > kMaxJetSize) Throw<SolverError>("NewmarkFormulation::Start", "system size ", n_, " exceeds ", kMaxJetSize);
    if (k > kMaxActiveContacts) Throw<SolverError>("NewmarkFormulation::Start", k, " active contacts exceed ", kMaxActiveContacts);
    current_.t = state.t;
    current_.q = state.q;
    current_.qd = state.qd;
    current_.qdd = state.qdd;
    PerturbedStart(state, &current_);
    current_.h_a = step_;
    current_.extra.resize(n_ - 6);
    for (int c = 0; c < k; ++c) {
      for (int j = 0; j < per_contact_; ++j) {
        current_.extra(per_contact_ * c + j) = state.contact[active_[c]].coordinates[j];
      }
      current_.extra(per_contact_ * k + c) = state.contact[active_[c]].normal_force;
    }
    normal_.assign(model_.contacts.size(), 0.0);
    g_next_.resize(events.size());
    fired_.reserve(events.size());
    located_.fired.reserve(events.size());
    g_current_ = Events(current_);
    h_ = step_;
    phase_steps_ = 0;
    ++stats_.restarts;
  }

  AdvanceResult Advance(double t_out, MechanicalState* state) override {
    AdvanceResult result;
    while (current_.t < t_out) {
      // Shorten the last steps so that t_out is hit exactly without a sliver step.
      const double remaining = t_out - current_.t;
      double h = h_;
      bool lands = false;
      if (remaining <= h * (1.0 + 1e-9)) {
        h = remaining;
        lands = true;
      } else if (remaining < 2.0 * h) {
        h = 0.5 * remaining;
      }
      StepState next;
      const double h_taken = StepWithHalving(current_, h, &next);
      if (lands && h_taken == h) next.t = t_out;  // exact landing despite round-off in t + h
      EventsInto(next, g_next_.data());
      CrossedEvents(events_, g_current_, g_next_, &fired_);
      if (!fired_.empty()) {
        LocateEvent(current_, h_taken, next, g_next_, &next, &fired_);
        current_ = next;
        EventsInto(current_, g_current_.data());
        ++stats_.steps;
        result.status = AdvanceStatus::kEvent;
        result.events = fired_;
        break;
      }
      current_ = next;
      g_current_.swap(g_next_);
      ++stats_.steps;
      if (++phase_steps_ > options_.max_steps) {
        Throw<SolverError>("NewmarkFormulation::Advance", "more than --max-steps = ", options_.max_steps,
                           " steps in one phase at t = ", current_.t, " s with step h = ", h_taken, " s");
      }
      // After a halving, regrow towards the nominal step.
      h_ = h_taken < h ? h_taken : std::min(step_, 2.0 * h_);
    }
    WriteState(current_, state);
    return result;
  }

  // stats_ counts over the whole run (the stepper lives across phases).
  SolverStats PhaseStats() const override { return stats_; }
  std::string integrator() const override {
    return scheme_.IsAverageAcceleration() ? "newmark-average-acceleration" : "generalized-alpha";
  }
  double fixed_step() const override { return step_; }
  // One Newton step from the current state (residual + Jet Jacobian + LU per iteration)
  // and the event functions, n times.
  bool EvaluateHotPathForTesting(int n) override {
    StepState next;
    for (int i = 0; i < n; ++i) {
      if (!SolveStep(current_, h_, &next)) return false;
      EventsInto(next, g_hot_path_.data());
    }
    return true;
  }

  // Testing hook (formulations/internal/newmark_testing.hpp): the exact tangent and the
  // Jet<24> one of the step h from the started state, at the predictor and at the iterate
  // after `newton_steps` Newton steps with the Jet tangent. False when an evaluation fails.
  bool TangentsForTesting(double h, int newton_steps, MatrixXd* exact, MatrixXd* jet) {
    StepState from = current_;
    RescalePseudoAcceleration(h, &from);
    XVector x(n_);
    x.head<6>() = from.q + h * from.qd + 0.5 * h * h * from.qdd;
    x.tail(n_ - 6) = from.extra;
    XMatrix Je(n_, n_), Jj(n_, n_);
    XVector F(n_);
    for (int iter = 0;; ++iter) {
      for (int i = 0; i < n_; ++i) xj_[i] = JetD(x(i), i);
      if (!StepResidual(from, h, xj_.data(), Fj_.data())) return false;
      for (int r = 0; r < n_; ++r) {
        F(r) = Fj_[r].a;
        for (int c = 0; c < n_; ++c) Jj(r, c) = Fj_[r].v[c];
      }
      if (iter == newton_steps) break;
      x += Jj.fullPivLu().solve(-F);
    }
    if (!StepJacobian(from, h, x.data(), &Je)) return false;
    *exact = Je;
    *jet = Jj;
    return true;
  }

  // Newmark step residual F(x) for any scalar type; false when a surface is evaluated
  // outside its domain (recoverable: the step is halved).
  template <typename T>
  bool StepResidual(const StepState& from, double h, const T* x, T* F) const {
    const int k = static_cast<int>(active_.size());
    Vector6<T> q, qd, qdd, a;
    StepKinematics(from, h, x, &q, &qd, &qdd, &a);
    const EulerAngleTrig<T> trig = EulerAngleTrigOf(q);  // once per pose (rotation.hpp)
    const PoseTpl<T> pose = PoseFromCoordinates(q, trig);
    const T* N = x + 6 + per_contact_ * k;
    ContactGeometryTpl<T> geo[kMaxActiveContacts];
    for (int c = 0; c < k; ++c) {
      const ContactPair& pair = model_.contacts[active_[c]];
      if (form_ == ContactForm::kChapter) {
        if (!ChapterContactResiduals(pair, pose, x + 6 + 4 * c, F + 6 + 5 * c, &geo[c],
                                     state_contact_[active_[c]].chart)) {
          return false;
        }
      } else {
        if (!ContactKinematics(pair, pose, &geo[c])) return false;
        F[6 + c] = geo[c].gap;  // φ_i = 0
      }
    }
    // Q + Σ N_i G_iᵀ − M ν̇ at t_{n+1} (Eqs. 1.48–1.57; solver/newton_euler.hpp).
    DataTpl<T>& data = Workspace(static_cast<T*>(nullptr));  // no allocation per call
    data.ligament_branch = &ligament_branch_;
    const Vector6<T> residual =
        NewtonEulerResidual(model_, from.t + h, q, trig, qd, qdd, pose, k, geo, N, &data);
    for (int i = 0; i < 6; ++i) F[i] = RowScale(h) * -residual(i);
    return true;
  }

  // ∂F/∂x of StepResidual, exact from the blocks of solver/newton_euler_jacobian.hpp:
  // q̇_{n+1} and q̈_{n+1} are affine in q_{n+1} (slopes γ/(βh) and
  // (1 − αm)/((1 − αf) β h²)), so ∂r/∂q_{n+1} = ∂r/∂q + γ/(βh) ∂r/∂q̇ + … ∂r/∂q̈; each contact
  // as a Jet of 10 over (q, c_i). False when a surface is evaluated outside its domain.
  bool StepJacobian(const StepState& from, double h, const double* x, XMatrix* Jout) const {
    XMatrix& J = *Jout;
    J.setZero(n_, n_);
    const int k = static_cast<int>(active_.size());
    Vector6d q, qd, qdd, a;
    StepKinematics(from, h, x, &q, &qd, &qdd, &a);
    const double dqd_dq = scheme_.gamma / (scheme_.beta * h);
    const double dqdd_dq = (1.0 - scheme_.alpha_m) / ((1.0 - scheme_.alpha_f) * scheme_.beta * h * h);
    const double row_scale = RowScale(h);
    data_.ligament_branch = &ligament_branch_;
    NewtonEulerPartials free;
    FreeNewtonEulerPartials(model_, from.t + h, q, qd, qdd, data_, &free);
    J.topLeftCorner(6, 6) = -row_scale * (free.d_q + dqd_dq * free.d_qd + dqdd_dq * free.d_qdd);
    const PoseTpl<ContactJet> pose = PoseWithCoordinateDerivatives<kContactJetSize>(q);
    const double* N = x + 6 + per_contact_ * k;
    for (int c = 0; c < k; ++c) {
      const ContactPair& pair = model_.contacts[active_[c]];
      const int col_c = 6 + per_contact_ * c;
      auto put = [&](int row, const ContactJet& v, double scale) {
        for (int j = 0; j < 6; ++j) J(row, j) += scale * v.v[j];
        for (int j = 0; j < per_contact_; ++j) J(row, col_c + j) += scale * v.v[6 + j];
      };
      ContactGeometryTpl<ContactJet> geo;
      if (form_ == ContactForm::kChapter) {
        ContactJet coords[4], r[5];
        for (int j = 0; j < 4; ++j) coords[j] = ContactJet(x[col_c + j], 6 + j);
        if (!ChapterContactResiduals(pair, pose, coords, r, &geo, state_contact_[active_[c]].chart)) return false;
        for (int j = 0; j < 5; ++j) put(6 + 5 * c + j, r[j], 1.0);
      } else {
        if (!ContactKinematics(pair, pose, &geo)) return false;
        put(6 + c, geo.gap, 1.0);
      }
      // F_NE = −RowScale (r_free − Σ N_i G_iᵀ).
      const Eigen::Matrix<ContactJet, 1, 6> G = ContactConstraintRow(pose, geo);
      const int col_N = 6 + per_contact_ * k + c;
      for (int i = 0; i < 6; ++i) {
        J(i, col_N) += row_scale * G(i).a;
        put(i, G(i), row_scale * N[c]);
      }
    }
    return true;
  }

  // Starting values of generalized-α (Newmark, Δα = αm − αf = 0 and αf = 0: q̇_0, a_0 = q̈_0
  // unchanged):
  //   a_0 = q̈_0 + Δα h q⃛_0                               (≈ q̈(t_0 + Δα h), Arnold & Brüls 2007)
  //   q̇_0 = q̇(t_0) + h² (1/6 − Δα/2 − β) q⃛_0            (perturbed start)
  // Why the second: along a constrained direction the positions are exact (φ = 0 each step),
  // so (e_v, h e_a), the errors of q̇_n and a_n, follow E_{n+1} = A E_n + δ_n with A
  // independent of h (eigenvalues of modulus ≤ ρ∞) and δ_n the scheme's defects on the exact
  // solution: position defect d = h³ q⃛ (1/6 − Δα/2 − β) (enters as d/(βh) in h e_a),
  // velocity defect O(h³) (γ = ½ − Δα). The smooth solution of the recursion is
  // e_v = d/h = h² q⃛ (1/6 − Δα/2 − β), h e_a = O(h³); an exact start (e_v = 0) differs from it
  // by O(h²) in e_v, which A turns into an O(h²) transient in h e_a, i.e. O(h) in a, q̈ and
  // the multipliers, decaying like ρ∞ⁿ (the initial layer seen on the manufactured knee).
  // Starting on the smooth solution removes it: the multipliers become second order over
  // the whole run (tests/exact_solution_test.cpp, manufactured knee; figures in
  // benchmarks/README.md, "Work-precision sweep"). The O(h²) velocity perturbation is within
  // the scheme's error.
  // q⃛_0 from the hidden constraint (solver/constrained_dynamics.hpp) along the Taylor path
  // q(t_0 ± s) = q_0 ± s q̇_0 + ½ s² q̈_0, q̇(t_0 ± s) = q̇_0 ± s q̈_0, by the central difference
  // with s = 1e-5 s (truncation ~s² |q⁽⁵⁾|/6, round-off ~ε|q̈|/s ≈ 1e-11 |q̈|; a forward
  // difference would leave an O(s) term, e.g. ½ s ω² q̈_0 on a linear oscillator whose
  // q⃛_0 is 0).
  void PerturbedStart(const MechanicalState& state, StepState* start) const {
    const double delta_alpha = scheme_.alpha_m - scheme_.alpha_f;
    start->a = state.qdd;
    if (delta_alpha == 0.0 && scheme_.alpha_f == 0.0) return;  // Newmark
    const double s = 1.0e-5;
    const Vector6d q_plus = state.q + s * state.qd + 0.5 * s * s * state.qdd;
    const Vector6d q_minus = state.q - s * state.qd + 0.5 * s * s * state.qdd;
    const Vector6d qdd_plus = SolveConstrainedAcceleration(model_, state.t + s, q_plus, state.qd + s * state.qdd,
                                                           active_, {}, &ligament_branch_).qdd;
    const Vector6d qdd_minus = SolveConstrainedAcceleration(model_, state.t - s, q_minus, state.qd - s * state.qdd,
                                                            active_, {}, &ligament_branch_).qdd;
    const Vector6d jerk = (qdd_plus - qdd_minus) / (2.0 * s);
    start->a = state.qdd + delta_alpha * step_ * jerk;
    start->qd = state.qd + step_ * step_ * (1.0 / 6.0 - 0.5 * delta_alpha - scheme_.beta) * jerk;
  }

  // The scheme's formulas (Newmark: a = q̈ = 4/h² (q − q_n − h q̇_n) − q̈_n):
  //   a_{n+1} = (q_{n+1} − q_n − h q̇_n − h² (½ − β) a_n) / (β h²)
  //   q̈_{n+1} = ((1 − αm) a_{n+1} + αm a_n − αf q̈_n) / (1 − αf)
  //   q̇_{n+1} = q̇_n + h ((1 − γ) a_n + γ a_{n+1})
  template <typename T>
  T PseudoAcceleration(const StepState& from, double h, int i, const T& q_next) const {
    return (q_next - from.q(i) - h * from.qd(i) - (h * h * (0.5 - scheme_.beta)) * from.a(i)) /
           (scheme_.beta * h * h);
  }
  template <typename T>
  T Acceleration(const StepState& from, int i, const T& a_next) const {
    return ((1.0 - scheme_.alpha_m) * a_next + scheme_.alpha_m * from.a(i) - scheme_.alpha_f * from.qdd(i)) /
           (1.0 - scheme_.alpha_f);
  }
  // q_{n+1} (the first six unknowns x) and what the scheme makes of it: a_{n+1}, q̈_{n+1},
  // q̇_{n+1} by the three formulas above. The residual, its Jacobian and the accepted step
  // all take them from here.
  template <typename T>
  void StepKinematics(const StepState& from, double h, const T* x, Vector6<T>* q, Vector6<T>* qd,
                      Vector6<T>* qdd, Vector6<T>* a) const {
    for (int i = 0; i < 6; ++i) {
      (*q)(i) = x[i];
      (*a)(i) = PseudoAcceleration(from, h, i, x[i]);
      (*qdd)(i) = Acceleration(from, i, (*a)(i));
      (*qd)(i) = from.qd(i) + h * ((1.0 - scheme_.gamma) * from.a(i) + scheme_.gamma * (*a)(i));
    }
  }
  // ∂q̈_{n+1}/∂q_{n+1} inverted: the Newton–Euler rows are scaled by it (h²/4 for
  // Newmark) so that they read ~ M Δq.
  double RowScale(double h) const {
    return scheme_.beta * h * h * (1.0 - scheme_.alpha_f) / (1.0 - scheme_.alpha_m);
  }

 private:
  // Newton–Raphson for one step; false on failure (no convergence, bad evaluation,
  // singular tangent). Counts its work in stats_.
  bool SolveStep(const StepState& from_given, double h, StepState* to) {
    const int k = static_cast<int>(active_.size());
    StepState from = from_given;
    RescalePseudoAcceleration(h, &from);
    XVector x(n_);
    x.head<6>() = from.q + h * from.qd + 0.5 * h * h * from.qdd;  // predictor: q̈ constant
    x.tail(n_ - 6) = from.extra;
    JetD* xj = xj_.data();
    JetD* Fj = Fj_.data();
    XMatrix J(n_, n_);
    XVector F(n_);
    const int first_force = 6 + per_contact_ * k;
    int worst = -1;  // largest weighted Newton update of the last iteration (failure message)
    double worst_update = 0.0;
    for (int iter = 0; iter < kMaxNewtonIterations; ++iter) {
      bool ok = false;
      try {
        if (jet_jacobian_) {  // --jacobian jet: one Jet<24> pass gives F and ∂F/∂x
          for (int i = 0; i < n_; ++i) xj[i] = JetD(x(i), i);
          ok = StepResidual(from, h, xj, Fj);
          if (ok) {
            for (int r = 0; r < n_; ++r) {
              F(r) = Fj[r].a;
              for (int c = 0; c < n_; ++c) J(r, c) = Fj[r].v[c];
            }
          }
        } else {
          ok = StepResidual(from, h, x.data(), F.data()) && StepJacobian(from, h, x.data(), &J);
        }
        if (!ok) NoteFailure("a contact surface evaluated outside its domain");
      } catch (const SolverError& e) {
        ok = false;  // e.g. the JCS singularity at a Newton iterate: kept for the final error
        NoteFailure(e.what());
      }
      ++stats_.residual_evaluations;
      ++stats_.jacobian_evaluations;
      if (!ok) return false;
      if (!F.allFinite() || !J.allFinite()) return NoteFailure("non-finite residual or tangent");
      // Column equilibration: the force columns are h²/4 G (RowScale G); solve for
      // RowScale ΔN instead.
      for (int c = first_force; c < n_; ++c) J.col(c) *= 1.0 / RowScale(h);
      const Eigen::FullPivLU<XMatrix> lu(J);
      ++stats_.linear_solver_setups;
      ++stats_.nonlinear_iterations;
      if (!lu.isInvertible()) return NoteFailure("singular tangent matrix");
      XVector dx = lu.solve(-F);
      dx.tail(n_ - first_force) *= 1.0 / RowScale(h);
      x += dx;
      if (!x.allFinite()) return NoteFailure("non-finite Newton iterate");
      double norm_positions = 0.0, norm_forces = 0.0, worst_ratio = -1.0;
      for (int i = 0; i < n_; ++i) {
        const bool force = i >= first_force;
        const double tol = options_.rtol * std::abs(x(i)) +
                           (force ? kForceAtolScale * options_.atol : options_.atol);
        double& norm = force ? norm_forces : norm_positions;
        const double ratio = std::abs(dx(i)) / tol;
        norm = std::max(norm, ratio);
        if (ratio > worst_ratio) {
          worst_ratio = ratio;
          worst = i;
          worst_update = dx(i);
        }
      }
      if (norm_positions <= 1.0 &&
          (norm_forces <= 1.0 || norm_positions <= kMultiplierAcceptFactor)) {
        to->t = from.t + h;
        StepKinematics(from, h, x.data(), &to->q, &to->qd, &to->qdd, &to->a);
        to->extra = x.tail(n_ - 6);
        to->h_a = h;
        return true;
      }
    }
    return NoteFailure(StrCat("no convergence in ", kMaxNewtonIterations, " iterations (largest Newton update ",
                              UnknownName(worst), " = ", worst_update, " ", UnknownUnit(worst), " at t = ",
                              from.t + h, " s, h = ", h, " s)"));
  }

  // x = (q: x0 … gamma, contact coordinates (chapter form), N per active contact).
  std::string UnknownName(int i) const {
    if (i < 0) return "none";
    if (i < 6) return CoordinateName(i);
    const int k = static_cast<int>(active_.size());
    const int coords = per_contact_ * k;
    auto compartment = [&](int c) { return CompartmentName(model_.contacts[active_[c]].compartment); };
    if (i < 6 + coords) {
      static const char* kCoord[4] = {"x_c", "y_c", "x'_c", "y'_c"};
      return StrCat(compartment((i - 6) / per_contact_), " ", kCoord[(i - 6) % per_contact_]);
    }
    return StrCat("N_", compartment(i - 6 - coords));
  }
  const char* UnknownUnit(int i) const {
    if (i >= 3 && i < 6) return "rad";
    return i >= 6 + per_contact_ * static_cast<int>(active_.size()) ? "N" : "m";
  }

  // Generalized-α with a step h different from the one a_n belongs to (output times,
  // halvings, regrowth, the start): a_n ≈ q̈(t_n + Δα h_a), Δα = αm − αf, is moved to
  // q̈(t_n + Δα h) along the line through q̈_n, a_n ≈ q̈_n + Δα h_a q⃛, i.e.
  //   a_n ← q̈_n + (h / h_a)(a_n − q̈_n),
  // so that a step-size change perturbs a by O(h²) instead of O(h) (an O(h) perturbation
  // of a excites the O(h) multiplier layer of Arnold & Brüls 2007, section 4). Newmark
  // (a = q̈) is unchanged.
  static void RescalePseudoAcceleration(double h, StepState* s) {
    if (s->h_a <= 0.0 || s->h_a == h) return;
    s->a = s->qdd + (h / s->h_a) * (s->a - s->qdd);
    s->h_a = h;
  }

  // Records why a Newton solve failed, for the error after the last halving: one entry per
  // kind (the text before its first " = ", so values do not split a kind), with its last
  // text and a count, in order of first occurrence. Returns false.
  bool NoteFailure(const std::string& reason) {
    const std::string kind = reason.substr(0, reason.find(" = "));
    for (FailureReason& f : failure_reasons_) {
      if (f.kind == kind) {
        f.text = reason;
        ++f.count;
        return false;
      }
    }
    failure_reasons_.push_back({kind, reason, 1});
    return false;
  }

  // Takes one step from `from`, halving h on Newton failure; returns the step taken.
  double StepWithHalving(const StepState& from, double h, StepState* to) {
    failure_reasons_.clear();
    for (;;) {
      if (SolveStep(from, h, to)) return h;
      ++stats_.convergence_failures;
      if (h <= 1.000001 * step_ * std::ldexp(1.0, -kMaxHalvings)) {
        // The underlying reasons (e.g. the JCS singularity thrown by the rotation map).
        std::string reasons;
        for (const FailureReason& f : failure_reasons_) {
          reasons += StrCat(reasons.empty() ? "" : "; ", f.text, " [", f.count, f.count == 1 ? " attempt]" : " attempts]");
        }
        Throw<SolverError>("NewmarkFormulation::Step", "Newton–Raphson did not converge in ",
                           kMaxNewtonIterations, " iterations at t = ", from.t, " s with step h = ", h,
                           " s after ", kMaxHalvings, " halvings below the nominal step ", step_,
                           " s (rtol = ", options_.rtol, ", atol = ", options_.atol, "); failures: ", reasons);
      }
      h *= 0.5;
      ++stats_.step_halvings;
    }
  }

  std::vector<double> Events(const StepState& s) {
    std::vector<double> g(events_.size());
    EventsInto(s, g.data());
    return g;
  }
  void EventsInto(const StepState& s, double* g) {
    if (events_.empty()) return;
    const int k = static_cast<int>(active_.size());
    for (int c = 0; c < k; ++c) normal_[active_[c]] = s.extra(per_contact_ * k + c);
    EvaluateEvents(scene_.model, events_, s.q, normal_, g);
    ++stats_.root_evaluations;
  }

  // The state at t_n + s inside an accepted step: cubic Hermite in (q, q̇) at both ends
  // (exact at the ends, O(h⁴)), q̇ its derivative, q̈ and (c, N) linear.
  static StepState Interpolate(const StepState& a, const StepState& b, double s) {
    const double h = b.t - a.t;
    const double u = s / h;
    const double h00 = (1 + 2 * u) * (1 - u) * (1 - u), h10 = u * (1 - u) * (1 - u);
    const double h01 = u * u * (3 - 2 * u), h11 = u * u * (u - 1);
    const double d00 = 6 * u * (u - 1) / h, d10 = (1 - u) * (1 - 3 * u), d01 = -d00, d11 = u * (3 * u - 2);
    StepState out;
    out.t = a.t + s;
    out.q = h00 * a.q + h10 * h * a.qd + h01 * b.q + h11 * h * b.qd;
    out.qd = d00 * a.q + d10 * a.qd + d01 * b.q + d11 * b.qd;
    out.qdd = (1 - u) * a.qdd + u * b.qdd;
    out.a = (1 - u) * a.a + u * b.a;
    out.extra = (1 - u) * a.extra + u * b.extra;
    return out;
  }

  // The earliest root in s ∈ (0, h] of the events on the step's interpolant, narrowed by
  // the shared locator (event_locator.hpp) to kEventTimeResolution; returns the
  // interpolated state at the right end (just past the root) and the events that fired.
  // (Retaking the step with a small h′ instead would amplify the Newton tolerance in q̈
  // and N by 4/h′², the index-3 ill-conditioning of position-level constraints, and for
  // generalized-α it would also pair a_n with a step it does not belong to.)
  void LocateEvent(const StepState& from, double h, const StepState& at_h, const std::vector<double>& g_h,
                   StepState* out, std::vector<int>* fired) {
    LocateEarliestEvent(
        events_, g_current_, g_h, h, kEventTimeResolution, kMaxEventIterations,
        [&](double s, double* g) { EventsInto(Interpolate(from, at_h, s), g); }, &locator_, &located_);
    *out = Interpolate(from, at_h, located_.s);
    fired->assign(located_.fired.begin(), located_.fired.end());
  }

  // extra = (chapter coordinates, per_contact_ per active contact; normal forces).
  void WriteState(const StepState& s, MechanicalState* state) const {
    const int k = static_cast<int>(active_.size());
    WriteBack(s.t, s.q, s.qd, s.qdd, s.extra.data() + per_contact_ * k, per_contact_ > 0 ? s.extra.data() : nullptr,
              per_contact_, state);
    state->active = active_;
  }

  StepControl options_;
  ContactForm form_;
  NewmarkScheme scheme_;
  bool jet_jacobian_ = false;  // --jacobian jet: the Jet<24> tangent (the reference)
  double step_ = kDefaultFixedStep;  // s, nominal
  double h_ = kDefaultFixedStep;     // s, next step to try
  int n_ = 6;
  int per_contact_ = 4;
  long phase_steps_ = 0;
  StepState current_;
  std::vector<double> g_hot_path_;  // EvaluateHotPathForTesting
  std::vector<double> g_current_;
  EventLocatorWorkspace locator_;
  LocatedEvent located_;
  std::vector<double> g_next_;        // events at the step's end
  std::vector<int> fired_;            // events that fired in the step
  std::vector<double> normal_;        // N per model contact, for EvaluateEvents
  std::array<JetD, kMaxJetSize> xj_, Fj_;  // Newton unknowns and residual with ∂/∂x
  // Newton–Euler workspaces of StepResidual (ligament lengths and tensions per element),
  // sized once from the model.
  mutable DataTpl<double> data_;
  mutable DataTpl<JetD> data_jet_;
  DataTpl<double>& Workspace(double*) const { return data_; }
  DataTpl<JetD>& Workspace(JetD*) const { return data_jet_; }
  SolverStats stats_;
  struct FailureReason {
    std::string kind, text;
    int count = 0;
  };
  std::vector<FailureReason> failure_reasons_;  // this step's failed Newton solves
};

}  // namespace

bool ReadNewmarkOptions(const OptionRequest& request, NewmarkOptions* options) {
  const FormulationOptions& o = request.options;
  options->control = o.step_control();
  options->jacobian = o.jacobian.value_or(JacobianKind::kExact);
  options->scheme = NewmarkScheme();  // average acceleration: β = 1/4, γ = 1/2
  return true;
}

std::unique_ptr<Formulation> CreateNewmarkScheme(const Scene& scene, const NewmarkOptions& options,
                                                 ContactForm form) {
  return std::make_unique<NewmarkFormulation>(scene, options, form);
}

bool NewmarkTangentsForTesting(const Scene& scene, const NewmarkOptions& options, ContactForm form,
                               const MechanicalState& state, double h, int newton_steps, MatrixXd* exact,
                               MatrixXd* jet) {
  NewmarkFormulation f(scene, options, form);
  f.Start(state, {});
  return f.TangentsForTesting(h, newton_steps, exact, jet);
}

FormulationMaker ConfigureNewmark(const OptionRequest& request) {
  NewmarkOptions options;
  if (!ReadNewmarkOptions(request, &options)) return nullptr;
  return [options](const Scene& scene) { return CreateNewmarkScheme(scene, options, ContactForm::kChapter); };
}
FormulationMaker ConfigureNewmarkReduced(const OptionRequest& request) {
  NewmarkOptions options;
  if (!ReadNewmarkOptions(request, &options)) return nullptr;
  return [options](const Scene& scene) {
    return CreateNewmarkScheme(scene, options, ContactForm::kClosedForm);
  };
}

}  // namespace kneedyn
