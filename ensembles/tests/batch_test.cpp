// The batch API and `kneedyn batch` (ensembles/batch.hpp): a variant is
// the run of the scene with that parameter changed by hand (a second path: LoadScene +
// edit + RunScene); runs do not leak state into each other (order and thread count do not
// change a row); the table reads back exactly; bad input names line, column and value,
// exits 2 and writes nothing.
#include <gtest/gtest.h>

#include <sys/wait.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "ensembles/batch.hpp"
#include "solver/error.hpp"

using namespace kneedyn;
using namespace kneedyn::ensembles;
namespace fs = std::filesystem;

namespace {

const std::string kScene = std::string(KNEEDYN_SOURCE_DIR) + "/reference-data/scenes/chapter_impact.yaml";

const Scene& Chapter() {
  static const Scene s = LoadScene(kScene);
  return s;
}

RunSettings Settings() {
  RunSettings r;
  r.formulation = "ede";
  r.options.integrator = IntegratorKind::kCvodeAdams;
  r.options.rtol = 1e-7;
  r.options.atol = 1e-9;
  return r;
}

std::string ParseError(const std::string& text) {
  try {
    ParseBatchVariants(text, "v.csv", Chapter().model);
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

double LiftoffTime(const RunResult& r) {
  for (const EventRecord& e : r.events) {
    if (e.name.rfind("liftoff_", 0) == 0) return e.time;
  }
  return -1.0;
}

TEST(BatchVariants, ParsesHeaderCommentsAndRows) {
  const BatchVariants v = ParseBatchVariants("# pulses\n\npulse.amplitude, PCL_anterior.k_linear\n90,10.5\n 110 , 12\n",
                                             "v.csv", Chapter().model);
  ASSERT_EQ(v.parameters.size(), 2u);
  EXPECT_EQ(v.parameters[0].kind, ParameterKind::kPulseAmplitude);
  EXPECT_EQ(v.parameters[1].kind, ParameterKind::kLigamentLinearStiffness);
  EXPECT_EQ(v.parameters[1].column, "PCL_anterior.k_linear_N_mm");
  ASSERT_EQ(v.rows.size(), 2u);
  EXPECT_EQ(v.rows[1][0], 110.0);
  EXPECT_EQ(v.rows[1][1], 12.0);
  // A spreadsheet's "CSV UTF-8" begins with a byte-order mark: read past it (before:
  // "no element '\ufeffpulse' in the base scene").
  const BatchVariants bom = ParseBatchVariants("\xEF\xBB\xBFpulse.amplitude\n90\n", "v.csv", Chapter().model);
  ASSERT_EQ(bom.parameters.size(), 1u);
  EXPECT_EQ(bom.parameters[0].kind, ParameterKind::kPulseAmplitude);
  EXPECT_EQ(bom.rows.size(), 1u);
}

TEST(BatchVariants, BadInputNamesLineColumnAndValue) {
  std::string m = ParseError("pulse.amplitude,mass\n100,5\n100,abc\n");
  EXPECT_NE(m.find("line 3"), std::string::npos) << m;
  EXPECT_NE(m.find("'mass' = 'abc'"), std::string::npos) << m;
  m = ParseError("pulse.amplitude\n1e400\n");
  EXPECT_NE(m.find("not a finite number"), std::string::npos) << m;
  m = ParseError("mass\n0\n");
  EXPECT_NE(m.find("'mass' = '0': must lie in [0.001, 1000] (the scene's range)"), std::string::npos) << m;
  // The scene file's limits: before, a variant's 1e9 N or -5 N pulse ran.
  for (const char* amplitude : {"1e9", "-5"}) {
    m = ParseError(std::string("pulse.amplitude\n") + amplitude + "\n");
    EXPECT_NE(m.find(std::string("'pulse.amplitude' = '") + amplitude + "': must lie in [0, 100000]"), std::string::npos) << m;
  }
  m = ParseError("pulse.amplitude,mass\n100\n");
  EXPECT_NE(m.find("line 2: 1 values, the header names 2"), std::string::npos) << m;
  m = ParseError("XYZ ligament.k_linear\n1\n");
  EXPECT_NE(m.find("no element 'XYZ ligament'"), std::string::npos) << m;
  m = ParseError("mass,mass\n1,2\n");
  EXPECT_NE(m.find("listed twice"), std::string::npos) << m;
  m = ParseError("PCL anterior.slack_length,PCL anterior.extension_ratio\n31,1.1\n");
  EXPECT_NE(m.find("line 1: 'PCL anterior.slack_length' and 'PCL anterior.extension_ratio': the slack length fixes L0"),
            std::string::npos) << m;
  // A misspelt pulse parameter is named with the pulse's two (before: "no element 'pulse'").
  m = ParseError("pulse.amplitud\n100\n");
  EXPECT_NE(m.find("the pulse's are pulse.amplitude and pulse.duration (nearest: pulse.amplitude)"), std::string::npos)
      << m;
  EXPECT_NE(ParseError("# nothing\n").find("no header"), std::string::npos);
  EXPECT_NE(ParseError("mass\n").find("no variant rows"), std::string::npos);
}

// An element's name in a parameter or outcome column is spelt as in trajectory.csv: spaces,
// '-' and '/' written '_' (docs/outputs.md, <element>), so the column families match by name.
// Before, sweep and batch columns kept the '-' of "MCL-deep" (trajectory: F_MCL_deep_N).
TEST(BatchVariants, ElementNamesAreSpeltAsTheTrajectorysColumns) {
  Model model = Chapter().model;
  int renamed = -1;
  for (size_t j = 0; j < model.ligaments.size(); ++j) {
    if (model.ligaments[j].name == "MCL deep") model.ligaments[j].name = "MCL-deep", renamed = static_cast<int>(j);
  }
  ASSERT_GE(renamed, 0);
  const ParameterSpec p = ResolveParameterName(model, "MCL_deep.k_linear", "test");
  EXPECT_EQ(p.ligament, renamed);
  EXPECT_EQ(p.column, "MCL_deep.k_linear_N_mm");
  EXPECT_EQ(ResolveParameterName(model, "MCL-deep.k_linear", "test").column, "MCL_deep.k_linear_N_mm");
}

TEST(Batch, VariantEqualsTheSceneEditedByHand) {
  Batch batch(Chapter(), Settings(), {"liftoff_time", "time_at_90"});
  const std::vector<ParameterSpec> p = {ResolveParameterName(Chapter().model, "pulse.amplitude", "test")};
  const RunRow row = batch.Run(p, {115.0}, 0);
  Scene edited = LoadScene(kScene);
  edited.model.pulse.amplitude = 115.0;
  const RunResult direct = RunScene(edited, Settings());
  ASSERT_TRUE(row.completed) << row.failure;
  ASSERT_TRUE(direct.completed);
  EXPECT_EQ(row.outcomes[0], LiftoffTime(direct));
  EXPECT_EQ(row.outcomes[1], direct.events.back().time);
  EXPECT_EQ(row.steps, direct.stats.steps);
  // And the pulse mattered: the nominal scene's lift-off differs.
  EXPECT_NE(LiftoffTime(RunScene(Chapter(), Settings())), row.outcomes[0]);
}

// A patellar facet's lift-off is not the knee's: on a scene where the patella leaves its
// medial facet and the condyles never separate (the direct run's events: no liftoff_medial
// or liftoff_lateral), the lift-off outcomes are NaN, as `kneedyn sensitivity` gives them.
// Before, the batch printed the facet's time (0.0587 s) as the knee's lift-off.
TEST(Batch, PatellarFacetLiftoffIsNotTheKneesLiftoff) {
  const Scene scene = LoadScene(std::string(KNEEDYN_SOURCE_DIR) + "/reference-data/scenes/hard/patella_medial_liftoff.yaml");
  RunSettings settings;
  settings.formulation = "ede";
  const RunResult direct = RunScene(scene, settings);
  ASSERT_TRUE(direct.completed) << direct.failure;
  bool facet_liftoff = false;
  for (const EventRecord& e : direct.events) {
    EXPECT_NE(e.name, "liftoff_medial");
    EXPECT_NE(e.name, "liftoff_lateral");
    facet_liftoff = facet_liftoff || e.name.rfind("liftoff_patellar_", 0) == 0;
  }
  ASSERT_TRUE(facet_liftoff) << "the scene no longer exercises a facet lift-off";
  Batch batch(scene, settings, {"liftoff_time", "liftoff_flexion"});
  const std::vector<ParameterSpec> p = {ResolveParameterName(scene.model, "pulse.amplitude", "test")};
  const RunRow row = batch.Run(p, {scene.model.pulse.amplitude}, 0);
  ASSERT_TRUE(row.completed) << row.failure;
  EXPECT_TRUE(std::isnan(row.outcomes[0])) << row.outcomes[0];
  EXPECT_TRUE(std::isnan(row.outcomes[1])) << row.outcomes[1];
}

TEST(Batch, RowsDoNotDependOnOrderOrThreads) {
  Batch batch(Chapter(), Settings(), {"liftoff_time", "liftoff_flexion"});
  BatchVariants v = ParseBatchVariants("pulse.amplitude,pulse.duration\n85,0.09\n120,0.11\n100,0.1\n", "v", Chapter().model);
  const SweepTable a = batch.RunAll(v, 1);
  std::swap(v.rows[0], v.rows[2]);
  const SweepTable b = batch.RunAll(v, 2);
  ASSERT_EQ(a.rows.size(), 3u);
  for (int i = 0; i < 3; ++i) {
    const int j = i == 0 ? 2 : i == 2 ? 0 : 1;
    EXPECT_TRUE(a.rows[i].completed);
    EXPECT_EQ(a.rows[i].outcomes, b.rows[j].outcomes) << i;
    EXPECT_EQ(a.rows[i].steps, b.rows[j].steps) << i;
  }
}

TEST(Batch, TableReadsBackExactly) {
  Batch batch(Chapter(), Settings(), {"liftoff_time"});
  const BatchVariants v = ParseBatchVariants("pulse.amplitude\n97.3\n", "v", Chapter().model);
  const SweepTable t = batch.RunAll(v);
  const std::string csv = FormatBatchCsv(t);
  std::istringstream in(csv);
  std::string header, line;
  std::getline(in, header);
  std::getline(in, line);
  EXPECT_EQ(header, "index,pulse.amplitude_N,liftoff_time_s,status,end_reason,steps,failure");
  std::istringstream fields(line);
  std::string f;
  std::getline(fields, f, ',');
  EXPECT_EQ(f, "0");
  std::getline(fields, f, ',');
  EXPECT_EQ(std::stod(f), 97.3);
  std::getline(fields, f, ',');
  EXPECT_EQ(std::stod(f), t.rows[0].outcomes[0]);
  std::getline(fields, f, ',');
  EXPECT_EQ(f, "completed");
}

int Sh(const std::string& command) {
  const int status = std::system(command.c_str());
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

TEST(BatchCli, WritesOneTableAndRefusesBadInput) {
  const fs::path work = fs::temp_directory_path() / "kneedyn_batch_cli_test";
  fs::remove_all(work);
  fs::create_directories(work);
  std::ofstream(work / "good.csv") << "pulse.amplitude\n100\n110\n";
  std::ofstream(work / "bad.csv") << "pulse.amplitude\n100\n-\n";
  const std::string exe = KNEEDYN_EXE;
  const std::string common = " batch " + kScene + " --formulation ede --integrator cvode-adams --rtol 1e-6 ";
  ASSERT_EQ(Sh(exe + common + "--variants " + (work / "good.csv").string() + " --out " +
               (work / "out/r.csv").string() + " --quiet"), 0);
  std::ifstream in(work / "out/r.csv");
  std::string line;
  int lines = 0;
  while (std::getline(in, line)) ++lines;
  EXPECT_EQ(lines, 3);
  const std::string err = (work / "err.txt").string();
  EXPECT_EQ(Sh(exe + common + "--variants " + (work / "bad.csv").string() + " --out " +
               (work / "out2/r.csv").string() + " 2> " + err), 2);
  EXPECT_FALSE(fs::exists(work / "out2"));
  std::ifstream e(err);
  std::string msg((std::istreambuf_iterator<char>(e)), std::istreambuf_iterator<char>());
  EXPECT_NE(msg.find("line 3, column 'pulse.amplitude' = '-'"), std::string::npos) << msg;
  EXPECT_EQ(Sh(exe + common + "--variants " + (work / "good.csv").string() + " --outcomes liftoff,x --out " +
               (work / "out3/r.csv").string() + " 2> " + err), 2);
  EXPECT_FALSE(fs::exists(work / "out3"));
  EXPECT_EQ(Sh(exe + common + "--variants " + (work / "good.csv").string() + " --outcomes liftoff_time,liftoff_time --out " +
               (work / "out5/r.csv").string() + " 2> " + err), 2);  // a sweep spec refuses it too
  EXPECT_FALSE(fs::exists(work / "out5"));
  // kneedyn run's output-grid rule, before the runs (before: each row failed, exit 0).
  EXPECT_EQ(Sh(exe + common + "--variants " + (work / "good.csv").string() + " --output-interval 1e-6 --out " +
               (work / "out4/r.csv").string() + " 2> " + err), 2);
  EXPECT_FALSE(fs::exists(work / "out4"));
  std::ifstream e4(err);
  const std::string msg4((std::istreambuf_iterator<char>(e4)), std::istreambuf_iterator<char>());
  EXPECT_NE(msg4.find("--output-interval = '1e-6': output interval 1e-06 s gives"), std::string::npos) << msg4;
  // kneedyn run's fixed-step rules on the base scene, before the runs (before: each row failed,
  // exit 0); the pulse rule not when a variant moves the pulse's duration.
  const auto refusal = [&](const std::string& args, const std::string& out) {
    EXPECT_EQ(Sh(exe + " batch " + kScene + " --variants " + (work / "good.csv").string() + " " + args + " --out " +
                 (work / out / "r.csv").string() + " 2> " + err), 2) << args;
    EXPECT_FALSE(fs::exists(work / out)) << args;
    std::ifstream e(err);
    return std::string((std::istreambuf_iterator<char>(e)), std::istreambuf_iterator<char>());
  };
  std::string m = refusal("--formulation newmark --step 0.008", "out6");
  EXPECT_NE(m.find("output interval 0.005 s is shorter than the fixed step 0.008 s"), std::string::npos) << m;
  m = refusal("--formulation ede --integrator rk4 --step 0.02 --output-interval 0.05", "out7");
  EXPECT_NE(m.find("pulse.duration_s = 0.1 s spans fewer than 10 fixed steps of 0.02 s"), std::string::npos) << m;
  {
    std::ofstream d(work / "durations.csv");
    d << "pulse.duration\n0.5\n";
  }
  EXPECT_EQ(Sh(exe + " batch " + kScene + " --variants " + (work / "durations.csv").string() +
               " --formulation ede --integrator rk4 --step 0.02 --output-interval 0.05 --out " +
               (work / "out8/r.csv").string() + " 2> " + err), 0);
  fs::remove_all(work);
}

}  // namespace
