// One output file written whole or not at all (formulations/output_file.hpp), the writer of
// the tools' single files (work_precision, score, batch, the catalog, make_reference,
// kneedyn_inverse, compare_counters, calibrate_reconstruction, simbody_work_precision).
//
// Validates: CheckOutputFile refuses an empty path, a directory, a path under a regular
// file, a directory this process cannot write in, a device, a FIFO and a symbolic link,
// naming the option and the path, and leaves nothing behind; it accepts a path under missing directories. WriteOutputFile creates
// them, writes the exact bytes, replaces an earlier file, and when it is refused leaves
// neither the file nor its temporary.
// Does not validate: a kill during the write (the rename is the atomic step; the run's own
// output sets are killed in output_publish_test.cpp).
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>

#include "formulations/output_file.hpp"
#include "solver/error.hpp"

namespace kneedyn {
namespace {

namespace fs = std::filesystem;

class OutputFile : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::path(::testing::TempDir()) / ("kneedyn_output_file_" + std::to_string(::getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override {
    fs::permissions(dir_, fs::perms::owner_all, fs::perm_options::add);
    fs::remove_all(dir_);
  }
  // The InputError's message of CheckOutputFile("tool", "--json", path), "" if accepted.
  static std::string Refusal(const std::string& path) {
    try {
      CheckOutputFile("tool", "--json", path);
    } catch (const InputError& e) {
      return e.what();
    }
    return "";
  }
  static std::string Read(const fs::path& p) {
    std::ifstream in(p, std::ios::binary);
    return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  }
  fs::path dir_;
};

TEST_F(OutputFile, UnwritablePathsAreRefusedNamingOptionAndPathAndNothingIsCreated) {
  std::ofstream(dir_ / "a_file") << "x";
  const std::string under_file = (dir_ / "a_file" / "sub" / "out.json").string();
  EXPECT_NE(Refusal("").find("tool(): --json = '': must name a file"), std::string::npos) << Refusal("");
  EXPECT_NE(Refusal(dir_.string()).find("is a directory"), std::string::npos) << Refusal(dir_.string());
  EXPECT_NE(Refusal(under_file).find("tool(): --json = '" + under_file + "': '" + (dir_ / "a_file").string() +
                                     "' is not a directory"),
            std::string::npos)
      << Refusal(under_file);
  if (::geteuid() != 0) {  // root writes anywhere
    fs::create_directories(dir_ / "read_only");
    fs::permissions(dir_ / "read_only", fs::perms::owner_read | fs::perms::owner_exec);
    EXPECT_NE(Refusal((dir_ / "read_only" / "out.json").string()).find("cannot write in"), std::string::npos);
  }
  // /proc: writable by its mode bits for root, yet nothing can be created there.
  EXPECT_NE(Refusal("/proc/kneedyn_no_such/out.json").find("cannot"), std::string::npos)
      << Refusal("/proc/kneedyn_no_such/out.json");
  const std::string deep = (dir_ / "new" / "deeper" / "out.json").string();
  EXPECT_EQ(Refusal(deep), "");
  EXPECT_FALSE(fs::exists(dir_ / "new")) << "CheckOutputFile created a directory";
  EXPECT_EQ(std::distance(fs::directory_iterator(dir_), fs::directory_iterator()), 1 + (::geteuid() != 0))
      << "CheckOutputFile left its probe behind";
}

// The directory form (kneedyn sweep --out, the catalog's --out): an existing directory or one
// that can be created is accepted, a file or a directory under one is refused; nothing is
// left behind either way.
TEST_F(OutputFile, DirectoryFormAcceptsExistingOrCreatableDirectoriesOnly) {
  std::ofstream(dir_ / "a_file") << "x";
  const auto refusal = [](const fs::path& dir) {
    try {
      CheckOutputDirectoryWritable("tool", "--out", dir.string());
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  EXPECT_EQ(refusal(dir_), "");
  EXPECT_EQ(refusal(dir_ / "new" / "deeper"), "");
  EXPECT_NE(refusal(dir_ / "a_file").find("--out = '" + (dir_ / "a_file").string() + "': exists and is not a directory"),
            std::string::npos)
      << refusal(dir_ / "a_file");
  EXPECT_NE(refusal(dir_ / "a_file" / "out").find("' is not a directory"), std::string::npos);
  EXPECT_NE(refusal("/proc/kneedyn_no_such").find("cannot"), std::string::npos) << refusal("/proc/kneedyn_no_such");
  EXPECT_NE(refusal("").find("must name a directory"), std::string::npos);
  EXPECT_EQ(std::distance(fs::directory_iterator(dir_), fs::directory_iterator()), 1) << "something was left";
}

TEST_F(OutputFile, WritesTheExactBytesIntoNewDirectoriesAndReplacesAnEarlierFile) {
  const fs::path file = dir_ / "new" / "deeper" / "out.json";
  const std::string text = std::string("{\"a\": 1}\n") + std::string(1, '\0') + "\xff";
  WriteOutputFile("tool", "--json", file.string(), text);
  EXPECT_EQ(Read(file), text);
  WriteOutputFile("tool", "--json", file.string(), "second\n");
  EXPECT_EQ(Read(file), "second\n");
  EXPECT_FALSE(fs::exists(file.string() + ".tmp"));
}

TEST_F(OutputFile, AFailedWriteLeavesNeitherFileNorTemporary) {
  std::ofstream(dir_ / "a_file") << "x";
  const fs::path file = dir_ / "a_file" / "out.json";
  EXPECT_THROW(WriteOutputFile("tool", "--json", file.string(), "text"), InputError);
  // A directory where the file should go: refused before a temporary is written.
  fs::create_directories(dir_ / "taken" / "out.json" / "inside");
  try {
    WriteOutputFile("tool", "--json", (dir_ / "taken" / "out.json").string(), "text");
    ADD_FAILURE() << "wrote over a directory";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("is a directory"), std::string::npos) << e.what();
  }
  EXPECT_FALSE(fs::exists(dir_ / "taken" / "out.json.tmp"));
  EXPECT_TRUE(fs::is_directory(dir_ / "taken" / "out.json" / "inside"));
}

// A device, a FIFO and a symbolic link are refused, and stay as they were: the write renames
// a new file over the path, which replaced each of them by a regular file (as root,
// `kneedyn score ... --out /dev/full` replaced the device).
TEST_F(OutputFile, DevicesFifosAndSymbolicLinksAreRefusedAndLeftAlone) {
  std::ofstream(dir_ / "target.json") << "keep";
  fs::create_symlink(dir_ / "target.json", dir_ / "link.json");
  ASSERT_EQ(::mkfifo((dir_ / "fifo.json").c_str(), 0600), 0);
  EXPECT_NE(Refusal((dir_ / "link.json").string()).find("is a symbolic link"), std::string::npos)
      << Refusal((dir_ / "link.json").string());
  EXPECT_NE(Refusal((dir_ / "fifo.json").string()).find("exists and is not a regular file"), std::string::npos)
      << Refusal((dir_ / "fifo.json").string());
  EXPECT_NE(Refusal("/dev/null").find("tool(): --json = '/dev/null': exists and is not a regular file"),
            std::string::npos)
      << Refusal("/dev/null");
  EXPECT_THROW(WriteOutputFile("tool", "--json", (dir_ / "link.json").string(), "text"), InputError);
  EXPECT_THROW(WriteOutputFile("tool", "--json", (dir_ / "fifo.json").string(), "text"), InputError);
  EXPECT_TRUE(fs::is_symlink(fs::symlink_status(dir_ / "link.json")));
  EXPECT_TRUE(fs::is_fifo(fs::symlink_status(dir_ / "fifo.json")));
  EXPECT_EQ(Read(dir_ / "target.json"), "keep");
  EXPECT_TRUE(fs::is_character_file("/dev/null"));
  EXPECT_EQ(Refusal((dir_ / "target.json").string()), "");  // a regular file is replaced, as before
}

}  // namespace
}  // namespace kneedyn
