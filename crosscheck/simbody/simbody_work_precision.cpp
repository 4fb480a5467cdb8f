// simbody_work_precision — the peer benchmark (crosscheck/simbody/README.md): work-precision
// of Simbody's integrators on a scene beside kneedyn's dae and ede, measured in the same run,
// against the same stored reference and the same metric (benchmarks/metrics.hpp) as
// benchmarks/work_precision.cpp, in the same JSON layout, so reports/figures.py draws them in
// one diagram.
//
//   simbody_work_precision [--short] [--scene FILE] [--reference FILE] [--json OUT]
//                          [--merge WORK_PRECISION_JSON] [--repetitions N] [--only SUBSTRING]
//
// Grid (full; --short: rkm rk3 verlet, dae, ede:dopri5 at 1e-4 1e-6 1e-8, cpodes-bdf
// at 1e-6 1e-8):
//   Simbody  rkm, rkf  accuracy 10^(−k/2), 1e-3 … 1e-12 (rkf … 1e-11)
//            rk3, verlet 1e-3 … 1e-9;  rk2 1e-3 … 1e-7;  see2 1e-5 … 1e-8
//            (coarser or tighter settings of the low-order methods take minutes);
//            constraint tolerance = accuracy (Simbody's default);
//            cpodes-bdf, cpodes-adams 1e-4 … 1e-10 through the kneedyn_simbody command
//            (CPodes cannot share a process with SUNDIALS 6.4, see MeasureThroughCommand).
//   kneedyn  dae, ede:dopri5, ede:verner65 at rtol 10^(−k/2), 1e-3 … 1e-10 (dae) /
//            1e-11 (ede), atol = 1e-2 rtol — the work_precision.cpp settings.
// Each setting runs once untimed (metrics, counters), then N times timed (process CPU
// time; N = 3, --short 2, 1 for a setting whose first run took > 2 s); median, min, max.
//
// Output: {header, results: [...] (work_precision.cpp's entry layout; formulation
// "simbody" with integrator = Simbody's), time_to_accuracy: per method the CPU time at
// scd 6 and 8 (log-linear interpolation between the bracketing settings of the runs the
// diagrams count: completed, with the reference's events; null when the method does not
// reach it), ratio_kneedyn_over_simbody at scd 6 and 8 (fastest kneedyn
// method / fastest Simbody method)}. --merge copies the results of a work_precision.cpp
// JSON except the methods measured here, so one file feeds the report; they were timed in
// that sweep's process, not this one: header.merged_from keeps its header and its context
// (git_commit, components), and only this run's own rows carry "engine".
// Exit 0 when the sweep ran, 2 on bad input.
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <CLI/CLI.hpp>

#include <algorithm>
#include <cmath>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <sstream>

#include "benchmarks/bench_run.hpp"
#include "crosscheck/simbody/simbody_solution.hpp"
#include "formulations/version.hpp"
#include "formulations/output_file.hpp"
#include "scene/internal/json_field.hpp"
#include "solver/error.hpp"
#include "solver/internal/command_line.hpp"

using namespace kneedyn;
using namespace kneedyn::bench;

