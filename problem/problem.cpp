#include "problem/problem.hpp"

#include <algorithm>
#include <cmath>

#include "formulations/formulation.hpp"
#include "solver/consistent_init.hpp"
#include "solver/contact_kinematics.hpp"
#include "solver/constraint_residuals.hpp"
#include "solver/error.hpp"

namespace kneedyn {
namespace {

[[noreturn]] void Fail(const std::string& message) { throw ProblemError(message); }

// The physics refused the state an outside solver handed in (KNEEDYN_SOLVER_ERROR, not a bad
// argument): an integrator may shorten its step and try again.
[[noreturn]] void RefuseState(const char* call, double t, const std::string& what) {
  throw SolverError(StrCat("Problem::", call, ": at t = ", t, " s ", what,
                           " (rule: the state keeps every active contact on its surfaces' charts; a shorter step "
                           "stays closer to the last accepted state)"));
}

// Outputs computed from finite inputs must be finite: a state far outside the model's range
// (a velocity of 1e200, say) overflows the dynamics, and a NaN handed back would be carried
// on by an outside integrator without a word.
void RequireFinite(const char* call, const char* name, const double* values, size_t count, double t) {
  for (size_t i = 0; i < count; ++i) {
    if (!std::isfinite(values[i])) {
      throw SolverError(StrCat("Problem::", call, ": ", name, "[", i, "] = ", values[i], " at t = ", t,
                               " s from finite inputs (rule: every output is finite; the state lies outside the range "
                               "the model evaluates)"));
    }
  }
}

}  // namespace

Problem::Problem(const Scene& scene, const std::string& form, double rtol, double atol)
    : scene_(scene),
      form_(form),
      rtol_(rtol),
      atol_(atol),
      workspace_(scene.model),
      chart_(std::make_unique<MdeChart>(scene.model)) {
  if (form != "ede" && form != "mde" && form != "dae" && form != "dae-ggl") {
    Fail("Problem: form = '" + Echo(form) + "': one of 'ede', 'mde', 'dae', 'dae-ggl'");
  }
  if (!(rtol > 0.0 && rtol <= kMaxRtol) || !(atol > 0.0 && atol <= kMaxAtol)) {
    Fail(StrCat("Problem: rtol = ", rtol, ", atol = ", atol, ": rtol must lie in ", kRtolRange, " and atol in ", kAtolRange,
                " (SI: m, m/s, rad), as in kneedyn run"));
  }
  const ScopedAngularVelocityMapReading map_reading = MapReading();
  const Model& model = scene.model;
  ConsistentInitOptions init;  // as kneedyn run: every contact active at t0
  init.form = is_dae() ? ContactForm::kChapter : ContactForm::kClosedForm;
  std::vector<int> active;
  for (int i = 0; i < static_cast<int>(model.contacts.size()); ++i) active.push_back(i);
  InitReport report;
  try {
    state_ = ConsistentInitialize(model, scene.initial, active, init, &report);
    // A start whose consistent forces pull (an assembled pose; docs/model.md §6) starts with
    // those contacts' lift-offs, as Simulator::Initialize does.
    ReleasePullingContacts(model, RestartProjection::kProject, PullingContact::kSeparate, "", &state_, &events_);
    SolveConstrainedAcceleration(model, state_.t, state_.q, state_.qd, state_.active);  // dependent rows: refused
  } catch (const SolverError& e) {
    // The scene's start, refused before any call: the scene's fault (KNEEDYN_INPUT_ERROR, as
    // kneedyn run's exit code 2), not a state an integrator could retry.
    Throw<InputError>("Problem", "the scene's start is refused: ", e.what());
  }
  if (is_dae()) {
    dae_ = std::make_unique<DaeSystem>(model, ContactForm::kChapter, ConstraintLevel::kVelocity, form == "dae-ggl");
  }
  double rate = 0.0;
  MaxActiveConstraintResiduals(model, state_, &max_position_residual_, &rate);
  t0_ = state_.t;
  normal_.assign(model.contacts.size(), 0.0);
  acc_.normal_force.reserve(kMaxConstrainedContacts);
  BeginPhase();
}

void Problem::BeginPhase() {
  const double gap_tolerance = RecontactGapTolerance(max_position_residual_, state_.q, rtol_, atol_);
  bool released = false;  // recorded in events_
  specs_ = phase_ > 0 ? StartRestartedPhase(scene_.model, scene_.end, gap_tolerance, RestartProjection::kProject,
                                            PullingContact::kSeparate, &state_, &events_, &released)
                      : StartPhase(scene_.model, scene_.end, gap_tolerance, RestartProjection::kProject, &state_);
  if (is_dae()) {
    dae_->SetPhase(state_.active, state_.contact, state_.ligament_branch);
    n_ = dae_->size();
    y0_.assign(n_, 0.0);
    yp0_.assign(n_, 0.0);
    dae_->InitialValues(state_, y0_.data(), yp0_.data());
  } else if (is_mde()) {
    // As the mde formulation's Start: a fresh chart at the phase start.
    chart_->Begin(state_.active, state_.q);
    BeginChart();
  } else {
    n_ = 12;
    y0_.assign(12, 0.0);
    yp0_.assign(12, 0.0);
    for (int i = 0; i < 6; ++i) {
      y0_[i] = state_.q(i);
      y0_[6 + i] = state_.qd(i);
      yp0_[i] = state_.qd(i);
      yp0_[6 + i] = state_.qdd(i);
    }
  }
}

void Problem::BeginChart() {
  const std::vector<int>& free = chart_->free();
  const int m = static_cast<int>(free.size());
  n_ = 2 * m;
  y0_.assign(n_, 0.0);
  yp0_.assign(n_, 0.0);
  for (int j = 0; j < m; ++j) {
    y0_[j] = state_.q(free[j]);
    y0_[m + j] = state_.qd(free[j]);
  }
  Rhs(state_.t, y0_.data(), n_, yp0_.data());
}

void Problem::CheckOpen(const char* call) const {
  if (ended_) Fail(StrCat("Problem::", call, ": the run has ended (", end_reason_, "); no phase is open"));
}

void Problem::CheckState(const char* call, const char* name, const double* y, int n) const {
  CheckOpen(call);
  if (y == nullptr) Fail(StrCat("Problem::", call, ": ", name, " is a null array"));
  if (n != n_) {
    Fail(StrCat("Problem::", call, ": ", name, " of size ", n, ", but phase ", phase_, " of the '", form_, "' form has ",
                n_, " components"));
  }
  for (int i = 0; i < n; ++i) {
    if (!std::isfinite(y[i])) {
      Fail(StrCat("Problem::", call, ": ", name, "[", i, "] = ", y[i], ": every component must be finite"));
    }
  }
}

void Problem::CheckTime(const char* call, double t) const {
  if (!std::isfinite(t)) Fail(StrCat("Problem::", call, ": t = ", t, ": must be finite"));
}

std::vector<double> Problem::differential_ids() const {
  CheckOpen("differential_ids");
  std::vector<double> id(n_, 1.0);
  if (is_dae()) {
    for (int i = 0; i < n_; ++i) id[i] = dae_->IsDifferential(i) ? 1.0 : 0.0;
  }
  return id;
}

std::vector<std::string> Problem::component_names() const {
  CheckOpen("component_names");
  std::vector<std::string> names;
  for (int i = 0; i < n_; ++i) {
    if (is_dae()) {
      names.push_back(dae_->UnknownName(i));
    } else if (is_mde()) {
      const int m = n_ / 2;
      names.push_back(i < m ? std::string(CoordinateName(chart_->free()[i]))
                            : std::string(CoordinateName(chart_->free()[i - m])) + "_rate");
    } else {
      names.push_back(i < 6 ? std::string(CoordinateName(i)) : std::string(CoordinateName(i - 6)) + "_rate");
    }
  }
  return names;
}

void Problem::AccelerationAt(double t, const double* y) const {
  const Vector6d q = Eigen::Map<const Vector6d>(y);
  const Vector6d qd = Eigen::Map<const Vector6d>(y + 6);
  SolveConstrainedAcceleration(scene_.model, t, q, qd, state_.active, {}, &state_.ligament_branch, &workspace_, &acc_);
}

// The ede formulation's right-hand side (formulations/ede.cpp, --stabilization none), or
// the mde formulation's (formulations/mde.cpp: MdeChart::Evaluate in the chart in use).
void Problem::Rhs(double t, const double* y, int n, double* f) const {
  if (is_dae()) Fail(StrCat("Problem::Rhs: the '", form_, "' form is a DAE; call Residual"));
  CheckTime("Rhs", t);
  const ScopedAngularVelocityMapReading map_reading = MapReading();
  CheckState("Rhs", "y", y, n);
  if (is_mde()) {
    const int m = n_ / 2;
    VecM sdd(m);
    MdeEvaluate(t, y, &sdd);
    for (int j = 0; j < m; ++j) {
      f[j] = y[m + j];
      f[m + j] = sdd(j);
    }
  } else {
    AccelerationAt(t, y);
    for (int i = 0; i < 6; ++i) {
      f[i] = y[6 + i];
      f[6 + i] = acc_.qdd(i);
    }
  }
  RequireFinite("Rhs", "f", f, static_cast<size_t>(n_), t);
}

void Problem::Jacobian(double t, const double* y, int n, double* J) const {
  if (is_dae()) Fail(StrCat("Problem::Jacobian: the '", form_, "' form is a DAE; call Jacobian(t, y, yp, c)"));
  CheckTime("Jacobian", t);
  const ScopedAngularVelocityMapReading map_reading = MapReading();
  CheckState("Jacobian", "y", y, n);
  if (is_mde()) {
    MdeJacobian(t, y, J);
    RequireFinite("Jacobian", "J", J, static_cast<size_t>(n_) * n_, t);
    return;
  }
  AccelerationAt(t, y);
  double dqdd_dx[72];
  if (!ConstrainedAccelerationJacobian(scene_.model, t, Eigen::Map<const Vector6d>(y), Eigen::Map<const Vector6d>(y + 6),
                                       acc_.qdd, state_.active, acc_.normal_force, &state_.ligament_branch, dqdd_dx)) {
    RefuseState("Jacobian", t, "a contact surface is evaluated outside its domain");
  }
  for (int i = 0; i < 6; ++i) {
    for (int j = 0; j < 12; ++j) {
      J[12 * i + j] = j == 6 + i ? 1.0 : 0.0;  // ∂q̇/∂(q, q̇)
      J[12 * (6 + i) + j] = dqdd_dx[12 * i + j];
    }
  }
  RequireFinite("Jacobian", "J", J, 144, t);
}

// mde: f = (ṡ, s̈) with s̈ = q̈_F, the free rows of the constrained acceleration at
// (q(s), q̇(s, ṡ)) (the chart's elimination; mde and ede solve the same equations). Chain rule:
//   ∂q/∂s = P = [I; −J_D⁻¹ J_F] (J = ∂φ/∂q), ∂q̇/∂ṡ = P,
//   ∂q̇/∂s: F rows 0, D rows −J_D⁻¹ (∂φ̇/∂q) P (from φ̇(q(s), q̇(s, ṡ)) ≡ 0, ∂φ̇/∂q̇ = J),
//   ∂s̈/∂(s, ṡ) = A_F [P 0; ∂q̇/∂s P],  A = ∂q̈/∂(q, q̇) (ConstrainedAccelerationJacobian);
// J and ∂φ̇/∂q by forward AD (ceres::Jet over q) through the contact kinematics of any pair.
MdeKinematics Problem::MdeEvaluate(double t, const double* y, VecM* sdd) const {
  const MdeKinematics kin = chart_->Evaluate(t, y, &state_.ligament_branch, sdd);
  chart_->SetStartPose(kin);
  return kin;
}

void Problem::MdeJacobian(double t, const double* y, double* Jf) const {
  const Model& model = scene_.model;
  const std::vector<int>& active = state_.active;
  const int k = static_cast<int>(active.size());
  VecM sdd(n_ / 2);
  const MdeKinematics kin = MdeEvaluate(t, y, &sdd);
  std::vector<double> normal_force(kin.normal_force.begin(), kin.normal_force.begin() + k);
  double A[72];
  if (!ConstrainedAccelerationJacobian(model, t, kin.q, kin.qd, kin.qdd, active, normal_force, &state_.ligament_branch,
                                       A)) {
    RefuseState("Jacobian", t, "a contact surface is evaluated outside its domain");
  }
  using Jet6 = ceres::Jet<double, 6>;
  Vector6<Jet6> qj, qdj;
  for (int i = 0; i < 6; ++i) qj(i) = Jet6(kin.q(i), i), qdj(i) = Jet6(kin.qd(i));
  const PoseTpl<Jet6> pose = PoseFromCoordinates(qj);
  const Vector6<Jet6> nu = GeneralizedVelocity(qj, qdj);
  MatrixXd phi_q(k, 6), phidot_q(k, 6);
  for (int c = 0; c < k; ++c) {
    ContactGeometryTpl<Jet6> geo;
    if (!ContactKinematics(model.contacts[active[c]], pose, &geo)) {
      RefuseState("Jacobian", t, StrCat("the ", CompartmentName(model.contacts[active[c]].compartment),
                                        " contact has no contact point"));
    }
    const Jet6 phidot = ContactConstraintRow(pose, geo).dot(nu);
    for (int i = 0; i < 6; ++i) phi_q(c, i) = geo.gap.v(i), phidot_q(c, i) = phidot.v(i);
  }
  const std::vector<int>& free = chart_->free();
  const std::vector<int>& elim = chart_->eliminated();
  const int m = static_cast<int>(free.size());
  MatrixXd P = MatrixXd::Zero(6, m), dqd_ds = MatrixXd::Zero(6, m);
  for (int j = 0; j < m; ++j) P(free[j], j) = 1.0;
  if (k > 0) {
    MatrixXd JD(k, k), JF(k, m);
    for (int c = 0; c < k; ++c) JD.col(c) = phi_q.col(elim[c]);
    for (int j = 0; j < m; ++j) JF.col(j) = phi_q.col(free[j]);
    const Eigen::FullPivLU<MatrixXd> lu(JD);
    const MatrixXd PD = -lu.solve(JF);
    for (int c = 0; c < k; ++c) P.row(elim[c]) = PD.row(c);
    const MatrixXd dD = -lu.solve(phidot_q * P);
    for (int c = 0; c < k; ++c) dqd_ds.row(elim[c]) = dD.row(c);
  }
  const Eigen::Map<const Eigen::Matrix<double, 6, 12, Eigen::RowMajor>> dqdd(A);
  const MatrixXd dsdd_ds = dqdd.leftCols(6) * P + dqdd.rightCols(6) * dqd_ds;
  const MatrixXd dsdd_dsd = dqdd.rightCols(6) * P;
  const int n = 2 * m;
  for (int i = 0; i < m; ++i) {
    for (int j = 0; j < n; ++j) {
      Jf[n * i + j] = j == m + i ? 1.0 : 0.0;  // ∂ṡ/∂(s, ṡ)
      Jf[n * (m + i) + j] = j < m ? dsdd_ds(free[i], j) : dsdd_dsd(free[i], j - m);
    }
  }
}

void Problem::Residual(double t, const double* y, const double* yp, int n, double* F) const {
  if (!is_dae()) Fail(StrCat("Problem::Residual: the '", form_, "' form is an ODE; call Rhs"));
  CheckTime("Residual", t);
  const ScopedAngularVelocityMapReading map_reading = MapReading();
  CheckState("Residual", "y", y, n);
  CheckState("Residual", "yp", yp, n);
  if (!dae_->Residual(t, y, yp, F)) RefuseState("Residual", t, "a contact surface is evaluated outside its domain");
  RequireFinite("Residual", "F", F, static_cast<size_t>(n_), t);
}

void Problem::Jacobian(double t, const double* y, const double* yp, double c, int n, double* J) const {
  if (!is_dae()) Fail(StrCat("Problem::Jacobian: the '", form_, "' form is an ODE; call Jacobian(t, y)"));
  CheckTime("Jacobian", t);
  const ScopedAngularVelocityMapReading map_reading = MapReading();
  CheckState("Jacobian", "y", y, n);
  CheckState("Jacobian", "yp", yp, n);
  if (!std::isfinite(c)) Fail(StrCat("Problem::Jacobian: c = ", c, ": must be finite"));
  std::vector<double> column_major(static_cast<size_t>(n_) * n_);
  if (!dae_->Jacobian(t, c, y, yp, column_major.data())) {
    RefuseState("Jacobian", t, "a contact surface is evaluated outside its domain");
  }
  for (int i = 0; i < n_; ++i) {
    for (int j = 0; j < n_; ++j) J[n_ * i + j] = column_major[static_cast<size_t>(n_) * j + i];
  }
  RequireFinite("Jacobian", "J", J, static_cast<size_t>(n_) * n_, t);
}

std::vector<std::string> Problem::event_names() const {
  CheckOpen("event_names");
  std::vector<std::string> names;
  for (const EventSpec& e : specs_) names.push_back(e.name);
  if (has_chart_event()) names.push_back(kChartEvent);
  return names;
}

std::vector<int> Problem::event_directions() const {
  CheckOpen("event_directions");
  std::vector<int> d;
  for (const EventSpec& e : specs_) d.push_back(e.direction);
  if (has_chart_event()) d.push_back(-1);
  return d;
}

// The formulations' root functions (ede.cpp, dae.cpp: N from the hidden constraint or from y).
void Problem::Events(double t, const double* y, int n, double* g) const {
  CheckTime("Events", t);
  const ScopedAngularVelocityMapReading map_reading = MapReading();
  CheckState("Events", "y", y, n);
  std::fill(normal_.begin(), normal_.end(), 0.0);
  if (is_mde()) {  // the mde formulation's Roots, then the chart's conditioning
    const MdeKinematics kin = MdeEvaluate(t, y, nullptr);
    for (size_t c = 0; c < state_.active.size(); ++c) normal_[state_.active[c]] = kin.normal_force[c];
    EvaluateEvents(scene_.model, specs_, kin.q, normal_, g);
    if (has_chart_event()) {
      double current = 0.0, best = 0.0;
      chart_->Conditioning(kin.q, &current, &best);
      g[specs_.size()] = current - kChartKeepFraction * best;  // the formulation's switch threshold
    }
    RequireFinite("Events", "g", g, static_cast<size_t>(event_count()), t);
    return;
  }
  const Vector6d q = Eigen::Map<const Vector6d>(y);
  if (is_dae()) {
    for (size_t c = 0; c < state_.active.size(); ++c) normal_[state_.active[c]] = y[dae_->NormalIndex(static_cast<int>(c))];
  } else if (!state_.active.empty()) {
    AccelerationAt(t, y);
    for (size_t c = 0; c < state_.active.size(); ++c) normal_[state_.active[c]] = acc_.normal_force[c];
  }
  EvaluateEvents(scene_.model, specs_, q, normal_, g);
  RequireFinite("Events", "g", g, static_cast<size_t>(event_count()), t);
}

MechanicalState Problem::StateAt(double t, const double* y, const double* yp) const {
  const ScopedAngularVelocityMapReading map_reading = MapReading();
  MechanicalState s = state_;
  s.t = t;
  if (!is_mde()) {  // mde's y is (s, ṡ) of the chart's free coordinates, 2m ≤ 12 values
    s.q = Eigen::Map<const Vector6d>(y);
    s.qd = Eigen::Map<const Vector6d>(y + 6);
  }
  if (is_dae()) {
    // q̈ from ẏ when given (the transition recomputes it from q, q̇ in any case).
    s.qdd = yp != nullptr ? Vector6d(Eigen::Map<const Vector6d>(yp + 6)) : Vector6d::Zero();
    const int per_contact = dae_->per_contact();
    for (size_t c = 0; c < s.active.size(); ++c) {
      ContactGuess& guess = s.contact[s.active[c]];
      for (int j = 0; j < per_contact; ++j) guess.coordinates[j] = y[dae_->CoordinateIndex(static_cast<int>(c)) + j];
      guess.normal_force = y[dae_->NormalIndex(static_cast<int>(c))];
    }
  } else if (is_mde()) {
    VecM sdd(n_ / 2);
    const MdeKinematics kin = MdeEvaluate(t, y, &sdd);
    s.q = kin.q;
    s.qd = kin.qd;
    s.qdd = kin.qdd;
    for (size_t c = 0; c < s.active.size(); ++c) s.contact[s.active[c]].normal_force = kin.normal_force[c];
    FillContactCoordinates(scene_.model, &s);
  } else {
    AccelerationAt(t, y);
    s.qdd = acc_.qdd;
    for (size_t c = 0; c < s.active.size(); ++c) s.contact[s.active[c]].normal_force = acc_.normal_force[c];
    FillContactCoordinates(scene_.model, &s);
  }
  return s;
}

// Everything Transition and BeginPhase assign. The DAE system's phase is set again from the
// saved state on Restore (DaeSystem::SetPhase is a function of it).
struct Problem::PhaseSnapshot {
  int n, phase;
  bool ended;
  std::string end_reason;
  double max_position_residual;
  MechanicalState state;
  std::vector<EventSpec> specs;
  size_t events_size;
  std::vector<double> y0, yp0;
  std::unique_ptr<MdeChart> chart;
};

Problem::PhaseSnapshot Problem::Save() const {
  return PhaseSnapshot{n_,     phase_, ended_, end_reason_, max_position_residual_, state_, specs_, events_.size(),
                       y0_,    yp0_,   std::make_unique<MdeChart>(*chart_)};
}

void Problem::Restore(PhaseSnapshot&& saved) {
  n_ = saved.n;
  phase_ = saved.phase;
  ended_ = saved.ended;
  end_reason_ = std::move(saved.end_reason);
  max_position_residual_ = saved.max_position_residual;
  state_ = std::move(saved.state);
  specs_ = std::move(saved.specs);
  events_.resize(saved.events_size);
  y0_ = std::move(saved.y0);
  yp0_ = std::move(saved.yp0);
  chart_ = std::move(saved.chart);
  if (is_dae()) dae_->SetPhase(state_.active, state_.contact, state_.ligament_branch);
}

bool Problem::Transition(double t, const double* y, const double* yp, int n, const std::vector<int>& events) {
  CheckTime("Transition", t);
  const ScopedAngularVelocityMapReading map_reading = MapReading();
  CheckState("Transition", "y", y, n);
  if (is_dae()) CheckState("Transition", "yp", yp, n);
  if (t < state_.t || t > scene_.end.time) {
    Fail(StrCat("Problem::Transition: t = ", t, " s: must lie in phase ", phase_, "'s [", state_.t, ", ", scene_.end.time,
                "] s (from its start to t_end)"));
  }
  if (events.empty()) Fail("Problem::Transition: no event given");
  for (size_t i = 0; i < events.size(); ++i) {
    const int k = events[i];
    if (k < 0 || k >= event_count()) {
      Fail(StrCat("Problem::Transition: event = ", k, ": phase ", phase_, " has events 0 to ", event_count() - 1));
    }
    if (std::find(events.begin(), events.begin() + i, k) != events.begin() + i) {
      Fail(StrCat("Problem::Transition: event = ", k, " is given twice: each root once"));
    }
  }
  PhaseSnapshot saved = Save();
  try {
    return TransitionUnguarded(t, y, yp, events);
  } catch (...) {
    Restore(std::move(saved));
    throw;
  }
}

bool Problem::TransitionUnguarded(double t, const double* y, const double* yp, const std::vector<int>& events) {
  MechanicalState s = StateAt(t, y, yp);
  // mde: the chart alone switches (the formulation's restart after a step, at its root here).
  const int chart_event = has_chart_event() ? static_cast<int>(specs_.size()) : -1;
  if (std::find(events.begin(), events.end(), chart_event) != events.end()) {
    if (events.size() > 1) {
      Fail(StrCat("Problem::Transition: '", kChartEvent, "' together with another event: hand them one at a time"));
    }
    state_.t = s.t, state_.q = s.q, state_.qd = s.qd, state_.qdd = s.qdd;
    chart_->ChooseAfresh(s.q);
    chart_->SetStartPose(s.q);
    BeginChart();
    return false;
  }
  // A ligament crossing the published law's jump alone only restarts the phase
  // (Simulator::Run): new branches, no mode switch, no sample.
  bool only_kinks = true;
  for (int k : events) only_kinks = only_kinks && specs_[k].kind == EventKind::kLigamentKink;
  if (only_kinks) {
    state_ = s;
    ++phase_;
    BeginPhase();
    return false;
  }
  double gap = 0.0, rate = 0.0;
  MaxActiveConstraintResiduals(scene_.model, s, &gap, &rate);
  max_position_residual_ = std::max(max_position_residual_, gap);
  const TransitionOutcome outcome =
      PhaseTransition(scene_.model, specs_, events, RestartProjection::kProject, PullingContact::kSeparate, &s, &events_);
  if (outcome.ended) {
    ended_ = true;
    end_reason_ = outcome.end_reason;
    state_ = s;
    return true;
  }
  state_ = s;
  ++phase_;
  BeginPhase();
  return false;
}

}  // namespace kneedyn
