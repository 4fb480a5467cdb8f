// The formulation registry: one line per formulation (formulation.hpp).
#include "formulations/formulation.hpp"

namespace kneedyn {

std::unique_ptr<Formulation> CreateDae(const Scene&, const FormulationOptions&);
std::unique_ptr<Formulation> CreateDaeReduced(const Scene&, const FormulationOptions&);
std::unique_ptr<Formulation> CreateDaeGgl(const Scene&, const FormulationOptions&);
std::unique_ptr<Formulation> CreateDaeGglReduced(const Scene&, const FormulationOptions&);
std::unique_ptr<Formulation> CreateNewmark(const Scene&, const FormulationOptions&);
std::unique_ptr<Formulation> CreateNewmarkReduced(const Scene&, const FormulationOptions&);
std::unique_ptr<Formulation> CreateGeneralizedAlpha(const Scene&, const FormulationOptions&);
std::unique_ptr<Formulation> CreateGeneralizedAlphaReduced(const Scene&, const FormulationOptions&);
std::unique_ptr<Formulation> CreateMde(const Scene&, const FormulationOptions&);
std::unique_ptr<Formulation> CreateEde(const Scene&, const FormulationOptions&);

const std::vector<FormulationInfo>& RegisteredFormulations() {
  static const std::vector<FormulationInfo> kRegistry = {
      {"dae", "chapter's index-2 DAE (modified reverse EDE), contact coordinates, IDA", {}, CreateDae},
      {"dae-reduced", "index-2 DAE with closed-form sphere-on-plane contact, IDA", {}, CreateDaeReduced},
      {"dae-ggl", "Gear-Gupta-Leimkuhler stabilized index-2 DAE (position and velocity constraints), contact coordinates, IDA", {}, CreateDaeGgl},
      {"dae-ggl-reduced", "GGL stabilized index-2 DAE with closed-form sphere-on-plane contact, IDA", {}, CreateDaeGglReduced},
      {"newmark", "chapter's reverse EDE: Newmark average acceleration, position-level contact coordinates, Newton", {}, CreateNewmark, /*fixed_step=*/true},
      {"newmark-reduced", "reverse EDE with closed-form sphere-on-plane gap, Newmark average acceleration", {}, CreateNewmarkReduced, /*fixed_step=*/true},
      {"generalized-alpha", "reverse EDE with the generalized-alpha scheme (Arnold-Bruels index 3, Chung-Hulbert --rho-inf), contact coordinates, Newton", {}, CreateGeneralizedAlpha, /*fixed_step=*/true},
      {"generalized-alpha-reduced", "generalized-alpha with closed-form sphere-on-plane gap", {}, CreateGeneralizedAlphaReduced, /*fixed_step=*/true},
      {"mde", "minimal ODE: closed-form elimination of the contact translations, projected Newton-Euler", {"euler", "rk4", "dopri5", "verner65", "fehlberg78", "cvode-bdf", "cvode-adams"}, CreateMde},
      {"ede", "excess ODE in (q, qdot) with the hidden constraint; --stabilization none|baumgarte|projection|cvode-projection", {"euler", "rk4", "dopri5", "verner65", "fehlberg78", "cvode-bdf", "cvode-adams"}, CreateEde},
  };
  return kRegistry;
}

}  // namespace kneedyn
