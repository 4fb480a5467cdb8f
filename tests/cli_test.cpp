// Tests of the command line `kneedyn run` (app/kneedyn_main.cpp).
//
// Validates: a chapter run exits 0 and writes trajectory.csv (named columns with units),
// trajectory.sto (OpenSim storage: endheader, inDegrees=yes, tab-separated) and
// summary.json (status, events, statistics, initialization, wall time); bad input exits
// with code 2, names the field and value and writes nothing; a solver failure exits 1 and
// writes results marked partial with the failure; no temporary files are left behind.
// Does not validate: the numbers in the files (dae_test.cpp, conformance_test.cpp).
#include <gtest/gtest.h>

#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include <ceres/version.h>
#include <sundials/sundials_config.h>

#include "scene/scene.hpp"
#include "tests/cli_support.hpp"

namespace kneedyn {
namespace {

namespace fs = std::filesystem;

std::string ChapterScenePath() { return ReferenceDataDir() + "/scenes/chapter_impact.yaml"; }

// The exit-code contract (0, 1, 2, never a signal) is checked on every kneedyn call.
using cli_test::CommandResult;
using cli_test::RunKneedyn;
using cli_test::RunShell;

// Refusals of a program other than `kneedyn`: `command` followed by each case's arguments
// exits 2 with a message that begins "<program>: error: " and holds the case's needle;
// `ran_marker` (what the program prints once it runs) never appears, and `not_written`
// (when given) does not exist afterwards.
void ExpectRefusedBeforeRunning(const std::string& command, const std::string& program,
                                const std::vector<std::pair<std::string, std::string>>& cases,
                                const std::string& ran_marker, const fs::path& not_written = {}) {
  for (const auto& [args, needle] : cases) {
    const CommandResult r = RunShell(command + args);
    EXPECT_EQ(r.exit_code, 2) << args << "\n" << r.output;
    EXPECT_EQ(r.output.rfind(program + ": error: ", 0), 0u) << r.output;
    EXPECT_NE(r.output.find(needle), std::string::npos) << r.output;
    EXPECT_EQ(r.output.find(ran_marker), std::string::npos) << "ran before refusing: " << r.output;
    if (!not_written.empty()) {
      EXPECT_FALSE(fs::exists(not_written)) << args;
    }
  }
}

// A fresh, empty temporary directory per test; removed at the end.
class CliTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = fs::temp_directory_path() /
           (std::string("kneedyn_cli_test_") + info->name() + "_" + std::to_string(::getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  std::string Out() const { return (dir_ / "out").string(); }

  // Files anywhere under the directory, excluding `keep` (inputs the test wrote).
  std::vector<std::string> FilesUnder(const fs::path& where, const std::string& keep = "") const {
    std::vector<std::string> files;
    if (!fs::exists(where)) return files;
    for (const auto& e : fs::recursive_directory_iterator(where)) {
      if (e.is_regular_file() && e.path().filename() != keep) files.push_back(e.path().string());
    }
    return files;
  }

  void ExpectNoTempFiles() const {
    for (const std::string& f : FilesUnder(dir_)) {
      EXPECT_EQ(f.find(".tmp"), std::string::npos) << "leftover " << f;
    }
  }

  // Bad input: exit code 2, a message with every needle, and nothing written.
  void ExpectRefused(const std::string& args, const std::vector<std::string>& needles,
                     const std::string& keep = "") {
    const CommandResult r = RunKneedyn(args);
    EXPECT_EQ(r.exit_code, 2) << args << "\n" << r.output;
    for (const std::string& n : needles) {
      EXPECT_NE(r.output.find(n), std::string::npos) << "'" << n << "' missing from: " << r.output;
    }
    EXPECT_TRUE(FilesUnder(dir_, keep).empty()) << args << " left files behind";
  }

  fs::path dir_;
};

std::string ReadText(const fs::path& p) {
  std::ifstream in(p);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

std::vector<std::string> Split(const std::string& line, char sep) {
  std::vector<std::string> out;
  std::stringstream ss(line);
  std::string item;
  while (std::getline(ss, item, sep)) out.push_back(item);
  return out;
}

bool Contains(const std::vector<std::string>& v, const std::string& s) {
  return std::find(v.begin(), v.end(), s) != v.end();
}

TEST_F(CliTest, ChapterRunWritesTrajectoryStorageAndSummary) {
  const CommandResult r = RunKneedyn("run '" + ChapterScenePath() + "' --formulation dae --quiet --out '" + Out() + "'");
  ASSERT_EQ(r.exit_code, 0) << r.output;

  // trajectory.csv: header with units.
  const std::string csv = ReadText(fs::path(Out()) / "trajectory.csv");
  ASSERT_FALSE(csv.empty());
  const std::string header = csv.substr(0, csv.find('\n'));
  const std::vector<std::string> cols = Split(header, ',');
  const std::vector<std::string> expected = {
      "time_s", "flexion_deg", "N_medial_N", "N_lateral_N", "gap_medial_mm", "gap_lateral_mm",
      "F_ACL_anterior_N", "F_ACL_posterior_N", "F_PCL_anterior_N", "F_PCL_posterior_N",
      "F_MCL_anterior_N", "F_MCL_oblique_N", "F_MCL_deep_N", "F_LCL_N", "F_capsule_medial_N",
      "F_capsule_lateral_N", "F_oblique_popliteal_N", "F_arcuate_popliteal_N"};
  for (const std::string& c : expected) EXPECT_TRUE(Contains(cols, c)) << c << " missing in: " << header;
  EXPECT_EQ(cols.front(), "time_s");
  // Data rows have as many fields as the header.
  std::stringstream lines(csv);
  std::string line;
  std::getline(lines, line);
  int rows = 0;
  while (std::getline(lines, line)) {
    if (line.empty()) continue;
    ++rows;
    EXPECT_EQ(Split(line + ",", ',').size(), cols.size()) << "row " << rows;
  }
  EXPECT_GT(rows, 50);

  // First row (reference pose): element lengths and strains as docs/model.md §10 gives them, e.g.
  // LCL L_ref = 62.572977 mm, L0 = 59.593311 mm, strain = e − 1 = 0.05 (Table 1.3).
  {
    std::stringstream again(csv);
    std::string first;
    std::getline(again, first);
    std::getline(again, first);
    const std::vector<std::string> v = Split(first + ",", ',');
    auto value = [&](const std::string& col) {
      const auto it = std::find(cols.begin(), cols.end(), col);
      EXPECT_NE(it, cols.end()) << col;
      return it == cols.end() ? std::nan("") : std::stod(v[it - cols.begin()]);
    };
    EXPECT_NEAR(value("L_LCL_mm"), 62.572977, 1e-6);
    EXPECT_NEAR(value("strain_LCL"), 1.050 - 1.0, 1e-9);  // e − 1 exactly (L0 = L_ref / e)
    EXPECT_NEAR(value("L_MCL_anterior_mm"), 71.324532, 1e-6);
    EXPECT_NEAR(value("strain_MCL_anterior"), 0.94 - 1.0, 1e-9);  // slack at extension
  }

  // trajectory.sto: OpenSim storage.
  const std::string sto = ReadText(fs::path(Out()) / "trajectory.sto");
  EXPECT_NE(sto.find("inDegrees=yes"), std::string::npos);
  const size_t end_header = sto.find("endheader\n");
  ASSERT_NE(end_header, std::string::npos);
  const std::string sto_cols_line =
      sto.substr(end_header + 10, sto.find('\n', end_header + 10) - (end_header + 10));
  const std::vector<std::string> sto_cols = Split(sto_cols_line, '\t');
  EXPECT_EQ(sto_cols.size(), cols.size()) << sto_cols_line;
  EXPECT_EQ(sto_cols.front(), "time");
  EXPECT_TRUE(Contains(sto_cols, "flexion_deg"));

  // summary.json.
  const nlohmann::json j = nlohmann::json::parse(ReadText(fs::path(Out()) / "summary.json"));
  EXPECT_EQ(j.at("status"), "completed");
  // The parameter set's file as read, absolute (a copy of a set keeps the set's name).
  EXPECT_TRUE(fs::equivalent(j.at("scene").at("parameter_set_file").get<std::string>(),
                             fs::path(KNEEDYN_SOURCE_DIR) / "reference-data" / "chapter_knee.yaml"))
      << j.at("scene").dump();
  EXPECT_TRUE(fs::path(j.at("scene").at("parameter_set_file").get<std::string>()).is_absolute());
  const auto& events = j.at("events");
  ASSERT_GE(events.size(), 2u);
  std::vector<std::string> names;
  for (const auto& e : events) {
    names.push_back(e.at("name").get<std::string>());
    EXPECT_TRUE(e.at("time").is_number());
    EXPECT_TRUE(e.at("flexion_deg").is_number());
  }
  EXPECT_EQ(names.front(), "liftoff_lateral");
  EXPECT_EQ(names.back(), "flexion_90");
  EXPECT_NEAR(events.back().at("flexion_deg").get<double>(), 90.0, 1e-6);
  const auto& stats = j.at("statistics");
  for (const char* k : {"steps", "residual_evaluations", "jacobian_evaluations", "nonlinear_iterations"}) {
    EXPECT_GT(stats.at(k).get<long>(), 0) << k;
  }
  for (const char* k : {"error_test_failures", "convergence_failures"}) {
    EXPECT_GE(stats.at(k).get<long>(), 0) << k;
  }
  const auto& init = j.at("initialization");
  for (const char* level : {"position", "velocity", "hidden_constraint"}) {
    EXPECT_TRUE(init.at(level).at("residual_before").is_number()) << level;
    EXPECT_TRUE(init.at(level).at("residual_after").is_number()) << level;
  }
  EXPECT_GT(init.at("position").at("residual_before").get<double>(),
            init.at("position").at("residual_after").get<double>());
  // Four coordinates held: square systems, solved by Newton's method directly.
  EXPECT_EQ(init.at("position").at("method"), "newton");
  EXPECT_EQ(init.at("hidden_constraint").at("method"), "newton");
  EXPECT_EQ(init.at("velocity").at("method"), "none");
  // docs/model.md §10: consistent forces, N_medial ≈ 233.35 N, N_lateral ≈ 243.33 N.
  const auto& forces = init.at("normal_force_N");
  EXPECT_NEAR(forces.at("medial").get<double>(), 233.35, 0.0051);
  EXPECT_NEAR(forces.at("lateral").get<double>(), 243.33, 0.0051);
  EXPECT_EQ(init.at("normal_force_guess_N").size(), 2u);
  EXPECT_GT(j.at("wall_time_s").get<double>(), 0.0);
  ExpectNoTempFiles();
}

TEST_F(CliTest, UnknownFormulationIsRefusedWithoutOutput) {
  ExpectRefused("run '" + ChapterScenePath() + "' --formulation nosuch --quiet --out '" + Out() + "'",
                {"nosuch"});
}

TEST_F(CliTest, NegativeRtolIsRefusedWithoutOutput) {
  ExpectRefused("run '" + ChapterScenePath() + "' --rtol -1 --quiet --out '" + Out() + "'", {"rtol", "-1"});
}

TEST_F(CliTest, NanRtolIsRefusedWithoutOutput) {
  ExpectRefused("run '" + ChapterScenePath() + "' --rtol nan --quiet --out '" + Out() + "'", {"rtol", "nan"});
}

// --jacobian: an unknown value and a formulation without a Newton matrix
// of its own are refused (exit 2, nothing written); the choice is recorded in summary.json.
TEST_F(CliTest, JacobianOptionIsCheckedAndRecorded) {
  ExpectRefused("run '" + ChapterScenePath() + "' --jacobian symbolic --quiet --out '" + Out() + "'",
                {"--jacobian", "symbolic"});
  ExpectRefused("run '" + ChapterScenePath() + "' --formulation ede --jacobian jet --quiet --out '" + Out() + "'",
                {"--jacobian", "jet", "ede"});
  for (const char* jacobian : {"jet", "difference-quotient"}) {
    fs::remove_all(Out());
    const CommandResult r = RunKneedyn("run '" + ChapterScenePath() + "' --formulation dae-reduced --jacobian " +
                                       jacobian + " --quiet --out '" + Out() + "'");
    ASSERT_EQ(r.exit_code, 0) << r.output;
    const nlohmann::json j = nlohmann::json::parse(ReadText(fs::path(Out()) / "summary.json"));
    EXPECT_EQ(j.at("settings").at("jacobian"), jacobian);
  }
  fs::remove_all(Out());
  const CommandResult r = RunKneedyn("run '" + ChapterScenePath() + "' --formulation mde --quiet --out '" + Out() + "'");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(nlohmann::json::parse(ReadText(fs::path(Out()) / "summary.json")).at("settings").at("jacobian").is_null());
}

// --contact-chart is read as text like the other names (CLI11's enum transformer accepted
// "0" and "1" and answered in its own words), and summary.json records the chart run: the
// two charts give different rounding, so the trajectories differ while the settings must too.
TEST_F(CliTest, ContactChartIsCheckedAndRecorded) {
  for (const char* bad : {"1", "height_field"}) {
    ExpectRefused("run '" + ChapterScenePath() + "' --contact-chart " + bad + " --quiet --out '" + Out() + "'",
                  {"--contact-chart", std::string("'") + bad + "'", "regular or height-field"});
  }
  std::string trajectory[2];
  const char* charts[2] = {"", "height-field"};
  for (int i = 0; i < 2; ++i) {
    fs::remove_all(Out());
    const std::string flag = *charts[i] ? std::string(" --contact-chart ") + charts[i] : "";
    const CommandResult r = RunKneedyn("run '" + ChapterScenePath() + "'" + flag + " --quiet --out '" + Out() + "'");
    ASSERT_EQ(r.exit_code, 0) << r.output;
    const nlohmann::json j = nlohmann::json::parse(ReadText(fs::path(Out()) / "summary.json"));
    EXPECT_EQ(j.at("settings").at("contact_chart"), *charts[i] ? charts[i] : "regular");
    trajectory[i] = ReadText(fs::path(Out()) / "trajectory.csv");
  }
  EXPECT_NE(trajectory[0], trajectory[1]) << "--contact-chart height-field changed nothing";
}

TEST_F(CliTest, MalformedSceneIsRefusedWithoutOutput) {
  std::string text = ReadText(ChapterScenePath());
  const std::string from = "amplitude_N: 100.0";
  ASSERT_NE(text.find(from), std::string::npos);
  text.replace(text.find(from), from.size(), "amplitude_N: abc");
  // The temp dir is elsewhere: point the parameter set at its absolute path.
  const std::string ps = "parameter_set: ../chapter_knee.yaml";
  ASSERT_NE(text.find(ps), std::string::npos);
  text.replace(text.find(ps), ps.size(), "parameter_set: " + ReferenceDataDir() + "/chapter_knee.yaml");
  const fs::path bad = dir_ / "bad_scene.yaml";
  {
    std::ofstream out(bad);
    out << text;
  }
  ExpectRefused("run '" + bad.string() + "' --quiet --out '" + Out() + "'", {"amplitude_N", "abc"},
                "bad_scene.yaml");
}

TEST_F(CliTest, MissingSceneFileIsRefusedWithoutOutput) {
  const std::string missing = (dir_ / "no_such_scene.yaml").string();
  ExpectRefused("run '" + missing + "' --quiet --out '" + Out() + "'", {"no_such_scene.yaml"});
}

TEST_F(CliTest, SolverFailureExitsOneWithPartialSummary) {
  const CommandResult r =
      RunKneedyn("run '" + ChapterScenePath() + "' --max-steps 5 --quiet --out '" + Out() + "'");
  EXPECT_EQ(r.exit_code, 1) << r.output;
  const fs::path summary = fs::path(Out()) / "summary.json";
  ASSERT_TRUE(fs::exists(summary));
  const nlohmann::json j = nlohmann::json::parse(ReadText(summary));
  EXPECT_EQ(j.at("status"), "partial");
  const std::string failure = j.at("failure").get<std::string>();
  EXPECT_NE(failure.find("IDA"), std::string::npos) << failure;
  EXPECT_NE(failure.find("t ="), std::string::npos) << failure;
  EXPECT_TRUE(fs::exists(fs::path(Out()) / "trajectory.csv"));
  EXPECT_NE(ReadText(fs::path(Out()) / "trajectory.sto").find("PARTIAL"), std::string::npos);
  ExpectNoTempFiles();
}


// reference-data/ is found at run time beside the executable (no source path in
// the binary); KNEEDYN_DATA_DIR overrides it. A scene naming its parameter set by a bare
// file name that is not beside the scene resolves it in the data directory.
// hard/jcs_crossing: beta(t) = 1 deg - 1 rad/s t crosses 0 at t = 0.017453 s. dae stepped
// over the band |sin beta| < 1e-3 and completed with angles past the singularity (exit 0);
// with output rows inside the band an output row threw and the run exited 2 with nothing
// written. Both are solver failures now (exit 1, partial results up to the singularity).
TEST_F(CliTest, RunThroughTheJcsSingularityIsASolverFailureWithPartialResults) {
  const std::string scene = ReferenceDataDir() + "/scenes/hard/jcs_crossing.yaml";
  const double t_cross = 1.0 * M_PI / 180.0;
  for (const char* extra : {"", " --output-interval 0.0005"}) {
    fs::remove_all(Out());
    const CommandResult r = RunKneedyn("run '" + scene + "'" + extra + " --quiet --out '" + Out() + "'");
    EXPECT_EQ(r.exit_code, 1) << extra << "\n" << r.output;
    EXPECT_NE(r.output.find("JCS singularity"), std::string::npos) << r.output;
    const nlohmann::json j = nlohmann::json::parse(ReadText(fs::path(Out()) / "summary.json"));
    EXPECT_EQ(j.at("status"), "partial");
    const std::vector<std::string> lines = Split(ReadText(fs::path(Out()) / "trajectory.csv"), '\n');
    ASSERT_GE(lines.size(), 3u);
    const double last_t = std::stod(Split(lines.back(), ',')[0]);
    EXPECT_LT(last_t, t_cross) << extra;
    EXPECT_GT(last_t, t_cross - 0.005 - 1e-9) << extra;  // within one output interval of it
  }
}

TEST_F(CliTest, DataDirectoryIsFoundBesideTheExecutableAndOverriddenByEnvironment) {
  const fs::path scene = dir_ / "bare_parameter_set.yaml";
  {
    std::string text = ReadText(ChapterScenePath());
    const std::string ps = "parameter_set: ../chapter_knee.yaml";
    ASSERT_NE(text.find(ps), std::string::npos);
    text.replace(text.find(ps), ps.size(), "parameter_set: chapter_knee.yaml");
    std::ofstream(scene) << text;
  }
  // From an unrelated working directory with the override unset: found beside the binary.
  const std::string in_tmp = "cd '" + dir_.string() + "' && env -u KNEEDYN_DATA_DIR ";
  CommandResult r = RunShell(in_tmp + "'" + KNEEDYN_EXE + "' info '" + scene.string() + "'");
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("consistent normal force"), std::string::npos) << r.output;
  // The override wins, and a wrong one is named in the message.
  const std::string bogus = (dir_ / "no_data_here").string();
  r = RunShell("KNEEDYN_DATA_DIR='" + bogus + "' '" + KNEEDYN_EXE + "' info '" + scene.string() + "'");
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find(bogus), std::string::npos) << r.output;
}


// --version names kneedyn's version (CMake's project version), the git commit the
// build came from (when the source tree is a git repository: git's own answer) and the
// library versions of the headers this test was compiled against.
TEST_F(CliTest, VersionNamesVersionCommitAndLibraries) {
  const CommandResult r = RunKneedyn("--version");
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find(std::string("kneedyn ") + KNEEDYN_PROJECT_VERSION), std::string::npos) << r.output;
  EXPECT_NE(r.output.find(std::string("SUNDIALS ") + SUNDIALS_VERSION), std::string::npos) << r.output;
  EXPECT_NE(r.output.find(std::string("Ceres ") + CERES_VERSION_STRING), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("Eigen 3."), std::string::npos) << r.output;
  // Where `score` finds its default reference and relative parameter sets: the build tree's
  // share/kneedyn (its link to reference-data/).
  EXPECT_NE(r.output.find("data directory: "), std::string::npos) << r.output;
  EXPECT_TRUE(fs::exists(fs::path(r.output.substr(r.output.find("data directory: ") + 16,
                                                  r.output.find('\n', r.output.find("data directory: ")) -
                                                      r.output.find("data directory: ") - 16)) /
                         "references" / "chapter_impact.json"))
      << r.output;
  EXPECT_EQ(r.output.find("(not found"), std::string::npos) << r.output;
  // A data directory without scenes/ is named as not found (before: named as if found).
  const CommandResult missing =
      RunShell(std::string("KNEEDYN_DATA_DIR=/nonexistent/kneedyn_data '") + KNEEDYN_EXE + "' --version");
  EXPECT_EQ(missing.exit_code, 0) << missing.output;
  EXPECT_NE(missing.output.find("data directory: /nonexistent/kneedyn_data (not found: no scenes/ there; set "
                                "KNEEDYN_DATA_DIR)"),
            std::string::npos)
      << missing.output;
  const CommandResult git =
      RunShell(std::string("git -C '") + KNEEDYN_SOURCE_DIR + "' rev-parse --short=12 HEAD");
  if (git.exit_code == 0 && fs::exists(fs::path(KNEEDYN_SOURCE_DIR) / ".git")) {
    const std::string commit = git.output.substr(0, 12);
    EXPECT_NE(r.output.find("git " + commit), std::string::npos) << r.output << " vs HEAD " << commit;
  } else {
    EXPECT_NE(r.output.find("not built from git"), std::string::npos) << r.output;
  }
}

// Every argument error exits 2, names the offending argument and writes nothing.
TEST_F(CliTest, ArgumentErrorsExitTwoAndNameTheArgument) {
  const std::string scene = "'" + ChapterScenePath() + "'";
  const std::string out = " --out '" + Out() + "'";
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"rnu " + scene + out, "'rnu'"},                      // mistyped subcommand
      {"run " + scene + " --rtol abc" + out, "--rtol"},     // not a number
      {"run " + scene + " --max-steps 1.5" + out, "--max-steps"},
      {"run " + scene + " --bogus" + out, "--bogus"},       // unknown option
      {"run " + scene + " --rtol" , "--rtol"},              // missing value
      {"run" + out, "scene"},                               // missing positional
      {"info", "scene"},
      {"", "subcommand"},
      {"--rtol 3 run " + scene + out, "--rtol"},             // option before the subcommand
      {"--rtol 3", "'--rtol'"},                            // ... and no subcommand
  };
  for (const auto& [args, named] : cases) {
    const CommandResult r = RunKneedyn(args);
    EXPECT_EQ(r.exit_code, 2) << "kneedyn " << args << "\n" << r.output;
    EXPECT_NE(r.output.find(named), std::string::npos) << "kneedyn " << args << "\n" << r.output;
    EXPECT_FALSE(fs::exists(Out())) << "kneedyn " << args;
  }
}

