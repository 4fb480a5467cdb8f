// `kneedyn score RESULT --scene S`: scores a trajectory CSV written by any solver against the
// stored reference of the scene with kneedyn's own metrics (metrics.hpp), the rules of
// docs/problem.md:
//
//   - RESULT: CSV, a header row then one row per output time; `time_s` (or `time`, s) and
//     any subset of trajectory.csv's columns (docs/outputs.md); an empty cell is a value
//     that does not exist (a separated contact's point). Optional `is_event` (1: an event
//     row): event rows are not compared at the sampling times; the last row is the state
//     of the end event when it is an event row, or, without `is_event`, when the reference
//     ended on an event and the row lies past the reference's last sampling time.
//   - The reference (reference-data/references/<scene>.json, make_reference.cpp) stores the
//     five classes at its sampling times only (every comparison_interval_s, 0.02 s, plus
//     the end event), no dense output. Between its samples it cannot be interpolated to
//     any use: cubic Hermite interpolation from its positions and velocities is 1.4 digits
//     off at the midpoints on chapter_impact (measured against dae at rtol 1e-10, which
//     agrees with the samples to 8.1 digits); the trajectory oscillates faster than 0.02 s.
//     So the reference's dense output is the reference run itself: rows at the sampling
//     times (matched within 1e-9 s) are compared with the stored samples; for rows at any
//     other time inside the reference's span (DenseReference below) the configuration
//     the reference records (`primary`: formulation, integrator, rtol, atol) is run again
//     with output rows at those times, and that run must reproduce the stored samples to
//     the reference's stated accuracy (accuracy_scd digits) before its rows are used. An
//     extended-precision reference cannot be run again by `kneedyn run`: its off-grid rows
//     come from DenseDoubleConfiguration (mde cvode-adams, rtol 1e-14), which must reproduce
//     the stored samples to kMinDenseReproductionScd digits, and what it reproduces then
//     caps the score (scd_ceiling, as in the work-precision sweep).
//     Reference sampling times without a row are missing (scd null; scd_compared over the
//     rest).
//   - Metrics: scd (positions, floors 1 mm and 1 deg: the work-precision figure; null when
//     a reference time is missing), mescd per class = −log10(mixed error), the mixed error
//     being max |e| / (1 + |x_ref|) in the class's units — kneedyn's scd with its floors of
//     1 unit is the same formula, so mescd is the scd of each class (over the times
//     present); event-time errors and digits (from --events); constraint drift (max |gap|
//     and |gap rate| over the rows with the contact in contact).
#pragma once

#include <map>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "benchmarks/metrics.hpp"
#include "scene/scene.hpp"