namespace {

struct Config {
  bool simbody = false;
  std::string integrator;  // Simbody's name, or kneedyn's (empty for dae)
  std::string formulation;  // kneedyn's; "simbody" for Simbody
  double tol = 1e-6;        // Simbody accuracy or kneedyn rtol
  std::string Key() const { return formulation + "/" + integrator; }
  std::string Name() const {
    char buf[32];
    std::snprintf(buf, sizeof(buf), "%.3g", tol);
    return Key() + (simbody ? "/accuracy=" : "/rtol=") + buf;
  }
};

struct Entry {
  Config config;
  std::string status = "ok", reason;
  Metrics metrics;
  SolverStats stats;
  std::vector<EventRecord> events;
  std::vector<double> cpu;  // s per timed repetition
};

double CpuSeconds() { return static_cast<double>(std::clock()) / CLOCKS_PER_SEC; }

std::vector<double> Decades(double from, double to) {  // 10^(−k/2) from `from` down to `to`
  std::vector<double> v;
  for (int k = static_cast<int>(std::lround(-2 * std::log10(from))); k <= std::lround(-2 * std::log10(to)); ++k) {
    v.push_back(std::pow(10.0, -k / 2.0));
  }
  return v;
}

std::vector<Config> Grid(bool short_mode) {
  std::vector<Config> g;
  auto add = [&](bool sb, const std::string& f, const std::string& i, const std::vector<double>& tols) {
    for (double t : tols) g.push_back({sb, i, f, t});
  };
  if (short_mode) {
    const std::vector<double> t = {1e-4, 1e-6, 1e-8};
    for (const char* i : {"rkm", "rk3", "verlet"}) add(true, "simbody", i, t);
    add(true, "simbody", "cpodes-bdf", {1e-6, 1e-8});  // at 1e-4 it chatters for 10 s
    add(false, "dae", "", t);
    add(false, "ede", "dopri5", t);
    return g;
  }
  add(true, "simbody", "rkm", Decades(1e-3, 1e-12));
  add(true, "simbody", "rkf", Decades(1e-3, 1e-11));
  add(true, "simbody", "rk3", Decades(1e-3, 1e-9));
  add(true, "simbody", "verlet", Decades(1e-3, 1e-9));
  add(true, "simbody", "rk2", Decades(1e-3, 1e-7));
  add(true, "simbody", "see2", Decades(1e-5, 1e-8));
  add(true, "simbody", "cpodes-bdf", Decades(1e-4, 1e-10));
  add(true, "simbody", "cpodes-adams", Decades(1e-4, 1e-10));
  add(false, "dae", "", Decades(1e-3, 1e-10));
  add(false, "ede", "dopri5", Decades(1e-3, 1e-11));
  add(false, "ede", "verner65", Decades(1e-3, 1e-11));
  return g;
}

simbody::Options SimbodyOptions(const Config& c) {
  simbody::Options o;
  o.integrator = c.integrator;
  o.accuracy = c.tol;
  return o;
}

BenchConfig KneedynConfig(const Config& c) {
  BenchConfig b;
  b.formulation = c.formulation;
  b.integrator = c.integrator;
  b.rtol = c.tol;
  b.atol = 1e-2 * c.tol;
  return b;
}

// One untimed run: metrics, counters, events.
void Measure(const Scene& scene, const Reference& ref, Entry* e) {
  const Config& c = e->config;
  if (c.simbody) {
    const simbody::Result r = simbody::Run(scene, SimbodyOptions(c));
    if (!r.run.completed) {
      e->status = "failed";
      e->reason = r.run.failure;
    }
    e->metrics = Compare(simbody::ToSolution(scene, r, ref.comparison_interval), ref.solution);
    AddRunMetrics(scene, r.run, ref.conservative, &e->metrics);
    ApplyScdCeiling(ref.accuracy_scd, &e->metrics);  // as kneedyn's rows (bench_run.cpp Evaluate)
    e->stats = r.run.stats;
    e->events = r.run.events;
  } else {
    const Outcome out = RunConfig(scene, KneedynConfig(c), ref.comparison_interval);
    e->status = out.status;
    e->reason = out.reason;
    e->metrics = Evaluate(scene, out, ref);
    e->stats = out.result.stats;
    e->events = out.result.events;
  }
}

double TimedRun(const Scene& scene, const Config& c) {
  const double t0 = CpuSeconds();
  if (c.simbody) {
    const simbody::Result r = simbody::Run(scene, SimbodyOptions(c));
    if (r.samples.empty()) std::fprintf(stderr, "?");
  } else {
    RunSettings s;
    s.formulation = c.formulation;
    s.options = KneedynConfig(c).Options();
    const RunResult r = RunScene(scene, s);
    if (r.samples.empty()) std::fprintf(stderr, "?");
  }
  return CpuSeconds() - t0;
}

// CPodes cannot run in this process: Debian's libSimTKmath exports its own copies of
// SUNDIALS' N_V* functions, and this program links SUNDIALS 6.4 for kneedyn, so CPodes
// would call the wrong ones (it aborts in nvector_SimTK.h). CPodes settings therefore run
// through the kneedyn_simbody command (which links no SUNDIALS); the Solution is read
// back from its trajectory.csv (12 significant digits) and summary.json, and the CPU
// time is the child's (getrusage), start-up and output writing included.
std::vector<std::string> SplitCsv(const std::string& line) {
  std::vector<std::string> out;
  std::string cell;
  for (char ch : line) {
    if (ch == ',') {
      out.push_back(cell);
      cell.clear();
    } else if (ch != '\r') {
      cell += ch;
    }
  }
  out.push_back(cell);
  return out;
}

double ChildCpuSeconds() {
  struct rusage ru;
  getrusage(RUSAGE_CHILDREN, &ru);
  return ru.ru_utime.tv_sec + ru.ru_stime.tv_sec + 1e-6 * (ru.ru_utime.tv_usec + ru.ru_stime.tv_usec);
}

std::string ColumnSafe(const std::string& name) {
  std::string out = name;
  for (char& c : out) {
    if (c == ' ' || c == '-' || c == '/') c = '_';
  }
  return out;
}

void MeasureThroughCommand(const Scene& scene, const std::string& scene_path, const Reference& ref,
                           int repetitions, Entry* e) {
  const Config& c = e->config;
  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() / StrCat("kneedyn_simbody_wp_", getpid());
  char tol[32];
  std::snprintf(tol, sizeof(tol), "%.17g", c.tol);
  const std::string cmd = StrCat(KNEEDYN_SIMBODY_EXE, " run '", scene_path, "' --integrator ", c.integrator,
                                 " --accuracy ", tol, " --quiet --out '", dir.string(), "' >/dev/null 2>&1");
  int status = 0;
  for (int r = 0; r < repetitions; ++r) {
    std::filesystem::remove_all(dir);
    const double t0 = ChildCpuSeconds();
    status = std::system(cmd.c_str());
    e->cpu.push_back(ChildCpuSeconds() - t0);
    if (r == 0 && e->cpu[0] > 2.0) break;
  }
  std::ifstream sf(dir / "summary.json");
  if (!sf) {
    e->status = "failed";
    e->reason = StrCat("kneedyn_simbody exited with status ", status, " and wrote no summary");
    e->metrics.scd = e->metrics.scd_compared = std::nan("");
    e->cpu.clear();
    return;
  }
  const nlohmann::json sum = nlohmann::json::parse(sf);
  if (sum.at("status") != "completed") {
    e->status = "failed";
    e->reason = sum.value("failure", std::string("partial"));
  }
  const nlohmann::json& st = sum.at("statistics");
  e->stats.steps = st.at("steps");
  e->stats.residual_evaluations = st.at("residual_evaluations");
  e->stats.error_test_failures = st.at("error_test_failures");
  e->stats.convergence_failures = st.at("convergence_failures");
  e->stats.nonlinear_iterations = st.at("nonlinear_iterations");
  e->stats.projections = st.at("projections");
  e->stats.restarts = st.at("restarts");
  for (const auto& ev : sum.at("events")) {
    e->events.push_back({ev.at("name"), ev.at("time"), ev.at("flexion_deg").get<double>() * M_PI / 180.0});
  }
  // Solution from trajectory.csv (names as benchmarks/metrics.cpp).
  Solution sol;
  std::vector<std::string> pos = {"x0_mm", "y0_mm", "z0_mm", "flexion_deg", "valgus_deg", "external_rotation_deg"};
  std::vector<std::string> vel = {"vx_mm_s", "vy_mm_s", "vz_mm_s", "flexion_rate_deg_s", "valgus_rate_deg_s",
                                  "external_rotation_rate_deg_s"};
  std::vector<std::string> pts, frc, lig;
  for (const ContactPair& pair : scene.model.contacts) {
    for (const char* frame : {"femoral", "tibial"})
      for (const char* axis : {"x", "y", "z"})
        pts.push_back(StrCat(frame, "_", CompartmentName(pair.compartment), "_", axis, "_mm"));
    frc.push_back(StrCat("N_", CompartmentName(pair.compartment), "_N"));
  }
  for (const Ligament& l : scene.model.ligaments) lig.push_back("F_" + ColumnSafe(l.name) + "_N");
  sol.names["positions"] = pos;
  sol.names["velocities"] = vel;
  sol.names["contact_points"] = pts;
  sol.names["contact_forces"] = frc;
  sol.names["ligament_forces"] = lig;
  for (const std::string& cl : VariableClasses()) sol.values[cl];
  std::ifstream csv(dir / "trajectory.csv");
  std::string line;
  std::getline(csv, line);
  std::map<std::string, size_t> col;
  const std::vector<std::string> header = SplitCsv(line);
  for (size_t k = 0; k < header.size(); ++k) col[header[k]] = k;
  auto pick = [&](const std::vector<std::string>& row, const std::vector<std::string>& names) {
    std::vector<double> v;
    for (const std::string& n : names) {
      const std::string& cell = row.at(col.at(n));
      v.push_back(cell.empty() ? std::nan("") : std::stod(cell));
    }
    return v;
  };
  std::vector<std::vector<std::string>> rows;
  while (std::getline(csv, line)) rows.push_back(SplitCsv(line));
  auto append = [&](const std::vector<std::string>& row) {
    sol.times.push_back(std::stod(row.at(col.at("time_s"))));
    sol.values["positions"].push_back(pick(row, pos));
    sol.values["velocities"].push_back(pick(row, vel));
    sol.values["contact_points"].push_back(pick(row, pts));
    sol.values["contact_forces"].push_back(pick(row, frc));
    sol.values["ligament_forces"].push_back(pick(row, lig));
  };
  for (const auto& row : rows) {
    if (row.at(col.at("is_event")) == "1") continue;
    const double t = std::stod(row.at(col.at("time_s")));
    if (std::abs(t - std::round(t / ref.comparison_interval) * ref.comparison_interval) > 1e-9) continue;
    append(row);
  }
  if (sum.at("status") == "completed" && !rows.empty() && rows.back().at(col.at("is_event")) == "1" &&
      sum.at("end_reason") != "end_time") {
    append(rows.back());
    sol.end_is_event = true;
  }
  sol.events = e->events;
  e->metrics = Compare(sol, ref.solution);
  ApplyScdCeiling(ref.accuracy_scd, &e->metrics);
  e->metrics.max_position_residual = sum.at("constraint_residuals").at("max_gap_mm").get<double>() * 1e-3;
  e->metrics.max_velocity_residual = sum.at("constraint_residuals").at("max_gap_rate_mm_s").get<double>() * 1e-3;
  std::filesystem::remove_all(dir);
}

nlohmann::json Finite(double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr); }

