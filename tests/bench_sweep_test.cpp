// The short work-precision sweep (benchmarks/work_precision.cpp --short): its JSON has
// every field the reports read, every registered formulation appears, a deliberately
// broken setting (dae, max_steps = 3) is a failed result with its reason, the CSV has one
// row per result, and the tightest dae setting agrees with the stored reference (produced
// by mde with cvode-adams at rtol 1e-14, other formulations) to more digits than the
// loosest one. Does not
// check timing values beyond their presence and order (min ≤ median ≤ max).
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <set>
#include <vector>
#include <string>

#include "formulations/formulation.hpp"

namespace {

class ShortSweep : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = std::filesystem::temp_directory_path() / ("kneedyn_sweep_" + std::to_string(::getpid()));
    std::filesystem::create_directories(dir_);
    const std::string cmd = std::string(KNEEDYN_WORK_PRECISION) +
                            " --short --include-broken --repetitions 2 --json " + (dir_ / "wp.json").string() +
                            " > " + (dir_ / "log.txt").string() + " 2>&1";
    exit_code_ = std::system(cmd.c_str());
    std::ifstream in(dir_ / "wp.json");
    if (in) in >> json_;
  }
  static void TearDownTestSuite() { std::filesystem::remove_all(dir_); }
  static std::filesystem::path dir_;
  static int exit_code_;
  static nlohmann::json json_;
};
std::filesystem::path ShortSweep::dir_;
int ShortSweep::exit_code_ = -1;
nlohmann::json ShortSweep::json_;

TEST_F(ShortSweep, WritesWellFormedJsonWithEveryField) {
  ASSERT_EQ(exit_code_, 0);
  ASSERT_TRUE(json_.contains("header"));
  for (const char* k : {"machine", "scene", "reference", "mode", "date", "repetitions"}) {
    EXPECT_TRUE(json_["header"].contains(k)) << k;
  }
  for (const char* k : {"uname", "nproc", "compiler", "build_type", "versions"}) {
    EXPECT_TRUE(json_["header"]["machine"].contains(k)) << k;
  }
  ASSERT_TRUE(json_["results"].is_array());
  ASSERT_GT(json_["results"].size(), 3u);
  for (const auto& r : json_["results"]) {
    for (const char* k : {"formulation", "integrator", "setting", "status", "reason", "metrics",
                          "cpu_time_s", "counters"}) {
      ASSERT_TRUE(r.contains(k)) << k << " in " << r.dump();
    }
    EXPECT_TRUE(r["status"] == "ok" || r["status"] == "failed") << r["status"];
    EXPECT_TRUE(r["setting"].contains("rtol") || r["setting"].contains("step")) << r["setting"];
    for (const char* k : {"scd", "mixed_error", "event_time_error_s", "event_angle_error_deg",
                          "max_position_residual_m", "max_velocity_residual_m_s"}) {
      EXPECT_TRUE(r["metrics"].contains(k)) << k;
    }
    for (const char* k : {"residual_evaluations", "jacobian_evaluations", "linear_solver_setups",
                          "nonlinear_iterations", "steps", "rejected_steps"}) {
      ASSERT_TRUE(r["counters"].contains(k)) << k;
      EXPECT_GE(r["counters"][k].get<long>(), 0);
    }
    const auto& t = r["cpu_time_s"];
    ASSERT_TRUE(t["median"].is_number()) << r.dump();
    EXPECT_LE(t["min"].get<double>(), t["median"].get<double>());
    EXPECT_LE(t["median"].get<double>(), t["max"].get<double>());
    if (r["status"] == "ok") {
      EXPECT_TRUE(r["metrics"]["scd"].is_number()) << r.dump();
      EXPECT_GT(r["counters"]["steps"].get<long>(), 0);
    } else {
      EXPECT_FALSE(r["reason"].get<std::string>().empty());
    }
  }
}

TEST_F(ShortSweep, CoversEveryRegisteredFormulation) {
  std::set<std::string> seen;
  for (const auto& r : json_["results"]) seen.insert(r["formulation"].get<std::string>());
  for (const kneedyn::FormulationInfo& info : kneedyn::RegisteredFormulations()) {
    if (info.needs_patella) continue;  // the sweep's scene has no patella
    EXPECT_TRUE(seen.count(info.name)) << info.name;
  }
}

TEST_F(ShortSweep, BrokenSettingIsAFailedResultWithItsReason) {
  int broken = 0;
  for (const auto& r : json_["results"]) {
    if (r["setting"].value("max_steps", 0) == 3) {
      ++broken;
      EXPECT_EQ(r["status"], "failed");
      EXPECT_NE(r["reason"].get<std::string>().find("t ="), std::string::npos) << r["reason"];
    }
  }
  EXPECT_EQ(broken, 1);
}

