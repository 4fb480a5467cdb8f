// What the fuzz targets share: the private directory of one fuzzing process (the targets
// write their input there as the files the code under test reads by path), the split of an
// input into two files at a marker line, and the cheap first physics of a run.
#pragma once

#include <unistd.h>

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <optional>
#include <string>
#include <vector>

#include "scene/scene.hpp"
#include "solver/constrained_dynamics.hpp"
#include "solver/dynamics.hpp"

namespace kneedyn_fuzz {

inline const std::string& WorkDir() {
  static const std::string dir = [] {
    const std::filesystem::path p =
        std::filesystem::temp_directory_path() / ("kneedyn_fuzz_" + std::to_string(::getpid()));
    std::filesystem::create_directories(p);
    return p.string();
  }();
  return dir;
}

inline void WriteFile(const std::string& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out << text;
}

// An input "FIRST\n<marker>\nSECOND" (the marker line, e.g. "#@params"): FIRST, and SECOND
// when the marker line is there.
struct SplitInput {
  std::string first;
  std::optional<std::string> second;
};
inline SplitInput SplitAtMarker(const uint8_t* data, size_t size, const std::string& marker) {
  const std::string input(reinterpret_cast<const char*>(data), size);
  const std::string line = "\n" + marker + "\n";
  const size_t at = input.find(line);
  if (at == std::string::npos) return {input, std::nullopt};
  return {input.substr(0, at), input.substr(at + line.size())};
}

// The applied wrench and the constrained accelerations with every contact active, at the
// scene's initial state. Throws what they throw (kneedyn::Error for a physics refusal).
inline void EvaluateFirstPhysics(const kneedyn::Scene& scene) {
  const kneedyn::Model& model = scene.model;
  kneedyn::Data d(model);
  kneedyn::ComputeAppliedWrench(model, 0.0, kneedyn::PoseFromCoordinates(scene.initial.q), &d);
  std::vector<int> active;
  for (int i = 0; i < static_cast<int>(model.contacts.size()); ++i) active.push_back(i);
  kneedyn::SolveConstrainedAcceleration(model, 0.0, scene.initial.q, scene.initial.qd, active);
}

}  // namespace kneedyn_fuzz
