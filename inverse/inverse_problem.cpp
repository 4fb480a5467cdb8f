// The bounded inverse problem (inverse_problem.hpp): statements as functions of one
// sensitivity run, and their Ceres fit with the regularization ‖x‖².
#include "inverse/inverse_problem.hpp"

#include <ceres/ceres.h>
#include <ceres/jet.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <memory>
#include <set>

#include "scene/internal/yaml_field.hpp"
#include "solver/error.hpp"
#include "solver/internal/ceres_logging.hpp"
#include "solver/pose.hpp"
#include "solver/units.hpp"

namespace kneedyn::inverse {

namespace {

using scene_detail::Field;

int CoordinateOf(const Field& f) {
  const std::string s = f.OneOf({"x0", "y0", "z0", "alpha", "beta", "gamma"}, "coordinate");
  static const char* kNames[] = {"x0", "y0", "z0", "alpha", "beta", "gamma"};
  for (int i = 0; i < 6; ++i) {
    if (s == kNames[i]) return i;
  }
  return -1;
}

bool IsAngle(int coordinate) { return coordinate >= kAlpha; }

// Sample k of the trajectory: flexion (deg) and coordinate c in display units (deg or mm).
double Display(int c, double v) { return IsAngle(c) ? RadToDeg(v) : MToMm(v); }

// ---- Closed-form statement values on the samples (templates: double or ceres::Jet).

// Linear interpolation of the flexion where v changes sign between samples 0 and 1.
template <typename T>
T CrossingFlexion(const T& a0, const T& a1, const T& v0, const T& v1) {
  return a0 + v0 / (v0 - v1) * (a1 - a0);
}

// Vertex (flexion) of the parabola v(a) through three samples around a discrete extremum.
template <typename T>
T VertexFlexion(const T& am, const T& a0, const T& ap, const T& vm, const T& v0, const T& vp) {
  const T d1 = (v0 - vm) / (a0 - am), d2 = (vp - v0) / (ap - a0);
  const T c = (d2 - d1) / (ap - am);
  using std::abs;
  if (abs(c) < T(1e-300)) return a0;
  return (am + a0) / T(2.0) - d1 / (T(2.0) * c);
}

// Value and gradient of f(inputs) (N inputs) through Jets: df/dp_j = Σ_k ∂f/∂in_k · d in_k/dp_j.
template <int N, typename F>
double Chain(F f, const std::array<double, N>& in, const std::array<const std::vector<double>*, N>& din, int np,
             std::vector<double>* grad) {
  using J = ceres::Jet<double, N>;
  std::array<J, N> jin;
  for (int k = 0; k < N; ++k) jin[k] = J(in[k], k);
  const J out = f(jin);
  if (grad != nullptr) {
    grad->assign(np, 0.0);
    for (int j = 0; j < np; ++j) {
      for (int k = 0; k < N; ++k) (*grad)[j] += out.v[k] * (*din[k])[j];
    }
  }
  return out.a;
}

// The trajectory as columns: flexion (deg), coordinate or its rate (display units) and their
// derivatives per parameter.
struct Series {
  std::vector<double> a, v;
  std::vector<std::vector<double>> da, dv;
};

Series SeriesOf(const sensitivity::SensitivityResult& r, int coordinate, bool rate, double offset, double sign) {
  Series s;
  const auto& tr = r.trajectory;
  const int np = static_cast<int>(r.parameters.size());
  const bool with_d = !tr.empty() && !tr.front().dq.empty();
  auto dcol = [&](size_t k, int c) {
    std::vector<double> d(np, 0.0);
    if (with_d) {
      for (int j = 0; j < np; ++j) d[j] = Display(c, tr[k].dq[j](c));
    }
    return d;
  };
  const size_t first = rate ? 1 : 0, last = rate ? tr.size() - 1 : tr.size();
  for (size_t k = first; k < last && tr.size() >= 3; ++k) {
    s.a.push_back(RadToDeg(tr[k].q(kAlpha)));
    s.da.push_back(dcol(k, kAlpha));
    if (!rate) {
      s.v.push_back(sign * (Display(coordinate, tr[k].q(coordinate)) - Display(coordinate, offset)));
      std::vector<double> d = dcol(k, coordinate);
      for (double& x : d) x *= sign;
      s.dv.push_back(d);
    } else {
      // Central difference in time of the fixed-time samples: (q_{k+1} − q_{k−1}) / 2h (per s).
      const double h2 = tr[k + 1].t - tr[k - 1].t;
      s.v.push_back(sign * (Display(coordinate, tr[k + 1].q(coordinate)) - Display(coordinate, tr[k - 1].q(coordinate))) / h2);
      std::vector<double> dp = dcol(k + 1, coordinate), dm = dcol(k - 1, coordinate);
      for (int j = 0; j < np; ++j) dp[j] = sign * (dp[j] - dm[j]) / h2;
      s.dv.push_back(dp);
    }
  }
  return s;
}

double TrajectoryStatement(const Statement& st, const sensitivity::SensitivityResult& r, std::vector<double>* grad) {
  const int np = static_cast<int>(r.parameters.size());
  if (st.kind == StatementKind::kCrossing) {
    const Series s = SeriesOf(r, st.coordinate, false, st.offset, 1.0);
    for (size_t k = 1; k < s.a.size(); ++k) {
      if (s.a[k - 1] >= 1.0 && s.v[k - 1] > 0.0 && s.v[k] <= 0.0) {
        return Chain<4>([](const auto& in) { return CrossingFlexion(in[0], in[1], in[2], in[3]); },
                        {s.a[k - 1], s.a[k], s.v[k - 1], s.v[k]}, {&s.da[k - 1], &s.da[k], &s.dv[k - 1], &s.dv[k]},
                        np, grad);
      }
    }
    Throw<SolverError>("StatementModel", "statement ", st.id, ": no + to - crossing after 1 deg of flexion");
  }
  const bool rate = st.kind == StatementKind::kRatePeakLocation;
  const Series s = SeriesOf(r, st.coordinate, rate, 0.0, st.sign);
  int best = -1;
  for (size_t k = 1; k + 1 < s.a.size(); ++k) {
    if (s.a[k] < st.window_lo_deg || s.a[k] > st.window_hi_deg) continue;
    if (best < 0 || s.v[k] > s.v[best]) best = static_cast<int>(k);
  }
  if (best < 0) Throw<SolverError>("StatementModel", "statement ", st.id, ": no samples in its flexion window");
  const size_t k = best;
  // A largest value at the window's edge (the run's last sample inside it, or the value still
  // rising there) is no peak: the parabola's vertex would lie outside its three samples.
  if (s.v[k + 1] > s.v[k] || s.v[k - 1] > s.v[k]) {
    Throw<SolverError>("StatementModel", "statement ", st.id, ": no maximum inside its flexion window [",
                       st.window_lo_deg, ", ", st.window_hi_deg, "] deg: the largest value is at its edge (",
                       s.a[k], " deg of flexion)");
  }
  return Chain<6>([](const auto& in) { return VertexFlexion(in[0], in[1], in[2], in[3], in[4], in[5]); },
                  {s.a[k - 1], s.a[k], s.a[k + 1], s.v[k - 1], s.v[k], s.v[k + 1]},
                  {&s.da[k - 1], &s.da[k], &s.da[k + 1], &s.dv[k - 1], &s.dv[k], &s.dv[k + 1]}, np, grad);
}

}  // namespace

InverseSpec LoadInverseSpec(const std::string& path) {
  const std::string text = scene_detail::ReadInputFile(path, "inverse problem file", {"LoadInverseSpec"});
  const Field root = scene_detail::ParseYamlDocument(text, path, "LoadInverseSpec");
  if (!root.IsMap()) root.Fail("the inverse problem file must be a YAML mapping");
  root.Keys({"schema_version", "reach_fraction", "parameters", "statements"});
  InverseSpec spec;
  if (root.Has("reach_fraction")) spec.reach_fraction = root.Child("reach_fraction").Range(1e-6, 1.0);
  const Field ps = root.Required("parameters");
  if (!ps.IsSequence() || ps.Size() == 0) ps.Fail("must be a non-empty list");
  std::set<std::string> names;
  for (size_t i = 0; i < ps.Size(); ++i) {
    const Field p = ps.Item(i);
    p.Keys({"name", "bound", "reason"});
    UncertainParameter u;
    u.name = p.Required("name").String();
    u.bound = p.Required("bound").Positive();
    u.reason = p.Required("reason").String();
    if (!names.insert(u.name).second) p.Required("name").Fail("duplicate parameter");
    spec.parameters.push_back(u);
  }
  const Field ss = root.Required("statements");
  if (!ss.IsSequence() || ss.Size() == 0) ss.Fail("must be a non-empty list");
  std::set<std::string> ids;
  for (size_t i = 0; i < ss.Size(); ++i) {
    const Field f = ss.Item(i);
    f.Keys({"id", "claim", "kind", "outcome", "coordinate", "offset", "sign", "window_deg", "duration_s", "target",
            "tolerance", "half", "reason"});
    Statement st;
    st.id = f.Required("id").Name();
    if (!ids.insert(st.id).second) f.Required("id").Fail("duplicate statement id");
    st.claim = f.Required("claim").Name();
    const std::string kind =
        f.Required("kind").OneOf({"outcome", "crossing", "peak_location", "rate_peak_location"}, "statement kind");
    st.kind = kind == "outcome" ? StatementKind::kOutcome
              : kind == "crossing" ? StatementKind::kCrossing
              : kind == "peak_location" ? StatementKind::kPeakLocation
                                       : StatementKind::kRatePeakLocation;
    if (st.kind == StatementKind::kOutcome) {
      st.outcome = f.Required("outcome").String();
    } else {
      st.coordinate = CoordinateOf(f.Required("coordinate"));
      if (f.Has("offset")) {
        // Display units in the file (deg or mm), SI inside.
        const double v = f.Child("offset").Range(-1000.0, 1000.0);
        st.offset = IsAngle(st.coordinate) ? DegToRad(v) : MmToM(v);
      }
      if (f.Has("sign")) {
        st.sign = f.Child("sign").Range(-1.0, 1.0);
        if (st.sign != 1.0 && st.sign != -1.0) f.Child("sign").Fail("must be 1 or -1");
      }
      if (f.Has("window_deg")) {
        const auto w = f.Child("window_deg").Vec2(360.0);
        if (!(w[0] < w[1])) f.Child("window_deg").Fail("must be [lo, hi] with lo < hi");
        st.window_lo_deg = w[0];
        st.window_hi_deg = w[1];
      }
    }
    if (f.Has("duration_s")) st.duration_s = f.Child("duration_s").Range(1e-3, 10.0);
    st.target = f.Required("target").Range(-1e5, 1e5);
    st.tolerance = f.Required("tolerance").Positive();
    // A statement's value comes from runs at --rtol (1e-8 by default, 1e-3 at most); finer
    // than a millionth of its size, a tolerance scales the runs' own error into the fit (and
    // near 1e-300 the squared residuals overflow, so that every step is invalid).
    const double min_tolerance = std::max(1.0, std::abs(st.target)) / 1e6;
    if (!(st.tolerance >= min_tolerance)) {
      f.Required("tolerance").Fail(StrCat("must be >= 1e-6 max(1, |target|) = ", min_tolerance,
                                          ": finer than the runs that compute the statement"));
    }
    st.half = f.Required("half").OneOf({"A", "B"}, "leave-some-out half");
    st.reason = f.Required("reason").String();
    spec.statements.push_back(st);
  }
  return spec;
}

StatementModel::StatementModel(Scene scene, InverseSpec spec, sensitivity::SensitivityOptions options)
    : scene_(std::move(scene)), spec_(std::move(spec)), options_(std::move(options)) {
  std::vector<std::string> names;
  for (const UncertainParameter& p : spec_.parameters) names.push_back(p.name);
  parameters_ = sensitivity::ResolveParameters(scene_, names, "parameters");
  for (const auto& p : parameters_) nominal_.push_back(p.nominal);
  for (int i = 0; i < num_parameters(); ++i) free_.push_back(i);
  std::vector<std::string> outcomes;
  for (const Statement& st : spec_.statements) {
    if (st.kind == StatementKind::kOutcome) outcomes.push_back(st.outcome);
  }
  if (!outcomes.empty()) (void)sensitivity::ResolveOutcomes(scene_, outcomes, "statements.outcome");
}

std::vector<double> StatementModel::Values(const std::vector<double>& x) const {
  std::vector<double> p = nominal_;
  for (int i = 0; i < num_parameters(); ++i) p[i] += x[i] * spec_.parameters[i].bound;
  return p;
}

StatementModel::Evaluation StatementModel::Evaluate(const std::vector<double>& x, const std::vector<int>& statements,
                                                    bool derivatives) const {
  Evaluation ev;
  ev.value.assign(statements.size(), 0.0);
  if (derivatives) ev.jacobian.assign(statements.size(), std::vector<double>(num_parameters(), 0.0));
  const std::vector<double> p = Values(x);
  // The free parameters go to the sensitivity run; the others are applied at their values too
  // (a non-free parameter may sit away from nominal in a warm start).
  std::vector<ensembles::ParameterSpec> params;
  std::vector<double> values;
  for (int i : free_) {
    params.push_back(parameters_[i]);
    values.push_back(p[i]);
  }
  std::map<double, std::vector<size_t>> by_duration;
  for (size_t k = 0; k < statements.size(); ++k) by_duration[spec_.statements[statements[k]].duration_s].push_back(k);
  for (const auto& [duration, members] : by_duration) {
    Scene s = scene_;
    if (duration > 0.0) s.model.pulse.duration = duration;
    // Non-free parameters away from nominal: applied through SceneForRun once.
    {
      ensembles::SweepSpec fixed;
      fixed.base = s;
      std::vector<double> fixed_values;
      std::set<int> is_free(free_.begin(), free_.end());
      for (int i = 0; i < num_parameters(); ++i) {
        if (!is_free.count(i) && x[i] != 0.0) {
          fixed.parameters.push_back(parameters_[i]);
          fixed_values.push_back(p[i]);
        }
      }
      if (!fixed.parameters.empty()) s = ensembles::SceneForRun(fixed, fixed_values);
    }
    std::vector<std::string> outcomes;
    for (size_t k : members) {
      const Statement& st = spec_.statements[statements[k]];
      if (st.kind == StatementKind::kOutcome) outcomes.push_back(st.outcome);
    }
    if (outcomes.empty()) outcomes.push_back("time_90_s");  // the run needs one outcome
    sensitivity::SensitivityOptions o = options_;
    o.derivatives = derivatives;
    ++runs;
    const sensitivity::SensitivityResult r = sensitivity::RunSensitivity(s, params, values, outcomes, o);
    for (size_t k : members) {
      const Statement& st = spec_.statements[statements[k]];
      std::vector<double> grad;
      double v;
      if (st.kind == StatementKind::kOutcome) {
        const size_t o_idx = std::find(r.outcomes.begin(), r.outcomes.end(), st.outcome) - r.outcomes.begin();
        v = r.values[o_idx];
        if (!std::isfinite(v)) Throw<SolverError>("StatementModel", "statement ", st.id, ": ", st.outcome, " not reached");
        // Built, then moved: copy-assigning into the empty grad draws GCC 12's false -Wnonnull.
        if (derivatives) grad = std::vector<double>(r.derivatives[o_idx]);
      } else {
        v = TrajectoryStatement(st, r, derivatives ? &grad : nullptr);
      }
      ev.value[k] = v;
      if (derivatives) {
        for (size_t j = 0; j < free_.size(); ++j) ev.jacobian[k][free_[j]] = grad[j] * spec_.parameters[free_[j]].bound;
      }
    }
  }
  return ev;
}

namespace {

// Residuals: w ((value − target)/tolerance + μ_k) of the fitted statements, then √λ x_i of
// the free unknowns; μ_k = multiplier / w² of the augmented Lagrangian (0 in a plain fit). Derivatives from the sensitivity run; the last evaluation is cached (Ceres asks
// for the Jacobian at the point it has just accepted).
class StatementCost : public ceres::CostFunction {
 public:
  StatementCost(const StatementModel& model, std::vector<int> fit, double weight, double regularization,
                std::vector<double> shift)
      : model_(model), fit_(std::move(fit)), weight_(weight), sqrt_lambda_(std::sqrt(regularization)),
        shift_(std::move(shift)) {
    nf_ = static_cast<int>(model_.free().size());
    set_num_residuals(static_cast<int>(fit_.size()) + (regularization > 0.0 ? nf_ : 0));
    mutable_parameter_block_sizes()->push_back(nf_);
  }

