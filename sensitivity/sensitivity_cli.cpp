#include "sensitivity/sensitivity_cli.hpp"

#include <fcntl.h>
#include <signal.h>
#include <stdio.h>
#include <unistd.h>

#include <nlohmann/json.hpp>

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>

#include "formulations/progress.hpp"
#include "formulations/version.hpp"
#include "solver/error.hpp"

namespace kneedyn::sensitivity {

namespace fs = std::filesystem;

namespace {

const char* const kFiles[] = {"sensitivity.csv", "sensitivity.json", "sensitivity_trajectory.csv"};

std::string Number(double v) {
  if (!std::isfinite(v)) return "";
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.12g", v);
  return buf;
}

nlohmann::json JsonNumber(double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr); }

fs::path OutputPath(const std::string& dir) {
  fs::path out = fs::path(dir).lexically_normal();
  if (out.filename().empty()) out = out.parent_path();
  if (out.empty() || out.filename() == "." || out.filename() == "..") {
    Throw<InputError>("kneedyn sensitivity", "--out = '", EchoPath(dir), "': must name a directory of its own (not '.', '..' or '/')");
  }
  return out;
}

void WriteFile(const fs::path& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary);
  if (!out) Throw<InputError>("kneedyn sensitivity", "cannot write '", EchoPath(path.string()), "'");
  out << text;
  out.close();
  if (!out) Throw<InputError>("kneedyn sensitivity", "failed writing '", EchoPath(path.string()), "'");
}

// Replaces `out` by `tmp` in one step (as `kneedyn run` publishes, run_output.hpp).
void Publish(const fs::path& tmp, const fs::path& out) {
  for (int attempt = 0; attempt < 100; ++attempt) {
    if (::renameat2(AT_FDCWD, tmp.c_str(), AT_FDCWD, out.c_str(), RENAME_NOREPLACE) == 0) return;
    if (errno != EEXIST) break;
    if (::renameat2(AT_FDCWD, tmp.c_str(), AT_FDCWD, out.c_str(), RENAME_EXCHANGE) == 0) return;
    if (errno != ENOENT) break;
  }
  Throw<InputError>("kneedyn sensitivity", "cannot publish '", EchoPath(tmp.string()), "' as '",
                    EchoPath(out.string()), "': ", std::strerror(errno));
}

// p / y · dy/dp (NaN when y = 0 or not reached).
double Normalized(double p, double y, double d) { return y != 0.0 ? p / y * d : std::nan(""); }

}  // namespace

void CheckSensitivityOutputDirectory(const std::string& dir) {
  const fs::path out = OutputPath(dir);
  std::error_code ec;
  const fs::file_status st = fs::symlink_status(out, ec);
  if (ec && ec != std::errc::no_such_file_or_directory) {
    Throw<InputError>("kneedyn sensitivity", "--out = '", EchoPath(dir), "': ", ec.message());
  }
  if (!fs::exists(st)) return;
  if (!fs::is_directory(st)) Throw<InputError>("kneedyn sensitivity", "--out = '", EchoPath(dir), "' exists and is not a directory");
  for (fs::directory_iterator it(out, ec), end; !ec && it != end; it.increment(ec)) {
    const std::string name = it->path().filename().string();
    const bool known = std::find(std::begin(kFiles), std::end(kFiles), name) != std::end(kFiles);
    if (!known || !it->is_regular_file()) {
      Throw<InputError>("kneedyn sensitivity", "--out = '", EchoPath(dir), "' holds '", Echo(name),
                        "', which is not part of a sensitivity output set; give a new or empty directory");
    }
  }
}