namespace kneedyn {
namespace bench {

// The most data rows a result CSV may have (and events an events CSV): 10 x kMaxOutputRows,
// the most sampling rows `kneedyn run` writes (scene/scene.hpp; its event rows are a few
// more), room for an outside solver that writes a row per step. A row costs about 0.5 KB
// once read (one row of each class, NaN where not given), so the cap bounds a result at
// about 0.5 GB, and the run again at its off-grid times (DenseReference) at as many output
// rows; a larger file is refused as it is read (docs/outputs.md), before more is stored.
constexpr size_t kMaxResultRows = 10 * static_cast<size_t>(kMaxOutputRows);

// A result CSV read into the classes of metrics.hpp (NaN where a column is not given).
struct ScoredResult {
  Solution solution;
  std::map<std::string, int> given_columns;  // per class: how many of its columns the CSV has
  std::vector<std::string> columns;          // the CSV's header
  size_t rows = 0;
  double max_gap_m = 0.0;       // NaN when no gap column
  double max_gap_rate_m_s = 0.0;
  // The most significant digits any value cell prints (ReadResultCsv; not the time or
  // is_event column; 0: not from a file):
  // the printing's precision, which caps the digits a score can measure (%.12g writes 0.5 as
  // "0.5", so the most, not the fewest, is the precision).
  int printed_significant_digits = 0;
  // Rows after the reference's end event (its time + 1e-9 s) other than the result's own end
  // row: no reference state exists there to compare (a result that reaches the end later
  // than the reference has some; they are counted and reported, never scored).
  size_t rows_after_reference_end = 0;
};

// Reads `path` for `reference`'s component names. Throws InputError naming the file, the
// line and the column (unknown column, no time column, a number that does not parse,
// times not increasing, more than kMaxResultRows rows). Linear in the file's size: lines
// are split into views, each row stored once.
ScoredResult ReadResultCsv(const std::string& path, const Scene& scene, const Solution& reference);

// Events a run reports, from kneedyn's summary.json ("events") or a CSV `name,time_s[,flexion_deg]`;
// from a summary.json also the run's scene name and status (empty for a CSV), which the
// caller checks against the scene scored and the result's failure.
struct EventsFile {
  std::vector<EventRecord> events;
  std::string scene;   // summary.json scene.name
  std::string status;  // summary.json status: completed, partial, ...
};
EventsFile ReadEvents(const std::string& path);

struct Score {
  Metrics metrics;                          // metrics.hpp: scd, scd_compared, mixed, events
  std::map<std::string, double> mescd;      // per class, −log10(mixed); NaN: not given
  std::map<std::string, double> event_digits;  // −log10(|t − t_ref| / t_ref)
};

// scd is over the six generalized coordinates: NaN (no figure) unless the result gives all
// of them (a result of one coordinate would otherwise score that coordinate's digits).
Score ScoreResult(const ScoredResult& result, const Solution& reference);

// The reference's end event (its name, e.g. flexion_90) is the result's end row: its time is
// scored as that event's. When `result` already has that event (from --events), the end row
// must be at its time (within 1e-9 s), else InputError naming both times and `events_source`;
// otherwise the end row's time and flexion are added as the event. Nothing when either does
// not end on an event, when the result failed (`failed`: its last event row is where it
// stopped), or when the end row's flexion is not the reference end state's (within 1e-3°:
// another event's row).
void ReconcileEndEvent(const Solution& reference, const std::string& events_source, bool failed,
                       ScoredResult* result);
// The reference's end-event name ("" when it does not end on an event).
std::string ReferenceEndEventName(const Solution& reference);

// "" when time t (s) lies in the scene's span, from the reference's start to the scene's
// end.time_s (within 1e-9 s), else the refusal's text: a result row or event outside it is
// no state of the run (times in ms, another scene's rows) and was ignored without a word.
std::string OutsideSceneSpan(const Scene& scene, const Solution& reference, double t);

// The result's non-event row times inside the reference's span (t0 to its last sampling
// time or end event) that are not sampling times of the reference (within 1e-9 s).
std::vector<double> OffGridTimes(const ScoredResult& result, const Solution& reference);

// The reference at its sampling times plus `times` (OffGridTimes): the stored samples, and
// at `times` the rows of the configuration reference_json["primary"] run again with output
// there. Throws SolverError when that run fails or reproduces the stored samples to fewer
// than reference_json["accuracy_scd"] digits (scd of positions); *reproduced_scd: what it
// reached.
// make_reference's name for its extended-precision integrator (primary.formulation).
inline constexpr const char* kExtendedPrecisionFormulation = "extended-precision";
// The configuration run again for off-grid rows when the reference is extended precision
// (no `kneedyn run` can repeat it): the earlier double reference's, mde cvode-adams at rtol
// 1e-14 (about 11 digits from the extended one), and the least agreement with the stored
// samples it must show before its rows are used.
nlohmann::json DenseDoubleConfiguration();
constexpr double kMinDenseReproductionScd = 10.0;
// The accuracy a score's ceiling derives from (metrics.hpp ApplyScdCeiling): the reference's
// stated accuracy_scd, or what the configuration run again for off-grid rows reproduced of
// the stored samples when that is lower (NaN reproduced_scd: no off-grid rows), or the
// result's printed significant digits when fewer (0: not printed): the reference's own
// samples printed with 12 digits score 11.34 on chapter_impact, the printing's limit.
double ScoreCeilingAccuracy(const nlohmann::json& reference_json, double reproduced_scd,
                            int printed_significant_digits = 0);
// Checks the fields of a reference document that scoring reads besides its solution (scene,
// accuracy_scd, comparison_interval_s, primary: formulation, integrator, rtol, atol, command)
// for their types, so that reading them later cannot throw or recurse; InputError names
// `document` and the field.
void CheckReferenceFields(const nlohmann::json& reference_json, const std::string& document);
Solution DenseReference(const Scene& scene, const nlohmann::json& reference_json, const Solution& reference,
                        const std::vector<double>& times, double* reproduced_scd);

// A reference document's solution as scoring reads it: CheckReferenceFields, then
// SolutionFromJson of its "solution"; InputError names `document` and the field.
Solution ReferenceSolution(const nlohmann::json& reference_json, const std::string& document);

// What becomes of a result's rows off the reference's sampling times (OffGridTimes).
enum class OffGridRows {
  kRunReferenceAgain,  // DenseReference: the reference's configuration run again there (kneedyn score)
  kNotCompared,        // compared at the sampling times only (fuzz targets: no integration per input)
};

// The energy error of a result on a conservative scene (metrics.hpp: max_i |E(t_i) − E(0)| /
// |E(0)|) from its printed positions and velocities, over the rows that give all twelve;
// E(0) from its first row, which must be at t = 0 and complete (else NaN).
double PrintedEnergyError(const Scene& scene, const Solution& result);

// A result scored against a reference the way `kneedyn score` does it: off-grid rows as
// `off_grid_rows` says, ScoreResult, then the ceiling of ScoreCeilingAccuracy
// (ApplyScdCeiling), and on a conservative reference the energy error (PrintedEnergyError). Throws SolverError when the configuration run again fails or does
// not reproduce the stored samples (DenseReference).
struct ReferenceScore {
  Score score;
  std::vector<double> off_grid_times;  // OffGridTimes, whatever was done with them
  double reproduced_scd;               // digits the configuration run again reproduced; NaN: not run
};
ReferenceScore ScoreAgainstReference(const Scene& scene, const nlohmann::json& reference_json,
                                     const Solution& reference, const ScoredResult& result, OffGridRows off_grid_rows);

// The work-precision `results` record of a score (docs/outputs.md, `work_precision --json`).
struct ScoreInfo {
  std::string solver_name;
  std::string integrator;
  nlohmann::json setting = nlohmann::json::object();  // rtol, atol, step as given
  nlohmann::json counters = nlohmann::json::object();
  double cpu_time_s = -1.0;                           // < 0: not given
  std::string failure;                                // non-empty: a failed run
};
nlohmann::json ScoreRecord(const ScoredResult& result, const Score& score, const ScoreInfo& info);

}  // namespace bench
}  // namespace kneedyn