// The other tools keep the same contract; work_precision --help works.
TEST_F(CliTest, CatalogAndWorkPrecisionKeepTheContract) {
  CommandResult r = RunShell(std::string("'") + KNEEDYN_WORK_PRECISION_EXE + "' --help");
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("--short"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("--repetitions"), std::string::npos) << r.output;
  r = RunShell(std::string("'") + KNEEDYN_WORK_PRECISION_EXE + "' --shrot");
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("--shrot"), std::string::npos) << r.output;
  r = RunShell(std::string("'") + KNEEDYN_WORK_PRECISION_EXE + "' --repetitions 1");
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("--repetitions"), std::string::npos) << r.output;
  // Refused before the sweep runs (exit 2, no progress line, nothing written): an --only that
  // names no configuration (Google Benchmark then wrote no JSON: abort, exit 134) and a --json
  // or --csv that cannot be written (abort after the sweep, or exit 2 after it with the JSON
  // already written).
  const fs::path a_file = fs::path(Out()).parent_path() / "a_file";
  std::ofstream(a_file) << "x";
  const std::string json = (fs::path(Out()).parent_path() / "wp.json").string();
  ExpectRefusedBeforeRunning(
      std::string("'") + KNEEDYN_WORK_PRECISION_EXE + "'", "work_precision",
      {{" --short --only no_such_method --json '" + json + "'", "--only = 'no_such_method': no configuration"},
       {" --short --only dae-ggl-reduced --json '" + (a_file / "wp.json").string() + "'", "--json = '"},
       {" --short --only dae-ggl-reduced --json '" + json + "' --csv '" + (a_file / "wp.csv").string() + "'",
        "--csv = '"},
       // CLI::Range printed its bounds as "0.000000 to 0.010000", the lower one 0 for 1e-300.
       {" --short --rtol-min 1e-301 --json '" + json + "'", "--rtol-min: '1e-301' must lie in [1e-300, 1e-2]"}},
      "[1/", json);
  r = RunShell(std::string("'") + KNEEDYN_CATALOG_EXE + "' --case");
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("--case"), std::string::npos) << r.output;
  // A selection with no run is refused (before: "wrote … (0 runs)", and --check passed with
  // nothing checked): index3_position_level runs the formulations that accept
  // --constraint-level position, which ede does not (its capability, `kneedyn formulations`).
  const std::string catalog_out = (fs::path(Out()).parent_path() / "catalog_none").string();
  r = RunShell(std::string("'") + KNEEDYN_CATALOG_EXE + "' --out '" + catalog_out +
               "' --case index3_position_level --formulation ede --check");
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("--case index3_position_level, --formulation ede: the selection has no run"),
            std::string::npos)
      << r.output;
  EXPECT_FALSE(fs::exists(catalog_out));
  r = RunShell(std::string("'") + KNEEDYN_CATALOG_EXE + "' --version");
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find(KNEEDYN_PROJECT_VERSION), std::string::npos) << r.output;
}

