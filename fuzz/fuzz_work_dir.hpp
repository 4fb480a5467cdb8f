// The private directory of one fuzzing process: the targets write their input there as the
// files the code under test reads by path.
#pragma once

#include <unistd.h>

#include <filesystem>
#include <string>

namespace kneedyn_fuzz {

inline const std::string& WorkDir() {
  static const std::string dir = [] {
    const std::filesystem::path p =
        std::filesystem::temp_directory_path() / ("kneedyn_fuzz_" + std::to_string(::getpid()));
    std::filesystem::create_directories(p);
    return p.string();
  }();
  return dir;
}

}  // namespace kneedyn_fuzz
