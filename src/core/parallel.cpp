#include "tabletop_shapes/core/parallel.h"

#include <algorithm>
#include <atomic>
#include <condition_variable>
#include <cstdlib>
#include <exception>
#include <mutex>
#include <thread>
#include <vector>

#include <pthread.h>
#include <sched.h>

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
      if (threads_.size() < helpers) {
        // The CPUs a new thread inherits: the helpers' bounds.
        CPU_ZERO(&helper_cpus_);
        if (sched_getaffinity(0, sizeof helper_cpus_, &helper_cpus_) != 0) CPU_ZERO(&helper_cpus_);
        helpers_off_cpu_ = -1;  // the new helpers may run anywhere yet
      }
      while (threads_.size() < helpers) {
        threads_.emplace_back([this] { serve(); });
        ++started_threads;
      }
      work_ = &work;
      wanted_ = helpers;
      taken_ = finished_ = 0;
      keepHelpersOffThisCpu();
    }
    wake_.notify_all();
    work();
    std::unique_lock<std::mutex> lock(mutex_);
    // Every item is taken once work() returns here: a helper still asleep would find none, so
    // it is not waited for (waking it could take as long as the items did).
    wanted_ = taken_;
    done_.wait(lock, [&] { return finished_ == wanted_; });
    work_ = nullptr;
    busy_ = false;
    return true;
  }

 private:
  // Keeps the helpers off the CPU the caller runs on, within the CPUs they were started with
  // (a `taskset` of the process stays in force). A woken helper may otherwise be queued on the
  // caller's busy CPU: this VM's kernel packs threads onto one vCPU while the load looks light,
  // and a 1-object chain frame's preprocessing then ran on one core (9.2 ms from the stamp, 7.6
  // with this). A syscall per helper, only when the caller has moved.
  void keepHelpersOffThisCpu() {
    const int cpu = sched_getcpu();
    if (cpu < 0 || cpu == helpers_off_cpu_ || !CPU_ISSET(cpu, &helper_cpus_)) return;
    cpu_set_t others = helper_cpus_;
    CPU_CLR(cpu, &others);
    if (CPU_COUNT(&others) == 0) return;  // one CPU only: helpers share it
    for (std::thread& thread : threads_) {
      pthread_setaffinity_np(thread.native_handle(), sizeof others, &others);
    }
    helpers_off_cpu_ = cpu;
  }

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
  cpu_set_t helper_cpus_;     // the CPUs the helpers were started with
  int helpers_off_cpu_ = -1;  // the CPU they were last kept off (-1: none)
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
