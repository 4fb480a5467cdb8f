#include "formulations/formulation.hpp"

#include <cmath>
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

bool FormulationOptions::Parse(ParsedFormulationOptions* out, std::string* error) const {
  auto fail = [&](const std::string& m) {
    if (error) *error = m;
    return false;
  };
  static const std::pair<const char*, IntegratorKind> kIntegrators[] = {
      {"", IntegratorKind::kDopri5},          {"euler", IntegratorKind::kEuler},
      {"rk4", IntegratorKind::kRk4},          {"dopri5", IntegratorKind::kDopri5},
      {"verner65", IntegratorKind::kVerner65}, {"fehlberg78", IntegratorKind::kFehlberg78},
      {"cvode-bdf", IntegratorKind::kCvodeBdf}, {"cvode-adams", IntegratorKind::kCvodeAdams}};
  static const std::pair<const char*, Stabilization> kStabilizations[] = {
      {"none", Stabilization::kNone}, {"baumgarte", Stabilization::kBaumgarte},
      {"projection", Stabilization::kProjection}, {"cvode-projection", Stabilization::kCvodeProjection}};
  static const std::pair<const char*, ConstraintLevel> kLevels[] = {
      {"velocity", ConstraintLevel::kVelocity}, {"position", ConstraintLevel::kPosition}};
  ParsedFormulationOptions parsed;
  bool found = false;
  for (const auto& [text, kind] : kIntegrators) {
    if (integrator == text) parsed.integrator = kind, found = true;
  }
  if (!found) {
    return fail("--integrator = '" + integrator +
                "' is not available; must be euler, rk4, dopri5, verner65, fehlberg78, cvode-bdf or cvode-adams");
  }
  found = false;
  for (const auto& [text, kind] : kStabilizations) {
    if (stabilization == text) parsed.stabilization = kind, found = true;
  }
  if (!found) {
    return fail("--stabilization = '" + stabilization + "'; must be none, baumgarte, projection or cvode-projection");
  }
  found = false;
  for (const auto& [text, kind] : kLevels) {
    if (constraint_level == text) parsed.constraint_level = kind, found = true;
  }
  if (!found) return fail("--constraint-level = '" + constraint_level + "'; must be velocity or position");
  static const std::pair<const char*, JacobianKind> kJacobians[] = {
      {"", JacobianKind::kExact}, {"exact", JacobianKind::kExact}, {"jet", JacobianKind::kJet},
      {"difference-quotient", JacobianKind::kDifferenceQuotient}};
  found = false;
  for (const auto& [text, kind] : kJacobians) {
    if (jacobian == text) parsed.jacobian = kind, found = true;
  }
  if (!found) return fail("--jacobian = '" + jacobian + "'; must be exact, jet or difference-quotient");
  if (out) *out = parsed;
  return true;
}

ParsedFormulationOptions FormulationOptions::Parsed() const {
  ParsedFormulationOptions parsed;
  std::string why;
  if (!Parse(&parsed, &why)) Throw<InputError>("FormulationOptions::Parse", why);
  return parsed;
}

