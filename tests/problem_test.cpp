// Tests of the open problem interface (problem/problem.hpp, problem/kneedyn/problem.h):
//  - the transition and the phase starts equal the hybrid simulator's (a spy stepper records
//    the simulator's event states and restarts; Problem is handed the same event states);
//  - f, F and the DAE Jacobian through Problem and the C interface equal the functions the
//    formulations call (SolveConstrainedAcceleration, DaeSystem) bitwise;
//  - the exact DAE Jacobian agrees with central differences of the residual;
//  - bad handles, sizes, NaN states and times, calls of the other form and after the end
//    return error codes with messages; a failed transition changes nothing; one handle used
//    from two threads gives the serial results.
#include "problem/problem.hpp"

#include <gtest/gtest.h>

#include <algorithm>

#include <cmath>
#include <cstring>
#include <fstream>
#include <sstream>
#include <climits>
#include <functional>
#include <limits>
#include <thread>
#include <tuple>

#include "formulations/internal/ode_integrator.hpp"
#include "formulations/simulator.hpp"
#include "kneedyn/problem.h"
#include "spy_stepper.hpp"
#include "test_support.hpp"

namespace kneedyn {
namespace {

using test_support::ChapterScene;
using test_support::ChapterSceneWith;
using test_support::ScenesDir;
using test_support::SpyStepper;

struct SimulatorRun {
  explicit SimulatorRun(const std::string& formulation, const Scene& scene) : spy(formulation, scene) {
    SimulatorSettings s;
    s.init.form = spy.contact_form();
    s.output_interval = scene.output_interval;
    Simulator simulator(scene, &spy, s, &record);
    simulator.Initialize();
    simulator.Run();
  }
  SpyStepper spy;
  RunResult record;
};

std::vector<std::string> Names(const std::vector<EventSpec>& specs) {
  std::vector<std::string> n;
  for (const EventSpec& e : specs) n.push_back(e.name);
  return n;
}

// Problem's events without mde's chart switch (the simulator's mde switches charts inside
// a step, no event).
std::vector<std::string> PhaseEventNames(const Problem& p) {
  std::vector<std::string> n = p.event_names();
  if (p.is_mde() && !n.empty() && n.back() == Problem::kChartEvent) n.pop_back();
  return n;
}

void ExpectBitwise(const double* a, const double* b, int n, const std::string& what) {
  for (int i = 0; i < n; ++i) EXPECT_EQ(std::memcmp(&a[i], &b[i], sizeof(double)), 0) << what << "[" << i << "]: " << a[i] << " vs " << b[i];
}

// The y of a form at a mechanical state (DaeSystem's layout for the DAE forms; for mde the
// coordinates `free` of the chart in use, ẏ = (ṡ, s̈) from the state's q̈).
void FormValues(const std::string& form, const Model& model, const MechanicalState& state, std::vector<double>* y,
                std::vector<double>* yp, const std::vector<int>& free = {}) {
  if (form == "mde") {
    const int m = static_cast<int>(free.size());
    y->assign(2 * m, 0.0);
    yp->assign(2 * m, 0.0);
    for (int j = 0; j < m; ++j) {
      (*y)[j] = state.q(free[j]), (*y)[m + j] = state.qd(free[j]);
      (*yp)[j] = state.qd(free[j]), (*yp)[m + j] = state.qdd(free[j]);
    }
    return;
  }
  if (form == "ede") {
    y->assign(12, 0.0);
    yp->assign(12, 0.0);
    for (int i = 0; i < 6; ++i) {
      (*y)[i] = state.q(i), (*y)[6 + i] = state.qd(i);
      (*yp)[i] = state.qd(i), (*yp)[6 + i] = state.qdd(i);
    }
    return;
  }
  DaeSystem system(model, ContactForm::kChapter, ConstraintLevel::kVelocity, form == "dae-ggl");
  system.SetPhase(state.active, state.contact, state.ligament_branch);
  y->assign(system.size(), 0.0);
  yp->assign(system.size(), 0.0);
  system.InitialValues(state, y->data(), yp->data());
}

// The phase starts and transitions of Problem equal the simulator's, bitwise, along the
// whole chapter run (lift-off, then the end flexion). For mde the phase start's ẏ is the
// chart's (ṡ, s̈) where the simulator's start holds q̈ of the hidden-constraint solve: the
// same physics by two formulations, compared to 1e-9 relative; and after a transition in a
// phase where mde switched its chart (the simulator's mde does so after a step, which
// Problem is not told of), its y0 to round-off.
// Returns the transitions whose next phase start was compared bitwise.
int ExpectProblemFollowsSimulator(const Scene& scene, const std::string& form) {
  SCOPED_TRACE(form);
  SimulatorRun run(form, scene);
  const bool ends_by_event = run.record.end_reason != "end_time";
  Problem problem(scene, form);
  int bitwise_transitions = 0;
  [&] {
    const auto expect_yp0 = [&](const std::vector<double>& want, const char* what) {
      if (form != "mde") return ExpectBitwise(problem.yp0().data(), want.data(), problem.size(), what);
      for (int i = 0; i < problem.size(); ++i) EXPECT_NEAR(problem.yp0()[i], want[i], 1e-9 * (1.0 + std::abs(want[i]))) << what << i;
    };
    std::vector<double> y, yp;
    FormValues(form, scene.model, run.spy.starts[0], &y, &yp, problem.free_coordinates());
    expect_yp0(yp, "yp0 of phase 0");
    ASSERT_EQ(problem.size(), static_cast<int>(y.size()));
    ExpectBitwise(problem.y0().data(), y.data(), problem.size(), "y0 of phase 0");
    EXPECT_EQ(PhaseEventNames(problem), Names(run.spy.start_events[0]));
    for (size_t e = 0; e < run.spy.event_states.size(); ++e) {
      ASSERT_EQ(run.spy.event_phase[e], problem.phase());
      const MechanicalState& at = run.spy.event_states[e];
      FormValues(form, scene.model, at, &y, &yp, problem.free_coordinates());
      const bool ended = problem.Transition(at.t, y.data(), yp.data(), static_cast<int>(y.size()), run.spy.fired[e]);
      ASSERT_EQ(ended, ends_by_event && e + 1 == run.spy.event_states.size());
      if (ended) {
        EXPECT_EQ(problem.end_reason(), run.record.end_reason);
        break;
      }
      const MechanicalState& next = run.spy.starts[run.spy.event_phase[e] + 1];
      EXPECT_EQ(problem.phase_state().active, next.active);
      FormValues(form, scene.model, next, &y, &yp, problem.free_coordinates());
      ASSERT_EQ(problem.size(), static_cast<int>(y.size()));
      const std::vector<int>& switched = run.spy.chart_switch_phases;
      if (std::find(switched.begin(), switched.end(), run.spy.event_phase[e]) == switched.end()) {
        ExpectBitwise(problem.y0().data(), y.data(), problem.size(), "y0 after the transition");
        ++bitwise_transitions;
      } else {
        // mde switched its chart inside this phase (after a step, no event: Problem is not
        // told), so Problem rebuilds the event state from the free coordinates of the chart
        // it still has: the same state through another elimination, equal to round-off
        // (measured: 1 ulp), and so is the next phase's start.
        for (int i = 0; i < problem.size(); ++i) {
          EXPECT_NEAR(problem.y0()[i], y[i], 1e-14 * (1.0 + std::abs(y[i]))) << "y0 after the transition[" << i << "]";
        }
      }
      expect_yp0(yp, "yp0 after the transition");
      EXPECT_EQ(PhaseEventNames(problem), Names(run.spy.start_events[run.spy.event_phase[e] + 1]));
    }
    ASSERT_EQ(problem.events_recorded().size(), run.record.events.size());
    for (size_t k = 0; k < run.record.events.size(); ++k) {
      EXPECT_EQ(problem.events_recorded()[k].name, run.record.events[k].name);
      EXPECT_EQ(problem.events_recorded()[k].time, run.record.events[k].time);
    }
  }();
  return bitwise_transitions;
}

TEST(Problem, TransitionEqualsSimulator) {
  const Scene& scene = ChapterScene();
  for (const std::string form : {"ede", "mde", "dae", "dae-ggl"}) {
    ASSERT_EQ(SimulatorRun(form, scene).record.end_reason, "flexion_90") << form;
    // Most transitions follow no chart switch: the lift-off and the kinks before it.
    EXPECT_GE(ExpectProblemFollowsSimulator(scene, form), 8) << form;
  }
}

// The simulator's phases through a violent run, many kinks and both lift-offs within 25 ms
// (a pulse of 1e5 N, the documented maximum): Problem, handed the simulator's event states,
// starts every next phase as the simulator did and records its events, for every form.
TEST(Problem, FollowsTheSimulatorThroughTheLargestPulse) {
  Scene scene = ChapterScene();
  scene.model.pulse.amplitude = 1.0e5;
  scene.end.time = 0.025;
  for (const std::string form : {"ede", "mde", "dae", "dae-ggl"}) {
    const RunResult record = SimulatorRun(form, scene).record;
    int liftoffs = 0;
    for (const EventRecord& e : record.events) liftoffs += e.name.compare(0, 8, "liftoff_") == 0;
    EXPECT_EQ(liftoffs, 2) << form;
    EXPECT_GE(ExpectProblemFollowsSimulator(scene, form), 5) << form;
  }
}

std::vector<double> Perturbed(const Problem& p);

// The chapter scene with its initial_state and end replaced, and `extra` keys added.
// The scene's reading of the angular-velocity map (docs/model.md §2: "every formulation uses
// it") holds in every Problem call, as in a run: the chapter's printed Eq. 1.20b, to 0.05 s.
// The simulator sets it for its run; the Problem's phase starts and transitions equal the
// simulator's bitwise, f at y0 is yp0 (the same solve), F(y0, yp0) vanishes, and the printed
// reading's f differs from the exact map's (the test discriminates). Before, Problem ignored
// the key: it answered with the exact map.
TEST(Problem, FollowsTheScenesAngularVelocityMapReading) {
  const Scene printed = ChapterSceneWith("{pose: reference, guesses: chapter}", "{time_s: 0.05}",
                                       "angular_velocity_map: printed_eq_1_20b\n");
  const Scene exact = ChapterSceneWith("{pose: reference, guesses: chapter}", "{time_s: 0.05}", "");
  ASSERT_EQ(printed.model.angular_velocity_map, AngularVelocityMapReading::kPrintedEq1_20b);
  for (const std::string form : {"ede", "mde", "dae", "dae-ggl"}) {
    SCOPED_TRACE(form);
    EXPECT_GE(ExpectProblemFollowsSimulator(printed, form), 1);
    const Problem p(printed, form), q(exact, form);
    std::vector<double> f(p.size()), g(q.size());
    if (p.is_dae()) {
      p.Residual(p.t0(), p.y0().data(), p.yp0().data(), p.size(), f.data());
      for (double r : f) EXPECT_LT(std::abs(r), 1e-8);
      // The exact map's residual at the printed reading's consistent values does not vanish.
      q.Residual(p.t0(), p.y0().data(), p.yp0().data(), q.size(), g.data());
      double worst = 0.0;
      for (double r : g) worst = std::max(worst, std::abs(r));
      EXPECT_GT(worst, 1e-3);
    } else {
      const std::vector<double> y = Perturbed(p);
      p.Rhs(p.t0(), p.y0().data(), p.size(), f.data());
      for (int i = 0; i < p.size(); ++i) EXPECT_NEAR(f[i], p.yp0()[i], 1e-9 * (1.0 + std::abs(f[i]))) << i;
      p.Rhs(p.t0(), y.data(), p.size(), f.data());
      q.Rhs(q.t0(), y.data(), q.size(), g.data());
      double worst = 0.0;
      for (int i = 0; i < p.size(); ++i) worst = std::max(worst, std::abs(f[i] - g[i]) / (1.0 + std::abs(g[i])));
      EXPECT_GT(worst, 1e-3);
    }
  }
}

// A start whose consistent forces pull (docs/model.md §6's example: the chapter scene with only
// alpha_deg: 30, N ≈ −9.6 and −9.9 kN) lifts both contacts off at t = 0 in the Problem as in a
// run: the same events recorded, the same first phase (no contact), bitwise. Before, the
// Problem kept both contacts pulling, whose falling lift-off roots start negative and never fire.
TEST(Problem, PullingStartLiftsOffAtOnceAsInARun) {
  const Scene scene = ChapterSceneWith("{pose: assemble, coordinates: {alpha_deg: 30}}", "{time_s: 0.02}", "");
  for (const std::string form : {"ede", "mde", "dae", "dae-ggl"}) {
    SCOPED_TRACE(form);
    ExpectProblemFollowsSimulator(scene, form);
    const Problem p(scene, form);
    ASSERT_EQ(p.events_recorded().size(), 2u);
    for (const EventRecord& e : p.events_recorded()) {
      EXPECT_EQ(e.name.rfind("liftoff_", 0), 0u) << e.name;
      EXPECT_EQ(e.time, 0.0);
    }
    EXPECT_TRUE(p.phase_state().active.empty());
  }
}

// A state of the first phase away from its start: y0 advanced by a small explicit step.
std::vector<double> Perturbed(const Problem& p) {
  std::vector<double> y = p.y0();
  for (size_t i = 0; i < y.size(); ++i) y[i] += 1.0e-3 * p.yp0()[i];
  return y;
}

// A start the physics refuses is the scene's fault (problem.h: KNEEDYN_INPUT_ERROR covers
// "the scene file or its start"; kneedyn run exits 2 for it), not a solver error an
// integrator could retry. Here both contacts are one and the same pair: dependent rows.
TEST(Problem, AStartThePhysicsRefusesIsAnInputError) {
  Scene scene = ChapterScene();
  scene.model.contacts[1] = scene.model.contacts[0];
  for (const char* form : {"ede", "dae"}) {
    try {
      Problem problem(scene, form, 1e-8, 1e-10);
      ADD_FAILURE() << form << ": a start with dependent contact rows was accepted";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find("the scene's start is refused"), std::string::npos) << e.what();
    } catch (const std::exception& e) {
      ADD_FAILURE() << form << ": not an InputError: " << e.what();
    }
  }
}

// The physics refusing a state an outside solver hands in is a solver error (the integrator
// may shorten its step), as for Rhs: also where the DAE forms' Residual and Jacobian are
// handed contact coordinates outside the surfaces' charts (before: KNEEDYN_BAD_ARGUMENT).
// The ODE forms of the chapter scene cannot meet it: their sphere-on-plane contact is closed
// form, defined at every pose.
TEST(Problem, ContactCoordinatesOffTheChartsAreASolverErrorInTheDaeCalls) {
  const std::string scene = ScenesDir() + "/chapter_impact.yaml";
  for (const char* form : {"dae", "dae-ggl"}) {
    kneedyn_problem* h = nullptr;
    ASSERT_EQ(kneedyn_problem_create(scene.c_str(), form, 0.0, 0.0, &h), KNEEDYN_OK) << form;
    int n = 0;
    ASSERT_EQ(kneedyn_problem_size(h, &n), KNEEDYN_OK);
    std::vector<double> y(n), yp(n, 0.0), out(n), J(static_cast<size_t>(n) * n);
    ASSERT_EQ(kneedyn_problem_initial_values(h, y.data(), yp.data(), n), KNEEDYN_OK) << form;
    // The first contact coordinate (y[12], an angle of the regular chart) 3 rad on: outside
    // every chart's domain (|u| < 80°, |v| < 170°).
    y[12] += 3.0;
    EXPECT_EQ(kneedyn_problem_residual(h, 0.0, y.data(), yp.data(), n, out.data()), KNEEDYN_SOLVER_ERROR)
        << form << ": " << kneedyn_last_error();
    EXPECT_NE(std::string(kneedyn_last_error()).find("outside its domain"), std::string::npos) << kneedyn_last_error();
    EXPECT_EQ(kneedyn_problem_dae_jacobian(h, 0.0, y.data(), yp.data(), 1.0, n, J.data()), KNEEDYN_SOLVER_ERROR)
        << form << ": " << kneedyn_last_error();
    kneedyn_problem_destroy(h);
  }
}

TEST(Problem, EdeRhsEqualsHiddenConstraintSolve) {
  const Scene& scene = ChapterScene();
  Problem p(scene, "ede");
  const std::vector<double> y = Perturbed(p);
  const double t = p.t0() + 1.0e-3;
  std::vector<double> f(12), f_c(12);
  p.Rhs(t, y.data(), 12, f.data());
  const MechanicalState& s = p.phase_state();
  const ConstrainedAcceleration a = SolveConstrainedAcceleration(
      scene.model, t, Eigen::Map<const Vector6d>(y.data()), Eigen::Map<const Vector6d>(y.data() + 6), s.active, {},
      &s.ligament_branch);
  ExpectBitwise(f.data(), y.data() + 6, 6, "f(q part)");
  ExpectBitwise(f.data() + 6, a.qdd.data(), 6, "f(q̇ part)");
  // Through the C interface.
  kneedyn_problem* h = nullptr;
  ASSERT_EQ(kneedyn_problem_create((ScenesDir() + "/chapter_impact.yaml").c_str(), "ede", 0.0, 0.0, &h), KNEEDYN_OK)
      << kneedyn_last_error();
  ASSERT_EQ(kneedyn_problem_rhs(h, t, y.data(), 12, f_c.data()), KNEEDYN_OK) << kneedyn_last_error();
  ExpectBitwise(f_c.data(), f.data(), 12, "C f");
  std::vector<double> J(144), J_c(144), g(p.event_count()), g_c(p.event_count());
  p.Jacobian(t, y.data(), 12, J.data());
  ASSERT_EQ(kneedyn_problem_jacobian(h, t, y.data(), 12, J_c.data()), KNEEDYN_OK);
  ExpectBitwise(J_c.data(), J.data(), 144, "C df/dy");
  p.Events(t, y.data(), 12, g.data());
  ASSERT_EQ(kneedyn_problem_events(h, t, y.data(), 12, g_c.data(), p.event_count()), KNEEDYN_OK);
  ExpectBitwise(g_c.data(), g.data(), p.event_count(), "C events");
  // Lift-off events are the contact forces of the same solve.
  EXPECT_EQ(p.event_names()[0], std::string("liftoff_") + CompartmentName(scene.model.contacts[s.active[0]].compartment));
  EXPECT_EQ(g[0], a.normal_force[0]);
  // The exact ∂f/∂y: its q̇ rows are (0 I) exactly.
  for (int i = 0; i < 6; ++i) {
    for (int j = 0; j < 12; ++j) EXPECT_EQ(J[12 * i + j], j == 6 + i ? 1.0 : 0.0) << i << "," << j;
  }
  EXPECT_EQ(kneedyn_problem_destroy(h), KNEEDYN_OK);
}

// Central differences of f against the exact ∂f/∂y of ede (forward AD + the implicit
// function theorem), in the first phase (2 contacts) and after the lateral lift-off (1), to
// 1e-5 of each column's scale. Step 1e-8 (1 + |y_j|): as for the DAE residual, the ligament
// terms make the quotient converge only as O(h) (measured in the first phase: 4.0e-4, 4.0e-5,
// 4.0e-6 relative at h = 1e-6, 1e-7, 1e-8, then round-off, 3.7e-5 at 1e-9): a wrong
// Jacobian would stay off by a constant instead.
// mde likewise: its exact ∂f/∂y (the chain rule through the chart's elimination on ede's
// constrained-acceleration Jacobian) against central differences of its own f.
class OdeJacobian : public ::testing::TestWithParam<const char*> {};
INSTANTIATE_TEST_SUITE_P(Problem, OdeJacobian, ::testing::Values("ede", "mde"));

TEST_P(OdeJacobian, MatchesCentralDifferences) {
  const std::string form = GetParam();
  const Scene& scene = ChapterScene();
  SimulatorRun run(form, scene);
  for (size_t phase : {size_t{0}, size_t{1}}) {
    SCOPED_TRACE(phase);
    Problem p(scene, form);
    // To the phase after the lift-off: the simulator's event states handed over in turn.
    for (size_t e = 0; phase == 1 && p.phase_state().active.size() == 2; ++e) {
      ASSERT_LT(e, run.spy.event_states.size());
      std::vector<double> y, yp;
      FormValues(form, scene.model, run.spy.event_states[e], &y, &yp, p.free_coordinates());
      ASSERT_FALSE(p.Transition(run.spy.event_states[e].t, y.data(), nullptr, p.size(), run.spy.fired[e]));
    }
    const int n = p.size();
    const std::vector<double> y = Perturbed(p);
    const double t = p.phase_start_time() + 1.0e-3;
    std::vector<double> J(n * n);
    p.Jacobian(t, y.data(), n, J.data());
    double worst = 0.0;
    for (int j = 0; j < n; ++j) {
      std::vector<double> yh = y, fp(n), fm(n);
      const double h = 1e-8 * (1.0 + std::abs(y[j]));
      yh[j] = y[j] + h, p.Rhs(t, yh.data(), n, fp.data());
      yh[j] = y[j] - h, p.Rhs(t, yh.data(), n, fm.data());
      double scale = 1.0;
      for (int i = 0; i < n; ++i) scale = std::max(scale, std::abs(J[n * i + j]));
      for (int i = 0; i < n; ++i) {
        const double fd = (fp[i] - fm[i]) / (2 * h);
        worst = std::max(worst, std::abs(J[n * i + j] - fd) / scale);
        EXPECT_NEAR(J[n * i + j], fd, 1e-5 * scale) << p.component_names()[j] << " row " << i;
      }
    }
    std::printf("%s phase %zu (%zu contacts): max |J - FD| / column scale = %.2g\n", form.c_str(), phase,
                p.phase_state().active.size(), worst);
  }
}

// Exact ∂f/∂y beyond the sphere on a plane: ellipsoidal condyles on polynomial plateaus
// (anatomical_surfaces: κ's derivative needs the surfaces' third chart derivatives, through
// TimeDual over the Jet) and the patella (patellofemoral_impact: the tendon force through
// PatellarTendonForce's implicit-function lift). Independent check: central differences of
// f with a step ladder h = 10^-3 … 10^-9 (1 + |y_j|). Their error against the exact
// Jacobian is (h²/6) f‴ plus round-off ~ ε |f| / h: it falls 100-fold per decade of h until
// round-off takes over; a dropped or wrong term leaves a floor at its size instead. The state
// is 0.01 s into the run (RK4 on f itself): at t0 the velocities are held at zero and the
// ligaments sit at their reference lengths, where the published law's kink makes central
// differences converge only as O(h) (OdeJacobian above). Checked by editing terms out: κ's
// derivative dropped leaves a floor of 30 of the column scale, the ellipsoid's or the
// polynomial's third derivatives 5e-5 and 3e-5, mde's ∂q̇/∂s term 1e-5 and 5e-6.
struct LadderPoint {
  double h, error;  // relative step; max |J − FD| / column scale
};

std::vector<LadderPoint> CentralDifferenceLadder(const Problem& p, double t, const std::vector<double>& y,
                                                 const std::vector<double>& J) {
  const int n = p.size();
  std::vector<double> scale(n, 1.0);
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) scale[j] = std::max(scale[j], std::abs(J[n * i + j]));
  }
  std::vector<LadderPoint> ladder;
  for (int decade = 3; decade <= 9; ++decade) {
    const double h_rel = std::pow(10.0, -decade);
    double worst = 0.0;
    for (int j = 0; j < n; ++j) {
      std::vector<double> yp = y, ym = y, fp(n), fm(n);
      yp[j] = y[j] + h_rel * (1.0 + std::abs(y[j]));
      ym[j] = y[j] - h_rel * (1.0 + std::abs(y[j]));
      p.Rhs(t, yp.data(), n, fp.data());
      p.Rhs(t, ym.data(), n, fm.data());
      for (int i = 0; i < n; ++i) {
        worst = std::max(worst, std::abs(J[n * i + j] - (fp[i] - fm[i]) / (yp[j] - ym[j])) / scale[j]);
      }
    }
    ladder.push_back({h_rel, worst});
  }
  return ladder;
}

