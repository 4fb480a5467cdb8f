#include "ensembles/sweep_output.hpp"

#include <nlohmann/json.hpp>

#include <cerrno>
#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <set>

#include "ensembles/sweep_io.hpp"
#include "scene/internal/json_field.hpp"
#include "scene/internal/yaml_field.hpp"
#include "solver/error.hpp"

namespace kneedyn::ensembles {

namespace fs = std::filesystem;

namespace {

std::string Number(double v) {
  if (std::isnan(v)) return "nan";
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.17g", v);
  return buf;
}

std::string Quoted(const std::string& s) {
  std::string out = "\"";
  for (char c : s) {
    if (c == '"') out += '"';
    out += (c == '\n' || c == '\r') ? ' ' : c;
  }
  return out + "\"";
}

void Publish(const std::string& tmp, const std::string& path) {
  std::error_code ec;
  fs::rename(tmp, path, ec);
  if (ec) Throw<Error>("WriteSweepResults", "cannot rename '", tmp, "' to '", path, "': ", ec.message());
}

// The table as CSV into `tmp` (not published).
void WriteCsv(const std::string& tmp, const SweepTable& table) {
  {
    std::ofstream out(tmp, std::ios::binary);
    if (!out) Throw<Error>("WriteCsv", "cannot write '", tmp, "'");
    out << "index";
    for (const std::string& c : table.parameter_columns) out << ',' << c;
    for (const std::string& c : table.outcome_columns) out << ',' << c;
    out << ",status,end_reason,steps,failure\n";
    for (const RunRow& r : table.rows) {
      out << r.index;
      for (double v : r.parameters) out << ',' << Number(v);
      for (double v : r.outcomes) out << ',' << Number(v);
      out << ',' << (r.completed ? "completed" : "failed") << ',' << r.end_reason << ',' << r.steps << ','
          << Quoted(r.failure) << '\n';
    }
    if (!out) Throw<Error>("WriteCsv", "write to '", tmp, "' failed: ", std::strerror(errno));
  }
}

// The HDF5 library is in the sweep I/O plugin (sweep_io_plugin.hpp): the table goes there as
// plain columns, into `tmp` (not published).
void WriteHdf5(const std::string& tmp, const SweepTable& table) {
  const KneedynSweepIo& io = SweepIo();  // throws InputError when the plugin is missing
  const size_t n = table.rows.size();
  std::vector<long long> index(n), steps(n);
  std::vector<const char*> status(n), end_reason(n), failure(n);
  for (size_t i = 0; i < n; ++i) {
    const RunRow& r = table.rows[i];
    index[i] = r.index;
    steps[i] = r.steps;
    status[i] = r.completed ? "completed" : "failed";
    end_reason[i] = r.end_reason.c_str();
    failure[i] = r.failure.c_str();
  }
  std::vector<std::vector<double>> values;
  auto columns = [&](const std::vector<std::string>& names, bool params) {
    std::vector<KneedynHdf5Column> cols;
    for (size_t k = 0; k < names.size(); ++k) {
      std::vector<double>& v = values.emplace_back(n);
      for (size_t i = 0; i < n; ++i) v[i] = params ? table.rows[i].parameters[k] : table.rows[i].outcomes[k];
      cols.push_back({names[k].c_str(), v.data()});
    }
    return cols;
  };
  values.reserve(table.parameter_columns.size() + table.outcome_columns.size());
  const std::vector<KneedynHdf5Column> parameters = columns(table.parameter_columns, true);
  const std::vector<KneedynHdf5Column> outcomes = columns(table.outcome_columns, false);
  const KneedynHdf5Table t{n,
                           index.data(),
                           parameters.data(),
                           parameters.size(),
                           outcomes.data(),
                           outcomes.size(),
                           status.data(),
                           end_reason.data(),
                           steps.data(),
                           failure.data()};
  char error[1024] = "";
  if (io.write_hdf5(tmp.c_str(), &t, error, sizeof error) != 0) Throw<Error>("WriteHdf5", error);
}

}  // namespace

void WriteSweepResults(const std::string& dir, const SweepTable& table) {
  SweepIo();  // a missing plugin (sweep.h5) is refused before anything is written
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) Throw<Error>("WriteSweepResults", "cannot create directory '", dir, "': ", ec.message());
  // Both files are written before either replaces an earlier sweep's: a failed write (a full
  // disk during sweep.h5) leaves the earlier pair as it was, never a new sweep.csv beside an
  // old sweep.h5.
  const std::string csv = (fs::path(dir) / "sweep.csv").string(), h5 = (fs::path(dir) / "sweep.h5").string();
  try {
    WriteCsv(csv + ".tmp", table);
    WriteHdf5(h5 + ".tmp", table);
  } catch (...) {
    for (const std::string& tmp : {csv + ".tmp", h5 + ".tmp"}) {
      if (fs::is_regular_file(tmp, ec)) fs::remove(tmp, ec);  // ours; not whatever else has the name
    }
    throw;
  }
  Publish(csv + ".tmp", csv);
  Publish(h5 + ".tmp", h5);
}

