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
// FRF evaluation on some virtual machines.
//
// Every ParallelFor is a job on one list. A job's caller runs its tasks as worker 0; an idle pool
// thread, and a caller waiting for its own job's last tasks, take the next task of an open job, the
// oldest first, as that job's worker 1, 2, ... (one number per thread and job, at most the job's
// worker count). A thread waiting inside a task (a nested ParallelFor) takes tasks only of jobs
// opened after its own: their tasks are at most as deep as its own, and it never runs a second task of
// a job it is inside. So a fit whose partner finished first gets the idle core for its FRF
// evaluations (the loop's two refits, the last candidates of a diagnosis), where one job at a time
// left it idle.
class Pool {
 public:
  static Pool& Get() {
    static Pool* pool = new Pool;  // never destroyed: the workers wait until the process ends
    return *pool;
  }

  void Run(int num_tasks, int workers, const std::function<void(int, int)>& task) {
    Job job;
    job.task = &task;
    job.num_tasks = num_tasks;
    job.workers = workers;
    std::unique_lock<std::mutex> lock(mutex_);
    while (num_threads_ < workers - 1) {
      ++num_threads_;
      std::thread([this] { WorkerLoop(); }).detach();
    }
    job.order = ++last_order_;
    jobs_.push_back(&job);
    changed_.notify_all();
    for (;;) {
      if (job.next < job.num_tasks) {
        RunTask(&lock, &job, job.next++, 0);
        continue;
      }
      if (job.running == 0) break;
      int t = 0, worker = 0;
      if (Job* other = FindTask(job.order, &t, &worker)) {
        RunTask(&lock, other, t, worker);
      } else {
        changed_.wait(lock);
      }
    }
    jobs_.erase(std::find(jobs_.begin(), jobs_.end(), &job));
    lock.unlock();
    if (job.error) std::rethrow_exception(job.error);
  }

 private:
  struct Job {
    const std::function<void(int, int)>* task = nullptr;
    int num_tasks = 0, workers = 0;
    std::uint64_t order = 0;             // opening order
    int next = 0;                        // the next task not yet taken
    int running = 0;                     // tasks taken and not finished
    std::vector<std::thread::id> helpers;  // helper h is worker h + 1
    std::exception_ptr error;
  };

  // The next task of the oldest open job opened after `after` that this thread may work on, with its
  // worker number there; nullptr when there is none. Under the lock.
  Job* FindTask(std::uint64_t after, int* t, int* worker) {
    const std::thread::id me = std::this_thread::get_id();
    for (Job* job : jobs_) {
      if (job->order <= after || job->next >= job->num_tasks) continue;
      auto it = std::find(job->helpers.begin(), job->helpers.end(), me);
      if (it == job->helpers.end()) {
        if (static_cast<int>(job->helpers.size()) + 1 >= job->workers) continue;  // every worker number taken
        it = job->helpers.insert(job->helpers.end(), me);
      }
      *worker = static_cast<int>(it - job->helpers.begin()) + 1;
      *t = job->next++;
      return job;
    }
    return nullptr;
  }

  // Runs task `t` of `job` as `worker` with the lock released. A task that throws ends the job: its
  // first exception is kept, the tasks not yet taken are not run.
  void RunTask(std::unique_lock<std::mutex>* lock, Job* job, int t, int worker) {
    ++job->running;
    lock->unlock();
    std::exception_ptr error;
    try {
      (*job->task)(t, worker);
    } catch (...) {
      error = std::current_exception();
    }
    lock->lock();
    if (error) {
      if (!job->error) job->error = error;
      job->next = job->num_tasks;
    }
    if (--job->running == 0 && job->next >= job->num_tasks) changed_.notify_all();
  }

  void WorkerLoop() {
    std::unique_lock<std::mutex> lock(mutex_);
    for (;;) {
      int t = 0, worker = 0;
      if (Job* job = FindTask(0, &t, &worker)) {
        RunTask(&lock, job, t, worker);
      } else {
        changed_.wait(lock);
      }
    }
  }

  std::mutex mutex_;                  // guards everything below and every open job
  std::condition_variable changed_;   // a job opened, or its last task finished
  std::vector<Job*> jobs_;            // the open jobs, oldest first
  std::uint64_t last_order_ = 0;
  int num_threads_ = 0;               // pool threads started
};

}  // namespace

void ParallelFor(int num_tasks, const std::function<void(int task, int worker)>& task) {
  if (num_tasks <= 0) return;
  const int workers = WorkersFor(num_tasks);
  if (workers > 1) {
    Pool::Get().Run(num_tasks, workers, task);
    return;
  }
  for (int t = 0; t < num_tasks; ++t) task(t, 0);
}

void RunConcurrently(const std::vector<std::function<void()>>& jobs) {
  // Every job runs, whatever another throws (ParallelFor would leave the untaken ones).
  std::vector<std::exception_ptr> errors(jobs.size());
  ParallelFor(static_cast<int>(jobs.size()), [&](int t, int) {
    try {
      jobs[static_cast<size_t>(t)]();
    } catch (...) {
      errors[static_cast<size_t>(t)] = std::current_exception();
    }
  });
  for (const auto& error : errors) {
    if (error) std::rethrow_exception(error);
  }
}

}  // namespace stagefit
