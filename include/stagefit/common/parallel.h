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

/// Runs task(t, worker) for every t in [0, num_tasks) on up to W = WorkersFor(num_tasks) threads of a
/// pool kept for the program's life, and returns when all are done. The calling thread is worker 0;
/// idle threads join as workers 1 .. W-1 and every worker takes the next task when it is done with
/// one, so which worker runs which task varies from run to run: a task must compute the same numbers
/// whichever worker runs it. Two tasks running at the same time have different worker numbers (for
/// per-worker scratch). Called from inside a task (nested), it runs on the calling thread, and threads
/// that are idle or waiting for their own last tasks help. The first exception a task throws is
/// rethrown here after the running tasks have finished; the tasks not yet taken are not run.
void ParallelFor(int num_tasks, const std::function<void(int task, int worker)>& task);

/// Runs each of `jobs` once, concurrently on the pool's threads (ParallelFor over them): for
/// independent fits, each of which spreads its own FRF evaluations well over fewer than all cores.
/// When one job finishes first, its thread helps the others' inner loops. Every job runs; the first
/// (in order) exception a job throws is rethrown after all have finished.
void RunConcurrently(const std::vector<std::function<void()>>& jobs);

/// The number of workers ParallelFor(num_tasks, ...) uses.
int WorkersFor(int num_tasks);

}  // namespace stagefit
