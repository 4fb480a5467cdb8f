// Test hook for the Newton tangent of newmark, newmark-reduced, generalized-alpha and
// generalized-alpha-reduced (tests/newmark_test.cpp, ExactTangentEqualsTheJetTangent). Not
// for production use: it builds the formulation, starts it at `state` (no events) and
// evaluates the step's tangent both ways.
#pragma once

#include "formulations/internal/newmark_scheme.hpp"

namespace kneedyn {

// ∂F/∂x of the step of size h (s) from `state`: `exact` by the structured assembly (what
// --jacobian exact factorizes), `jet` by one Jet<24> pass of the residual (--jacobian jet),
// both at the same x: the step's predictor, moved by `newton_steps` Newton steps. False when
// an evaluation fails there.
bool NewmarkTangentsForTesting(const Scene& scene, const NewmarkOptions& options, ContactForm form,
                               const MechanicalState& state, double h, int newton_steps, MatrixXd* exact,
                               MatrixXd* jet);

}  // namespace kneedyn
