#pragma once
// Threads for the numerical kernels.
//
// The FRF evaluation at many frequencies is the inner loop of every fit and diagnosis; its frequency
// blocks are independent, so it spreads them over the machine's cores. Results do not depend on the
// number of threads: each task computes the same numbers whichever thread runs it.

#include <functional>
#include <vector>

namespace stagefit {

/// The number of threads a kernel may use (>= 1): the last SetMaxThreads() value, else the
/// environment variable STAGEFIT_THREADS when it is a positive integer, else the hardware's count.
int MaxThreads();

/// Sets MaxThreads() for the whole program; 0 returns to the default above.
void SetMaxThreads(int threads);

/// Runs task(t, worker) for every t in [0, num_tasks) on W = WorkersFor(num_tasks) threads of a pool
/// kept for the program's life, the calling thread being worker 0: worker w takes t = w, w + W, ...
/// in increasing order. Called from inside a task, or while another thread's ParallelFor holds the
/// pool, it runs every task on the calling thread as worker 0. Returns when all are done. An
/// exception thrown by a task is rethrown here (the first one, after every thread has finished).
void ParallelFor(int num_tasks, const std::function<void(int task, int worker)>& task);

/// Runs each of `jobs` once, concurrently on the pool's threads (ParallelFor over them): for
/// independent fits, each of which spreads its own FRF evaluations well over fewer than all cores.
/// Inside a job, a ParallelFor runs on the job's thread alone. The first exception a job throws is
/// rethrown after every job has finished.
void RunConcurrently(const std::vector<std::function<void()>>& jobs);

/// The number of workers ParallelFor(num_tasks, ...) uses.
int WorkersFor(int num_tasks);

}  // namespace stagefit
