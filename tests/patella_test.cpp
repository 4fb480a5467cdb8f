// The patello-femoral joint (docs/model.md §12): the patella's equilibrium, the tendon
// force's derivative, the refusal of a non-pulling quadriceps, and the three couplings
// (ODE check, Newton-based DAE, staggered) against each other.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <sstream>
#include <unistd.h>

#include <nlohmann/json.hpp>

#include "formulations/formulation.hpp"
#include "formulations/run.hpp"
#include "formulations/run_output.hpp"
#include "scene/scene.hpp"
#include "solver/consistent_init.hpp"
#include "solver/constraint_residuals.hpp"
#include "solver/contact_kinematics.hpp"
#include "solver/dynamics.hpp"
#include "solver/patella.hpp"
#include "solver/rotation.hpp"
#include "solver/units.hpp"

namespace kneedyn {
namespace {

Scene ImpactScene() { return LoadScene("reference-data/scenes/patellofemoral_impact.yaml"); }

// The impact scene with a quadriceps half-sine of 1e5 N over a 50 N baseline, lasting
// `duration` (s): the largest force the scene format allows, for the pulse tests below.
Scene ImpactSceneWithQuadricepsHalfSine(double duration) {
  Scene scene = ImpactScene();
  QuadricepsForce& quadriceps = scene.model.patella->quadriceps;
  quadriceps.shape = QuadricepsShape::kHalfSine;
  quadriceps.baseline = 50.0;
  quadriceps.magnitude = 1.0e5;
  quadriceps.duration = duration;
  return scene;
}

// Tibial poses the knee passes through: the chapter's impact (no patella, ede) at the first
// output rows past the given flexion angles.
std::vector<Vector6d> ChapterPoses(const std::vector<double>& alpha_deg) {
  RunSettings settings;
  settings.formulation = "ede";
  const RunResult run = RunScene(LoadScene("reference-data/scenes/chapter_impact.yaml"), settings);
  std::vector<Vector6d> poses;
  for (double a : alpha_deg) {
    for (const MechanicalState& s : run.samples) {
      if (s.q(kAlpha) >= DegToRad(a) - 1e-9) {
        poses.push_back(s.q);
        break;
      }
    }
  }
  EXPECT_EQ(poses.size(), alpha_deg.size());
  return poses;
}

TEST(Patella, EquilibriumHoldsAtTheSolvedPatellaByASecondContactDescription) {
  const Scene scene = ImpactScene();
  ASSERT_TRUE(scene.model.patella.has_value());
  const Patella& patella = *scene.model.patella;
  for (const Vector6d& q : ChapterPoses({0.0, 30.0, 60.0, 89.0})) {
    SCOPED_TRACE(q(kAlpha));
    PatellaGuess guess;
    const Vector3d tuberosity_F = TuberosityInF(patella, PoseFromCoordinates(q));
    SolvePatella(patella, tuberosity_F, "test", &guess);
    EXPECT_LT(PatellaResidualNorm(patella, tuberosity_F, guess.x), 1e-13);
    // Independent of the chapter-form residuals: the closed-form sphere-on-plane contact
    // (contact.hpp) at the solved pose closes both facets, and the six equilibrium
    // equations written with its contact points and the tendon from the apex hold in N.
    const Pose pose = PatellaPose(guess.x.data());
    const double F_Q = 50.0;
    Vector3d force = F_Q * patella.quadriceps.direction_F;
    const Vector3d base_F = pose.PointInF(patella.base_P), apex_F = pose.PointInF(patella.apex_P);
    Vector3d moment = base_F.cross(force);  // about F's origin this time
    EXPECT_NEAR((tuberosity_F - apex_F).norm(), patella.tendon_length, 1e-14);
    const Vector3d tendon = guess.x[kPatellaTendonRatio] * F_Q * (tuberosity_F - apex_F).normalized();
    force += tendon;
    moment += apex_F.cross(tendon);
    for (int i = 0; i < 2; ++i) {
      SphereOnPlane sop;
      ASSERT_TRUE(SphereOnPlaneForm(patella.facet[i], &sop));
      const ContactGeometry g = SphereOnPlaneContact(sop, pose);
      EXPECT_NEAR(g.gap, 0.0, 1e-14) << "facet " << i;
      const double N = guess.x[kPatellaFacetRatio + i] * F_Q;
      EXPECT_GT(N, 0.0) << "facet " << i << " pulls";
      const Vector3d contact_force = -N * (pose.R_FT * g.normal_T);
      force += contact_force;
      moment += g.point_F.cross(contact_force);
    }
    EXPECT_LT(force.norm(), 1e-11 * F_Q);
    EXPECT_LT(moment.norm(), 1e-12 * F_Q);
    EXPECT_GT(guess.x[kPatellaTendonRatio], 0.0);
  }
}

TEST(Patella, TendonForceDerivativeMatchesCentralDifferences) {
  const Scene scene = ImpactScene();
  const Patella& patella = *scene.model.patella;
  const Vector6d q = ChapterPoses({40.0}).at(0);
  using J6 = ceres::Jet<double, 6>;
  Vector6<J6> qj;
  for (int i = 0; i < 6; ++i) qj(i) = J6(q(i), i);
  PatellaGuess guess;
  J6 tension;
  Vector3<J6> force;
  PatellarTendonForce(patella, 0.0, PoseFromCoordinates(qj), &guess, &tension, &force);
  for (int i = 0; i < 6; ++i) {
    const double h = i < 3 ? 1e-6 : 1e-5;
    Vector6d qp = q, qm = q;
    qp(i) += h;
    qm(i) -= h;
    double tp, tm;
    Vector3d fp, fm;
    PatellaGuess g = guess;
    PatellarTendonForce(patella, 0.0, PoseFromCoordinates(qp), &g, &tp, &fp);
    PatellarTendonForce(patella, 0.0, PoseFromCoordinates(qm), &g, &tm, &fm);
    const Vector3d fd = (fp - fm) / (2 * h);
    for (int k = 0; k < 3; ++k) {
      EXPECT_NEAR(force(k).v(i), fd(k), 1e-6 * (1.0 + fd.norm())) << "dF_" << k << "/dq_" << i;
    }
    EXPECT_NEAR(tension.v(i), (tp - tm) / (2 * h), 1e-6 * (1.0 + std::abs(tension.v(i))));
  }
}

std::string SceneWithQuadriceps(const std::string& quadriceps) {
  return R"(name: q
parameter_set: ../chapter_knee.yaml
ligaments: all
contacts: [medial, lateral]
gravity: {enabled: true}
pulse: {shape: none}
patella:
  trochlea_medial: {centre_mm: [-22.0, -8.0, 14.0], radius_mm: 28.0}
  trochlea_lateral: {centre_mm: [22.0, -8.0, 14.0], radius_mm: 28.0}
  facet_medial: {normal_P: [-0.5, -0.8660254037844386, 0.0], offset_mm: 0.0}
  facet_lateral: {normal_P: [0.42261826174069944, -0.9063077870366499, 0.0], offset_mm: 0.0}
  apex_P_mm: [0.0, 8.0, -22.0]
  base_P_mm: [0.0, 12.0, 20.0]
  tuberosity_T_mm: [4.0, 34.0, 183.0]
  tendon_length_mm: 42.0
  quadriceps: )" + quadriceps + R"(
initial_state: {pose: reference}
end: {time_s: 0.1}
)";
}

TEST(Patella, QuadricepsThatDoesNotPullIsRefusedNamingTheField) {
  const std::string dir = "reference-data/scenes";
  const std::pair<std::string, std::string> cases[] = {
      {"{shape: constant, magnitude_N: 0.0}", "patella.quadriceps.magnitude_N = 0"},
      {"{shape: constant, magnitude_N: -20}", "patella.quadriceps.magnitude_N = -20"},
      {"{shape: ramp, magnitude_N: 200.0, duration_s: 0.1}", "patella.quadriceps.baseline_N = 0"},
      {"{shape: half_sine, baseline_N: 50, magnitude_N: -80, duration_s: 0.1}", "magnitude_N = -80"},
  };
  for (const auto& [quadriceps, expected] : cases) {
    try {
      ParseScene(SceneWithQuadriceps(quadriceps), "q.yaml", dir);
      ADD_FAILURE() << quadriceps << " accepted";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(expected), std::string::npos) << e.what();
    }
  }
  EXPECT_NO_THROW(ParseScene(SceneWithQuadriceps("{shape: ramp, baseline_N: 10, magnitude_N: 200, duration_s: 0.1}"),
                             "q.yaml", dir));
}

