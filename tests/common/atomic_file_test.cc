#include "stagefit/common/atomic_file.h"

#include <gtest/gtest.h>

#include <fstream>
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

}  // namespace
}  // namespace stagefit