TEST_F(ShortSweep, DaeAccuracyGrowsAsTheToleranceTightens) {
  double loose = -1, tight = -1;
  for (const auto& r : json_["results"]) {
    if (r["formulation"] != "dae" || r["status"] != "ok" || r["setting"].contains("max_steps")) continue;
    const double rtol = r["setting"]["rtol"].get<double>();
    if (rtol > 5e-4) loose = r["metrics"]["scd"].get<double>();
    if (rtol < 5e-7) tight = r["metrics"]["scd"].get<double>();
  }
  ASSERT_GT(loose, 0.0);
  ASSERT_GT(tight, 0.0);
  EXPECT_GT(tight, loose + 2.0);  // 4 decades of rtol: at least 2 more digits
  EXPECT_GT(tight, 4.0);          // rtol 1e-7 against the mde reference (measured 4.99)
}

TEST_F(ShortSweep, CsvHasOneRowPerResult) {
  std::ifstream in(dir_ / "wp.csv");
  ASSERT_TRUE(in);
  std::string line;
  size_t lines = 0;
  std::getline(in, line);
  EXPECT_EQ(line.rfind("formulation,integrator,rtol,atol,step,status,scd", 0), 0u);
  while (std::getline(in, line)) ++lines;
  EXPECT_EQ(lines, json_["results"].size());
}

// The fairness manifest (context.components): every component compiled into the methods on
// the time axis, with its version, origin and flags; with the bundled SUNDIALS
// (cmake/sundials.cmake) SUNDIALS carries kneedyn's own optimization flags.
TEST_F(ShortSweep, FairnessManifestNamesEveryComponentAndSundialsIsBuiltLikeKneedyn) {
  ASSERT_EQ(exit_code_, 0);
  ASSERT_TRUE(json_["context"].contains("components"));
  std::map<std::string, nlohmann::json> by_name;
  for (const auto& c : json_["context"]["components"]) by_name[c.at("name").get<std::string>()] = c;
  for (const char* name : {"kneedyn", "SUNDIALS", "Eigen", "Ceres"}) {
    ASSERT_TRUE(by_name.count(name)) << name;
    for (const char* field : {"version", "origin", "compile_flags"}) {
      EXPECT_FALSE(by_name[name].at(field).get<std::string>().empty()) << name << "." << field;
    }
  }
  EXPECT_EQ(by_name["SUNDIALS"]["version"], "6.4.1");
#ifdef KNEEDYN_SUNDIALS_BUNDLED
  const std::string sundials_flags = by_name["SUNDIALS"]["compile_flags"].get<std::string>();
  const std::string kneedyn_flags = by_name["kneedyn"]["compile_flags"].get<std::string>();
  EXPECT_NE(sundials_flags.find("-O"), std::string::npos) << sundials_flags;
  EXPECT_NE(kneedyn_flags.find(sundials_flags), std::string::npos)
      << "SUNDIALS '" << sundials_flags << "' vs kneedyn '" << kneedyn_flags << "'";
  EXPECT_NE(by_name["SUNDIALS"]["origin"].get<std::string>().find("source package"), std::string::npos);
#endif
}

// The file is Google Benchmark's own JSON (what its tools/compare.py reads): a
// context, and in `benchmarks` one `iteration` entry per repetition of every setting plus
// the aggregates, with time units; names carry no sweep mode, min_time or repeat count
// (a short and a full run compare name by name). The mean aggregate equals the mean of
// the repetitions Google Benchmark itself wrote.
TEST_F(ShortSweep, IsGoogleBenchmarkJsonWithEveryRepetition) {
  ASSERT_EQ(exit_code_, 0);
  ASSERT_TRUE(json_.contains("context"));
  EXPECT_TRUE(json_["context"].contains("date"));
  EXPECT_TRUE(json_["context"].contains("num_cpus"));
  ASSERT_TRUE(json_["benchmarks"].is_array());
  std::map<std::string, std::vector<double>> cpu_by_name;
  std::map<std::string, double> mean_by_name;
  for (const auto& b : json_["benchmarks"]) {
    const std::string name = b.at("name").get<std::string>();
    for (const char* banned : {"short", "full", "min_time", "repeats"}) {
      EXPECT_EQ(name.find(banned), std::string::npos) << name;
    }
    EXPECT_EQ(b.at("time_unit"), "ms") << name;
    EXPECT_TRUE(b.at("real_time").is_number()) << name;
    const std::string run_name = b.at("run_name").get<std::string>();
    if (b.at("run_type") == "iteration") {
      EXPECT_EQ(b.at("repetitions").get<int>(), 2) << name;
      cpu_by_name[run_name].push_back(b.at("cpu_time").get<double>());
    } else if (b.at("aggregate_name") == "mean") {
      mean_by_name[run_name] = b.at("cpu_time").get<double>();
    }
  }
  EXPECT_EQ(cpu_by_name.size(), json_["results"].size());
  for (const auto& r : json_["results"]) {
    const std::string name = r.at("name").get<std::string>();
    ASSERT_EQ(cpu_by_name[name].size(), 2u) << name;
    ASSERT_TRUE(mean_by_name.count(name)) << name;
    const double mean = 0.5 * (cpu_by_name[name][0] + cpu_by_name[name][1]);
    EXPECT_NEAR(mean_by_name[name], mean, 1e-9 * mean + 1e-15) << name;
  }
}

}  // namespace
