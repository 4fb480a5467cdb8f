// Finding and opening kneedyn's run-time plugins, <libdir>/kneedyn/<file> (the Ceres
// fallback, solver/ceres_fallback.hpp; the sweep I/O, ensembles/sweep_io.hpp). They are
// dlopen'ed on first use so that a plain run never maps their libraries.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

namespace kneedyn {

struct OpenedPlugin {
  void* handle = nullptr;          // dlopen handle; null when no candidate file exists or dlopen failed
  std::filesystem::path path;      // the candidate that exists (empty when none does)
  std::string dlopen_error;        // dlerror() when the file exists but dlopen failed
  std::string tried;               // the candidates that do not exist, quoted and comma separated
};

// Candidates, in order: <dir>/<libdir>/kneedyn/<file_name> for the directory of the shared
// object holding `anchor` (when it is not the executable, e.g. the Python module) and of the
// running executable, and up to four levels above each (the build tree's tests/ and
// benchmarks/, the install's bin/); then `extra_paths` (absolute build-tree or install paths).
std::vector<std::filesystem::path> PluginCandidates(const char* file_name, const void* anchor,
                                                    const std::vector<std::string>& extra_paths = {});

// dlopen's the first candidate that exists, with `dlopen_flags` (RTLD_NOW | RTLD_LOCAL or
// RTLD_GLOBAL). Throws nothing: the caller words the error for its own use.
OpenedPlugin OpenPlugin(const char* file_name, const void* anchor, int dlopen_flags,
                        const std::vector<std::string>& extra_paths = {});

}  // namespace kneedyn
