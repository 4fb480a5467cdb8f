// Batch throughput (`kneedyn batch`'s API): N chapter-scene runs with different pulses in one
// process on one core through the batch API (ensembles/batch.hpp), at a setting whose
// accuracy is measured first (scd of the nominal scene against the stored reference,
// benchmarks/metrics.hpp; must be ≥ --min-scd, else exit 1 before timing).
//
//   batch_throughput [--runs 1000] [--formulation ede --integrator cvode-adams
//                    --rtol 1e-8 --atol 1e-10] [--min-scd 6] [--csv OUT.csv]
//   cmake --build build --target bench_batch
//
// Variants: pulse amplitude and duration on a deterministic 2-D grid-free sequence,
// A_i = 80 + 40 frac(i φ) N, t0_i = 0.08 + 0.04 frac(i φ²) s (φ golden ratio, i = 0…N−1).
// Target (benchmarks/README.md, "Performance targets: where they stand"): 1,000 runs at scd ≥ 6 in ≤
// 1 s on one core. Printed: runs/s of wall and of process CPU time, failed runs, accepted
// steps, the time to format the results table (std::to_chars), and the scd measured.
#include <CLI/CLI.hpp>

#include <chrono>
#include <cmath>
#include <cstdio>

#include <sys/resource.h>

#include "benchmarks/bench_run.hpp"
#include "ensembles/batch.hpp"
#include "formulations/formulation.hpp"
#include "formulations/output_file.hpp"
#include "solver/internal/command_line.hpp"
#include "solver/error.hpp"

using namespace kneedyn;
using namespace kneedyn::ensembles;

namespace {

double CpuSeconds() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return u.ru_utime.tv_sec + 1e-6 * u.ru_utime.tv_usec + u.ru_stime.tv_sec + 1e-6 * u.ru_stime.tv_usec;
}

double Frac(double x) { return x - std::floor(x); }

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"batch throughput: many chapter-scene runs with different pulses in one process"};
  long runs = 1000;
  bench::BenchConfig c;
  c.formulation = "ede";
  c.integrator = "cvode-adams";
  c.rtol = 1e-8;
  c.atol = 1e-10;
  double min_scd = 6.0;
  std::string csv;
  app.add_option("--runs", runs, "number of variants")->capture_default_str();
  app.add_option("--formulation", c.formulation)->capture_default_str();
  app.add_option("--integrator", c.integrator)->capture_default_str();
  app.add_option("--rtol", c.rtol)->capture_default_str();
  app.add_option("--atol", c.atol)->capture_default_str();
  app.add_option("--min-scd", min_scd, "accuracy the setting must reach on the nominal scene")->capture_default_str();
  app.add_option("--csv", csv, "write the results table here");
  if (const int code = ParseCommandLine(app, argc, argv, "batch_throughput"); code >= 0) return code;
  try {
    // The variants and the results table are held whole: 1e11 runs ended in the OOM killer.
    constexpr long kMaxRuns = 1000000;
    if (runs < 1 || runs > kMaxRuns) {
      Throw<InputError>("batch_throughput", "--runs = ", runs, ": must be in [1, ", kMaxRuns, "]");
    }
    if (!std::isfinite(min_scd)) Throw<InputError>("batch_throughput", "--min-scd = ", min_scd, ": must be finite");
    if (!csv.empty()) CheckOutputFile("batch_throughput", "--csv", csv);
    const std::string dir = ReferenceDataDir();
    const Scene scene = LoadScene(dir + "/scenes/chapter_impact.yaml");
    // A setting no run can have is refused (exit 2), not measured as scd nan (exit 1).
    (void)CreateFormulation(c.formulation, scene, c.Options());
    const bench::Reference ref = bench::LoadReference(dir + "/references/chapter_impact.json");
    const bench::Outcome nominal = bench::RunConfig(scene, c, ref.comparison_interval);
    const double scd = bench::Evaluate(scene, nominal, ref).scd;
    std::printf("setting %s: scd %.2f on the nominal scene (required >= %.1f)\n", c.Name().c_str(), scd, min_scd);
    if (!(scd >= min_scd)) {
      std::printf("FAILED: the setting does not reach the required accuracy; not timed\n");
      return 1;
    }

    BatchVariants variants;
    variants.path = "batch_throughput";
    variants.parameters = {ResolveParameterName(scene.model, "pulse.amplitude", "batch_throughput"),
                           ResolveParameterName(scene.model, "pulse.duration", "batch_throughput")};
    const double phi = (1.0 + std::sqrt(5.0)) / 2.0;
    for (long i = 0; i < runs; ++i) {
      variants.rows.push_back({80.0 + 40.0 * Frac(i * phi), 0.08 + 0.04 * Frac(i * phi * phi)});
    }
    RunSettings settings;
    settings.formulation = c.formulation;
    settings.options = c.Options();
    Batch batch(scene, settings, {"liftoff_time", "liftoff_flexion", "time_at_90"});

    const double cpu0 = CpuSeconds();
    const auto t0 = std::chrono::steady_clock::now();
    const SweepTable table = batch.RunAll(variants, 1);
    const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    const double cpu = CpuSeconds() - cpu0;
    long failed = 0, steps = 0;
    for (const RunRow& r : table.rows) failed += !r.completed, steps += r.steps;

    const auto f0 = std::chrono::steady_clock::now();
    const std::string text = FormatBatchCsv(table);
    const double format_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - f0).count();
    std::printf("%ld runs on 1 thread: %.3f s wall, %.3f s CPU -> %.1f runs/s (wall), %.1f runs/s (CPU); "
                "%ld failed, %ld accepted steps (%.0f per run)\n",
                runs, wall, cpu, runs / wall, runs / cpu, failed, steps, static_cast<double>(steps) / runs);
    std::printf("results table: %zu bytes formatted in %.2f ms (std::to_chars)\n", text.size(), 1e3 * format_s);
    std::printf("target: %ld runs at scd >= 6 in <= %.2f s on one core: %s (CPU time)\n", runs,
                runs / 1000.0, cpu <= runs / 1000.0 ? "met" : "not met");
    if (!csv.empty()) WriteOutputFile("batch_throughput", "--csv", csv, text);
    return failed == 0 ? 0 : 1;
  } catch (const InputError& e) {
    std::fprintf(stderr, "batch_throughput: error: %s\n", e.what());
    return 2;
  } catch (const std::exception& e) {  // any other failure: a message and exit 1, no abort
    std::fprintf(stderr, "batch_throughput: error: %s\n", e.what());
    return 1;
  }
}
