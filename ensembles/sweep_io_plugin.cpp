// kneedyn_sweep_io.so: the Open MPI and HDF5 side of `kneedyn sweep` (sweep_io_plugin.hpp).
// Built as a CMake MODULE from this file alone, linked with HDF5 and (KNEEDYN_WITH_MPI)
// Open MPI; it exports kneedyn_sweep_io_v1 and nothing else (-fvisibility=hidden).
#include "ensembles/sweep_io_plugin.hpp"

#include <hdf5.h>

#include <algorithm>
#include <cstdio>
#include <exception>
#include <string>

#ifdef KNEEDYN_WITH_MPI
// The C API only: without these, mpi.h declares the C++ bindings (libmpi_cxx).
#define OMPI_SKIP_MPICXX 1
#define MPICH_SKIP_MPICXX 1
#include <mpi.h>
#endif

namespace {

struct Failure : std::exception {
  explicit Failure(std::string m) : message(std::move(m)) {}
  std::string message;
};

void SetError(const std::string& message, char* error, size_t error_size) {
  if (error_size == 0) return;
  std::snprintf(error, error_size, "%s", message.c_str());
}

// HDF5 calls return < 0 on failure; one checked-call helper, so that
// every failure names the call and the file.
template <typename T>
T H5Check(T value, const char* call, const char* path) {
  if (value < 0) throw Failure(std::string(call) + " failed for '" + path + "'");
  return value;
}

void WriteHdf5Columns(const char* path, const KneedynHdf5Table& t) {
  const hsize_t n = t.rows;
  H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);  // errors become messages, not stderr dumps
  const hid_t file = H5Check(H5Fcreate(path, H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT), "H5Fcreate", path);
  // No modification times in the object headers: equal tables → equal bytes.
  const hid_t dcpl = H5Pcreate(H5P_DATASET_CREATE);
  H5Pset_obj_track_times(dcpl, false);
  const hid_t gcpl = H5Pcreate(H5P_GROUP_CREATE);
  H5Pset_obj_track_times(gcpl, false);
  const hid_t space = H5Screate_simple(1, &n, nullptr);
  auto write = [&](hid_t where, const char* name, hid_t type, const void* data) {
    const hid_t ds = H5Check(H5Dcreate2(where, name, type, space, H5P_DEFAULT, dcpl, H5P_DEFAULT), "H5Dcreate2", path);
    if (n > 0) H5Check(H5Dwrite(ds, type, H5S_ALL, H5S_ALL, H5P_DEFAULT, data), "H5Dwrite", path);
    H5Dclose(ds);
  };
  write(file, "index", H5T_NATIVE_LLONG, t.index);
  auto columns = [&](const char* group, const KneedynHdf5Column* cols, size_t count) {
    const hid_t g = H5Check(H5Gcreate2(file, group, H5P_DEFAULT, gcpl, H5P_DEFAULT), "H5Gcreate2", path);
    for (size_t k = 0; k < count; ++k) write(g, cols[k].name, H5T_NATIVE_DOUBLE, cols[k].values);
    H5Gclose(g);
  };
  columns("parameters", t.parameters, t.parameter_count);
  columns("outcomes", t.outcomes, t.outcome_count);
  const hid_t str = H5Tcopy(H5T_C_S1);
  H5Tset_size(str, H5T_VARIABLE);
  H5Tset_cset(str, H5T_CSET_UTF8);
  write(file, "status", str, t.status);
  write(file, "end_reason", str, t.end_reason);
  write(file, "steps", H5T_NATIVE_LLONG, t.steps);
  write(file, "failure", str, t.failure);
  H5Tclose(str);
  H5Sclose(space);
  H5Pclose(dcpl);
  H5Pclose(gcpl);
  H5Check(H5Fclose(file), "H5Fclose", path);
}

int WriteHdf5(const char* path, const KneedynHdf5Table* table, char* error, size_t error_size) {
  try {
    WriteHdf5Columns(path, *table);
    return 0;
  } catch (const Failure& f) {
    SetError(f.message, error, error_size);
  } catch (const std::exception& e) {
    SetError(std::string("HDF5 output: ") + e.what(), error, error_size);
  }
  return 1;
}

#ifdef KNEEDYN_WITH_MPI

void MpiInit(int* rank, int* size, int* ranks_on_node) {
  int initialized = 0;
  MPI_Initialized(&initialized);
  if (!initialized) MPI_Init(nullptr, nullptr);  // MPI's default handler aborts on errors
  MPI_Comm_rank(MPI_COMM_WORLD, rank);
  MPI_Comm_size(MPI_COMM_WORLD, size);
  MPI_Comm node;
  MPI_Comm_split_type(MPI_COMM_WORLD, MPI_COMM_TYPE_SHARED, *rank, MPI_INFO_NULL, &node);
  MPI_Comm_size(node, ranks_on_node);
  MPI_Comm_free(&node);
}

void MpiFinalize() {
  int finalized = 0;
  MPI_Finalized(&finalized);
  if (!finalized) MPI_Finalize();
}

void MpiReduce(double wall_s, long failed, double* max_wall_s, long* sum_failed) {
  MPI_Reduce(&wall_s, max_wall_s, 1, MPI_DOUBLE, MPI_MAX, 0, MPI_COMM_WORLD);
  MPI_Reduce(&failed, sum_failed, 1, MPI_LONG, MPI_SUM, 0, MPI_COMM_WORLD);
}

void MpiGatherSizes(long long my_size, long long* sizes) {
  MPI_Gather(&my_size, 1, MPI_LONG_LONG, sizes, 1, MPI_LONG_LONG, 0, MPI_COMM_WORLD);
}

// Point-to-point in chunks: a part may exceed MPI_Gatherv's int counts and displacements.
void MpiGatherBytes(const char* mine, long long my_size, char* const* buffers, const long long* sizes) {
  constexpr long long kChunk = 1 << 30;
  int rank = 0, size = 1;
  MPI_Comm_rank(MPI_COMM_WORLD, &rank);
  MPI_Comm_size(MPI_COMM_WORLD, &size);
  if (rank != 0) {
    for (long long done = 0; done < my_size;) {
      const int chunk = static_cast<int>(std::min(my_size - done, kChunk));
      MPI_Send(const_cast<char*>(mine + done), chunk, MPI_CHAR, 0, 7, MPI_COMM_WORLD);
      done += chunk;
    }
    return;
  }
  for (int r = 1; r < size; ++r) {
    for (long long done = 0; done < sizes[r];) {
      const int chunk = static_cast<int>(std::min(sizes[r] - done, kChunk));
      MPI_Recv(buffers[r] + done, chunk, MPI_CHAR, r, 7, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
      done += chunk;
    }
  }
}

constexpr KneedynSweepIo kSweepIo = {KNEEDYN_SWEEP_IO_ABI, 1,          &WriteHdf5,      &MpiInit,
                                     &MpiFinalize,         &MpiReduce, &MpiGatherSizes, &MpiGatherBytes};
#else
constexpr KneedynSweepIo kSweepIo = {KNEEDYN_SWEEP_IO_ABI, 0, &WriteHdf5, nullptr, nullptr, nullptr, nullptr, nullptr};
#endif

}  // namespace

extern "C" __attribute__((visibility("default"))) const KneedynSweepIo* kneedyn_sweep_io_v1() { return &kSweepIo; }
