#include "ensembles/batch_cli.hpp"

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>

#include "ensembles/batch.hpp"
#include "formulations/output_file.hpp"
#include "formulations/progress.hpp"
#include "solver/error.hpp"

namespace kneedyn::ensembles {

BatchCommand::BatchCommand(CLI::App& app) {
  cmd_ = app.add_subcommand("batch", "run many variants of one scene in this process (CSV of parameter values)");
  cmd_->add_option("scene", scene_path_, "scene file (YAML)")->required();
  cmd_->add_option("--variants", variants_path_, "CSV: header of parameter names, one row per run")->required();
  cmd_->add_option("--out", out_path_, "results table (CSV)")->capture_default_str();
  cmd_->add_option("--formulation", settings_.formulation, "formulation name")->capture_default_str();
  // Numbers and names are kept as typed and converted once in Run (ReadOptionText), so that
  // every refusal echoes the text given.
  auto text_option = [this](const char* flag, const std::string& help, const std::string& default_text = "") {
    CLI::Option* o = cmd_->add_option(flag, typed_[flag], help);
    if (!default_text.empty()) o->default_str(default_text);
  };
  text_option("--rtol", "relative tolerance", StrCat(settings_.options.rtol));
  text_option("--atol", "absolute tolerance (SI)", StrCat(settings_.options.atol));
  text_option("--integrator", "integrator (formulations with a choice: see `kneedyn formulations`)");
  text_option("--step", "fixed step in s");
  text_option("--output-interval", "s between samples the outcomes see (0: scene's)");
  cmd_->add_option("--outcomes", outcomes_, "outcome groups (as in a sweep spec)")->delimiter(',')->capture_default_str();
  text_option("--threads", "worker threads", StrCat(threads_));
  cmd_->add_flag("--quiet", quiet_, "no summary on stdout and no progress on stderr (shown only on a terminal)");
}

int BatchCommand::Run() {
  try {
    for (auto it = typed_.begin(); it != typed_.end();) {  // keep only the options given
      it = cmd_->count(it->first) ? std::next(it) : typed_.erase(it);
    }
    if (const std::string why = ReadOptionText(typed_, &settings_.options); !why.empty()) {
      Throw<InputError>("kneedyn batch", why);
    }
    if (const auto it = typed_.find("--threads"); it != typed_.end()) {
      long threads = 0;
      if (!ParseInteger(it->second, &threads) || threads < 1 || threads > 4096) {
        Throw<InputError>("kneedyn batch", "--threads = '", Echo(it->second), "': must be an integer in [1, 4096]");
      }
      threads_ = static_cast<int>(threads);
    }
    if (const auto it = typed_.find("--output-interval"); it != typed_.end()) {
      if (!ParseReal(it->second, &settings_.output_interval) || settings_.output_interval < 0.0) {
        Throw<InputError>("kneedyn batch", "--output-interval = '", Echo(it->second),
                          "': must be a finite number >= 0 (0: the scene's)");
      }
    }
    CheckOptions(FindFormulation(settings_.formulation), settings_.options, typed_);
    CheckOutputFile("kneedyn batch", "--out", out_path_);  // before the runs
    Scene scene = LoadScene(scene_path_);
    if (std::string why; settings_.output_interval > 0.0 &&
                         !IsValidOutputInterval(settings_.output_interval, scene.end.time, &why)) {
      // kneedyn run's rule, before the runs (no variant moves the end time): not a failed row each.
      Throw<InputError>("kneedyn batch", "--output-interval = '", Echo(typed_.at("--output-interval")), "': ", why);
    }
    const BatchVariants variants = LoadBatchVariants(variants_path_, scene.model);
    CheckFixedStepBeforeRuns(scene, settings_, variants.parameters);
    Batch batch(std::move(scene), settings_, outcomes_);
    const auto t0 = std::chrono::steady_clock::now();
    // `\r` progress only on a terminal, as the sweep's.
    const bool tty = !quiet_ && StderrIsTerminal();
    std::function<void(const SweepProgress&)> progress;
    if (tty) progress = TerminalProgress("batch");
    const SweepTable table = batch.RunAll(variants, threads_, progress);
    if (tty) std::fprintf(stderr, "\n");
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    const std::string csv = FormatBatchCsv(table);
    try {
      WriteOutputFile("kneedyn batch", "--out", out_path_, csv);
    } catch (const InputError& e) {  // checked before the runs: the system failed since
      std::fprintf(stderr, "kneedyn batch: error: %s\n", MessageUnder("kneedyn batch", e.what()).c_str());
      return 1;
    }
    long failed = 0;
    for (const RunRow& r : table.rows) failed += !r.completed;
    if (!quiet_) {
      std::printf("%zu runs (%ld failed) in %.3f s (%.1f runs/s, %d thread%s) -> %s\n", table.rows.size(), failed,
                  seconds, table.rows.size() / seconds, threads_, threads_ == 1 ? "" : "s", out_path_.c_str());
    }
    return 0;
  } catch (const InputError& e) {
    std::fprintf(stderr, "kneedyn batch: error: %s\n", MessageUnder("kneedyn batch", e.what()).c_str());
    return 2;
  }
}

}  // namespace kneedyn::ensembles