// make_reference refuses bad settings before its runs (an hour for the extended method), with
// exit 2 and nothing written: --interval 0 looped without end; a bad --rtol or --check-rtol was
// recorded as a failed run (exit 1) after the other configuration had run; an --out under
// /proc was refused only after the runs.
TEST_F(CliTest, MakeReferenceRefusesBadSettingsBeforeRunning) {
  const std::string make_reference = std::string("timeout 60 '") + KNEEDYN_MAKE_REFERENCE_EXE + "' --scene '" +
                                     ChapterScenePath() + "'";
  const std::string out = (fs::path(Out()).parent_path() / "reference.json").string();
  ExpectRefusedBeforeRunning(
      make_reference, "make_reference",
      {{" --out '" + out + "' --interval 0", "--interval: output interval 0 s; must lie in [1e-06, 10] s"},
       {" --out '" + out + "' --method formulations --rtol -1",
        "--formulation --integrator --rtol --atol: CreateFormulation(): --rtol = -1"},
       {" --out '" + out + "' --method formulations --check-rtol 0.9",
        "--check --check-integrator --check-rtol --check-atol: CreateFormulation(): --rtol = 0.9"},
       {" --out /proc/kneedyn_no_such/reference.json", "--out = '/proc/kneedyn_no_such/reference.json': cannot"},
       // Before: a negative check tolerance ran as the primary's, and --check-step -1 was refused
       // after the ~50 s primary run.
       {" --out '" + out + "' --method formulations --check-rtol -1", "--check-rtol = -1: must be >= 0"},
       {" --out '" + out + "' --check-step -1", "--check-step = -1 s: must be > 0"},
       // Each method's options with the other were ignored (the extended run started).
       {" --out '" + out + "' --rtol -1", "--rtol applies to --method formulations only, not to --method extended"},
       {" --out '" + out + "' --formulation nope", "--formulation applies to --method formulations only"},
       {" --out '" + out + "' --method formulations --stages 4", "--stages applies to --method extended only"}},
      "wrote ", out);
}

