// Tests of `kneedyn score` (benchmarks/score.hpp): a built-in run's own trajectory.csv scores
// the scd the work-precision machinery computes for that run (bench::Evaluate), to the CSV's
// printed precision; a subset of columns scores its classes only; missing comparison times
// and bad columns are reported.
#include "benchmarks/score.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <unistd.h>

#include "benchmarks/bench_run.hpp"
#include "formulations/run_output.hpp"
#include "solver/error.hpp"
#include "test_support.hpp"

namespace kneedyn {
namespace {

namespace fs = std::filesystem;
using test_support::ChapterScene;

// trajectory.csv prints 12 significant digits: each value is off by ≤ 5e-12 |x| (half a unit
// of the 12th digit of a mantissa 1.000…). At an error level 10^-d of (|x| + 1) (scd, mixed
// error) that moves the digits d by ≤ 5e-12 / 10^-d / ln 10 (2e-7 at d = 5).
double PrintedPrecisionDigits(double d) { return 5e-12 / std::pow(10.0, -d) / std::log(10.0); }

struct BuiltIn {
  bench::Metrics metrics;
  fs::path dir;
};

BuiltIn RunDae(const bench::Reference& ref, const std::string& name) {
  bench::BenchConfig config;
  config.formulation = "dae";
  config.rtol = 1e-8;
  config.atol = 1e-10;
  const bench::Outcome outcome = bench::RunConfig(ChapterScene(), config, ref.comparison_interval);
  EXPECT_EQ(outcome.status, "ok") << outcome.reason;
  BuiltIn b;
  b.metrics = bench::Evaluate(ChapterScene(), outcome, ref);
  b.dir = fs::temp_directory_path() / ("kneedyn_score_test_" + name + std::to_string(::getpid()));
  fs::remove_all(b.dir);
  RunSettings settings;
  settings.formulation = "dae";
  settings.options.rtol = config.rtol;
  settings.options.atol = config.atol;
  WriteRunOutputs(b.dir.string(), ChapterScene(), settings, outcome.result);
  return b;
}

const bench::Reference& Reference() {
  static const bench::Reference ref =
      bench::LoadReference(ReferenceDataDir() + "/references/chapter_impact.json");
  return ref;
}

TEST(Score, OwnTrajectoryGivesTheRunsScd) {
  const BuiltIn run = RunDae(Reference(), "own");
  const fs::path csv = run.dir / "trajectory.csv";
  bench::ScoredResult result = bench::ReadResultCsv(csv.string(), ChapterScene(), Reference().solution);
  result.solution.events = bench::ReadEvents((run.dir / "summary.json").string()).events;
  const bench::Score score = bench::ScoreResult(result, Reference().solution);
  const bench::Metrics& m = score.metrics;
  std::printf("dae rtol 1e-8: scd built-in %.6f, from trajectory.csv %.6f\n", run.metrics.scd, m.scd);
  ASSERT_TRUE(std::isfinite(run.metrics.scd));
  EXPECT_NEAR(m.scd, run.metrics.scd, PrintedPrecisionDigits(run.metrics.scd));
  EXPECT_EQ(m.compared_times, run.metrics.compared_times);
  EXPECT_EQ(m.missing_times, 0);
  for (const std::string& c : bench::VariableClasses()) {
    const double built_in = -std::log10(run.metrics.mixed.at(c));
    EXPECT_NEAR(score.mescd.at(c), built_in, PrintedPrecisionDigits(built_in)) << c;
  }
  // Events from summary.json: the run's own event times (printed with 17 digits).
  for (const auto& [name, err] : run.metrics.event_time) EXPECT_NEAR(m.event_time.at(name), err, 1e-15) << name;
  // Drift from the gap columns (mm, 12 digits) against the run's own maximum (m).
  EXPECT_NEAR(m.max_position_residual, run.metrics.max_position_residual, 1e-12 * run.metrics.max_position_residual + 1e-18);
  fs::remove_all(run.dir);
}

// On the conservative scene the score records the energy error from the printed positions
// and velocities: it equals the one the work-precision sweep computes from the run's own
// states (bench::Evaluate, metrics.cpp EnergyError) to the CSV's 12 digits. Without the
// velocity columns it is null.
TEST(Score, ConservativeSceneEnergyErrorFromThePrintedStates) {
  const Scene scene = LoadScene(ReferenceDataDir() + "/scenes/conservative.yaml");
  const std::string reference_file = ReferenceDataDir() + "/references/conservative.json";
  const bench::Reference ref = bench::LoadReference(reference_file);
  ASSERT_TRUE(ref.conservative);
  bench::BenchConfig config;
  config.formulation = "ede";
  config.integrator = "dopri5";
  config.rtol = 1e-6;  // an energy error well above the CSV's rounding
  config.atol = 1e-8;
  const bench::Outcome outcome = bench::RunConfig(scene, config, ref.comparison_interval);
  ASSERT_EQ(outcome.status, "ok") << outcome.reason;
  const double built_in = bench::Evaluate(scene, outcome, ref).energy_error;
  const fs::path dir = fs::temp_directory_path() / ("kneedyn_score_energy_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  RunSettings settings;
  settings.formulation = "ede";
  WriteRunOutputs(dir.string(), scene, settings, outcome.result);
  const bench::ScoredResult result = bench::ReadResultCsv((dir / "trajectory.csv").string(), scene, ref.solution);
  const double scored =
      bench::ScoreAgainstReference(scene, ref.json, ref.solution, result, bench::OffGridRows::kNotCompared)
          .score.metrics.energy_error;
  std::printf("conservative, ede dopri5 rtol 1e-6: energy error from the states %.6e, from trajectory.csv %.6e\n",
              built_in, scored);
  ASSERT_GT(built_in, 1e-7);
  // 12 printed digits move a ligament's length by ~1e-13 m, its energy by ~1e-11 J: ~1e-10 of
  // E(0) here (measured: 3e-10).
  EXPECT_NEAR(scored, built_in, 1e-9);
  bench::ScoredResult positions_only = result;
  for (auto& row : positions_only.solution.values.at("velocities")) std::fill(row.begin(), row.end(), NAN);
  EXPECT_FALSE(std::isfinite(bench::PrintedEnergyError(scene, positions_only.solution)));
  fs::remove_all(dir);
}

// Positions only, at the reference's sampling times only, without is_event: the same scd;
// the classes not given have no digits.
TEST(Score, SubsetOfColumnsAndTimes) {
  const BuiltIn run = RunDae(Reference(), "subset");
  const TrajectoryTable table = [&] {
    std::ifstream in(run.dir / "trajectory.csv");
    TrajectoryTable t;
    std::string line, cell;
    std::getline(in, line);
    std::istringstream h(line);
    while (std::getline(h, cell, ',')) t.columns.push_back(cell);
    while (std::getline(in, line)) {
      std::istringstream r(line);
      std::vector<double> row;
      while (std::getline(r, cell, ',')) row.push_back(cell.empty() ? NAN : std::stod(cell));
      t.rows.push_back(row);
    }
    return t;
  }();
  auto col = [&](const std::string& n) {
    return static_cast<size_t>(std::find(table.columns.begin(), table.columns.end(), n) - table.columns.begin());
  };
  const std::vector<std::string> keep = {"time_s", "x0_mm", "y0_mm", "z0_mm", "flexion_deg", "valgus_deg",
                                         "external_rotation_deg"};
  const fs::path subset = run.dir / "subset.csv";
  {
    std::ofstream out(subset);
    out.precision(17);
    for (size_t k = 0; k < keep.size(); ++k) out << (k ? "," : "") << keep[k];
    out << "\n";
    for (size_t r = 0; r < table.rows.size(); ++r) {
      const std::vector<double>& row = table.rows[r];
      const bool last = r + 1 == table.rows.size();
      const double t = row[col("time_s")];
      const bool sampling = std::abs(t / 0.02 - std::round(t / 0.02)) < 1e-6;
      if (row[col("is_event")] == 1.0 && !last) continue;
      if (!sampling && !last) continue;
      for (size_t k = 0; k < keep.size(); ++k) out << (k ? "," : "") << row[col(keep[k])];
      out << "\n";
    }
  }
  const bench::ScoredResult result = bench::ReadResultCsv(subset.string(), ChapterScene(), Reference().solution);
  const bench::Score score = bench::ScoreResult(result, Reference().solution);
  EXPECT_NEAR(score.metrics.scd, run.metrics.scd, PrintedPrecisionDigits(run.metrics.scd));
  EXPECT_EQ(score.metrics.missing_times, 0);
  EXPECT_TRUE(std::isnan(score.mescd.at("contact_forces")));
  EXPECT_TRUE(std::isnan(score.mescd.at("velocities")));
  EXPECT_NEAR(score.mescd.at("positions"), run.metrics.scd, PrintedPrecisionDigits(run.metrics.scd));
  fs::remove_all(run.dir);
}

TEST(Score, MissingTimesAndBadColumns) {
  const fs::path dir = fs::temp_directory_path() / ("kneedyn_score_bad_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  const bench::Solution& ref = Reference().solution;
  // The reference's own positions at its first three times only: exact there, the rest missing.
  {
    std::ofstream out(dir / "short.csv");
    out.precision(17);
    out << "time_s,x0_mm,y0_mm,z0_mm,flexion_deg,valgus_deg,external_rotation_deg\n";
    for (int i = 0; i < 3; ++i) {
      out << ref.times[i];
      for (double v : ref.values.at("positions")[i]) out << "," << v;
      out << "\n";
    }
  }
  const bench::Score s =
      bench::ScoreResult(bench::ReadResultCsv((dir / "short.csv").string(), ChapterScene(), ref), ref);
  EXPECT_TRUE(std::isnan(s.metrics.scd));
  EXPECT_TRUE(std::isinf(s.metrics.scd_compared));  // exact at the times it has
  EXPECT_EQ(s.metrics.compared_times, 3);
  EXPECT_EQ(s.metrics.missing_times, static_cast<int>(ref.times.size()) - 3);

  // The same file as R's write.csv or Python's csv.QUOTE_ALL writes it, every field in
  // double quotes, and with the reference's own spelling of a column ("F_ACL anterior_N" for
  // trajectory.csv's F_ACL_anterior_N): read as the plain file (before: "column '"time_s"' is
  // not a trajectory.csv column").
  {
    std::ofstream out(dir / "quoted.csv");
    out.precision(17);
    out << "\"time_s\",\"x0_mm\",\"y0_mm\",\"z0_mm\",\"flexion_deg\",\"valgus_deg\",\"external_rotation_deg\","
           "\"F_ACL anterior_N\"\n";
    for (int i = 0; i < 3; ++i) {
      out << '"' << ref.times[i] << '"';
      for (double v : ref.values.at("positions")[i]) out << ",\"" << v << '"';
      out << ",0\n";
    }
  }
  const bench::ScoredResult quoted = bench::ReadResultCsv((dir / "quoted.csv").string(), ChapterScene(), ref);
  EXPECT_EQ(quoted.columns.back(), "F_ACL_anterior_N");
  const bench::Score q = bench::ScoreResult(quoted, ref);
  EXPECT_TRUE(std::isinf(q.metrics.scd_compared));  // exact at the times it has, as short.csv
  EXPECT_EQ(q.metrics.compared_times, 3);

  {
    std::ofstream out(dir / "typo.csv");
    out << "time_s,flexon_deg\n0,0\n";
  }
  try {
    bench::ReadResultCsv((dir / "typo.csv").string(), ChapterScene(), ref);
    FAIL() << "an unknown column was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("flexon_deg"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("flexion_deg"), std::string::npos) << e.what();
  }
  {
    std::ofstream out(dir / "notime.csv");
    out << "flexion_deg\n0\n";
  }
  EXPECT_THROW(bench::ReadResultCsv((dir / "notime.csv").string(), ChapterScene(), ref), InputError);
  fs::remove_all(dir);
}

// A CSV's printing caps what a score can measure: the reference's own samples printed with
// 12 significant digits score about 11.3 (docs/problem.md), so the ceiling is 12 − 1 = 11 and
// that score is flagged above it; printed with 16 digits the reference's own ceiling
// (accuracy_scd 15.7 − 1) applies. Before, rows on the reference's times kept the 14.7 ceiling
// whatever the printing, and the 12-digit 11.34 read as a measured accuracy.
TEST(Score, PrintedDigitsCapTheCeiling) {
  const nlohmann::json& solution = Reference().json.at("solution");
  const nlohmann::json& positions = solution.at("classes").at("positions");
  const std::vector<double> times = solution.at("times_s").get<std::vector<double>>();
  const double stated = Reference().json.at("accuracy_scd").get<double>();
  for (const int digits : {12, 16}) {
    const fs::path csv = fs::temp_directory_path() / ("kneedyn_score_printed_" + std::to_string(digits) + "_" +
                                                      std::to_string(::getpid()) + ".csv");
    {
      std::ofstream out(csv);
      out << "time_s";
      for (const auto& name : positions.at("names")) out << "," << name.get<std::string>();
      out << "\n";
      char buf[64];
      for (size_t i = 0; i < times.size(); ++i) {
        std::snprintf(buf, sizeof(buf), "%.17g", times[i]);
        out << buf;
        for (const auto& v : positions.at("values").at(i)) {
          std::snprintf(buf, sizeof(buf), "%.*g", digits, v.get<double>());
          out << "," << buf;
        }
        out << "\n";
      }
    }
    const bench::ScoredResult result = bench::ReadResultCsv(csv.string(), ChapterScene(), Reference().solution);
    fs::remove(csv);
    EXPECT_EQ(result.printed_significant_digits, digits == 12 ? 12 : 16);
    const bench::ReferenceScore scored = bench::ScoreAgainstReference(
        ChapterScene(), Reference().json, Reference().solution, result, bench::OffGridRows::kNotCompared);
    const bench::Metrics& m = scored.score.metrics;
    std::printf("reference printed with %d digits: scd %.2f, ceiling %.2f, above %d\n", digits, m.scd, m.scd_ceiling,
                m.scd_above_ceiling);
    if (digits == 12) {
      EXPECT_EQ(m.scd_ceiling, 11.0);
      EXPECT_TRUE(m.scd_above_ceiling);
    } else {
      EXPECT_NEAR(m.scd_ceiling, stated - 1.0, 1e-12);
    }
  }
}

// Rows off the reference's sampling grid (docs/problem.md): the reference's own check
// configuration (ede dopri5 rtol 1e-13, which agrees with the stored samples to 11.2 digits)
// written every 5 ms scores >= 10 digits over all its rows, three quarters of them off the
// 20 ms grid, compared with the reference configuration run again there; a planted 1e-6 deg
// error on one off-grid row brings the scd to ~6 (so those rows count); and a reference
// whose recorded configuration cannot reproduce its samples is refused.
TEST(Score, RowsOffTheSamplingGridAreComparedWithTheReferenceRunAgain) {
  const Scene& scene = ChapterScene();
  RunSettings settings;
  settings.formulation = "ede";
  settings.options.integrator = IntegratorOption("dopri5");
  settings.options.rtol = 1e-13;
  settings.options.atol = 1e-15;
  settings.output_interval = 0.005;
  const RunResult run = RunScene(scene, settings);
  ASSERT_TRUE(run.completed) << run.failure;
  const fs::path dir = fs::temp_directory_path() / ("kneedyn_score_test_dense" + std::to_string(::getpid()));
  fs::remove_all(dir);
  WriteRunOutputs(dir.string(), scene, settings, run);
  const std::string csv = (dir / "trajectory.csv").string();
  const bench::Solution& stored = Reference().solution;
  bench::ScoredResult result = bench::ReadResultCsv(csv, scene, stored);
  const std::vector<double> off = bench::OffGridTimes(result, stored);
  ASSERT_GE(off.size(), 3 * (stored.times.size() - 1) - 3);  // 5 ms rows between the 20 ms ones
  double reproduced = 0.0;
  const bench::Solution dense = bench::DenseReference(scene, Reference().json, stored, off, &reproduced);
  // The stored reference is extended precision: its off-grid rows come from the double
  // configuration, which must reproduce the stored samples to kMinDenseReproductionScd
  // digits and then caps the score's ceiling (it is below the stated 15.7 digits).
  ASSERT_EQ(Reference().json.at("primary").value("formulation", ""), bench::kExtendedPrecisionFormulation);
  EXPECT_GE(reproduced, bench::kMinDenseReproductionScd);
  EXPECT_LT(reproduced, Reference().json.at("accuracy_scd").get<double>());
  EXPECT_EQ(bench::ScoreCeilingAccuracy(Reference().json, reproduced), reproduced);
  EXPECT_EQ(dense.times.size(), stored.times.size() + off.size());
  const bench::Score score = bench::ScoreResult(result, dense);
  std::printf("ede dopri5 1e-13 every 5 ms: scd %.2f over %d times (%zu off the grid); reference run again: %.2f\n",
              score.metrics.scd, score.metrics.compared_times, off.size(), reproduced);
  EXPECT_EQ(score.metrics.missing_times, 0);
  EXPECT_EQ(score.metrics.compared_times, static_cast<int>(dense.times.size()));
  EXPECT_GE(score.metrics.scd, 10.0);

  // One planted error on an off-grid row: flexion + 1e-6 deg at the first off-grid time.
  std::ifstream in(csv);
  std::stringstream text;
  text << in.rdbuf();
  std::istringstream lines(text.str());
  std::string header, line, out;
  std::getline(lines, header);
  out = header + "\n";
  std::vector<std::string> names;
  {
    std::istringstream h(header);
    std::string cell;
    while (std::getline(h, cell, ',')) names.push_back(cell);
  }
  const size_t flexion = std::find(names.begin(), names.end(), "flexion_deg") - names.begin();
  ASSERT_LT(flexion, names.size());
  bool planted = false;
  while (std::getline(lines, line)) {
    std::vector<std::string> cells;
    std::istringstream l(line);
    std::string cell;
    while (std::getline(l, cell, ',')) cells.push_back(cell);
    if (!planted && std::abs(std::stod(cells[0]) - off[0]) < 1e-12) {
      char buf[64];
      std::snprintf(buf, sizeof buf, "%.17g", std::stod(cells[flexion]) + 1e-6);
      cells[flexion] = buf;
      planted = true;
    }
    for (size_t k = 0; k < cells.size(); ++k) out += (k ? "," : "") + cells[k];
    out += "\n";
  }
  ASSERT_TRUE(planted);
  const fs::path bad_csv = dir / "planted.csv";
  std::ofstream(bad_csv) << out;
  const bench::ScoredResult bad = bench::ReadResultCsv(bad_csv.string(), scene, stored);
  const bench::Score bad_score = bench::ScoreResult(bad, dense);
  // |e| = 1e-6 deg over |α| + 1 deg, α(off[0]) < 1 deg at 5 ms: between 5.7 and 6.
  EXPECT_GT(bad_score.metrics.scd, 5.6);
  EXPECT_LT(bad_score.metrics.scd, 6.1);

  // Result times the run again gets a sample of its own for, one row each: 1e-11 s after the
  // scene's 5 ms outputs (two rows each and a 1e-11 s step before), and 5e-13 s after the
  // lift-off (merged with the event's sample, which was not taken: no row).
  const double liftoff = stored.events.at(0).time;
  ASSERT_EQ(stored.events.at(0).name, "liftoff_lateral");
  const std::vector<double> near = {0.005 + 1e-11, 0.01 + 1e-11, liftoff + 5e-13};
  const bench::Solution near_dense = bench::DenseReference(scene, Reference().json, stored, near, &reproduced);
  EXPECT_EQ(near_dense.times.size(), stored.times.size() + near.size());
  EXPECT_GE(reproduced, bench::kMinDenseReproductionScd);
  for (const double t : near) {
    EXPECT_EQ(std::count_if(near_dense.times.begin(), near_dense.times.end(),
                            [t](double s) { return std::abs(s - t) <= 1e-12; }),
              1)
        << t;
  }

  // A reference whose recorded configuration is too loose to reproduce its samples.
  nlohmann::json loose = Reference().json;
  loose["primary"] = {{"formulation", "ede"}, {"integrator", "dopri5"}, {"rtol", 1e-5}, {"atol", 1e-7},
                      {"command", "kneedyn run ... --formulation ede --integrator dopri5 --rtol 1e-5 --atol 1e-7"}};
  try {
    bench::DenseReference(scene, loose, stored, off, &reproduced);
    ADD_FAILURE() << "a reference reproduced to " << reproduced << " digits was accepted";
  } catch (const SolverError& e) {
    EXPECT_NE(std::string(e.what()).find("accuracy_scd"), std::string::npos) << e.what();
  }
  fs::remove_all(dir);
}

// What an outside solver's file can hold that no value does (found by probing `kneedyn
// score`): "inf", "nan" or a number past double's range in a cell was skipped or made the
// score "exact"; an empty coordinate, or a class whose every cell is empty, compared nothing
// and scored +inf digits; an empty or "inf" event time was accepted. Each is refused naming
// the file, line and column, or, for a class with nothing in common, has no figure (NaN).
// A byte-order mark before the header is read past; a row repeated off the sampling grid is
// one time to run the reference to, not two.
TEST(Score, NonFiniteCellsAndEmptyCoordinatesAreRefusedAndNothingComparedHasNoDigits) {
  const fs::path dir = fs::temp_directory_path() / ("kneedyn_score_cells_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  const bench::Solution& ref = Reference().solution;
  const auto write = [&](const std::string& name, const std::string& text) {
    std::ofstream((dir / name).string(), std::ios::binary) << text;
    return (dir / name).string();
  };
  // The reference's own positions at its first three times.
  std::ostringstream rows;
  rows.precision(17);
  for (int i = 0; i < 3; ++i) {
    rows << ref.times[i];
    for (double v : ref.values.at("positions")[i]) rows << "," << v;
    rows << "\n";
  }
  const std::string header = "time_s,x0_mm,y0_mm,z0_mm,flexion_deg,valgus_deg,external_rotation_deg\n";
  const auto refusal = [&](const std::string& path) {
    try {
      bench::ReadResultCsv(path, ChapterScene(), ref);
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  for (const char* bad : {"inf", "-inf", "nan", "1e999"}) {
    const std::string path = write("bad.csv", header + rows.str() + "0.06,1,1,1," + bad + ",1,1\n");
    EXPECT_NE(refusal(path).find(std::string("line 5, column flexion_deg: '") + bad + "' is not a finite number"),
              std::string::npos)
        << refusal(path);
  }
  const std::string empty_cell = write("empty.csv", header + rows.str() + "0.06,1,1,1,,1,1\n");
  EXPECT_NE(refusal(empty_cell).find("line 5, column flexion_deg: empty"), std::string::npos) << refusal(empty_cell);
  const std::string empty_time = write("empty_time.csv", header + rows.str() + ",1,1,1,1,1,1\n");
  EXPECT_NE(refusal(empty_time).find("line 5, column time_s: empty"), std::string::npos) << refusal(empty_time);

  // A byte-order mark: the same score as without it (exact at these three times).
  const bench::Score with_bom = bench::ScoreResult(
      bench::ReadResultCsv(write("bom.csv", "\xEF\xBB\xBF" + header + rows.str()), ChapterScene(), ref), ref);
  EXPECT_EQ(with_bom.metrics.compared_times, 3);
  EXPECT_TRUE(std::isinf(with_bom.metrics.scd_compared) && with_bom.metrics.scd_compared > 0);

  // Contact points given but empty in every row: no figure for that class, not "exact".
  std::ostringstream points;
  points << "time_s,femoral_medial_x_mm\n";
  for (int i = 0; i < 3; ++i) points << ref.times[i] << ",\n";
  const bench::Score none =
      bench::ScoreResult(bench::ReadResultCsv(write("points.csv", points.str()), ChapterScene(), ref), ref);
  EXPECT_TRUE(std::isnan(none.mescd.at("contact_points"))) << none.mescd.at("contact_points");
  EXPECT_TRUE(std::isnan(none.metrics.scd_compared));  // no position columns either

  // A row repeated at a time between two sampling times: one off-grid time.
  const double mid = 0.5 * (ref.times[1] + ref.times[2]);
  std::ostringstream repeated;
  repeated.precision(17);
  repeated << header << ref.times[0] << ",1,1,1,1,1,1\n";
  for (int k = 0; k < 2; ++k) repeated << mid << ",1,1,1,1,1,1\n";
  const bench::ScoredResult r = bench::ReadResultCsv(write("repeated.csv", repeated.str()), ChapterScene(), ref);
  EXPECT_EQ(bench::OffGridTimes(r, ref), std::vector<double>{mid});
  // Two rows at one time that differ: which is the solution there? Refused, naming the line
  // (before, the second was ignored: a 1-degree error in it left the score unchanged), unless
  // one of them is an event row.
  std::ostringstream differ;
  differ.precision(17);
  differ << header << ref.times[0] << ",1,1,1,1,1,1\n" << mid << ",1,1,1,1,1,1\n" << mid << ",1,1,1,2,1,1\n";
  EXPECT_NE(refusal(write("differ.csv", differ.str())).find("line 4: time"), std::string::npos)
      << refusal(write("differ.csv", differ.str()));
  std::ostringstream event_pair;
  event_pair.precision(17);
  event_pair << "time_s,x0_mm,y0_mm,z0_mm,flexion_deg,valgus_deg,external_rotation_deg,is_event\n"
             << ref.times[0] << ",1,1,1,1,1,1,0\n" << mid << ",1,1,1,1,1,1,1\n" << mid << ",1,1,1,2,1,1,0\n";
  const bench::ScoredResult left_right = bench::ReadResultCsv(write("pair.csv", event_pair.str()), ChapterScene(), ref);
  EXPECT_EQ(left_right.rows, 3u);
  EXPECT_EQ(left_right.solution.values.at("positions").back()[3], 2.0);  // the row after the event row is kept
  // is_event is 1, 0 or empty: 2 or -1 read as "not an event" before.
  for (const char* flag : {"2", "-1", "0.5"}) {
    std::ostringstream flagged;
    flagged.precision(17);
    flagged << "time_s,x0_mm,y0_mm,z0_mm,flexion_deg,valgus_deg,external_rotation_deg,is_event\n"
            << ref.times[0] << ",1,1,1,1,1,1," << flag << "\n";
    EXPECT_NE(refusal(write("flag.csv", flagged.str())).find(std::string("line 2, column is_event: '") + flag + "'"),
              std::string::npos)
        << refusal(write("flag.csv", flagged.str()));
  }

  // Event times: empty or not finite is refused; flexion may be empty.
  for (const char* time : {"", "inf", "nan"}) {
    const std::string events = write("events.csv", std::string("name,time_s,flexion_deg\nflexion_90,") + time + ",\n");
    try {
      bench::ReadEvents(events);
      ADD_FAILURE() << "event time '" << time << "' accepted";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find("line 2, column time_s"), std::string::npos) << e.what();
    }
  }
  EXPECT_EQ(bench::ReadEvents(write("events.csv", "\xEF\xBB\xBFname,time_s,flexion_deg\nflexion_90,0.3,\n")).events.size(), 1u);
  // The header `time`, as the result CSV accepts it.
  EXPECT_EQ(bench::ReadEvents(write("events.csv", "name,time\nflexion_90,0.3\n")).events.at(0).time, 0.3);

  // A reference's comparison interval must be > 0 (it spaces the reference run again).
  nlohmann::json zero = Reference().json;
  zero["comparison_interval_s"] = 0.0;
  try {
    bench::CheckReferenceFields(zero, "REF");
    ADD_FAILURE() << "comparison_interval_s = 0 accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("field 'comparison_interval_s' = 0: must be > 0 s"), std::string::npos)
        << e.what();
  }
  fs::remove_all(dir);
}

// The scd is over the six generalized coordinates (docs/problem.md): the reference's own rows
// with one coordinate column have no scd, though that column is exact (before: scd 11.28 for
// x0 alone, above the 10.08 of the complete result it came from). The end row is the state
// at the reference's end event (flexion_90): its time is scored as that event's, so an end row
// 1 ms late gives the event −log10(1e-3 / t_end) digits (before: never compared), rows past the
// reference's end are counted, and an events file that puts the end event elsewhere than the
// end row is refused.
TEST(Score, ScdNeedsEveryCoordinateAndTheEndRowsTimeIsTheEndEvents) {
  const fs::path dir = fs::temp_directory_path() / ("kneedyn_score_end_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  const bench::Solution& ref = Reference().solution;
  ASSERT_TRUE(ref.end_is_event);
  ASSERT_EQ(bench::ReferenceEndEventName(ref), "flexion_90");
  const size_t n = ref.times.size();
  const double t_end = ref.times.back();
  // The reference's own rows (17 digits: exact), the last one as the end row at `end_time`,
  // with `extra_rows` copies of the end state at times between the reference's end and it.
  const auto write = [&](const std::string& name, bool only_x0, double end_time, int extra_rows) {
    std::ofstream out(dir / name);
    out.precision(17);
    out << (only_x0 ? "time_s,x0_mm,is_event\n" : "time_s,x0_mm,y0_mm,z0_mm,flexion_deg,valgus_deg,external_rotation_deg,is_event\n");
    const auto row = [&](double t, size_t i, int event) {
      out << t;
      const std::vector<double>& p = ref.values.at("positions")[i];
      for (size_t j = 0; j < (only_x0 ? 1 : p.size()); ++j) out << "," << p[j];
      out << "," << event << "\n";
    };
    for (size_t i = 0; i + 1 < n; ++i) row(ref.times[i], i, 0);
    for (int k = 1; k <= extra_rows; ++k) row(t_end + k * (end_time - t_end) / (extra_rows + 1), n - 1, 0);
    row(end_time, n - 1, 1);
    return (dir / name).string();
  };
  const bench::Score whole = bench::ScoreResult(
      bench::ReadResultCsv(write("whole.csv", false, t_end, 0), ChapterScene(), ref), ref);
  EXPECT_TRUE(std::isinf(whole.metrics.scd)) << whole.metrics.scd;  // the reference's own rows
  const bench::Score x0 = bench::ScoreResult(
      bench::ReadResultCsv(write("x0.csv", true, t_end, 0), ChapterScene(), ref), ref);
  EXPECT_TRUE(std::isnan(x0.metrics.scd)) << x0.metrics.scd;
  EXPECT_TRUE(std::isnan(x0.metrics.scd_compared)) << x0.metrics.scd_compared;
  EXPECT_TRUE(std::isinf(x0.mescd.at("positions")));  // the column given is still compared

  bench::ScoredResult late = bench::ReadResultCsv(write("late.csv", false, t_end + 1e-3, 2), ChapterScene(), ref);
  EXPECT_EQ(late.rows_after_reference_end, 2u);
  bench::ReconcileEndEvent(ref, "the result", false, &late);
  const bench::Score scored = bench::ScoreResult(late, ref);
  EXPECT_NEAR(scored.event_digits.at("flexion_90"), -std::log10(1e-3 / t_end), 1e-6);

  bench::ScoredResult contradicted = bench::ReadResultCsv(write("late2.csv", false, t_end + 1e-3, 0), ChapterScene(), ref);
  contradicted.solution.events.push_back({"flexion_90", t_end, DegToRad(90.0)});
  try {
    bench::ReconcileEndEvent(ref, "--events = 'e.csv'", false, &contradicted);
    FAIL() << "an end event away from the end row was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("--events = 'e.csv': event flexion_90"), std::string::npos) << e.what();
  }

  // A failed result's last event row is where it stopped, not the end event: none is added
  // (before the rule: a flexion_90 at the lift-off's 52.6°). Nor is one for a completed
  // result whose last event row is at another flexion than the reference's end.
  bench::ScoredResult failed = bench::ReadResultCsv(write("failed.csv", false, t_end + 1e-3, 0), ChapterScene(), ref);
  bench::ReconcileEndEvent(ref, "the result", true, &failed);
  EXPECT_TRUE(failed.solution.events.empty());
  bench::ScoredResult elsewhere = bench::ReadResultCsv(write("elsewhere.csv", false, t_end, 0), ChapterScene(), ref);
  elsewhere.solution.values.at("positions").back()[3] -= 37.4;  // the end row at the lift-off's 52.6°
  bench::ReconcileEndEvent(ref, "the result", false, &elsewhere);
  EXPECT_TRUE(elsewhere.solution.events.empty());
  fs::remove_all(dir);
}

}  // namespace
}  // namespace kneedyn
