// The IDA driver of the chapter DAE (dae.cpp), shared by `dae`/`dae-reduced` and
// `dae-ggl`/`dae-ggl-reduced` (dae_ggl.cpp): the system is formulations/internal/dae_system.hpp; what
// differs between the variants is declared here.
#pragma once

#include <algorithm>
#include <memory>

#include "formulations/internal/dae_system.hpp"
#include "formulations/formulation.hpp"

namespace kneedyn {

struct DaeOnIdaVariant {
  const char* name;  // the formulation's name, in messages
  // Gear–Gupta–Leimkuhler stabilized form (dae_system.hpp); it also stops IDA at every output
  // time (outputs are step values, on which both constraint levels hold).
  bool ggl;
};

// Absolute tolerance of unknown i in IDA's Newton test (dae.cpp, dae_ggl.cpp; also the IDAS
// sensitivities, so that their phases take the formulations' steps). The index-2 unknowns
// (N, newtons, and GGL's μ, m/s: every unknown from NormalIndex(0) on) carry round-off of
// order ε/h² in Newton corrections; they get kForceAtolScale (formulation.hpp) per unit
// --atol, floored at kGglIndexTwoAtolFloor for GGL (dae_ggl.cpp's header comment says why).
constexpr double kGglIndexTwoAtolFloor = 1.0e-3;
inline double DaeUnknownAtol(bool ggl, const DaeSystem& system, int i, double atol) {
  if (i < system.NormalIndex(0)) return atol;
  const double scaled = atol * kForceAtolScale;
  return ggl ? std::max(kGglIndexTwoAtolFloor, scaled) : scaled;
}

// The options of dae, dae-reduced, dae-ggl and dae-ggl-reduced, typed and checked.
struct IdaOptions {
  StepControl control;  // IDA's tolerances, step cap and step budget
  ConstraintLevel constraint_level = ConstraintLevel::kVelocity;  // dae: index 2 | index-3 variant
  JacobianKind jacobian = JacobianKind::kExact;                    // the iteration matrix
};
// Reads them from a request (dae.cpp); the registry line's capabilities have been checked,
// and these formulations have no rule of their own beyond them.
bool ReadIdaOptions(const OptionRequest& request, IdaOptions* options);

std::unique_ptr<Formulation> CreateDaeOnIda(const Scene& scene, const IdaOptions& options,
                                            ContactForm form, const DaeOnIdaVariant& variant);

}  // namespace kneedyn
