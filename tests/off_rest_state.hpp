// A consistent state moved off rest for the derivative checks of the DAE systems
// (dae_system_test, monolithic_test): the residual need not vanish there.
#pragma once

#include <random>

#include "solver/dynamics.hpp"
#include "solver/pose.hpp"
#include "solver/state.hpp"
#include "solver/units.hpp"

namespace kneedyn::test_support {

// At t = 0.03 s (inside the pulse), from rng in this order: translational rates ±0.05 m/s,
// angular rates ±1 rad/s, accelerations ±5; flexion +20° off the reference pose, where the
// ligaments sit at their slack length (a kink of the law that central differences would
// straddle); the ligament branches there.
inline void MoveOffRest(const Model& model, std::mt19937* rng, MechanicalState* s) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  s->t = 0.03;
  for (int i = 0; i < 3; ++i) s->qd(i) = 0.05 * u(*rng);
  for (int i = 3; i < 6; ++i) s->qd(i) = 1.0 * u(*rng);
  for (int i = 0; i < 6; ++i) s->qdd(i) = 5.0 * u(*rng);
  s->q(kAlpha) += DegToRad(20.0);
  s->ligament_branch = LigamentBranchesAt(model, s->q, s->qd);
}

}  // namespace kneedyn::test_support