// The constant shape uses magnitude_N alone: a baseline_N or duration_s given with it would
// be ignored, so it is refused, naming the key, the shape and the rule. The other shapes use
// both (their forces depend on them: QuadricepsMagnitude).
TEST(Patella, QuadricepsKeysTheShapeDoesNotUseAreRefused) {
  const std::string dir = "reference-data/scenes";
  for (const char* quadriceps : {"{shape: constant, magnitude_N: 50.0, baseline_N: 10.0}",
                                 "{shape: constant, magnitude_N: 50.0, duration_s: 0.2}"}) {
    try {
      ParseScene(SceneWithQuadriceps(quadriceps), "q.yaml", dir);
      ADD_FAILURE() << quadriceps << " accepted";
    } catch (const InputError& e) {
      const std::string what = e.what();
      const std::string key = std::string(quadriceps).find("baseline_N") != std::string::npos ? "baseline_N" : "duration_s";
      EXPECT_NE(what.find("field 'patella.quadriceps." + key + "'"), std::string::npos) << what;
      EXPECT_NE(what.find("not used by quadriceps shape constant"), std::string::npos) << what;
    }
  }
  for (const char* quadriceps : {"{shape: constant, magnitude_N: 50.0}",
                                 "{shape: ramp, baseline_N: 10, magnitude_N: 200, duration_s: 0.1}",
                                 "{shape: half_sine, baseline_N: 10, magnitude_N: 200, duration_s: 0.1}"}) {
    EXPECT_NO_THROW(ParseScene(SceneWithQuadriceps(quadriceps), "q.yaml", dir)) << quadriceps;
  }
}

// A patella without an extent along P's z (apex and base at one height) is refused naming
// base_P_mm (before: it ran, and its facet contacts were reported off the patella by
// 4e-14 mm, the round-off of a zero-length extent).
TEST(Patella, PatellaWithoutExtentIsRefusedNamingTheBase) {
  std::string text = SceneWithQuadriceps("{shape: constant, magnitude_N: 50.0}");
  const std::string base = "base_P_mm: [0.0, 12.0, 20.0]";
  text.replace(text.find(base), base.size(), "base_P_mm: [0.0, 8.0, -21.5]");
  try {
    ParseScene(text, "q.yaml", "reference-data/scenes");
    ADD_FAILURE() << "a patella 0.5 mm long was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("field 'patella.base_P_mm': z = -21.5 mm lies within 1 mm of apex_P_mm's z = -22 mm"),
              std::string::npos)
        << e.what();
  }
}

// Start geometry the builder cannot solve is refused naming the keys that decide it.
// A tendon too short for the two-facet positions of the apex: the refusal names
// patella.tendon_length_mm and the apex's closest distance D from the tuberosity. D is a
// threshold, checked as one: a tendon 0.1 % shorter is refused for its reach, one 0.1 %
// longer gets past that test (it may still find no equilibrium, a different refusal).
TEST(Patella, TendonThatCannotReachIsRefusedWithTheLengthItNeeds) {
  const std::string dir = "reference-data/scenes";
  const auto with_tendon = [](double length_mm) {
    std::string text = SceneWithQuadriceps("{shape: constant, magnitude_N: 50.0}");
    const std::string key = "tendon_length_mm: 42.0";
    return text.replace(text.find(key), key.size(), StrCat("tendon_length_mm: ", length_mm));
  };
  const auto refusal = [&](double length_mm) -> std::string {
    try {
      ParseScene(with_tendon(length_mm), "q.yaml", dir);
    } catch (const InputError& e) {
      return e.what();
    }
    return "";
  };
  const std::string what = refusal(5.0);
  EXPECT_NE(what.find("field 'patella'"), std::string::npos) << what;
  EXPECT_NE(what.find("patella.tendon_length_mm = 5 mm"), std::string::npos) << what;
  const std::string marker = "passes ";
  const size_t at = what.find(marker);
  ASSERT_NE(at, std::string::npos) << what;
  const double closest_mm = std::stod(what.substr(at + marker.size()));
  EXPECT_GT(closest_mm, 5.0) << what;
  EXPECT_LT(closest_mm, 42.0) << what;  // the shipped length reaches
  EXPECT_NE(refusal(0.999 * closest_mm).find("cannot reach the tuberosity"), std::string::npos);
  EXPECT_EQ(refusal(1.001 * closest_mm).find("cannot reach the tuberosity"), std::string::npos);
  // The shipped impact scene with a tendon of 400 mm (42 shipped): no equilibrium, and the
  // refusal names the key and its value (before: only the tuberosity's position and Newton's
  // failure).
  std::ifstream in(dir + "/patellofemoral_impact.yaml");
  std::string impact((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const std::string key = "tendon_length_mm: 42.0";
  ASSERT_NE(impact.find(key), std::string::npos);
  impact.replace(impact.find(key), key.size(), "tendon_length_mm: 400.0");
  try {
    ParseScene(impact, "long.yaml", dir);
    ADD_FAILURE() << "a 400 mm tendon was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("no patellar equilibrium at the scene's start with patella.tendon_length_mm = 400 mm"),
              std::string::npos)
        << e.what();
  }
}

// A trochlear contact coordinate past its chart's edge is refused with where it is: both
// facets' (u, v) in degrees and the edges (before: "left its chart" and nothing else).
TEST(Patella, ContactCoordinateOffItsChartIsRefusedWithItsCoordinates) {
  const Scene scene = ImpactScene();
  const Patella& patella = *scene.model.patella;
  std::array<double, kPatellaUnknowns> x = patella.start_unknowns;
  x[kPatellaChart] = DegToRad(85.0);  // the medial trochlear chart's u, past |u| < 80°
  try {
    PatellaFacetGaps(patella, x);
    ADD_FAILURE() << "a chart coordinate of 85 deg was evaluated";
  } catch (const SolverError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("trochlear chart (u, v) = (85, "), std::string::npos) << what;
    EXPECT_NE(what.find("the chart ends at |u| = 80, |v| = 170 deg"), std::string::npos) << what;
  }
}