// y advanced by RK4 on the form's own f (steps of 20 µs, the C example's stable step).
std::vector<double> AdvancedState(const Problem& p, double duration, double* t) {
  const int n = p.size();
  std::vector<double> y = p.y0(), k1(n), k2(n), k3(n), k4(n), yt(n);
  const double dt = 2.0e-5;
  *t = p.t0();
  for (int step = 0; step * dt < duration - 1e-12; ++step, *t += dt) {
    p.Rhs(*t, y.data(), n, k1.data());
    for (int i = 0; i < n; ++i) yt[i] = y[i] + 0.5 * dt * k1[i];
    p.Rhs(*t + 0.5 * dt, yt.data(), n, k2.data());
    for (int i = 0; i < n; ++i) yt[i] = y[i] + 0.5 * dt * k2[i];
    p.Rhs(*t + 0.5 * dt, yt.data(), n, k3.data());
    for (int i = 0; i < n; ++i) yt[i] = y[i] + dt * k3[i];
    p.Rhs(*t + dt, yt.data(), n, k4.data());
    for (int i = 0; i < n; ++i) y[i] += dt / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
  }
  return y;
}

class GeneralSurfaceJacobian : public ::testing::TestWithParam<std::tuple<const char*, const char*>> {};
INSTANTIATE_TEST_SUITE_P(Problem, GeneralSurfaceJacobian,
                         ::testing::Combine(::testing::Values("anatomical_surfaces", "patellofemoral_impact"),
                                            ::testing::Values("ede", "mde")));

