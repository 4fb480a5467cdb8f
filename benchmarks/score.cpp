#include "benchmarks/score.hpp"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <limits>
#include <sstream>

#include "formulations/formulation.hpp"
#include "formulations/run_output.hpp"
#include "scene/internal/json_field.hpp"
#include "scene/internal/yaml_field.hpp"
#include "solver/error.hpp"
#include "solver/units.hpp"

namespace kneedyn {
namespace bench {

namespace {

const double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kTimeMatch = 1e-9;  // s, as metrics.cpp

std::vector<std::string> SplitCsvLine(std::string line) {
  if (!line.empty() && line.back() == '\r') line.pop_back();
  std::vector<std::string> cells;
  std::string cell;
  std::istringstream in(line);
  while (std::getline(in, cell, ',')) cells.push_back(cell);
  if (!line.empty() && line.back() == ',') cells.push_back("");
  return cells;
}

// A cell as a number: empty = NaN (a value that does not exist).
double ParseCell(const std::string& cell, const std::string& path, size_t line, const std::string& column) {
  if (cell.empty()) return kNaN;
  char* end = nullptr;
  const double v = std::strtod(cell.c_str(), &end);
  if (end == cell.c_str() || *end != '\0') {
    Throw<InputError>("kneedyn score", EchoPath(path), " line ", line, ", column ", column, ": '", Echo(cell),
                      "' is not a number");
  }
  return v;
}


// An event name as read: kneedyn's names are printable ASCII (docs/model.md §9), and a name
// goes into the score's JSON, which holds only valid UTF-8.
std::string EventName(const std::string& name, const std::string& path, size_t line) {
  for (const char ch : name) {
    const unsigned char c = static_cast<unsigned char>(ch);
    if (c < 0x20 || c >= 0x7f) {
      Throw<InputError>("kneedyn score", "--events = '", EchoPath(path), "' line ", line, ", column name: '", Echo(name),
                        "' is not an event name (printable ASCII, e.g. liftoff_lateral, flexion_90)");
    }
  }
  return name;
}

nlohmann::json Finite(double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr); }

}  // namespace

ScoredResult ReadResultCsv(const std::string& path, const Scene& scene, const Solution& reference) {
  std::istringstream in(scene_detail::ReadInputFile(path, "RESULT", scene_detail::TableFileRule("kneedyn score")));
  std::string line;
  if (!std::getline(in, line)) Throw<InputError>("kneedyn score", EchoPath(path), ": empty (no header row)");
  ScoredResult out;
  out.columns = SplitCsvLine(line);
  // The documented columns of trajectory.csv for this scene (run_output.hpp), and the time.
  const std::vector<std::string> known = MakeTrajectoryTable(scene, RunResult()).columns;
  int time_col = -1, event_col = -1;
  for (size_t c = 0; c < out.columns.size(); ++c) {
    const std::string& name = out.columns[c];
    if (std::count(out.columns.begin(), out.columns.end(), name) > 1) {
      Throw<InputError>("kneedyn score", EchoPath(path), " header: column '", Echo(name), "' appears twice");
    }
    if (name == "time_s" || name == "time") {
      time_col = static_cast<int>(c);
      continue;
    }
    if (name == "is_event") event_col = static_cast<int>(c);
    if (std::find(known.begin(), known.end(), name) == known.end()) {
      std::string nearest;
      int best = std::numeric_limits<int>::max();
      for (const std::string& k : known) {
        const int d = EditDistance(name, k);
        if (d < best) best = d, nearest = k;
      }
      Throw<InputError>("kneedyn score", EchoPath(path), " header: column '", Echo(name),
                        "' is not a trajectory.csv column of this scene (docs/outputs.md); nearest: '", nearest, "'");
    }
  }
  if (time_col < 0) Throw<InputError>("kneedyn score", EchoPath(path), " header: no time column ('time_s' or 'time', s)");

  // Column index of each class component (−1: not given).
  std::map<std::string, std::vector<int>> index;
  for (const std::string& c : VariableClasses()) {
    out.given_columns[c] = 0;
    for (const std::string& name : reference.names.at(c)) {
      const auto it = std::find(out.columns.begin(), out.columns.end(), ColumnSafeName(name));
      index[c].push_back(it == out.columns.end() ? -1 : static_cast<int>(it - out.columns.begin()));
      if (it != out.columns.end()) ++out.given_columns[c];
    }
    out.solution.names[c] = reference.names.at(c);
    out.solution.values[c];
  }
  auto column = [&](const std::string& name) {
    const auto it = std::find(out.columns.begin(), out.columns.end(), name);
    return it == out.columns.end() ? -1 : static_cast<int>(it - out.columns.begin());
  };
  struct Drift {
    int gap, rate, point, force;
  };
  std::vector<Drift> drift;
  bool have_gap = false;
  for (const ContactPair& pair : scene.model.contacts) {
    const std::string c = CompartmentName(pair.compartment);
    drift.push_back({column("gap_" + c + "_mm"), column("gap_rate_" + c + "_mm_s"), column("femoral_" + c + "_x_mm"),
                     column("N_" + c + "_N")});
    have_gap = have_gap || drift.back().gap >= 0 || drift.back().rate >= 0;
  }
  if (!have_gap) out.max_gap_m = out.max_gap_rate_m_s = kNaN;

  std::vector<double> row_times;
  std::vector<bool> row_event;
  size_t line_no = 1;
  while (std::getline(in, line)) {
    ++line_no;
    if (line.empty() || line == "\r") continue;
    const std::vector<std::string> cells = SplitCsvLine(line);
    if (cells.size() != out.columns.size()) {
      Throw<InputError>("kneedyn score", EchoPath(path), " line ", line_no, ": ", cells.size(), " cells for ", out.columns.size(),
                        " columns");
    }
    std::vector<double> v(cells.size());
    for (size_t c = 0; c < cells.size(); ++c) v[c] = ParseCell(cells[c], path, line_no, out.columns[c]);
    const double t = v[time_col];
    if (!std::isfinite(t) || (!row_times.empty() && !(t >= row_times.back()))) {
      Throw<InputError>("kneedyn score", EchoPath(path), " line ", line_no, ": time ", Echo(cells[time_col]),
                        " is not finite or decreases");
    }
    row_times.push_back(t);
    row_event.push_back(event_col >= 0 && v[event_col] == 1.0);
    for (const std::string& c : VariableClasses()) {
      std::vector<double> values;
      for (int k : index[c]) values.push_back(k < 0 ? kNaN : v[k]);
      out.solution.values[c].push_back(values);
    }
    // Drift over the rows where the contact is in contact: its contact point exists (or,
    // without point columns, N > 0; without either, every row).
    for (const Drift& d : drift) {
      const bool active = d.point >= 0 ? !std::isnan(v[d.point]) : d.force >= 0 ? v[d.force] > 0.0 : true;
      if (!active) continue;
      if (d.gap >= 0 && !std::isnan(v[d.gap])) out.max_gap_m = std::max(out.max_gap_m, MmToM(std::abs(v[d.gap])));
      if (d.rate >= 0 && !std::isnan(v[d.rate])) {
        out.max_gap_rate_m_s = std::max(out.max_gap_rate_m_s, MmToM(std::abs(v[d.rate])));
      }
    }
  }
  out.rows = row_times.size();
  if (out.rows == 0) Throw<InputError>("kneedyn score", EchoPath(path), ": no data rows");

  // The sampling rows first, then the end-event state as the last entry (metrics.hpp).
  const double last_sampling_time =
      reference.times.size() >= 2 ? reference.times[reference.times.size() - 2] : reference.times.back();
  const bool end_row = event_col >= 0 ? static_cast<bool>(row_event.back())
                                      : reference.end_is_event && row_times.back() > last_sampling_time + kTimeMatch;
  Solution& s = out.solution;
  std::map<std::string, std::vector<std::vector<double>>> values;
  for (size_t r = 0; r < out.rows; ++r) {
    const bool last = r + 1 == out.rows;
    if (row_event[r] && !(last && end_row)) continue;  // an event row inside the run
    if (last && end_row) continue;                      // appended below
    s.times.push_back(row_times[r]);
    for (const std::string& c : VariableClasses()) values[c].push_back(s.values[c][r]);
  }
  if (end_row) {
    s.times.push_back(row_times.back());
    for (const std::string& c : VariableClasses()) values[c].push_back(s.values[c].back());
    s.end_is_event = true;
  }
  for (const std::string& c : VariableClasses()) s.values[c] = values[c];
  return out;
}

std::vector<EventRecord> ReadEvents(const std::string& path) {
  const std::string body = scene_detail::ReadInputFile(path, "--events file", scene_detail::TableFileRule("kneedyn score"));
  std::vector<EventRecord> events;
  const size_t first = body.find_first_not_of(" \t\r\n");
  if (first != std::string::npos && body[first] == '{') {  // kneedyn's summary.json
    nlohmann::json j;
    try {
      j = nlohmann::json::parse(body);
    } catch (const nlohmann::json::exception& e) {
      Throw<InputError>("kneedyn score", "--events = '", EchoPath(path), "': not a summary.json with events (", e.what(), ")");
    }
    const scene_detail::JsonFields read("kneedyn score", "--events = '" + EchoPath(path) + "'");
    const nlohmann::json& list = read.List(j, "", "events");
    for (size_t i = 0; i < list.size(); ++i) {
      const std::string where = StrCat("events[", i, "].");
      events.push_back({EventName(read.String(list[i], where, "name"), path, 1), read.Number(list[i], where, "time"),
                        DegToRad(read.Number(list[i], where, "flexion_deg"))});
    }
    return events;
  }
  std::istringstream lines(body);
  std::string line;
  std::getline(lines, line);
  const std::vector<std::string> header = SplitCsvLine(line);
  const auto name_col = std::find(header.begin(), header.end(), "name") - header.begin();
  const auto time_col = std::find(header.begin(), header.end(), "time_s") - header.begin();
  const auto angle_col = std::find(header.begin(), header.end(), "flexion_deg") - header.begin();
  if (name_col == static_cast<long>(header.size()) || time_col == static_cast<long>(header.size())) {
    Throw<InputError>("kneedyn score", "--events = '", EchoPath(path), "': a CSV needs the columns name and time_s");
  }
  size_t line_no = 1;
  while (std::getline(lines, line)) {
    ++line_no;
    if (line.empty() || line == "\r") continue;
    const std::vector<std::string> cells = SplitCsvLine(line);
    if (cells.size() != header.size()) Throw<InputError>("kneedyn score", EchoPath(path), " line ", line_no, ": wrong number of cells");
    const double angle =
        angle_col < static_cast<long>(header.size()) ? ParseCell(cells[angle_col], path, line_no, "flexion_deg") : kNaN;
    events.push_back({EventName(cells[name_col], path, line_no), ParseCell(cells[time_col], path, line_no, "time_s"),
                      DegToRad(angle)});
  }
  return events;
}

Score ScoreResult(const ScoredResult& result, const Solution& reference) {
  Score score;
  score.metrics = Compare(result.solution, reference);
  score.metrics.max_position_residual = result.max_gap_m;
  score.metrics.max_velocity_residual = result.max_gap_rate_m_s;
  if (result.given_columns.at("positions") == 0) score.metrics.scd = score.metrics.scd_compared = kNaN;
  for (const std::string& c : VariableClasses()) {
    score.mescd[c] = result.given_columns.at(c) > 0 ? -std::log10(score.metrics.mixed.at(c)) : kNaN;
  }
  for (const EventRecord& e : reference.events) {
    const auto it = score.metrics.event_time.find(e.name);
    if (it == score.metrics.event_time.end() || score.event_digits.count(e.name)) continue;
    score.event_digits[e.name] = -std::log10(it->second / std::abs(e.time));
  }
  return score;
}

std::vector<double> OffGridTimes(const ScoredResult& result, const Solution& reference) {
  std::vector<double> off;
  if (reference.times.empty()) return off;
  const Solution& r = result.solution;
  const size_t n = r.end_is_event ? r.times.size() - 1 : r.times.size();
  const double t_last = reference.times.back();
  for (size_t i = 0; i < n; ++i) {
    const double t = r.times[i];
    if (t < reference.times.front() - kTimeMatch || t > t_last + kTimeMatch) continue;
    const auto it = std::lower_bound(reference.times.begin(), reference.times.end(), t - kTimeMatch);
    if (it != reference.times.end() && std::abs(*it - t) <= kTimeMatch) continue;
    off.push_back(t);
  }
  return off;
}

nlohmann::json DenseDoubleConfiguration() {
  return {{"formulation", "mde"},
          {"integrator", "cvode-adams"},
          {"rtol", 1.0e-14},
          {"atol", 1.0e-16},
          {"command", "kneedyn run SCENE --formulation mde --integrator cvode-adams --rtol 1e-14 --atol 1e-16"}};
}

void CheckReferenceFields(const nlohmann::json& reference_json, const std::string& document) {
  const scene_detail::JsonFields read("kneedyn score", document);
  (void)read.String(reference_json, "", "scene");
  for (const char* key : {"accuracy_scd", "comparison_interval_s"}) {
    if (read.Find(reference_json, "", key)) (void)read.Number(reference_json, "", key);
  }
  const nlohmann::json* primary = read.Find(reference_json, "", "primary");
  if (primary == nullptr) return;
  for (const char* key : {"formulation", "integrator", "command"}) {
    if (read.Find(*primary, "primary.", key)) (void)read.String(*primary, "primary.", key);
  }
  for (const char* key : {"rtol", "atol"}) {
    if (read.Find(*primary, "primary.", key)) (void)read.Number(*primary, "primary.", key);
  }
}

double ScoreCeilingAccuracy(const nlohmann::json& reference_json, double reproduced_scd) {
  const double stated = reference_json.value("accuracy_scd", kNaN);
  return std::isfinite(reproduced_scd) ? std::min(stated, reproduced_scd) : stated;
}

Solution DenseReference(const Scene& scene, const nlohmann::json& reference_json, const Solution& reference,
                        const std::vector<double>& times, double* reproduced_scd) {
  nlohmann::json primary = reference_json.value("primary", nlohmann::json::object());
  // An extended-precision reference (make_reference --method extended) is not a `kneedyn
  // run` configuration: its off-grid rows come from the double configuration below, checked
  // against the stored samples like any other; what it reproduces caps the score
  // (ScoreCeilingAccuracy).
  const bool extended = primary.value("formulation", std::string()) == kExtendedPrecisionFormulation;
  if (extended) primary = DenseDoubleConfiguration();
  RunSettings settings;
  FormulationOptions& o = settings.options;
  try {
    settings.formulation = primary.at("formulation").get<std::string>();
    o.integrator = IntegratorOption(primary.value("integrator", std::string()));
    o.rtol = primary.at("rtol").get<double>();
    o.atol = primary.at("atol").get<double>();
  } catch (const nlohmann::json::exception& e) {
    // Not primary.dump(): a hostile reference may nest its fields arbitrarily deep.
    Throw<InputError>("kneedyn score", "the reference records no configuration to run again (primary needs "
                      "formulation, rtol and atol: ", e.what(), ")");
  }
  settings.output_times = times;
  const ContactForm form = CreateFormulation(settings.formulation, scene, o)->contact_form();
  const RunResult run = RunScene(scene, settings);
  if (!run.completed) {
    Throw<SolverError>("kneedyn score", "the reference configuration (", primary.value("command", ""),
                       ") failed when run again with output at the result's times: ", run.failure);
  }
  // The run again must be the stored reference: its sampling times against the stored samples.
  const double interval = reference_json.value("comparison_interval_s", kDefaultComparisonInterval);
  const Metrics check = Compare(ExtractSolution(scene, form, run, interval), reference);
  const double accuracy = extended ? kMinDenseReproductionScd : reference_json.value("accuracy_scd", 0.0);
  *reproduced_scd = check.scd;
  if (!(check.scd >= accuracy)) {
    Throw<SolverError>("kneedyn score", "the reference configuration (", primary.value("command", ""),
                       ") run again with output at the result's times reproduces the stored samples to ", check.scd,
                       " digits (rule: at least ", accuracy, extended ? " digits for the double configuration of an extended-precision reference" : " = the reference's accuracy_scd",
                       "); score at the reference's sampling times instead");
  }
  const Solution at = ExtractSolutionAt(scene, form, run, times);
  // Merge: the stored samples at their times, the run's rows at `times`, in time order; the
  // end event (stored) last.
  Solution dense = reference;
  dense.times.clear();
  for (const std::string& c : VariableClasses()) dense.values[c].clear();
  const size_t n_stored = reference.end_is_event ? reference.times.size() - 1 : reference.times.size();
  const size_t n_at = at.end_is_event ? at.times.size() - 1 : at.times.size();
  size_t i = 0, j = 0;
  const auto take = [&](const Solution& from, size_t k) {
    dense.times.push_back(from.times[k]);
    for (const std::string& c : VariableClasses()) dense.values[c].push_back(from.values.at(c)[k]);
  };
  while (i < n_stored || j < n_at) {
    if (j >= n_at || (i < n_stored && reference.times[i] <= at.times[j])) {
      take(reference, i++);
    } else {
      take(at, j++);
    }
  }
  if (reference.end_is_event) take(reference, reference.times.size() - 1);
  if (j != times.size()) {
    Throw<SolverError>("kneedyn score", "the reference run again has rows at ", j, " of the ", times.size(),
                       " result times inside its span");
  }
  return dense;
}

Solution ReferenceSolution(const nlohmann::json& reference_json, const std::string& document) {
  CheckReferenceFields(reference_json, document);
  return SolutionFromJson(scene_detail::JsonFields("kneedyn score", document).At(reference_json, "", "solution"),
                          document);
}

ReferenceScore ScoreAgainstReference(const Scene& scene, const nlohmann::json& reference_json,
                                     const Solution& reference, const ScoredResult& result, OffGridRows off_grid_rows) {
  ReferenceScore out{{}, OffGridTimes(result, reference), kNaN};
  const bool run_again = !out.off_grid_times.empty() && off_grid_rows == OffGridRows::kRunReferenceAgain;
  out.score = ScoreResult(
      result, run_again ? DenseReference(scene, reference_json, reference, out.off_grid_times, &out.reproduced_scd)
                        : reference);
  // Above the reference's accuracy (or what the run again reproduced) − 1 digit, the error
  // measured is the reference's own: flagged as in the work-precision sweep.
  const double ceiling_accuracy = ScoreCeilingAccuracy(reference_json, out.reproduced_scd);
  if (std::isfinite(ceiling_accuracy)) ApplyScdCeiling(ceiling_accuracy, &out.score.metrics);
  return out;
}

nlohmann::json ScoreRecord(const ScoredResult& result, const Score& score, const ScoreInfo& info) {
  nlohmann::json metrics = MetricsJson(score.metrics);
  // A class the CSV does not give has no error (MetricsJson writes 0 for an empty class).
  for (const auto& [c, n] : result.given_columns) {
    if (n == 0 && metrics.contains("mixed_error")) metrics["mixed_error"][c] = nullptr;
  }
  for (const auto& [c, v] : score.mescd) metrics["mescd"][c] = Finite(v);
  for (const auto& [e, v] : score.event_digits) metrics["event_time_digits"][e] = Finite(v);
  nlohmann::json r;
  r["name"] = info.solver_name;
  r["formulation"] = info.solver_name;
  r["integrator"] = info.integrator;
  r["setting"] = info.setting;
  r["status"] = info.failure.empty() ? "ok" : "failed";
  r["reason"] = info.failure;
  r["metrics"] = metrics;
  r["cpu_time_s"] = info.cpu_time_s < 0.0 ? nlohmann::json(nullptr)
                                          : nlohmann::json{{"median", info.cpu_time_s}, {"min", info.cpu_time_s},
                                                           {"max", info.cpu_time_s}};
  r["counters"] = info.counters;
  r["events"] = nlohmann::json::array();
  for (const EventRecord& e : result.solution.events) {
    r["events"].push_back({{"name", e.name}, {"time_s", e.time}, {"flexion_deg", Finite(RadToDeg(e.flexion))}});
  }
  r["columns_given"] = result.given_columns;
  r["rows"] = result.rows;
  return r;
}

}  // namespace bench
}  // namespace kneedyn
