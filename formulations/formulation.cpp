#include "formulations/formulation.hpp"

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cstdlib>
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
constexpr Spelling<LinearSolverKind> kLinearSolvers[] = {
    {"structured", LinearSolverKind::kStructured}, {"dense", LinearSolverKind::kDense}};
constexpr Spelling<ContactChart> kContactCharts[] = {
    {"regular", ContactChart::kRegular}, {"height-field", ContactChart::kHeightField}};

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
const char* OptionName(LinearSolverKind value) { return NameIn(kLinearSolvers, value); }
const char* OptionName(ContactChart value) { return NameIn(kContactCharts, value); }

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
bool ParseOptionValue(const std::string& text, LinearSolverKind* value, std::string* error) {
  return ParseIn(kLinearSolvers, "--linear-solver", "", text, value, error);
}
bool ParseOptionValue(const std::string& text, ContactChart* value, std::string* error) {
  return ParseIn(kContactCharts, "--contact-chart", "", text, value, error);
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
template LinearSolverKind ParsedOptionValue<LinearSolverKind>(const std::string&);
template ContactChart ParsedOptionValue<ContactChart>(const std::string&);

bool ParseReal(const std::string& text, double* value) {
  if (text.empty() || std::isspace(static_cast<unsigned char>(text[0]))) return false;
  errno = 0;
  char* end = nullptr;
  const double v = std::strtod(text.c_str(), &end);
  if (end != text.c_str() + text.size() || errno == ERANGE || !std::isfinite(v)) return false;
  *value = v;
  return true;
}

bool ParseInteger(const std::string& text, long* value) {
  if (text.empty() || std::isspace(static_cast<unsigned char>(text[0]))) return false;
  errno = 0;
  char* end = nullptr;
  const long v = std::strtol(text.c_str(), &end, 10);
  if (end != text.c_str() + text.size() || errno == ERANGE) return false;
  *value = v;
  return true;
}

namespace {

// An enum option's spelling into `value`; `why` gets the refusal.
template <typename Enum>
void ReadName(const std::string& text, Enum* value, std::string* why) {
  ParseOptionValue(text, value, why);
}
template <typename Enum>
void ReadName(const std::string& text, std::optional<Enum>* value, std::string* why) {
  Enum v{};
  if (ParseOptionValue(text, &v, why)) *value = v;
}

}  // namespace

std::string ReadOptionText(const OptionText& typed, FormulationOptions* options) {
  FormulationOptions& o = *options;
  std::string why;
  for (const auto& entry : typed) {
    const std::string& flag = entry.first;
    const std::string& text = entry.second;
    const auto number = [&](double* value) {
      if (!ParseReal(text, value)) why = StrCat(flag, " = '", Echo(text), "': ", kRealRule);
    };
    const auto optional_number = [&](std::optional<double>* value) {
      double v = 0.0;
      number(&v);
      *value = v;
    };
    const auto name = [&](auto* value) { ReadName(text, value, &why); };
    if (flag == "--rtol") number(&o.rtol);
    else if (flag == "--atol") number(&o.atol);
    else if (flag == "--step") number(&o.step);
    else if (flag == "--max-step") number(&o.max_step);
    else if (flag == "--rho-inf") number(&o.rho_inf);
    else if (flag == "--alpha-m") optional_number(&o.alpha_m);
    else if (flag == "--alpha-f") optional_number(&o.alpha_f);
    else if (flag == "--beta") optional_number(&o.newmark_beta);
    else if (flag == "--gamma") optional_number(&o.newmark_gamma);
    else if (flag == "--max-steps") {
      if (!ParseInteger(text, &o.max_steps)) {
        why = StrCat("--max-steps = '", Echo(text), "': not an integer in [1, 100000000]");
      }
    } else if (flag == "--integrator") name(&o.integrator);
    else if (flag == "--stabilization") name(&o.stabilization);
    else if (flag == "--constraint-level") name(&o.constraint_level);
    else if (flag == "--jacobian") name(&o.jacobian);
    else if (flag == "--linear-solver") name(&o.linear_solver);
    else if (flag == "--contact-chart") name(&o.contact_chart);
    if (!why.empty()) return why;
  }
  return "";
}

std::string OptionRequest::Shown(const char* flag, double value) const {
  const auto it = typed.find(flag);
  return it != typed.end() ? Echo(it->second) : StrCat(value);
}

bool OptionRequest::Fail(const std::string& message) const {
  if (error) *error = message;
  return false;
}

namespace {

// The rules every formulation shares (StepControl's ranges) and what its registry line
// accepts; the formulation's reader checks the rest (its own options' rules).
bool CheckShared(const OptionRequest& r) {
  const FormulationInfo& info = r.info;
  const FormulationOptions& o = r.options;
  const std::string& name = info.name;
  if (!(std::isfinite(o.rtol) && o.rtol > 0.0 && o.rtol <= kMaxRtol)) {
    return r.Fail(StrCat("--rtol = ", r.Shown("--rtol", o.rtol), "; must lie in ", kRtolRange));
  }
  if (!(std::isfinite(o.atol) && o.atol > 0.0 && o.atol <= kMaxAtol)) {
    return r.Fail(StrCat("--atol = ", r.Shown("--atol", o.atol), "; must lie in ", kAtolRange, " (SI: m, m/s, rad)"));
  }
  if (!(std::isfinite(o.step) && (o.step == 0.0 || (o.step >= 1e-9 && o.step <= 0.1)))) {
    return r.Fail(StrCat("--step = ", r.Shown("--step", o.step),
                         " s; must be 0 (method default) or lie in [1e-9, 0.1] s"));
  }
  if (!(std::isfinite(o.max_step) && o.max_step >= 0.0 && o.max_step <= 100.0)) {
    return r.Fail(StrCat("--max-step = ", r.Shown("--max-step", o.max_step), " s; must lie in [0, 100] s (0: none)"));
  }
  if (o.max_steps < 1 || o.max_steps > 100000000) {
    const auto it = r.typed.find("--max-steps");
    return r.Fail(StrCat("--max-steps = ", it != r.typed.end() ? Echo(it->second) : StrCat(o.max_steps),
                         "; must lie in [1, 100000000]"));
  }
  // What the formulation accepts (its registry line).
  const bool scheme_given = o.alpha_m || o.alpha_f || o.newmark_beta || o.newmark_gamma;
  if (!info.scheme_parameters && (scheme_given || r.typed.count("--rho-inf") || o.rho_inf != FormulationOptions().rho_inf)) {
    return r.Fail(StrCat("--rho-inf / --alpha-m / --alpha-f / --beta / --gamma apply only to ",
                         FormulationsWith(&FormulationInfo::scheme_parameters), ", not to ", name,
                         info.fixed_step ? " (its rule is fixed: beta = 1/4, gamma = 1/2)" : ""));
  }
  if (o.integrator && info.integrators.empty()) {
    return r.Fail(StrCat("--integrator = '", OptionName(*o.integrator), "': formulation '", name,
                         "' has a fixed integrator and takes no --integrator"));
  }
  if (o.integrator && !Accepts(info.integrators, *o.integrator)) {
    return r.Fail(StrCat("--integrator = '", OptionName(*o.integrator), "' is not available for formulation '", name,
                         "'; choose one of: ", Accepted(info.integrators)));
  }
  if (!Accepts(info.stabilizations, o.stabilization)) {
    return r.Fail(StrCat("--stabilization = '", OptionName(o.stabilization), "' is not available for formulation '",
                         name, "'; it accepts: ", Accepted(info.stabilizations)));
  }
  if (!Accepts(info.constraint_levels, o.constraint_level)) {
    return r.Fail(StrCat("--constraint-level = '", OptionName(o.constraint_level),
                         "' is not available for formulation '", name, "'; it accepts: ",
                         Accepted(info.constraint_levels)));
  }
  if (o.jacobian && info.jacobians.empty()) {
    return r.Fail(StrCat("--jacobian = '", OptionName(*o.jacobian), "': formulation '", name,
                         "' forms no Newton matrix of its own; the option does not apply"));
  }
  if (o.jacobian && !Accepts(info.jacobians, *o.jacobian)) {
    return r.Fail(StrCat("--jacobian = '", OptionName(*o.jacobian), "' is not available for formulation '", name,
                         "'; it accepts: ", Accepted(info.jacobians)));
  }
  if (!info.contact_chart && o.contact_chart != FormulationOptions().contact_chart) {
    return r.Fail(StrCat("--contact-chart = '", OptionName(o.contact_chart), "': formulation '", name,
                         "' eliminates the contact coordinates in closed form; the option does not apply"));
  }
  if (o.linear_solver && !Accepts(info.linear_solvers, *o.linear_solver)) {
    return r.Fail(StrCat("--linear-solver = '", OptionName(*o.linear_solver), "': formulation '", name,
                         info.linear_solvers.empty() ? "' solves no IDA Newton system; the option does not apply"
                                                     : "' does not take it"));
  }
  // Step control: a fixed-step method takes --step, an error-controlled one --max-step.
  if (IsFixedStep(info, o.integrator)) {
    if (o.max_step != 0.0) {  // a fixed-step method, or an ODE form with euler or rk4
      const std::string with = info.fixed_step ? "" : StrCat(" with --integrator ", OptionName(*o.integrator));
      return r.Fail(StrCat("--max-step = ", r.Shown("--max-step", o.max_step), " s: ", name, with,
                           " takes fixed steps; use --step"));
    }
  } else if (o.step != 0.0) {
    const std::string with = o.integrator ? StrCat(" with --integrator ", OptionName(*o.integrator)) : "";
    return r.Fail(StrCat("--step = ", r.Shown("--step", o.step), " s: ", name, with,
                         " chooses its own steps under --rtol/--atol",
                         info.integrators.empty() ? "" : " (only euler and rk4 take a fixed step)", "; use --max-step"));
  }
  return true;
}

// The maker, or an empty one with the refusal in *error.
FormulationMaker ConfigureOrRefuse(const FormulationInfo& info, const FormulationOptions& options,
                                   const OptionText& typed, std::string* error) {
  const OptionRequest request{info, options, typed, error};
  if (!CheckShared(request)) return nullptr;
  FormulationMaker maker = info.create(request);
  if (!maker && error->empty()) *error = StrCat("formulation '", info.name, "' refused its options");
  return maker;
}

}  // namespace

bool ValidateOptions(const FormulationInfo& info, const FormulationOptions& options, std::string* error,
                     const OptionText& typed) {
  std::string why;
  if (ConfigureOrRefuse(info, options, typed, &why)) return true;
  if (error) *error = why;
  return false;
}

void CheckOptions(const FormulationInfo& info, const FormulationOptions& options, const OptionText& typed) {
  std::string why;
  if (!ValidateOptions(info, options, &why, typed)) Throw<InputError>("CheckOptions", why);
}

FormulationMaker Configure(const FormulationInfo& info, const FormulationOptions& options, const OptionText& typed) {
  std::string why;
  FormulationMaker maker = ConfigureOrRefuse(info, options, typed, &why);
  if (!maker) Throw<InputError>("CreateFormulation", why);
  return maker;
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

std::vector<FormulationInfo> WithUniqueNames(std::vector<FormulationInfo> formulations) {
  for (size_t i = 0; i < formulations.size(); ++i) {
    for (size_t j = 0; j < i; ++j) {
      if (formulations[i].name == formulations[j].name) {
        throw std::logic_error(StrCat("formulations/registry.cpp: formulation '", formulations[i].name,
                                      "' is registered twice (entries ", j + 1, " and ", i + 1,
                                      "); each name once"));
      }
    }
  }
  return formulations;
}

const FormulationInfo* RegisteredFormulation(const std::string& name) {
  for (const FormulationInfo& info : RegisteredFormulations()) {
    if (info.name == name) return &info;
  }
  return nullptr;
}

std::string FormulationsWith(bool FormulationInfo::*field, bool value) {
  std::string out;
  for (const FormulationInfo& f : RegisteredFormulations()) {
    if (f.*field == value) out += (out.empty() ? "" : ", ") + f.name;
  }
  return out;
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
  return Configure(FindFormulation(name), options)(scene);
}

}  // namespace kneedyn
