#include "benchmarks/score.hpp"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <limits>
#include <sstream>
#include <string_view>

#include "formulations/formulation.hpp"
#include "formulations/run_output.hpp"
#include "scene/internal/csv_fields.hpp"
#include "scene/internal/json_field.hpp"
#include "scene/internal/yaml_field.hpp"
#include "solver/error.hpp"
#include "solver/observables.hpp"
#include "solver/pose.hpp"
#include "solver/units.hpp"

namespace kneedyn {
namespace bench {

namespace {

const double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kTimeMatch = 1e-9;  // s, as metrics.cpp

using scene_detail::CsvFieldCount;    // fields counted before anything is stored,
using scene_detail::ForEachCsvField;  // then split into views (scene/internal/csv_fields.hpp)

// A CSV line without its '\r' (a CRLF file).
std::string_view CsvLine(std::string_view line) {
  if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
  return line;
}

// The lines of a file's text, in order, as views (no copy of the text into a stream).
class Lines {
 public:
  explicit Lines(std::string_view text) : text_(text) {}
  bool Next(std::string_view* line) {
    if (pos_ >= text_.size()) return false;
    const size_t end = text_.find('\n', pos_);
    const size_t stop = end == std::string_view::npos ? text_.size() : end;
    *line = text_.substr(pos_, stop - pos_);
    pos_ = stop + 1;
    return true;
  }

