// A program linking kneedyn_solver alone (no loader, no formulations): the ctest `layering`
// (tests/layering_test.py) checks with ldd that it pulls in no YAML library, and runs it to
// show the physics library is usable without the loader.
//
// What it runs: the consistent initialization of a free tibia (no contacts, no ligaments)
// under gravity, built in code. Exact answer: the centre of mass accelerates at g (and the
// rotations not at all, the body starting at rest), so q̈ = (g, 0, 0, 0). Exit 0 when the
// hidden level reproduces it to 1e-9 m/s², 1 otherwise.
#include <cmath>
#include <cstdio>

#include "solver/consistent_init.hpp"

int main() {
  using namespace kneedyn;
  Model model;
  model.mass = 4.5;                                  // kg
  model.inertia_T = Vector3d(0.07, 0.07, 0.005);     // kg m²
  model.gravity_F = Vector3d(0.0, -9.81, 0.0);       // m/s²
  InitialState initial;
  initial.q << 0.0, -0.2, 0.0, 0.3, M_PI / 2, 0.1;   // β = 90°: away from the JCS singularity
  const MechanicalState s = ConsistentInitialize(model, initial, {}, ConsistentInitOptions(), nullptr);
  const double err = std::max((s.qdd.head<3>() - model.gravity_F).cwiseAbs().maxCoeff(),
                              s.qdd.tail<3>().cwiseAbs().maxCoeff());
  std::printf("solver_only_probe: max |qdd - (g, 0)| = %.3g\n", err);
  return err <= 1e-9 ? 0 : 1;
}
