#include "ensembles/sweep_mpi.hpp"

#include <algorithm>
#include <cstdlib>
#include <string>
#include <vector>

#include "ensembles/sweep_output.hpp"
#include "solver/error.hpp"

#ifdef KNEEDYN_WITH_MPI
#include <mpi.h>
#endif

namespace kneedyn::ensembles {

namespace {

bool LaunchedByMpi() {
  for (const char* v : {"OMPI_COMM_WORLD_SIZE", "PMI_SIZE", "PMIX_RANK"}) {
    if (std::getenv(v)) return true;
  }
  return false;
}

}  // namespace

#ifdef KNEEDYN_WITH_MPI

bool MpiSession::Available() { return true; }

MpiSession::MpiSession() {
  if (!LaunchedByMpi()) return;
  int initialized = 0;
  MPI_Initialized(&initialized);
  if (!initialized) MPI_Init(nullptr, nullptr);
  active_ = true;
  MPI_Comm_rank(MPI_COMM_WORLD, &rank_);
  MPI_Comm_size(MPI_COMM_WORLD, &size_);
  MPI_Comm node;
  MPI_Comm_split_type(MPI_COMM_WORLD, MPI_COMM_TYPE_SHARED, rank_, MPI_INFO_NULL, &node);
  MPI_Comm_size(node, &ranks_on_node_);
  MPI_Comm_free(&node);
}

MpiSession::~MpiSession() {
  if (!active_) return;
  int finalized = 0;
  MPI_Finalized(&finalized);
  if (!finalized) MPI_Finalize();
}

MpiGathered MpiSession::Gather(SweepTable* table, double wall_s, long failed) {
  MpiGathered g;
  MPI_Reduce(&wall_s, &g.wall_s, 1, MPI_DOUBLE, MPI_MAX, 0, MPI_COMM_WORLD);
  MPI_Reduce(&failed, &g.failed, 1, MPI_LONG, MPI_SUM, 0, MPI_COMM_WORLD);
  const std::string mine = SerializeRows(table->rows);
  const long long my_size = static_cast<long long>(mine.size());
  std::vector<long long> sizes(size_);
  MPI_Gather(&my_size, 1, MPI_LONG_LONG, sizes.data(), 1, MPI_LONG_LONG, 0, MPI_COMM_WORLD);
  // Point-to-point receives: a part may exceed MPI_Gatherv's int displacements.
  if (rank_ != 0) {
    const char* p = mine.data();
    long long left = my_size;
    while (left > 0) {
      const int chunk = static_cast<int>(std::min<long long>(left, 1 << 30));
      MPI_Send(p, chunk, MPI_CHAR, 0, 7, MPI_COMM_WORLD);
      p += chunk;
      left -= chunk;
    }
    return g;
  }
  for (int r = 1; r < size_; ++r) {
    std::string buf(static_cast<size_t>(sizes[r]), '\0');
    char* p = buf.data();
    long long left = sizes[r];
    while (left > 0) {
      const int chunk = static_cast<int>(std::min<long long>(left, 1 << 30));
      MPI_Recv(p, chunk, MPI_CHAR, r, 7, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
      p += chunk;
      left -= chunk;
    }
    for (RunRow& row : DeserializeRows(buf)) {
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

#else  // built without MPI

bool MpiSession::Available() { return false; }

MpiSession::MpiSession() {
  if (LaunchedByMpi() && std::getenv("OMPI_COMM_WORLD_RANK") && std::string(std::getenv("OMPI_COMM_WORLD_SIZE")) != "1") {
    Throw<InputError>("kneedyn sweep", "launched by mpirun, but this kneedyn was built without MPI "
                      "(CMake option KNEEDYN_WITH_MPI); use --shard i/n and --merge instead");
  }
}
MpiSession::~MpiSession() = default;
MpiGathered MpiSession::Gather(SweepTable*, double wall_s, long failed) { return {wall_s, failed}; }

#endif

}  // namespace kneedyn::ensembles
