// Files of `kneedyn run`, published as one complete set (see WriteRunOutputs):
//   trajectory.csv  one row per output time plus every event; named columns with units
//   trajectory.sto  the same as an OpenSim storage file (inDegrees=yes, tab-separated)
//   summary.json    scene, formulation, settings, initialization, events, final state,
//                   solver statistics, wall time, status (partial when the solver failed)
// Column names and JSON fields are a contract for reports and benchmarks: extend, never
// rename; a change of meaning raises kSummarySchemaVersion. docs/outputs.md documents them.
#pragma once

#include <nlohmann/json.hpp>
#include <array>
#include <limits>
#include <string>
#include <vector>

#include "formulations/run.hpp"

namespace kneedyn {

// summary.json "schema_version" (docs/outputs.md). 1: files without the field (the
// earliest ones); 2: adds schema_version, git_commit, command_line, settings.step_mode,
// settings.mean_step_s, settings.requested; settings.integrator and settings.step_s
// become the integrator and fixed step actually used (step_s null when adaptive).
constexpr int kSummarySchemaVersion = 2;

struct TrajectoryTable {
  std::vector<std::string> columns;        // with units, e.g. "flexion_deg"
  std::vector<std::vector<double>> rows;   // NaN = empty (e.g. contact point when separated)
  // Rows whose patella columns are empty: the equilibrium followed from the row before did
  // not reach their tibial pose (a failed run's last row, at a fold of the patella's
  // equilibrium, docs/model.md §12): the row's time (s) and the solver's reason.
  std::vector<std::pair<double, std::string>> patella_not_followed;
  // Per patellar facet (medial, lateral): the row whose pressing contact lies farthest outside
  // the patella's proximal-distal extent, apex_P to base_P (the facets are unbounded planes,
  // docs/model.md §12); time_s NaN when every contact lay on it.
  struct OffPatella {
    double time_s = std::numeric_limits<double>::quiet_NaN();
    double z_P_mm = 0.0;  // the contact's z in P, mm
    double beyond_mm = 0.0;  // how far outside the extent, mm
  };
  std::array<OffPatella, 2> patella_contact_off;
};

TrajectoryTable MakeTrajectoryTable(const Scene& scene, const RunResult& result);

// What a run did that its status does not say (summary.json's `warnings`, docs/outputs.md):
//  - kind "pulling_contact": a contact whose normal force pulled (< 0 N) in a row written:
//    a patellar facet without patella.facet_liftoff (λ of either sign, docs/model.md §12), or
//    a tibial contact. The contact's own lift-off event row is not counted: there the force
//    is 0 by the event's definition (docs/model.md §9) and its value is the event location's
//    error (−4e-12 N with dae, −1.8e-11 N with staggered on the patellofemoral impact), unless
//    it pulls by more than kLiftoffRowForceFraction of the column's largest |force|. A force
//    above −kPullingForceFloorN is round-off, not a pull.
//  - kind "patella_not_followed": a row whose patella columns are empty
//    (TrajectoryTable::patella_not_followed); `time_s` and `message` only.
//  - kind "patella_contact_off": a pressing facet's contact outside the patella's extent
//    (TrajectoryTable::patella_contact_off); `contact`, `time_s` of its farthest row, `message`.
//  - kind "sparse_output": fewer than kMinOutputRows rows besides the start and the events.
//  - kind "start_not_at_nearest_points": a tibial contact whose gap column (the nearest-point
//    distance) at the first row exceeds kStartGapToleranceMm after a consistent start.
//  - kind "separated_contact_penetrates": a separated tibial contact whose gap fell below
//    the tolerances' re-contact hysteresis while the drift had widened it (docs/model.md §9).
//  - kind "ligament_overstretched": an element whose strain passed kMaxPlausibleStrain in a row.
//  - kind "short_contact_phase": OutputWarnings, below.
//  - kind "liftoff_force_not_zero": a tibial lift-off whose consistent normal force at the
//    event state (EventRecord::consistent_normal_force) exceeds kLiftoffConsistentForceFraction
//    of the contact's largest force over the rows; `contact`, `column`, `force_N`, `time_s`.
struct OutputWarning {
  std::string kind;     // "pulling_contact" | "patella_not_followed" | "patella_contact_off" | "sparse_output" |
                        // "start_not_at_nearest_points" | "separated_contact_penetrates" |
                        // "ligament_overstretched" | "short_contact_phase" | "liftoff_force_not_zero"
  std::string column;   // the trajectory column, e.g. "N_patella_lateral_N", "N_medial_N"
  std::string contact;  // "patellar facet lateral", "tibial contact medial"
  double min_force_N = 0.0;  // the column's most negative value, N
  double duration_s = 0.0;   // short_contact_phase: from one change of the contact to the next, s
  double force_N = 0.0;      // liftoff_force_not_zero: the consistent normal force at the lift-off, N
  double time_s = 0.0;       // its row's time, s (the first row of that value)
  std::string message;  // one line for the CLI and summary.json
};
// From the rows of `table` (MakeTrajectoryTable of `result`) and result.events: the pulling
// contacts in column order, then the rows whose patella was not followed, then the facets
// whose contact left the patella, then a sparse output, then the contacts whose start is not
// at the nearest points, then the separated contacts that sank into their plateaus, then the
// overstretched elements, then, for a fixed-step run, each contact phase or separation
// shorter than kMinResolvedSteps steps, then the lift-offs whose force was not zero.
constexpr int kMinResolvedSteps = 10;
// Fewer output rows than this besides the start and the events: "sparse_output".
constexpr size_t kMinOutputRows = 3;
// A start row's gap (mm) beyond which the consistent start is not at the surfaces' nearest
// points ("start_not_at_nearest_points"); a consistent start closes it to ~1e-13 mm.
constexpr double kStartGapToleranceMm = 1e-6;
constexpr double kLiftoffRowForceFraction = 1e-4;
// N: a normal force above −this is round-off, not a pull (a scene without ligaments, the
// tibia falling off its plateau, wrote N = −2.4e-34 N and was warned); far below any force
// the model resolves (the tibia's weight is 39 N).
constexpr double kPullingForceFloorN = 1e-9;
// A strain (L − L0)/L0 beyond which an element is no ligament ("ligament_overstretched"):
// ligaments tear at strains of a few tenths, and every shipped scene stays below 0.61 (the
// hard case patella_quadriceps_2000N; the chapter scene 0.20); twice its slack length is a
// pose the knee cannot take (an assembled start at 80° of flexion: 28, i.e. 2,825 %).
constexpr double kMaxPlausibleStrain = 1.0;
// A lift-off whose consistent normal force at the event state (the contact kept) exceeds this
// fraction of the contact's largest force over the rows ("liftoff_force_not_zero"): the
// method's own N crossed zero before the knee's. Measured on the chapter scene (~243 N peak)
// at the defaults: ede, mde ~1e-11 N, dae 6.0e-4 N, generalized-alpha 5.7e-4 N, dae-ggl 2.4e-3 N
// (dae at rtol 1e-3: 0.070 N); newmark's lift-off 0.7 ms early 4.3 N (1.8 %), on the hard cases
// 1.2 N (hard/pulse_2000N, 0.17 ms early, 0.51 %) to 25.3 N (stiff_ligaments_10x), its lift-offs
// within 0.1 ms of dae's 0.06 to 0.4 N (< 0.2 %).
constexpr double kLiftoffConsistentForceFraction = 5e-3;
std::vector<OutputWarning> OutputWarnings(const TrajectoryTable& table, const RunResult& result);

// summary.json; `warnings` are OutputWarnings of the run's table.
nlohmann::json SummaryJson(const Scene& scene, const RunSettings& settings, const RunResult& result,
                           const std::vector<OutputWarning>& warnings);
nlohmann::json StatsJson(const SolverStats& stats);

// Checks that `dir` can receive an output set before a run starts: it is absent, or a
// directory holding nothing but regular files named as the set's (a previous set).
// Throws InputError naming --out and the rule otherwise.
void CheckOutputDirectory(const std::string& dir);

// Publishes the three files as one set: they are written into a private
// temporary directory beside `dir` (".<name>.kneedyn-tmp-<pid>-<random>"), which then
// replaces `dir` in one atomic rename (Linux renameat2 RENAME_EXCHANGE when `dir` exists).
// After a kill at any moment `dir` holds the previous complete set or the new one; a
// later run removes temporaries whose process has ended. Of two runs into the same `dir`,
// the last to publish wins whole. Throws InputError (checks of CheckOutputDirectory).
// Returns summary.json's warnings (OutputWarnings), for the caller to show.
std::vector<OutputWarning> WriteRunOutputs(const std::string& dir, const Scene& scene, const RunSettings& settings,
                     const RunResult& result);

// The bytes of printf("%.12g", v) for the numbers of trajectory.csv/.sto, written into
// `out` (no terminating NUL); returns their count. By one or two double products for
// 1e-30 ≤ |v| < 1e12 (but within 5e-4 of a 12-digit tie), through std::to_chars(general,
// 12) otherwise.
constexpr size_t kTrajectoryNumberChars = 32;  // "-1.23456789012e-308": 19
size_t FormatTrajectoryNumber(double v, char (&out)[kTrajectoryNumberChars]);

// ColumnSafeName ("ACL anterior" -> "ACL_anterior"): solver/model.hpp.

}  // namespace kneedyn
