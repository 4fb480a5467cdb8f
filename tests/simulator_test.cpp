// Tests of the hybrid simulator (formulations/simulator.hpp): the states it hands a stepper at
// a restart under each RestartProjection, its refusal of a pulling contact and the
// re-contact hysteresis rule.
#include "formulations/simulator.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <optional>
#include <sstream>
#include <string>

#include "formulations/run.hpp"
#include "formulations/run_output.hpp"
#include "scene/scene.hpp"
#include "solver/consistent_init.hpp"
#include "solver/constraint_residuals.hpp"
#include "solver/contact_kinematics.hpp"
#include "solver/error.hpp"
#include "solver/events.hpp"
#include "solver/ligament.hpp"
#include "solver/pose.hpp"
#include "spy_stepper.hpp"
#include "test_support.hpp"

namespace kneedyn {
namespace {

using test_support::ChapterScene;
using test_support::ChapterSceneWith;
using test_support::ScenesDir;
using test_support::SpyStepper;

SimulatorSettings Settings(const Scene& scene, const Formulation& stepper) {
  SimulatorSettings s;
  s.init.form = stepper.contact_form();
  s.output_interval = scene.output_interval;
  return s;
}

// The largest |φ_i| of the active contacts (m).
double MaxGap(const Scene& scene, const MechanicalState& state) {
  double gap = 0.0, rate = 0.0;
  MaxActiveConstraintResiduals(scene.model, state, &gap, &rate);
  return gap;
}

// kProject restarts from (q, q̇) on the constraints (CompleteHiddenConstraint: gaps to
// 1e-14 m), although the event state drifted (ede without stabilization: ~1e-8 m at the
// lift-off); kKeepState restarts from the event state exactly.
TEST(Simulator, RestartProjection) {
  const Scene& scene = ChapterScene();
  for (RestartProjection restart : {RestartProjection::kProject, RestartProjection::kKeepState}) {
    SpyStepper spy("ede", scene);
    SimulatorSettings settings = Settings(scene, spy);
    settings.restart = restart;
    RunResult record;
    Simulator simulator(scene, &spy, settings, &record);
    simulator.Initialize();
    simulator.Run();
    ASSERT_EQ(record.end_reason, "flexion_90");
    // The lift-off of the chapter scene, then the end: one restart after an event switch.
    size_t n_events = 0;
    double max_event_gap = 0.0;
    for (size_t k = 0; k + 1 < spy.starts.size(); ++k) {
      const MechanicalState& next = spy.starts[k + 1];
      // The event state the phase ended in: the last one reported before this start.
      const MechanicalState* event = nullptr;
      for (const MechanicalState& e : spy.event_states) {
        if (e.t <= next.t) event = &e;
      }
      if (event == nullptr || event->t != next.t) continue;
      ++n_events;
      if (restart == RestartProjection::kKeepState) {
        EXPECT_EQ(next.q, event->q) << "t = " << next.t;
        EXPECT_EQ(next.qd, event->qd) << "t = " << next.t;
      } else {
        EXPECT_LE(MaxGap(scene, next), 1e-13) << "t = " << next.t;
        max_event_gap = std::max(max_event_gap, MaxGap(scene, *event));
      }
    }
    EXPECT_GE(n_events, 1u);
    // Drift to remove (else the kProject check shows nothing).
    if (restart == RestartProjection::kProject) {
      EXPECT_GT(max_event_gap, 1e-12);
    }
  }
}

// A re-contact that bounces off at once (distal pulse, dae: recontact_lateral and
// liftoff_lateral at t = 0.024886 s): kSeparate records the second lift-off, kRefuse stops
// there with a SolverError naming the compartment.
TEST(Simulator, PullingContact) {
  const Scene scene = LoadScene(ScenesDir() + "/hard/distal_pulse_both_separate.yaml");
  double bounce = -1.0;
  {
    SpyStepper spy("dae", scene);
    RunResult record;
    Simulator simulator(scene, &spy, Settings(scene, spy), &record);
    simulator.Initialize();
    simulator.Run();
    for (size_t k = 1; k < record.events.size() && bounce < 0.0; ++k) {
      if (record.events[k].name == "liftoff_lateral" && record.events[k - 1].name == "recontact_lateral" &&
          record.events[k].time == record.events[k - 1].time) {
        bounce = record.events[k].time;
      }
    }
    ASSERT_GT(bounce, 0.0) << "no re-contact that bounces off";
  }
  SpyStepper spy("dae", scene);
  SimulatorSettings settings = Settings(scene, spy);
  settings.pulling = PullingContact::kRefuse;
  RunResult record;
  Simulator simulator(scene, &spy, settings, &record);
  simulator.Initialize();
  try {
    simulator.Run();
    FAIL() << "kRefuse ran through the bounce at t = " << bounce;
  } catch (const SolverError& e) {
    EXPECT_NE(std::string(e.what()).find("lateral contact would pull"), std::string::npos) << e.what();
    EXPECT_EQ(simulator.state().t, bounce);
  }
}

// An assembled start whose consistent forces pull (docs/model.md §6: the chapter scene with
// only alpha_deg: 30, N ≈ −9.6 and −9.9 kN) starts with both lift-offs at t = 0, and no
// row of the run has an active contact that pulls (N ≥ 0, docs/model.md §4). kRefuse stops
// there, naming the start.
TEST(Simulator, PullingStartLiftsOffAtOnce) {
  const Scene scene = ChapterSceneWith("{pose: assemble, coordinates: {alpha_deg: 30}}", "{time_s: 0.02}");
  for (const char* formulation : {"dae", "ede"}) {
    SpyStepper spy(formulation, scene);
    RunResult record;
    Simulator simulator(scene, &spy, Settings(scene, spy), &record);
    simulator.Initialize();
    simulator.Run();
    ASSERT_GE(record.events.size(), 2u) << formulation;
    for (int k = 0; k < 2; ++k) {
      EXPECT_EQ(record.events[k].name.rfind("liftoff_", 0), 0u) << formulation << ": " << record.events[k].name;
      EXPECT_EQ(record.events[k].time, 0.0) << formulation;
    }
    ASSERT_FALSE(record.samples.empty());
    EXPECT_FALSE(record.sample_is_event[0]) << formulation << ": the t = 0 row is a sampling row (kneedyn score)";
    for (const MechanicalState& s : record.samples) {
      for (int i : s.active) EXPECT_GE(s.contact[i].normal_force, -1e-6) << formulation << " t = " << s.t;
    }
  }
  SpyStepper spy("dae", scene);
  SimulatorSettings settings = Settings(scene, spy);
  settings.pulling = PullingContact::kRefuse;
  RunResult record;
  Simulator simulator(scene, &spy, settings, &record);
  try {
    simulator.Initialize();
    FAIL() << "kRefuse started with pulling contacts";
  } catch (const SolverError& e) {
    EXPECT_NE(std::string(e.what()).find("contact would pull"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("at the start"), std::string::npos) << e.what();
  }
}

// The one re-contact hysteresis rule: 10 · max(drift, rtol · |x0| + atol).
TEST(Simulator, RecontactGapTolerance) {
  Vector6d q = Vector6d::Zero();
  q.head<3>() << 3e-3, 0.0, 4e-3;  // |x0| = 5 mm
  EXPECT_DOUBLE_EQ(RecontactGapTolerance(0.0, q, 1e-6, 1e-8), 10.0 * (1e-6 * 5e-3 + 1e-8));
  EXPECT_DOUBLE_EQ(RecontactGapTolerance(1e-6, q, 1e-6, 1e-8), 1e-5);
}

// kink_<element> names an element as its trajectory columns do (docs/outputs.md: spaces as
// '_'); sensitivity.json had written "kink_MCL deep" beside the column strain_MCL_deep.
TEST(PhaseStart, KinkEventsNameTheirElementsAsTheColumns) {
  const Scene& scene = ChapterScene();
  ConsistentInitOptions init;
  InitReport report;
  const MechanicalState state = ConsistentInitialize(scene.model, scene.initial, {0, 1}, init, &report);
  RunResult none;
  const std::vector<std::string> columns = MakeTrajectoryTable(scene, none).columns;
  int kinks = 0;
  for (const EventSpec& e : EventsForPhase(scene.model, scene.end, state)) {
    if (e.kind != EventKind::kLigamentKink) continue;
    ++kinks;
    const std::string column = "strain_" + e.name.substr(5);
    EXPECT_NE(std::find(columns.begin(), columns.end(), column), columns.end()) << e.name << ": no column " << column;
  }
  EXPECT_EQ(kinks, 12);
}

// pulling_contact flags a normal force below −1e-9 N (kPullingForceFloorN, docs/outputs.md);
// above it the value is round-off: a scene without ligaments, its tibia falling off the
// plateau, wrote N = −2.4e-34 N and was warned of a pull past an unlocated lift-off.
TEST(OutputWarnings, PullingContactIsAForceBeyondRoundOff) {
  RunResult run;
  const auto pulls = [&](double force_N) {
    TrajectoryTable table;
    table.columns = {"time_s", "is_event", "N_medial_N"};
    table.rows = {{0.0, 0.0, 240.0}, {0.005, 0.0, force_N}, {0.01, 0.0, 10.0}};
    int n = 0;
    for (const OutputWarning& w : OutputWarnings(table, run)) n += w.kind == "pulling_contact";
    return n;
  };
  EXPECT_EQ(pulls(-2.4e-34), 0);
  EXPECT_EQ(pulls(-0.5e-9), 0);
  EXPECT_EQ(pulls(-2e-9), 1);
  EXPECT_EQ(pulls(-3.9), 1);
}

// A separated compartment re-contacts when its gap falls below min(its gap at separation, 0)
// by the hysteresis (docs/model.md §9), whatever restarts come between: a restart while the
// condyle sinks (a ligament kink) keeps the line. Before, every phase measured it from the
// gap at its own start, so each restart on a sinking condyle lowered the line by another
// hysteresis.
TEST(PhaseStart, RecontactLineStaysAtTheGapOfSeparationAcrossRestarts) {
  const Scene& scene = ChapterScene();
  const Model& model = scene.model;
  ConsistentInitOptions init;
  InitReport report;
  MechanicalState state = ConsistentInitialize(model, scene.initial, {0, 1}, init, &report);
  const auto lateral_gap = [&](const Vector6d& q) {
    return RequireContactKinematics(model.contacts[1], PoseFromCoordinates(q), "test").gap;
  };
  const auto recontact_offset = [&](double gap_tolerance) {
    for (const EventSpec& e : EventsForPhase(model, scene.end, state, gap_tolerance)) {
      if (e.kind == EventKind::kRecontact && e.contact == 1) return e.offset;
    }
    ADD_FAILURE() << "no re-contact root for the lateral contact";
    return 0.0;
  };
  state.active = {0};  // the lateral compartment separates here
  const double at_separation = lateral_gap(state.q);
  RecordSeparationGaps(model, &state);
  ASSERT_EQ(state.separation_gap.size(), 2u);
  EXPECT_TRUE(std::isnan(state.separation_gap[0]));  // in contact
  EXPECT_EQ(state.separation_gap[1], at_separation);
  const double tolerance = 5e-9;  // m
  EXPECT_DOUBLE_EQ(recontact_offset(tolerance), std::min(at_separation, 0.0) - tolerance);

  // The condyle sinks 3 nm (z0 moved along the gap's slope), then a restart.
  Vector6d dz = Vector6d::Zero();
  dz(2) = 1e-6;
  const double slope = (lateral_gap(state.q + dz) - lateral_gap(state.q - dz)) / 2e-6;  // m per m
  ASSERT_GT(std::abs(slope), 0.1);
  state.q(2) -= 3e-9 / slope;
  const double sunk = lateral_gap(state.q);
  ASSERT_NEAR(sunk, at_separation - 3e-9, 1e-11);
  RecordSeparationGaps(model, &state);
  EXPECT_EQ(state.separation_gap[1], at_separation);
  EXPECT_DOUBLE_EQ(recontact_offset(tolerance), std::min(at_separation, 0.0) - tolerance);
  // A hysteresis smaller than the sinking (a smaller tolerance at this phase): the root starts
  // 1 nm above zero, not below it where it could never cross.
  EXPECT_DOUBLE_EQ(recontact_offset(1e-9), sunk - kMinRecontactHysteresis);

  // In contact again, then separated anew: measured from the new separation.
  state.active = {0, 1};
  RecordSeparationGaps(model, &state);
  EXPECT_TRUE(std::isnan(state.separation_gap[1]));
  state.active = {0};
  RecordSeparationGaps(model, &state);
  EXPECT_EQ(state.separation_gap[1], sunk);

  // The re-contact event itself forgets the old separation, whether the contact stays closed
  // or bounces off at once (ReleasePullingContacts, no phase start between): the next phase
  // measures from the gap after the impact, not from the separation before it.
  const std::vector<EventSpec> specs = EventsForPhase(model, scene.end, state, tolerance);
  std::vector<int> fired;
  for (int k = 0; k < static_cast<int>(specs.size()); ++k) {
    if (specs[k].kind == EventKind::kRecontact && specs[k].contact == 1) fired.push_back(k);
  }
  ASSERT_EQ(fired.size(), 1u);
  std::vector<EventRecord> events;
  PhaseTransition(model, specs, fired, RestartProjection::kProject, PullingContact::kSeparate, &state, &events);
  EXPECT_TRUE(std::isnan(state.separation_gap[1])) << state.separation_gap[1];
}

// Each crossing of a ligament's kink length (1 + 2ε1) L0 (docs/model.md §5 and §9, the
// published law's jump) restarts the run once, in every formulation. Independent count: the
// sign changes of L_j − L_kink over the trajectory sampled every 0.1 ms (the chapter scene's
// 11 crossings are milliseconds apart). Without MeasureKinkRootsFromPhaseStart the restart's
// round-off left some roots on the side the locked branch had left, and ede (CVODE, ARKODE)
// and the IDA forms restarted twice for them (18 kink restarts for 11 crossings).
TEST(PhaseStart, EachKinkCrossingRestartsOnce) {
  struct Case {
    const char* formulation;
    std::optional<IntegratorKind> integrator;  // of the ODE forms (ede, mde); the DAE forms have IDA
    double rtol;
  };
  const Scene& scene = ChapterScene();
  for (const Case& c : {Case{"dae", std::nullopt, 1e-8}, Case{"dae-reduced", std::nullopt, 1e-8},
                        Case{"ede", IntegratorKind::kCvodeAdams, 1e-9}, Case{"ede", IntegratorKind::kDopri5, 1e-8},
                        Case{"mde", IntegratorKind::kDopri5, 1e-8}}) {
    SCOPED_TRACE(std::string(c.formulation) + " rtol " + std::to_string(c.rtol));
    RunSettings settings = test_support::SettingsAt(c.formulation, c.rtol, 1e-2 * c.rtol);
    if (c.integrator) settings.options.integrator = *c.integrator;
    settings.output_interval = 1e-4;            // s
    const RunResult r = RunScene(scene, settings);
    ASSERT_TRUE(r.completed) << r.failure;
    long sign_changes = 0;
    for (const Ligament& lig : scene.model.ligaments) {
      int previous = 0;
      for (const MechanicalState& s : r.samples) {
        const double g = LigamentSpan_F(lig, PoseFromCoordinates(s.q)).norm() - LigamentKinkLength(lig);
        const int side = g > 0.0 ? 1 : -1;
        if (previous != 0 && side != previous) ++sign_changes;
        previous = side;
      }
    }
    EXPECT_GT(sign_changes, 0);
    EXPECT_EQ(r.ligament_kink_crossings, sign_changes);
  }
}

// A start the knee cannot take is warned: the chapter scene assembled at 80° of flexion
// stretches elements to many times their slack length (the posterior ACL to a strain of
// about 28), which a run completes without a word; the chapter's own start stays below 0.2
// (docs/model.md), with no warning. The warning names the element and the row of its largest
// strain, read here from the table's strain column.
TEST(Simulator, OverstretchedElementsAreWarned) {
  const auto overstretched = [](const Scene& scene, std::vector<OutputWarning>* found) {
    RunSettings settings;
    settings.formulation = "ede";
    const RunResult run = RunScene(scene, settings);
    const TrajectoryTable table = MakeTrajectoryTable(scene, run);
    for (const OutputWarning& w : OutputWarnings(table, run)) {
      if (w.kind == "ligament_overstretched") found->push_back(w);
    }
    return table;
  };
  std::vector<OutputWarning> warnings;
  const TrajectoryTable table =
      overstretched(ChapterSceneWith("{pose: assemble, coordinates: {alpha_deg: 80}}", "{time_s: 0.01}"), &warnings);
  ASSERT_FALSE(warnings.empty());
  for (const OutputWarning& w : warnings) {
    const size_t c = static_cast<size_t>(std::find(table.columns.begin(), table.columns.end(), w.column) -
                                         table.columns.begin());
    ASSERT_LT(c, table.columns.size()) << w.column;
    double largest = -1.0, at = -1.0;
    for (const std::vector<double>& row : table.rows) {
      if (row[c] > largest) largest = row[c], at = row[0];
    }
    EXPECT_GT(largest, 1.0) << w.column;
    EXPECT_EQ(w.time_s, at) << w.column;
  }
  std::vector<OutputWarning> chapter;
  overstretched(ChapterScene(), &chapter);
  EXPECT_TRUE(chapter.empty()) << chapter.front().message;
}

}  // namespace
}  // namespace kneedyn
