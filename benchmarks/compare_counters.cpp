// compare_counters — CI performance tracking with deterministic counters
// (benchmarks/README.md, "CI counter tracking").
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
//     process, alternately, min of `repeats` thread CPU times each) exceeds the baseline ratio by more than the
//     factor ratio_tolerance. Absolute times are never compared (machines differ).
// Counters that fall are reported (update the baseline with --write) but do not fail.
// --write reruns everything and rewrites the baseline file (keeping its thresholds), with a
// `provenance` {command, commit, date} of the recording (for --instructions, inside
// instruction_counts, with the measured kneedyn's `--version`).
//
//   compare_counters --instructions --kneedyn PATH [--valgrind PATH] [--write]
//
// Instead of the above (benchmarks/README.md, "Instruction counts"): the whole-process
// instruction count (valgrind --tool=cachegrind --cache-sim=no, total `I refs`) of `kneedyn
// run` on each entry of the baseline's `instruction_counts.runs` (one per registered
// formulation without a patella, kept by hand and checked by the test
// Registry.EveryFormulationIsInTheReadmesTableAndTheBaselines, and the runtime targets'
// configurations). Fails when a count exceeds its baseline by more than
// `instruction_counts.threshold` (+5 %); a count below baseline × (1 − threshold) is reported
// so the baseline can be tightened (--write). A run whose entry has `outside_run_scene` is
// also counted under callgrind twice, whole and with collection only inside
// `kneedyn::RunScene`: the difference is start-up, scene loading and writing the outputs,
// gated against that field by the same threshold (a regression there moves a whole-process
// count by a fraction of its own size) and printed as a share of the run beside
// `outside_target_share`. Without valgrind it prints why and exits 77 (ctest
// SKIP_RETURN_CODE).
// Exit codes: 0 pass, 1 regression, 2 bad input, 77 skipped (no valgrind).
#include <CLI/CLI.hpp>

#include "solver/internal/command_line.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <sstream>
#include <time.h>
#include <unistd.h>

#include "benchmarks/bench_run.hpp"
#include "formulations/output_file.hpp"
#include "formulations/version.hpp"
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

// CPU time of this thread, s: unlike wall time it does not count the time the scheduler
// gives other processes, so the ratio holds on a loaded machine (a wall-time ratio read
// 12.6 against 1.35 with seven builds on two cores).
double ThreadCpuSeconds() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

// The ratio numerator/denominator of the min over repeats of each configuration's thread
// CPU time; the two are timed alternately so that a slow phase of the machine (cache
// pressure, frequency) falls on both.
double MinCpuTimeRatio(const Scene& scene, const BenchConfig& numerator, const BenchConfig& denominator,
                       int repeats) {
  double best[2] = {1e300, 1e300};
  const BenchConfig* configs[2] = {&numerator, &denominator};
  for (int i = 0; i < repeats; ++i) {
    for (int k = 0; k < 2; ++k) {
      const double start = ThreadCpuSeconds();
      RunConfig(scene, *configs[k]);
      best[k] = std::min(best[k], ThreadCpuSeconds() - start);
    }
  }
  return best[0] / best[1];
}

std::string ScenePath(const std::string& name) {
  return ReferenceDataDir() + "/scenes/" + name + ".yaml";
}

// Single-quoted for /bin/sh.
std::string Quote(const std::string& s) {
  std::string out = "'";
  for (char c : s) out += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return out + "'";
}

// The first executable `name` on PATH, or empty.
std::string FindOnPath(const std::string& name) {
  if (name.find('/') != std::string::npos) return access(name.c_str(), X_OK) == 0 ? name : "";
  const char* path = std::getenv("PATH");
  std::stringstream dirs(path ? path : "");
  std::string dir;
  while (std::getline(dirs, dir, ':')) {
    const std::string candidate = (dir.empty() ? "." : dir) + "/" + name;
    if (access(candidate.c_str(), X_OK) == 0) return candidate;
  }
  return "";
}