// make_reference --verify reads a stored reference's every field before regenerating it:
// a malformed or foreign file is refused naming it and the field (exit 2). Before, a missing
// 'primary' ended in a bare JSON message (exit 1), a missing 'agreement' only after the
// run, and an unknown formulation was reported as a failed run (exit 1).
TEST_F(CliTest, MakeReferenceVerifyRefusesAMalformedReferenceBeforeRunning) {
  const fs::path stored = fs::path(KNEEDYN_SOURCE_DIR) / "reference-data" / "references" / "chapter_impact.json";
  std::ifstream in(stored);
  ASSERT_TRUE(in) << stored;
  const nlohmann::json reference = nlohmann::json::parse(in);
  const auto variant = [&](const std::string& name, const std::function<void(nlohmann::json*)>& change) {
    nlohmann::json j = reference;
    change(&j);
    const fs::path p = dir_ / name;
    std::ofstream(p) << j.dump();
    return p.string();
  };
  const std::string no_primary = variant("no_primary.json", [](nlohmann::json* j) { j->erase("primary"); });
  const std::string no_agreement = variant("no_agreement.json", [](nlohmann::json* j) { j->erase("agreement"); });
  const std::string unknown = variant("unknown.json", [](nlohmann::json* j) {
    (*j)["primary"] = {{"formulation", "nope"}, {"rtol", 1e-10}, {"atol", 1e-12}};
  });
  const std::string make_reference = std::string("timeout 60 '") + KNEEDYN_MAKE_REFERENCE_EXE + "' --scene '" +
                                     ChapterScenePath() + "' --verify ";
  ExpectRefusedBeforeRunning(make_reference, "make_reference",
                             {{"'" + no_primary + "'", "--verify = '" + no_primary + "': [json.exception.out_of_range.403] key 'primary' not found"},
                              {"'" + no_agreement + "'", "--verify = '" + no_agreement + "': [json.exception.out_of_range.403] key 'agreement' not found"},
                              {"'" + unknown + "'", "its primary run: FindFormulation(): unknown formulation 'nope'"}},
                             "regenerated");
}

