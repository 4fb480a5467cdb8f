// The SUNDIALS IDA set-up and tear-down of one contact phase, shared by the IDA formulations
// (dae.cpp, dae_ggl.cpp) instead of each writing the same sequence of calls.
#pragma once

#include <idas/idas.h>
#include <sunlinsol/sunlinsol_dense.h>
#include <sunmatrix/sunmatrix_dense.h>

#include <algorithm>
#include <cfloat>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <string>
#include <vector>

#include "formulations/formulation.hpp"
#include "formulations/internal/ida_statistics.hpp"
#include "formulations/internal/kinematic_block_solver.hpp"
#include "formulations/internal/sundials_util.hpp"

namespace kneedyn {

// The IDA objects of one phase. EndPhase() adds their counters to `accumulated` and keeps
// the last step for the next phase's first step; the objects stay, and the next Start()
// re-initializes them when the next phase has the same size (Reserve). Free() returns them.
struct IdaPhase {
  void* mem = nullptr;
  N_Vector y = nullptr, yp = nullptr;
  SUNMatrix A = nullptr;
  SUNLinearSolver LS = nullptr;
  int n = 0;                // size of y, ẏ, A and LS
  bool counted = true;      // the phase's counters are in `accumulated` (EndPhase)
  double last_step = 0.0;  // s: last step of the previous phase, the restart's first step
  long max_steps = 0;      // --max-steps: the phase's step budget (Start's options.max_steps)

  // y, ẏ of `size` unknowns for the next Start: the last phase's when it had that size (its
  // IDA memory is then re-initialized; IDAReInit cannot change the size), else new ones.
  void Reserve(SUNContext ctx, int size) {
    if (y != nullptr && size == n) return;
    Release();
    y = NewSerialVector(size, ctx);
    yp = NewSerialVector(size, ctx);
    n = size;
  }

  void EndPhase(SolverStats* accumulated, bool watches_roots) {
    if (mem == nullptr || counted) return;
    *accumulated += IdaStatistics(mem, watches_roots);
    IDAGetLastStep(mem, &last_step);
    counted = true;
  }

  void Free(SolverStats* accumulated, bool watches_roots) {
    EndPhase(accumulated, watches_roots);
    Release();
  }

  // What IDASolve's failure `flag` was and where: "<FLAG_NAME> at t = … s with step h = … s"
  // (the message text both IDA drivers, dae.cpp and the IDAS sensitivities, put after their
  // function name).
  std::string SolveFailure(int flag) const {
    double h = 0.0, t_cur = 0.0;
    IDAGetCurrentStep(mem, &h);
    IDAGetCurrentTime(mem, &t_cur);
    std::string text = ReturnFlagText(IDAGetReturnFlagName, flag);
    if (flag == IDA_TOO_MUCH_WORK) text = StepBudgetFailure(max_steps, text);
    return StrCat(text, " at t = ", t_cur, " s with step h = ", h, " s");
  }

  // Steps left of the phase's budget (StepBudgetFailure, sundials_util.hpp). IDA's step
  // counter starts at 0 with each phase (IDAInit, IDAReInit).
  long StepsLeft() const {
    long steps = 0;
    IDAGetNumSteps(mem, &steps);
    return max_steps - steps;
  }

  // IDASolve to t_out (IDA_NORMAL: interpolated there) with what the phase's budget has left;
  // IDA_TOO_MUCH_WORK when t_out needs a step and none is left. Returns IDASolve's flag,
  // *t_reached its time.
  int Solve(double t_out, double* t_reached) {
    long steps = 0;
    double t_current = 0.0;  // s: the end of IDA's last step
    IDAGetNumSteps(mem, &steps);
    IDAGetCurrentTime(mem, &t_current);
    const long limit = PerCallStepLimit(max_steps, steps, t_out, t_current);
    if (limit == 0) return IDA_TOO_MUCH_WORK;
    IDASetMaxNumSteps(mem, limit);
    return IDASolve(mem, t_out, t_reached, y, yp, IDA_NORMAL);
  }

