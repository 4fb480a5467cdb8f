// Ceres's Levenberg–Marquardt, the fallback of the consistent initialization
// (solver/consistent_init.cpp), behind a C interface in the plugin
// <libdir>/kneedyn/kneedyn_ceres_fallback.so (solver/ceres_fallback_plugin.cpp).
// Why a plugin: libceres brings glog, SuiteSparse, LAPACK/ATLAS, libgfortran, libgomp and
// libmetis, which the dynamic loader would map and relocate in every process, while a run
// of the chapter scenes takes the direct Newton path and never calls Ceres
// (benchmarks/performance-log.md, "Start-up, loading and output"). The plugin is loaded the first
// time a level falls back.
#pragma once

extern "C" {

// r (num_residuals) and, if J is not null, the row-major num_residuals × num_unknowns
// Jacobian at x. Returns 1 on success, 0 when the residual cannot be evaluated there.
typedef int (*KneedynResidualFn)(void* user, const double* x, double* r, double* J);

struct KneedynLeastSquares {
  int num_unknowns;
  int num_residuals;
  KneedynResidualFn evaluate;
  void* user;
  int max_iterations;  // Ceres's max_num_iterations
};

// Minimizes ½|r(x)|² from x (overwritten) with Ceres (dense QR, tolerances of
// solver/consistent_init.cpp); *iterations = Ceres's iteration count. Returns 1 when
// Ceres ran (converged or not: the caller checks the residual), 0 on an internal error.
typedef int (*KneedynCeresSolveFn)(const KneedynLeastSquares* problem, double* x, int* iterations);

#define KNEEDYN_CERES_FALLBACK_ENTRY "kneedyn_ceres_fallback_solve_v1"

}  // extern "C"

namespace kneedyn {

// The plugin's solve function, loaded once per process; SolverError naming the paths tried
// when the plugin is missing or not of this kneedyn.
KneedynCeresSolveFn CeresFallback();

}  // namespace kneedyn