// batch_throughput, the batch target's benchmark, refuses what no measurement can use
// (exit 2, before any run): --runs 1e11 ended in the OOM killer (exit 137); a --rtol or
// --formulation that no run can have was measured as 'scd nan' (exit 1); an unwritable --csv
// was refused after the timed runs.
TEST_F(CliTest, ThroughputBenchmarksRefuseBadSettingsBeforeRunning) {
  const std::string bench = std::string("timeout 60 '") + KNEEDYN_BATCH_THROUGHPUT_EXE + "'";
  ExpectRefusedBeforeRunning(
      bench, "batch_throughput",
      {{" --runs 100000000000", "--runs = 100000000000: must be in [1, 1000000]"},
       {" --runs 2 --rtol -1", "--rtol = -1; must lie in (0, 0.5]"},
       {" --runs 2 --formulation nope", "unknown formulation 'nope'"},
       {" --runs 2 --csv /proc/kneedyn_no_such/t.csv", "--csv = '/proc/kneedyn_no_such/t.csv': cannot"}},
      "on the nominal scene");
  // sweep_throughput dropped an unwritable --json silently (exit 0) and took --min-scd nan
  // as a failed accuracy check (exit 1).
  const std::string sweep_bench = std::string("cd '") + KNEEDYN_SOURCE_DIR + "' && timeout 60 '" +
                                  KNEEDYN_SWEEP_THROUGHPUT_EXE + "'";
  ExpectRefusedBeforeRunning(sweep_bench, "sweep_throughput",
                             {{" --json /proc/kneedyn_no_such/t.json", "--json = '/proc/kneedyn_no_such/t.json': cannot"},
                              {" --min-scd nan", "--min-scd = nan: must be finite"}},
                             "runs/s");
  // calibrate_reconstruction took --rtol in (0, 1): at 0.7 every run refused it, the fit
  // counted them as failed runs and wrote placeholder angles, exit 0; and its messages
  // lacked the "error:" of the contract.
  const std::string calibrate = std::string("cd '") + KNEEDYN_SOURCE_DIR + "' && timeout 60 '" +
                                KNEEDYN_CALIBRATE_EXE + "' --out '" + Out() + "/c.json'";
  ExpectRefusedBeforeRunning(calibrate, "calibrate_reconstruction",
                             {{" --rtol 0.7 --grid 1 --max-iterations 0", "--rtol = 0.7; must lie in (0, 0.5]"},
                              {" --grid 0", "--grid = 0: must be >= 1"}},
                             "best: scale", fs::path(Out()) / "c.json");
}