 private:
  std::string_view text_;
  size_t pos_ = 0;
};

// The significant digits a number cell prints: the digits of its mantissa from the first
// nonzero one ("-5.74028008286" 12, "0.000123" 3, "1e-05" 1, "0" 0); quotes and blanks around
// it are not digits.
int SignificantDigits(std::string_view cell) {
  int digits = 0;
  bool leading = true;
  for (const char ch : cell) {
    if (ch == 'e' || ch == 'E') break;
    if (ch < '0' || ch > '9') continue;
    if (leading && ch == '0') continue;
    leading = false;
    ++digits;
  }
  return digits;
}

// A cell as a number: empty = NaN (a value that does not exist). `buffer`: reused storage
// for the cell's text (strtod reads up to its first NUL, as it did on the cell's string).
// "nan", "inf" and a number past double's range are refused: a value that exists is finite,
// and a non-finite one would be skipped by the comparison or score as "exact".
double ParseCell(std::string_view cell, std::string* buffer, const std::string& path, size_t line,
                 const std::string& column) {
  if (cell.empty()) return kNaN;
  buffer->assign(cell.data(), cell.size());
  char* end = nullptr;
  const double v = std::strtod(buffer->c_str(), &end);
  if (end == buffer->c_str() || *end != '\0') {
    Throw<InputError>("kneedyn score", EchoPath(path), " line ", line, ", column ", column, ": '", Echo(*buffer),
                      "' is not a number");
  }
  if (!std::isfinite(v)) {
    Throw<InputError>("kneedyn score", EchoPath(path), " line ", line, ", column ", column, ": '", Echo(*buffer),
                      "' is not a finite number (a value that does not exist is an empty cell)");
  }
  return v;
}

// An event name as read: kneedyn's names are printable ASCII (docs/outputs.md, `events`), and a name
// goes into the score's JSON, which holds only valid UTF-8.
std::string EventName(std::string_view view, const std::string& path, size_t line) {
  std::string name(view);
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
  const std::string text = scene_detail::ReadInputFile(path, "RESULT", scene_detail::TableFileRule("kneedyn score"));
  Lines lines(scene_detail::WithoutByteOrderMark(text));
  std::string_view line;
  if (!lines.Next(&line)) Throw<InputError>("kneedyn score", EchoPath(path), ": empty (no header row)");
  ScoredResult out;
  // The documented columns of trajectory.csv for this scene (run_output.hpp), and the time.
  const std::vector<std::string> known = MakeTrajectoryTable(scene, RunResult()).columns;
  size_t longest_known = 0;
  for (const std::string& k : known) longest_known = std::max(longest_known, k.size());
  // A valid header names each of `known`, time_s and time at most once: more cells than that
  // hold a name twice or an unknown one, found among the first max_columns + 1 (checked
  // below as for any header), so the rest is not kept.
  const size_t max_columns = known.size() + 3;  // and a row index
  const std::string_view header = CsvLine(line);
  std::vector<std::string> typed;  // the header as written, for the messages
  ForEachCsvField(header, [&](size_t c, std::string_view name) {
    if (c > max_columns) return false;
    typed.emplace_back(name);
    // The names as the reference's solution.classes spell them ("F_ACL anterior_N") are the
    // trajectory.csv columns they stand for.
    out.columns.push_back(ColumnSafeName(typed.back()));
    return true;
  });
  int time_col = -1, event_col = -1;
  for (size_t c = 0; c < out.columns.size(); ++c) {
    const std::string& name = out.columns[c];
    if (std::count(out.columns.begin(), out.columns.end(), name) > 1) {
      Throw<InputError>("kneedyn score", EchoPath(path), " header: column '", Echo(typed[c]), "' appears twice");
    }
    if (c == 0 && name.empty()) continue;  // a row index without a name (pandas' to_csv, R's write.csv)
    if (name == "time_s" || name == "time") {
      if (time_col >= 0) {  // which one holds the times? Before, the last one was used silently.
        Throw<InputError>("kneedyn score", EchoPath(path), " header: columns '", typed[time_col], "' and '", typed[c],
                          "' both name the time; give one");
      }
      time_col = static_cast<int>(c);
      continue;
    }
    if (name == "is_event") event_col = static_cast<int>(c);
    if (std::find(known.begin(), known.end(), name) == known.end()) {
      // The nearest known name, for a name that can be a typo of one: not for one over
      // twice the longest (its edit distance to every name costs its length times theirs:
      // a 16 MB name took 27 s).
      std::string nearest;
      if (name.size() <= 2 * longest_known) {
        int best = std::numeric_limits<int>::max();
        for (const std::string& k : known) {
          const int d = EditDistance(name, k);
          if (d < best) best = d, nearest = k;
        }
      }
      Throw<InputError>("kneedyn score", EchoPath(path), " header: column '", Echo(typed[c]),
                        "' is not a trajectory.csv column of this scene (docs/outputs.md)",
                        nearest.empty() ? std::string() : "; nearest: '" + nearest + "'");
    }
  }
  if (out.columns.size() != CsvFieldCount(header)) {  // not reached: the kept cells break a rule above
    Throw<InputError>("kneedyn score", EchoPath(path), " header: more than ", max_columns, " columns");
  }
  if (time_col < 0) Throw<InputError>("kneedyn score", EchoPath(path), " header: no time column ('time_s' or 'time', s)");

  // Column index of each class component (−1: not given).
  struct ClassColumns {
    std::vector<int> index;
    std::vector<std::vector<double>>* rows;
  };
  std::vector<ClassColumns> classes;
  for (const std::string& c : VariableClasses()) {
    out.given_columns[c] = 0;
    ClassColumns cc{{}, &out.solution.values[c]};
    for (const std::string& name : reference.names.at(c)) {
      const auto it = std::find(out.columns.begin(), out.columns.end(), ColumnSafeName(name));
      cc.index.push_back(it == out.columns.end() ? -1 : static_cast<int>(it - out.columns.begin()));
      if (it != out.columns.end()) ++out.given_columns[c];
    }
    out.solution.names[c] = reference.names.at(c);
    classes.push_back(std::move(cc));
  }
  // The generalized coordinates and their rates exist at every time: an empty cell there is
  // refused (else it is skipped, and a column left empty would compare nothing).
  std::vector<bool> always_valued(out.columns.size(), false);
  always_valued[time_col] = true;
  for (size_t k = 0; k < classes.size(); ++k) {
    if (VariableClasses()[k] != "positions" && VariableClasses()[k] != "velocities") continue;
    for (const int index : classes[k].index) {
      if (index >= 0) always_valued[index] = true;
    }
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

  // Rows are counted as they are read and stored as the Solution's rows at once, the sampling
  // rows in order and the end-event state last (metrics.hpp): an event row (is_event = 1) is
  // dropped when a row follows it. Past kMaxResultRows rows the file is refused before the
  // row is stored.
  Solution& s = out.solution;
  std::vector<double> v(out.columns.size()), last_row;
  std::string cell_buffer;
  double last_time = kNaN;
  bool last_is_event = false;  // the last row stored has is_event = 1
  size_t line_no = 1;
  while (lines.Next(&line)) {
    ++line_no;
    if (line.empty() || line == "\r") continue;
    const std::string_view row = CsvLine(line);
    const size_t cells = CsvFieldCount(row);
    if (cells != out.columns.size()) {
      Throw<InputError>("kneedyn score", EchoPath(path), " line ", line_no, ": ", cells, " cells for ", out.columns.size(),
                        " columns");
    }
    if (out.rows == kMaxResultRows) {
      Throw<InputError>("kneedyn score", EchoPath(path), " line ", line_no, ": more than ", kMaxResultRows,
                        " data rows (rule: at most kMaxResultRows = 10 x kneedyn's own limit of ",
                        static_cast<size_t>(kMaxOutputRows), " output rows; docs/outputs.md)");
    }
    std::string_view time_cell, event_cell;
    ForEachCsvField(row, [&](size_t c, std::string_view cell) {
      if (cell.empty() && always_valued[c]) {
        Throw<InputError>("kneedyn score", EchoPath(path), " line ", line_no, ", column ", out.columns[c],
                          ": empty; a time, a generalized coordinate or its rate has a value in every row");
      }
      v[c] = ParseCell(cell, &cell_buffer, path, line_no, out.columns[c]);
      if (static_cast<int>(c) != time_col && static_cast<int>(c) != event_col) {  // the values' printing
        out.printed_significant_digits = std::max(out.printed_significant_digits, SignificantDigits(cell));
      }
      if (static_cast<int>(c) == time_col) time_cell = cell;
      if (static_cast<int>(c) == event_col) event_cell = cell;
      return true;
    });
    const double t = v[time_col];
    if (const std::string outside = OutsideSceneSpan(scene, reference, t); !outside.empty()) {
      Throw<InputError>("kneedyn score", EchoPath(path), " line ", line_no, ": time ", Echo(std::string(time_cell)),
                        outside);
    }
    if (out.rows > 0 && !(t >= last_time)) {
      Throw<InputError>("kneedyn score", EchoPath(path), " line ", line_no, ": time ", Echo(std::string(time_cell)),
                        " decreases (the row before: ", last_time, ")");
    }
    if (event_col >= 0 && !std::isnan(v[event_col]) && v[event_col] != 0.0 && v[event_col] != 1.0) {
      Throw<InputError>("kneedyn score", EchoPath(path), " line ", line_no, ", column is_event: '",
                        Echo(std::string(event_cell)), "'; must be 1 (an event row), 0 or empty");
    }
    const bool is_event = event_col >= 0 && v[event_col] == 1.0;
    // Two rows at one time: which one is the solution there? Only the same row again or an
    // event row (not compared at the sampling times) may share it; before, the second row was
    // ignored whatever it held.
    const auto same_cells = [&] {
      return std::equal(v.begin(), v.end(), last_row.begin(),
                        [](double a, double b) { return a == b || (std::isnan(a) && std::isnan(b)); });
    };
    if (out.rows > 0 && t == last_time && !is_event && !last_is_event && !same_cells()) {
      Throw<InputError>("kneedyn score", EchoPath(path), " line ", line_no, ": time ", Echo(std::string(time_cell)),
                        " repeats the row before's with other values; rows at one time are refused unless they are "
                        "the same or one of them is an event row (is_event = 1)");
    }
    last_row = v;
    ++out.rows;
    last_time = t;
    if (last_is_event) {  // an event row inside the run
      s.times.pop_back();
      for (const ClassColumns& cc : classes) cc.rows->pop_back();
    }
    s.times.push_back(t);
    for (const ClassColumns& cc : classes) {
      std::vector<double>& values = cc.rows->emplace_back(cc.index.size());
      for (size_t j = 0; j < cc.index.size(); ++j) values[j] = cc.index[j] < 0 ? kNaN : v[cc.index[j]];
    }
    last_is_event = is_event;
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
  if (out.rows == 0) Throw<InputError>("kneedyn score", EchoPath(path), ": no data rows");
  if (reference.end_is_event) {  // rows past the reference's end (the result's end row aside)
    const size_t n = s.times.size() - 1;
    for (size_t i = 0; i < n; ++i) out.rows_after_reference_end += s.times[i] > reference.times.back() + kTimeMatch;
  }

  // The last row is the end-event state when it is an event row, or, without is_event, when
  // the reference ended on an event and the row lies past its last sampling time.
  const double last_sampling_time =
      reference.times.size() >= 2 ? reference.times[reference.times.size() - 2] : reference.times.back();
  s.end_is_event = event_col >= 0 ? last_is_event
                                  : reference.end_is_event && last_time > last_sampling_time + kTimeMatch;
  return out;
}

std::string OutsideSceneSpan(const Scene& scene, const Solution& reference, double t) {
  const double start = reference.times.empty() ? 0.0 : reference.times.front();
  if (t >= start - kTimeMatch && t <= scene.end.time + kTimeMatch) return "";
  return StrCat(" s lies outside the scene's span [", start, ", ", scene.end.time,
                "] s (its start and end.time_s; times are in seconds)");
}

EventsFile ReadEvents(const std::string& path) {
  const std::string body = scene_detail::ReadInputFile(path, "--events file", scene_detail::TableFileRule("kneedyn score"));
  EventsFile file;
  std::vector<EventRecord>& events = file.events;
  const size_t first = body.find_first_not_of(" \t\r\n");
  if (first != std::string::npos && body[first] == '{') {  // kneedyn's summary.json
    const std::string document = "--events = '" + EchoPath(path) + "'";
    nlohmann::json j;
    try {
      j = scene_detail::ParseJsonDocument(body, "kneedyn score", document);
    } catch (const nlohmann::json::exception& e) {
      Throw<InputError>("kneedyn score", "--events = '", EchoPath(path), "': not a summary.json with events (", e.what(), ")");
    }
    const scene_detail::JsonFields read("kneedyn score", document);
    const nlohmann::json& list = read.List(j, "", "events");
    for (size_t i = 0; i < list.size(); ++i) {
      const std::string where = StrCat("events[", i, "].");
      events.push_back({EventName(read.String(list[i], where, "name"), path, 1), read.Number(list[i], where, "time"),
                        DegToRad(read.Number(list[i], where, "flexion_deg"))});
    }
    if (const nlohmann::json* scene = read.Find(j, "", "scene")) file.scene = read.String(*scene, "scene.", "name");
    if (read.Find(j, "", "status") != nullptr) file.status = read.String(j, "", "status");
    return file;
  }
  Lines lines(scene_detail::WithoutByteOrderMark(body));
  std::string_view line;
  lines.Next(&line);
  const std::string_view header = CsvLine(line);
  const size_t n_header = CsvFieldCount(header);
  size_t name_col = n_header, time_col = n_header, angle_col = n_header;
  // Each column once, and no other: a misspelled flexion column was dropped silently.
  ForEachCsvField(header, [&](size_t c, std::string_view cell) {
    if (c == 0 && cell.empty()) return true;  // a row index without a name (pandas, R), as the result CSV
    const bool time = cell == "time_s" || cell == "time";  // as the result CSV
    size_t* col = cell == "name" ? &name_col : time ? &time_col : cell == "flexion_deg" ? &angle_col : nullptr;
    if (col == nullptr) {
      Throw<InputError>("kneedyn score", "--events = '", EchoPath(path), "' header: column '", Echo(std::string(cell)),
                        "' is not one of name, time_s (or time), flexion_deg");
    }
    if (*col != n_header) {
      Throw<InputError>("kneedyn score", "--events = '", EchoPath(path), "' header: column '", Echo(std::string(cell)),
                        "' repeats ", time ? "the time" : "a column");
    }
    *col = c;
    return true;
  });
  if (name_col == n_header || time_col == n_header) {
    Throw<InputError>("kneedyn score", "--events = '", EchoPath(path), "': a CSV needs the columns name and time_s (or time)");
  }
  std::string cell_buffer;
  size_t line_no = 1;
  while (lines.Next(&line)) {
    ++line_no;
    if (line.empty() || line == "\r") continue;
    const std::string_view row = CsvLine(line);
    if (CsvFieldCount(row) != n_header) {
      Throw<InputError>("kneedyn score", "--events = '", EchoPath(path), "' line ", line_no, ": ", CsvFieldCount(row),
                        " cells for ", n_header, " columns (rule: one cell per header column)");
    }
    if (events.size() == kMaxResultRows) {
      Throw<InputError>("kneedyn score", "--events = '", EchoPath(path), "' line ", line_no, ": more than ", kMaxResultRows,
                        " events (rule: at most kMaxResultRows, as result rows)");
    }
    std::string_view name, time, angle;
    ForEachCsvField(row, [&](size_t c, std::string_view cell) {
      if (c == name_col) name = cell;
      if (c == time_col) time = cell;
      if (c == angle_col) angle = cell;
      return true;
    });
    const double flexion = angle_col < n_header ? ParseCell(angle, &cell_buffer, path, line_no, "flexion_deg") : kNaN;
    std::string event_name = EventName(name, path, line_no);
    if (time.empty()) {
      Throw<InputError>("kneedyn score", "--events = '", EchoPath(path), "' line ", line_no,
                        ", column time_s: empty; an event has a time");
    }
    const double event_time = ParseCell(time, &cell_buffer, path, line_no, "time_s");
    events.push_back({std::move(event_name), event_time, DegToRad(flexion)});
  }
  return file;
}

Score ScoreResult(const ScoredResult& result, const Solution& reference) {
  Score score;
  score.metrics = Compare(result.solution, reference);
  score.metrics.max_position_residual = result.max_gap_m;
  score.metrics.max_velocity_residual = result.max_gap_rate_m_s;
  if (result.given_columns.at("positions") < static_cast<int>(reference.names.at("positions").size())) {
    score.metrics.scd = score.metrics.scd_compared = kNaN;
  }
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

std::string ReferenceEndEventName(const Solution& reference) {
  if (!reference.end_is_event || reference.times.empty()) return "";
  for (const EventRecord& e : reference.events) {
    if (std::abs(e.time - reference.times.back()) <= kTimeMatch) return e.name;
  }
  return "";
}

void ReconcileEndEvent(const Solution& reference, const std::string& events_source, bool failed,
                       ScoredResult* result) {
  Solution& r = result->solution;
  const std::string name = ReferenceEndEventName(reference);
  if (failed || name.empty() || !r.end_is_event || r.times.empty()) return;
  // The end state's flexion (α, deg; the positions' fourth component): a last event row at
  // another flexion (a lift-off) is not the end event.
  const std::vector<double>& end_positions = r.values.at("positions").back();
  const std::vector<double>& reference_end = reference.values.at("positions").back();
  if (end_positions.size() > 3 && reference_end.size() > 3 && !std::isnan(end_positions[3]) &&
      !(std::abs(end_positions[3] - reference_end[3]) <= 1e-3)) {
    return;
  }
  const double t_end = r.times.back();
  for (const EventRecord& e : r.events) {
    if (e.name != name) continue;
    if (std::abs(e.time - t_end) > kTimeMatch) {
      Throw<InputError>("kneedyn score", events_source, ": event ", name, " at time ", e.time,
                        " s, but the result's end row (the state at its end event) is at ", t_end,
                        " s; they must agree within 1e-9 s");
    }
    return;  // its first occurrence is the one scored (Compare)
  }
  const double flexion_deg = end_positions.size() > 3 ? end_positions[3] : kNaN;  // α, deg (docs/outputs.md)
  r.events.push_back({name, t_end, DegToRad(flexion_deg)});
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
    if (!off.empty() && t == off.back()) continue;  // a repeated row: one time to run the reference to
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
  if (read.Find(reference_json, "", "accuracy_scd")) (void)read.Number(reference_json, "", "accuracy_scd");
  // The sampling of the reference run again at off-grid rows (DenseReference).
  if (read.Find(reference_json, "", "comparison_interval_s")) {
    const double interval = read.Number(reference_json, "", "comparison_interval_s");
    if (!(interval > 0.0)) read.Fail("comparison_interval_s", StrCat(" = ", interval, ": must be > 0 s"));
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

double ScoreCeilingAccuracy(const nlohmann::json& reference_json, double reproduced_scd,
                            int printed_significant_digits) {
  double accuracy = reference_json.value("accuracy_scd", kNaN);
  if (std::isfinite(reproduced_scd)) accuracy = std::min(accuracy, reproduced_scd);
  if (printed_significant_digits > 0) accuracy = std::min(accuracy, static_cast<double>(printed_significant_digits));
  return accuracy;
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
  // Bounded by the result's rows (kMaxResultRows, ReadResultCsv) when they come from a file.
  if (times.size() > kMaxResultRows) {
    Throw<InputError>("kneedyn score", "DenseReference: ", times.size(), " off-grid times; at most kMaxResultRows = ",
                      kMaxResultRows);
  }
  settings.output_times = times;
  // Uniform output only at the stored sampling times: an off-grid time is more than kTimeMatch
  // from those, so no pair of output times is closer than that (a result row 1e-11 s after
  // the scene's 5 ms grid made a 1e-11 s step, and the run again lost a digit).
  const double interval = reference_json.value("comparison_interval_s", kDefaultComparisonInterval);
  std::string unusable;  // a comparison interval no run can output at keeps the scene's interval
  if (IsValidOutputInterval(interval, scene.end.time, &unusable)) settings.output_interval = interval;
  const ContactForm form = CreateFormulation(settings.formulation, scene, o)->contact_form();
  Solution at;  // the run's rows at `times`; the run itself is freed once they are taken
  {
    const RunResult run = RunScene(scene, settings);
    if (!run.completed) {
      Throw<SolverError>("kneedyn score", "the reference configuration (", primary.value("command", ""),
                         ") failed when run again with output at the result's times: ", run.failure);
    }
    // The run again must be the stored reference: its sampling times against the stored samples.
    const Metrics check = Compare(ExtractSolution(scene, form, run, interval), reference);
    const double accuracy = extended ? kMinDenseReproductionScd : reference_json.value("accuracy_scd", 0.0);
    *reproduced_scd = check.scd;
    if (!(check.scd >= accuracy)) {
      Throw<SolverError>("kneedyn score", "the reference configuration (", primary.value("command", ""),
                         ") run again with output at the result's times reproduces the stored samples to ", check.scd,
                         " digits (rule: at least ", accuracy, extended ? " digits for the double configuration of an extended-precision reference" : " = the reference's accuracy_scd",
                         "); score at the reference's sampling times instead");
    }
    at = ExtractSolutionAt(scene, form, run, times);
  }
  // Merge: the stored samples at their times, the run's rows at `times` (moved, not copied),
  // in time order; the end event (stored) last.
  Solution dense;
  dense.end_is_event = reference.end_is_event;
  dense.names = reference.names;
  dense.events = reference.events;
  for (const auto& [c, rows] : reference.values) dense.values[c].reserve(rows.size() + at.times.size());
  dense.times.reserve(reference.times.size() + at.times.size());
  const size_t n_stored = reference.end_is_event ? reference.times.size() - 1 : reference.times.size();
  const size_t n_at = at.end_is_event ? at.times.size() - 1 : at.times.size();
  size_t i = 0, j = 0;
  const auto take_stored = [&](size_t k) {
    dense.times.push_back(reference.times[k]);
    for (const std::string& c : VariableClasses()) dense.values[c].push_back(reference.values.at(c)[k]);
  };
  const auto take_run = [&](size_t k) {
    dense.times.push_back(at.times[k]);
    for (const std::string& c : VariableClasses()) dense.values[c].push_back(std::move(at.values.at(c)[k]));
  };
  while (i < n_stored || j < n_at) {
    if (j >= n_at || (i < n_stored && reference.times[i] <= at.times[j])) {
      take_stored(i++);
    } else {
      take_run(j++);
    }
  }
  if (reference.end_is_event) take_stored(reference.times.size() - 1);
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

double PrintedEnergyError(const Scene& scene, const Solution& result) {
  const auto& positions = result.values.at("positions");    // x0, y0, z0 mm; flexion, valgus, rotation deg
  const auto& velocities = result.values.at("velocities");  // their rates, mm/s and deg/s
  EnergyDrift drift;
  for (size_t i = 0; i < result.times.size(); ++i) {
    if (i >= positions.size() || i >= velocities.size()) break;
    const std::vector<double>& p = positions[i];
    const std::vector<double>& v = velocities[i];
    if (p.size() != 6 || v.size() != 6 ||
        !std::all_of(p.begin(), p.end(), [](double x) { return std::isfinite(x); }) ||
        !std::all_of(v.begin(), v.end(), [](double x) { return std::isfinite(x); })) {
      if (i == 0) return kNaN;  // no E(0)
      continue;
    }
    Vector6d q, qd;
    for (int a = 0; a < 3; ++a) q(kX0 + a) = MmToM(p[a]), qd(kX0 + a) = MmToM(v[a]);
    q(kAlpha) = DegToRad(p[3]), q(kBeta) = DegToRad(p[4] + 90.0), q(kGamma) = DegToRad(p[5]);  // valgus = β − 90°
    qd(kAlpha) = DegToRad(v[3]), qd(kBeta) = DegToRad(v[4]), qd(kGamma) = DegToRad(v[5]);
    if (i == 0 && result.times[0] != 0.0) return kNaN;
    drift.Add(ComputeEnergies(scene.model, q, qd).mechanical);
  }
  return drift.Relative();
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
  const double ceiling_accuracy =
      ScoreCeilingAccuracy(reference_json, out.reproduced_scd, result.printed_significant_digits);
  if (std::isfinite(ceiling_accuracy)) ApplyScdCeiling(ceiling_accuracy, &out.score.metrics);
  // The conservative scene's energy error, as the work-precision sweep records it for kneedyn's
  // runs (null when the result gives no positions and velocities from t = 0).
  if (reference_json.value("conservative", false)) {
    const double energy_error = PrintedEnergyError(scene, result.solution);
    if (std::isfinite(energy_error)) out.score.metrics.energy_error = energy_error;
  }
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
  r["rows_after_reference_end"] = result.rows_after_reference_end;
  return r;
}

}  // namespace bench
}  // namespace kneedyn