std::vector<std::vector<double>> CentralDifferences(const Scene& scene, const std::vector<ensembles::ParameterSpec>& parameters,
                                                    const std::vector<double>& values,
                                                    const std::vector<std::string>& outcomes,
                                                    const SensitivityOptions& options, double relative_step) {
  SensitivityOptions plain = options;
  plain.derivatives = false;
  std::vector<std::vector<double>> fd(outcomes.size(), std::vector<double>(parameters.size()));
  for (size_t j = 0; j < parameters.size(); ++j) {
    const double h = relative_step * (values[j] != 0.0 ? std::abs(values[j]) : 1.0);
    std::vector<double> up = values, down = values;
    up[j] += h, down[j] -= h;
    const SensitivityResult a = RunSensitivity(scene, parameters, up, outcomes, plain);
    const SensitivityResult b = RunSensitivity(scene, parameters, down, outcomes, plain);
    for (size_t k = 0; k < outcomes.size(); ++k) fd[k][j] = (a.values[k] - b.values[k]) / (2 * h);
  }
  return fd;
}

void WriteSensitivityOutputs(const std::string& dir, const Scene& scene, const SensitivityOptions& options,
                             const SensitivityResult& r, const std::vector<std::vector<double>>* fd, double fd_step,
                             const std::vector<std::string>& command_line) {
  CheckSensitivityOutputDirectory(dir);
  const fs::path out = OutputPath(dir);
  std::error_code ec;
  if (!out.parent_path().empty()) fs::create_directories(out.parent_path(), ec);
  std::random_device random;
  char suffix[64];
  std::snprintf(suffix, sizeof suffix, "%ld-%08x", static_cast<long>(::getpid()), random());
  const fs::path tmp = out.parent_path() / ("." + out.filename().string() + ".kneedyn-tmp-" + suffix);
  if (!fs::create_directory(tmp, ec) || ec) {
    Throw<InputError>("kneedyn sensitivity", "--out = '", EchoPath(dir), "': cannot create '", EchoPath(tmp.string()), "'");
  }
  try {
    std::ostringstream csv;
    csv << "outcome,parameter,parameter_value,value,derivative,normalized" << (fd ? ",fd_derivative" : "") << "\n";
    nlohmann::json rows = nlohmann::json::array();
    for (size_t k = 0; k < r.outcomes.size(); ++k) {
      for (size_t j = 0; j < r.parameters.size(); ++j) {
        const double d = r.derivatives[k][j];
        const double n = Normalized(r.parameter_values[j], r.values[k], d);
        csv << r.outcomes[k] << ',' << r.parameter_columns[j] << ',' << Number(r.parameter_values[j]) << ','
            << Number(r.values[k]) << ',' << Number(d) << ',' << Number(n);
        nlohmann::json row = {{"outcome", r.outcomes[k]}, {"parameter", r.parameter_columns[j]},
                              {"parameter_value", JsonNumber(r.parameter_values[j])}, {"value", JsonNumber(r.values[k])},
                              {"derivative", JsonNumber(d)}, {"normalized", JsonNumber(n)}};
        if (fd) {
          csv << ',' << Number((*fd)[k][j]);
          row["fd_derivative"] = JsonNumber((*fd)[k][j]);
        }
        csv << "\n";
        rows.push_back(row);
      }
    }
    nlohmann::json j;
    j["kneedyn_version"] = KneedynVersion();
    j["git_commit"] = KneedynGitCommit();
    j["command_line"] = command_line;
    j["scene"] = {{"name", scene.name}, {"path", scene.path}};
    j["settings"] = {{"formulation", options.formulation}, {"integrator", SensitivityIntegrator(options.formulation)},
                     {"sensitivity_method", SensitivityMethod(options.formulation)},
                     {"rtol", options.rtol}, {"atol", options.atol}, {"max_steps", options.max_steps},
                     {"output_interval_s", options.output_interval > 0.0 ? options.output_interval : scene.output_interval},
                     {"fd_relative_step", fd ? nlohmann::json(fd_step) : nlohmann::json(nullptr)}};
    j["end_reason"] = r.end_reason;
    nlohmann::json events = nlohmann::json::array();
    for (const SensitivityEvent& e : r.events) {
      nlohmann::json dt = nlohmann::json::object();
      for (size_t p = 0; p < e.dtime.size(); ++p) dt[r.parameter_columns[p]] = JsonNumber(e.dtime[p]);
      events.push_back({{"name", e.name}, {"time", e.time}, {"flexion_deg", e.flexion * 180.0 / M_PI}, {"dtime_dp", dt}});
    }
    j["events"] = events;
    const SolverStats& s = r.stats;
    j["statistics"] = {{"steps", s.steps}, {"rhs_evaluations", s.residual_evaluations},
                       {"jacobian_evaluations", s.jacobian_evaluations}, {"linear_solver_setups", s.linear_solver_setups},
                       {"nonlinear_iterations", s.nonlinear_iterations}, {"error_test_failures", s.error_test_failures},
                       {"convergence_failures", s.convergence_failures}, {"root_evaluations", s.root_evaluations},
                       {"restarts", s.restarts}, {"sensitivity_rhs_evaluations", r.sensitivity_rhs_evaluations},
                       {"sensitivity_error_test_failures", r.sensitivity_error_test_failures},
                       {"initial_sensitivity_residual",
                        IsOdeSensitivity(options.formulation) || r.parameters.empty() ? nlohmann::json(nullptr)
                                                                             : nlohmann::json(r.initial_sensitivity_residual)}};
    j["wall_time_s"] = r.wall_time_s;
    j["rows"] = rows;
    // The trajectory and ∂q/∂p at the output times, one row per (time, parameter).
    std::ostringstream traj;
    const char* coords[] = {"x0_mm", "y0_mm", "z0_mm", "flexion_deg", "valgus_deg", "external_rotation_deg"};
    traj << "time_s,parameter";
    for (const char* c : coords) traj << ',' << c;
    for (const char* c : coords) traj << ",d_" << c;
    traj << "\n";
    auto unit = [](int i, double v) { return i < 3 ? v * 1e3 : v * 180.0 / M_PI; };
    for (const TrajectorySample& row : r.trajectory) {
      for (size_t p = 0; p < r.parameter_columns.size(); ++p) {
        traj << Number(row.t) << ',' << r.parameter_columns[p];
        for (int i = 0; i < 6; ++i) traj << ',' << Number(unit(i, row.q(i) - (i == 4 ? M_PI / 2 : 0.0)));
        for (int i = 0; i < 6; ++i) traj << ',' << (p < row.dq.size() ? Number(unit(i, row.dq[p](i))) : std::string());
        traj << "\n";
      }
    }
    WriteFile(tmp / "sensitivity_trajectory.csv", traj.str());
    WriteFile(tmp / "sensitivity.csv", csv.str());
    WriteFile(tmp / "sensitivity.json", j.dump(2, ' ', false, nlohmann::json::error_handler_t::replace) + "\n");
    Publish(tmp, out);
  } catch (...) {
    fs::remove_all(tmp, ec);
    throw;
  }
  fs::remove_all(tmp, ec);  // the previous set, if there was one
}