// SUNDIALS prints nothing itself; its own message (here IDA's, CVODE's and
// ARKODE's "mxstep steps taken before reaching tout") is in the failure reason and in
// summary.json. Without a terminal there are no `\r` progress updates.
TEST_F(CliTest, SundialsMessagesGoIntoTheFailureReasonNotToStderr) {
  const std::vector<std::pair<std::string, std::string>> runs = {
      {"--formulation dae", "IDAS"},  // IDA's API from libsundials_idas
      {"--formulation ede --integrator cvode-adams", "CVODES"},  // CVODE's API from libsundials_cvodes
      {"--formulation ede --integrator dopri5", "ARKODE"}};
  for (const auto& [options, module] : runs) {
    fs::remove_all(Out());
    const CommandResult r =
        RunKneedyn("run '" + ChapterScenePath() + "' " + options + " --max-steps 5 --out '" + Out() + "'");
    EXPECT_EQ(r.exit_code, 1) << options << "\n" << r.output;
    EXPECT_EQ(r.output.find("[" + module + " ERROR]"), std::string::npos) << r.output;
    EXPECT_EQ(r.output.find('\r'), std::string::npos) << "progress written to a pipe: " << r.output;
    ASSERT_TRUE(fs::exists(fs::path(Out()) / "summary.json")) << options;
    const nlohmann::json j = nlohmann::json::parse(ReadText(fs::path(Out()) / "summary.json"));
    const std::string failure = j.at("failure").get<std::string>();
    EXPECT_NE(failure.find("[" + module + " "), std::string::npos) << failure;
    EXPECT_NE(failure.find("mxstep steps taken before reaching tout"), std::string::npos) << failure;
    EXPECT_NE(r.output.find("mxstep steps taken"), std::string::npos) << r.output;  // the reason printed
  }
}

// The catalog prints i/N progress with elapsed time and time left.
TEST_F(CliTest, CatalogPrintsCountedProgress) {
  const CommandResult r = RunShell(std::string("'") + KNEEDYN_CATALOG_EXE + "' --case c1_law --formulation dae" +
                                   " --formulation mde --no-reference --out '" + Out() + "'");
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("[1/2, "), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("[2/2, "), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("elapsed, ~0.0s left]"), std::string::npos) << r.output;  // nothing left after 2/2
}

// The catalog's `warnings` column lists what each run says of itself (summary.json's
// warnings): the same kinds, with counts, as `kneedyn run` of that case and formulation at the
// catalog's options writes. The chapter scene's guess_offset_1e-6mm with newmark lifts off
// 0.7 ms early on its oscillating force (liftoff_force_not_zero) and chatters
// (short_contact_phase); dae warns of nothing. Before, the catalog had no such column and
// listed the newmark run as a plain completion.
TEST_F(CliTest, CatalogListsEachRunsWarnings) {
  const std::string scene = std::string(KNEEDYN_SOURCE_DIR) + "/reference-data/scenes/hard/guess_offset_1e-6mm.yaml";
  const CommandResult r = RunShell(std::string("'") + KNEEDYN_CATALOG_EXE + "' --case guess_offset_1e-6mm" +
                                   " --formulation newmark --formulation dae --no-reference --out '" + Out() + "'");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  std::istringstream csv(ReadText(fs::path(Out()) / "hard_cases.csv"));
  std::string header, line;
  std::getline(csv, header);
  ASSERT_NE(header.find(",events,warnings,reason"), std::string::npos) << header;
  std::map<std::string, std::string> listed;  // formulation -> warnings cell
  while (std::getline(csv, line)) {
    // ...,"events","warnings","reason": the second-last quoted cell.
    const size_t reason = line.rfind(",\"");
    const size_t warnings = line.rfind(",\"", reason - 1);
    ASSERT_NE(warnings, std::string::npos) << line;
    const std::string formulation = line.substr(line.find(',') + 1, line.find(',', line.find(',') + 1) - line.find(',') - 1);
    listed[formulation] = line.substr(warnings + 2, reason - warnings - 3);
  }
  for (const std::string formulation : {"newmark", "dae"}) {
    const std::string out = Out() + "_" + formulation;
    // The catalog's options (app/hard_case_catalog.cpp): rtol 1e-8, atol 1e-10; h = 1e-4 s fixed.
    const std::string options = std::string(" --rtol 1e-8 --atol 1e-10") + (formulation == "dae" ? "" : " --step 1e-4");
    const CommandResult run = RunKneedyn("run '" + scene + "' --formulation " + formulation + options + " --quiet --out '" + out + "'");
    ASSERT_EQ(run.exit_code, 0) << run.output;
    std::map<std::string, int> kinds;
    const nlohmann::json summary = nlohmann::json::parse(ReadText(fs::path(out) / "summary.json"));
    for (const auto& w : summary.at("warnings")) ++kinds[w.at("kind").get<std::string>()];
    std::string expected;
    for (const auto& [kind, n] : kinds) expected += (expected.empty() ? "" : " ") + kind + (n > 1 ? "×" + std::to_string(n) : "");
    EXPECT_EQ(listed[formulation], expected) << formulation;
    fs::remove_all(out);
  }
  EXPECT_NE(listed["newmark"].find("liftoff_force_not_zero"), std::string::npos) << listed["newmark"];
  EXPECT_EQ(listed["dae"], "");
}

// An output interval longer than the run writes the start and the event rows alone: the
// summary warns (sparse_output), since its constraint_residuals and the peaks come from the
// rows; the scene's own 5 ms rows give no such warning. Before, nothing was said.
TEST_F(CliTest, AnOutputIntervalLongerThanTheRunIsWarned) {
  const auto kinds = [this](const std::string& extra) {
    fs::remove_all(Out());
    const CommandResult r = RunKneedyn("run '" + ChapterScenePath() + "'" + extra + " --quiet --out '" + Out() + "'");
    EXPECT_EQ(r.exit_code, 0) << r.output;
    std::vector<std::string> found;
    const nlohmann::json summary = nlohmann::json::parse(ReadText(fs::path(Out()) / "summary.json"));
    for (const auto& w : summary.at("warnings")) found.push_back(w.at("kind").get<std::string>());
    return found;
  };
  const std::vector<std::string> sparse = kinds(" --output-interval 10");
  EXPECT_NE(std::find(sparse.begin(), sparse.end(), "sparse_output"), sparse.end())
      << ReadText(fs::path(Out()) / "summary.json");
  const std::vector<std::string> dense = kinds("");
  EXPECT_EQ(std::find(dense.begin(), dense.end(), "sparse_output"), dense.end());
}

