// In-process batches (ensembles/README.md, "In-process batches"): one scene loaded once, many
// variants of it run in one process, parameters overridden per run with the sweep's named
// parameters (sweep_spec.hpp: "pulse.amplitude", "ACL anterior.k_linear", ...), results
// formatted only when asked for (std::to_chars).
//
//   kneedyn batch SCENE --variants FILE.csv [--out results.csv] [--formulation ...]
//
// Variants file (CSV): a header naming the parameters, then one row per run with the
// values in the parameter-set units (N, s, kg, N/mm, mm; ensembles/README.md). Lines that
// are empty or start with '#' are skipped. Every rule a file can break is an InputError
// naming file, line, column and value, raised before any run.
#pragma once

#include <string>
#include <vector>

#include "ensembles/sweep.hpp"
#include "ensembles/sweep_spec.hpp"

namespace kneedyn::ensembles {

struct BatchVariants {
  std::string path;                       // the file (for messages)
  std::vector<ParameterSpec> parameters;  // resolved against the base scene
  std::vector<std::vector<double>> rows;  // one per run, parallel to parameters
};

BatchVariants ParseBatchVariants(const std::string& text, const std::string& label, const Model& base);
BatchVariants LoadBatchVariants(const std::string& path, const Model& base);

// A loaded scene and run settings, reused for every variant.
class Batch {
 public:
  // outcome_groups as in a sweep spec (liftoff_time, liftoff_flexion, time_at_90,
  // peak_ligament_force, ...). Throws InputError on an unknown group or formulation.
  Batch(Scene base, RunSettings run, std::vector<std::string> outcome_groups);

  // Runs variant `index` with `parameters` set to `values`. Never throws for a failing
  // run: the row says failed and why.
  RunRow Run(const std::vector<ParameterSpec>& parameters, const std::vector<double>& values, long index);

  // Every row of `variants` in order on `threads` workers (1: this thread only). `progress`,
  // when set, is called (serialised) after every finished run, as RunSweep's.
  SweepTable RunAll(const BatchVariants& variants, int threads = 1,
                    const std::function<void(const SweepProgress&)>& progress = {});

  const std::vector<std::string>& outcome_columns() const { return outcome_columns_; }

 private:
  SweepSpec spec_;  // base scene, outcome groups, run settings; parameters set per call
  std::vector<std::string> outcome_columns_;
};

// The results table: index, parameter columns, outcome columns, status, end_reason,
// steps, failure. Numbers in the shortest form that reads back exactly (std::to_chars).
std::string FormatBatchCsv(const SweepTable& table);

}  // namespace kneedyn::ensembles
