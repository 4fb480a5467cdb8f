#include "ensembles/batch.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <fstream>
#include <sstream>
#include <string_view>

#include "scene/internal/csv_fields.hpp"
#include "scene/internal/yaml_field.hpp"
#include "solver/error.hpp"

namespace kneedyn::ensembles {

namespace {

std::string Trim(const std::string& s) {
  const size_t a = s.find_first_not_of(" \t\r");
  if (a == std::string::npos) return "";
  const size_t b = s.find_last_not_of(" \t\r");
  return s.substr(a, b - a + 1);
}

std::string_view TrimView(std::string_view s) {
  const size_t a = s.find_first_not_of(" \t\r");
  if (a == std::string_view::npos) return {};
  const size_t b = s.find_last_not_of(" \t\r");
  return s.substr(a, b - a + 1);
}

using scene_detail::CsvFieldCount;    // fields counted before anything is split,
using scene_detail::ForEachCsvField;  // then split into views (scene/internal/csv_fields.hpp)

// Shortest round-trip form.
void AppendNumber(std::string* out, double v) {
  if (std::isnan(v)) {
    *out += "nan";
    return;
  }
  char buf[32];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);
  out->append(buf, r.ptr);
}

void AppendText(std::string* out, const std::string& s) {
  if (s.find_first_of(",\"\n") == std::string::npos) {
    *out += s;
    return;
  }
  *out += '"';
  for (char c : s) {
    if (c == '"') *out += '"';
    *out += c == '\n' ? ' ' : c;
  }
  *out += '"';
}

}  // namespace

BatchVariants ParseBatchVariants(const std::string& text, const std::string& label, const Model& base) {
  BatchVariants v;
  v.path = label;
  std::stringstream in(std::string(scene_detail::WithoutByteOrderMark(text)));
  std::string line;
  long line_no = 0;
  bool header = false;
  while (std::getline(in, line)) {
    ++line_no;
    const std::string t = Trim(line);
    if (t.empty() || t[0] == '#') continue;
    if (!header) {
      header = true;
      // Each header cell is checked as it is split: the first bad one is refused before the
      // rest of the line is looked at.
      ForEachCsvField(t, [&](size_t c, std::string_view cell) {
        cell = TrimView(cell);
        if (cell.empty()) {
          Throw<InputError>("LoadBatchVariants", label, ": line ", line_no, ", column ", c + 1,
                            ": empty parameter name in the header");
        }
        const std::string name(cell);
        ParameterSpec p = ResolveParameterName(base, name, label + ": line " + std::to_string(line_no));
        for (const ParameterSpec& q : v.parameters) {
          if (q.column == p.column) {
            Throw<InputError>("LoadBatchVariants", label, ": line ", line_no, ": parameter '", Echo(name),
                              "' listed twice");
          }
        }
        v.parameters.push_back(p);
      });
      if (const std::string why = ParametersThatCannotVaryTogether(v.parameters); !why.empty()) {
        Throw<InputError>("LoadBatchVariants", label, ": line ", line_no, ": ", why);
      }
      continue;
    }
    const size_t fields = CsvFieldCount(t);
    if (fields != v.parameters.size()) {
      Throw<InputError>("LoadBatchVariants", label, ": line ", line_no, ": ", fields, " values, the header names ",
                        v.parameters.size(), " parameters");
    }
    std::vector<double> row(fields);
    ForEachCsvField(t, [&](size_t c, std::string_view f) {
      f = TrimView(f);
      const auto r = std::from_chars(f.data(), f.data() + f.size(), row[c]);
      if (f.empty() || r.ec != std::errc() || r.ptr != f.data() + f.size() || !std::isfinite(row[c])) {
        Throw<InputError>("LoadBatchVariants", label, ": line ", line_no, ", column '", v.parameters[c].name,
                          "' = '", Echo(std::string(f)), "': not a finite number");
      }
      if (const ParameterRange range = RangeOf(v.parameters[c].kind); !range.Contains(row[c])) {
        Throw<InputError>("LoadBatchVariants", label, ": line ", line_no, ", column '", v.parameters[c].name,
                          "' = '", Echo(std::string(f)), "': must lie in ", range.Describe(), " (the scene's range)");
      }
    });
    v.rows.push_back(std::move(row));
  }
  if (!header) Throw<InputError>("LoadBatchVariants", label, ": no header line naming the parameters");
  if (v.rows.empty()) Throw<InputError>("LoadBatchVariants", label, ": no variant rows after the header");
  return v;
}

