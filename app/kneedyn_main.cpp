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
#include <filesystem>
#include <functional>
#include <iostream>
#include <iterator>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "ensembles/batch_cli.hpp"
#include "ensembles/sweep_cli.hpp"
#include "benchmarks/score_cli.hpp"
#include "sensitivity/sensitivity_cli.hpp"
#include "solver/internal/command_line.hpp"
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

// "name (a, b), name (c)": the formulations whose registry line accepts more than the
// default for `field`, each with the values it accepts (for --help).
template <typename Enum>
std::string AcceptedBy(std::vector<Enum> FormulationInfo::*field) {
  std::string out;
  for (const FormulationInfo& f : RegisteredFormulations()) {
    const std::vector<Enum>& values = f.*field;
    if (values.empty() || (values.size() == 1 && values[0] == Enum{})) continue;
    std::string list;
    for (Enum v : values) list += (list.empty() ? "" : "|") + std::string(OptionName(v));
    out += (out.empty() ? "" : ", ") + f.name + ": " + list;
  }
  return out;
}

// The methods that take --step: fixed-step formulations and fixed-step integrators.
std::string FixedStepMethods() {
  std::string out;
  for (const FormulationInfo& f : RegisteredFormulations()) {
    if (f.fixed_step) out += (out.empty() ? "" : ", ") + f.name;
    for (IntegratorKind i : f.integrators) {
      if (!f.fixed_step && IsFixedStep(f, i)) out += StrCat(", ", f.name, " --integrator ", OptionName(i));
    }
  }
  return out;
}

// Whether CLI11 may print help for this command line (-h or --help, also inside a cluster
// of short flags such as -qh): the help texts that list the registry's accepted values are
// built only then (~0.07 M instructions of a default run otherwise; callgrind).
bool AsksForHelp(int argc, char** argv) {
  for (int i = 1; i < argc; ++i) {
    const std::string_view a = argv[i];
    if (a == "--") break;  // positionals after it
    if (a.rfind("--help", 0) == 0) return true;
    if (a.size() > 1 && a[0] == '-' && a[1] != '-' && a.find('h') != std::string_view::npos) return true;
  }
  return false;
}

