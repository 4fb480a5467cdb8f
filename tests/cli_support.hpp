// Shared by the command-line tests (cli_test.cpp, hostile_input_test.cpp, output_publish_test.cpp):
// runs `kneedyn` as a child process and checks the exit-code contract on every call. The
// shell and file helpers (RunShell, ReadText, WriteText, ...) also serve tests that do not
// run kneedyn (ensembles/tests/sweep_cli_test.cpp, run_output_format_test.cpp).
#pragma once

#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "scene/scene.hpp"

namespace kneedyn::cli_test {

namespace fs = std::filesystem;

struct CommandResult {
  int exit_code = -1;   // -1: killed by a signal
  std::string output;   // stdout and stderr
};

// Runs a shell command with stderr merged into stdout (any program; no contract check).
inline CommandResult RunShell(const std::string& shell_command) {
  const std::string command = shell_command + " 2>&1";
  CommandResult result;
  FILE* pipe = popen(command.c_str(), "r");
  if (pipe == nullptr) return result;
  char buffer[4096];
  size_t n = 0;
  while ((n = fread(buffer, 1, sizeof(buffer), pipe)) > 0) result.output.append(buffer, n);
  const int status = pclose(pipe);
  result.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return result;
}

inline std::string ReadText(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

inline void WriteText(const fs::path& p, const std::string& text) {
  std::ofstream out(p, std::ios::binary);
  out << text;
  out.close();
  // A short write (a full disk) would pass a different input to the test; say so instead.
  if (!out) ADD_FAILURE() << "could not write " << text.size() << " bytes to " << p << " (a full disk?)";
}

// `text` with the first occurrence of `from` replaced by `to` (the test fails if absent).
inline std::string Replaced(std::string text, const std::string& from, const std::string& to) {
  const size_t at = text.find(from);
  EXPECT_NE(at, std::string::npos) << "'" << from << "' not in the text";
  if (at != std::string::npos) text.replace(at, from.size(), to);
  return text;
}

inline std::string ChapterScenePath() { return ReferenceDataDir() + "/scenes/chapter_impact.yaml"; }
inline std::string ChapterParameterSetPath() { return ReferenceDataDir() + "/chapter_knee.yaml"; }

// The chapter scene's text with the parameter set given by absolute path (so that it can be
// written anywhere).
inline std::string ChapterSceneText() {
  return Replaced(ReadText(ChapterScenePath()), "parameter_set: ../chapter_knee.yaml",
                  "parameter_set: " + ChapterParameterSetPath());
}

// What runs kneedyn itself needs its path, KNEEDYN_EXE (a compile definition of the tests
// that run it); the helpers above serve any test.
#ifdef KNEEDYN_EXE

// Runs `kneedyn <args>` with stderr merged into stdout. The contract (README "Exit codes")
// is checked here for every call: the process exits normally with 0, 1 or 2.
inline CommandResult RunKneedyn(const std::string& args) {
  const CommandResult result = RunShell(std::string("'") + KNEEDYN_EXE + "' " + args);
  EXPECT_NE(result.exit_code, -1) << "killed by a signal: " << args.substr(0, 300);
  EXPECT_TRUE(result.exit_code == 0 || result.exit_code == 1 || result.exit_code == 2)
      << "exit code " << result.exit_code << " outside the contract from: " << args.substr(0, 300);
  return result;
}

// A fresh, empty temporary directory per test; removed at the end.
class CliFixture : public ::testing::Test {
 public:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = fs::temp_directory_path() /
           (std::string("kneedyn_") + info->test_suite_name() + "_" + info->name() + "_" +
            std::to_string(::getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_ / "in");
  }
  void TearDown() override { fs::remove_all(dir_); }

  std::string Out() const { return (dir_ / "out").string(); }

  // Writes an input file under dir/in and returns its path.
  std::string Input(const std::string& name, const std::string& text) const {
    const fs::path p = dir_ / "in" / name;
    WriteText(p, text);
    return p.string();
  }

  // Every entry (file or directory) under dir, except the inputs under dir/in.
  std::vector<std::string> Written() const {
    std::vector<std::string> files;
    for (const auto& e : fs::recursive_directory_iterator(dir_)) {
      const std::string p = e.path().string();
      if (p.rfind((dir_ / "in").string(), 0) != 0) files.push_back(p);
    }
    return files;
  }

  // Bad input: exit code 2, a message with every needle, nothing written, and a message of
  // bounded length (values are echoed cut).
  CommandResult ExpectRefused(const std::string& args, const std::vector<std::string>& needles) {
    const CommandResult r = RunKneedyn(args);
    EXPECT_EQ(r.exit_code, 2) << args.substr(0, 300) << "\n" << r.output;
    for (const std::string& n : needles) {
      EXPECT_NE(r.output.find(n), std::string::npos) << "'" << n << "' missing from: " << r.output;
    }
    EXPECT_TRUE(Written().empty()) << args.substr(0, 300) << " left " << Written().front();
    EXPECT_LT(r.output.size(), 2000u) << r.output.substr(0, 300);
    return r;
  }

  // `kneedyn run SCENE --quiet --out OUT EXTRA`.
  std::string RunArgs(const std::string& scene, const std::string& extra = "") const {
    return "run '" + scene + "' --quiet --out '" + Out() + "' " + extra;
  }

  fs::path dir_;
};

#endif  // KNEEDYN_EXE

}  // namespace kneedyn::cli_test
