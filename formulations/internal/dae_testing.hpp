// Test hook for the `dae` / `dae-reduced` residual and IDA Jacobian (tests/dae_test.cpp).
// Not for production use: it builds the DaeSystem that IdaDriver<DaeSystem> drives, sets its
// phase at `state` (no events) and evaluates the members IDA calls.
#pragma once

#include <vector>

#include "formulations/formulation.hpp"

namespace kneedyn {

// F(t, y, ẏ) and, if J is non-null, dF/dy + cj dF/dẏ (the matrix IDA factorizes), for
// the formulation of `form` started at `state` (unknown layout: formulations/dae.cpp).
// `size` (if non-null) receives the number of unknowns. Returns false on a recoverable
// residual failure.
bool DaeResidualAndJacobianForTesting(const Scene& scene, const FormulationOptions& options,
                                      ContactForm form, const MechanicalState& state, double t,
                                      const std::vector<double>& y, const std::vector<double>& yp,
                                      double cj, std::vector<double>* F, MatrixXd* J, int* size);

}  // namespace kneedyn
