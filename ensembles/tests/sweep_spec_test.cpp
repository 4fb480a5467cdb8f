// Sweep specs (ensembles/sweep_spec.hpp). Validates: strict validation (every rejected
// spec names the field and the value), parameter resolution against the base scene, the
// parameter-to-model mapping (an attachment moved with e fixed gives L0 = |AB| / e at the
// reference pose, computed here from the coordinates), and the inverse normal CDF against
// SciPy's norm.ppf. Does not run sweeps (sweep_test.cpp).
#include <gtest/gtest.h>

#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>

#include "ensembles/sweep_spec.hpp"
#include "solver/error.hpp"
#include "solver/patella.hpp"
#include "solver/pose.hpp"

using namespace kneedyn;
using namespace kneedyn::ensembles;

namespace {

namespace fs = std::filesystem;
const std::string kScenes = std::string(KNEEDYN_SOURCE_DIR) + "/reference-data/scenes";

std::string Spec(const std::string& parameters, const std::string& design = "{type: sobol, samples: 4}",
                 const std::string& extra = "") {
  return "scene: chapter_impact.yaml\nparameters:\n" + parameters + "\ndesign: " + design +
         "\noutcomes: [liftoff_time, peak_ligament_force]\n" + extra;
}

SweepSpec Parse(const std::string& text) { return ParseSweepSpec(text, "spec.yaml", kScenes); }

// The message of the InputError the text raises ("" if none).
std::string Rejection(const std::string& text) {
  try {
    Parse(text);
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

}  // namespace

TEST(SweepSpec, ResolvesParametersWithTheBaseScenesNominalValues) {
  const SweepSpec s = Parse(Spec(
      "  - {name: PCL anterior.k_linear, relative: 0.3}\n"
      "  - {name: MCL_deep.tibial_y, uniform: [-2, 2]}\n"
      "  - {name: pulse.amplitude, normal: [100, 10]}\n"
      "  - {name: pulse.duration, uniform: [0.08, 0.12]}\n"
      "  - {name: LCL.slack_length, relative: 0.05}",
      "{type: lhs, samples: 10, seed: 3}", ""));
  ASSERT_EQ(s.parameters.size(), 5u);
  EXPECT_EQ(s.parameters[0].column, "PCL_anterior.k_linear_N_mm");
  EXPECT_DOUBLE_EQ(s.parameters[0].nominal, 125.0);  // Table 1.2
  EXPECT_DOUBLE_EQ(s.parameters[0].a, 87.5);
  EXPECT_DOUBLE_EQ(s.parameters[0].b, 162.5);
  EXPECT_EQ(s.parameters[1].column, "MCL_deep.tibial_y_mm");
  EXPECT_DOUBLE_EQ(s.parameters[1].nominal, 0.0);  // Table 1.1
  EXPECT_EQ(s.parameters[2].distribution, Distribution::kNormal);
  EXPECT_EQ(s.parameters[3].column, "pulse.duration_s");
  EXPECT_EQ(s.design.type, DesignType::kLatinHypercube);
  EXPECT_EQ(s.design.seed, 3u);
  EXPECT_EQ(s.run.formulation, "dae");
}

// The spec format's example in ensembles/README.md is a valid spec as printed (its scene path
// is relative to a spec in reference-data/specs/). Before, its `integrator: ""` was refused.
TEST(SweepSpec, TheReadmeExampleIsAccepted) {
  std::ifstream in(std::string(KNEEDYN_SOURCE_DIR) + "/ensembles/README.md");
  const std::string readme((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const size_t section = readme.find("## Spec format (YAML)");
  ASSERT_NE(section, std::string::npos);
  const size_t from = readme.find("```yaml\n", section);
  ASSERT_NE(from, std::string::npos);
  const size_t to = readme.find("```", from + 8);
  ASSERT_NE(to, std::string::npos);
  const std::string example = readme.substr(from + 8, to - from - 8);
  try {
    const SweepSpec spec = ParseSweepSpec(example, "README.md", std::string(KNEEDYN_SOURCE_DIR) + "/reference-data/specs");
    EXPECT_EQ(spec.parameters.size(), 3u);
  } catch (const InputError& e) {
    ADD_FAILURE() << e.what() << "\n" << example;
  }
}

// A normal distribution of a parameter that must stay > 0 is accepted when every draw does
// (mean − 8.2 sd > 0): the range, not the distribution's kind, is the rule; its draws at the
// unit cube's ends are the extremes the spec check tested.
TEST(SweepSpec, ANormalWhoseDrawsStayInTheRangeIsAccepted) {
  const SweepSpec s = Parse(Spec("  - {name: mass, normal: [4, 0.1]}"));
  const ParameterSpec& p = s.parameters[0];
  EXPECT_EQ(p.distribution, Distribution::kNormal);
  EXPECT_GT(p.FromUnit(0.0), 3.1);
  EXPECT_LT(p.FromUnit(0.0), 3.2);
  EXPECT_NEAR(p.FromUnit(0.0) + p.FromUnit(1.0), 8.0, 1e-9);  // symmetric about the mean
  for (double u : {1e-300, 1e-20, 0.5, 1.0 - 1e-17}) EXPECT_TRUE(RangeOf(p.kind).Contains(p.FromUnit(u))) << u;
}

TEST(SweepSpec, RejectionsNameTheFieldAndTheValue) {
  struct Case {
    std::string text, must_contain;
  };
  const std::vector<Case> cases = {
      {Spec("  - {name: PCL middle.k_linear, relative: 0.3}"), "'PCL middle.k_linear'"},
      {Spec("  - {name: PCL anterior.k_lin, relative: 0.3}"), "unknown property 'k_lin'"},
      {Spec("  - {name: mass, uniform: [5, 4]}"), "parameters[0].uniform[1]' = '4'"},
      {Spec("  - {name: mass, uniform: [-1, 4]}"), "mass must lie in [0.001, 1000] (the scene's range); this range is [-1, 4]"},
      // The scene file's limits hold for a sweep's values too (before, these ran).
      {Spec("  - {name: pulse.amplitude, uniform: [-1.0e9, -1.0e8]}"), "must lie in [0, 100000]"},
      {Spec("  - {name: PCL anterior.k_linear, uniform: [0, 10]}"), "must lie in (0, 1000000]"},
      {Spec("  - {name: MCL deep.tibial_y, uniform: [-2000, 0]}"), "must lie in [-1000, 1000]"},
      // A normal's draws reach mean ± 8.2 sd (FromUnit clamps u to [2^-53, 1 - 2^-53]).
      {Spec("  - {name: mass, normal: [4, 0.5]}"), "this normal distribution draws values in [-0.1"},
      {Spec("  - {name: mass, relative: 1.5}"), "parameters[0].relative' = '1.5'"},
      // The run count it would take, as the grid's refusal gives it (before: "too many runs").
      {Spec("  - {name: mass, relative: 0.1}", "{type: saltelli, samples: 50000000}"),
       "design.samples' = '50000000': samples × (parameters + 2) = 150000000 runs"},
      {Spec("  - {name: mass, relative: 0.1, uniform: [1, 2]}"), "exactly one of"},
      {Spec("  - {name: mass, relativ: 0.1}"), "unknown key 'parameters[0].relativ'"},
      {Spec("  - {name: MCL deep.tibial_y, relative: 0.1}"), "nominal value"},
      {Spec("  - {name: mass, relative: 0.1}\n  - {name: mass, relative: 0.2}"), "listed twice"},
      // e moves nothing once the slack length is set: its column varied, its outcomes did not.
      {Spec("  - {name: PCL anterior.slack_length, relative: 0.1}\n  - {name: PCL anterior.extension_ratio, relative: 0.01}"),
       "'PCL anterior.slack_length' and 'PCL anterior.extension_ratio': the slack length fixes L0"},
      // Accepted and ignored before: the Sobol' and Saltelli designs are not random.
      {Spec("  - {name: mass, relative: 0.1}", "{type: saltelli, samples: 4, seed: 99}"),
       "design.seed' = '99': only an lhs design is random"},
      {Spec("  - {name: mass, relative: 0.1}", "{type: halton, samples: 4}"), "'halton'"},
      {Spec("  - {name: mass, relative: 0.1}", "{type: sobol, samples: 0}"), "design.samples' = '0'"},
      {Spec("  - {name: mass, relative: 0.1}", "{type: sobol, samples: 2.5}"), "'2.5'"},
      // YAML: a quoted scalar is a string, not a number.
      {Spec("  - {name: mass, relative: \"0.1\"}"), "parameters[0].relative' = '0.1': must be a number, not a quoted string"},
      {Spec("  - {name: mass, relative: 0.1}", "{type: sobol, samples: '4'}"), "design.samples' = '4': must be a number, not a quoted string"},
      {Spec("  - {name: mass, relative: 0.1}", "{type: grid, samples: 4}"), "takes 'levels'"},
      {Spec("  - {name: pulse.amplitude, normal: [100, 5]}", "{type: grid, levels: 3}"), "bounded"},
      {Spec("  - {name: mass, relative: 0.1}", "{type: sobol, samples: 4}", "solver: {rtol: -1}\n"), "rtol"},
      {Spec("  - {name: mass, relative: 0.1}", "{type: sobol, samples: 4}", "solver: {formulation: magic}\n"),
       "'magic'"},
      {Spec("  - {name: mass, relative: 0.1}", "{type: sobol, samples: 4}", "extra_key: 1\n"), "unknown key 'extra_key'"},
      // kneedyn run's output-grid rule on the scene's end time, before the runs (before: every
      // row failed with RunScene's message naming --output-interval, exit 0).
      {Spec("  - {name: mass, relative: 0.1}", "{type: sobol, samples: 4}", "solver: {output_interval_s: 0.000001}\n"),
       "solver.output_interval_s' = '0.000001': output interval 1e-06 s gives"},
      // kneedyn run's fixed-step rule on the base scene, before the runs.
      {Spec("  - {name: mass, relative: 0.1}", "{type: sobol, samples: 4}", "solver: {formulation: newmark, output_interval_s: 0.00005}\n"),
       "output interval 5e-05 s is shorter than the fixed step 0.0001 s"},
      {"scene: nowhere.yaml\nparameters: [{name: mass, relative: 0.1}]\ndesign: {type: sobol, samples: 2}\n"
       "outcomes: [liftoff_time]\n",
       "nowhere.yaml"},
      // A directory: before, LoadScene's message without the spec's file or field.
      {"scene: /tmp\nparameters: [{name: mass, relative: 0.1}]\ndesign: {type: sobol, samples: 2}\n"
       "outcomes: [liftoff_time]\n",
       "field 'scene' = '/tmp': not a regular file"},
      {"scene: chapter_impact.yaml\nparameters: [{name: mass, relative: 0.1}]\ndesign: {type: sobol, samples: 2}\n"
       "outcomes: [liftoff_angle]\n",
       "'liftoff_angle'"},
      // A pulse parameter of a scene without a pulse would change nothing.
      {"scene: gravity_only.yaml\nparameters: [{name: pulse.amplitude, uniform: [50, 150]}]\n"
       "design: {type: sobol, samples: 2}\noutcomes: [time_90]\n",
       "'pulse.amplitude': the base scene has no tibial pulse (pulse.shape none)"},
      {"analytic: ishigami\nparameters: [{name: x4, uniform: [0, 1]}]\ndesign: {type: sobol, samples: 2}\n"
       "outcomes: [value]\n",
       "'x4'"},
  };
  for (const Case& c : cases) {
    const std::string why = Rejection(c.text);
    EXPECT_NE(why.find(c.must_contain), std::string::npos) << "spec:\n" << c.text << "\nmessage: " << why;
    EXPECT_NE(why.find("spec.yaml"), std::string::npos) << why;
  }
}

// A uniform parameter's last grid level is its upper end exactly: a + 1 (b − a) is not b for
// some pairs (0.03 + (0.3 − 0.03) = 0.30000000000000004), and the lower end is a.
// Shards must run one model: the fingerprint covers the scene's and the parameter set's bytes,
// not only the spec's (a scene edited between two shards merged without a word).
TEST(SweepSpec, FingerprintCoversTheSceneAndItsParameterSet) {
  const fs::path dir = fs::temp_directory_path() / ("kneedyn_fingerprint_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir / "scenes");
  fs::copy_file(kScenes + "/../chapter_knee.yaml", dir / "chapter_knee.yaml");
  fs::copy_file(kScenes + "/chapter_impact.yaml", dir / "scenes" / "chapter_impact.yaml");
  const std::string spec = Spec("  - {name: mass, relative: 0.1}");
  const auto fingerprint = [&] { return ParseSweepSpec(spec, "spec.yaml", (dir / "scenes").string()).fingerprint; };
  const std::uint64_t original = fingerprint();
  EXPECT_EQ(fingerprint(), original);  // the same files, the same fingerprint
  std::ofstream(dir / "chapter_knee.yaml", std::ios::app) << "# edited\n";
  const std::uint64_t edited_parameters = fingerprint();
  EXPECT_NE(edited_parameters, original);
  std::ofstream(dir / "scenes" / "chapter_impact.yaml", std::ios::app) << "# edited\n";
  EXPECT_NE(fingerprint(), edited_parameters);
  fs::remove_all(dir);
}

TEST(SweepSpec, UniformEndsAreExact) {
  for (const auto& [a, b] : std::vector<std::pair<double, double>>{{0.03, 0.3}, {0.1, 0.7}, {-5.0, 0.3}, {1.0, 2.0}}) {
    ParameterSpec p;
    p.distribution = Distribution::kUniform;
    p.a = a;
    p.b = b;
    EXPECT_EQ(p.FromUnit(0.0), a);
    EXPECT_EQ(p.FromUnit(1.0), b);
    EXPECT_EQ(p.FromUnit(0.5), a + 0.5 * (b - a));  // inside: as before
  }
  ASSERT_NE(0.03 + 1.0 * (0.3 - 0.03), 0.3);  // the case that was wrong
}

TEST(SweepSpec, SaltelliRefusesMoreParametersThanTheSobolTableCovers) {
  std::string params;  // 33 distinct parameters
  const char* elements[] = {"ACL anterior", "ACL posterior", "PCL anterior", "PCL posterior", "MCL anterior",
                            "MCL oblique", "MCL deep", "LCL", "capsule medial", "capsule lateral",
                            "oblique popliteal"};
  for (const char* e : elements) {
    for (const char* p : {"k_linear", "k_parabolic", "extension_ratio"}) {
      params += "  - {name: " + std::string(e) + "." + p + ", relative: 0.1}\n";
    }
  }
  EXPECT_NE(Rejection(Spec(params, "{type: saltelli, samples: 4}")).find("at most 32 parameters"), std::string::npos);
}

TEST(SweepSpec, SceneForRunMovesSlackLengthWithTheAttachment) {
  const SweepSpec s = Parse(Spec(
      "  - {name: PCL anterior.femoral_x, uniform: [-10, 0]}\n"
      "  - {name: PCL anterior.k_linear, relative: 0.3}\n"
      "  - {name: LCL.slack_length, relative: 0.05}\n"
      "  - {name: pulse.duration, uniform: [0.05, 0.15]}"));
  const Scene scene = SceneForRun(s, {-6.0, 100.0, 50.0, 0.12});
  const Model& m = scene.model;
  const Ligament& pcl = m.ligaments[s.parameters[0].ligament];
  EXPECT_DOUBLE_EQ(pcl.p_FoA_F.x(), -0.006);
  EXPECT_DOUBLE_EQ(pcl.k_linear, 100.0e3);
  // L0 = |A_F − (R0 + R_FT B_T)| / e at the reference pose, e = 1.004 (Table 1.3).
  const Pose ref = PoseFromCoordinates(scene.reference_q);
  const Vector3d span = pcl.p_FoA_F - (ref.p_FoTo_F + ref.R_FT * pcl.p_ToB_T);
  EXPECT_NEAR(pcl.slack_length, span.norm() / 1.004, 1e-15);
  const Ligament& lcl = m.ligaments[s.parameters[2].ligament];
  EXPECT_DOUBLE_EQ(lcl.slack_length, 0.050);
  EXPECT_NEAR(lcl.extension_ratio, lcl.reference_length / 0.050, 1e-15);
  EXPECT_DOUBLE_EQ(m.pulse.duration, 0.12);
  // Untouched elements keep the base scene's values.
  EXPECT_EQ(m.ligaments[0].slack_length, s.base.model.ligaments[0].slack_length);
}

// A principal moment of inertia is a sweep parameter: its nominal value is the parameter
// set's (principal_inertia_kg_m2: 0.0672, 0.0672, 0.005334) and a run's value replaces only
// that moment.
TEST(SweepSpec, PrincipalInertiaIsAParameter) {
  const SweepSpec s = Parse(Spec(
      "  - {name: inertia_z, relative: 0.1}\n"
      "  - {name: inertia_x, uniform: [0.06, 0.07]}"));
  EXPECT_EQ(s.parameters[0].kind, ParameterKind::kPrincipalInertia);
  EXPECT_DOUBLE_EQ(s.parameters[0].nominal, 0.005334);
  EXPECT_EQ(s.parameters[0].column, "inertia_z_kg_m2");
  EXPECT_DOUBLE_EQ(s.parameters[1].nominal, 0.0672);
  const Scene scene = SceneForRun(s, {0.006, 0.065});
  EXPECT_DOUBLE_EQ(scene.model.inertia_T.z(), 0.006);
  EXPECT_DOUBLE_EQ(scene.model.inertia_T.x(), 0.065);
  EXPECT_DOUBLE_EQ(scene.model.inertia_T.y(), 0.0672);
  EXPECT_THROW(Parse(Spec("  - {name: inertia_w, relative: 0.1}")), InputError);
}

// The patella's quadriceps magnitude and tendon length are sweep parameters of a scene with
// a patella (nominal values from patellofemoral_impact.yaml: 50 N, 42 mm); a longer tendon
// moves the patella's start equilibrium, whose tendon then has the new length.
TEST(SweepSpec, QuadricepsAndTendonLengthAreParameters) {
  const std::string params = "  - {name: quadriceps.magnitude, uniform: [40, 60]}\n"
                             "  - {name: patella.tendon_length, uniform: [40, 46]}";
  const SweepSpec s = Parse("scene: patellofemoral_impact.yaml\nparameters:\n" + params +
                            "\ndesign: {type: sobol, samples: 4}\noutcomes: [liftoff_time]\n");
  EXPECT_EQ(s.parameters[0].kind, ParameterKind::kQuadricepsMagnitude);
  EXPECT_DOUBLE_EQ(s.parameters[0].nominal, 50.0);
  EXPECT_EQ(s.parameters[1].column, "patella.tendon_length_mm");
  EXPECT_DOUBLE_EQ(s.parameters[1].nominal, 42.0);
  const Scene scene = SceneForRun(s, {55.0, 45.0});
  const Patella& p = *scene.model.patella;
  EXPECT_DOUBLE_EQ(p.quadriceps.magnitude, 55.0);
  EXPECT_DOUBLE_EQ(p.tendon_length, 0.045);
  const Vector3d apex_F = PatellaPose(p.start_unknowns.data()).PointInF(p.apex_P);
  const Vector3d tuberosity_F = TuberosityInF(p, PoseFromCoordinates(p.start_q));
  EXPECT_NEAR((tuberosity_F - apex_F).norm(), 0.045, 1e-13);
  EXPECT_NE(Rejection(Spec("  - {name: quadriceps.magnitude, uniform: [40, 60]}")).find("no patella"), std::string::npos);
}

TEST(SweepSpec, InverseNormalCdfMatchesScipy) {
  EXPECT_NEAR(InverseNormalCdf(0.975), 1.959963984540054, 1e-15);
  EXPECT_NEAR(InverseNormalCdf(0.3), -0.5244005127080409, 1e-15);
  EXPECT_NEAR(InverseNormalCdf(1e-10), -6.361340902404056, 1e-13);
  EXPECT_EQ(InverseNormalCdf(0.5), 0.0);
}
