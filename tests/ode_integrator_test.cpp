// Tests of dopri5 in OdeIntegrator (formulations/internal/ode_integrator.hpp): it runs in
// ARKODE's ERKStep, whose first stage is the previous step's last stage (Dormand–Prince is
// first same as last: the last row of A is b and c = 1).
//
// On the oscillator x'' = −x, x(0) = 1 (exact solution cos t), counted by the problem itself:
//   - six right-hand sides per attempted step, not seven (ARKStep 6.4 evaluates the first
//     stage again), plus a few for the first step's estimate;
//   - the last stage is evaluated at exactly the step's end (t_n+1, y_n+1), bitwise: the root
//     functions at the step's end find that point among the right-hand side's (what lets
//     ede's and mde's caches serve them without a new constrained solve);
//   - the solution is cos t to the tolerance's order at t = 20 s (independent of the stepper),
//     and agrees with verner65's (ARKStep) at a tight tolerance.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <vector>

#include "formulations/internal/ode_integrator.hpp"

namespace kneedyn {
namespace {

// The oscillator, recording the points (t, y) of its right-hand sides and counting the
// root-function calls that fall on one of them.
class CountingOscillator : public OdeProblem {
 public:
  bool Rhs(double t, const double* y, double* ydot) override {
    ydot[0] = y[1];
    ydot[1] = -y[0];
    ++rhs_calls;
    last_t = t, last_y[0] = y[0], last_y[1] = y[1];
    return true;
  }
  void Roots(double t, const double* y, double* g) override {
    g[0] = y[0] + 2.0;  // never zero (|x| <= 1): only the calls are of interest
    ++root_calls;
    if (t == last_t && std::memcmp(y, last_y, sizeof last_y) == 0) ++root_calls_at_last_rhs_point;
  }
  long rhs_calls = 0, root_calls = 0, root_calls_at_last_rhs_point = 0;
  double last_t = -1.0, last_y[2] = {0.0, 0.0};
};

OdeOptions Options(IntegratorKind kind, double rtol) {
  OdeOptions o;
  o.integrator = kind;
  o.control.rtol = rtol;
  o.control.atol = rtol * 1e-2;
  return o;
}

VectorXd Initial() {
  VectorXd y(2);
  y << 1.0, 0.0;
  return y;
}

// Integrates to t_end in one call (stop time t_end); returns y(t_end).
VectorXd RunTo(OdeIntegrator* integrator, CountingOscillator* problem, double t_end,
              const std::vector<int>& directions) {
  VectorXd y = Initial();
  double t = 0.0;
  std::vector<int> roots;
  integrator->Start(problem, 0.0, y, directions);
  EXPECT_FALSE(integrator->Evolve(t_end, false, &t, &y, &roots));
  EXPECT_EQ(t, t_end);
  return y;
}

TEST(Dopri5, SixRightHandSidesPerAttemptedStep) {
  OdeIntegrator integrator(Options(IntegratorKind::kDopri5, 1e-8), "test");
  CountingOscillator problem;
  RunTo(&integrator, &problem, 20.0, {});
  const SolverStats s = integrator.stats();
  const long attempts = s.steps + s.error_test_failures;
  ASSERT_GT(s.steps, 100);
  EXPECT_EQ(s.residual_evaluations, problem.rhs_calls);  // the counter is the calls
  // Six per attempt; the rest is the first step's estimate and the first stage at t = 0.
  EXPECT_GE(problem.rhs_calls, 6 * attempts);
  EXPECT_LE(problem.rhs_calls, 6 * attempts + 4) << attempts << " attempted steps";
}

TEST(Dopri5, LastStageIsTheStepEnd) {
  OdeIntegrator integrator(Options(IntegratorKind::kDopri5, 1e-8), "test");
  CountingOscillator problem;
  RunTo(&integrator, &problem, 20.0, {-1});
  const SolverStats s = integrator.stats();
  // ARKODE checks the roots once at the start and once at each step's end; every step's
  // end is the point of the right-hand side evaluated just before it (its last stage).
  EXPECT_EQ(problem.root_calls, s.steps + 1);
  EXPECT_EQ(problem.root_calls_at_last_rhs_point, s.steps);
}

TEST(Dopri5, SolutionIsTheOscillators) {
  OdeIntegrator dopri5(Options(IntegratorKind::kDopri5, 1e-10), "test");
  OdeIntegrator verner65(Options(IntegratorKind::kVerner65, 1e-10), "test");
  CountingOscillator a, b;
  const VectorXd y = RunTo(&dopri5, &a, 20.0, {});
  const VectorXd z = RunTo(&verner65, &b, 20.0, {});
  // Global error over ~3 periods: a few hundred times the tolerance at most.
  EXPECT_NEAR(y(0), std::cos(20.0), 1e-7);
  EXPECT_NEAR(y(1), -std::sin(20.0), 1e-7);
  EXPECT_NEAR(y(0), z(0), 1e-7);
  EXPECT_NEAR(y(1), z(1), 1e-7);
}

}  // namespace
}  // namespace kneedyn
