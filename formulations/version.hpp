// What built this program: kneedyn's version, the git commit of the source tree it was built
// from (empty when not built from git; "-dirty" when it had uncommitted changes), and the
// versions of the numerical libraries (SUNDIALS, Ceres, Eigen). Used by `--version` and
// summary.json.
#pragma once

#include <string>
#include <vector>

namespace kneedyn {

std::string KneedynVersion();    // "0.1.0"
std::string KneedynGitCommit();  // "1a2b3c4d5e6f", "1a2b3c4d5e6f-dirty" or ""
std::string SundialsVersion();
std::string CeresVersion();
std::string EigenVersion();
// Two lines: "kneedyn 0.1.0 (git 1a2b3c4d5e6f)\nSUNDIALS 6.4.1, Ceres 2.1.0, Eigen 3.4.0";
// other programs: "work_precision (kneedyn 0.1.0, git 1a2b3c4d5e6f)\n...".
std::string VersionReport(const std::string& program);

// One component of a benchmark's fairness manifest: what ran, where it came from and how it
// was compiled, so that a reader can see whether two methods in one diagram were built alike.
struct BuildComponent {
  std::string name;           // "kneedyn", "SUNDIALS", "Ceres", "Eigen"
  std::string version;
  std::string origin;         // "this repository", "Debian 12 source package ... built by kneedyn", ...
  std::string compile_flags;  // compiler and optimization flags, or how they are known
};
// The components compiled into this program (kneedyn, SUNDIALS, Eigen, Ceres).
std::vector<BuildComponent> BuildManifest();

}  // namespace kneedyn