  // After y, yp are filled: IDACreate … IDARootInit for the phase, or IDAReInit of the last
  // phase's objects when Reserve kept them (the same state as new ones: counters, step
  // history, the linear solver's interface and the root functions are set up afresh). The
  // unknowns marked 1 in `id` are differential, the others algebraic and excluded from the
  // error test (IDASetSuppressAlg: index-2 multipliers); per-component tolerances (rtol,
  // atol); stop at `end_time`. First step: a quarter of the previous phase's last step on
  // restarts, else 1e-4 s · sqrt(rtol / 1e-6) (BDF1 local error ∝ h²; IDA's own estimate,
  // ~1e-11 s at rtol 1e-10, is so small that the O(ε/h²) round-off of the index-2 forces
  // defeats the Newton test), which IDA's error test then adjusts. `owner` names the
  // formulation in errors. `extra_root_directions`: root functions `roots` evaluates after
  // the events' (the IDAS sensitivities' peak conditions dv/dt = 0), with their directions.
  // `linear_solver`: the Newton systems' solver on the dense matrix the Jacobian callback
  // fills (structured: q eliminated through the rows F1–F6 first,
  // kinematic_block_solver.hpp; the unknowns must start with q, u and the rows with F1–F6);
  // one kind for all phases of a run.
  void Start(SUNContext ctx, int size, IDAResFn residual, IDALsJacFn jacobian, IDARootFn roots,
             void* user, double t0, N_Vector atol, N_Vector id, const StepControl& options,
             double end_time, const std::vector<EventSpec>& events, const char* owner,
             SundialsMessages* messages, const std::vector<int>& extra_root_directions = {},
             LinearSolverKind linear_solver = LinearSolverKind::kStructured,
             double max_first_step = std::numeric_limits<double>::infinity()) {
    auto check = [&](int flag, const char* call) {
      CheckSundials(flag, call, owner, IDAGetReturnFlagName, messages);
    };
    if (y == nullptr || size != n) Throw<SolverError>(owner, "IdaPhase::Start: y, yp not reserved for ", size, " unknowns");
    if (mem == nullptr) {
      mem = IDACreate(ctx);
      if (mem == nullptr) Throw<SolverError>(owner, "IDACreate failed");
      check(IDASetErrHandlerFn(mem, &SundialsMessages::Handler, messages), "IDASetErrHandlerFn");
      check(IDAInit(mem, residual, t0, y, yp), "IDAInit");
      check(IDASetUserData(mem, user), "IDASetUserData");
      check(IDASetSuppressAlg(mem, SUNTRUE), "IDASetSuppressAlg");
      check(IDASetMaxNumSteps(mem, options.max_steps), "IDASetMaxNumSteps");
      if (options.max_step > 0.0) check(IDASetMaxStep(mem, options.max_step), "IDASetMaxStep");
      A = SUNDenseMatrix(n, n, ctx);
      LS = linear_solver == LinearSolverKind::kStructured ? NewKinematicBlockSolver(n, ctx) : SUNLinSol_Dense(y, A, ctx);
      if (A == nullptr || LS == nullptr) Throw<SolverError>(owner, "IDA's matrix or linear solver of size ", n, " not allocated");
    } else {
      check(IDAReInit(mem, t0, y, yp), "IDAReInit");
      check(IDARootInit(mem, 0, nullptr), "IDARootInit");  // the root functions' state afresh
    }
    counted = false;
    max_steps = options.max_steps;
    check(IDASVtolerances(mem, options.rtol, atol), "IDASVtolerances");
    check(IDASetId(mem, id), "IDASetId");
    check(IDASetStopTime(mem, end_time), "IDASetStopTime");
    // max_first_step: a pulse still to come is resolved (PulseResolvingStep, formulation.hpp).
    const double h0 = std::min(max_first_step, last_step > 0.0 ? 0.25 * last_step
                                                               : std::clamp(1e-4 * std::sqrt(options.rtol / 1e-6), 1e-8, 1e-3));
    check(IDASetInitStep(mem, h0), "IDASetInitStep");
    // Attached again on a re-initialization: a new interface, its counters at zero.
    check(IDASetLinearSolver(mem, LS, A), "IDASetLinearSolver");
    check(IDASetJacFn(mem, jacobian), "IDASetJacFn");
    if (!events.empty() || !extra_root_directions.empty()) {
      std::vector<int> dir = RootDirections(events);
      dir.insert(dir.end(), extra_root_directions.begin(), extra_root_directions.end());
      check(IDARootInit(mem, static_cast<int>(dir.size()), roots), "IDARootInit");
      check(IDASetRootDirection(mem, dir.data()), "IDASetRootDirection");
      check(IDASetNoInactiveRootWarn(mem), "IDASetNoInactiveRootWarn");
    }
  }

