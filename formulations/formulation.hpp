// One interface for every formulation. A formulation integrates the knee
// from a consistent MechanicalState in one contact mode and stops at the first event of
// that phase: it is the stepper of the hybrid simulator (simulator.hpp), which owns
// everything that must behave the same for all formulations: consistent initialization,
// contact switching (lift-off, re-contact, both separated), the end condition and output
// times; the run driver (run.hpp) writes the files.
//
// Adding a formulation: one new file defining a Formulation subclass (with its
// EvaluateHotPathForTesting), its typed options and its Configure function, and one line in registry.cpp (KNEEDYN_FACTORY declares the Configure function there;
// CMake globs formulations/*.cpp). It then appears in `kneedyn run --formulation`, the conformance tests,
// the benchmarks and the reports.
#pragma once

#include <functional>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "scene/scene.hpp"
#include "solver/consistent_init.hpp"
#include "solver/events.hpp"
#include "solver/state.hpp"

namespace kneedyn {

// Solver statistics with the solvers' own counter names. Cumulative over
// all phases of a run. Counters a method does not have stay 0.
struct SolverStats {
  long steps = 0;                   // accepted steps
  long residual_evaluations = 0;    // DAE residual / ODE right-hand-side evaluations
  long jacobian_evaluations = 0;
  long linear_solver_setups = 0;    // LU factorizations
  long nonlinear_iterations = 0;    // Newton iterations
  long error_test_failures = 0;
  long convergence_failures = 0;    // nonlinear solver convergence failures
  long step_halvings = 0;           // Newmark: step halved after a Newton failure
  long root_evaluations = 0;        // event-function evaluations
  long projections = 0;             // EDE: projections onto the constraints
  long restarts = 0;                // solver (re)starts: one per contact phase

