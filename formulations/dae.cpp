// `dae` and `dae-reduced`: the chapter's modified reverse EDE (section 1.3), an index-2
// DAE, on SUNDIALS IDA (DASSL's maintained successor).
//
// Unknowns y (chapter form, k active contacts, n = 12 + 5k: 22 two-point, 17 one-point):
//   q = (x0, y0, z0, α, β, γ), u = (vx, vy, vz, ωα, ωβ, ωγ),
//   c_i = (xc, yc, x′c, y′c) per contact, then N_i per contact.
// Residuals F(t, y, ẏ) (Eqs. 1.40–1.61):
//   F1–F6    u − q̇                                          (kinematic, Eqs. 1.40–1.47)
//   F7–F9    ΣF − m v̇                                        (Newton, in F)
//   F10–F12  ΣM′ − I ẇ − w × I w, ẇ = E u̇_ang + Ė u_ang     (Euler, in T; docs/model.md §2 exact E)
//   per contact: x, y of Eq. 1.8; the normal condition; x, y of Eq. 1.13.
// The normal condition: the printed F15/F18 (z of Eq. 1.8, a position-level constraint)
// makes the system index 3, not the index 2 the chapter states. kneedyn's `dae` uses its
// time derivative, the normal approach velocity φ̇ = G ν = 0 (contact.hpp), so that the
// contact coordinates are index 1 and the forces index 2 — the semi-explicit index-2 form
// the chapter describes. `--constraint-level position` keeps the printed position-level
// condition (the index-3 variant, --constraint-level position). Position drift of the velocity-level form is
// reported in every trajectory row (gap_*_mm).
//
// `dae-reduced`: the same physics with the closed-form sphere-on-plane contact:
// y = (q, u, N_i), n = 12 + k, constraint φ̇_i = 0 (or φ_i = 0 at position level).
//
// The system itself (unknowns, residual rows, exact Jacobian) is formulations/internal/dae_system.hpp,
// shared with dae-ggl and the IDAS sensitivities. The IDA driver (IdaDriver<DaeSystem>,
// formulations/internal/dae_on_ida.hpp) serves dae, dae-reduced and, with the GGL variant of
// dae_ggl.cpp, dae-ggl and dae-ggl-reduced.
//
// IDA settings: IDASetId (q, u differential; c, N algebraic) with IDASetSuppressAlg, so
// the index-2 algebraic variables are excluded from the error test; dense Jacobian
// dF/dy + cj dF/dẏ exact from the system's blocks (--jacobian jet: the Jet<24> reference;
// difference-quotient: IDA's own), solved with q eliminated through F1–F6 before an LU of
// the other n − 6 unknowns (--linear-solver structured, kinematic_block_solver.hpp; dense:
// SUNDIALS' LU of the whole matrix); root functions from solver/events.hpp.
// Every phase starts IDA from the driver's consistent state: IDAReInit when the phase has as
// many unknowns as the last (a kink crossing), IDA rebuilt at the new size after a
// contact-mode switch (IDAReInit cannot change the size). IDACalcIC is not used (it is only
// valid for index 1);
// the initial y, ẏ come from the consistent initialization.
#include <idas/idas.h>
#include <sunlinsol/sunlinsol_dense.h>
#include <sunmatrix/sunmatrix_dense.h>

#include <algorithm>
#include <cmath>
#include <memory>

#include "formulations/internal/dae_on_ida.hpp"
#include "formulations/internal/dae_system.hpp"
#include "formulations/internal/dae_testing.hpp"
#include "formulations/internal/formulation_base.hpp"
#include "formulations/internal/ida_phase.hpp"
#include "formulations/internal/sundials_util.hpp"
#include "solver/dynamics.hpp"

namespace kneedyn {
namespace {

constexpr DaeOnIdaVariant kPlain = {"dae", false};
constexpr DaeOnIdaVariant kPlainReduced = {"dae-reduced", false};

}  // namespace

bool ReadIdaOptions(const OptionRequest& request, IdaOptions* options) {
  const FormulationOptions& o = request.options;
  options->control = o.step_control();
  options->constraint_level = o.constraint_level;
  options->jacobian = o.jacobian.value_or(JacobianKind::kExact);
  options->linear_solver = o.linear_solver.value_or(LinearSolverKind::kStructured);
  return true;
}

std::unique_ptr<Formulation> CreateDaeOnIda(const Scene& scene, const IdaOptions& options,
                                            ContactForm form, const DaeOnIdaVariant& variant) {
  return std::make_unique<IdaDriver<DaeSystem>>(scene, options, form, variant, scene.model, form,
                                                options.constraint_level, variant.ggl);
}

FormulationMaker ConfigureDae(const OptionRequest& request) {
  IdaOptions options;
  if (!ReadIdaOptions(request, &options)) return nullptr;
  return [options](const Scene& scene) { return CreateDaeOnIda(scene, options, ContactForm::kChapter, kPlain); };
}
FormulationMaker ConfigureDaeReduced(const OptionRequest& request) {
  IdaOptions options;
  if (!ReadIdaOptions(request, &options)) return nullptr;
  return [options](const Scene& scene) {
    return CreateDaeOnIda(scene, options, ContactForm::kClosedForm, kPlainReduced);
  };
}

// Test hook (dae_testing.hpp).
bool DaeResidualAndJacobianForTesting(const Scene& scene, const FormulationOptions& options,
                                      ContactForm form, const MechanicalState& state, double t,
                                      const std::vector<double>& y, const std::vector<double>& yp,
                                      double cj, std::vector<double>* F, MatrixXd* J, int* size) {
  DaeSystem system(scene.model, form, options.constraint_level, /*ggl=*/false);
  system.SetPhase(state.active, state.contact, state.ligament_branch);
  const int n = system.size();
  if (size) *size = n;
  if (static_cast<int>(y.size()) != n || static_cast<int>(yp.size()) != n) return false;
  if (F) {
    F->assign(n, 0.0);
    if (!system.Residual(t, y.data(), yp.data(), F->data())) return false;
  }
  if (J) {
    J->resize(n, n);
    const bool ok = options.jacobian == JacobianKind::kJet
                        ? system.JacobianByJets(t, cj, y.data(), yp.data(), J->data())
                        : system.Jacobian(t, cj, y.data(), yp.data(), J->data());
    if (!ok) return false;
  }
  return true;
}

}  // namespace kneedyn
