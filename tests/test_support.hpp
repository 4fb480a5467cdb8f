// Helpers shared by the GoogleTest suites: where the scenes are, the chapter scene, and the
// registered formulations as test parameters (so a new formulation enters every
// parameterized suite through its registry line alone).
#pragma once

#include <gtest/gtest.h>

#include <cctype>
#include <fstream>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "formulations/formulation.hpp"
#include "formulations/run.hpp"
#include "solver/contact_kinematics.hpp"
#include "scene/scene.hpp"

namespace kneedyn::test_support {

// The sphere-on-plane data of a pair that must have one (chapter surfaces).
inline SphereOnPlane SopOf(const ContactPair& pair) {
  SphereOnPlane s;
  EXPECT_TRUE(SphereOnPlaneForm(pair, &s)) << "not a sphere on a plane";
  return s;
}

inline std::string ScenesDir() { return ReferenceDataDir() + "/scenes"; }

// reference-data/scenes/chapter_impact.yaml, loaded once.
inline const Scene& ChapterScene() {
  static const Scene scene = LoadScene(ScenesDir() + "/chapter_impact.yaml");
  return scene;
}

// chapter_impact.yaml with its initial_state and end replaced (YAML flow text, e.g.
// "{pose: assemble, coordinates: {alpha_deg: 30}}" and "{time_s: 0.02}") and `extra` top-level
// lines added before its output block.
inline Scene ChapterSceneWith(const std::string& initial_state, const std::string& end,
                              const std::string& extra = "") {
  std::ifstream file(ScenesDir() + "/chapter_impact.yaml");
  std::stringstream buffer;
  buffer << file.rdbuf();
  std::string text = buffer.str();
  const size_t from = text.find("initial_state:"), to = text.find("\noutput:");
  EXPECT_NE(from, std::string::npos);
  EXPECT_NE(to, std::string::npos);
  if (from == std::string::npos || to == std::string::npos) return ChapterScene();
  text.replace(from, to - from, "initial_state: " + initial_state + "\nend: " + end + "\n" + extra);
  return ParseScene(text, "chapter_variant.yaml", ScenesDir());
}

// A shipped scene (e.g. "anatomical_surfaces.yaml") with lines of its text replaced: each
// edit's first string must occur in the file (a failure names it).
inline Scene ShippedSceneWith(const std::string& file_name,
                              const std::vector<std::pair<std::string, std::string>>& edits) {
  std::ifstream file(ScenesDir() + "/" + file_name);
  std::stringstream buffer;
  buffer << file.rdbuf();
  std::string text = buffer.str();
  for (const auto& [from, to] : edits) {
    const size_t at = text.find(from);
    EXPECT_NE(at, std::string::npos) << "not in " << file_name << ": " << from;
    if (at != std::string::npos) text.replace(at, from.size(), to);
  }
  return ParseScene(text, "edited_" + file_name, ScenesDir());
}

// anatomical_surfaces.yaml edited into one contact phase of 1 s (to 40.6 degrees of flexion and
// back; the 45-degree end is not reached): gravity off, a damped sine of 250 N, the C1 law (no
// kink restarts).
inline Scene AnatomicalSinglePhaseScene() {
  return ShippedSceneWith("anatomical_surfaces.yaml",
                          {{"gravity: {enabled: true}", "gravity: {enabled: false}"},
                           {"ligament_law: published", "ligament_law: c1_continuous"},
                           {"pulse: {shape: reconstructed, amplitude_N: 100.0, duration_s: 0.1}",
                            "pulse: {shape: damped_sine, amplitude_N: 250.0, duration_s: 0.1}"},
                           {"end: {flexion_deg: 60.0, time_s: 2.0}", "end: {flexion_deg: 45.0, time_s: 1.0}"}});
}

// Run settings for `formulation` at the tolerances rtol, atol (defaults otherwise).
inline RunSettings SettingsAt(const std::string& formulation, double rtol, double atol) {
  RunSettings settings;
  settings.formulation = formulation;
  settings.options.rtol = rtol;
  settings.options.atol = atol;
  return settings;
}

// Those that run the tibio-femoral scenes (not the ones that need a patella).
inline std::vector<std::string> RegisteredFormulationNames() {
  std::vector<std::string> names;
  for (const FormulationInfo& info : RegisteredFormulations()) {
    if (!info.needs_patella) names.push_back(info.name);
  }
  return names;
}

// GoogleTest parameter names allow [A-Za-z0-9_]: "dae-reduced" -> "dae_reduced".
struct FormulationParamName {
  std::string operator()(const ::testing::TestParamInfo<std::string>& info) const {
    std::string n = info.param;
    for (char& c : n) {
      if (!std::isalnum(static_cast<unsigned char>(c))) c = '_';
    }
    return n;
  }
};

}  // namespace kneedyn::test_support
