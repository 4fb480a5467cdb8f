#include "formulations/version.hpp"

#include <sundials/sundials_config.h>
#include <ceres/version.h>
#include <Eigen/Core>

#include "kneedyn_git_commit.h"  // generated at every build by cmake/git_commit.cmake

#ifndef KNEEDYN_VERSION
#define KNEEDYN_VERSION "unknown"
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

}  // namespace kneedyn