bool FormulationOptions::IsValid(std::string* error) const {
  auto fail = [&](const std::string& m) {
    if (error) *error = m;
    return false;
  };
  if (!(std::isfinite(rtol) && rtol > 0.0 && rtol <= 0.5)) {
    return fail(StrCat("--rtol = ", rtol, "; must lie in (0, 0.5]"));
  }
  if (!(std::isfinite(atol) && atol > 0.0 && atol <= 1e-2)) {
    return fail(StrCat("--atol = ", atol, "; must lie in (0, 1e-2] (SI: m, m/s, rad)"));
  }
  if (!(std::isfinite(step) && (step == 0.0 || (step >= 1e-9 && step <= 0.1)))) {
    return fail(StrCat("--step = ", step, " s; must be 0 (method default) or lie in [1e-9, 0.1] s"));
  }
  if (!(std::isfinite(max_step) && max_step >= 0.0 && max_step <= 100.0)) {
    return fail(StrCat("--max-step = ", max_step, " s; must lie in [0, 100] s (0: none)"));
  }
  if (max_steps < 1 || max_steps > 100000000) {
    return fail(StrCat("--max-steps = ", max_steps, "; must lie in [1, 1e8]"));
  }
  if (!(baumgarte_alpha >= 0.0) || !(baumgarte_beta >= 0.0)) {
    return fail(StrCat("Baumgarte gains (", baumgarte_alpha, ", ", baumgarte_beta, "); must be >= 0"));
  }
  if (!Parse(nullptr, error)) return false;  // the string options, parsed once
  if (!(rho_inf >= 0.0 && rho_inf <= 1.0)) {
    return fail(StrCat("--rho-inf = ", rho_inf, "; must be in [0, 1]"));
  }
  const int given = std::isfinite(alpha_m) + std::isfinite(alpha_f) + std::isfinite(newmark_beta) +
                    std::isfinite(newmark_gamma);
  if (given != 0 && given != 4) {
    return fail(StrCat("--alpha-m/--alpha-f/--beta/--gamma: ", given, " of 4 given (", alpha_m, ", ", alpha_f,
                       ", ", newmark_beta, ", ", newmark_gamma, "); give all four or none (then from --rho-inf)"));
  }
  if (given == 4 && !(alpha_m < 1.0 && alpha_f < 1.0 && newmark_beta > 0.0 && newmark_gamma > 0.0)) {
    return fail(StrCat("generalized-alpha parameters (alpha_m, alpha_f, beta, gamma) = (", alpha_m, ", ", alpha_f,
                       ", ", newmark_beta, ", ", newmark_gamma, "); need alpha_m < 1, alpha_f < 1, beta > 0, gamma > 0"));
  }
  return true;
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

bool IsFixedStep(const FormulationInfo& info, const std::string& integrator) {
  return info.fixed_step || integrator == "euler" || integrator == "rk4";
}

bool HasErrorControl(const FormulationInfo& info, const std::string& integrator) {
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
  if (!options.IsValid(&why)) Throw<InputError>("CreateFormulation", why);
  if (!info.integrators.empty() && !options.integrator.empty()) {
    bool ok = false;
    std::string list;
    for (const std::string& i : info.integrators) {
      ok = ok || i == options.integrator;
      list += (list.empty() ? "" : ", ") + i;
    }
    if (!ok) {
      Throw<InputError>("CreateFormulation", "--integrator = '", options.integrator,
                        "' is not available for formulation '", name, "'; choose one of: ", list);
    }
  } else if (info.integrators.empty() && !options.integrator.empty()) {
    Throw<InputError>("CreateFormulation", "--integrator = '", options.integrator,
                      "': formulation '", name, "' has a fixed integrator and takes no --integrator");
  }
  auto one_of = [](const std::vector<std::string>& values, const std::string& v, std::string* list) {
    bool ok = false;
    for (const std::string& x : values) {
      ok = ok || x == v;
      *list += (list->empty() ? "" : ", ") + x;
    }
    return ok;
  };
  std::string list;
  if (!one_of(info.stabilizations, options.stabilization, &list)) {
    Throw<InputError>("CreateFormulation", "--stabilization = '", options.stabilization,
                      "' is not available for formulation '", name, "'; it accepts: ", list);
  }
  list.clear();
  if (!one_of(info.constraint_levels, options.constraint_level, &list)) {
    Throw<InputError>("CreateFormulation", "--constraint-level = '", options.constraint_level,
                      "' is not available for formulation '", name, "'; it accepts: ", list);
  }
  list.clear();
  if (!options.jacobian.empty() && !one_of(info.jacobians, options.jacobian, &list)) {
    if (info.jacobians.empty()) {
      Throw<InputError>("CreateFormulation", "--jacobian = '", options.jacobian, "': formulation '", name,
                        "' forms no Newton matrix of its own; the option does not apply");
    }
    Throw<InputError>("CreateFormulation", "--jacobian = '", options.jacobian,
                      "' is not available for formulation '", name, "'; it accepts: ", list);
  }
  return info.create(scene, options);
}

}  // namespace kneedyn