TEST_P(GeneralSurfaceJacobian, CentralDifferencesConvergeToItAsHSquared) {
  const std::string scene_name = std::get<0>(GetParam()), form = std::get<1>(GetParam());
  const std::string path = ScenesDir() + "/" + scene_name + ".yaml";
  const Scene scene = LoadScene(path);
  Problem p(scene, form);
  ASSERT_EQ(p.phase_state().active.size(), 2u);
  double t = 0.0;
  const std::vector<double> y = AdvancedState(p, 0.01, &t);
  const int n = p.size();
  std::vector<double> J(n * n), J_c(n * n);
  p.Jacobian(t, y.data(), n, J.data());
  const std::vector<LadderPoint> ladder = CentralDifferenceLadder(p, t, y, J);
  double best = ladder[0].error;
  for (const LadderPoint& l : ladder) best = std::min(best, l.error);
  std::printf("%s %s: max |J - FD| / column scale at h =", scene_name.c_str(), form.c_str());
  for (const LadderPoint& l : ladder) std::printf(" %.0e: %.1e,", l.h, l.error);
  std::printf("\n");
  // Round-off floor: f carries up to ~6e-14 relative noise from its Newton solves (contact
  // points; the patella's, warm-started from the last call; the error at h = 1e-7 is that
  // noise over h), so C h² + noise / h bottoms out at 2e-8 … 8e-8 of the column scale near
  // h = 1e-6 (measured 1.6e-8 … 7.3e-8); 3e-7 leaves a factor 4.
  EXPECT_LT(best, 3e-7);
  // Where truncation dominates (error ≥ 10 × the floor), each decade of h gains 100-fold
  // (O(h²)); 30 rejects O(h) (10-fold) with margin.
  int decades = 0;
  for (size_t k = 0; k + 1 < ladder.size(); ++k) {
    if (ladder[k + 1].error < 10.0 * best) break;
    EXPECT_GT(ladder[k].error / ladder[k + 1].error, 30.0) << "h = " << ladder[k].h;
    ++decades;
  }
  EXPECT_GE(decades, 2) << "the truncation regime must span two decades of h";
  // Bitwise the same through the C interface, with the same call history (the patella's
  // equilibrium is solved by Newton from the last solution: f depends on the calls before it
  // at round-off level).
  Problem fresh(scene, form);
  kneedyn_problem* h = nullptr;
  ASSERT_EQ(kneedyn_problem_create(path.c_str(), form.c_str(), 0.0, 0.0, &h), KNEEDYN_OK) << kneedyn_last_error();
  fresh.Jacobian(t, y.data(), n, J.data());
  ASSERT_EQ(kneedyn_problem_jacobian(h, t, y.data(), n, J_c.data()), KNEEDYN_OK) << kneedyn_last_error();
  ExpectBitwise(J_c.data(), J.data(), n * n, "C df/dy");
  std::vector<double> f(n), f_c(n);
  fresh.Rhs(t, y.data(), n, f.data());
  ASSERT_EQ(kneedyn_problem_rhs(h, t, y.data(), n, f_c.data()), KNEEDYN_OK) << kneedyn_last_error();
  ExpectBitwise(f_c.data(), f.data(), n, "C f");
  EXPECT_EQ(kneedyn_problem_destroy(h), KNEEDYN_OK);
}

