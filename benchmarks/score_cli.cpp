#include "benchmarks/score_cli.hpp"

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <set>
#include <utility>

#include "benchmarks/score.hpp"
#include "formulations/output_file.hpp"
#include "formulations/version.hpp"
#include "scene/internal/json_field.hpp"
#include "scene/internal/yaml_field.hpp"
#include "scene/scene.hpp"
#include "solver/error.hpp"

namespace kneedyn::bench {

namespace fs = std::filesystem;

namespace {

std::string Digits(double v) {
  if (v == std::numeric_limits<double>::infinity()) return "exact";  // no error at all
  if (!std::isfinite(v)) return "-";  // no figure, or an infinite error
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%.2f", v);
  return buf;
}

// m as mm with 3 digits; "-" where the result gives no figure (null in the JSON).
std::string Millis(double m) {
  if (std::isnan(m)) return "-";
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%.3g", 1e3 * m);
  return buf;
}

// Counters from a JSON file: an object of numbers, or kneedyn's summary.json ("statistics").
nlohmann::json ReadCounters(const std::string& path) {
  const std::string text =
      scene_detail::ReadInputFile(path, "--counters file", scene_detail::TableFileRule("kneedyn score"));
  nlohmann::json j;
  try {
    j = scene_detail::ParseJsonDocument(text, "kneedyn score", "--counters = '" + EchoPath(path) + "'");
  } catch (const nlohmann::json::exception& e) {
    Throw<InputError>("kneedyn score", "--counters = '", EchoPath(path), "': not JSON (", e.what(), ")");
  }
  if (j.is_object() && j.contains("statistics")) j = j["statistics"];
  if (!j.is_object()) Throw<InputError>("kneedyn score", "--counters = '", EchoPath(path), "': not a JSON object");
  for (const auto& [k, v] : j.items()) {
    if (!v.is_number()) Throw<InputError>("kneedyn score", "--counters = '", EchoPath(path), "': counter '", k, "' is not a number");
  }
  return j;
}

}  // namespace

ScoreCommand::ScoreCommand(CLI::App& app) {
  cmd_ = app.add_subcommand("score", "score a trajectory CSV from any solver against the scene's stored reference "
                                     "(docs/problem.md)");
  cmd_->add_option("result", result_path_, "CSV: time_s (or time) and any trajectory.csv columns")->required();
  cmd_->add_option("--scene", scene_path_, "scene file (YAML)")->required();
  cmd_->add_option("--reference", reference_path_,
                   "reference JSON (default: references/<scene name>.json in the data directory, which `kneedyn --version` names)");
  cmd_->add_option("--events", events_path_, "the run's events: kneedyn's summary.json, or CSV name,time_s[,flexion_deg]");
  cmd_->add_option("--solver-name", solver_name_, "name of the solver in the record")->capture_default_str();
  cmd_->add_option("--integrator", integrator_, "integrator or method detail, as text");
  cmd_->add_option("--rtol", rtol_, "relative tolerance the solver ran at (recorded)");
  cmd_->add_option("--atol", atol_, "absolute tolerance the solver ran at (recorded)");
  cmd_->add_option("--step", step_, "fixed step in s the solver ran at (recorded)");
  cmd_->add_option("--counters", counters_path_, "JSON object of counters (or kneedyn's summary.json)");
  cmd_->add_option("--counter", counters_, "a counter as name=value (repeatable)");
  cmd_->add_option("--cpu-time", cpu_time_, "CPU time of the solver in s (recorded)");
  cmd_->add_option("--failed", failure_, "the solver failed, for this reason: a failed result is recorded as such");
  cmd_->add_option("--out", out_path_, "JSON to write (default: RESULT with .score.json)");
}

int ScoreCommand::Run(int argc, char** argv) {
  try {
    // The default lies beside RESULT, which a pipe (kneedyn score <(my_solver) ...) has not.
    std::error_code ec;
    if (out_path_.empty() && fs::exists(result_path_, ec) && !fs::is_regular_file(result_path_, ec)) {
      Throw<InputError>("kneedyn score", "RESULT = '", EchoPath(result_path_),
                        "' is not a regular file (a pipe?), so there is no RESULT.score.json beside it: give --out");
    }
    const std::string out_path =
        out_path_.empty() ? fs::path(result_path_).replace_extension(".score.json").string() : out_path_;
    CheckOutputFile("kneedyn score", "--out", out_path);  // before the reference may be run again
    const Scene scene = LoadScene(scene_path_);
    std::string reference_file = reference_path_;
    if (reference_file.empty()) {
      reference_file = ReferenceDataDir() + "/references/" + scene.name + ".json";
      std::error_code ec;
      if (!fs::exists(reference_file, ec)) {
        Throw<InputError>("kneedyn score", "no stored reference for scene '", scene.name, "' (", reference_file,
                          "); give --reference");
      }
    }
    const std::string reference_text =
        scene_detail::ReadInputFile(reference_file, "--reference file", scene_detail::TableFileRule("kneedyn score"));
    nlohmann::json ref_json;
    try {
      ref_json = scene_detail::ParseJsonDocument(reference_text, "kneedyn score",
                                                 "--reference = '" + EchoPath(reference_file) + "'");
    } catch (const nlohmann::json::exception& e) {
      Throw<InputError>("kneedyn score", "--reference = '", EchoPath(reference_file), "': not a kneedyn reference (", e.what(),
                        ")");
    }
    const std::string document = "--reference = '" + EchoPath(reference_file) + "'";
    const Solution reference = ReferenceSolution(ref_json, document);  // its other fields checked too
    const std::string reference_scene = ref_json.at("scene").get<std::string>();
    if (reference_scene != scene.name) {
      Throw<InputError>("kneedyn score", document, " is for scene '", Echo(reference_scene), "', not '", scene.name, "'");
    }
    // A scene of the same name that ends before the reference does is another version of it
    // (a copy with a shorter end.time_s): its rows off the reference's grid cannot be run
    // again to compare (before: exit 1, "reproduces the stored samples to nan digits").
    if (!reference.times.empty() && !OutsideSceneSpan(scene, reference, reference.times.back()).empty()) {
      Throw<InputError>("kneedyn score", "--scene: scene '", scene.name, "' ends at end.time_s = ", scene.end.time,
                        " s, before the last time of ", document, " (", reference.times.back(),
                        " s): the reference was made for another version of the scene");
    }
    ScoredResult result = ReadResultCsv(result_path_, scene, reference);
    // Events the reference does not have are listed, not scored: a misspelled name would
    // otherwise only leave that event's score empty.
    std::vector<std::string> unmatched_events;
    std::string run_failure = failure_;
    if (!events_path_.empty()) {
      EventsFile events = ReadEvents(events_path_);
      if (!events.scene.empty() && events.scene != scene.name) {
        Throw<InputError>("kneedyn score", "--events = '", EchoPath(events_path_), "': the summary of a run of scene '",
                          Echo(events.scene), "', not of '", scene.name, "' (--scene)");
      }
      // A run that ended early scores as the failure it is, unless --failed says why.
      if (run_failure.empty() && !events.status.empty() && events.status != "completed") {
        run_failure = StrCat("the run's summary.json (--events) has status '", Echo(events.status), "'");
      }
      for (const EventRecord& e : events.events) {  // as the result's rows (ReadResultCsv)
        if (const std::string outside = OutsideSceneSpan(scene, reference, e.time); !outside.empty()) {
          Throw<InputError>("kneedyn score", "--events = '", EchoPath(events_path_), "': event ", e.name, " at time ",
                            e.time, outside);
        }
      }
      result.solution.events = std::move(events.events);
      for (const EventRecord& e : result.solution.events) {
        const bool known = std::any_of(reference.events.begin(), reference.events.end(),
                                       [&e](const EventRecord& r) { return r.name == e.name; });
        if (!known) unmatched_events.push_back(e.name);
      }
    }
    ScoreInfo info;
    info.solver_name = solver_name_;
    info.integrator = integrator_;
    // What the solver ran at, recorded as given: a value that no run can have is refused
    // rather than left out (before, --rtol -5 and --step nan were dropped silently).
    for (const auto& [option, value] : {std::pair<const char*, double>{"--rtol", rtol_}, {"--atol", atol_}, {"--step", step_}}) {
      if (cmd_->count(option) == 0) continue;
      if (!(std::isfinite(value) && value > 0.0)) {
        Throw<InputError>("kneedyn score", option, " = ", value, ": must be a finite number > 0");
      }
      info.setting[std::string(option).substr(2)] = value;
    }
    if (cmd_->count("--cpu-time") > 0 && !(std::isfinite(cpu_time_) && cpu_time_ >= 0.0)) {
      Throw<InputError>("kneedyn score", "--cpu-time = ", cpu_time_, ": must be a finite number of seconds >= 0");
    }
    if (!counters_path_.empty()) info.counters = ReadCounters(counters_path_);
    std::set<std::string> named;  // by --counter
    for (const std::string& c : counters_) {
      const size_t eq = c.find('=');
      char* end = nullptr;
      const double v = eq == std::string::npos ? 0.0 : std::strtod(c.c_str() + eq + 1, &end);
      if (eq == std::string::npos || eq == 0 || end == c.c_str() + eq + 1 || *end != '\0') {
        Throw<InputError>("kneedyn score", "--counter = '", Echo(c), "': give name=value");
      }
      if (!std::isfinite(v)) Throw<InputError>("kneedyn score", "--counter = '", Echo(c), "': the value must be finite");
      if (!named.insert(c.substr(0, eq)).second) {
        Throw<InputError>("kneedyn score", "--counter = '", Echo(c), "': counter '", Echo(c.substr(0, eq)),
                          "' given twice");
      }
      info.counters[c.substr(0, eq)] = v;  // over the --counters file's value of that name
    }
    ReconcileEndEvent(reference,
                      events_path_.empty() ? std::string("the result") : "--events = '" + EchoPath(events_path_) + "'",
                      !run_failure.empty(), &result);
    info.cpu_time_s = cpu_time_;
    info.failure = run_failure;
    // Rows off the reference's sampling times: against the reference run again there.
    const ReferenceScore scored =
        ScoreAgainstReference(scene, ref_json, reference, result, OffGridRows::kRunReferenceAgain);
    const Score& score = scored.score;
    const std::vector<double>& off_grid = scored.off_grid_times;
    const double reproduced_scd = scored.reproduced_scd;
    std::string comparison = "the reference's sampling times (within 1e-9 s) and its end event";
    if (!off_grid.empty()) {
      comparison += StrCat(", and ", off_grid.size(), " other result times, where the reference configuration ",
                           "was run again with output there (it reproduces the stored samples to ",
                           Digits(reproduced_scd), " digits)");
    }

    nlohmann::json out;
    out["kneedyn_version"] = KneedynVersion();
    out["git_commit"] = KneedynGitCommit();
    out["command_line"] = std::vector<std::string>(argv, argv + argc);
    out["header"] = {{"scene", scene.name},
                     {"scene_file", scene_path_},
                     {"reference", reference_file},
                     {"reference_primary", ref_json.value("primary", nlohmann::json::object()).value("command", "")},
                     {"reference_accuracy_scd", ref_json.value("accuracy_scd", nlohmann::json(nullptr))},
                     {"comparison", comparison},
                     {"off_grid_times", off_grid.size()},
                     {"reference_reproduced_scd", std::isfinite(reproduced_scd) ? nlohmann::json(reproduced_scd)
                                                                                : nlohmann::json(nullptr)},
                     {"printed_significant_digits", result.printed_significant_digits},
                     {"metrics_definition", "benchmarks/metrics.hpp, benchmarks/score.hpp, docs/problem.md"},
                     {"result_file", result_path_},
                     {"events_not_in_reference", unmatched_events}};
    out["results"] = nlohmann::json::array({ScoreRecord(result, score, info)});
    {
      // Formatted before anything is written. A path or argument that is not UTF-8 is
      // replaced (U+FFFD) in the JSON, never thrown on.
      const std::string text = out.dump(2, ' ', false, nlohmann::json::error_handler_t::replace);
      WriteOutputFile("kneedyn score", "--out", out_path, text + "\n");
    }

    const Metrics& m = score.metrics;
    std::printf("%s (%s) against %s: %d of %d reference times compared", result_path_.c_str(), solver_name_.c_str(),
                reference_file.c_str(), m.compared_times, m.compared_times + m.missing_times);
    if (!off_grid.empty()) {
      std::printf(" (%zu of them off its sampling grid: the reference run again there, reproducing the stored "
                  "samples to %s digits)", off_grid.size(), Digits(reproduced_scd).c_str());
    }
    std::printf("%s\n", run_failure.empty() ? "" : (" [failed: " + run_failure + "]").c_str());
    const int n_positions = static_cast<int>(reference.names.at("positions").size());
    if (result.given_columns.at("positions") < n_positions) {
      std::printf("  scd - (it needs all %d generalized coordinates; the result gives %d)\n", n_positions,
                  result.given_columns.at("positions"));
    } else {
      std::printf("  scd %s (positions; over the compared times %s)%s\n", Digits(m.scd).c_str(),
                  Digits(m.scd_compared).c_str(),
                  m.scd_above_ceiling ? StrCat(" -- above the ceiling ", Digits(m.scd_ceiling),
                                               ": the reference or the result's printing cannot measure it")
                                            .c_str()
                                      : "");
    }
    std::printf("  %-16s %8s %8s\n", "class", "columns", "mescd");
    for (const std::string& c : VariableClasses()) {
      std::printf("  %-16s %8d %8s\n", c.c_str(), result.given_columns.at(c), Digits(score.mescd.at(c)).c_str());
    }
    for (const auto& [name, err] : m.event_time) {
      if (std::isnan(err)) {
        std::printf("  event %-20s |dt| = - (not in the result)\n", name.c_str());
        continue;
      }
      const std::string digits = Digits(score.event_digits.at(name));
      const double angle_deg = m.event_angle.at(name);
      char angle[32];
      std::snprintf(angle, sizeof angle, "%.3g deg", angle_deg);
      std::printf("  event %-20s |dt| = %.3g s (%s%s), |d flexion| = %s\n", name.c_str(), err, digits.c_str(),
                  digits == "exact" ? "" : " digits",
                  std::isnan(angle_deg) ? "- (no flexion given)" : angle);
    }
    if (!unmatched_events.empty()) {
      std::string names;
      for (const EventRecord& r : reference.events) names += (names.empty() ? "" : ", ") + r.name;
      for (const std::string& name : unmatched_events) {
        std::printf("  event %-20s not scored: the reference's events are %s\n", Echo(name).c_str(), names.c_str());
      }
    }
    if (result.rows_after_reference_end > 0) {
      std::printf("  %zu rows after the reference's end (%s at %.10g s) not compared: no reference state there\n",
                  result.rows_after_reference_end, ReferenceEndEventName(reference).c_str(), reference.times.back());
    }
    std::printf("  drift: max |gap| %s mm, max |gap rate| %s mm/s\n", Millis(m.max_position_residual).c_str(),
                Millis(m.max_velocity_residual).c_str());
    std::printf("  wrote %s\n", out_path.c_str());
    return 0;
  } catch (const InputError& e) {
    std::fprintf(stderr, "kneedyn score: error: %s\n", MessageUnder("kneedyn score", e.what()).c_str());
    return 2;
  } catch (const Error& e) {
    std::fprintf(stderr, "kneedyn score: error: %s\n", MessageUnder("kneedyn score", e.what()).c_str());
    return 1;
  }
}

}  // namespace kneedyn::bench