namespace {

nlohmann::json Nums(const std::vector<double>& v) {
  nlohmann::json a = nlohmann::json::array();
  for (double x : v) a.push_back(std::isnan(x) ? nlohmann::json(nullptr) : nlohmann::json(x));
  return a;
}

}  // namespace

void WritePart(const std::string& path, const SweepTable& table, long shard, long shards) {
  nlohmann::json j;
  j["kind"] = "kneedyn_sweep_part";
  j["fingerprint"] = std::to_string(table.fingerprint);
  j["total_runs"] = table.total_runs;
  j["shard"] = shard;
  j["shards"] = shards;
  j["parameter_columns"] = table.parameter_columns;
  j["outcome_columns"] = table.outcome_columns;
  nlohmann::json rows = nlohmann::json::array();
  for (const RunRow& r : table.rows) {
    rows.push_back({{"index", r.index}, {"parameters", Nums(r.parameters)}, {"outcomes", Nums(r.outcomes)},
                    {"completed", r.completed}, {"end_reason", r.end_reason}, {"steps", r.steps},
                    {"failure", r.failure}});
  }
  j["rows"] = rows;
  const fs::path parent = fs::path(path).parent_path();
  std::error_code ec;
  if (!parent.empty()) fs::create_directories(parent, ec);
  const std::string tmp = path + ".tmp";
  {
    std::ofstream out(tmp, std::ios::binary);
    if (!out) Throw<Error>("WritePart", "cannot write '", tmp, "'");
    out << j.dump() << '\n';  // shortest round-trip doubles
  }
  Publish(tmp, path);
}

SweepTable ReadPart(const std::string& path) {
  const std::string text = scene_detail::ReadInputFile(path, "part file", scene_detail::TableFileRule("ReadPart"));
  nlohmann::json j;
  try {
    j = scene_detail::ParseJsonDocument(text, "ReadPart", path);
  } catch (const nlohmann::json::exception& e) {
    Throw<InputError>("ReadPart", path, ": not a valid part file: ", e.what());
  }
  if (!j.is_object()) Throw<InputError>("ReadPart", path, ": not a kneedyn sweep part (not a JSON object)");
  const scene_detail::JsonFields read("ReadPart", path);
  if (read.String(j, "", "kind") != "kneedyn_sweep_part") {
    read.Fail("kind", " = " + read.Brief(j.at("kind")) + ": not a kneedyn sweep part");
  }
  // Only WritePart's fields: a hand-edited or foreign field is refused, not ignored.
  const auto only_fields = [&read](const nlohmann::json& object, const std::string& where,
                                   std::initializer_list<const char*> fields) {
    if (!object.is_object()) return;  // refused by the field reads below, naming it
    for (const auto& item : object.items()) {
      if (std::none_of(fields.begin(), fields.end(), [&](const char* f) { return item.key() == f; })) {
        std::string names;
        for (const char* f : fields) names += (names.empty() ? "" : ", ") + std::string(f);
        read.Fail(where + Echo(item.key()), ": not a field of a sweep part (its fields: " + names + ")");
      }
    }
  };
  only_fields(j, "", {"kind", "fingerprint", "total_runs", "shard", "shards", "parameter_columns", "outcome_columns", "rows"});
  SweepTable t;
  t.source = path;
  // The spec's 64-bit FNV-1a hash, as decimal digits (WritePart).
  const std::string fingerprint = read.String(j, "", "fingerprint");
  errno = 0;
  const unsigned long long value = std::strtoull(fingerprint.c_str(), nullptr, 10);
  if (fingerprint.empty() || fingerprint.size() > 20 || fingerprint.find_first_not_of("0123456789") != std::string::npos ||
      errno == ERANGE) {
    read.Fail("fingerprint", " = '" + Echo(fingerprint) + "': must be the spec's fingerprint, a decimal 64-bit number");
  }
  t.fingerprint = value;
  t.total_runs = read.Integer(j, "", "total_runs", 1, kMaxSweepRuns);
  // --shard i/n (WritePart writes both; a part without them is one of a single split, 0/1).
  // n may exceed the runs: some shards are empty.
  if (read.Find(j, "", "shard") != nullptr && read.Find(j, "", "shards") == nullptr) {
    read.Fail("shards", ": missing; a part that gives its shard gives the shard count too (--shard i/n)");
  }
  if (read.Find(j, "", "shards") != nullptr) t.shards = read.Integer(j, "", "shards", 1, kMaxSweepRuns);
  if (read.Find(j, "", "shard") != nullptr || t.shards > 1) t.shard = read.Integer(j, "", "shard", 0, t.shards - 1);
  t.parameter_columns = read.Strings(read.List(j, "", "parameter_columns"), "parameter_columns");
  t.outcome_columns = read.Strings(read.List(j, "", "outcome_columns"), "outcome_columns");
  const nlohmann::json& rows = read.List(j, "", "rows");
  for (size_t i = 0; i < rows.size(); ++i) {
    const std::string where = StrCat("rows[", i, "].");
    RunRow row;
    only_fields(rows[i], where, {"index", "parameters", "outcomes", "completed", "end_reason", "steps", "failure"});
    row.index = read.Integer(rows[i], where, "index", 0, t.total_runs - 1);
    if (row.index % t.shards != t.shard) {  // ShardIndices: shard i of n holds i, i + n, i + 2n, ...
      read.Fail(where + "index", StrCat(" = ", row.index, ": not a run of shard ", t.shard, " of ", t.shards,
                                        " (it holds the indices i with i mod ", t.shards, " = ", t.shard, ")"));
    }
    row.parameters = read.Numbers(read.At(rows[i], where, "parameters"), where + "parameters", t.parameter_columns.size());
    for (size_t k = 0; k < row.parameters.size(); ++k) {  // null is an unreached outcome's, never a parameter's
      if (std::isnan(row.parameters[k])) {
        read.Fail(StrCat(where, "parameters[", k, "]"), " = null: every run has a value of each parameter");
      }
    }
    row.outcomes = read.Numbers(read.At(rows[i], where, "outcomes"), where + "outcomes", t.outcome_columns.size());
    row.completed = read.Boolean(rows[i], where, "completed");
    row.end_reason = read.String(rows[i], where, "end_reason");
    row.steps = read.Integer(rows[i], where, "steps", 0, std::numeric_limits<long>::max());
    row.failure = read.String(rows[i], where, "failure");
    t.rows.push_back(std::move(row));
  }
  return t;
}

