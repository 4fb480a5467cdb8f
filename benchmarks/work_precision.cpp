// work_precision — work-precision sweep of every registered formulation
// (benchmarks/README.md, "Work-precision sweep").
//
//   work_precision [--short] [--scene FILE] [--reference FILE] [--json OUT] [--csv OUT]
//                  [--repetitions N] [--only SUBSTRING] [--rtol-min R] [--include-broken]
//                  [--include DIR]... [--benchmark_* flags]
//
// For every formulation in RegisteredFormulations() (and each of its integrators):
//   adaptive    rtol = 10^(−k/4), atol = 1e-2 rtol: 1e-2 … 1e-11 (37 settings; --short 3);
//               --rtol-min R changes the tightest (keep it ≥ 3 decades above the
//               reference's rtol 1e-14: the stored references, scd ≥ 11.2, measure scd
//               up to ~10)
//               ede additionally with --stabilization projection (dopri5) and
//               cvode-projection (cvode-bdf)
//   fixed step  h = 4e-3 / 2^i s, i = 0 … 5: 4e-3 … 1.25e-4 (6 settings; --short 2);
//               newmark and generalized-alpha (second order, and their lift-off error at
//               h = 1.25e-4 is 1.6e-5 s) down to i = 8, h = 1.5625e-5 s (9 settings), so
//               that they reach their digits; Newton tolerance rtol 1e-9, atol 1e-11
// Each setting is run once untimed for its metrics (metrics.hpp, against the stored
// reference) and its deterministic solver counters, then timed by Google Benchmark
// (RegisterBenchmark, 5 repetitions (--short 3), aggregates only: median, min, max CPU time). The
// counters go to state.counters too. A run that fails is a result: status failed with the
// solver's reason (its partial metrics and time are kept). --include-broken adds one
// deliberately broken setting (dae with max_steps = 3) for the tests.
//
// --include DIR: outside solvers' results scored by `kneedyn score` (docs/problem.md), every
// file named score.json or *.score.json under DIR, join the results as they are (status,
// reason, metrics, their own CPU time and counters; "origin": "outside", "source": the file):
// not run or timed here, and a failed outside run stays a failed result. Each file must be
// scored against this sweep's scene and reference, else exit 2 naming the file. The fairness
// manifest (context.components) gets one entry per outside formulation name, its version and
// flags "not recorded".
//
// Output: one JSON per sweep {header: {machine, scene, reference, mode, date, ...},
// results: [{formulation, integrator, setting, status, reason, metrics, cpu_time_s
// {median, min, max}, counters}]} and a compact CSV with one row per result.
// Written completely or not at all. Exit 0 when the sweep ran (failed runs included),
// 2 on bad input.
#include <benchmark/benchmark.h>
#include <CLI/CLI.hpp>

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <regex>
#include <sstream>

#include "benchmarks/bench_run.hpp"
#include "solver/internal/command_line.hpp"
#include "formulations/progress.hpp"
#include "formulations/output_file.hpp"
#include "formulations/version.hpp"
#include "scene/internal/json_field.hpp"
#include "solver/error.hpp"

using namespace kneedyn;
using namespace kneedyn::bench;

namespace {

struct Entry {
  BenchConfig config;
  Outcome outcome;
  Metrics metrics;
  std::map<std::string, double> cpu;  // median, min, max (s)
};

// Collects the aggregates while printing them like the console reporter.
class CollectingReporter : public benchmark::ConsoleReporter {
 public:
  explicit CollectingReporter(std::map<std::string, Entry*>* by_name)
      : benchmark::ConsoleReporter(::isatty(::fileno(stdout)) ? OO_Defaults : OO_Tabular), by_name_(by_name) {}
  void ReportRuns(const std::vector<Run>& runs) override {
    for (const Run& run : runs) {
      if (run.run_type != Run::RT_Aggregate) continue;
      auto it = by_name_->find(run.run_name.function_name);
      if (it == by_name_->end()) continue;
      const std::string& agg = run.aggregate_name;
      if (agg == "median" || agg == "min" || agg == "max") {
        it->second->cpu[agg] = 1e-3 * run.GetAdjustedCPUTime();  // unit: kMillisecond -> s
      }
    }
    ConsoleReporter::ReportRuns(runs);
  }