// A separated condyle re-contacts when its gap falls below the hysteresis, 10 × max(drift,
// rtol |x0| + atol) (docs/model.md §9). ede euler at its default step drifts 0.048 mm, so the
// hysteresis reaches ~0.5 mm and the separated lateral condyle sinks 0.34 mm into its plateau
// (the gap column, read here from the rows without a contact point) with no re-contact: the
// run warns, naming the row of deepest penetration. dae's separated rows stay within the
// tolerances' hysteresis (rtol 1e-6, atol 1e-8 at |x0| ≈ 0.215 m: 2.2e-3 mm), and it does
// not warn. Before, neither said anything.
TEST_F(CliTest, ASeparatedCondyleSinkingIntoItsPlateauIsWarned) {
  const auto deepest = [this](const std::string& args, nlohmann::json* warnings) {
    fs::remove_all(Out());
    const CommandResult r = RunKneedyn("run '" + ChapterScenePath() + "' " + args + " --quiet --out '" + Out() + "'");
    EXPECT_EQ(r.exit_code, 0) << r.output;
    *warnings = nlohmann::json::parse(ReadText(fs::path(Out()) / "summary.json")).at("warnings");
    std::ifstream in(fs::path(Out()) / "trajectory.csv");
    std::string line, cell;
    std::getline(in, line);
    std::vector<std::string> cols;
    for (std::istringstream h(line); std::getline(h, cell, ',');) cols.push_back(cell);
    const auto at = [&](const char* n) { return std::find(cols.begin(), cols.end(), n) - cols.begin(); };
    const auto t_col = at("time_s"), gap_col = at("gap_lateral_mm"), point_col = at("tibial_lateral_x_mm");
    std::pair<double, double> min_gap{0.0, -1.0};  // mm, s
    while (std::getline(in, line)) {
      std::vector<std::string> row;
      for (std::istringstream r(line); std::getline(r, cell, ',');) row.push_back(cell);
      row.resize(cols.size());
      if (!row[point_col].empty()) continue;  // in contact
      const double gap = std::stod(row[gap_col]);
      if (gap < min_gap.first) min_gap = {gap, std::stod(row[t_col])};
    }
    return min_gap;
  };
  nlohmann::json warnings;
  const auto [euler_gap_mm, euler_t] = deepest("--formulation ede --integrator euler --output-interval 0.001", &warnings);
  EXPECT_LT(euler_gap_mm, -0.1);
  const auto it = std::find_if(warnings.begin(), warnings.end(),
                               [](const nlohmann::json& w) { return w.at("kind") == "separated_contact_penetrates"; });
  ASSERT_NE(it, warnings.end()) << warnings.dump();
  EXPECT_EQ((*it).at("column"), "gap_lateral_mm");
  EXPECT_EQ((*it).at("time_s").get<double>(), euler_t);
  const auto [dae_gap_mm, dae_t] = deepest("--formulation dae --output-interval 0.001", &warnings);
  EXPECT_GT(dae_gap_mm, -2.2e-3) << "at t = " << dae_t;
  for (const auto& w : warnings) EXPECT_NE(w.at("kind"), "separated_contact_penetrates") << w.dump();
}

// On a terminal (a pseudo-terminal from script(1)) `kneedyn batch` and `kneedyn sensitivity`
// show `\r` progress on stderr, as run and sweep do, and --quiet silences it; through a pipe
// nothing (before: neither had progress, and sensitivity had no --quiet).
TEST_F(CliTest, BatchAndSensitivityShowProgressOnATerminal) {
  if (RunShell("command -v script").exit_code != 0) GTEST_SKIP() << "script(1) (bsdutils) not installed";
  const fs::path dir(Out());
  fs::create_directories(dir);
  std::ofstream(dir / "v.csv") << "pulse.amplitude\n90\n110\n";
  const auto on_terminal = [](const std::string& command) {
    return RunShell("script -qec \"" + command + "\" /dev/null");
  };
  const std::string exe = std::string("'") + KNEEDYN_EXE + "'";
  const std::string batch = exe + " batch '" + ChapterScenePath() + "' --variants '" + (dir / "v.csv").string() + "'";
  CommandResult r = on_terminal(batch + " --out '" + (dir / "b1.csv").string() + "'");
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("\r[batch] 2/2 runs (0 failed)"), std::string::npos) << r.output;
  r = on_terminal(batch + " --quiet --out '" + (dir / "b2.csv").string() + "'");
  EXPECT_EQ(r.output.find("[batch]"), std::string::npos) << r.output;
  r = RunShell(batch + " --out '" + (dir / "b3.csv").string() + "' 2>&1");
  EXPECT_EQ(r.output.find("[batch]"), std::string::npos) << r.output;  // not a terminal
  const std::string sensitivity =
      exe + " sensitivity '" + ChapterScenePath() + "' --parameters mass --outcomes time_90_s --out '";
  r = on_terminal(sensitivity + (dir / "s1").string() + "'");
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("\r[sensitivity] t = 0.050 s"), std::string::npos) << r.output;
  r = on_terminal(sensitivity + (dir / "s2").string() + "' --quiet");
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_EQ(r.output.find("[sensitivity]"), std::string::npos) << r.output;
}

// The catalog refuses what it cannot use before its runs, with exit 2 and its own prefix:
// a --cases-dir that is not a directory or lacks a selected case's file (before: 233 rows
// 'error', exit 0), an --out that cannot be created (before: every case run, then an
// uncaught filesystem_error, abort, exit 134) and a --contact-chart that names no chart.
TEST_F(CliTest, CatalogRefusesAnUnusableCasesDirOrOutBeforeRunning) {
  const std::string catalog = std::string("'") + KNEEDYN_CATALOG_EXE + "' --case c1_law --formulation dae --no-reference";
  const fs::path empty_dir = fs::path(Out()).parent_path() / "no_cases";
  fs::create_directories(empty_dir);
  const fs::path not_dir = fs::path(Out()).parent_path() / "a_file";
  std::ofstream(not_dir) << "x";
  ExpectRefusedBeforeRunning(
      catalog, "kneedyn_catalog",
      {{" --cases-dir /nonexistent --out '" + Out() + "'", "--cases-dir = '/nonexistent': not a directory"},
       {" --cases-dir '" + empty_dir.string() + "' --out '" + Out() + "'",
        "1 of the 1 case files are missing or not regular files (c1_law.yaml)"},
       {" --out '" + (not_dir / "out").string() + "'", "--out = '" + (not_dir / "out").string() + "'"},
       {" --contact-chart 1 --out '" + Out() + "'", "--contact-chart = '1'; must be regular or height-field"}},
      "[1/1", Out());
}

