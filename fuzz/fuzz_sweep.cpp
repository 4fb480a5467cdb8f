// libFuzzer target: the sweep specification of `kneedyn sweep` (ensembles/sweep_spec.hpp),
// then what a sweep does with it before its first integration: the design's unit-cube
// matrix (when it is small), the first rows applied to the base scene (SceneForRun: the
// model builder re-derives what depends on them) and the cheap first physics of each run,
// as fuzz_variants does; for an analytic test function, its value at those rows.
//
// Input: a spec's YAML text. Scene paths are relative to reference-data/scenes, so
// "scene: chapter_impact.yaml" names the chapter scene. The design matrix is built only for
// at most 4,096 numbers (a spec may ask for 10⁸ runs, which `kneedyn sweep` would run), and
// at most the first 4 rows are applied. An InputError or SolverError is an accepted outcome;
// a crash, sanitizer report, leak, hang or any other exception is a finding.
//
// Build and run: bash .ci/bootstrap fuzz [SECONDS] sweep (clang, -fsanitize=fuzzer,address,undefined).
#include <cstdint>
#include <string>
#include <vector>

#include "ensembles/design.hpp"
#include "ensembles/sweep.hpp"
#include "ensembles/sweep_spec.hpp"
#include "fuzz/fuzz_support.hpp"
#include "scene/scene.hpp"
#include "solver/error.hpp"

namespace {

constexpr long kMaxDesignNumbers = 4096;
constexpr long kMaxRowsApplied = 4;

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  namespace ens = kneedyn::ensembles;
  const std::string text(reinterpret_cast<const char*>(data), size);
  try {
    const ens::SweepSpec spec = ens::ParseSweepSpec(text, "fuzz.yaml", kneedyn::ReferenceDataDir() + "/scenes");
    const int d = static_cast<int>(spec.parameters.size());
    const long rows = ens::DesignRows(spec.design, d);
    if (rows <= 0 || rows > kMaxDesignNumbers / (d > 0 ? d : 1)) return 0;
    const std::vector<double> unit = ens::DesignMatrix(spec.design, d);
    for (long r = 0; r < rows && r < kMaxRowsApplied; ++r) {
      std::vector<double> values(static_cast<size_t>(d));
      for (int k = 0; k < d; ++k) values[k] = spec.parameters[k].FromUnit(unit[r * d + k]);
      if (spec.analytic != ens::AnalyticModel::kNone) {  // no scene: the test function's value
        ens::EvaluateRunAt(spec, r, values);
        continue;
      }
      try {
        kneedyn_fuzz::EvaluateFirstPhysics(ens::SceneForRun(spec, values));
      } catch (const kneedyn::Error&) {
        // This row refused (a value the model cannot take) or a physics refusal: the next row.
      }
    }
  } catch (const kneedyn::InputError&) {
    // A refused spec: the expected outcome for most inputs.
  }
  return 0;
}
