// The one-step scheme behind `newmark` and `generalized-alpha` (newmark.cpp): the
// generalized-α method for constrained mechanical systems in the index-3 form of Arnold &
// Brüls (2007), "Convergence of the generalized-α scheme for constrained mechanical
// systems", Multibody Syst. Dyn. 18:185–202:
//
//   q_{n+1} = q_n + h q̇_n + h² (½ − β) a_n + h² β a_{n+1}
//   q̇_{n+1} = q̇_n + h (1 − γ) a_n + h γ a_{n+1}
//   (1 − αm) a_{n+1} + αm a_n = (1 − αf) q̈_{n+1} + αf q̈_n,     a_0 = q̈_0
//   equations of motion and position-level contact conditions at t_{n+1}
//
// (a: pseudo-acceleration). αm = αf = 0 gives Newmark (a = q̈); β = 1/4, γ = 1/2 its
// average-acceleration rule. Chung & Hulbert (1993) parameters from the spectral radius
// at infinity ρ∞ ∈ [0, 1] (second order, unconditionally stable, maximal high-frequency
// dissipation for that ρ∞):
//   αm = (2ρ∞ − 1)/(ρ∞ + 1),  αf = ρ∞/(ρ∞ + 1),  γ = ½ − αm + αf,  β = ¼ (γ + ½)².
#pragma once

#include <cmath>
#include <memory>

#include "formulations/formulation.hpp"
#include "solver/error.hpp"

namespace kneedyn {

struct NewmarkScheme {
  double alpha_m = 0.0;
  double alpha_f = 0.0;
  double beta = 0.25;
  double gamma = 0.5;
  // Newmark's average acceleration (trapezoidal rule) exactly, the `newmark` formulations' scheme.
  bool IsAverageAcceleration() const { return alpha_m == 0.0 && alpha_f == 0.0 && beta == 0.25 && gamma == 0.5; }
};

inline NewmarkScheme ChungHulbertScheme(double rho_inf) {
  NewmarkScheme s;
  s.alpha_m = (2.0 * rho_inf - 1.0) / (rho_inf + 1.0);
  s.alpha_f = rho_inf / (rho_inf + 1.0);
  s.gamma = 0.5 - s.alpha_m + s.alpha_f;
  s.beta = 0.25 * (s.gamma + 0.5) * (s.gamma + 0.5);
  return s;
}

// The options of newmark, newmark-reduced, generalized-alpha and generalized-alpha-reduced,
// typed and checked.
struct NewmarkOptions {
  StepControl control;  // the fixed step; rtol, atol: the Newton test
  JacobianKind jacobian = JacobianKind::kExact;  // the Newton matrix
  NewmarkScheme scheme;  // newmark: average acceleration; generalized-alpha: ReadGeneralizedAlphaOptions
};
// Reads them from a request (newmark.cpp), with the average-acceleration rule.
bool ReadNewmarkOptions(const OptionRequest& request, NewmarkOptions* options);

// newmark.cpp: the Newmark machinery (Newton, step halving, events) with options.scheme.
std::unique_ptr<Formulation> CreateNewmarkScheme(const Scene& scene, const NewmarkOptions& options,
                                                 ContactForm form);

}  // namespace kneedyn
