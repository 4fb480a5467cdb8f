// The patella's parameters in sweeps and sensitivity studies (ensembles/sweep_spec.hpp,
// docs/model.md §12; names in ensembles/README.md): a sweep value is the same model as the
// same number edited into the scene file, a forward sensitivity agrees with central
// differences, and a patella parameter named on a scene without a patella is refused.
#include <gtest/gtest.h>

#include <cmath>

#include "cli_support.hpp"
#include "ensembles/sweep.hpp"
#include "ensembles/sweep_spec.hpp"
#include "formulations/run.hpp"
#include "scene/scene.hpp"
#include "sensitivity/forward_sensitivity.hpp"
#include "sensitivity/sensitivity_cli.hpp"
#include "solver/error.hpp"
#include "solver/patella.hpp"

namespace kneedyn {
namespace {

using cli_test::CommandResult;
using cli_test::ReadText;
using cli_test::Replaced;
using cli_test::RunKneedyn;
using cli_test::WriteText;
namespace fs = std::filesystem;

const std::string kScenes = std::string(KNEEDYN_SOURCE_DIR) + "/reference-data/scenes/";

fs::path FreshDir(const std::string& name) {
  const fs::path d = fs::temp_directory_path() / ("kneedyn_patella_parameters_" + name + "_" + std::to_string(::getpid()));
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}

ensembles::SweepSpec Spec(const std::string& parameters) {
  return ensembles::ParseSweepSpec("scene: patellofemoral_impact.yaml\nparameters:\n" + parameters +
                                       "\ndesign: {type: sobol, samples: 2}\noutcomes: [liftoff_time, time_at_90]\n"
                                       "solver: {formulation: ede}\n",
                                   "test spec", kScenes);
}

// The run of a scene file with one text edit, through the loader (path 2 of the tests below).
RunResult RunEdited(const ensembles::SweepSpec& spec, const std::string& from, const std::string& to) {
  const std::string text = Replaced(ReadText(kScenes + "patellofemoral_impact.yaml"), from, to);
  EXPECT_NE(text.find(to), std::string::npos);
  const Scene scene = ParseScene(text, "edited", kScenes);
  return RunScene(scene, spec.run);
}

double EventTime(const RunResult& r, const std::string& prefix) {
  for (const EventRecord& e : r.events) {
    if (e.name.rfind(prefix, 0) == 0) return e.time;
  }
  return NAN;
}

// Two paths to the same model: the sweep applies the value to the loaded model
// (SceneForRun), the loader reads it from the edited file and builds the model from scratch
// (the patella's start equilibrium included). Same model, same run: the outcomes are equal
// to the last bit.
void ExpectSweepEqualsEditedFile(const std::string& parameter, double value, const std::string& from,
                                 const std::string& to) {
  SCOPED_TRACE(parameter);
  const ensembles::SweepSpec spec = Spec("  - {name: " + parameter + ", uniform: [1, 100]}");
  const ensembles::RunRow row = ensembles::EvaluateRunAt(spec, 0, {value});
  ASSERT_TRUE(row.completed) << row.failure;
  const RunResult edited = RunEdited(spec, from, to);
  ASSERT_TRUE(edited.completed) << edited.failure;
  ASSERT_EQ(row.outcomes.size(), 2u);
  EXPECT_EQ(row.outcomes[0], EventTime(edited, "liftoff_"));  // liftoff_time_s
  EXPECT_EQ(row.outcomes[1], EventTime(edited, "flexion_90"));  // time_90_s
  EXPECT_FALSE(std::isnan(row.outcomes[1]));
}

TEST(PatellaParameters, QuadricepsMagnitudeSweepEqualsTheEditedSceneFile) {
  ExpectSweepEqualsEditedFile("quadriceps.magnitude", 80.0, "magnitude_N: 50.0", "magnitude_N: 80.0");
}

TEST(PatellaParameters, TrochlearRadiusSweepEqualsTheEditedSceneFile) {
  ExpectSweepEqualsEditedFile("patella.trochlea_medial.radius", 30.0,
                              "trochlea_medial: {centre_mm: [-22.0, -8.0, 14.0], radius_mm: 28.0}",
                              "trochlea_medial: {centre_mm: [-22.0, -8.0, 14.0], radius_mm: 30.0}");
}

TEST(PatellaParameters, FacetOffsetAndTrochlearCentreAreParameters) {
  const ensembles::SweepSpec spec = Spec("  - {name: patella.facet_lateral.offset, uniform: [-1, 1]}\n"
                                         "  - {name: patella.trochlea_lateral.centre_y, uniform: [-9, -7]}\n"
                                         "  - {name: patella.tendon_length, uniform: [40, 44]}");
  EXPECT_EQ(spec.parameters[0].column, "patella.facet_lateral.offset_mm");
  EXPECT_EQ(spec.parameters[0].nominal, 0.0);
  EXPECT_EQ(spec.parameters[1].nominal, -8.0);
  EXPECT_EQ(spec.parameters[1].axis, 1);
  const Scene scene = ensembles::SceneForRun(spec, {0.5, -7.5, 43.0});
  const Patella& p = *scene.model.patella;
  Vector3d centre, normal;
  double radius = 0.0, offset = 0.0;
  ASSERT_TRUE(p.facet[1].femoral_surface->SphereForm(&centre, &radius));
  ASSERT_TRUE(p.facet[1].tibial_surface->PlaneForm(&normal, &offset));
  EXPECT_DOUBLE_EQ(centre.y(), -0.0075);
  EXPECT_DOUBLE_EQ(offset, 0.0005);
  // The base scene's surfaces are untouched (SceneForRun builds new ones).
  ASSERT_TRUE(spec.base.model.patella->facet[1].femoral_surface->SphereForm(&centre, &radius));
  EXPECT_DOUBLE_EQ(centre.y(), -0.008);
  // The start equilibrium is that of the new geometry: its residuals vanish there.
  const Vector3d tuberosity_F = TuberosityInF(p, PoseFromCoordinates(p.start_q));
  EXPECT_LT(PatellaResidualNorm(p, tuberosity_F, p.start_unknowns), 1e-12);
  // Baseline and duration belong to a ramp or a half-sine, not to the impact's constant force.
  EXPECT_THROW(Spec("  - {name: quadriceps.baseline, uniform: [10, 20]}"), InputError);
  EXPECT_THROW(Spec("  - {name: patella.trochlea_middle.radius, uniform: [10, 20]}"), InputError);
}

// d(time at 90°)/d(tendon length): CVODES forward sensitivities against central differences
// of two more runs (relative step 1e-3): two independent derivatives of the same outcome.
TEST(PatellaParameters, TendonLengthSensitivityAgreesWithCentralDifferences) {
  const Scene scene = LoadScene(kScenes + "patellofemoral_impact.yaml");
  const std::vector<ensembles::ParameterSpec> params = {
      ensembles::ResolveParameterName(scene, "patella.tendon_length", "test", "parameters")};
  ASSERT_DOUBLE_EQ(params[0].nominal, 42.0);
  sensitivity::SensitivityOptions options;
  options.rtol = 1e-9;
  options.atol = 1e-11;
  const std::vector<std::string> outcomes = {"time_90_s"};
  const sensitivity::SensitivityResult r = sensitivity::RunSensitivity(scene, params, {42.0}, outcomes, options);
  const auto fd = sensitivity::CentralDifferences(scene, params, {42.0}, outcomes, options, 1e-3);
  const double forward = r.derivatives[0][0], central = fd[0][0];
  EXPECT_TRUE(std::isfinite(forward));
  EXPECT_NE(forward, 0.0);
  EXPECT_NEAR(forward, central, 1e-3 * std::abs(central)) << "forward " << forward << " s/mm, central " << central;
}

// A patella parameter on a scene without a patella: exit 2 naming the parameter, nothing
// written (kneedyn sensitivity and kneedyn sweep).
TEST(PatellaParameters, PatellaParameterOnASceneWithoutPatellaExitsTwoNamingIt) {
  const fs::path dir = FreshDir("refusal");
  const std::string chapter = kScenes + "chapter_impact.yaml";
  const fs::path out = dir / "out";
  CommandResult r = RunKneedyn("sensitivity '" + chapter +
                               "' --parameters patella.tendon_length --outcomes time_90_s --out '" + out.string() + "'");
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("patella.tendon_length"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(out));
  const fs::path spec = dir / "spec.yaml";
  WriteText(spec, "scene: " + chapter + "\nparameters:\n  - {name: quadriceps.magnitude, uniform: [40, 60]}\n"
                  "design: {type: sobol, samples: 2}\noutcomes: [time_at_90]\n");
  r = RunKneedyn("sweep '" + spec.string() + "' --out '" + out.string() + "'");
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("quadriceps.magnitude"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(out));
  fs::remove_all(dir);
}

}  // namespace
}  // namespace kneedyn