  bool Evaluate(double const* const* parameters, double* residuals, double** jacobians) const override {
    std::vector<double> x(model_.num_parameters(), 0.0);
    for (int j = 0; j < nf_; ++j) x[model_.free()[j]] = parameters[0][j];
    if (x != cached_x_ || !have_cache_) {
      try {
        cache_ = model_.Evaluate(x, fit_, true);
      } catch (const Error&) {
        have_cache_ = false;
        return false;  // Ceres shrinks the step
      }
      cached_x_ = x;
      have_cache_ = true;
    }
    const size_t ns = fit_.size();
    for (size_t k = 0; k < ns; ++k) {
      const Statement& st = model_.spec().statements[fit_[k]];
      residuals[k] = weight_ * ((cache_.value[k] - st.target) / st.tolerance + shift_[k]);
    }
    const bool reg = num_residuals() > static_cast<int>(ns);
    if (reg) {
      for (int j = 0; j < nf_; ++j) residuals[ns + j] = sqrt_lambda_ * parameters[0][j];
    }
    if (jacobians != nullptr && jacobians[0] != nullptr) {
      double* J = jacobians[0];
      for (size_t k = 0; k < ns; ++k) {
        const Statement& st = model_.spec().statements[fit_[k]];
        for (int j = 0; j < nf_; ++j) J[k * nf_ + j] = weight_ * cache_.jacobian[k][model_.free()[j]] / st.tolerance;
      }
      if (reg) {
        for (int i = 0; i < nf_; ++i) {
          for (int j = 0; j < nf_; ++j) J[(ns + i) * nf_ + j] = i == j ? sqrt_lambda_ : 0.0;
        }
      }
    }
    return true;
  }

