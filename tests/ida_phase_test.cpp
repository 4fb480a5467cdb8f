// Tests of IdaPhase (formulations/internal/ida_phase.hpp), the IDA set-up of one phase.
//
// Validates: a phase started on the last phase's IDA objects (IDAReInit, the path every
// restart of the IDA formulations takes when the size is unchanged) runs exactly as one
// started on new objects (IDACreate/IDAInit) with the same first step: the same y bit for bit,
// the same counters (its own, not the previous phase's: steps, residuals, Jacobians, setups,
// Newton iterations, failures, root evaluations) and the same root located. On y' = −λ∘y
// (λ = 1, 2, 3 1/s) with two root functions, one crossed in each phase. Does not validate:
// the knee's phases (bytecmp of whole runs, benchmarks/performance-log.md "Phases re-initialized").
// SolveToStopTime: a stop time a sliver (1e-9 of a step) past a run of equal steps is
// reached by steps of at least a quarter of that step, where IDA_NORMAL with IDASetStopTime
// alone takes the sliver as a step; y there is exp(−λ t).
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <vector>

#include "formulations/internal/ida_phase.hpp"
#include "formulations/internal/sundials_util.hpp"

namespace kneedyn {
namespace {

constexpr int kN = 3;
constexpr double kLambda[kN] = {1.0, 2.0, 3.0};  // 1/s

int Residual(double, N_Vector yy, N_Vector yp, N_Vector rr, void*) {
  for (int i = 0; i < kN; ++i) NvData(rr)[i] = NvData(yp)[i] + kLambda[i] * NvData(yy)[i];
  return 0;
}

int Jacobian(double, double cj, N_Vector, N_Vector, N_Vector, SUNMatrix J, void*, N_Vector, N_Vector, N_Vector) {
  for (int i = 0; i < kN; ++i) SM_ELEMENT_D(J, i, i) = cj + kLambda[i];
  return 0;
}

// y0 = 0.5 at t = ln 2 s (first phase), y0 = 0.2 at t = ln 5 s (second phase).
int Roots(double, N_Vector yy, N_Vector, double* g, void*) {
  g[0] = NvData(yy)[0] - 0.5;
  g[1] = NvData(yy)[0] - 0.2;
  return 0;
}

struct PhaseResult {
  std::vector<double> y;
  std::vector<double> root_times;  // s
  SolverStats stats;
};

// One phase from (t0, y0) to t_end on `phase` (re-initialized when it holds objects of kN).
PhaseResult RunPhase(SundialsContext& ctx, SundialsMessages* messages, IdaPhase* phase, double t0,
                     const std::vector<double>& y0, double t_end) {
  phase->Reserve(ctx, kN);
  N_Vector atol = NewSerialVector(kN, ctx);
  N_Vector id = NewSerialVector(kN, ctx);
  for (int i = 0; i < kN; ++i) {
    NvData(phase->y)[i] = y0[i];
    NvData(phase->yp)[i] = -kLambda[i] * y0[i];
    NvData(atol)[i] = 1e-12;
    NvData(id)[i] = 1.0;
  }
  StepControl control;
  control.rtol = 1e-9;
  phase->Start(ctx, kN, &Residual, &Jacobian, &Roots, nullptr, t0, atol, id, control, t_end, {}, "IdaPhaseTest",
               messages, {0, 0}, LinearSolverKind::kDense);
  N_VDestroy(atol);
  N_VDestroy(id);
  PhaseResult result;
  double t = t0;
  while (t < t_end) {
    const int flag = IDASolve(phase->mem, t_end, &t, phase->y, phase->yp, IDA_NORMAL);
    EXPECT_GE(flag, 0) << IDAGetReturnFlagName(flag);
    if (flag < 0) break;
    if (flag == IDA_ROOT_RETURN) result.root_times.push_back(t);
  }
  result.y.assign(NvData(phase->y), NvData(phase->y) + kN);
  phase->EndPhase(&result.stats, /*watches_roots=*/true);
  return result;
}

TEST(IdaPhase, ReinitializedPhaseRunsAsANewOne) {
  SundialsContext ctx;
  SundialsMessages messages;
  IdaPhase reused;
  const PhaseResult first = RunPhase(ctx, &messages, &reused, 0.0, {1.0, 1.0, 1.0}, 1.0);
  ASSERT_EQ(first.root_times.size(), 1u);
  EXPECT_NEAR(first.root_times[0], std::log(2.0), 1e-7);
  const double last_step = reused.last_step;  // s: the next phase's first step is a quarter of it
  ASSERT_GT(last_step, 0.0);
  void* const first_mem = reused.mem;
  const PhaseResult again = RunPhase(ctx, &messages, &reused, 1.0, first.y, 2.0);
  EXPECT_EQ(reused.mem, first_mem) << "the same size: the IDA memory is re-initialized, not rebuilt";

  IdaPhase fresh;
  fresh.last_step = last_step;
  const PhaseResult anew = RunPhase(ctx, &messages, &fresh, 1.0, first.y, 2.0);
  ASSERT_EQ(again.root_times.size(), 1u);
  ASSERT_EQ(anew.root_times.size(), 1u);
  EXPECT_NEAR(anew.root_times[0], std::log(5.0), 1e-7);
  EXPECT_EQ(std::memcmp(&again.root_times[0], &anew.root_times[0], sizeof(double)), 0);
  for (int i = 0; i < kN; ++i) {
    EXPECT_EQ(std::memcmp(&again.y[i], &anew.y[i], sizeof(double)), 0) << "y[" << i << "] " << again.y[i] << " vs " << anew.y[i];
  }
  const SolverStats& a = again.stats;
  const SolverStats& b = anew.stats;
  EXPECT_GT(b.steps, 0);
  EXPECT_GT(b.jacobian_evaluations, 0);
  EXPECT_EQ(a.steps, b.steps);
  EXPECT_EQ(a.residual_evaluations, b.residual_evaluations);
  EXPECT_EQ(a.jacobian_evaluations, b.jacobian_evaluations);
  EXPECT_EQ(a.linear_solver_setups, b.linear_solver_setups);
  EXPECT_EQ(a.nonlinear_iterations, b.nonlinear_iterations);
  EXPECT_EQ(a.error_test_failures, b.error_test_failures);
  EXPECT_EQ(a.convergence_failures, b.convergence_failures);
  EXPECT_EQ(a.root_evaluations, b.root_evaluations);
  SolverStats counted_already;  // EndPhase added both phases' counters; Free returns the objects
  reused.Free(&counted_already, true);
  fresh.Free(&counted_already, true);
  EXPECT_EQ(counted_already.steps, 0);
}

// A phase on y' = −λ∘y from y = 1 at t = 0, steps capped at h (the local error at rtol
// 1e-3 is far below tolerance, so IDA's steps grow to the cap and stay there).
void StartCapped(SundialsContext& ctx, SundialsMessages* messages, IdaPhase* phase, double h) {
  phase->Reserve(ctx, kN);
  N_Vector atol = NewSerialVector(kN, ctx);
  N_Vector id = NewSerialVector(kN, ctx);
  for (int i = 0; i < kN; ++i) {
    NvData(phase->y)[i] = 1.0;
    NvData(phase->yp)[i] = -kLambda[i];
    NvData(atol)[i] = 1e-8;
    NvData(id)[i] = 1.0;
  }
  StepControl control;
  control.rtol = 1e-3;
  control.max_step = h;
  phase->Start(ctx, kN, &Residual, &Jacobian, nullptr, nullptr, 0.0, atol, id, control, 1.0, {}, "IdaPhaseTest",
               messages, {}, LinearSolverKind::kDense);
  N_VDestroy(atol);
  N_VDestroy(id);
}

// Steps until IDA's next step is the cap h (s, to round-off); then the stop time 1e-9 h
// past three more.
double StopTimeASliverPastThreeSteps(IdaPhase* phase, double h) {
  double t = 0.0, next = 0.0;
  for (int i = 0; i < 100 && !(next > (1.0 - 1e-12) * h); ++i) {
    EXPECT_EQ(IDASolve(phase->mem, 1.0, &t, phase->y, phase->yp, IDA_ONE_STEP), IDA_SUCCESS);
    IDAGetCurrentStep(phase->mem, &next);
  }
  EXPECT_GT(next, (1.0 - 1e-12) * h) << "the steps did not reach the cap";
  return t + 3.0 * next + 1e-9 * h;
}

TEST(IdaPhase, SolveToStopTimeTakesNoSliverOfAStep) {
  constexpr double kH = 1e-3;  // s
  SundialsContext ctx;
  SundialsMessages messages;
  IdaPhase plain, phase;
  StartCapped(ctx, &messages, &plain, kH);
  StartCapped(ctx, &messages, &phase, kH);
  const double t_stop = StopTimeASliverPastThreeSteps(&plain, kH);
  ASSERT_EQ(StopTimeASliverPastThreeSteps(&phase, kH), t_stop) << "the two phases run alike";
  double t = 0.0, last = 0.0;
  // What IDA does alone: three steps of h, then one of ~1e-12 s.
  ASSERT_EQ(IDASetStopTime(plain.mem, t_stop), IDA_SUCCESS);
  ASSERT_GE(IDASolve(plain.mem, t_stop, &t, plain.y, plain.yp, IDA_NORMAL), 0);  // IDA_SUCCESS: tout = tstop
  ASSERT_EQ(t, t_stop);
  IDAGetLastStep(plain.mem, &last);
  EXPECT_LT(last, 1e-6 * kH) << "IDA no longer takes the sliver: SolveToStopTime's case is gone";
  long plain_steps = 0, steps = 0;
  IDAGetNumSteps(plain.mem, &plain_steps);
  // SolveToStopTime: the third step split in two equal ones, none below h/4.
  long before = 0;
  IDAGetNumSteps(phase.mem, &before);
  ASSERT_EQ(phase.SolveToStopTime(t_stop, &t), IDA_TSTOP_RETURN);
  EXPECT_EQ(t, t_stop);
  IDAGetLastStep(phase.mem, &last);
  EXPECT_GT(last, 0.25 * kH);
  IDAGetNumSteps(phase.mem, &steps);
  EXPECT_EQ(steps - before, 4);  // h, h, h/2, h/2
  EXPECT_EQ(steps, plain_steps);
  for (int i = 0; i < kN; ++i) {
    const double exact = std::exp(-kLambda[i] * t_stop);
    EXPECT_NEAR(NvData(phase.y)[i], exact, 1e-3 * exact) << i;  // rtol
  }
  SolverStats stats;
  plain.Free(&stats, false);
  phase.Free(&stats, false);
}

}  // namespace
}  // namespace kneedyn