// The catalog's "refused" expectation is the README's "must be refused": a jcs_singular_pose
// that the loader accepts (β = 0.1°, moving towards the singularity) fails during
// integration with a JCS message, which --check now counts as not met (exit 1); before,
// any failure naming the JCS passed. The shipped case is refused and passes.
TEST_F(CliTest, CatalogRefusedExpectationNeedsARefusal) {
  const fs::path cases = fs::path(Out()).parent_path() / "jcs_cases";
  fs::create_directories(cases);
  std::string text = ReadText(fs::path(KNEEDYN_SOURCE_DIR) / "reference-data/scenes/hard/jcs_singular_pose.yaml");
  const std::string pose = "beta_deg: 0.01, gamma_deg: 0.0}";
  ASSERT_NE(text.find(pose), std::string::npos);
  text.replace(text.find(pose), pose.size(), "beta_deg: 0.1, gamma_deg: 0.0}\n  velocities: {beta_deg_s: -57.29578}");
  const size_t set_line = text.find("parameter_set: ");  // the case's relative path, made absolute
  ASSERT_NE(set_line, std::string::npos);
  text.replace(set_line, text.find('\n', set_line) - set_line,
               "parameter_set: " + (fs::path(KNEEDYN_SOURCE_DIR) / "reference-data/chapter_knee.yaml").string());
  std::ofstream(cases / "jcs_singular_pose.yaml") << text;
  const std::string catalog = std::string("'") + KNEEDYN_CATALOG_EXE + "' --check --case jcs_singular_pose --formulation dae --no-reference";
  const CommandResult moving = RunShell(catalog + " --cases-dir '" + cases.string() + "' --out '" + Out() + "'");
  EXPECT_EQ(moving.exit_code, 1) << moving.output;
  const std::string row = ReadText(fs::path(Out()) / "hard_cases.csv");
  EXPECT_NE(row.find("jcs_singular_pose,dae,solver_failure,refused,no"), std::string::npos) << row;
  fs::remove_all(Out());
  const CommandResult shipped = RunShell(catalog + " --out '" + Out() + "'");
  EXPECT_EQ(shipped.exit_code, 0) << shipped.output;
}

// summary.json describes the run: schema version, command line, version and
// commit, and the integrator and step actually used (rk4 with the default step: the
// registry's documented kDefaultFixedStep; dae: IDA, adaptive, with a mean step that
// spans the simulated time in the counted steps).
TEST_F(CliTest, SummaryRecordsWhatActuallyRan) {
  CommandResult r = RunKneedyn("run '" + ChapterScenePath() + "' --formulation mde --integrator rk4 --quiet --out '" +
                               Out() + "'");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  nlohmann::json j = nlohmann::json::parse(ReadText(fs::path(Out()) / "summary.json"));
  EXPECT_EQ(j.at("schema_version").get<int>(), 2);
  EXPECT_EQ(j.at("kneedyn_version").get<std::string>(), KNEEDYN_PROJECT_VERSION);
  EXPECT_TRUE(j.at("git_commit").is_string());
  const auto& argv = j.at("command_line");
  ASSERT_GE(argv.size(), 4u);
  EXPECT_EQ(argv.at(1), "run");
  EXPECT_EQ(argv.at(2), ChapterScenePath());
  EXPECT_EQ(j.at("settings").at("integrator"), "rk4");
  EXPECT_EQ(j.at("settings").at("step_mode"), "fixed");
  EXPECT_DOUBLE_EQ(j.at("settings").at("step_s").get<double>(), 1.0e-4);  // kDefaultFixedStep
  EXPECT_EQ(j.at("settings").at("requested").at("step_s").get<double>(), 0.0);

  fs::remove_all(Out());
  r = RunKneedyn("run '" + ChapterScenePath() + "' --quiet --out '" + Out() + "'");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  j = nlohmann::json::parse(ReadText(fs::path(Out()) / "summary.json"));
  const auto& s = j.at("settings");
  EXPECT_EQ(s.at("integrator"), "ida");
  EXPECT_EQ(s.at("step_mode"), "adaptive");
  EXPECT_TRUE(s.at("step_s").is_null());
  const double span = j.at("events").back().at("time").get<double>();  // run starts at t = 0
  const long steps = j.at("statistics").at("steps").get<long>();
  EXPECT_NEAR(s.at("mean_step_s").get<double>() * static_cast<double>(steps), span, 1e-9 * span);
  EXPECT_EQ(s.at("max_steps").get<long>(), 200000);  // the documented default
  EXPECT_TRUE(s.at("generalized_alpha").is_null());

  // generalized-alpha records its scheme: ρ∞ = 0.5 gives Chung & Hulbert's αm = (2ρ − 1)/(ρ + 1)
  // = 0, αf = ρ/(ρ + 1) = 1/3, γ = 1/2 − αm + αf = 5/6, β = (γ + 1/2)²/4 = 4/9. Before, only a
  // typed --rho-inf was in command_line, and a default run held it nowhere.
  fs::remove_all(Out());
  r = RunKneedyn("run '" + ChapterScenePath() + "' --formulation generalized-alpha --rho-inf 0.5 --max-steps 99999 "
                 "--quiet --out '" + Out() + "'");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const auto ga = nlohmann::json::parse(ReadText(fs::path(Out()) / "summary.json")).at("settings");
  EXPECT_EQ(ga.at("max_steps").get<long>(), 99999);
  EXPECT_EQ(ga.at("generalized_alpha").at("rho_inf").get<double>(), 0.5);
  EXPECT_NEAR(ga.at("generalized_alpha").at("alpha_m").get<double>(), 0.0, 1e-15);
  EXPECT_NEAR(ga.at("generalized_alpha").at("alpha_f").get<double>(), 1.0 / 3.0, 1e-15);
  EXPECT_NEAR(ga.at("generalized_alpha").at("gamma").get<double>(), 5.0 / 6.0, 1e-15);
  EXPECT_NEAR(ga.at("generalized_alpha").at("beta").get<double>(), 4.0 / 9.0, 1e-15);
  EXPECT_TRUE(ga.at("baumgarte_gains_1_s").is_null());

  // ede with Baumgarte's stabilization records the gains it ran with (no option sets them;
  // before, no file said what they were): docs/outputs.md's 20 and 20 1/s.
  fs::remove_all(Out());
  r = RunKneedyn("run '" + ChapterScenePath() + "' --formulation ede --stabilization baumgarte --quiet --out '" + Out() +
                 "'");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const auto bg = nlohmann::json::parse(ReadText(fs::path(Out()) / "summary.json")).at("settings");
  EXPECT_EQ(bg.at("baumgarte_gains_1_s").at("alpha").get<double>(), 20.0);
  EXPECT_EQ(bg.at("baumgarte_gains_1_s").at("beta").get<double>(), 20.0);
}

}  // namespace
}  // namespace kneedyn
