// The interface between kneedyn and its sweep I/O plugin, kneedyn_sweep_io.so:
// the one shared object that links Open MPI and HDF5. It is loaded (dlopen, sweep_io.hpp)
// only by what needs those libraries: `kneedyn sweep` launched by mpirun, and writing
// sweep.h5 (a sweep without --shard, --merge, the Python module's run_sweep with out_dir).
// Every other command, `kneedyn run` first, never maps Open MPI, HDF5 and the ~40 shared
// objects they bring (libcurl, gnutls, kerberos, ldap, hwloc, libevent...; about 60 % of
// the dynamic loader's work before; benchmarks/README.md).
// Plain C: the two sides share no C++ object, allocation or exception. Functions returning
// int give 0 on success, else non-zero with a NUL-terminated message in error[error_size].
#pragma once

#include <stddef.h>

extern "C" {

// Raised whenever a struct or function below changes; the loader refuses another value.
#define KNEEDYN_SWEEP_IO_ABI 2
// The one exported symbol: const KneedynSweepIo* kneedyn_sweep_io_v1(void).
#define KNEEDYN_SWEEP_IO_ENTRY "kneedyn_sweep_io_v1"

struct KneedynHdf5Column {
  const char* name;
  const double* values;  // `rows` values
};

// The columns of sweep.h5 (sweep_output.hpp), each `rows` long.
struct KneedynHdf5Table {
  unsigned long long rows;
  const long long* index;
  const KneedynHdf5Column* parameters;
  size_t parameter_count;
  const KneedynHdf5Column* outcomes;
  size_t outcome_count;
  const char* const* status;
  const char* const* end_reason;
  const long long* steps;
  const char* const* failure;
};

struct KneedynSweepIo {
  int abi;       // KNEEDYN_SWEEP_IO_ABI
  int with_mpi;  // 0: built without MPI (the mpi_* members are null)
  // Creates `path` (truncating) with the datasets of sweep.h5; no timestamps.
  int (*write_hdf5)(const char* path, const struct KneedynHdf5Table* table, char* error, size_t error_size);
  // MPI_Init (unless already initialised); this rank, the world size, ranks on this node.
  // No error return: MPI's default error handler (MPI_ERRORS_ARE_FATAL) aborts the job on
  // a failure (ABI 1 had an error buffer that nothing ever filled).
  void (*mpi_init)(int* rank, int* size, int* ranks_on_node);
  void (*mpi_finalize)(void);
  // Collective: rank 0 receives the largest wall_s and the sum of failed.
  void (*mpi_reduce)(double wall_s, long failed, double* max_wall_s, long* sum_failed);
  // Collective: rank 0 receives every rank's byte count in sizes[0..size-1].
  void (*mpi_gather_sizes)(long long my_size, long long* sizes);
  // Collective, after mpi_gather_sizes: ranks > 0 send their bytes; rank 0 receives rank
  // r's into buffers[r] (sizes[r] bytes, r = 1..size-1; buffers[0] unused).
  void (*mpi_gather_bytes)(const char* mine, long long my_size, char* const* buffers, const long long* sizes);
};

typedef const struct KneedynSweepIo* (*KneedynSweepIoEntry)(void);

}  // extern "C"
