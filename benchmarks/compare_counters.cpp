// compare_counters — CI performance tracking with deterministic counters (issue 5).
//
//   compare_counters [--baseline benchmarks/baseline_counters.json] [--write]
//
// Reruns the baseline's fixed set of runs (scene, formulation, integrator, setting) and
// fails (exit 1) when
//   - a solver counter (residual_evaluations, jacobian_evaluations, linear_solver_setups,
//     nonlinear_iterations, steps, rejected_steps) exceeds its baseline by more than
//     counter_threshold (relative, +10 %);
//   - the accuracy scd (metrics.hpp, against the scene's stored reference) drops by more
//     than scd_drop (0.5 digit) below its baseline;
//   - a run that succeeded in the baseline fails;
//   - the run-time ratio numerator/denominator (two configurations timed in this same
//     process, min of `repeats` RunResult.wall_time_s each) exceeds the baseline ratio by more than the
//     factor ratio_tolerance. Absolute times are never compared (machines differ).
// Counters that fall are reported (update the baseline with --write) but do not fail.
// --write reruns everything and rewrites the baseline file (keeping its thresholds).
// Exit codes: 0 pass, 1 regression, 2 bad input.
#include <CLI/CLI.hpp>

#include "formulations/cli.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <fstream>
#include <iostream>

#include "benchmarks/bench_run.hpp"
#include "solver/error.hpp"

using namespace kneedyn;
using namespace kneedyn::bench;

