// The initial state a run starts from and the condition that ends it: plain data, filled
// by the model builder (model_builder.hpp: BuildInitialState) and the scene loader
// (scene/scene.hpp: the end condition), and
// read by the consistent initialization (consistent_init.hpp) and the events (events.hpp).
// No parsing here: the physics library knows no file format.
#pragma once

#include <array>
#include <optional>
#include <string>
#include <vector>

#include "solver/height_field.hpp"
#include "solver/scalar.hpp"

namespace kneedyn {

// Chapter-form unknowns of one contact: c in `chart` (height field: (xc, yc, x′c, y′c) in m;
// regular: angles in rad, contact.hpp), and N in newtons.
struct ContactGuess {
  std::array<double, 4> coordinates = {0.0, 0.0, 0.0, 0.0};
  // The chart the coordinates are given in (contact.hpp); scenes give height-field (x, y)
  // coordinates, the consistent initialization converts them to the run's chart.
  ContactChart chart = ContactChart::kHeightField;
  double normal_force = 0.0;
};

struct InitialState {
  Vector6d q = Vector6d::Zero();   // SI; the starting point of the position level
  Vector6d qd = Vector6d::Zero();  // SI
  // What the consistent initialization keeps fixed (consistent_init.hpp): coordinates
  // (indices into q) and rates (indices into q̇). Scene key initial_state.hold lists names:
  // x0 … gamma, x0_dot … gamma_dot, or 'velocities' for all six rates. With
  // `pose: assemble` the coordinates the scene gives are the held ones and the others
  // start from the reference pose and are solved (OpenSim's assemble).
  std::vector<int> held;
  std::vector<int> held_velocities;  // indices into q̇ held by the velocity level
  // Per model.contacts entry: starting guesses for the chapter-form unknowns.
  std::vector<ContactGuess> contact_guesses;
  std::string guesses_source;  // "chapter" or "pose"
  // The chapter's DASSL start (docs/model.md §6): the guesses go to the integrator as they are,
  // without the consistent initialization's levels (dae only; scene key initial_state.start).
  bool unprojected = false;
};

// When a run stops: at the first of α reaching `flexion` (if set) and t reaching `time`.
struct EndCondition {
  std::optional<double> flexion;  // rad: stop when α reaches it (event flexion_<deg>)
  double time = 2.0;              // s: stop at this time at the latest
};

}  // namespace kneedyn
