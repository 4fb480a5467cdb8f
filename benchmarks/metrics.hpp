// Accuracy metrics of a run against a reference solution, in one place
// (benchmarks/README.md, "Metrics").
//
// A Solution holds a run's values at fixed comparison times (multiples of a comparison
// interval, e.g. 0.02 s, plus the state of the end event) in five variable classes, in
// the user units of trajectory.csv:
//   positions        x0, y0, z0 [mm], flexion, valgus, external rotation [deg]
//   velocities       their rates [mm/s, deg/s]
//   contact_points   femoral and tibial contact points, per active contact [mm]
//                    (chapter coordinates for ContactForm::kChapter, closed-form
//                    sphere-on-plane points from q for kClosedForm)
//   contact_forces   N per contact [N] (0 when separated)
//   ligament_forces  F_j per element [N]
// A value is NaN where it does not exist (contact point of a separated contact); NaN in
// either solution skips the entry.
//
// Formulas (e = x − x_ref, over all comparison times i and components j of a class):
//   scd   = −log10( max_ij |e_ij| / (|x_ref,ij| + floor_j) )        positions only;
//           NaN (null in JSON) when the run lacks a comparison time (failed run, or a
//           run that reached the end event early); scd_compared: over the times it has
//           (IVP Test Set: significant correct digits). floor_j keeps near-zero
//           components from dominating: kScdFloorMm = 1 mm for x0, y0, z0 and
//           kScdFloorDeg = 1 deg for the angles — an absolute error of 1e-k mm or deg
//           on a near-zero component counts as k digits.
//   mixed = max_ij |e_ij| / (1 + |x_ref,ij|)                          per class
//   event errors: |t − t_ref| [s] and |α − α_ref| [deg] per reference event name (first
//           occurrence); NaN when the run does not have the event.
//   residuals: RunResult.max_position_residual [m], max_velocity_residual [m/s].
//   energy: max_i |E(t_i) − E(0)| / |E(0)| over all samples (mechanical energy of
//           solver/observables.hpp), meaningful on conservative scenes only.
//   ceiling: scd_ceiling = the reference's accuracy_scd − 1; scd_above_ceiling flags an scd
//           the reference cannot measure (ApplyScdCeiling).
// Every per-state quantity comes from solver/observables.hpp (ComputeObservables), like
// trajectory.csv's columns.
#pragma once

#include <limits>
#include <map>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "formulations/run.hpp"

