#include "ensembles/sweep_io.hpp"

#include <dlfcn.h>

#include <string>

#include "solver/error.hpp"
#include "solver/plugin_loader.hpp"

namespace kneedyn::ensembles {

namespace {

constexpr const char* kPluginName = "kneedyn_sweep_io.so";

// nullptr when no candidate exists (*tried lists them); throws when one exists but is not
// loadable or not of this kneedyn.
const KneedynSweepIo* Load(std::string* tried) {
  // RTLD_GLOBAL: Open MPI's own components (dlopen'ed by MPI_Init) resolve its symbols.
  const OpenedPlugin plugin = OpenPlugin(kPluginName, reinterpret_cast<const void*>(&SweepIo), RTLD_NOW | RTLD_GLOBAL);
  *tried = plugin.tried;
  if (plugin.path.empty()) return nullptr;
  if (!plugin.handle) {
    Throw<InputError>("kneedyn sweep", "cannot load the sweep I/O plugin '", plugin.path.string(), "': ",
                      plugin.dlopen_error,
                      " (it links Open MPI and HDF5; needed for mpirun and sweep.h5; --shard i/n needs none)");
  }
  const auto entry = reinterpret_cast<KneedynSweepIoEntry>(dlsym(plugin.handle, KNEEDYN_SWEEP_IO_ENTRY));
  const KneedynSweepIo* io = entry ? entry() : nullptr;
  if (!io || io->abi != KNEEDYN_SWEEP_IO_ABI) {
    Throw<InputError>("kneedyn sweep", "the sweep I/O plugin '", plugin.path.string(), "' is not of this kneedyn (",
                      entry ? StrCat("interface ", io ? io->abi : -1, ", expected ", KNEEDYN_SWEEP_IO_ABI)
                            : std::string("no " KNEEDYN_SWEEP_IO_ENTRY),
                      "); reinstall kneedyn");
  }
  return io;
}

}  // namespace

const KneedynSweepIo& SweepIo() {
  static const KneedynSweepIo* const io = [] {
    std::string tried;
    const KneedynSweepIo* found = Load(&tried);
    if (!found) {
      Throw<InputError>("kneedyn sweep", "the sweep I/O plugin ", kPluginName,
                        " (Open MPI and HDF5: needed for mpirun and for writing sweep.h5) is missing; looked for ",
                        tried, ". Reinstall kneedyn, or use --shard i/n (part files need no plugin)");
    }
    return found;
  }();
  return *io;
}

}  // namespace kneedyn::ensembles