// Instructions executed (the `summary:` line of the tool's output file, the `I refs` it
// prints) by `kneedyn run SCENE --formulation F ARGS... --out TMP --quiet` under valgrind.
// `tool` is cachegrind (the whole process), callgrind (the same) or callgrind with
// `--toggle-collect=FUNCTION` (only inside FUNCTION and what it calls).
enum class Tool { kCachegrind, kCallgrind, kCallgrindInsideRunScene };
long long CountInstructions(const std::string& valgrind, const std::string& kneedyn,
                            const std::string& scene, const nlohmann::json& run, Tool tool,
                            const std::filesystem::path& tmp, std::string* failure) {
  const std::filesystem::path out_file = tmp / "valgrind.out", log = tmp / "log.txt";
  std::filesystem::remove(out_file);
  // Each run publishes into a directory that does not exist yet: replacing the last run's
  // files costs ~26 k instructions more, which made a count depend on the entry before it.
  std::filesystem::remove_all(tmp / "out");
  std::string cmd = Quote(valgrind);
  if (tool == Tool::kCachegrind) {
    cmd += " --tool=cachegrind --cache-sim=no --cachegrind-out-file=" + Quote(out_file.string());
  } else {
    cmd += " --tool=callgrind --callgrind-out-file=" + Quote(out_file.string());
    // The scope of the in-process times and of instruction_sweep.py.
    if (tool == Tool::kCallgrindInsideRunScene) cmd += " " + Quote("--toggle-collect=kneedyn::RunScene(*");
  }
  cmd += " " + Quote(kneedyn) + " run " + Quote(scene) + " --formulation " +
         Quote(run.at("formulation").get<std::string>());
  for (const nlohmann::json& a : run.at("args")) cmd += " " + Quote(a.get<std::string>());
  cmd += " --quiet --out " + Quote((tmp / "out").string()) + " > " + Quote(log.string()) + " 2>&1";
  const int status = std::system(cmd.c_str());
  std::ifstream in(out_file);
  std::string line;
  while (std::getline(in, line)) {
    if (line.rfind("summary:", 0) == 0) {
      if (status != 0) *failure = "kneedyn run exited with status " + std::to_string(status) + " (log " + log.string() + ")";
      return std::atoll(line.c_str() + 8);
    }
  }
  *failure = "no valgrind summary (status " + std::to_string(status) + "; log " + log.string() + ")";
  return -1;
}

// Prints a count against its baseline; false above baseline × (1 + threshold).
bool WithinBaseline(const char* what, long long n, double b, double threshold) {
  std::printf(" (baseline %.0f, %+.1f %%)\n", b, 100.0 * (n / b - 1.0));
  if (n > b * (1.0 + threshold)) {
    std::printf("  REGRESSION: %s %lld > baseline %.0f (+%.0f %% allowed)\n", what, n, b, 100 * threshold);
    return false;
  }
  if (n < b * (1.0 - threshold)) {
    std::printf("  improved: %s %lld < baseline %.0f (tighten it: compare_counters --instructions --write)\n", what,
                n, b);
  }
  return true;
}

// Start-up, scene loading and output of `run`: callgrind's whole-process count minus its
// count inside kneedyn::RunScene. -1 with *failure set when either count fails or the
// difference is not in (0, whole). Both counts are callgrind's: cachegrind's whole count of
// the same run (the entry's `instructions`) is ~60 k higher, which would bias the difference.
long long CountOutsideRunScene(const std::string& valgrind, const std::string& kneedyn, const std::string& scene,
                               const nlohmann::json& run, const std::filesystem::path& tmp, long long* whole,
                               std::string* failure) {
  *whole = CountInstructions(valgrind, kneedyn, scene, run, Tool::kCallgrind, tmp, failure);
  if (!failure->empty()) return -1;
  const long long inside = CountInstructions(valgrind, kneedyn, scene, run, Tool::kCallgrindInsideRunScene, tmp, failure);
  if (!failure->empty()) return -1;
  if (!(inside > 0 && inside < *whole)) {
    *failure = "callgrind counted " + std::to_string(inside) + " instructions inside kneedyn::RunScene of " +
               std::to_string(*whole) + " (the rule: 0 < inside < whole; was the function renamed?)";
    return -1;
  }
  return *whole - inside;
}

// A baseline run's count `field` (instructions, outside_run_scene): a positive number, else
// InputError naming the run, the field and its value. Checked for every run before any runs.
double BaselineCount(const nlohmann::json& run, const char* field, const std::string& baseline_path) {
  const nlohmann::json value = run.contains(field) ? run.at(field) : nlohmann::json();
  if (!value.is_number() || !(value.get<double>() > 0.0)) {
    Throw<InputError>("compare_counters", "--baseline '", baseline_path, "': instruction_counts.runs entry ",
                      run.value("formulation", nlohmann::json()).dump(), ": ", field, " = ", value.dump(),
                      " (an instruction count: a number > 0)");
  }
  return value.get<double>();
}

