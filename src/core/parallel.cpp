#include "tabletop_shapes/core/parallel.h"

#include <algorithm>
#include <atomic>
#include <cstdlib>
#include <exception>
#include <mutex>
#include <thread>
#include <vector>

namespace tabletop_shapes {
namespace {

std::atomic<unsigned> chosen_threads{0};
// True on a thread while it runs the items of a parallelFor with more than one thread.
thread_local bool running_parallel_items = false;

unsigned threadsFromEnvironment() {
  const char* text = std::getenv("TABLETOP_SHAPES_THREADS");
  if (!text) return 0;
  char* end = nullptr;
  const long threads = std::strtol(text, &end, 10);
  return *end == '\0' && threads > 0 && threads <= 1024 ? static_cast<unsigned>(threads) : 0;
}

}  // namespace

unsigned workerThreads() {
  if (const unsigned chosen = chosen_threads.load()) return chosen;
  static const unsigned from_environment = threadsFromEnvironment();
  if (from_environment) return from_environment;
  return std::max(1u, std::thread::hardware_concurrency());
}

void setWorkerThreads(unsigned threads) { chosen_threads = threads; }

unsigned freeWorkerThreads() { return running_parallel_items ? 1 : workerThreads(); }

void parallelFor(size_t n, const std::function<void(size_t)>& body, unsigned threads) {
  if (threads == 0) threads = workerThreads();
  const size_t workers = std::min<size_t>(threads, n);
  if (workers <= 1) {
    for (size_t i = 0; i < n; ++i) body(i);
    return;
  }
  std::atomic<size_t> next{0};
  std::exception_ptr error;
  std::mutex error_mutex;
  auto work = [&]() {
    const bool was_running_items = running_parallel_items;
    running_parallel_items = true;
    for (size_t i = next++; i < n; i = next++) {
      try {
        body(i);
      } catch (...) {
        std::lock_guard<std::mutex> lock(error_mutex);
        if (!error) error = std::current_exception();
      }
    }
    running_parallel_items = was_running_items;
  };
  std::vector<std::thread> helpers;
  helpers.reserve(workers - 1);
  for (size_t t = 1; t < workers; ++t) helpers.emplace_back(work);
  work();
  for (std::thread& helper : helpers) helper.join();
  if (error) std::rethrow_exception(error);
}

}  // namespace tabletop_shapes
