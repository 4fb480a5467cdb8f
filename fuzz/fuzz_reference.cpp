// libFuzzer target: a reference document as `kneedyn score --reference` reads it
// (benchmarks/score.hpp: ReferenceSolution), then a fixed result scored against it as score
// does (ScoreAgainstReference): the result CSV read against the reference's columns, the
// comparison, the ceiling and the record. When the result has rows off the reference's sampling times
// and the reference names a cheap configuration (rtol >= 1e-6, not an extended-precision
// one), that configuration is run again for them (DenseReference), as score does; other
// configurations are not run, to keep an input's time bounded.
//
// Input: the reference's JSON text. The scene is the chapter scene; the results are two
// CSVs of flexion 0, at 0 and 20 ms (on the shipped references' grid) and at 0 and 10 ms. An
// InputError (and a SolverError of the configuration run again) is an accepted outcome; a
// crash, sanitizer report, leak, hang or any other exception is a finding.
//
// Build and run: bash .ci/bootstrap fuzz [SECONDS] reference (clang, -fsanitize=fuzzer,address,undefined).
#include <cstdint>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "benchmarks/metrics.hpp"
#include "benchmarks/score.hpp"
#include "fuzz/fuzz_support.hpp"
#include "scene/scene.hpp"
#include "solver/error.hpp"

namespace {

const kneedyn::Scene& ChapterScene() {
  static const kneedyn::Scene scene = kneedyn::LoadScene(kneedyn::ReferenceDataDir() + "/scenes/chapter_impact.yaml");
  return scene;
}

// Whether score's rerun of the reference configuration is cheap enough to fuzz.
bool CheapRerun(const nlohmann::json& reference) {
  const auto primary = reference.find("primary");
  if (primary == reference.end() || !primary->is_object()) return true;  // refused before running
  if (primary->value("formulation", std::string()) == kneedyn::bench::kExtendedPrecisionFormulation) return false;
  const auto rtol = primary->find("rtol");
  return rtol == primary->end() || !rtol->is_number() || rtol->get<double>() >= 1e-6;
}

// The result CSV at `times` (s; flexion 0): on the stored grid of the shipped references
// (every 20 ms) or off it.
std::string ResultFile(const char* name, const char* rows) {
  const std::string path = kneedyn_fuzz::WorkDir() + "/" + name;
  kneedyn_fuzz::WriteFile(path, std::string("time_s,flexion_deg\n") + rows);
  return path;
}

// Reads the result against the reference and scores it as score does
// (ScoreAgainstReference); off-grid rows are run again only when `rerun`.
void ScoreAgainst(const std::string& result_path, const kneedyn::bench::Solution& reference,
                  const nlohmann::json& document, bool rerun) {
  namespace bench = kneedyn::bench;
  const kneedyn::Scene& scene = ChapterScene();
  bench::ScoredResult result = bench::ReadResultCsv(result_path, scene, reference);
  bench::ReconcileEndEvent(reference, "the result", /*failed=*/false, &result);
  const bench::ReferenceScore scored = bench::ScoreAgainstReference(
      scene, document, reference, result,
      rerun ? bench::OffGridRows::kRunReferenceAgain : bench::OffGridRows::kNotCompared);
  bench::ScoreInfo info;
  info.solver_name = "fuzz";
  (void)bench::ScoreRecord(result, scored.score, info).dump();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  namespace bench = kneedyn::bench;
  static const std::string on_grid = ResultFile("on_grid.csv", "0,0\n0.02,0\n");
  static const std::string off_grid = ResultFile("off_grid.csv", "0,0\n0.01,0\n");
  nlohmann::json document;
  try {
    document = nlohmann::json::parse(reinterpret_cast<const char*>(data), reinterpret_cast<const char*>(data) + size);
  } catch (const nlohmann::json::exception&) {
    return 0;  // score refuses a reference that is not JSON (InputError)
  }
  try {
    const bench::Solution reference = bench::ReferenceSolution(document, "fuzz reference");
    ScoreAgainst(on_grid, reference, document, false);
    ScoreAgainst(off_grid, reference, document, CheapRerun(document));
  } catch (const kneedyn::InputError&) {
    // A refused reference: the expected outcome for most inputs.
  } catch (const kneedyn::SolverError&) {
    // The configuration run again failed or did not reproduce the stored samples: score
    // reports that (exit 1).
  }
  return 0;
}
