// Sweep result files (ensembles/README.md): one row per run, failed runs kept.
//   sweep.csv  index, parameters, outcomes, status, end_reason, steps, failure
//              (numbers as %.17g: they read back to the same doubles; NaN as "nan")
//   sweep.h5   the same columns as HDF5 datasets: /index, /parameters/<col>,
//              /outcomes/<col>, /status, /end_reason, /steps, /failure; no timestamps, so
//              equal tables give equal bytes
//   part-<i>-of-<n>.json  one shard's rows (--shard i/n), for `kneedyn sweep --merge`
// Every file is written to a temporary name and renamed: complete or absent.
// sweep.h5 is written by the sweep I/O plugin (HDF5; sweep_io.hpp): WriteSweepResults
// throws InputError, before writing anything, when it is missing.
#pragma once

#include <string>
#include <vector>

#include "ensembles/sweep.hpp"

namespace kneedyn::ensembles {

// dir/sweep.csv and dir/sweep.h5 (dir created if needed), both written under temporary
// names before either is renamed into place.
void WriteSweepResults(const std::string& dir, const SweepTable& table);

void WritePart(const std::string& path, const SweepTable& table, long shard, long shards);
SweepTable ReadPart(const std::string& path);  // throws InputError naming file and field

// Combines parts of one spec into the whole table; throws InputError unless they come
// from the same spec and cover every run index exactly once.
SweepTable MergeParts(const std::vector<SweepTable>& parts);

// Flat binary form of rows for MPI gathering (sweep_mpi.cpp); exact for doubles.
std::string SerializeRows(const std::vector<RunRow>& rows);
std::vector<RunRow> DeserializeRows(const std::string& bytes);

}  // namespace kneedyn::ensembles
