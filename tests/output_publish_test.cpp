// Output sets published as one (formulations/run_output.hpp,
// WriteRunOutputs), through `kneedyn run`.
//
// Validates: an --out that holds something other than an output set (a directory named
// trajectory.csv, a foreign file) is refused with exit 2 and left as it was; a second run
// replaces a previous set whole and leaves no temporary; temporaries of dead runs are
// removed; two concurrent runs into one --out both exit normally and leave one consistent
// set; `kill -9` at random moments leaves either the previous complete set or the new
// complete set, never a mix (KNEEDYN_KILL_TRIALS trials, default 6; the `slow` ctest entry
// runs 60).
// Consistency of a set: the three files exist; summary.json parses; the .sto header names
// the scene summary.json names; the .sto's nRows and columns equal the CSV's.
#include <fcntl.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <nlohmann/json.hpp>
#include <random>
#include <set>
#include <thread>

#include "tests/cli_support.hpp"

namespace kneedyn::cli_test {
namespace {

using OutputPublish = CliFixture;

// The set in `out`: "" if absent, else the scene name; fails the test if mixed or partial.
std::string SetIn(const fs::path& out) {
  if (!fs::exists(out)) return "";
  std::set<std::string> names;
  for (const auto& e : fs::directory_iterator(out)) names.insert(e.path().filename().string());
  EXPECT_EQ(names, (std::set<std::string>{"trajectory.csv", "trajectory.sto", "summary.json"}));
  if (names.size() != 3) return "?";
  const nlohmann::json j = nlohmann::json::parse(ReadText(out / "summary.json"), nullptr, false);
  EXPECT_FALSE(j.is_discarded());
  if (j.is_discarded()) return "?";
  const std::string scene = j.at("scene").at("name").get<std::string>();
  const std::string sto = ReadText(out / "trajectory.sto");
  const std::string csv = ReadText(out / "trajectory.csv");
  EXPECT_EQ(sto.rfind("kneedyn_" + scene + "\n", 0), 0u) << "sto of another run than summary " << scene;
  const size_t rows_at = sto.find("nRows=");
  const long sto_rows = rows_at == std::string::npos ? -1 : std::atol(sto.c_str() + rows_at + 6);
  const long csv_rows = static_cast<long>(std::count(csv.begin(), csv.end(), '\n')) - 1;
  EXPECT_EQ(sto_rows, csv_rows) << "csv and sto of different runs";
  const std::string csv_header = csv.substr(0, csv.find('\n'));
  const size_t cols_at = sto.find("nColumns=");
  const long sto_cols = cols_at == std::string::npos ? -1 : std::atol(sto.c_str() + cols_at + 9);
  EXPECT_EQ(sto_cols, static_cast<long>(std::count(csv_header.begin(), csv_header.end(), ',')) + 1);
  return scene;
}

std::string ShortScene(const CliFixture& f) {
  // One ligament, no contact: a different scene name, column count and row count.
  return f.Input("one.yaml", Replaced(ReadText(ReferenceDataDir() + "/scenes/one_ligament.yaml"),
                                      "parameter_set: ../chapter_knee.yaml",
                                      "parameter_set: " + ChapterParameterSetPath()));
}

std::vector<std::string> Temporaries(const fs::path& dir) {
  std::vector<std::string> t;
  for (const auto& e : fs::directory_iterator(dir)) {
    if (e.path().filename().string().find(".kneedyn-tmp-") != std::string::npos) t.push_back(e.path().string());
  }
  return t;
}

TEST_F(OutputPublish, OutWhoseTrajectoryIsADirectoryIsRefusedAndKept) {
  fs::create_directories(fs::path(Out()) / "trajectory.csv");
  const CommandResult r = RunKneedyn(RunArgs(ChapterScenePath()));
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("--out"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("trajectory.csv"), std::string::npos) << r.output;
  EXPECT_TRUE(fs::is_directory(fs::path(Out()) / "trajectory.csv"));
  EXPECT_TRUE(Temporaries(dir_).empty());
}

// --out naming no directory of its own ('.', '..', the root) is refused with the rule; the
// root was refused only by its first entry ("holds 'bin', which is not part of an output set").
TEST_F(OutputPublish, OutThatIsNoDirectoryOfItsOwnIsRefused) {
  for (const char* out : {".", "..", "/", "//"}) {
    ExpectRefused("run '" + ChapterScenePath() + "' --quiet --out '" + out + "'",
                  {std::string("--out = '") + out + "'", "must name a directory of its own"});
  }
}

TEST_F(OutputPublish, OutWithForeignFileIsRefused) {
  fs::create_directories(Out());
  WriteText(fs::path(Out()) / "notes.txt", "mine");
  const CommandResult r = RunKneedyn(RunArgs(ChapterScenePath()));
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_EQ(ReadText(fs::path(Out()) / "notes.txt"), "mine");
}

TEST_F(OutputPublish, SecondRunReplacesTheSetWholeAndRemovesStaleTemporaries) {
  ASSERT_EQ(RunKneedyn(RunArgs(ShortScene(*this))).exit_code, 0);
  EXPECT_EQ(SetIn(Out()), "one_ligament");
  // A temporary of a run that has ended (pid 1 is alive; a reaped child's pid is not).
  const pid_t child = fork();
  if (child == 0) _exit(0);
  waitpid(child, nullptr, 0);
  const fs::path stale = dir_ / (".out.kneedyn-tmp-" + std::to_string(child) + "-deadbeef");
  fs::create_directories(stale);
  WriteText(stale / "trajectory.csv", "half");
  ASSERT_EQ(RunKneedyn(RunArgs(ChapterScenePath())).exit_code, 0);
  EXPECT_EQ(SetIn(Out()), "chapter_impact");
  EXPECT_TRUE(Temporaries(dir_).empty()) << Temporaries(dir_).front();
}

// `kneedyn score DIR/trajectory.csv` writes DIR/trajectory.score.json by default: the next
// run into DIR replaces the set and that score, which scored the replaced trajectory, with it
// (it was refused as a foreign file, so the two documented defaults blocked each other).
TEST_F(OutputPublish, RunReplacesASetHoldingTheScoreOfItsTrajectory) {
  ASSERT_EQ(RunKneedyn(RunArgs(ChapterScenePath())).exit_code, 0);
  const fs::path score = fs::path(Out()) / "trajectory.score.json";
  const CommandResult scored = RunKneedyn("score '" + (fs::path(Out()) / "trajectory.csv").string() + "' --scene '" +
                                          ChapterScenePath() + "'");
  ASSERT_EQ(scored.exit_code, 0) << scored.output;
  ASSERT_TRUE(fs::exists(score));
  const CommandResult again = RunKneedyn(RunArgs(ShortScene(*this)));
  EXPECT_EQ(again.exit_code, 0) << again.output;
  EXPECT_EQ(SetIn(Out()), "one_ligament");
  EXPECT_FALSE(fs::exists(score));
}

TEST_F(OutputPublish, ConcurrentRunsLeaveOneWholeSet) {
  const std::string one = ShortScene(*this);
  for (int trial = 0; trial < 3; ++trial) {
    CommandResult a, b;
    std::thread ta([&] { a = RunKneedyn(RunArgs(ChapterScenePath())); });
    std::thread tb([&] { b = RunKneedyn(RunArgs(one)); });
    ta.join();
    tb.join();
    EXPECT_EQ(a.exit_code, 0) << a.output;
    EXPECT_EQ(b.exit_code, 0) << b.output;
    const std::string s = SetIn(Out());
    EXPECT_TRUE(s == "chapter_impact" || s == "one_ligament") << s;
    EXPECT_TRUE(Temporaries(dir_).empty());
  }
}

TEST_F(OutputPublish, KillNineNeverLeavesAMixedSet) {
  const char* env = std::getenv("KNEEDYN_KILL_TRIALS");
  const int trials = env ? std::atoi(env) : 6;
  ASSERT_EQ(RunKneedyn(RunArgs(ShortScene(*this))).exit_code, 0);
  // Time of a whole run, to spread the kills over it.
  const auto t0 = std::chrono::steady_clock::now();
  ASSERT_EQ(RunKneedyn(RunArgs(ChapterScenePath(), "--formulation mde")).exit_code, 0);
  const double run_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::mt19937 rng(18);
  std::uniform_real_distribution<double> when(0.0, 1.2 * run_s);
  int killed = 0;
  for (int trial = 0; trial < trials; ++trial) {
    const std::string scene = trial % 2 ? ShortScene(*this) : ChapterScenePath();
    const pid_t pid = fork();
    if (pid == 0) {
      const int null = open("/dev/null", O_WRONLY);
      dup2(null, 1);
      dup2(null, 2);
      execl(KNEEDYN_EXE, KNEEDYN_EXE, "run", scene.c_str(), "--formulation", "mde", "--quiet", "--out",
            Out().c_str(), static_cast<char*>(nullptr));
      _exit(127);
    }
    std::this_thread::sleep_for(std::chrono::duration<double>(when(rng)));
    if (kill(pid, SIGKILL) == 0) ++killed;
    int status = 0;
    waitpid(pid, &status, 0);
    const std::string s = SetIn(Out());
    EXPECT_TRUE(s == "chapter_impact" || s == "one_ligament") << "trial " << trial << ": '" << s << "'";
  }
  // The next run cleans what the killed ones left.
  ASSERT_EQ(RunKneedyn(RunArgs(ChapterScenePath(), "--formulation mde")).exit_code, 0);
  EXPECT_EQ(SetIn(Out()), "chapter_impact");
  EXPECT_TRUE(Temporaries(dir_).empty());
  std::printf("kill -9 trials: %d (run %.3f s)\n", trials, run_s);
  (void)killed;
}

}  // namespace
}  // namespace kneedyn::cli_test
