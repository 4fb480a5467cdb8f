// libFuzzer target: the part files `kneedyn sweep --merge` reads (ensembles/sweep_output.hpp:
// ReadPart, MergeParts), then what the merge does with them before writing: the rows in
// MPI's flat binary form and back (SerializeRows, DeserializeRows), which must give the
// same bytes.
//
// Input: a part file's JSON text, optionally followed by a line "#@part" and a second part
// file; both are written to the fuzzing process's private directory and read by path, as
// `kneedyn sweep --merge` reads them. An InputError is an accepted outcome; a crash,
// sanitizer report, leak, hang, any other exception or a round trip that changes the rows
// is a finding.
//
// Build and run: bash .ci/bootstrap fuzz [SECONDS] part (clang, -fsanitize=fuzzer,address,undefined).
#include <cstdint>
#include <cstdlib>
#include <string>
#include <vector>

#include "ensembles/sweep.hpp"
#include "ensembles/sweep_output.hpp"
#include "fuzz/fuzz_support.hpp"
#include "solver/error.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  namespace ens = kneedyn::ensembles;
  const kneedyn_fuzz::SplitInput input = kneedyn_fuzz::SplitAtMarker(data, size, "#@part");
  std::vector<std::string> texts = {input.first};
  if (input.second) texts.push_back(*input.second);
  try {
    std::vector<ens::SweepTable> parts;
    for (size_t i = 0; i < texts.size(); ++i) {
      const std::string path = kneedyn_fuzz::WorkDir() + "/part-" + std::to_string(i) + ".json";
      kneedyn_fuzz::WriteFile(path, texts[i]);
      parts.push_back(ens::ReadPart(path));
    }
    const ens::SweepTable all = ens::MergeParts(parts);
    const std::string bytes = ens::SerializeRows(all.rows);
    if (ens::SerializeRows(ens::DeserializeRows(bytes)) != bytes) std::abort();  // the round trip changed a row
  } catch (const kneedyn::InputError&) {
    // A refused part or merge: the expected outcome for most inputs.
  }
  return 0;
}
