// One benchmark configuration (formulation × integrator × setting), its run and its
// metrics against a stored reference; shared by make_reference, work_precision and
// compare_counters.
#pragma once

#include <nlohmann/json.hpp>
#include <limits>
#include <string>

#include "benchmarks/metrics.hpp"

namespace kneedyn {
namespace bench {

struct BenchConfig {
  std::string formulation;
  std::string integrator;  // empty: the formulation's only method
  bool fixed_step = false;
  double rtol = 1e-6;      // adaptive; fixed-step: Newton tolerance where there is one
  double atol = 1e-8;
  double step = 0.0;       // s, fixed-step
  long max_steps = 200000;
  std::string stabilization = "none";  // ede: none|baumgarte|projection|cvode-projection

  std::string Name() const;              // "dae/rtol=1e-06" or "mde:rk4/step=0.001"
  nlohmann::json SettingJson() const;    // {rtol, atol} or {step} (+ max_steps if changed)
  FormulationOptions Options() const;
};

// Fixed-step methods (take --step; sweep the step, not the tolerance): the euler and rk4
// integrators and the newmark formulations.
bool IsFixedStep(const std::string& formulation, const std::string& integrator);

struct Outcome {
  RunResult result;
  ContactForm form = ContactForm::kChapter;
  Solution solution;
  std::string status;  // ok | failed
  std::string reason;  // failure or input error message
};

// Runs a configuration on a scene. Input errors (a setting the formulation rejects) come
// back as a failed outcome with the message, like solver failures.
Outcome RunConfig(const Scene& scene, const BenchConfig& config,
                  double comparison_interval = kDefaultComparisonInterval);

struct Reference {
  nlohmann::json json;
  Solution solution;
  double comparison_interval = kDefaultComparisonInterval;
  bool conservative = false;
  double accuracy_scd = std::numeric_limits<double>::quiet_NaN();  // stated; NaN: none
};
// Reads reference-data/references/<file>.json; throws InputError.
Reference LoadReference(const std::string& path);

// Metrics of an outcome against a reference (residuals and energy included).
Metrics Evaluate(const Scene& scene, const Outcome& outcome, const Reference& reference);

nlohmann::json CountersJson(const SolverStats& s);

// uname, nproc, compiler, build type, library versions.
nlohmann::json MachineJson();

// argv as one shell line (arguments quoted where needed): the header's "command", so a
// sweep file says how it was made.
std::string CommandLine(int argc, char** argv);

}  // namespace bench
}  // namespace kneedyn
