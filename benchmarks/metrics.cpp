#include "benchmarks/metrics.hpp"

#include <Eigen/Core>
#include <algorithm>
#include <ceres/version.h>
#include <cmath>
#include <cstdio>
#include <limits>
#include <set>
#include <sundials/sundials_config.h>
#include <unordered_map>

#include "formulations/simulator.hpp"
#include "scene/internal/json_field.hpp"
#include "solver/error.hpp"
#include "solver/observables.hpp"
#include "solver/units.hpp"

namespace kneedyn {
namespace bench {

namespace {

constexpr double kTimeMatch = 1e-9;  // s
const double kNaN = std::numeric_limits<double>::quiet_NaN();

// Row of every class at one sample (solver/observables.hpp).
void AppendRow(const Scene& scene, ContactForm form, const MechanicalState& st, Solution* s) {
  const Vector6d& q = st.q;
  const Vector6d& qd = st.qd;
  Observables obs;
  ComputeObservables(scene.model, st,
                     form == ContactForm::kClosedForm ? ContactPointSource::kPose
                                                      : ContactPointSource::kStateCoordinates,
                     &obs);
  const JointObservables& j = obs.joint;
  s->values["positions"].push_back({MToMm(q(kX0)), MToMm(q(kY0)), MToMm(q(kZ0)), j.flexion_deg,
                                    j.valgus_deg, j.external_rotation_deg});
  s->values["velocities"].push_back({MToMm(qd(kX0)), MToMm(qd(kY0)), MToMm(qd(kZ0)),
                                     j.flexion_rate_deg_s, j.valgus_rate_deg_s,
                                     j.external_rotation_rate_deg_s});
  std::vector<double> points, forces, tensions;
  for (const ContactObservables& c : obs.contacts) {  // NaN where no point (separated)
    for (int a = 0; a < 3; ++a) points.push_back(MToMm(c.point_F(a)));
    for (int a = 0; a < 3; ++a) points.push_back(MToMm(c.point_T(a)));
    forces.push_back(c.normal_force);
  }
  for (const LigamentObservables& l : obs.ligaments) tensions.push_back(l.tension);
  s->values["contact_points"].push_back(points);
  s->values["contact_forces"].push_back(forces);
  s->values["ligament_forces"].push_back(tensions);
}

nlohmann::json Finite(double v) {
  return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr);
}

}  // namespace

const std::vector<std::string>& VariableClasses() {
  static const std::vector<std::string> kClasses = {
      "positions", "velocities", "contact_points", "contact_forces", "ligament_forces"};
  return kClasses;
}

namespace {

// The solution of `result` at the samples `keep` accepts (by index), plus the end event's
// state (metrics.hpp).
template <typename Keep>
Solution Extract(const Scene& scene, ContactForm form, const RunResult& result, Keep keep) {
  const Model& model = scene.model;
  Solution s;
  s.names["positions"] = {"x0_mm", "y0_mm", "z0_mm", "flexion_deg", "valgus_deg",
                          "external_rotation_deg"};
  s.names["velocities"] = {"vx_mm_s", "vy_mm_s", "vz_mm_s", "flexion_rate_deg_s",
                           "valgus_rate_deg_s", "external_rotation_rate_deg_s"};
  for (const ContactPair& pair : model.contacts) {
    for (const char* frame : {"femoral", "tibial"}) {
      for (const char* axis : {"x", "y", "z"}) {
        s.names["contact_points"].push_back(
            StrCat(frame, "_", CompartmentName(pair.compartment), "_", axis, "_mm"));
      }
    }
    s.names["contact_forces"].push_back(StrCat("N_", CompartmentName(pair.compartment), "_N"));
  }
  for (const Ligament& lig : model.ligaments) s.names["ligament_forces"].push_back("F_" + lig.name + "_N");
  for (const std::string& c : VariableClasses()) s.values[c];  // present even when empty

  const bool ended_on_event = result.completed && !result.samples.empty() &&
                              result.sample_is_event.back() && result.end_reason != "end_time";
  const size_t n_sampling = result.samples.size() - (ended_on_event ? 1 : 0);
  for (size_t k = 0; k < n_sampling; ++k) {
    if (!keep(k)) continue;
    s.times.push_back(result.samples[k].t);
    AppendRow(scene, form, result.samples[k], &s);
  }
  if (ended_on_event) {
    s.times.push_back(result.samples.back().t);
    AppendRow(scene, form, result.samples.back(), &s);
    s.end_is_event = true;
  }
  s.events = result.events;
  return s;
}

}  // namespace

Solution ExtractSolution(const Scene& scene, ContactForm form, const RunResult& result,
                         double interval) {
  if (!(interval > 0.0)) {
    Throw<InputError>("ExtractSolution", "comparison interval = ", interval, " s; must be > 0");
  }
  return Extract(scene, form, result, [&result, interval](size_t k) {
    const double t = result.samples[k].t;
    return !result.sample_is_event[k] && std::abs(t - std::round(t / interval) * interval) <= kTimeMatch;
  });
}

Solution ExtractSolutionAt(const Scene& scene, ContactForm form, const RunResult& result,
                           const std::vector<double>& times) {
  // One sample per time: the one at it, or the output or event sample the simulator merged it
  // with (kOutputTimeMerge), the nearest when two are that close. Not every sample within
  // kTimeMatch: a time 1e-11 s after a uniform output has a sample of its own beside that one.
  const std::vector<MechanicalState>& samples = result.samples;
  std::vector<bool> chosen(samples.size(), false);
  size_t first = 0;  // the first sample not more than kOutputTimeMerge before t
  for (const double t : times) {
    while (first < samples.size() && samples[first].t < t - kOutputTimeMerge) ++first;
    size_t nearest = samples.size();
    for (size_t k = first; k < samples.size() && samples[k].t <= t + kOutputTimeMerge; ++k) {
      if (nearest == samples.size() || std::abs(samples[k].t - t) < std::abs(samples[nearest].t - t)) nearest = k;
    }
    if (nearest < samples.size()) chosen[nearest] = true;
  }
  return Extract(scene, form, result, [&chosen](size_t k) { return bool(chosen[k]); });
}

double ScdFromErrors(const std::vector<double>& x, const std::vector<double>& x_ref,
                     const std::vector<double>& floors) {
  if (x.size() != x_ref.size() || x.size() != floors.size()) {
    Throw<InputError>("ScdFromErrors", "sizes ", x.size(), ", ", x_ref.size(), ", ", floors.size(),
                      "; must be equal");
  }
  double worst = 0.0;
  for (size_t j = 0; j < x.size(); ++j) {
    if (std::isnan(x[j]) || std::isnan(x_ref[j])) continue;
    worst = std::max(worst, std::abs(x[j] - x_ref[j]) / (std::abs(x_ref[j]) + floors[j]));
  }
  return -std::log10(worst);  // +inf for an exact match
}

double MixedError(const std::vector<double>& x, const std::vector<double>& x_ref) {
  if (x.size() != x_ref.size()) {
    Throw<InputError>("MixedError", "sizes ", x.size(), " and ", x_ref.size(), "; must be equal");
  }
  double worst = 0.0;
  for (size_t j = 0; j < x.size(); ++j) {
    if (std::isnan(x[j]) || std::isnan(x_ref[j])) continue;
    worst = std::max(worst, std::abs(x[j] - x_ref[j]) / (1.0 + std::abs(x_ref[j])));
  }
  return worst;
}

Metrics Compare(const Solution& run, const Solution& reference) {
  Metrics m;
  // Pairs (run row, reference row) to compare.
  std::vector<std::pair<size_t, size_t>> pairs;
  const size_t n_ref_uniform = reference.times.size() - (reference.end_is_event ? 1 : 0);
  const size_t n_run_uniform = run.times.size() - (run.end_is_event ? 1 : 0);
  // Each reference time is paired with the first run row within kTimeMatch of it. Both lists
  // are sorted (every Solution kneedyn builds or reads is), so the first candidate row only
  // moves forward: one merge pass, O(n_ref + n_run) (before, a scan from the first row for
  // every reference time: 400k result rows took 56 s). fl(a − t) is monotone in a and in t,
  // so the row found is the one the scan from the start finds. Times that are not finite and
  // non-decreasing (no Solution kneedyn builds) keep that scan.
  const auto sorted = [](const std::vector<double>& t, size_t n) {
    for (size_t k = 0; k < n; ++k) {
      if (!std::isfinite(t[k]) || (k > 0 && !(t[k] >= t[k - 1]))) return false;
    }
    return true;
  };
  const bool merge = sorted(run.times, n_run_uniform) && sorted(reference.times, n_ref_uniform);
  size_t first = 0;  // merge: the first run row not more than kTimeMatch before reference.times[i]
  for (size_t i = 0; i < n_ref_uniform; ++i) {
    size_t k = 0;
    if (merge) {
      while (first < n_run_uniform && run.times[first] - reference.times[i] < -kTimeMatch) ++first;
      k = first < n_run_uniform && run.times[first] - reference.times[i] <= kTimeMatch ? first : n_run_uniform;
    } else {
      while (k < n_run_uniform && std::abs(run.times[k] - reference.times[i]) > kTimeMatch) ++k;
    }
    if (k < n_run_uniform) {
      pairs.push_back({k, i});
    } else {
      ++m.missing_times;
    }
  }
  if (reference.end_is_event) {
    if (run.end_is_event) {
      pairs.push_back({run.times.size() - 1, reference.times.size() - 1});
    } else {
      ++m.missing_times;
    }
  }
  m.compared_times = static_cast<int>(pairs.size());

  double worst_scd = std::numeric_limits<double>::infinity();
  const std::vector<double> floors = {kScdFloorMm, kScdFloorMm, kScdFloorMm,
                                      kScdFloorDeg, kScdFloorDeg, kScdFloorDeg};
  bool positions_compared = false;
  for (const std::string& c : VariableClasses()) {
    double mixed = 0.0;
    bool compared = false;  // some component has a value in both at some time (else no figure, not "exact")
    const auto& rv = run.values.at(c);
    const auto& fv = reference.values.at(c);
    for (const auto& [k, i] : pairs) {
      mixed = std::max(mixed, MixedError(rv[k], fv[i]));
      for (size_t j = 0; j < rv[k].size() && j < fv[i].size() && !compared; ++j) {
        compared = !std::isnan(rv[k][j]) && !std::isnan(fv[i][j]);
      }
      if (c == "positions") {
        worst_scd = std::min(worst_scd, ScdFromErrors(rv[k], fv[i], floors));
      }
    }
    m.mixed[c] = compared ? mixed : kNaN;
    if (c == "positions") positions_compared = compared;
  }
  // A run that misses comparison times (it failed) has no scd; its mixed errors cover
  // the times it has.
  m.scd = !positions_compared || m.missing_times > 0 ? kNaN : worst_scd;
  m.scd_compared = !positions_compared ? kNaN : worst_scd;

  // The run's first event of each name, through a hash map (before, a scan of the run's
  // events per reference event: O(R × E)).
  std::unordered_map<std::string, const EventRecord*> first_of_name;
  first_of_name.reserve(run.events.size());
  for (const EventRecord& r : run.events) first_of_name.emplace(r.name, &r);  // keeps the first
  for (const EventRecord& e : reference.events) {
    if (m.event_time.count(e.name)) continue;  // first occurrence only
    const auto found = first_of_name.find(e.name);
    const EventRecord* it = found == first_of_name.end() ? nullptr : found->second;
    m.event_time[e.name] = it == nullptr ? kNaN : std::abs(it->time - e.time);
    m.event_angle[e.name] = it == nullptr ? kNaN : RadToDeg(std::abs(it->flexion - e.flexion));
  }
  return m;
}

void EnergyDrift::Add(double mechanical_energy_J) {
  if (!started_) {
    started_ = true;
    initial_J_ = mechanical_energy_J;
  }
  worst_J_ = std::max(worst_J_, std::abs(mechanical_energy_J - initial_J_));
}

double EnergyDrift::Relative() const {
  return std::isfinite(initial_J_) && initial_J_ != 0.0 ? worst_J_ / std::abs(initial_J_) : kNaN;
}

double EnergyError(const Scene& scene, const RunResult& result) {
  EnergyDrift drift;
  for (const MechanicalState& s : result.samples) drift.Add(ComputeEnergies(scene.model, s.q, s.qd).mechanical);
  return drift.Relative();
}

void AddRunMetrics(const Scene& scene, const RunResult& result, bool conservative, Metrics* m) {
  m->max_position_residual = result.max_position_residual;
  m->max_velocity_residual = result.max_velocity_residual;
  if (conservative) m->energy_error = EnergyError(scene, result);
}

nlohmann::json SolutionJson(const Solution& s) {
  nlohmann::json j;
  j["times_s"] = s.times;
  j["end_is_event"] = s.end_is_event;
  for (const std::string& c : VariableClasses()) {
    nlohmann::json rows = nlohmann::json::array();
    for (const auto& row : s.values.at(c)) {
      nlohmann::json r = nlohmann::json::array();
      for (double v : row) r.push_back(Finite(v));
      rows.push_back(r);
    }
    j["classes"][c] = {{"names", s.names.at(c)}, {"values", rows}};
  }
  j["events"] = nlohmann::json::array();
  for (const EventRecord& e : s.events) {
    j["events"].push_back({{"name", e.name}, {"time_s", e.time}, {"flexion_deg", RadToDeg(e.flexion)}});
  }
  return j;
}

Solution SolutionFromJson(const nlohmann::json& j, const std::string& document) {
  const scene_detail::JsonFields read("SolutionFromJson", document);
  const std::string top = "solution.";
  Solution s;
  const nlohmann::json& times = read.List(j, top, "times_s");
  s.times = read.Numbers(times, top + "times_s");
  if (s.times.size() < 2) {
    read.Fail(top + "times_s", StrCat(": must hold at least 2 sample times (it has ", s.times.size(), ")"));
  }
  for (size_t i = 0; i < s.times.size(); ++i) {
    if (!std::isfinite(s.times[i]) || (i > 0 && !(s.times[i] > s.times[i - 1]))) {
      read.Fail(StrCat(top, "times_s[", i, "]"), StrCat(" = ", s.times[i], ": sample times must be finite and increasing"));
    }
  }
  s.end_is_event = read.Boolean(j, top, "end_is_event");
  const nlohmann::json& classes = read.At(j, top, "classes");
  for (const std::string& c : VariableClasses()) {
    const std::string where = top + "classes." + c + ".";
    const nlohmann::json& jc = read.At(classes, top + "classes.", c.c_str());
    s.names[c] = read.Strings(read.List(jc, where, "names"), where + "names");
    const nlohmann::json& rows = read.List(jc, where, "values");
    if (rows.size() != s.times.size()) {
      read.Fail(where + "values", StrCat(": must hold one row per sample time (", s.times.size(), "), not ", rows.size()));
    }
    auto& values = s.values[c];
    for (size_t r = 0; r < rows.size(); ++r) {
      values.push_back(read.Numbers(rows[r], StrCat(where, "values[", r, "]"), s.names[c].size()));
    }
  }
  const nlohmann::json& events = read.List(j, top, "events");
  for (size_t i = 0; i < events.size(); ++i) {
    const std::string where = StrCat(top, "events[", i, "].");
    s.events.push_back({read.String(events[i], where, "name"), read.Number(events[i], where, "time_s"),
                        DegToRad(read.Number(events[i], where, "flexion_deg"))});
  }
  return s;
}

void ApplyScdCeiling(double reference_accuracy_scd, Metrics* m) {
  m->scd_ceiling = reference_accuracy_scd - kScdCeilingMargin;
  m->scd_above_ceiling = std::isfinite(m->scd_ceiling) && !std::isnan(m->scd) && m->scd > m->scd_ceiling;
}

std::string WrongEventReason(const Metrics& m, const std::vector<EventRecord>& run_events) {
  std::string missing, late;
  double late_by = 0.0;
  for (const auto& [name, error_s] : m.event_time) {
    if (!std::isfinite(error_s)) {
      missing += (missing.empty() ? "" : ", ") + name;
    } else if (error_s > kWrongEventTimeS && error_s > late_by) {
      late = name;
      late_by = error_s;
    }
  }
  if (!missing.empty()) return "wrong events: reference event(s) " + missing + " missing";
  if (!late.empty()) {
    char ms[32];
    std::snprintf(ms, sizeof(ms), "%.1f", late_by * 1e3);
    return "wrong event time: " + late + " off by " + ms + " ms";
  }
  if (m.event_time.empty()) return "";
  std::set<std::string> extra;  // sorted, each once
  for (const EventRecord& e : run_events) {
    if (e.name.compare(0, 5, "kink_") != 0 && e.name != "flexion_90" && !m.event_time.count(e.name)) extra.insert(e.name);
  }
  if (extra.empty()) return "";
  std::string names;
  for (const std::string& n : extra) names += (names.empty() ? "" : ", ") + n;
  return "wrong events: " + names + " not in the reference";
}

nlohmann::json MetricsJson(const Metrics& m) {
  nlohmann::json j;
  j["scd"] = Finite(m.scd);
  j["scd_compared"] = Finite(m.scd_compared);
  for (const auto& [c, v] : m.mixed) j["mixed_error"][c] = Finite(v);
  for (const auto& [e, v] : m.event_time) j["event_time_error_s"][e] = Finite(v);
  for (const auto& [e, v] : m.event_angle) j["event_angle_error_deg"][e] = Finite(v);
  j["max_position_residual_m"] = Finite(m.max_position_residual);
  j["max_velocity_residual_m_s"] = Finite(m.max_velocity_residual);
  j["energy_error"] = m.energy_error < 0.0 ? nlohmann::json(nullptr) : Finite(m.energy_error);
  j["compared_times"] = m.compared_times;
  j["missing_times"] = m.missing_times;
  j["scd_ceiling"] = Finite(m.scd_ceiling);
  j["scd_above_ceiling"] = m.scd_above_ceiling;
  // scd is +inf, written null, when every compared position equals the reference's.
  j["scd_exact"] = m.scd == std::numeric_limits<double>::infinity();
  return j;
}

nlohmann::json LibraryVersionsJson() {
  return {{"sundials", SUNDIALS_VERSION},
          {"ceres", CERES_VERSION_STRING},
          {"eigen", StrCat(EIGEN_WORLD_VERSION, ".", EIGEN_MAJOR_VERSION, ".", EIGEN_MINOR_VERSION)}};
}

}  // namespace bench
}  // namespace kneedyn
