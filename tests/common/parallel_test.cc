#include "stagefit/common/parallel.h"

#include <gtest/gtest.h>

#include <atomic>
#include <functional>
#include <stdexcept>
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
        EXPECT_EQ(worker_of[t], t % workers) << "task " << t;
      }
    }
  }
}

TEST(ParallelFor, RethrowsATaskExceptionAfterAllFinish) {
  const ThreadCountGuard guard(2);
  std::atomic<int> finished{0};
  EXPECT_THROW(ParallelFor(6,
                           [&](int t, int) {
                             if (t == 3) throw std::runtime_error("task 3");
                             ++finished;
                           }),
               std::runtime_error);
  // Worker 1 (tasks 1, 3, 5) stops at its throw; worker 0 runs 0, 2, 4.
  EXPECT_EQ(finished.load(), 4);
  // The pool still works afterwards.
  std::atomic<int> count{0};
  ParallelFor(4, [&](int, int) { ++count; });
  EXPECT_EQ(count.load(), 4);
}

TEST(ParallelFor, NestedCallsRunOnTheirCallingThread) {
  const ThreadCountGuard guard(2);
  std::atomic<int> inner{0};
  ParallelFor(2, [&](int, int) {
    ParallelFor(3, [&](int, int worker) {
      EXPECT_EQ(worker, 0);
      ++inner;
    });
  });
  EXPECT_EQ(inner.load(), 6);
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
        ParallelFor(5, [&](int, int) { ++inner; });  // on the job's thread alone when jobs run in parallel
      });
    }
    RunConcurrently(jobs);
    for (int j = 0; j < 3; ++j) EXPECT_EQ(runs[j].load(), 1) << "job " << j << ", " << threads << " threads";
    EXPECT_EQ(inner.load(), 15) << threads << " threads";
  }
  RunConcurrently({});  // nothing to run
}

TEST(RunConcurrently, RethrowsAJobsExceptionAfterTheOthersFinish) {
  const ThreadCountGuard guard(2);
  std::atomic<bool> other_done{false};
  EXPECT_THROW(RunConcurrently({[] { throw std::runtime_error("first job"); }, [&] { other_done = true; }}),
               std::runtime_error);
  EXPECT_TRUE(other_done.load());
}

}  // namespace
}  // namespace stagefit
