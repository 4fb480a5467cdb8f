// The SUNDIALS IDA set-up and tear-down of one contact phase, shared by the IDA formulations
// (dae.cpp, dae_ggl.cpp) instead of each writing the same sequence of calls.
#pragma once

#include <idas/idas.h>
#include <sunlinsol/sunlinsol_dense.h>
#include <sunmatrix/sunmatrix_dense.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
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
    return StrCat(ReturnFlagText(IDAGetReturnFlagName, flag), " at t = ", t_cur, " s with step h = ", h, " s");
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
             LinearSolverKind linear_solver = LinearSolverKind::kStructured) {
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
    check(IDASVtolerances(mem, options.rtol, atol), "IDASVtolerances");
    check(IDASetId(mem, id), "IDASetId");
    check(IDASetStopTime(mem, end_time), "IDASetStopTime");
    const double h0 = last_step > 0.0 ? 0.25 * last_step
                                      : std::clamp(1e-4 * std::sqrt(options.rtol / 1e-6), 1e-8, 1e-3);
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
