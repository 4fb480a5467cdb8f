// `kneedyn batch`: registered on the kneedyn CLI by one line.
//   kneedyn batch SCENE --variants FILE.csv [--out results.csv] [--formulation NAME]
//                 [--rtol R] [--atol A] [--integrator I] [--step H] [--outcomes a,b,...]
//                 [--threads N] [--output-interval S]
// The scene is read once; each CSV row is one run (ensembles/batch.hpp). Exit codes: 0 done
// (failed runs are rows); 2 bad input (scene, variants, options; nothing written); 1 the
// results file cannot be written.
#pragma once

#include <CLI/CLI.hpp>

#include <string>
#include <vector>

#include "formulations/run.hpp"

namespace kneedyn::ensembles {

class BatchCommand {
 public:
  explicit BatchCommand(CLI::App& app);
  bool parsed() const { return cmd_->parsed(); }
  int Run();

 private:
  CLI::App* cmd_;
  std::string scene_path_, variants_path_, out_path_ = "out/batch.csv";
  RunSettings settings_;
  OptionText typed_;  // the numeric and named options as typed (flag -> text)
  std::vector<std::string> outcomes_ = {"liftoff_time", "liftoff_flexion", "time_at_90"};
  int threads_ = 1;
  bool quiet_ = false;
};

}  // namespace kneedyn::ensembles
