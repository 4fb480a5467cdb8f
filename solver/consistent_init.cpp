#include "solver/consistent_init.hpp"

#include <algorithm>
#include <cmath>
#include <exception>
#include <limits>
#include <memory>
#include <vector>

#include <Eigen/LU>

#include "solver/ceres_fallback.hpp"
#include "solver/constrained_dynamics.hpp"
#include "solver/contact_kinematics.hpp"
#include "solver/error.hpp"
#include "solver/patella.hpp"
#include "solver/scalar.hpp"

namespace kneedyn {
namespace {

constexpr int kStride = 4;  // Jet size of each forward-AD pass (as Ceres's DynamicAutoDiffCostFunction<F, 4>)

// Position level: the pose with the free coordinates taken from the unknowns x[0].
struct PositionUnknowns {
  const Model* model;
  Vector6d q_fixed;
  std::vector<int> free;    // coordinate indices
  std::vector<int> active;  // contact indices
  ContactChart chart = ContactChart::kRegular;

  template <typename T>
  PoseTpl<T> PoseOf(T const* x) const {
    Vector6<T> q = q_fixed.cast<T>();
    for (size_t i = 0; i < free.size(); ++i) q(free[i]) = x[i];
    return PoseFromCoordinates(q);
  }
};

// Chapter form: unknowns = free coordinates + 4 per active contact; 5 residuals each.
struct ChapterPositionResidual : PositionUnknowns {
  template <typename T>
  bool operator()(T const* const* x, T* r) const {
    const PoseTpl<T> pose = PoseOf(x[0]);
    for (size_t k = 0; k < active.size(); ++k) {
      const T* c = x[0] + free.size() + 4 * k;
      if (!ChapterContactResiduals(model->contacts[active[k]], pose, c, r + 5 * k,
                                   static_cast<ContactGeometryTpl<T>*>(nullptr), chart)) {
        return false;
      }
    }
    return true;
  }
};

// Gap form: unknowns = free coordinates; residual φ_i per contact (contact_kinematics.hpp).
struct ClosedPositionResidual : PositionUnknowns {
  template <typename T>
  bool operator()(T const* const* x, T* r) const {
    const PoseTpl<T> pose = PoseOf(x[0]);
    for (size_t k = 0; k < active.size(); ++k) {
      ContactGeometryTpl<T> geo;
      if (!ContactKinematics(model->contacts[active[k]], pose, &geo)) return false;
      r[k] = geo.gap;
    }
    return true;
  }
};

// Hidden level: unknowns (ν̇, N); residuals M ν̇ − Q − Gᵀ N (6) and G ν̇ + κ (k).
struct HiddenResidual {
  Matrix6d M;
  Vector6d Q;
  MatrixXd G;  // k×6
  VectorXd kappa;