namespace kneedyn {
namespace bench {

constexpr double kScdFloorMm = 1.0;   // mm, x0 y0 z0
constexpr double kScdFloorDeg = 1.0;  // deg, α β γ
constexpr double kDefaultComparisonInterval = 0.02;  // s

// Class names, in report order.
const std::vector<std::string>& VariableClasses();

struct Solution {
  std::vector<double> times;  // s; the last one is the end state when end_is_event
  bool end_is_event = false;
  // Per class: names of the components and values[i][j] at times[i].
  std::map<std::string, std::vector<std::string>> names;
  std::map<std::string, std::vector<std::vector<double>>> values;
  std::vector<EventRecord> events;
};

// Values of `result` at the uniform output times that are multiples of `interval`
// (within 1e-9 s) plus, when the run ended on an event, the last sample.
Solution ExtractSolution(const Scene& scene, ContactForm form, const RunResult& result,
                         double interval = kDefaultComparisonInterval);

// Values of `result` at `times` (increasing), one row each: the sample at that time, or the
// output or event sample within kOutputTimeMerge (formulations/simulator.hpp) that the
// simulator gave it; plus the end event's state like ExtractSolution.
Solution ExtractSolutionAt(const Scene& scene, ContactForm form, const RunResult& result,
                           const std::vector<double>& times);

struct Metrics {
  double scd = 0.0;                          // digits; +inf for an exact match; NaN: times missing
  double scd_compared = 0.0;                 // the same over the times compared only
  std::map<std::string, double> mixed;       // per class
  std::map<std::string, double> event_time;  // s, per reference event name
  std::map<std::string, double> event_angle; // deg
  double max_position_residual = 0.0;        // m
  double max_velocity_residual = 0.0;        // m/s
  double energy_error = -1.0;                // relative; < 0: not computed
  int compared_times = 0;                    // comparison times found in both
  int missing_times = 0;                     // reference times the run lacks (failure)
  // The highest scd the reference can measure: its accuracy_scd − 1 (kScdCeilingMargin);
  // NaN when the reference states none. scd above it is flagged, not a result: the error
  // measured there is the reference's own.
  double scd_ceiling = std::numeric_limits<double>::quiet_NaN();
  bool scd_above_ceiling = false;
};

// Digits kept between a reference's stated accuracy and the highest scd it scores.
constexpr double kScdCeilingMargin = 1.0;
// Sets m->scd_ceiling = reference_accuracy_scd − kScdCeilingMargin and flags m->scd above it.
void ApplyScdCeiling(double reference_accuracy_scd, Metrics* m);

// The farthest a run's event may lie from the reference's and the run still be drawn as a
// result on the work-precision diagrams (reports/bench_data.py, WRONG_EVENT_TIME_S): 1 ms is
// 0.5° of flexion at the end of the chapter run, so any run whose positions carry 2 or more
// digits places its events closer.
constexpr double kWrongEventTimeS = 1e-3;
// Why a completed run's events make it a failure on the diagrams, "" when they do not: a
// reference event missing or off by more than kWrongEventTimeS, or a contact event the
// reference lacks (kink_* and flexion_90 are not contact events). The rule of
// reports/bench_data.py classify_run, for the C++ sweeps' own summaries.
std::string WrongEventReason(const Metrics& m, const std::vector<EventRecord>& run_events);

// scd of positions: −log10 max |e| / (|ref| + floor). Exposed for tests.
double ScdFromErrors(const std::vector<double>& x, const std::vector<double>& x_ref,
                     const std::vector<double>& floors);
// max |e| / (1 + |ref|), skipping NaN pairs; 0 when nothing compared.
double MixedError(const std::vector<double>& x, const std::vector<double>& x_ref);

// Compares at the reference's times (matching within 1e-9 s, each with the run's first row
// there; the reference's end-event state against the run's end-event state when both ended
// on an event). Linear in the two lengths when both lists of times are finite and
// non-decreasing, as every Solution kneedyn builds or reads is. Events: each reference
// event name against the run's first event of that name (a hash map).
Metrics Compare(const Solution& run, const Solution& reference);

// Fills the residuals and the energy error from a run.
void AddRunMetrics(const Scene& scene, const RunResult& result, bool conservative, Metrics* m);

// The energy error's reduction, max_i |E(t_i) − E(0)| / |E(0)|, over mechanical energies
// given in time order (the first is E(0)); NaN without a finite, nonzero E(0). Shared by a
// run's own samples (EnergyError) and a printed result's rows (`kneedyn score`).
class EnergyDrift {
 public:
  void Add(double mechanical_energy_J);
  double Relative() const;

 private:
  double initial_J_ = std::numeric_limits<double>::quiet_NaN();
  double worst_J_ = 0.0;
  bool started_ = false;
};

// Maximum relative energy error over a run's samples (EnergyDrift).
double EnergyError(const Scene& scene, const RunResult& result);

nlohmann::json SolutionJson(const Solution& s);
// The "solution" object of a reference or bench record, checked field by field: at least
// two sample times, increasing, every variable class with its names and one row of that many numbers
// (null: NaN) per time, events with a name, a time and a flexion. InputError names
// `document` and the field ("solution.classes.positions.values[3]").
Solution SolutionFromJson(const nlohmann::json& j, const std::string& document = "a solution JSON");
nlohmann::json MetricsJson(const Metrics& m);  // non-finite numbers as null

// "SUNDIALS 6.4.1, Ceres 2.1.0, Eigen 3.4.0" as a JSON object.
nlohmann::json LibraryVersionsJson();

}  // namespace bench
}  // namespace kneedyn