SweepTable MergeParts(const std::vector<SweepTable>& parts) {
  if (parts.empty()) Throw<InputError>("MergeParts", "no part files given");
  // parts[0]'s description without its rows (copying them to clear them held a part twice),
  // and room for every row at once.
  SweepTable all;
  all.fingerprint = parts[0].fingerprint;
  all.total_runs = parts[0].total_runs;
  all.parameter_columns = parts[0].parameter_columns;
  all.outcome_columns = parts[0].outcome_columns;
  size_t total_rows = 0;
  for (const SweepTable& t : parts) total_rows += t.rows.size();
  all.rows.reserve(total_rows);
  for (size_t p = 0; p < parts.size(); ++p) {
    const SweepTable& t = parts[p];
    // The first field that differs, with both values and both files.
    const auto differs = [&](const char* field, const std::string& here, const std::string& first) {
      Throw<InputError>("MergeParts", "part ", p + 1, " ('", EchoPath(t.source), "') comes from another sweep than part 1 ('",
                        EchoPath(parts[0].source), "'): field '", field, "' = ", here, " vs ", first,
                        " (the fingerprint covers the spec, scene and parameter-set files' bytes)");
    };
    const auto list = [](const std::vector<std::string>& v) { return nlohmann::json(v).dump(); };
    if (t.fingerprint != all.fingerprint) {
      differs("fingerprint", std::to_string(t.fingerprint), std::to_string(all.fingerprint));
    }
    if (t.total_runs != all.total_runs) differs("total_runs", std::to_string(t.total_runs), std::to_string(all.total_runs));
    if (t.parameter_columns != all.parameter_columns) {
      differs("parameter_columns", list(t.parameter_columns), list(all.parameter_columns));
    }
    if (t.outcome_columns != all.outcome_columns) differs("outcome_columns", list(t.outcome_columns), list(all.outcome_columns));
    all.rows.insert(all.rows.end(), t.rows.begin(), t.rows.end());
  }
  std::sort(all.rows.begin(), all.rows.end(), [](const RunRow& a, const RunRow& b) { return a.index < b.index; });
  // A run given twice, named with the parts that hold it (before: the first index past it,
  // which was not the duplicate, and no file).
  for (size_t i = 1; i < all.rows.size(); ++i) {
    if (all.rows[i].index != all.rows[i - 1].index) continue;
    const long index = all.rows[i].index;
    std::string holders;
    for (size_t p = 0; p < parts.size(); ++p) {
      for (const RunRow& r : parts[p].rows) {
        if (r.index != index) continue;
        holders += StrCat(holders.empty() ? "" : " and ", "part ", p + 1, " ('", EchoPath(parts[p].source), "')");
      }
    }
    Throw<InputError>("MergeParts", "run index ", index, " appears twice: in ", holders, " (", all.total_runs,
                      " runs expected)");
  }
  if (static_cast<long>(all.rows.size()) != all.total_runs) {
    // How many, the first few, and the shards to run again when every part is of one split.
    std::vector<long> missing;
    size_t k = 0;
    for (long i = 0; i < all.total_runs && missing.size() < 5; ++i) {
      if (k < all.rows.size() && all.rows[k].index == i) {
        ++k;
      } else {
        missing.push_back(i);
      }
    }
    std::string first;
    for (long i : missing) first += (first.empty() ? "" : ", ") + std::to_string(i);
    std::string shards;
    const bool one_split = std::all_of(parts.begin(), parts.end(), [&](const SweepTable& t) { return t.shards == parts[0].shards; });
    if (one_split && parts[0].shards > 1) {
      for (long s = 0; s < parts[0].shards; ++s) {
        if (std::none_of(parts.begin(), parts.end(), [s](const SweepTable& t) { return t.shard == s; })) {
          shards += StrCat(shards.empty() ? "" : ", ", "part-", s, "-of-", parts[0].shards, ".json");
        }
      }
    }
    Throw<InputError>("MergeParts", all.total_runs - static_cast<long>(all.rows.size()), " of ", all.total_runs,
                      " runs are missing (indices ", first, all.total_runs - static_cast<long>(all.rows.size()) > 5 ? ", ..." : "",
                      ")", shards.empty() ? "" : "; not given: " + shards + " (kneedyn sweep SPEC --shard i/n)");
  }
  return all;
}

