// Loads the sweep I/O plugin kneedyn_sweep_io.so (sweep_io_plugin.hpp: Open MPI and
// HDF5) on first use, so that only what needs those libraries maps them.
// Where it is looked for (found at run time, never baked in; as ReferenceDataDir finds the
// data): <dir>/<libdir>/kneedyn/kneedyn_sweep_io.so for <dir> the directory of the
// binary that holds this code (the Python module) or of the running executable, and up to
// four levels above; <libdir> is the install's library directory (e.g. lib). The build tree
// has the same layout: <build>/<libdir>/kneedyn/ beside <build>/formulations/kneedyn.
#pragma once

#include "ensembles/sweep_io_plugin.hpp"

namespace kneedyn::ensembles {

// The plugin's functions, loaded once (thread-safe). Throws InputError (exit 2) naming the
// plugin, the paths tried and the loader's message when it is missing or unusable, and
// telling what works without it (--shard i/n writes part files, which need no plugin).
const KneedynSweepIo& SweepIo();

}  // namespace kneedyn::ensembles