// A number of the baseline (`where` names its field; `fallback` when absent, null: required)
// that `valid` accepts, else InputError with `rule`. A negative threshold had turned every
// entry into a regression, or every counter into an improvement.
double BaselineNumber(const nlohmann::json& parent, const char* field, const std::string& where,
                      const std::string& baseline_path, bool (*valid)(double), const char* rule,
                      const nlohmann::json& fallback = nlohmann::json()) {
  const nlohmann::json value = parent.contains(field) ? parent.at(field) : fallback;
  if (!value.is_number() || !valid(value.get<double>())) {
    Throw<InputError>("compare_counters", "--baseline '", baseline_path, "': ", where, " = ", value.dump(), " (", rule,
                      ")");
  }
  return value.get<double>();
}
// What recorded a baseline section (its --write): the command line, the commit this program
// was built from (formulations/version.hpp, "-dirty" for uncommitted changes) and the UTC date.
nlohmann::json Provenance(int argc, char** argv) {
  std::string command = "compare_counters";
  for (int i = 1; i < argc; ++i) command += std::string(" ") + argv[i];
  char date[32];
  const std::time_t now = std::time(nullptr);
  std::tm utc{};
  gmtime_r(&now, &utc);
  std::strftime(date, sizeof date, "%Y-%m-%dT%H:%M:%SZ", &utc);
  const std::string commit = KneedynGitCommit();
  return {{"command", command}, {"commit", commit.empty() ? "unknown (not built from git)" : commit}, {"date", date}};
}

// The first line of `kneedyn --version` (its version and commit), or why it is not known.
std::string VersionLineOf(const std::string& kneedyn) {
  const std::string cmd = "'" + kneedyn + "' --version 2>/dev/null";
  FILE* pipe = popen(cmd.c_str(), "r");
  if (pipe == nullptr) return "unknown (could not run --version)";
  char line[256] = {0};
  const bool read = std::fgets(line, sizeof line, pipe) != nullptr;
  pclose(pipe);
  std::string text = read ? line : "unknown (no --version output)";
  while (!text.empty() && (text.back() == '\n' || text.back() == '\r')) text.pop_back();
  return text;
}

bool IsFraction(double v) { return v > 0.0 && v < 1.0; }
constexpr char kThresholdRule[] = "a relative threshold: a number, 0 < threshold < 1";

