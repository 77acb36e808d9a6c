#include "tabletop_shapes/core/parallel.h"

#include <algorithm>
#include <atomic>
#include <condition_variable>
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

std::atomic<size_t> started_threads{0};

// Helper threads kept between parallelFor calls: a frame makes ~9 calls, and starting and
// joining a thread costs 36-52 us each time. One call at a time uses them (tryRun).
class HelperPool {
 public:
  ~HelperPool() {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      stopping_ = true;
    }
    wake_.notify_all();
    for (std::thread& thread : threads_) thread.join();
  }

  // Runs work() on `helpers` pool threads and on the calling thread, and returns when all are
  // done; false (nothing run) when the pool is running another call's work.
  bool tryRun(size_t helpers, const std::function<void()>& work) {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (busy_) return false;
      busy_ = true;
      while (threads_.size() < helpers) {
        threads_.emplace_back([this] { serve(); });
        ++started_threads;
      }
      work_ = &work;
      wanted_ = helpers;
      taken_ = finished_ = 0;
    }
    wake_.notify_all();
    work();
    std::unique_lock<std::mutex> lock(mutex_);
    done_.wait(lock, [&] { return finished_ == wanted_; });
    work_ = nullptr;
    busy_ = false;
    return true;
  }

 private:
  void serve() {
    std::unique_lock<std::mutex> lock(mutex_);
    for (;;) {
      wake_.wait(lock, [&] { return stopping_ || (work_ && taken_ < wanted_); });
      if (stopping_) return;
      ++taken_;
      const std::function<void()>* work = work_;
      lock.unlock();
      (*work)();
      lock.lock();
      if (++finished_ == wanted_) done_.notify_all();
    }
  }

  std::mutex mutex_;
  std::condition_variable wake_, done_;
  std::vector<std::thread> threads_;
  const std::function<void()>* work_ = nullptr;
  size_t wanted_ = 0, taken_ = 0, finished_ = 0;
  bool busy_ = false, stopping_ = false;
};

HelperPool& helperPool() {
  static HelperPool pool;
  return pool;
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
  if (!helperPool().tryRun(workers - 1, work)) {
    // The pool is running another parallelFor (one started within its items, or from another
    // thread: nodelets of one manager): helpers of this call's own.
    std::vector<std::thread> helpers;
    helpers.reserve(workers - 1);
    for (size_t t = 1; t < workers; ++t) {
      helpers.emplace_back(work);
      ++started_threads;
    }
    work();
    for (std::thread& helper : helpers) helper.join();
  }
  if (error) std::rethrow_exception(error);
}

size_t parallelThreadsStarted() { return started_threads.load(); }

}  // namespace tabletop_shapes
