// kneedyn — command line.
//   kneedyn run SCENE --formulation NAME [--rtol R] [--atol A] [--out DIR] ...
//   kneedyn info SCENE          reference pose, contact points, slack lengths and forces
//   kneedyn formulations        the registered formulations and their integrators
//   kneedyn sweep SPEC          an ensemble of runs (ensembles/sweep_cli.hpp)
//   kneedyn batch SCENE --variants FILE.csv   many variants in one process (ensembles/batch_cli.hpp)
//   kneedyn sensitivity SCENE   forward sensitivities (sensitivity/sensitivity_cli.hpp)
//   kneedyn score RESULT --scene S   score a trajectory CSV (benchmarks/score_cli.hpp)
// Exit codes: 0 success; 1 solver failure (partial results written, marked partial);
// 2 bad input (nothing written).
#include <CLI/CLI.hpp>

#include <cmath>
#include <cstdio>
#include <iostream>
#include <map>

#include "ensembles/batch_cli.hpp"
#include "ensembles/sweep_cli.hpp"
#include "benchmarks/score_cli.hpp"
#include "sensitivity/sensitivity_cli.hpp"
#include "formulations/cli.hpp"
#include "formulations/progress.hpp"
#include "formulations/run.hpp"
#include "formulations/run_output.hpp"
#include "formulations/version.hpp"
#include "solver/constrained_dynamics.hpp"
#include "solver/error.hpp"
#include "solver/units.hpp"

using namespace kneedyn;

