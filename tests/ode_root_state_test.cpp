// Tests of a root's state in OdeIntegrator (formulations/internal/ode_integrator.hpp): with
// verner65 and fehlberg78 it is the method's own discrete solution at the root, not ARKODE's
// Hermite interpolant (StepToRoot).
//
// Validates, on the oscillator x'' = −x, x(0) = 1 (root g = x, decreasing, at t = π/2 s), at
// a loose tolerance (long steps, where the interpolant and the steps differ by 3e-6 to 5e-5):
//   - the root's (t, y) equals the state a second integrator reaches by stepping to that t
//     with no root function, from the same first step (ARKODE's stop time shortens the
//     crossing step to end there): the same steps, so the same discrete solution to
//     round-off (1e-12);
//   - g = x vanishes at the returned state to round-off: the root is the discrete
//     solution's, refined on its steps;
//   - the root time is π/2 to the method's accuracy (independent check, 1e-5 s);
//   - Evolve and Reset after such a root refuse (the solver is left at a trial step).
// dopri5 keeps the interpolant's state (measured not to pay; benchmarks/performance-log.md, "Event
// states of the high-order Runge–Kutta methods"): its root state differs from its steps'.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "formulations/internal/ode_integrator.hpp"
#include "solver/error.hpp"

namespace kneedyn {
namespace {

constexpr double kPi = 3.14159265358979323846;

class Oscillator : public OdeProblem {
 public:
  bool Rhs(double, const double* y, double* ydot) override {
    ydot[0] = y[1];
    ydot[1] = -y[0];
    return true;
  }
  void Roots(double, const double* y, double* g) override { g[0] = y[0]; }
};

OdeOptions Options(IntegratorKind kind) {
  OdeOptions o;
  o.integrator = kind;
  o.control.rtol = 1e-5;
  o.control.atol = 1e-7;
  return o;
}

struct RootRun {
  double t = 0.0;
  VectorXd y;
};

VectorXd Initial() {
  VectorXd y(2);
  y << 1.0, 0.0;
  return y;
}

// Starts the oscillator's phase with a first step that does not depend on the output time
// (ARKODE's own first-step estimate does): a quarter of the last step of a phase run before
// to t = 0.1 s, the same in every run here.
void StartWithFixedFirstStep(OdeIntegrator* integrator, Oscillator* problem, const std::vector<int>& directions) {
  VectorXd y = Initial();
  double t = 0.0;
  std::vector<int> roots;
  integrator->Start(problem, 0.0, y, directions);
  ASSERT_FALSE(integrator->Evolve(0.1, false, &t, &y, &roots));
  integrator->Start(problem, 0.0, Initial(), directions);
}

RootRun RunToRoot(OdeIntegrator* integrator, Oscillator* problem) {
  RootRun r;
  r.y = Initial();
  StartWithFixedFirstStep(integrator, problem, {-1});
  std::vector<int> roots;
  EXPECT_TRUE(integrator->Evolve(3.0, false, &r.t, &r.y, &roots));
  EXPECT_EQ(roots, std::vector<int>({-1}));
  return r;
}

// The state of the same method's steps at time t, without root functions.
VectorXd SteppedTo(IntegratorKind kind, double t) {
  Oscillator problem;
  OdeIntegrator integrator(Options(kind), "ode_root_state_test");
  VectorXd y = Initial();
  StartWithFixedFirstStep(&integrator, &problem, {});
  double reached = 0.0;
  std::vector<int> roots;
  EXPECT_FALSE(integrator.Evolve(t, false, &reached, &y, &roots));
  EXPECT_EQ(reached, t);
  return y;
}

class SteppedRootState : public ::testing::TestWithParam<IntegratorKind> {};

TEST_P(SteppedRootState, IsTheDiscreteSolutionAtTheRoot) {
  Oscillator problem;
  OdeIntegrator integrator(Options(GetParam()), "ode_root_state_test");
  ASSERT_TRUE(integrator.steps_to_roots());
  const RootRun root = RunToRoot(&integrator, &problem);
  const VectorXd stepped = SteppedTo(GetParam(), root.t);
  EXPECT_NEAR(root.y(0), stepped(0), 1e-12);
  EXPECT_NEAR(root.y(1), stepped(1), 1e-12);
  EXPECT_LE(std::abs(root.y(0)), 1e-12);  // x = 0 on the discrete solution
  EXPECT_NEAR(root.t, kPi / 2.0, 1e-5);
  EXPECT_NEAR(root.y(1), -1.0, 1e-5);
  // The trial steps and root evaluations are counted.
  EXPECT_GT(integrator.stats().root_evaluations, 0);
}

TEST_P(SteppedRootState, EvolveAndResetRefuseUntilStart) {
  Oscillator problem;
  OdeIntegrator integrator(Options(GetParam()), "ode_root_state_test");
  RootRun root = RunToRoot(&integrator, &problem);
  std::vector<int> roots;
  EXPECT_THROW(integrator.Evolve(3.0, false, &root.t, &root.y, &roots), SolverError);
  EXPECT_THROW(integrator.Reset(root.t, root.y), SolverError);
  // A new phase from the root runs on.
  integrator.Start(&problem, root.t, root.y, {});
  EXPECT_FALSE(integrator.Evolve(3.0, false, &root.t, &root.y, &roots));
  EXPECT_NEAR(root.y(0), std::cos(3.0), 1e-4);
}

INSTANTIATE_TEST_SUITE_P(HighOrder, SteppedRootState,
                         ::testing::Values(IntegratorKind::kVerner65, IntegratorKind::kFehlberg78));

// The control: dopri5's root state is the interpolant's, which is not its steps' state at
// the root time (so the comparison above can tell the two apart).
TEST(InterpolatedRootState, Dopri5KeepsTheInterpolant) {
  Oscillator problem;
  OdeIntegrator integrator(Options(IntegratorKind::kDopri5), "ode_root_state_test");
  ASSERT_FALSE(integrator.steps_to_roots());
  const RootRun root = RunToRoot(&integrator, &problem);
  const VectorXd stepped = SteppedTo(IntegratorKind::kDopri5, root.t);
  EXPECT_GT(std::abs(root.y(1) - stepped(1)) + std::abs(root.y(0) - stepped(0)), 1e-11);
  EXPECT_NEAR(root.t, kPi / 2.0, 1e-5);
}

}  // namespace
}  // namespace kneedyn
