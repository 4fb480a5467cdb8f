// The formulation registry: one line per formulation (formulation.hpp). A line names the
// formulation, says what it is, gives its factory (KNEEDYN_FACTORY declares the Configure
// function defined in the formulation's own file, which reads the formulation's typed
// options) and sets, by name, the capabilities that differ from FormulationInfo's defaults.
#include "formulations/formulation.hpp"

namespace kneedyn {
namespace {

const std::vector<IntegratorKind> kOdeIntegrators = {
    IntegratorKind::kEuler,      IntegratorKind::kRk4,      IntegratorKind::kDopri5,    IntegratorKind::kVerner65,
    IntegratorKind::kFehlberg78, IntegratorKind::kCvodeBdf, IntegratorKind::kCvodeAdams};
const std::vector<ConstraintLevel> kBothLevels = {ConstraintLevel::kVelocity, ConstraintLevel::kPosition};
const std::vector<JacobianKind> kIdaJacobians = {JacobianKind::kExact, JacobianKind::kJet,
                                                 JacobianKind::kDifferenceQuotient};
const std::vector<LinearSolverKind> kIdaLinearSolvers = {LinearSolverKind::kStructured, LinearSolverKind::kDense};
const std::vector<JacobianKind> kNewtonJacobians = {JacobianKind::kExact, JacobianKind::kJet};

}  // namespace

const std::vector<FormulationInfo>& RegisteredFormulations() {
  static const std::vector<FormulationInfo> kRegistry = WithUniqueNames({
      FormulationInfo("dae", "chapter's index-2 DAE (modified reverse EDE), contact coordinates, IDA", KNEEDYN_FACTORY(ConfigureDae)).UnprojectedStart().AlgebraicForces().ConstraintLevels(kBothLevels).Jacobians(kIdaJacobians).LinearSolvers(kIdaLinearSolvers).Sensitivity(SensitivityForm::kDae),
      FormulationInfo("dae-reduced", "index-2 DAE with closed-form sphere-on-plane contact, IDA", KNEEDYN_FACTORY(ConfigureDaeReduced)).AlgebraicForces().ConstraintLevels(kBothLevels).Jacobians(kIdaJacobians).LinearSolvers(kIdaLinearSolvers).Sensitivity(SensitivityForm::kDae),
      FormulationInfo("dae-ggl", "Gear-Gupta-Leimkuhler stabilized index-2 DAE (position and velocity constraints), contact coordinates, IDA", KNEEDYN_FACTORY(ConfigureDaeGgl)).AlgebraicForces().Jacobians(kIdaJacobians).LinearSolvers(kIdaLinearSolvers).Sensitivity(SensitivityForm::kDaeGgl),
      FormulationInfo("dae-ggl-reduced", "GGL stabilized index-2 DAE with closed-form sphere-on-plane contact, IDA", KNEEDYN_FACTORY(ConfigureDaeGglReduced)).AlgebraicForces().Jacobians(kIdaJacobians).LinearSolvers(kIdaLinearSolvers).Sensitivity(SensitivityForm::kDaeGgl),
      FormulationInfo("newmark", "chapter's reverse EDE: Newmark average acceleration, position-level contact coordinates, Newton", KNEEDYN_FACTORY(ConfigureNewmark)).FixedStep().AlgebraicForces().Jacobians(kNewtonJacobians),
      FormulationInfo("newmark-reduced", "reverse EDE with closed-form sphere-on-plane gap, Newmark average acceleration", KNEEDYN_FACTORY(ConfigureNewmarkReduced)).FixedStep().AlgebraicForces().Jacobians(kNewtonJacobians),
      FormulationInfo("generalized-alpha", "reverse EDE with the generalized-alpha scheme (Arnold-Bruels index 3, Chung-Hulbert --rho-inf), contact coordinates, Newton", KNEEDYN_FACTORY(ConfigureGeneralizedAlpha)).FixedStep().AlgebraicForces().Jacobians(kNewtonJacobians).SchemeParameters(),
      FormulationInfo("generalized-alpha-reduced", "generalized-alpha with closed-form sphere-on-plane gap", KNEEDYN_FACTORY(ConfigureGeneralizedAlphaReduced)).FixedStep().AlgebraicForces().Jacobians(kNewtonJacobians).SchemeParameters(),
      FormulationInfo("mde", "minimal ODE: closed-form elimination of the contact translations, projected Newton-Euler", KNEEDYN_FACTORY(ConfigureMde)).Integrators(kOdeIntegrators).NoContactChart(),
      FormulationInfo("ede", "excess ODE in (q, qdot) with the hidden constraint; --stabilization none|baumgarte|projection|cvode-projection", KNEEDYN_FACTORY(ConfigureEde)).Integrators(kOdeIntegrators).Stabilizations({Stabilization::kNone, Stabilization::kBaumgarte, Stabilization::kProjection, Stabilization::kCvodeProjection}).Sensitivity(SensitivityForm::kOde),
      FormulationInfo("staggered", "the chapter's staggered tibia-patella procedure (section 1.7): the tendon force lagged one step --step, dopri5 inside a step", KNEEDYN_FACTORY(ConfigureStaggered)).FixedStep().NeedsPatella().NoContactChart(),
      FormulationInfo("monolithic", "the chapter's monolithic tibia-patella DAE (section 1.7): dae's index-2 DAE plus the patella's 17 equilibrium unknowns as algebraic variables, IDA", KNEEDYN_FACTORY(ConfigureMonolithic)).AlgebraicForces().ConstraintLevels(kBothLevels).Jacobians(kIdaJacobians).LinearSolvers(kIdaLinearSolvers).NeedsPatella(),
      FormulationInfo("monolithic-ggl", "the monolithic tibia-patella DAE with the tibia in the Gear-Gupta-Leimkuhler stabilized form (dae-ggl), IDA", KNEEDYN_FACTORY(ConfigureMonolithicGgl)).AlgebraicForces().Jacobians(kIdaJacobians).LinearSolvers(kIdaLinearSolvers).NeedsPatella(),
  });
  return kRegistry;
}

}  // namespace kneedyn