 private:
  std::map<std::string, Entry*>* by_name_;
};

double MinOf(const std::vector<double>& v) { return *std::min_element(v.begin(), v.end()); }
double MaxOf(const std::vector<double>& v) { return *std::max_element(v.begin(), v.end()); }

std::vector<BenchConfig> Grid(bool short_mode, double rtol_min, const std::string& only,
                              bool include_broken) {
  std::vector<BenchConfig> grid;
  std::vector<double> rtols, steps;
  if (short_mode) {
    rtols = {1e-3, 1e-5, 1e-7};
    steps = {2e-3, 5e-4};
  } else {
    const int k_max = static_cast<int>(std::lround(-4.0 * std::log10(rtol_min)));
    for (int k = 8; k <= k_max; ++k) rtols.push_back(std::pow(10.0, -k / 4.0));
    for (int i = 0; i <= 5; ++i) steps.push_back(4e-3 / std::pow(2.0, i));
  }
  for (const FormulationInfo& info : RegisteredFormulations()) {
    if (info.needs_patella) continue;  // the chapter scene has no patella
    std::vector<std::string> integrators = OptionNames(info.integrators);
    if (integrators.empty()) integrators.push_back("");
    for (const std::string& integ : integrators) {
      BenchConfig c;
      c.formulation = info.name;
      c.integrator = integ;
      c.fixed_step = IsFixedStep(info.name, integ);
      if (c.fixed_step) {
        if (info.fixed_step) {  // tolerances drive the Newton test
          c.rtol = 1e-9;
          c.atol = 1e-11;
        }
        std::vector<double> own_steps = steps;
        if (info.fixed_step && !short_mode) {  // newmark family: three more halvings
          for (int i = 6; i <= 8; ++i) own_steps.push_back(4e-3 / std::pow(2.0, i));
        }
        for (double h : own_steps) {
          c.step = h;
          grid.push_back(c);
        }
      } else {
        // ede: also the two projections: kneedyn's project-and-restart with an
        // explicit RK method, CVODE's own (CVodeSetProjFn) with BDF.
        // Which formulations have them is their declared capability (FormulationInfo).
        const auto declares = [&info](const char* s) {
          const Stabilization value = ParsedOptionValue<Stabilization>(s);
          return std::find(info.stabilizations.begin(), info.stabilizations.end(), value) != info.stabilizations.end();
        };
        std::vector<std::string> stabilizations = {"none"};
        if (declares("projection") && integ == "dopri5") stabilizations.push_back("projection");
        if (declares("cvode-projection") && integ == "cvode-bdf") stabilizations.push_back("cvode-projection");
        for (const std::string& stab : stabilizations) {
          c.stabilization = stab;
          for (double r : rtols) {
            c.rtol = r;
            c.atol = 1e-2 * r;
            grid.push_back(c);
          }
        }
        c.stabilization = "none";
      }
    }
  }
  if (!only.empty()) {
    grid.erase(std::remove_if(grid.begin(), grid.end(),
                              [&](const BenchConfig& c) { return c.Name().find(only) == std::string::npos; }),
               grid.end());
  }
  if (include_broken) {
    BenchConfig c;
    c.formulation = "dae";
    c.rtol = 1e-6;
    c.atol = 1e-8;
    c.max_steps = 3;
    grid.push_back(c);
  }
  return grid;
}

bool IsScoreFile(const std::filesystem::path& p) {
  const std::string name = p.filename().string();
  const std::string suffix = ".score.json";
  return name == "score.json" ||
         (name.size() > suffix.size() && name.compare(name.size() - suffix.size(), suffix.size(), suffix) == 0);
}

// The results of every score file under `dir` (sorted by path, so the output is stable),
// each marked as an outside result with its file. Throws InputError naming the directory
// or the file: no such directory, no score file in it, not kneedyn score's JSON, scored
// against another scene or reference.
std::vector<nlohmann::json> IncludedResults(const std::string& dir, const std::string& scene_name,
                                            const std::string& reference_command, nlohmann::json* files) {
  namespace fs = std::filesystem;
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) Throw<InputError>("work_precision", "--include = '", EchoPath(dir), "': not a directory");
  std::vector<fs::path> paths;
  for (const auto& entry : fs::recursive_directory_iterator(dir)) {
    if (entry.is_regular_file() && IsScoreFile(entry.path())) paths.push_back(entry.path());
  }
  if (paths.empty()) {
    Throw<InputError>("work_precision", "--include = '", EchoPath(dir),
                      "': no score.json or *.score.json (written by kneedyn score) under it");
  }
  std::sort(paths.begin(), paths.end());
  std::vector<nlohmann::json> results;
  for (const fs::path& path : paths) {
    const std::string where = "--include = '" + EchoPath(dir) + "': '" + path.string() + "'";
    nlohmann::json j;
    try {
      std::ifstream in(path);
      std::stringstream text;
      text << in.rdbuf();
      j = scene_detail::ParseJsonDocument(text.str(), "work_precision", where);  // nesting checked as read
    } catch (const nlohmann::json::exception& e) {
      Throw<InputError>("work_precision", where, ": not JSON (", e.what(), ")");
    }
    if (!j.is_object() || !j.contains("header") || !j["header"].is_object() || !j.contains("results") ||
        !j["results"].is_array()) {
      Throw<InputError>("work_precision", where, ": not kneedyn score's JSON (no header and results)");
    }
    const nlohmann::json& h = j["header"];
    const std::string scored_scene = h.value("scene", std::string());
    if (scored_scene != scene_name) {
      Throw<InputError>("work_precision", where, ": scored on scene '", scored_scene, "', the sweep runs '",
                        scene_name, "'");
    }
    const std::string scored_reference = h.value("reference_primary", std::string());
    if (scored_reference != reference_command) {
      Throw<InputError>("work_precision", where, ": scored against another reference (made by '", scored_reference,
                        "'; the sweep's was made by '", reference_command, "')");
    }
    for (nlohmann::json r : j["results"]) {
      if (!r.is_object() || !r.contains("formulation") || !r.contains("status") || !r.contains("metrics")) {
        Throw<InputError>("work_precision", where, ": a result without formulation, status and metrics");
      }
      r["origin"] = "outside";
      r["source"] = path.string();
      results.push_back(r);
    }
    files->push_back(path.string());
  }
  return results;
}

