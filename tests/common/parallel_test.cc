#include "stagefit/common/parallel.h"

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <functional>
#include <stdexcept>
#include <thread>
#include <vector>

namespace stagefit {
namespace {

// Restores the default thread count when a test ends.
struct ThreadCountGuard {
  explicit ThreadCountGuard(int threads) { SetMaxThreads(threads); }
  ~ThreadCountGuard() { SetMaxThreads(0); }
};

TEST(ParallelFor, RunsEveryTaskOnceOnTheWorkersItAnnounces) {
  for (const int threads : {1, 2, 3, 8}) {
    const ThreadCountGuard guard(threads);
    for (const int tasks : {0, 1, 2, 5, 64}) {
      std::vector<std::atomic<int>> runs(tasks);
      std::vector<int> worker_of(tasks, -1);
      const int workers = WorkersFor(tasks);
      EXPECT_EQ(workers, std::max(1, std::min(threads, tasks)));
      ParallelFor(tasks, [&](int t, int worker) {
        ++runs[t];
        worker_of[t] = worker;
      });
      for (int t = 0; t < tasks; ++t) {
        EXPECT_EQ(runs[t].load(), 1) << "task " << t << " of " << tasks << ", " << threads << " threads";
        EXPECT_GE(worker_of[t], 0) << "task " << t;
        EXPECT_LT(worker_of[t], workers) << "task " << t;
      }
    }
  }
}

TEST(ParallelFor, RethrowsATaskExceptionAfterTheRunningOnesFinish) {
  const ThreadCountGuard guard(2);
  std::vector<std::atomic<int>> runs(6);
  std::atomic<int> running{0};
  EXPECT_THROW(ParallelFor(6,
                           [&](int t, int) {
                             ++running;
                             ++runs[t];
                             if (t == 3) {
                               --running;
                               throw std::runtime_error("task 3");
                             }
                             std::this_thread::sleep_for(std::chrono::milliseconds(2));
                             --running;
                           }),
               std::runtime_error);
  // No task still runs when the exception arrives; none ran twice.
  EXPECT_EQ(running.load(), 0);
  for (int t = 0; t < 6; ++t) EXPECT_LE(runs[t].load(), 1) << "task " << t;
  EXPECT_EQ(runs[3].load(), 1);
  // The pool still works afterwards.
  std::atomic<int> count{0};
  ParallelFor(4, [&](int, int) { ++count; });
  EXPECT_EQ(count.load(), 4);
}

// Tasks running at the same time have different worker numbers, also in nested calls.
TEST(ParallelFor, ConcurrentTasksHaveDistinctWorkerNumbers) {
  const ThreadCountGuard guard(3);
  std::atomic<int> inner{0};
  std::atomic<bool> clash{false};
  std::vector<std::atomic<int>> outer_busy(3);
  ParallelFor(6, [&](int, int outer_worker) {
    if (outer_busy[outer_worker]++ != 0) clash = true;
    std::vector<std::atomic<int>> busy(3);
    ParallelFor(8, [&](int, int worker) {
      ASSERT_LT(worker, 3);
      if (busy[worker]++ != 0) clash = true;
      std::this_thread::sleep_for(std::chrono::microseconds(200));
      --busy[worker];
      ++inner;
    });
    --outer_busy[outer_worker];
  });
  EXPECT_EQ(inner.load(), 48);
  EXPECT_FALSE(clash.load());
}

// A nested call gets the help of a thread whose own task has finished: with two threads, the outer
// loop's short task ends and its thread runs one of the long task's inner tasks beside the other.
TEST(ParallelFor, IdleThreadsHelpNestedCalls) {
  const ThreadCountGuard guard(2);
  std::atomic<int> started{0};
  std::atomic<bool> together{false};
  ParallelFor(2, [&](int t, int) {
    if (t != 1) return;
    ParallelFor(2, [&](int, int) {
      ++started;
      // Both inner tasks running at once (waited for up to 10 s).
      for (int i = 0; i < 10000 && started.load() < 2; ++i) std::this_thread::sleep_for(std::chrono::milliseconds(1));
      if (started.load() == 2) together = true;
    });
  });
  EXPECT_TRUE(together.load());
}

TEST(RunConcurrently, RunsEachJobOnceAndItsInnerLoopsWhole) {
  for (const int threads : {1, 2, 4}) {
    const ThreadCountGuard guard(threads);
    std::vector<std::atomic<int>> runs(3);
    std::atomic<int> inner{0};
    std::vector<std::function<void()>> jobs;
    for (int j = 0; j < 3; ++j) {
      jobs.push_back([&, j] {
        ++runs[j];
        ParallelFor(5, [&](int, int) { ++inner; });
      });
    }
    RunConcurrently(jobs);
    for (int j = 0; j < 3; ++j) EXPECT_EQ(runs[j].load(), 1) << "job " << j << ", " << threads << " threads";
    EXPECT_EQ(inner.load(), 15) << threads << " threads";
  }
  RunConcurrently({});  // nothing to run
}

TEST(RunConcurrently, RethrowsAJobsExceptionAfterTheOthersFinish) {
  for (const int threads : {1, 2}) {
    const ThreadCountGuard guard(threads);
    std::atomic<bool> other_done{false};
    EXPECT_THROW(RunConcurrently({[] { throw std::runtime_error("first job"); }, [&] { other_done = true; }}),
                 std::runtime_error);
    EXPECT_TRUE(other_done.load()) << threads << " threads";
  }
}

}  // namespace
}  // namespace stagefit
