#include "solver/ceres_fallback.hpp"

#include <dlfcn.h>

#include <string>

#include "solver/error.hpp"
#include "solver/plugin_loader.hpp"

namespace kneedyn {
namespace {

constexpr const char* kPluginName = "kneedyn_ceres_fallback.so";

KneedynCeresSolveFn Load() {
  const OpenedPlugin plugin = OpenPlugin(kPluginName, reinterpret_cast<const void*>(&CeresFallback),
                                         RTLD_NOW | RTLD_LOCAL);
  if (plugin.path.empty()) {
    Throw<SolverError>("ConsistentInitialize", "the Ceres fallback plugin ", kPluginName,
                       " (Levenberg-Marquardt, needed when the direct Newton path of a level fails) is missing; looked for ",
                       plugin.tried, ". Reinstall kneedyn");
  }
  if (!plugin.handle) {
    Throw<SolverError>("ConsistentInitialize", "cannot load the Ceres fallback plugin '", plugin.path.string(),
                       "': ", plugin.dlopen_error);
  }
  void* entry = dlsym(plugin.handle, KNEEDYN_CERES_FALLBACK_ENTRY);
  if (!entry) {
    Throw<SolverError>("ConsistentInitialize", "the Ceres fallback plugin '", plugin.path.string(), "' has no ",
                       KNEEDYN_CERES_FALLBACK_ENTRY, "; it is not of this kneedyn (reinstall kneedyn)");
  }
  return reinterpret_cast<KneedynCeresSolveFn>(entry);
}

}  // namespace

KneedynCeresSolveFn CeresFallback() {
  static const KneedynCeresSolveFn solve = Load();
  return solve;
}

}  // namespace kneedyn
