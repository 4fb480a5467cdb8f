// The thread pool of a sweep and a batch: each run index once, on a given number of threads.
#pragma once

#include <cstddef>
#include <functional>

namespace kneedyn::ensembles {

// Calls body(k) for k = 0 … count − 1, each once, on min(threads, count) threads (the
// caller's among them; at least one), in no fixed order. The first exception a body throws
// stops the other threads after their current k and is rethrown here once all have stopped:
// escaping a std::thread, it would terminate the process. Bodies that write only their own
// k's slot need no lock.
void ForEachRunInParallel(std::size_t count, int threads, const std::function<void(std::size_t)>& body);

}  // namespace kneedyn::ensembles