  // A remaining step shorter than this fraction of IDA's next step is a sliver (SolveToStopTime).
  static constexpr double kSliverFraction = 1.0e-4;

  // IDASolve to the stop time t_stop (s) ending on a step there, not interpolating to it (the
  // GGL forms' outputs, dae_ggl.cpp). Returns IDASolve's flag: IDA_TSTOP_RETURN (IDA_SUCCESS
  // from the budget's last step) with y, ẏ at t_stop, IDA_ROOT_RETURN, or a failure (< 0);
  // *t_reached is the time returned. At most the steps left of the phase's budget (StepsLeft).
  // Why not IDA_NORMAL with IDASetStopTime alone: IDA cuts only a step that would pass the
  // stop time, so a step ending just short of it leaves a remainder of any length. Runs of
  // equal steps drift off the output grid by round-off (one_ligament.yaml: 8 steps of 6.25e-4 s
  // ended 3.0e-14 s before t = 0.02 s), and on a 3e-14 s step the index-2 unknowns N, μ carry
  // round-off ∝ 1/h² (dae_ggl.cpp's header): N_medial = −5e5 N fired a false lift-off, and the
  // restart's first step, a quarter of that one, failed to converge. So IDA steps one at a time
  // (IDA_ONE_STEP, the same steps as IDA_NORMAL), and a step that would end less than
  // kSliverFraction of itself short of the stop time is replaced by two equal steps to it (a
  // stop time halfway first). Round-off drift is ~1e-10 of a step; the shortest remainder
  // steps on the shipped scenes are ~8e-4 of the step before and are left alone.
  int SolveToStopTime(double t_stop, double* t_reached) {
    double target = t_stop;  // t_stop, or the halfway stop time of a split
    int flag = IDASetStopTime(mem, target);
    while (flag >= 0) {
      if (StepsLeft() <= 1) {
        // The budget's last step in IDA_NORMAL, so that running out fails as IDA's own
        // (IDA_TOO_MUCH_WORK, "mxstep steps taken before reaching tout").
        if (target != t_stop) flag = IDASetStopTime(mem, target = t_stop);
        if (flag >= 0) flag = Solve(t_stop, t_reached);
        break;
      }
      long steps = 0;
      double tn = 0.0, h = 0.0;
      IDAGetNumSteps(mem, &steps);
      IDAGetCurrentTime(mem, &tn);
      IDAGetCurrentStep(mem, &h);  // the next step IDA tries (already cut to a stop time it would pass)
      // IDA snaps to the stop time within 100 ε (|t| + |h'|), h' ≥ h / 2 its step after this one.
      const double remainder = target - (tn + h);
      if (steps > 0 && remainder > 100.0 * DBL_EPSILON * (std::abs(target) + 0.5 * std::abs(h)) &&
          remainder < kSliverFraction * std::abs(h)) {
        flag = IDASetStopTime(mem, target = tn + 0.5 * (target - tn));
        if (flag < 0) break;
      }
      flag = IDASolve(mem, target, t_reached, y, yp, IDA_ONE_STEP);
      if (flag == IDA_TSTOP_RETURN && target != t_stop) {
        flag = IDASetStopTime(mem, target = t_stop);
      } else if (flag != IDA_SUCCESS) {
        break;
      }
    }
    return flag;
  }

 private:
  void Release() {
    if (mem != nullptr) IDAFree(&mem);
    mem = nullptr;
    if (LS) { SUNLinSolFree(LS); LS = nullptr; }
    if (A) { SUNMatDestroy(A); A = nullptr; }
    if (y) { N_VDestroy(y); y = nullptr; }
    if (yp) { N_VDestroy(yp); yp = nullptr; }
    n = 0;
  }
};

}  // namespace kneedyn
