#include "stagefit/common/parallel.h"

#include <algorithm>
#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <cstdlib>
#include <exception>
#include <mutex>
#include <thread>
#include <vector>

namespace stagefit {
namespace {

std::atomic<int> g_max_threads{0};  // 0: not set

int DefaultThreads() {
  if (const char* text = std::getenv("STAGEFIT_THREADS")) {
    char* end = nullptr;
    const long value = std::strtol(text, &end, 10);
    if (end != text && *end == '\0' && value >= 1) return static_cast<int>(std::min(value, 1024L));
  }
  return std::max(1, static_cast<int>(std::thread::hardware_concurrency()));
}

}  // namespace

int MaxThreads() {
  const int set = g_max_threads.load(std::memory_order_relaxed);
  if (set > 0) return set;
  static const int default_threads = DefaultThreads();
  return default_threads;
}

void SetMaxThreads(int threads) { g_max_threads.store(std::max(0, threads), std::memory_order_relaxed); }

int WorkersFor(int num_tasks) { return std::max(1, std::min(MaxThreads(), num_tasks)); }

namespace {

// Worker threads kept for the life of the program: creating threads per call costs more than a whole
// FRF evaluation on some virtual machines. One job at a time; a ParallelFor from inside a task, or
// while another thread's job runs, runs on its calling thread alone.
class Pool {
 public:
  static Pool& Get() {
    static Pool* pool = new Pool;  // never destroyed: the workers wait until the process ends
    return *pool;
  }

  // Runs the job when the pool is free; false (nothing run) when it is busy.
  bool TryRun(int num_tasks, int workers, const std::function<void(int, int)>& task) {
    std::unique_lock<std::mutex> job_lock(job_mutex_, std::try_to_lock);
    if (!job_lock.owns_lock()) return false;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      while (static_cast<int>(threads_.size()) < workers - 1) {
        const int w = static_cast<int>(threads_.size()) + 1;
        threads_.emplace_back([this, w] { WorkerLoop(w); });
        threads_.back().detach();
      }
      task_ = &task;
      num_tasks_ = num_tasks;
      workers_ = workers;
      remaining_ = workers - 1;
      error_ = nullptr;
      ++generation_;
    }
    wake_.notify_all();
    RunShare(0);
    std::unique_lock<std::mutex> lock(mutex_);
    done_.wait(lock, [this] { return remaining_ == 0; });
    task_ = nullptr;
    if (error_) std::rethrow_exception(error_);
    return true;
  }

 private:
  void RunShare(int worker) {
    in_task_ = true;
    try {
      for (int t = worker; t < num_tasks_; t += workers_) (*task_)(t, worker);
    } catch (...) {
      std::lock_guard<std::mutex> lock(mutex_);
      if (!error_) error_ = std::current_exception();
    }
    in_task_ = false;
  }

  void WorkerLoop(int worker) {
    std::uint64_t seen = 0;
    for (;;) {
      {
        std::unique_lock<std::mutex> lock(mutex_);
        wake_.wait(lock, [&] { return generation_ != seen; });
        seen = generation_;
        if (worker >= workers_) continue;
      }
      RunShare(worker);
      std::lock_guard<std::mutex> lock(mutex_);
      if (--remaining_ == 0) done_.notify_one();
    }
  }

 public:
  static thread_local bool in_task_;

 private:
  std::mutex job_mutex_;  // one job at a time
  std::mutex mutex_;      // guards everything below
  std::condition_variable wake_, done_;
  std::vector<std::thread> threads_;
  const std::function<void(int, int)>* task_ = nullptr;
  int num_tasks_ = 0, workers_ = 0, remaining_ = 0;
  std::uint64_t generation_ = 0;
  std::exception_ptr error_;
};

thread_local bool Pool::in_task_ = false;

}  // namespace

void ParallelFor(int num_tasks, const std::function<void(int task, int worker)>& task) {
  if (num_tasks <= 0) return;
  const int workers = WorkersFor(num_tasks);
  if (workers > 1 && !Pool::in_task_ && Pool::Get().TryRun(num_tasks, workers, task)) return;
  for (int t = 0; t < num_tasks; ++t) task(t, 0);
}

void RunConcurrently(const std::vector<std::function<void()>>& jobs) {
  ParallelFor(static_cast<int>(jobs.size()), [&](int t, int) { jobs[static_cast<size_t>(t)](); });
}

}  // namespace stagefit
