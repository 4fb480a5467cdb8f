// Helpers shared by the sensitivity suites (forward_sensitivity_test, dae_sensitivity_test).
#pragma once

#include <cmath>
#include <string>
#include <vector>

#include "scene/scene.hpp"
#include "sensitivity/forward_sensitivity.hpp"
#include "sensitivity/sensitivity_cli.hpp"

namespace kneedyn::sensitivity::test_support {

// reference-data/scenes/chapter_impact.yaml.
inline Scene Chapter() {
  return LoadScene(std::string(KNEEDYN_SOURCE_DIR) + "/reference-data/scenes/chapter_impact.yaml");
}

// The parameters' nominal values, in their order.
inline std::vector<double> Nominal(const std::vector<ensembles::ParameterSpec>& params) {
  std::vector<double> v;
  for (const auto& p : params) v.push_back(p.nominal);
  return v;
}

// The two runs of a central difference in parameter j: without derivatives at p with p[j]
// moved by ±h, h = 1e-4 |p[j]|.
struct CentralDifferenceRuns {
  double h;
  SensitivityResult up, down;
};
inline CentralDifferenceRuns RunCentralDifference(const Scene& scene,
                                                  const std::vector<ensembles::ParameterSpec>& params,
                                                  const std::vector<double>& p, size_t j,
                                                  const std::vector<std::string>& outcomes,
                                                  SensitivityOptions options) {
  options.derivatives = false;
  CentralDifferenceRuns runs;
  runs.h = 1e-4 * std::abs(p[j]);
  std::vector<double> up = p, down = p;
  up[j] += runs.h, down[j] -= runs.h;
  runs.up = RunSensitivity(scene, params, up, outcomes, options);
  runs.down = RunSensitivity(scene, params, down, outcomes, options);
  return runs;
}

}  // namespace kneedyn::sensitivity::test_support
