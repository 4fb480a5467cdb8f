// Sweep runner (ensembles/sweep.hpp, sweep_output.hpp). Validates: a run's outcomes agree
// with `RunScene` + the run driver's own trajectory file (run_output.cpp computes the
// element forces on its own path); rows are identical whatever the thread count; failed
// runs are kept with a reason and NaN outcomes; the Ishigami function at a point where it
// is known in closed form; part merging refuses gaps, duplicates and foreign parts.
#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>
#include <stdexcept>

#include "ensembles/sweep.hpp"
#include "ensembles/sweep_output.hpp"
#include "formulations/run_output.hpp"
#include "solver/error.hpp"
#include "solver/units.hpp"

using namespace kneedyn;
using namespace kneedyn::ensembles;
namespace fs = std::filesystem;

namespace {

const std::string kScenes = std::string(KNEEDYN_SOURCE_DIR) + "/reference-data/scenes";

SweepSpec Parse(const std::string& text) { return ParseSweepSpec(text, "spec.yaml", kScenes); }

size_t Column(const std::vector<std::string>& cols, const std::string& name) {
  for (size_t i = 0; i < cols.size(); ++i) {
    if (cols[i] == name) return i;
  }
  ADD_FAILURE() << "no column " << name;
  return 0;
}

// Largest value of a column of a run's trajectory.csv.
double ColumnMax(const std::string& csv, const std::string& name) {
  std::ifstream in(csv);
  std::string line;
  std::getline(in, line);
  std::vector<std::string> header;
  std::stringstream hs(line);
  for (std::string c; std::getline(hs, c, ',');) header.push_back(c);
  const size_t k = Column(header, name);
  double best = -INFINITY;
  while (std::getline(in, line)) {
    std::stringstream ls(line);
    std::string cell;
    for (size_t i = 0; i <= k; ++i) std::getline(ls, cell, ',');
    best = std::max(best, std::stod(cell));
  }
  return best;
}

}  // namespace

TEST(Sweep, NominalRunAgreesWithTheRunDriverAndItsTrajectoryFile) {
  // A one-level grid sits at the middle of each range: here exactly the chapter's values.
  const SweepSpec spec = Parse(
      "scene: chapter_impact.yaml\n"
      "parameters: [{name: pulse.amplitude, uniform: [90, 110]}, {name: PCL anterior.k_linear, uniform: [120, 130]}]\n"
      "design: {type: grid, levels: 1}\n"
      "outcomes: [liftoff_time, liftoff_flexion, peak_ligament_force, peak_contact_force, time_at_90,"
      " ligament_force_at_90, contact_force_at_90]\n"
      "solver: {formulation: dae-reduced, rtol: 1.0e-8, atol: 1.0e-10, output_interval_s: 0.002}\n");
  const SweepTable t = RunSweep(spec, ShardIndices(spec, 0, 1), 1);
  ASSERT_EQ(t.rows.size(), 1u);
  const RunRow& r = t.rows[0];
  ASSERT_TRUE(r.completed) << r.failure;
  EXPECT_EQ(r.parameters, (std::vector<double>{100.0, 125.0}));

  const Scene scene = LoadScene(kScenes + "/chapter_impact.yaml");
  RunSettings settings = spec.run;
  const RunResult direct = RunScene(scene, settings);
  ASSERT_TRUE(direct.completed);
  EXPECT_EQ(r.outcomes[Column(t.outcome_columns, "liftoff_time_s")], direct.events.front().time);
  EXPECT_EQ(r.outcomes[Column(t.outcome_columns, "liftoff_flexion_deg")], RadToDeg(direct.events.front().flexion));
  EXPECT_EQ(r.outcomes[Column(t.outcome_columns, "time_90_s")], direct.events.back().time);
  EXPECT_EQ(r.steps, direct.stats.steps);
  // Lateral lift-off near 52.6° (README, all formulations agree).
  EXPECT_NEAR(r.outcomes[Column(t.outcome_columns, "liftoff_flexion_deg")], 52.597, 0.01);

  const fs::path dir = fs::temp_directory_path() / "kneedyn_sweep_test_nominal";
  fs::remove_all(dir);
  WriteRunOutputs(dir.string(), scene, settings, direct);
  const std::string csv = (dir / "trajectory.csv").string();
  for (const char* e : {"PCL_anterior", "MCL_anterior", "ACL_anterior"}) {
    const double peak = r.outcomes[Column(t.outcome_columns, std::string("peak_F_") + e + "_N")];
    EXPECT_NEAR(peak, ColumnMax(csv, std::string("F_") + e + "_N"), 1e-9 * peak) << e;
  }
  EXPECT_NEAR(r.outcomes[Column(t.outcome_columns, "peak_N_medial_N")], ColumnMax(csv, "N_medial_N"), 1e-8);
  fs::remove_all(dir);
}

