// The formulation registry: one line per formulation (formulation.hpp), with its
// capabilities; KNEEDYN_FACTORY declares the Create function defined in the formulation's file.
// Fields: name, summary, integrators, factory, fixed_step, algebraic_forces, stabilizations,
// constraint_levels (then general_surfaces, event_location: true unless given; jacobians: the
// --jacobian values, none unless given; sensitivity: the form's forward sensitivities, none
// unless given).
#include "formulations/formulation.hpp"

namespace kneedyn {

const std::vector<FormulationInfo>& RegisteredFormulations() {
  static const std::vector<FormulationInfo> kRegistry = {
      {"dae", "chapter's index-2 DAE (modified reverse EDE), contact coordinates, IDA", {}, KNEEDYN_FACTORY(CreateDae), false, true, {"none"}, {"velocity", "position"}, true, true, {"exact", "jet", "difference-quotient"}, SensitivityForm::kDae},
      {"dae-reduced", "index-2 DAE with closed-form sphere-on-plane contact, IDA", {}, KNEEDYN_FACTORY(CreateDaeReduced), false, true, {"none"}, {"velocity", "position"}, true, true, {"exact", "jet", "difference-quotient"}, SensitivityForm::kDae},
      {"dae-ggl", "Gear-Gupta-Leimkuhler stabilized index-2 DAE (position and velocity constraints), contact coordinates, IDA", {}, KNEEDYN_FACTORY(CreateDaeGgl), false, true, {"none"}, {"velocity"}, true, true, {"exact", "jet", "difference-quotient"}, SensitivityForm::kDaeGgl},
      {"dae-ggl-reduced", "GGL stabilized index-2 DAE with closed-form sphere-on-plane contact, IDA", {}, KNEEDYN_FACTORY(CreateDaeGglReduced), false, true, {"none"}, {"velocity"}, true, true, {"exact", "jet", "difference-quotient"}, SensitivityForm::kDaeGgl},
      {"newmark", "chapter's reverse EDE: Newmark average acceleration, position-level contact coordinates, Newton", {}, KNEEDYN_FACTORY(CreateNewmark), true, true, {"none"}, {"velocity"}, true, true, {"exact", "jet"}},
      {"newmark-reduced", "reverse EDE with closed-form sphere-on-plane gap, Newmark average acceleration", {}, KNEEDYN_FACTORY(CreateNewmarkReduced), true, true, {"none"}, {"velocity"}, true, true, {"exact", "jet"}},
      {"generalized-alpha", "reverse EDE with the generalized-alpha scheme (Arnold-Bruels index 3, Chung-Hulbert --rho-inf), contact coordinates, Newton", {}, KNEEDYN_FACTORY(CreateGeneralizedAlpha), true, true, {"none"}, {"velocity"}, true, true, {"exact", "jet"}},
      {"generalized-alpha-reduced", "generalized-alpha with closed-form sphere-on-plane gap", {}, KNEEDYN_FACTORY(CreateGeneralizedAlphaReduced), true, true, {"none"}, {"velocity"}, true, true, {"exact", "jet"}},
      {"mde", "minimal ODE: closed-form elimination of the contact translations, projected Newton-Euler", {"euler", "rk4", "dopri5", "verner65", "fehlberg78", "cvode-bdf", "cvode-adams"}, KNEEDYN_FACTORY(CreateMde)},
      {"ede", "excess ODE in (q, qdot) with the hidden constraint; --stabilization none|baumgarte|projection|cvode-projection", {"euler", "rk4", "dopri5", "verner65", "fehlberg78", "cvode-bdf", "cvode-adams"}, KNEEDYN_FACTORY(CreateEde), false, false, {"none", "baumgarte", "projection", "cvode-projection"}, {"velocity"}, true, true, {}, SensitivityForm::kOde},
  };
  return kRegistry;
}

}  // namespace kneedyn