  SolverStats& operator+=(const SolverStats& o);
  long rejected_steps() const { return error_test_failures + convergence_failures + step_halvings; }
};

// The values of the options that choose a method. Spelled on the command line, in Python,
// in sweep specs and in summary.json as OptionName gives (ParseOptionValue reads them back).
enum class IntegratorKind { kEuler, kRk4, kDopri5, kVerner65, kFehlberg78, kCvodeBdf, kCvodeAdams };
enum class Stabilization { kNone, kBaumgarte, kProjection, kCvodeProjection };
enum class ConstraintLevel { kVelocity, kPosition };  // dae: index 2 | index-3 variant
// How a Newton-based formulation gets its iteration matrix: exact from blocks
// differentiated at their own size (default), the Jet<24> derivative of the whole residual
// (the reference), or the integrator's own difference quotients (IDA).
enum class JacobianKind { kExact, kJet, kDifferenceQuotient };
// How an IDA formulation solves its Newton systems: q eliminated through the kinematic rows
// F1–F6 before a partial-pivoting LU of the rest (default;
// formulations/internal/kinematic_block_solver.hpp), or SUNDIALS' dense LU of the whole
// matrix (for A/B measurements).
enum class LinearSolverKind { kStructured, kDense };

const char* OptionName(IntegratorKind value);   // "euler", ..., "cvode-adams"
const char* OptionName(Stabilization value);    // "none", "baumgarte", ...
const char* OptionName(ConstraintLevel value);  // "velocity", "position"
const char* OptionName(JacobianKind value);     // "exact", "jet", "difference-quotient"
const char* OptionName(LinearSolverKind value);  // "structured", "dense"
const char* OptionName(ContactChart value);      // "regular", "height-field"
// `text` as the value it spells; false, with a message naming the option (--integrator, ...),
// the text and the accepted spellings, when it spells none.
bool ParseOptionValue(const std::string& text, IntegratorKind* value, std::string* error);
bool ParseOptionValue(const std::string& text, Stabilization* value, std::string* error);
bool ParseOptionValue(const std::string& text, ConstraintLevel* value, std::string* error);
bool ParseOptionValue(const std::string& text, JacobianKind* value, std::string* error);
bool ParseOptionValue(const std::string& text, LinearSolverKind* value, std::string* error);
bool ParseOptionValue(const std::string& text, ContactChart* value, std::string* error);
// Throwing variant: InputError with that message.
template <typename Enum>
Enum ParsedOptionValue(const std::string& text);
// For drivers that name integrators as text: "" (not given) <-> no value.
std::optional<IntegratorKind> IntegratorOption(const std::string& text);  // throws InputError
std::string IntegratorOptionName(std::optional<IntegratorKind> integrator);
// The spellings of a list of values (a capability list of FormulationInfo).
template <typename Enum>
std::vector<std::string> OptionNames(const std::vector<Enum>& values) {
  std::vector<std::string> names;
  for (Enum v : values) names.push_back(OptionName(v));
  return names;
}

// The tolerances' ranges, for every method and the Problem interface: rtol in (0, kMaxRtol],
// atol in (0, kMaxAtol] (SI: m, m/s, rad). Past them an error test accepts anything and the
// re-contact threshold, which scales with them, never closes.
inline constexpr double kMaxRtol = 0.5;
inline constexpr double kMaxAtol = 1e-2;
inline constexpr char kRtolRange[] = "(0, 0.5]";   // as the refusals state them
inline constexpr char kAtolRange[] = "(0, 1e-2]";

// Step control, which every formulation has.
struct StepControl {
  double rtol = 1.0e-6;    // relative tolerance (adaptive methods; the Newton test of fixed-step ones)
  double atol = 1.0e-8;    // absolute tolerance (SI units of each state)
  double step = 0.0;       // s: fixed step (euler, rk4, newmark*, generalized-alpha*); 0 = method default
  double max_step = 0.0;   // s: cap on adaptive steps; 0 = none
  long max_steps = 200000;  // per phase
};

// What a boundary (the command line, Python, a sweep spec, a batch, a driver) was given: one
// typed value per option any formulation takes, the defaults where nothing was given. No
// formulation receives it: each reads its own typed options from it, once (OptionRequest,
// Configure below), and refuses what does not apply to it. Summaries record it as requested.
struct FormulationOptions {
  double rtol = StepControl().rtol;
  double atol = StepControl().atol;
  std::optional<IntegratorKind> integrator;  // mde, ede; not given: dopri5
  double step = StepControl().step;
  double max_step = StepControl().max_step;
  long max_steps = StepControl().max_steps;
  Stabilization stabilization = Stabilization::kNone;  // ede
  double baumgarte_alpha = 20.0;  // 1/s
  double baumgarte_beta = 20.0;   // 1/s
  // Chart of the contact coordinates (contact.hpp) the consistent initialization and the
  // chapter-form formulations use: regular | height-field
  ContactChart contact_chart = ContactChart::kRegular;
  ConstraintLevel constraint_level = ConstraintLevel::kVelocity;  // dae: index 2 | index 3
  // dae*, dae-ggl*, newmark*, generalized-alpha*; not given: exact (FormulationInfo::jacobians
  // lists what a formulation accepts; one that forms no Newton matrix accepts none).
  std::optional<JacobianKind> jacobian;
  // dae*, dae-ggl*, monolithic*; not given: structured (FormulationInfo::linear_solvers).
  std::optional<LinearSolverKind> linear_solver;
  // generalized-alpha (newmark_scheme.hpp): spectral radius at infinity ρ∞ ∈ [0, 1], or
  // the four parameters explicitly (all four or none; none: from ρ∞).
  double rho_inf = 0.9;
  std::optional<double> alpha_m;
  std::optional<double> alpha_f;
  std::optional<double> newmark_beta;
  std::optional<double> newmark_gamma;

