// `kneedyn sensitivity` (sensitivity/sensitivity_cli.hpp): the exit-code contract, nothing
// written on bad input, the output set's files and fields.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include "cli_support.hpp"

namespace kneedyn::cli_test {
namespace {

const std::string kScene = std::string(KNEEDYN_SOURCE_DIR) + "/reference-data/scenes/chapter_impact.yaml";

fs::path FreshDir(const std::string& name) {
  const fs::path d = fs::temp_directory_path() / ("kneedyn_sensitivity_cli_" + name + "_" + std::to_string(::getpid()));
  fs::remove_all(d);
  return d;
}

TEST(SensitivityCli, BadNamesExitTwoNamingTheFieldAndNearestNameWritingNothing) {
  const fs::path out = FreshDir("bad");
  CommandResult r = RunKneedyn("sensitivity '" + kScene + "' --parameters PCL_anterior.k_lnear --outcomes time_90_s --out '" +
                               out.string() + "'");
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("--parameters"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("'PCL_anterior.k_linear'"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(out));
  r = RunKneedyn("sensitivity '" + kScene + "' --parameters mass --outcomes time_at_91 --out '" + out.string() + "'");
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("--outcomes"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("'time_at_90'"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(out));
  r = RunKneedyn("sensitivity '" + kScene + "' --parameters mass --outcomes time_90_s --rtol -1 --out '" + out.string() + "'");
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("--rtol"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(out));
  // One element's slack length and extension ratio: the first fixes L0, so every derivative
  // by the second read an exact 0 (alone it is not: liftoff_time_lateral, 0.034 s).
  r = RunKneedyn("sensitivity '" + kScene + "' --parameters MCL_deep.slack_length,mass,MCL_deep.extension_ratio "
                 "--outcomes time_90_s --out '" + out.string() + "'");
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("'MCL_deep.slack_length' and 'MCL_deep.extension_ratio'"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(out));
}

TEST(SensitivityCli, ImpactIsASolverRefusalWithNothingWritten) {
  const fs::path out = FreshDir("impact");
  const CommandResult r = RunKneedyn("sensitivity '" + std::string(KNEEDYN_SOURCE_DIR) +
                                     "/reference-data/scenes/hard/lateral_pulse_recontact.yaml' --parameters mass "
                                     "--outcomes time_90_s --out '" + out.string() + "'");
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("impact"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(out));
}

TEST(SensitivityCli, WritesCsvAndJsonAsOneSet) {
  const fs::path out = FreshDir("ok");
  const CommandResult r = RunKneedyn("sensitivity '" + kScene +
                                     "' --parameters 'PCL anterior.k_linear,pulse.amplitude' --outcomes "
                                     "liftoff_time_s,peak_F_PCL_anterior_N --out '" + out.string() + "'");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const std::string csv = ReadText(out / "sensitivity.csv");
  EXPECT_EQ(csv.substr(0, csv.find('\n')), "outcome,parameter,parameter_value,value,derivative,normalized");
  EXPECT_EQ(std::count(csv.begin(), csv.end(), '\n'), 5);  // header + 2 outcomes x 2 parameters
  const std::string traj = ReadText(out / "sensitivity_trajectory.csv");
  EXPECT_EQ(traj.substr(0, traj.find(',', traj.find(',') + 1)), "time_s,parameter");
  const nlohmann::json j = nlohmann::json::parse(ReadText(out / "sensitivity.json"));
  EXPECT_EQ(j["rows"].size(), 4u);
  EXPECT_EQ(j["end_reason"], "flexion_90");
  EXPECT_GT(j["statistics"]["steps"].get<long>(), 0);
  const auto& row = j["rows"][0];
  EXPECT_EQ(row["outcome"], "liftoff_time_s");
  EXPECT_EQ(row["parameter"], "PCL_anterior.k_linear_N_mm");
  // normalized = p / y · dy/dp
  EXPECT_NEAR(row["normalized"].get<double>(),
              row["parameter_value"].get<double>() / row["value"].get<double>() * row["derivative"].get<double>(), 1e-9);
  // A second run replaces the set; a directory holding anything else is refused.
  EXPECT_EQ(RunKneedyn("sensitivity '" + kScene + "' --parameters mass --outcomes time_90_s --out '" + out.string() + "'").exit_code, 0);
  WriteText(out / "other.txt", "x");
  const CommandResult refused = RunKneedyn("sensitivity '" + kScene + "' --parameters mass --outcomes time_90_s --out '" + out.string() + "'");
  EXPECT_EQ(refused.exit_code, 2) << refused.output;
  EXPECT_NE(refused.output.find("other.txt"), std::string::npos) << refused.output;
  fs::remove_all(out);
}

// The 90° outcomes are read at the flexion_90 event alone, as sweeps and batches read them: a
// scene that ends at 60° (anatomical_surfaces: end flexion_deg 60, its summary's end event
// flexion_60) has none, in both drivers. Before, time_90_s was the time at 60° (0.2431 s) and
// N90_medial_N the force there.
TEST(SensitivityCli, NinetyDegreeOutcomesNeedTheNinetyDegreeEnd) {
  const std::string scene = std::string(KNEEDYN_SOURCE_DIR) + "/reference-data/scenes/anatomical_surfaces.yaml";
  for (const char* formulation : {"ede", "dae"}) {
    const fs::path out = FreshDir(std::string("at60_") + formulation);
    const CommandResult r = RunKneedyn("sensitivity '" + scene + "' --formulation " + formulation +
                                       " --parameters mass --outcomes time_90_s,N90_medial_N,peak_N_medial_N --out '" +
                                       out.string() + "'");
    ASSERT_EQ(r.exit_code, 0) << r.output;
    const nlohmann::json j = nlohmann::json::parse(ReadText(out / "sensitivity.json"));
    EXPECT_EQ(j["end_reason"], "flexion_60") << formulation;
    ASSERT_EQ(j["rows"].size(), 3u);
    for (const auto& row : j["rows"]) {
      if (row["outcome"] == "peak_N_medial_N") {
        EXPECT_TRUE(row["value"].is_number()) << formulation << ": the peak is defined at any end";
      } else {
        EXPECT_TRUE(row["value"].is_null()) << formulation << " " << row["outcome"] << " = " << row["value"];
        EXPECT_TRUE(row["derivative"].is_null()) << formulation << " " << row["outcome"];
      }
    }
    fs::remove_all(out);
  }
}

// --spec takes the scene, parameter names and outcome groups of a sweep spec: the table must
// be the one the same names give on the command line; refusals exit 2 and write nothing.
TEST(SensitivityCli, SpecGivesTheSameTableAsExplicitNames) {
  const fs::path dir = FreshDir("spec");
  fs::create_directories(dir);
  const fs::path spec = dir / "spec.yaml";
  WriteText(spec, "scene: " + kScene +
                      "\nparameters:\n  - {name: PCL anterior.k_linear, relative: 0.3}\n"
                      "  - {name: pulse.amplitude, relative: 0.2}\n"
                      "design: {type: saltelli, samples: 8}\noutcomes: [liftoff_time, time_at_90]\n");
  const CommandResult from_spec = RunKneedyn("sensitivity --spec '" + spec.string() + "' --out '" + (dir / "a").string() + "'");
  ASSERT_EQ(from_spec.exit_code, 0) << from_spec.output;
  const CommandResult named = RunKneedyn("sensitivity '" + kScene +
                                         "' --parameters 'PCL anterior.k_linear,pulse.amplitude' --outcomes "
                                         "liftoff_time,time_at_90 --out '" + (dir / "b").string() + "'");
  ASSERT_EQ(named.exit_code, 0) << named.output;
  const std::string a = ReadText(dir / "a" / "sensitivity.csv");
  EXPECT_GT(std::count(a.begin(), a.end(), '\n'), 4);
  EXPECT_EQ(a, ReadText(dir / "b" / "sensitivity.csv"));
  for (const std::string& args : {std::string("--spec '") + spec.string() + "' '" + kScene + "'",
                                  std::string("--spec '") + spec.string() + "' --parameters mass",
                                  std::string("--spec '") + (dir / "missing.yaml").string() + "'", std::string()}) {
    const CommandResult r = RunKneedyn("sensitivity " + args + " --out '" + (dir / "c").string() + "'");
    EXPECT_EQ(r.exit_code, 2) << args << ": " << r.output;
    EXPECT_FALSE(fs::exists(dir / "c")) << args;
  }
  // A sweep parameter without a sensitivity, from a spec: the spec and the rule are named
  // (before: "--parameters: 'inertia_x' is not a parameter of this scene; nearest valid
  // name: 'LCL.tibial_x'", an option never given).
  const fs::path inertia = dir / "inertia.yaml";
  WriteText(inertia, "scene: " + kScene + "\nparameters:\n  - {name: inertia_x, relative: 0.1}\n"
                         "design: {type: lhs, samples: 2}\noutcomes: [liftoff_time]\n");
  const CommandResult r = RunKneedyn("sensitivity --spec '" + inertia.string() + "' --out '" + (dir / "c").string() + "'");
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("--spec = '" + inertia.string() + "': parameters: 'inertia_x' is a sweep parameter whose "
                          "sensitivity is not implemented"),
            std::string::npos)
      << r.output;
  EXPECT_FALSE(fs::exists(dir / "c"));
  // The program's name once: "kneedyn sensitivity: error: --parameters: …" (before:
  // "kneedyn sensitivity: error: kneedyn sensitivity(): --parameters: …").
  const CommandResult unknown = RunKneedyn("sensitivity '" + kScene + "' --parameters nosuch --outcomes liftoff_time "
                                           "--out '" + (dir / "c").string() + "'");
  EXPECT_EQ(unknown.exit_code, 2) << unknown.output;
  EXPECT_NE(unknown.output.find("kneedyn sensitivity: error: --parameters: 'nosuch'"), std::string::npos)
      << unknown.output;
  fs::remove_all(dir);
}

// --formulation dae: the same files and fields (extended, not renamed), the JSON naming IDAS;
// a formulation without sensitivities exits 2 naming the field and value, writing nothing.
TEST(SensitivityCli, DaeFormulationWritesTheSameSetNamingIdas) {
  const fs::path out = FreshDir("dae");
  CommandResult r = RunKneedyn("sensitivity '" + kScene + "' --formulation newmark --parameters mass --outcomes time_90_s --out '" +
                               out.string() + "'");
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("--formulation = 'newmark'"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(out));
  r = RunKneedyn("sensitivity '" + kScene + "' --formulation dae --parameters 'PCL anterior.k_linear,pulse.amplitude' "
                 "--outcomes liftoff_time_s,peak_F_PCL_anterior_N --out '" + out.string() + "'");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("IDAS BDF"), std::string::npos) << r.output;
  const std::string csv = ReadText(out / "sensitivity.csv");
  EXPECT_EQ(csv.substr(0, csv.find('\n')), "outcome,parameter,parameter_value,value,derivative,normalized");
  EXPECT_EQ(std::count(csv.begin(), csv.end(), '\n'), 5);
  const std::string traj = ReadText(out / "sensitivity_trajectory.csv");
  EXPECT_EQ(traj.substr(0, traj.find('\n')),
            "time_s,parameter,x0_mm,y0_mm,z0_mm,flexion_deg,valgus_deg,external_rotation_deg,d_x0_mm,d_y0_mm,d_z0_mm,"
            "d_flexion_deg,d_valgus_deg,d_external_rotation_deg");
  const nlohmann::json j = nlohmann::json::parse(ReadText(out / "sensitivity.json"));
  EXPECT_EQ(j["settings"]["formulation"], "dae");
  EXPECT_EQ(j["settings"]["integrator"], "idas-bdf");
  EXPECT_EQ(j["end_reason"], "flexion_90");
  EXPECT_GT(j["statistics"]["sensitivity_rhs_evaluations"].get<long>(), 0);
  EXPECT_LT(j["statistics"]["initial_sensitivity_residual"].get<double>(), 1e-7);
  EXPECT_EQ(j["rows"][0]["outcome"], "liftoff_time_s");
  EXPECT_TRUE(j["rows"][0]["derivative"].is_number());
  fs::remove_all(out);
}

}  // namespace
}  // namespace kneedyn::cli_test