namespace {

const char* kCounters[] = {"residual_evaluations", "jacobian_evaluations", "linear_solver_setups",
                           "nonlinear_iterations", "steps", "rejected_steps"};

BenchConfig ConfigFromJson(const nlohmann::json& r) {
  BenchConfig c;
  c.formulation = r.at("formulation").get<std::string>();
  c.integrator = r.value("integrator", "");
  const nlohmann::json& s = r.at("setting");
  c.fixed_step = s.contains("step");
  if (c.fixed_step) {
    c.step = s.at("step").get<double>();
    c.rtol = s.value("newton_rtol", c.rtol);
    c.atol = s.value("newton_atol", c.atol);
  } else {
    c.rtol = s.at("rtol").get<double>();
    c.atol = s.at("atol").get<double>();
  }
  c.max_steps = s.value("max_steps", c.max_steps);
  c.stabilization = s.value("stabilization", c.stabilization);
  return c;
}

// CPU-time proxy: min over repeats of the run's wall time (RunResult.wall_time_s).
double MinTime(const Scene& scene, const BenchConfig& c, int repeats) {
  double best = 1e300;
  for (int i = 0; i < repeats; ++i) best = std::min(best, RunConfig(scene, c).result.wall_time_s);
  return best;
}

std::string ScenePath(const std::string& name) {
  return ReferenceDataDir() + "/scenes/" + name + ".yaml";
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"kneedyn counter regression check"};
  std::string baseline_path = "benchmarks/baseline_counters.json";
  bool write = false;
  app.add_option("--baseline", baseline_path, "baseline JSON")->capture_default_str();
  app.add_flag("--write", write, "rerun and rewrite the baseline");
  if (const int code = ParseCommandLine(app, argc, argv, "compare_counters"); code >= 0) return code;
  try {
    nlohmann::json base;
    {
      std::ifstream in(baseline_path);
      if (!in) Throw<InputError>("compare_counters", "--baseline '", baseline_path, "' cannot be read");
      in >> base;
    }
    const double threshold = base.at("counter_threshold").get<double>();
    const double scd_drop = base.at("scd_drop").get<double>();
    bool ok = true;
    std::map<std::string, Scene> scenes;
    std::map<std::string, Reference> refs;
    for (nlohmann::json& r : base.at("runs")) {
      const std::string scene_name = r.at("scene").get<std::string>();
      if (!scenes.count(scene_name)) {
        scenes.emplace(scene_name, LoadScene(ScenePath(scene_name)));
        refs.emplace(scene_name, LoadReference(ReferenceDataDir() + "/references/" + scene_name + ".json"));
      }
      const Scene& scene = scenes.at(scene_name);
      const BenchConfig c = ConfigFromJson(r);
      const Outcome out = RunConfig(scene, c, refs.at(scene_name).comparison_interval);
      const Metrics m = Evaluate(scene, out, refs.at(scene_name));
      const nlohmann::json counters = CountersJson(out.result.stats);
      std::printf("%-16s %-32s %-6s scd %.2f\n", scene_name.c_str(), c.Name().c_str(), out.status.c_str(), m.scd);
      if (write) {
        r["status"] = out.status;
        r["scd"] = std::isfinite(m.scd) ? nlohmann::json(m.scd) : nlohmann::json(nullptr);
        for (const char* k : kCounters) r["counters"][k] = counters.at(k);
        continue;
      }
      if (r.at("status") == "ok" && out.status != "ok") {
        std::printf("  REGRESSION: run failed: %s\n", out.reason.c_str());
        ok = false;
        continue;
      }
      for (const char* k : kCounters) {
        const double b = r.at("counters").at(k).get<double>();
        const double n = counters.at(k).get<double>();
        const double limit = b * (1.0 + threshold);
        if (n > limit && n > b + 1) {  // +1: a counter at 0 or 1 may move by one
          std::printf("  REGRESSION: %s = %.0f > baseline %.0f (+%.0f %% allowed)\n", k, n, b, 100 * threshold);
          ok = false;
        } else if (n < b * (1.0 - threshold)) {
          std::printf("  improved: %s = %.0f < baseline %.0f (consider --write)\n", k, n, b);
        }
      }
      if (!r.at("scd").is_null() && !(m.scd >= r.at("scd").get<double>() - scd_drop)) {
        std::printf("  REGRESSION: scd %.2f < baseline %.2f - %.1f\n", m.scd, r.at("scd").get<double>(), scd_drop);
        ok = false;
      }
    }

    nlohmann::json& ratio = base.at("runtime_ratio");
    const std::string scene_name = ratio.at("scene").get<std::string>();
    const Scene scene = LoadScene(ScenePath(scene_name));
    const int repeats = ratio.at("repeats").get<int>();
    const BenchConfig num = ConfigFromJson(ratio.at("numerator"));
    const BenchConfig den = ConfigFromJson(ratio.at("denominator"));
    const double value = MinTime(scene, num, repeats) / MinTime(scene, den, repeats);
    std::printf("runtime ratio %s / %s = %.3f", num.Name().c_str(), den.Name().c_str(), value);
    if (write) {
      ratio["value"] = value;
      std::printf("\n");
      const std::string tmp = baseline_path + ".tmp";
      {
        std::ofstream f(tmp);
        f << base.dump(1) << "\n";
        if (!f) Throw<InputError>("compare_counters", "--baseline '", baseline_path, "' cannot be written");
      }
      std::rename(tmp.c_str(), baseline_path.c_str());
      std::printf("wrote %s\n", baseline_path.c_str());
      return 0;
    }
    const double b = ratio.at("value").get<double>();
    const double factor = ratio.at("ratio_tolerance").get<double>();
    std::printf(" (baseline %.3f, allowed x%.1f)\n", b, factor);
    if (value > b * factor) {
      std::printf("  REGRESSION: runtime ratio %.3f > %.3f x %.1f\n", value, b, factor);
      ok = false;
    }
    std::printf("%s\n", ok ? "counters within baseline" : "PERFORMANCE REGRESSION");
    return ok ? 0 : 1;
  } catch (const InputError& e) {
    std::cerr << "compare_counters: " << e.what() << "\n";
    return 2;
  } catch (const nlohmann::json::exception& e) {
    std::cerr << "compare_counters: --baseline '" << baseline_path << "': " << e.what() << "\n";
    return 2;
  }
}
