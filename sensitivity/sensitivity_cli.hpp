// `kneedyn sensitivity`: registered on the kneedyn CLI by one line.
//   kneedyn sensitivity SCENE --parameters a,b,c --outcomes x,y [--formulation ede|dae|dae-reduced|dae-ggl|dae-ggl-reduced]
//                       [--rtol R] [--atol A] [--max-steps N] [--output-interval S] [--fd-step H] [--out DIR]
//   kneedyn sensitivity SCENE --list      the parameter and outcome names the scene accepts
// Writes DIR/sensitivity.csv, DIR/sensitivity.json and DIR/sensitivity_trajectory.csv
// (docs/outputs.md), published as one
// set like `kneedyn run`'s files. --fd-step H > 0 adds central finite differences with
// relative step H (two more runs per parameter) beside each derivative.
// Exit codes: 0 done; 1 solver failure (nothing written: a derivative table is only
// meaningful whole); 2 bad input (names, options, --out), nothing written.
#pragma once

#include <CLI/CLI.hpp>

#include <string>
#include <vector>

#include "sensitivity/forward_sensitivity.hpp"

namespace kneedyn::sensitivity {

class SensitivityCommand {
 public:
  explicit SensitivityCommand(CLI::App& app);
  bool parsed() const { return cmd_->parsed(); }
  int Run(int argc, char** argv);  // catches InputError (exit 2) and Error (exit 1) itself

 private:
  CLI::App* cmd_;
  std::string scene_path_;
  std::vector<std::string> parameters_;
  std::vector<std::string> outcomes_;
  SensitivityOptions options_;
  double fd_step_ = 0.0;
  OptionText typed_;  // the numeric options as typed (flag -> text)
  std::string out_dir_ = "out/sensitivity";
  bool list_ = false;
  bool quiet_ = false;
  std::string spec_path_;  // --spec: scene, parameter names and outcomes of a sweep spec
};

// Central finite differences of the outcomes: for each parameter j, runs at p_j (1 ± h)
// (± h when p_j = 0) without derivatives. Returns [outcome][parameter].
std::vector<std::vector<double>> CentralDifferences(const Scene& scene,
                                                    const std::vector<ensembles::ParameterSpec>& parameters,
                                                    const std::vector<double>& values,
                                                    const std::vector<std::string>& outcomes,
                                                    const SensitivityOptions& options, double relative_step);

// Files of one result (CSV + JSON) published as one set into `dir` (see the .cpp).
void WriteSensitivityOutputs(const std::string& dir, const Scene& scene, const SensitivityOptions& options,
                             const SensitivityResult& result, const std::vector<std::vector<double>>* fd,
                             double fd_step, const std::vector<std::string>& command_line);
// Refuses an unusable --out before anything runs (InputError).
void CheckSensitivityOutputDirectory(const std::string& dir);

}  // namespace kneedyn::sensitivity