SensitivityCommand::SensitivityCommand(CLI::App& app) {
  cmd_ = app.add_subcommand("sensitivity",
                            "forward sensitivities (CVODES for ede, IDAS for the DAE forms) of outcomes with respect to "
                            "named parameters");
  cmd_->add_option("scene", scene_path_, "scene file (YAML); or give --spec");
  cmd_->add_option("--spec", spec_path_,
                   "a sweep spec (kneedyn sweep): its scene, parameter names and outcomes, at the nominal values");
  cmd_->add_option("--parameters", parameters_, "comma-separated parameter names (as in a sweep spec)")->delimiter(',');
  cmd_->add_option("--outcomes", outcomes_, "comma-separated outcome columns or groups (as in a sweep spec)")->delimiter(',');
  std::string ode, dae;  // the registry's forms with sensitivities
  for (const std::string& f : SensitivityFormulations()) {
    std::string& list = IsOdeSensitivity(f) ? ode : dae;
    list += (list.empty() ? "" : " | ") + f;
  }
  cmd_->add_option("--formulation", options_.formulation, "form integrated: " + ode + " (CVODES) | " + dae + " (IDAS)")
      ->capture_default_str();
  // Numbers are kept as typed and converted once in Run, so that every refusal echoes the
  // text given.
  auto text_option = [this](const char* flag, const std::string& help, const std::string& default_text) {
    cmd_->add_option(flag, typed_[flag], help)->default_str(default_text);
  };
  text_option("--rtol", "relative tolerance", StrCat(options_.rtol));
  text_option("--atol", "absolute tolerance (SI)", StrCat(options_.atol));
  text_option("--max-steps", "step budget per phase", StrCat(options_.max_steps));
  text_option("--output-interval", "s between trajectory rows (0: scene's)", StrCat(options_.output_interval));
  text_option("--fd-step", "relative step of central finite differences to print beside (0: none)", StrCat(fd_step_));
  cmd_->add_option("--out", out_dir_, "output directory")->capture_default_str();
  cmd_->add_flag("--list", list_, "print the parameter and outcome names of the scene");
  cmd_->add_flag("--quiet", quiet_, "no progress on stderr (shown only on a terminal)");
}

