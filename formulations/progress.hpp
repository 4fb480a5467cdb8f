// Console progress for long loops: the catalog and the sweeps print "i/N" with
// the elapsed time and an estimate of the time left, one line per item (log-friendly);
// `\r` updates only where stderr is a terminal.
#pragma once

#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <string>

namespace kneedyn {

inline bool StderrIsTerminal() { return ::isatty(::fileno(stderr)) == 1; }

// "1h02m", "3m05s", "12.3s"
inline std::string FormatDuration(double s) {
  char buf[32];
  if (!(s >= 0.0)) return "?";
  if (s < 60.0) {
    std::snprintf(buf, sizeof buf, "%.1fs", s);
  } else if (s < 3600.0) {
    std::snprintf(buf, sizeof buf, "%dm%02ds", static_cast<int>(s) / 60, static_cast<int>(s) % 60);
  } else {
    std::snprintf(buf, sizeof buf, "%dh%02dm", static_cast<int>(s) / 3600, static_cast<int>(s) % 3600 / 60);
  }
  return buf;
}

// Counts finished items of a known total; Next() returns "[i/N, 12.3s elapsed, ~1m05s left]".
// The estimate is the mean time per finished item times the items left.
class ProgressCounter {
 public:
  explicit ProgressCounter(long total) : total_(total), start_(std::chrono::steady_clock::now()) {}

  std::string Next() {
    ++done_;
    const double elapsed =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
    const double left = done_ > 0 ? elapsed / static_cast<double>(done_) * static_cast<double>(total_ - done_) : -1.0;
    return "[" + std::to_string(done_) + "/" + std::to_string(total_) + ", " + FormatDuration(elapsed) +
           " elapsed, ~" + FormatDuration(left) + " left]";
  }
  long done() const { return done_; }
  long total() const { return total_; }

 private:
  long total_ = 0;
  long done_ = 0;
  std::chrono::steady_clock::time_point start_;
};

}  // namespace kneedyn
