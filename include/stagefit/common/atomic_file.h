#pragma once
// Outputs are written atomically: to a temporary file beside the target, then renamed over it, so a
// reader (or an interrupted run) sees either the old file or the complete new one, never half a file.

#include <filesystem>
#include <fstream>
#include <string>
#include <string_view>
#include <vector>

namespace stagefit {

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
  const std::filesystem::path& target() const { return target_; }
  const std::filesystem::path& temporary_path() const { return temporary_; }

  /// Flushes, closes and renames the temporary file over the target. Throws InputError on failure.
  void Commit();

 private:
  std::filesystem::path target_;
  std::filesystem::path temporary_;
  std::ofstream stream_;
  bool committed_ = false;
};

/// Writes `content` to `target` atomically.
void WriteFileAtomically(const std::filesystem::path& target, std::string_view content);

/// Throws InputError when `output` is the same file as any of `inputs` (the program never writes over
/// one of its inputs). Paths that do not exist yet never clash.
void CheckNotAnInput(const std::filesystem::path& output,
                     const std::vector<std::filesystem::path>& inputs);

}  // namespace stagefit