// The options of `kneedyn run` as typed (flag -> text) into `settings` (ReadOptionText, and
// --output-interval). Returns the first refusal, naming the flag and the text, or "".
std::string ReadRunOptions(const OptionText& typed, RunSettings* settings) {
  if (std::string why = ReadOptionText(typed, &settings->options); !why.empty()) return why;
  const auto it = typed.find("--output-interval");
  if (it == typed.end()) return "";
  if (!ParseReal(it->second, &settings->output_interval)) {
    return StrCat("--output-interval = '", Echo(it->second), "': ", kRealRule);
  }
  if (!(settings->output_interval > 0.0)) {
    return StrCat("--output-interval = '", Echo(it->second), "'; must be > 0 (omit it for the scene's)");
  }
  return "";
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
  // Formed only when asked for: the data directory is searched for on disk.
  app.set_version_flag(
      "--version", std::function<std::string()>([] {
        // Named as found; when it has no scenes/ the programs cannot run a shipped scene.
        std::error_code ec;
        const std::string dir = ReferenceDataDir();
        const bool usable = std::filesystem::is_directory(std::filesystem::path(dir) / "scenes", ec);
        return VersionReport("kneedyn") + "\ndata directory: " + dir +
               (usable ? "" : " (not found: no scenes/ there; set KNEEDYN_DATA_DIR)");
      }),
      "print the version, git commit, library versions and the data directory (scenes, references)");

  std::string scene_path, out_dir = "out/run";
  RunSettings settings;
  FormulationOptions& options = settings.options;
  bool quiet = false;
  CLI::App* run = app.add_subcommand("run", "integrate a scene with one formulation");
  run->add_option("scene", scene_path, "scene file (YAML)")->required();
  run->add_option("--formulation", settings.formulation, "formulation name (see `kneedyn formulations`)")
      ->capture_default_str();
  // Numbers and names are kept as typed and converted once, after parsing (ReadRunOptions),
  // so that every message echoes the text given.
  OptionText typed;
  const bool describe = AsksForHelp(argc, argv);  // else the help texts below stay empty
  std::vector<std::pair<const char*, const CLI::Option*>> text_options;  // each flag of `typed`, its option
  // A flag is registered only when help may be printed or the command line holds it ("--flag"
  // or "--flag=..."): registering one costs ~12 k instructions (CLI11 parses its names and
  // compares them with every other option's), 0.2 M of a default run with none given
  // (callgrind), and a flag the command line does not hold can match nothing.
  const auto given = [argc, argv](std::string_view flag) {
    for (int i = 1; i < argc; ++i) {
      const std::string_view a = argv[i];
      if (a.compare(0, flag.size(), flag) == 0 && (a.size() == flag.size() || a[flag.size()] == '=')) return true;
    }
    return false;
  };
  auto text_option = [&](const char* flag, const std::string& help, const std::string& default_text = "") {
    if (!describe && !given(flag)) return;
    CLI::Option* o = run->add_option(flag, typed[flag], help);
    if (!default_text.empty()) o->default_str(default_text);
    text_options.emplace_back(flag, o);
  };
  const auto accepted = [describe](auto field) { return describe ? AcceptedBy(field) : std::string(); };
  const auto shown = [describe](auto value) { return describe ? StrCat(value) : std::string(); };
  const FormulationOptions defaults;
  text_option("--rtol", "relative tolerance (fixed-step methods: their Newton test, if any, and the re-contact threshold)",
              shown(defaults.rtol));
  text_option("--atol", "absolute tolerance (SI)", shown(defaults.atol));
  text_option("--integrator", "integrator (" + accepted(&FormulationInfo::integrators) + ")");
  text_option("--step", "fixed step in s (" + (describe ? FixedStepMethods() : std::string()) + ")");
  text_option("--max-step", "largest adaptive step in s (0: none)");
  text_option("--max-steps", "step budget per phase, over all its output intervals",
              shown(defaults.max_steps));
  text_option("--stabilization", "stabilization (" + accepted(&FormulationInfo::stabilizations) + ")",
              shown(OptionName(defaults.stabilization)));
  text_option("--constraint-level", "constraint level: velocity (index 2) | position (index-3 variant) (" +
                                        accepted(&FormulationInfo::constraint_levels) + ")",
              shown(OptionName(defaults.constraint_level)));
  const std::string scheme = describe ? FormulationsWith(&FormulationInfo::scheme_parameters) : std::string();
  text_option("--rho-inf", scheme + ": spectral radius at infinity in [0, 1]", shown(defaults.rho_inf));
  text_option("--alpha-m", scheme + ": alpha_m (with --alpha-f, --beta, --gamma)");
  text_option("--alpha-f", scheme + ": alpha_f");
  text_option("--beta", scheme + ": beta");
  text_option("--gamma", scheme + ": gamma");
  text_option("--jacobian", "Newton matrix: exact (default) | jet (the Jet<24> reference) | difference-quotient "
                            "(IDA's own) (" + accepted(&FormulationInfo::jacobians) + ")");
  text_option("--linear-solver", "IDA's Newton systems: structured (default; q eliminated through the rows "
                                 "u - q' = 0 first) | dense (SUNDIALS' LU of the whole matrix) (" +
                                     accepted(&FormulationInfo::linear_solvers) + ")");
  text_option("--contact-chart",
              "chart of the contact coordinates of the consistent initialization and of the formulations "
              "that accept it (not " + (describe ? FormulationsWith(&FormulationInfo::contact_chart, false) : "") +
                  "): regular | height-field (the chapter's, singular at the condyle rim)",
              shown(OptionName(defaults.contact_chart)));
  text_option("--output-interval", "s between output rows (> 0; omit it for the scene's)");
  run->add_option("--out", out_dir, "output directory")->capture_default_str();
  run->add_flag("--quiet", quiet, "no progress on stderr");

  // The other subcommands' option sets are built only when the command line is not a `run`
  // (top-level --help lists them): building them cost ~0.6 M instructions, ~1.5 % of a
  // default run (callgrind), and `kneedyn run ...` never parses them; info and formulations
  // another ~45 k.
  const bool run_command = argc > 1 && std::string(argv[1]) == "run";
  std::string info_scene;
  CLI::App* info = nullptr;
  CLI::App* list = nullptr;
  if (!run_command) {
    info = app.add_subcommand("info", "print the scene's reference pose, slack lengths and forces");
    info->add_option("scene", info_scene, "scene file (YAML)")->required();
    list = app.add_subcommand("formulations", "list the registered formulations");
  }
  std::optional<ensembles::SweepCommand> sweep;  // kneedyn sweep (ensembles/sweep_cli.hpp)
  std::optional<ensembles::BatchCommand> batch;  // kneedyn batch (ensembles/batch_cli.hpp)
  std::optional<sensitivity::SensitivityCommand> sensitivity;  // sensitivity/sensitivity_cli.hpp
  std::optional<bench::ScoreCommand> score;  // kneedyn score (benchmarks/score_cli.hpp)
  if (!run_command) {
    sweep.emplace(app);
    batch.emplace(app);
    sensitivity.emplace(app);
    score.emplace(app);
  }

  if (const int code = ParseCommandLine(app, argc, argv, "kneedyn"); code >= 0) return code;
  if (sweep && sweep->parsed()) return sweep->Run();
  if (batch && batch->parsed()) return batch->Run();
  if (sensitivity && sensitivity->parsed()) return sensitivity->Run(argc, argv);
  if (score && score->parsed()) return score->Run(argc, argv);
  // Keep only the options given; asked of each option itself (run->count(flag) looks the flag
  // up among all of run's options by name: ~80 k instructions for the 17, callgrind).
  for (const auto& [flag, option] : text_options) {
    if (option->count() == 0) typed.erase(flag);
  }
  std::vector<const std::string*> texts = {&scene_path, &info_scene, &out_dir, &settings.formulation};
  for (const auto& [flag, text] : typed) texts.push_back(&text);
  for (const std::string* s : texts) {
    if (s->size() > 1024) {
      std::fprintf(stderr, "kneedyn: error: argument '%s' is longer than 1024 characters\n", Echo(*s).c_str());
      return 2;
    }
  }
  try {
    if (info && *info) return Info(info_scene);
    if (list && *list) {
      int width = 0;  // the longest name's: the summaries start in one column
      for (const FormulationInfo& f : RegisteredFormulations()) width = std::max(width, static_cast<int>(f.name.size()));
      for (const FormulationInfo& f : RegisteredFormulations()) {
        std::printf("%-*s  %s", width, f.name.c_str(), f.summary.c_str());
        if (!f.integrators.empty()) {
          std::printf(" [--integrator");
          for (IntegratorKind i : f.integrators) std::printf(" %s", OptionName(i));
          std::printf("]");
        }
        if (f.needs_patella) std::printf(" [needs a patella: scene section patella]");
        std::printf("\n");
      }
      return 0;
    }
    // The options, converted and checked once, before anything is read or written.
    if (const std::string why = ReadRunOptions(typed, &settings); !why.empty()) {
      std::fprintf(stderr, "kneedyn: error: %s\n", Clip(why).c_str());
      return 2;
    }
    CheckOptions(FindFormulation(settings.formulation), options, typed);
    CheckOutputDirectory(out_dir);  // refuse an unusable --out before running
    const Scene scene = LoadScene(scene_path);
    settings.command_line.assign(argv, argv + argc);
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
    std::vector<OutputWarning> warnings;
    try {
      warnings = WriteRunOutputs(out_dir, scene, settings, result);
    } catch (const std::exception& e) {  // its messages name --out
      std::fprintf(stderr, "kneedyn: error: %s\n", Clip(e.what()).c_str());
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
    std::fflush(stdout);  // the warnings follow the summary when both streams go to one file
    // summary.json's warnings, on stderr with or without --quiet (it hides progress only).
    for (const OutputWarning& w : warnings) std::fprintf(stderr, "kneedyn run: warning: %s\n", w.message.c_str());
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
