#include "ensembles/sweep_cli.hpp"

#include <algorithm>
#include <cerrno>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <new>
#include <thread>

#include "ensembles/design.hpp"
#include "ensembles/sweep.hpp"
#include "ensembles/sweep_io.hpp"
#include "ensembles/sweep_mpi.hpp"
#include "ensembles/sweep_output.hpp"
#include "formulations/output_file.hpp"
#include "solver/error.hpp"

namespace kneedyn::ensembles {

namespace {

// "i/n": 0 <= i < n <= kMaxSweepRuns (more shards than a sweep can have runs is a typo;
// strtol saturates past LONG_MAX, hence the range check).
void ParseShard(const std::string& text, long* shard, long* shards) {
  const size_t slash = text.find('/');
  char* end1 = nullptr;
  char* end2 = nullptr;
  if (slash != std::string::npos) {
    const std::string a = text.substr(0, slash), b = text.substr(slash + 1);
    errno = 0;
    *shard = std::strtol(a.c_str(), &end1, 10);
    *shards = std::strtol(b.c_str(), &end2, 10);
    if (!a.empty() && !b.empty() && *end1 == '\0' && *end2 == '\0' && errno != ERANGE && *shards >= 1 &&
        *shards <= kMaxSweepRuns && *shard >= 0 && *shard < *shards) {
      return;
    }
  }
  Throw<InputError>("kneedyn sweep", "--shard = '", Echo(text), "': expected i/n with integers 0 <= i < n <= ",
                    kMaxSweepRuns);
}

// "3.2 GB" (decimal gigabytes, one decimal).
std::string FormatGigabytes(double bytes) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.1f GB", bytes / 1e9);
  return buf;
}

}  // namespace

SweepCommand::SweepCommand(CLI::App& app) {
  cmd_ = app.add_subcommand("sweep", "run an ensemble (grid, lhs, sobol, saltelli) of a scene: one row per run");
  cmd_->add_option("spec", spec_path_, "sweep spec (YAML, ensembles/README.md)");
  cmd_->add_option("--threads", threads_, "worker threads (0: all cores)")->capture_default_str();
  cmd_->add_option("--out", out_dir_, "output directory (sweep.csv, sweep.h5, or part files)")
      ->capture_default_str();
  cmd_->add_option("--shard", shard_, "run only shard i of n (index % n == i): writes DIR/part-i-of-n.json");
  cmd_->add_option("--merge", merge_, "combine part files into DIR/sweep.{csv,h5}")->expected(1, -1);
  cmd_->add_flag("--quiet", quiet_, "no progress on stderr");
}

