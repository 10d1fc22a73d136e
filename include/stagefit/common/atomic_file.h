#pragma once
// Outputs are written atomically: to a temporary file beside the target, then renamed over it, so a
// reader (or an interrupted run) sees either the old file or the complete new one, never half a file.
// Temporary files are named "<target>.tmp-<pid>-<n>". They are removed when a write is abandoned (an
// exception), and, once RemoveTemporaryFilesOnSignal() was called, when the program is interrupted
// by SIGINT, SIGTERM or SIGHUP; only a SIGKILL (or a crash) during a write can leave one behind.

#include <filesystem>
#include <fstream>
#include <string>
#include <string_view>
#include <vector>

namespace stagefit {

/// A temporary path "<target>.tmp-<pid>-<n>" beside `target`, for writers that need a file name
/// (matio). The file, once the writer created it, is removed on destruction (and on interruption)
/// unless MoveOverTarget() renamed it over the target.
class TemporaryPath {
 public:
  explicit TemporaryPath(std::filesystem::path target);
  ~TemporaryPath();
  TemporaryPath(const TemporaryPath&) = delete;
  TemporaryPath& operator=(const TemporaryPath&) = delete;

  const std::filesystem::path& path() const { return temporary_; }
  const std::filesystem::path& target() const { return target_; }

  /// Renames the temporary file over the target (atomic on one file system). Throws InputError on
  /// failure, after removing the temporary file.
  void MoveOverTarget();

 private:
  std::filesystem::path target_;
  std::filesystem::path temporary_;
  int slot_ = -1;  ///< entry in the list of files removed on interruption; -1 = not listed
  bool moved_ = false;
};

/// A file being written. Write to stream(), then Commit(); if destroyed without Commit() (an
/// exception, an early return) the temporary file is removed and the target is left untouched.
class AtomicFile {
 public:
  /// Opens "<target>.tmp-<pid>-<n>" for writing. Throws InputError when the folder does not exist or
  /// cannot be written.
  explicit AtomicFile(std::filesystem::path target);
  ~AtomicFile();
  AtomicFile(const AtomicFile&) = delete;
  AtomicFile& operator=(const AtomicFile&) = delete;

  std::ostream& stream() { return stream_; }
  const std::filesystem::path& target() const { return temporary_.target(); }
  const std::filesystem::path& temporary_path() const { return temporary_.path(); }

  /// Flushes, closes and renames the temporary file over the target. Throws InputError on failure.
  void Commit();

 private:
  TemporaryPath temporary_;
  std::ofstream stream_;
};

/// Writes `content` to `target` atomically.
void WriteFileAtomically(const std::filesystem::path& target, std::string_view content);

/// Throws InputError when `output` is the same file as any of `inputs` (the program never writes over
/// one of its inputs). Paths that do not exist yet never clash.
void CheckNotAnInput(const std::filesystem::path& output,
                     const std::vector<std::filesystem::path>& inputs);

/// Installs handlers for SIGINT, SIGTERM and SIGHUP that remove the temporary files of the writes in
/// progress, then end the program by the same signal (exit status 128 + signal in a shell), so that an
/// interrupted run leaves the earlier outputs intact and no temporary file behind. The handler only
/// calls async-signal-safe functions (unlink, sigaction, raise). Call once, at the start of main().
void RemoveTemporaryFilesOnSignal();

}  // namespace stagefit