// A scene's contact outcomes are its contact pairs', as trajectory.csv's N_<compartment>_N:
// chapter_impact.yaml has both; no_contact.yaml has none, so a spec that asks for them is
// refused, naming the outcome (before: peak_N_medial_N and _lateral_N of 0 N, which no run
// of it computes).
TEST(Sweep, ContactOutcomesAreTheScenesContactPairs) {
  try {
    Parse("scene: no_contact.yaml\nparameters: [{name: mass, uniform: [4, 5]}]\ndesign: {type: grid, levels: 1}\n"
          "outcomes: [liftoff_time, peak_contact_force]\n");
    ADD_FAILURE() << "a contact outcome of a scene without contacts was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("the scene has no contact pairs"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("outcomes"), std::string::npos) << e.what();
  }
  for (const auto& [scene, expected] : std::vector<std::pair<std::string, std::vector<std::string>>>{
           {"chapter_impact.yaml", {"peak_N_medial_N", "peak_N_lateral_N", "N90_medial_N", "N90_lateral_N"}}}) {
    const SweepSpec spec = Parse("scene: " + scene +
                                 "\nparameters: [{name: mass, uniform: [4, 5]}]\ndesign: {type: grid, levels: 1}\n"
                                 "outcomes: [peak_contact_force, contact_force_at_90]\n");
    EXPECT_EQ(OutcomeColumns(spec), expected) << scene;
    const std::vector<std::string> trajectory = MakeTrajectoryTable(spec.base, RunResult{}).columns;
    for (const std::string& c : expected) {  // peak_N_medial_N and N90_medial_N → N_medial_N
      const std::string compartment_force = "N_" + c.substr(c.rfind("N90_", 0) == 0 ? 4 : 7);
      EXPECT_NE(std::find(trajectory.begin(), trajectory.end(), compartment_force), trajectory.end()) << c;
    }
  }
}

TEST(Sweep, RowsDoNotDependOnTheThreadCount) {
  const SweepSpec spec = Parse(
      "scene: chapter_impact.yaml\n"
      "parameters: [{name: pulse.amplitude, uniform: [60, 140]}, {name: MCL deep.k_linear, relative: 0.3},"
      " {name: mass, relative: 0.2}]\n"
      "design: {type: lhs, samples: 6, seed: 7}\n"
      "outcomes: [liftoff_flexion, peak_ligament_force]\n"
      "solver: {formulation: dae-reduced, rtol: 1.0e-6, atol: 1.0e-8}\n");
  const std::vector<long> all = ShardIndices(spec, 0, 1);
  const SweepTable one = RunSweep(spec, all, 1), two = RunSweep(spec, all, 2);
  EXPECT_EQ(SerializeRows(one.rows), SerializeRows(two.rows));
  // A shard's rows are the same rows.
  const SweepTable odd = RunSweep(spec, ShardIndices(spec, 1, 2), 2);
  ASSERT_EQ(odd.rows.size(), 3u);
  EXPECT_EQ(SerializeRows({odd.rows[1]}), SerializeRows({one.rows[3]}));
}

TEST(Sweep, FailedRunsAreKeptWithTheirReason) {
  const SweepSpec spec = Parse(
      "scene: chapter_impact.yaml\n"
      "parameters: [{name: pulse.amplitude, uniform: [90, 110]}]\n"
      "design: {type: sobol, samples: 2}\n"
      "outcomes: [liftoff_time, peak_contact_force]\n"
      "solver: {formulation: dae-reduced, max_steps: 3}\n");
  const SweepTable t = RunSweep(spec, ShardIndices(spec, 0, 1), 2);
  ASSERT_EQ(t.rows.size(), 2u);
  for (const RunRow& r : t.rows) {
    EXPECT_FALSE(r.completed);
    EXPECT_FALSE(r.failure.empty());
    EXPECT_TRUE(std::isnan(r.outcomes[1]));
  }
}

// Shard i of n holds the indices k with k mod n = i (the definition), also when n is as
// large as a long allows: the index loop stops before i + n could overflow.
TEST(Sweep, ShardIndicesAreTheResidueClassEvenForHugeShardCounts) {
  const SweepSpec spec = Parse(
      "analytic: ishigami\n"
      "parameters: [{name: x1, uniform: [0, 1]}, {name: x2, uniform: [0, 1]}, {name: x3, uniform: [0, 1]}]\n"
      "design: {type: sobol, samples: 25}\noutcomes: [value]\n");
  EXPECT_EQ(ShardIndices(spec, 0, 10), (std::vector<long>{0, 10, 20}));
  EXPECT_EQ(ShardIndices(spec, 4, 10), (std::vector<long>{4, 14, 24}));
  EXPECT_EQ(ShardIndices(spec, 24, 25), (std::vector<long>{24}));
  EXPECT_TRUE(ShardIndices(spec, 30, 40).empty());
  const long huge = std::numeric_limits<long>::max();
  EXPECT_EQ(ShardIndices(spec, 1, huge), (std::vector<long>{1}));
  EXPECT_EQ(ShardIndices(spec, 0, huge - 1), (std::vector<long>{0}));
}

