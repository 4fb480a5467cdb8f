// libFuzzer target: scene + parameter-set parsing and model building,
// then the cheap first physics of a run (applied wrench, constrained accelerations at the
// initial state).
//
// Input: a scene's YAML text, optionally followed by a line "#@params" and a parameter
// set's YAML text; the latter is written to params.yaml in a private directory that is the
// scene's base directory (seeds say `parameter_set: params.yaml`). Any InputError or
// SolverError is an accepted outcome; a crash, sanitizer report, leak, hang or any other
// exception is a finding.
//
// Build and run: bash .ci/bootstrap fuzz [SECONDS] (clang, -fsanitize=fuzzer,address,undefined).
#include <cstdint>
#include <fstream>
#include <string>

#include "fuzz/fuzz_work_dir.hpp"
#include "solver/constrained_dynamics.hpp"
#include "solver/dynamics.hpp"
#include "solver/error.hpp"
#include "scene/scene.hpp"

using kneedyn_fuzz::WorkDir;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string input(reinterpret_cast<const char*>(data), size);
  const std::string marker = "\n#@params\n";
  const size_t at = input.find(marker);
  const std::string scene_text = input.substr(0, at);
  const std::string params_text = at == std::string::npos ? "" : input.substr(at + marker.size());
  {
    std::ofstream out(WorkDir() + "/params.yaml", std::ios::binary | std::ios::trunc);
    out << params_text;
  }
  try {
    const kneedyn::Scene scene = kneedyn::ParseScene(scene_text, "fuzz.yaml", WorkDir());
    const kneedyn::Model& model = scene.model;
    const kneedyn::Pose pose = kneedyn::PoseFromCoordinates(scene.initial.q);
    kneedyn::Data d(model);
    kneedyn::ComputeAppliedWrench(model, 0.0, pose, &d);
    std::vector<int> active;
    for (int i = 0; i < static_cast<int>(model.contacts.size()); ++i) active.push_back(i);
    kneedyn::SolveConstrainedAcceleration(model, 0.0, scene.initial.q, scene.initial.qd, active);
  } catch (const kneedyn::Error&) {
    // Refused input or a physics refusal: the expected outcome for most inputs.
  }
  return 0;
}
