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
// --alpha-f, --beta, --gamma (all four) set them explicitly (αm = αf = 0, β = 1/4, γ = 1/2
// reproduces `newmark`). Fixed step --step (default 1e-4 s); --rtol/--atol drive the Newton
// test as for newmark.
#include "formulations/internal/newmark_scheme.hpp"

namespace kneedyn {

std::unique_ptr<Formulation> CreateGeneralizedAlpha(const Scene& scene, const FormulationOptions& options) {
  return CreateNewmarkScheme(scene, options, ContactForm::kChapter, SchemeFromOptions(options),
                             "generalized-alpha");
}

std::unique_ptr<Formulation> CreateGeneralizedAlphaReduced(const Scene& scene,
                                                           const FormulationOptions& options) {
  return CreateNewmarkScheme(scene, options, ContactForm::kClosedForm, SchemeFromOptions(options),
                             "generalized-alpha-reduced");
}

}  // namespace kneedyn