namespace {

int Info(const std::string& path) {
  const Scene scene = LoadScene(path);
  const Model& model = scene.model;
  const Vector6d& q = scene.reference_q;
  std::printf("scene %s (parameter set %s)\n", scene.name.c_str(), scene.parameter_set.c_str());
  std::printf("reference pose (full extension): R0 = (%.9f, %.9f, %.6f) mm, alpha = %g deg, "
              "beta = %g deg, gamma = %g deg\n",
              MToMm(q(0)), MToMm(q(1)), MToMm(q(2)), RadToDeg(q(3)), RadToDeg(q(4)), RadToDeg(q(5)));
  const Pose pose = PoseFromCoordinates(q);
  for (const ContactPair& pair : model.contacts) {
    ContactGeometry g;
    if (!ContactKinematics(pair, pose, &g)) continue;
    std::printf("%-8s contact: femoral (%.6f, %.6f, %.6f) mm, tibial (%.6f, %.6f, %.6f) mm\n",
                CompartmentName(pair.compartment), MToMm(g.point_F.x()), MToMm(g.point_F.y()),
                MToMm(g.point_F.z()), MToMm(g.point_T.x()), MToMm(g.point_T.y()), MToMm(g.point_T.z()));
  }
  Data data(model);
  ComputeAppliedWrench(model, 0.0, pose, &data);
  std::printf("%-20s %12s %12s %12s\n", "element", "L_ref (mm)", "L0 (mm)", "F_ref (N)");
  for (size_t j = 0; j < model.ligaments.size(); ++j) {
    const Ligament& l = model.ligaments[j];
    std::printf("%-20s %12.6f %12.6f %12.4f\n", l.name.c_str(), MToMm(l.reference_length),
                MToMm(l.slack_length), data.ligament_tension[j]);
  }
  std::vector<int> all;
  for (int i = 0; i < static_cast<int>(model.contacts.size()); ++i) all.push_back(i);
  if (!all.empty()) {
    const ConstrainedAcceleration ca = SolveConstrainedAcceleration(model, 0.0, q, Vector6d::Zero(), all);
    for (size_t i = 0; i < all.size(); ++i) {
      std::printf("consistent normal force at rest, %s: %.4f N\n",
                  CompartmentName(model.contacts[all[i]].compartment), ca.normal_force[i]);
    }
  }
  return 0;
}

// A message as printed: values in it are already cut (Echo); this only bounds the whole.
std::string Clip(const std::string& m) { return m.size() > 4000 ? m.substr(0, 4000) + "..." : m; }

// Exit codes (README "Exit codes"): 0 completed; 1 solver failure while integrating, with
// the results up to there written and marked partial; 2 bad input or arguments, including
// what the input makes impossible before integration starts (a singular or inconsistent
// initial pose), and an unusable --out; nothing is written then. No other code.
int Main(int argc, char** argv) {
  CLI::App app{"kneedyn: 3D dynamic knee model (Hefzy & Abdel-Rahman) — verification and benchmark suite"};
  app.require_subcommand(1);
  app.set_version_flag("--version", VersionReport("kneedyn"), "print the version, git commit and library versions");

  std::string scene_path, out_dir = "out/run";
  RunSettings settings;
  bool quiet = false;
  CLI::App* run = app.add_subcommand("run", "integrate a scene with one formulation");
  run->add_option("scene", scene_path, "scene file (YAML)")->required();
  run->add_option("--formulation", settings.formulation, "formulation name (see `kneedyn formulations`)")
      ->capture_default_str();
  run->add_option("--rtol", settings.options.rtol, "relative tolerance")->capture_default_str();
  run->add_option("--atol", settings.options.atol, "absolute tolerance (SI)")->capture_default_str();
  run->add_option("--integrator", settings.options.integrator, "integrator (mde, ede)");
  run->add_option("--step", settings.options.step, "fixed step in s (euler, rk4, newmark)");
  run->add_option("--max-step", settings.options.max_step, "largest adaptive step in s (0: none)");
  run->add_option("--max-steps", settings.options.max_steps, "step budget per phase")->capture_default_str();
  run->add_option("--stabilization", settings.options.stabilization, "ede: none|baumgarte|projection|cvode-projection")
      ->capture_default_str();
  run->add_option("--constraint-level", settings.options.constraint_level,
                  "dae: velocity (index 2) | position (index-3 variant)")->capture_default_str();
  run->add_option("--rho-inf", settings.options.rho_inf, "generalized-alpha: spectral radius at infinity in [0, 1]")
      ->capture_default_str();
  run->add_option("--alpha-m", settings.options.alpha_m, "generalized-alpha: alpha_m (with --alpha-f, --beta, --gamma)");
  run->add_option("--alpha-f", settings.options.alpha_f, "generalized-alpha: alpha_f");
  run->add_option("--beta", settings.options.newmark_beta, "generalized-alpha: beta");
  run->add_option("--gamma", settings.options.newmark_gamma, "generalized-alpha: gamma");
  run->add_option("--jacobian", settings.options.jacobian,
                  "dae*, newmark*, generalized-alpha*: Newton matrix exact (default) | jet (the Jet<24> "
                  "reference) | difference-quotient (IDA's own)");
  run->add_option("--contact-chart", settings.options.contact_chart,
                  "dae, newmark: chart of the contact coordinates: regular | height-field "
                  "(the chapter's, singular at the condyle rim)")
      ->transform(CLI::CheckedTransformer(std::map<std::string, ContactChart>{
          {"regular", ContactChart::kRegular}, {"height-field", ContactChart::kHeightField}}));
  run->add_option("--output-interval", settings.output_interval, "s between output rows (0: scene's)");
  run->add_option("--out", out_dir, "output directory")->capture_default_str();
  run->add_flag("--quiet", quiet, "no progress on stderr");

  std::string info_scene;
  CLI::App* info = app.add_subcommand("info", "print the scene's reference pose, slack lengths and forces");
  info->add_option("scene", info_scene, "scene file (YAML)")->required();

  CLI::App* list = app.add_subcommand("formulations", "list the registered formulations");

  ensembles::SweepCommand sweep(app);  // kneedyn sweep (ensembles/sweep_cli.hpp)
  ensembles::BatchCommand batch(app);  // kneedyn batch (ensembles/batch_cli.hpp)
  sensitivity::SensitivityCommand sensitivity(app);  // kneedyn sensitivity (sensitivity/sensitivity_cli.hpp)
  bench::ScoreCommand score(app);  // kneedyn score (benchmarks/score_cli.hpp)

  if (const int code = ParseCommandLine(app, argc, argv, "kneedyn"); code >= 0) return code;
  if (sweep.parsed()) return sweep.Run();
  if (batch.parsed()) return batch.Run();
  if (sensitivity.parsed()) return sensitivity.Run(argc, argv);
  if (score.parsed()) return score.Run(argc, argv);
  for (const std::string* s : {&scene_path, &info_scene, &out_dir, &settings.formulation,
                               &settings.options.integrator, &settings.options.stabilization,
                               &settings.options.constraint_level, &settings.options.jacobian}) {
    if (s->size() > 1024) {
      std::fprintf(stderr, "kneedyn: error: argument '%s' is longer than 1024 characters\n", Echo(*s).c_str());
      return 2;
    }
  }
  if (run->count("--output-interval") && settings.output_interval == 0.0) {
    std::fprintf(stderr, "kneedyn: error: --output-interval = 0; must be > 0 (omit it for the scene's)\n");
    return 2;
  }
  try {
    if (*info) return Info(info_scene);
    if (*list) {
      for (const FormulationInfo& f : RegisteredFormulations()) {
        std::printf("%-16s %s", f.name.c_str(), f.summary.c_str());
        if (!f.integrators.empty()) {
          std::printf(" [--integrator");
          for (const std::string& i : f.integrators) std::printf(" %s", i.c_str());
          std::printf("]");
        }
        std::printf("\n");
      }
      return 0;
    }
    const Scene scene = LoadScene(scene_path);
    settings.command_line.assign(argv, argv + argc);
    CheckOutputDirectory(out_dir);  // refuse an unusable --out before running
    // `\r` progress only on a terminal (logs and pipes get the summary lines alone).
    const bool show_progress = !quiet && StderrIsTerminal();
    if (show_progress) {
      double last = -1.0;
      settings.progress = [&](double t, double alpha) {
        if (t - last < 0.05 && last >= 0.0) return;
        last = t;
        std::fprintf(stderr, "\r[kneedyn] t = %.3f s  flexion = %6.2f deg", t, RadToDeg(alpha));
      };
    }
    const RunResult result = RunScene(scene, settings);
    if (show_progress) std::fprintf(stderr, "\n");
    try {
      WriteRunOutputs(out_dir, scene, settings, result);
    } catch (const std::exception& e) {
      std::fprintf(stderr, "kneedyn: error: --out = '%s': %s\n", Echo(out_dir).c_str(), Clip(e.what()).c_str());
      return 2;
    }
    const SolverStats& s = result.stats;
    std::printf("%s: %s with %s in %.3f s wall\n", scene.name.c_str(),
                result.completed ? ("completed (" + result.end_reason + ")").c_str() : "FAILED",
                settings.formulation.c_str(), result.wall_time_s);
    std::printf("  init: position residual %.3e -> %.3e, hidden %.3e -> %.3e\n",
                result.init.position.residual_before, result.init.position.residual_after,
                result.init.hidden.residual_before, result.init.hidden.residual_after);
    for (const EventRecord& e : result.events) {
      std::printf("  event %-18s t = %.6f s  flexion = %.4f deg\n", e.name.c_str(), e.time, RadToDeg(e.flexion));
    }
    std::printf("  steps %ld, residual evals %ld, Jacobian evals %ld, LU %ld, Newton iters %ld, "
                "error-test fails %ld, convergence fails %ld, restarts %ld\n",
                s.steps, s.residual_evaluations, s.jacobian_evaluations, s.linear_solver_setups,
                s.nonlinear_iterations, s.error_test_failures, s.convergence_failures, s.restarts);
    std::printf("  max constraint residual: gap %.3e mm, gap rate %.3e mm/s\n",
                MToMm(result.max_position_residual), MToMm(result.max_velocity_residual));
    std::printf("  wrote %s/{trajectory.csv, trajectory.sto, summary.json}\n", out_dir.c_str());
    if (!result.completed) {
      std::fprintf(stderr, "kneedyn run: solver failed: %s\n  (results up to there written, marked partial)\n",
                   result.failure.c_str());
      return 1;
    }
    return 0;
  } catch (const std::exception& e) {
    // Before integration: the scene, the options or the initial state refused (exit 2).
    std::fprintf(stderr, "kneedyn: error: %s\n", Clip(e.what()).c_str());
    return 2;
  }
}

}  // namespace

int main(int argc, char** argv) {
  try {
    return Main(argc, argv);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "kneedyn: error: %s\n", Clip(e.what()).c_str());
  } catch (...) {
    std::fprintf(stderr, "kneedyn: error: unknown exception\n");
  }
  return 2;
}