// The mde form's f and events are the mde formulation's own right-hand side and root
// functions (its OdeProblem callbacks, started at the same phase start), bitwise, through
// Problem and the C interface; its chart leaves the contacts' translations out.
TEST(Problem, MdeRhsAndEventsEqualMdeFormulation) {
  const Scene& scene = ChapterScene();
  SimulatorRun run("mde", scene);
  Problem p(scene, "mde");
  ASSERT_EQ(p.phase_state().active.size(), 2u);
  ASSERT_EQ(p.size(), 8);  // 6 − 2 free coordinates and their rates
  EXPECT_EQ(p.free_coordinates(), (std::vector<int>{kY0, kAlpha, kBeta, kGamma}));
  std::unique_ptr<Formulation> mde = CreateFormulation("mde", scene, {});
  mde->Start(run.spy.starts[0], run.spy.start_events[0]);
  OdeProblem* ode = dynamic_cast<OdeProblem*>(mde.get());
  ASSERT_NE(ode, nullptr);
  const int n = p.size();
  const std::vector<double> y = Perturbed(p);
  const double t = p.t0() + 1.0e-3;
  std::vector<double> f(n), f_ref(n), f_c(n), J(n * n), J_c(n * n);
  p.Rhs(t, y.data(), n, f.data());
  ASSERT_TRUE(ode->Rhs(t, y.data(), f_ref.data()));
  ExpectBitwise(f.data(), f_ref.data(), n, "f");
  const int m = p.event_count();
  ASSERT_EQ(p.event_names().back(), Problem::kChartEvent);
  std::vector<double> g(m), g_ref(m - 1), g_c(m);
  p.Events(t, y.data(), n, g.data());
  ode->Roots(t, y.data(), g_ref.data());
  ExpectBitwise(g.data(), g_ref.data(), m - 1, "events");
  EXPECT_GT(g[m - 1], 0.0) << "the chart chosen at the start is the best one";
  kneedyn_problem* h = nullptr;
  ASSERT_EQ(kneedyn_problem_create((ScenesDir() + "/chapter_impact.yaml").c_str(), "mde", 0.0, 0.0, &h), KNEEDYN_OK)
      << kneedyn_last_error();
  int n_c = 0;
  ASSERT_EQ(kneedyn_problem_size(h, &n_c), KNEEDYN_OK);
  ASSERT_EQ(n_c, n);
  ASSERT_EQ(kneedyn_problem_rhs(h, t, y.data(), n, f_c.data()), KNEEDYN_OK) << kneedyn_last_error();
  ExpectBitwise(f_c.data(), f.data(), n, "C f");
  p.Jacobian(t, y.data(), n, J.data());
  ASSERT_EQ(kneedyn_problem_jacobian(h, t, y.data(), n, J_c.data()), KNEEDYN_OK);
  ExpectBitwise(J_c.data(), J.data(), n * n, "C df/dy");
  ASSERT_EQ(kneedyn_problem_events(h, t, y.data(), n, g_c.data(), m), KNEEDYN_OK);
  ExpectBitwise(g_c.data(), g.data(), m, "C events");
  // The coordinates y stands for: s itself, and the eliminated x0, z0 on both contacts.
  double q[6], qd[6];
  ASSERT_EQ(kneedyn_problem_coordinates(h, t, y.data(), nullptr, n, q, qd), KNEEDYN_OK);
  for (int j = 0; j < 4; ++j) EXPECT_EQ(q[p.free_coordinates()[j]], y[j]);
  const MechanicalState at = p.Coordinates(t, y.data(), nullptr, n);
  double gap = 1.0, rate = 1.0;
  MaxActiveConstraintResiduals(scene.model, at, &gap, &rate);
  EXPECT_LT(gap, 1e-15) << "the elimination puts both contacts on their surfaces";
  EXPECT_LT(rate, 1e-12);
  // The other form's calls and a chart switch with another event are refused.
  EXPECT_EQ(kneedyn_problem_residual(h, t, y.data(), y.data(), n, f_c.data()), KNEEDYN_BAD_ARGUMENT);
  const int both[2] = {0, m - 1};
  int ended = 0;
  EXPECT_EQ(kneedyn_problem_transition(h, t, y.data(), nullptr, n, both, 2, &ended), KNEEDYN_BAD_ARGUMENT);
  EXPECT_NE(std::string(kneedyn_last_error()).find("mde_chart"), std::string::npos) << kneedyn_last_error();
  // The chart switch alone: the same state in the best chart (here the same one), same size.
  const int chart = m - 1;
  ASSERT_EQ(kneedyn_problem_transition(h, t, y.data(), nullptr, n, &chart, 1, &ended), KNEEDYN_OK);
  EXPECT_EQ(ended, 0);
  std::vector<double> y_next(n);
  ASSERT_EQ(kneedyn_problem_initial_values(h, y_next.data(), nullptr, n), KNEEDYN_OK);
  ExpectBitwise(y_next.data(), y.data(), n, "y after the chart switch");
  EXPECT_EQ(kneedyn_problem_destroy(h), KNEEDYN_OK);
}

