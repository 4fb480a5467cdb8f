#include "ensembles/batch_cli.hpp"

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>

#include "ensembles/batch.hpp"
#include "solver/error.hpp"

namespace kneedyn::ensembles {

BatchCommand::BatchCommand(CLI::App& app) {
  cmd_ = app.add_subcommand("batch", "run many variants of one scene in this process (CSV of parameter values)");
  cmd_->add_option("scene", scene_path_, "scene file (YAML)")->required();
  cmd_->add_option("--variants", variants_path_, "CSV: header of parameter names, one row per run")->required();
  cmd_->add_option("--out", out_path_, "results table (CSV)")->capture_default_str();
  cmd_->add_option("--formulation", settings_.formulation, "formulation name")->capture_default_str();
  cmd_->add_option("--rtol", settings_.options.rtol, "relative tolerance")->capture_default_str();
  cmd_->add_option("--atol", settings_.options.atol, "absolute tolerance (SI)")->capture_default_str();
  cmd_->add_option_function<std::string>(
      "--integrator",
      [this](const std::string& text) {
        IntegratorKind kind{};
        std::string why;
        if (!ParseOptionValue(text, &kind, &why)) throw CLI::ValidationError(why);
        settings_.options.integrator = kind;
      },
      "integrator (formulations with a choice: see `kneedyn formulations`)");
  cmd_->add_option("--step", settings_.options.step, "fixed step in s");
  cmd_->add_option("--output-interval", settings_.output_interval, "s between samples the outcomes see (0: scene's)");
  cmd_->add_option("--outcomes", outcomes_, "outcome groups (as in a sweep spec)")->delimiter(',')->capture_default_str();
  cmd_->add_option("--threads", threads_, "worker threads")->capture_default_str();
  cmd_->add_flag("--quiet", quiet_, "no summary on stdout");
}

int BatchCommand::Run() {
  try {
    if (threads_ < 1 || threads_ > 4096) Throw<InputError>("kneedyn batch", "--threads = ", threads_, ": must be in [1, 4096]");
    if (settings_.output_interval < 0.0) {
      Throw<InputError>("kneedyn batch", "--output-interval = ", settings_.output_interval, ": must be >= 0");
    }
    const std::filesystem::path out(out_path_);
    if (out_path_.empty() || std::filesystem::is_directory(out)) {
      Throw<InputError>("kneedyn batch", "--out = '", out_path_, "': must name a file");
    }
    Scene scene = LoadScene(scene_path_);
    const BatchVariants variants = LoadBatchVariants(variants_path_, scene.model);
    Batch batch(std::move(scene), settings_, outcomes_);
    const auto t0 = std::chrono::steady_clock::now();
    const SweepTable table = batch.RunAll(variants, threads_);
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    const std::string csv = FormatBatchCsv(table);
    try {
      if (out.has_parent_path()) std::filesystem::create_directories(out.parent_path());
      const std::string tmp = out_path_ + ".tmp";
      {
        std::ofstream f(tmp, std::ios::binary);
        f << csv;
        if (!f) throw std::runtime_error("cannot write '" + tmp + "'");
      }
      std::filesystem::rename(tmp, out);
    } catch (const std::exception& e) {
      std::fprintf(stderr, "kneedyn batch: error: --out = '%s': %s\n", out_path_.c_str(), e.what());
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
    std::fprintf(stderr, "kneedyn batch: error: %s\n", e.what());
    return 2;
  }
}

}  // namespace kneedyn::ensembles
