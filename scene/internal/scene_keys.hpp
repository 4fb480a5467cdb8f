// The one table of what a scene file and a parameter set accept: the keys of each mapping
// and the values of each enumerated field. The loader's key checks and messages read it;
// tests/scene_test.cpp checks it against the format document
// (reference-data/scenes/README.md) and the fuzzer's dictionary (fuzz/yaml.dict), so the
// three cannot drift apart. Adding a key or a value starts here; a surface type's keys and
// name come from the type itself (solver/surface_types.hpp).
#pragma once

#include <string>
#include <string_view>
#include <vector>

namespace kneedyn {

struct SceneKeyTable {
  const char* mapping;               // e.g. "scene", "scene.pulse", "surface.plane"
  std::vector<const char*> entries;  // its keys, or the accepted values of a field
};

// Mappings and their keys. "scene" is a scene file's top level, "parameter_set" a
// parameter set's; "surface.TYPE" a surface of that type.
const std::vector<SceneKeyTable>& SceneMappingKeys();
// Enumerated fields and their values ("scene.pulse.shape": the pulse shapes).
const std::vector<SceneKeyTable>& SceneFieldValues();

// The keys of one mapping, the values of one field (std::logic_error if not in the table).
// By string_view: a literal name costs no std::string (a heap one past 15 characters).
const std::vector<const char*>& KeysOf(std::string_view mapping);
const std::vector<const char*>& ValuesOf(std::string_view field);

}  // namespace kneedyn
