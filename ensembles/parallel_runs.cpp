#include "ensembles/parallel_runs.hpp"

#include <algorithm>
#include <atomic>
#include <exception>
#include <mutex>
#include <thread>
#include <vector>

namespace kneedyn::ensembles {

void ForEachRunInParallel(std::size_t count, int threads, const std::function<void(std::size_t)>& body) {
  std::atomic<std::size_t> next{0};
  std::mutex mutex;
  std::exception_ptr first_error;
  auto worker = [&] {
    try {
      for (std::size_t k = next++; k < count; k = next++) body(k);
    } catch (...) {
      next = count;  // the others stop after their current run
      const std::lock_guard<std::mutex> lock(mutex);
      if (!first_error) first_error = std::current_exception();
    }
  };
  const std::size_t workers = std::max<std::size_t>(1, std::min<std::size_t>(std::max(threads, 1), count));
  std::vector<std::thread> pool;
  for (std::size_t t = 1; t < workers; ++t) pool.emplace_back(worker);
  worker();
  for (std::thread& t : pool) t.join();
  if (first_error) std::rethrow_exception(first_error);
}

}  // namespace kneedyn::ensembles
