#include "formulations/formulation.hpp"

#include <algorithm>
#include <cmath>
#include <iterator>
#include <utility>

#include "solver/error.hpp"

namespace kneedyn {

SolverStats& SolverStats::operator+=(const SolverStats& o) {
  steps += o.steps;
  residual_evaluations += o.residual_evaluations;
  jacobian_evaluations += o.jacobian_evaluations;
  linear_solver_setups += o.linear_solver_setups;
  nonlinear_iterations += o.nonlinear_iterations;
  error_test_failures += o.error_test_failures;
  convergence_failures += o.convergence_failures;
  step_halvings += o.step_halvings;
  root_evaluations += o.root_evaluations;
  projections += o.projections;
  restarts += o.restarts;
  return *this;
}

namespace {

template <typename Enum>
struct Spelling {
  const char* text;
  Enum value;
};

// Each value's spelling, in the order messages list them.
constexpr Spelling<IntegratorKind> kIntegrators[] = {
    {"euler", IntegratorKind::kEuler},           {"rk4", IntegratorKind::kRk4},
    {"dopri5", IntegratorKind::kDopri5},         {"verner65", IntegratorKind::kVerner65},
    {"fehlberg78", IntegratorKind::kFehlberg78}, {"cvode-bdf", IntegratorKind::kCvodeBdf},
    {"cvode-adams", IntegratorKind::kCvodeAdams}};
constexpr Spelling<Stabilization> kStabilizations[] = {
    {"none", Stabilization::kNone}, {"baumgarte", Stabilization::kBaumgarte},
    {"projection", Stabilization::kProjection}, {"cvode-projection", Stabilization::kCvodeProjection}};
constexpr Spelling<ConstraintLevel> kConstraintLevels[] = {
    {"velocity", ConstraintLevel::kVelocity}, {"position", ConstraintLevel::kPosition}};
constexpr Spelling<JacobianKind> kJacobians[] = {
    {"exact", JacobianKind::kExact}, {"jet", JacobianKind::kJet},
    {"difference-quotient", JacobianKind::kDifferenceQuotient}};

template <typename Enum, size_t N>
const char* NameIn(const Spelling<Enum> (&table)[N], Enum value) {
  for (const Spelling<Enum>& s : table) {
    if (s.value == value) return s.text;
  }
  return "?";
}

// "a, b or c"
template <typename List, typename Name>
std::string Alternatives(const List& list, Name name) {
  std::string out;
  size_t i = 0;
  for (const auto& item : list) {
    out += i == 0 ? "" : (i + 1 == std::size(list) ? " or " : ", ");
    out += name(item);
    ++i;
  }
  return out;
}

template <typename Enum, size_t N>
bool ParseIn(const Spelling<Enum> (&table)[N], const char* flag, const char* rule, const std::string& text,
             Enum* value, std::string* error) {
  for (const Spelling<Enum>& s : table) {
    if (text == s.text) {
      if (value) *value = s.value;
      return true;
    }
  }
  if (error) {
    *error = StrCat(flag, " = '", Echo(text), "'", rule, "; must be ",
                    Alternatives(table, [](const Spelling<Enum>& s) { return s.text; }));
  }
  return false;
}

// The value as the user typed it when known, else as printed.
template <typename T>
std::string Shown(const OptionText& typed, const char* flag, const T& value) {
  const auto it = typed.find(flag);
  return it != typed.end() ? Echo(it->second) : StrCat(value);
}

template <typename Enum>
bool Accepts(const std::vector<Enum>& accepted, Enum value) {
  return std::find(accepted.begin(), accepted.end(), value) != accepted.end();
}

template <typename Enum>
std::string Accepted(const std::vector<Enum>& accepted) {
  std::string out;
  for (Enum v : accepted) out += (out.empty() ? "" : ", ") + std::string(OptionName(v));
  return out;
}

}  // namespace

const char* OptionName(IntegratorKind value) { return NameIn(kIntegrators, value); }
const char* OptionName(Stabilization value) { return NameIn(kStabilizations, value); }
const char* OptionName(ConstraintLevel value) { return NameIn(kConstraintLevels, value); }
const char* OptionName(JacobianKind value) { return NameIn(kJacobians, value); }

bool ParseOptionValue(const std::string& text, IntegratorKind* value, std::string* error) {
  return ParseIn(kIntegrators, "--integrator", " is not available", text, value, error);
}
bool ParseOptionValue(const std::string& text, Stabilization* value, std::string* error) {
  return ParseIn(kStabilizations, "--stabilization", "", text, value, error);
}
bool ParseOptionValue(const std::string& text, ConstraintLevel* value, std::string* error) {
  return ParseIn(kConstraintLevels, "--constraint-level", "", text, value, error);
}
bool ParseOptionValue(const std::string& text, JacobianKind* value, std::string* error) {
  return ParseIn(kJacobians, "--jacobian", "", text, value, error);
}

template <typename Enum>
Enum ParsedOptionValue(const std::string& text) {
  Enum value{};
  std::string why;
  if (!ParseOptionValue(text, &value, &why)) Throw<InputError>("ParseOptionValue", why);
  return value;
}
template IntegratorKind ParsedOptionValue<IntegratorKind>(const std::string&);

std::optional<IntegratorKind> IntegratorOption(const std::string& text) {
  if (text.empty()) return std::nullopt;
  return ParsedOptionValue<IntegratorKind>(text);
}

std::string IntegratorOptionName(std::optional<IntegratorKind> integrator) {
  return integrator ? OptionName(*integrator) : "";
}
template Stabilization ParsedOptionValue<Stabilization>(const std::string&);
template ConstraintLevel ParsedOptionValue<ConstraintLevel>(const std::string&);
template JacobianKind ParsedOptionValue<JacobianKind>(const std::string&);

bool ValidateOptions(const FormulationInfo& info, const FormulationOptions& o, std::string* error,
                     const OptionText& typed) {
  auto fail = [&](const std::string& m) {
    if (error) *error = m;
    return false;
  };
  const std::string& name = info.name;
  // The rules every formulation shares.
  if (!(std::isfinite(o.rtol) && o.rtol > 0.0 && o.rtol <= 0.5)) {
    return fail(StrCat("--rtol = ", Shown(typed, "--rtol", o.rtol), "; must lie in (0, 0.5]"));
  }
  if (!(std::isfinite(o.atol) && o.atol > 0.0 && o.atol <= 1e-2)) {
    return fail(StrCat("--atol = ", Shown(typed, "--atol", o.atol), "; must lie in (0, 1e-2] (SI: m, m/s, rad)"));
  }
  if (!(std::isfinite(o.step) && (o.step == 0.0 || (o.step >= 1e-9 && o.step <= 0.1)))) {
    return fail(StrCat("--step = ", Shown(typed, "--step", o.step),
                       " s; must be 0 (method default) or lie in [1e-9, 0.1] s"));
  }
  if (!(std::isfinite(o.max_step) && o.max_step >= 0.0 && o.max_step <= 100.0)) {
    return fail(StrCat("--max-step = ", Shown(typed, "--max-step", o.max_step), " s; must lie in [0, 100] s (0: none)"));
  }
  if (o.max_steps < 1 || o.max_steps > 100000000) {
    return fail(StrCat("--max-steps = ", Shown(typed, "--max-steps", o.max_steps), "; must lie in [1, 1e8]"));
  }
  if (!(o.baumgarte_alpha >= 0.0) || !(o.baumgarte_beta >= 0.0)) {
    return fail(StrCat("Baumgarte gains (", o.baumgarte_alpha, ", ", o.baumgarte_beta, "); must be >= 0"));
  }
  if (!(o.rho_inf >= 0.0 && o.rho_inf <= 1.0)) {
    return fail(StrCat("--rho-inf = ", Shown(typed, "--rho-inf", o.rho_inf), "; must be in [0, 1]"));
  }
  const std::optional<double>* scheme[] = {&o.alpha_m, &o.alpha_f, &o.newmark_beta, &o.newmark_gamma};
  const char* scheme_flags[] = {"--alpha-m", "--alpha-f", "--beta", "--gamma"};
  int given = 0;
  std::string given_list;
  for (int i = 0; i < 4; ++i) {
    if (!scheme[i]->has_value()) continue;
    ++given;
    given_list += StrCat(given_list.empty() ? "" : ", ", scheme_flags[i], " = ", Shown(typed, scheme_flags[i], **scheme[i]));
    if (!std::isfinite(**scheme[i])) {
      return fail(StrCat(scheme_flags[i], " = ", Shown(typed, scheme_flags[i], **scheme[i]), "; must be finite"));
    }
  }
  // What the formulation accepts (its registry line).
  if (!info.scheme_parameters && (given > 0 || o.rho_inf != FormulationOptions().rho_inf)) {
    return fail(StrCat("--rho-inf / --alpha-m / --alpha-f / --beta / --gamma apply to generalized-alpha only, not to ",
                       name, info.fixed_step ? " (its rule is fixed: beta = 1/4, gamma = 1/2)" : ""));
  }
  if (given != 0 && given != 4) {
    return fail(StrCat("--alpha-m/--alpha-f/--beta/--gamma: ", given, " of 4 given (", given_list,
                       "); give all four or none (then from --rho-inf)"));
  }
  if (given == 4 && !(*o.alpha_m < 1.0 && *o.alpha_f < 1.0 && *o.newmark_beta > 0.0 && *o.newmark_gamma > 0.0)) {
    return fail(StrCat("generalized-alpha parameters (alpha_m, alpha_f, beta, gamma) = (", *o.alpha_m, ", ",
                       *o.alpha_f, ", ", *o.newmark_beta, ", ", *o.newmark_gamma,
                       "); need alpha_m < 1, alpha_f < 1, beta > 0, gamma > 0"));
  }
  if (o.integrator && info.integrators.empty()) {
    return fail(StrCat("--integrator = '", OptionName(*o.integrator), "': formulation '", name,
                       "' has a fixed integrator and takes no --integrator"));
  }
  if (o.integrator && !Accepts(info.integrators, *o.integrator)) {
    return fail(StrCat("--integrator = '", OptionName(*o.integrator), "' is not available for formulation '", name,
                       "'; choose one of: ", Accepted(info.integrators)));
  }
  if (!Accepts(info.stabilizations, o.stabilization)) {
    return fail(StrCat("--stabilization = '", OptionName(o.stabilization), "' is not available for formulation '",
                       name, "'; it accepts: ", Accepted(info.stabilizations)));
  }
  if (!Accepts(info.constraint_levels, o.constraint_level)) {
    return fail(StrCat("--constraint-level = '", OptionName(o.constraint_level),
                       "' is not available for formulation '", name, "'; it accepts: ",
                       Accepted(info.constraint_levels)));
  }
  if (o.jacobian && info.jacobians.empty()) {
    return fail(StrCat("--jacobian = '", OptionName(*o.jacobian), "': formulation '", name,
                       "' forms no Newton matrix of its own; the option does not apply"));
  }
  if (o.jacobian && !Accepts(info.jacobians, *o.jacobian)) {
    return fail(StrCat("--jacobian = '", OptionName(*o.jacobian), "' is not available for formulation '", name,
                       "'; it accepts: ", Accepted(info.jacobians)));
  }
  // Step control: a fixed-step method takes --step, an error-controlled one --max-step.
  const std::string with = o.integrator ? StrCat(" with --integrator ", OptionName(*o.integrator)) : "";
  if (IsFixedStep(info, o.integrator)) {
    if (info.fixed_step && o.max_step != 0.0) {
      return fail(StrCat("--max-step = ", Shown(typed, "--max-step", o.max_step), " s: ", name,
                         " takes fixed steps; use --step"));
    }
  } else if (o.step != 0.0) {
    return fail(StrCat("--step = ", Shown(typed, "--step", o.step), " s: ", name, with,
                       " chooses its own steps under --rtol/--atol",
                       info.integrators.empty() ? "" : " (only euler and rk4 take a fixed step)", "; use --max-step"));
  }
  if (o.stabilization == Stabilization::kCvodeProjection && o.integrator != IntegratorKind::kCvodeBdf) {
    return fail(StrCat("--stabilization cvode-projection", with.empty() ? " with the default integrator" : with,
                       ": CVODE's projection (CVodeSetProjFn) exists only for cvode-bdf; use --integrator "
                       "cvode-bdf or --stabilization projection"));
  }
  if (o.stabilization == Stabilization::kProjection && o.integrator == IntegratorKind::kCvodeAdams) {
    // The project-and-restart loop would restart the multistep method at order 1 every step.
    return fail("--stabilization projection with --integrator cvode-adams: not supported (CVODE projects only "
                "with BDF); use cvode-bdf or an ERK method");
  }
  return true;
}

void CheckOptions(const FormulationInfo& info, const FormulationOptions& options, const OptionText& typed) {
  std::string why;
  if (!ValidateOptions(info, options, &why, typed)) Throw<InputError>("CheckOptions", why);
}

std::vector<int> RootDirections(const std::vector<EventSpec>& events) {
  std::vector<int> directions;
  for (const EventSpec& e : events) directions.push_back(e.direction);
  return directions;
}

AdvanceResult EventResult(const std::vector<int>& root_flags) {
  AdvanceResult result;
  result.status = AdvanceStatus::kEvent;
  for (size_t i = 0; i < root_flags.size(); ++i) {
    if (root_flags[i] != 0) result.events.push_back(static_cast<int>(i));
  }
  return result;
}

bool IsFixedStep(const FormulationInfo& info, std::optional<IntegratorKind> integrator) {
  return info.fixed_step || integrator == IntegratorKind::kEuler || integrator == IntegratorKind::kRk4;
}

bool IsFixedStep(const FormulationInfo& info, const std::string& integrator) {
  return IsFixedStep(info, IntegratorOption(integrator));
}

bool HasErrorControl(const FormulationInfo& info, const std::string& integrator) {
  return !IsFixedStep(info, integrator);
}

bool HasErrorControl(const FormulationInfo& info, std::optional<IntegratorKind> integrator) {
  return !IsFixedStep(info, integrator);
}

const FormulationInfo& FindFormulation(const std::string& name) {
  std::string known;
  for (const FormulationInfo& info : RegisteredFormulations()) {
    if (info.name == name) return info;
    known += (known.empty() ? "" : ", ") + info.name;
  }
  Throw<InputError>("FindFormulation", "unknown formulation '", name, "'; registered: ", known);
}

std::unique_ptr<Formulation> CreateFormulation(const std::string& name, const Scene& scene,
                                               const FormulationOptions& options) {
  const FormulationInfo& info = FindFormulation(name);
  std::string why;
  if (!ValidateOptions(info, options, &why)) Throw<InputError>("CreateFormulation", why);
  return info.create(scene, options);
}

}  // namespace kneedyn
