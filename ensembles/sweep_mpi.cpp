#include "ensembles/sweep_mpi.hpp"

#include <algorithm>
#include <cstdlib>
#include <string>
#include <vector>

#include "ensembles/sweep_io.hpp"
#include "ensembles/sweep_output.hpp"
#include "solver/error.hpp"

// Open MPI itself is in the sweep I/O plugin (sweep_io_plugin.hpp), loaded here only when
// the process was launched by an MPI launcher.

namespace kneedyn::ensembles {

namespace {

bool LaunchedByMpi() {
  for (const char* v : {"OMPI_COMM_WORLD_SIZE", "PMI_SIZE", "PMIX_RANK"}) {
    if (std::getenv(v)) return true;
  }
  return false;
}

void RefuseWithoutMpi() {
  if (std::getenv("OMPI_COMM_WORLD_RANK") && std::string(std::getenv("OMPI_COMM_WORLD_SIZE")) != "1") {
    Throw<InputError>("kneedyn sweep", "launched by mpirun, but this kneedyn was built without MPI "
                      "(CMake option KNEEDYN_WITH_MPI); use --shard i/n and --merge instead");
  }
}

}  // namespace

bool MpiSession::Available() {
#ifdef KNEEDYN_WITH_MPI
  return true;
#else
  return false;
#endif
}

MpiSession::MpiSession() {
  if (!LaunchedByMpi()) return;
  // Without MPI in this kneedyn or in its plugin (SweepIo throws InputError when the plugin
  // is missing): refused under an Open MPI launch of more than one rank, else one process.
  if (!Available() || !SweepIo().with_mpi) {
    RefuseWithoutMpi();
    return;
  }
  SweepIo().mpi_init(&rank_, &size_, &ranks_on_node_);  // no error return: MPI aborts on errors
  active_ = true;
}

MpiSession::~MpiSession() {
  if (active_) SweepIo().mpi_finalize();
}

MpiGathered MpiSession::Gather(SweepTable* table, double wall_s, long failed) {
  MpiGathered g{wall_s, failed};
  if (!active_) return g;
  const KneedynSweepIo& io = SweepIo();
  io.mpi_reduce(wall_s, failed, &g.wall_s, &g.failed);
  const std::string mine = SerializeRows(table->rows);
  std::vector<long long> sizes(size_);
  io.mpi_gather_sizes(static_cast<long long>(mine.size()), sizes.data());
  std::vector<std::string> parts(rank_ == 0 ? size_ : 0);
  std::vector<char*> buffers(parts.size(), nullptr);
  for (int r = 1; r < static_cast<int>(parts.size()); ++r) {
    parts[r].assign(static_cast<size_t>(sizes[r]), '\0');
    buffers[r] = parts[r].data();
  }
  io.mpi_gather_bytes(mine.data(), static_cast<long long>(mine.size()), buffers.data(), sizes.data());
  if (rank_ != 0) return g;
  for (int r = 1; r < size_; ++r) {
    for (RunRow& row : DeserializeRows(parts[r])) {
      if (row.parameters.size() != table->parameter_columns.size() ||
          row.outcomes.size() != table->outcome_columns.size()) {
        Throw<Error>("MpiSession::Gather", "rank ", r, " sent a row of another shape (index ", row.index, ")");
      }
      table->rows.push_back(std::move(row));
    }
  }
  std::sort(table->rows.begin(), table->rows.end(), [](const RunRow& a, const RunRow& b) { return a.index < b.index; });
  if (static_cast<long>(table->rows.size()) != table->total_runs) {
    Throw<Error>("MpiSession::Gather", "gathered ", table->rows.size(), " rows, expected ", table->total_runs);
  }
  return g;
}

}  // namespace kneedyn::ensembles
