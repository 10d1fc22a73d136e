#pragma once
// Error types shared by every layer. The command line maps them to exit codes (SPEC §4):
//   UsageError -> 1, InputError -> 2, NumericalError -> 3.

#include <sstream>
#include <stdexcept>
#include <string>

namespace stagefit {

/// A command-line usage error (unknown option, missing argument). Exit code 1.
class UsageError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Bad user input: a file, field or value that is wrong. The message names the file, the field, the
/// value and what was expected. Exit code 2.
class InputError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// The numerics failed (singular system, fit that does not converge when the caller asked for
/// convergence). Exit code 3.
class NumericalError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

namespace internal {
[[noreturn]] void AssertionFailed(const char* condition, const char* file, int line,
                                  const std::string& message);
}  // namespace internal

}  // namespace stagefit

/// Always-on check of an internal invariant (not of user input): throws std::logic_error.
#define STAGEFIT_ASSERT(condition, message)                                                  \
  do {                                                                                       \
    if (!(condition)) {                                                                      \
      std::ostringstream stagefit_assert_stream_;                                            \
      stagefit_assert_stream_ << message;                                                    \
      ::stagefit::internal::AssertionFailed(#condition, __FILE__, __LINE__,                  \
                                            stagefit_assert_stream_.str());                  \
    }                                                                                        \
  } while (false)