// CPU time at a target scd on one method's curve (settings in order of tightening).
double TimeAt(std::vector<std::pair<double, double>> pts, double target) {  // (scd, cpu)
  for (size_t i = 0; i < pts.size(); ++i) {
    if (pts[i].first >= target) {
      if (i == 0) return pts[0].second;  // the loosest setting already reaches it
      const auto [s0, c0] = pts[i - 1];
      const auto [s1, c1] = pts[i];
      const double f = (target - s0) / (s1 - s0);
      return std::exp(std::log(c0) + f * (std::log(c1) - std::log(c0)));
    }
  }
  return std::nan("");
}

}  // namespace

int main(int argc, char** argv) {
  bool short_mode = false;
  std::string scene_path = ReferenceDataDir() + "/scenes/chapter_impact.yaml";
  std::string reference_path, json_path = "simbody_work_precision.json", merge_path, only;
  int repetitions = 0;
  // The command line through the suite's one parser (--help; every argument error exits 2).
  CLI::App app{"Simbody's integrators beside kneedyn's dae and ede: work-precision on one scene, "
               "against the same reference and metric as work_precision (crosscheck/simbody/README.md)"};
  app.add_flag("--short", short_mode, "the short grid (rkm rk3 verlet, dae, ede:dopri5, cpodes-bdf)");
  app.add_option("--scene", scene_path, "scene file")->capture_default_str();
  app.add_option("--reference", reference_path, "stored reference (default: references/<scene name>.json)");
  app.add_option("--json", json_path, "output JSON")->capture_default_str();
  app.add_option("--merge", merge_path, "a work_precision JSON whose other methods' results are copied in");
  app.add_option("--only", only, "run only the methods whose name contains this text");
  app.add_option("--repetitions", repetitions, "timed runs per setting (default 3, --short 2)")
      ->check(CLI::Range(1, 1000));
  if (const int code = ParseCommandLine(app, argc, argv, "simbody_work_precision"); code >= 0) return code;
  try {
    if (repetitions == 0) repetitions = short_mode ? 2 : 3;
    CheckOutputFile("simbody_work_precision", "--json", json_path);  // before the runs
    const Scene scene = LoadScene(scene_path);
    if (reference_path.empty()) reference_path = ReferenceDataDir() + "/references/" + scene.name + ".json";
    const Reference reference = LoadReference(reference_path);
    nlohmann::json merged = nlohmann::json::array();
    nlohmann::json merged_header;
    nlohmann::json merged_context;  // null when the merged file has none
    if (!merge_path.empty()) {
      std::ifstream f(merge_path);
      if (!f) Throw<InputError>("simbody_work_precision", "--merge = '", merge_path, "': cannot be read");
      std::stringstream text;
      text << f.rdbuf();
      nlohmann::json j;
      try {  // nesting checked as it is read, as for every JSON document a user gives
        j = scene_detail::ParseJsonDocument(text.str(), "simbody_work_precision", "--merge = '" + merge_path + "'");
      } catch (const nlohmann::json::exception&) {
        j = nlohmann::json::value_t::discarded;
      }
      if (j.is_discarded() || !j.is_object() || !j.contains("results") || !j.contains("header")) {
        Throw<InputError>("simbody_work_precision", "--merge = '", merge_path, "': not a work_precision JSON");
      }
      merged = j.at("results");
      merged_header = j.at("header");
      // The merged sweep's build (git_commit, components) is in its context, not its header.
      if (j.contains("context")) merged_context = j["context"];
    }

    std::vector<Entry> entries;
    for (const Config& c : Grid(short_mode)) {
      if (!only.empty() && c.Name().find(only) == std::string::npos) continue;
      Entry e;
      e.config = c;
      if (c.simbody && c.integrator.rfind("cpodes", 0) == 0) {
        MeasureThroughCommand(scene, scene_path, reference, repetitions, &e);
      } else {
        Measure(scene, reference, &e);
        const double first = TimedRun(scene, c);
        e.cpu.push_back(first);
        for (int r = 1; r < repetitions && first < 2.0; ++r) e.cpu.push_back(TimedRun(scene, c));
      }
      std::sort(e.cpu.begin(), e.cpu.end());
      std::fprintf(stderr, "%-44s %-6s scd %6.2f  cpu %8.4f s  %s\n", c.Name().c_str(), e.status.c_str(),
                   e.metrics.scd, e.cpu.empty() ? std::nan("") : e.cpu[e.cpu.size() / 2],
                   (e.status == "ok" ? WrongEventReason(e.metrics, e.events) : e.reason).c_str());
      entries.push_back(std::move(e));
    }

    nlohmann::json out;
    nlohmann::json& h = out["header"];
    h["machine"] = MachineJson();
    h["machine"]["versions"]["simbody"] = "3.7";
    h["scene"] = scene.name;
    h["scene_file"] = scene_path;
    h["reference"] = reference_path;
    h["reference_primary"] = reference.json.at("primary");
    h["reference_accuracy_scd"] = reference.json.at("accuracy_scd");
    h["scd_ceiling"] = std::isfinite(reference.accuracy_scd) ? nlohmann::json(reference.accuracy_scd - kScdCeilingMargin)
                                                             : nlohmann::json(nullptr);
    h["mode"] = short_mode ? "short" : "full";
    h["repetitions"] = repetitions;
    h["timer"] = "process CPU time (std::clock) of one whole run (start, integration, outputs in memory)";
    h["metrics_definition"] = "benchmarks/metrics.hpp";
    h["generator"] = "crosscheck/simbody/simbody_work_precision.cpp";
    h["command"] = CommandLine(argc, argv);
    if (!merge_path.empty()) {
      h["merged_from"] = {{"file", merge_path}, {"header", merged_header}, {"context", merged_context}};
    }
    char date[32];
    const std::time_t now = std::time(nullptr);
    std::strftime(date, sizeof(date), "%Y-%m-%dT%H:%M:%SZ", std::gmtime(&now));
    h["date"] = date;

    std::map<std::string, bool> measured_keys;
    nlohmann::json results = nlohmann::json::array();
    std::map<std::string, std::vector<std::pair<double, double>>> curves;  // key -> (scd, cpu)
    for (const Entry& e : entries) {
      const Config& c = e.config;
      nlohmann::json r;
      r["formulation"] = c.formulation;
      r["integrator"] = c.integrator;
      r["engine"] = c.simbody ? "simbody" : "kneedyn";
      r["setting"] = c.simbody ? nlohmann::json{{"accuracy", c.tol}, {"constraint_tolerance", c.tol}}
                               : nlohmann::json{{"rtol", c.tol}, {"atol", 1e-2 * c.tol}};
      r["status"] = e.status;
      r["reason"] = e.reason;
      if (c.integrator.rfind("cpodes", 0) == 0) r["timing"] = "kneedyn_simbody subprocess (start-up and output files included)";
      r["metrics"] = MetricsJson(e.metrics);
      if (e.cpu.empty()) {
        r["cpu_time_s"] = {{"median", nullptr}, {"min", nullptr}, {"max", nullptr}};
      } else {
        r["cpu_time_s"] = {{"median", e.cpu[e.cpu.size() / 2]}, {"min", e.cpu.front()}, {"max", e.cpu.back()}};
      }
      r["counters"] = CountersJson(e.stats);
      r["events"] = nlohmann::json::array();
      for (const EventRecord& ev : e.events) r["events"].push_back({{"name", ev.name}, {"time_s", ev.time}});
      results.push_back(r);
      const std::string key = c.formulation + " / " + (c.integrator.empty() ? "-" : c.integrator);
      measured_keys[key + " / none"] = true;  // this program runs no stabilization
      // A run with the wrong events is drawn as a failure (reports/bench_data.py), so it is
      // no point of the curve its time to accuracy is read from either.
      if (e.status == "ok" && std::isfinite(e.metrics.scd) && !e.cpu.empty() &&
          WrongEventReason(e.metrics, e.events).empty()) {
        curves[key].push_back({e.metrics.scd, e.cpu[e.cpu.size() / 2]});
      }
    }
    for (const nlohmann::json& r : merged) {  // the merged file's other methods
      const std::string integ = r.value("integrator", std::string());
      // A method is its formulation, integrator and stabilization: ede dopri5 with projection
      // is not the plain ede dopri5 measured here, and is kept.
      const nlohmann::json setting = r.value("setting", nlohmann::json::object());
      const std::string stab = setting.is_object() ? setting.value("stabilization", std::string("none")) : "none";
      const std::string key =
          r.value("formulation", std::string("?")) + " / " + (integ.empty() ? "-" : integ) + " / " + stab;
      if (measured_keys.count(key)) continue;
      nlohmann::json copied = r;
      copied.erase("engine");  // timed in the merged file's process, not here (a re-merge's rows too)
      results.push_back(copied);
    }
    out["results"] = results;
    // The fairness manifest (formulations/version.hpp): this program's kneedyn build, plus
    // Simbody as Debian ships it.
    nlohmann::json components = nlohmann::json::array();
    for (const BuildComponent& c : BuildManifest()) {
      components.push_back({{"name", c.name}, {"version", c.version}, {"origin", c.origin},
                            {"compile_flags", c.compile_flags}});
    }
    components.push_back({{"name", "Simbody"}, {"version", "3.7"},
                          {"origin", "Debian 12 binary package libsimbody-dev (shared)"},
                          {"compile_flags", "as built by Debian (dpkg-buildflags: -O2)"}});
    out["context"]["components"] = components;
    out["context"]["kneedyn_version"] = KneedynVersion();
    out["context"]["git_commit"] = KneedynGitCommit();

    nlohmann::json tta = nlohmann::json::object();
    double best_k[2] = {INFINITY, INFINITY}, best_s[2] = {INFINITY, INFINITY};
    std::string best_k_name[2], best_s_name[2];
    const double targets[2] = {6.0, 8.0};
    for (const auto& [key, pts] : curves) {
      for (int t = 0; t < 2; ++t) {
        const double cpu = TimeAt(pts, targets[t]);
        tta[key][t == 0 ? "scd6_cpu_s" : "scd8_cpu_s"] = Finite(cpu);
        if (!std::isfinite(cpu)) continue;
        const bool sb = key.rfind("simbody", 0) == 0;
        double& best = sb ? best_s[t] : best_k[t];
        if (cpu < best) {
          best = cpu;
          (sb ? best_s_name[t] : best_k_name[t]) = key;
        }
      }
    }
    out["time_to_accuracy"] = tta;
    for (int t = 0; t < 2; ++t) {
      const std::string k = t == 0 ? "scd6" : "scd8";
      // null unless both reach it (a Simbody time of inf made the ratio 0)
      const double ratio = std::isfinite(best_k[t]) && std::isfinite(best_s[t]) ? best_k[t] / best_s[t] : NAN;
      out["ratio_kneedyn_over_simbody"][k] = {
          {"ratio", Finite(ratio)},
          {"kneedyn_fastest", best_k_name[t]}, {"kneedyn_cpu_s", Finite(best_k[t])},
          {"simbody_fastest", best_s_name[t]}, {"simbody_cpu_s", Finite(best_s[t])}};
      std::fprintf(stderr, "time to %s: kneedyn %s %.4f s, Simbody %s %.4f s, ratio kneedyn/Simbody %.3f\n",
                   k.c_str(), best_k_name[t].c_str(), best_k[t], best_s_name[t].c_str(), best_s[t],
                   ratio);
    }

    WriteOutputFile("simbody_work_precision", "--json", json_path, out.dump(1) + "\n");
    std::fprintf(stderr, "wrote %s (%zu results)\n", json_path.c_str(), results.size());
    return 0;
  } catch (const InputError& e) {
    std::fprintf(stderr, "simbody_work_precision: error: %s\n", e.what());
    return 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "simbody_work_precision: error: %s\n", e.what());
    return 1;
  }
}
