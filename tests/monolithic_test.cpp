// The monolithic DAE of the knee with its patella (formulations/monolithic.cpp,
// formulations/internal/monolithic_system.hpp; docs/model.md §12, "The monolithic DAE").
//
// Validates:
//  - the exact Jacobian (the tibia's blocks plus the coupling blocks as a Jet over (q, x))
//    equals the JetD derivative of the whole residual to round-off, and that one equals
//    central differences of the double residual (independent of the Jets), plain and GGL;
//  - the coupling rows against the eliminated form: at a state of an `ede` run (the patella
//    solved by Newton inside the right-hand side), completed to round-off by the hidden
//    constraint (whose tendon force is PatellarTendonForce, solver/dynamics.hpp) and with x
//    from SolvePatella, every residual row of the monolithic DAE is zero to round-off;
//  - `monolithic` (rtol 1e-10) and `monolithic-ggl` (rtol 1e-12)
//    against `ede` at rtol 1e-12 (an independent form: an ODE integrator, closed-form
//    contact, the patella by Newton) on patellofemoral_impact: the same events, their times
//    to 1e-8 relative, and the patellar pose at the events — the DAE's own unknowns x, not a
//    Newton solve afterwards — to 1e-8 of the coordinate's scale (0.05 m, 1 rad);
//  - on patellofemoral_extension run past its end (to 0.38 s) the medial facet force
//    crosses zero near extension: both stop there with the facet's SolverError, at the time
//    where λ_medial of SolvePatella along the `ede` solution crosses zero (to 1e-8
//    relative), with the patellar pose there to 1e-8 of its scale;
//  - on patella_fold (facet_liftoff on) both follow ede to the medial facet's
//    lift-off and stop after it with the fold's error: the same events, times to 1e-8
//    relative, the patellar pose at them;
//  - on patella_medial_liftoff (a genuine one-facet branch) both follow ede through the
//    medial facet's re-contact, lift-off and re-contact, with λ_medial = 0 and a positive
//    gap in between, and the Jacobian with that facet separated is exact;
//  - a scene without a patella is refused.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "formulations/formulation.hpp"
#include "formulations/internal/monolithic_system.hpp"
#include "formulations/run.hpp"
#include "formulations/simulator.hpp"
#include "scene/scene.hpp"
#include "solver/consistent_init.hpp"
#include "solver/dynamics.hpp"
#include "solver/patella.hpp"
#include "tests/off_rest_state.hpp"

