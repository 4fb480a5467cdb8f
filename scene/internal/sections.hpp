// The scene loader's sections: each reads one part of a scene or parameter-set file into
// the plain descriptions of the model builder (solver/model_builder.hpp). They only read
// and check what the file says; what follows from it (reference pose, slack lengths, k_par,
// initial guesses) is the builder's. Internal to kneedyn_scene.
#pragma once

#include <map>
#include <string>

#include "scene/scene.hpp"
#include "scene/internal/yaml_field.hpp"
#include "solver/model_builder.hpp"

namespace kneedyn::scene_detail {

// A parameter set file (parameter_set.cpp).
struct ParameterSet {
  std::string name;
  std::string file;                    // the file it was read from (LoadParameterSet)
  double mass = 0.0;                   // kg
  Vector3d inertia_T;                  // kg m²
  double g = 0.0;                      // m/s²
  Vector3d gravity_direction_F;        // not normalised
  std::map<std::string, SurfacePair> compartments;  // "medial", "lateral"
  std::vector<Ligament> ligaments;     // attachments and stiffnesses, SI
  Vector6d reference_q = Vector6d::Zero();
  std::array<std::optional<ChapterContactGuess>, kMaxContacts> chapter_guesses;
};
ParameterSet LoadParameterSet(const std::string& path);

// A compartment's two surfaces (surfaces.cpp).
SurfacePair ParseCompartment(const Field& f);

// Scene sections. `top` is the scene's top level.
void ParseBody(const Field& top, const ParameterSet& ps, ModelDescription* model);          // loads.cpp
void ParseGravity(const Field& top, const ParameterSet& ps, ModelDescription* model);       // loads.cpp
void ParsePulse(const Field& top, ModelDescription* model);                                 // loads.cpp
void ParseConstantLoad(const Field& top, ModelDescription* model);                          // loads.cpp
void ParsePatella(const Field& top, ModelDescription* model);                               // patella.cpp
void ParseLigaments(const Field& top, const ParameterSet& ps, ModelDescription* model);     // ligaments.cpp
void ParseContacts(const Field& top, const ParameterSet& ps, ModelDescription* model);      // surfaces.cpp
// Refuses a key of `section` that names no compartment of the model's contacts: nothing would
// read it (surfaces.cpp).
void RefuseCompartmentsNotInContacts(const Field& section, const ModelDescription& model);
InitialStateRequest ParseInitialState(const Field& top, const ParameterSet& ps,
                                      const ModelDescription& model);                       // initial_state.cpp
void ParseEndAndOutput(const Field& top, Scene* scene);                                     // end_condition.cpp

}  // namespace kneedyn::scene_detail