 private:
  const StatementModel& model_;
  std::vector<int> fit_;
  double weight_, sqrt_lambda_;
  std::vector<double> shift_;  // multiplier estimate / w² per statement (augmented Lagrangian)
  int nf_ = 0;
  mutable std::vector<double> cached_x_;
  mutable StatementModel::Evaluation cache_;
  mutable bool have_cache_ = false;
};

}  // namespace

FitResult Fit(const StatementModel& model, const std::vector<int>& fit, const FitOptions& options) {
  if (fit.empty()) Throw<InputError>("Fit", "no statements to fit");
  const int nf = static_cast<int>(model.free().size());
  const long runs0 = model.runs;
  std::vector<double> y(nf, 0.0);
  FitResult result;
  std::vector<double> shift(fit.size(), 0.0);
  std::vector<double> best_y;
  bool best_reached = false;
  double best_norm = 0.0, best_worst = 0.0;
  for (double w : options.weights) {
    for (int outer = 0; outer <= options.multiplier_updates; ++outer) {
      ceres::Problem::Options po;
      po.cost_function_ownership = ceres::TAKE_OWNERSHIP;
      ceres::Problem problem(po);
      problem.AddResidualBlock(new StatementCost(model, fit, w, options.regularization, shift), nullptr, y.data());
      if (options.box > 0.0) {
        for (int j = 0; j < nf; ++j) {
          problem.SetParameterLowerBound(y.data(), j, -options.box);
          problem.SetParameterUpperBound(y.data(), j, options.box);
        }
      }
      ceres::Solver::Options so;
      so.linear_solver_type = ceres::DENSE_QR;
      so.max_num_iterations = options.max_iterations;
      so.num_threads = 1;  // deterministic
      if (options.isotropic) {
        // Isotropic trust region in x (D = I, no Jacobi scaling).
        so.jacobi_scaling = false;
        so.min_lm_diagonal = 1.0;
        so.max_lm_diagonal = 1.0;
      }
      so.function_tolerance = 1e-10;
      so.parameter_tolerance = 1e-10;
      so.logging_type = ceres::SILENT;
      ceres::Solver::Summary summary;
      QuietCeresLogging();  // the summary's report is the outcome
      ceres::Solve(so, &problem, &summary);
      result.iterations += static_cast<int>(summary.iterations.size());
      result.converged = summary.termination_type == ceres::CONVERGENCE;
      result.report += (result.report.empty() ? "" : " | ") +
                       ("w " + std::to_string(w) + " update " + std::to_string(outer) + ": " + summary.BriefReport());
      // The stage's end point: kept if it is the best so far (reaching every statement with the
      // smallest ‖x‖, else the smallest largest |r|), and the multiplier update
      // λ ← λ + w² r (here μ = λ / w²: μ ← μ + r).
      std::vector<double> x(model.num_parameters(), 0.0);
      for (int j = 0; j < nf; ++j) x[model.free()[j]] = y[j];
      bool met = true, reached = true;
      double worst = 0.0;
      try {
        const StatementModel::Evaluation ev = model.Evaluate(x, fit, false);
        for (size_t k = 0; k < fit.size(); ++k) {
          const Statement& st = model.spec().statements[fit[k]];
          const double r = (ev.value[k] - st.target) / st.tolerance;
          met = met && std::abs(r) <= 0.1 * model.spec().reach_fraction;
          reached = reached && std::abs(r) <= model.spec().reach_fraction;
          worst = std::max(worst, std::abs(r));
          shift[k] += r;
        }
      } catch (const Error&) {
        break;
      }
      double norm = 0.0;
      for (double v : y) norm += v * v;
      norm = std::sqrt(norm);
      const bool better = best_y.empty() || (reached && !best_reached) ||
                          (reached == best_reached && (reached ? norm < best_norm : worst < best_worst));
      if (better) {
        best_y = y;
        best_reached = reached;
        best_norm = norm;
        best_worst = worst;
      }
      if (met || options.multiplier_updates == 0) break;
    }
  }
  if (!best_y.empty()) y = best_y;
  result.x.assign(model.num_parameters(), 0.0);
  for (int j = 0; j < nf; ++j) result.x[model.free()[j]] = y[j];
  double n2 = 0.0;
  for (double v : result.x) {
    n2 += v * v;
    result.max_abs = std::max(result.max_abs, std::abs(v));
  }
  result.norm = std::sqrt(n2);
  const StatementModel::Evaluation ev = model.Evaluate(result.x, fit, false);
  result.value = ev.value;
  for (size_t k = 0; k < fit.size(); ++k) {
    const Statement& st = model.spec().statements[fit[k]];
    result.residual.push_back((ev.value[k] - st.target) / st.tolerance);
  }
  result.runs = model.runs - runs0;
  return result;
}

}  // namespace kneedyn::inverse
