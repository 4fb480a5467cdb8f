// IDA's own counters as a SolverStats (the solvers' own counter names), shared by the IDA formulations
// (dae.cpp, dae_ggl.cpp) instead of each reading the same nine getters.
#pragma once

#include <idas/idas.h>

#include "formulations/formulation.hpp"

namespace kneedyn {

// Counters of the IDA instance `ida_mem` since its IDAInit; root evaluations only when the
// phase watches roots (IDAGetNumGEvals fails without IDARootInit).
inline SolverStats IdaStatistics(void* ida_mem, bool watches_roots) {
  SolverStats s;
  long v = 0;
  IDAGetNumSteps(ida_mem, &v); s.steps = v;
  IDAGetNumResEvals(ida_mem, &v); s.residual_evaluations = v;
  IDAGetNumJacEvals(ida_mem, &v); s.jacobian_evaluations = v;
  IDAGetNumLinSolvSetups(ida_mem, &v); s.linear_solver_setups = v;
  IDAGetNumNonlinSolvIters(ida_mem, &v); s.nonlinear_iterations = v;
  IDAGetNumErrTestFails(ida_mem, &v); s.error_test_failures = v;
  IDAGetNumNonlinSolvConvFails(ida_mem, &v); s.convergence_failures = v;
  if (watches_roots) { IDAGetNumGEvals(ida_mem, &v); s.root_evaluations = v; }
  return s;
}

}  // namespace kneedyn
