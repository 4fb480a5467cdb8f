#include "formulations/version.hpp"

#include <sundials/sundials_config.h>
#include <ceres/version.h>
#include <Eigen/Core>

#include "kneedyn_git_commit.h"  // generated at every build by cmake/git_commit.cmake

#ifndef KNEEDYN_VERSION
#define KNEEDYN_VERSION "unknown"
#endif
// Set by formulations/CMakeLists.txt from the configured build (cmake/sundials.cmake for
// SUNDIALS' origin and flags).
#ifndef KNEEDYN_CXX_COMPILER
#define KNEEDYN_CXX_COMPILER "unknown"
#endif
#ifndef KNEEDYN_CXX_FLAGS
#define KNEEDYN_CXX_FLAGS "unknown"
#endif
#ifndef KNEEDYN_SUNDIALS_ORIGIN
#define KNEEDYN_SUNDIALS_ORIGIN "unknown"
#endif
#ifndef KNEEDYN_SUNDIALS_C_FLAGS
#define KNEEDYN_SUNDIALS_C_FLAGS "unknown"
#endif

namespace kneedyn {

std::string KneedynVersion() { return KNEEDYN_VERSION; }
std::string KneedynGitCommit() { return KNEEDYN_GIT_COMMIT; }
std::string SundialsVersion() { return SUNDIALS_VERSION; }
std::string CeresVersion() { return CERES_VERSION_STRING; }
std::string EigenVersion() {
  return std::to_string(EIGEN_WORLD_VERSION) + "." + std::to_string(EIGEN_MAJOR_VERSION) + "." +
         std::to_string(EIGEN_MINOR_VERSION);
}

std::string VersionReport(const std::string& program) {
  const std::string commit = KneedynGitCommit();
  const std::string origin = commit.empty() ? std::string("not built from git") : "git " + commit;
  const std::string first = program == "kneedyn"
                                ? "kneedyn " + KneedynVersion() + " (" + origin + ")"
                                : program + " (kneedyn " + KneedynVersion() + ", " + origin + ")";
  return first + "\nSUNDIALS " +
         SundialsVersion() + ", Ceres " + CeresVersion() + ", Eigen " + EigenVersion();
}

std::vector<BuildComponent> BuildManifest() {
  const std::string kneedyn_flags = std::string(KNEEDYN_CXX_COMPILER) + " " + KNEEDYN_CXX_FLAGS;
  const std::string commit = KneedynGitCommit();
  return {
      {"kneedyn", KneedynVersion(), commit.empty() ? "this repository" : "this repository, git " + commit,
       kneedyn_flags},
      {"SUNDIALS", SundialsVersion(), KNEEDYN_SUNDIALS_ORIGIN, KNEEDYN_SUNDIALS_C_FLAGS},
      // Header-only: compiled into kneedyn's objects with kneedyn's flags.
      {"Eigen", EigenVersion(), "Debian 12 package libeigen3-dev (header-only)", kneedyn_flags},
      // Consistent initialization's fallback only; not on any method's time axis (the
      // programs hold only Ceres' header-only Jet; its solver is in the plugin).
      {"Ceres", CeresVersion(),
       "Debian 12 binary package libceres-dev (static libceres.a, in the plugin kneedyn_ceres_fallback, "
       "loaded only when the direct Newton start at t = 0 fails)",
       "as built by Debian (dpkg-buildflags: -O2)"},
  };
}

}  // namespace kneedyn
