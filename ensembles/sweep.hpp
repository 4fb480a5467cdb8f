// Running a sweep (ensembles/README.md): every run of a spec's design through the library's
// run driver (formulations/run.hpp), in one process on a thread pool, one row per run.
//
// Bitwise reproducibility: run i depends only on i (design row i, sweep_spec.hpp); each
// run writes its own row; rows are ordered by index before anything is written. Nothing
// that depends on the thread, the rank or the clock enters a row.
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "ensembles/sweep_spec.hpp"

namespace kneedyn::ensembles {

struct RunRow {
  long index = 0;
  std::vector<double> parameters;  // spec units, parallel to SweepTable::parameter_columns
  std::vector<double> outcomes;    // NaN when the run did not reach it
  bool completed = false;          // false: solver or model failure, see failure
  std::string end_reason;          // run.hpp end_reason (flexion_90, end_time) or empty
  long steps = 0;                  // accepted solver steps (the work behind the row)
  std::string failure;             // empty when completed
};

struct SweepTable {
  std::uint64_t fingerprint = 0;   // of the spec and its scene's files (SweepSpec::fingerprint)
  std::string source;              // the part file it was read from (ReadPart), for messages
  long total_runs = 0;             // rows of the whole design
  std::vector<std::string> parameter_columns;
  std::vector<std::string> outcome_columns;
  std::vector<RunRow> rows;        // ascending index
  long shard = 0, shards = 1;      // a part's --shard i/n (ReadPart); the whole table: 0/1
};

// Result columns of the spec's outcome groups, with units:
//   liftoff_time → liftoff_time_s; liftoff_flexion → liftoff_flexion_deg (first lift-off
//   of either tibial compartment; a patellar facet's liftoff_patellar_* is not one); peak_ligament_force → peak_F_<element>_N; peak_contact_force →
//   peak_N_<compartment>_N; time_at_90 → time_90_s; ligament_force_at_90 → F90_<element>_N;
//   contact_force_at_90 → N90_<compartment>_N. Peaks are maxima over the output rows
//   (solver.output_interval_s apart, plus every event).
std::vector<std::string> OutcomeColumns(const SweepSpec& spec);

// One run: the design row's parameter values applied to the base scene, RunScene, the
// outcomes. Never throws for a failing run: the row says failed and why.
RunRow EvaluateRun(const SweepSpec& spec, long index, const std::vector<double>& unit_row);
// The same with the parameter values given directly (spec units, parallel to
// spec.parameters): kneedyn batch (ensembles/batch.hpp).
RunRow EvaluateRunAt(const SweepSpec& spec, long index, const std::vector<double>& values);

struct SweepProgress {
  long done = 0, total = 0, failed = 0;
  double elapsed_s = 0.0;
};

// The `\r` progress line of `kneedyn sweep` and `kneedyn batch` on a terminal ("[label] done/total
// runs (failed)  rate  elapsed  time left"), at most every 0.2 s and at the last run.
std::function<void(const SweepProgress&)> TerminalProgress(const std::string& label);

// rows->at(k) = run_one(k) for k < rows->size() on `threads` workers (ForEachRunInParallel),
// calling `progress` (when set, serialised) after every finished run: the loop of RunSweep and
// Batch::RunAll.
void EvaluateRowsInParallel(int threads, const std::function<RunRow(size_t)>& run_one,
                            const std::function<void(const SweepProgress&)>& progress, std::vector<RunRow>* rows);

// Runs the design rows `indices` (ascending) on `threads` workers. `progress`, when set,
// is called (serialised) after every finished run.
SweepTable RunSweep(const SweepSpec& spec, const std::vector<long>& indices, int threads,
                    const std::function<void(const SweepProgress&)>& progress = {});

// All design rows of the spec, or those of shard i of n (index % n == i).
std::vector<long> ShardIndices(const SweepSpec& spec, long shard, long shards);

}  // namespace kneedyn::ensembles