int SensitivityCommand::Run(int argc, char** argv) {
  try {
    for (const std::string* s : {&scene_path_, &spec_path_, &out_dir_, &options_.formulation}) {
      if (s->size() > 1024) Throw<InputError>("kneedyn sensitivity", "argument '", Echo(*s), "' is longer than 1024 characters");
    }
    for (auto it = typed_.begin(); it != typed_.end();) {  // keep only the options given
      it = cmd_->count(it->first) ? std::next(it) : typed_.erase(it);
    }
    for (const auto& [flag, text] : typed_) {
      const bool ok = flag == "--max-steps"         ? ParseInteger(text, &options_.max_steps)
                      : flag == "--rtol"            ? ParseReal(text, &options_.rtol)
                      : flag == "--atol"            ? ParseReal(text, &options_.atol)
                      : flag == "--output-interval" ? ParseReal(text, &options_.output_interval)
                                                    : ParseReal(text, &fd_step_);
      if (!ok) {
        Throw<InputError>("kneedyn sensitivity", flag, " = '", Echo(text), "': must be ",
                          flag == "--max-steps" ? "an integer >= 1 (in long's range)" : "a finite number (in double's range)");
      }
    }
    std::string why;
    if (!options_.IsValid(&why, typed_)) Throw<InputError>("kneedyn sensitivity", why);
    if (!(fd_step_ >= 0.0 && fd_step_ < 0.5)) {
      const auto it = typed_.find("--fd-step");
      Throw<InputError>("kneedyn sensitivity", "--fd-step = '", Echo(it != typed_.end() ? it->second : StrCat(fd_step_)),
                        "': must be in [0, 0.5)");
    }
    if (scene_path_.empty() == spec_path_.empty()) {
      Throw<InputError>("kneedyn sensitivity", "give either a scene file or --spec (", scene_path_.empty() ? "neither" : "both",
                        " given)");
    }
    Scene scene;
    if (!spec_path_.empty()) {
      if (!parameters_.empty() || !outcomes_.empty()) {
        Throw<InputError>("kneedyn sensitivity", "--spec = '", EchoPath(spec_path_),
                          "': takes the parameters and outcomes from the spec; do not also give --parameters/--outcomes");
      }
      const ensembles::SweepSpec spec = ensembles::LoadSweepSpec(spec_path_);
      if (spec.analytic != ensembles::AnalyticModel::kNone) {
        Throw<InputError>("kneedyn sensitivity", "--spec = '", EchoPath(spec_path_), "': an analytic test function, not a scene");
      }
      scene = spec.base;
      for (const ensembles::ParameterSpec& p : spec.parameters) parameters_.push_back(p.name);
      outcomes_ = spec.outcome_groups;
    } else {
      scene = LoadScene(scene_path_);
    }
    if (list_) {
      std::printf("parameters:\n");
      for (const std::string& n : ParameterNames(scene)) std::printf("  %s\n", n.c_str());
      std::printf("outcomes:\n");
      for (const std::string& n : OutcomeNames(scene)) std::printf("  %s\n", n.c_str());
      return 0;
    }
    // Names from a spec are refused as the spec's fields, not as options never given.
    const std::string from = spec_path_.empty() ? "" : "--spec = '" + EchoPath(spec_path_) + "': ";
    const std::vector<ensembles::ParameterSpec> params =
        ResolveParameters(scene, parameters_, from.empty() ? "--parameters" : from + "parameters");
    const std::vector<std::string> outcomes =
        ResolveOutcomes(scene, outcomes_, from.empty() ? "--outcomes" : from + "outcomes");
    CheckSensitivityOutputDirectory(out_dir_);
    std::vector<double> values;
    for (const ensembles::ParameterSpec& p : params) values.push_back(p.nominal);
    // `\r` progress only on a terminal, as kneedyn run's (a run with derivatives of one patella
    // parameter takes over a minute).
    const bool show_progress = !quiet_ && StderrIsTerminal();
    SensitivityOptions run_options = options_;
    if (show_progress) {
      run_options.progress = [last = -1.0](double t, double alpha) mutable {
        if (t - last < 0.05 && last >= 0.0) return;
        last = t;
        std::fprintf(stderr, "\r[sensitivity] t = %.3f s  flexion = %6.2f deg", t, alpha * 180.0 / M_PI);
      };
    }
    // The progress line ends before anything else is printed, an error included.
    SensitivityResult r;
    try {
      r = RunSensitivity(scene, params, values, outcomes, run_options);
    } catch (...) {
      if (show_progress) std::fputc('\n', stderr);
      throw;
    }
    if (show_progress) std::fputc('\n', stderr);
    std::vector<std::vector<double>> fd;
    if (fd_step_ > 0.0) fd = CentralDifferences(scene, params, values, outcomes, options_, fd_step_);
    WriteSensitivityOutputs(out_dir_, scene, options_, r, fd_step_ > 0.0 ? &fd : nullptr, fd_step_,
                            std::vector<std::string>(argv, argv + argc));
    const bool ode = IsOdeSensitivity(options_.formulation);
    std::printf("%s: %zu outcomes x %zu parameters (%s, %s BDF, rtol %g) in %.3f s wall, end %s\n",
                scene.name.c_str(), outcomes.size(), params.size(), options_.formulation.c_str(), ode ? "CVODES" : "IDAS",
                options_.rtol, r.wall_time_s, r.end_reason.c_str());
    std::printf("  steps %ld, %s evals %ld, sensitivity %s evals %ld, restarts %ld\n", r.stats.steps, ode ? "rhs" : "residual",
                r.stats.residual_evaluations, ode ? "rhs" : "residual", r.sensitivity_rhs_evaluations, r.stats.restarts);
    if (!ode) std::printf("  consistent initial sensitivities: relative residual %.2g\n", r.initial_sensitivity_residual);
    std::printf("  %-28s %-32s %14s %14s %12s%s\n", "outcome", "parameter", "value", "derivative", "normalized",
                fd_step_ > 0.0 ? "    fd_derivative   rel.diff" : "");
    for (size_t k = 0; k < outcomes.size(); ++k) {
      for (size_t j = 0; j < params.size(); ++j) {
        const double d = r.derivatives[k][j];
        std::printf("  %-28s %-32s %14.8g %14.8g %12.5g", outcomes[k].c_str(), params[j].column.c_str(), r.values[k], d,
                    Normalized(values[j], r.values[k], d));
        if (fd_step_ > 0.0) {
          const double f = fd[k][j];
          std::printf("  %15.8g %10.2e", f, std::abs(d - f) / std::max(std::abs(f), 1e-300));
        }
        std::printf("\n");
      }
    }
    std::printf("  wrote %s/{sensitivity.csv, sensitivity.json, sensitivity_trajectory.csv}\n", out_dir_.c_str());
    return 0;
  } catch (const InputError& e) {
    std::fprintf(stderr, "kneedyn sensitivity: error: %s\n", MessageUnder("kneedyn sensitivity", e.what()).c_str());
    return 2;
  } catch (const Error& e) {
    std::fprintf(stderr, "kneedyn sensitivity: error: %s\n", MessageUnder("kneedyn sensitivity", e.what()).c_str());
    return 1;
  }
}

}  // namespace kneedyn::sensitivity
