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
#include <string>

#include "fuzz/fuzz_support.hpp"
#include "scene/scene.hpp"
#include "solver/error.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace kneedyn_fuzz;
  const SplitInput input = SplitAtMarker(data, size, "#@params");
  WriteFile(WorkDir() + "/params.yaml", input.second.value_or(""));
  try {
    EvaluateFirstPhysics(kneedyn::ParseScene(input.first, "fuzz.yaml", WorkDir()));
  } catch (const kneedyn::Error&) {
    // Refused input or a physics refusal: the expected outcome for most inputs.
  }
  return 0;
}
