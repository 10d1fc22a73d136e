#pragma once
// Shared by the libFuzzer programs of tests/fuzz/ (one per file reader). Each writes the input bytes
// to a scratch file, as the reader takes a path, and calls the reader. An InputError is the reader's
// documented answer to a malformed file and ends the input quietly; any other exception escapes and
// libFuzzer reports it as a crash, as it does for sanitizer findings, timeouts and huge allocations.

#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <system_error>

#include "stagefit/common/error.h"

namespace stagefit::fuzz {

/// A folder private to this process, removed when it exits normally: in $STAGEFIT_FUZZ_TMPDIR when
/// set, else in /dev/shm (memory) when it exists, else in the system's temporary folder.
inline const std::filesystem::path& ScratchFolder() {
  namespace fs = std::filesystem;
  static const fs::path folder = [] {
    fs::path base;
    if (const char* env = std::getenv("STAGEFIT_FUZZ_TMPDIR"); env != nullptr && *env != '\0') {
      base = env;
    } else if (std::error_code ec; fs::is_directory("/dev/shm", ec)) {
      base = "/dev/shm";
    } else {
      base = fs::temp_directory_path();
    }
    const fs::path p = base / ("stagefit-fuzz-" + std::to_string(::getpid()));
    fs::create_directories(p);
    std::atexit([] {
      std::error_code ignored;
      fs::remove_all(ScratchFolder(), ignored);
    });
    return p;
  }();
  return folder;
}

/// Writes `size` bytes at `data` to ScratchFolder()/`name`, replacing what was there; returns the path.
inline std::filesystem::path WriteScratchFile(const std::string& name, const std::uint8_t* data,
                                              std::size_t size) {
  const std::filesystem::path path = ScratchFolder() / name;
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
  out.close();
  if (!out) std::abort();  // a full /dev/shm or TMPDIR, not a finding: stop loudly
  return path;
}

/// Removes ScratchFolder()/`name` if it exists.
inline void RemoveScratchFile(const std::string& name) {
  std::error_code ignored;
  std::filesystem::remove(ScratchFolder() / name, ignored);
}

/// True when the input has the header of a MATLAB v7.3 file (an HDF5 file) and the environment
/// variable STAGEFIT_FUZZ_V73 is not 1. Such inputs are skipped by the .mat targets: most mutations
/// of them end inside the HDF5 library (1.10), which on corrupt files allocates by declared sizes
/// (gigabytes, never touched), leaks and reports "infinite loop closing library". Those are HDF5's
/// bugs, not stagefit's, and would make every short run fail at random; STAGEFIT_FUZZ_V73=1 fuzzes
/// them too (docs/reliability.md).
inline bool SkipMatV73(const std::uint8_t* data, std::size_t size) {
  static const bool fuzz_v73 = [] {
    const char* env = std::getenv("STAGEFIT_FUZZ_V73");
    return env != nullptr && std::string(env) == "1";
  }();
  if (fuzz_v73 || size < 128) return false;
  const std::uint8_t* v = data + 124;  // version 0x0200, then "IM" (little-endian) or "MI" (big)
  return (v[0] == 0x00 && v[1] == 0x02 && v[2] == 'I' && v[3] == 'M') ||
         (v[0] == 0x02 && v[1] == 0x00 && v[2] == 'M' && v[3] == 'I');
}

/// Calls `read()`; an InputError is the expected outcome of most inputs and is swallowed.
template <typename Read>
void ReadAcceptingInputError(Read&& read) {
  try {
    read();
  } catch (const InputError&) {
  }
}

}  // namespace stagefit::fuzz