// The mde form on a surface pair without a closed form, along one contact phase of 1 s that
// flexes to 40.6 degrees and back (test_support::AnatomicalSinglePhaseScene): f must evaluate
// at every state of an accurate dae run of it, taken in time order as an outside solver would. Started from the phase start
// alone, the elimination's first Newton iterate fell off the medial cap from about 36 degrees on
// and f failed there; re-seeded at each evaluation (as the patella's equilibrium), it follows.
// Each f is also checked against the state: s̈ = the dae run's q̈ of the free coordinates.
TEST(Problem, MdeRhsFollowsALongPhaseOnGeneralSurfaces) {
  const Scene scene = test_support::AnatomicalSinglePhaseScene();
  RunSettings settings = test_support::SettingsAt("dae", 1e-10, 1e-12);
  const RunResult dae = RunScene(scene, settings);
  ASSERT_TRUE(dae.completed) << dae.failure;
  ASSERT_TRUE(dae.events.empty()) << "one phase";
  Problem p(scene, "mde");
  ASSERT_EQ(p.phase_state().active.size(), 2u);
  const std::vector<int> free = p.free_coordinates();
  const int n = p.size();
  int evaluated = 0;
  double max_flexion_deg = 0.0;
  for (const MechanicalState& state : dae.samples) {
    if (state.t <= p.t0()) continue;
    std::vector<double> y, yp, f(n);
    FormValues("mde", scene.model, state, &y, &yp, free);
    try {
      p.Rhs(state.t, y.data(), n, f.data());
    } catch (const std::exception& e) {
      ADD_FAILURE() << "t = " << state.t << " s, flexion " << state.q(kAlpha) * 180.0 / M_PI << " deg: " << e.what();
      break;
    }
    for (int j = 0; j < n / 2; ++j) {
      EXPECT_NEAR(f[n / 2 + j], yp[n / 2 + j], 1e-4 * (1.0 + std::abs(yp[n / 2 + j]))) << "t = " << state.t << " s, s̈[" << j << "]";
    }
    ++evaluated;
    max_flexion_deg = std::max(max_flexion_deg, state.q(kAlpha) * 180.0 / M_PI);
  }
  EXPECT_GT(evaluated, 150);
  EXPECT_GT(max_flexion_deg, 40.0) << "through the flexion where f had failed";
  // An evaluation re-seeds the elimination at its own point, so the same call again gives the
  // same f bitwise (the start pose is the answer at its own coordinates; a Newton step from it
  // had moved f by ~2e-14 relative).
  std::vector<double> y, yp, f1(n), f2(n);
  FormValues("mde", scene.model, dae.samples[dae.samples.size() / 2], &y, &yp, free);
  const double t = dae.samples[dae.samples.size() / 2].t;
  p.Rhs(t, y.data(), n, f1.data());
  p.Rhs(t, y.data(), n, f2.data());
  ExpectBitwise(f2.data(), f1.data(), n, "f at the same point twice");
}

TEST(Problem, DaeResidualAndJacobianEqualDaeSystem) {
  const Scene& scene = ChapterScene();
  kneedyn_problem* h = nullptr;
  for (const std::string form : {"dae", "dae-ggl"}) {
    SCOPED_TRACE(form);
    Problem p(scene, form);
    ASSERT_EQ(kneedyn_problem_create((ScenesDir() + "/chapter_impact.yaml").c_str(), form.c_str(), 0.0, 0.0, &h),
              KNEEDYN_OK) << kneedyn_last_error();
    const int n = p.size();
    const std::vector<double> y = Perturbed(p), yp = p.yp0();
    const double t = p.t0() + 1.0e-3, c = 37.5;
    DaeSystem system(scene.model, ContactForm::kChapter, ConstraintLevel::kVelocity, form == "dae-ggl");
    system.SetPhase(p.phase_state().active, p.phase_state().contact, p.phase_state().ligament_branch);
    ASSERT_EQ(system.size(), n);
    std::vector<double> F(n), F_ref(n), F_c(n), J(n * n), J_ref(n * n), J_c(n * n);
    p.Residual(t, y.data(), yp.data(), n, F.data());
    ASSERT_TRUE(system.Residual(t, y.data(), yp.data(), F_ref.data()));
    ExpectBitwise(F.data(), F_ref.data(), n, "F");
    ASSERT_EQ(kneedyn_problem_residual(h, t, y.data(), yp.data(), n, F_c.data()), KNEEDYN_OK);
    ExpectBitwise(F_c.data(), F_ref.data(), n, "C F");
    p.Jacobian(t, y.data(), yp.data(), c, n, J.data());
    ASSERT_TRUE(system.Jacobian(t, c, y.data(), yp.data(), J_ref.data()));  // column-major
    for (int i = 0; i < n; ++i) {
      for (int j = 0; j < n; ++j) ExpectBitwise(&J[n * i + j], &J_ref[n * j + i], 1, "J");
    }
    ASSERT_EQ(kneedyn_problem_dae_jacobian(h, t, y.data(), yp.data(), c, n, J_c.data()), KNEEDYN_OK);
    ExpectBitwise(J_c.data(), J.data(), n * n, "C J");
    // Central differences of F in y and ẏ: dF/dy + c dF/dẏ, to 1e-6 of the column scale.
    // Step 1e-9: the ligament terms make the difference quotient converge only as O(h)
    // (2e-5 relative at h = 1e-6, 2e-8 at 1e-9, measured on x0).
    for (int j = 0; j < n; ++j) {
      std::vector<double> yh = y, yph = yp, Fp(n), Fm(n), Gp(n), Gm(n);
      const double hy = 1e-9 * (1.0 + std::abs(y[j])), hp = 1e-9 * (1.0 + std::abs(yp[j]));
      yh[j] = y[j] + hy, p.Residual(t, yh.data(), yp.data(), n, Fp.data());
      yh[j] = y[j] - hy, p.Residual(t, yh.data(), yp.data(), n, Fm.data());
      yph[j] = yp[j] + hp, p.Residual(t, y.data(), yph.data(), n, Gp.data());
      yph[j] = yp[j] - hp, p.Residual(t, y.data(), yph.data(), n, Gm.data());
      double scale = 1.0;
      for (int i = 0; i < n; ++i) scale = std::max(scale, std::abs(J[n * i + j]));
      for (int i = 0; i < n; ++i) {
        const double fd = (Fp[i] - Fm[i]) / (2 * hy) + c * (Gp[i] - Gm[i]) / (2 * hp);
        EXPECT_NEAR(J[n * i + j], fd, 1e-6 * scale) << p.component_names()[j] << " row " << i;
      }
    }
    EXPECT_EQ(kneedyn_problem_destroy(h), KNEEDYN_OK);
  }
}

