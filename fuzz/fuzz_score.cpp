// libFuzzer target: what `kneedyn score` reads from an outside solver, scored against the
// chapter scene's stored reference (benchmarks/score.hpp): the result CSV, the events file
// (a summary.json or a CSV), the comparison at the reference's sampling times and the
// work-precision record written from it.
//
// Input: a result CSV's text, optionally followed by a line "#@events" and an events file's
// text. Scored as score does (ScoreAgainstReference), except that the reference's
// configuration is not run again for off-grid rows (a whole integration per input): the
// result is compared at the sampling times it has.
// An InputError is the accepted outcome of a refused file; a crash, sanitizer report, leak,
// hang or any other exception is a finding.
//
// Build and run: bash .ci/bootstrap fuzz [SECONDS] score (clang, -fsanitize=fuzzer,address,undefined).
#include <cstdint>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>

#include "benchmarks/metrics.hpp"
#include "benchmarks/score.hpp"
#include "fuzz/fuzz_support.hpp"
#include "scene/scene.hpp"
#include "solver/error.hpp"

namespace {

struct ChapterReference {
  kneedyn::Scene scene;
  nlohmann::json document;
  kneedyn::bench::Solution solution;
};

// The scene and its stored reference, read once (KNEEDYN_DATA_DIR or the build tree's data).
const ChapterReference& Reference() {
  static const ChapterReference r = [] {
    const std::string data = kneedyn::ReferenceDataDir();
    ChapterReference out{kneedyn::LoadScene(data + "/scenes/chapter_impact.yaml"), {}, {}};
    std::ifstream in(data + "/references/chapter_impact.json");
    out.document = nlohmann::json::parse(in);
    out.solution = kneedyn::bench::ReferenceSolution(out.document, "the chapter reference");
    return out;
  }();
  return r;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  namespace bench = kneedyn::bench;
  using namespace kneedyn_fuzz;
  const ChapterReference& reference = Reference();
  const SplitInput input = SplitAtMarker(data, size, "#@events");
  const std::string result_path = WorkDir() + "/result.csv";
  const std::string events_path = WorkDir() + "/events";
  WriteFile(result_path, input.first);
  if (input.second) WriteFile(events_path, *input.second);
  try {
    bench::ScoredResult result = bench::ReadResultCsv(result_path, reference.scene, reference.solution);
    if (input.second) result.solution.events = bench::ReadEvents(events_path).events;
    bench::ReconcileEndEvent(reference.solution, "--events", /*failed=*/false, &result);
    const bench::ReferenceScore scored = bench::ScoreAgainstReference(
        reference.scene, reference.document, reference.solution, result, bench::OffGridRows::kNotCompared);
    bench::ScoreInfo info;
    info.solver_name = "fuzz";
    (void)bench::ScoreRecord(result, scored.score, info).dump();
  } catch (const kneedyn::InputError&) {
    // A refused file: the expected outcome for most inputs.
  }
  return 0;
}
