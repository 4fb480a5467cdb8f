// Ceres writes through glog. Uninitialised, glog prints "Logging before InitGoogleLogging"
// and then every message at WARNING or above to stderr, for instance Levenberg–Marquardt's
// "Terminating: Number of consecutive invalid steps ..." at ERROR even with
// logging_type = SILENT; initialised with its defaults it writes log files under /tmp.
// Ceres reports every outcome in its Solver::Summary, which kneedyn turns into its own
// messages, so a kneedyn program lets it print nothing by itself: glog is initialised once
// per process to stderr and FATAL only (a FATAL message aborts, and is the one kept). A
// host that initialised glog itself keeps its own settings.
//
// Not installed (solver/internal/): it needs glog's headers, which only Ceres users have.
#pragma once

#include <glog/logging.h>

namespace kneedyn {

inline void QuietCeresLogging() {
  static const bool done = [] {
    if (!google::IsGoogleLoggingInitialized()) {
      FLAGS_logtostderr = true;
      FLAGS_minloglevel = google::GLOG_FATAL;
      google::InitGoogleLogging("kneedyn");
    }
    return true;
  }();
  (void)done;
}

}  // namespace kneedyn