// A facet normal pointing away from the femur (anteriorly) is refused naming it: before, it
// asked for a longer tendon (65.5 mm) and, given one, put the patella behind the trochlear
// centres with positive facet forces.
TEST(Patella, FacetNormalFacingAwayFromTheFemurIsRefused) {
  std::ifstream in("reference-data/scenes/patellofemoral_impact.yaml");
  std::string impact((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const std::string key = "facet_lateral: {normal_P: [0.42261826174069944, -0.9063077870366499, 0.0]";
  ASSERT_NE(impact.find(key), std::string::npos);
  impact.replace(impact.find(key), key.size(), "facet_lateral: {normal_P: [-0.42261826174069944, 0.9063077870366499, 0.0]");
  try {
    ParseScene(impact, "flipped.yaml", "reference-data/scenes");
    ADD_FAILURE() << "a facet facing away from the femur was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("patella.facet_lateral.normal_P = (-0.42"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("posteriorly (y < 0"), std::string::npos) << e.what();
  }
}

// The documented default quadriceps direction [0, 0, 1] has no start equilibrium in the
// shipped impact geometry: the refusal says why, a facet force ratio the force balance
// needs negative (that facet would pull), and names the direction it used.
TEST(Patella, StartWithoutEquilibriumSaysWhichForceWouldPull) {
  std::ifstream in("reference-data/scenes/patellofemoral_impact.yaml");
  std::stringstream buffer;
  buffer << in.rdbuf();
  std::string text = buffer.str();
  const std::string direction = ", direction_F: [0.06, -0.2, 1.0]";
  ASSERT_NE(text.find(direction), std::string::npos);
  EXPECT_NO_THROW(ParseScene(text, "patellofemoral_impact.yaml", "reference-data/scenes"));
  text.erase(text.find(direction), direction.size());
  try {
    ParseScene(text, "patellofemoral_impact.yaml", "reference-data/scenes");
    FAIL() << "the default quadriceps direction was accepted";
  } catch (const InputError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("no patellar equilibrium at the scene's start"), std::string::npos) << what;
    EXPECT_NE(what.find("patella.quadriceps.direction_F (as a unit vector [0, 0, 1])"), std::string::npos) << what;
    const size_t at = what.find("lambda_medial = ");
    ASSERT_NE(at, std::string::npos) << what;
    const double medial = std::stod(what.substr(at + 16));
    const double lateral = std::stod(what.substr(what.find("lambda_lateral = ") + 17));
    EXPECT_LT(std::min(medial, lateral), 0.0) << what;
  }
}

TEST(Patella, StaggeredRefusesASceneWithoutPatella) {
  const Scene chapter = LoadScene("reference-data/scenes/chapter_impact.yaml");
  EXPECT_FALSE(chapter.model.patella.has_value());
  FormulationOptions options;
  options.step = 1e-3;
  try {
    CreateFormulation("staggered", chapter, options);
    ADD_FAILURE() << "staggered accepted a scene without a patella";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("no patella"), std::string::npos) << e.what();
  }
  EXPECT_TRUE(FindFormulation("staggered").needs_patella);
}

RunResult RunWith(const Scene& scene, const std::string& formulation, double rtol, double atol, double step = 0.0) {
  RunSettings settings;
  settings.formulation = formulation;
  settings.options.rtol = rtol;
  settings.options.atol = atol;
  settings.options.step = step;
  RunResult result = RunScene(scene, settings);
  EXPECT_TRUE(result.completed) << formulation << ": " << result.failure;
  return result;
}

// The patella's six coordinates at every event row of a run.
std::vector<std::array<double, 6>> PatellarPoseAtEvents(const Scene& scene, const RunResult& run) {
  std::vector<std::array<double, 6>> out;
  PatellaGuess guess;
  for (size_t i = 0; i < run.samples.size(); ++i) {
    if (!run.sample_is_event[i]) continue;
    const Patella& p = *scene.model.patella;
    SolvePatella(p, TuberosityInF(p, PoseFromCoordinates(run.samples[i].q)), "test", &guess);
    out.push_back({guess.x[0], guess.x[1], guess.x[2], guess.x[3], guess.x[4], guess.x[5]});
  }
  return out;
}

// The ODE check (ede: the tibia's ODE, the patella solved inside the right-hand side) and
// dae (IDA on the tibia's index-2 DAE, the tendon force and its implicit-function
// derivative in the residual): two integrators, two contact descriptions, one patella.
TEST(PatellaRuns, OdeAndDaeAgreeOnEventTimesAndPatellarPose) {
  const Scene scene = ImpactScene();
  const RunResult ode = RunWith(scene, "ede", 1e-12, 1e-14);
  // IDA at rtol 1e-11 fails (corrector convergence at t = 0.277 s, on the lateral normal
  // force): a limit of the plain index-2 tibia, not of the patella's Newton solve — dae fails
  // the same way on chapter_impact (no patella) at rtol 1e-12, and the monolithic DAE, with
  // no Newton solve inside, at the same time; the GGL forms pass (tests/monolithic_test.cpp).
  const RunResult dae = RunWith(scene, "dae", 1e-10, 1e-12);
  ASSERT_EQ(ode.events.size(), dae.events.size());
  ASSERT_GE(ode.events.size(), 1u);
  for (size_t i = 0; i < ode.events.size(); ++i) {
    EXPECT_EQ(ode.events[i].name, dae.events[i].name);
    EXPECT_NEAR(ode.events[i].time, dae.events[i].time, 1e-8 * ode.events[i].time) << ode.events[i].name;
  }
  const auto a = PatellarPoseAtEvents(scene, ode), b = PatellarPoseAtEvents(scene, dae);
  ASSERT_EQ(a.size(), b.size());
  for (size_t i = 0; i < a.size(); ++i) {
    for (int k = 0; k < 6; ++k) {
      const double scale = k < 3 ? 0.05 : 1.0;  // m, rad: the size of the coordinate
      EXPECT_NEAR(a[i][k], b[i][k], 1e-8 * scale) << "event " << i << " " << PatellaUnknownName(k);
    }
  }
}

// The chapter's one-step lag is a first-order splitting: halving Δt halves the coupling
// error against the ODE check (the inner integration is tight, so the lag dominates).
TEST(PatellaRuns, StaggeredCouplingErrorShrinksAtFirstOrder) {
  Scene scene = ImpactScene();
  scene.end.flexion.reset();
  scene.end.time = 0.1;
  const RunResult reference = RunWith(scene, "ede", 1e-12, 1e-14);
  double error[2];
  const double steps[2] = {2e-3, 1e-3};
  for (int k = 0; k < 2; ++k) {
    const RunResult run = RunWith(scene, "staggered", 1e-12, 1e-14, steps[k]);
    ASSERT_EQ(run.samples.size(), reference.samples.size());
    error[k] = (run.samples.back().q - reference.samples.back().q).tail<3>().cwiseAbs().maxCoeff();
  }
  const double order = std::log2(error[0] / error[1]);
  RecordProperty("observed_order", std::to_string(order));
  std::printf("coupling error at t = 0.1 s: %.3e (dt = 2 ms), %.3e (dt = 1 ms); observed order %.3f\n", error[0],
              error[1], order);
  EXPECT_GT(error[1], 0.0);
  EXPECT_GE(order, 0.8);
  EXPECT_LE(order, 1.3);
}

// A larger Q-angle: the quadriceps pulls more laterally (direction (0.14, −0.2, 1) in F, 8°
// lateral instead of 3°) and presses the patella into the lateral facet; at extension the
// medial facet then separates (docs/model.md §12, facet lift-off).
Patella WithLateralPull(const Patella& base) {
  Patella patella = base;
  patella.quadriceps.direction_F = Vector3d(0.14, -0.2, 1.0).normalized();
  patella.facet_liftoff = true;
  return patella;
}

// The separated facet by a second description: the closed-form sphere-on-plane contact
// (contact.hpp) at the solved pose gives the medial facet a positive gap (the chart
// coordinates' e·n equals it) and closes the lateral one, and the patella balances in N on
// the lateral facet alone.
TEST(PatellaLiftoff, SeparatedFacetSolvesTheComplementarityByASecondContactDescription) {
  const Scene scene = ImpactScene();
  const Patella patella = WithLateralPull(*scene.model.patella);
  const Vector6d q = ChapterPoses({0.0}).at(0);
  const Vector3d tuberosity_F = TuberosityInF(patella, PoseFromCoordinates(q));
  PatellaGuess guess;  // from the scene's start, where both facets press
  SolvePatella(patella, tuberosity_F, "test", &guess);
  EXPECT_FALSE(guess.pressing[0]);
  EXPECT_TRUE(guess.pressing[1]);
  EXPECT_EQ(guess.x[kPatellaFacetRatio], 0.0);
  EXPECT_LT(PatellaResidualNorm(patella, tuberosity_F, guess.x, guess.pressing), 1e-13);
  const Pose pose = PatellaPose(guess.x.data());
  ContactGeometry g[2];
  for (int i = 0; i < 2; ++i) {
    SphereOnPlane sop;
    ASSERT_TRUE(SphereOnPlaneForm(patella.facet[i], &sop));
    g[i] = SphereOnPlaneContact(sop, pose);
  }
  EXPECT_GT(g[0].gap, 1e-6);  // m: separated by more than round-off
  EXPECT_NEAR(PatellaFacetGaps(patella, guess.x)[0], g[0].gap, 1e-14);
  EXPECT_NEAR(g[1].gap, 0.0, 1e-14);
  EXPECT_LT(PatellarContactFunction(patella, guess, 0), 0.0);
  const double F_Q = 50.0;
  const Vector3d base_F = pose.PointInF(patella.base_P), apex_F = pose.PointInF(patella.apex_P);
  Vector3d force = F_Q * patella.quadriceps.direction_F;
  Vector3d moment = base_F.cross(force);
  const Vector3d tendon = guess.x[kPatellaTendonRatio] * F_Q * (tuberosity_F - apex_F).normalized();
  force += tendon;
  moment += apex_F.cross(tendon);
  const double N = guess.x[kPatellaFacetRatio + 1] * F_Q;
  EXPECT_GT(N, 0.0);
  const Vector3d contact_force = -N * (pose.R_FT * g[1].normal_T);
  force += contact_force;
  moment += g[1].point_F.cross(contact_force);
  EXPECT_LT(force.norm(), 1e-11 * F_Q);
  EXPECT_LT(moment.norm(), 1e-12 * F_Q);
  // Back to the scene's quadriceps line from this warm start: the medial facet presses again.
  PatellaGuess back = guess;
  Patella scene_line = *scene.model.patella;
  scene_line.facet_liftoff = true;
  SolvePatella(scene_line, tuberosity_F, "test", &back);
  EXPECT_TRUE(back.pressing[0] && back.pressing[1]);
  EXPECT_GT(back.x[kPatellaFacetRatio], 0.0);
}

// The hard case patella_fold (extension under the larger Q-angle; its medial facet's force
// crosses zero as the knee extends, where ede, mde and dae must agree on the time).
//
// This scene holds α, β, γ, y0 with one contact active, so x0 and z0 have one consistency
// condition between them: the consistent start is a curve, and the chapter-form position
// level (dae's) used to land on another point of it than the gap form's (ede's, mde's):
// x0 9e-4 mm and z0 2.1e-3 mm apart, and dae's lift-off came 1.8e-6 s after ede's and
// mde's. Every form now starts from the gap form's point (solver/consistent_init.cpp).
TEST(PatellaLiftoff, EveryContactFormStartsTheUnderdeterminedSceneFromTheSamePose) {
  const Scene scene = LoadScene("reference-data/scenes/hard/patella_fold.yaml");
  InitReport chapter_report, gap_report;
  ConsistentInitOptions chapter, gap;
  chapter.form = ContactForm::kChapter;
  gap.form = ContactForm::kClosedForm;
  const MechanicalState a = ConsistentInitialize(scene.model, scene.initial, {0}, chapter, &chapter_report);
  const MechanicalState b = ConsistentInitialize(scene.model, scene.initial, {0}, gap, &gap_report);
  EXPECT_EQ(a.q, b.q) << a.q.transpose() << "\n" << b.q.transpose();
  // Held coordinates unchanged; the start moved off the scene's pose (it is not consistent).
  for (int i : {kAlpha, kBeta, kGamma, kY0}) EXPECT_EQ(a.q(i), scene.initial.q(i)) << i;
  EXPECT_GT((a.q - scene.initial.q).head<3>().norm(), 1e-7);  // m
  // The chapter form's own residuals (Eqs. 1.8, 1.13) hold there with its contact coordinates.
  std::vector<double> gap_value, rate;
  ConstraintResiduals(scene.model, a, &gap_value, &rate);
  EXPECT_NEAR(gap_value[0], 0.0, 1e-12);  // m
  EXPECT_LE(chapter_report.position.residual_after, 1e-11);
}

// The hard case patella_fold: as the knee extends under the larger Q-angle the
// medial facet's force crosses zero, but the one-facet branch folds back there (docs/model.md
// §12). The ODE check (ede), the minimal ODE (mde) and the DAE (dae) locate the lift-off at
// the same time, where the facet's force ratio and gap are zero, and then stop with the
// fold's SolverError instead of running on with a pulling facet.
TEST(PatellaLiftoff, ExtensionUnderLateralPullStopsAtTheFoldAfterTheMedialLiftoffInEdeMdeAndDae) {
  const Scene scene = LoadScene("reference-data/scenes/hard/patella_fold.yaml");
  auto run = [&](const std::string& formulation) {
    RunSettings settings;
    settings.formulation = formulation;
    settings.options.rtol = 1e-10;
    settings.options.atol = 1e-12;
    return RunScene(scene, settings);
  };
  const RunResult ode = run("ede"), dae = run("dae"), mde = run("mde");
  for (const RunResult* r : {&ode, &dae, &mde}) {
    EXPECT_FALSE(r->completed);
    EXPECT_NE(r->failure.find("medial facet switches"), std::string::npos) << r->failure;
    EXPECT_NE(r->failure.find("one-facet branch has folded back"), std::string::npos) << r->failure;
    ASSERT_FALSE(r->events.empty());
    EXPECT_EQ(r->events.back().name, "liftoff_patellar_medial");
  }
  const double t_ode = ode.events.back().time, t_dae = dae.events.back().time, t_mde = mde.events.back().time;
  std::printf("liftoff_patellar_medial: ede %.12f s, mde %.12f s, dae %.12f s\n", t_ode, t_mde, t_dae);
  // 8 digits, as the impact scene's events (OdeAndDaeAgreeOnEventTimesAndPatellarPose).
  EXPECT_NEAR(t_dae, t_ode, 1e-8 * t_ode);
  EXPECT_NEAR(t_mde, t_ode, 1e-8 * t_ode);
  const Patella& patella = *scene.model.patella;
  int found = 0;
  for (size_t i = 0; i < ode.samples.size(); ++i) {
    if (!ode.sample_is_event[i] || ode.samples[i].t != t_ode) continue;
    PatellaGuess guess;
    SolvePatella(patella, TuberosityInF(patella, PoseFromCoordinates(ode.samples[i].q)), "test", &guess);
    EXPECT_NEAR(guess.x[kPatellaFacetRatio], 0.0, 1e-8);
    EXPECT_NEAR(PatellaFacetGaps(patella, guess.x)[0], 0.0, 1e-9);  // m
    ++found;
  }
  EXPECT_EQ(found, 1);
}

// The hard case patella_medial_liftoff (the impact with a lateral quadriceps line and 200 N):
// a genuine one-facet branch. The medial facet starts separated, re-contacts, lifts off and
// re-contacts; ede, mde and dae record the same switches at times 1e-8 apart, each switch
// with a positive compliance (CheckPatellarFacetSwitch), and between the lift-off and the
// re-contact the medial facet is separated by a second contact description (the closed-form
// sphere-on-plane gap at the solved pose > 0) while the lateral one presses.
TEST(PatellaLiftoff, GenuineLiftoffSeparatesTheMedialFacetBetweenItsSwitchesInEdeMdeAndDae) {
  const Scene scene = LoadScene("reference-data/scenes/hard/patella_medial_liftoff.yaml");
  const RunResult ode = RunWith(scene, "ede", 1e-10, 1e-12);
  const RunResult dae = RunWith(scene, "dae", 1e-10, 1e-12);
  const RunResult mde = RunWith(scene, "mde", 1e-10, 1e-12);
  const std::vector<std::string> expected = {"recontact_patellar_medial", "liftoff_patellar_medial",
                                             "recontact_patellar_medial"};
  for (const RunResult* r : {&ode, &dae, &mde}) {
    std::vector<std::string> names;
    for (const EventRecord& e : r->events) names.push_back(e.name);
    ASSERT_EQ(names, expected);
  }
  for (size_t k = 0; k < expected.size(); ++k) {
    const double t = ode.events[k].time;
    EXPECT_NEAR(dae.events[k].time, t, 1e-8 * t) << expected[k];
    EXPECT_NEAR(mde.events[k].time, t, 1e-8 * t) << expected[k];
    std::printf("%s: ede %.12f s, mde %.12f s, dae %.12f s\n", expected[k].c_str(), t, mde.events[k].time,
                dae.events[k].time);
  }
  const Patella& patella = *scene.model.patella;
  SphereOnPlane sop[2];
  for (int i = 0; i < 2; ++i) ASSERT_TRUE(SphereOnPlaneForm(patella.facet[i], &sop[i]));
  PatellaGuess guess;  // warm-started along the run, as its right-hand side is
  int separated_rows = 0;
  for (size_t i = 0; i < ode.samples.size(); ++i) {
    const Vector3d tuberosity_F = TuberosityInF(patella, PoseFromCoordinates(ode.samples[i].q));
    SolvePatella(patella, tuberosity_F, "test", &guess);
    const double t = ode.samples[i].t;
    if (ode.sample_is_event[i]) {
      const int facet = 0;
      const double compliance = PatellarFacetCompliance(patella, tuberosity_F, guess.x, facet);
      std::printf("switch at t = %.6f s: d gap/d lambda_medial = %.3f mm\n", t, MToMm(compliance));
      EXPECT_GT(compliance, 0.0) << "t = " << t;
      continue;
    }
    if (t <= ode.events[1].time || t >= ode.events[2].time) continue;
    const Pose pose = PatellaPose(guess.x.data());
    EXPECT_FALSE(guess.pressing[0]) << "t = " << t;
    EXPECT_EQ(guess.x[kPatellaFacetRatio], 0.0);
    EXPECT_GT(SphereOnPlaneContact(sop[0], pose).gap, 1e-9) << "t = " << t;  // m
    EXPECT_NEAR(SphereOnPlaneContact(sop[1], pose).gap, 0.0, 1e-13);
    EXPECT_GT(guess.x[kPatellaFacetRatio + 1], 0.1);
    ++separated_rows;
  }
  EXPECT_GE(separated_rows, 3);
}

// The fold by two nonlinear solves, against the linearization CheckPatellarFacetSwitch
// judges by: at the medial lift-off of patella_fold, the tuberosity moved on past
// it (along its path over the last output interval), the two-facet equilibrium pulls
// (λ_medial < 0) and the one-facet one penetrates (gap_medial < 0): neither holds. Their
// ratio is the compliance, gap_one = −(∂gap/∂λ) λ_two to first order in the step.
TEST(PatellaLiftoff, PastTheFoldNeitherBranchHoldsAndTheirRatioIsTheCompliance) {
  const Scene scene = LoadScene("reference-data/scenes/hard/patella_fold.yaml");
  RunSettings settings;
  settings.formulation = "ede";
  settings.options.rtol = 1e-10;
  settings.options.atol = 1e-12;
  const RunResult ode = RunScene(scene, settings);
  ASSERT_GE(ode.samples.size(), 3u);
  ASSERT_TRUE(ode.sample_is_event.back());
  const Patella& lifting = *scene.model.patella;
  Patella pressing = lifting;
  pressing.facet_liftoff = false;  // both facets press, λ of either sign
  const Vector3d at_F = TuberosityInF(lifting, PoseFromCoordinates(ode.samples.back().q));
  const Vector3d before_F = TuberosityInF(lifting, PoseFromCoordinates(ode.samples[ode.samples.size() - 2].q));
  PatellaGuess at;
  SolvePatella(pressing, at_F, "test", &at);
  const double compliance = PatellarFacetCompliance(lifting, at_F, at.x, 0);
  std::printf("medial facet compliance at the lift-off: %.6f mm per unit lambda\n", MToMm(compliance));
  EXPECT_LT(compliance, 0.0);
  for (double s : {1e-3, 1e-2}) {
    SCOPED_TRACE(s);
    const Vector3d past_F = at_F + s * (at_F - before_F);
    PatellaGuess two = at;
    SolvePatella(pressing, past_F, "test", &two);
    PatellaGuess one = at;
    one.pressing = {{false, true}};
    one.x[kPatellaFacetRatio] = 0.0;
    SolvePatella(lifting, past_F, "test", &one);  // the switch back fails: it stays separated
    ASSERT_FALSE(one.pressing[0]);
    const double lambda_two = two.x[kPatellaFacetRatio], gap_one = PatellaFacetGaps(lifting, one.x)[0];
    std::printf("s = %g: lambda_medial (both press) %.3e, gap_medial (lateral only) %.3e mm\n", s, lambda_two,
                MToMm(gap_one));
    EXPECT_LT(lambda_two, 0.0);
    EXPECT_LT(gap_one, 0.0);
    EXPECT_GT(one.x[kPatellaFacetRatio + 1], 0.0);
    EXPECT_NEAR(gap_one / (-lambda_two), compliance, 0.05 * std::abs(compliance));
  }
}


// A quadriceps half-sine is a pulse as the tibial one is (docs/model.md §7, §12): F_Q is at its
// baseline at both ends, so a step that spans it never sees it. 1e5 N for 3 µs moves the
// tibia (flexion at 2 ms: -0.0160° against -0.0033° without it, ede at rtol 1e-10, the
// reference here); IDA's default first step (1e-4 s) passed it whole, and every fixed-step
// method at its default 1e-4 s ran as if it were not there.
TEST(PatellaRuns, ShortQuadricepsHalfSineIsSeenByIdaAndRefusedByFixedSteps) {
  Scene scene = ImpactSceneWithQuadricepsHalfSine(3.0e-6);
  scene.end.time = 0.002;
  scene.output_interval = 0.001;
  const auto flexion_at_end = [](const RunResult& r) { return r.samples.back().q(kAlpha); };
  const double reference = flexion_at_end(RunWith(scene, "ede", 1e-10, 1e-12));
  Scene baseline_only = scene;
  baseline_only.model.patella->quadriceps.magnitude = 0.0;
  const double without = flexion_at_end(RunWith(baseline_only, "ede", 1e-10, 1e-12));
  ASSERT_GT(std::abs(without - reference), DegToRad(0.01)) << "the pulse must move the tibia for this test to mean anything";
  for (const char* formulation : {"dae", "dae-ggl", "monolithic", "monolithic-ggl"}) {
    RunSettings settings;
    settings.formulation = formulation;
    const RunResult run = RunScene(scene, settings);
    ASSERT_TRUE(run.completed) << formulation << ": " << run.failure;
    EXPECT_NEAR(flexion_at_end(run), reference, 0.1 * std::abs(without - reference)) << formulation;
  }
  for (const char* formulation : {"newmark", "generalized-alpha", "staggered"}) {
    RunSettings settings;
    settings.formulation = formulation;
    try {
      RunScene(scene, settings);
      ADD_FAILURE() << formulation << " ran a 3 us quadriceps pulse at a 1e-4 s step";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find("patella.quadriceps.duration_s = 3e-06 s"), std::string::npos) << e.what();
    }
  }
}

// The trajectory's patella columns follow the equilibrium through the rows' poses. With a
// 1e5 N quadriceps half-sine of 0.01 s the tuberosity moves 26 mm between two rows; the
// straight solve from the last row failed there (SolverError from MakeTrajectoryTable), so a
// run that had stopped with its own failure at t = 0.046 s (partial: exit 1, its rows and
// reason written) ended with exit 2 and nothing written. Each row's solution must hold its
// 17 equations.
TEST(PatellaRuns, TrajectoryTableFollowsThePatellaAcrossLargeMovesBetweenRows) {
  Scene scene = ImpactSceneWithQuadricepsHalfSine(0.01);
  RunSettings settings;
  settings.formulation = "ede";
  const RunResult run = RunScene(scene, settings);
  ASSERT_GT(run.samples.size(), 5u);
  TrajectoryTable table;
  ASSERT_NO_THROW(table = MakeTrajectoryTable(scene, run));
  ASSERT_EQ(table.rows.size(), run.samples.size());
  size_t tendon_column = 0;
  while (tendon_column < table.columns.size() && table.columns[tendon_column] != "tendon_quadriceps_ratio") ++tendon_column;
  ASSERT_LT(tendon_column, table.columns.size());
  // Independently of the table's path: the equilibrium at the row's pose, followed in small
  // steps of the tuberosity from the previous row, has the same tendon ratio.
  const Patella& p = *scene.model.patella;
  PatellaGuess guess;
  for (size_t i = 0; i < run.samples.size(); ++i) {
    const Vector3d tuberosity_F = TuberosityInF(p, PoseFromCoordinates(run.samples[i].q));
    SolvePatellaAlongTibialPath(p, i == 0 ? p.start_q : run.samples[i - 1].q, run.samples[i].q, "test", &guess);
    EXPECT_LT(PatellaResidualNorm(p, tuberosity_F, guess.x), 1e-12) << "row " << i;
    EXPECT_NEAR(table.rows[i][tendon_column], guess.x[kPatellaTendonRatio], 1e-9) << "row " << i;
  }
}

// Without facet_liftoff the monolithic DAE stops where a facet force changes sign (its root
// g = λ_i). A start with a facet already pulling never crossed that root: the quadriceps line
// (0.3, -0.2, 1) pulls the impact scene's medial facet at t = 0 (N = -8.1 N); monolithic ran
// 0.12 s so and then stopped where the facet pressed again, saying it "would pull".
TEST(PatellaRuns, MonolithicStopsAtTheStartWhenAFacetPullsThere) {
  Scene scene = ImpactScene();
  scene.model.patella->quadriceps.direction_F = Vector3d(0.3, -0.2, 1.0).normalized();
  SolvePatellaStart(scene.reference_q, scene.initial.q, &*scene.model.patella);
  // The premise, from the patella's own solve at the start: the medial facet pulls.
  const Patella& p = *scene.model.patella;
  PatellaGuess guess;
  SolvePatella(p, TuberosityInF(p, PoseFromCoordinates(scene.initial.q)), "test", &guess);
  ASSERT_LT(guess.x[kPatellaFacetRatio], -0.1);
  ASSERT_GT(guess.x[kPatellaFacetRatio + 1], 0.0);
  for (const char* formulation : {"monolithic", "monolithic-ggl"}) {
    RunSettings settings;
    settings.formulation = formulation;
    const RunResult run = RunScene(scene, settings);
    EXPECT_FALSE(run.completed) << formulation;
    EXPECT_NE(run.failure.find("medial patellar facet pulls at the start of the phase at t = 0 s"), std::string::npos)
        << formulation << ": " << run.failure;
    EXPECT_EQ(run.samples.size(), 1u) << formulation;
  }
}

// --max-steps bounds a phase's coupling steps: dopri5's budget is per call, i.e. per coupling
// step, so staggered at --step 1e-9 (a valid step) ran the impact scene's 3.4e8 coupling
// steps with no bound (killed after 60 s with --max-steps 1000). Here 2000 coupling steps of
// 1e-9 s against a budget of 1000: stopped, where the old code completed.
TEST(PatellaRuns, StaggeredHonoursMaxStepsAcrossCouplingSteps) {
  Scene scene = ImpactScene();
  scene.end.time = 2.0e-6;
  scene.output_interval = 1.0e-6;
  RunSettings settings;
  settings.formulation = "staggered";
  settings.options.step = 1.0e-9;
  settings.options.max_steps = 1000;
  const RunResult run = RunScene(scene, settings);
  EXPECT_FALSE(run.completed);
  EXPECT_NE(run.failure.find("more than --max-steps = 1000 coupling steps of 1e-09 s"), std::string::npos)
      << run.failure;
  settings.options.max_steps = 3000;
  EXPECT_TRUE(RunScene(scene, settings).completed);
}

// The written set of a run, read back: summary.json and trajectory.csv's columns.
struct WrittenRun {
  nlohmann::json summary;
  std::vector<std::string> columns;
  std::vector<std::vector<std::string>> rows;  // the CSV's cells as written ("" = empty)
};

WrittenRun WriteAndRead(const Scene& scene, const RunSettings& settings, const RunResult& run, const std::string& tag) {
  namespace fs = std::filesystem;
  const fs::path dir = fs::temp_directory_path() / ("kneedyn_patella_test_" + std::to_string(::getpid()) + "_" + tag);
  fs::remove_all(dir);
  WriteRunOutputs(dir.string(), scene, settings, run);
  WrittenRun w;
  std::ifstream summary(dir / "summary.json");
  w.summary = nlohmann::json::parse(summary);
  std::ifstream csv(dir / "trajectory.csv");
  std::string line;
  for (bool header = true; std::getline(csv, line); header = false) {
    std::vector<std::string> cells;
    std::stringstream ss(line);
    for (std::string cell; std::getline(ss, cell, ',');) cells.push_back(cell);
    if (!line.empty() && line.back() == ',') cells.emplace_back();
    (header ? w.columns : (w.rows.emplace_back(), w.rows.back())) = cells;
  }
  fs::remove_all(dir);
  return w;
}

// A completed run whose patellar facet pulls (no facet_liftoff: λ of either sign, docs/model.md
// §12) says so: summary.json's warnings hold one entry per pulling facet, its most negative
// force and the time, equal to the minimum of its column in trajectory.csv as written (read
// back here, not taken from the code's table). The quadriceps line (0.3, -0.2, 1) pulls the
// impact scene's medial facet from t = 0 (MonolithicStopsAtTheStartWhenAFacetPullsThere). The
// shipped scene (line (0.06, -0.2, 1)) has no warning with dae, whose lift-off row of the
// lateral tibial contact holds a force of round-off below 0 (the event's own row, not a pull).
TEST(PatellaRuns, PullingFacetIsNamedInTheSummaryWarnings) {
  Scene scene = ImpactScene();
  scene.model.patella->quadriceps.direction_F = Vector3d(0.3, -0.2, 1.0).normalized();
  SolvePatellaStart(scene.reference_q, scene.initial.q, &*scene.model.patella);
  RunSettings settings;
  settings.formulation = "ede";
  const RunResult run = RunScene(scene, settings);
  ASSERT_TRUE(run.completed) << run.failure;
  const WrittenRun w = WriteAndRead(scene, settings, run, "pull");
  ASSERT_TRUE(w.summary.contains("warnings"));
  const nlohmann::json& warnings = w.summary["warnings"];
  int pulling = 0;
  for (const char* facet : {"medial", "lateral"}) {
    const std::string column = std::string("N_patella_") + facet + "_N";
    const size_t c = static_cast<size_t>(std::find(w.columns.begin(), w.columns.end(), column) - w.columns.begin());
    ASSERT_LT(c, w.columns.size()) << column;
    double min_force = 0.0, at = 0.0;
    for (const auto& row : w.rows) {
      const double v = std::stod(row.at(c));
      if (v < min_force) min_force = v, at = std::stod(row.at(0));
    }
    const nlohmann::json* entry = nullptr;
    for (const nlohmann::json& x : warnings) {
      if (x["column"] == column) entry = &x;
    }
    if (min_force < 0.0) {
      ++pulling;
      ASSERT_NE(entry, nullptr) << column << " pulls (" << min_force << " N) without a warning: " << warnings.dump();
      EXPECT_EQ((*entry)["kind"], "pulling_contact");
      EXPECT_EQ((*entry)["contact"], std::string("patellar facet ") + facet);
      EXPECT_LT((*entry)["min_force_N"].get<double>(), 0.0);
      // The CSV holds 12 significant digits.
      EXPECT_NEAR((*entry)["min_force_N"].get<double>(), min_force, 1e-11 * std::abs(min_force)) << column;
      EXPECT_NEAR((*entry)["time_s"].get<double>(), at, 1e-11) << column;
      const std::string message = (*entry)["message"];
      EXPECT_NE(message.find(std::string("patellar facet ") + facet + " pulled"), std::string::npos) << message;
    } else {
      EXPECT_EQ(entry, nullptr) << column << " never pulls: " << warnings.dump();
    }
  }
  EXPECT_GE(pulling, 1) << "the premise: a facet pulls with this quadriceps line";
  EXPECT_EQ(warnings.size(), static_cast<size_t>(pulling)) << warnings.dump();

  const Scene shipped = ImpactScene();
  settings.formulation = "dae";
  const RunResult plain = RunScene(shipped, settings);
  ASSERT_TRUE(plain.completed) << plain.failure;
  const WrittenRun p = WriteAndRead(shipped, settings, plain, "plain");
  EXPECT_TRUE(p.summary["warnings"].is_array());
  EXPECT_TRUE(p.summary["warnings"].empty()) << p.summary["warnings"].dump();
}

// The patellar facets are unbounded planes: a tuberosity at the tibial origin (the tendon then
// pulls the patella 150 mm distal) puts both trochlear contacts far off the patella, and the
// run completed with no word. The warning's row and z are checked against a second
// description of the contact, the sphere's: point_F = C − r n_F, with n_F = R_FP n̂ and the
// pose from the written columns, then z in P. The shipped scene's contacts lie on the patella
// (its dae run has no warning, above).
TEST(PatellaRuns, ContactOffThePatellaIsWarned) {
  Scene scene = ImpactScene();
  Patella& patella = *scene.model.patella;
  patella.tuberosity_T = Vector3d::Zero();
  SolvePatellaStart(scene.reference_q, scene.initial.q, &patella);
  RunSettings settings;
  settings.formulation = "ede";
  const RunResult run = RunScene(scene, settings);
  ASSERT_TRUE(run.completed) << run.failure;
  const WrittenRun w = WriteAndRead(scene, settings, run, "off");
  const auto column = [&](const std::string& name) {
    const size_t c = static_cast<size_t>(std::find(w.columns.begin(), w.columns.end(), name) - w.columns.begin());
    EXPECT_LT(c, w.columns.size()) << name;
    return c;
  };
  const double z_low = std::min(patella.apex_P.z(), patella.base_P.z());
  const double z_high = std::max(patella.apex_P.z(), patella.base_P.z());
  int warned = 0;
  for (int i = 0; i < 2; ++i) {
    const std::string facet = i == 0 ? "medial" : "lateral";
    Vector3d centre_F, normal_P;
    double radius = 0.0, offset = 0.0;
    ASSERT_TRUE(patella.facet[i].femoral_surface->SphereForm(&centre_F, &radius));
    ASSERT_TRUE(patella.facet[i].tibial_surface->PlaneForm(&normal_P, &offset));
    double worst_beyond_mm = 0.0, worst_t = 0.0, worst_z_mm = 0.0;
    for (const auto& row : w.rows) {
      if (!(std::stod(row.at(column("N_patella_" + facet + "_N"))) > 0.0)) continue;
      const Vector3d origin_F(MmToM(std::stod(row.at(column("patella_shift_mm")))),
                              MmToM(std::stod(row.at(column("patella_anterior_mm")))),
                              MmToM(std::stod(row.at(column("patella_proximal_mm")))));
      const Matrix3d R_FP = RotationFT(DegToRad(std::stod(row.at(column("patella_flexion_deg")))),
                                       kPi / 2 + DegToRad(std::stod(row.at(column("patella_tilt_deg")))),
                                       DegToRad(std::stod(row.at(column("patella_rotation_deg")))));
      const Vector3d point_F = centre_F - radius * (R_FP * normal_P);
      const double z_mm = MToMm((R_FP.transpose() * (point_F - origin_F)).z());
      const double beyond_mm = std::max(MToMm(z_low) - z_mm, z_mm - MToMm(z_high));
      if (beyond_mm > worst_beyond_mm) worst_beyond_mm = beyond_mm, worst_t = std::stod(row.at(0)), worst_z_mm = z_mm;
    }
    ASSERT_GT(worst_beyond_mm, 100.0) << facet << ": the premise, a contact far off the patella";
    const nlohmann::json* entry = nullptr;
    for (const nlohmann::json& x : w.summary["warnings"]) {
      if (x["kind"] == "patella_contact_off" && x["contact"] == "patellar facet " + facet) entry = &x;
    }
    ASSERT_NE(entry, nullptr) << w.summary["warnings"].dump();
    ++warned;
    EXPECT_NEAR((*entry)["time_s"].get<double>(), worst_t, 1e-11) << facet;
    const std::string message = (*entry)["message"];
    const std::string marker = "z = ";
    ASSERT_NE(message.find(marker), std::string::npos) << message;
    // The CSV's 12 digits of the pose carry ~1e-9 mm to a point 0.2 m away.
    EXPECT_NEAR(std::stod(message.substr(message.find(marker) + marker.size())), worst_z_mm, 1e-6) << message;
    EXPECT_NE(message.find("patella.tuberosity_T_mm"), std::string::npos) << message;
  }
  EXPECT_EQ(warned, 2);
}

// The same warnings for the tibial contacts, from a table built here: a force below 0 in an
// ordinary row is reported (the column's minimum and its time), the contact's own lift-off
// event row is not (its force is 0 by the event's definition), another event's row is.
TEST(PatellaRuns, PullingTibialContactIsReportedOutsideItsOwnLiftoffRow) {
  TrajectoryTable table;
  table.columns = {"time_s", "is_event", "N_medial_N", "N_lateral_N", "F_ACL_N"};
  table.rows = {{0.0, 0.0, 10.0, 5000.0, -3.0},  // lateral: lift-off rows within 0.5 N are located
                {0.1, 1.0, -0.0005, 2.0, 1.0},  // liftoff_medial's row, within 1e-4 of 10 N: not counted
                {0.2, 0.0, 0.0, -0.25, 1.0},
                {0.3, 1.0, 0.0, -0.5, 1.0},    // liftoff_medial's again: lateral counts
                {0.4, 0.0, 0.0, -0.5, 1.0}};
  RunResult result;
  result.events = {{"liftoff_medial", 0.1, 0.0}, {"recontact_medial", 0.3, 0.0}};
  // The pulling contacts alone (five planted rows are also a sparse output).
  const auto PullingWarnings = [](const TrajectoryTable& t, const RunResult& r) {
    std::vector<OutputWarning> out;
    for (const OutputWarning& w : OutputWarnings(t, r)) {
      if (w.kind == "pulling_contact") out.push_back(w);
    }
    return out;
  };
  const std::vector<OutputWarning> pulling = PullingWarnings(table, result);
  ASSERT_EQ(pulling.size(), 1u);
  EXPECT_EQ(pulling[0].column, "N_lateral_N");
  EXPECT_EQ(pulling[0].contact, "tibial contact lateral");
  EXPECT_EQ(pulling[0].min_force_N, -0.5);
  EXPECT_EQ(pulling[0].time_s, 0.3);  // the first row of the minimum
  result.events = {{"liftoff_lateral", 0.3, 0.0}};  // now 0.3 is the lateral lift-off's row
  const std::vector<OutputWarning> after = PullingWarnings(table, result);
  ASSERT_EQ(after.size(), 2u);  // medial's -0.0005 at 0.1 is no lift-off row any more
  EXPECT_EQ(after[0].column, "N_medial_N");
  EXPECT_EQ(after[0].min_force_N, -0.0005);
  EXPECT_EQ(after[1].time_s, 0.4);
  // A lift-off row that pulls by 5 % of the column's largest force is a lift-off the method
  // did not locate (newmark halving before a failure: -32.5 N of 2.2 kN): counted.
  table.rows[1][2] = -0.5;
  result.events = {{"liftoff_medial", 0.1, 0.0}, {"recontact_medial", 0.3, 0.0}};
  const std::vector<OutputWarning> unlocated = PullingWarnings(table, result);
  ASSERT_EQ(unlocated.size(), 2u);
  EXPECT_EQ(unlocated[0].column, "N_medial_N");
  EXPECT_EQ(unlocated[0].min_force_N, -0.5);
  EXPECT_EQ(unlocated[0].time_s, 0.1);
}

// A failed run that stops where the patella's equilibrium leaves the model's geometry: the
// 40-fold quadriceps force with newmark at --step 1e-5 holds on with its small steps to
// t = 0.0984 s, past its last row (0.095 s), and fails there with "no patellar equilibrium
// found": the lateral trochlear contact point has reached the edge of its sphere's chart
// (|u| < 80°, |v| < 170°, solver/height_field.hpp), where the equilibrium goes on, its
// Jacobian regular, on a sphere the chart no longer describes (not a fold: an independent
// solve followed it 50 % further; the message names the edge). A row at such a pose (written by a method whose output falls there: here the last row
// moved on along the last interval's direction until it is past the edge) is one where the path
// MakeTrajectoryTable follows from the row before finds no equilibrium. The set is written,
// that row's patella columns empty, its other columns not, and a warning of kind
// patella_not_followed gives its time. Before, WriteRunOutputs threw: exit 2 and nothing
// written. The same rows in a run marked completed get the same empty columns, and the
// warning says the run's own steps got there.
TEST(PatellaRuns, RowPastTheChartEdgeOfAFailedRunHasEmptyPatellaColumnsAndAWarning) {
  const Scene scene = LoadScene("reference-data/scenes/hard/patella_quadriceps_2000N.yaml");
  RunSettings settings;
  settings.formulation = "newmark";
  settings.options.step = 1e-5;
  RunResult run = RunScene(scene, settings);
  ASSERT_FALSE(run.completed);
  ASSERT_NE(run.failure.find("no patellar equilibrium found"), std::string::npos) << run.failure;
  EXPECT_NE(run.failure.find("the lateral trochlear contact point reached the edge of its sphere's chart"),
            std::string::npos)
      << run.failure;
  ASSERT_GE(run.samples.size(), 2u);
  // The last row moved on along the last interval's direction until the patella, followed
  // from the last row (as the table follows it), has no equilibrium on the chart there.
  const MechanicalState last_row = run.samples.back();
  const MechanicalState& before = run.samples[run.samples.size() - 2];
  const Patella& patella = *scene.model.patella;
  PatellaGuess at_last;  // followed from row to row as MakeTrajectoryTable does
  Vector6d from_q = patella.start_q;
  for (const MechanicalState& row : run.samples) {
    SolvePatellaAlongTibialPath(patella, from_q, row.q, "test", &at_last);
    from_q = row.q;
  }
  MechanicalState past = last_row;
  bool beyond = false;
  for (double f = 0.5; f <= 8.0 && !beyond; f *= 1.25) {
    past.t = last_row.t + f * (last_row.t - before.t);
    past.q = last_row.q + f * (last_row.q - before.q);
    PatellaGuess guess = at_last;
    try {
      SolvePatellaAlongTibialPath(patella, last_row.q, past.q, "test", &guess);
    } catch (const SolverError&) {
      beyond = true;
    }
  }
  ASSERT_TRUE(beyond) << "no pose past the chart's edge along the last interval's direction";
  run.samples.push_back(past);
  run.sample_is_event.push_back(false);
  const WrittenRun w = WriteAndRead(scene, settings, run, "fold");
  ASSERT_EQ(w.rows.size(), run.samples.size());
  const auto column = [&](const std::string& name) {
    return static_cast<size_t>(std::find(w.columns.begin(), w.columns.end(), name) - w.columns.begin());
  };
  const size_t first_patella = column("patella_shift_mm"), flexion = column("flexion_deg");
  ASSERT_LT(first_patella, w.columns.size());
  const std::vector<std::string>& last = w.rows.back();
  for (size_t c = first_patella; c < w.columns.size(); ++c) EXPECT_EQ(last[c], "") << w.columns[c];
  EXPECT_NE(last[flexion], "");
  for (size_t c = first_patella; c < w.columns.size(); ++c) EXPECT_NE(w.rows[w.rows.size() - 2][c], "") << w.columns[c];
  int found = 0;
  for (const nlohmann::json& warning : w.summary["warnings"]) {
    if (warning["kind"] != "patella_not_followed") continue;
    ++found;
    EXPECT_EQ(warning["time_s"].get<double>(), run.samples.back().t);
    EXPECT_NE(warning["message"].get<std::string>().find("no patellar equilibrium found"), std::string::npos);
  }
  EXPECT_EQ(found, 1) << w.summary["warnings"].dump();
  EXPECT_EQ(w.summary["status"], "partial");
  run.completed = true;
  const TrajectoryTable completed = MakeTrajectoryTable(scene, run);
  ASSERT_EQ(completed.patella_not_followed.size(), 1u);
  EXPECT_EQ(completed.patella_not_followed[0].first, run.samples.back().t);
  EXPECT_TRUE(std::isnan(completed.rows.back()[first_patella]));
  const std::vector<OutputWarning> warnings = OutputWarnings(completed, run);
  const auto warning = std::find_if(warnings.begin(), warnings.end(),
                                    [](const OutputWarning& o) { return o.kind == "patella_not_followed"; });
  ASSERT_NE(warning, warnings.end());
  EXPECT_NE(warning->message.find("which the run's own steps reached"), std::string::npos) << warning->message;
}

// staggered's failure at the fold names the coupling step where the patella's equilibrium was
// lost, and the "last state" is there, past the last 5 ms row (before: the row's time, no t
// and no step in the reason, docs/outputs.md's "last state").
TEST(PatellaRuns, StaggeredFailureNamesTheCouplingStepAndItsState) {
  const Scene scene = LoadScene("reference-data/scenes/hard/patella_quadriceps_2000N.yaml");
  RunSettings settings;
  settings.formulation = "staggered";
  const RunResult run = RunScene(scene, settings);
  ASSERT_FALSE(run.completed);
  const std::string marker = "at the coupling step ending at t = ";
  const size_t at = run.failure.find(marker);
  ASSERT_NE(at, std::string::npos) << run.failure;
  const double t_fail = std::stod(run.failure.substr(at + marker.size()));
  EXPECT_NE(run.failure.find("no patellar equilibrium found"), std::string::npos) << run.failure;
  EXPECT_NE(run.failure.find("(--step h = "), std::string::npos) << run.failure;
  const std::string last = "last state t = ";
  ASSERT_NE(run.failure.find(last), std::string::npos) << run.failure;
  EXPECT_EQ(std::stod(run.failure.substr(run.failure.find(last) + last.size())), t_fail) << run.failure;
  ASSERT_FALSE(run.samples.empty());
  EXPECT_GT(t_fail, run.samples.back().t) << run.failure;
}

}  // namespace
}  // namespace kneedyn
