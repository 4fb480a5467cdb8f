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
  std::filesystem::path path;      // the file opened, or the candidate that exists (empty when none does)
  std::string dlopen_error;        // dlerror() when the file exists but dlopen failed
  std::string tried;               // where it was looked for, for a message: the candidates, quoted
                                   // and comma separated, then the dynamic linker's search
};

// Where kneedyn's run-time files (its plugins, its data directory) are looked for, in order:
// <dir>/<relative> for the directory of the shared object holding `anchor` when it is not the
// executable (the Python module), then for that of the running executable, each followed by
// up to four levels above it (the build tree's tests/ and benchmarks/, the install's bin/).
// No path is compiled in: the installed static libraries are the build tree's files, and the
// prefix is chosen at install time.
std::vector<std::filesystem::path> RunTimeCandidates(const std::filesystem::path& relative, const void* anchor);

// RunTimeCandidates of <libdir>/kneedyn/<file_name>.
std::vector<std::filesystem::path> PluginCandidates(const char* file_name, const void* anchor);

// dlopen's the first candidate that exists, with `dlopen_flags` (RTLD_NOW | RTLD_LOCAL or
// RTLD_GLOBAL); when none exists, `file_name` alone, through the dynamic linker's search
// (LD_LIBRARY_PATH, the program's run path, on which kneedyn's CMake package and kneedyn.pc
// put <prefix>/<libdir>/kneedyn: a program built against the installed libraries, anywhere).
// Throws nothing: the caller words the error for its own use.
OpenedPlugin OpenPlugin(const char* file_name, const void* anchor, int dlopen_flags);

}  // namespace kneedyn