namespace {

void PutBytes(std::string* out, const void* p, size_t n) { out->append(static_cast<const char*>(p), n); }
template <typename T>
void Put(std::string* out, T v) { PutBytes(out, &v, sizeof v); }
void PutString(std::string* out, const std::string& s) {
  Put<std::uint64_t>(out, s.size());
  out->append(s);
}
template <typename T>
T Get(const std::string& in, size_t* pos) {
  T v;
  if (*pos + sizeof v > in.size()) Throw<Error>("DeserializeRows", "truncated buffer");
  std::memcpy(&v, in.data() + *pos, sizeof v);
  *pos += sizeof v;
  return v;
}
std::string GetString(const std::string& in, size_t* pos) {
  const auto n = Get<std::uint64_t>(in, pos);
  if (*pos + n > in.size()) Throw<Error>("DeserializeRows", "truncated buffer");
  std::string s = in.substr(*pos, n);
  *pos += n;
  return s;
}

}  // namespace

std::string SerializeRows(const std::vector<RunRow>& rows) {
  std::string out;
  Put<std::uint64_t>(&out, rows.size());
  for (const RunRow& r : rows) {
    Put<std::int64_t>(&out, r.index);
    Put<std::uint64_t>(&out, r.parameters.size());
    for (double v : r.parameters) Put(&out, v);
    Put<std::uint64_t>(&out, r.outcomes.size());
    for (double v : r.outcomes) Put(&out, v);
    Put<std::uint8_t>(&out, r.completed ? 1 : 0);
    PutString(&out, r.end_reason);
    Put<std::int64_t>(&out, r.steps);
    PutString(&out, r.failure);
  }
  return out;
}

std::vector<RunRow> DeserializeRows(const std::string& bytes) {
  size_t pos = 0;
  std::vector<RunRow> rows(Get<std::uint64_t>(bytes, &pos));
  for (RunRow& r : rows) {
    r.index = Get<std::int64_t>(bytes, &pos);
    r.parameters.resize(Get<std::uint64_t>(bytes, &pos));
    for (double& v : r.parameters) v = Get<double>(bytes, &pos);
    r.outcomes.resize(Get<std::uint64_t>(bytes, &pos));
    for (double& v : r.outcomes) v = Get<double>(bytes, &pos);
    r.completed = Get<std::uint8_t>(bytes, &pos) != 0;
    r.end_reason = GetString(bytes, &pos);
    r.steps = Get<std::int64_t>(bytes, &pos);
    r.failure = GetString(bytes, &pos);
  }
  return rows;
}

}  // namespace kneedyn::ensembles