nlohmann::json Finite(double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr); }

std::string CsvCell(const nlohmann::json& v) {
  if (v.is_null()) return "";
  if (v.is_string()) {
    std::string s = v.get<std::string>();
    std::replace(s.begin(), s.end(), '"', '\'');
    return "\"" + s + "\"";
  }
  return v.dump();
}

}  // namespace

int main(int argc, char** argv) {
  bool short_mode = false, include_broken = false;
  std::string scene_path = ReferenceDataDir() + "/scenes/chapter_impact.yaml";
  std::string reference_path;
  std::string json_path = "work_precision.json", csv_path;
  std::string only;
  std::vector<std::string> include_dirs;
  int repetitions = 0;  // default: 3 (--short), 5 (full)
  double rtol_min = 1e-11;  // reference at rtol 1e-14: three decades tighter
  CLI::App app{"work_precision: accuracy (scd) against the stored reference and CPU time of every "
                "formulation and setting on one scene (benchmarks/README.md). Options --benchmark_*=V "
                "go to Google Benchmark."};
  app.add_flag("--short", short_mode, "the short sweep (CI): fewer settings, 3 repetitions");
  app.add_flag("--include-broken", include_broken, "also settings known to fail");
  app.add_option("--scene", scene_path, "scene file")->capture_default_str();
  app.add_option("--reference", reference_path, "reference JSON (default: references/<scene>.json)");
  app.add_option("--json", json_path, "output JSON (Google Benchmark's format)")->capture_default_str();
  app.add_option("--csv", csv_path, "output CSV (default: the JSON's name with .csv)");
  app.add_option("--only", only, "only configurations whose name contains this");
  app.add_option("--include", include_dirs,
                 "also the outside results scored by `kneedyn score` under DIR (score.json, *.score.json; "
                 "repeatable)");
  app.add_option("--rtol-min", rtol_min, "tightest rtol of the sweep, in [1e-300, 1e-2]")
      ->check(CLI::Validator(
          [](std::string& text) {  // CLI::Range printed its bounds with %f: "0.000000 to 0.010000"
            double v = 0.0;
            return ParseReal(text, &v) && v >= 1e-300 && v <= 1e-2 ? std::string()
                                                                 : "'" + Echo(text) + "' must lie in [1e-300, 1e-2]";
          },
          "", "RTOL"))
      ->capture_default_str();
  app.add_option("--repetitions", repetitions, "repetitions per setting (default 3 short, 5 full)")
      ->check(CLI::Range(2, 1000));
  app.set_version_flag("--version", VersionReport("work_precision"));
  app.allow_extras();
  if (const int code = ParseCommandLine(app, argc, argv, "work_precision"); code >= 0) return code;
  // The rest goes to Google Benchmark; anything else is an error naming the argument.
  std::vector<std::string> extras = app.remaining();
  std::vector<char*> rest = {argv[0]};
  for (const std::string& a : extras) {
    if (a.rfind("--benchmark_", 0) != 0) {
      std::fprintf(stderr, "work_precision: error: unknown argument '%s'\nRun 'work_precision --help' for the arguments.\n",
                   a.c_str());
      return 2;
    }
    rest.push_back(const_cast<char*>(a.c_str()));
  }
  try {
    if (repetitions == 0) repetitions = short_mode ? 3 : 5;
    if (csv_path.empty()) {
      csv_path = json_path.size() > 5 && json_path.substr(json_path.size() - 5) == ".json"
                     ? json_path.substr(0, json_path.size() - 5) + ".csv"
                     : json_path + ".csv";
    }
    // Checked before the sweep, which takes minutes: a path that cannot be written was
    // refused only after it (and --json into a missing /proc directory ended in abort).
    CheckOutputFile("work_precision", "--json", json_path);
    CheckOutputFile("work_precision", "--csv", csv_path);
    const Scene scene = LoadScene(scene_path);
    if (reference_path.empty()) reference_path = ReferenceDataDir() + "/references/" + scene.name + ".json";
    const Reference reference = LoadReference(reference_path);
    // Read before the sweep runs: a bad file stops it at once.
    nlohmann::json included_files = nlohmann::json::array();
    std::vector<nlohmann::json> included;
    for (const std::string& dir : include_dirs) {
      for (nlohmann::json& r : IncludedResults(dir, scene.name, reference.json.at("primary").value("command", ""),
                                               &included_files)) {
        included.push_back(std::move(r));
      }
    }

    std::vector<Entry> entries;
    for (const BenchConfig& c : Grid(short_mode, rtol_min, only, include_broken)) entries.push_back({c, {}, {}, {}});
    if (entries.empty()) {  // Google Benchmark would then write no JSON at all
      Throw<InputError>("work_precision", "--only = '", Echo(only), "': no configuration of the ",
                        short_mode ? "short" : "full", " sweep has it in its name");
    }
    std::map<std::string, Entry*> by_name;
    ProgressCounter progress(static_cast<long>(entries.size()));
    for (Entry& e : entries) {
      e.outcome = RunConfig(scene, e.config, reference.comparison_interval);
      e.metrics = Evaluate(scene, e.outcome, reference);
      std::fprintf(stderr, "%s %-40s %-6s scd %6.2f  %s\n", progress.Next().c_str(), e.config.Name().c_str(), e.outcome.status.c_str(),
                   e.metrics.scd, e.outcome.reason.c_str());
      by_name[e.config.Name()] = &e;
      Entry* ep = &e;
      benchmark::RegisterBenchmark(e.config.Name().c_str(),
                                   [ep, &scene](benchmark::State& state) {
                                     RunSettings settings;
                                     settings.formulation = ep->config.formulation;
                                     settings.options = ep->config.Options();
                                     for (auto _ : state) {
                                       RunResult r;
                                       if (ep->outcome.status == "ok" || !ep->outcome.result.samples.empty()) {
                                         r = RunScene(scene, settings);
                                       }
                                       benchmark::DoNotOptimize(r);
                                     }
                                     const SolverStats& s = ep->outcome.result.stats;
                                     state.counters["residual_evaluations"] = s.residual_evaluations;
                                     state.counters["jacobian_evaluations"] = s.jacobian_evaluations;
                                     state.counters["linear_solver_setups"] = s.linear_solver_setups;
                                     state.counters["nonlinear_iterations"] = s.nonlinear_iterations;
                                     state.counters["steps"] = s.steps;
                                     state.counters["rejected_steps"] = s.rejected_steps();
                                     state.counters["scd"] = std::isfinite(ep->metrics.scd) ? ep->metrics.scd : 0.0;
                                   })
          ->Unit(benchmark::kMillisecond)  // compare.py prints whole time units
          // Minimum time and repetitions go in as flags below: set here, Google Benchmark
          // would append them (mode-dependent) to the names, and compare.py could not
          // match a short run against a full one.
          ->DisplayAggregatesOnly(true)  // the JSON file keeps every repetition
          ->ComputeStatistics("min", MinOf)
          ->ComputeStatistics("max", MaxOf);
    }

    // Google Benchmark writes its own JSON (context, per-repetition and aggregate entries,
    // time units) so that its tools/compare.py reads our files; kneedyn's header and
    // results are added beside them (docs/outputs.md).
    const std::string gbench_path =
        (std::filesystem::temp_directory_path() / ("kneedyn_work_precision_" + std::to_string(::getpid()) + ".json"))
            .string();
    std::string out_flag = "--benchmark_out=" + gbench_path;
    std::string format_flag = "--benchmark_out_format=json";
    std::string min_time_flag = std::string("--benchmark_min_time=") + (short_mode ? "0.005" : "0.05");
    std::string repetitions_flag = "--benchmark_repetitions=" + std::to_string(repetitions);
    rest.insert(rest.begin() + 1, {min_time_flag.data(), repetitions_flag.data()});  // user flags win
    rest.push_back(out_flag.data());
    rest.push_back(format_flag.data());
    int bargc = static_cast<int>(rest.size());
    benchmark::Initialize(&bargc, rest.data());
    CollectingReporter reporter(&by_name);
    benchmark::RunSpecifiedBenchmarks(&reporter);
    benchmark::Shutdown();

    nlohmann::json out;
    {
      std::ifstream in(gbench_path);
      if (!in) Throw<InputError>("work_precision", "Google Benchmark wrote no '", gbench_path, "'");
      // Google Benchmark prints NaN (e.g. the cv of a counter that is 0 in every
      // repetition), which is not JSON: such values become null.
      std::stringstream text;
      text << in.rdbuf();
      out = nlohmann::json::parse(
          std::regex_replace(text.str(), std::regex(R"(:\s*-?(NaN|nan|inf|Infinity)\b)"), ": null"));
    }
    std::filesystem::remove(gbench_path);
    out["context"]["kneedyn_version"] = KneedynVersion();
    out["context"]["git_commit"] = KneedynGitCommit();
    out["context"]["kneedyn_mode"] = short_mode ? "short" : "full";
    out["context"]["kneedyn_scene"] = scene.name;
    // The fairness manifest: how every component on the time axis was built (the report
    // prints it beside the diagrams; peers such as Simbody and SciPy append their own).
    nlohmann::json components = nlohmann::json::array();
    for (const BuildComponent& c : BuildManifest()) {
      components.push_back({{"name", c.name}, {"version", c.version}, {"origin", c.origin},
                            {"compile_flags", c.compile_flags}});
    }
    // Outside solvers (--include) were built and timed elsewhere: one entry per formulation
    // name, saying so, so that the manifest never implies they were built alike.
    std::map<std::string, std::string> outside;  // formulation -> its first score file
    for (const nlohmann::json& r : included) {
      outside.emplace(r.value("formulation", std::string("?")), r.value("source", std::string()));
    }
    for (const auto& [name, source] : outside) {
      components.push_back({{"name", name},
                            {"version", "not recorded"},
                            {"origin", "outside solver, scored by kneedyn score (" + source + "); built and timed outside kneedyn"},
                            {"compile_flags", "not recorded"}});
    }
    out["context"]["components"] = components;
    nlohmann::json& h = out["header"];
    h["machine"] = MachineJson();
    h["scene"] = scene.name;
    h["scene_file"] = scene_path;
    h["reference"] = reference_path;
    h["reference_primary"] = reference.json.at("primary");
    h["reference_accuracy_scd"] = reference.json.at("accuracy_scd");
    // The highest scd the reference can measure (metrics.hpp: ApplyScdCeiling); runs above
    // it carry metrics.scd_above_ceiling.
    h["scd_ceiling"] = std::isfinite(reference.accuracy_scd) ? nlohmann::json(reference.accuracy_scd - kScdCeilingMargin)
                                                             : nlohmann::json(nullptr);
    h["mode"] = short_mode ? "short" : "full";
    h["repetitions"] = repetitions;
    h["rtol_min"] = rtol_min;
    h["metrics_definition"] = "benchmarks/metrics.hpp";
    h["command"] = CommandLine(argc, argv);
    if (!include_dirs.empty()) {
      h["included"] = {{"directories", include_dirs}, {"files", included_files},
                       {"note", "outside results scored by kneedyn score; their CPU times are their own, "
                                "measured by the outside driver, not by Google Benchmark here"}};
    }
    const std::time_t now = std::time(nullptr);
    char date[32];
    std::strftime(date, sizeof date, "%Y-%m-%dT%H:%M:%SZ", std::gmtime(&now));
    h["date"] = date;
    out["results"] = nlohmann::json::array();
    std::string csv =
        "formulation,integrator,rtol,atol,step,status,scd,mixed_positions,mixed_velocities,"
        "mixed_contact_points,mixed_contact_forces,mixed_ligament_forces,max_position_residual_m,"
        "cpu_median_s,cpu_min_s,cpu_max_s,residual_evaluations,jacobian_evaluations,"
        "linear_solver_setups,nonlinear_iterations,steps,rejected_steps,reason\n";
    for (const Entry& e : entries) {
      nlohmann::json r;
      r["name"] = e.config.Name();  // the Google Benchmark entries' run_name
      r["formulation"] = e.config.formulation;
      r["integrator"] = e.config.integrator;
      r["setting"] = e.config.SettingJson();
      r["status"] = e.outcome.status;
      r["reason"] = e.outcome.reason;
      r["metrics"] = MetricsJson(e.metrics);
      for (const char* k : {"median", "min", "max"}) {
        r["cpu_time_s"][k] = e.cpu.count(k) ? Finite(e.cpu.at(k)) : nlohmann::json(nullptr);
      }
      r["counters"] = CountersJson(e.outcome.result.stats);
      r["events"] = nlohmann::json::array();
      for (const EventRecord& ev : e.outcome.result.events) {  // contact and end events, first 20
        if (ev.name.rfind("kink_", 0) == 0 || r["events"].size() >= 20) continue;
        r["events"].push_back({{"name", ev.name}, {"time_s", ev.time}});
      }
      out["results"].push_back(r);
    }
    for (nlohmann::json& r : included) out["results"].push_back(std::move(r));
    for (const nlohmann::json& r : out["results"]) {
      // Included records may lack fields (a hand-written score): missing cells are empty.
      const auto field = [](const nlohmann::json& o, const char* k) {
        return o.is_object() ? o.value(k, nlohmann::json(nullptr)) : nlohmann::json(nullptr);
      };
      const nlohmann::json m = field(r, "metrics"), s = field(r, "setting"), c = field(r, "counters"),
                           cpu = field(r, "cpu_time_s"), mixed = field(m, "mixed_error");
      std::vector<nlohmann::json> cells = {
          field(r, "formulation"), field(r, "integrator"), field(s, "rtol"), field(s, "atol"), field(s, "step"),
          field(r, "status"), field(m, "scd"), field(mixed, "positions"), field(mixed, "velocities"),
          field(mixed, "contact_points"), field(mixed, "contact_forces"), field(mixed, "ligament_forces"),
          field(m, "max_position_residual_m"), field(cpu, "median"), field(cpu, "min"), field(cpu, "max"),
          field(c, "residual_evaluations"), field(c, "jacobian_evaluations"), field(c, "linear_solver_setups"),
          field(c, "nonlinear_iterations"), field(c, "steps"), field(c, "rejected_steps"), field(r, "reason")};
      for (size_t i = 0; i < cells.size(); ++i) csv += (i ? "," : "") + CsvCell(cells[i]);
      csv += "\n";
    }
    WriteOutputFile("work_precision", "--json", json_path, out.dump(1) + "\n");
    WriteOutputFile("work_precision", "--csv", csv_path, csv);
    std::fprintf(stderr, "wrote %s and %s (%zu results, %zu of them included)\n", json_path.c_str(), csv_path.c_str(),
                 out["results"].size(), included.size());
    return 0;
  } catch (const InputError& e) {
    std::cerr << "work_precision: error: " << e.what() << "\n";
    return 2;
  } catch (const std::exception& e) {  // outside the runs, which report their own failures
    std::cerr << "work_precision: error: " << e.what() << "\n";
    return 1;
  }
}
