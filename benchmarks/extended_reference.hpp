// Extended-precision reference solutions (benchmarks/README.md, "Reference solutions"):
// the knee integrated in a wider scalar — float128 (float128_scalar.hpp, 113-bit mantissa,
// ε = 1.9e-34; the stored references) or long double (x87, 64-bit mantissa, ε = 1.1e-19) —
// through the same templated physics as every formulation, by implicit Gauss–Legendre collocation
// (gauss_legendre.hpp), as the stepper of the one hybrid Simulator (formulations/simulator.hpp:
// consistent initialization, samples, lift-off and re-contact transitions, ligament-branch
// restarts are the simulator's, as in every run).
//
// The stepper integrates y = (q, q̇) with q̈ from the hidden constraint φ̈ = 0
// (SolveConstrainedAccelerationTpl<T>, no stabilization): at the step sizes used the local
// error is below ε_T, so the constraints drift by round-off only (the run's max |φ| is
// recorded). Steps of at most `step` end exactly at output times, at event roots and at the
// ligaments' slack lengths (the law is only C¹ there: a step across it would lose the
// method's order; a slack crossing is no event, the step just ends there). Event roots
// (EvaluateEventsTpl) are located by the Illinois variant of regula falsi on the time,
// each trial an exact collocation step from the step start, to a bracket of a few ε_T.
//
// Between phases the simulator hands over a double MechanicalState (its transition ran in
// double); the stepper keeps its long double state when that state equals its own rounded
// to double within 1e-12 relative (lift-off, ligament kink: the transition leaves q, q̇
// unchanged and the double projection only rounds), and starts from the double state
// otherwise (an impact changed q̇), counted in `restarts_from_double`.
//
// The Solution's values are computed from the long double state and rounded once (the
// conversions of metrics.hpp: mm, deg, valgus = β − 90°); the double observables would lose
// digits to cancellation (valgus near β = 90°, ligament elongation L − L0).
// T wider than double: sphere-on-plane tibio-femoral contacts only (the general contact solve
// runs in double); the patella's equilibrium is the double solve refined in T
// (solver/patella_extended.hpp) on surfaces evaluated in T (solver/surface_wide.hpp).
#pragma once

#include <string>

#include "benchmarks/metrics.hpp"
#include "formulations/run.hpp"

namespace kneedyn {
namespace bench {

struct ExtendedReferenceSettings {
  int stages = 6;                 // Gauss–Legendre stages s (order 2s)
  double step = 2.5e-4;           // s, largest step
  double output_interval = kDefaultComparisonInterval;  // s, the simulator's samples
};

struct ExtendedReferenceRun {
  RunResult result;    // the simulator's record (double samples)
  Solution solution;   // comparison values from the long double states (ExtractSolution's rows)
  long steps = 0;                  // collocation steps, event and slack trials included
  long rhs_evaluations = 0;
  long newton_iterations = 0;
  long event_iterations = 0;       // regula-falsi trials
  long slack_breakpoints = 0;      // steps ended at a ligament slack length
  long restarts_from_double = 0;   // phases started from the simulator's double state
  double max_gap_m = 0.0;          // max |φ_i| of active contacts at the samples, in T
  double max_gap_rate_m_s = 0.0;   // max |φ̇_i|
  double energy_error = 0.0;       // max |E − E(0)| / |E(0)| over the samples, in T
  double cpu_time_s = 0.0;
};

// Runs the scene with scalar T (double, long double, Float128). Throws SolverError/InputError like
// RunScene's simulator (not caught here).
template <typename T>
ExtendedReferenceRun RunExtendedReference(const Scene& scene, const ExtendedReferenceSettings& settings,
                                          double comparison_interval = kDefaultComparisonInterval);

}  // namespace bench
}  // namespace kneedyn
