// kneedyn_simbody — the chapter knee in Simbody (crosscheck/simbody/README.md), from a
// scene, in one command:
//
//   kneedyn_simbody run SCENE [--integrator rkm] [--accuracy 1e-6] [--constraint-tolerance 0]
//                   [--step 0] [--output-interval 0] [--max-steps N] [--out DIR] [--quiet]
//
// Writes DIR/{trajectory.csv, trajectory.sto, summary.json} in the layout of `kneedyn run`
// (formulations/run_output.hpp). Exit codes: 0 success, 1 solver failure (results up to
// the failure written, marked partial), 2 bad input (nothing written).
#include <CLI/CLI.hpp>
#include <cstdio>

#include "solver/internal/command_line.hpp"
#include "crosscheck/simbody/simbody_knee.hpp"
#include "formulations/output_file.hpp"
#include "solver/error.hpp"
#include "solver/units.hpp"

using namespace kneedyn;

int main(int argc, char** argv) {
  CLI::App app{"kneedyn_simbody: the chapter knee rebuilt in Simbody (independent cross-check)"};
  app.require_subcommand(1);
  std::string scene_path, out_dir = "out/simbody";
  simbody::Options options;
  bool quiet = false;
  std::string integrators;
  for (const std::string& n : simbody::IntegratorNames()) integrators += (integrators.empty() ? "" : "|") + n;
  CLI::App* run = app.add_subcommand("run", "integrate a scene with a Simbody integrator");
  run->add_option("scene", scene_path, "scene file (YAML)")->required();
  run->add_option("--integrator", options.integrator, integrators)->capture_default_str();
  run->add_option("--accuracy", options.accuracy, "Simbody's relative accuracy")->capture_default_str();
  run->add_option("--constraint-tolerance", options.constraint_tolerance,
                  "constraint projection tolerance (0: = accuracy)")->capture_default_str();
  run->add_option("--step", options.fixed_step, "fixed step in s (see; optional for the others)");
  run->add_option("--output-interval", options.output_interval, "s between output rows (0: scene's)");
  run->add_option("--max-steps", options.max_steps, "step budget")->capture_default_str();
  run->add_option("--out", out_dir, "output directory")->capture_default_str();
  run->add_flag("--quiet", quiet, "print nothing on success");
  if (const int code = ParseCommandLine(app, argc, argv, "kneedyn_simbody"); code >= 0) return code;
  try {
    std::string why;
    if (!options.IsValid(&why)) Throw<InputError>("kneedyn_simbody run", why);
    CheckOutputDirectoryWritable("kneedyn_simbody run", "--out", out_dir);  // before the run
    const Scene scene = LoadScene(scene_path);
    const simbody::Result result = simbody::Run(scene, options);
    simbody::WriteOutputs(out_dir, scene, options, result);
    const RunResult& r = result.run;
    if (!quiet) {
      std::printf("%s: %s with Simbody %s (accuracy %g) in %.3f s wall\n", scene.name.c_str(),
                  r.completed ? ("completed (" + r.end_reason + ")").c_str() : "FAILED",
                  options.integrator.c_str(), options.accuracy, r.wall_time_s);
      std::printf("  init (Assembler): gap %.3e -> %.3e m; N =", r.init.position.residual_before,
                  r.init.position.residual_after);
      for (double n : r.init.normal_force) std::printf(" %.6f", n);
      std::printf(" N\n");
      for (const EventRecord& e : r.events) {
        std::printf("  event %-18s t = %.10f s  flexion = %.6f deg\n", e.name.c_str(), e.time, RadToDeg(e.flexion));
      }
      std::printf("  steps %ld, realizations %ld, projections %ld, error-test fails %ld, "
                  "convergence fails %ld, iterations %ld, restarts %ld (kink crossings %ld)\n",
                  r.stats.steps, r.stats.residual_evaluations, r.stats.projections, r.stats.error_test_failures,
                  r.stats.convergence_failures, r.stats.nonlinear_iterations, r.stats.restarts,
                  r.ligament_kink_crossings);
      std::printf("  max constraint residual: gap %.3e mm, gap rate %.3e mm/s; energy drift %.3e\n",
                  MToMm(r.max_position_residual), MToMm(r.max_velocity_residual), simbody::EnergyDrift(result));
      std::printf("  wrote %s/{trajectory.csv, trajectory.sto, summary.json}\n", out_dir.c_str());
    }
    if (!r.completed) {
      std::fprintf(stderr, "kneedyn_simbody run: solver failed: %s\n  (results up to there written, marked partial)\n",
                   r.failure.c_str());
      return 1;
    }
    return 0;
  } catch (const InputError& e) {
    std::fprintf(stderr, "kneedyn_simbody: error: %s\n", e.what());
    return 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "kneedyn_simbody: error: %s\n", e.what());
    return 1;
  }
}
