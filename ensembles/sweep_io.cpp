#include "ensembles/sweep_io.hpp"

#include <dlfcn.h>

#include <filesystem>
#include <string>
#include <vector>

#include "solver/error.hpp"

#ifndef KNEEDYN_PLUGIN_LIBDIR
#define KNEEDYN_PLUGIN_LIBDIR "lib"
#endif

namespace kneedyn::ensembles {

namespace fs = std::filesystem;

namespace {

constexpr const char* kPluginName = "kneedyn_sweep_io.so";

// Directories to search from: the binary holding this code when it is a shared object
// (the Python module), then the running executable's.
std::vector<fs::path> StartDirectories() {
  std::vector<fs::path> dirs;
  std::error_code ec;
  const fs::path exe = fs::weakly_canonical(fs::read_symlink("/proc/self/exe", ec), ec);
  Dl_info info{};
  if (dladdr(reinterpret_cast<void*>(&SweepIo), &info) != 0 && info.dli_fname && info.dli_fname[0] == '/') {
    std::error_code ec2;
    const fs::path object = fs::weakly_canonical(fs::path(info.dli_fname), ec2);
    if (!ec2 && object != exe) dirs.push_back(object.parent_path());
  }
  if (!exe.empty()) dirs.push_back(exe.parent_path());
  return dirs;
}

const KneedynSweepIo* Load(std::string* tried) {
  for (fs::path dir : StartDirectories()) {
    for (int up = 0; up < 5 && !dir.empty(); ++up, dir = dir.parent_path()) {
      const fs::path candidate = dir / KNEEDYN_PLUGIN_LIBDIR / "kneedyn" / kPluginName;
      std::error_code ec;
      if (fs::is_regular_file(candidate, ec)) {
        // RTLD_GLOBAL: Open MPI's own components (dlopen'ed by MPI_Init) resolve its symbols.
        void* handle = dlopen(candidate.c_str(), RTLD_NOW | RTLD_GLOBAL);
        if (!handle) {
          const char* why = dlerror();
          Throw<InputError>("kneedyn sweep", "cannot load the sweep I/O plugin '", candidate.string(), "': ",
                            why ? why : "unknown dlopen error",
                            " (it links Open MPI and HDF5; needed for mpirun and sweep.h5; --shard i/n needs none)");
        }
        const auto entry = reinterpret_cast<KneedynSweepIoEntry>(dlsym(handle, KNEEDYN_SWEEP_IO_ENTRY));
        const KneedynSweepIo* io = entry ? entry() : nullptr;
        if (!io || io->abi != KNEEDYN_SWEEP_IO_ABI) {
          Throw<InputError>("kneedyn sweep", "the sweep I/O plugin '", candidate.string(), "' is not of this kneedyn (",
                            entry ? StrCat("interface ", io ? io->abi : -1, ", expected ", KNEEDYN_SWEEP_IO_ABI)
                                  : std::string("no " KNEEDYN_SWEEP_IO_ENTRY),
                            "); reinstall kneedyn");
        }
        return io;
      }
      *tried += (tried->empty() ? "'" : ", '") + candidate.string() + "'";
      if (dir == dir.root_path()) break;
    }
  }
  return nullptr;
}

}  // namespace

const KneedynSweepIo& SweepIo() {
  static const KneedynSweepIo* const io = [] {
    std::string tried;
    const KneedynSweepIo* found = Load(&tried);
    if (!found) {
      Throw<InputError>("kneedyn sweep", "the sweep I/O plugin ", kPluginName,
                        " (Open MPI and HDF5: needed for mpirun and for writing sweep.h5) is missing; looked for ",
                        tried.empty() ? std::string("(no directory to search)") : tried,
                        ". Reinstall kneedyn, or use --shard i/n (part files need no plugin)");
    }
    return found;
  }();
  return *io;
}

}  // namespace kneedyn::ensembles
