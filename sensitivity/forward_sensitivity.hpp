// Forward sensitivities of a scene's outcomes with SUNDIALS CVODES.
//
// The ODE form is ede's index-1 form with the full state y = (q, q̇) ∈ R¹²:
//   ẏ = f(t, y, p) = (q̇, q̈),  q̈ from SolveConstrainedAcceleration (solver/, Eqs. 1.17–1.24
//   with φ̈_i = 0 of the active contacts), on the ligament branches locked for the phase.
// f reads the parameter values from the array p that CVODES owns (CVodeSetSensParams);
// p is applied to a private copy of the scene through ensembles::SceneForRun, the same
// path `kneedyn sweep` uses, so a parameter means the same thing in both commands. The
// sensitivity right-hand side is CVODES' centred difference quotient (simultaneous
// perturbation of y and p); s_j = ∂y/∂p_j is integrated with error control (staggered
// corrector, CVodeSetSensErrCon).
//
// Events (solver/events.hpp: lift-off N_i = 0, the end flexion α = α_end, the published
// law's kink L_j = (1 + 2ε1) L0_j; re-contact φ_i = 0) are located by CVODES' root finder.
// At a root g(τ, y(τ), p) = 0 the implicit-function relation gives
//   dτ/dp = −(∂g/∂y s + ∂g/∂p) / (∂g/∂t + ∂g/∂y f⁻),
// and where the vector field changes (lift-off, kink branch switch) the sensitivities jump:
//   s⁺ = s⁻ + (f⁻ − f⁺) dτ/dp          (y continuous; Hiskens & Pai 2000, Eq. 9).
// Re-contact is a plastic impact (a state reset with its own jump matrix): refused with a
// SolverError naming the time; the chapter scene has none. The phases are run by the hybrid
// simulator of `kneedyn run` (formulations/simulator.hpp: consistent start, events, re-contact
// hysteresis, output times) with two settings of its own: RestartProjection::kKeepState (y is
// not projected onto the constraints at a restart: the jump above is for a y continuous at
// the event) and PullingContact::kRefuse (a contact that would pull after a switch, i.e. a
// simultaneous lift-off, has no sensitivity).
//
// Outcomes (column names of ensembles::OutcomeColumns, the sweep's):
//   liftoff_time_s, liftoff_flexion_deg   first lift-off: dτ/dp; dα/dp = s_α + α̇ dτ/dp
//   liftoff_time_<c>_s, liftoff_flexion_<c>_deg   the same for compartment c (medial, lateral)
//   time_90_s                             end event: dτ/dp
//   F90_<element>_N, N90_<compartment>_N  values at the end event: Dv·(dτ/dp, s + f dτ/dp, e_j)
//   peak_F_<element>_N, peak_N_<c>_N      maxima over the run: interior maxima located as
//       roots of dv/dt (direction −1), derivative by the envelope theorem ∂v/∂y s + ∂v/∂p;
//       a maximum at t = 0 or at an event (one-sided value, e.g. at a kink) uses the
//       value-at-event formula above.
// Partial derivatives of g and v (∂/∂y·s + ∂/∂p, ∂/∂t + ∂/∂y·f) are directional central
// differences of the solver/ functions (no physics re-derived here).
//
// --formulation dae | dae-reduced | dae-ggl | dae-ggl-reduced: the same outcomes, names and
// result from the index-2 DAE of formulations/internal/dae_system.hpp on SUNDIALS IDAS
// (dae_sensitivity.cpp: consistent initial sensitivities, the sensitivity residual, the
// algebraic unknowns re-solved at each restart).
#pragma once

#include <functional>
#include <string>
#include <vector>

#include "ensembles/sweep_spec.hpp"
#include "formulations/run.hpp"

namespace kneedyn::sensitivity {

// The forms with sensitivities, as the registry declares them (FormulationInfo::sensitivity),
// in registry order: ODE forms on CVODES (this header; ede), DAE forms on IDAS
// (dae_sensitivity.cpp: the chapter-form and closed-form contact, plain and GGL).
std::vector<std::string> SensitivityFormulations();
// Whether `formulation` is an ODE form (CVODES) rather than a DAE form (IDAS); false for a
// name without sensitivities.
bool IsOdeSensitivity(const std::string& formulation);

struct SensitivityOptions {
  std::string formulation = "ede";  // one of SensitivityFormulations()
  double rtol = 1.0e-8;             // CVODES / IDAS relative tolerance (state and sensitivities)
  double atol = 1.0e-10;            // absolute tolerance (SI units of each state)
  long max_steps = 200000;          // per phase
  double output_interval = 0.0;     // s between trajectory samples; 0: the scene's
  bool derivatives = true;          // false: outcomes only (for finite differences)
  // Called with (t [s], flexion [rad]) at every output row (progress; unset: nothing).
  std::function<void(double, double)> progress;

