#include "stagefit/common/atomic_file.h"

#include <signal.h>
#include <unistd.h>

#include <array>
#include <atomic>
#include <cstdio>
#include <cstring>

#include "stagefit/common/error.h"

namespace stagefit {
namespace fs = std::filesystem;

namespace {
std::atomic<int> g_counter{0};

// The temporary files of writes in progress, for the signal handler: fixed storage (no allocation
// in the handler), a slot is free (0), being filled (1) or holds a path to remove (2).
constexpr int kMaxPending = 64;
constexpr std::size_t kMaxPathBytes = 4096;
std::array<std::atomic<int>, kMaxPending> g_slot_state{};
char g_slot_path[kMaxPending][kMaxPathBytes];

int ListPending(const fs::path& path) {
  const std::string& s = path.native();
  if (s.size() >= kMaxPathBytes) return -1;
  for (int i = 0; i < kMaxPending; ++i) {
    int expected = 0;
    if (g_slot_state[i].compare_exchange_strong(expected, 1)) {
      std::memcpy(g_slot_path[i], s.c_str(), s.size() + 1);
      g_slot_state[i].store(2);
      return i;
    }
  }
  return -1;  // more than kMaxPending writes at once: this one is not cleaned up on a signal
}

void Unlist(int slot) {
  if (slot >= 0) g_slot_state[slot].store(0);
}

void RemovePendingAndReraise(int signal_number) {
  for (int i = 0; i < kMaxPending; ++i) {
    if (g_slot_state[i].load() == 2) ::unlink(g_slot_path[i]);
  }
  // The handler was installed with SA_RESETHAND: the default action (end the program) is back, and
  // the re-raised signal is delivered when this handler returns.
  ::raise(signal_number);
}

}  // namespace

TemporaryPath::TemporaryPath(fs::path target) : target_(std::move(target)) {
  temporary_ = target_;
  temporary_ += ".tmp-" + std::to_string(::getpid()) + "-" + std::to_string(g_counter++);
  slot_ = ListPending(temporary_);
}

TemporaryPath::~TemporaryPath() {
  if (!moved_) {
    std::error_code ignored;
    fs::remove(temporary_, ignored);
  }
  Unlist(slot_);
}

void TemporaryPath::MoveOverTarget() {
  std::error_code ec;
  fs::rename(temporary_, target_, ec);
  if (ec) {
    fs::remove(temporary_, ec);
    throw InputError("cannot replace output file '" + target_.string() + "': " + ec.message());
  }
  moved_ = true;
}

AtomicFile::AtomicFile(fs::path target) : temporary_(std::move(target)) {
  stream_.open(temporary_.path(), std::ios::binary | std::ios::trunc);
  if (!stream_) {
    throw InputError("cannot write output file '" + temporary_.target().string() +
                     "': the folder does not exist or is not writable");
  }
}

AtomicFile::~AtomicFile() { stream_.close(); }

void AtomicFile::Commit() {
  stream_.flush();
  const bool ok = static_cast<bool>(stream_);
  stream_.close();
  if (!ok || stream_.fail()) {
    throw InputError("writing output file '" + temporary_.target().string() + "' failed (disk full?)");
  }
  temporary_.MoveOverTarget();
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

void RemoveTemporaryFilesOnSignal() {
  struct sigaction action;
  std::memset(&action, 0, sizeof action);
  action.sa_handler = RemovePendingAndReraise;
  action.sa_flags = SA_RESETHAND;
  sigemptyset(&action.sa_mask);
  for (int signal_number : {SIGINT, SIGTERM, SIGHUP}) ::sigaction(signal_number, &action, nullptr);
}

}  // namespace stagefit
