// MPI for `kneedyn sweep` (docs/cluster.md). MPI is initialised only when the process
// was launched by an MPI launcher (OMPI_COMM_WORLD_SIZE, PMI_SIZE or PMIX_RANK set), so a
// plain `kneedyn` never starts an MPI runtime. Rank r runs the indices i with
// i % size == r (sweep.hpp ShardIndices); rank 0 gathers the rows, orders them by index
// and writes the one result file, byte-identical to a single-process run.
// Built without MPI (CMake option KNEEDYN_WITH_MPI off or MPI not found) the session is
// always inactive. Open MPI is called through the sweep I/O plugin (sweep_io.hpp), loaded
// by the constructor only when launched by an MPI launcher: a missing plugin is an
// InputError (exit 2) there.
#pragma once

#include "ensembles/sweep.hpp"

namespace kneedyn::ensembles {

struct MpiGathered {
  double wall_s = 0.0;  // slowest rank's wall time
  long failed = 0;      // over all ranks
};

class MpiSession {
 public:
  MpiSession();
  ~MpiSession();
  MpiSession(const MpiSession&) = delete;
  MpiSession& operator=(const MpiSession&) = delete;

  bool active() const { return active_; }
  int rank() const { return rank_; }
  int size() const { return size_; }
  int ranks_on_node() const { return ranks_on_node_; }

  // Collective: every rank's rows to rank 0 (into *table, ordered by index); others keep
  // theirs. Throws Error when the ranks' tables disagree in shape.
  MpiGathered Gather(SweepTable* table, double wall_s, long failed);

  // Whether this build can use MPI at all.
  static bool Available();

 private:
  bool active_ = false;
  int rank_ = 0, size_ = 1, ranks_on_node_ = 1;
};

}  // namespace kneedyn::ensembles
