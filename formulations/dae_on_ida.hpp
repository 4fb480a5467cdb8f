// The IDA driver of the chapter DAE (dae.cpp), shared by `dae`/`dae-reduced` and
// `dae-ggl`/`dae-ggl-reduced` (dae_ggl.cpp): the system is formulations/dae_system.hpp; what
// differs between the variants is declared here.
#pragma once

#include <memory>

#include "formulations/formulation.hpp"

namespace kneedyn {

struct DaeOnIdaVariant {
  const char* name;            // the formulation's name, in messages
  bool ggl;                    // Gear–Gupta–Leimkuhler stabilized form (dae_system.hpp)
  // Absolute tolerances of the index-2 unknowns in IDA's Newton test: max(floor, scale · --atol).
  double force_atol_scale;     // N per unit --atol (normal forces)
  double force_atol_floor;     // N
  double mu_atol_scale;        // GGL multipliers μ, m/s per unit --atol
  double mu_atol_floor;        // m/s
  bool stop_at_outputs;        // IDASetStopTime at every output time (outputs are step values)
};

std::unique_ptr<Formulation> CreateDaeOnIda(const Scene& scene, const FormulationOptions& options,
                                            ContactForm form, const DaeOnIdaVariant& variant);

}  // namespace kneedyn