int InstructionCounts(nlohmann::json& base, const std::string& baseline_path, const std::string& valgrind_name,
                      const std::string& kneedyn, bool write, const nlohmann::json& provenance) {
  const std::string valgrind = FindOnPath(valgrind_name);
  if (valgrind.empty()) {
    std::printf("SKIPPED: valgrind ('%s') not found on PATH; instruction counts need it "
                "(Debian package valgrind, installed by .ci/bootstrap)\n", valgrind_name.c_str());
    return 77;
  }
  if (kneedyn.empty() || access(kneedyn.c_str(), X_OK) != 0) {
    Throw<InputError>("compare_counters", "--kneedyn '", kneedyn, "' is not an executable");
  }
  nlohmann::json& ic = base.at("instruction_counts");
  const double threshold =
      BaselineNumber(ic, "threshold", "instruction_counts.threshold", baseline_path, IsFraction, kThresholdRule);
  const double target_share = BaselineNumber(ic, "outside_target_share", "instruction_counts.outside_target_share",
                                             baseline_path, IsFraction, "a share of the run: a number, 0 < share < 1",
                                             0.10);
  if (!write) {
    for (const nlohmann::json& r : ic.at("runs")) {
      BaselineCount(r, "instructions", baseline_path);
      if (r.contains("outside_run_scene")) BaselineCount(r, "outside_run_scene", baseline_path);
    }
  }
  const std::string scene = ScenePath(ic.at("scene").get<std::string>());
  const std::filesystem::path tmp =
      std::filesystem::temp_directory_path() / ("kneedyn_icount_" + std::to_string(getpid()));
  std::filesystem::create_directories(tmp);
  bool ok = true;
  for (nlohmann::json& r : ic.at("runs")) {
    std::string args;
    for (const nlohmann::json& a : r.at("args")) args += " " + a.get<std::string>();
    if (args.empty()) args = " (its defaults)";
    std::string failure;
    const long long n = CountInstructions(valgrind, kneedyn, scene, r, Tool::kCachegrind, tmp, &failure);
    std::printf("%-26s %-34s %12lld instructions", r.at("formulation").get<std::string>().c_str(), args.c_str(), n);
    if (!failure.empty()) {
      std::printf("\n  %s: %s\n", n < 0 || !write ? "REGRESSION" : "note", failure.c_str());
      ok = false;
      continue;
    }
    if (write) {
      r["instructions"] = n;
      std::printf("\n");
    } else {
      ok = WithinBaseline("instructions", n, BaselineCount(r, "instructions", baseline_path), threshold) && ok;
    }
    if (!r.contains("outside_run_scene")) continue;
    long long whole = 0;
    const long long outside = CountOutsideRunScene(valgrind, kneedyn, scene, r, tmp, &whole, &failure);
    if (outside < 0) {
      std::printf("  REGRESSION: outside RunScene: %s\n", failure.c_str());
      ok = false;
      continue;
    }
    const double share = double(outside) / double(whole);
    std::printf("%-26s %-34s %12lld outside RunScene, %.1f %% of %lld (target <= %.0f %%: %s)",
                r.at("formulation").get<std::string>().c_str(), args.c_str(), outside, 100 * share, whole,
                100 * target_share, share <= target_share ? "met" : "not met");
    if (write) {
      r["outside_run_scene"] = outside;
      std::printf("\n");
    } else {
      ok = WithinBaseline("outside RunScene", outside, BaselineCount(r, "outside_run_scene", baseline_path),
                          threshold) &&
           ok;
    }
  }
  if (ok) std::filesystem::remove_all(tmp);
  if (write) {
    if (!ok) {
      std::printf("not written: a run failed\n");
      return 1;
    }
    ic["provenance"] = provenance;
    ic["provenance"]["kneedyn"] = VersionLineOf(kneedyn);
    WriteOutputFile("compare_counters", "--baseline", baseline_path, base.dump(1) + "\n");
    std::printf("wrote instruction_counts of %s\n", baseline_path.c_str());
    return 0;
  }
  std::printf("%s\n", ok ? "instruction counts within baseline" : "PERFORMANCE REGRESSION");
  return ok ? 0 : 1;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"kneedyn counter regression check"};
  std::string baseline_path = "benchmarks/baseline_counters.json";
  bool write = false, instructions = false;
  std::string kneedyn, valgrind = "valgrind";
  app.add_option("--baseline", baseline_path, "baseline JSON")->capture_default_str();
  app.add_flag("--write", write, "rerun and rewrite the baseline");
  app.add_flag("--instructions", instructions,
               "check (or with --write record) the valgrind instruction counts of `kneedyn run` instead");
  app.add_option("--kneedyn", kneedyn, "the kneedyn executable (with --instructions)");
  app.add_option("--valgrind", valgrind, "valgrind executable (with --instructions)")->capture_default_str();
  if (const int code = ParseCommandLine(app, argc, argv, "compare_counters"); code >= 0) return code;
  try {
    // --write replaces the baseline at the end: a path it cannot replace is refused now, not
    // after minutes of runs.
    if (write) CheckOutputFile("compare_counters", "--baseline", baseline_path);
    nlohmann::json base;
    {
      std::ifstream in(baseline_path);
      if (!in) Throw<InputError>("compare_counters", "--baseline '", baseline_path, "' cannot be read");
      in >> base;
    }
    if (instructions) return InstructionCounts(base, baseline_path, valgrind, kneedyn, write, Provenance(argc, argv));
    const double threshold =
        BaselineNumber(base, "counter_threshold", "counter_threshold", baseline_path, IsFraction, kThresholdRule);
    const double scd_drop = BaselineNumber(
        base, "scd_drop", "scd_drop", baseline_path, [](double v) { return v >= 0.0; },
        "digits the scd may fall: a number >= 0");
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
    const double value = MinCpuTimeRatio(scene, num, den, repeats);
    std::printf("runtime ratio %s / %s = %.3f", num.Name().c_str(), den.Name().c_str(), value);
    if (write) {
      ratio["value"] = value;
      std::printf("\n");
      base["provenance"] = Provenance(argc, argv);
      WriteOutputFile("compare_counters", "--baseline", baseline_path, base.dump(1) + "\n");
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
    std::cerr << "compare_counters: error: " << e.what() << "\n";
    return 2;
  } catch (const nlohmann::json::exception& e) {
    std::cerr << "compare_counters: error: --baseline '" << baseline_path << "': " << e.what() << "\n";
    return 2;
  } catch (const std::exception& e) {  // any other failure: a message and exit 1, no abort
    std::cerr << "compare_counters: error: " << e.what() << "\n";
    return 1;
  }
}
