#include "ensembles/sweep.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <mutex>

#include "ensembles/parallel_runs.hpp"
#include "formulations/progress.hpp"
#include "formulations/run_output.hpp"  // ColumnSafeName: the trajectory's spelling of an element
#include "solver/dynamics.hpp"
#include "solver/error.hpp"
#include "solver/units.hpp"

namespace kneedyn::ensembles {

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

bool Wants(const SweepSpec& spec, const char* group) {
  return std::find(spec.outcome_groups.begin(), spec.outcome_groups.end(), group) != spec.outcome_groups.end();
}

// Ishigami & Homma (1990): f = sin x1 + a sin² x2 + b x3⁴ sin x1, a = 7, b = 0.1.
double Ishigami(const std::vector<double>& x) {
  return std::sin(x[0]) + 7.0 * std::sin(x[1]) * std::sin(x[1]) +
         0.1 * std::pow(x[2], 4) * std::sin(x[0]);
}

// Tensions of every element at a sample (on the branch the driver locked, if any).
std::vector<double> TensionsAt(const Model& model, const MechanicalState& s) {
  Data data(model);
  if (s.ligament_branch.size() == model.ligaments.size()) data.ligament_branch = &s.ligament_branch;
  ComputeAppliedWrench(model, s.t, PoseFromCoordinates(s.q), &data);
  return data.ligament_tension;
}

double NormalForce(const MechanicalState& s, int contact) {
  return contact >= 0 && s.IsActive(contact) ? s.contact[contact].normal_force : 0.0;
}

}  // namespace

std::vector<std::string> OutcomeColumns(const SweepSpec& spec) {
  std::vector<std::string> cols;
  if (spec.analytic != AnalyticModel::kNone) return {"value"};
  const Model& m = spec.base.model;
  auto per_element = [&](const std::string& prefix) {
    for (const Ligament& l : m.ligaments) cols.push_back(prefix + ColumnSafeName(l.name) + "_N");
  };
  auto per_contact = [&](const std::string& prefix) {  // the model's contact pairs, as trajectory.csv's N_<c>_N
    for (const ContactPair& pair : m.contacts) cols.push_back(prefix + CompartmentName(pair.compartment) + "_N");
  };
  // Fixed order, whatever the order in the spec.
  if (Wants(spec, "liftoff_time")) cols.push_back("liftoff_time_s");
  if (Wants(spec, "liftoff_flexion")) cols.push_back("liftoff_flexion_deg");
  if (Wants(spec, "peak_ligament_force")) per_element("peak_F_");
  if (Wants(spec, "peak_contact_force")) per_contact("peak_N_");
  if (Wants(spec, "time_at_90")) cols.push_back("time_90_s");
  if (Wants(spec, "ligament_force_at_90")) per_element("F90_");
  if (Wants(spec, "contact_force_at_90")) per_contact("N90_");
  return cols;
}

RunRow EvaluateRun(const SweepSpec& spec, long index, const std::vector<double>& unit_row) {
  std::vector<double> values;
  for (size_t k = 0; k < spec.parameters.size(); ++k) values.push_back(spec.parameters[k].FromUnit(unit_row[k]));
  return EvaluateRunAt(spec, index, values);
}