// The index of the phase's end event (flexion_<deg>) among its m events, or -1.
int EndEventIndex(const kneedyn_problem* h, int m) {
  for (int k = 0; k < m; ++k) {
    const char* name = nullptr;
    if (kneedyn_problem_event_name(h, k, &name) == KNEEDYN_OK && std::string(name).rfind("flexion_", 0) == 0) return k;
  }
  return -1;
}

TEST(Problem, BadCallsReturnErrorsWithMessages) {
  const std::string scene = ScenesDir() + "/chapter_impact.yaml";
  kneedyn_problem* h = nullptr;
  int n = 0;
  double y[64] = {}, f[64] = {}, J[64 * 64] = {};
  // Creation.
  EXPECT_EQ(kneedyn_problem_create(scene.c_str(), "rk4", 0.0, 0.0, &h), KNEEDYN_BAD_ARGUMENT);
  EXPECT_NE(std::string(kneedyn_last_error()).find("'rk4'"), std::string::npos) << kneedyn_last_error();
  EXPECT_EQ(h, nullptr);
  EXPECT_EQ(kneedyn_problem_create("/nonexistent.yaml", "ede", 0.0, 0.0, &h), KNEEDYN_INPUT_ERROR);
  EXPECT_NE(std::string(kneedyn_last_error()).find("nonexistent"), std::string::npos) << kneedyn_last_error();
  EXPECT_EQ(kneedyn_problem_create(nullptr, "ede", 0.0, 0.0, &h), KNEEDYN_BAD_ARGUMENT);
  // A tolerance that is not a number is refused, -inf too (it had passed as "<= 0: the
  // defaults"; Python refuses it as well).
  for (const double bad : {-std::numeric_limits<double>::infinity(), std::numeric_limits<double>::infinity(),
                           std::numeric_limits<double>::quiet_NaN()}) {
    EXPECT_EQ(kneedyn_problem_create(scene.c_str(), "ede", bad, 0.0, &h), KNEEDYN_BAD_ARGUMENT) << bad;
    EXPECT_EQ(kneedyn_problem_create(scene.c_str(), "ede", 0.0, bad, &h), KNEEDYN_BAD_ARGUMENT) << bad;
    EXPECT_NE(std::string(kneedyn_last_error()).find("must be finite"), std::string::npos) << kneedyn_last_error();
    EXPECT_EQ(h, nullptr);
  }
  // Tolerances past kneedyn run's ranges would open the re-contact threshold (it scales with
  // them) beyond any gap: refused as run refuses them.
  EXPECT_EQ(kneedyn_problem_create(scene.c_str(), "ede", 1e300, 0.0, &h), KNEEDYN_BAD_ARGUMENT);
  EXPECT_NE(std::string(kneedyn_last_error()).find("(0, 0.5]"), std::string::npos) << kneedyn_last_error();
  EXPECT_EQ(kneedyn_problem_create(scene.c_str(), "ede", 0.0, 0.02, &h), KNEEDYN_BAD_ARGUMENT);
  EXPECT_EQ(h, nullptr);
  EXPECT_EQ(kneedyn_problem_create(scene.c_str(), "ede", 0.0, 0.0, nullptr), KNEEDYN_BAD_ARGUMENT);
  // Bad handles: null, foreign, destroyed.
  EXPECT_EQ(kneedyn_problem_size(nullptr, &n), KNEEDYN_BAD_HANDLE);
  EXPECT_NE(std::string(kneedyn_last_error()).find("kneedyn_problem_size"), std::string::npos);
  EXPECT_EQ(kneedyn_problem_size(reinterpret_cast<kneedyn_problem*>(y), &n), KNEEDYN_BAD_HANDLE);
  ASSERT_EQ(kneedyn_problem_create(scene.c_str(), "ede", 0.0, 0.0, &h), KNEEDYN_OK);
  kneedyn_problem* dead = nullptr;
  ASSERT_EQ(kneedyn_problem_create(scene.c_str(), "dae", 0.0, 0.0, &dead), KNEEDYN_OK);
  ASSERT_EQ(kneedyn_problem_destroy(dead), KNEEDYN_OK);
  EXPECT_EQ(kneedyn_problem_rhs(dead, 0.0, y, 12, f), KNEEDYN_BAD_HANDLE);
  EXPECT_EQ(kneedyn_problem_destroy(dead), KNEEDYN_BAD_HANDLE);
  // A problem created next may occupy the destroyed one's memory; the old handle stays
  // refused and cannot reach or free the new problem.
  kneedyn_problem* reborn = nullptr;
  ASSERT_EQ(kneedyn_problem_create(scene.c_str(), "dae", 0.0, 0.0, &reborn), KNEEDYN_OK);
  EXPECT_NE(reborn, dead);
  EXPECT_EQ(kneedyn_problem_size(dead, &n), KNEEDYN_BAD_HANDLE);
  EXPECT_EQ(kneedyn_problem_destroy(dead), KNEEDYN_BAD_HANDLE);
  ASSERT_EQ(kneedyn_problem_size(reborn, &n), KNEEDYN_OK);
  EXPECT_EQ(n, 22);  // the dae form's first phase: 12 states, 10 multipliers and velocities of the constraints
  EXPECT_EQ(kneedyn_problem_destroy(reborn), KNEEDYN_OK);
  // Sizes, NaN, null arrays, the other form's calls.
  ASSERT_EQ(kneedyn_problem_initial_values(h, y, nullptr, 12), KNEEDYN_OK);
  EXPECT_EQ(kneedyn_problem_rhs(h, 0.0, y, 11, f), KNEEDYN_BAD_ARGUMENT);
  EXPECT_NE(std::string(kneedyn_last_error()).find("size 11"), std::string::npos) << kneedyn_last_error();
  EXPECT_EQ(kneedyn_problem_initial_values(h, y, nullptr, 13), KNEEDYN_BAD_ARGUMENT);
  EXPECT_EQ(kneedyn_problem_rhs(h, 0.0, nullptr, 12, f), KNEEDYN_BAD_ARGUMENT);
  EXPECT_EQ(kneedyn_problem_rhs(h, 0.0, y, 12, nullptr), KNEEDYN_BAD_ARGUMENT);
  double y_nan[12];
  std::memcpy(y_nan, y, sizeof y_nan);
  y_nan[4] = std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(kneedyn_problem_rhs(h, 0.0, y_nan, 12, f), KNEEDYN_BAD_ARGUMENT);
  EXPECT_NE(std::string(kneedyn_last_error()).find("y[4] = nan"), std::string::npos) << kneedyn_last_error();
  EXPECT_EQ(kneedyn_problem_jacobian(h, 0.0, y_nan, 12, J), KNEEDYN_BAD_ARGUMENT);
  // A finite state whose dynamics overflow (a flexion rate of 1e200 rad/s) gives no output.
  double y_huge[12];
  std::memcpy(y_huge, y, sizeof y_huge);
  y_huge[9] = 1e200;
  EXPECT_EQ(kneedyn_problem_rhs(h, 0.0, y_huge, 12, f), KNEEDYN_SOLVER_ERROR);
  EXPECT_NE(std::string(kneedyn_last_error()).find("every output is finite"), std::string::npos) << kneedyn_last_error();
  int m_huge = 0;
  ASSERT_EQ(kneedyn_problem_event_count(h, &m_huge), KNEEDYN_OK);
  EXPECT_EQ(kneedyn_problem_events(h, 0.0, y_huge, 12, f, m_huge), KNEEDYN_SOLVER_ERROR);
  EXPECT_NE(std::string(kneedyn_last_error()).find("g["), std::string::npos) << kneedyn_last_error();
  EXPECT_EQ(kneedyn_problem_residual(h, 0.0, y, y, 12, f), KNEEDYN_BAD_ARGUMENT);
  EXPECT_NE(std::string(kneedyn_last_error()).find("ODE"), std::string::npos) << kneedyn_last_error();
  EXPECT_EQ(kneedyn_problem_dae_jacobian(h, 0.0, y, y, 1.0, 12, J), KNEEDYN_BAD_ARGUMENT);
  int m = 0, ended = 0;
  ASSERT_EQ(kneedyn_problem_event_count(h, &m), KNEEDYN_OK);
  EXPECT_EQ(kneedyn_problem_events(h, 0.0, y, 12, f, m + 1), KNEEDYN_BAD_ARGUMENT);
  const char* name = nullptr;
  EXPECT_EQ(kneedyn_problem_event_name(h, m, &name), KNEEDYN_BAD_ARGUMENT);
  // Transitions: an event out of range; then the end event (the last), after which no
  // phase is open.
  int bad_event = m;
  EXPECT_EQ(kneedyn_problem_transition(h, 0.1, y, nullptr, 12, &bad_event, 1, &ended), KNEEDYN_BAD_ARGUMENT);
  EXPECT_NE(std::string(kneedyn_last_error()).find("event = "), std::string::npos) << kneedyn_last_error();
  const int end_event = EndEventIndex(h, m);
  ASSERT_GE(end_event, 0);
  ASSERT_EQ(kneedyn_problem_transition(h, 0.1, y, nullptr, 12, &end_event, 1, &ended), KNEEDYN_OK);
  EXPECT_EQ(ended, 1);
  EXPECT_EQ(kneedyn_problem_rhs(h, 0.1, y, 12, f), KNEEDYN_BAD_ARGUMENT);
  EXPECT_NE(std::string(kneedyn_last_error()).find("ended"), std::string::npos) << kneedyn_last_error();
  EXPECT_EQ(kneedyn_problem_transition(h, 0.1, y, nullptr, 12, &end_event, 1, &ended), KNEEDYN_BAD_ARGUMENT);
  EXPECT_EQ(kneedyn_problem_destroy(h), KNEEDYN_OK);
  EXPECT_EQ(kneedyn_problem_destroy(nullptr), KNEEDYN_OK);
}