BatchVariants LoadBatchVariants(const std::string& path, const Model& base) {
  const std::string text =
      scene_detail::ReadInputFile(path, "variants file", scene_detail::TableFileRule("LoadBatchVariants"));
  return ParseBatchVariants(text, path, base);
}

Batch::Batch(Scene base, RunSettings run, std::vector<std::string> outcome_groups) {
  for (const std::string& g : outcome_groups) {
    if (OutcomeGroups().count(g) == 0) {
      Throw<InputError>("kneedyn batch", "--outcomes: unknown outcome '", g,
                        "'; expected liftoff_time, liftoff_flexion, peak_ligament_force, peak_contact_force, "
                        "time_at_90, ligament_force_at_90, contact_force_at_90");
    }
    if (std::count(outcome_groups.begin(), outcome_groups.end(), g) > 1) {  // as a sweep spec refuses it
      Throw<InputError>("kneedyn batch", "--outcomes: outcome '", g, "' listed twice");
    }
    if (const std::string why = OutcomeGroupEmptyFor(base.model, g); !why.empty()) {
      Throw<InputError>("kneedyn batch", "--outcomes: outcome '", g, "': ", why);
    }
  }
  CreateFormulation(run.formulation, base, run.options);  // checks the options (ValidateOptions)
  spec_.path = "kneedyn batch";
  spec_.scene_path = base.path;
  spec_.base = std::move(base);
  spec_.outcome_groups = std::move(outcome_groups);
  spec_.run = std::move(run);
  outcome_columns_ = OutcomeColumns(spec_);
}

RunRow Batch::Run(const std::vector<ParameterSpec>& parameters, const std::vector<double>& values, long index) {
  spec_.parameters = parameters;
  return EvaluateRunAt(spec_, index, values);
}

SweepTable Batch::RunAll(const BatchVariants& variants, int threads,
                         const std::function<void(const SweepProgress&)>& progress) {
  spec_.parameters = variants.parameters;
  SweepTable table;
  table.total_runs = static_cast<long>(variants.rows.size());
  for (const ParameterSpec& p : variants.parameters) table.parameter_columns.push_back(p.column);
  table.outcome_columns = outcome_columns_;
  table.rows.resize(variants.rows.size());
  EvaluateRowsInParallel(
      threads, [&](size_t k) { return EvaluateRunAt(spec_, static_cast<long>(k), variants.rows[k]); }, progress,
      &table.rows);
  return table;
}

std::string FormatBatchCsv(const SweepTable& table) {
  std::string out = "index";
  for (const std::string& c : table.parameter_columns) out += "," + c;
  for (const std::string& c : table.outcome_columns) out += "," + c;
  out += ",status,end_reason,steps,failure\n";
  out.reserve(out.size() * (table.rows.size() + 1) * 2);
  char buf[32];
  for (const RunRow& r : table.rows) {
    out.append(buf, std::to_chars(buf, buf + sizeof buf, r.index).ptr);
    for (double v : r.parameters) {
      out += ',';
      AppendNumber(&out, v);
    }
    for (double v : r.outcomes) {
      out += ',';
      AppendNumber(&out, v);
    }
    out += r.completed ? ",completed," : ",failed,";
    AppendText(&out, r.end_reason);
    out += ',';
    out.append(buf, std::to_chars(buf, buf + sizeof buf, r.steps).ptr);
    out += ',';
    AppendText(&out, r.failure);
    out += '\n';
  }
  return out;
}

}  // namespace kneedyn::ensembles
