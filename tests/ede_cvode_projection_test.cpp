// `ede --stabilization cvode-projection`: CVODE's own projection
// (CVodeSetProjFn) with cvode-bdf, beside kneedyn's project-and-restart `projection`.
//
// Validates, on the chapter scene at rtol 1e-8: the position constraint stays at the
// projection tolerance (< 1e-13 m; without stabilization it drifts beyond 1e-10 m at the
// same settings); the events agree with `dae` at rtol 1e-10 (1e-6 s); CVODE keeps its
// order and step history (accepted steps within 1.5× of the unstabilized run, whereas
// restarting BDF at order 1 after every projection multiplies them by ~250, measured);
// integrators without CVODE's projection are refused naming the option; the
// project-and-restart loop counts the Jacobian of every restart.
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

// kneedyn's project-and-restart loop (`projection`) re-initializes CVODE after each
// projection (CVodeReInit). CVODE's linear solver interface evaluates the Jacobian afresh at
// the first step after that (a new Jacobian at step 0), here by difference quotients over
// the 12 EDE states: so every restart adds one Jacobian and at least 12 right-hand sides to
// the totals. (They were once counted as 0: CVodeReInit zeroes the interface's counters only
// at the next CVode call, after the driver had read its baseline.)
TEST(EdeCvodeProjection, RestartLoopCountsTheJacobianOfEveryRestart) {
  Scene scene = ChapterScene();
  scene.end.time = 0.02;  // s: some hundred projections
  RunSettings s;
  s.formulation = "ede";
  s.options.integrator = IntegratorKind::kCvodeBdf;
  s.options.stabilization = Stabilization::kProjection;
  const RunResult r = RunScene(scene, s);
  ASSERT_TRUE(r.completed) << r.failure;
  std::printf("ede cvode-bdf projection to 0.02 s: %ld projections, %ld steps, %ld Jacobians, %ld right-hand sides\n",
              r.stats.projections, r.stats.steps, r.stats.jacobian_evaluations, r.stats.residual_evaluations);
  ASSERT_GT(r.stats.projections, 50);
  // Each projection but one at the end is followed by a restart (a Reset, or a new phase).
  EXPECT_GE(r.stats.jacobian_evaluations, r.stats.projections - 1);
  EXPECT_GE(r.stats.residual_evaluations, r.stats.steps + 12 * r.stats.jacobian_evaluations);
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