  StepControl step_control() const { return {rtol, atol, step, max_step, max_steps}; }
};

// How the user spelled options on the command line ("--rtol" -> "1e-6"), so that messages
// echo the text; options absent from it are printed from their values.
using OptionText = std::map<std::string, std::string>;

// A number given as an option's text: the whole text (no blanks, no trailing characters),
// finite and representable (strtod's ERANGE refused, so 1e999 is not taken as inf nor 1e-999
// as 0). A command-line parser would read "" as 0 and clamp an integer beyond its type's range.
bool ParseReal(const std::string& text, double* value);
// ParseReal's rule as the refusals state it.
inline constexpr char kRealRule[] =
    "must be a finite number, 0 or of magnitude within double's normal range (2.2e-308 to 1.8e308)";
// A decimal integer given as text: the whole text, within long's range.
bool ParseInteger(const std::string& text, long* value);

// The text options of a boundary (flag -> text as typed: "--rtol" -> "1e-6", "--integrator"
// -> "rk4", ...) converted into `options`: numbers must be the whole text, finite and
// representable; names one of their spellings. Flags it does not know are left alone.
// Returns the first refusal, naming the flag and the text as typed, or "".
std::string ReadOptionText(const OptionText& typed, FormulationOptions* options);

enum class AdvanceStatus { kReachedTime, kEvent };

struct AdvanceResult {
  AdvanceStatus status = AdvanceStatus::kReachedTime;
  std::vector<int> events;  // indices into the phase's EventSpec list that fired
};

// SUNDIALS glue shared by the formulations that locate events with a root finder:
// the root directions of a phase's events (−1, 0, +1, in order), and the AdvanceResult for
// the root flags the solver reports (kEvent with every index whose flag is nonzero).
std::vector<int> RootDirections(const std::vector<EventSpec>& events);
AdvanceResult EventResult(const std::vector<int>& root_flags);

class Formulation {
 public:
  virtual ~Formulation() = default;
  // The contact description its initialization must satisfy.
  virtual ContactForm contact_form() const = 0;
  // Prepares a phase from a consistent state (positions, velocities, hidden constraint)
  // with the contacts in state.active; `events` are the roots to watch in this phase.
  virtual void Start(const MechanicalState& state, const std::vector<EventSpec>& events) = 0;
  // Integrates towards t_out (> state->t). Stops at t_out or at the first event root,
  // whichever comes first, and writes the state reached (including normal forces of the
  // active contacts and qdd). Throws SolverError with the solver's reason, t and h.
  virtual AdvanceResult Advance(double t_out, MechanicalState* state) = 0;
  // Cumulative statistics.
  virtual SolverStats stats() const = 0;
  // The integrator actually run ("ida", "dopri5", "newmark-average-acceleration", ...) and
  // its fixed step in s (0: adaptive), for summary.json. Defaults: not stated.
  virtual std::string integrator() const { return ""; }
  virtual double fixed_step() const { return 0.0; }
  // Testing hook (tests/zero_allocation_test.cpp): after Start, calls the
  // callbacks the solver calls inside a phase (residual or right-hand side, Jacobian, root
  // functions; Newton step for the steppers) n times at the current state, through the same
  // code the solver runs. Returns false when the formulation has no such hook, which the test
  // refuses: every registered formulation overrides it.
  virtual bool EvaluateHotPathForTesting(int n) { (void)n; return false; }
};

struct FormulationInfo;

// A request for one formulation's options, with where a refusal goes. A formulation's file reads
// its own typed options from it (the family readers: ReadIdaOptions, ReadOdeOptions,
// ReadNewmarkOptions in formulations/internal/) after Configure has checked what every
// formulation shares (StepControl's ranges, the capabilities of the registry line).
struct OptionRequest {
  const FormulationInfo& info;
  const FormulationOptions& options;
  const OptionText& typed;  // the text given, for the messages
  std::string* error;       // the refusal: the option, its value as typed and the rule