namespace kneedyn {
namespace {

const Scene& ImpactScene() {
  static const Scene scene = LoadScene("reference-data/scenes/patellofemoral_impact.yaml");
  return scene;
}
const Scene& ExtensionScene() {
  static const Scene scene = LoadScene("reference-data/scenes/patellofemoral_extension.yaml");
  return scene;
}

// The size of patella coordinate k for its tolerance: m for the translations, rad for the angles.
double PatellaScale(int k) { return k < 3 ? 0.05 : 1.0; }

RunResult RunWith(const Scene& scene, const std::string& formulation, double rtol, double atol) {
  RunSettings settings;
  settings.formulation = formulation;
  settings.options.rtol = rtol;
  settings.options.atol = atol;
  RunResult result = RunScene(scene, settings);
  EXPECT_TRUE(result.completed) << formulation << ": " << result.failure;
  return result;
}

// A consistent state at the start of the impact scene, moved off rest (random rates,
// accelerations and forces: the residual need not vanish for a derivative check).
struct Perturbed {
  MechanicalState state;
  std::vector<double> y, yp;
};
Perturbed PerturbedState(MonolithicSystem* system, unsigned seed) {
  const Scene& scene = ImpactScene();
  ConsistentInitOptions init;
  Perturbed p;
  p.state = ConsistentInitialize(scene.model, scene.initial, {0, 1}, init, nullptr);
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  MechanicalState& s = p.state;
  test_support::MoveOffRest(scene.model, &rng, &s);
  system->SetPhase(s.active, s.contact, s.ligament_branch);
  const int n = system->size();
  p.y.assign(n, 0.0);
  p.yp.assign(n, 0.0);
  system->InitialValues(s, p.y.data(), p.yp.data());
  for (int i = 12; i < system->tibia().NormalIndex(0); ++i) p.y[i] += 2e-4 * u(rng);
  for (int k = 0; k < 2; ++k) p.y[system->tibia().NormalIndex(k)] += 10.0 * u(rng);
  if (system->tibia().ggl()) {
    for (int k = 0; k < 2; ++k) p.y[system->tibia().MuIndex(k)] = 0.3 * u(rng);
  }
  for (int i = 0; i < kPatellaUnknowns; ++i) {
    p.y[system->PatellaIndex(i)] += (i < kPatellaFacetRatio ? 1e-3 : 0.05) * u(rng);
    p.yp[system->PatellaIndex(i)] += 1e-2 * u(rng);
  }
  return p;
}

class MonolithicJacobian : public ::testing::TestWithParam<bool> {};

TEST_P(MonolithicJacobian, ExactEqualsJetDerivativeAndCentralDifferences) {
  const bool ggl = GetParam();
  MonolithicSystem system(ImpactScene().model, ConstraintLevel::kVelocity, ggl);
  const Perturbed p = PerturbedState(&system, 2026);
  const int n = system.size();
  EXPECT_EQ(n, ggl ? 41 : 39);
  const double t = p.state.t, cj = 850.0;  // a typical α/h (1/s)
  std::vector<double> exact(n * n), jet(n * n);
  ASSERT_TRUE(system.Jacobian(t, cj, p.y.data(), p.yp.data(), exact.data()));
  ASSERT_TRUE(system.JacobianByJets(t, cj, p.y.data(), p.yp.data(), jet.data()));
  double largest = 0.0;
  for (double v : jet) largest = std::max(largest, std::abs(v));
  for (int col = 0; col < n; ++col) {
    for (int row = 0; row < n; ++row) {
      EXPECT_NEAR(exact[row + n * col], jet[row + n * col], 1e-12 * largest + 1e-10 * std::abs(jet[row + n * col]))
          << "dF[" << row << "]/d " << system.UnknownName(col);
    }
  }
  // Central differences of the double residual, dF/dy_j + cj dF/dẏ_j, step relative to y_j.
  std::vector<double> Fp(n), Fm(n);
  int coupling_entries = 0;
  for (int col = 0; col < n; ++col) {
    const double h = 1e-6 * std::max(1.0, std::abs(p.y[col])) * (col < 3 || col >= 12 ? 0.1 : 1.0);
    std::vector<double> y = p.y, yp = p.yp;
    y[col] = p.y[col] + h;
    yp[col] = p.yp[col] + cj * h;
    ASSERT_TRUE(system.Residual(t, y.data(), yp.data(), Fp.data()));
    y[col] = p.y[col] - h;
    yp[col] = p.yp[col] - cj * h;
    ASSERT_TRUE(system.Residual(t, y.data(), yp.data(), Fm.data()));
    for (int row = 0; row < n; ++row) {
      const double fd = (Fp[row] - Fm[row]) / (2 * h);
      const double a = jet[row + n * col];
      EXPECT_NEAR(a, fd, 1e-6 * (largest * 1e-3 + std::abs(a)) + 1e-5) << "dF[" << row << "]/d " << system.UnknownName(col);
      const bool coupling = (row >= system.tibia_size()) != (col >= system.tibia_size());
      if (coupling && std::abs(a) > 1e-3) ++coupling_entries;
    }
  }
  // The check sees the coupling: the tibia's rows depend on x, the patella's on q.
  EXPECT_GT(coupling_entries, 30);
}

INSTANTIATE_TEST_SUITE_P(PlainAndGgl, MonolithicJacobian, ::testing::Values(false, true),
                         [](const ::testing::TestParamInfo<bool>& info) { return info.param ? "ggl" : "plain"; });

// The eliminated form's state makes every monolithic row vanish: the tendon's pull from the
// unknowns x (Eq. 1.63, PatellaCouplingRows) is the one ComputeAppliedWrench applies after
// solving the patella (PatellarTendonForce), in sign, frame and moment arm.
TEST(MonolithicSystem, ResidualVanishesAtAStateOfTheEliminatedForm) {
  const Scene& scene = ImpactScene();
  const RunResult ede = RunWith(scene, "ede", 1e-10, 1e-12);
  ASSERT_GE(ede.samples.size(), 40u);
  int checked = 0;
  for (size_t i : {size_t{5}, size_t{20}, ede.samples.size() / 2, ede.samples.size() - 2}) {
    MechanicalState s = ede.samples[i];
    if (s.active.empty()) continue;
    SCOPED_TRACE("t = " + std::to_string(s.t) + " s");
    CompleteHiddenConstraint(scene.model, &s);  // (q, q̇) on the constraints, q̈ and N with the solved patella
    for (bool ggl : {false, true}) {
      MonolithicSystem system(scene.model, ConstraintLevel::kVelocity, ggl);
      system.SetPhase(s.active, s.contact, s.ligament_branch);
      const int n = system.size(), nt = system.tibia_size();
      std::vector<double> y(n), yp(n), F(n);
      system.InitialValues(s, y.data(), yp.data());
      ASSERT_TRUE(system.Residual(s.t, y.data(), yp.data(), F.data()));
      for (int r = 0; r < 6; ++r) EXPECT_EQ(F[r], 0.0) << "kinematic row " << r;
      for (int r = 6; r < 12; ++r) EXPECT_NEAR(F[r], 0.0, 1e-9) << "Newton-Euler row " << r << " (N, N m)";
      for (int r = 12; r < nt; ++r) EXPECT_NEAR(F[r], 0.0, 1e-12) << system.UnknownName(r) << " row (m, m/s)";
      for (int r = nt; r < n; ++r) EXPECT_NEAR(F[r], 0.0, 1e-12) << "patella row " << r - nt;
      // Not trivially zero: the tendon pulls with tens of newtons there.
      Vector6d tendon;
      double rows[kPatellaUnknowns];
      const Patella& patella = *scene.model.patella;
      ASSERT_TRUE(PatellaCouplingRows(patella, kBothFacetsPress, QuadricepsMagnitude(patella.quadriceps, s.t),
                                      PoseFromCoordinates(s.q), y.data() + nt, rows, &tendon));
      EXPECT_GT(tendon.head<3>().norm(), 10.0);
      ++checked;
    }
  }
  EXPECT_GE(checked, 6);
}

// Event names and times, and the patella's unknowns x at each event row: the monolithic
// formulation's own (test hook) or, for the eliminated form, SolvePatella at the row's pose.
struct EventsAndPatella {
  RunResult run;
  std::vector<std::array<double, kPatellaUnknowns>> x_at_events;
  std::array<double, kPatellaUnknowns> x_last{};  // at the end of the last Advance
  std::vector<std::array<double, kPatellaUnknowns>> x_at_rows;  // every recorded row, as run.samples
};

EventsAndPatella RunMonolithic(const Scene& scene, const std::string& formulation, double rtol, double atol) {
  EventsAndPatella out;
  FormulationOptions options;
  options.rtol = rtol;
  options.atol = atol;
  std::unique_ptr<Formulation> stepper = CreateFormulation(formulation, scene, options);
  SimulatorSettings sim;
  sim.init.form = stepper->contact_form();
  sim.output_interval = scene.output_interval;
  sim.rtol = rtol;
  sim.atol = atol;
  sim.sample = [&](const MechanicalState&, bool is_event) {
    std::array<double, kPatellaUnknowns> x{};  // none at the first row, before the first Advance
    const bool have = MonolithicPatellaUnknownsForTesting(*stepper, &x);
    out.x_at_rows.push_back(x);
    if (!is_event) return;
    EXPECT_TRUE(have);
    out.x_at_events.push_back(x);
  };
  Simulator simulator(scene, stepper.get(), sim, &out.run);
  simulator.Initialize();
  try {
    simulator.Run();
    out.run.completed = true;
  } catch (const Error& e) {
    out.run.failure = e.what();
  }
  EXPECT_TRUE(MonolithicPatellaUnknownsForTesting(*stepper, &out.x_last));
  out.run.stats = stepper->stats();
  return out;
}

EventsAndPatella EliminatedReference(const Scene& scene, bool expect_completed = true) {
  EventsAndPatella out;
  if (expect_completed) {
    out.run = RunWith(scene, "ede", 1e-12, 1e-14);
  } else {
    RunSettings settings;
    settings.formulation = "ede";
    settings.options.rtol = 1e-12;
    settings.options.atol = 1e-14;
    out.run = RunScene(scene, settings);
  }
  const Patella& p = *scene.model.patella;
  PatellaGuess guess;
  for (size_t i = 0; i < out.run.samples.size(); ++i) {  // every row: the warm start follows the motion
    SolvePatella(p, TuberosityInF(p, PoseFromCoordinates(out.run.samples[i].q)), "test", &guess);
    out.x_at_rows.push_back(guess.x);
    if (out.run.sample_is_event[i]) out.x_at_events.push_back(guess.x);
  }
  out.x_last = guess.x;
  return out;
}

void ExpectAgreement(const EventsAndPatella& reference, const EventsAndPatella& run, const std::string& name,
                     bool expect_completed = true) {
  if (expect_completed) {
    ASSERT_TRUE(run.run.completed) << run.run.failure;
  }
  ASSERT_EQ(reference.run.events.size(), run.run.events.size()) << name;
  ASSERT_GE(reference.run.events.size(), 1u);
  for (size_t i = 0; i < reference.run.events.size(); ++i) {
    EXPECT_EQ(reference.run.events[i].name, run.run.events[i].name);
    const double t_ref = reference.run.events[i].time, t = run.run.events[i].time;
    EXPECT_NEAR(t, t_ref, 1e-8 * t_ref) << name << " " << reference.run.events[i].name;
    std::printf("%s %-20s t = %.12f s (ede %.12f s), relative difference %.2e\n", name.c_str(),
                reference.run.events[i].name.c_str(), t, t_ref, std::abs(t - t_ref) / t_ref);
  }
  ASSERT_EQ(reference.x_at_events.size(), run.x_at_events.size());
  for (size_t i = 0; i < run.x_at_events.size(); ++i) {
    double worst = 0.0;
    for (int k = 0; k < 6; ++k) {
      const double d = std::abs(run.x_at_events[i][k] - reference.x_at_events[i][k]) / PatellaScale(k);
      worst = std::max(worst, d);
      EXPECT_LE(d, 1e-8) << name << " event row " << i << " " << PatellaUnknownName(k);
    }
    std::printf("%s event row %zu: patellar pose difference %.2e of the scale\n", name.c_str(), i, worst);
  }
}

// The tightest tolerance plain `monolithic` passes: at rtol 1e-11 IDA's corrector fails at
// t = 0.2772 s with N_lateral's weighted error dominant, as plain `dae` does there (and on
// chapter_impact, without a patella, at rtol 1e-12): a limit of the index-2 tibia, which GGL
// lifts, not of the patella's rows.
constexpr double kPlainRtol = 1e-10;

// The monolithic forms and the rtol each runs at (atol 1e-2 rtol): GGL at 1e-12.
struct MonolithicForm {
  const char* name;
  double rtol;
};
constexpr MonolithicForm kMonolithicForms[] = {{"monolithic", kPlainRtol}, {"monolithic-ggl", 1e-12}};

TEST(MonolithicRuns, AgreesWithTheOdeFormOnTheImpactScene) {
  const Scene& scene = ImpactScene();
  const EventsAndPatella reference = EliminatedReference(scene);
  ExpectAgreement(reference, RunMonolithic(scene, "monolithic", kPlainRtol, 1e-2 * kPlainRtol), "monolithic");
  ExpectAgreement(reference, RunMonolithic(scene, "monolithic-ggl", 1e-12, 1e-14), "monolithic-ggl");
}

// On the extension scene run past its end the medial facet's force ratio λ_medial falls
// through zero near extension (t = 0.3613 s, 29.9°): the facet would pull. The scene ends at
// 0.35 s for that reason (patellofemoral_extension.yaml); here its end is moved to 0.38 s,
// the scene's earlier end, so that the crossing lies inside the run. The eliminated forms run
// on with λ < 0 (nothing in them watches it); the monolithic DAE, whose λ are unknowns with a
// root function each, stops there with a SolverError naming the facet and the time. That time
// and the patellar pose there agree with where λ_medial of SolvePatella along the `ede`
// solution crosses zero.
TEST(MonolithicRuns, StopsWhereTheOdeFormsMedialFacetForceCrossesZeroOnTheExtensionScene) {
  Scene scene = ExtensionScene();
  ASSERT_LT(scene.end.time, 0.3613);  // the scene itself ends before the crossing
  scene.end.time = 0.38;              // s: past it
  for (const MonolithicForm& c : kMonolithicForms) {
    SCOPED_TRACE(c.name);
    const EventsAndPatella run = RunMonolithic(scene, c.name, c.rtol, 1e-2 * c.rtol);
    ASSERT_FALSE(run.run.completed);
    const std::string& why = run.run.failure;
    EXPECT_NE(why.find("the medial patellar facet's force ratio lambda changes sign at t = "), std::string::npos) << why;
    const double t_stop = run.run.samples.empty() ? 0.0 : run.run.samples.back().t;  // last row before the stop
    const size_t at = why.find("at t = ");
    ASSERT_NE(at, std::string::npos);
    const double t_root = std::stod(why.substr(at + 7));
    EXPECT_GT(t_root, t_stop);
    EXPECT_NEAR(run.x_last[kPatellaFacetRatio], 0.0, 1e-9);  // the DAE's own λ at its root
    // ede at rtol 1e-12 with rows 1 µs either side of the root and at it, from the DAE's
    // initial pose: the scene holds four coordinates, so the start's position level
    // (consistent_init.hpp) is under-determined. Every contact form now lands on the same
    // point of it (PatellaLiftoff.EveryContactFormStartsTheUnderdeterminedSceneFromTheSamePose);
    // the shared start keeps this comparison independent of that.
    Scene same_start = scene;
    same_start.initial.q = run.run.samples.at(0).q;
    RunSettings settings;
    settings.formulation = "ede";
    settings.options.rtol = 1e-12;
    settings.options.atol = 1e-14;
    settings.output_times = {t_root - 1e-6, t_root, t_root + 1e-6};
    const RunResult ede = RunScene(same_start, settings);
    ASSERT_TRUE(ede.completed) << ede.failure;
    EXPECT_EQ(ede.samples.at(0).q, run.run.samples.at(0).q);
    const Patella& p = *scene.model.patella;
    double lambda[3] = {}, t[3] = {};
    std::array<double, kPatellaUnknowns> x_at_root{};
    int found = 0;
    PatellaGuess guess;
    for (const MechanicalState& s : ede.samples) {  // every row: the warm start follows the motion
      SolvePatella(p, TuberosityInF(p, PoseFromCoordinates(s.q)), "test", &guess);
      for (int k = 0; k < 3; ++k) {
        if (std::abs(s.t - settings.output_times[k]) > 1e-13) continue;
        lambda[k] = guess.x[kPatellaFacetRatio];
        t[k] = s.t;
        if (k == 1) x_at_root = guess.x;
        ++found;
      }
    }
    ASSERT_EQ(found, 3);
    ASSERT_LT(lambda[0] * lambda[2], 0.0) << "λ_medial of the ODE form does not cross zero there";
    const double t_cross = t[0] - lambda[0] * (t[2] - t[0]) / (lambda[2] - lambda[0]);  // O(1e-12 s) interpolation
    EXPECT_NEAR(t_root, t_cross, 1e-8 * t_cross);
    std::printf("%s: medial facet force zero at t = %.12f s (ede: %.12f s, relative difference %.2e)\n", c.name,
                t_root, t_cross, std::abs(t_root - t_cross) / t_cross);
    double worst = 0.0;
    for (int k = 0; k < 6; ++k) {
      const double d = std::abs(run.x_last[k] - x_at_root[k]) / PatellaScale(k);
      worst = std::max(worst, d);
      EXPECT_LE(d, 1e-8) << PatellaUnknownName(k);
    }
    std::printf("%s: patellar pose difference there %.2e of the scale\n", c.name, worst);
  }
}

// patella_fold (reference-data/scenes/hard/): with the scene's facet_liftoff the
// medial facet's force crosses zero as the knee extends, but the one-facet branch folds back
// there (docs/model.md §12): past it no equilibrium holds, so every formulation records the
// lift-off and stops at the start of the next phase with the fold's SolverError. Against
// `ede` at rtol 1e-12 from the same start (the scene holds four coordinates, so the start
// depends on the contact description: see the extension test above): the same events, the
// lift-off among them, their times to 1e-8 relative and the patellar pose at them (the
// DAE's own x) to 1e-8 of the scale, and the same error.
TEST(MonolithicRuns, StopsAtTheFoldAfterTheMedialFacetLiftoffAsTheOdeFormDoes) {
  const Scene scene = LoadScene("reference-data/scenes/hard/patella_fold.yaml");
  ASSERT_TRUE(scene.model.patella && scene.model.patella->facet_liftoff);
  EventsAndPatella reference;
  for (const MonolithicForm& c : kMonolithicForms) {
    SCOPED_TRACE(c.name);
    const EventsAndPatella run = RunMonolithic(scene, c.name, c.rtol, 1e-2 * c.rtol);
    ASSERT_FALSE(run.run.completed);
    EXPECT_NE(run.run.failure.find("medial facet switches"), std::string::npos) << run.run.failure;
    EXPECT_NE(run.run.failure.find("one-facet branch has folded back"), std::string::npos) << run.run.failure;
    if (reference.run.samples.empty()) {
      Scene same_start = scene;
      same_start.initial.q = run.run.samples.at(0).q;
      reference = EliminatedReference(same_start, /*expect_completed=*/false);
      ASSERT_FALSE(reference.run.completed);
      EXPECT_NE(reference.run.failure.find("one-facet branch has folded back"), std::string::npos)
          << reference.run.failure;
    }
    EXPECT_EQ(reference.run.samples.at(0).q, run.run.samples.at(0).q);
    ASSERT_FALSE(reference.run.events.empty());
    EXPECT_EQ(reference.run.events.back().name, "liftoff_patellar_medial");
    ExpectAgreement(reference, run, c.name, /*expect_completed=*/false);
  }
}

// patella_medial_liftoff (reference-data/scenes/hard/): a genuine one-facet branch. The
// medial facet starts separated, re-contacts, lifts off and re-contacts (docs/model.md §12);
// the monolithic DAE replaces the separated facet's gap row by λ_medial = 0. Against `ede` at
// rtol 1e-12 from the same start: the same events, their times to 1e-8 relative, the
// patellar pose at them and at the end (the DAE's own x) to 1e-8 of the scale; between the
// lift-off and the re-contact the DAE's λ_medial is exactly 0, its medial gap (e·n at its
// own chart coordinates) > 0 and its λ_lateral > 0.
TEST(MonolithicRuns, FollowsTheOdeFormThroughTheGenuineMedialFacetLiftoff) {
  const Scene scene = LoadScene("reference-data/scenes/hard/patella_medial_liftoff.yaml");
  ASSERT_TRUE(scene.model.patella && scene.model.patella->facet_liftoff);
  const Patella& p = *scene.model.patella;
  EventsAndPatella reference;
  for (const MonolithicForm& c : kMonolithicForms) {
    SCOPED_TRACE(c.name);
    const EventsAndPatella run = RunMonolithic(scene, c.name, c.rtol, 1e-2 * c.rtol);
    ASSERT_TRUE(run.run.completed) << run.run.failure;
    if (reference.run.samples.empty()) {
      Scene same_start = scene;
      same_start.initial.q = run.run.samples.at(0).q;
      reference = EliminatedReference(same_start);
    }
    ExpectAgreement(reference, run, c.name);
    std::vector<std::string> names;
    for (const EventRecord& e : run.run.events) names.push_back(e.name);
    const std::vector<std::string> expected = {"recontact_patellar_medial", "liftoff_patellar_medial",
                                               "recontact_patellar_medial"};
    ASSERT_EQ(names, expected);
    const double t_liftoff = run.run.events[1].time, t_recontact = run.run.events[2].time;
    int separated_rows = 0;
    for (size_t i = 0; i < run.run.samples.size(); ++i) {
      const double t = run.run.samples[i].t;
      if (run.run.sample_is_event[i] || t <= t_liftoff || t >= t_recontact) continue;
      const std::array<double, kPatellaUnknowns>& x = run.x_at_rows.at(i);
      EXPECT_EQ(x[kPatellaFacetRatio], 0.0) << "t = " << t;
      EXPECT_GT(PatellaFacetGaps(p, x)[0], 1e-9) << "t = " << t;  // m
      EXPECT_GT(x[kPatellaFacetRatio + 1], 0.1) << "t = " << t;
      ++separated_rows;
    }
    EXPECT_GE(separated_rows, 3);
    double worst = 0.0;
    for (int k = 0; k < 6; ++k) {
      const double d = std::abs(run.x_last[k] - reference.x_last[k]) / PatellaScale(k);
      worst = std::max(worst, d);
      EXPECT_LE(d, 1e-8) << PatellaUnknownName(k);
    }
    std::printf("%s: patellar pose at the end %.2e of the scale from ede's\n", c.name, worst);
  }
}

// The monolithic Jacobian with the medial facet separated (its row λ_medial = 0): at a state
// of patella_medial_liftoff between the lift-off and the re-contact, moved off the solution,
// the exact Jacobian equals the JetD derivative and central differences, plain and GGL.
class MonolithicSeparatedFacetJacobian : public ::testing::TestWithParam<bool> {};

TEST_P(MonolithicSeparatedFacetJacobian, ExactEqualsJetDerivativeAndCentralDifferences) {
  const bool ggl = GetParam();
  const Scene scene = LoadScene("reference-data/scenes/hard/patella_medial_liftoff.yaml");
  const RunResult ede = RunWith(scene, "ede", 1e-10, 1e-12);
  ASSERT_GE(ede.events.size(), 2u);
  ASSERT_EQ(ede.events[1].name, "liftoff_patellar_medial");
  const double t_mid = ede.events[1].time + 0.005;  // s: the medial facet separated (re-contact 0.0758 s)
  MechanicalState s;
  for (const MechanicalState& row : ede.samples) {
    if (row.t >= t_mid) {
      s = row;
      break;
    }
  }
  ASSERT_GE(s.t, t_mid);
  MonolithicSystem system(scene.model, ConstraintLevel::kVelocity, ggl);
  system.SetPhase(s.active, s.contact, s.ligament_branch);
  const int n = system.size();
  std::vector<double> y0(n), yp0(n);
  system.InitialValues(s, y0.data(), yp0.data());
  ASSERT_FALSE(system.facets()[0]) << "the medial facet presses at t = " << s.t;
  ASSERT_TRUE(system.facets()[1]);
  ASSERT_EQ(y0[system.PatellaIndex(kPatellaFacetRatio)], 0.0);
  std::mt19937 rng(2027);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<double> y = y0, yp = yp0;
  for (int i = 0; i < kPatellaUnknowns; ++i) {
    y[system.PatellaIndex(i)] += (i < kPatellaFacetRatio ? 1e-4 : 0.01) * u(rng);
    yp[system.PatellaIndex(i)] += 1e-2 * u(rng);
  }
  const double t = s.t, cj = 850.0;
  std::vector<double> exact(n * n), jet(n * n), F(n);
  ASSERT_TRUE(system.Jacobian(t, cj, y.data(), yp.data(), exact.data()));
  ASSERT_TRUE(system.JacobianByJets(t, cj, y.data(), yp.data(), jet.data()));
  ASSERT_TRUE(system.Residual(t, y.data(), yp.data(), F.data()));
  // The separated facet's row is λ_medial itself: ∂/∂λ_medial = 1, nothing else.
  const int row = system.PatellaIndex(5 * 0 + 2), col = system.PatellaIndex(kPatellaFacetRatio);
  EXPECT_EQ(F[row], y[col]);
  for (int j = 0; j < n; ++j) EXPECT_EQ(exact[row + n * j], j == col ? 1.0 : 0.0) << system.UnknownName(j);
  double largest = 0.0;
  for (double v : jet) largest = std::max(largest, std::abs(v));
  std::vector<double> Fp(n), Fm(n);
  for (int c = 0; c < n; ++c) {
    for (int r = 0; r < n; ++r) {
      EXPECT_NEAR(exact[r + n * c], jet[r + n * c], 1e-12 * largest + 1e-10 * std::abs(jet[r + n * c]))
          << "dF[" << r << "]/d " << system.UnknownName(c);
    }
    const double h = 1e-6 * std::max(1.0, std::abs(y[c])) * (c < 3 || c >= 12 ? 0.1 : 1.0);
    std::vector<double> yh = y, yph = yp;
    yh[c] = y[c] + h;
    yph[c] = yp[c] + cj * h;
    ASSERT_TRUE(system.Residual(t, yh.data(), yph.data(), Fp.data()));
    yh[c] = y[c] - h;
    yph[c] = yp[c] - cj * h;
    ASSERT_TRUE(system.Residual(t, yh.data(), yph.data(), Fm.data()));
    for (int r = 0; r < n; ++r) {
      const double fd = (Fp[r] - Fm[r]) / (2 * h), a = exact[r + n * c];
      EXPECT_NEAR(a, fd, 1e-6 * (largest * 1e-3 + std::abs(a)) + 1e-5) << "dF[" << r << "]/d " << system.UnknownName(c);
    }
  }
}

INSTANTIATE_TEST_SUITE_P(PlainAndGgl, MonolithicSeparatedFacetJacobian, ::testing::Values(false, true),
                         [](const ::testing::TestParamInfo<bool>& info) { return info.param ? "ggl" : "plain"; });

TEST(MonolithicRuns, ASceneWithoutPatellaIsRefused) {
  const Scene chapter = LoadScene("reference-data/scenes/chapter_impact.yaml");
  for (const char* name : {"monolithic", "monolithic-ggl"}) {
    EXPECT_TRUE(FindFormulation(name).needs_patella) << name;
    try {
      CreateFormulation(name, chapter, FormulationOptions());
      ADD_FAILURE() << name << " accepted a scene without a patella";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find("no patella"), std::string::npos) << e.what();
    }
  }
}

}  // namespace
}  // namespace kneedyn
