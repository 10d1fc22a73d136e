#include "stagefit/common/atomic_file.h"

#include <unistd.h>

#include <atomic>
#include <cstdio>

#include "stagefit/common/error.h"

namespace stagefit {
namespace fs = std::filesystem;

namespace {
std::atomic<int> g_counter{0};
}

AtomicFile::AtomicFile(fs::path target) : target_(std::move(target)) {
  temporary_ = target_;
  temporary_ += ".tmp-" + std::to_string(::getpid()) + "-" + std::to_string(g_counter++);
  stream_.open(temporary_, std::ios::binary | std::ios::trunc);
  if (!stream_) {
    throw InputError("cannot write output file '" + target_.string() +
                     "': the folder does not exist or is not writable");
  }
}

AtomicFile::~AtomicFile() {
  if (!committed_) {
    stream_.close();
    std::error_code ignored;
    fs::remove(temporary_, ignored);
  }
}

void AtomicFile::Commit() {
  stream_.flush();
  bool ok = static_cast<bool>(stream_);
  stream_.close();
  if (!ok) {
    std::error_code ignored;
    fs::remove(temporary_, ignored);
    throw InputError("writing output file '" + target_.string() + "' failed (disk full?)");
  }
  std::error_code ec;
  fs::rename(temporary_, target_, ec);
  if (ec) {
    fs::remove(temporary_, ec);
    throw InputError("cannot replace output file '" + target_.string() + "': " + ec.message());
  }
  committed_ = true;
}

void WriteFileAtomically(const fs::path& target, std::string_view content) {
  AtomicFile file(target);
  file.stream().write(content.data(), static_cast<std::streamsize>(content.size()));
  file.Commit();
}

void CheckNotAnInput(const fs::path& output, const std::vector<fs::path>& inputs) {
  std::error_code ec;
  if (!fs::exists(output, ec)) return;
  for (const auto& input : inputs) {
    if (input.empty() || !fs::exists(input, ec)) continue;
    if (fs::equivalent(output, input, ec)) {
      throw InputError("output file '" + output.string() + "' is also an input ('" + input.string() +
                       "'); refusing to write over an input");
    }
  }
}

}  // namespace stagefit
