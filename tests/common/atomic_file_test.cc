#include "stagefit/common/atomic_file.h"

#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <fstream>
#include <regex>
#include <sstream>

#include "stagefit/common/error.h"

namespace stagefit {
namespace {
namespace fs = std::filesystem;

std::string ReadAll(const fs::path& p) {
  std::ifstream in(p);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

TEST(AtomicFile, AbandonedWriteLeavesOldContentIntact) {
  fs::path dir = fs::temp_directory_path() / "stagefit_atomic_test";
  fs::create_directories(dir);
  fs::path target = dir / "result.csv";
  WriteFileAtomically(target, "old\n");
  {
    AtomicFile file(target);
    file.stream() << "half of a new";
    // destroyed without Commit(): as when an exception interrupts a run
  }
  EXPECT_EQ(ReadAll(target), "old\n");
  for (const auto& entry : fs::directory_iterator(dir)) {
    EXPECT_EQ(entry.path().filename(), "result.csv") << "temporary file left behind";
  }
  WriteFileAtomically(target, "new\n");
  EXPECT_EQ(ReadAll(target), "new\n");
  fs::remove_all(dir);
}

TEST(AtomicFile, MissingFolderIsAnInputError) {
  EXPECT_THROW(WriteFileAtomically("/nonexistent-folder/x.csv", "x"), InputError);
}

TEST(CheckNotAnInput, RefusesToOverwriteAnInput) {
  fs::path p = fs::temp_directory_path() / "stagefit_input.toml";
  WriteFileAtomically(p, "x");
  EXPECT_THROW(CheckNotAnInput(p, {p}), InputError);
  EXPECT_NO_THROW(CheckNotAnInput(fs::temp_directory_path() / "other.toml", {p}));
  fs::remove(p);
}

TEST(TemporaryPath, IsNamedAfterTheTargetAndRemovedUnlessMoved) {
  fs::path dir = fs::temp_directory_path() / "stagefit_temporary_path_test";
  fs::remove_all(dir);
  fs::create_directories(dir);
  const fs::path target = dir / "out.mat";
  fs::path abandoned;
  {
    TemporaryPath t(target);
    abandoned = t.path();
    std::ofstream(t.path()) << "partial";
    EXPECT_TRUE(std::regex_match(t.path().filename().string(),
                                 std::regex("out\\.mat\\.tmp-" + std::to_string(::getpid()) + "-[0-9]+")))
        << t.path();
  }
  EXPECT_FALSE(fs::exists(abandoned));
  EXPECT_FALSE(fs::exists(target));
  {
    TemporaryPath t(target);
    std::ofstream(t.path()) << "complete";
    t.MoveOverTarget();
  }
  EXPECT_EQ(ReadAll(target), "complete");
  EXPECT_EQ(std::distance(fs::directory_iterator(dir), fs::directory_iterator()), 1);
  fs::remove_all(dir);
}

// Runs, in a child process, a write that is interrupted by SIGINT half-way; returns how the child
// ended (its wait status).
int InterruptedWrite(const fs::path& target, bool install_handler) {
  const pid_t pid = ::fork();
  if (pid == 0) {
    if (install_handler) RemoveTemporaryFilesOnSignal();
    AtomicFile file(target);
    file.stream() << "half of a new" << std::flush;
    ::raise(SIGINT);
    ::_exit(0);  // not reached: SIGINT ends the child
  }
  int status = 0;
  ::waitpid(pid, &status, 0);
  return status;
}

std::vector<std::string> FileNames(const fs::path& dir) {
  std::vector<std::string> names;
  for (const auto& e : fs::directory_iterator(dir)) names.push_back(e.path().filename().string());
  return names;
}

TEST(RemoveTemporaryFilesOnSignal, InterruptedWriteLeavesTheOldFileAndNoTemporary) {
  fs::path dir = fs::temp_directory_path() / "stagefit_atomic_signal_test";
  fs::remove_all(dir);
  fs::create_directories(dir);
  const fs::path target = dir / "result.csv";
  WriteFileAtomically(target, "old\n");
  const int status = InterruptedWrite(target, true);
  ASSERT_TRUE(WIFSIGNALED(status)) << "the child should end by the signal, as without a handler";
  EXPECT_EQ(WTERMSIG(status), SIGINT);
  EXPECT_EQ(ReadAll(target), "old\n");
  EXPECT_EQ(FileNames(dir), std::vector<std::string>{"result.csv"});
  fs::remove_all(dir);
}

TEST(RemoveTemporaryFilesOnSignal, WithoutTheHandlerTheTemporaryRemains) {
  // The control of the test above: the default action leaves the temporary file behind.
  fs::path dir = fs::temp_directory_path() / "stagefit_atomic_no_handler_test";
  fs::remove_all(dir);
  fs::create_directories(dir);
  const fs::path target = dir / "result.csv";
  WriteFileAtomically(target, "old\n");
  const int status = InterruptedWrite(target, false);
  ASSERT_TRUE(WIFSIGNALED(status));
  EXPECT_EQ(ReadAll(target), "old\n");
  EXPECT_EQ(FileNames(dir).size(), 2u);
  fs::remove_all(dir);
}

}  // namespace
}  // namespace stagefit