// Every state-taking call refuses a time that is not finite, naming it; yp's faults name yp.
TEST(Problem, NonFiniteTimesAndBadYpAreRefusedNamingThem) {
  const Scene& scene = ChapterScene();
  const double inf = std::numeric_limits<double>::infinity(), nan = std::numeric_limits<double>::quiet_NaN();
  Problem ode(scene, "ede");
  const std::vector<double> y = ode.y0();
  std::vector<double> out(12 * 12);
  for (double t : {nan, inf, -inf}) {
    SCOPED_TRACE(t);
    auto expect_time_refused = [&](const std::function<void()>& call) {
      try {
        call();
        ADD_FAILURE() << "accepted t = " << t;
      } catch (const ProblemError& e) {
        EXPECT_NE(std::string(e.what()).find("t = "), std::string::npos) << e.what();
      }
    };
    expect_time_refused([&] { ode.Rhs(t, y.data(), 12, out.data()); });
    expect_time_refused([&] { ode.Jacobian(t, y.data(), 12, out.data()); });
    expect_time_refused([&] { ode.Events(t, y.data(), 12, out.data()); });
    expect_time_refused([&] { ode.Coordinates(t, y.data(), nullptr, 12); });
    expect_time_refused([&] { ode.Transition(t, y.data(), nullptr, 12, {0}); });
  }
  Problem dae(scene, "dae");
  const int n = dae.size();
  std::vector<double> yd = dae.y0(), ypd = dae.yp0(), F(n * n);
  EXPECT_THROW(dae.Residual(nan, yd.data(), ypd.data(), n, F.data()), ProblemError);
  EXPECT_THROW(dae.Jacobian(inf, yd.data(), ypd.data(), 1.0, n, F.data()), ProblemError);
  ypd[4] = nan;
  try {
    dae.Residual(0.0, yd.data(), ypd.data(), n, F.data());
    ADD_FAILURE() << "accepted yp[4] = nan";
  } catch (const ProblemError& e) {
    EXPECT_NE(std::string(e.what()).find("yp[4] = nan"), std::string::npos) << e.what();
  }
  try {
    dae.Residual(0.0, yd.data(), nullptr, n, F.data());
    ADD_FAILURE() << "accepted a null yp";
  } catch (const ProblemError& e) {
    EXPECT_NE(std::string(e.what()).find("yp is a null array"), std::string::npos) << e.what();
  }
}

