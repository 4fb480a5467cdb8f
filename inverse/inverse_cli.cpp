// kneedyn_inverse — the bounded inverse problem on one scene (inverse_problem.hpp).
//
//   kneedyn_inverse --scene FILE --spec inverse/inverse_problem.yaml --out FIT.json
//                   [--targets C1,K6,...|none] [--folds A,B|none] [--no-leave-some-out] [--formulation dae] [--rtol R]
//                   [--max-iterations K] [--weights W,...] [--multiplier-updates U]
//
// Per target (a claim id: all statements of that claim together):
//   - the smallest change: Fit with the weights' continuation (inverse_problem.hpp), from x = 0;
//   - the closest approach within the printed precision: the same fit with |x_i| ≤ 1;
//   - every statement's value at both fits and at x = 0.
// Leave-some-out: the statements of half A fitted together, those of half B judged at the
// fit, and the other way round.
// The claims check at the fitted parameters (which claims it fixes and breaks) is run by
// reports/inverse_problem.py on this file. Exit 0 done, 1 solver failure at x = 0, 2 bad input.
#include <CLI/CLI.hpp>
#include <chrono>
#include <cmath>
#include <fstream>
#include <iostream>
#include <nlohmann/json.hpp>

#include <Eigen/Dense>

#include "inverse/inverse_problem.hpp"
#include "formulations/output_file.hpp"
#include "solver/error.hpp"
#include "solver/internal/command_line.hpp"

using namespace kneedyn;
using namespace kneedyn::inverse;

