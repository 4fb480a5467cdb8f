// `kneedyn sweep` end to end (ensembles/sweep_cli.hpp). Validates the contract of
// ensembles/README.md:
// the same bytes (sweep.csv and sweep.h5) with 1 and 2 threads, with two shards merged,
// and with 2 MPI ranks; bad input exits 2 and writes nothing, a design too large for memory
// included; no progress output when stderr is not a terminal.
#include <gtest/gtest.h>

#include <sys/wait.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

#include "tests/cli_support.hpp"

using namespace std::string_literals;
namespace fs = std::filesystem;

namespace {

using kneedyn::cli_test::ReadText;
using kneedyn::cli_test::RunShell;

// Each test has its own directory (ctest -j runs them concurrently), under one per process
// (two checkouts' runs on one machine do not meet), removed at exit when every test passed
// (kept to look at otherwise).
fs::path ProcessDir() {
  return fs::temp_directory_path() / ("kneedyn_sweep_cli_test_" + std::to_string(::getpid()));
}
class RemoveProcessDirWhenPassed : public ::testing::Environment {
 public:
  void TearDown() override {
    std::error_code ignored;
    if (::testing::UnitTest::GetInstance()->Passed()) fs::remove_all(ProcessDir(), ignored);
  }
};
::testing::Environment* const g_remove_process_dir =
    ::testing::AddGlobalTestEnvironment(new RemoveProcessDirWhenPassed);

fs::path WorkDir() { return ProcessDir() / ::testing::UnitTest::GetInstance()->current_test_info()->name(); }

int Sh(const std::string& command) {
  const int status = std::system(command.c_str());
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

// WORK/NAME: a spec of the chapter scene with `body` (parameters, design, outcomes...).
fs::path WriteChapterSpec(const fs::path& work, const std::string& name, const std::string& body) {
  fs::create_directories(work);
  const fs::path spec = work / name;
  std::ofstream(spec) << "scene: " << KNEEDYN_SOURCE_DIR << "/reference-data/scenes/chapter_impact.yaml\n" << body;
  return spec;
}

// Seven runs of the chapter scene (a Sobol' design over three parameters).
fs::path WriteSpec(const fs::path& work) {
  return WriteChapterSpec(work, "spec.yaml",
                          "parameters:\n"
                          "  - {name: pulse.amplitude, uniform: [70, 130]}\n"
                          "  - {name: PCL anterior.k_linear, relative: 0.3}\n"
                          "  - {name: MCL anterior.femoral_y, uniform: [-3, 1]}\n"
                          "design: {type: sobol, samples: 7}\n"
                          "outcomes: [liftoff_time, liftoff_flexion, peak_ligament_force, peak_contact_force]\n"
                          "solver: {formulation: dae-reduced, rtol: 1.0e-6, atol: 1.0e-8}\n");
}

std::string Kneedyn() { return KNEEDYN_EXE; }

}  // namespace

TEST(SweepCli, SameBytesWithOneAndTwoThreadsAndFromMergedShards) {
  const fs::path work = WorkDir();
  fs::remove_all(work);
  const fs::path spec = WriteSpec(work);
  ASSERT_EQ(Sh(Kneedyn() + " sweep " + spec.string() + " --threads 1 --out " + (work / "t1").string() +
               " > /dev/null 2> " + (work / "t1.err").string()), 0);
  ASSERT_EQ(Sh(Kneedyn() + " sweep " + spec.string() + " --threads 2 --out " + (work / "t2").string() + " > /dev/null"), 0);
  for (const char* f : {"sweep.csv", "sweep.h5"}) {
    const std::string a = ReadText(work / "t1" / f);
    ASSERT_FALSE(a.empty()) << f;
    EXPECT_EQ(a, ReadText(work / "t2" / f)) << f << " differs between 1 and 2 threads";
  }
  EXPECT_EQ(ReadText(work / "t1.err"), "");  // not a terminal: no progress line
  const std::string csv = ReadText(work / "t1" / "sweep.csv");
  EXPECT_EQ(std::count(csv.begin(), csv.end(), '\n'), 8);  // header + 7 runs
  EXPECT_EQ(csv.rfind("index,pulse.amplitude_N,PCL_anterior.k_linear_N_mm,MCL_anterior.femoral_y_mm,"
                      "liftoff_time_s,liftoff_flexion_deg,peak_F_ACL_anterior_N", 0), 0u);

  for (const char* shard : {"0/2", "1/2"}) {
    ASSERT_EQ(Sh(Kneedyn() + " sweep " + spec.string() + " --threads 1 --shard " + shard + " --out " +
                 (work / "parts").string() + " > /dev/null"), 0);
  }
  ASSERT_EQ(Sh(Kneedyn() + " sweep --merge " + (work / "parts/part-1-of-2.json").string() + " " +
               (work / "parts/part-0-of-2.json").string() + " --out " + (work / "merged").string() + " > " +
               (work / "merge.out").string()), 0);
  for (const char* f : {"sweep.csv", "sweep.h5"}) {
    EXPECT_EQ(ReadText(work / "t1" / f), ReadText(work / "merged" / f)) << f << " differs after merging shards";
  }
  // The merge counts the failed runs as every sweep does (before: the total only).
  size_t failed = 0;
  for (size_t at = csv.find(",failed,"); at != std::string::npos; at = csv.find(",failed,", at + 1)) ++failed;
  EXPECT_NE(ReadText(work / "merge.out").find("merged 2 parts: 7 runs (" + std::to_string(failed) + " failed)"),
            std::string::npos) << ReadText(work / "merge.out");
  // One part alone is refused (runs missing): exit 2, nothing written, and the message names
  // how many runs are missing and the part to run (before: "run index 0 is missing").
  EXPECT_EQ(Sh(Kneedyn() + " sweep --merge " + (work / "parts/part-1-of-2.json").string() + " --out " +
               (work / "half").string() + " > /dev/null 2> " + (work / "half.err").string()), 2);
  EXPECT_FALSE(fs::exists(work / "half"));
  EXPECT_NE(ReadText(work / "half.err").find("4 of 7 runs are missing (indices 0, 2, 4, 6); not given: part-0-of-2.json"),
            std::string::npos) << ReadText(work / "half.err");

  // A part's fields are WritePart's: an unknown field, a row of another shard or a null
  // parameter (a parameter has a value in every run) is refused naming the field (before:
  // merged, the null as a `nan` parameter).
  const std::string part1 = ReadText(work / "parts/part-1-of-2.json");
  const auto refused = [&](const std::string& name, const std::string& text, const std::string& field) {
    std::ofstream(work / name) << text;
    const int code = Sh(Kneedyn() + " sweep --merge " + (work / "parts/part-0-of-2.json").string() + " " +
                        (work / name).string() + " --out " + (work / "bad").string() + " > /dev/null 2> " +
                        (work / "bad.err").string());
    EXPECT_EQ(code, 2) << name;
    EXPECT_NE(ReadText(work / "bad.err").find("field '" + field + "'"), std::string::npos) << ReadText(work / "bad.err");
    EXPECT_FALSE(fs::exists(work / "bad"));
  };
  ASSERT_EQ(part1.rfind("{", 0), 0u);
  refused("extra.json", "{\"extra\":1," + part1.substr(1), "extra");
  const size_t first_index = part1.find("\"index\":1,");
  ASSERT_NE(first_index, std::string::npos) << part1;
  refused("shifted.json", part1.substr(0, first_index) + "\"index\":2," + part1.substr(first_index + 10), "rows[0].index");
  const size_t params = part1.find("\"parameters\":[");
  ASSERT_NE(params, std::string::npos);
  refused("null.json", part1.substr(0, params + 14) + "null" + part1.substr(part1.find(',', params + 14)),
          "rows[0].parameters[0]");

  // sweep.csv and sweep.h5 are published together: when sweep.h5 cannot be written (here a
  // directory in the way of its temporary file), the earlier pair stays as it was (before: a
  // new sweep.csv beside the old sweep.h5).
  const fs::path again = work / "again";
  fs::create_directories(again / "sweep.h5.tmp");
  fs::copy_file(work / "t1" / "sweep.csv", again / "sweep.csv");
  fs::copy_file(work / "t1" / "sweep.h5", again / "sweep.h5");
  const fs::path other = WriteChapterSpec(work, "other.yaml",
                                          "parameters:\n  - {name: pulse.amplitude, uniform: [90, 110]}\n"
                                          "design: {type: grid, levels: 2}\noutcomes: [liftoff_time]\n"
                                          "solver: {formulation: dae-reduced}\n");
  EXPECT_EQ(Sh(Kneedyn() + " sweep " + other.string() + " --threads 1 --out " + again.string() + " > /dev/null 2>&1"), 1);
  EXPECT_EQ(ReadText(again / "sweep.csv"), ReadText(work / "t1" / "sweep.csv"));
  EXPECT_EQ(ReadText(again / "sweep.h5"), ReadText(work / "t1" / "sweep.h5"));
  EXPECT_FALSE(fs::exists(again / "sweep.csv.tmp"));
}

TEST(SweepCli, TwoMpiRanksGiveTheSameBytes) {
  const std::string mpiexec = KNEEDYN_MPIEXEC;
  if (mpiexec.empty()) GTEST_SKIP() << "built without MPI (KNEEDYN_WITH_MPI off)";
  const fs::path work = WorkDir();
  const fs::path spec = WriteSpec(work);
  fs::remove_all(work / "t1");
  fs::remove_all(work / "mpi");
  ASSERT_EQ(Sh(Kneedyn() + " sweep " + spec.string() + " --threads 1 --out " + (work / "t1").string() + " > /dev/null"), 0);
  // CI runs as root; Open MPI refuses root unless told otherwise: only for this command.
  // Under `bootstrap sanitize`, LeakSanitizer reports Open MPI's own allocations (8 KB
  // blocks from its dlclose'd MCA components, "unknown module"): leak checking is off for
  // the ranks only; the single-process run above is still checked. No effect otherwise.
  const std::string env =
      "OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 OMPI_MCA_rmaps_base_oversubscribe=1 "
      "ASAN_OPTIONS=detect_leaks=0 ";
  // timeout: a hung launcher fails the test in 5 minutes instead of holding a ctest slot.
  ASSERT_EQ(Sh(env + "timeout 300 " + mpiexec + " -n 2 --oversubscribe " + Kneedyn() + " sweep " + spec.string() +
               " --threads 1 --out " + (work / "mpi").string() + " > " + (work / "mpi.log").string() + " 2>&1"), 0)
      << ReadText(work / "mpi.log");
  for (const char* f : {"sweep.csv", "sweep.h5"}) {
    EXPECT_EQ(ReadText(work / "t1" / f), ReadText(work / "mpi" / f)) << f << " differs under 2 MPI ranks";
  }
  EXPECT_NE(ReadText(work / "mpi.log").find("on 2 MPI ranks"), std::string::npos) << ReadText(work / "mpi.log");
}

TEST(SweepCli, BadInputExitsTwoNamingFieldAndValueAndWritesNothing) {
  const fs::path work = WorkDir();
  fs::create_directories(work);
  const fs::path bad = work / "bad.yaml";
  std::ofstream(bad) << "scene: " << KNEEDYN_SOURCE_DIR << "/reference-data/scenes/chapter_impact.yaml\n"
                     << "parameters: [{name: mass, uniform: [4, 3]}]\ndesign: {type: sobol, samples: 2}\n"
                        "outcomes: [liftoff_time]\n";
  const fs::path out = work / "bad_out";
  fs::remove_all(out);
  EXPECT_EQ(Sh(Kneedyn() + " sweep " + bad.string() + " --out " + out.string() + " > /dev/null 2> " +
               (work / "bad.err").string()), 2);
  const std::string err = ReadText(work / "bad.err");
  EXPECT_NE(err.find("parameters[0].uniform[1]' = '3'"), std::string::npos) << err;
  EXPECT_FALSE(fs::exists(out));
  EXPECT_EQ(Sh(Kneedyn() + " sweep " + bad.string() + " --shard 2/2 --out " + out.string() + " > /dev/null 2> " +
               (work / "shard.err").string()), 2);
  EXPECT_NE(ReadText(work / "shard.err").find("--shard = '2/2'"), std::string::npos) << ReadText(work / "shard.err");
  EXPECT_FALSE(fs::exists(out));
  // CLI11 gives --merge its first value whatever it is: an option there was read as a part file.
  EXPECT_EQ(Sh(Kneedyn() + " sweep --merge --quiet --out " + out.string() + " > /dev/null 2> " +
               (work / "merge.err").string()), 2);
  EXPECT_NE(ReadText(work / "merge.err").find("--merge = '--quiet': an option, not a part file"), std::string::npos)
      << ReadText(work / "merge.err");
  EXPECT_FALSE(fs::exists(out));
}

// An --out that cannot be written is refused before the runs, with exit 2, in all three modes
// (a whole sweep, a shard, a merge); before, the sweep ran and then failed to write, exit 1.
TEST(SweepCli, UnwritableOutIsRefusedBeforeTheRuns) {
  const fs::path work = WorkDir();
  fs::remove_all(work);
  fs::create_directories(work);
  std::ofstream(work / "a_file") << "x";
  const fs::path out = work / "a_file" / "out";
  const std::string spec = KNEEDYN_SOURCE_DIR "/reference-data/specs/ishigami.yaml";
  for (const std::string& mode : {spec, spec + " --shard 0/2", "--merge " + (work / "part.json").string()}) {
    EXPECT_EQ(Sh(Kneedyn() + " sweep " + mode + " --quiet --out " + out.string() + " > " + (work / "out.txt").string() +
                 " 2> " + (work / "err").string()), 2) << mode;
    const std::string err = ReadText(work / "err");
    EXPECT_NE(err.find("--out = '" + out.string() + "': '" + (work / "a_file").string() + "' is not a directory"),
              std::string::npos) << err;
    EXPECT_EQ(ReadText(work / "out.txt"), "") << "ran before refusing: " << mode;
  }
}

// --shard i/n with n past the run limit is refused naming the option. Before, n parsed past
// LONG_MAX saturated to it, and the shard's index loop overflowed (i + n): the run evaluated
// design rows at negative indices and wrote part-1-of-9223372036854775807.json.
TEST(SweepCli, ShardCountPastTheRunLimitIsRefused) {
  const fs::path work = WorkDir();
  fs::remove_all(work);
  fs::create_directories(work);
  const fs::path out = work / "out";
  for (const std::string shard : {"1/99999999999999999999", "0/100000001", "9223372036854775806/9223372036854775807"}) {
    EXPECT_EQ(Sh(Kneedyn() + " sweep " KNEEDYN_SOURCE_DIR "/reference-data/specs/ishigami.yaml --shard " + shard +
                 " --out " + out.string() + " > /dev/null 2> " + (work / "err").string()), 2) << shard;
    const std::string err = ReadText(work / "err");
    EXPECT_NE(err.find("--shard = '" + shard + "'"), std::string::npos) << err;
    EXPECT_NE(err.find("<= 100000000"), std::string::npos) << err;
    EXPECT_FALSE(fs::exists(out)) << shard;
  }
}

// A spec within the run limit (10⁸) whose design does not fit in memory is refused naming
// the design field, its value and the matrix's size, and writes nothing; before, the
// command ended with "std::bad_alloc". The address space is capped at 3 GB (`ulimit -v`)
// so that the 3.2 GB design matrix fails on any machine; AddressSanitizer's shadow memory
// cannot live under such a cap, so the sanitizer build skips this test.
TEST(SweepCli, DesignLargerThanMemoryIsRefusedNamingTheDesign) {
#if defined(__SANITIZE_ADDRESS__)
  GTEST_SKIP() << "ulimit -v and AddressSanitizer exclude each other";
#endif
  const fs::path work = WorkDir();
  fs::remove_all(work);
  const fs::path spec = WriteChapterSpec(work, "huge.yaml",
                                         "parameters:\n"
                                         "  - {name: pulse.amplitude, uniform: [80, 120]}\n"
                                         "  - {name: pulse.duration, uniform: [0.08, 0.12]}\n"
                                         "  - {name: mass, relative: 0.1}\n"
                                         "  - {name: PCL anterior.k_linear, relative: 0.3}\n"
                                         "design: {type: lhs, samples: 100000000, seed: 1}\n"
                                         "outcomes: [liftoff_time]\n");
  const fs::path out = work / "out";
  for (const std::string shard : {"", " --shard 0/2"}) {
    EXPECT_EQ(Sh("ulimit -v 3000000; " + Kneedyn() + " sweep " + spec.string() + shard + " --threads 1 --out " +
                 out.string() + " > /dev/null 2> " + (work / "err").string()), 2) << shard;
    const std::string err = ReadText(work / "err");
    EXPECT_NE(err.find("huge.yaml: field 'design.samples' = 100000000: 100000000 runs of 4 parameters do not fit"),
              std::string::npos) << err;
    EXPECT_NE(err.find("3.2 GB"), std::string::npos) << err;
    EXPECT_FALSE(fs::exists(out)) << shard;
  }
}

// Open MPI and HDF5 are in the plugin kneedyn_sweep_io.so (ensembles/sweep_io.hpp),
// not in the kneedyn binary: neither its DT_NEEDED entries nor the whole ldd closure name
// them, while the plugin's do (the same check sees them where they are).
TEST(SweepCli, KneedynBinaryMapsNeitherMpiNorHdf5) {
  const std::string needed = RunShell("readelf -d " + Kneedyn()).output;
  ASSERT_NE(needed.find("(NEEDED)"), std::string::npos) << needed;  // readelf ran
  const std::string closure = RunShell("ldd " + Kneedyn()).output;
  ASSERT_NE(closure.find("libc.so"), std::string::npos) << closure;  // ldd ran
  for (const char* lib : {"libmpi", "libhdf5", "libopen-pal", "libcurl"}) {
    EXPECT_EQ(needed.find(lib), std::string::npos) << lib << " in DT_NEEDED:\n" << needed;
    EXPECT_EQ(closure.find(lib), std::string::npos) << lib << " in ldd:\n" << closure;
  }
  const std::string plugin = RunShell("readelf -d " KNEEDYN_SWEEP_IO).output;
  EXPECT_NE(plugin.find("libhdf5"), std::string::npos) << plugin;
  if (!std::string(KNEEDYN_MPIEXEC).empty()) {
    EXPECT_NE(plugin.find("libmpi"), std::string::npos) << plugin;
  }
}

// A kneedyn without its plugin (a copy of the binary in a directory with no
// lib/kneedyn/ above it): `kneedyn run` and `--shard` work; what needs the plugin (sweep.h5,
// --merge) exits 2 with a message naming it and what works instead, before writing anything.
TEST(SweepCli, MissingPluginIsAClearErrorAndWritesNothing) {
  const fs::path work = WorkDir();
  fs::remove_all(work);
  const fs::path spec = WriteSpec(work);
  fs::create_directories(work / "bin");
  fs::copy_file(Kneedyn(), work / "bin" / "kneedyn");
  const std::string lone = (work / "bin" / "kneedyn").string();
  EXPECT_EQ(Sh(lone + " run " KNEEDYN_SOURCE_DIR "/reference-data/scenes/chapter_impact.yaml --formulation ede --out " +
               (work / "run").string() + " > /dev/null 2>&1"), 0);
  EXPECT_TRUE(fs::exists(work / "run" / "trajectory.csv"));
  EXPECT_EQ(Sh(lone + " sweep " + spec.string() + " --threads 1 --shard 0/2 --out " + (work / "parts").string() +
               " > /dev/null 2>&1"), 0);
  EXPECT_TRUE(fs::exists(work / "parts" / "part-0-of-2.json"));
  EXPECT_EQ(Sh(lone + " sweep " + spec.string() + " --threads 1 --out " + (work / "all").string() + " > /dev/null 2> " +
               (work / "all.err").string()), 2);
  const std::string err = ReadText(work / "all.err");
  EXPECT_NE(err.find("kneedyn_sweep_io.so"), std::string::npos) << err;
  EXPECT_NE(err.find((work / "lib" / "kneedyn" / "kneedyn_sweep_io.so").string()), std::string::npos) << err;
  EXPECT_NE(err.find("--shard i/n"), std::string::npos) << err;
  EXPECT_FALSE(fs::exists(work / "all"));
  EXPECT_EQ(Sh(lone + " sweep --merge " + (work / "parts/part-0-of-2.json").string() + " --out " +
               (work / "merged").string() + " > /dev/null 2>&1"), 2);
  EXPECT_FALSE(fs::exists(work / "merged"));
}

// cmake/static_tool.cmake: with KNEEDYN_STATIC_TOOL the kneedyn binary takes SUNDIALS,
// libyaml, libstdc++ and libgcc from their archives and links no Ceres (its plugin,
// solver/ceres_fallback.hpp): none of them, nor Ceres' chain, is a DT_NEEDED entry; if
// libunwind ever is, libgcc_s comes before it, so that C++ exceptions keep GCC's unwinder
// (libunwind.so.8 also defines _Unwind_RaiseException).
TEST(SweepCli, StaticToolNeedsOnlyRuntimeLibraries) {
  if (!KNEEDYN_STATIC_TOOL) GTEST_SKIP() << "KNEEDYN_STATIC_TOOL off";
  const std::string needed = RunShell("readelf -d " + Kneedyn()).output;
  ASSERT_NE(needed.find("(NEEDED)"), std::string::npos) << needed;
  for (const char* lib : {"libglog", "libgflags", "libsundials", "libyaml", "libcholmod", "libcxsparse", "liblapack",
                          "libatlas", "libceres", "libstdc++", "libgfortran", "libgomp", "libmetis"}) {
    EXPECT_EQ(needed.find(lib), std::string::npos) << lib << " in DT_NEEDED:\n" << needed;
  }
  const size_t gcc_s = needed.find("[libgcc_s.so"), unwind = needed.find("[libunwind.so");
  if (unwind != std::string::npos) {
    ASSERT_NE(gcc_s, std::string::npos) << needed;
    EXPECT_LT(gcc_s, unwind) << needed;
  }
}