  // The value as the user typed it when known, else as printed.
  std::string Shown(const char* flag, double value) const;
  // Stores `message` as the refusal; returns false.
  bool Fail(const std::string& message) const;
};

// A formulation bound to its typed options, read and checked: builds it for a scene.
using FormulationMaker = std::function<std::unique_ptr<Formulation>(const Scene&)>;
// A registry line's factory: reads the formulation's typed options from the request and binds
// them to its constructor; an empty maker after request.Fail.
using FormulationFactory = std::function<FormulationMaker(const OptionRequest&)>;

// The forward sensitivities a form has (sensitivity/, `kneedyn sensitivity --formulation`):
// none; CVODES on its ODE y = (q, q̇); IDAS on its index-2 DAE (dae_system.hpp), plain or GGL.
enum class SensitivityForm { kNone, kOde, kDae, kDaeGgl };

// What a formulation can do, declared once in its registry line: drivers and tests ask
// these (and GTEST_SKIP on them) instead of comparing names. Each capability is a named
// field; a registry line sets the ones that differ from the defaults through the setters:
//   FormulationInfo("name", "summary", KNEEDYN_FACTORY(CreateName)).FixedStep().Jacobians({...})
struct FormulationInfo {
  std::string name;
  std::string summary;
  FormulationFactory create;
  std::vector<IntegratorKind> integrators;  // values --integrator accepts; empty: none
  bool fixed_step = false;  // steps only with --step (its tolerances drive a Newton test)
  // The contact forces are unknowns of the solver (DAE, Newton on the step equations) rather
  // than computed from the state (ODE formulations through the hidden constraint).
  bool algebraic_forces = false;
  std::vector<Stabilization> stabilizations = {Stabilization::kNone};          // --stabilization
  std::vector<ConstraintLevel> constraint_levels = {ConstraintLevel::kVelocity};  // --constraint-level
  // Reads --contact-chart (the chart of its contact coordinates); mde eliminates them in
  // closed form and takes none.
  bool contact_chart = true;
  std::vector<JacobianKind> jacobians;  // values --jacobian accepts; empty: the option does not apply
  std::vector<LinearSolverKind> linear_solvers;  // values --linear-solver accepts; empty: does not apply
  // Takes the generalized-alpha parameters (--rho-inf, --alpha-m, --alpha-f, --beta, --gamma).
  bool scheme_parameters = false;
  // Which forward sensitivities `kneedyn sensitivity` runs for it (none: not available).
  SensitivityForm sensitivity = SensitivityForm::kNone;
  // Runs only scenes with a patella (scene section patella; docs/model.md §12): refused
  // with InputError on others.
  bool needs_patella = false;
  // Starts from the scene's pose unprojected (initial_state.start: unprojected, the chapter's
  // DASSL start, docs/model.md §6): its own integrator corrects the first step.
  bool unprojected_start = false;

