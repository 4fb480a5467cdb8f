// `kneedyn sweep`: registered on the kneedyn CLI by one line.
//   kneedyn sweep SPEC.yaml [--threads N] [--out DIR] [--shard i/n] [--quiet]
//   kneedyn sweep --merge PART.json... [--out DIR]
//   mpirun -n N kneedyn sweep SPEC.yaml   (runs distributed by index, one result file)
// Exit codes: 0 done (failed runs are rows, counted on stdout); 2 bad input (spec, options,
// parts), nothing written.
#pragma once

#include <CLI/CLI.hpp>

#include <string>
#include <vector>

namespace kneedyn::ensembles {

class SweepCommand {
 public:
  explicit SweepCommand(CLI::App& app);
  bool parsed() const { return cmd_->parsed(); }
  int Run();  // catches InputError (exit 2) and Error (exit 1) itself

 private:
  CLI::App* cmd_;
  std::string spec_path_;
  std::string out_dir_ = "out/sweep";
  int threads_ = 0;  // 0: all cores (per MPI rank: cores / ranks on the node)
  std::string shard_;
  std::vector<std::string> merge_;
  bool quiet_ = false;
};

}  // namespace kneedyn::ensembles
