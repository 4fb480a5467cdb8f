#include "benchmarks/bench_run.hpp"

#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <sys/utsname.h>
#include <thread>

#include "formulations/run_output.hpp"
#include "solver/error.hpp"

#ifndef KNEEDYN_BUILD_TYPE
#define KNEEDYN_BUILD_TYPE "unknown"
#endif

namespace kneedyn {
namespace bench {

namespace {
std::string Num(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.3g", v);
  return buf;
}
}  // namespace

bool IsFixedStep(const std::string& formulation, const std::string& integrator) {
  return IsFixedStep(FindFormulation(formulation), integrator);
}

std::string BenchConfig::Name() const {
  std::string name = formulation;
  if (!integrator.empty()) name += ":" + integrator;
  name += fixed_step ? "/step=" + Num(step) : "/rtol=" + Num(rtol);
  if (max_steps != 200000) name += "/max_steps=" + std::to_string(max_steps);
  if (stabilization != "none") name += "/stabilization=" + stabilization;
  return name;
}

nlohmann::json BenchConfig::SettingJson() const {
  nlohmann::json j;
  if (fixed_step) {
    j["step"] = step;
    if (FindFormulation(formulation).fixed_step) {  // tolerances drive its Newton test
      j["newton_rtol"] = rtol;
      j["newton_atol"] = atol;
    }
  } else {
    j["rtol"] = rtol;
    j["atol"] = atol;
  }
  if (max_steps != 200000) j["max_steps"] = max_steps;
  if (stabilization != "none") j["stabilization"] = stabilization;
  return j;
}

FormulationOptions BenchConfig::Options() const {
  FormulationOptions o;
  o.integrator = IntegratorOption(integrator);
  o.rtol = rtol;
  o.atol = atol;
  if (fixed_step) o.step = step;
  o.max_steps = max_steps;
  o.stabilization = ParsedOptionValue<Stabilization>(stabilization);
  return o;
}

Outcome RunConfig(const Scene& scene, const BenchConfig& config, double comparison_interval) {
  Outcome out;
  RunSettings settings;
  settings.formulation = config.formulation;
  settings.options = config.Options();
  try {
    out.form = CreateFormulation(config.formulation, scene, settings.options)->contact_form();
    out.result = RunScene(scene, settings);
  } catch (const std::exception& e) {  // InputError: a setting the formulation rejects
    out.status = "failed";
    out.reason = e.what();
    return out;
  }
  out.status = out.result.completed ? "ok" : "failed";
  out.reason = out.result.failure;
  out.solution = ExtractSolution(scene, out.form, out.result, comparison_interval);
  return out;
}

Reference LoadReference(const std::string& path) {
  std::ifstream in(path);
  if (!in) Throw<InputError>("LoadReference", "reference file '", path, "' cannot be read");
  Reference r;
  try {
    in >> r.json;
    r.solution = SolutionFromJson(r.json.at("solution"), "reference file '" + path + "'");
    r.comparison_interval = r.json.at("comparison_interval_s").get<double>();
    r.conservative = r.json.value("conservative", false);
    if (r.json.contains("accuracy_scd") && r.json["accuracy_scd"].is_number()) {
      r.accuracy_scd = r.json["accuracy_scd"].get<double>();
    }
  } catch (const nlohmann::json::exception& e) {
    Throw<InputError>("LoadReference", "reference file '", path, "': ", e.what());
  }
  return r;
}

Metrics Evaluate(const Scene& scene, const Outcome& outcome, const Reference& reference) {
  Metrics m;
  if (outcome.result.samples.empty()) {
    m.scd = std::nan("");
    m.missing_times = static_cast<int>(reference.solution.times.size());
    for (const std::string& c : VariableClasses()) m.mixed[c] = std::nan("");
    return m;
  }
  m = Compare(outcome.solution, reference.solution);
  AddRunMetrics(scene, outcome.result, reference.conservative, &m);
  ApplyScdCeiling(reference.accuracy_scd, &m);
  return m;
}

nlohmann::json CountersJson(const SolverStats& s) {
  return {{"residual_evaluations", s.residual_evaluations},
          {"jacobian_evaluations", s.jacobian_evaluations},
          {"linear_solver_setups", s.linear_solver_setups},
          {"nonlinear_iterations", s.nonlinear_iterations},
          {"steps", s.steps},
          {"rejected_steps", s.rejected_steps()},
          {"error_test_failures", s.error_test_failures},
          {"convergence_failures", s.convergence_failures},
          {"root_evaluations", s.root_evaluations},
          {"projections", s.projections},
          {"restarts", s.restarts}};
}

nlohmann::json MachineJson() {
  nlohmann::json j;
  utsname u{};
  if (uname(&u) == 0) {
    j["uname"] = std::string(u.sysname) + " " + u.nodename + " " + u.release + " " + u.version + " " + u.machine;
  }
  j["nproc"] = std::thread::hardware_concurrency();
#if defined(__clang__)
  j["compiler"] = std::string("clang ") + __clang_version__;
#elif defined(__GNUC__)
  j["compiler"] = std::string("gcc ") + __VERSION__;
#endif
  j["build_type"] = KNEEDYN_BUILD_TYPE;
  j["versions"] = LibraryVersionsJson();
  return j;
}

std::string CommandLine(int argc, char** argv) {
  std::string out;
  for (int i = 0; i < argc; ++i) {
    std::string a = argv[i];
    // Quoted when a shell would split or expand it, so the line can be pasted back.
    const bool plain = !a.empty() && a.find_first_not_of("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ"
                                                         "0123456789_-+=/.,:@%") == std::string::npos;
    if (!plain) {
      std::string q = "'";
      for (char c : a) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
      a = q + "'";
    }
    out += (i ? " " : "") + a;
  }
  return out;
}

}  // namespace bench
}  // namespace kneedyn