  // False with a message naming the option, its value (as typed when `typed` has it: flag ->
  // text) and the rule.
  bool IsValid(std::string* error, const OptionText& typed = {}) const;
};

struct SensitivityEvent {
  std::string name;            // liftoff_lateral, flexion_90, kink_<element>
  double time = 0.0;           // s
  double flexion = 0.0;        // rad
  std::vector<double> dtime;   // dτ/dp_j, s per parameter unit (empty without derivatives)
};

// The trajectory and its sensitivities at one output time (fixed t: dq/dp = s_q(t)).
struct TrajectorySample {
  double t = 0.0;                     // s
  Vector6d q = Vector6d::Zero();      // (x0, y0, z0 [m], α, β, γ [rad])
  std::vector<Vector6d> dq;           // per parameter, ∂q/∂p_j (SI per parameter unit); empty without derivatives
};

struct SensitivityResult {
  std::vector<std::string> parameters;   // names as given
  std::vector<std::string> parameter_columns;  // sweep column names (with units)
  std::vector<double> parameter_values;  // spec units
  std::vector<std::string> outcomes;     // outcome columns
  std::vector<double> values;            // per outcome; NaN when not reached
  // d outcome / d parameter, row-major [outcome][parameter]; NaN without derivatives.
  std::vector<std::vector<double>> derivatives;
  std::vector<SensitivityEvent> events;
  std::string end_reason;                // flexion_<deg> or end_time
  std::vector<TrajectorySample> trajectory;  // t = 0 and every output interval before the end
  SolverStats stats;                     // CVODES / IDAS counters summed over phases
  long sensitivity_rhs_evaluations = 0;  // CVodeGetSensNumRhsEvals / IDAGetSensNumResEvals
  long sensitivity_error_test_failures = 0;
  // DAE forms: the largest |F_y s + F_ẏ ṡ + F_p| of the consistent initial sensitivities at
  // a phase start, relative to the size of its row's terms (dae_sensitivity.cpp; 0 for ede,
  // or without derivatives).
  double initial_sensitivity_residual = 0.0;
  double wall_time_s = 0.0;
};

// Parameter names (those of a sweep spec: "PCL anterior.k_linear" or "PCL_anterior.k_linear",
// "pulse.amplitude", "mass", ...). Unknown names throw InputError naming `field`, the
// value and the nearest valid name.
std::vector<ensembles::ParameterSpec> ResolveParameters(const Scene& scene, const std::vector<std::string>& names,
                                                        const std::string& field = "--parameters");
// Every parameter name the scene accepts (for messages and documentation).
std::vector<std::string> ParameterNames(const Scene& scene);

// Outcome columns (e.g. peak_F_PCL_anterior_N) or sweep outcome groups (e.g.
// peak_ligament_force, expanded to their columns). Unknown names: InputError as above.
std::vector<std::string> ResolveOutcomes(const Scene& scene, const std::vector<std::string>& names,
                                         const std::string& field = "--outcomes");
std::vector<std::string> OutcomeNames(const Scene& scene);

// Integrates the scene at parameter values `values` (spec units, parallel to `parameters`)
// and returns the outcomes and, with options.derivatives, their derivatives. Throws
// InputError for bad options, SolverError when integration fails or meets an impact.
SensitivityResult RunSensitivity(const Scene& scene, const std::vector<ensembles::ParameterSpec>& parameters,
                                 const std::vector<double>& values, const std::vector<std::string>& outcomes,
                                 const SensitivityOptions& options);

// What the result files say integrated: "cvodes-bdf" (ede) or "idas-bdf" (the DAE forms),
// and how the sensitivity equations' right-hand side / residual was formed.
const char* SensitivityIntegrator(const std::string& formulation);
const char* SensitivityMethod(const std::string& formulation);

// Levenshtein distance: kneedyn::EditDistance (solver/error.hpp).
using kneedyn::EditDistance;

}  // namespace kneedyn::sensitivity
