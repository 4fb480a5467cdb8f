#include "solver/ceres_fallback.hpp"

#include <dlfcn.h>

#include <filesystem>
#include <string>
#include <vector>

#include "solver/error.hpp"

#ifndef KNEEDYN_PLUGIN_LIBDIR
#define KNEEDYN_PLUGIN_LIBDIR "lib"
#endif

namespace kneedyn {
namespace {

namespace fs = std::filesystem;
constexpr const char* kPluginName = "kneedyn_ceres_fallback.so";

// Where to look: <dir>/<libdir>/kneedyn/ for the directory of the object holding this code
// (a shared object such as the Python module) and of the running executable, and up to four
// levels above each (the build tree's tests/, benchmarks/, the install's bin/); then the
// build tree's and the install prefix's own paths (programs elsewhere linking the installed
// library).
std::vector<fs::path> Candidates() {
  std::vector<fs::path> dirs;
  std::error_code ec;
  const fs::path exe = fs::weakly_canonical(fs::read_symlink("/proc/self/exe", ec), ec);
  Dl_info info{};
  if (dladdr(reinterpret_cast<void*>(&CeresFallback), &info) != 0 && info.dli_fname && info.dli_fname[0] == '/') {
    std::error_code ec2;
    const fs::path object = fs::weakly_canonical(fs::path(info.dli_fname), ec2);
    if (!ec2 && object != exe) dirs.push_back(object.parent_path());
  }
  if (!exe.empty()) dirs.push_back(exe.parent_path());
  std::vector<fs::path> out;
  for (fs::path dir : dirs) {
    for (int up = 0; up < 5 && !dir.empty(); ++up, dir = dir.parent_path()) {
      out.push_back(dir / KNEEDYN_PLUGIN_LIBDIR / "kneedyn" / kPluginName);
      if (dir == dir.root_path()) break;
    }
  }
#ifdef KNEEDYN_CERES_FALLBACK_BUILD_PATH
  out.emplace_back(KNEEDYN_CERES_FALLBACK_BUILD_PATH);
#endif
#ifdef KNEEDYN_CERES_FALLBACK_INSTALL_PATH
  out.emplace_back(KNEEDYN_CERES_FALLBACK_INSTALL_PATH);
#endif
  return out;
}

KneedynCeresSolveFn Load() {
  std::string tried;
  for (const fs::path& candidate : Candidates()) {
    std::error_code ec;
    if (!fs::is_regular_file(candidate, ec)) {
      tried += (tried.empty() ? "'" : ", '") + candidate.string() + "'";
      continue;
    }
    void* handle = dlopen(candidate.c_str(), RTLD_NOW | RTLD_LOCAL);
    if (!handle) {
      const char* why = dlerror();
      Throw<SolverError>("ConsistentInitialize", "cannot load the Ceres fallback plugin '", candidate.string(),
                         "': ", why ? why : "unknown dlopen error");
    }
    void* entry = dlsym(handle, KNEEDYN_CERES_FALLBACK_ENTRY);
    if (!entry) {
      Throw<SolverError>("ConsistentInitialize", "the Ceres fallback plugin '", candidate.string(), "' has no ",
                         KNEEDYN_CERES_FALLBACK_ENTRY, "; it is not of this kneedyn (reinstall kneedyn)");
    }
    return reinterpret_cast<KneedynCeresSolveFn>(entry);
  }
  Throw<SolverError>("ConsistentInitialize", "the Ceres fallback plugin ", kPluginName,
                     " (Levenberg-Marquardt, needed when the direct Newton path of a level fails) is missing; looked for ",
                     tried.empty() ? std::string("(nothing)") : tried, ". Reinstall kneedyn");
}

}  // namespace

KneedynCeresSolveFn CeresFallback() {
  static const KneedynCeresSolveFn solve = Load();
  return solve;
}

}  // namespace kneedyn