namespace {

nlohmann::json StatementValues(const StatementModel& model, const std::vector<double>& x, const std::vector<int>& all) {
  nlohmann::json out = nlohmann::json::object();
  try {
    const auto ev = model.Evaluate(x, all, false);
    for (size_t k = 0; k < all.size(); ++k) {
      const Statement& st = model.spec().statements[all[k]];
      const double r = (ev.value[k] - st.target) / st.tolerance;
      out[st.id] = {{"value", ev.value[k]}, {"target", st.target}, {"residual", r}, {"within_tolerance", std::abs(r) <= 1.0}};
    }
  } catch (const Error& e) {
    // One failed run: evaluate statement by statement so the others still show.
    for (int i : all) {
      const Statement& st = model.spec().statements[i];
      try {
        const double v = model.Evaluate(x, {i}, false).value[0];
        const double r = (v - st.target) / st.tolerance;
        out[st.id] = {{"value", v}, {"target", st.target}, {"residual", r}, {"within_tolerance", std::abs(r) <= 1.0}};
      } catch (const Error& e2) {
        out[st.id] = {{"value", nullptr}, {"target", st.target}, {"error", e2.what()}};
      }
    }
  }
  return out;
}

nlohmann::json FitJson(const StatementModel& model, const FitResult& f, const std::vector<int>& fit) {
  const InverseSpec& spec = model.spec();
  nlohmann::json params = nlohmann::json::object(), normalized = nlohmann::json::object(),
                 moved = nlohmann::json::array();
  std::vector<int> order;
  for (int i = 0; i < model.num_parameters(); ++i) {
    normalized[spec.parameters[i].name] = f.x[i];
    if (f.x[i] != 0.0 && std::abs(f.x[i]) >= 0.1 * f.max_abs) order.push_back(i);
  }
  std::sort(order.begin(), order.end(), [&](int a, int b) { return std::abs(f.x[a]) > std::abs(f.x[b]); });
  for (int i : order) {
    params[spec.parameters[i].name] = f.x[i] * spec.parameters[i].bound;
    moved.push_back({{"name", spec.parameters[i].name}, {"normalized", f.x[i]}, {"change", f.x[i] * spec.parameters[i].bound},
                     {"nominal", model.nominal()[i]}, {"bound", spec.parameters[i].bound}});
  }
  bool reached = true;
  nlohmann::json fitted = nlohmann::json::object();
  for (size_t k = 0; k < fit.size(); ++k) {
    const Statement& st = spec.statements[fit[k]];
    const bool ok = std::abs(f.value[k] - st.target) <= spec.reach_fraction * st.tolerance;
    reached = reached && ok;
    fitted[st.id] = {{"value", f.value[k]}, {"target", st.target}, {"residual", f.residual[k]}, {"reached", ok}};
  }
  return {{"reached", reached},
          {"normalized_change", f.norm},
          {"max_normalized_change", f.max_abs},
          {"beyond_precision", f.max_abs > 1.0},
          {"parameters", params},
          {"moved", moved},
          {"all_parameters_normalized", normalized},
          {"fitted_statements", fitted},
          {"iterations", f.iterations},
          {"runs", f.runs},
          {"converged", f.converged},
          {"ceres", f.report}};
}

// The minimum-norm change of the problem linearized at x = 0: x = Jᵀ (J Jᵀ)⁻¹ (target − value),
// J from the sensitivities. A first-order estimate beside the nonlinear fit.
nlohmann::json Linearized(const StatementModel& model, const std::vector<int>& fit) {
  const auto ev = model.Evaluate(std::vector<double>(model.num_parameters(), 0.0), fit, true);
  const int ns = static_cast<int>(fit.size()), np = model.num_parameters();
  Eigen::MatrixXd J(ns, np);
  Eigen::VectorXd d(ns);
  for (int k = 0; k < ns; ++k) {
    for (int j = 0; j < np; ++j) J(k, j) = ev.jacobian[k][j];
    d(k) = model.spec().statements[fit[k]].target - ev.value[k];
  }
  const Eigen::VectorXd x = J.transpose() * (J * J.transpose()).ldlt().solve(d);
  nlohmann::json top = nlohmann::json::object();
  std::vector<int> order(np);
  for (int j = 0; j < np; ++j) order[j] = j;
  std::sort(order.begin(), order.end(), [&](int a, int b) { return std::abs(x(a)) > std::abs(x(b)); });
  for (int i = 0; i < std::min(np, 8); ++i) top[model.spec().parameters[order[i]].name] = x(order[i]);
  nlohmann::json gradient_norm = nlohmann::json::object();
  for (int k = 0; k < ns; ++k) gradient_norm[model.spec().statements[fit[k]].id] = J.row(k).norm();
  return {{"normalized_change", x.norm()}, {"max_normalized_change", x.cwiseAbs().maxCoeff()},
          {"largest_normalized", top}, {"gradient_norm_per_unit_x", gradient_norm}};
}

std::vector<std::string> Split(const std::string& s) {
  std::vector<std::string> out;
  size_t start = 0;
  while (start <= s.size()) {
    const size_t end = s.find(',', start);
    const std::string item = s.substr(start, end == std::string::npos ? std::string::npos : end - start);
    if (!item.empty()) out.push_back(item);
    if (end == std::string::npos) break;
    start = end + 1;
  }
  return out;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"kneedyn_inverse: the smallest change of the uncertain quantities that reaches the chapter's statements"};
  std::string scene_path, spec_path, out_path, targets_arg, folds_arg = "A,B", formulation = "dae";
  double rtol = 1e-8;
  int max_iterations = FitOptions().max_iterations, multiplier_updates = FitOptions().multiplier_updates;
  bool no_lso = false, isotropic = false;
  std::vector<double> weights = FitOptions().weights;
  app.add_option("--scene", scene_path, "scene file (a reading is a scene variant)")->required();
  app.add_option("--spec", spec_path, "parameter/bounds and statements file")->required();
  app.add_option("--out", out_path, "output JSON")->required();
  app.add_option("--targets", targets_arg, "claim ids to reach one at a time (default: every claim of the statements)");
  app.add_flag("--no-leave-some-out", no_lso, "skip the leave-some-out folds");
  app.add_option("--folds", folds_arg, "leave-some-out folds to run: the halves fitted (A, B; 'none': no fold)")
      ->capture_default_str();
  app.add_option("--formulation", formulation, "sensitivity formulation (ede, dae, ...)")->capture_default_str();
  app.add_option("--rtol", rtol, "relative tolerance of every run (atol = 1e-2 rtol)")->capture_default_str();
  app.add_option("--max-iterations", max_iterations, "Ceres iterations per continuation stage")->capture_default_str();
  app.add_flag("--isotropic", isotropic, "Levenberg-Marquardt trust region as a ball in x (no Jacobi scaling)");
  app.add_option("--multiplier-updates", multiplier_updates, "augmented-Lagrangian updates per weight (>= 0)")
      ->capture_default_str();
  app.add_option("--weights", weights, "penalty weights of the statement residuals, one Ceres stage each")
      ->delimiter(',')->capture_default_str();
  if (const int code = ParseCommandLine(app, argc, argv, "kneedyn_inverse"); code >= 0) return code;
  const auto t0 = std::chrono::steady_clock::now();
  try {
    if (!(rtol > 0.0 && rtol < 1e-3)) Throw<InputError>("kneedyn_inverse", "--rtol = ", rtol, ": must be in (0, 1e-3)");
    for (double w : weights) {
      if (!(w > 0.0 && w <= 1e8)) Throw<InputError>("kneedyn_inverse", "--weights: ", w, ": each must be in (0, 1e8]");
    }
    if (weights.empty()) Throw<InputError>("kneedyn_inverse", "--weights: give at least one");
    if (multiplier_updates < 0 || multiplier_updates > 100) {
      Throw<InputError>("kneedyn_inverse", "--multiplier-updates = ", multiplier_updates, ": must be in [0, 100]");
    }
    if (max_iterations < 1) Throw<InputError>("kneedyn_inverse", "--max-iterations = ", max_iterations, ": must be >= 1");
    CheckOutputFile("kneedyn_inverse", "--out", out_path);  // before the fits, which take minutes
    sensitivity::SensitivityOptions options;
    options.formulation = formulation;
    options.rtol = rtol;
    options.atol = 1e-2 * rtol;
    options.output_interval = 0.001;
    std::string why;
    if (!options.IsValid(&why)) Throw<InputError>("kneedyn_inverse", "--formulation/--rtol: ", why);
    const StatementModel model(LoadScene(scene_path), LoadInverseSpec(spec_path), options);
    const InverseSpec& spec = model.spec();
    std::vector<int> all;
    std::vector<std::string> claims;
    for (size_t i = 0; i < spec.statements.size(); ++i) {
      all.push_back(static_cast<int>(i));
      if (std::find(claims.begin(), claims.end(), spec.statements[i].claim) == claims.end()) claims.push_back(spec.statements[i].claim);
    }
    std::vector<std::string> targets = targets_arg.empty() ? claims : Split(targets_arg);
    if (targets_arg == "none") targets.clear();
    std::vector<std::string> folds = folds_arg == "none" || no_lso ? std::vector<std::string>() : Split(folds_arg);
    for (const std::string& h : folds) {
      if (h != "A" && h != "B") {
        Throw<InputError>("kneedyn_inverse", "--folds = '", Echo(folds_arg), "': '", Echo(h),
                          "' is not a fold; give A, B or both (A,B), or none alone");
      }
    }
    for (const std::string& t : targets) {
      if (std::find(claims.begin(), claims.end(), t) == claims.end()) {
        Throw<InputError>("kneedyn_inverse", "--targets: '", Echo(t), "' is no claim of the statements in ", EchoPath(spec_path));
      }
    }
    nlohmann::json out;
    out["scene"] = scene_path;
    out["spec"] = spec_path;
    out["settings"] = {{"formulation", formulation}, {"rtol", rtol}, {"atol", 1e-2 * rtol}, {"output_interval_s", 0.001},
                       {"max_iterations_per_stage", max_iterations}, {"weights", weights},
                       {"multiplier_updates", multiplier_updates}, {"isotropic", isotropic},
                       {"reach_fraction", spec.reach_fraction}};
    out["statements"] = nlohmann::json::array();
    for (const Statement& st : spec.statements) {
      out["statements"].push_back({{"id", st.id}, {"claim", st.claim}, {"target", st.target}, {"tolerance", st.tolerance},
                                   {"half", st.half}, {"duration_s", st.duration_s}});
    }
    out["targets"] = nlohmann::json::object();
    out["leave_some_out"] = nlohmann::json::object();
    out["baseline"] = StatementValues(model, std::vector<double>(model.num_parameters(), 0.0), all);
    std::cerr << "kneedyn_inverse: baseline done\n";
    FitOptions fo;
    fo.max_iterations = max_iterations;
    fo.weights = weights;
    fo.multiplier_updates = multiplier_updates;
    fo.isotropic = isotropic;
    for (const std::string& t : targets) {
      std::vector<int> fit;
      for (int i : all) {
        if (spec.statements[i].claim == t) fit.push_back(i);
      }
      nlohmann::json tj, linear;
      try {
        linear = Linearized(model, fit);
      } catch (const Error& e) {
        linear = {{"error", e.what()}};
      }
      try {
        const FitResult f = Fit(model, fit, fo);
        tj = FitJson(model, f, fit);
        tj["statements_at_fit"] = StatementValues(model, f.x, all);
        FitOptions box = fo;
        box.box = 1.0;
        box.weights = {1.0};
        box.multiplier_updates = 0;
        box.regularization = 0.0;
        const FitResult fb = Fit(model, fit, box);
        tj["within_precision"] = FitJson(model, fb, fit);
      } catch (const Error& e) {
        tj = {{"reached", false}, {"error", e.what()}};
      }
      tj["linearized"] = linear;
      std::cerr << "kneedyn_inverse: target " << t << ": reached " << tj["reached"] << ", |x| "
                << (tj.contains("normalized_change") ? tj["normalized_change"].dump() : "-") << "\n";
      out["targets"][t] = tj;
    }
    {
      for (const std::string& half : folds) {
        std::vector<int> fit, judged;
        for (int i : all) (spec.statements[i].half == half ? fit : judged).push_back(i);
        nlohmann::json fj;
        try {
          const FitResult f = Fit(model, fit, fo);
          fj = FitJson(model, f, fit);
          fj["judged_at_fit"] = StatementValues(model, f.x, judged);
        } catch (const Error& e) {
          fj = {{"error", e.what()}};
        }
        fj["fitted"] = nlohmann::json::array();
        fj["judged"] = nlohmann::json::array();
        for (int i : fit) fj["fitted"].push_back(spec.statements[i].id);
        for (int i : judged) fj["judged"].push_back(spec.statements[i].id);
        std::cerr << "kneedyn_inverse: leave-some-out fit on half " << half << " done\n";
        out["leave_some_out"][std::string("fit_") + half] = fj;
      }
    }
    out["runtime_s"] = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    out["runs"] = model.runs;
    WriteOutputFile("kneedyn_inverse", "--out", out_path, out.dump(1) + "\n");
    return 0;
  } catch (const InputError& e) {  // "kneedyn_inverse: error: ..." as the other tools write it
    std::cerr << "kneedyn_inverse: error: " << e.what() << "\n";
    return 2;
  } catch (const Error& e) {
    std::cerr << "kneedyn_inverse: error: " << e.what() << "\n";
    return 1;
  }
}
