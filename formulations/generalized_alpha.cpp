// `generalized-alpha` and `generalized-alpha-reduced`: the reverse EDE of `newmark` (same
// unknowns, residual, Newton solver, step halving and event location: newmark.cpp) with the
// generalized-α scheme of Arnold & Brüls (2007) in its index-3 form (newmark_scheme.hpp).
//
// Why: Newmark's trapezoidal rule (ρ∞ = 1) does not damp the high-frequency error modes of
// the index-3 system, so the normal forces oscillate without decay and the lateral lift-off
// (zero of N_lateral) comes early. Generalized-α with ρ∞ < 1 damps them while staying
// second order in positions, velocities and multipliers.
//
// Options: --rho-inf (default 0.9) gives Chung–Hulbert's αm, αf, β, γ; --alpha-m,
// --alpha-f, --beta, --gamma (all four, γ = 1/2 − αm + αf, αm ≤ αf ≤ 1/2,
// β ≥ 1/4 + (αf − αm)/2) set them explicitly
// (αm = αf = 0, β = 1/4, γ = 1/2 reproduces `newmark`). Fixed step --step (default
// 1e-4 s); --rtol/--atol drive the Newton test as for newmark.
#include "formulations/internal/newmark_scheme.hpp"

#include <cmath>
#include <string>

#include "solver/error.hpp"

namespace kneedyn {
namespace {

// Newmark's options with the scheme asked for: αm, αf, β, γ when given explicitly (all four),
// else Chung–Hulbert from --rho-inf.
bool ReadGeneralizedAlphaOptions(const OptionRequest& request, NewmarkOptions* options) {
  if (!ReadNewmarkOptions(request, options)) return false;
  const FormulationOptions& o = request.options;
  if (!(o.rho_inf >= 0.0 && o.rho_inf <= 1.0)) {
    return request.Fail(StrCat("--rho-inf = ", request.Shown("--rho-inf", o.rho_inf), "; must be in [0, 1]"));
  }
  const std::optional<double>* given_values[] = {&o.alpha_m, &o.alpha_f, &o.newmark_beta, &o.newmark_gamma};
  const char* flags[] = {"--alpha-m", "--alpha-f", "--beta", "--gamma"};
  int given = 0;
  std::string given_list;
  for (int i = 0; i < 4; ++i) {
    if (!given_values[i]->has_value()) continue;
    const double value = **given_values[i];
    ++given;
    given_list += StrCat(given_list.empty() ? "" : ", ", flags[i], " = ", request.Shown(flags[i], value));
    if (!std::isfinite(value)) {
      return request.Fail(StrCat(flags[i], " = ", request.Shown(flags[i], value), "; must be finite"));
    }
  }
  if (given == 0) {
    options->scheme = ChungHulbertScheme(o.rho_inf);
    return true;
  }
  if (given != 4) {
    return request.Fail(StrCat("--alpha-m/--alpha-f/--beta/--gamma: ", given, " of 4 given (", given_list,
                               "); give all four or none (then from --rho-inf)"));
  }
  // The four set the scheme whole: a --rho-inf beside them would be dropped silently.
  if (request.typed.count("--rho-inf") || o.rho_inf != FormulationOptions().rho_inf) {
    return request.Fail(StrCat("--rho-inf = ", request.Shown("--rho-inf", o.rho_inf), " and ", given_list,
                               ": give --rho-inf or the four scheme parameters, not both"));
  }
  const NewmarkScheme scheme{*o.alpha_m, *o.alpha_f, *o.newmark_beta, *o.newmark_gamma};
  if (!(scheme.alpha_m < 1.0 && scheme.alpha_f < 1.0 && scheme.beta > 0.0 && scheme.gamma > 0.0)) {
    return request.Fail(StrCat("generalized-alpha parameters (alpha_m, alpha_f, beta, gamma) = (", scheme.alpha_m,
                               ", ", scheme.alpha_f, ", ", scheme.beta, ", ", scheme.gamma,
                               "); need alpha_m < 1, alpha_f < 1, beta > 0, gamma > 0"));
  }
  // Second order needs γ = 1/2 − αm + αf (Chung & Hulbert 1993; Arnold & Brüls 2007 for the
  // index-3 form). Off it the scheme is first order, which nothing here states or tests (γ
  // raised by 0.1 did not converge on the conservative scene as h went 4e-4 → 5e-5 s).
  // 1e-5: three parameters typed to six decimals are off by up to 1.5e-6 (the default
  // ρ∞ = 0.9 as 0.421053, 0.473684, 0.277008, 0.552632 is accepted).
  const double second_order_gamma = 0.5 - scheme.alpha_m + scheme.alpha_f;
  if (!(std::abs(scheme.gamma - second_order_gamma) <= 1e-5)) {
    return request.Fail(StrCat("--gamma = ", request.Shown("--gamma", scheme.gamma), " with --alpha-m = ", scheme.alpha_m,
                               " and --alpha-f = ", scheme.alpha_f, ": must be 1/2 - alpha_m + alpha_f = ",
                               second_order_gamma, " (within 1e-5) for second order"));
  }
  // Unconditional stability on the linear oscillator needs αm ≤ αf ≤ 1/2 and
  // β ≥ 1/4 + (αf − αm)/2 (Chung & Hulbert 1993); outside it the spectral radius exceeds 1 as
  // ω h grows (αm = 0.3, αf = 0.6 on the Chung–Hulbert β: 1.5), so the fixed step would amplify
  // the stiff ligament and contact modes. Same 1e-5 allowance for typed decimals.
  const double beta_floor = 0.25 + 0.5 * (scheme.alpha_f - scheme.alpha_m);
  if (!(scheme.alpha_m <= scheme.alpha_f + 1e-5 && scheme.alpha_f <= 0.5 + 1e-5 && scheme.beta >= beta_floor - 1e-5)) {
    return request.Fail(StrCat("generalized-alpha parameters (alpha_m, alpha_f, beta) = (", scheme.alpha_m, ", ",
                               scheme.alpha_f, ", ", scheme.beta,
                               "): unconditional stability needs alpha_m <= alpha_f <= 1/2 and beta >= 1/4 + "
                               "(alpha_f - alpha_m)/2 = ",
                               beta_floor, " (within 1e-5)"));
  }
  options->scheme = scheme;
  return true;
}

}  // namespace

FormulationMaker ConfigureGeneralizedAlpha(const OptionRequest& request) {
  NewmarkOptions options;
  if (!ReadGeneralizedAlphaOptions(request, &options)) return nullptr;
  return [options](const Scene& scene) {
    return CreateNewmarkScheme(scene, options, ContactForm::kChapter);
  };
}

FormulationMaker ConfigureGeneralizedAlphaReduced(const OptionRequest& request) {
  NewmarkOptions options;
  if (!ReadGeneralizedAlphaOptions(request, &options)) return nullptr;
  return [options](const Scene& scene) {
    return CreateNewmarkScheme(scene, options, ContactForm::kClosedForm);
  };
}

}  // namespace kneedyn
