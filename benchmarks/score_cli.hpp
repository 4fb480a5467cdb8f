// `kneedyn score RESULT --scene S` (score.hpp): the subcommand, registered by kneedyn_main.cpp.
#pragma once

#include <CLI/CLI.hpp>

#include <string>
#include <vector>

namespace kneedyn::bench {

class ScoreCommand {
 public:
  explicit ScoreCommand(CLI::App& app);
  bool parsed() const { return cmd_->parsed(); }
  int Run(int argc, char** argv);  // catches InputError (exit 2) and Error (exit 1) itself

 private:
  CLI::App* cmd_;
  std::string result_path_;
  std::string scene_path_;
  std::string reference_path_;
  std::string events_path_;
  std::string counters_path_;
  std::vector<std::string> counters_;
  std::string solver_name_ = "outside solver";
  std::string integrator_;
  double rtol_ = -1.0, atol_ = -1.0, step_ = -1.0, cpu_time_ = -1.0;
  std::string failure_;
  std::string out_path_;
};

}  // namespace kneedyn::bench