RunRow EvaluateRunAt(const SweepSpec& spec, long index, const std::vector<double>& values) {
  RunRow row;
  row.index = index;
  row.parameters = values;
  if (spec.analytic == AnalyticModel::kIshigami) {
    std::vector<double> x(3, 0.0);
    for (size_t k = 0; k < spec.parameters.size(); ++k) x[spec.parameters[k].axis] = row.parameters[k];
    row.outcomes = {Ishigami(x)};
    row.completed = true;
    row.end_reason = "analytic";
    return row;
  }
  const size_t n_out = OutcomeColumns(spec).size();
  row.outcomes.assign(n_out, kNaN);
  RunResult result;
  Scene scene;
  try {
    scene = SceneForRun(spec, row.parameters);
    result = RunScene(scene, spec.run);
  } catch (const std::exception& e) {
    row.completed = false;
    row.failure = e.what();
    return row;
  }
  row.completed = result.completed;
  row.failure = result.failure;
  row.end_reason = result.end_reason;
  row.steps = result.stats.steps;
  const Model& m = scene.model;
  const int n_contacts = static_cast<int>(m.contacts.size());

  // Outcomes from what was computed (a failed run still gives what it reached: a lift-off
  // before the failure is kept; peaks and 90° values of a failed run are NaN).
  const EventRecord* liftoff = nullptr;
  const EventRecord* at90 = nullptr;
  for (const EventRecord& e : result.events) {
    // A condyle's lift-off, as `kneedyn sensitivity` counts it: liftoff_patellar_* is the
    // patella leaving a trochlear facet, not the knee's lift-off.
    const bool condylar =
        e.name == LiftoffEventName(Compartment::kMedial) || e.name == LiftoffEventName(Compartment::kLateral);
    if (!liftoff && condylar) liftoff = &e;
    if (e.name == Flexion90EventName()) at90 = &e;
  }
  std::vector<double> peak_F(m.ligaments.size(), 0.0);
  std::vector<double> peak_N(m.contacts.size(), 0.0);
  for (const MechanicalState& s : result.samples) {
    const std::vector<double> F = TensionsAt(m, s);
    for (size_t j = 0; j < F.size(); ++j) peak_F[j] = std::max(peak_F[j], F[j]);
    for (int i = 0; i < n_contacts; ++i) peak_N[i] = std::max(peak_N[i], NormalForce(s, i));
  }
  size_t c = 0;
  auto put = [&](double v) { row.outcomes[c++] = v; };
  if (Wants(spec, "liftoff_time")) put(liftoff ? liftoff->time : kNaN);
  if (Wants(spec, "liftoff_flexion")) put(liftoff ? RadToDeg(liftoff->flexion) : kNaN);
  if (Wants(spec, "peak_ligament_force")) {
    for (double f : peak_F) put(row.completed ? f : kNaN);
  }
  if (Wants(spec, "peak_contact_force")) {
    for (double n : peak_N) put(row.completed ? n : kNaN);
  }
  const bool reached90 = row.completed && at90 && !result.samples.empty();
  const MechanicalState* s90 = reached90 ? &result.samples.back() : nullptr;
  if (Wants(spec, "time_at_90")) put(reached90 ? at90->time : kNaN);
  if (Wants(spec, "ligament_force_at_90")) {
    if (s90) {
      for (double f : TensionsAt(m, *s90)) put(f);
    } else {
      for (size_t j = 0; j < m.ligaments.size(); ++j) put(kNaN);
    }
  }
  if (Wants(spec, "contact_force_at_90")) {
    for (int i = 0; i < n_contacts; ++i) put(s90 ? NormalForce(*s90, i) : kNaN);
  }
  return row;
}

std::vector<long> ShardIndices(const SweepSpec& spec, long shard, long shards) {
  const long total = DesignRows(spec.design, static_cast<int>(spec.parameters.size()));
  std::vector<long> out;
  for (long i = shard; i < total; i += shards) {
    out.push_back(i);
    if (shards > total - i) break;  // i + shards would pass total (and could overflow a long)
  }
  return out;
}

std::function<void(const SweepProgress&)> TerminalProgress(const std::string& label) {
  return [label, last = std::chrono::steady_clock::now() - std::chrono::seconds(1)](const SweepProgress& p) mutable {
    const auto now = std::chrono::steady_clock::now();
    if (now - last < std::chrono::milliseconds(200) && p.done < p.total) return;
    last = now;
    const double rate = p.elapsed_s > 0 ? p.done / p.elapsed_s : 0.0;
    const double left = rate > 0 ? (p.total - p.done) / rate : 0.0;
    std::fprintf(stderr, "\r[%s] %ld/%ld runs (%ld failed)  %.1f runs/s  elapsed %s  time left %s   ", label.c_str(),
                 p.done, p.total, p.failed, rate, FormatDuration(p.elapsed_s).c_str(), FormatDuration(left).c_str());
  };
}

SweepTable RunSweep(const SweepSpec& spec, const std::vector<long>& indices, int threads,
                    const std::function<void(const SweepProgress&)>& progress) {
  const int d = static_cast<int>(spec.parameters.size());
  SweepTable table;
  table.fingerprint = spec.fingerprint;
  table.total_runs = DesignRows(spec.design, d);
  for (const ParameterSpec& p : spec.parameters) table.parameter_columns.push_back(p.column);
  table.outcome_columns = OutcomeColumns(spec);
  const std::vector<double> unit = DesignMatrix(spec.design, d);
  table.rows.resize(indices.size());

  EvaluateRowsInParallel(
      threads,
      [&](size_t k) {
        const long i = indices[k];
        const std::vector<double> u(unit.begin() + i * d, unit.begin() + (i + 1) * d);
        return EvaluateRun(spec, i, u);
      },
      progress, &table.rows);
  return table;
}

void EvaluateRowsInParallel(int threads, const std::function<RunRow(size_t)>& run_one,
                            const std::function<void(const SweepProgress&)>& progress, std::vector<RunRow>* rows) {
  std::mutex mutex;
  SweepProgress state;
  state.total = static_cast<long>(rows->size());
  const auto start = std::chrono::steady_clock::now();
  ForEachRunInParallel(rows->size(), threads, [&](size_t k) {
    (*rows)[k] = run_one(k);
    if (progress) {
      const std::lock_guard<std::mutex> lock(mutex);
      ++state.done;
      if (!(*rows)[k].completed) ++state.failed;
      state.elapsed_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      progress(state);
    }
  });
}

}  // namespace kneedyn::ensembles
