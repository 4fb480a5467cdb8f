// Sweep throughput (ensembles/README.md): runs per second per core of `kneedyn sweep` on the
// chapter scene at a setting whose accuracy is measured first (scd against the stored
// reference, benchmarks/metrics.hpp; must be ≥ --min-scd), single thread vs all threads
// (in process, ensembles/sweep.hpp) vs 2 MPI ranks (`mpirun -n 2 kneedyn sweep`, wall time
// of the whole command including MPI start-up).
//
//   sweep_throughput --spec reference-data/specs/throughput.yaml --kneedyn build/formulations/kneedyn
//                    [--mpiexec mpirun] [--json OUT.json]
//
// The fixture owns its inputs, so that a figure can be reproduced: the spec fixes design,
// seed and solver; the work behind each figure (runs, failed runs, accepted steps) is printed
// beside it.
#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <thread>

#include <sys/resource.h>

#include "solver/internal/command_line.hpp"
#include "benchmarks/bench_run.hpp"
#include "ensembles/sweep.hpp"
#include "ensembles/sweep_output.hpp"
#include "formulations/output_file.hpp"
#include "solver/error.hpp"

using namespace kneedyn;
using namespace kneedyn::ensembles;

namespace {

double CpuSeconds(int who) {
  rusage u{};
  getrusage(who, &u);
  return u.ru_utime.tv_sec + 1e-6 * u.ru_utime.tv_usec + u.ru_stime.tv_sec + 1e-6 * u.ru_stime.tv_usec;
}

struct Timing {
  std::string label;
  int workers = 1;   // threads or ranks
  long runs = 0, failed = 0, steps = 0;
  double wall_s = 0.0;
  double cpu_s = 0.0;  // user + system CPU time of the workers (getrusage)
  double RunsPerSecond() const { return runs / wall_s; }
  double RunsPerSecondPerCore() const { return RunsPerSecond() / workers; }
  // On a shared machine wall time includes waiting for a core; runs per CPU second does not.
  double RunsPerCpuSecond() const { return runs / cpu_s; }
};

Timing InProcess(const SweepSpec& spec, int threads) {
  Timing t;
  t.label = std::to_string(threads) + (threads == 1 ? " thread" : " threads");
  t.workers = threads;
  const double cpu0 = CpuSeconds(RUSAGE_SELF);
  const auto start = std::chrono::steady_clock::now();
  const SweepTable table = RunSweep(spec, ShardIndices(spec, 0, 1), threads);
  t.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  t.cpu_s = CpuSeconds(RUSAGE_SELF) - cpu0;
  t.runs = static_cast<long>(table.rows.size());
  for (const RunRow& r : table.rows) {
    t.failed += !r.completed;
    t.steps += r.steps;
  }
  return t;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"kneedyn sweep throughput on the chapter scene"};
  std::string spec_path = "reference-data/specs/throughput.yaml", kneedyn_exe, mpiexec = "mpirun", json_path;
  double min_scd = 6.0;
  app.add_option("--spec", spec_path, "sweep spec (its base scene, solver settings and design)")->capture_default_str();
  app.add_option("--kneedyn", kneedyn_exe, "kneedyn executable for the MPI figure (empty: skip)");
  app.add_option("--mpiexec", mpiexec, "MPI launcher")->capture_default_str();
  app.add_option("--min-scd", min_scd, "required accuracy of the setting")->capture_default_str();
  app.add_option("--json", json_path, "write the figures as JSON");
  if (const int code = ParseCommandLine(app, argc, argv, "sweep_throughput"); code >= 0) return code;
  try {
    if (!std::isfinite(min_scd)) Throw<InputError>("sweep_throughput", "--min-scd = ", min_scd, ": must be finite");
    if (!json_path.empty()) CheckOutputFile("sweep_throughput", "--json", json_path);
    const SweepSpec spec = LoadSweepSpec(spec_path);
    // 1. Accuracy of the spec's solver setting on the base scene (nominal parameters).
    const std::string reference_path =
        ReferenceDataDir() + "/references/" + spec.base.name + ".json";
    const bench::Reference reference = bench::LoadReference(reference_path);
    bench::BenchConfig config;
    config.formulation = spec.run.formulation;
    config.integrator = IntegratorOptionName(spec.run.options.integrator);
    config.rtol = spec.run.options.rtol;
    config.atol = spec.run.options.atol;
    config.max_steps = spec.run.options.max_steps;
    const bench::Outcome outcome = bench::RunConfig(spec.base, config, reference.comparison_interval);
    const bench::Metrics metrics = bench::Evaluate(spec.base, outcome, reference);
    std::printf("setting %s on %s: scd %.2f against %s (required >= %.1f)\n", config.Name().c_str(),
                spec.base.name.c_str(), metrics.scd, reference_path.c_str(), min_scd);
    if (!(metrics.scd >= min_scd)) {
      std::fprintf(stderr, "sweep_throughput: scd %.2f < %.1f: tighten the spec's tolerances\n", metrics.scd, min_scd);
      return 1;
    }
    // 2. Timings. The load average says how shared the machine was.
    double load[1] = {-1.0};
    getloadavg(load, 1);
    std::printf("load average (1 min) before timing: %.2f on %u cores\n", load[0], std::thread::hardware_concurrency());
    std::vector<Timing> timings;
    timings.push_back(InProcess(spec, 1));
    const int cores = std::max(1u, std::thread::hardware_concurrency());
    if (cores > 1) timings.push_back(InProcess(spec, cores));
    if (!kneedyn_exe.empty()) {
      namespace fs = std::filesystem;
      const fs::path out = fs::temp_directory_path() / "kneedyn_sweep_throughput_mpi";
      const std::string command = "OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 " + mpiexec +
                                  " -n 2 --oversubscribe " + kneedyn_exe + " sweep " + spec_path +
                                  " --threads 1 --quiet --out " + out.string() + " > /dev/null";
      const double cpu0 = CpuSeconds(RUSAGE_CHILDREN);
      const auto start = std::chrono::steady_clock::now();
      const int rc = std::system(command.c_str());
      Timing t;
      t.label = "2 MPI ranks x 1 thread";
      t.workers = 2;
      t.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      t.cpu_s = CpuSeconds(RUSAGE_CHILDREN) - cpu0;  // mpirun + both ranks
      t.runs = timings[0].runs;
      t.failed = timings[0].failed;
      t.steps = timings[0].steps;
      if (rc != 0) std::fprintf(stderr, "sweep_throughput: '%s' failed (%d); no MPI figure\n", command.c_str(), rc);
      else timings.push_back(t);
      fs::remove_all(out);
    }
    nlohmann::json j;
    j["spec"] = spec_path;
    j["setting"] = config.Name();
    j["scd"] = metrics.scd;
    j["machine"] = bench::MachineJson();
    j["load_average_1min_before"] = load[0];
    for (const Timing& t : timings) {
      std::printf("%-24s %6ld runs (%ld failed, %ld steps) in %8.3f s wall, %8.3f s CPU: %8.2f runs/s, "
                  "%8.2f runs/s per core (wall), %8.2f runs per CPU second\n",
                  t.label.c_str(), t.runs, t.failed, t.steps, t.wall_s, t.cpu_s, t.RunsPerSecond(),
                  t.RunsPerSecondPerCore(), t.RunsPerCpuSecond());
      j["results"].push_back({{"configuration", t.label}, {"workers", t.workers}, {"runs", t.runs},
                              {"failed", t.failed}, {"steps", t.steps}, {"wall_s", t.wall_s}, {"cpu_s", t.cpu_s}, {"runs_per_cpu_s", t.RunsPerCpuSecond()},
                              {"runs_per_s", t.RunsPerSecond()}, {"runs_per_s_per_core", t.RunsPerSecondPerCore()}});
    }
    // Before, an unwritable --json was dropped silently (exit 0).
    if (!json_path.empty()) WriteOutputFile("sweep_throughput", "--json", json_path, j.dump(2) + "\n");
    return 0;
  } catch (const InputError& e) {
    std::fprintf(stderr, "sweep_throughput: error: %s\n", e.what());
    return 2;
  } catch (const std::exception& e) {  // a run's failure, a file system error: no abort
    std::fprintf(stderr, "sweep_throughput: error: %s\n", e.what());
    return 1;
  }
}