TEST(Sweep, IshigamiAtAKnownPoint) {
  const SweepSpec spec = Parse(
      "analytic: ishigami\n"
      "parameters: [{name: x1, uniform: [0, 3.141592653589793]}, {name: x2, uniform: [0, 3.141592653589793]},"
      " {name: x3, uniform: [0.5, 1.5]}]\n"
      "design: {type: grid, levels: 1}\noutcomes: [value]\n");
  const SweepTable t = RunSweep(spec, {0}, 1);
  // sin(π/2) + 7 sin²(π/2) + 0.1 · 1⁴ · sin(π/2) = 8.1
  EXPECT_NEAR(t.rows[0].outcomes[0], 8.1, 1e-14);
}

// What a worker throws outside a run (here the progress callback, on whichever thread
// evaluates the third run) reaches RunSweep's caller once every worker has stopped. Before,
// it escaped a std::thread (or left one unjoined) and std::terminate ended the process.
TEST(Sweep, AnExceptionInAWorkerReachesTheCallerWithTwoThreads) {
  const SweepSpec spec = Parse(
      "analytic: ishigami\n"
      "parameters: [{name: x1, uniform: [0, 1]}, {name: x2, uniform: [0, 1]}, {name: x3, uniform: [0, 1]}]\n"
      "design: {type: sobol, samples: 64}\noutcomes: [value]\n");
  for (int threads : {1, 2}) {
    std::atomic<int> calls{0};
    const auto throw_on_third = [&](const SweepProgress&) {
      if (++calls == 3) throw std::runtime_error("progress callback failed");
    };
    EXPECT_THROW(RunSweep(spec, ShardIndices(spec, 0, 1), threads, throw_on_third), std::runtime_error) << threads;
    EXPECT_LT(calls.load(), 64) << "the workers stop at the first error";
  }
}

TEST(SweepOutput, RowsRoundTripAndMergeRefusesGapsDuplicatesAndForeignParts) {
  SweepTable a;
  a.fingerprint = 42;
  a.total_runs = 3;
  a.parameter_columns = {"p"};
  a.outcome_columns = {"o"};
  RunRow r;
  r.parameters = {0.1};
  r.outcomes = {NAN};
  r.failure = "a, \"quoted\" reason";
  for (long i : {0, 2}) {
    r.index = i;
    a.rows.push_back(r);
  }
  SweepTable b = a;
  b.rows = {r};
  b.rows[0].index = 1;
  const std::string bytes = SerializeRows(a.rows);
  EXPECT_EQ(SerializeRows(DeserializeRows(bytes)), bytes);

  const fs::path dir = fs::temp_directory_path() / "kneedyn_sweep_test_parts";
  fs::remove_all(dir);
  WritePart((dir / "a.json").string(), a, 0, 2);
  WritePart((dir / "b.json").string(), b, 1, 2);
  const SweepTable merged = MergeParts({ReadPart((dir / "a.json").string()), ReadPart((dir / "b.json").string())});
  ASSERT_EQ(merged.rows.size(), 3u);
  EXPECT_TRUE(std::isnan(merged.rows[1].outcomes[0]));
  EXPECT_EQ(merged.rows[1].failure, r.failure);
  EXPECT_THROW(MergeParts({a}), InputError);     // index 1 missing
  EXPECT_THROW(MergeParts({a, b, b}), InputError);  // index 1 twice
  // A part given twice: its first run is named, with both parts (before: "run index 1
  // appears twice", index 1 being the one present once).
  try {
    MergeParts({ReadPart((dir / "a.json").string()), ReadPart((dir / "a.json").string()),
                ReadPart((dir / "b.json").string())});
    ADD_FAILURE() << "a part given twice was merged";
  } catch (const InputError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("run index 0 appears twice: in part 1 ('" + (dir / "a.json").string() + "') and part 2"),
              std::string::npos) << what;
  }
  SweepTable foreign = b;
  foreign.fingerprint = 43;
  EXPECT_THROW(MergeParts({a, foreign}), InputError);
  // The refusal names both files and the field (before: only the two fingerprints).
  WritePart((dir / "foreign.json").string(), foreign, 1, 2);
  try {
    MergeParts({ReadPart((dir / "a.json").string()), ReadPart((dir / "foreign.json").string())});
    ADD_FAILURE() << "a part of another sweep was merged";
  } catch (const InputError& e) {
    const std::string what = e.what();
    for (const std::string& s : {(dir / "foreign.json").string(), (dir / "a.json").string(),
                                 std::string("field 'fingerprint' = 43 vs 42")}) {
      EXPECT_NE(what.find(s), std::string::npos) << s << " in " << what;
    }
  }
  std::ofstream((dir / "bad.json").string()) << "{\"kind\": \"something\"}";
  EXPECT_THROW(ReadPart((dir / "bad.json").string()), InputError);
  fs::remove_all(dir);
}
