// `dae-ggl` and `dae-ggl-reduced`: the Gear–Gupta–Leimkuhler (1985) stabilized index-2
// form of the chapter's system (section 1.3, Eqs. 1.40–1.61) on SUNDIALS IDA; the pattern
// of SUNDIALS' examples/ida/serial/idaSlCrank_dns.c.
//
// `dae` (dae.cpp) enforces only the normal approach velocity φ̇ = G ν = 0, so the gap φ
// drifts between contact-mode switches. GGL enforces both levels and restores the balance
// of equations and unknowns with one extra multiplier μ_i per active contact:
//
//   q̇ = u + Σ_i K_iᵀ μ_i                      K_i = ∂φ_i/∂q = G_i B(q), B = diag(1, E(β, γ))
//   M ν̇ = Q(t, q, ν) + Σ_i N_i G_iᵀ            (Eqs. 1.48–1.57, solver/dynamics.hpp)
//   φ_i(q, c_i) = 0                              (position level: z of Eq. 1.8 / closed-form gap)
//   G_i ν = 0                                    (velocity level, contact.hpp)
//   x, y of Eq. 1.8 and of Eq. 1.13 for c_i     (chapter form only)
//
// ∂φ/∂q = G B holds on the contact manifold (the tangential motion of the contact point
// does not change the gap to first order), so μ = 0 along the exact solution: the
// stabilization changes nothing but the numerical drift. Position-level residuals are
// exactly zero at every step (to the Newton tolerance), without projection.
//
// Unknowns y (k active contacts): q(6), u(6), c(4k, chapter form only), N(k), μ(k); chapter
// n = 12 + 6k (24 for two contacts), closed form n = 12 + 2k. Residual rows: F1–F6 the
// stabilized kinematics, F7–F12 Newton–Euler, per contact (e_x, e_y of Eq. 1.8, x, y of
// Eq. 1.13, φ, Gν) or (φ, Gν).
//
// Scaling and tolerances (IDASVtolerances, per component, given --rtol r and --atol a):
//   q, u, c        a                      (m, rad, m/s, rad/s, m: all O(0.01–1) in SI)
//   N              max(a · 1e4, 1e-3 N)   (forces are O(10²–10³) N, so a force error of
//                                          a·1e4 N weighs like a position error of a m)
//   μ              max(a · 1e4, 1e-3 m/s) (μ is a velocity correction, exactly 0 in theory)
// Why these are loose: N and μ are index-2 unknowns. A Newton error δN, δμ moves u, q by
// h M⁻¹ Gᵀ δN, h K δμ per step, which the weights of u and q already police; N and μ
// themselves carry round-off ε·M·|q|/h² ≈ 2e-3 N and cj·ε·|φ terms| ≈ 1e-17 m / h (at
// h = 1e-7 s), so tighter tolerances make the Newton test fail on round-off at the tiny
// first steps of tight runs; the floors let the tightest settings complete
// (tests/dae_ggl_test.cpp; benchmarks/README.md, "Work-precision sweep"). Scaling the
// unknowns instead (N/N_ref) would be equivalent for IDA's WRMS tests.
// IDASetId marks q, u differential and c, N, μ algebraic; IDASetSuppressAlg excludes the
// algebraic unknowns from the local error test (their BDF error is not O(h^{p+1}) for
// index 2), as in idaSlCrank_dns.c. The system (unknowns, residual, the exact Jacobian
// dF/dy + cj dF/dẏ) is formulations/internal/dae_system.hpp and the IDA driver that of dae
// (dae_on_ida.hpp), both shared with dae; this file declares what GGL changes: the
// stabilized system, the tolerances above and stopping at every output time (with no
// sliver of a step before it: IdaPhase::SolveToStopTime, formulations/internal/ida_phase.hpp).
#include <memory>

#include "formulations/internal/dae_on_ida.hpp"

namespace kneedyn {
namespace {

// The tolerances of the header comment: DaeUnknownAtol (dae_on_ida.hpp).
constexpr DaeOnIdaVariant kGgl = {"dae-ggl", true};
constexpr DaeOnIdaVariant kGglReduced = {"dae-ggl-reduced", true};

}  // namespace

FormulationMaker ConfigureDaeGgl(const OptionRequest& request) {
  IdaOptions options;
  if (!ReadIdaOptions(request, &options)) return nullptr;
  return [options](const Scene& scene) { return CreateDaeOnIda(scene, options, ContactForm::kChapter, kGgl); };
}
FormulationMaker ConfigureDaeGglReduced(const OptionRequest& request) {
  IdaOptions options;
  if (!ReadIdaOptions(request, &options)) return nullptr;
  return [options](const Scene& scene) {
    return CreateDaeOnIda(scene, options, ContactForm::kClosedForm, kGglReduced);
  };
}

}  // namespace kneedyn