  template <typename T>
  bool operator()(T const* const* x, T* r) const {
    const int k = static_cast<int>(G.rows());
    for (int i = 0; i < 6; ++i) {
      T s = T(-Q(i));
      for (int j = 0; j < 6; ++j) s += M(i, j) * x[0][j];
      for (int c = 0; c < k; ++c) s -= G(c, i) * x[0][6 + c];
      r[i] = s;
    }
    for (int c = 0; c < k; ++c) {
      T s = T(kappa(c));
      for (int j = 0; j < 6; ++j) s += G(c, j) * x[0][j];
      r[6 + c] = s;
    }
    return true;
  }
};

template <typename Functor>
double MaxResidual(const Functor& f, const std::vector<double>& x, int num_residuals) {
  std::vector<double> r(num_residuals);
  const double* params[] = {x.data()};
  if (!f(params, r.data())) return std::numeric_limits<double>::infinity();
  double m = 0.0;
  for (double v : r) m = std::max(m, std::abs(v));
  return m;
}

// r(x) and, if J is not null, the row-major num_residuals × n Jacobian by forward AD in
// passes of kStride unknowns: what Ceres's DynamicAutoDiffCostFunction<Functor, kStride>
// computes (the same Jet operations, so the same bits), without linking Ceres itself
// (solver/ceres_fallback.hpp).
template <typename Functor>
bool EvaluateResidual(const Functor& f, const double* x, int n, int num_residuals, double* r, double* J) {
  if (J == nullptr) {
    const double* params[] = {x};
    return f(params, r);
  }
  using JetT = ceres::Jet<double, kStride>;
  std::vector<JetT> xj(n), rj(num_residuals);
  const JetT* params[] = {xj.data()};
  for (int start = 0; start < n; start += kStride) {
    for (int i = 0; i < n; ++i) {
      xj[i].a = x[i];
      xj[i].v.setZero();
      if (i >= start && i < start + kStride) xj[i].v[i - start] = 1.0;
    }
    if (!f(params, rj.data())) return false;
    for (int k = 0; k < num_residuals; ++k) {
      for (int j = start; j < std::min(n, start + kStride); ++j) J[k * n + j] = rj[k].v[j - start];
    }
  }
  for (int k = 0; k < num_residuals; ++k) r[k] = rj[k].a;
  return true;
}

// The C callback of the Ceres plugin: a functor and its sizes; an exception thrown by the
// functor (e.g. the JCS singularity of solver/rotation.hpp) is kept and rethrown after
// Ceres returns, since nothing may cross the plugin's C interface.
template <typename Functor>
struct FallbackProblem {
  const Functor* functor;
  int n, num_residuals;
  std::exception_ptr error;
  static int Evaluate(void* user, const double* x, double* r, double* J) {
    auto* self = static_cast<FallbackProblem*>(user);
    try {
      return EvaluateResidual(*self->functor, x, self->n, self->num_residuals, r, J) ? 1 : 0;
    } catch (...) {
      if (!self->error) self->error = std::current_exception();
      return 0;
    }
  }
};

// The direct path: Newton's method on a square system (as many unknowns as residuals) with
// the Jacobian from the same automatic differentiation Ceres would use. Iterates until the
// step no longer changes x (relative 1e-15), as Ceres's parameter tolerance does, so both
// paths end at the same root to round-off. Returns false, leaving *x unchanged, when the
// system is not square, the functor fails, the Jacobian is singular or the residual does
// not reach `tolerance` within `max_iterations`: the caller falls back to Ceres.
template <typename Functor>
bool SolveLevelByNewton(const Functor& functor, std::vector<double>* x, int num_residuals,
                        double tolerance, int max_iterations, int* iterations) {
  const int n = static_cast<int>(x->size());
  if (n != num_residuals || n == 0 || max_iterations < 1) return false;
  Eigen::Map<VectorXd> xv(x->data(), n);
  const VectorXd x_start = xv;
  VectorXd r(n);
  Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> J(n, n);
  bool converged = false;
  int it = 0;
  double previous = std::numeric_limits<double>::infinity();
  for (; it < max_iterations; ++it) {
    if (!EvaluateResidual(functor, x->data(), n, n, r.data(), J.data()) || !r.allFinite() || !J.allFinite()) break;
    // At the root's round-off level the residual stops falling: done.
    const double current = r.cwiseAbs().maxCoeff();
    if (current <= tolerance && (current == 0.0 || current >= previous)) {
      converged = true;
      break;
    }
    previous = current;
    const Eigen::PartialPivLU<MatrixXd> lu(J);
    // A (near-)singular Jacobian: no unique Newton step; Ceres's damped steps handle it.
    if (!(std::abs(lu.determinant()) > 0.0) || lu.rcond() < 1e-14) break;
    const VectorXd step = lu.solve(r);
    if (!step.allFinite()) break;
    xv -= step;
    if (step.cwiseAbs().maxCoeff() <= 1e-15 * std::max(1.0, xv.cwiseAbs().maxCoeff())) {
      converged = true;
      ++it;
      break;
    }
  }
  if (converged && MaxResidual(functor, *x, num_residuals) <= tolerance) {
    *iterations = it;
    return true;
  }
  xv = x_start;
  return false;
}

template <typename Functor>
InitLevelReport SolveLevel(const char* level, Functor* functor, std::vector<double>* x,
                           int num_residuals, double tolerance, const ConsistentInitOptions& options) {
  InitLevelReport rep;
  rep.residual_before = MaxResidual(*functor, *x, num_residuals);
  // Nothing free (every coordinate held, closed form): nothing to solve; Ceres would abort.
  if (rep.residual_before > tolerance && !x->empty()) {
    if (SolveLevelByNewton(*functor, x, num_residuals, tolerance, options.newton_iterations,
                           &rep.iterations)) {
      rep.method = InitMethod::kNewton;
    } else {
      rep.method = InitMethod::kCeres;
      FallbackProblem<Functor> problem{functor, static_cast<int>(x->size()), num_residuals, nullptr};
      const KneedynLeastSquares least_squares{problem.n, num_residuals, &FallbackProblem<Functor>::Evaluate,
                                              &problem, options.max_iterations};
      const int ran = CeresFallback()(&least_squares, x->data(), &rep.iterations);
      if (problem.error) std::rethrow_exception(problem.error);
      if (!ran) Throw<SolverError>("ConsistentInitialize", level, " level: the Ceres fallback failed internally");
    }
  }
  rep.residual_after = MaxResidual(*functor, *x, num_residuals);
  if (!(rep.residual_after <= tolerance)) {
    Throw<SolverError>("ConsistentInitialize", level, " level: residual ", rep.residual_after,
                       " after ", rep.iterations, " iterations exceeds the tolerance ",
                       tolerance, " (started at ", rep.residual_before, ")");
  }
  return rep;
}

double MaxAbs(const VectorXd& v) { return v.size() ? v.cwiseAbs().maxCoeff() : 0.0; }

}  // namespace

bool ConsistentInitOptions::IsValid(std::string* error) const {
  auto fail = [&](const std::string& m) {
    if (error) *error = m;
    return false;
  };
  if (!(position_tolerance > 0.0)) return fail(StrCat("position_tolerance = ", position_tolerance, "; must be > 0"));
  if (!(velocity_tolerance > 0.0)) return fail(StrCat("velocity_tolerance = ", velocity_tolerance, "; must be > 0"));
  if (!(hidden_tolerance > 0.0)) return fail(StrCat("hidden_tolerance = ", hidden_tolerance, "; must be > 0"));
  if (max_iterations < 1) return fail(StrCat("max_iterations = ", max_iterations, "; must be >= 1"));
  if (newton_iterations < 0) return fail(StrCat("newton_iterations = ", newton_iterations, "; must be >= 0"));
  return true;
}

void FillContactCoordinates(const Model& model, MechanicalState* state) {
  const Pose pose = PoseFromCoordinates(state->q);
  for (int i : state->active) {
    double chart[4];
    const ContactGeometry g =
        RequireContactKinematics(model.contacts[i], pose, "FillContactCoordinates", chart);
    if (state->contact[i].chart == ContactChart::kRegular) {
      state->contact[i].coordinates = {chart[0], chart[1], chart[2], chart[3]};
    } else {
      state->contact[i].coordinates = {g.point_F.x(), g.point_F.y(), g.point_T.x(), g.point_T.y()};
    }
  }
}

namespace {

// Height-field (x, y) coordinates → the regular charts' (u, v) of the same surface points
// (a point off its surface's domain: the contact kinematics' solution instead).
void ConvertContactCoordinates(const Model& model, ContactChart chart, MechanicalState* state) {
  const Pose pose = PoseFromCoordinates(state->q);
  for (size_t i = 0; i < state->contact.size() && i < model.contacts.size(); ++i) {
    ContactGuess& g = state->contact[i];
    if (g.chart == chart) continue;
    g.chart = chart;
    if (chart == ContactChart::kHeightField) continue;  // only scenes give height-field ones
    const ContactPair& pair = model.contacts[i];
    HeightSample hf, ht;
    double kin[4];
    ContactGeometry geo;
    if (pair.femoral_surface->Evaluate(g.coordinates[0], g.coordinates[1], &hf) &&
        pair.tibial_surface->Evaluate(g.coordinates[2], g.coordinates[3], &ht)) {
      pair.femoral_surface->ChartCoordinates(Vector3d(g.coordinates[0], g.coordinates[1], hf.value), kin);
      pair.tibial_surface->ChartCoordinates(Vector3d(g.coordinates[2], g.coordinates[3], ht.value), kin + 2);
    } else if (!ContactKinematics(pair, pose, &geo, kin)) {
      continue;  // left as is: the position level reports the failure
    }
    g.coordinates = {kin[0], kin[1], kin[2], kin[3]};
  }
}

// Constraint rows G_i (k×6, contact.hpp) of the active contacts at `pose`.
MatrixXd ActiveConstraintRows(const Model& model, const MechanicalState& state, const Pose& pose) {
  const int k = static_cast<int>(state.active.size());
  MatrixXd G(k, 6);
  for (int c = 0; c < k; ++c) {
    G.row(c) = ContactConstraintRow(
        pose, RequireContactKinematics(model.contacts[state.active[c]], pose, "ConsistentInitialize"));
  }
  return G;
}

// Level 2: φ̇ = G B(q) q̇ = 0 by the minimum-norm correction of the rates not held; G are
// the active contacts' rows at state->q (ActiveConstraintRows).
InitLevelReport SolveVelocityLevel(const MatrixXd& G, const std::vector<int>& held_velocities,
                                   const ConsistentInitOptions& options, MechanicalState* state,
                                   bool restart = false) {
  InitLevelReport vel;
  Matrix6d B = Matrix6d::Identity();
  B.bottomRightCorner<3, 3>() = AngularVelocityMap(state->q(kBeta), state->q(kGamma));
  const MatrixXd A = G * B;
  vel.residual_before = MaxAbs(A * state->qd);
  if (vel.residual_before > options.velocity_tolerance) {
    std::vector<int> free;
    for (int i = 0; i < 6; ++i) {
      if (std::find(held_velocities.begin(), held_velocities.end(), i) == held_velocities.end()) free.push_back(i);
    }
    if (free.empty()) {
      Throw<SolverError>("ConsistentInitialize", "velocity level: residual ", vel.residual_before,
                         " m/s exceeds the tolerance ", options.velocity_tolerance,
                         " and every velocity is held; free some (initial_state.hold)");
    }
    MatrixXd Af(G.rows(), free.size());
    for (size_t j = 0; j < free.size(); ++j) Af.col(j) = A.col(free[j]);
    const VectorXd delta = Af.completeOrthogonalDecomposition().solve(-(A * state->qd));
    for (size_t j = 0; j < free.size(); ++j) state->qd(free[j]) += delta(j);
  }
  vel.residual_after = MaxAbs(A * state->qd);
  if (!(vel.residual_after <= options.velocity_tolerance)) {
    // A restart holds no rate (CompleteHiddenConstraint): what is left comes from the rows
    // themselves, not from a choice of the scene.
    Throw<SolverError>(restart ? "CompleteHiddenConstraint" : "ConsistentInitialize",
                       "velocity level at t = ", state->t, " s: residual ", vel.residual_after,
                       " m/s exceeds the tolerance ", options.velocity_tolerance,
                       restart
                           ? " after the minimum-norm correction of every rate (the active contacts' rows are near "
                             "dependent here, or the run has diverged)"
                           : " (the held velocities violate the contact constraints; free some)");
  }
  return vel;
}

// Level 3, the hidden constraint (linear in ν̇, N), by Ceres from the force guesses in
// state->contact[].normal_force: the initialization reports its iterations. (A restart
// solves it directly instead: CompleteHiddenConstraint.)
// `pose` and `G` at state->q, as the velocity level had them.
InitLevelReport SolveHiddenLevel(const Model& model, const Pose& pose, const MatrixXd& G,
                                 const ConsistentInitOptions& options, MechanicalState* state) {
  const int k = static_cast<int>(state->active.size());
  const Vector6d nu = GeneralizedVelocity(state->q, state->qd);
  VectorXd kappa(k);
  for (int c = 0; c < k; ++c) {
    kappa(c) = ContactRateTerm(model.contacts[state->active[c]], state->q, state->qd, pose, nu);
  }
  Data data(model);
  data.ligament_branch = &state->ligament_branch;
  ComputeAppliedWrench(model, state->t, pose, &data);
  auto* hidden = new HiddenResidual{MassMatrix(model),
                                    GeneralizedForce(model, data, Vector3d(nu.tail<3>())), G, kappa};
  std::unique_ptr<HiddenResidual> hidden_owner(hidden);
  std::vector<double> x(6 + k, 0.0);
  for (int c = 0; c < k; ++c) x[6 + c] = state->contact[state->active[c]].normal_force;
  const InitLevelReport hid =
      SolveLevel("hidden-constraint", hidden, &x, 6 + k, options.hidden_tolerance, options);
  Vector6d nu_dot;
  for (int i = 0; i < 6; ++i) nu_dot(i) = x[i];
  state->qdd = CoordinateAcceleration(state->q, state->qd, nu_dot);
  for (int c = 0; c < k; ++c) state->contact[state->active[c]].normal_force = x[6 + c];
  return hid;
}

}  // namespace

MechanicalState ConsistentInitialize(const Model& model, const InitialState& init,
                                     const std::vector<int>& active,
                                     const ConsistentInitOptions& options, InitReport* report) {
  std::string why;
  if (!options.IsValid(&why)) Throw<InputError>("ConsistentInitialize", why);
  MechanicalState state;
  state.t = 0.0;
  state.q = init.q;
  state.qd = init.qd;
  state.active = active;
  state.contact = init.contact_guesses;
  ConvertContactCoordinates(model, options.chart, &state);
  InitReport rep;
  rep.form = options.form == ContactForm::kChapter ? "chapter" : "closed_form";
  if (init.unprojected) {
    // The chapter's DASSL start: the guesses as they are, accelerations zero; no level solved.
    state.qdd = Vector6d::Zero();
    for (const ContactGuess& g : state.contact) {
      rep.normal_force_guess.push_back(g.normal_force);
      rep.normal_force.push_back(g.normal_force);
    }
    rep.form += " (unprojected start)";
    if (report) *report = rep;
    return state;
  }
  for (int i : init.held) rep.held.push_back(CoordinateName(i));
  for (int i : init.held_velocities) rep.held.push_back(std::string(CoordinateName(i)) + "_dot");
  for (const ContactGuess& g : state.contact) rep.normal_force_guess.push_back(g.normal_force);

  std::vector<int> free;
  for (int i = 0; i < kNumCoordinates; ++i) {
    if (std::find(init.held.begin(), init.held.end(), i) == init.held.end()) free.push_back(i);
  }
  const int k = static_cast<int>(active.size());
  // Gap form: φ_i = 0 over the free coordinates.
  auto solve_gaps = [&]() {
    auto* f = new ClosedPositionResidual{{&model, state.q, free, active, options.chart}};
    std::unique_ptr<ClosedPositionResidual> owner(f);
    std::vector<double> x;
    for (int i : free) x.push_back(state.q(i));
    const InitLevelReport level = SolveLevel("position", f, &x, k, options.position_tolerance, options);
    for (size_t i = 0; i < free.size(); ++i) state.q(free[i]) = x[i];
    return level;
  };
  if (k > 0) {
    if (options.form == ContactForm::kChapter) {
      // More free coordinates than active contacts (patella_fold: x0, z0 free, one
      // contact): the consistent positions are a curve, and the chapter form's least-squares
      // solve (5 residuals per contact in its 4 contact coordinates and the free coordinates)
      // lands on another point of it than the gap form's: 2e-3 mm apart there, and dae met the
      // patellar lift-off 1.8e-6 s after ede and mde. The chapter form takes the gap form's
      // point, so that every formulation starts from the same state; its own solve below
      // then only checks it.
      InitLevelReport gap_level;
      const bool underdetermined = free.size() > active.size();
      if (underdetermined) gap_level = solve_gaps();
      auto* f = new ChapterPositionResidual{{&model, state.q, free, active, options.chart}};
      std::unique_ptr<ChapterPositionResidual> owner(f);
      auto unknowns = [&]() {
        std::vector<double> x;
        for (int i : free) x.push_back(state.q(i));
        for (int c : active) {
          for (double v : state.contact[c].coordinates) x.push_back(v);
        }
        return x;
      };
      std::vector<double> x = unknowns();
      // The contact coordinates of the gap form's pose (the guesses kept where they already fit).
      if (underdetermined && (gap_level.method != InitMethod::kNone ||
                              MaxResidual(*f, x, 5 * k) > options.position_tolerance)) {
        FillContactCoordinates(model, &state);
        x = unknowns();
      }
      rep.position = SolveLevel("position", f, &x, 5 * k, options.position_tolerance, options);
      if (underdetermined && rep.position.method == InitMethod::kNone) {
        rep.position = gap_level;  // the solve that moved the coordinates
        rep.position.residual_after = std::max(rep.position.residual_after, MaxResidual(*f, x, 5 * k));
      }
      for (size_t i = 0; i < free.size(); ++i) state.q(free[i]) = x[i];
      for (int c = 0; c < k; ++c) {
        for (int j = 0; j < 4; ++j) state.contact[active[c]].coordinates[j] = x[free.size() + 4 * c + j];
      }
    } else {
      rep.position = solve_gaps();
      FillContactCoordinates(model, &state);
    }
  }
  CheckJcsRegular(state.q(kBeta), "ConsistentInitialize");
  const Pose pose = PoseFromCoordinates(state.q);
  const MatrixXd G = ActiveConstraintRows(model, state, pose);
  rep.velocity = SolveVelocityLevel(G, init.held_velocities, options, &state);
  rep.hidden = SolveHiddenLevel(model, pose, G, options, &state);
  for (const ContactGuess& g : state.contact) rep.normal_force.push_back(g.normal_force);
  for (int i = 0; i < static_cast<int>(model.contacts.size()); ++i) {
    if (!state.IsActive(i)) rep.normal_force[i] = 0.0;
  }
  if (report) *report = rep;
  return state;
}

void ProjectRestartPose(const Model& model, MechanicalState* state) {
  // Gaps to round-off, not to the init's 1e-11 m: the chapter-form contact coordinates
  // filled by CompleteHiddenConstraint from the closed form satisfy Eqs. 1.8 and the
  // velocity rows only at φ = 0. At a 4e-12 m gap `dae` restarted off them and its first
  // step moved u by ~3e-11 m/s at any step size (gravity_only, rtol 1e-10: IDA_ERR_FAIL
  // after a kink).
  constexpr double kGapTolerance = 1.0e-14;  // m
  ProjectOntoContacts(model, state->active, kGapTolerance, 20, &state->q);
}

void CompleteHiddenConstraint(const Model& model, MechanicalState* state) {
  // After a mode switch the remaining velocity constraints hold to the integrator's
  // tolerance (lift-off) or exactly (after the impact impulse, taken at the projected
  // pose): the minimum-norm correction over all rates removes that residual before the
  // restart.
  const ConsistentInitOptions options;
  ProjectRestartPose(model, state);
  SolveVelocityLevel(ActiveConstraintRows(model, *state, PoseFromCoordinates(state->q)), {}, options, state,
                     /*restart=*/true);
  // Cheap restarts (benchmarks/README.md, "Restarts"): the hidden level is linear in (ν̇, N);
  // at a restart it is solved directly (the Schur-complement solve of
  // constrained_dynamics.hpp) instead of by Ceres from guesses.
  const ConstrainedAcceleration a = RestartAcceleration(model, state);
  state->qdd = a.qdd;
  for (size_t c = 0; c < state->active.size(); ++c) state->contact[state->active[c]].normal_force = a.normal_force[c];
  FillContactCoordinates(model, state);
}

ConstrainedAcceleration RestartAcceleration(const Model& model, MechanicalState* state) {
  if (!model.patella) {
    return SolveConstrainedAcceleration(model, state->t, state->q, state->qd, state->active, {}, &state->ligament_branch);
  }
  const Patella& patella = *model.patella;
  auto followed = std::make_shared<PatellaGuess>(state->patella ? *state->patella : PatellaGuess());
  SolvePatellaAlongTibialPath(patella, state->patella ? state->patella_q : patella.start_q, state->q,
                              "RestartAcceleration", followed.get());
  ConstrainedDynamicsWorkspace workspace(model);
  workspace.data.patella_guess = *followed;
  ConstrainedAcceleration out;
  SolveConstrainedAcceleration(model, state->t, state->q, state->qd, state->active, {}, &state->ligament_branch,
                               &workspace, &out);
  state->patella = std::move(followed);
  state->patella_q = state->q;
  return out;
}

}  // namespace kneedyn
