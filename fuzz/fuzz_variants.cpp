// libFuzzer target: the variants file of `kneedyn batch` (ensembles/batch.hpp), each row
// applied to the base scene through the sweep's parameter setters (SceneForRun: the model
// builder re-derives what depends on them), then the cheap first physics of a run at the
// variant's initial state (applied wrench, constrained accelerations), as fuzz_scene does.
//
// Input: a variants CSV's text. The base scene is the chapter scene, or the patello-femoral
// impact scene when the input starts with the comment line "#patella" (its parameters:
// quadriceps.*, patella.*). At most the first 8 rows are applied. An InputError or
// SolverError is an accepted outcome; a crash, sanitizer report, leak, hang or any other
// exception is a finding.
//
// Build and run: bash .ci/bootstrap fuzz [SECONDS] variants (clang, -fsanitize=fuzzer,address,undefined).
#include <cstdint>
#include <string>
#include <vector>

#include "ensembles/batch.hpp"
#include "ensembles/sweep_spec.hpp"
#include "fuzz/fuzz_support.hpp"
#include "scene/scene.hpp"
#include "solver/error.hpp"

namespace {

// The base scene, loaded once (KNEEDYN_DATA_DIR or the build tree's data).
const kneedyn::Scene& BaseScene(bool patella) {
  static const kneedyn::Scene chapter = kneedyn::LoadScene(kneedyn::ReferenceDataDir() + "/scenes/chapter_impact.yaml");
  static const kneedyn::Scene patellofemoral =
      kneedyn::LoadScene(kneedyn::ReferenceDataDir() + "/scenes/patellofemoral_impact.yaml");
  return patella ? patellofemoral : chapter;
}

constexpr size_t kMaxRowsApplied = 8;

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  namespace ens = kneedyn::ensembles;
  const std::string text(reinterpret_cast<const char*>(data), size);
  const bool patella = text.rfind("#patella\n", 0) == 0;
  const kneedyn::Scene& base = BaseScene(patella);
  try {
    const ens::BatchVariants variants = ens::ParseBatchVariants(text, "fuzz.csv", base.model);
    ens::SweepSpec spec;
    spec.base = base;
    spec.parameters = variants.parameters;
    for (size_t r = 0; r < variants.rows.size() && r < kMaxRowsApplied; ++r) {
      try {
        kneedyn_fuzz::EvaluateFirstPhysics(ens::SceneForRun(spec, variants.rows[r]));
      } catch (const kneedyn::Error&) {
        // This row refused (a value the model cannot take) or a physics refusal: the next row.
      }
    }
  } catch (const kneedyn::InputError&) {
    // A refused file: the expected outcome for most inputs.
  }
  return 0;
}
