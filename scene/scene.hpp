// Scenes: what one run models. A scene file (YAML, human-written) names a parameter set
// under reference-data/ and selects ligaments, contacts, loads, gravity, the ligament-law
// variant, the initial state and the end condition. Only what a scene names is built. See
// reference-data/scenes/README.md for the format and scene/internal/scene_keys.hpp for the table of
// accepted keys and values.
//
// The loader (library kneedyn_scene, parsing with libyaml) only reads: each section of the
// file (scene/internal/sections.hpp) fills a plain description, and the model builder of the physics
// library (solver/model_builder.hpp) turns the descriptions into the Model, InitialState
// and EndCondition the physics functions take; solver/ includes nothing from here.
//
// Every rule a scene can break is reported as InputError naming the file, the field, the
// value and the rule.
#pragma once

#include <array>
#include <optional>
#include <string>
#include <vector>

#include "solver/initial_state.hpp"
#include "solver/model.hpp"
#include "solver/pose.hpp"

namespace kneedyn {

struct Scene {
  std::string path;         // file it was read from
  std::string name;
  std::string description;
  std::string parameter_set;  // name of the parameter set
  std::string parameter_set_file;  // the file it was read from, as found (beside the scene or in the data directory)
  Model model;
  Vector6d reference_q = Vector6d::Zero();  // full extension, SI (docs/model.md §6)
  InitialState initial;
  EndCondition end;
  double output_interval = 0.005;  // s
};

// Practical limits of a run: the end time, and the output grid (a row is a few
// hundred bytes of state; 1e6 rows would be hundreds of MB).
constexpr double kMaxEndTime = 100.0;          // s
constexpr double kMinOutputInterval = 1.0e-6;  // s
constexpr double kMaxOutputRows = 1.0e5;       // end time / output interval

// Whether an output interval (s) is usable up to end_time (s); else `why` says which rule.
bool IsValidOutputInterval(double interval, double end_time, std::string* why);

// Reads and validates a scene file; throws InputError.
Scene LoadScene(const std::string& path);

// Same, from text; `label` stands for the file name in messages and `base_dir` resolves
// the relative parameter-set path.
Scene ParseScene(const std::string& yaml_text, const std::string& label,
                 const std::string& base_dir);

// Directory of the installed reference data (for tools and tests).
std::string ReferenceDataDir();

}  // namespace kneedyn