int SweepCommand::Run() {
  try {
    // Before the runs (hours for a large design): an --out that cannot be written was refused
    // only when the results were, with exit 1.
    CheckOutputDirectoryWritable("kneedyn sweep", "--out", out_dir_);
    if (!merge_.empty()) {
      if (!spec_path_.empty()) Throw<InputError>("kneedyn sweep", "--merge takes part files, not a spec ('", spec_path_, "')");
      SweepIo();  // sweep.h5: a missing plugin is refused before reading or writing
      std::vector<SweepTable> parts;
      for (const std::string& p : merge_) {
        // CLI11 gives --merge its first value whatever it looks like: `--merge --quiet` read
        // a part file named '--quiet'.
        std::error_code ec;
        if (p.size() > 1 && p[0] == '-' && !std::filesystem::exists(p, ec)) {
          Throw<InputError>("kneedyn sweep", "--merge = '", Echo(p), "': an option, not a part file; give --merge PART...");
        }
        parts.push_back(ReadPart(p));
      }
      const SweepTable all = MergeParts(parts);
      WriteSweepResults(out_dir_, all);
      const long failed = std::count_if(all.rows.begin(), all.rows.end(), [](const RunRow& r) { return !r.completed; });
      std::printf("merged %zu parts: %zu runs (%ld failed) -> %s/sweep.{csv,h5}\n", parts.size(), all.rows.size(), failed,
                  out_dir_.c_str());
      return 0;
    }
    if (spec_path_.empty()) Throw<InputError>("kneedyn sweep", "a spec file is required (or --merge PART...)");
    if (threads_ < 0 || threads_ > 4096) Throw<InputError>("kneedyn sweep", "--threads = ", threads_, ": must be in [0, 4096]");
    long shard = 0, shards = 1;
    if (!shard_.empty()) ParseShard(shard_, &shard, &shards);

    MpiSession mpi;  // a no-op unless launched by mpirun
    if (mpi.active() && !shard_.empty()) {
      Throw<InputError>("kneedyn sweep", "--shard and mpirun exclude each other: ranks already split the runs");
    }
    const SweepSpec spec = LoadSweepSpec(spec_path_);
    if (shard_.empty()) SweepIo();  // sweep.h5: a missing plugin is refused before the runs
    int threads = threads_;
    if (threads == 0) {
      const int cores = std::max(1u, std::thread::hardware_concurrency());
      threads = std::max(1, cores / std::max(1, mpi.ranks_on_node()));
    }
    if (mpi.active()) {
      shard = mpi.rank();
      shards = mpi.size();
    }
    std::vector<long> indices;
    SweepTable table;
    // The design is held in memory whole (its unit-cube matrix, the run indices, the results
    // table) before the first run; a spec within the run limit can still ask for more than
    // the machine has. That is a refusal naming the design, not std::bad_alloc.
    const auto refuse_design_size = [&spec] {
      const int d = static_cast<int>(spec.parameters.size());
      const long runs = DesignRows(spec.design, d);
      const bool grid = spec.design.type == DesignType::kGrid;
      Throw<InputError>("kneedyn sweep", spec.path, ": field 'design.", grid ? "levels" : "samples", "' = ",
                        grid ? spec.design.levels : spec.design.samples, ": ", runs, " runs of ", d,
                        " parameters do not fit in this machine's memory (the design matrix alone is ",
                        FormatGigabytes(static_cast<double>(runs) * d * sizeof(double)),
                        ", held whole by every shard); use a smaller design");
    };
    try {
      indices = ShardIndices(spec, shard, shards);
    } catch (const std::bad_alloc&) {
      refuse_design_size();
    }
    const bool tty = !quiet_ && isatty(STDERR_FILENO) && mpi.rank() == 0;
    std::function<void(const SweepProgress&)> progress;
    if (tty) progress = TerminalProgress("sweep");
    const auto start = std::chrono::steady_clock::now();
    try {
      table = RunSweep(spec, indices, threads, progress);
    } catch (const std::bad_alloc&) {
      refuse_design_size();
    }
    if (tty) std::fprintf(stderr, "\n");
    const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    long failed = 0;
    for (const RunRow& r : table.rows) failed += !r.completed;
    if (mpi.active()) {
      const MpiGathered g = mpi.Gather(&table, wall, failed);
      if (mpi.rank() != 0) return 0;
      WriteSweepResults(out_dir_, table);
      std::printf("sweep %s: %zu runs (%ld failed) on %d MPI ranks x %d threads in %.3f s wall (%.2f runs/s)\n",
                  spec.path.c_str(), table.rows.size(), g.failed, mpi.size(), threads, g.wall_s,
                  table.rows.size() / g.wall_s);
      std::printf("  wrote %s/sweep.{csv,h5}\n", out_dir_.c_str());
      return 0;
    }
    if (!shard_.empty()) {
      const std::string part = (std::filesystem::path(out_dir_) /
                                ("part-" + std::to_string(shard) + "-of-" + std::to_string(shards) + ".json")).string();
      WritePart(part, table, shard, shards);
      std::printf("sweep %s shard %ld/%ld: %zu runs (%ld failed) on %d threads in %.3f s wall\n  wrote %s\n",
                  spec.path.c_str(), shard, shards, table.rows.size(), failed, threads, wall, part.c_str());
      return 0;
    }
    WriteSweepResults(out_dir_, table);
    std::printf("sweep %s: %zu runs (%ld failed) on %d threads in %.3f s wall (%.2f runs/s)\n",
                spec.path.c_str(), table.rows.size(), failed, threads, wall, table.rows.size() / wall);
    std::printf("  wrote %s/sweep.{csv,h5}\n", out_dir_.c_str());
    return 0;
  } catch (const InputError& e) {
    std::fprintf(stderr, "kneedyn sweep: error: %s\n", MessageUnder("kneedyn sweep", e.what()).c_str());
    return 2;
  } catch (const Error& e) {
    std::fprintf(stderr, "kneedyn sweep: error: %s\n", MessageUnder("kneedyn sweep", e.what()).c_str());
    return 1;
  }
}

}  // namespace kneedyn::ensembles