// A transition's events are distinct, and its time lies between the phase start and t_end.
TEST(Problem, TransitionRefusesRepeatedEventsAndTimesOutsideThePhase) {
  const Scene& scene = ChapterScene();
  Problem p(scene, "ede");
  const std::vector<double> y = p.y0();
  auto message = [&](double t, const std::vector<int>& events) {
    try {
      p.Transition(t, y.data(), nullptr, 12, events);
    } catch (const ProblemError& e) {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  EXPECT_NE(message(0.01, {0, 0}).find("event = 0 is given twice"), std::string::npos) << message(0.01, {0, 0});
  EXPECT_NE(message(p.t0() - 5.0, {0}).find("must lie in phase 0"), std::string::npos) << message(p.t0() - 5.0, {0});
  EXPECT_NE(message(p.t_end() * 2.0, {0}).find("must lie in phase 0"), std::string::npos);
  EXPECT_NE(message(1e300, {0}).find("t = 1e+300"), std::string::npos) << message(1e300, {0});
  EXPECT_EQ(p.phase(), 0);
  EXPECT_TRUE(p.events_recorded().empty());
}

// A transition that throws part-way (here the next phase's consistent initialization, from
// a state 1e3 off the constraints, after the event state was taken and, for a lift-off, the
// event recorded) leaves the problem as it was: phase, start, values, events and records;
// the same problem then transitions exactly as a fresh one does.
TEST(Problem, FailedTransitionLeavesThePhaseAsItWas) {
  const Scene& scene = ChapterScene();
  for (const std::string form : {"ede", "mde", "dae", "dae-ggl"}) {
    SCOPED_TRACE(form);
    const bool dae = form.rfind("dae", 0) == 0;
    Problem fresh(scene, form);
    const std::vector<double> y0 = fresh.y0(), yp0 = fresh.yp0();
    const std::vector<std::string> names = fresh.event_names();
    const int liftoff = static_cast<int>(std::find(names.begin(), names.end(), "liftoff_lateral") - names.begin());
    ASSERT_LT(liftoff, static_cast<int>(names.size()));
    std::vector<double> far = y0;
    for (size_t i = 0; i < far.size(); ++i) far[i] += (i % 2 == 0 ? 1.0e3 : -1.0e3);
    Problem expected(scene, form);  // the transition from the start state, for comparison
    expected.Transition(0.05, y0.data(), dae ? yp0.data() : nullptr, expected.size(), {liftoff});
    int failed = 0;
    for (int k = 0; k < static_cast<int>(names.size()); ++k) {
      Problem p(scene, form);
      try {
        p.Transition(0.05, far.data(), dae ? yp0.data() : nullptr, p.size(), {k});
        continue;  // some events take even this state (the end; mde's lift-offs, whose chart absorbs it)
      } catch (const std::exception&) {
        ++failed;
      }
      ASSERT_EQ(p.phase(), 0) << names[k];
      EXPECT_EQ(p.phase_start_time(), p.t0()) << names[k];
      EXPECT_EQ(p.y0(), y0) << names[k];
      EXPECT_EQ(p.yp0(), yp0) << names[k];
      EXPECT_EQ(p.event_names(), names) << names[k];
      EXPECT_TRUE(p.events_recorded().empty()) << names[k];
      p.Transition(0.05, y0.data(), dae ? yp0.data() : nullptr, p.size(), {liftoff});
      EXPECT_EQ(p.phase(), 1) << names[k];
      EXPECT_EQ(p.y0(), expected.y0()) << names[k];
      EXPECT_EQ(p.yp0(), expected.yp0()) << names[k];
      EXPECT_EQ(p.event_names(), expected.event_names()) << names[k];
      EXPECT_EQ(p.events_recorded().size(), expected.events_recorded().size()) << names[k];
    }
    // The twelve kinks fail in every form; the lift-offs too in ede and the DAE forms.
    EXPECT_GE(failed, form == "mde" ? 12 : 14);
  }
}

// The C interface: n_events is checked before events[] is read; the last failure's message
// outlives later successes; after the end what belongs to a phase is refused and the end
// reason and the records answer.
TEST(Problem, CInterfaceChecksCountsKeepsMessagesAndAnswersAfterTheEnd) {
  const std::string scene = ScenesDir() + "/chapter_impact.yaml";
  kneedyn_problem* h = nullptr;
  ASSERT_EQ(kneedyn_problem_create(scene.c_str(), "ede", 0.0, 0.0, &h), KNEEDYN_OK) << kneedyn_last_error();
  double y[12], f[12], ids[12];
  ASSERT_EQ(kneedyn_problem_initial_values(h, y, nullptr, 12), KNEEDYN_OK);
  int m = 0, ended = 0, n = 0, count = -1;
  ASSERT_EQ(kneedyn_problem_event_count(h, &m), KNEEDYN_OK);
  int one_event[1] = {0};  // a count past the array would make the library read past it
  EXPECT_EQ(kneedyn_problem_transition(h, 0.01, y, nullptr, 12, one_event, INT_MAX, &ended), KNEEDYN_BAD_ARGUMENT);
  EXPECT_NE(std::string(kneedyn_last_error()).find("n_events = 2147483647"), std::string::npos) << kneedyn_last_error();
  EXPECT_EQ(kneedyn_problem_transition(h, 0.01, y, nullptr, 12, one_event, m + 1, &ended), KNEEDYN_BAD_ARGUMENT);
  const std::string failure = kneedyn_last_error();
  ASSERT_EQ(kneedyn_problem_rhs(h, 0.0, y, 12, f), KNEEDYN_OK);
  EXPECT_EQ(std::string(kneedyn_last_error()), failure) << "a success cleared the last failure's message";
  const char* reason = nullptr;
  ASSERT_EQ(kneedyn_problem_end_reason(h, &reason), KNEEDYN_OK);
  EXPECT_STREQ(reason, "");
  ASSERT_EQ(kneedyn_problem_event_record_count(h, &count), KNEEDYN_OK);
  EXPECT_EQ(count, 0);
  const char* name = nullptr;
  EXPECT_EQ(kneedyn_problem_event_record(h, 0, &name, nullptr, nullptr), KNEEDYN_BAD_ARGUMENT);
  const int end_event = EndEventIndex(h, m);
  ASSERT_GE(end_event, 0);
  ASSERT_EQ(kneedyn_problem_transition(h, 0.1, y, nullptr, 12, &end_event, 1, &ended), KNEEDYN_OK);
  ASSERT_EQ(ended, 1);
  EXPECT_EQ(kneedyn_problem_size(h, &n), KNEEDYN_BAD_ARGUMENT);
  EXPECT_NE(std::string(kneedyn_last_error()).find("ended"), std::string::npos) << kneedyn_last_error();
  EXPECT_EQ(kneedyn_problem_differential_ids(h, ids, 12), KNEEDYN_BAD_ARGUMENT);
  EXPECT_EQ(kneedyn_problem_event_count(h, &m), KNEEDYN_BAD_ARGUMENT);
  EXPECT_EQ(kneedyn_problem_event_name(h, 0, &name), KNEEDYN_BAD_ARGUMENT);
  ASSERT_EQ(kneedyn_problem_end_reason(h, &reason), KNEEDYN_OK);
  EXPECT_EQ(std::string(reason).rfind("flexion_", 0), 0u) << reason;
  ASSERT_EQ(kneedyn_problem_event_record_count(h, &count), KNEEDYN_OK);
  ASSERT_EQ(count, 1);
  double t_event = 0.0, flexion = 0.0;
  ASSERT_EQ(kneedyn_problem_event_record(h, 0, &name, &t_event, &flexion), KNEEDYN_OK);
  EXPECT_STREQ(name, reason);
  EXPECT_EQ(t_event, 0.1);
  EXPECT_EQ(flexion, y[3]);  // the flexion angle of the state handed over (rad)
  EXPECT_EQ(kneedyn_problem_destroy(h), KNEEDYN_OK);
}

// One handle, two threads, each evaluating f at its own states: every value equals the
// serial one (the handle's workspace is shared, so the calls must take turns).
TEST(Problem, OneHandleFromTwoThreadsGivesTheSerialValues) {
  const std::string scene = ScenesDir() + "/chapter_impact.yaml";
  kneedyn_problem* h = nullptr;
  ASSERT_EQ(kneedyn_problem_create(scene.c_str(), "ede", 0.0, 0.0, &h), KNEEDYN_OK) << kneedyn_last_error();
  std::vector<double> y0(12);
  ASSERT_EQ(kneedyn_problem_initial_values(h, y0.data(), nullptr, 12), KNEEDYN_OK);
  constexpr int kCalls = 100000;  // the unguarded handle gave wrong f in 5 of 5 such runs
  std::vector<std::vector<double>> state(2, y0), serial(2, std::vector<double>(12));
  state[1][9] += 0.5;  // another angular rate (rad/s): another acceleration
  for (int w = 0; w < 2; ++w) ASSERT_EQ(kneedyn_problem_rhs(h, 0.01, state[w].data(), 12, serial[w].data()), KNEEDYN_OK);
  ASSERT_NE(serial[0], serial[1]);
  int mismatches[2] = {0, 0}, errors[2] = {0, 0};
  auto worker = [&](int w) {
    std::vector<double> f(12);
    for (int i = 0; i < kCalls; ++i) {
      if (kneedyn_problem_rhs(h, 0.01, state[w].data(), 12, f.data()) != KNEEDYN_OK) ++errors[w];
      if (f != serial[w]) ++mismatches[w];
    }
  };
  std::thread a(worker, 0), b(worker, 1);
  a.join();
  b.join();
  EXPECT_EQ(errors[0] + errors[1], 0);
  EXPECT_EQ(mismatches[0] + mismatches[1], 0);
  EXPECT_EQ(kneedyn_problem_destroy(h), KNEEDYN_OK);
}

}  // namespace
}  // namespace kneedyn
