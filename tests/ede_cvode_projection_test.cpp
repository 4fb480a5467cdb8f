// `ede --stabilization cvode-projection`: CVODE's own projection
// (CVodeSetProjFn) with cvode-bdf, beside kneedyn's project-and-restart `projection`.
//
// Validates, on the chapter scene at rtol 1e-8: the position constraint stays at the
// projection tolerance (< 1e-13 m; without stabilization it drifts beyond 1e-10 m at the
// same settings); the events agree with `dae` at rtol 1e-10 (1e-6 s); CVODE keeps its
// order and step history (accepted steps within 1.5× of the unstabilized run, whereas
// restarting BDF at order 1 after every projection multiplies them by ~250, measured);
// integrators without CVODE's projection are refused naming the option, and the
// project-and-restart `projection` with a multistep method (it restarts at order 1 after
// every projection, ~40x the steps) naming cvode-projection; a restart's Jacobian is counted.
// Does not validate: which projection is cheaper at equal accuracy (work-precision sweep).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <string>

#include "formulations/run.hpp"
#include "solver/error.hpp"
#include "tests/test_support.hpp"

namespace kneedyn {
namespace {

using test_support::ChapterScene;

RunResult RunEde(const std::string& stabilization, double rtol) {
  RunSettings s;
  s.formulation = "ede";
  s.options.integrator = IntegratorKind::kCvodeBdf;
  s.options.stabilization = ParsedOptionValue<Stabilization>(stabilization);
  s.options.rtol = rtol;
  s.options.atol = 1e-2 * rtol;
  return RunScene(ChapterScene(), s);
}

TEST(EdeCvodeProjection, HoldsConstraintsKeepsStepHistoryAndFindsEvents) {
  const RunResult none = RunEde("none", 1e-8);
  const RunResult proj = RunEde("cvode-projection", 1e-8);
  ASSERT_TRUE(none.completed && proj.completed) << none.failure << proj.failure;
  RunSettings ref_settings;
  ref_settings.formulation = "dae";
  ref_settings.options.rtol = 1e-10;
  ref_settings.options.atol = 1e-12;
  const RunResult dae = RunScene(ChapterScene(), ref_settings);
  ASSERT_TRUE(dae.completed) << dae.failure;
  std::printf("ede cvode-bdf rtol 1e-8: max |gap| none %.3e m, cvode-projection %.3e m; steps %ld vs %ld\n",
              none.max_position_residual, proj.max_position_residual, none.stats.steps, proj.stats.steps);
  EXPECT_GT(none.max_position_residual, 1e-10);
  EXPECT_LT(proj.max_position_residual, 1e-13);
  EXPECT_LT(proj.stats.steps, 1.5 * none.stats.steps);
  ASSERT_EQ(proj.events.size(), dae.events.size());
  for (size_t i = 0; i < dae.events.size(); ++i) {
    EXPECT_EQ(proj.events[i].name, dae.events[i].name);
    EXPECT_NEAR(proj.events[i].time, dae.events[i].time, 1e-6) << dae.events[i].name;
  }
}

// Every restart of a phase (a ligament kink, a lift-off) re-initializes CVODE (CVodeReInit),
// whose linear solver interface then evaluates the Jacobian afresh at its first step, here
// by difference quotients over the 12 EDE states: so every restart adds one Jacobian and at
// least 12 right-hand sides to the totals. (They were once counted as 0: CVodeReInit zeroes
// the interface's counters only at the next CVode call, after the driver had read its
// baseline.)
TEST(EdeCvodeProjection, RestartsCountTheirJacobians) {
  RunSettings s;
  s.formulation = "ede";
  s.options.integrator = IntegratorKind::kCvodeBdf;
  const RunResult r = RunScene(ChapterScene(), s);
  ASSERT_TRUE(r.completed) << r.failure;
  std::printf("ede cvode-bdf: %ld restarts, %ld steps, %ld Jacobians, %ld right-hand sides\n", r.stats.restarts,
              r.stats.steps, r.stats.jacobian_evaluations, r.stats.residual_evaluations);
  ASSERT_GT(r.stats.restarts, 5);
  EXPECT_GE(r.stats.jacobian_evaluations, r.stats.restarts);
  EXPECT_GE(r.stats.residual_evaluations, r.stats.steps + 12 * r.stats.jacobian_evaluations);
}

// The project-and-restart loop with a multistep method: refused, pointing to CVODE's own
// projection.
TEST(EdeCvodeProjection, RestartLoopRefusedWithMultistepMethods) {
  for (const char* integrator : {"cvode-bdf", "cvode-adams"}) {
    FormulationOptions o;
    o.integrator = ParsedOptionValue<IntegratorKind>(integrator);
    o.stabilization = Stabilization::kProjection;
    try {
      CreateFormulation("ede", ChapterScene(), o);
      ADD_FAILURE() << integrator << ": no InputError";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find("--stabilization cvode-projection"), std::string::npos) << e.what();
    }
  }
}

TEST(EdeCvodeProjection, RefusedWithoutCvodeBdf) {
  for (const char* integrator : {"dopri5", "cvode-adams", "rk4"}) {
    FormulationOptions o;
    o.integrator = ParsedOptionValue<IntegratorKind>(integrator);
    o.stabilization = Stabilization::kCvodeProjection;
    if (std::string(integrator) == "rk4") o.step = 1e-3;
    try {
      CreateFormulation("ede", ChapterScene(), o);
      ADD_FAILURE() << integrator << ": no InputError";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find("cvode-projection"), std::string::npos) << e.what();
    }
  }
  FormulationOptions mde;
  mde.stabilization = Stabilization::kCvodeProjection;
  EXPECT_THROW(CreateFormulation("mde", ChapterScene(), mde), InputError);
}

}  // namespace
}  // namespace kneedyn