  FormulationInfo(std::string name_, std::string summary_, FormulationFactory create_)
      : name(std::move(name_)), summary(std::move(summary_)), create(std::move(create_)) {}
  FormulationInfo& Integrators(std::vector<IntegratorKind> v) { integrators = std::move(v); return *this; }
  FormulationInfo& FixedStep() { fixed_step = true; return *this; }
  FormulationInfo& AlgebraicForces() { algebraic_forces = true; return *this; }
  FormulationInfo& Stabilizations(std::vector<Stabilization> v) { stabilizations = std::move(v); return *this; }
  FormulationInfo& ConstraintLevels(std::vector<ConstraintLevel> v) { constraint_levels = std::move(v); return *this; }
  FormulationInfo& NoContactChart() { contact_chart = false; return *this; }
  FormulationInfo& Jacobians(std::vector<JacobianKind> v) { jacobians = std::move(v); return *this; }
  FormulationInfo& LinearSolvers(std::vector<LinearSolverKind> v) { linear_solvers = std::move(v); return *this; }
  FormulationInfo& SchemeParameters() { scheme_parameters = true; return *this; }
  FormulationInfo& Sensitivity(SensitivityForm form) { sensitivity = form; return *this; }
  FormulationInfo& NeedsPatella() { needs_patella = true; return *this; }
  FormulationInfo& UnprojectedStart() { unprojected_start = true; return *this; }
};

// The one check of FormulationOptions for a formulation: the rules every formulation shares
// (StepControl's ranges) and what `info` accepts (integrators, stabilizations, constraint
// levels, Jacobians, step control, scheme parameters), then the formulation's own rules as it
// reads its typed options. False with a message naming the option, its value as typed and the
// rule. The CLI, Python, sweep specs and batches call it where the options come in;
// CreateFormulation calls it before building, as its precondition.
bool ValidateOptions(const FormulationInfo& info, const FormulationOptions& options, std::string* error,
                     const OptionText& typed = {});
// Throwing variant: InputError with that message.
void CheckOptions(const FormulationInfo& info, const FormulationOptions& options, const OptionText& typed = {});
// The formulation bound to its typed options (ValidateOptions' check, then the binding);
// throws InputError with the refusal.
FormulationMaker Configure(const FormulationInfo& info, const FormulationOptions& options,
                           const OptionText& typed = {});

// A registry line's factory (registry.cpp): a Configure function defined in the formulation's
// own file, declared inside the lambda, so that the registry line is all a new formulation
// adds outside its file. The function reads the formulation's typed options and returns them
// bound to its constructor:
//   FormulationMaker ConfigureName(const OptionRequest& request) {
//     NameOptions options;  // typed: enums, numbers; no strings
//     if (!ReadNameOptions(request, &options)) return nullptr;
//     return [options](const Scene& scene) { return std::make_unique<NameFormulation>(scene, options); };
//   }
#define KNEEDYN_FACTORY(function)                                                             \
  [](const OptionRequest& request) {                                                          \
    FormulationMaker function(const OptionRequest&);                                           \
    return function(request);                                                                 \
  }

// Step a fixed-step method takes when --step is 0 (s).
constexpr double kDefaultFixedStep = 1.0e-4;

// Steps a pulse must span to be resolved: a fixed step longer than a tenth of the pulse is
// refused (the Simulator), and an adaptive IDA phase that starts within the pulse begins with
// at most a tenth of it (a longer first step can pass a short pulse whole and never see it: a
// half-sine is zero at both ends). docs/model.md §7.
constexpr double kStepsPerPulse = 10.0;

// The longest step that resolves the pulses at time t (s): a tenth of a pulse's duration
// while it lasts; infinity once every pulse has ended or when the scene has none. The
// quadriceps half-sine (docs/model.md §12) is a pulse as the tibial one is: F_Q is at its
// baseline at both ends, so a step that spans it never sees it (a ramp is not: it keeps its
// end value). `field` and `duration` name the scene key that sets the step, for messages.
struct PulseStepLimit {
  double step = std::numeric_limits<double>::infinity();  // s
  const char* field = "";                                  // e.g. "pulse.duration_s"
  double duration = 0.0;                                   // s, that field's value
};

inline PulseStepLimit PulseResolvingStepLimit(const Model& model, double t) {
  PulseStepLimit limit;
  if (model.pulse.shape != PulseShape::kNone && model.pulse.amplitude != 0.0 && t < model.pulse.duration) {
    limit = {model.pulse.duration / kStepsPerPulse, "pulse.duration_s", model.pulse.duration};
  }
  if (model.patella) {
    const QuadricepsForce& q = model.patella->quadriceps;
    if (q.shape == QuadricepsShape::kHalfSine && q.magnitude != 0.0 && t < q.duration &&
        q.duration / kStepsPerPulse < limit.step) {
      limit = {q.duration / kStepsPerPulse, "patella.quadriceps.duration_s", q.duration};
    }
  }
  return limit;
}

inline double PulseResolvingStep(const Model& model, double t) { return PulseResolvingStepLimit(model, t).step; }

// Absolute Newton tolerance of a multiplier (contact force N, newtons; GGL's μ) per unit
// --atol (m, rad), in every method that solves for the multipliers as unknowns (dae, dae-ggl
// and the IDAS sensitivities through dae_on_ida.hpp; newmark, generalized-alpha): the
// multipliers of position- or velocity-level constraints carry Newton round-off of order
// ε/h² (index 2 and 3), so they cannot be held to the positions' tolerance.
constexpr double kForceAtolScale = 1.0e4;

// Whether (formulation, integrator) advances with a fixed --step rather than error control:
// a fixed-step formulation, or the fixed-step integrators euler and rk4. Drivers (tests,
// catalog, benchmarks) use it to choose a step grid or a tolerance grid.
// `integrator` as spelled ("" = not given) or as typed.
bool IsFixedStep(const FormulationInfo& info, const std::string& integrator);
bool IsFixedStep(const FormulationInfo& info, std::optional<IntegratorKind> integrator);

// The registry (registry.cpp), in a stable order.
const std::vector<FormulationInfo>& RegisteredFormulations();
// `formulations` as given, after checking that no name repeats: throws std::logic_error
// naming a repeated one (a second registry line would otherwise be listed twice and never run).
std::vector<FormulationInfo> WithUniqueNames(std::vector<FormulationInfo> formulations);
const FormulationInfo& FindFormulation(const std::string& name);  // throws InputError
// The registry line of `name`, or null (a name outside the registry: Simbody's, say).
const FormulationInfo* RegisteredFormulation(const std::string& name);
// "a, b": the registered formulations whose `field` is `value`, for messages and help texts
// (derived from the registry, never a hand-kept list).
std::string FormulationsWith(bool FormulationInfo::*field, bool value = true);
std::unique_ptr<Formulation> CreateFormulation(const std::string& name, const Scene& scene,
                                               const FormulationOptions& options);

}  // namespace kneedyn
